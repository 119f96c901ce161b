"""The failsafe state machine alone: each fault trips it, recovery needs valid data for a while."""

import math

import pytest

from autopilot.daemon.config import FailsafeConfig
from autopilot.daemon.failsafe import CAUSES, LATCHED, Failsafe, Observation, detect, inside_polygon

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


FAULTS = [
    ("heading_stale", dict(heading_age_s=1.2)),
    ("heading_stale", dict(heading_age_s=math.inf, heading_valid=False)),
    ("heading_invalid", dict(heading_valid=False)),
    ("position_stale", dict(position_age_s=3.5)),
    ("no_fix", dict(fix_quality=0)),
    ("mbed_ack_missing", dict(ack_consecutive_missing=5)),
    ("compass_port_lost", dict(compass_connected=False)),
    ("mbed_port_lost", dict(mbed_connected=False)),
    ("nmea_garbage", dict(last_garbage_t_s=-0.5)),  # relative to t_s, patched below
    ("mbed_garbage", dict(last_mbed_garbage_t_s=-0.5)),  # relative to t_s, patched below
    ("geofence", dict(north_m=60.0, east_m=0.0)),
    ("max_distance", dict(north_m=80.0, east_m=-80.0, _fence=False)),
    ("max_mission_time", dict(mission_time_s=600.0)),
]


@pytest.mark.parametrize("cause, change", FAULTS, ids=[f"{c}-{i}" for i, (c, _) in enumerate(FAULTS)])
def test_each_fault_trips_zero_thrust_in_the_same_cycle(cause, change):
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
    assert next(e for e in d.events if e.name == "failsafe").fields["action"] == "zero_thrust"


def test_thresholds_are_not_faults():
    assert detect(good(0.0, heading_age_s=1.0, position_age_s=3.0, ack_consecutive_missing=4), CFG) == {}
    assert detect(good(5.0, last_garbage_t_s=4.0), CFG) == {}  # exactly garbage_hold_s ago


def test_zero_thrust_is_kept_while_the_fault_lasts_and_resumes_after_resume_valid_s():
    fs = Failsafe(CFG)
    t = run_until_auto(fs)
    fs.update(good(t, heading_age_s=2.0))
    for k in range(1, 30):  # fault lasts 3 s
        assert not fs.update(good(t + 0.1 * k, heading_age_s=2.0)).thrust_allowed
    t_clear = t + 3.0
    d = fs.update(good(t_clear))
    assert [e.name for e in d.events] == ["fault_cleared"] and not d.thrust_allowed
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
        assert not d.thrust_allowed and cause in d.active
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
