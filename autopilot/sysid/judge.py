"""What a fitted model is worth: its noise, whether it is adequate, how much an effect explains.

- :func:`model_noise`: the noise model (per channel) estimated from a fit's residuals
  (``noise.estimate``, restricted maximum likelihood inside the sensor's bounds).
- :func:`channels`: per channel (position, heading) the weighted chi-square per measurement
  under the noise model, the raw residual RMS and what the noise alone would leave.
  A channel is *adequate* when its chi-square per measurement is at most ADEQUATE_CHI2 and a
  noise model free of the sensor's bounds (:class:`noise.NoiseBounds`) explains the residual no
  better than one inside them (:func:`beyond_sensor`, a likelihood ratio): the noise a real
  sensor can have explains the residual. Otherwise the residual holds model error.
- :func:`explained`: how much of the reference's residual an effect removes, per channel, in
  units of the sensor's noise RMS (the effect must remove at least MIN_EFFECT_SIZE of that on
  some channel to be named: statistically significant but well inside the noise is a model
  detail no autopilot needs, and a log's timing is never exact: a 15 ms "sensor delay" in
  closed-loop logs, real to the statistics, moved the heading by a third of its noise).
- :func:`away_from_null`: the joint z of an effect's parameters from their no-effect values
  (sqrt of the sum of z^2, against the 99.73 % point of chi with as many degrees of freedom:
  3 sigma for one parameter).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from autopilot.sysid.effects import BY_NAME, PARAM_BY_KEY
from autopilot.sysid.fit import Fit
from autopilot.sysid.noise import NoiseBounds, estimate, restricted_deviance
from autopilot.sysid.replay import (
    Noise,
    Prepared,
    channel_costs,
    predict,
    raw_residuals,
    residuals,
    rmse,
)

ADEQUATE_CHI2 = 1.3  # per channel and measurement
# the deviance a noise model free of the sensor's bounds may gain before the residual counts as more
# than noise: the 99.9 % point of chi-square with 3 degrees of freedom (the three noise parameters)
BEYOND_SENSOR_MAX = 16.3
MIN_EFFECT_SIZE = 0.5  # sensor noise RMS explained on some channel
AWAY_P = 0.9973  # "clearly away from no effect": the 3-sigma point


def predict_fit(prep: Prepared, vessel, fit: Fit) -> dict:
    n = len(fit.trials)
    values = {k: np.full(n, v) for k, v in fit.values().items()}
    return predict(prep, vessel, np.array(fit.trials), fit.x0, values)


def _series(prep: Prepared, vessel, fit: Fit) -> tuple[list, list]:
    """A fit's residual series of both channels for noise.restricted_deviance: per trial the position
    blocks (north, east) and the heading block, each with the residuals' sensitivities to the trial's
    fitted initial state (what the fit absorbed), by finite differences.

    The states are shared by the channels, and the heading (10 Hz, a tenth of a degree) pins the
    initial heading and yaw rate: those are the heading's design, not the position's. Left free in
    the position's too, the initial heading would absorb a rotated track there, which the fit could
    not do (a 14 deg heading bias scored as nothing)."""
    from autopilot.sysid.fit import FD_STATES, X0_FD, X0_SCALE

    n = len(fit.trials)
    x0s, tri = [fit.x0], [np.array(fit.trials)]
    for s in FD_STATES:
        xp = fit.x0.copy()
        xp[:, s] += X0_FD * X0_SCALE[s]
        x0s.append(xp)
        tri.append(np.array(fit.trials))
    values = {k: np.full(n * (1 + len(FD_STATES)), v) for k, v in fit.values().items()}
    pred = predict(prep, vessel, np.concatenate(tri), np.vstack(x0s), values)
    pos, hdg = [], []
    for j, i in enumerate(fit.trials):
        runs = [j + q * n for q in range(1 + len(FD_STATES))]
        rn, re, rh = raw_residuals(prep, i, pred, runs)
        if not (np.all(np.isfinite(rn)) and np.all(np.isfinite(rh))):
            continue
        m = prep.measured[i]
        d = [(x[1:] - x[0]).T / (X0_FD * X0_SCALE[list(FD_STATES)]) for x in (rn, re, rh)]  # (samples, states)
        zeros, ones = np.zeros(m.t_pos_s.size), np.ones(m.t_pos_s.size)
        u = list(FD_STATES).index(3)
        design = np.vstack([np.column_stack([ones, zeros, d[0][:, u]]), np.column_stack([zeros, ones, d[1][:, u]])])
        pos.append(([(m.t_pos_s, rn[0]), (m.t_pos_s, re[0])], _independent(design)))
        hdg.append(([(m.t_psi_s, rh[0])], _independent(d[2])))
    return pos, hdg


def _independent(design: np.ndarray) -> np.ndarray:
    """The design's columns that are not (nearly) combinations of the others (a yaw rate the fit can
    hardly see, a heading column equal to the offset)."""
    norm = np.linalg.norm(design, axis=0)
    cols = design[:, norm > 1e-9 * max(norm.max(), 1e-300)] / norm[norm > 1e-9 * max(norm.max(), 1e-300)]
    _, r, piv = __import__("scipy.linalg", fromlist=["qr"]).qr(cols, mode="economic", pivoting=True)
    keep = np.abs(np.diag(r)) > 1e-6 * abs(r[0, 0]) if r.size else np.zeros(0, bool)
    return cols[:, np.sort(piv[: int(keep.sum())])]


def model_noise(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> Noise:
    """The noise both channels would need to explain ``fit``'s residuals (inside ``bounds``)."""
    pos, hdg = _series(prep, vessel, fit)
    return Noise(estimate(pos, bounds.channel("position"), prep.noise.position, bounds.time_prior),
                 estimate(hdg, bounds.channel("heading"), prep.noise.heading, bounds.time_prior))


def beyond_sensor(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> dict:
    """Per channel: how much better a noise model free of the sensor's bounds explains ``fit``'s
    residuals (the drop of the restricted deviance, -2 log-likelihood, from the best noise inside
    the bounds to the best without them). Near zero when the residual is the sensor's noise; large
    when it holds what no sensor gives (metres of slow drift, degrees of heading error)."""
    out = {}
    for ch, series in zip(("position", "heading"), _series(prep, vessel, fit)):
        inside = estimate(series, bounds.channel(ch), getattr(prep.noise, ch), bounds.time_prior)
        (w_lo, w_hi), (g_lo, g_hi), (t_lo, t_hi) = bounds.channel(ch)
        free = ((w_lo, 100 * w_hi), (g_lo, 100 * g_hi), (t_lo, 100 * t_hi))
        outside = estimate(series, free, inside, bounds.time_prior)
        out[ch] = max(restricted_deviance(series, inside) - restricted_deviance(series, outside), 0.0)
    return out


class Scores:
    """Scores of fitted models for the choice (cached per fit): each model's own noise (REML inside
    the sensor's bounds) and its restricted deviance under it (noise.restricted_deviance: what the
    fitted initial states absorb is projected out); BIC differences add k ln m per parameter.

    Each model gets its own noise (the profile likelihood). Judged instead by the noise of the
    candidate under test, the baseline of calm closed-loop logs lost to a 20 % deadband and a 4 %
    thrust asymmetry (a candidate whose noise estimate happens to come out small makes every other
    model look worse); by one noise for all, a model missing an effect is judged by a noise that
    wanders by the effect's size. The price: an effect that looks like the sensor's own wander
    (a 0.2 m/s current over five 30-s pond logs against 1.5-2 m of GPS wander) scores little."""

    def __init__(self, prep: Prepared, vessel, bounds: NoiseBounds):
        self.prep, self.vessel, self.bounds = prep, vessel, bounds
        self._series: dict = {}
        self._noise: dict = {}

    @staticmethod
    def _key(fit: Fit):
        """What a score depends on: the model, its values and states (not the weighting's cost)."""
        return (fit.keys, np.asarray(fit.theta, float).tobytes(), np.asarray(fit.x0, float).tobytes(), fit.trials,
                tuple(sorted(fit.fixed.items())))

    def series(self, fit: Fit):
        key = self._key(fit)
        if key not in self._series:
            self._series[key] = _series(self.prep, self.vessel, fit)
        return self._series[key]

    def noise(self, fit: Fit) -> Noise:
        key = self._key(fit)
        if key not in self._noise:
            pos, hdg = self.series(fit)
            b = self.bounds
            self._noise[key] = Noise(estimate(pos, b.channel("position"), self.prep.noise.position, b.time_prior),
                                     estimate(hdg, b.channel("heading"), self.prep.noise.heading, b.time_prior))
        return self._noise[key]

    def deviance(self, fit: Fit, noise: Noise | None = None) -> float:
        noise = noise or self.noise(fit)
        pos, hdg = self.series(fit)
        return restricted_deviance(pos, noise.position) + restricted_deviance(hdg, noise.heading)

    def delta_bic(self, fit: Fit, ref: Fit) -> float:
        """BIC of ``fit`` minus ``ref``'s, each under its own noise (class docstring)."""
        extra = (fit.n_params - ref.n_params) * math.log(max(fit.n_obs, 2))
        return self.deviance(fit) - self.deviance(ref) + extra

    def __call__(self, fit: Fit) -> dict:
        return {"noise": self.noise(fit), "deviance": self.deviance(fit)}


def rescore(prep: Prepared, vessel, fit: Fit) -> Fit:
    """``fit`` with its cost recomputed under ``prep``'s noise model (same parameters and states)."""
    pred = predict_fit(prep, vessel, fit)
    cost = sum(float(np.sum(np.nan_to_num(residuals(prep, i, pred, [j])[0], nan=1e3) ** 2)) for j, i in enumerate(fit.trials))
    return dataclasses.replace(fit, cost=cost)


def channels(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds, *, adequate_chi2: float = ADEQUATE_CHI2,
             full: bool = True) -> dict:
    """Per channel: chi-square per measurement, residual RMS, the noise's share, adequacy (module
    docstring; with ``full``, also the test against a noise free of the sensor's bounds)."""
    pred = predict_fit(prep, vessel, fit)
    costs = channel_costs(prep, pred, fit.trials, range(len(fit.trials)))
    gap = rmse(prep, fit.trials, pred, range(len(fit.trials)))
    beyond = beyond_sensor(prep, vessel, fit, bounds) if full else {}
    out = {}
    for ch, unit in (("position", "m"), ("heading", "deg")):
        cost, count = costs[ch]
        c2 = cost / max(count, 1)
        ok = c2 <= adequate_chi2 and beyond.get(ch, 0.0) <= BEYOND_SENSOR_MAX
        out[ch] = {"chi2_per_measurement": c2, "measurements": count, "adequate": bool(ok),
                   f"residual_rms_{unit}": gap[f"{ch}_{unit}"], f"noise_rms_{unit}": gap[f"{ch}_noise_{unit}"],
                   f"beyond_noise_{unit}": gap[f"{ch}_model_{unit}"],
                   "deviance_beyond_sensor": beyond.get(ch)}
    return out


def noise_summary(noise: Noise) -> dict:
    p, h = noise.position, noise.heading
    return {"position": {"white_m": p.white, "wander_m": p.wander, "time_s": p.time_s, "rms_m": p.rms},
            "heading": {"white_deg": math.degrees(h.white), "wander_deg": math.degrees(h.wander), "time_s": h.time_s,
                        "rms_deg": math.degrees(h.rms)}}


def explained(prep: Prepared, vessel, ref: Fit, fit: Fit) -> dict:
    """Per channel the residual RMS ``fit`` removes from ``ref``'s, in units of the sensor's noise RMS
    (white and wander together, of ``prep``'s noise model; horizontal for the position)."""
    a = rmse(prep, ref.trials, predict_fit(prep, vessel, ref), range(len(ref.trials)))
    b = rmse(prep, fit.trials, predict_fit(prep, vessel, fit), range(len(fit.trials)))
    scale = {"position": math.sqrt(2.0) * prep.noise.position.rms, "heading": math.degrees(prep.noise.heading.rms)}
    out = {}
    for ch, unit in (("position", "m"), ("heading", "deg")):
        gone = math.sqrt(max(a[f"{ch}_{unit}"] ** 2 - b[f"{ch}_{unit}"] ** 2, 0.0))
        out[ch] = gone / max(scale[ch], 1e-9)
    return out


def away_from_null(fit: Fit, effect: str) -> tuple[float, float]:
    """(joint z of ``effect``'s parameters from their no-effect values, the 3-sigma limit for that many)."""
    from scipy.stats import chi2

    keys = BY_NAME[effect].keys
    z2 = 0.0
    for k in keys:
        s = float(fit.sigma[fit.keys.index(k)])
        d = float(fit.theta[fit.keys.index(k)]) - PARAM_BY_KEY[k].null
        z2 += (d / s) ** 2 if s > 0 and math.isfinite(s) else 0.0
    return math.sqrt(z2), math.sqrt(float(chi2.ppf(AWAY_P, len(keys))))


def is_away(fit: Fit, effect: str) -> bool:
    z, limit = away_from_null(fit, effect)
    return z >= limit
