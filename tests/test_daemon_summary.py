"""What `autopilot run` tells the person at the terminal when the run ends."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from autopilot.daemon.app import end_summary
from autopilot.daemon.loop import LoopState
from autopilot.logschema import Mode


def _loop(*, cycles, skipped, failsafes=(), speedup=100.0, complete=True, lines_lost=0, log_failing=False,
          stop_acknowledged=True, stop_signal=None, hold_zero=None, board_answered=True, finished=None, mode="complete",
          time_stop_stayed=False, time_stop_from=None):
    st = LoopState(cycles=cycles, skipped=skipped, reached=[0, 1, 2] if complete else [], mode=mode,
                   finished=complete if finished is None else finished,
                   closest_m={0: 0.41, 1: 0.27, 2: float("nan")} if complete else {0: 0.41},
                   completed_t_s=38.0 if complete else None, failsafe_causes=list(failsafes),
                   stop_acknowledged=stop_acknowledged, stop_signal=stop_signal)
    held = speedup * cycles / (cycles + skipped)  # the rate a loop at that speedup skipping so many deadlines keeps
    return SimpleNamespace(state=st, clock=SimpleNamespace(now_s=lambda: 45.0, speedup=speedup), t0_s=5.0,
                           mission=SimpleNamespace(waypoints_ne_m=np.zeros((3, 2))), speedup_held=lambda: held,
                           log=SimpleNamespace(lines_lost=lines_lost, failing=log_failing), hold_zero=hold_zero,
                           time_stop_stayed=time_stop_stayed, time_stop_from=time_stop_from,
                           ap=SimpleNamespace(mode=Mode.STOP if hold_zero else Mode.AUTO),
                           thrusters=SimpleNamespace(answered=board_answered))


def test_a_clean_run():
    lines = end_summary(_loop(cycles=400, skipped=0, speedup=10.0), "/l/m.jsonl", sim=True)
    assert lines[0] == "log: /l/m.jsonl"
    assert lines[1] == "mission complete after 40.0 s: 3 of 3 waypoint(s) reached; zero thrust acknowledged by the Mbed"
    assert "  W0: reached, closest approach 0.41 m" in lines and "  W2: reached, closest approach n/a" in lines
    assert "failsafes: 0" in lines
    assert not any("could not keep up" in ln for ln in lines)


def test_a_bench_run_that_could_not_keep_up_says_so():
    lines = end_summary(_loop(cycles=300, skipped=100, failsafes=("heading_stale", "mbed_ack_missing")), "x", sim=True)
    assert "failsafes: 2 (heading_stale, mbed_ack_missing)" in lines
    keep = [ln for ln in lines if "could not keep up" in ln]
    assert keep and "100 of 400 deadlines skipped" in keep[0] and "lower --speedup" in keep[0]
    assert any("speedup held ~75 of --speedup 100" in ln for ln in lines)


def test_an_unfinished_mission():
    lines = end_summary(_loop(cycles=100, skipped=0, complete=False), "x", sim=False)
    assert lines[1].startswith("mission not complete") and "0 of 3 waypoint(s) reached" in lines[1]
    assert "  W1: not reached, closest approach n/a" in lines


def test_a_log_cut_short_and_an_unacknowledged_stop_are_said():
    """Found by an operator audit: the summary pointed at a log a full disk had cut short as if it were whole, and
    an Mbed that never acknowledged the final zero was only a JSON field in that log."""
    lines = end_summary(_loop(cycles=400, skipped=0, lines_lost=12, log_failing=True, stop_acknowledged=False), "x",
                        sim=False)
    assert lines[1] == "  the log lost 12 line(s): a write failed (disk full?); it is incomplete, without its stop line"
    assert lines[2].startswith("WARNING: the Mbed did not acknowledge the final zero thrust")
    clean = end_summary(_loop(cycles=400, skipped=0), "x", sim=False)
    assert not any("lost" in ln or "WARNING" in ln for ln in clean)


def test_a_stop_by_signal_and_a_held_start_are_said():
    """Found by a new-user audit: a run ended by SIGTERM said only "mission not complete" (the signal and the
    acknowledged zero were in the JSON stop line), and one held at zero thrust by an interrupted mission's progress
    never said why."""
    lines = end_summary(_loop(cycles=95, skipped=0, complete=False, stop_signal="SIGTERM"), "x", sim=False)
    assert lines[1] == ("mission not complete after 40.0 s: 0 of 3 waypoint(s) reached; stopped by SIGTERM; zero "
                        "thrust acknowledged by the Mbed")
    timed = end_summary(_loop(cycles=95, skipped=0, complete=False, stop_signal="SIGTERM", time_stop_stayed=True),
                        "x", sim=False)  # stayed up after its time limit's stop (a link, systemd)
    assert "; stopped by max_mission_time, then by SIGTERM; zero thrust" in timed[1], timed
    held = end_summary(_loop(cycles=95, skipped=0, complete=False, hold_zero="interrupted mission found"), "x",
                       sim=True)
    assert "  the boat waited at zero thrust from the start: interrupted mission found" in held


def test_a_board_that_never_answered_is_not_a_thruster_left_running():
    """Found by an on-boat audit: a run whose Mbed port never opened ended with "WARNING: the Mbed did not
    acknowledge the final zero thrust: check that the thrusters stopped", for thrusters that had never run."""
    lines = end_summary(_loop(cycles=40, skipped=0, complete=False, stop_acknowledged=False, board_answered=False),
                        "x", sim=False)
    assert lines[1].startswith("the Mbed never acknowledged a command in this run")
    assert not any("WARNING" in ln for ln in lines)


def test_a_run_stopped_in_its_final_hold_is_not_called_complete():
    """Found by a new-user audit: station-keep stopped by SIGTERM 153 s into its 300-s hold said "mission complete"
    (the stop line said signal). The route is complete; the run was stopped in what follows it."""
    lines = end_summary(_loop(cycles=400, skipped=0, stop_signal="SIGTERM", finished=False, mode="hold"), "x", sim=True)
    assert lines[1] == ("route complete after 40.0 s: 3 of 3 waypoint(s) reached; then in hold, stopped by SIGTERM; "
                        "zero thrust acknowledged by the Mbed")
    done = end_summary(_loop(cycles=400, skipped=0, stop_signal=None), "x", sim=True)
    assert done[1].startswith("mission complete after 40.0 s")
    # a final hold max_mission_time stopped, the daemon staying up until the signal (logschema.time_stop_words)
    timed = end_summary(_loop(cycles=400, skipped=0, stop_signal="SIGTERM", finished=False, mode="stop",
                              time_stop_stayed=True, time_stop_from=("hold", 1560.4)), "x", sim=True)
    assert "; then in hold for 1560 s until max_mission_time stopped it; stopped by SIGTERM;" in timed[1]
    moved = end_summary(_loop(cycles=400, skipped=0, stop_signal="SIGTERM", finished=False, mode="rtl",
                              time_stop_stayed=True, time_stop_from=("hold", 7.25)), "x", sim=True)
    assert "; then in hold for 7.2 s until max_mission_time stopped it; then in rtl, stopped by SIGTERM;" in moved[1]
    # the time limit ended the run there (nothing keeping it up): it said "mission complete", the hold unsaid
    ended = end_summary(_loop(cycles=400, skipped=0, finished=False, mode="stop", time_stop_from=("hold", 1560.0)),
                        "x", sim=True)
    assert ended[1].startswith("route complete after 40.0 s: 3 of 3 waypoint(s) reached; then in hold for 1560 s "
                               "until max_mission_time stopped it;"), ended[1]


def test_a_run_that_stayed_up_after_its_mission_says_how_it_ended():
    """Rereading the change: a daemon that stayed up after the mission's stop (a ground station link, systemd) and
    was then stopped by SIGTERM said "mission complete" and nothing of the signal; the review says "mission
    complete; then stopped by SIGTERM"."""
    lines = end_summary(_loop(cycles=400, skipped=0, stop_signal="SIGTERM", finished=True, mode="complete"), "x",
                        sim=True)
    assert lines[1] == ("mission complete after 40.0 s: 3 of 3 waypoint(s) reached; then stopped by SIGTERM; "
                        "zero thrust acknowledged by the Mbed")


def test_a_resumed_run_counts_from_where_it_resumed_and_each_failsafe_once():
    """Found by a new user's test: a run resumed at W2 said "0 of 9 reached; W0: not reached, W1: not reached",
    though the run before had reached them; and "failsafes: 52 (heading_stale, heading_stale, ...)" hid the time
    limit that ended the run."""
    loop = _loop(cycles=400, skipped=0, complete=False,
                 failsafes=("heading_stale",) * 51 + ("max_mission_time",))
    loop.start_index = 2
    loop.state.reached, loop.state.closest_m = [2], {2: 0.5}
    lines = end_summary(loop, "x", sim=False)
    assert lines[1].startswith("mission not complete after 40.0 s: 1 of 1 waypoint(s) reached (this run started at W2: "
                               "W0-W1 were an earlier run's)"), lines[1]
    assert "  W0: an earlier run's" in lines and "  W1: an earlier run's" in lines
    assert "  W2: reached, closest approach 0.50 m" in lines
    assert "failsafes: 52 (heading_stale x51, max_mission_time)" in lines


def test_the_time_said_is_the_stop_lines():
    """Under --speedup max the clock ran on through the shutdown: the console said "after 54.0 s" for a stop line
    (and a review) of 53.11 s (a new user's test)."""
    loop = _loop(cycles=400, skipped=0)
    loop.state.stopped_t_s = 38.46
    assert end_summary(loop, "x", sim=True)[1].startswith("mission complete after 38.5 s:")
