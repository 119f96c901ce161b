"""The control loop's command queue (ControlLoop.submit): who waits, who is refused, what a stick packet replaces.

Found by a new user's test of the MAVLink link (2026-12-07): a second station sending 2000 DO_CHANGE_SPEED a
second filled the whole queue, and the operator's DISARM, HOLD and `autopilot ctl stop` were refused while the
boat drove on; with QGC's joystick on, a switch to MANUAL was answered ACCEPTED and never made (the next stick
packet replaced it in the queue).
"""

from __future__ import annotations

import collections
from types import SimpleNamespace

from autopilot.daemon.loop import COMMANDS_QUEUED_MAX, COMMANDS_QUEUED_PER_SOURCE_MAX, ControlLoop
from autopilot.logschema import Mode


def _loop():
    return SimpleNamespace(commands=collections.deque(), _queued=collections.Counter(), _flooded=False,
                           log_event=lambda *a, **k: None, ap=SimpleNamespace(mode=Mode.AUTO),
                           _enqueue=None)


def _submit(loop, request):
    loop._enqueue = lambda r, a: ControlLoop._enqueue(loop, r, a)
    answers = []
    ControlLoop.submit(loop, request, answers.append)
    return answers


def test_a_flood_of_one_command_does_not_lock_out_the_operator():
    """Every station's requests come as source "mavlink" (the link's), the flood's and the operator's alike."""
    loop = _loop()
    for _ in range(5 * COMMANDS_QUEUED_PER_SOURCE_MAX):
        _submit(loop, {"command": "speed", "speed_m_s": 1.0, "source": "mavlink"})
    assert len(loop.commands) == COMMANDS_QUEUED_PER_SOURCE_MAX
    refused = _submit(loop, {"command": "speed", "speed_m_s": 1.0, "source": "mavlink"})
    assert refused and refused[0]["busy"] and "speed commands of mavlink already waiting" in refused[0]["answer"]
    for command in ("hold", "rtl", "arm", "disarm"):
        assert _submit(loop, {"command": command, "source": "mavlink"}) == []  # queued, answered in a cycle
    assert _submit(loop, {"command": "stop", "source": "ctl"}) == []
    assert [r["command"] for r, _ in list(loop.commands)[-5:]] == ["hold", "rtl", "arm", "disarm", "stop"]
    while loop.commands:  # the cycles take them: the counts follow
        ControlLoop.next_command(loop)
    assert not +loop._queued


def test_stop_disarm_and_a_failsafes_request_are_never_refused_nor_queued_twice():
    loop = _loop()
    for k in range(COMMANDS_QUEUED_MAX):
        _submit(loop, {"command": f"c{k % 10}", "source": "mavlink"})
    assert len(loop.commands) == COMMANDS_QUEUED_MAX
    assert _submit(loop, {"command": "hold", "source": "ctl"})[0]["busy"]
    lost = {"command": "rtl", "source": "mavlink", "cause": "mavlink: ground station lost", "failsafe": True}
    for request in ({"command": "stop", "source": "ctl"}, {"command": "disarm", "source": "mavlink"}, lost):
        assert _submit(loop, request) == []
    assert [r["command"] for r, _ in list(loop.commands)[-3:]] == ["stop", "disarm", "rtl"]
    for _ in range(20_000):  # a flood of disarms is one disarm waiting
        again = _submit(loop, {"command": "disarm", "source": "mavlink"})
        assert again[0]["ok"] and "waiting already" in again[0]["answer"]
    assert len(loop.commands) == COMMANDS_QUEUED_MAX + 3


def test_a_stick_packet_replaces_a_stick_packet_not_a_choice_of_manual():
    loop = _loop()
    first = _submit(loop, {"command": "manual", "forward_nd": 0.1, "turn_nd": 0.0, "source": "mavlink 255"})
    second = _submit(loop, {"command": "manual", "forward_nd": 0.2, "turn_nd": 0.0, "source": "mavlink 255"})
    assert first and "superseded" in first[0]["answer"] and not second and len(loop.commands) == 1
    choice = _submit(loop, {"command": "manual", "forward_nd": 0.0, "turn_nd": 0.0, "explicit": True,
                            "source": "mavlink 255"})
    assert choice == [] and len(loop.commands) == 1 and loop.commands[0][0].get("explicit")  # it replaced the sticks
    sticks = _submit(loop, {"command": "manual", "forward_nd": 0.3, "turn_nd": 0.0, "source": "mavlink 255"})
    assert sticks == [] and len(loop.commands) == 2  # queued after the choice, which stays to be made
    assert loop.commands[0][0].get("explicit") and loop.commands[1][0]["forward_nd"] == 0.3


def test_a_distance_limit_below_where_the_boat_is_is_refused():
    """PARAM_SET FS_MAX_DIST 1 mid-run was taken: the max_distance failsafe latched at once and the run was over
    (setting it back did not help); FS_MAX_TIME already refused a limit the run had passed."""
    from autopilot.daemon.commands import _param_set
    from autopilot.daemon.config import DaemonConfig
    from autopilot.gnc import NavInput

    applied = []
    loop = SimpleNamespace(cfg=DaemonConfig(), clock=SimpleNamespace(now_s=lambda: 60.0), t0_s=0.0,
                           apply_config=applied.append, log=SimpleNamespace(event=lambda *a, **k: None))
    here = NavInput(north_m=60.0, east_m=80.0, psi_rad=0.0, speed_m_s=1.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    request = {"key": "failsafe.max_distance_m", "value": 50.0, "name": "FS_MAX_DIST", "source": "mavlink 255"}
    ok, answer = _param_set(loop, request, here, "", "link")
    assert not ok and answer == ("FS_MAX_DIST refused: 50 m is not more than the boat's 100 m from the origin now "
                                 "(the failsafe would take the boat at once, latched)") and not applied
    ok, answer = _param_set(loop, {**request, "value": 150.0}, here, "", "link")
    assert ok and applied[-1].failsafe.max_distance_m == 150.0


def test_manual_is_chosen_while_disarmed_then_armed_at_neutral_sticks():
    """Found by a new user's test of the link: disarmed, DO_SET_MODE MANUAL was DENIED ("arm first") while every
    other mode was accepted: ArduPilot Rover's sequence (MANUAL, then arm) was refused, and a user armed in AUTO,
    where the boat drove at once."""
    from autopilot.daemon.commands import _manual
    from autopilot.gnc import Autopilot, GncConfig

    ap = Autopilot(GncConfig(), [(10.0, 0.0)], armed=False)
    loop = SimpleNamespace(ap=ap, state=SimpleNamespace(manual_input_wall_s=None),
                           clock=SimpleNamespace(wall_elapsed_s=lambda: 1.0))
    ok, answer = _manual(loop, {"command": "manual", "explicit": True, "forward_nd": 0.0, "turn_nd": 0.0}, None, "", "link")
    assert ok and ap.mode is Mode.MANUAL and not ap.armed, answer
    _manual(loop, {"command": "manual", "forward_nd": 0.6, "turn_nd": 0.0}, None, "", "link")  # the stick forward
    assert ap.request("arm", None, cause="link")[0] is False  # the arming check: sticks at neutral
    _manual(loop, {"command": "manual", "forward_nd": 0.0, "turn_nd": 0.0}, None, "", "link")
    assert ap.request("arm", None, cause="link") == (True, "armed") and ap.mode is Mode.MANUAL


def test_manual_chosen_disarmed_waits_for_the_arm_before_its_silence_counts():
    """A review: MANUAL chosen disarmed without a joystick took the manual timeout's hold half a second later, so
    the arm ran the thrusters keeping station."""
    from autopilot.daemon.config import DaemonConfig
    from autopilot.gnc import Autopilot, GncConfig

    ap = Autopilot(GncConfig(), [(10.0, 0.0)], armed=False)
    ap.request("manual", None, cause="link")
    now = [100.0]
    loop = SimpleNamespace(ap=ap, cfg=DaemonConfig(), state=SimpleNamespace(manual_input_wall_s=100.0),
                           clock=SimpleNamespace(wall_elapsed_s=lambda: now[0]))
    for now[0] in (100.2, 101.0, 105.0):  # disarmed and silent for 5 s: still manual
        ControlLoop._manual_timeout(loop, None, "no position", now[0])
        assert ap.mode is Mode.MANUAL
    assert ap.request("arm", None, cause="link") == (True, "armed")
    now[0] = 105.3
    ControlLoop._manual_timeout(loop, None, "no position", now[0])
    assert ap.mode is Mode.MANUAL  # 0.3 s since the arm
    now[0] = 106.0
    ControlLoop._manual_timeout(loop, None, "no position", now[0])
    assert ap.mode is not Mode.MANUAL  # then the silence counts: the configured action (stop without a position)
