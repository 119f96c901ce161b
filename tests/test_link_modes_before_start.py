"""GUIDED and LOITER set from a planner before control starts, over real UDP (pymavlink as the ground station).

`autopilot run --sim --mavlink udpout:...` as in tests/test_link_mavlink.py, with the shipped wait for a
confirmed first fix made long enough to act in. Found by an operator audit: before the first fix the mode
change was DENIED ("hold refused: position stale") and the boat flew the mission once control started;
after it, it was ACCEPTED but the HEARTBEAT went on saying INITIALISING (16), and the planner showed the
change undone. Now the HEARTBEAT carries the mode set, with the state BOOT until control starts.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from tests.test_link_mavlink import Boat

CONFIRM_S = 20.0  # failsafe.position_confirm_s: control starts this long after the first fix (5 s wall at 4x)
ROVER_GUIDED, ROVER_LOITER = 15, 5


def _ours(m) -> bool:
    return m.get_srcSystem() == 1


def test_guided_then_loiter_set_before_control_starts_are_reported_and_flown(tmp_path):
    boat = Boat(tmp_path, config={"failsafe": {"position_confirm_s": CONFIRM_S}})
    try:
        assert boat.recv("HEARTBEAT", pred=_ours).custom_mode == 16  # INITIALISING: the mission starts by itself
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, ROVER_GUIDED).result == mavlink.MAV_RESULT_ACCEPTED
        hb = boat.recv("HEARTBEAT", pred=lambda m: _ours(m) and m.custom_mode != 16)
        assert (hb.custom_mode, hb.system_status) == (ROVER_GUIDED, mavlink.MAV_STATE_BOOT)
        boat.gcs.mav.set_mode_send(1, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, ROVER_LOITER)
        assert boat.recv("COMMAND_ACK", pred=lambda m: m.command == 11).result == mavlink.MAV_RESULT_ACCEPTED
        hb = boat.recv("HEARTBEAT", pred=lambda m: _ours(m) and m.custom_mode != ROVER_GUIDED)
        assert (hb.custom_mode, hb.system_status) == (ROVER_LOITER, mavlink.MAV_STATE_BOOT)
        assert {c["mode"] for c in boat.cycles()} == {"waiting"}  # all this before control started
        boat.mode_is("hold", 30.0)
        hb = boat.recv("HEARTBEAT", pred=lambda m: _ours(m) and m.system_status != mavlink.MAV_STATE_BOOT)
        assert (hb.custom_mode, hb.system_status) == (ROVER_LOITER, mavlink.MAV_STATE_ACTIVE)
    finally:
        assert boat.stop() == 0
    driven = [c for c in boat.cycles() if c["mode"] != "waiting"]
    assert driven and {c["mode"] for c in driven} == {"hold"}  # the mission never flown
    launch = next(r for r in boat.log() if r["event"] == "launch")
    assert math.hypot(driven[0]["hold_north_m"] - launch["north_m"], driven[0]["hold_east_m"] - launch["east_m"]) < 1.0
    modes = [(r["from"], r["mode"], r["cause"]) for r in boat.log() if r["event"] == "mode"]
    assert modes == [("auto", "hold", "mavlink guided"), ("hold", "hold", "mavlink hold")]
