"""Commands, sticks and bad bytes from ground stations, as QGroundControl and Mission Planner send them (a link
audit, 2026-12-06).

The daemon under `autopilot run --sim`, pymavlink as the ground stations over loopback UDP (the rig of
tests/test_link_mavlink.py). What the boat did is read back from its own mission log.
"""

from __future__ import annotations

import math
import os
import time

import pytest
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.geo import local_to_latlon
from tests.test_link_mavlink import ORIGIN, Boat

NAN = math.nan
ROVER_MANUAL, ROVER_ACRO = 0, 1


def _stream_sticks(boat: Boat, mav, seconds: float, z: int, target: int = 1) -> None:
    """MANUAL_CONTROL at 20 Hz (a planner's joystick) to system ``target``, throttle ``z``, steering centred."""
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        mav.manual_control_send(target, 0, 0, z, 0, 0)
        boat.beat()
        boat.gcs.recv_match(blocking=True, timeout=0.05)


def test_only_the_ground_stations_sticks_drive(tmp_path):
    """Found by the audit: MANUAL_CONTROL was taken from any system. A second planner's joystick (system 254: a
    tablet's QGroundControl) drove the boat at 80 % in MANUAL, and its stream kept the manual timeout from ever
    firing once the operator's station (255) went quiet. ArduPilot takes sticks from SYSID_MYGCS only: here
    mavlink.gcs_system_id, whose heartbeat already counts for link loss."""
    boat = Boat(tmp_path)
    tablet = mavlink.MAVLink(boat.gcs, srcSystem=254, srcComponent=190)
    try:
        boat.mode_is("auto")
        n = len(boat.log())
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, ROVER_MANUAL).result == mavlink.MAV_RESULT_ACCEPTED
        _stream_sticks(boat, tablet, 2.0, 800)  # the operator's station sends none
        boat.mode_is("hold")  # the manual timeout: no input from the ground station
        tablet_run = [r for r in boat.log()[n:] if r["event"] == "cycle" and r["mode"] == "manual"]
        assert tablet_run and max(abs(r["tau_com_n"]) for r in tablet_run) < 1.0
        timeout = next(r for r in boat.log()[n:] if r["event"] == "mode" and r["mode"] == "hold")
        assert timeout["from"] == "manual" and timeout["cause"].startswith("manual: no input")
        said = [r for r in boat.log()[n:] if r["event"] == "command" and "from system 254 ignored" in str(r["answer"])]
        assert len(said) == 1 and not said[0]["accepted"]  # once, not 40 times

        # stop 48's note: sticks broadcast to system 0 were taken (PX4 does, ArduPilot does not): a planner's
        # joystick meant for one boat of a fleet drove every boat on the radio
        n = len(boat.log())
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, ROVER_MANUAL).result == mavlink.MAV_RESULT_ACCEPTED
        _stream_sticks(boat, boat.gcs.mav, 1.5, 800, target=0)
        broadcast = [r for r in boat.log()[n:] if r["event"] == "cycle" and r["mode"] == "manual"]
        assert broadcast and max(abs(r["tau_com_n"]) for r in broadcast) < 1.0
        said = [r for r in boat.log()[n:] if r["event"] == "command" and "to system 0 ignored" in str(r["answer"])]
        assert len(said) == 1 and "mavlink.system_id 1" in said[0]["answer"]

        n = len(boat.log())  # the ground station's own sticks, to this boat, still drive
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, ROVER_MANUAL).result == mavlink.MAV_RESULT_ACCEPTED
        _stream_sticks(boat, boat.gcs.mav, 1.5, 800)
        driven = [r for r in boat.log()[n:] if r["event"] == "cycle" and r["mode"] == "manual"]
        assert max(r["tau_com_n"] for r in driven) > 10.0
    finally:
        assert boat.stop() == 0


def test_change_speed_is_flown_a_bad_one_denied_and_an_unsupported_command_said(tmp_path):
    """Mission Planner's and QGroundControl's Change Speed (MAV_CMD_DO_CHANGE_SPEED) was answered UNSUPPORTED (stop
    47's note): it is now the speed over ground of every leg, as ArduPilot Rover's desired speed; param2 -1 changes
    nothing, -2 gives the planned speeds back; a speed outside [0.05, 3.5] m/s, a NaN or a climb speed (param1 2) is
    DENIED naming the parameter. Found by an earlier audit: a command the boat does not carry out (DO_SET_SERVO, a
    number MAVLink does not define) was answered UNSUPPORTED and nothing else; now said, once every 10 s a command."""
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        n = len(boat.log())
        assert boat.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, 1, 1.6, -1, 0).result == mavlink.MAV_RESULT_ACCEPTED
        # told to every station (read first: wait_log's heartbeats read past it)
        assert boat.recv("STATUSTEXT", pred=lambda m: m.text == "speed 1.6 m/s on every leg (mavlink speed)")
        said = boat.wait_log(lambda r: r["event"] == "speed", what="the speed set", after=n)
        assert (said["speed_m_s"], said["cause"]) == (1.6, "mavlink speed")
        boat.wait_log(lambda r: r["event"] == "cycle" and r["t_s"] > said["t_s"] + 6.0, what="6 s at it", after=n)
        flown = [r["speed_cmd_m_s"] for r in boat.log()[n:] if r["event"] == "cycle" and r["t_s"] > said["t_s"]
                 and r["mode"] == "auto" and r.get("speed_cmd_m_s")]
        assert max(flown) == pytest.approx(1.6, abs=0.01), flown  # the pond mission's planned 1.0 m/s before
        for params, why in (((1, -3.0), "param2 (speed, m/s) -3 is not in [0.05, 3.5] m/s"),
                            ((1, 1e9), "param2 (speed, m/s) 1e+09 is not in [0.05, 3.5]"),
                            ((0, NAN), "param2 (speed, m/s) nan is not"),
                            ((2, 1.0), "param1 (speed type) 2 is not 0 (airspeed) or 1 (ground speed)")):
            assert boat.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, *params, -1, 0).result == mavlink.MAV_RESULT_DENIED
            boat.wait_log(lambda r, w=why: r["event"] == "command" and w in str(r.get("answer")), what=why, after=n)
        assert boat.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, 0, -1.0, -1, 0).result == mavlink.MAV_RESULT_ACCEPTED
        assert boat.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, 1, -2.0, -1, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "speed" and r["speed_m_s"] is None, what="the planned speeds", after=n)
        assert [r["speed_m_s"] for r in boat.log()[n:] if r["event"] == "speed"] == [1.6, None]  # -1: no change

        n = len(boat.log())
        assert boat.command(mavlink.MAV_CMD_DO_SET_SERVO, 9, 1500).result == mavlink.MAV_RESULT_UNSUPPORTED
        # read before the next command: Boat.command drains what came before it (at 8x the text came in that gap)
        text = boat.recv("STATUSTEXT", pred=lambda m: m.text.startswith("DO_SET_SERVO not supported"))
        assert text.severity == mavlink.MAV_SEVERITY_WARNING
        assert boat.command(mavlink.MAV_CMD_DO_SET_SERVO, 9, 1900).result == mavlink.MAV_RESULT_UNSUPPORTED
        assert boat.command(55555).result == mavlink.MAV_RESULT_UNSUPPORTED  # no MAV_CMD at all
        boat.wait_log(lambda r: r["event"] == "command" and r["answer"] == "command 55555 not supported",
                      what="the unknown command", after=n)
        said = [r for r in boat.log()[n:] if r["event"] == "command" and r["command"] == "DO_SET_SERVO"]
        assert len(said) == 1 and not said[0]["accepted"] and "two thrusters" in said[0]["answer"]
        assert not [r for r in boat.log()[n:] if r["event"] in ("mode", "param", "arming", "speed")]
        boat.mode_is("auto")
    finally:
        assert boat.stop() == 0


def test_bad_input_is_refused_and_logged_and_the_daemon_flies_on(tmp_path):
    """A regression guard of the audit (these were right): ARM with NaN, a custom mode the boat has not (ACRO, 99,
    -1, 1.5), a reposition to NaN are DENIED naming what is wrong; a reposition with NaN in the fields that may be
    NaN (speed, yaw, altitude) is taken; garbage datagrams and frames cut short are dropped; a MAVLink 1 ground
    station is answered (a command and a float MISSION_ITEM upload); the daemon never stops or breaks a handler."""
    boat = Boat(tmp_path)
    v1 = mavlink1.MAVLink(None, srcSystem=255, srcComponent=190)
    try:
        boat.mode_is("auto")
        n = len(boat.log())
        denied = [(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (NAN,), "param1 nan is not 0 (disarm) or 1 (arm)"),
                  (mavlink.MAV_CMD_DO_SET_MODE, (1, ROVER_ACRO), "mode 1 (ACRO) not supported"),
                  (mavlink.MAV_CMD_DO_SET_MODE, (1, 99), "mode 99 (unknown) not supported"),
                  (mavlink.MAV_CMD_DO_SET_MODE, (1, -1), "param2 (custom mode) -1 is not a whole number"),
                  (mavlink.MAV_CMD_DO_SET_MODE, (1, 1.5), "param2 (custom mode) 1.5 is not a whole number"),
                  (mavlink.MAV_CMD_DO_REPOSITION, (-1, 0, 0, NAN, NAN, NAN, NAN), "position nan, nan is not valid")]
        for command, params, why in denied:
            assert boat.command(command, *params).result == mavlink.MAV_RESULT_DENIED, why
            boat.wait_log(lambda r, w=why: r["event"] == "command" and w in str(r.get("answer")), what=why, after=n)
        boat.mode_is("auto")

        for _ in range(100):  # a broken radio bridge: random bytes, frames cut short
            boat.gcs.write(os.urandom(280))
        boat.gcs.write(b"\xfd\x20\x00\x00\x00\xff\xbe\x4c\x00\x00")
        boat.gcs.write(b"\xfe\x21\x00\xff")
        boat.gcs.write(mavlink1.MAVLink_command_long_message(
            1, 1, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 0).pack(v1))
        ack = boat.recv("COMMAND_ACK", pred=lambda m: m.command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "mode" and r["mode"] == "rtl" and r["cause"] == "mavlink rtl",
                      what="the rtl", after=n)

        lat, lon = local_to_latlon(20.0, 20.0, *ORIGIN)
        go_here = boat.command(mavlink.MAV_CMD_DO_REPOSITION, NAN, 1, 0, NAN, lat, lon, NAN)
        assert go_here.result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("hold")

        boat.drain()  # a MAVLink 1 upload of float MISSION_ITEMs, home at item 0
        points = [ORIGIN, local_to_latlon(30.0, 30.0, *ORIGIN)]
        boat.gcs.write(mavlink1.MAVLink_mission_count_message(1, 1, 2).pack(v1))
        while True:
            m = boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
            if m.get_type() == "MISSION_ACK":
                break
            lat, lon = points[m.seq]
            boat.gcs.write(mavlink1.MAVLink_mission_item_message(1, 1, m.seq, 3, 16, 0, 1, 0, 0, 0, 0, lat, lon,
                                                                 0).pack(v1))
        assert m.type == mavlink.MAV_MISSION_ACCEPTED
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="the MAVLink 1 upload", after=n)
        assert [[round(x) for x in w] for w in replaced["waypoints"]] == [[30, 30]]
        assert boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1) is not None
    finally:
        assert boat.stop() == 0
    assert not [r for r in boat.log() if r["event"] == "info" and r.get("message") == "mavlink message not handled"]
