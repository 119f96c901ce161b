"""Realistic trials: the measurements a real boat's logs hold (project issue 12), for tests and benchmarks.

The truth is :func:`autopilot.sysid.truth.simulate_truth` on a 100 Hz grid (the
project's simulator, independent of the replay code). The measurement model is
:mod:`autopilot.sim.gps_error`, the one the simulated SC-30 of ``autopilot run
--sim`` uses too:

- GPS position fixes at 1 Hz (``fix_period_s``) in a 10 Hz log (``LOG_DT_S``),
  at a random phase: a fix is measured at its time and appears on the first
  log row at or after it. Between fixes the rows hold the last fix repeated
  (``cells="held"``, as the daemon's mission log and ``review --export csv``
  write it) or empty cells (``cells="empty"``); ``time_columns=True`` adds the
  ``position_time_s`` / ``heading_time_s`` columns (the measurement times).
- Position error per axis: Gauss-Markov wander (``draw_models``: 0.5-2 m,
  correlation time 30-60 s) plus 0.15 m white; 1 % of the fixes jump 10 m.
- Heading every 100 ms: 0.3 deg of Gauss-Markov wander (correlation time 20-60 s),
  quantised to 0.1 deg, 0.5 % of the sentences lost (an empty cell, or the
  last heading held with its own time when ``cells="held"``).

The trial is built from these columns by the same code that reads a trial CSV
(:func:`autopilot.sysid.trials.trial_from_columns`), so the held-fix rules are
exercised exactly as on a user's file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.sim import VesselParams
from autopilot.sim.gps_error import (
    GpsErrorModel,
    HeadingErrorModel,
    heading_errors,
    position_errors,
    quantise_deg,
)
from autopilot.sysid.trials import Trial, trial_from_columns
from autopilot.sysid.truth import Truth, sensed, simulate_truth

CELLS = ("held", "empty")


@dataclass(frozen=True)
class Measurement:
    """How a trial is measured and logged."""

    gps: GpsErrorModel = GpsErrorModel()
    heading: HeadingErrorModel = HeadingErrorModel()
    fix_period_s: float = 1.0
    cells: str = "held"  # rows between fixes: "held" (last fix repeated) or "empty"
    time_columns: bool = False  # write position_time_s / heading_time_s

    def __post_init__(self):
        if self.cells not in CELLS:
            raise ValueError(f"cells: {self.cells!r} is not one of {CELLS}")


def draw_models(rng: np.random.Generator) -> tuple[GpsErrorModel, HeadingErrorModel]:
    """The sensor of one set of trials (issue 12's ranges): the same receiver and compass for all of them."""
    gps = GpsErrorModel(wander_m=rng.uniform(0.5, 2.0), wander_time_s=rng.uniform(30.0, 60.0), white_m=0.15,
                        outlier_rate=0.01, outlier_m=10.0)
    heading = HeadingErrorModel(wander_deg=0.3, wander_time_s=rng.uniform(20.0, 60.0), white_deg=0.0,
                                resolution_deg=0.1, loss_rate=0.005)
    return gps, heading


def _last_at_or_before(t_rows: np.ndarray, t_samples: np.ndarray) -> np.ndarray:
    """Per row, the index of the last sample measured at or before it (-1: none yet)."""
    return np.searchsorted(t_samples, t_rows + 1e-9, side="right") - 1


def measure(truth: Truth, meas: Measurement, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The trial's CSV columns (NaN = empty cell) as a logger would write them from ``truth``."""
    t = truth.t_log_s
    t_fix = np.arange(rng.uniform(0.0, meas.fix_period_s), t[-1] + 1e-9, meas.fix_period_s)
    n_true, e_true, _ = sensed(truth, t_fix)
    dn, de, _ = position_errors(meas.gps, t_fix, rng)
    k = _last_at_or_before(t, t_fix)
    fresh = np.r_[k[:1] >= 0, np.diff(k) > 0]
    show = k >= 0 if meas.cells == "held" else fresh
    kk = np.maximum(k, 0)
    cols = {"t_s": t,
            "north_m": np.where(show, (n_true + dn)[kk], np.nan),
            "east_m": np.where(show, (e_true + de)[kk], np.nan),
            "pwm_port_pct": truth.duty_port_pct, "pwm_stbd_pct": truth.duty_stbd_pct}
    _, _, psi = sensed(truth, t)
    err, lost = heading_errors(meas.heading, t, rng)
    hdg = quantise_deg(np.degrees(psi) + err, meas.heading.resolution_deg)
    ok = ~lost
    h_t = np.where(ok, t, np.nan)
    if meas.cells == "held":  # a lost sentence: the row repeats the last heading (with its own time)
        j = np.maximum.accumulate(np.where(ok, np.arange(t.size), 0))
        hdg, h_t = hdg[j], h_t[j]
        ok = np.isfinite(h_t)
    cols["heading_deg"] = np.where(ok, hdg, np.nan)
    if meas.time_columns:
        cols["position_time_s"] = np.where(show, t_fix[kk], np.nan)
        cols["heading_time_s"] = np.where(ok, h_t, np.nan)
    return cols


def make_realistic_trial(vessel: VesselParams, effects: dict, rng: np.random.Generator, meas: Measurement, *,
                         name: str, duration_s: float = 60.0, curve: ThrustCurve | None = None) -> Trial:
    """One trial: random manoeuvres with the hidden ``effects``, measured as ``meas`` says."""
    truth = simulate_truth(vessel, effects, rng, duration_s=duration_s, curve=curve)
    return trial_from_columns(name, measure(truth, meas, rng), curve=curve)


def make_realistic_trials(vessel: VesselParams, effects: dict, seed: int, *, n_trials: int = 4,
                          duration_s: float = 60.0, cells: str = "held", time_columns: bool = False,
                          gps: GpsErrorModel | None = None, heading: HeadingErrorModel | None = None) -> list[Trial]:
    """``n_trials`` trials with the hidden ``effects``, one sensor (drawn unless given), reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    g, h = draw_models(rng)
    meas = Measurement(gps=gps or g, heading=heading or h, cells=cells, time_columns=time_columns)
    return [make_realistic_trial(vessel, effects, rng, meas, name=f"trial{i}", duration_s=duration_s)
            for i in range(n_trials)]


def write_columns_csv(cols: dict[str, np.ndarray], path) -> None:
    """The columns as a trial CSV (empty cell = NaN), as a user's logger would."""
    names = list(cols)
    data = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        fh.writelines(",".join("" if not np.isfinite(v) else f"{v:.6f}" for v in row) + "\n" for row in data)
