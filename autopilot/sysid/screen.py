"""Screening: a few batched Gauss-Newton steps of every candidate from a fit, to rank them and start them.

Each step solves the linearised problem [J_x0 | J_effect] (the initial-state columns are the
base fit's); a step that raises the actual cost is halved. All candidates (and their grid starts)
go through one batched replay per step. One linear step misranks large effects (30 deg heading
errors are far from linear), hence several.
"""

from __future__ import annotations

import itertools

import numpy as np

from autopilot.sim import VesselParams
from autopilot.sysid.effects import BY_NAME, PARAM_BY_KEY
from autopilot.sysid.fit import (
    DIVERGED,
    FREE_STATES,
    GN_MAX_STEP,
    X0_LIMIT,
    X0_SCALE,
    Fit,
    Problem,
    theta_bounds,
)
from autopilot.sysid.prediction import Prepared, predict, residuals


def screen(prep: Prepared, vessel: VesselParams, base: Fit, candidates, *, iterations: int = 3) -> dict[str, dict]:
    """Per candidate: the lowest actual cost met (``predicted_cost``, used for ranking), ``base_cost``
    (``base`` on the same trials) and its parameters and states as a start (module docstring)."""
    candidates = [c for c in candidates if c not in base.effects]
    if not candidates:
        return {}
    prob = Problem(prep, vessel, base.keys, base.trials, base.x0, fixed=base.fixed)
    z_base = prob.pack(base.theta, base.x0)
    base_cost = float(np.sum(prob.fun(z_base) ** 2))
    jac = prob.jac(z_base)
    # the base's own parameters move with the candidate's (their columns at the base, as the states'): a second
    # effect that the first absorbed in part pays only once the first gives it back (a weak starboard motor in
    # wind: the wind fitted alone bent 0.7 m/s to carry the motor's moment; with the wind held there, the motor
    # screened at no gain and the pair was never fitted; moved together, the pair went to the truth)
    j_lead, j_x0 = jac[:, : len(base.keys)], jac[:, len(base.keys) :]
    lead = dict(zip(base.keys, base.theta))
    state = {(c, g): {"theta": {**lead, **start}, "x0": base.x0.copy(), "cost": np.inf, "prev": None,
                      "best": (np.inf, {**lead, **start}, base.x0.copy())}
             for c in candidates for g, start in enumerate(_starts(BY_NAME[c]))}
    for _ in range(iterations + 1):
        resid = _batch_residuals(prep, vessel, base, state)
        for key, st in state.items():
            _step(st, BY_NAME[key[0]], resid, key, j_lead, base.keys, j_x0, vessel, len(base.trials))
    out = {}
    for (c, g), st in state.items():
        cost, theta, x0 = st["best"]
        if c not in out or cost < out[c]["predicted_cost"]:
            out[c] = {"predicted_cost": cost, "base_cost": base_cost, "theta": [theta[k] for k in BY_NAME[c].keys],
                      "lead_theta": [theta[k] for k in base.keys], "x0": x0}
    return out


def _batch_residuals(prep, vessel, base: Fit, state: dict) -> dict:
    """Weighted residuals of every state's current point and of its parameter perturbations, one replay."""
    n = len(base.trials)
    base_values = base.values()
    runs_vals, runs_x0, meta = [], [], []
    for key, st in state.items():
        runs_vals.append(dict(st["theta"]))
        runs_x0.append(st["x0"])
        meta.append((key, None))
        for k in BY_NAME[key[0]].keys:
            v = dict(st["theta"])
            v[k] += PARAM_BY_KEY[k].fd_step * PARAM_BY_KEY[k].scale
            runs_vals.append(v)
            runs_x0.append(st["x0"])
            meta.append((key, k))
    all_keys = sorted({k for v in runs_vals for k in v} | set(base_values))
    values = {k: np.repeat([v.get(k, base_values.get(k, PARAM_BY_KEY[k].null)) for v in runs_vals], n) for k in all_keys}
    pred = predict(prep, vessel, np.tile(np.array(base.trials), len(runs_vals)), np.vstack(runs_x0), values)
    resid = {}
    for q, mk in enumerate(meta):
        r = np.concatenate([residuals(prep, i, pred, [j])[0] for i, j in zip(base.trials, range(q * n, (q + 1) * n))])
        resid[mk] = np.where(np.isfinite(r), r, DIVERGED)
    return resid


def _step(st: dict, eff, resid: dict, key, j_lead, lead_keys, j_x0, vessel, n: int) -> None:
    """One Gauss-Newton step of one candidate's start and the base's parameters (halved back after an overshoot)."""
    free = list(FREE_STATES)
    r0 = resid[(key, None)]
    cost = float(np.sum(r0**2))
    if cost < st["best"][0]:
        st["best"] = (cost, dict(st["theta"]), st["x0"].copy())
    if st["prev"] is not None and cost > st["cost"]:  # overshoot: back half way
        p_theta, p_x0 = st["prev"]
        st["theta"] = {k: 0.5 * (st["theta"][k] + p_theta[k]) for k in st["theta"]}
        st["x0"] = 0.5 * (st["x0"] + p_x0)
        return
    st["cost"] = cost
    cols = [(resid[(key, k)] - r0) / PARAM_BY_KEY[k].fd_step for k in eff.keys]
    step, *_ = np.linalg.lstsq(np.column_stack([j_x0, j_lead] + cols), -r0, rcond=None)
    st["prev"] = (dict(st["theta"]), st["x0"].copy())
    for k, d in zip((*lead_keys, *eff.keys), step[j_x0.shape[1] :]):
        lo, hi = theta_bounds(k, vessel)
        d = float(np.clip(d, -GN_MAX_STEP, GN_MAX_STEP))  # a linearisation is not trusted far out
        st["theta"][k] = float(np.clip(st["theta"][k] + d * PARAM_BY_KEY[k].scale, lo, hi))
    x0 = st["x0"].copy()
    x0[:, free] += step[: j_x0.shape[1]].reshape(n, len(free)) * X0_SCALE[free]
    st["x0"] = np.clip(x0, -X0_LIMIT, X0_LIMIT)


def _starts(eff) -> list[dict]:
    """Screening starts of an effect: its start values, and a grid where the parameter has one."""
    grids = [PARAM_BY_KEY[k].grid or (PARAM_BY_KEY[k].start,) for k in eff.keys]
    return [dict(zip(eff.keys, combo)) for combo in itertools.product(*grids)]
