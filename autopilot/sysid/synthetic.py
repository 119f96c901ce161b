"""Synthetic trials with hidden effects, made by the project's simulator (tests, benchmark).

The truth is simulated independently of the identification's replay code:
current through ``simulate(current=...)``, quadratic yaw damping and hydro
changes by editing VesselParams, a hard (not softened) deadband, the thrust
lag integrated on a 100 Hz grid, sensor effects applied to the fine-grid
truth. Measurements: 10 Hz, white position noise, heading noise quantised
to 0.1 deg, a few dropped sensor samples (the logged command kept) and a few empty cells.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.sim import VesselParams, simulate
from autopilot.sysid.trials import Trial, make_trial

# manoeuvre segments: (port duty %, starboard duty %) held, or "ramp" rows (start, end) per side
SEGMENTS = (
    ((60, 60), (60, 60)),  # straight, medium
    ((100, 100), (100, 100)),  # straight, fast
    ((30, 30), (30, 30)),  # straight, slow
    ((100, 20), (100, 20)),  # turn to starboard
    ((20, 100), (20, 100)),  # turn to port
    ((80, 0), (80, 0)),  # hard turn to starboard
    ((0, 80), (0, 80)),  # hard turn to port
    ((0, 0), (60, 60)),  # ramp up from rest-ish speeds through the low duties
    ((50, 10), (10, 50)),  # turn reversal sweep
    ((100, -40), (100, -40)),  # spin to starboard with reverse
)


def schedule(rng: np.random.Generator, duration_s: float, dt_s: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random sequence of segments (6-12 s each) as signed duty series at dt_s."""
    t = np.arange(0.0, duration_s + dt_s / 2, dt_s)
    dp, ds = np.empty(t.size), np.empty(t.size)
    k = 0
    order = rng.permutation(len(SEGMENTS))
    q = 0
    while k < t.size:
        seg = SEGMENTS[order[q % len(SEGMENTS)]]
        q += 1
        n = int(rng.uniform(6.0, 12.0) / dt_s)
        sl = slice(k, min(k + n, t.size))
        m = sl.stop - sl.start
        frac = np.linspace(0.0, 1.0, m)
        dp[sl] = seg[0][0] + (seg[1][0] - seg[0][0]) * frac
        ds[sl] = seg[0][1] + (seg[1][1] - seg[0][1]) * frac
        k += n
    return t, dp, ds


def _lag_mean(u: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """Mean over each step of y' = (u - y) / tau with u held (the exact continuous solution)."""
    a = math.exp(-dt_s / tau_s)
    gain = tau_s / dt_s * (1.0 - a)
    y = np.empty_like(u)
    state = u[0]
    for k, uk in enumerate(u.tolist()):
        y[k] = uk + (state - uk) * gain
        state = a * state + (1.0 - a) * uk
    return y


def hidden_params(vessel: VesselParams, effects: dict) -> VesselParams:
    """The vessel with hydro-type hidden effects written into its fields."""
    changes = {}
    if "yaw_damping_quadratic.n_rr_nm_s2" in effects:
        changes["yaw_damping_quadratic_nm_s2"] = vessel.yaw_damping_quadratic_nm_s2 + effects["yaw_damping_quadratic.n_rr_nm_s2"]
    if "hydro_refit.resistance_linear_n_s_m" in effects:
        changes["resistance_linear_n_s_m"] = vessel.resistance_linear_n_s_m + effects["hydro_refit.resistance_linear_n_s_m"]
    if "hydro_refit.n_r_nd" in effects:
        changes["n_r_nd"] = vessel.n_r_nd + effects["hydro_refit.n_r_nd"]
    return dataclasses.replace(vessel, **changes)


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
    fine = 0.01
    t10, dp10, ds10 = schedule(rng, duration_s)
    tf = np.arange(0.0, duration_s + fine / 2, fine)
    k = np.minimum((tf / 0.1 + 1e-9).astype(int), t10.size - 1)
    dpf, dsf = dp10[k], ds10[k]
    d0 = effects.get("thrust_deadband.threshold_pct", 0.0)
    tpf = np.where(np.abs(dpf) >= d0, curve.thrust_from_signed_duty_n(dpf), 0.0)
    tsf = np.where(np.abs(dsf) >= d0, curve.thrust_from_signed_duty_n(dsf), 0.0)
    a = effects.get("thrust_asymmetry.asymmetry_nd", 0.0)
    tpf, tsf = tpf * (1 + a), tsf * (1 - a)
    tau = effects.get("thrust_lag.time_constant_s", 0.0)
    if tau > 0:  # first-order lag of the 100 Hz held command, exact mean over each 10 ms step
        tpf, tsf = _lag_mean(tpf, tau, fine), _lag_mean(tsf, tau, fine)
    f_n = effects.get("wind_force.north_n", 0.0)
    f_e = effects.get("wind_force.east_n", 0.0)
    m_z = effects.get("wind_force.moment_nm", 0.0)
    ext = None
    if f_n or f_e or m_z:
        def ext(t_s, state):
            psi = state[..., 2]
            return f_n * np.cos(psi) + f_e * np.sin(psi), -f_n * np.sin(psi) + f_e * np.cos(psi), m_z + 0.0 * psi

    c_n = effects.get("current.north_m_s", 0.0)
    c_e = effects.get("current.east_m_s", 0.0)
    current = None
    if c_n or c_e:
        current = (math.hypot(c_n, c_e), math.degrees(math.atan2(c_e, c_n)))
    speed0 = rng.uniform(0.0, 1.5)
    psi0 = rng.uniform(-math.pi, math.pi)
    x0 = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), psi0, speed0, 0.0, 0.0])
    if current is not None:  # start moving with the water plus its own speed
        x0[3] += c_n * math.cos(psi0) + c_e * math.sin(psi0)
        x0[4] += -c_n * math.sin(psi0) + c_e * math.cos(psi0)
    truth = simulate(hidden_params(vessel, effects), tf, tpf, tsf, x0=x0, current=current, external_force=ext, dt_s=fine)
    delay = effects.get("sensor_delay.delay_s", 0.0)
    tq = np.maximum(t10 - delay, 0.0)
    n = np.interp(tq, tf, truth["north_m"])
    e = np.interp(tq, tf, truth["east_m"])
    psi = np.interp(tq, tf, truth["psi_rad"])
    lx = effects.get("antenna_offset.forward_m", 0.0)
    ly = effects.get("antenna_offset.starboard_m", 0.0)
    n, e = n + lx * np.cos(psi) - ly * np.sin(psi), e + lx * np.sin(psi) + ly * np.cos(psi)
    psi = psi + math.radians(effects.get("heading_bias.bias_deg", 0.0))
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
