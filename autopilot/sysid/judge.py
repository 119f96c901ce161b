"""What a fitted model is worth: its noise, whether it is adequate, how much an effect explains.

- :func:`model_noise`: the noise model (per channel) estimated from a fit's residuals
  (``noise.estimate``, restricted maximum likelihood inside the sensor's bounds).
- :func:`channels`: per channel (position, heading, velocity) the weighted chi-square per measurement
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

from autopilot.sysid.channels import CHANNELS, POSITION
from autopilot.sysid.effects import BY_NAME, PARAM_BY_KEY
from autopilot.sysid.fit import Fit
from autopilot.sysid.noise import NoiseBounds, estimate, restricted_deviance
from autopilot.sysid.prediction import (
    Noise,
    Prepared,
    channel_costs,
    channel_residuals,
    predict,
    rmse,
    trial_cost,
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


# the initial states whose sensitivities each channel's noise estimate projects out (besides the
# position's north and east offsets): the heading pins the heading and yaw rate, so those are the
# heading's; the speed is everyone's
OWN_STATES = {"position": (3,), "heading": None, "velocity": (3,)}  # None: every finite-differenced state


def _series(prep: Prepared, vessel, fit: Fit) -> dict:
    """A fit's residual series per channel for noise.restricted_deviance: per trial the channel's
    component blocks (north and east, or the heading), each with the residuals' sensitivities to the
    trial's fitted initial state (what the fit absorbed), by finite differences.

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
    steps = X0_FD * X0_SCALE[list(FD_STATES)]
    out = {c.name: [] for c in prep.channels}
    for j, i in enumerate(fit.trials):
        runs = [j + q * n for q in range(1 + len(FD_STATES))]
        res = {c: channel_residuals(prep, i, pred, runs, c) for c in prep.channels}
        if not all(np.all(np.isfinite(r)) for parts in res.values() for r in parts):
            continue
        for c, parts in res.items():
            if not parts or parts[0].shape[1] == 0:
                continue
            t = prep.measured[i].get(c.name).t_s
            d = [(x[1:] - x[0]).T / steps for x in parts]  # per component (samples, states)
            own = OWN_STATES[c.name]
            cols = list(range(len(FD_STATES))) if own is None else [FD_STATES.index(q) for q in own]
            if c is POSITION:  # the offsets are exact (translation invariance), the speed by difference
                zeros, ones = np.zeros(t.size), np.ones(t.size)
                design = np.vstack([np.column_stack([ones, zeros, d[0][:, cols]]),
                                    np.column_stack([zeros, ones, d[1][:, cols]])])
            else:
                design = np.vstack([dq[:, cols] for dq in d])
            out[c.name].append(([(t, x[0]) for x in parts], _independent(design)))
    return out


def _independent(design: np.ndarray) -> np.ndarray:
    """The design's columns that are not (nearly) combinations of the others (a yaw rate the fit can
    hardly see, a heading column equal to the offset)."""
    norm = np.linalg.norm(design, axis=0)
    cols = design[:, norm > 1e-9 * max(norm.max(), 1e-300)] / norm[norm > 1e-9 * max(norm.max(), 1e-300)]
    _, r, piv = __import__("scipy.linalg", fromlist=["qr"]).qr(cols, mode="economic", pivoting=True)
    keep = np.abs(np.diag(r)) > 1e-6 * abs(r[0, 0]) if r.size else np.zeros(0, bool)
    return cols[:, np.sort(piv[: int(keep.sum())])]


def _estimate(series: dict, prep: Prepared, bounds: NoiseBounds) -> Noise:
    """Each channel's noise (restricted maximum likelihood inside ``bounds``) from residual series."""
    return Noise(**{name: estimate(items, bounds.channel(name), prep.noise.of(name), bounds.prior(name))
                    for name, items in series.items()})


def model_noise(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> Noise:
    """The noise each channel would need to explain ``fit``'s residuals (inside ``bounds``)."""
    return _estimate(_series(prep, vessel, fit), prep, bounds)


def beyond_sensor(prep: Prepared, vessel, fit: Fit, bounds: NoiseBounds) -> dict:
    """Per channel: how much better a noise model free of the sensor's bounds explains ``fit``'s
    residuals (the drop of the restricted deviance, -2 log-likelihood, from the best noise inside
    the bounds to the best without them). Near zero when the residual is the sensor's noise; large
    when it holds what no sensor gives (metres of slow drift, degrees of heading error)."""
    out = {}
    for ch, series in _series(prep, vessel, fit).items():
        inside = estimate(series, bounds.channel(ch), prep.noise.of(ch), bounds.prior(ch))
        (w_lo, w_hi), (g_lo, g_hi), (t_lo, t_hi) = bounds.channel(ch)
        free = ((w_lo, 100 * w_hi), (g_lo, 100 * g_hi), (t_lo, 100 * t_hi))
        outside = estimate(series, free, inside, bounds.prior(ch))
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
            self._noise[key] = _estimate(self.series(fit), self.prep, self.bounds)
        return self._noise[key]

    def deviance(self, fit: Fit, noise: Noise | None = None) -> float:
        noise = noise or self.noise(fit)
        return sum(restricted_deviance(items, noise.of(ch)) for ch, items in self.series(fit).items())

    def delta_bic(self, fit: Fit, ref: Fit) -> float:
        """BIC of ``fit`` minus ``ref``'s, each under its own noise (class docstring)."""
        extra = (fit.n_params - ref.n_params) * math.log(max(fit.n_obs, 2))
        return self.deviance(fit) - self.deviance(ref) + extra

    def __call__(self, fit: Fit) -> dict:
        return {"noise": self.noise(fit), "deviance": self.deviance(fit)}


def rescore(prep: Prepared, vessel, fit: Fit) -> Fit:
    """``fit`` with its cost recomputed under ``prep``'s noise model (same parameters and states)."""
    pred = predict_fit(prep, vessel, fit)
    cost = sum(trial_cost(prep, i, pred, j) for j, i in enumerate(fit.trials))
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
    for c in prep.channels:
        cost, count = costs[c.name]
        c2 = cost / max(count, 1)
        past_bounds = beyond.get(c.name, 0.0) > BEYOND_SENSOR_MAX
        ok = c2 <= adequate_chi2 and not past_bounds
        k = c.key_unit
        out[c.name] = {"chi2_per_measurement": c2, "measurements": count, "adequate": bool(ok),
                       f"residual_rms_{k}": gap[f"{c.name}_{k}"], f"noise_rms_{k}": gap[f"{c.name}_noise_{k}"],
                       f"beyond_noise_{k}": gap[f"{c.name}_model_{k}"],
                       "deviance_beyond_sensor": beyond.get(c.name),
                       # why, in words, when the chi-square alone would have passed (the terminal said only
                       # "chi-square 0.843: NOT adequate")
                       "why_not": (f"the noise model absorbs the residual only past the sensor's bounds: deviance "
                                   f"{beyond[c.name]:.3g} beyond them, {BEYOND_SENSOR_MAX:g} allowed")
                       if past_bounds and c2 <= adequate_chi2 else None}
    return out


def noise_summary(noise: Noise) -> dict:
    """Each channel's noise model in its shown unit (white, wander, its correlation time, the RMS of both)."""
    out = {}
    for c in CHANNELS:
        n = noise.of(c.name)
        if n is not None:
            k = c.key_unit
            out[c.name] = {f"white_{k}": c.shown(n.white), f"wander_{k}": c.shown(n.wander), "time_s": n.time_s,
                           f"rms_{k}": c.shown(n.rms)}
    return out


def explained(prep: Prepared, vessel, ref: Fit, fit: Fit) -> dict:
    """Per channel the residual RMS ``fit`` removes from ``ref``'s, in units of the sensor's noise RMS
    (white and wander together, of ``prep``'s noise model; horizontal for position and velocity)."""
    a = rmse(prep, ref.trials, predict_fit(prep, vessel, ref), range(len(ref.trials)))
    b = rmse(prep, fit.trials, predict_fit(prep, vessel, fit), range(len(fit.trials)))
    out = {}
    for c in prep.channels:
        key = f"{c.name}_{c.key_unit}"
        scale = c.shown(prep.noise.of(c.name).rms) * (math.sqrt(2.0) if c.horizontal else 1.0)
        gone = math.sqrt(max(a[key] ** 2 - b[key] ** 2, 0.0))
        out[c.name] = gone / max(scale, 1e-9)
    return out


AT_BOUND = 0.97  # an estimate this close to its largest allowed value sits at the bound
# ... and the bound holds it back when freeing it gains this much deviance (chi-square, 1 degree of freedom,
# 95 %): the data ask for more noise than a sensor has. An estimate at the bound that gains nothing sits on a
# flat likelihood (a wander the fitted initial states absorb in short logs), which says nothing of the model.
BOUND_BINDING = 3.84


def at_bounds(noise: Noise, bounds: NoiseBounds, adequacy: dict | None = None) -> list[str]:
    """The channels whose noise estimate sits at the largest a sensor may have (white or wander part) and,
    given ``adequacy``, would grow past it (its deviance_beyond_sensor), as sentences: there the residual may
    hold a model error of the noise's size that the data cannot tell from noise (one short log, a current
    against metres of GPS wander). Without ``adequacy``: every part at its bound, binding or not."""
    out = []
    for c in CHANNELS:
        n = noise.of(c.name)
        if n is None or (adequacy is not None
                         and (adequacy.get(c.name, {}).get("deviance_beyond_sensor") or 0.0) < BOUND_BINDING):
            continue
        (_, w_hi), (_, g_hi), _ = bounds.channel(c.name)
        for part, value, hi in (("white", n.white, w_hi), ("wander", n.wander, g_hi)):
            if value >= AT_BOUND * hi:
                out.append(f"the {c.name} noise's {part} part is at its bound ({c.shown(value):.3g} of "
                           f"{c.shown(hi):.3g} {c.unit})")
    return out


def binding(adequacy: dict) -> dict[str, float]:
    """Channel -> the deviance freeing its noise from the sensor's bounds would gain, for each where that is at least
    BOUND_BINDING: the residual asks for more noise than the sensor has, whichever part holds it back (at_bounds
    names only a white or wander part within AT_BOUND of its limit: a wander at 0.953 of its 1-deg bound, the
    correlation time held too, gained 5.2 and was named nowhere, a sysid audit)."""
    return {ch: float(c["deviance_beyond_sensor"]) for ch, c in adequacy.items()
            if (c.get("deviance_beyond_sensor") or 0.0) >= BOUND_BINDING}


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
