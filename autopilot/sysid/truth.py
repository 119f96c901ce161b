"""The truth of a synthetic trial: hidden effects simulated by the project's simulator, on a fine grid.

Independent of the identification's replay code (``prediction.py`` and the hooks of
``effects.py``), on purpose: a test that checks the replay against itself proves
nothing. Here the current goes through ``simulate(current=...)``, quadratic yaw
damping and hydro changes are edits of VesselParams, the deadband is hard (not
softened), the thrust lag is integrated on the 100 Hz grid, and the sensor
effects (delay, antenna lever arm, heading bias) are applied to the fine-grid
truth when it is sampled (:func:`sensed`).

Effects outside the candidate list, for the trials that must end ``unexplained``:

    thrust_fade.fraction    both thrusts fade linearly over the trial to (1 - fraction)
                            of the command (a battery that sags)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.sim import VesselParams, simulate
from autopilot.sim.motors import weak_motor_gains

FINE_DT_S = 0.01  # the truth's grid (s)
LOG_DT_S = 0.1  # the commands' rate, as the daemon's 10 Hz loop (s)
UNLISTED = ("thrust_fade.fraction",)

# manoeuvre segments: (port duty %, starboard duty %) at the start and at the end (a ramp when they differ)
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


def schedule(rng: np.random.Generator, duration_s: float, dt_s: float = LOG_DT_S) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
        frac = np.linspace(0.0, 1.0, sl.stop - sl.start)
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


@dataclass(frozen=True)
class Truth:
    """A simulated trial: commands at the log rate, the true motion on the fine grid, the hidden effects."""

    t_log_s: np.ndarray
    duty_port_pct: np.ndarray
    duty_stbd_pct: np.ndarray
    t_fine_s: np.ndarray
    state: dict  # simulate() output on t_fine_s
    effects: dict


def _thrusts(effects: dict, dpf: np.ndarray, dsf: np.ndarray, tf: np.ndarray, curve: ThrustCurve):
    d0 = effects.get("thrust_deadband.threshold_pct", 0.0)
    tpf = np.where(np.abs(dpf) >= d0, curve.thrust_from_signed_duty_n(dpf), 0.0)
    tsf = np.where(np.abs(dsf) >= d0, curve.thrust_from_signed_duty_n(dsf), 0.0)
    a = effects.get("thrust_asymmetry.asymmetry_nd", 0.0)
    tpf, tsf = tpf * (1 + a), tsf * (1 - a)
    port, stbd = weak_motor_gains(float(effects.get("weak_motor.loss_nd", 0.0)))
    tpf, tsf = tpf * port, tsf * stbd
    fade = effects.get("thrust_fade.fraction", 0.0)
    if fade:
        g = 1.0 - fade * tf / max(tf[-1], 1e-9)
        tpf, tsf = tpf * g, tsf * g
    tau = effects.get("thrust_lag.time_constant_s", 0.0)
    if tau > 0:  # first-order lag of the 100 Hz held command, exact mean over each 10 ms step
        tpf, tsf = _lag_mean(tpf, tau, FINE_DT_S), _lag_mean(tsf, tau, FINE_DT_S)
    return tpf, tsf


def _wind(effects: dict):
    f_n = effects.get("wind_force.north_n", 0.0)
    f_e = effects.get("wind_force.east_n", 0.0)
    m_z = effects.get("wind_force.moment_nm", 0.0)
    if not (f_n or f_e or m_z):
        return None

    def ext(t_s, state):
        psi = state[..., 2]
        return f_n * np.cos(psi) + f_e * np.sin(psi), -f_n * np.sin(psi) + f_e * np.cos(psi), m_z + 0.0 * psi

    return ext


def simulate_truth(vessel: VesselParams, effects: dict, rng: np.random.Generator, *, duration_s: float,
                   curve: ThrustCurve | None = None) -> Truth:
    """Random manoeuvres (:func:`schedule`) flown with the hidden ``effects`` (key -> value)."""
    curve = curve or ThrustCurve()
    t10, dp10, ds10 = schedule(rng, duration_s)
    tf = np.arange(0.0, duration_s + FINE_DT_S / 2, FINE_DT_S)
    k = np.minimum((tf / LOG_DT_S + 1e-9).astype(int), t10.size - 1)
    tpf, tsf = _thrusts(effects, dp10[k], ds10[k], tf, curve)
    c_n = effects.get("current.north_m_s", 0.0)
    c_e = effects.get("current.east_m_s", 0.0)
    current = (math.hypot(c_n, c_e), math.degrees(math.atan2(c_e, c_n))) if (c_n or c_e) else None
    speed0 = rng.uniform(0.0, 1.5)
    psi0 = rng.uniform(-math.pi, math.pi)
    x0 = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), psi0, speed0, 0.0, 0.0])
    if current is not None:  # start moving with the water plus its own speed
        x0[3] += c_n * math.cos(psi0) + c_e * math.sin(psi0)
        x0[4] += -c_n * math.sin(psi0) + c_e * math.cos(psi0)
    a_n, a_e = effects.get("wind.north_m_s", 0.0), effects.get("wind.east_m_s", 0.0)
    # the simulator's own wind (its Environment and rhs), not the identification's hook: the air's velocity
    # (towards) as the meteorological speed and direction it blows from
    air = (math.hypot(a_n, a_e), (math.degrees(math.atan2(a_e, a_n)) + 180.0) % 360.0) if (a_n or a_e) else None
    state = simulate(hidden_params(vessel, effects), tf, tpf, tsf, x0=x0, current=current, wind=air,
                     external_force=_wind(effects), dt_s=FINE_DT_S)
    return Truth(t10, dp10, ds10, tf, dict(state), dict(effects))


def sensed_velocity(truth: Truth, t_s, h_s: float = 0.5 * FINE_DT_S) -> tuple[np.ndarray, np.ndarray]:
    """The velocity over ground (north_m_s, east_m_s) of what :func:`sensed` reports (the antenna's, with the
    hidden sensor effects), by a central difference of it."""
    t = np.asarray(t_s, dtype=float)
    n1, e1, _ = sensed(truth, t + h_s)
    n0, e0, _ = sensed(truth, t - h_s)
    return (n1 - n0) / (2 * h_s), (e1 - e0) / (2 * h_s)


def sensed(truth: Truth, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a perfect sensor with the hidden sensor effects reports at ``t_s``: (north_m, east_m, psi_rad)."""
    e = truth.effects
    tq = np.maximum(np.asarray(t_s, dtype=float) - e.get("sensor_delay.delay_s", 0.0), 0.0)
    tq_fix = np.maximum(tq - e.get("fix_delay.delay_s", 0.0), 0.0)  # the fix later still; the heading on time
    n = np.interp(tq_fix, truth.t_fine_s, truth.state["north_m"])
    east = np.interp(tq_fix, truth.t_fine_s, truth.state["east_m"])
    psi = np.interp(tq, truth.t_fine_s, truth.state["psi_rad"])
    lx, ly = e.get("antenna_offset.forward_m", 0.0), e.get("antenna_offset.starboard_m", 0.0)
    n, east = n + lx * np.cos(psi) - ly * np.sin(psi), east + lx * np.sin(psi) + ly * np.cos(psi)
    return n, east, psi + math.radians(e.get("heading_bias.bias_deg", 0.0))
