"""Batched replay of trials through the simulator with candidate effects applied.

All trials are put on one uniform time grid (the median sample interval),
thrust held from each command to the next (the motors hold their last
command). A *run* is one trial with one initial state and one set of effect
values; many runs are integrated in a single batched ``simulate`` call, so a
finite-difference Jacobian over all trials costs one call.

Initial state of a run: (north_m, east_m, psi_rad, u_m_s, v_m_s, r_rad_s) at
the trial's first sample, u and v over ground (the shared state contract).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from autopilot.geo import wrap_pi
from autopilot.sim import STATE_NAMES, VesselParams, simulate
from autopilot.sysid.effects import PARAM_BY_KEY
from autopilot.sysid.trials import Trial, noise_sigma

SCALAR_MAX_RUNS = 24  # below this many runs the scalar loop beats numpy batching
DEADBAND_SOFT_PCT = 1.0  # half-width of the softened deadband edge (keeps the fit differentiable)
POS_NOISE_FLOOR_M = 0.02
HEADING_NOISE_FLOOR_RAD = math.radians(0.03)


@dataclass(frozen=True)
class Prepared:
    """Trials on a common grid with their measurements and noise levels."""

    trials: tuple[Trial, ...]
    dt_s: float
    t_grid: np.ndarray  # (G,)
    thrust_port_n: np.ndarray  # (N, G) zero-order hold of the commands
    thrust_stbd_n: np.ndarray
    duty_port_pct: np.ndarray
    duty_stbd_pct: np.ndarray
    pos_idx: tuple[np.ndarray, ...]  # per trial: sample indices with a valid position
    psi_idx: tuple[np.ndarray, ...]  # per trial: sample indices with a valid heading
    sigma_pos_m: np.ndarray  # (N,)
    sigma_psi_rad: np.ndarray  # (N,)

    @property
    def n_trials(self) -> int:
        return len(self.trials)

    def n_residuals(self, i: int) -> int:
        return 2 * self.pos_idx[i].size + self.psi_idx[i].size


def prepare(trials, *, dt_s: float | None = None) -> Prepared:
    """Put trials on one grid and estimate each trial's measurement noise."""
    trials = tuple(trials)
    if not trials:
        raise ValueError("no trials")
    if dt_s is None:
        dt_s = float(np.median(np.concatenate([np.diff(t.t_s) for t in trials])))
        dt_s = max(round(dt_s, 3), 0.01)
    length = max(t.t_s[-1] for t in trials)
    g = np.arange(0.0, length + dt_s * 0.999, dt_s)
    shape = (len(trials), g.size)
    tp, ts, dp, ds = (np.empty(shape) for _ in range(4))
    pos_idx, psi_idx, s_pos, s_psi = [], [], [], []
    for i, tr in enumerate(trials):
        k = np.clip(np.searchsorted(tr.t_s, g + 1e-9, side="right") - 1, 0, tr.t_s.size - 1)
        tp[i], ts[i] = tr.thrust_port_n[k], tr.thrust_stbd_n[k]
        dp[i], ds[i] = tr.duty_port_pct[k], tr.duty_stbd_pct[k]
        # a grid time with no logged sample (a dropped row): the command sent then is unknown;
        # interpolating between the neighbours is exact on ramps and half wrong at a step,
        # holding the previous one is wrong on every ramp sample (measurably biases the fits)
        gap = np.abs(tr.t_s[k] - g) > 0.5 * dt_s
        gap &= g <= tr.t_s[-1]
        if gap.any():
            for arr, src in ((tp, tr.thrust_port_n), (ts, tr.thrust_stbd_n), (dp, tr.duty_port_pct), (ds, tr.duty_stbd_pct)):
                arr[i, gap] = np.interp(g[gap], tr.t_s, src)
        pos_idx.append(np.flatnonzero(np.isfinite(tr.north_m) & np.isfinite(tr.east_m)))
        psi_idx.append(np.flatnonzero(np.isfinite(tr.heading_rad)))
        sn = noise_sigma(tr.north_m, tr.t_s, floor=POS_NOISE_FLOOR_M)
        se = noise_sigma(tr.east_m, tr.t_s, floor=POS_NOISE_FLOOR_M)
        s_pos.append(math.sqrt(0.5 * (sn * sn + se * se)))
        s_psi.append(noise_sigma(_unwrap_gappy(tr.heading_rad), tr.t_s, floor=HEADING_NOISE_FLOOR_RAD))
    return Prepared(trials, dt_s, g, tp, ts, dp, ds, tuple(pos_idx), tuple(psi_idx), np.array(s_pos), np.array(s_psi))


def _unwrap_gappy(angle_rad: np.ndarray) -> np.ndarray:
    """np.unwrap over the valid samples, NaN kept in the gaps."""
    out = np.full(angle_rad.shape, np.nan)
    ok = np.isfinite(angle_rad)
    out[ok] = np.unwrap(angle_rad[ok])
    return out


def truncate(trial: Trial, end_s: float) -> Trial:
    """The trial's samples up to ``end_s``."""
    keep = trial.t_s <= end_s
    changes = {}
    for f in dataclasses.fields(trial):
        val = getattr(trial, f.name)
        if isinstance(val, np.ndarray):
            changes[f.name] = val[keep]
    return dataclasses.replace(trial, **changes)


def initial_state(trial: Trial, *, window_s: float = 3.0) -> np.ndarray:
    """State at the first sample from quadratic fits to the first seconds of position and heading.

    Only a start: noise makes the velocities rough (``fit.estimate_x0`` refines them).
    """
    t = trial.t_s
    sel = t <= t[0] + window_s
    ok = sel & np.isfinite(trial.north_m) & np.isfinite(trial.east_m)
    okh = sel & np.isfinite(trial.heading_rad)
    deg = 2 if ok.sum() > 10 else 1
    pn = np.polyfit(t[ok] - t[0], trial.north_m[ok], deg)
    pe = np.polyfit(t[ok] - t[0], trial.east_m[ok], deg)
    psi_u = np.unwrap(trial.heading_rad[okh])
    ph = np.polyfit(t[okh] - t[0], psi_u, 2 if okh.sum() > 10 else 1)
    psi0 = float(ph[-1])
    vn, ve = float(pn[-2]), float(pe[-2])
    c, s = math.cos(psi0), math.sin(psi0)
    # sway from a few seconds of noisy positions is mostly noise; it decays within a second anyway
    return np.array([pn[-1], pe[-1], wrap_pi(psi0), vn * c + ve * s, 0.0, ph[-2]])


def _values(values: dict, key: str, n_runs: int) -> np.ndarray | None:
    """Per-run values of one effect parameter, or None when it is at its no-effect value everywhere."""
    if key not in values:
        return None
    v = np.broadcast_to(np.asarray(values[key], dtype=float), (n_runs,))
    return None if np.all(v == PARAM_BY_KEY[key].null) else v


def lag_filter(thrust: np.ndarray, tau_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Interval-mean of a first-order lag driven by a zero-order-hold command (exact for ZOH).

    y' = (u - y) / tau; over [t_k, t_k + dt) with u_k held, the mean of y is
    u_k + (y_k - u_k) (tau / dt)(1 - a), a = exp(-dt / tau), and y_{k+1} = a y_k + (1 - a) u_k.
    Using the mean keeps the simulator's zero-order hold centred (no extra half-sample delay).
    """
    out = thrust.copy()
    for j in range(thrust.shape[0]):
        tau = float(tau_s[j])
        if tau <= 1e-6:
            continue
        a = math.exp(-dt_s / tau)
        g = tau / dt_s * (1.0 - a)
        u = thrust[j]
        y = np.empty_like(u)
        y[0] = u[0]
        from scipy.signal import lfilter

        # y_{k+1} = a y_k + (1 - a) u_k  ->  y[1:] from u[:-1], initial state y_0 = u_0 (at rest)
        y[1:], _ = lfilter([1.0 - a], [1.0, -a], u[:-1], zi=[a * u[0]])
        out[j] = u + (y - u) * g
    return out


def _deadband_gain(duty_pct: np.ndarray, threshold_pct: np.ndarray) -> np.ndarray:
    return np.clip((np.abs(duty_pct) - threshold_pct[:, None]) / (2 * DEADBAND_SOFT_PCT) + 0.5, 0.0, 1.0)


def _simulate_scalar(vessel, g, tp, ts, x0, dt, n_rr, d_r1, d_nr, external=None) -> dict:
    """Runs one by one on the simulator's scalar path (faster than a small batch).

    The hydro-type effects are written into VesselParams fields here, which is
    exactly what the batched path's external force adds.
    """
    n_runs = tp.shape[0]
    out = {name: np.empty((n_runs, g.size)) for name in STATE_NAMES}
    for j in range(n_runs):
        changes = {}
        if n_rr is not None:
            changes["yaw_damping_quadratic_nm_s2"] = vessel.yaw_damping_quadratic_nm_s2 + float(n_rr[j])
        if d_r1 is not None:
            changes["resistance_linear_n_s_m"] = vessel.resistance_linear_n_s_m + float(d_r1[j])
        if d_nr is not None:
            changes["n_r_nd"] = vessel.n_r_nd + float(d_nr[j])
        params = dataclasses.replace(vessel, **changes) if changes else vessel
        # a parameter trial far out may blow up: NaN, the fit sees huge residuals
        run = simulate(params, g, tp[j], ts[j], x0=x0[j], dt_s=dt, external_force=external, diverged_as_nan=True)
        for name in STATE_NAMES:
            out[name][j] = run[name]
    return out


def predict(prep: Prepared, vessel: VesselParams, trial_idx, x0, values: dict) -> dict:
    """Simulate runs and return what the sensors would report on the grid (see :func:`_predict`)."""
    with np.errstate(all="ignore"):  # a far-out parameter trial may overflow; the caller sees NaN
        return _predict(prep, vessel, trial_idx, x0, values)


def _predict(prep: Prepared, vessel: VesselParams, trial_idx, x0, values: dict) -> dict:
    """Simulate runs and return what the sensors would report on the grid.

    trial_idx: (R,) trial of each run; x0: (R, 6) initial states; values: effect key ->
    scalar or (R,) array. Returns ``north_m``, ``east_m``, ``psi_rad`` (R, G) as measured
    (delay, antenna, bias applied) and the true ``u_m_s``, ``v_m_s``, ``r_rad_s``.
    """
    idx = np.asarray(trial_idx, dtype=int)
    n_runs = idx.size
    x0 = np.array(np.broadcast_to(np.asarray(x0, dtype=float), (n_runs, 6)))
    g, dt = prep.t_grid, prep.dt_s
    tp = prep.thrust_port_n[idx].copy()
    ts = prep.thrust_stbd_n[idx].copy()
    v = lambda key: _values(values, key, n_runs)  # noqa: E731

    if (a := v("thrust_asymmetry.asymmetry_nd")) is not None:
        tp *= 1.0 + a[:, None]
        ts *= 1.0 - a[:, None]
    if (d0 := v("thrust_deadband.threshold_pct")) is not None:
        tp *= _deadband_gain(prep.duty_port_pct[idx], d0)
        ts *= _deadband_gain(prep.duty_stbd_pct[idx], d0)
    if (tau := v("thrust_lag.time_constant_s")) is not None:
        tp, ts = lag_filter(tp, tau, dt), lag_filter(ts, tau, dt)

    f_n, f_e, m_z = v("wind_force.north_n"), v("wind_force.east_n"), v("wind_force.moment_nm")
    n_rr = v("yaw_damping_quadratic.n_rr_nm_s2")
    d_r1 = v("hydro_refit.resistance_linear_n_s_m")
    d_nr = v("hydro_refit.n_r_nd")
    forces = any(x is not None for x in (f_n, f_e, m_z, n_rr, d_r1, d_nr))
    external = None
    if forces:
        zeros = np.zeros(n_runs)
        f_n = zeros if f_n is None else f_n
        f_e = zeros if f_e is None else f_e
        k_nr = None if d_nr is None else vessel.moment_scale_kg * vessel.length_m * d_nr

        def external(t_s, state):  # body-frame (X, Y, N); state is water-relative (see below)
            psi, u, vv, r = state[:, 2], state[:, 3], state[:, 4], state[:, 5]
            c, s = np.cos(psi), np.sin(psi)
            x_e = f_n * c + f_e * s
            y_e = -f_n * s + f_e * c
            n_e = zeros if m_z is None else m_z
            if n_rr is not None:
                n_e = n_e - n_rr * np.abs(r) * r
            if d_r1 is not None:  # R = r1 u (SPEC 5): a change of r1 is a force -d_r1 u_r
                x_e = x_e - d_r1 * u
            if k_nr is not None:  # N_H term 1/2 rho L^2 d U N'_r L r (Eq 3.21)
                n_e = n_e + k_nr * np.sqrt(u * u + vv * vv) * r
            return x_e, y_e, n_e

    # A uniform steady current only shifts the water-relative motion (model.py works in
    # relative velocity; the added forces depend on psi and r only): simulate calm water
    # from the relative initial velocity and add current * t to the track.
    c_n, c_e = v("current.north_m_s"), v("current.east_m_s")
    has_current = c_n is not None or c_e is not None
    if has_current:
        c_n = np.zeros(n_runs) if c_n is None else c_n
        c_e = np.zeros(n_runs) if c_e is None else c_e
        cp, sp = np.cos(x0[:, 2]), np.sin(x0[:, 2])
        x0[:, 3] -= c_n * cp + c_e * sp
        x0[:, 4] -= -c_n * sp + c_e * cp

    wind = any(x is not None for x in (v("wind_force.north_n"), v("wind_force.east_n"), m_z))
    if not wind and n_runs <= SCALAR_MAX_RUNS:
        out = _simulate_scalar(vessel, g, tp, ts, x0, dt, n_rr, d_r1, d_nr)
    else:
        # batched; a run that blows up (a far-out parameter trial) comes back NaN, the others stand
        out = simulate(vessel, g, tp, ts, x0=x0, external_force=external, dt_s=dt, diverged_as_nan=True)
    north, east, psi = out["north_m"], out["east_m"], out["psi_rad"]
    u, vv, r = out["u_m_s"], out["v_m_s"], out["r_rad_s"]
    if has_current:
        north = north + c_n[:, None] * g
        east = east + c_e[:, None] * g
        # report ground velocity in body axes
        c, s = np.cos(psi), np.sin(psi)
        u = u + c_n[:, None] * c + c_e[:, None] * s
        vv = vv - c_n[:, None] * s + c_e[:, None] * c

    if (delay := v("sensor_delay.delay_s")) is not None:
        north, east, psi = north.copy(), east.copy(), psi.copy()
        for j in range(n_runs):
            if delay[j] > 0:
                tq = np.maximum(g - delay[j], 0.0)
                north[j] = np.interp(tq, g, north[j])
                east[j] = np.interp(tq, g, east[j])
                psi[j] = np.interp(tq, g, psi[j])
    lx, ly = v("antenna_offset.forward_m"), v("antenna_offset.starboard_m")
    if lx is not None or ly is not None:
        lx = np.zeros(n_runs) if lx is None else lx
        ly = np.zeros(n_runs) if ly is None else ly
        c, s = np.cos(psi), np.sin(psi)
        north = north + lx[:, None] * c - ly[:, None] * s
        east = east + lx[:, None] * s + ly[:, None] * c
    if (bias := v("heading_bias.bias_deg")) is not None:
        psi = psi + np.radians(bias)[:, None]
    return {"north_m": north, "east_m": east, "psi_rad": psi, "u_m_s": u, "v_m_s": vv, "r_rad_s": r}


def residuals(prep: Prepared, i: int, pred: dict, j: int, *, weighted: bool = True) -> np.ndarray:
    """Residuals (measured - predicted) of run ``j`` of ``pred`` against trial ``i``.

    Order: north at valid positions, east at valid positions, heading at valid headings;
    divided by the trial's noise sigmas when ``weighted``.
    """
    tr = prep.trials[i]
    t = tr.t_s
    pi, hi = prep.pos_idx[i], prep.psi_idx[i]
    g = prep.t_grid
    k = np.rint(t / prep.dt_s).astype(int)
    on_grid = np.all(np.abs(g[np.minimum(k, g.size - 1)] - t) < 1e-6)
    if on_grid:
        n_p = pred["north_m"][j, k[pi]]
        e_p = pred["east_m"][j, k[pi]]
        h_p = pred["psi_rad"][j, k[hi]]
    else:
        n_p = np.interp(t[pi], g, pred["north_m"][j])
        e_p = np.interp(t[pi], g, pred["east_m"][j])
        h_p = np.interp(t[hi], g, pred["psi_rad"][j])
    rn = tr.north_m[pi] - n_p
    re = tr.east_m[pi] - e_p
    rh = wrap_pi(tr.heading_rad[hi] - h_p)
    if weighted:
        sp, sh = prep.sigma_pos_m[i], prep.sigma_psi_rad[i]
        return np.concatenate([rn / sp, re / sp, rh / sh])
    return np.concatenate([rn, re, rh])


def rmse(prep: Prepared, trials_idx, pred: dict, runs) -> dict:
    """Position (m, horizontal distance) and heading (deg) RMS errors over the given trials."""
    se_pos = se_psi = noise_pos = noise_psi = 0.0
    n_pos = n_psi = 0
    for i, j in zip(trials_idx, runs):
        r = residuals(prep, i, pred, j, weighted=False)
        m = prep.pos_idx[i].size
        se_pos += float(np.sum(r[:m] ** 2) + np.sum(r[m : 2 * m] ** 2))
        se_psi += float(np.sum(r[2 * m :] ** 2))
        noise_pos += 2.0 * m * prep.sigma_pos_m[i] ** 2
        noise_psi += (r.size - 2 * m) * prep.sigma_psi_rad[i] ** 2
        n_pos += m
        n_psi += r.size - 2 * m
    n_pos, n_psi = max(n_pos, 1), max(n_psi, 1)
    return {
        "position_m": math.sqrt(se_pos / n_pos),
        "heading_deg": math.degrees(math.sqrt(se_psi / n_psi)),
        # the part of the gap the measurement noise (estimated from the data) does not explain
        "position_model_m": math.sqrt(max(se_pos - noise_pos, 0.0) / n_pos),
        "heading_model_deg": math.degrees(math.sqrt(max(se_psi - noise_psi, 0.0) / n_psi)),
    }
