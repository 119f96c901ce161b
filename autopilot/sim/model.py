"""The 3-DOF MMG manoeuvring model of the WAM-V (thesis ch. 3, SPEC sections 2-5).

States (earth-fixed local frame, body axes x forward, y starboard)::

    north_m, east_m   position of the centre of gravity
    psi_rad           heading from north, clockwise positive
    u_m_s, v_m_s      velocity over ground in body axes
    r_rad_s           yaw rate, > 0 turns to starboard

Inputs: thrust_port_n, thrust_stbd_n (N, negative = astern), the environment.

Equations (Eq 3.3, hull forces Eq 3.19-3.21, propulsion Eq 3.6 with the sign
of SPEC 2), written in the velocity relative to the water (u_r, v_r) =
(u, v) - current in body axes, which is exact for a uniform steady current::

    (m + m_x) du_r/dt = X_H + X_P + X_E + (m + m_y) v_r r
    (m + m_y) dv_r/dt = Y_H + Y_E - (m + m_x) u_r r
    (I_z + J_z) dr/dt = N_H + N_P + N_E
    du/dt = du_r/dt + r v_c,   dv/dt = dv_r/dt - r u_c      (current turns in body axes)

    X_H = -R(u_r) + X_vv v_r^2                              R = r1 u + r2 |u| u  (SPEC 5)
    Y_H = 1/2 rho L d [U (Y'_v v_r + Y'_r L r) + Y'_vvv v_r^3 / U] - Y_0(v_r)
    N_H = 1/2 rho L^2 d [U (N'_v v_r + N'_r L r) + N'_vvv v_r^3 / U] - N_0(r)
    X_P = (1 - t_P)(T_P + T_S),   N_P = (1 - d_NP) y_P (T_P - T_S)

U = |(u_r, v_r)|. The MMG terms vanish at U = 0, so Y_0(v) = d1 v + d2 |v| v
and N_0(r) = n1 r + n2 |r| r keep sway and yaw damped when the boat spins in
place (SPEC 3; file 003 Eq 4-6). v^3/U is bounded by v^2 and tends to 0.
X_E, Y_E, N_E are environment and external forces (autopilot.sim.environment).

The right-hand side is one function that works on floats (with ``math``) and
on numpy arrays over a batch of runs (with ``numpy``), so the single-run and
batched simulations integrate the very same equations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from autopilot.sim.environment import CALM, Environment
from autopilot.sim.params import VesselParams

# A right-hand side: (t_s, n, e, psi, u, v, r, thrust_port_n, thrust_stbd_n) -> 6 derivatives.
Rhs = Callable[..., tuple]

_TINY_SPEED_M_S = 1e-12  # only guards 0/0 in v^3/U; |v^3/U| <= v^2 anyway


@lru_cache(maxsize=64)
def make_rhs(
    params: VesselParams,
    env: Environment = CALM,
    external_force: Callable | None = None,
    vectorised: bool = False,
) -> Rhs:
    """The model's right-hand side with every constant bound (pure, cached)."""
    return _bind(params, env.current_ne_m_s, env.wind_ne_m_s, env.wind_speed_m_s > 0.0, env.sinusoidal,
                 external_force, np if vectorised else math)


def make_batch_rhs(params_runs, envs, external_force: Callable | None = None) -> Rhs:
    """The right-hand side of a batch of runs that differ in their parameters and environments.

    ``params_runs`` and ``envs``: one :class:`VesselParams` and one :class:`Environment` per run;
    every constant becomes an array over the runs (the states of the batch are arrays of the same
    length), so the equations are the very ones of :func:`make_rhs`. A run without a sinusoidal
    force gets amplitude and bias 0 (the force is then exactly 0).
    """
    from dataclasses import fields

    from autopilot.sim.environment import SinusoidalDisturbance

    params_runs, envs = list(params_runs), list(envs)
    if len(params_runs) != len(envs) or not params_runs:
        raise ValueError("make_batch_rhs needs one VesselParams and one Environment per run (at least one run)")
    stacked = {f.name: np.array([getattr(p, f.name) for p in params_runs], dtype=float)
               for f in fields(VesselParams) if f.type in ("float", float)}
    p = VesselParams(**stacked)  # fields as arrays over the runs: the derived properties follow
    cur = np.array([e.current_ne_m_s for e in envs], dtype=float).reshape(-1, 2)
    air = np.array([e.wind_ne_m_s for e in envs], dtype=float).reshape(-1, 2)
    sinus = None
    if any(e.sinusoidal is not None for e in envs):
        off = SinusoidalDisturbance(amplitude_n=0.0, bias_n=0.0)
        runs = [e.sinusoidal or off for e in envs]
        sinus = SinusoidalDisturbance(**{f.name: np.array([getattr(s, f.name) for s in runs], dtype=float)
                                         for f in fields(SinusoidalDisturbance)})
    wind_on = np.array([e.wind_speed_m_s > 0.0 for e in envs])  # no wind: no air drag either (as make_rhs)
    return _bind(p, (cur[:, 0], cur[:, 1]), (air[:, 0], air[:, 1]), wind_on, sinus, external_force, np)


def windage_gains(p) -> tuple:
    """(k_x, k_y, k_n) of the windage model (autopilot.sim.environment): 1/2 rho_a C_X A_F, 1/2 rho_a C_Y A_L
    and -rho_a C_N A_L L, from the vessel's parameters (floats, or arrays over a batch)."""
    rho = p.air_density_kg_m3
    return (0.5 * rho * p.wind_cx * p.frontal_area_m2, 0.5 * rho * p.wind_cy * p.lateral_area_m2,
            -rho * p.wind_cn * p.lateral_area_m2 * p.length_m)


def windage(gains, air_n_m_s, air_e_m_s, cos_psi, sin_psi, u_m_s, v_m_s) -> tuple:
    """Body-frame (X N, Y N, N N m) of air flowing at (north, east) on a boat heading (cos, sin) psi and moving at
    (u, v) in body axes (the environment docstring's X_w, Y_w, N_w; floats or arrays)."""
    a_x = air_n_m_s * cos_psi + air_e_m_s * sin_psi - u_m_s
    a_y = -air_n_m_s * sin_psi + air_e_m_s * cos_psi - v_m_s
    k_x, k_y, k_n = gains
    return k_x * a_x * abs(a_x), k_y * a_y * abs(a_y), k_n * a_x * a_y


def _bind(p, current_ne_m_s, wind_ne_m_s, wind_on, sinus, ext, xp) -> Rhs:
    """The right-hand side over the parameters ``p`` (floats, or arrays over a batch of runs; then
    ``wind_on`` is a mask over the runs)."""
    sqrt, cos, sin = xp.sqrt, xp.cos, xp.sin
    mx, my, iz = p.mass_x_kg, p.mass_y_kg, p.inertia_z_kg_m2
    inv_mx, inv_my, inv_iz = 1.0 / mx, 1.0 / my, 1.0 / iz
    length = p.length_m
    kf, km = p.force_scale_kg_m, p.moment_scale_kg
    r1, r2 = p.resistance_linear_n_s_m, p.resistance_quadratic_n_s2_m2
    x_vv = kf * p.x_vv_nd
    y_v, y_r, y_vvv = kf * p.y_v_nd, kf * p.y_r_nd * length, kf * p.y_vvv_nd
    n_v, n_r, n_vvv = km * p.n_v_nd, km * p.n_r_nd * length, km * p.n_vvv_nd
    d_v1, d_v2 = p.sway_damping_linear_n_s_m, p.sway_damping_quadratic_n_s2_m2
    d_r1, d_r2 = p.yaw_damping_linear_nm_s, p.yaw_damping_quadratic_nm_s2
    k_xp = 1.0 - p.thrust_deduction  # Eq 3.6
    k_np = (1.0 - p.moment_deduction) * p.y_p_m  # Eq 3.6 with SPEC 2's sign

    cur_n, cur_e = current_ne_m_s
    has_current = bool(np.any(cur_n != 0.0) or np.any(cur_e != 0.0))
    air_n, air_e = wind_ne_m_s
    has_wind = bool(np.any(wind_on))
    gains = windage_gains(p)
    if isinstance(wind_on, np.ndarray):  # a batch: the runs without wind have no windage term at all
        gains = tuple(k * wind_on for k in gains)
    ext_columns = bool(getattr(ext, "takes_columns", False))

    def rhs(t_s, n, e, psi, u, v, r, thrust_port_n, thrust_stbd_n):
        c, s = cos(psi), sin(psi)
        if has_current:
            u_c = cur_n * c + cur_e * s
            v_c = -cur_n * s + cur_e * c
            u_r, v_r = u - u_c, v - v_c
        else:
            u_c = v_c = 0.0
            u_r, v_r = u, v
        speed = sqrt(u_r * u_r + v_r * v_r) + _TINY_SPEED_M_S
        v3_over_u = v_r * v_r * v_r / speed
        # hull (Eq 3.19-3.21) + zero-speed damping + propulsion (Eq 3.6)
        fx = -(r1 + r2 * abs(u_r)) * u_r + x_vv * v_r * v_r + k_xp * (thrust_port_n + thrust_stbd_n)
        fy = speed * (y_v * v_r + y_r * r) + y_vvv * v3_over_u - (d_v1 + d_v2 * abs(v_r)) * v_r
        mz = speed * (n_v * v_r + n_r * r) + n_vvv * v3_over_u - (d_r1 + d_r2 * abs(r)) * r
        mz = mz + k_np * (thrust_port_n - thrust_stbd_n)
        if has_wind:
            w_x, w_y, w_n = windage(gains, air_n, air_e, c, s, u, v)
            fx, fy, mz = fx + w_x, fy + w_y, mz + w_n
        if sinus is not None:  # file 003 Eq 7, earth-fixed direction
            f_d = sinus.amplitude_n * sin(sinus.omega_rad_s * t_s) + sinus.bias_n
            fx = fx + f_d * cos(sinus.angle_rad - psi)
            fy = fy + f_d * sin(sinus.angle_rad - psi)
        if ext is not None:
            if ext_columns:  # the states as they are (floats or arrays over the runs): nothing to stack
                x_e, y_e, n_e = ext(t_s, n, e, psi, u, v, r)
            else:
                x_e, y_e, n_e = ext(t_s, np.stack(np.broadcast_arrays(n, e, psi, u, v, r), axis=-1))
            fx, fy, mz = fx + x_e, fy + y_e, mz + n_e
        # Eq 3.3 in relative velocities
        du_r = (fx + my * v_r * r) * inv_mx
        dv_r = (fy - mx * u_r * r) * inv_my
        dr = mz * inv_iz
        du = du_r + r * v_c
        dv = dv_r - r * u_c
        return u * c - v * s, u * s + v * c, r, du, dv, dr

    return rhs
