"""A hold, a GUIDED or a pause asked for before control starts (the helm's first step with a position): pure.

Found by an operator audit: LOITER or GUIDED set from a planner before the first fix was refused ("position
stale") and the boat flew the mission once control started; set after the first fix but before it was
confirmed, it was accepted and the planner was shown INITIALISING. Now it is taken, reported as the mode
asked for, and placed when control starts. The daemon and the link: tests/test_daemon_modes_before_start.py
and tests/test_link_modes_before_start.py.
"""

from __future__ import annotations

import dataclasses
import math

from autopilot.daemon.cycle import reported_mode
from autopilot.gnc import Autopilot, GncConfig, NavInput
from autopilot.gnc.modes import HoldMode, PausedMode, PendingHold
from autopilot.logschema import Mode

# where control starts: 3 m north and 4 m east of the origin, at rest, heading east
START = NavInput(north_m=3.0, east_m=4.0, psi_rad=math.pi / 2.0, speed_m_s=0.0, yaw_rate_rad_s=0.0,
                 course_rad=math.pi / 2.0)


def helm() -> Autopilot:
    return Autopilot(GncConfig(), [(30.0, 0.0), (30.0, 30.0)])


def test_a_hold_before_the_first_fix_is_taken_reported_and_placed_where_control_starts():
    ap = helm()
    assert not ap.mode_chosen and reported_mode(Mode.WAITING, ap) is Mode.WAITING  # the mission's own start
    assert ap.request("hold", None, cause="mavlink guided", unavailable="position stale") == (True, "hold")
    assert isinstance(ap.current, PendingHold) and ap.mode is Mode.HOLD
    assert reported_mode(Mode.WAITING, ap) is Mode.HOLD  # the planner's GUIDED, not INITIALISING
    # asked again (a planner repeats it until the heartbeat shows it): the same pending hold, its cause the new one
    pending = ap.current
    assert ap.request("hold", None, cause="mavlink hold") == (True, "hold")
    assert ap.current is pending and ap.mode_cause == "mavlink hold"
    out = ap.step(START, 0.1)  # control starts
    assert isinstance(ap.current, HoldMode) and out.mode is Mode.HOLD
    assert out.hold_target_ne_m == (3.0, 4.0) and out.reached_index is None  # held there, the mission not flown
    assert [(f["from"], f["mode"], f["cause"]) for name, f in ap.pop_events() if name == "mode"] == [
        ("auto", "hold", "mavlink guided"), ("hold", "hold", "mavlink hold")]  # none more when it begins


def test_a_go_here_and_a_heading_given_before_the_start_are_kept():
    ap = helm()
    assert ap.request("hold", None, cause="mavlink reposition", target_ne_m=(10.0, -5.0)) == (True, "hold")
    assert ap.request("hold", None, cause="ctl hold --heading 90", heading_rad=math.pi / 2.0) == (True, "hold")
    out = ap.step(START, 0.1)
    assert out.hold_target_ne_m == (3.0, 4.0)  # the last asked for: here, at the heading given
    assert math.isclose(ap.current.keeper.heading_rad, math.pi / 2.0)
    ap = helm()
    ap.request("hold", None, cause="mavlink reposition", target_ne_m=(10.0, -5.0))
    assert ap.step(START, 0.1).hold_target_ne_m == (10.0, -5.0)


def test_a_pause_before_the_start_resumes_into_the_mission_and_the_mission_may_be_chosen_back():
    ap = helm()
    assert ap.request("pause", None, cause="ctl pause") == (True, "paused")
    assert ap.request("resume", None, cause="ctl resume") == (True, "auto")  # no position needed to go back
    assert ap.current is ap.auto and ap.mode_chosen  # chosen: shown as AUTO, not INITIALISING
    assert ap.request("pause", None, cause="ctl pause") == (True, "paused")
    out = ap.step(START, 0.1)
    assert isinstance(ap.current, PausedMode) and out.hold_target_ne_m == (3.0, 4.0)
    assert ap.request("resume", START, cause="ctl resume") == (True, "auto")  # the mission from its first waypoint
    assert ap.wp_index == 0


def test_after_the_start_a_position_is_needed_again_and_rtl_waits_for_a_launch_point():
    ap = helm()
    assert ap.request("rtl", None, cause="ctl rtl", unavailable="position stale") == (
        False, "rtl refused: no launch point yet (control has not started)")
    ap.step(START, 0.1)
    # control has started: a hold without a position is refused (ArduPilot's requires_position), as before
    assert ap.request("hold", None, cause="ctl hold", unavailable="position stale") == (
        False, "hold refused: position stale")
    moving = dataclasses.replace(START, speed_m_s=1.0)
    assert ap.request("hold", moving, cause="ctl hold") == (True, "hold")
    assert not isinstance(ap.current, PendingHold)  # placed at once (its stopping point ahead)
    assert ap.current.keeper.target[1] > START.east_m


def test_a_failsafe_hold_before_the_start_is_refused_and_its_fault_takes_stop():
    """The guard: a fault's hold without a position takes stop, before control starts too (never a pending hold
    that would drive the boat once data came back)."""
    from autopilot.daemon.cycle import answer_failsafe
    from autopilot.daemon.failsafe import Request

    ap = helm()
    ok, answer = ap.request("hold", None, cause="failsafe geofence", unavailable="position stale")
    assert not ok and answer == "hold refused: position stale" and ap.mode is Mode.AUTO
    req = Request(cause="geofence", action="hold", configured="hold")
    assert answer_failsafe(ap, req, None, "position stale") == ("stop", "hold refused: position stale")
    assert ap.mode is Mode.STOP


def test_the_link_s_lost_station_action_before_the_start_is_kept_as_an_operator_s():
    """README's modes table: the link's own action (ground station lost) is not a latched fault's, and is kept."""
    from autopilot.gnc.modes import RtlMode

    ap = helm()
    assert ap.request("hold", None, cause="mavlink: ground station lost", unavailable="position stale") == (True, "hold")
    assert isinstance(ap.current, PendingHold)
    ap = Autopilot(GncConfig(), [(30.0, 0.0)], launch_ne_m=(0.0, 0.0))  # a restart carrying its launch point
    assert ap.request("rtl", None, cause="mavlink: ground station lost", unavailable="position stale") == (True, "rtl")
    assert isinstance(ap.current, RtlMode)
