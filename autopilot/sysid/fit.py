"""Output-error least squares of effect parameters with per-trial initial states.

The unknowns are the effect parameters (shared by all trials) and each
trial's initial state (a nuisance: a noisy start would otherwise bias every
effect). Residuals are measured minus predicted position and heading at the
measurement times, weighted through the noise model (``noise.Whitener``:
wandering + white, the generalised least-squares cost r' S^-1 r), so the cost
is a chi-square over the m measurements and the 95 % intervals come from the
Jacobian: cov = s^2 (J^T J)^-1, s^2 = max(cost / (m - n), 1) (never narrower
than the noise model says).

The Jacobian is a batched finite difference: the initial state of trial i
only moves trial i, so one ``simulate`` call with N (1 + 4 + p) runs gives
all columns; north/east offsets are analytic (the model is translation
invariant).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.sim import VesselParams
from autopilot.sysid.effects import BY_NAME, PARAM_BY_KEY, Z_95
from autopilot.sysid.effects import bounds as effect_bounds
from autopilot.sysid.prediction import Prepared, predict, residuals

# scales of the nuisance initial state (north, east, psi, u, v, r) and their FD steps (scaled units)
X0_SCALE = np.array([1.0, 1.0, 0.05, 0.1, 0.05, 0.02])
X0_FD = 1e-3
# psi, u, r by finite difference; north, east analytic. Sway v0 is held at its start value:
# the strong sway damping (SPEC 3) erases it within a second, so it is not identifiable
# from a track and leaving it free only makes the problem ill-conditioned.
FD_STATES = (2, 3, 5)
FREE_STATES = (0, 1, 2, 3, 5)
X0_LIMIT = np.array([np.inf, np.inf, np.inf, 6.0, 3.0, 1.5])  # |u|, |v| (m/s), |r| (rad/s) a WAM-V can have
GN_MAX_STEP = 20.0  # largest screening step, in units of the parameter's scale
DIVERGED = 1e3  # residual of every sample when a trial step makes the simulation blow up


def theta_bounds(key: str, vessel: VesselParams) -> tuple[float, float]:
    """Bounds of an effect parameter (its effect's ``bounds`` hook: the updated VesselParams stays in range)."""
    return effect_bounds(key, vessel)


@dataclass
class Fit:
    """A fitted model: effect parameters, per-trial initial states, cost and intervals."""

    effects: tuple[str, ...]
    keys: tuple[str, ...]
    theta: np.ndarray  # effect parameter values (SI, as in effects.py)
    sigma: np.ndarray  # 1-sigma of theta (NaN when not identifiable)
    x0: np.ndarray  # (len(trials), 6)
    trials: tuple[int, ...]
    cost: float  # weighted sum of squared residuals (chi-square)
    n_obs: int  # measurements (the weighted rows may be more: noise.Whitener)
    nfev: int = 0
    fixed: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.keys) + len(FREE_STATES) * len(self.trials)

    @property
    def bic(self) -> float:
        return self.cost + self.n_params * math.log(max(self.n_obs, 2))

    @property
    def aic(self) -> float:
        return self.cost + 2.0 * self.n_params

    def values(self) -> dict[str, float]:
        out = dict(self.fixed)
        out.update({k: float(v) for k, v in zip(self.keys, self.theta)})
        return out

    def ci95(self) -> dict[str, tuple[float, float]]:
        return {k: (float(v - Z_95 * s), float(v + Z_95 * s)) for k, v, s in zip(self.keys, self.theta, self.sigma)}


class Problem:
    """Residuals and batched Jacobian of one model over a set of trials."""

    def __init__(self, prep: Prepared, vessel: VesselParams, keys, trials, x0, *, fixed=None):
        self.prep, self.vessel = prep, vessel
        self.x0_start = np.array(x0, dtype=float).reshape(len(trials), 6)
        self.keys = tuple(keys)
        self.trials = tuple(trials)
        self.fixed = dict(fixed or {})
        self.scale = np.array([PARAM_BY_KEY[k].scale for k in self.keys])
        self.fd = np.array([PARAM_BY_KEY[k].fd_step for k in self.keys])
        self.sizes = [prep.n_rows(i) for i in self.trials]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)])
        self.n_obs = int(sum(prep.n_measurements(i) for i in self.trials))
        # d(weighted residual) / d(north offset): the weighted -1 of every position (the model is
        # translation invariant), the same for east
        self.pos_ones = [prep.pos_weights[i].apply(-np.ones(prep.measured[i].t_pos_s.size)) for i in self.trials]
        self.nfev = 0

    @property
    def p(self) -> int:
        return len(self.keys)

    def split(self, z):
        theta = z[: self.p] * self.scale
        x0 = self.x0_start.copy()
        x0[:, FREE_STATES] = z[self.p :].reshape(len(self.trials), len(FREE_STATES)) * X0_SCALE[list(FREE_STATES)]
        return theta, x0

    def bounds(self):
        lo = [theta_bounds(k, self.vessel)[0] / s for k, s in zip(self.keys, self.scale)]
        hi = [theta_bounds(k, self.vessel)[1] / s for k, s in zip(self.keys, self.scale)]
        free = list(FREE_STATES)
        lim = np.tile(X0_LIMIT[free] / X0_SCALE[free], len(self.trials))
        return np.concatenate([lo, -lim]), np.concatenate([hi, lim])

    def pack(self, theta, x0) -> np.ndarray:
        return np.concatenate([np.asarray(theta, float) / self.scale, (np.asarray(x0)[:, FREE_STATES] / X0_SCALE[list(FREE_STATES)]).ravel()])

    def _runs(self, thetas, x0s, tri):
        """Simulate runs: thetas (R, p), x0s (R, 6), trial indices (R,)."""
        values = dict(self.fixed)
        for k, key in enumerate(self.keys):
            values[key] = thetas[:, k]
        self.nfev += 1
        with np.errstate(all="ignore"):
            return predict(self.prep, self.vessel, tri, x0s, values)

    def residual_vector(self, pred, runs) -> np.ndarray:
        r = np.concatenate([residuals(self.prep, i, pred, [j])[0] for i, j in zip(self.trials, runs)])
        return np.where(np.isfinite(r), r, DIVERGED)

    def fun(self, z) -> np.ndarray:
        theta, x0 = self.split(z)
        n = len(self.trials)
        try:
            pred = self._runs(np.tile(theta, (n, 1)), x0, np.array(self.trials))
        except FloatingPointError:  # a trust-region step too far: tell the solver it is bad
            return np.full(int(self.offsets[-1]), DIVERGED)
        return self.residual_vector(pred, range(n))

    def jac(self, z, *, with_theta: bool = True, extra: dict | None = None) -> np.ndarray:
        """Jacobian d(residual)/dz by batched forward differences (extra: key -> step columns)."""
        theta, x0 = self.split(z)
        n = len(self.trials)
        tri = np.array(self.trials)
        thetas, x0s, trials = [np.tile(theta, (n, 1))], [x0], [tri]
        for s in FD_STATES:  # one perturbed run per trial and state
            xp = x0.copy()
            xp[:, s] += X0_FD * X0_SCALE[s]
            thetas.append(np.tile(theta, (n, 1)))
            x0s.append(xp)
            trials.append(tri)
        cols = range(self.p) if with_theta else ()
        for k in cols:
            tp = theta.copy()
            tp[k] += self.fd[k] * self.scale[k]
            thetas.append(np.tile(tp, (n, 1)))
            x0s.append(x0)
            trials.append(tri)
        pred = self._runs(np.vstack(thetas), np.vstack(x0s), np.concatenate(trials))
        base = self.residual_vector(pred, range(n))
        m = base.size
        nf = len(FREE_STATES)
        n_cols = (self.p if with_theta else 0) + nf * n
        jac = np.zeros((m, n_cols))
        col0 = self.p if with_theta else 0
        for t_pos, i in enumerate(self.trials):
            lo, hi = self.offsets[t_pos], self.offsets[t_pos + 1]
            rows_p = self.prep.pos_weights[i].rows
            c = col0 + nf * t_pos
            jac[lo : lo + rows_p, c] = X0_SCALE[0] * self.pos_ones[t_pos]
            jac[lo + rows_p : lo + 2 * rows_p, c + 1] = X0_SCALE[1] * self.pos_ones[t_pos]
            fd_runs = [(q + 1) * n + t_pos for q in range(len(FD_STATES))]
            r = residuals(self.prep, i, pred, fd_runs)
            r = np.where(np.isfinite(r), r, DIVERGED)
            for q, s in enumerate(FD_STATES):
                jac[lo:hi, c + FREE_STATES.index(s)] = (r[q] - base[lo:hi]) / X0_FD
        for k in cols:
            runs = range((1 + len(FD_STATES) + k) * n, (2 + len(FD_STATES) + k) * n)
            r = self.residual_vector(pred, runs)
            jac[:, k] = (r - base) / self.fd[k]
        return jac


def fit_model(
    prep: Prepared,
    vessel: VesselParams,
    effects,
    trials,
    x0,
    *,
    theta0=None,
    fixed: dict | None = None,
    max_nfev: int = 40,
    horizons_s=(),
    free_through_horizons: bool = False,
) -> Fit:
    """Least squares (scipy trf) of the effects' parameters and the trials' initial states.

    ``horizons_s``: first fit the first seconds of every trial, growing the horizon
    (e.g. 10 s, 30 s), then all of it. An output-error fit of a long trial from a
    poor start falls into local minima (a wrong initial yaw rate turns the whole
    track); short horizons are nearly linear and lead it to the right basin.
    Given values (``theta0``) are held there and only the states fit; without
    ``theta0`` the parameters fit from their starts through the horizons too, and
    with ``free_through_horizons`` from ``theta0`` (a multimodal effect's grid
    start: search.from_each_start).
    """
    keys = tuple(k for e in effects for k in BY_NAME[e].keys)
    trials = tuple(trials)
    x0 = np.asarray(x0, dtype=float)
    if not keys and len(trials) > 1:  # states only: the trials are separate problems
        return _fit_states_apart(prep, vessel, effects, trials, x0, fixed=fixed, max_nfev=max_nfev, horizons_s=horizons_s)
    if keys and theta0 is not None and len(theta0) != len(keys):
        raise ValueError(f"theta0 has {len(theta0)} values for {len(keys)} parameters {keys}")
    if horizons_s:
        x0, theta0 = _through_horizons(prep, vessel, effects, keys, trials, x0, theta0, fixed, horizons_s,
                                       free=free_through_horizons)
    return _solve(prep, vessel, effects, keys, trials, x0, theta0, fixed, max_nfev)


def _cost(prep, vessel, keys, trials, x0, theta, fixed) -> float:
    probe = Problem(prep, vessel, keys, trials, x0, fixed=fixed)
    return float(np.sum(probe.fun(probe.pack(theta, x0)) ** 2))


def _through_horizons(prep, vessel, effects, keys, trials, x0, theta0, fixed, horizons_s, *, free: bool = False):
    """(states, values) to start the whole fit from: fitted through growing horizons, kept only when they
    fit the whole trials better than the given start, and never worse than "no effect" from the given
    states. Given values are held through the horizons (only the states fit): a short horizon may hold
    nothing that fixes a parameter, which then drifts onto a flat stretch it cannot leave (a 23.0 %
    deadband started at its true value went to 29 % at chi-square 1.13 for 0.93, seed 1008). With ``free`` the
    given values are where the parameters start, and they fit through the horizons too."""
    held = bool(keys) and theta0 is not None and not free
    hold = dict(fixed or {}) | (dict(zip(keys, (float(v) for v in theta0))) if held else {})
    x0_h, theta_h = x0, theta0
    for h in horizons_s:
        if h >= prep.t_grid[-1] * 0.8:
            break
        f = fit_model(prep.subset(trials, h), vessel, () if held else effects, tuple(range(len(trials))), x0_h,
                      theta0=None if held else theta_h, fixed=hold, max_nfev=15)
        x0_h, theta_h = f.x0, (list(f.theta) if keys and not held else theta_h)
    starts = [PARAM_BY_KEY[k].start for k in keys]
    c_start = _cost(prep, vessel, keys, trials, x0, starts if theta0 is None else theta0, fixed)
    c_hor = _cost(prep, vessel, keys, trials, x0_h, starts if theta_h is None else theta_h, fixed)
    best_x0, best_theta, best = (x0_h, theta_h, c_hor) if c_hor <= c_start else (x0, theta0, c_start)
    if keys:
        null = [PARAM_BY_KEY[k].null for k in keys]
        if _cost(prep, vessel, keys, trials, x0, null, fixed) < best:
            return x0, null
    return best_x0, best_theta


def _solve(prep, vessel, effects, keys, trials, x0, theta0, fixed, max_nfev) -> Fit:
    """The trust-region least squares from (x0, theta0), with the curvature intervals."""
    from scipy.optimize import least_squares

    prob = Problem(prep, vessel, keys, trials, x0, fixed=fixed)
    if theta0 is None:
        theta0 = [PARAM_BY_KEY[k].start for k in keys]
    lo, hi = prob.bounds()
    z0 = np.clip(prob.pack(theta0, x0), lo * 0.999, hi * 0.999)
    p = len(keys)
    if p:  # strictly inside the bounds (trf requires it)
        pad = 1e-9 * (np.abs(lo[:p]) + np.abs(hi[:p]) + 1.0)
        z0[:p] = np.clip(z0[:p], lo[:p] + pad, hi[:p] - pad)
    # lsmr: no SVD of the tall Jacobian (multi-threaded BLAS SVDs crawl on a busy machine)
    sol = least_squares(prob.fun, z0, jac=prob.jac, bounds=(lo, hi), method="trf", x_scale=1.0, tr_solver="lsmr",
                        ftol=3e-5, xtol=1e-6, gtol=1e-8, max_nfev=max_nfev)
    theta, x0_fit = prob.split(sol.x)
    cost = float(np.sum(sol.fun**2))
    m = prob.n_obs
    sigma = np.full(p, np.nan)
    if p:
        dof = max(m - sol.jac.shape[1], 1)
        try:
            cov = np.linalg.pinv(sol.jac.T @ sol.jac) * max(cost / dof, 1.0)
            sigma = np.sqrt(np.maximum(np.diag(cov)[:p], 0.0)) * prob.scale
        except np.linalg.LinAlgError:
            pass
    return Fit(tuple(effects), keys, theta, sigma, x0_fit, tuple(trials), cost, m, prob.nfev, dict(fixed or {}))


def _fit_states_apart(prep, vessel, effects, trials, x0, *, fixed, max_nfev, horizons_s) -> Fit:
    """Only initial states to fit (no effect, or effects held fixed): each trial on its own, exactly the
    joint problem's solution but not stalled by the others (a joint trust region, one radius for all,
    stopped one trial of five 6.5 deg off, a basin it left when fitted alone; its error then made a
    wind force "fit"). Also faster: four runs a trial stay on the simulator's scalar path."""
    parts = [fit_model(prep, vessel, effects, (i,), x0[[k]], fixed=fixed, max_nfev=max_nfev, horizons_s=horizons_s)
             for k, i in enumerate(trials)]
    return Fit(tuple(effects), (), np.zeros(0), np.zeros(0), np.vstack([f.x0 for f in parts]), tuple(trials),
               float(sum(f.cost for f in parts)), int(sum(f.n_obs for f in parts)), int(sum(f.nfev for f in parts)),
               dict(fixed or {}))
