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
  units of the residual the noise alone would leave (the effect must remove at least
  MIN_EFFECT_SIZE of that on some channel to be named: statistically significant but smaller
  than the noise is a model detail no autopilot needs, and the noise model is never exact).
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
from autopilot.sysid.replay import Noise, Prepared, channel_costs, predict, raw_residuals, residuals, rmse

ADEQUATE_CHI2 = 1.3  # per channel and measurement
# the deviance a noise model free of the sensor's bounds may gain before the residual counts as more
# than noise: the 99.9 % point of chi-square with 3 degrees of freedom (the three noise parameters)
BEYOND_SENSOR_MAX = 16.3
MIN_EFFECT_SIZE = 1.0  # noise RMS explained on some channel
AWAY_P = 0.9973  # "clearly away from no effect": the 3-sigma point


def predict_fit(prep: Prepared, vessel, fit: Fit) -> dict:
    n = len(fit.trials)
    values = {k: np.full(n, v) for k, v in fit.values().items()}
    return predict(prep, vessel, np.array(fit.trials), fit.x0, values)


def _series(prep: Prepared, vessel, fit: Fit) -> tuple[list, list]:
    """A fit's residual series ((t_s, r) per trial and axis, mean removed) of both channels."""
    pred = predict_fit(prep, vessel, fit)
    pos, hdg = [], []
    for j, i in enumerate(fit.trials):
        rn, re, rh = raw_residuals(prep, i, pred, [j])
        m = prep.measured[i]
        if not (np.all(np.isfinite(rn)) and np.all(np.isfinite(rh))):
            continue
        pos += [(m.t_pos_s, rn[0] - rn[0].mean()), (m.t_pos_s, re[0] - re[0].mean())]
        hdg.append((m.t_psi_s, rh[0] - rh[0].mean()))
    return pos, hdg


def model_noise(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> Noise:
    """The noise both channels would need to explain ``fit``'s residuals (inside ``bounds``)."""
    pos, hdg = _series(prep, vessel, fit)
    return Noise(estimate(pos, bounds.channel("position"), prep.noise.position),
                 estimate(hdg, bounds.channel("heading"), prep.noise.heading))


def beyond_sensor(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> dict:
    """Per channel: how much better a noise model free of the sensor's bounds explains ``fit``'s
    residuals (the drop of the restricted deviance, -2 log-likelihood, from the best noise inside
    the bounds to the best without them). Near zero when the residual is the sensor's noise; large
    when it holds what no sensor gives (metres of slow drift, degrees of heading error)."""
    out = {}
    for ch, series in zip(("position", "heading"), _series(prep, vessel, fit)):
        inside = estimate(series, bounds.channel(ch), getattr(prep.noise, ch))
        (w_lo, w_hi), (g_lo, g_hi), (t_lo, t_hi) = bounds.channel(ch)
        free = ((w_lo, 100 * w_hi), (g_lo, 100 * g_hi), (t_lo, 100 * t_hi))
        outside = estimate(series, free, inside)
        out[ch] = max(restricted_deviance(series, inside) - restricted_deviance(series, outside), 0.0)
    return out


class Scores:
    """The profile score of fitted models (cached per fit): each channel's restricted deviance
    (-2 log-likelihood, noise.restricted_deviance) under the noise that channel needs for that model
    (REML inside the sensor's bounds), summed, plus k ln m for the model's parameters (BIC).

    Each model gets its own noise: under one noise for all, a model missing an effect is judged by
    a noise that wanders by the effect's size (a 0.2 m/s current in five pond logs: the baseline's
    GPS wander came out at the 3 m bound, and the current lost to a wind force)."""

    def __init__(self, prep: Prepared, vessel, bounds: NoiseBounds):
        self.prep, self.vessel, self.bounds = prep, vessel, bounds
        self._cache: dict = {}

    @staticmethod
    def _key(fit: Fit):
        """What the score depends on: the model, its values and states (not the weighting's cost)."""
        return (fit.keys, np.asarray(fit.theta, float).tobytes(), np.asarray(fit.x0, float).tobytes(), fit.trials,
                tuple(sorted(fit.fixed.items())))

    def __call__(self, fit: Fit) -> dict:
        key = self._key(fit)
        if key in self._cache:
            return self._cache[key]
        pos, hdg = _series(self.prep, self.vessel, fit)
        noise = Noise(estimate(pos, self.bounds.channel("position"), self.prep.noise.position),
                      estimate(hdg, self.bounds.channel("heading"), self.prep.noise.heading))
        dev = {"position": restricted_deviance(pos, noise.position), "heading": restricted_deviance(hdg, noise.heading)}
        out = {"noise": noise, "deviance": dev, "bic": sum(dev.values()) + fit.n_params * math.log(max(fit.n_obs, 2))}
        self._cache[key] = out
        return out

    def bic(self, fit: Fit) -> float:
        return self(fit)["bic"]


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
    """Per channel the residual RMS ``fit`` removes from ``ref``'s, in units of the RMS the noise alone
    would leave (replay.rmse's ``*_noise_*``: the noise model's residual once the initial states took
    their share)."""
    a = rmse(prep, ref.trials, predict_fit(prep, vessel, ref), range(len(ref.trials)))
    b = rmse(prep, fit.trials, predict_fit(prep, vessel, fit), range(len(fit.trials)))
    out = {}
    for ch, unit in (("position", "m"), ("heading", "deg")):
        gone = math.sqrt(max(a[f"{ch}_{unit}"] ** 2 - b[f"{ch}_{unit}"] ** 2, 0.0))
        out[ch] = gone / max(a[f"{ch}_noise_{unit}"], 1e-9)
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
