"""The operator's speed for the legs (MAVLink DO_CHANGE_SPEED, `autopilot ctl speed`): pure parts.

Mission Planner's and QGroundControl's Change Speed was answered UNSUPPORTED (stop 47's note): an operator who
had to slow the boat near swimmers or a moored vessel could only pause it, or edit and upload the mission again.
The flights through the daemon and the link are in tests/test_link_audit_commands.py and tests/test_daemon_modes.py.
"""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from autopilot.daemon.cli import _status_lines
from autopilot.daemon.control import check_request, parse_request
from autopilot.daemon.state import Progress, StateStore
from autopilot.gnc import Autopilot, GncConfig, NavInput
from autopilot.logschema import Mode

# on the first leg's line, facing along it: no turn to slow the speed, far from the arrival slow-down
ON_LEG = NavInput(north_m=5.0, east_m=0.0, psi_rad=0.0, speed_m_s=1.0, yaw_rate_rad_s=0.0, course_rad=0.0)


def helm():
    # the second leg has a planned speed of its own (a mission's DO_CHANGE_SPEED item)
    return Autopilot(GncConfig(), [(60.0, 0.0), (60.0, 60.0), (0.0, 60.0)], speeds_m_s=[None, 0.7, None])


def wanted(ap: Autopilot, nav: NavInput = ON_LEG) -> float:
    return ap.step(nav, 0.1).speed_cmd_m_s


def test_the_operators_speed_replaces_the_planned_one_on_every_leg_and_is_given_back():
    ap = helm()
    assert wanted(ap) == pytest.approx(GncConfig().guidance.default_speed_m_s)
    assert ap.set_speed(1.8, cause="ctl speed") == "1.8 m/s"
    assert wanted(ap) == pytest.approx(1.8)
    ap.set_current(1, cause="ctl")  # the leg planned at 0.7 m/s flies the operator's too
    on_second = dataclasses.replace(ON_LEG, north_m=60.0, east_m=10.0, psi_rad=math.pi / 2, course_rad=math.pi / 2)
    assert wanted(ap, on_second) == pytest.approx(1.8)
    # a turn still slows it (turn_speed_floor_nd): facing north on an eastward leg
    assert wanted(ap, dataclasses.replace(on_second, psi_rad=0.0)) < 1.8 * 0.75
    assert ap.set_speed(None, cause="ctl speed") == "the mission's planned speeds"
    assert wanted(ap, on_second) == pytest.approx(0.7)
    events = [f for name, f in ap.pop_events() if name == "speed"]
    assert events == [{"speed_m_s": 1.8, "cause": "ctl speed"}, {"speed_m_s": None, "cause": "ctl speed"}]
    ap.set_speed(None, cause="ctl speed")  # no change: no event
    assert not [f for name, f in ap.pop_events() if name == "speed"]


def test_it_survives_a_pause_and_flies_the_return_a_new_mission_gives_the_planned_speeds_back():
    ap = helm()
    ap.step(ON_LEG, 0.1)
    ap.set_speed(1.5, cause="mavlink speed")
    assert ap.request("pause", ON_LEG, cause="ctl pause") == (True, "paused")
    assert ap.step(ON_LEG, 0.1).mode is Mode.PAUSED
    assert ap.request("resume", ON_LEG, cause="ctl resume") == (True, "auto")
    assert wanted(ap) == pytest.approx(1.5)
    # the return home (launch at 5 m north; the boat 40 m north of it, facing it)
    away = dataclasses.replace(ON_LEG, north_m=45.0, psi_rad=math.pi, course_rad=math.pi)
    assert ap.request("rtl", away, cause="ctl rtl") == (True, "rtl")
    out = ap.step(away, 0.1)
    assert out.mode is Mode.RTL and out.speed_cmd_m_s == pytest.approx(1.5)
    assert ap.request("hold", away, cause="ctl hold")[0]  # (on a return, the return keeps it: below)
    ap.replace_mission([(30.0, 0.0)], cause="mavlink mission")
    assert ap.speed_m_s is None
    assert [f for name, f in ap.pop_events() if name == "speed"][-1] == {"speed_m_s": None, "cause": "mavlink mission"}
    ap.set_speed(1.5, cause="ctl speed")
    ap.clear_mission(ON_LEG, cause="mavlink mission_clear")
    assert ap.speed_m_s is None


@pytest.mark.parametrize("line, why", [
    (b"speed", "speed needs speed_m_s"),
    (b'{"command": "speed", "speed_m_s": 0}', "speed_m_s 0 is not a speed in [0.05, 3.5] m/s"),
    (b'{"command": "speed", "speed_m_s": 9}', "speed_m_s 9 is not a speed in [0.05, 3.5] m/s"),
    (b'{"command": "speed", "speed_m_s": "fast"}', "speed_m_s 'fast' is not a speed in"),
    (b'{"command": "speed", "speed_m_s": true}', "speed_m_s True is not a speed in"),
    (b'{"command": "speed", "speed_m_s": NaN}', "speed_m_s nan is not a speed in"),
    (b'{"command": "hold", "speed_m_s": 1}', "speed_m_s is for speed only, not hold"),
])
def test_a_control_socket_speed_outside_the_range_is_refused_naming_the_field(line, why):
    req, refusal = parse_request(line)
    refusal = refusal or check_request(req)
    assert refusal is not None and why in refusal


def test_a_control_socket_speed_or_null_is_taken():
    for line in (b'{"command": "speed", "speed_m_s": 1.25}', b'{"command": "speed", "speed_m_s": null}'):
        req, refusal = parse_request(line)
        assert refusal is None and check_request(req) is None


def test_the_speed_is_saved_and_a_file_with_a_wrong_one_is_not_trusted(tmp_path):
    store = StateStore(tmp_path)
    store.save(Progress("m.yaml", "ab", 2, "running", speed_m_s=1.2))
    assert StateStore(tmp_path).load().speed_m_s == 1.2
    data = json.loads(store.path.read_text())
    for bad in (0, -1, 7.0, "1.2", True):
        store.path.write_text(json.dumps({**data, "speed_m_s": bad}))
        progress, problem = StateStore(tmp_path).read()
        assert progress is None and "speed_m_s" in problem
    store.path.write_text(json.dumps({k: v for k, v in data.items() if k != "speed_m_s"}))  # a file from before
    assert StateStore(tmp_path).load().speed_m_s is None


def test_ctl_status_says_the_operators_speed():
    base = {"mode": "auto", "t_s": 1.0, "cycle": 10, "wp_index": 1, "wp_count": 3}
    assert not [line for line in _status_lines(base) if line.startswith("speed:")]
    assert "speed: 1.5 m/s on every leg, the operator's" in "\n".join(_status_lines({**base, "speed_set_m_s": 1.5}))


# ---------------------------------------------------------------------------------------------- found by a review


def _loop(tmp_path, **failsafe):
    """The daemon's control loop on a clock the test steps, the boat steaming north (tests.test_daemon_cycle);
    ``failsafe``: its settings other than the defaults."""
    import numpy as np

    from autopilot.clock import SimClock
    from autopilot.daemon.config import DaemonConfig
    from autopilot.daemon.loop import ControlLoop
    from autopilot.daemon.missionlog import MissionLog
    from autopilot.daemon.sd_notify import Notifier
    from autopilot.mission import Mission
    from tests.test_daemon_cycle import ORIGIN, FakeCompass, FakeThrusters

    cfg, clock = DaemonConfig(), SimClock()
    cfg = dataclasses.replace(cfg, failsafe=dataclasses.replace(cfg.failsafe, **failsafe))
    mission = Mission("north", np.array([(200.0, 0.0), (300.0, 0.0)]), (None, None), None, *ORIGIN)
    loop = ControlLoop(cfg, clock=clock, autopilot=Autopilot(cfg.gnc, mission.waypoints_ne_m), mission=mission,
                       mission_path="m.yaml", mission_sha256="x", compass=FakeCompass(clock), thrusters=FakeThrusters(),
                       log=MissionLog(tmp_path / "l.jsonl", console=None), notifier=Notifier(None),
                       store=StateStore(tmp_path / "state"))
    loop.save_progress("running")  # as run() does at its start
    t = [0.0]

    def cycles(n: int) -> None:
        for _ in range(n):
            t[0] += 0.1
            clock.advance_to(t[0])
            loop.cycle(t[0], 0.0)

    def command(**request) -> dict:
        replies = []
        loop.submit({"source": "ctl", **request}, replies.append)
        cycles(1)
        return replies[-1]

    cycles(60)  # control has started
    return loop, command


@pytest.mark.parametrize("first", ["hold", None])
def test_a_clear_with_the_operators_speed_set_is_saved_cleared(tmp_path, first):
    """The clear gives the planned speeds back; the loop saw the speed change and saved the progress "running" over
    the clear's "cleared" (as the clear's own hold did in the mission): a crash, and a restart with
    resume_after_restart flew the cleared mission (or an uploaded one) again instead of holding."""
    loop, command = _loop(tmp_path)
    if first:
        assert command(command=first)["ok"]
    assert command(command="speed", speed_m_s=0.6)["ok"]
    assert loop.store.load().speed_m_s == 0.6
    assert command(command="mission_clear")["ok"]
    saved = loop.store.load()
    assert (saved.status, saved.speed_m_s) == ("cleared", None)
    assert loop.store.interrupted("x", 2)[1].startswith("the last run's mission was cleared")
    assert command(command="arm")["ok"] and command(command="speed", speed_m_s=1.0)["ok"]
    assert loop.store.load().status == "cleared"  # whatever is saved while the run goes on without a mission


def test_the_speed_answer_while_the_mission_is_cleared_says_a_new_one_has_its_own(tmp_path):
    """'flown once the mission or a return goes on' with no mission: the only way to one, an upload, gives the
    planned speeds back."""
    _, command = _loop(tmp_path)
    assert command(command="mission_clear")["ok"]
    answer = command(command="speed", speed_m_s=0.6)["answer"]
    assert "flown on a return (now hold): the mission is cleared, and a new one is flown at its planned speeds" \
        in answer, answer


def test_a_mission_uploaded_or_cleared_on_a_return_leaves_the_return_its_speed():
    """The boat slowed to 0.6 m/s near swimmers on its way home sped up to WP_SPEED when the planner uploaded the
    next mission (or cleared it); the planned speeds come back when the new mission is flown."""
    ap = helm()
    ap.step(ON_LEG, 0.1)
    away = dataclasses.replace(ON_LEG, north_m=45.0, psi_rad=math.pi, course_rad=math.pi)
    ap.set_speed(0.6, cause="ctl speed")
    assert ap.request("rtl", away, cause="ctl rtl") == (True, "rtl")
    ap.replace_mission([(30.0, 0.0)], cause="mavlink mission")
    assert ap.speed_m_s == 0.6 and ap.step(away, 0.1).speed_cmd_m_s == pytest.approx(0.6)
    assert ap.request("pause", away, cause="ctl pause")[0] and ap.request("resume", away, cause="ctl resume")[1] == "rtl"
    assert ap.step(away, 0.1).speed_cmd_m_s == pytest.approx(0.6)  # still the way home
    ap.pop_events()
    assert ap.request("auto", away, cause="mavlink auto") == (True, "auto")  # the new mission
    assert ap.speed_m_s is None
    assert [f for name, f in ap.pop_events() if name == "speed"] == [
        {"speed_m_s": None, "cause": "mavlink auto: the mission uploaded on a return"}]
    # cleared on the way home: the same
    ap.set_speed(0.6, cause="ctl speed")
    assert ap.request("rtl", away, cause="ctl rtl")[0]
    ap.clear_mission(away, cause="mavlink mission_clear")
    assert ap.speed_m_s == 0.6 and ap.step(away, 0.1).speed_cmd_m_s == pytest.approx(0.6)
    # elsewhere (here paused in the mission) a new mission gives the planned speeds back at once, as before
    ap.replace_mission([(30.0, 0.0)], cause="mavlink mission")
    assert ap.request("auto", away, cause="ctl") == (True, "auto")
    ap.set_speed(0.6, cause="ctl speed")
    assert ap.request("pause", away, cause="ctl pause")[0]
    ap.replace_mission([(40.0, 0.0)], cause="mavlink mission")
    assert ap.speed_m_s is None


def _fly(speed_m_s, waypoints, *, rtl=False, holds_s=None, t_max_s=150.0, commands=()):
    """A closed-loop flight (the simulated boat, calm water): (t, mode, speed over ground, distance from the
    launch point, distance from the first waypoint) each cycle."""
    import numpy as np

    from autopilot.daemon.cycle import nav_input
    from autopilot.gnc.navigation import NavMemory, NavRules, assemble
    from autopilot.sim import default_params_path, load_params, step
    from autopilot.sim.sensors import SensorModel

    params = load_params(default_params_path())
    ap = Autopilot(GncConfig(), waypoints, rtl=rtl, holds_s=holds_s, boat_length_m=params.length_m)
    if speed_m_s is not None:
        ap.set_speed(speed_m_s, cause="ctl speed")
    sensors, memory, rules = SensorModel(52.0, 4.4), NavMemory(), NavRules()
    x, t, rows, todo = np.zeros(6), 0.0, [], list(commands)
    while t < t_max_s:
        nav, memory = assemble(sensors.observe(t, x), t, memory, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
        while todo and t >= todo[0][0]:
            ap.request(todo.pop(0)[1], nav_input(nav), cause="ctl")
        out = ap.step(nav_input(nav), 0.1)
        rows.append((t, out.mode, math.hypot(x[3], x[4]), math.hypot(x[0], x[1]),
                     math.hypot(x[0] - waypoints[0][0], x[1] - waypoints[0][1])))
        for _ in range(2):
            x = step(params, x, out.thrust_port_n, out.thrust_stbd_n, 0.05, t_s=t)
            t += 0.05
    return rows


def test_the_closing_on_a_point_the_boat_stops_at_is_no_faster_than_the_operators_speed():
    """The last hold.approach_m (8 m) to the launch point of a return, and the way back to a hold item's point, are
    station keeping's, at up to hold.approach_speed_m_s (1 m/s): the boat slowed to 0.5 m/s near swimmers sped up
    to 0.92 m/s right at the launch point (and flew back to a hold item at 1 m/s)."""
    rows = _fly(0.5, [(30.0, 0.0)], rtl=True)
    home = [sog for _, mode, sog, d_home, _ in rows if mode is Mode.RTL and d_home <= 8.0]
    assert home and max(home) < 0.55, max(home)
    assert max(sog for _, mode, sog, *_ in rows if mode is Mode.AUTO) < 0.55
    # a hold item at 25 m, an rtl taken from it, then back into the mission: back to the item's point, and held
    rows = _fly(0.5, [(25.0, 0.0), (25.0, 25.0)], holds_s=[600.0, None], t_max_s=260.0,
                commands=[(80.0, "rtl"), (160.0, "resume")])
    back = [sog for t, mode, sog, *_ in rows if t > 160.0 and mode is Mode.AUTO]
    assert back and max(back) < 0.7, max(back)  # (0.61: the speed trim's overshoot from rest; it went up to 0.99)
    # without the operator's speed, as before: the approach's own
    rows = _fly(None, [(30.0, 0.0)], rtl=True)
    assert max(sog for _, mode, sog, d_home, _ in rows if mode is Mode.RTL and d_home <= 8.0) > 0.8


def test_an_arm_or_a_speed_after_the_time_limits_stop_keeps_the_run_saved_aborted(tmp_path):
    """Stop 48's note: staying up after max_mission_time stopped the boat (systemd), the daemon saved the run
    aborted (a restart must not fly the mission again); an arm or a speed given then re-saved it "running"."""
    loop, command = _loop(tmp_path, max_mission_time_s=10.0)
    loop.stay_when_done = "NOTIFY_SOCKET is set (systemd)"
    for _ in range(200):
        command(command="status")
        if loop.failsafe.action_of("max_mission_time") == "stop":
            break
    assert loop.failsafe.action_of("max_mission_time") == "stop"
    assert loop.time_stopped()
    assert (loop.store.load().status, loop.store.load().reason) == ("aborted", "max_mission_time")
    assert command(command="speed", speed_m_s=0.8)["ok"] and command(command="disarm")["ok"]
    assert command(command="arm")["ok"]
    saved = loop.store.load()
    assert (saved.status, saved.reason, saved.speed_m_s, saved.armed) == ("aborted", "max_mission_time", 0.8, True)
    assert "max_mission_time" in loop.store.interrupted("x", 2)[1]  # a restart holds the boat
