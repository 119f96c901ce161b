"""Closed-loop trials: mission logs flown by the real daemon with ``--sim`` (tests and benchmarks).

``autopilot.daemon.app.run_daemon`` runs the whole autopilot (drivers, failsafe,
GNC, the mission log writer) against the simulated SC-30 and Mbed on
pseudo-terminals, on a sped-up clock. The simulated SC-30 measures with the
realistic error model (:mod:`autopilot.sim.gps_error`: one fix a second with
wandering error and outliers, a wandering quantised heading with lost
sentences), the water has the hidden current. The pond missions are
``config/missions/pond-9.*.yaml`` (thesis Table 9.1).

This is the one sysid module that runs the daemon; identification itself only
reads the logs it writes.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from autopilot.resources import missions_dir

POND_MISSIONS = tuple(sorted(missions_dir().glob("pond-9.*.yaml")))
SPEEDUP = 2.0  # the daemon's clock runs this many times faster than real time (see below)
# Faster clocks make the logs lie: at 20x a millisecond of event-loop delay is 20 ms of boat time, so
# every command reaches the simulated motors and every sentence the daemon tens of milliseconds later
# than the log says (five calm logs at 20x fitted a 0.1 s thrust lag and sensor delay, BIC -80; at 5x
# nothing). A heading stale by a loaded machine even trips the failsafe.
# The SC-30's line for the closed-loop trials. At 4800 baud a sentence reaches the daemon 40 ms (HDT
# alone) to ~250 ms (queued behind a 1 Hz GGA/RMC) after it was measured, and the log stamps the
# arrival: its heading times lag the measurements by a varying 0.04-0.25 s, which the replay sees as
# a sensor delay of ~0.1 s (a real property of such logs, not a hidden effect of the boat). At
# 38400 baud (SPEC 10: "38400 on some ports") the lag is a few milliseconds.
FAST_BAUD = 38400


def realistic_sim(rng: np.random.Generator, *, seed: int, current_speed_m_s: float = 0.0,
                  current_towards_deg: float = 0.0):
    """A SimConfig whose SC-30 measures like issue 12's sensor (ranges of realistic.draw_models)."""
    from autopilot.daemon.config import SimConfig

    return SimConfig(
        seed=seed, current_speed_m_s=current_speed_m_s, current_towards_deg=current_towards_deg % 360.0,
        position_noise_m=0.15, position_wander_m=float(rng.uniform(0.5, 2.0)),
        position_wander_time_s=float(rng.uniform(30.0, 60.0)), position_outlier_rate=0.01, position_outlier_m=10.0,
        heading_noise_deg=0.0, heading_wander_deg=0.3, heading_wander_time_s=float(rng.uniform(20.0, 60.0)),
        heading_loss_rate=0.005,
    )


def fly(mission, sim, log_dir, *, speedup: float = SPEEDUP, baud: int = 4800) -> Path:
    """Fly one mission under ``--sim`` with the SimConfig ``sim``; returns the mission log's path."""
    from autopilot.daemon.app import RunOptions, run_daemon
    from autopilot.daemon.config import DaemonConfig, SerialConfig

    cfg = DaemonConfig(sim=sim, serial=SerialConfig(sc30_baud=baud))
    log_dir = Path(log_dir)
    before = set(log_dir.glob("*.jsonl"))
    with tempfile.TemporaryDirectory(prefix="sysid-state-") as state, _quiet():
        code = run_daemon(cfg, RunOptions(str(mission), sim=True, speedup=speedup, log_dir=str(log_dir),
                                          state_dir=state, fresh=True))
    new = sorted(set(log_dir.glob("*.jsonl")) - before, key=lambda p: p.stat().st_mtime)
    if code != 0 or not new:
        raise RuntimeError(f"autopilot run --sim {mission}: exit {code}, {len(new)} new log(s) in {log_dir}")
    return new[-1]


@contextlib.contextmanager
def _quiet():
    """The daemon's console lines (its events, on the process's own stdout/stderr) out of sight."""
    saved = [os.dup(1), os.dup(2)]
    sys.stdout.flush()
    sys.stderr.flush()
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        os.dup2(null.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)


def fly_pond_logs(log_dir, seed: int, *, n_logs: int = 5, current_speed_m_s: float = 0.0,
                  current_towards_deg: float | None = None, speedup: float = SPEEDUP, baud: int = FAST_BAUD) -> list[Path]:
    """``n_logs`` pond missions (cycling through pond-9.1..9.4) with one sensor and one current, from ``seed``.

    The current's direction is drawn unless given; each flight has its own noise seed. ``baud``: the
    SC-30's line (FAST_BAUD by default, see there).
    """
    rng = np.random.default_rng(seed)
    towards = float(rng.uniform(0.0, 360.0)) if current_towards_deg is None else current_towards_deg
    sim = realistic_sim(rng, seed=0, current_speed_m_s=current_speed_m_s, current_towards_deg=towards)
    import dataclasses

    Path(log_dir).mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(n_logs):
        mission = POND_MISSIONS[k % len(POND_MISSIONS)]
        flight = dataclasses.replace(sim, seed=int(rng.integers(0, 2**31 - 1)))
        out.append(fly(mission, flight, log_dir, speedup=speedup, baud=baud))
    return out
