"""The failsafe state machine alone: each fault trips it, recovery needs valid data for a while; latched
faults ask for their configured action, guarded (issue 15)."""

import dataclasses
import math

import pytest

from autopilot.daemon.commands import waiting_note
from autopilot.daemon.config import FailsafeActions, FailsafeConfig
from autopilot.daemon.failsafe import (
    CAUSES,
    FAULT_CLASS,
    LATCHED,
    Failsafe,
    Observation,
    Request,
    detect,
    guarded_action,
    inside_polygon,
    resting_voltage_v,
)

CFG = FailsafeConfig(heading_stale_s=1.0, position_stale_s=3.0, ack_missing_n=5, garbage_hold_s=1.0,
                     resume_valid_s=2.0, start_valid_s=1.0, max_mission_time_s=600.0, max_distance_m=100.0)
SQUARE = ((-50.0, -50.0), (-50.0, 50.0), (50.0, 50.0), (50.0, -50.0))


def good(t_s: float, **kw) -> Observation:
    base = dict(t_s=t_s, heading_age_s=0.05, heading_valid=True, position_age_s=0.5, fix_quality=1,
                ack_consecutive_missing=0, compass_connected=True, mbed_connected=True,
                last_garbage_t_s=None, north_m=1.0, east_m=2.0, mission_time_s=t_s)
    base.update(kw)
    return Observation(**base)


def run_until_auto(fs: Failsafe, t_s: float = 0.0, dt_s: float = 0.1) -> float:
    while fs.mode != "auto":
        fs.update(good(t_s))
        t_s += dt_s
        assert t_s < 10
    return t_s


TRANSIENT = [
    ("heading_stale", dict(heading_age_s=1.2)),
    ("heading_stale", dict(heading_age_s=math.inf, heading_valid=False)),
    ("heading_invalid", dict(heading_valid=False)),
    ("heading_frozen", dict(heading_still_turn_rad=math.radians(-20.0))),  # CFG's heading_frozen_deg: 20 deg
    ("position_stale", dict(position_age_s=3.5)),
    ("no_fix", dict(fix_quality=0)),
    ("mbed_ack_missing", dict(ack_consecutive_missing=5)),
    ("compass_port_lost", dict(compass_connected=False)),
    ("mbed_port_lost", dict(mbed_connected=False)),
    ("nmea_garbage", dict(last_garbage_t_s=-0.5)),  # relative to t_s, patched below
    ("mbed_garbage", dict(last_mbed_garbage_t_s=-0.5)),  # relative to t_s, patched below
]
LATCHING = [
    ("geofence", dict(north_m=60.0, east_m=0.0)),
    ("max_distance", dict(north_m=80.0, east_m=-80.0, _fence=False)),
    ("max_mission_time", dict(mission_time_s=600.0)),
]


@pytest.mark.parametrize("cause, change", TRANSIENT, ids=[f"{c}-{i}" for i, (c, _) in enumerate(TRANSIENT)])
def test_each_sensor_or_link_fault_trips_zero_thrust_in_the_same_cycle(cause, change):
    change = dict(change)
    fence = None if change.pop("_fence", True) is False else SQUARE
    fs = Failsafe(CFG, fence_ne_m=fence)
    t = run_until_auto(fs)
    assert fs.update(good(t)).thrust_allowed
    for key in ("last_garbage_t_s", "last_mbed_garbage_t_s"):
        if key in change:
            change[key] = t - 0.5
    d = fs.update(good(t + 0.1, **change))
    assert not d.thrust_allowed and d.mode == "failsafe"
    assert cause in d.active
    names = [(e.name, e.fields.get("cause")) for e in d.events]
    assert ("fault", cause) in names and ("failsafe", cause) in names
    ev = next(e for e in d.events if e.name == "failsafe").fields
    assert ev["action"] == "stop" and ev["configured"] == "stop" and ev["fallback"] is None
    assert d.requests == ()  # the failsafe itself stops the GNC: nothing for the helm


@pytest.mark.parametrize("cause, change", LATCHING, ids=[c for c, _ in LATCHING])
def test_each_latched_fault_asks_once_for_its_configured_action(cause, change):
    change = dict(change)
    fence = None if change.pop("_fence", True) is False else SQUARE
    fs = Failsafe(CFG, fence_ne_m=fence)
    t = run_until_auto(fs)
    d = fs.update(good(t + 0.1, **change))
    assert d.thrust_allowed and cause in d.active  # the helm carries the action out
    assert d.requests == (Request(cause, fs.configured(cause), fs.configured(cause), None),)
    assert ("fault", cause) in [(e.name, e.fields.get("cause")) for e in d.events]
    assert fs.update(good(t + 0.2, **change)).requests == ()  # once
    assert fs.action_of(cause) == fs.configured(cause)


def test_the_actions_are_configured_per_class():
    acts = FailsafeActions(geofence="hold", max_distance="stop", max_mission_time="rtl", battery_low="hold")
    fs = Failsafe(dataclasses.replace(CFG, actions=acts))
    assert [fs.configured(c) for c in ("geofence", "max_distance", "max_mission_time", "battery_low")] == [
        "hold", "stop", "rtl", "hold"]
    assert fs.configured("mbed_ack_missing") == "stop" and fs.configured("battery_critical") == "stop"
    assert {FAULT_CLASS[c] for c in CAUSES} >= {"position", "heading", "mbed"}


@pytest.mark.parametrize("configured, cls, missing, expect", [
    ("rtl", "geofence", None, ("rtl", None)),
    ("hold", "battery_low", None, ("hold", None)),
    ("rtl", "battery_low", "position stale", ("stop", "rtl needs a position and a heading: position stale")),
    ("rtl", "position", None, ("stop", "rtl needs a position and a heading: this is a position fault")),
    ("hold", "heading", None, ("stop", "hold needs a position and a heading: this is a heading fault")),
    ("rtl", "mbed", None, ("stop", None)),
    ("stop", "geofence", "heading stale", ("stop", None)),
])
def test_the_guard_never_takes_hold_or_rtl_without_a_position_and_heading(configured, cls, missing, expect):
    assert guarded_action(configured, cls, missing) == expect


def test_a_latched_fault_while_the_position_is_stale_takes_stop():
    fs = Failsafe(CFG, fence_ne_m=SQUARE)
    t = run_until_auto(fs)
    d = fs.update(good(t, north_m=60.0, east_m=0.0, position_age_s=5.0))  # outside, and the fix is old
    assert d.requests == (Request("geofence", "stop", "rtl", "rtl needs a position and a heading: position stale"),)
    assert d.mode == "failsafe"  # the stale position stops the GNC too


def test_battery_stages_need_the_voltage_low_for_their_time():
    cfg = dataclasses.replace(CFG, battery_low_v=12.0, battery_low_s=10.0, battery_critical_v=11.7,
                              battery_critical_s=5.0)
    fs = Failsafe(cfg)
    t = run_until_auto(fs)
    for k in range(95):  # a sag shorter than battery_low_s is not an empty battery
        assert fs.update(good(t + 0.1 * k, battery_v=11.9)).requests == ()
    assert fs.update(good(t + 9.6, battery_v=12.3)).requests == ()  # it recovered: the timer starts again
    t2 = t + 10.0
    reqs = [fs.update(good(t2 + 0.1 * k, battery_v=11.9)).requests for k in range(102)]
    got = [(k, r) for k, r in enumerate(reqs) if r]
    assert got == [(100, (Request("battery_low", "rtl", "rtl", None),))]
    t3 = t2 + 11.0
    reqs = [fs.update(good(t3 + 0.1 * k, battery_v=11.5)).requests for k in range(52)]
    got = [(k, r) for k, r in enumerate(reqs) if r]
    assert got == [(50, (Request("battery_critical", "stop", "stop", None),))]
    assert set(fs.latched) == {"battery_low", "battery_critical"}
    assert fs.update(good(t3 + 6.0, battery_v=None)).active[-2:] == ("battery_low", "battery_critical")  # latched


def test_a_later_failsafe_never_drives_a_boat_a_failsafe_stopped():
    """Found by a new-user audit: a flat battery (below both thresholds at once) tripped battery_critical after
    its 5 s and battery_low after its 10 s; low's rtl then replaced critical's stop and the boat drove on for
    half an hour on an empty battery. Now the stop stands; between hold and rtl the later one is taken."""
    cfg = dataclasses.replace(CFG, battery_low_v=12.0, battery_low_s=10.0, battery_critical_v=11.7,
                              battery_critical_s=5.0, actions=FailsafeActions(battery_low="rtl", geofence="hold"))
    fs = Failsafe(cfg)
    t = run_until_auto(fs)
    reqs = [r for k in range(120) for r in fs.update(good(t + 0.1 * k, battery_v=11.0)).requests]
    assert [(r.cause, r.action, r.overruled_by) for r in reqs] == [
        ("battery_critical", "stop", None), ("battery_low", "rtl", ("battery_critical", "stop"))]
    assert reqs[1].fallback == "battery_critical took stop before: a failsafe does not drive a boat a failsafe stopped"
    assert fs.action_of("battery_low") == "rtl"  # what it asked: its own configured action, not taken

    fs = Failsafe(cfg, fence_ne_m=[(-10.0, -10.0), (-10.0, 10.0), (10.0, 10.0), (10.0, -10.0)])  # hold, then rtl
    t = run_until_auto(fs)
    first = fs.update(good(t, north_m=20.0, east_m=0.0)).requests
    assert [(r.cause, r.action, r.overruled_by) for r in first] == [("geofence", "hold", None)]
    reqs = [r for k in range(1, 120) for r in fs.update(good(t + 0.1 * k, north_m=20.0, east_m=0.0,
                                                                battery_v=11.9)).requests]
    assert [(r.cause, r.action, r.overruled_by) for r in reqs] == [("battery_low", "rtl", None)]  # home on low


def test_a_failsafe_leaves_a_stopped_helm_stopped_whoever_stopped_it():
    """Found by fault injection: `ctl stop` (or the stop an interrupted mission holds at start), then battery_low's
    rtl drove the boat, 60 cycles at up to full thrust."""
    from autopilot.daemon.cycle import answer_failsafe
    from autopilot.daemon.failsafe import Request
    from autopilot.gnc import Autopilot, GncConfig, NavInput

    ap = Autopilot(GncConfig(), [(50.0, 0.0)])
    nav = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    ap.step(nav, 0.1)
    ap.request("stop", None, cause="ctl stop")
    assert answer_failsafe(ap, Request("battery_low", "rtl", "rtl"), nav, "") == (
        "stop", "the stop in force (ctl stop) stands: a failsafe does not drive a stopped boat")
    assert ap.mode.value == "stop"
    late = Request("battery_low", "rtl", "rtl", "battery_critical took stop before", overruled_by=("battery_critical",
                                                                                                    "stop"))
    ap.request("rtl", nav, cause="ctl rtl")  # the operator brings it home after the critical stop: kept
    assert answer_failsafe(ap, late, nav, "") == ("stop", late.fallback) and ap.mode.value == "rtl"
    ap.request("hold", nav, cause="ctl hold")  # not stopped: a failsafe's rtl is taken
    assert answer_failsafe(ap, Request("geofence", "rtl", "rtl"), nav, "") == ("rtl", None) and ap.mode.value == "rtl"


def test_resting_voltage_takes_out_the_sag_of_the_duties():
    assert resting_voltage_v(None, 50.0, 50.0, 1.2) is None
    assert resting_voltage_v(11.5, 100.0, -100.0, 1.2) == pytest.approx(12.7)  # reverse draws the same
    assert resting_voltage_v(12.3, 0.0, 0.0, 1.2) == 12.3
    assert resting_voltage_v(12.0, 50.0, 50.0, 1.2) == pytest.approx(12.0 + 1.2 * 0.125)


def test_thresholds_are_not_faults():
    assert detect(good(0.0, heading_age_s=1.0, position_age_s=3.0, ack_consecutive_missing=4), CFG) == {}
    assert detect(good(5.0, last_garbage_t_s=4.0), CFG) == {}  # exactly garbage_hold_s ago
    assert detect(good(5.0, heading_still_turn_rad=math.radians(19.9)), CFG) == {}


def test_zero_thrust_is_kept_while_the_fault_lasts_and_resumes_after_resume_valid_s():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    fs.update(good(t, heading_age_s=2.0))
    for k in range(1, 30):  # fault lasts 3 s
        assert not fs.update(good(t + 0.1 * k, heading_age_s=2.0)).thrust_allowed
    t_clear = t + 3.0
    d = fs.update(good(t_clear))
    assert [e.name for e in d.events] == ["fault_cleared"] and not d.thrust_allowed
    # what an operator's accepted command is told meanwhile (it said "until the failsafe clears: " and nothing)
    assert waiting_note(d, CFG.resume_valid_s) == (f"zero thrust until the data has been valid for "
                                                   f"{CFG.resume_valid_s:g} s (the fault has cleared)")
    k = 1
    while True:
        d = fs.update(good(t_clear + 0.1 * k))
        if d.thrust_allowed:
            break
        k += 1
    assert 0.1 * k == pytest.approx(CFG.resume_valid_s)
    assert [e.name for e in d.events] == ["failsafe_cleared", "resume"]
    assert d.events[1].fields["cause"] == "heading_stale"
    assert d.events[1].fields["valid_for_s"] == pytest.approx(CFG.resume_valid_s)


def test_an_accepted_command_during_a_fault_is_told_which():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    assert waiting_note(fs.update(good(t, heading_age_s=2.0)), CFG.resume_valid_s) == \
        "zero thrust until the failsafe clears: heading_stale"


def test_a_flapping_fault_restarts_the_recovery_timer():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    fs.update(good(t, fix_quality=0))
    fs.update(good(t + 1.0))
    fs.update(good(t + 2.5, fix_quality=0))  # back before resume_valid_s elapsed
    assert not fs.update(good(t + 4.0)).thrust_allowed
    assert not fs.update(good(t + 5.9)).thrust_allowed
    assert fs.update(good(t + 6.0)).thrust_allowed


@pytest.mark.parametrize("cause, change", [
    ("geofence", dict(north_m=60.0, east_m=0.0)),
    ("max_distance", dict(north_m=99.0, east_m=99.0)),
    ("max_mission_time", dict(mission_time_s=1e4)),
])
def test_latched_faults_never_clear(cause, change):
    assert cause in LATCHED
    fs = Failsafe(CFG, fence_ne_m=SQUARE if cause == "geofence" else None)
    t = run_until_auto(fs)
    fs.update(good(t, **change))
    for k in range(1, 100):
        d = fs.update(good(t + 0.1 * k))
        assert cause in d.active and d.requests == ()
        assert all(e.name != "fault_cleared" for e in d.events)
    assert cause in fs.latched


def test_waiting_until_start_valid_then_auto_without_failsafe_event():
    fs = Failsafe(CFG)
    d0 = fs.update(Observation(t_s=0.0))  # nothing received yet
    assert d0.mode == "waiting" and not d0.thrust_allowed
    assert d0.events == ()  # missing data while starting is expected: no fault events
    assert {"heading_stale", "position_stale"} <= set(d0.active)
    assert not fs.update(good(0.1)).thrust_allowed
    assert not fs.update(good(1.0)).thrust_allowed
    d = fs.update(good(1.1))
    assert d.thrust_allowed and d.mode == "auto"


def test_several_faults_each_logged_once():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    d = fs.update(good(t, compass_connected=False, heading_age_s=5.0, position_age_s=5.0))
    faults = [e.fields["cause"] for e in d.events if e.name == "fault"]
    assert sorted(faults) == ["compass_port_lost", "heading_stale", "position_stale"]
    assert [e.name for e in d.events].count("failsafe") == 1
    d2 = fs.update(good(t + 0.1, compass_connected=False, heading_age_s=5.1, position_age_s=5.1))
    assert d2.events == ()


def test_causes_match_the_log_schema():
    schema = open("docs/log-schema.md", encoding="utf-8").read()
    for cause in CAUSES:
        assert f"`{cause}`" in schema


@pytest.mark.parametrize("point, inside", [
    ((0.0, 0.0), True), ((49.9, 0.0), True), ((50.0, 0.0), True), ((50.1, 0.0), False),
    ((0.0, -51.0), False), ((-50.0, -50.0), True),
])
def test_inside_polygon_square(point, inside):
    assert inside_polygon(*point, SQUARE) is inside


def test_inside_polygon_concave():
    u_shape = ((0, 0), (0, 30), (30, 30), (30, 20), (10, 20), (10, 10), (30, 10), (30, 0))
    assert inside_polygon(5, 15, u_shape)
    assert not inside_polygon(20, 15, u_shape)  # in the notch
    assert inside_polygon(20, 5, u_shape)


def test_port_loss_while_waiting_is_reported():
    fs = Failsafe(CFG)
    d = fs.update(Observation(t_s=0.0, mbed_connected=False))
    assert [(e.name, e.fields["cause"]) for e in d.events] == [("fault", "mbed_port_lost")]
    d = fs.update(Observation(t_s=0.1))
    assert [(e.name, e.fields["cause"]) for e in d.events] == [("fault_cleared", "mbed_port_lost")]


def _steered(fs: Failsafe, t0_s: float, seconds: float, error_deg: float | None, *, since_s: float = 0.0,
             dt_s: float = 0.1, **kw):
    """Feed ``seconds`` of cycles with the compass heading still since ``since_s`` and the helm steering
    ``error_deg`` off it; the last decision and the time after."""
    t, d = t0_s, None
    for _ in range(round(seconds / dt_s)):
        t += dt_s
        d = fs.update(good(t, heading_still_since_s=since_s,
                           steered_heading_error_rad=None if error_deg is None else math.radians(error_deg), **kw))
    return d, t


def test_the_helm_steering_a_heading_that_never_moves_is_a_frozen_heading_until_it_moves():
    """A compass stuck whole (its ROT frozen near zero too) sums no turn: the helm's own demand is the evidence.
    heading_frozen_steer_error_deg (20) of error for heading_frozen_steer_s (3 s), counted while the compass
    heading stays within 0.5 deg; zero thrust then, and no resume before the heading moves."""
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    d, t = _steered(fs, t, 2.8, 25.0)
    assert d.mode == "auto" and "heading_frozen" not in d.active  # 2.8 s: a WAM-V starting a turn
    d, t = _steered(fs, t, 0.3, -25.0)  # either side counts
    assert d.mode == "failsafe" and "heading_frozen" in d.active
    fault = next(e for e in d.events if e.name == "fault")
    assert "while the helm steered 20 deg or more off it for 3.0 s (limit 3 s)" in fault.fields["detail"]
    d, t = _steered(fs, t, 10.0, None)  # zero thrust: the helm does not steer, the heading stays where it was
    assert d.mode == "failsafe" and "heading_frozen" in d.active
    d, t = _steered(fs, t, 0.1, None, since_s=t)  # it moved
    assert "heading_frozen" not in d.active and any(e.name == "fault_cleared" for e in d.events)
    d, t = _steered(fs, t, 2.2, None, since_s=t)
    assert d.mode == "auto"  # resume_valid_s (2 s) later


@pytest.mark.parametrize("error_deg, cfg_change", [
    (19.0, {}),  # below heading_frozen_steer_error_deg: a boat pinned by the wind, steering hard, is not stuck
    (90.0, {"heading_frozen_steer_s": 0.0}),  # off (a bench with the boat out of the water)
])
def test_steering_that_does_not_count_never_makes_a_frozen_heading(error_deg, cfg_change):
    fs = Failsafe(dataclasses.replace(CFG, **cfg_change))
    t = run_until_auto(fs)
    d, t = _steered(fs, t, 30.0, error_deg)
    assert d.mode == "auto" and not d.active


def test_the_steering_time_restarts_when_the_heading_moves():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    for k in range(10):  # 2 s at a time, each with the heading moved: 20 s of steering, never 3 s of it unanswered
        d, t = _steered(fs, t, 2.0, 45.0, since_s=float(k))
        assert d.mode == "auto" and not d.active


def test_a_stale_heading_is_not_called_frozen_but_the_steering_is_remembered():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    d, t = _steered(fs, t, 3.5, 30.0)
    assert "heading_frozen" in d.active
    d, t = _steered(fs, t, 1.0, None, heading_age_s=5.0)  # the sentences stopped: that is heading_stale
    assert "heading_stale" in d.active and "heading_frozen" not in d.active
    d, t = _steered(fs, t, 0.1, None)  # back, at the same heading: still frozen
    assert "heading_frozen" in d.active


def test_a_leg_is_outside_a_polygon_where_any_piece_of_it_is():
    """The legs of a mission inside a concave fence (a new-user audit: only the waypoints were checked)."""
    from autopilot.daemon.failsafe import segment_outside_polygon

    ell = ((-5.0, -5.0), (60.0, -5.0), (60.0, 10.0), (10.0, 10.0), (10.0, 60.0), (-5.0, 60.0))
    assert segment_outside_polygon((50.0, 0.0), (0.0, 50.0), ell) == pytest.approx((25.0, 25.0))
    assert segment_outside_polygon((50.0, 0.0), (5.0, 0.0), ell) is None
    assert segment_outside_polygon((5.0, 0.0), (0.0, 50.0), ell) is None
    assert segment_outside_polygon((10.0, 10.0), (10.0, 50.0), ell) is None  # along an edge, from the inner corner
    # through the inner corner's vertex and out: touching the boundary at a vertex, not crossing an edge
    out = segment_outside_polygon((0.0, 0.0), (20.0, 20.0), ell)
    assert out is not None and out[0] > 10.0 and out[1] > 10.0
    square = ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0))
    assert segment_outside_polygon((1.0, 1.0), (9.0, 9.0), square) is None  # convex: never
    assert segment_outside_polygon((5.0, 5.0), (15.0, 5.0), square) is not None  # its end outside


def test_a_fault_latched_before_a_restart_is_told_apart_from_one_of_this_run():
    """ctl status lists a restored latched fault as "before the restart" (an operator audit): the failsafe names them."""
    fs = Failsafe(CFG, fence_ne_m=SQUARE)
    fs.restore_latched(["geofence", "heading_stale"])  # a transient one is not latched across a restart
    d = fs.update(good(0.0, mission_time_s=1e4))  # this run's own
    assert fs.latched == ("geofence", "max_mission_time") and fs.restored == ("geofence",)
    assert {"geofence", "max_mission_time"} <= set(d.active)


def test_a_mission_ended_with_stop_has_no_time_to_run_out():
    """A review of 2026-12-06: a daemon staying up (systemd) after its mission's stop tripped max_mission_time half
    an hour on at zero thrust, saved the run aborted, and the next boot held the boat for it."""
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    d = fs.update(good(t, mission_time_s=None))  # the daemon's observation once the mission has ended with stop
    assert "max_mission_time" not in d.active and d.requests == ()
    assert "max_mission_time" in fs.update(good(t + 0.1, mission_time_s=600.0)).active  # under way, it trips
