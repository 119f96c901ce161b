"""What `autopilot run` tells the person at the terminal when the run ends."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from autopilot.daemon.app import end_summary
from autopilot.daemon.loop import LoopState


def _loop(*, cycles, skipped, failsafes=(), speedup=100.0, complete=True):
    st = LoopState(cycles=cycles, skipped=skipped, reached=[0, 1, 2] if complete else [0],
                   closest_m={0: 0.41, 1: 0.27, 2: float("nan")} if complete else {0: 0.41},
                   completed_t_s=38.0 if complete else None, failsafe_causes=list(failsafes))
    held = speedup * cycles / (cycles + skipped)  # the rate a loop at that speedup skipping so many deadlines keeps
    return SimpleNamespace(state=st, clock=SimpleNamespace(now_s=lambda: 45.0, speedup=speedup), t0_s=5.0,
                           mission=SimpleNamespace(waypoints_ne_m=np.zeros((3, 2))), speedup_held=lambda: held)


def test_a_clean_run():
    lines = end_summary(_loop(cycles=400, skipped=0, speedup=10.0), "/l/m.jsonl", sim=True)
    assert lines[0] == "log: /l/m.jsonl"
    assert lines[1] == "mission complete after 40.0 s: 3 of 3 waypoint(s) reached"
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
    assert lines[1].startswith("mission not complete") and "1 of 3 waypoint(s) reached" in lines[1]
    assert "  W1: not reached, closest approach n/a" in lines
