"""The MAVLink mission protocol (https://mavlink.io/en/services/mission.html), vehicle side.

    upload     GCS: MISSION_COUNT n      -> us: MISSION_REQUEST_INT 0 .. n-1 (each re-asked after
               GCS: MISSION_ITEM_INT k      ITEM_TIMEOUT_S, ITEM_RETRIES times) -> checked as a mission
                                            file is (autopilot.mission.mission_from_items) -> the loop
                                            swaps it in between two cycles -> MISSION_ACK ACCEPTED, or
                                            an error code naming the item (and a STATUSTEXT saying why)
    download   GCS: MISSION_REQUEST_LIST -> us: MISSION_COUNT; GCS: MISSION_REQUEST(_INT) k -> MISSION_ITEM_INT k
    clear      GCS: MISSION_CLEAR_ALL    -> the loop clears it (holds if it was flying it) -> MISSION_ACK
               (or MISSION_COUNT 0)         (DENIED while another station uploads; the uploader's own ends its upload)
    current    GCS: MISSION_SET_CURRENT  -> the loop jumps there -> MISSION_CURRENT
    go here    GCS: MISSION_ITEM(_INT) with current = 2 (a guided goto) -> hold there -> MISSION_ACK

Item 0 is home, as ArduPilot's planners write it; fence and rally items (mission types 1, 2) are not
supported (MAV_MISSION_UNSUPPORTED). One upload at a time: a station is its ids, its endpoint and its address
on it (two planners on one port may both be 255/190), and the upload's requests and acks go to it alone.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.mission import NAV_WAYPOINT, MissionItemError, mission_from_items

__all__ = ["MissionProtocol", "ITEM_TIMEOUT_S", "ITEM_RETRIES"]

ITEM_TIMEOUT_S = 1.5
ITEM_RETRIES = 5
MAX_ITEMS = 500
_ERROR_CODE = {
    "command": mavlink.MAV_MISSION_UNSUPPORTED, "frame": mavlink.MAV_MISSION_UNSUPPORTED_FRAME,
    "x": mavlink.MAV_MISSION_INVALID_PARAM5_X, "y": mavlink.MAV_MISSION_INVALID_PARAM6_Y,
    "param1": mavlink.MAV_MISSION_INVALID_PARAM1, "param2": mavlink.MAV_MISSION_INVALID_PARAM2,
    "sequence": mavlink.MAV_MISSION_INVALID_SEQUENCE,
    "mission": mavlink.MAV_MISSION_INVALID,
}


@dataclass
class _Upload:
    peer: tuple[int, int]  # (system, component) of the ground station uploading
    count: int
    source: object = None  # where its datagrams come from on its endpoint (its UDP address; None: a radio)
    items: list = field(default_factory=list)
    asked_at: float = 0.0
    retries: int = 0


def item_of(msg) -> dict:
    """A MISSION_ITEM_INT (or the float MISSION_ITEM) as the mission parser's item."""
    is_int = msg.get_type() == "MISSION_ITEM_INT"
    return dict(seq=msg.seq, frame=msg.frame, command=msg.command, param1=float(msg.param1),
                param2=float(msg.param2), lat_deg=msg.x / 1e7 if is_int else float(msg.x),
                lon_deg=msg.y / 1e7 if is_int else float(msg.y))


def _is_home(item: dict) -> bool:
    """Item 0 as QGroundControl and Mission Planner write home for an ArduPilot vehicle: a waypoint (16) in the
    global frame (0)."""
    return int(item.get("command", -1)) == NAV_WAYPOINT and int(item.get("frame", -1)) == mavlink.MAV_FRAME_GLOBAL


class MissionProtocol:
    """One per link. ``link.send(endpoint, message)``, ``link.submit(request, answer)``, ``link.refused(what, why)`` (logged; the log's listener shows it)."""

    def __init__(self, link) -> None:
        self.link = link
        self.uploads: dict = {}  # endpoint -> _Upload
        self.download_items: list | None = None
        self._download_of: tuple | None = None  # (the loop's mission, cleared) the download's items are of

    def handle(self, ep, msg, source=None) -> None:
        """One mission message from endpoint ``ep``; ``source`` is the sender's address on it (None: a radio)."""
        t = msg.get_type()
        mission_type = getattr(msg, "mission_type", 0)
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        mav = ep.mav
        if t == "MISSION_COUNT":
            if mission_type != mavlink.MAV_MISSION_TYPE_MISSION:
                self._ack(ep, peer, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)
                return
            if self._another_uploads(ep, peer, source, "mission"):
                return
            # a count from the station uploading starts its upload again (as ArduPilot's): its empty mission's
            # clear left the old upload asking it for items for 9 s, then acked CANCELLED (a link audit)
            self.uploads.pop(ep, None)
            if msg.count == 0:  # an empty mission: MAVLink's way to clear it, as MISSION_CLEAR_ALL
                self._clear(ep, peer, to=source)
                return
            if not 1 <= msg.count <= MAX_ITEMS:
                self.link.refused("mission", f"mission refused: {msg.count} items (1..{MAX_ITEMS})")
                self._ack(ep, peer, mavlink.MAV_MISSION_NO_SPACE, to=source)
                return
            self.uploads[ep] = _Upload(peer, msg.count, source)
            self._ask(ep)
        elif t in ("MISSION_ITEM_INT", "MISSION_ITEM") and msg.current == 2:
            # a guided "fly to here" (Mission Planner's, ArduPilot's convention): not a mission item
            it = item_of(msg)
            request = self.link.reposition(it["lat_deg"], it["lon_deg"])
            if request is None:
                self._ack(ep, peer, mavlink.MAV_MISSION_ERROR)
                return
            self.link.submit({**request, "source": "mavlink"},
                             lambda reply: self._ack(ep, peer, mavlink.MAV_MISSION_ACCEPTED if reply["ok"]
                                                     else mavlink.MAV_MISSION_ERROR))
        elif t in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            up = self.uploads.get(ep)
            if up is None or (up.peer, up.source) != (peer, source) or msg.seq != len(up.items):
                return  # not asked for (a duplicate, or not from the station uploading): the next request follows
            up.items.append(item_of(msg))
            up.retries = 0
            if len(up.items) < up.count:
                self._ask(ep)
            else:
                del self.uploads[ep]
                self._finish(ep, up)
        elif t == "MISSION_REQUEST_LIST":
            if mission_type != mavlink.MAV_MISSION_TYPE_MISSION:
                ep.send(mav.mission_count_encode(peer[0], peer[1], 0, mission_type))
                return
            self.download_items = self.link.mission_items()
            self._download_of = self._mission_now()
            ep.send(mav.mission_count_encode(peer[0], peer[1], len(self.download_items)))
        elif t in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            # the items counted at the list request, while that mission is the loop's: one uploaded or cleared since
            # is served as it is now, as ArduPilot serves from its store (the old one's count refused its items)
            same = self.download_items is not None and self._download_of is not None and (
                self._download_of[0] is self._mission_now()[0] and self._download_of[1] == self._mission_now()[1])
            items = self.download_items if same else self.link.mission_items()
            if not 0 <= msg.seq < len(items):
                self._ack(ep, peer, mavlink.MAV_MISSION_INVALID_SEQUENCE)
                return
            it = items[msg.seq]
            current = 1 if it["seq"] == self.link.current_item() else 0
            if t == "MISSION_REQUEST":  # asked for the float item, answered with it (as ArduPilot does)
                ep.send(mav.mission_item_encode(peer[0], peer[1], it["seq"], it["frame"], it["command"], current, 1,
                                                it["param1"], it["param2"], 0.0, 0.0, it["lat_deg"], it["lon_deg"], 0.0))
                return
            ep.send(mav.mission_item_int_encode(
                peer[0], peer[1], it["seq"], it["frame"], it["command"], current, 1, it["param1"], it["param2"],
                0.0, 0.0, int(round(it["lat_deg"] * 1e7)), int(round(it["lon_deg"] * 1e7)), 0.0))
        elif t == "MISSION_CLEAR_ALL":
            # MAV_MISSION_TYPE_ALL (255) clears every type there is: here the mission
            if mission_type not in (mavlink.MAV_MISSION_TYPE_MISSION, mavlink.MAV_MISSION_TYPE_ALL):
                self._ack(ep, peer, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)
                return
            # while another station uploads, refused (ArduPilot refuses any clear while it receives): that upload
            # would have replaced the cleared mission moments later; the uploading station's own clear ends its
            # upload (it went on asking for items for 9 s, then acked CANCELLED)
            if self._another_uploads(ep, peer, source, "mission clear", mission_type):
                return
            self.uploads.pop(ep, None)
            self._clear(ep, peer, mission_type, to=source)
        elif t in ("MISSION_WRITE_PARTIAL_LIST", "MISSION_REQUEST_PARTIAL_LIST"):
            # answered, not left to the planner's timeout (ArduPilot takes them; here a mission is whole)
            self.link.refused("mission", f"{t} not supported: send the whole mission (MISSION_COUNT) or ask for "
                                         "it whole (MISSION_REQUEST_LIST)")
            self._ack(ep, peer, mavlink.MAV_MISSION_UNSUPPORTED, mission_type)
        elif t == "MISSION_ACK":
            up = self.uploads.get(ep)
            if up is not None and (up.peer, up.source) == (peer, source):
                # the uploading station ends its upload (OPERATION_CANCELLED, or any other outcome of its own): the
                # boat kept asking it for the next item for 9 s, and another station's upload was refused meanwhile
                # (a new-user audit); the mission being flown stays
                del self.uploads[ep]
                self.link.refused("mission", f"mission upload cancelled by the ground station after {len(up.items)} "
                                             f"of {up.count} items (MISSION_ACK {msg.type})")
        elif t == "MISSION_SET_CURRENT":
            seq = self.link.item_to_fly(int(msg.seq))
            index = self.link.waypoint_of_item(seq, "MISSION_SET_CURRENT")
            if index is None:
                self.link.send_mission_current()  # the answer MAVLink has: the current item, unchanged
                return
            self.link.submit({"command": "set_current", "index": index, "item": seq, "source": "mavlink"},
                             lambda reply: self.link.send_mission_current())

    def _another_uploads(self, ep, peer, source, what: str, mission_type: int = 0) -> bool:
        """True, and ``what`` refused (DENIED, logged and shown), while a station other than this one uploads.

        One upload at a time: two stations' items once filled one mission, acked to the other. A station on another
        endpoint, or at another address on the same one, is another even with the same ids: QGC and Mission Planner
        are both 255/190, and on one udpin port the second's MISSION_COUNT restarted the first's upload, which
        then took either's items and acked both ACCEPTED (a link audit)."""
        for e, up in self.uploads.items():
            if e is ep and (up.peer, up.source) == (peer, source):
                continue
            where = " on another link" if e is not ep else " at another address" if up.peer == peer else ""
            self.link.refused("mission", f"{what} refused: system {up.peer[0]}{where} is uploading one")
            self._ack(ep, peer, mavlink.MAV_MISSION_DENIED, mission_type, to=source)
            return True
        return False

    def _clear(self, ep, peer, mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION, to=None) -> None:
        # the ack echoes the request's type, as ArduPilot does: QGC ignored one of type 0 for a clear of 255
        self.link.submit({"command": "mission_clear", "source": "mavlink"},
                         lambda reply: self._ack(ep, peer, mavlink.MAV_MISSION_ACCEPTED if reply["ok"]
                                                 else mavlink.MAV_MISSION_DENIED, mission_type, to=to))

    def tick(self, now_s: float) -> None:
        """Re-ask a missing item; give up after ITEM_RETRIES (the running mission stays)."""
        for ep, up in list(self.uploads.items()):
            if now_s - up.asked_at < ITEM_TIMEOUT_S:
                continue
            if up.retries >= ITEM_RETRIES:
                del self.uploads[ep]
                self.link.refused("mission", f"mission upload abandoned: item {len(up.items)} never came")
                self._ack(ep, up.peer, mavlink.MAV_MISSION_OPERATION_CANCELLED, to=up.source)
                continue
            up.retries += 1
            self._ask(ep)

    def _mission_now(self) -> tuple:
        loop = self.link.loop
        return loop.mission, bool(loop.ap.mission_cleared)

    def _ask(self, ep) -> None:
        up = self.uploads[ep]
        up.asked_at = time.monotonic()
        ep.send(ep.mav.mission_request_int_encode(up.peer[0], up.peer[1], len(up.items)), to=up.source)

    def _ack(self, ep, peer, code: int, mission_type: int = 0, to=None) -> None:
        """MISSION_ACK to ``peer``; ``to``: its source on the endpoint, so that only it hears (None: everyone)."""
        ep.send(ep.mav.mission_ack_encode(peer[0], peer[1], code, mission_type), to=to)

    def _finish(self, ep, up: _Upload) -> None:
        if len(up.items) == 1 and _is_home(up.items[0]):
            # home alone: a planner's mission with every waypoint deleted, as QGroundControl and Mission Planner
            # upload it to an ArduPilot vehicle; refused as "no waypoints" before (stop 48's note), it is a clear, as
            # MISSION_COUNT 0 and MISSION_CLEAR_ALL. One item of another kind (a waypoint sent the PX4 way, a lone
            # return or loiter) stays refused: cleared, the boat held without a word (a review)
            self._clear(ep, up.peer, to=up.source)
            return
        origin = self.link.origin()
        try:
            mission = mission_from_items(up.items, origin_lat_deg=origin[0], origin_lon_deg=origin[1],
                                         max_range_m=self.link.max_range_m())
        except MissionItemError as exc:
            self.link.refused("mission", str(exc))
            self._ack(ep, up.peer, _ERROR_CODE.get(exc.field, mavlink.MAV_MISSION_INVALID), to=up.source)
            return

        def answer(reply: dict) -> None:
            self._ack(ep, up.peer, mavlink.MAV_MISSION_ACCEPTED if reply["ok"] else mavlink.MAV_MISSION_DENIED,
                      to=up.source)

        self.link.submit({"command": "mission", "mission": mission, "source": "mavlink"}, answer)
