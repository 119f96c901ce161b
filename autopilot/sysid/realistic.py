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
- ``velocity=True`` adds the receiver's speed and course over ground (``sog_m_s``,
  ``cog_deg``) with each fix, as RMC carries them: the antenna's true velocity plus a
  white error of ``VELOCITY_WHITE_M_S`` per axis (drawn per set of trials; a Doppler
  velocity, the SC-30's own accuracy is not in the sources), printed to 0.01 kn and
  0.1 deg. The issue's measurement model has no velocity; the daemon's logs do.

The trial is built from these columns by the same code that reads a trial CSV
(:func:`autopilot.sysid.trials.trial_from_columns`), so the held-fix rules are
exercised exactly as on a user's file.
"""

from __future__ import annotations

import dataclasses
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
    velocity_errors,
)
from autopilot.sysid.trials import Trial, trial_from_columns
from autopilot.sysid.truth import Truth, sensed, sensed_velocity, simulate_truth

CELLS = ("held", "empty")
VELOCITY_WHITE_M_S = (0.03, 0.1)  # range of the velocity error per axis (1 sigma)
KNOT_M_S = 1852.0 / 3600.0


@dataclass(frozen=True)
class Measurement:
    """How a trial is measured and logged."""

    gps: GpsErrorModel = GpsErrorModel()
    heading: HeadingErrorModel = HeadingErrorModel()
    fix_period_s: float = 1.0
    cells: str = "held"  # rows between fixes: "held" (last fix repeated) or "empty"
    time_columns: bool = False  # write position_time_s / heading_time_s
    velocity: bool = False  # write sog_m_s / cog_deg with each fix (gps.velocity_white_m_s per axis)

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
    if meas.velocity:  # drawn after the position and heading errors: the same seed gives them unchanged
        vn, ve = sensed_velocity(truth, t_fix)
        dvn, dve = velocity_errors(meas.gps, t_fix, rng)
        vn, ve = vn + dvn, ve + dve
        sog = np.round(np.hypot(vn, ve) / KNOT_M_S, 2) * KNOT_M_S  # as RMC prints them
        cog = np.round(np.degrees(np.arctan2(ve, vn)) % 360.0, 1)
        cols["sog_m_s"] = np.where(show, sog[kk], np.nan)
        cols["cog_deg"] = np.where(show, cog[kk], np.nan)
    return cols


def make_realistic_trial(vessel: VesselParams, effects: dict, rng: np.random.Generator, meas: Measurement, *,
                         name: str, duration_s: float = 60.0, curve: ThrustCurve | None = None) -> Trial:
    """One trial: random manoeuvres with the hidden ``effects``, measured as ``meas`` says."""
    truth = simulate_truth(vessel, effects, rng, duration_s=duration_s, curve=curve)
    return trial_from_columns(name, measure(truth, meas, rng), curve=curve)


def make_realistic_trials(vessel: VesselParams, effects: dict, seed: int, *, n_trials: int = 4,
                          duration_s: float = 60.0, cells: str = "held", time_columns: bool = False,
                          velocity: bool = False, gps: GpsErrorModel | None = None,
                          heading: HeadingErrorModel | None = None) -> list[Trial]:
    """``n_trials`` trials with the hidden ``effects``, one sensor (drawn unless given), reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    g, h = draw_models(rng)
    if velocity and gps is None:  # its own stream: the other draws stay those of the same seed without it
        g = dataclasses.replace(g, velocity_white_m_s=float(np.random.default_rng([seed, 7]).uniform(*VELOCITY_WHITE_M_S)))
    meas = Measurement(gps=gps or g, heading=heading or h, cells=cells, time_columns=time_columns, velocity=velocity)
    return [make_realistic_trial(vessel, effects, rng, meas, name=f"trial{i}", duration_s=duration_s)
            for i in range(n_trials)]


def write_columns_csv(cols: dict[str, np.ndarray], path) -> None:
    """The columns as a trial CSV (empty cell = NaN), as a user's logger would."""
    names = list(cols)
    data = np.column_stack([np.asarray(cols[k], dtype=float) for k in names])
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(names) + "\n")
        fh.writelines(",".join("" if not np.isfinite(v) else f"{v:.6f}" for v in row) + "\n" for row in data)
