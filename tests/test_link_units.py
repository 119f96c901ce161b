"""The MAVLink link's pure parts: mode numbering, parameters, endpoints, mission items, telemetry, the key."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.daemon.config import DaemonConfig
from autopilot.link import params as P
from autopilot.link import telemetry as T
from autopilot.link.endpoint import parse_endpoint
from autopilot.link.link import load_signing_key
from autopilot.link.modes import ROVER_MODES, command_for_rover_mode, rover_mode
from autopilot.logschema import Mode
from autopilot.mission import MissionItemError, mission_from_items, mission_to_items
from autopilot.schema import ConfigError

MAV = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)


def test_every_mode_has_a_rover_number_and_the_planners_modes_map_back():
    for m in Mode:
        assert rover_mode(m) in ROVER_MODES
    assert [command_for_rover_mode(n) for n in (10, 5, 11, 4, 0, 15)] == ["auto", "hold", "rtl", "stop", "manual",
                                                                           "hold"]
    assert command_for_rover_mode(3) is None and command_for_rover_mode(12) is None  # STEERING, SMART_RTL
    # the hold at home an rtl ends in is Rover's RTL still (LOITER came unasked: a GCS audit)
    assert rover_mode("hold", "rtl: at the launch point") == 11 and rover_mode("hold", "ctl hold") == 5


def test_a_mode_change_is_said_with_the_planners_name_of_the_mode():
    """Found by a GCS audit: the LOITER chosen came back as "mode hold", the HOLD as "mode stop"."""
    assert T.event_text("mode", {"mode": "hold", "cause": "mavlink hold"})[1] == "mode hold (LOITER): mavlink hold"
    assert T.event_text("mode", {"mode": "stop", "cause": "mavlink stop"})[1] == "mode stop (HOLD): mavlink stop"
    assert T.event_text("mode", {"mode": "hold", "cause": "mavlink guided"})[1] == "mode hold (GUIDED): mavlink guided"


def test_parameters_are_configuration_keys_with_their_ranges():
    cfg = DaemonConfig()
    for p in P.PARAMS:
        assert len(p.name) <= 16
        assert math.isfinite(P.value_of(cfg, p))  # every key exists
    kp = P.by_name("HDG_KP")
    assert P.check_set(cfg, kp, 2.0) == 2.0
    with pytest.raises(ConfigError, match=r"HDG_KP \(gnc.pid.kp_n_per_deg: 50.0 is outside the allowed range \[0, 10\]"):
        P.check_set(cfg, kp, 50.0)
    with pytest.raises(ConfigError, match="not a finite number"):
        P.check_set(cfg, kp, float("nan"))
    act = P.by_name("FS_GF_ACT")
    assert P.value_of(cfg, act) == 2.0 and P.check_set(cfg, act, 1.0) == "hold"  # stop, hold, rtl
    with pytest.raises(ConfigError, match="is not one of 0 = stop, 1 = hold, 2 = rtl"):
        P.check_set(cfg, act, 3.0)
    assert P.check_set(cfg, P.by_name("FS_ACK_MISS"), 7.0) == 7 and isinstance(P.check_set(cfg, P.by_name("FS_ACK_MISS"), 7.0), int)
    # the wire's float32: 1.2 arrives as 1.2000000476837158; the value set (and logged) is the 1.2 typed
    f32 = float(np.float32(1.2))
    assert f32 != 1.2 and P.check_set(cfg, kp, f32) == 1.2
    with pytest.raises(ConfigError, match=r"HDG_KP \(gnc.pid.kp_n_per_deg: 10.1 is outside"):
        P.check_set(cfg, kp, float(np.float32(10.1)))
    # the declared type: a REAL32 (or 0, unsaid) is read as the float it is; any other is another type's bytes
    assert P.check_set(cfg, kp, 2.0, mavlink.MAV_PARAM_TYPE_REAL32) == 2.0 == P.check_set(cfg, kp, 2.0, 0)
    with pytest.raises(ConfigError, match=r"HDG_KP \(gnc.pid.kp_n_per_deg\): param_type 6 \(MAV_PARAM_TYPE_INT32\) "
                                          r"refused: every parameter here is a float, param_type 9 "):
        P.check_set(cfg, kp, 1.401298464324817e-45, mavlink.MAV_PARAM_TYPE_INT32)
    assert P.WIRE_TYPE == mavlink.MAV_PARAM_TYPE_REAL32


@pytest.mark.parametrize("url, kind", [("udpout:127.0.0.1:14550", "udpout"), ("udpin:0.0.0.0:14550", "udpin"),
                                       ("/dev/ttyUSB0:57600", "serial"), ("serial:/dev/radio:115200", "serial")])
def test_endpoint_forms(url, kind):
    assert parse_endpoint(url).kind == kind


@pytest.mark.parametrize("url, words", [
    ("tcp:1.2.3.4:5760", "not an endpoint (udpout:HOST:PORT, udpin:ADDR:PORT or /dev/PATH:BAUD)"),
    ("udpout:14550", "expected udpout:HOST:PORT"),
    ("udpin:0.0.0.0:99999", "port 99999 outside 1..65535"),
    ("udpout:host:abc", "port 'abc' is not a number"),
    ("/dev/ttyUSB0", "needs its baud rate"),
    ("/dev/ttyUSB0:1234", "baud rate 1234 is not one of"),
])
def test_bad_endpoints_are_refused_naming_what_is_wrong(url, words):
    with pytest.raises(ValueError) as exc:
        parse_endpoint(url)
    assert words in str(exc.value) and repr(url) in str(exc.value)
    with pytest.raises(ConfigError, match="mavlink.endpoints"):
        from autopilot.link.config import MavlinkConfig

        MavlinkConfig(endpoints=(url,))


def _item(seq, cmd, lat, lon, frame=3, p1=0.0):
    return dict(seq=seq, frame=frame, command=cmd, param1=p1, param2=0.0, lat_deg=lat, lon_deg=lon)


def test_mission_items_round_trip_and_refusals_name_the_item():
    items = [_item(0, 16, 52.0, 4.4, frame=0), _item(1, 16, 52.0002, 4.4), _item(2, 19, 52.0003, 4.4001, p1=30.0),
             _item(3, 20, 0, 0, frame=2)]
    m = mission_from_items(items, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert m.holds_s == (None, 30.0) and m.rtl
    back = mission_to_items(m)
    assert [b["command"] for b in back] == [16, 16, 19, 20] and back[2]["param1"] == 30.0
    for bad, field, words in [
        (items[:1] + [_item(1, 16, 95.0, 4.4)], "x", "item 1: latitude 95.0 outside -90..90 deg"),
        (items[:1] + [_item(1, 16, 52.0, 200.0)], "y", "longitude"),
        (items[:1] + [_item(1, 16, 52.0, 4.4, frame=1)], "frame", "frame 1 not supported"),
        (items[:1] + [_item(1, 183, 52.0, 4.4)], "command", "command 183 not supported"),
        (items[:1] + [_item(2, 16, 52.0, 4.4)], "sequence", "item 1 arrived as item 2"),
        (items[:1] + [_item(1, 19, 52.001, 4.4, p1=-3.0)], "param1", "loiter time -3 s outside"),
        (items[:1] + [_item(1, 16, 60.0, 4.4)], "mission", "farther than"),
        (items[:1] + [_item(1, 20, 0, 0, frame=2), _item(2, 16, 52.0, 4.4)], "command", "nothing may follow"),
    ]:
        with pytest.raises(MissionItemError) as exc:
            mission_from_items(bad, origin_lat_deg=52.0, origin_lon_deg=4.4)
        assert exc.value.field == field and words in str(exc.value), str(exc.value)


def test_change_speed_minus_one_means_no_change():
    """MAVLink's DO_CHANGE_SPEED param2 -1 is "no change"; it was refused as a negative speed."""
    items = [_item(0, 16, 52.0, 4.4, frame=0), dict(_item(1, 178, 0, 0, frame=2), param2=1.5),
             _item(2, 16, 52.0002, 4.4), dict(_item(3, 178, 0, 0, frame=2), param2=-1.0), _item(4, 16, 52.0003, 4.4)]
    m = mission_from_items(items, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert m.speeds_m_s == (1.5, 1.5)


def test_heartbeat_says_mode_arming_and_state():
    hb = T.heartbeat(MAV, {"mode": "auto", "armed": True})
    assert (hb.type, hb.autopilot, hb.custom_mode, hb.system_status) == (11, 3, 10, mavlink.MAV_STATE_ACTIVE)
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert T.heartbeat(MAV, {"mode": "failsafe"}).system_status == mavlink.MAV_STATE_CRITICAL
    off = T.heartbeat(MAV, {"mode": "hold", "armed": False})
    assert off.custom_mode == 5 and not off.base_mode & 128 and off.system_status == mavlink.MAV_STATE_STANDBY
    assert T.heartbeat(MAV, {"mode": "manual"}).base_mode & mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    # a hold asked for as GUIDED (or a "go here") is GUIDED while it lasts: reported as LOITER, QGC's Start Mission
    # (GUIDED, arm, MISSION_START) saw the mode change fail and gave up (found by a GCS audit)
    assert T.heartbeat(MAV, {"mode": "hold", "mode_cause": "mavlink guided"}).custom_mode == 15
    assert T.heartbeat(MAV, {"mode": "hold", "mode_cause": "mavlink hold"}).custom_mode == 5


def test_sys_status_health_follows_the_failsafe():
    st = {"active_faults": ["position_stale", "mbed_ack_missing"], "battery_v": 12.31}
    s = T.sys_status(MAV, st)
    gps, mag, motors = (T.SENSORS[k] for k in ("position", "heading", "mbed"))
    assert s.onboard_control_sensors_present & gps and not s.onboard_control_sensors_health & gps
    assert s.onboard_control_sensors_health & mag and not s.onboard_control_sensors_health & motors
    assert s.voltage_battery == 12310
    assert T.sys_status(MAV, {"active_faults": []}).voltage_battery == 65535  # not reported: UINT16_MAX


def test_no_position_is_sent_before_the_first_fix_and_long_texts_are_chunked():
    assert T.global_position_int(MAV, {"lat_deg": None}, 0) is None
    gp = T.global_position_int(MAV, {"lat_deg": 52.1, "lon_deg": 4.3, "sog_m_s": 1.0, "cog_deg": 90.0,
                                     "heading_deg": 359.96}, 10)
    assert (gp.lat, gp.lon, gp.vx, gp.vy, gp.hdg) == (521000000, 43000000, 0, 100, 35996)
    chunks = T.statustext(MAV, 4, "x" * 120)
    assert len(chunks) == 3 and len({c.id for c in chunks}) == 1 and [c.chunk_seq for c in chunks] == [0, 1, 2]
    # a multiple of 50: the last chunk must end with a NUL, so an empty one follows (found by a GCS audit)
    chunks = T.statustext(MAV, 4, "y" * 100)
    assert [len(c.text) for c in chunks] == [50, 50, 0] and [c.chunk_seq for c in chunks] == [0, 1, 2]


def test_a_position_jump_is_said_to_the_ground_station():
    refused = T.event_text("position_jump", {"distance_m": 299.6, "gate_m": 35.0, "accepted": False})
    moved = T.event_text("position_jump", {"distance_m": 61.4, "gate_m": 45.0, "accepted": True})
    assert refused == (mavlink.MAV_SEVERITY_WARNING, "GPS jump of 300 m refused")
    assert moved == (mavlink.MAV_SEVERITY_NOTICE, "GPS position moved 61 m (two fixes agree)")
    assert T.event_text("position_jump", {"distance_m": 420.0, "accepted": False, "repeated": True}) is None


def test_signing_key_file_must_be_private_and_well_formed(tmp_path):
    f = tmp_path / "k"
    f.write_text("ab" * 32)
    f.chmod(0o600)
    assert load_signing_key(str(f)) == bytes([0xAB]) * 32
    f.chmod(0o640)
    with pytest.raises(ConfigError, match=r"readable by others \(mode 640\); chmod 600"):
        load_signing_key(str(f))
    f.chmod(0o600)
    f.write_text("not a key")
    with pytest.raises(ConfigError, match="expected 64 hexadecimal digits or 32 bytes"):
        load_signing_key(str(f))
    with pytest.raises(ConfigError, match="cannot read"):
        load_signing_key(str(tmp_path / "missing"))


def test_message_interval_keeps_each_rate_in_its_configured_range():
    """Found by review: SET_MESSAGE_INTERVAL with -1 turned the HEARTBEAT off (heartbeat_hz's range is
    [0.2, 10] Hz in the configuration), and the ground station then counted the boat lost."""
    from autopilot.link.config import MavlinkRates
    from autopilot.link.link import rate_for_interval

    rates = MavlinkRates()
    hb, att = mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_ATTITUDE
    assert rate_for_interval(rates, hb, -1) == (None, "SET_MESSAGE_INTERVAL refused: HEARTBEAT off (-1) is below "
                                                      "rates.heartbeat_hz's minimum 0.2 Hz")
    assert rate_for_interval(rates, hb, 1e9)[0] is None and "0.001 Hz (1e+09 us)" in rate_for_interval(rates, hb, 1e9)[1]
    assert rate_for_interval(rates, hb, 0) == (1.0, "") and rate_for_interval(rates, hb, 2e5) == (5.0, "")
    assert rate_for_interval(rates, hb, 10.0) == (10.0, "")  # faster than allowed: the fastest allowed
    assert rate_for_interval(rates, att, -1) == (0.0, "")  # telemetry may be turned off
    assert rate_for_interval(rates, att, 1e5) == (10.0, "") and rate_for_interval(rates, att, 1.0) == (50.0, "")


def test_the_ground_station_back_text_has_no_dangling_colon():
    """Found by a ground-station audit: 'ground station back:' (the action of a station's return is None)."""
    assert T.event_text("gcs", {"state": "back", "action": None})[1] == "ground station back"
    assert T.event_text("gcs", {"state": "lost", "action": "hold"})[1] == "ground station lost: hold"


def test_ais_vessel_carries_status_zero_dimension_flags_and_the_turn_rate():
    """Found by an AIS audit: navigational status 0 ("under way using engine") was sent as 15 (undefined), a 300-m
    bow was flagged "larger than 511 m" (the flag was set above 255), and the turn rate was always 0, not valid."""
    import math

    from pymavlink.dialects.v20 import ardupilotmega as dialect

    from autopilot.drivers.ais import AisTarget
    from autopilot.link.telemetry import ais_vessel

    mav = dialect.MAVLink(None)
    t = AisTarget(mmsi=244000101, ais_class="A", last_t_s=0.0, lat_deg=52.0, lon_deg=4.4, sog_m_s=2.0, cog_rad=0.0,
                  heading_rad=0.0, nav_status=0, to_bow_m=300.0, to_stern_m=511.0, to_port_m=20.0,
                  to_starboard_m=63.0, turn_rad_s=math.radians(-1.5))
    m = ais_vessel(mav, t, 1.0)
    assert m.navigational_status == 0
    assert (m.dimension_bow, m.dimension_stern, m.dimension_port, m.dimension_starboard) == (300, 511, 20, 63)
    assert not m.flags & dialect.AIS_FLAGS_LARGE_BOW_DIMENSION and not m.flags & dialect.AIS_FLAGS_LARGE_PORT_DIMENSION
    assert m.flags & dialect.AIS_FLAGS_LARGE_STERN_DIMENSION and m.flags & dialect.AIS_FLAGS_LARGE_STARBOARD_DIMENSION
    assert m.flags & dialect.AIS_FLAGS_VALID_TURN_RATE and m.turn_rate == -15  # 0.1 deg/s
    unknown = ais_vessel(mav, AisTarget(mmsi=1, ais_class="B", last_t_s=0.0, lat_deg=52.0, lon_deg=4.4), 1.0)
    assert unknown.navigational_status == 15 and not unknown.flags & dialect.AIS_FLAGS_VALID_TURN_RATE


@pytest.mark.parametrize("tau_com_n", [-40.0, 40.0, -500.0])
def test_vfr_hud_encodes_a_reverse_throttle_as_its_size(tau_com_n):
    """Found by a GCS audit: a negative common thrust (braking in a hold, backing) made VFR_HUD's uint16 throttle
    unencodable, and the HUD froze on old values for as long as it lasted. ArduPilot sends abs()."""
    msg = T.vfr_hud(MAV, {"sog_m_s": 0.4, "heading_deg": 359.6, "tau_com_n": tau_com_n, "max_forward_n": 200.0})
    decoded = mavlink.MAVLink(None).parse_char(msg.pack(MAV))
    assert decoded.throttle == min(100, round(abs(tau_com_n) / 2.0)) and decoded.heading == 0


def test_a_message_that_does_not_encode_is_counted_and_told_once_per_send():
    from autopilot.link.link import _Port

    class Quiet:
        tx_errors = 0
        sent: list = []

        def send(self, data):
            self.sent.append(data)

    told = []
    port = _Port(Quiet(), MAV, lambda kind, exc: told.append((kind, type(exc).__name__)))
    port.send(MAV.vfr_hud_encode(0.0, 0.0, 0, -20, 0.0, 0.0))  # uint16 throttle -20: does not pack
    port.send(MAV.vfr_hud_encode(0.0, 0.0, 0, 20, 0.0, 0.0))
    assert port.endpoint.tx_errors == 1 and len(port.endpoint.sent) == 1
    assert told == [("VFR_HUD", "error")]


def test_the_waypoints_done_before_the_missions_rtl_are_not_said_to_be_the_mission_complete():
    """Found by a GCS audit: "mission complete" came before the mission's own RTL item ran."""
    assert T.event_text("mission_complete", {"wp_count": 3, "rtl": True})[1] == \
        "mission waypoints done: returning to launch"
    assert T.event_text("mission_complete", {"wp_count": 3, "rtl": False})[1] == "mission complete"
    assert T.event_text("mission_complete", {"wp_count": 3})[1] == "mission complete"  # a log before the field
