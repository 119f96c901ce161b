"""Fixed-step fourth-order Runge-Kutta integration of the model (file 003 and thesis use RK4).

``simulate`` integrates one run with Python floats (a tight scalar loop is the
fastest way to push a 6-state model through numpy-free arithmetic) and a batch
of runs with numpy arrays over the runs; both call the same right-hand side.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import numpy as np

from autopilot.sim.environment import CALM, Environment
from autopilot.sim.model import make_rhs
from autopilot.sim.params import VesselParams

STATE_NAMES = ("north_m", "east_m", "psi_rad", "u_m_s", "v_m_s", "r_rad_s")


def _rk4(rhs, t, h, x, tp, ts):
    """One RK4 step of the 6 states ``x`` (a tuple of floats or arrays)."""
    n, e, psi, u, v, r = x
    k1 = rhs(t, n, e, psi, u, v, r, tp, ts)
    h2 = 0.5 * h
    k2 = rhs(t + h2, n + h2 * k1[0], e + h2 * k1[1], psi + h2 * k1[2], u + h2 * k1[3], v + h2 * k1[4], r + h2 * k1[5], tp, ts)
    k3 = rhs(t + h2, n + h2 * k2[0], e + h2 * k2[1], psi + h2 * k2[2], u + h2 * k2[3], v + h2 * k2[4], r + h2 * k2[5], tp, ts)
    k4 = rhs(t + h, n + h * k3[0], e + h * k3[1], psi + h * k3[2], u + h * k3[3], v + h * k3[4], r + h * k3[5], tp, ts)
    h6 = h / 6.0
    return (
        n + h6 * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
        e + h6 * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
        psi + h6 * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]),
        u + h6 * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3]),
        v + h6 * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4]),
        r + h6 * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5]),
    )


def _environment(current, wind, env: Environment | None) -> Environment:
    if env is not None:
        return env
    if current is None and wind is None:
        return CALM
    c_speed, c_towards = current if current is not None else (0.0, 0.0)
    w_speed, w_from = wind if wind is not None else (0.0, 0.0)
    return Environment(
        current_speed_m_s=float(c_speed),
        current_towards_deg=float(c_towards),
        wind_speed_m_s=float(w_speed),
        wind_from_deg=float(w_from),
    )


def step(
    params: VesselParams,
    state,
    thrust_port_n,
    thrust_stbd_n,
    dt_s: float,
    *,
    t_s: float = 0.0,
    env: Environment | None = None,
    external_force: Callable | None = None,
) -> np.ndarray:
    """Advance ``state`` ((6,) or (n_runs, 6)) by one RK4 step of ``dt_s`` with constant thrust."""
    x = np.asarray(state, dtype=float)
    batched = x.ndim == 2
    rhs = make_rhs(params, env or CALM, external_force, batched)
    if batched:
        cols = tuple(x[:, k] for k in range(6))
        tp = np.broadcast_to(np.asarray(thrust_port_n, dtype=float), cols[0].shape)
        ts = np.broadcast_to(np.asarray(thrust_stbd_n, dtype=float), cols[0].shape)
    else:
        cols = tuple(float(c) for c in x)
        tp, ts = float(thrust_port_n), float(thrust_stbd_n)
    out = _rk4(rhs, float(t_s), float(dt_s), cols, tp, ts)
    return np.stack(out, axis=-1) if batched else np.array(out)


def rk4_step(rhs, state_cols, thrust_port_n, thrust_stbd_n, dt_s: float, *, t_s: float = 0.0) -> tuple:
    """One RK4 step of a prepared right-hand side (``make_rhs`` or ``make_batch_rhs``) on the six state
    columns (floats, or arrays over a batch); thrusts as the columns."""
    return _rk4(rhs, float(t_s), float(dt_s), tuple(state_cols), thrust_port_n, thrust_stbd_n)


def _substeps(t_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Number of RK4 steps in each output interval (the step never exceeds dt_s)."""
    intervals = np.diff(t_s)
    return np.maximum(1, np.ceil(intervals / dt_s - 1e-9).astype(int))


def simulate(
    params: VesselParams,
    t_s,
    thrust_port_n,
    thrust_stbd_n,
    *,
    x0=None,
    current=None,
    wind=None,
    external_force: Callable | None = None,
    dt_s: float = 0.05,
    env: Environment | None = None,
    diverged_as_nan: bool = False,
) -> Mapping[str, np.ndarray]:
    """Simulate the model at the times ``t_s`` with thrusts held from each time to the next.

    Inputs:
        t_s: 1-D increasing array of output times (s).
        thrust_port_n, thrust_stbd_n: shape (len(t_s),) for one run or
            (n_runs, len(t_s)) for a batch (N; negative = astern).
        x0: (north_m, east_m, psi_rad, u_m_s, v_m_s, r_rad_s), shape (6,) or
            (n_runs, 6); rest at the origin heading north if omitted.
        current: (speed_m_s, towards_deg); wind: (speed_m_s, from_deg).
        external_force: f(t_s, state) -> (X_n, Y_n, N_nm) in body axes,
            state of shape (6,) or (n_runs, 6); or, when it has ``takes_columns = True``,
            f(t_s, north, east, psi, u, v, r) with each state a float or an array over the runs
            (no array built per call: the identification's force hooks).
        dt_s: the largest RK4 step (s); each output interval is split evenly.
        env: a full :class:`Environment` instead of current/wind.
        diverged_as_nan: return a run that blew up as NaN from start to end instead of raising
            FloatingPointError (the runs of a batch are independent, so the others stand; the
            identification tries far-out parameters and must not lose a whole batch to one).
    Outputs: mapping of ``t_s`` and the six states, each shaped like the thrust input.
    """
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError("t_s must be a non-empty 1-D array of times")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("t_s must be strictly increasing")
    if not (dt_s > 0 and math.isfinite(dt_s)):
        raise ValueError(f"dt_s: {dt_s!r} must be a positive number of seconds")
    tp = np.asarray(thrust_port_n, dtype=float)
    ts = np.asarray(thrust_stbd_n, dtype=float)
    if tp.shape != ts.shape or tp.shape[-1] != t.size or tp.ndim not in (1, 2):
        raise ValueError(
            f"thrust arrays must both have shape ({t.size},) or (n_runs, {t.size}); got {tp.shape} and {ts.shape}"
        )
    if not (np.all(np.isfinite(tp)) and np.all(np.isfinite(ts))):
        raise ValueError("thrust arrays contain NaN or infinite values")
    batched = tp.ndim == 2
    environment = _environment(current, wind, env)
    rhs = make_rhs(params, environment, external_force, batched)
    n_runs = tp.shape[0] if batched else 1
    x0_arr = np.zeros(6) if x0 is None else np.asarray(x0, dtype=float)
    if batched:
        x0_arr = np.broadcast_to(x0_arr, (n_runs, 6))
    elif x0_arr.shape != (6,):
        raise ValueError(f"x0 must have shape (6,) for one run, got {x0_arr.shape}")
    if not np.all(np.isfinite(x0_arr)):
        raise ValueError("x0 contains NaN or infinite values")

    out = np.empty(tp.shape + (6,)) if batched else np.empty((t.size, 6))
    steps = _substeps(t, dt_s)
    if batched:
        x = tuple(np.array(x0_arr[:, k]) for k in range(6))
        out[:, 0, :] = x0_arr
        # a run that blows up is found below and said once; numpy's overflow warnings on the way printed
        # "RuntimeWarning: overflow encountered in multiply" and a line of model.py above that message
        with np.errstate(over="ignore", invalid="ignore"):
            for k in range(t.size - 1):
                h = (t[k + 1] - t[k]) / steps[k]
                p_k, s_k = tp[:, k], ts[:, k]
                for j in range(steps[k]):
                    x = _rk4(rhs, t[k] + j * h, h, x, p_k, s_k)
                out[:, k + 1, :] = np.stack(x, axis=-1)
    else:
        x = tuple(float(c) for c in x0_arr)
        out[0] = x
        tp_l, ts_l, t_l, steps_l = tp.tolist(), ts.tolist(), t.tolist(), steps.tolist()
        rk4 = _rk4
        try:
            for k in range(t.size - 1):
                n_sub = steps_l[k]
                t0 = t_l[k]
                h = (t_l[k + 1] - t0) / n_sub
                p_k, s_k = tp_l[k], ts_l[k]
                for j in range(n_sub):
                    x = rk4(rhs, t0 + j * h, h, x, p_k, s_k)
                out[k + 1] = x
        except (ValueError, OverflowError):  # the math module's answer to an infinite state
            out[:] = np.inf
    if not np.all(np.isfinite(out)):
        if not diverged_as_nan:
            raise FloatingPointError("the simulation diverged (NaN or infinite state); check the parameters and dt_s")
        bad = ~np.all(np.isfinite(out.reshape(n_runs, -1)), axis=1)
        out[bad if batched else slice(None)] = np.nan
    result = {"t_s": t}
    for k, name in enumerate(STATE_NAMES):
        result[name] = out[..., k]
    return result
