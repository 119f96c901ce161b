"""Closed-loop trials: mission logs flown by the real daemon with ``--sim`` (tests and benchmarks).

``autopilot run --sim`` runs the whole autopilot (drivers, failsafe, GNC, the
mission log writer) in its own process, as a user starts it, against the
simulated SC-30 and Mbed on pseudo-terminals, on a sped-up clock. The simulated SC-30 measures with the
realistic error model (:mod:`autopilot.sim.gps_error`: one fix a second with
wandering error and outliers, a wandering quantised heading with lost
sentences), the water has the hidden current. The pond missions are
``config/missions/pond-9.*.yaml`` (thesis Table 9.1).

This is the one sysid module that runs the daemon; identification itself only
reads the logs it writes.
"""

from __future__ import annotations

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
# The SC-30's line for the closed-loop trials: 4800 baud, the default and what a real SC-30 installation
# reads (SPEC 10). There a heading reaches the daemon 40-260 ms after it was measured, by an amount that
# changes from tick to tick; the driver stamps it with its measurement tick (drivers/line_timing.py), so
# the log's heading_age_s is the measurement's age. Stamped on arrival instead, five calm logs came out
# `unexplained` (the heading's wander at its bound); the earlier benchmark flew at 38400 baud to avoid it.
BAUD = 4800
PARALLEL_FLIGHTS = 4  # flights at a time (fly_pond_logs)
FLIGHT_TIMEOUT_S = 300.0  # a pond mission at 2x takes ~20 s


def realistic_sim(rng: np.random.Generator, *, seed: int, current_speed_m_s: float = 0.0,
                  current_towards_deg: float = 0.0, wind_speed_m_s: float = 0.0, wind_from_deg: float = 0.0):
    """A SimConfig whose SC-30 measures like issue 12's sensor (ranges of realistic.draw_models), its speed and
    course over ground with a velocity error of 0.03-0.1 m/s per axis (realistic.VELOCITY_WHITE_M_S)."""
    from autopilot.daemon.config import SimConfig

    return SimConfig(
        seed=seed, current_speed_m_s=current_speed_m_s, current_towards_deg=current_towards_deg % 360.0,
        wind_speed_m_s=wind_speed_m_s, wind_from_deg=wind_from_deg % 360.0,
        position_noise_m=0.15, position_wander_m=float(rng.uniform(0.5, 2.0)),
        position_wander_time_s=float(rng.uniform(30.0, 60.0)), position_outlier_rate=0.01, position_outlier_m=10.0,
        heading_noise_deg=0.0, heading_wander_deg=0.3, heading_wander_time_s=float(rng.uniform(20.0, 60.0)),
        heading_loss_rate=0.005, velocity_noise_m_s=float(rng.uniform(0.03, 0.1)),
    )


def fly(mission, sim, log_dir, *, speedup: float = SPEEDUP, baud: int = BAUD) -> Path:
    """Fly one mission under ``--sim`` with the SimConfig ``sim``; returns the mission log's path."""
    return _landed(mission, *_launch(mission, sim, log_dir, speedup=speedup, baud=baud))


def _launch(mission, sim, log_dir, *, speedup: float, baud: int):
    """``autopilot run --sim`` as a user runs it, in its own process, its configuration, state and control
    socket in ``log_dir`` (a second flight at the same time must not find the first one's socket)."""
    import subprocess

    import yaml

    from autopilot.daemon.config import DaemonConfig, SerialConfig
    from autopilot.schema import to_dict

    flight_dir = Path(log_dir)
    flight_dir.mkdir(parents=True, exist_ok=True)
    config = flight_dir / "autopilot.yaml"
    config.write_text(yaml.safe_dump(to_dict(DaemonConfig(sim=sim, serial=SerialConfig(sc30_baud=baud)))))
    state = tempfile.mkdtemp(prefix="sysid-state-")
    args = [sys.executable, "-m", "autopilot", "run", "--sim", "--config", str(config), "--mission", str(mission),
            "--speedup", str(speedup), "--log-dir", str(flight_dir), "--state-dir", state, "--runtime-dir", state,
            "--fresh"]
    with open(flight_dir / "daemon-output.txt", "w") as out:
        proc = subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT)
    return proc, flight_dir, state


def _landed(mission, proc, flight_dir: Path, state: str) -> Path:
    """The flight's mission log once its daemon has ended (its output in the error when it failed)."""
    import shutil

    try:
        code = proc.wait(timeout=FLIGHT_TIMEOUT_S)
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    finally:
        shutil.rmtree(state, ignore_errors=True)
    logs = sorted(flight_dir.glob("*.jsonl"), key=lambda p: p.stat().st_mtime)
    if code != 0 or not logs:
        tail = (flight_dir / "daemon-output.txt").read_text(errors="replace")[-1500:]
        raise RuntimeError(f"autopilot run --sim {mission}: exit {code}, {len(logs)} log(s) in {flight_dir}:\n{tail}")
    return logs[-1]


def fly_pond_logs(log_dir, seed: int, *, n_logs: int = 5, current_speed_m_s: float = 0.0,
                  current_towards_deg: float | None = None, speedup: float = SPEEDUP, baud: int = BAUD,
                  jobs: int = PARALLEL_FLIGHTS, wind_speed_m_s: float = 0.0, wind_from_deg: float = 0.0,
                  thrust_gains: tuple[float, float] = (1.0, 1.0)) -> list[Path]:
    """``n_logs`` pond missions (cycling through pond-9.1..9.4) with one sensor and one current, from ``seed``.

    The current's direction is drawn unless given; the wind (the simulator's windage) is given or none; the motors
    make ``thrust_gains`` (port, starboard) of the table's thrust;
    each flight has its own noise seed. ``baud``: the
    SC-30's line (BAUD by default, see there). ``jobs`` flights at a time, each a daemon in its own process
    writing to its own ``flight-<k>/`` (the flights wait on the clock, not the processor: four at 2x use
    about a tenth of a core each); the logs are returned in flight order.
    """
    rng = np.random.default_rng(seed)
    towards = float(rng.uniform(0.0, 360.0)) if current_towards_deg is None else current_towards_deg
    sim = realistic_sim(rng, seed=0, current_speed_m_s=current_speed_m_s, current_towards_deg=towards,
                        wind_speed_m_s=wind_speed_m_s, wind_from_deg=wind_from_deg)
    import dataclasses

    sim = dataclasses.replace(sim, thrust_gain_port=float(thrust_gains[0]), thrust_gain_stbd=float(thrust_gains[1]))

    flights = []
    for k in range(n_logs):
        flight_dir = Path(log_dir) / f"flight-{k}"
        flight_dir.mkdir(parents=True, exist_ok=True)
        flights.append((POND_MISSIONS[k % len(POND_MISSIONS)],
                        dataclasses.replace(sim, seed=int(rng.integers(0, 2**31 - 1))), flight_dir))
    out: list[Path] = []
    for first in range(0, n_logs, max(1, jobs)):
        batch = [(m, _launch(m, f, d, speedup=speedup, baud=baud)) for m, f, d in flights[first:first + max(1, jobs)]]
        out += [_landed(m, *launched) for m, launched in batch]
    return out
