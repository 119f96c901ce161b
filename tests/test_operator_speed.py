"""The operator's speed for the legs (MAVLink DO_CHANGE_SPEED, `autopilot ctl speed`): pure parts.

Mission Planner's and QGroundControl's Change Speed was answered UNSUPPORTED (stop 47's note): an operator who
had to slow the boat near swimmers or a moored vessel could only pause it, or edit and upload the mission again.
The flights through the daemon and the link are in tests/test_link_audit_commands.py and tests/test_restart.py.
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
    ap.replace_mission([(30.0, 0.0)], cause="mavlink mission")
    assert ap.speed_m_s is None
    assert [f for name, f in ap.pop_events() if name == "speed"][-1] == {"speed_m_s": None, "cause": "mavlink mission"}
    ap.set_speed(1.5, cause="ctl speed")
    ap.clear_mission(ON_LEG, cause="mavlink mission_clear")
    assert ap.speed_m_s is None


@pytest.mark.parametrize("line, why", [
    (b"speed", "speed needs speed_m_s"),
    (b'{"command": "speed", "speed_m_s": 0}', "speed_m_s 0 outside (0, 3.5] m/s"),
    (b'{"command": "speed", "speed_m_s": 9}', "speed_m_s 9 outside (0, 3.5] m/s"),
    (b'{"command": "speed", "speed_m_s": "fast"}', "speed_m_s 'fast' outside"),
    (b'{"command": "speed", "speed_m_s": true}', "speed_m_s True outside"),
    (b'{"command": "speed", "speed_m_s": NaN}', "speed_m_s nan outside"),
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
