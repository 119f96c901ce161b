"""Synthetic trials with white measurement noise at 10 Hz: the original test case (issue 5).

The truth is :func:`autopilot.sysid.truth.simulate_truth` (independent of the
replay code). Measurements: 10 Hz positions and headings, white position
noise, heading noise quantised to 0.1 deg, a few dropped sensor samples (the
logged command kept) and a few empty cells. What a real boat's logs look like
(1 Hz fixes, wandering GPS error, outliers) is :mod:`autopilot.sysid.realistic`.
"""

from __future__ import annotations

import numpy as np

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.sim import VesselParams
from autopilot.sysid.trials import Trial, make_trial
from autopilot.sysid.truth import hidden_params, schedule, sensed, simulate_truth  # noqa: F401 (re-exported)


def make_trial_with_effects(
    vessel: VesselParams,
    effects: dict,
    rng: np.random.Generator,
    *,
    name: str,
    duration_s: float = 90.0,
    pos_noise_m: float = 0.5,
    heading_noise_deg: float = 0.3,
    dropped: int = 5,
    curve: ThrustCurve | None = None,
) -> Trial:
    """One synthetic trial: random manoeuvres, hidden ``effects`` (key -> value), measured at 10 Hz."""
    curve = curve or ThrustCurve()
    truth = simulate_truth(vessel, effects, rng, duration_s=duration_s, curve=curve)
    t10, dp10, ds10 = truth.t_log_s, truth.duty_port_pct, truth.duty_stbd_pct
    n, e, psi = sensed(truth, t10)
    n = n + rng.normal(0, pos_noise_m, n.size)
    e = e + rng.normal(0, pos_noise_m, e.size)
    hdg = np.round((np.degrees(psi) + rng.normal(0, heading_noise_deg, psi.size)) % 360.0, 1)
    # dropped samples: the sensor sample is lost (position and heading empty) while the cycle's
    # command is still logged, as in the daemon's mission log; plus a few single empty cells
    keep = np.ones(t10.size, dtype=bool)
    lost = rng.choice(np.arange(30, t10.size), size=dropped, replace=False)
    n[lost] = np.nan
    e[lost] = np.nan
    hdg[lost] = np.nan
    gaps = rng.choice(np.arange(30, t10.size), size=dropped, replace=False)
    n[gaps] = np.nan
    hdg[rng.choice(np.arange(30, t10.size), size=dropped, replace=False)] = np.nan
    return make_trial(
        name,
        t10[keep],
        north_m=n[keep],
        east_m=e[keep],
        heading_deg=hdg[keep],
        pwm_port_pct=dp10[keep],
        pwm_stbd_pct=ds10[keep],
        curve=curve,
    )


def make_trials(vessel: VesselParams, effects: dict, seed: int, *, n_trials: int = 5, duration_s: float = 90.0,
                pos_noise_m: float | None = None) -> list[Trial]:
    """``n_trials`` synthetic trials with the hidden ``effects``, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0.3, 1.0) if pos_noise_m is None else pos_noise_m
    return [
        make_trial_with_effects(vessel, effects, rng, name=f"trial{i}", duration_s=duration_s, pos_noise_m=noise)
        for i in range(n_trials)
    ]
