"""The mission protocol as QGroundControl and Mission Planner drive it, quirks included (a link audit, 2026-12-06).

The daemon under `autopilot run --sim`, pymavlink as the ground stations over loopback UDP (the rig of
tests/test_link_mavlink.py). What the boat did is read back from its own mission log.
"""

from __future__ import annotations

import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.geo import local_to_latlon
from tests.test_link_mavlink import ORIGIN, Boat, _free_udp_port

REQUESTS = ["MISSION_REQUEST_INT", "MISSION_REQUEST"]
WAYPOINT, LOITER_TURNS, DO_JUMP, DO_SET_SERVO = 16, 18, 177, 183
GLOBAL, MISSION_FRAME, GLOBAL_RELATIVE_ALT, GLOBAL_INT, GLOBAL_RELATIVE_ALT_INT = 0, 2, 3, 5, 6


def _item(seq: int, north_m: float, east_m: float, *, command: int = WAYPOINT, frame: int = GLOBAL_RELATIVE_ALT_INT,
          param1: float = 0.0, param2: float = 0.0) -> tuple:
    """(seq, frame, command, param1, param2, lat_deg, lon_deg) of a point ``north_m``, ``east_m`` from the origin."""
    lat, lon = local_to_latlon(north_m, east_m, *ORIGIN)
    return seq, frame, command, param1, param2, lat, lon


def _send(mav, it: tuple, *, as_float: bool = False) -> None:
    """MISSION_ITEM_INT, or the float MISSION_ITEM that Mission Planner still sends."""
    seq, frame, command, p1, p2, lat, lon = it
    if as_float:
        mav.mission_item_send(1, 1, seq, frame, command, 0, 1, p1, p2, 0, 0, lat, lon, 0)
    else:
        mav.mission_item_int_send(1, 1, seq, frame, command, 0, 1, p1, p2, 0, 0, round(lat * 1e7), round(lon * 1e7), 0)


def _upload(boat: Boat, items: list[tuple], *, as_float: bool = False) -> tuple[int, list[int]]:
    """A whole upload as a planner drives it: (the MISSION_ACK type, the item numbers asked for)."""
    boat.drain()
    boat.gcs.mav.mission_count_send(1, 1, len(items))
    asked = []
    while True:
        m = boat.recv([*REQUESTS, "MISSION_ACK"])
        if m.get_type() == "MISSION_ACK":
            return m.type, asked
        asked.append(m.seq)
        _send(boat.gcs.mav, items[m.seq], as_float=as_float)


def _quiet(boat: Boat, seconds: float, types=(*REQUESTS, "MISSION_ACK")) -> list:
    """What of ``types`` the ground station hears in ``seconds`` (beating meanwhile)."""
    heard = []
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        boat.beat()
        m = boat.gcs.recv_match(type=list(types), blocking=True, timeout=0.1)
        if m is not None:
            heard.append(m)
    return heard


def _refusals(boat: Boat, after: int = 0) -> list[str]:
    return [str(r["answer"]) for r in boat.log()[after:] if r["event"] == "command" and not r["accepted"]]


def test_a_clear_during_an_upload_ends_the_uploaders_upload_and_is_refused_to_another_station(tmp_path):
    """Found by the audit. A planner that gives up mid-upload and clears (MISSION_COUNT 0, or MISSION_CLEAR_ALL) was
    answered ACCEPTED, and then the dead upload went on asking it for the next item five times over 9 s, acked
    OPERATION_CANCELLED, logged "upload abandoned" and refused another station's upload meanwhile; ArduPilot's
    count restarts the upload. A second station's clear during an upload was carried out and silently undone by
    the upload's end moments later (ArduPilot refuses a clear while it receives): now DENIED, saying why."""
    boat = Boat(tmp_path)
    other = mavlink.MAVLink(boat.gcs, srcSystem=254, srcComponent=190)  # a second planner on the same link
    square = [_item(0, 0.0, 0.0, frame=GLOBAL), _item(1, 40.0, 0.0), _item(2, 40.0, 40.0), _item(3, 0.0, 40.0)]
    try:
        boat.mode_is("auto")
        for clear in ("count 0", "clear all"):
            boat.drain()
            boat.gcs.mav.mission_count_send(1, 1, 4)
            assert boat.recv(REQUESTS).seq == 0
            _send(boat.gcs.mav, square[0])
            assert boat.recv(REQUESTS).seq == 1
            if clear == "count 0":
                boat.gcs.mav.mission_count_send(1, 1, 0)
            else:
                boat.gcs.mav.mission_clear_all_send(1, 1)
            assert boat.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
            boat.mode_is("hold")  # cleared: it holds
            heard = _quiet(boat, 2.5)  # more than ITEM_TIMEOUT_S: the old upload re-asked item 1 by now
            assert not heard, (clear, [(m.get_type(), getattr(m, "seq", None)) for m in heard])

        assert _upload(boat, square)[0] == mavlink.MAV_MISSION_ACCEPTED  # a mission to fly again
        assert boat.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("auto")
        boat.gcs.mav.mission_count_send(1, 1, 4)  # 255 uploads ...
        assert boat.recv(REQUESTS).seq == 0
        n = len(boat.log())
        other.mission_clear_all_send(1, 1)  # ... and 254 clears meanwhile
        denied = boat.recv("MISSION_ACK", pred=lambda m: m.target_system == 254)
        assert denied.type == mavlink.MAV_MISSION_DENIED
        boat.wait_log(lambda r: r["event"] == "command" and "mission clear refused: system 255 is uploading one"
                      in str(r.get("answer")), what="the refusal", after=n)
        for seq in range(4):  # 255's upload goes on, untouched
            if seq:
                assert boat.recv(REQUESTS, pred=lambda m: m.target_system == 255).seq == seq
            _send(boat.gcs.mav, square[seq])
        assert boat.recv("MISSION_ACK", pred=lambda m: m.target_system == 255).type == mavlink.MAV_MISSION_ACCEPTED
        boat.mode_is("auto")
        assert not [r for r in boat.log()[n:] if r["event"] == "command" and r["command"] == "mission_clear"]
        assert not [a for a in _refusals(boat) if "abandoned" in a]
    finally:
        assert boat.stop() == 0


def test_two_planners_with_the_same_ids_on_one_udpin_port_are_told_apart(tmp_path):
    """Found by the audit: QGroundControl and Mission Planner are both system 255, component 190. On one udpin port
    the second one's MISSION_COUNT restarted the first one's upload; the boat asked both (replies went to every
    peer), took whichever item came first, and acked both ACCEPTED: a mission neither had sent, or the first's
    mission reported as the second's. Now the sender's address tells them apart: the second is DENIED, and only
    it hears so, the first's upload goes on and is the mission flown."""
    port = _free_udp_port()
    boat = Boat(tmp_path, extra_args=("--mavlink", f"udpin:127.0.0.1:{port}"))
    qgc = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    planner = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    qgc_items = [_item(0, 0.0, 0.0, frame=GLOBAL), _item(1, 40.0, 0.0), _item(2, 40.0, 30.0)]
    planner_items = [_item(0, 0.0, 0.0, frame=GLOBAL), _item(1, -40.0, 0.0), _item(2, -40.0, -30.0)]
    heard = {"qgc": [], "planner": []}

    def pump(seconds: float) -> None:
        """Both planners answer every request they hear with their own items, as each would mid-upload."""
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            boat.beat()
            boat.gcs.recv_match(blocking=False)
            for name, conn, items in (("qgc", qgc, qgc_items), ("planner", planner, planner_items)):
                m = conn.recv_match(type=[*REQUESTS, "MISSION_ACK"], blocking=True, timeout=0.02)
                if m is None:
                    continue
                heard[name].append((m.get_type(), m.seq if m.get_type() != "MISSION_ACK" else m.type))
                if m.get_type() != "MISSION_ACK":
                    _send(conn.mav, items[m.seq])

    try:
        boat.mode_is("auto")
        for conn in (qgc, planner):  # the boat knows a udpin peer from what it sent
            conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        time.sleep(0.3)
        n = len(boat.log())
        qgc.mav.mission_count_send(1, 1, 3)
        request = qgc.recv_match(type=REQUESTS, blocking=True, timeout=10)
        assert request is not None and request.seq == 0
        heard["qgc"].append((request.get_type(), 0))
        _send(qgc.mav, qgc_items[0])
        planner.mav.mission_count_send(1, 1, 3)
        pump(3.0)
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="the mission", after=n)
    finally:
        qgc.close()
        planner.close()
        assert boat.stop() == 0
    acks = {name: [v for kind, v in got if kind == "MISSION_ACK"] for name, got in heard.items()}
    assert acks == {"qgc": [mavlink.MAV_MISSION_ACCEPTED], "planner": [mavlink.MAV_MISSION_DENIED]}, heard
    assert [v for kind, v in heard["qgc"] if kind != "MISSION_ACK"] == [0, 1, 2]
    assert [[round(x) for x in w] for w in replaced["waypoints"]] == [[40, 0], [40, 30]]
    assert any("mission refused: system 255 at another address is uploading one" in a for a in _refusals(boat, n))


def test_planners_quirks_are_answered_as_ardupilot_answers_them(tmp_path):
    """The quirks the two planners bring, each answered (a regression guard of the audit: these were right).
    Items the boat cannot fly (DO_JUMP, DO_SET_SERVO, NAV_LOITER_TURNS) are refused MAV_MISSION_UNSUPPORTED naming the
    item, the running mission kept; Mission Planner's float MISSION_ITEM upload, home at item 0, is flown; the global
    frames are taken, MAV_FRAME_MISSION for a waypoint refused; a duplicate or out-of-order item is ignored and the
    upload completes; the download gives back what was uploaded; a count of 0 clears and the boat holds."""
    boat = Boat(tmp_path)
    home = _item(0, 0.0, 0.0, frame=GLOBAL)
    try:
        boat.mode_is("auto")
        for command, bad in ((DO_JUMP, _item(3, 0, 0, command=DO_JUMP, frame=MISSION_FRAME, param1=1, param2=2)),
                             (DO_SET_SERVO, _item(3, 0, 0, command=DO_SET_SERVO, frame=MISSION_FRAME, param1=9,
                                                  param2=1500)),
                             (LOITER_TURNS, _item(3, 0.0, 40.0, command=LOITER_TURNS, param1=2))):
            n = len(boat.log())
            code, asked = _upload(boat, [home, _item(1, 40.0, 0.0), _item(2, 40.0, 40.0), bad])
            assert (code, asked) == (mavlink.MAV_MISSION_UNSUPPORTED, [0, 1, 2, 3])
            boat.wait_log(lambda r: r["event"] == "command" and f"item 3: command {command} not supported"
                          in str(r.get("answer")), what="the refusal", after=n)
        assert not [r for r in boat.log() if r["event"] == "mission_replaced"]  # the configured mission flies on

        for frame, code in ((GLOBAL_RELATIVE_ALT, mavlink.MAV_MISSION_ACCEPTED), (GLOBAL_INT, mavlink.MAV_MISSION_ACCEPTED),
                            (MISSION_FRAME, mavlink.MAV_MISSION_UNSUPPORTED_FRAME)):
            items = [home, _item(1, 30.0, 0.0, frame=frame), _item(2, 30.0, 30.0, frame=frame)]
            assert _upload(boat, items)[0] == code, frame

        n = len(boat.log())
        flown = [home, _item(1, 40.0, -10.0, frame=GLOBAL_RELATIVE_ALT), _item(2, 20.0, 30.0, frame=GLOBAL_RELATIVE_ALT)]
        assert _upload(boat, flown, as_float=True)[0] == mavlink.MAV_MISSION_ACCEPTED
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="the float upload", after=n)
        # a float32 latitude near 52 deg is good to ~0.4 m: Mission Planner's own precision
        assert [[round(x) for x in w] for w in replaced["waypoints"]] == [[40, -10], [20, 30]]
        boat.mode_is("auto")

        n = len(boat.log())  # duplicates and an item out of order: ignored, the next request follows
        boat.drain()
        boat.gcs.mav.mission_count_send(1, 1, 3)
        assert boat.recv(REQUESTS).seq == 0
        square = [home, _item(1, -30.0, 0.0), _item(2, -30.0, 30.0)]
        _send(boat.gcs.mav, square[0])
        _send(boat.gcs.mav, square[0])
        _send(boat.gcs.mav, square[2])
        assert boat.recv(REQUESTS).seq == 1
        _send(boat.gcs.mav, square[1])
        assert boat.recv(REQUESTS).seq == 2
        _send(boat.gcs.mav, square[2])
        assert boat.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
        _send(boat.gcs.mav, square[2])  # the last item again (a planner that missed the ack): nothing follows
        assert not _quiet(boat, 1.0)
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="the upload", after=n)
        assert [[round(x) for x in w] for w in replaced["waypoints"]] == [[-30, 0], [-30, 30]]

        boat.drain()
        boat.gcs.mav.mission_request_list_send(1, 1)
        assert boat.recv("MISSION_COUNT").count == 3
        for seq in (1, 2):
            boat.gcs.mav.mission_request_int_send(1, 1, seq)
            it = boat.recv("MISSION_ITEM_INT", pred=lambda m, s=seq: m.seq == s)
            assert (it.command, it.frame, it.x, it.y) == (WAYPOINT, GLOBAL_RELATIVE_ALT_INT, round(square[seq][5] * 1e7),
                                                          round(square[seq][6] * 1e7))
        boat.gcs.mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_ACCEPTED)

        boat.gcs.mav.mission_count_send(1, 1, 0)
        assert boat.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
        boat.mode_is("hold")
    finally:
        assert boat.stop() == 0
