"""Candidate effects: physically named extensions of the model, few parameters each, each in one place.

An effect declares its parameters (name, unit, no-effect value, bounds, scale)
and carries its own hooks; the replay (``prediction.predict``), the reports, the
YAML outputs and the table mode call the hooks and never name an effect.
Every effect acts outside the simulator's equations, so the simulator stays
as it is:

    identifier              parameters                        hook: where it acts
    current                 north_m_s, east_m_s               water: uniform steady current (exact: the
                                                              model is written in water-relative velocity,
                                                              so the track is the calm-water track + c t)
    wind_force              north_n, east_n, moment_nm        force: steady earth-frame force + yaw moment
    wind                    north_m_s, east_m_s               force: steady wind through the vessel's windage
                                                              (sim.model.windage), turning with the heading
    thrust_asymmetry        asymmetry_nd (a)                  thrust: T_P (1 + a), T_S (1 - a)
    weak_motor              loss_nd (w)                       thrust: one motor short of the table, the other
                                                              on it: T_P (1 - w) for w > 0, T_S (1 + w) for w < 0
    thrust_lag              time_constant_s                   thrust: first-order lag of both thrusts
    thrust_deadband         threshold_pct                     thrust: none below |duty| = threshold
                                                              (edge softened over +-1 % duty)
    heading_bias            bias_deg                          sensed: compass reads psi + bias
    antenna_offset          forward_m, starboard_m            sensed: GPS antenna at this body lever arm
    sensor_delay            delay_s                           sensed: position and heading reported late
    fix_delay               delay_s                           sensed: position (and its velocity) late, the
                                                              heading on time
    yaw_damping_quadratic   n_rr_nm_s2                        fields (force when batched): extra -N_rr |r| r
    hydro_refit             resistance_linear_n_s_m, n_r_nd   fields (force when batched): re-fit of
                                                              VesselParams fields, fitted as changes

Hooks (all optional; ``v`` maps the effect's parameter names to per-run arrays):
``thrust(v, tp, ts, ctx)`` -> (tp, ts); ``force(v, vessel)`` -> f(psi, u, v, r) -> (X, Y, N)
body-frame; ``fields(v, vessel)`` -> VesselParams changes (scalar values; ``field_limits`` what a
written file must respect); ``water(v)`` ->
(north_m_s, east_m_s); ``sensed(v, out, t_s)`` -> out; ``bounds(name, vessel)``;
``derived(value, sigma)`` -> extra report rows; ``reported(name, value, vessel)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from autopilot.sim.motors import weak_motor_gains

Z_95 = 1.959964  # a 95 % interval is value +- Z_95 sigma (the normal 97.5 % quantile), everywhere in sysid
DEADBAND_SOFT_PCT = 1.0  # half-width of the softened deadband edge (keeps the fit differentiable)


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect: name, unit, the no-effect value, bounds, typical size."""

    name: str
    unit: str
    null: float
    lo: float
    hi: float
    scale: float
    fd_step: float = 1e-3  # finite-difference step in units of ``scale``
    init: float | None = None  # starting value when the null value has no gradient
    grid: tuple[float, ...] | None = None  # screening starts when the cost is far from quadratic
    # the cost is flat between steps (a threshold between the duties a trial holds): a fit stuck
    # above the noise is profiled over ``grid`` (search.profile)
    stepwise: bool = False
    # more starts for a stuck multimodal fit's retries (search.from_each_start), after the grid's: far starts that
    # would only slow the screening of every log
    retry_grid: tuple[float, ...] = ()
    # a minimum at the mirrored value too (a weak port or a weak starboard motor, each side of a kink at the null; a
    # wind and the reversed wind, both components mirrored): a fit that starts on the wrong side stays there, so the
    # leading single and a pair's second effect are fitted from the mirrored value too (search.polish_and_retry,
    # search.fit_pairs)
    mirrored: bool = False

    def __post_init__(self):
        if self.stepwise and not self.grid:
            raise ValueError(f"{self.name}: a stepwise parameter needs a grid to profile over")

    @property
    def start(self) -> float:
        return self.null if self.init is None else self.init


class Effect:
    """A candidate effect: parameters (SI; degrees only where the name says so) and hooks."""

    name: str = ""
    params: tuple[EffectParam, ...] = ()
    doc: str = ""
    kind: str = ""  # "input", "force", "environment", "sensor", "hydro"
    steady: bool = False  # observable in a steady-state table
    vessel_fields: bool = False  # written into vessel-updated.yaml (VesselParams fields), else effects.yaml
    sensed_order: int = 0  # order of the ``sensed`` hooks (delay, then lever arm, then bias)
    multimodal: bool = False  # the cost has several minima: a fit stuck above the noise is retried from each start
    # a velocity (north_m_s, east_m_s) whose curvature interval means nothing near no effect: what the trials cannot
    # rule out is given as an upper bound of its speed, probed (intervals.speed_bound)
    speed_bounded: bool = False
    # another effect that explains the same thing nearly alike (a thrust asymmetry, a weak motor: the same ratio of
    # the two sides' thrusts, a common gain apart): a pair chosen with one is fitted with the other in its place too
    # (search.sibling_pair), from ``as_sibling``'s values
    sibling: str | None = None

    def as_sibling(self, value: dict) -> list[float]:
        """The sibling's parameters (in its keys' order) giving what ``value`` gives, as nearly as it can."""
        raise NotImplementedError(self.name)

    def alias_at_speed(self, value: dict, speed_m_s: float) -> str | None:
        """What else, on straight runs at ``speed_m_s``, looks as this effect with ``value`` (parameter name ->
        value) does, said with the verdict; None: nothing in particular."""
        return None

    def key(self, param: EffectParam) -> str:
        return f"{self.name}.{param.name}"

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(self.key(p) for p in self.params)

    def bounds(self, name: str, vessel) -> tuple[float, float]:
        p = next(p for p in self.params if p.name == name)
        return p.lo, p.hi

    def reported(self, name: str, value: float, vessel) -> float:
        """The value as reported (hydro_refit: the new field value, not the change)."""
        return value

    def derived(self, value: dict, sigma: dict) -> list[dict]:
        """Extra report rows computed from the parameters."""
        return []

    thrust = None
    # force(v, vessel, water_ne_m_s): (psi, u, v, r) -> (X, Y, N), the state through the water; ``water_ne_m_s`` the
    # current fitted beside it (m/s, towards north/east), for a force that goes with a velocity over ground (the wind)
    force = None
    fields = None
    water = None
    sensed = None
    field_limits: ClassVar[dict] = {}  # VesselParams field -> (lo, hi) a written file must respect

    def written_fields(self, v, vessel) -> dict:
        """``fields`` held inside ``field_limits`` (what vessel-updated.yaml gets)."""
        out = self.fields(v, vessel)
        for name, (lo, hi) in self.field_limits.items():
            if name in out:
                out[name] = min(max(out[name], lo), hi)
        return out

    def __repr__(self) -> str:
        return f"<effect {self.name}>"


def param_row(name, unit, value, sigma) -> dict:
    """One reported parameter: value, unit, sigma and its 95 % interval (summary.json, table reports)."""
    return {"name": name, "unit": unit, "value": value, "ci95": [value - Z_95 * sigma, value + Z_95 * sigma], "sigma": sigma}


def polar_rows(value: dict, sigma: dict, direction: str, turn_deg: float) -> list[dict]:
    """Speed and direction rows of a velocity given as ``north_m_s``, ``east_m_s`` (the direction it goes towards
    plus ``turn_deg``: 180 for where a wind blows from). Sigmas by the delta method; the 95 % intervals are the
    range of the speed and of the direction over the components' 95 % ellipse (:func:`speed_interval`): a speed
    is never below 0 (the delta method gave "-0.02 .. 0.06 m/s" for a current of 0.02 +- 0.02 per component),
    and when the ellipse holds no velocity at all the direction is any (0 .. 360)."""
    vn, ve, sn, se = value["north_m_s"], value["east_m_s"], sigma["north_m_s"], sigma["east_m_s"]
    speed = math.hypot(vn, ve)
    s_speed = math.sqrt((vn * sn) ** 2 + (ve * se) ** 2) / max(speed, 1e-9)
    s_dir = math.degrees(math.sqrt((ve * sn) ** 2 + (vn * se) ** 2)) / max(speed**2, 1e-12)
    angle = (math.degrees(math.atan2(ve, vn)) + turn_deg) % 360.0
    speed_row, dir_row = param_row("speed_m_s", "m/s", speed, s_speed), param_row(direction, "deg", angle, s_dir)
    lo, hi, turn = speed_interval(vn, ve, sn, se)
    if math.isfinite(lo):
        speed_row["ci95"] = [lo, hi]
        dir_row["ci95"] = [0.0, 360.0] if turn is None else [angle - turn[0], angle + turn[1]]
    return [speed_row, dir_row]


def speed_interval(vn: float, ve: float, sn: float, se: float) -> tuple[float, float, tuple | None]:
    """(lowest, highest speed, (degrees the direction turns one way, the other) or None when it may be any) over
    the 95 % ellipse of a velocity's components (each +- Z_95 sigma, their correlation not kept): under a quadratic
    cost the range of a function of the parameters over that region is its profile interval. NaN when a sigma is."""
    if not (math.isfinite(sn) and math.isfinite(se)):
        return math.nan, math.nan, None
    a = np.linspace(0.0, 2.0 * math.pi, 721)
    n, e = vn + Z_95 * sn * np.cos(a), ve + Z_95 * se * np.sin(a)
    speed = np.hypot(n, e)
    inside = (vn / max(Z_95 * sn, 1e-300)) ** 2 + (ve / max(Z_95 * se, 1e-300)) ** 2 <= 1.0
    if inside:
        return 0.0, float(speed.max()), None
    turn = np.degrees(np.angle(np.exp(1j * (np.arctan2(e, n) - math.atan2(ve, vn)))))  # from the estimate's
    return float(speed.min()), float(speed.max()), (float(max(-turn.min(), 0.0)), float(max(turn.max(), 0.0)))


class Current(Effect):
    name, kind = "current", "environment"
    params = (EffectParam("north_m_s", "m/s", 0.0, -2.0, 2.0, 0.1), EffectParam("east_m_s", "m/s", 0.0, -2.0, 2.0, 0.1))
    doc = "uniform steady water current (velocity towards north/east)"

    def water(self, v):
        return v["north_m_s"], v["east_m_s"]

    def derived(self, value, sigma):
        """Speed and direction (towards), intervals by the delta method."""
        return polar_rows(value, sigma, "towards_deg", 0.0)


class WindForce(Effect):
    name, kind = "wind_force", "force"
    params = (EffectParam("north_n", "N", 0.0, -200.0, 200.0, 5.0), EffectParam("east_n", "N", 0.0, -200.0, 200.0, 5.0),
              EffectParam("moment_nm", "N m", 0.0, -200.0, 200.0, 2.0))
    doc = "steady force in the earth frame and a steady yaw moment (wind on the superstructure)"

    def force(self, v, vessel, water_ne_m_s=(0.0, 0.0)):
        f_n, f_e, m_z = v["north_n"], v["east_n"], v["moment_nm"]
        scalar = isinstance(f_n, float)  # one run on the simulator's scalar path: plain floats
        cos, sin = (math.cos, math.sin) if scalar else (np.cos, np.sin)

        def f(psi, u, vv, r):  # earth-frame force into body axes
            c, s = cos(psi), sin(psi)
            return f_n * c + f_e * s, -f_n * s + f_e * c, m_z if scalar else m_z + 0.0 * psi

        return f


class Wind(Effect):
    name, kind, multimodal, speed_bounded = "wind", "force", True, True
    # near no wind its curvature interval is read across the windage's switch (no wind, no force: the boat's own air
    # drag comes on with any wind): a calm pond's "not ruled out" was wind.north_m_s -0.029 .. 0.029 m/s, which no
    # data can say of a force that goes with the wind's square; intervals.speed_bound probes the speeds instead
    # the force goes with the air's velocity squared: a fit started near no wind went the wrong way (5 m/s from the
    # east fitted 4.3 m/s from the south-west at chi-square 7.4, the truth at 1.7): screened from a 3 x 3 grid
    # (from the four quadrants alone, 1 of 6 realistic draws was found)
    # Retried from +-10 m/s too: 8.9 m/s from the south was reached from (9, 0) or (10, -5) and not from any start
    # of the grid (stuck at chi-square 22-300): unexplained.
    # Mirrored: the windage's moment (k_n a_x a_y) is even in the air's velocity, so the reversed wind turns the boat
    # alike and only the drift tells the two apart. 5.6 m/s from 087 beside a port motor 10 % weak (three pond logs):
    # the wind alone stopped at 5.0 m/s from 262, chi-square 1.14, the mirrored start went to the truth at 0.60 (510
    # BIC points), and only beside it did the weak motor screen first: unexplained before, the pair named after.
    params = (EffectParam("north_m_s", "m/s", 0.0, -25.0, 25.0, 1.0, init=0.5, grid=(-6.0, 0.0, 6.0),
                          retry_grid=(-10.0, 10.0), mirrored=True),
              EffectParam("east_m_s", "m/s", 0.0, -25.0, 25.0, 1.0, init=0.5, grid=(-6.0, 0.0, 6.0),
                          retry_grid=(-10.0, 10.0), mirrored=True))
    doc = ("steady wind (the air's velocity over ground, towards north/east) through the vessel's windage model (its frontal "
           "and lateral areas and coefficients): a force that turns with the heading, as the simulator's")

    def force(self, v, vessel, water_ne_m_s=(0.0, 0.0)):
        """``water_ne_m_s``: the current fitted beside it (m/s, towards north/east; scalars or (R,) arrays)."""
        from autopilot.sim.model import windage, windage_gains

        w_n, w_e = v["north_m_s"], v["east_m_s"]
        scalar = isinstance(w_n, float)
        cos, sin = (math.cos, math.sin) if scalar else (np.cos, np.sin)
        # no wind is no force, the boat's own air drag included, as in the simulator (make_rhs: no windage term
        # without wind): the other candidates' runs of a batched replay carry this hook at the null value, and
        # the drag of still air there moved their predictions (a calm log's fix_delay went unranked, `none`)
        on = (w_n != 0.0) or (w_e != 0.0) if scalar else ((np.asarray(w_n) != 0.0) | (np.asarray(w_e) != 0.0))
        gains = tuple(k * on for k in windage_gains(vessel))
        # the replay's state moves through the water (prediction._predict), the wind is over ground (as the
        # simulator's, the benchmark's truth and a SimConfig's): the boat's windage sees the wind minus the current.
        # Fitted as the air relative to the water, a wind named beside a 0.2 m/s current was the wind minus the
        # current, its interval 0.04 m/s wide round it (a sysid audit, 2026-12-06)
        a_n, a_e = w_n - water_ne_m_s[0], w_e - water_ne_m_s[1]

        def f(psi, u, vv, r):
            return windage(gains, a_n, a_e, cos(psi), sin(psi), u, vv)

        return f

    def derived(self, value, sigma):
        """Speed and the direction it blows from (meteorological), intervals by the delta method."""
        return polar_rows(value, sigma, "from_deg", 180.0)


class ThrustAsymmetry(Effect):
    name, kind, steady = "thrust_asymmetry", "input", True
    params = (EffectParam("asymmetry_nd", "-", 0.0, -0.6, 0.6, 0.05, grid=(-0.08, -0.04, 0.0, 0.04, 0.08)),)
    doc = "one side pushes more: port thrust x (1 + a), starboard x (1 - a)"
    order = 0
    # 4.3 m/s of wind from 292 beside a port motor 7.6 % weak (three pond logs): wind + thrust_asymmetry (-0.040)
    # was fitted, not wind + weak_motor (the weak motor alone sat on the starboard side, where the wind did not
    # screen beside it); the asymmetry was then dropped as not clearly away from none: unexplained. In its place,
    # the weak motor went to +0.077, 11.7 BIC points better
    sibling = "weak_motor"

    def as_sibling(self, value):
        """The weak motor with the same port/starboard ratio: (1 + a)/(1 - a) = 1 - w (w > 0), 1/(1 + w) (w < 0)."""
        a = float(value["asymmetry_nd"])
        return [-2.0 * a / (1.0 + abs(a))]

    def thrust(self, v, tp, ts, ctx):
        a = np.asarray(v["asymmetry_nd"], dtype=float)
        a = a[:, None] if tp.ndim == 2 else a
        return tp * (1.0 + a), ts * (1.0 - a)


class WeakMotor(Effect):
    # Found by an audit: a port motor 6 % short (a fouled propeller) in three calm pond logs was named `wind`
    # 2.1 m/s, thrust_asymmetry 37 BIC points behind: the asymmetry moves both sides, so it carries a 3 % common
    # thrust gain that a weak motor does not have, and the steady speed tells them apart. One signed parameter,
    # not two gains: a common gain aliases with hydro_refit's resistance in steady running.
    name, kind, steady = "weak_motor", "input", True
    params = (EffectParam("loss_nd", "-", 0.0, -0.6, 0.6, 0.05, grid=(-0.12, -0.05, 0.05, 0.12), mirrored=True),)
    doc = ("one motor makes less than the thrust table, the other as the table: port x (1 - w) when w > 0, "
           "starboard x (1 + w) when w < 0 (a fouled propeller, a weak motor or ESC)")
    order = 0
    sibling = "thrust_asymmetry"

    def as_sibling(self, value):
        """The asymmetry with the same port/starboard ratio (ThrustAsymmetry.as_sibling inverted)."""
        w = float(value["loss_nd"])
        return [-w / (2.0 - abs(w))]

    def thrust(self, v, tp, ts, ctx):
        w = np.asarray(v["loss_nd"], dtype=float)
        port, stbd = weak_motor_gains(w[:, None] if tp.ndim == 2 else w)
        return tp * port, ts * stbd

    def derived(self, value, sigma):
        """The weak motor's thrust as a fraction of the table's (the other makes the table's)."""
        w = value["loss_nd"]
        side = "port" if w >= 0.0 else "stbd"
        row = param_row(f"{side}_gain_nd", "-", 1.0 - abs(w), sigma["loss_nd"])
        row["ci95"] = [max(row["ci95"][0], 0.0), min(row["ci95"][1], 1.0)]  # a weak motor makes no more than the table
        return [row]


def deadband_gain(duty_pct: np.ndarray, threshold_pct: np.ndarray) -> np.ndarray:
    """Thrust gain of a deadband, 0 below the threshold and 1 above, softened over +-DEADBAND_SOFT_PCT."""
    return np.clip((np.abs(duty_pct) - threshold_pct[:, None]) / (2 * DEADBAND_SOFT_PCT) + 0.5, 0.0, 1.0)


class ThrustDeadband(Effect):
    name, kind, steady = "thrust_deadband", "input", True
    params = (EffectParam("threshold_pct", "%", 0.0, 0.0, 60.0, 10.0, fd_step=0.03, init=5.0,
                          grid=(5.0, 12.0, 19.0, 26.0, 33.0, 40.0), stepwise=True),)
    doc = "no thrust below a duty threshold (the motor does not start)"
    order = 1

    def thrust(self, v, tp, ts, ctx):
        d0 = v["threshold_pct"]
        return tp * deadband_gain(ctx["duty_port_pct"], d0), ts * deadband_gain(ctx["duty_stbd_pct"], d0)


def lag_filter(thrust: np.ndarray, tau_s: np.ndarray, dt_s: float) -> np.ndarray:
    """Interval-mean of a first-order lag driven by a zero-order-hold command (exact for ZOH).

    y' = (u - y) / tau; over [t_k, t_k + dt) with u_k held, the mean of y is
    u_k + (y_k - u_k) (tau / dt)(1 - a), a = exp(-dt / tau), and y_{k+1} = a y_k + (1 - a) u_k.
    Using the mean keeps the simulator's zero-order hold centred (no extra half-sample delay).
    """
    from scipy.signal import lfilter

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
        # y_{k+1} = a y_k + (1 - a) u_k  ->  y[1:] from u[:-1], initial state y_0 = u_0 (at rest)
        y[1:], _ = lfilter([1.0 - a], [1.0, -a], u[:-1], zi=[a * u[0]])
        out[j] = u + (y - u) * g
    return out


class ThrustLag(Effect):
    name, kind = "thrust_lag", "input"
    params = (EffectParam("time_constant_s", "s", 0.0, 0.0, 10.0, 0.5, grid=(0.0, 0.5, 1.0, 2.0)),)
    doc = "motor spin-up: thrust follows the command with a first-order lag"
    order = 2  # after the gain effects: the lag acts on the thrust the motor makes

    def thrust(self, v, tp, ts, ctx):
        tau = v["time_constant_s"]
        return lag_filter(tp, tau, ctx["dt_s"]), lag_filter(ts, tau, ctx["dt_s"])


class HeadingBias(Effect):
    name, kind, sensed_order = "heading_bias", "sensor", 2
    params = (EffectParam("bias_deg", "deg", 0.0, -30.0, 30.0, 1.0),)
    doc = "compass mounted off the centre line: it reads psi + bias"

    def sensed(self, v, out, t_s):
        return {**out, "psi_rad": out["psi_rad"] + np.radians(v["bias_deg"])[:, None]}


class AntennaOffset(Effect):
    name, kind, sensed_order = "antenna_offset", "sensor", 1
    params = (EffectParam("forward_m", "m", 0.0, -5.0, 5.0, 0.5), EffectParam("starboard_m", "m", 0.0, -5.0, 5.0, 0.5))
    doc = "GPS antenna away from the centre of gravity (body lever arm)"

    def alias_at_speed(self, value, speed_m_s):
        # three pond logs with a 0.14-s fix delay, cut at a 3-s gap, were named an antenna 0.127 m aft with nothing
        # said of the delay it is on a straight run (a new user's test, 2026-12-07)
        aft_m = -value["forward_m"]
        if aft_m <= 0.0:  # forward of the centre: no latency does that
            return None
        return (f"an antenna {aft_m:.2g} m aft is, on straight runs at the trials' typical {speed_m_s:.2g} m/s, "
                f"fixes {aft_m / speed_m_s:.2g} s late (a receiver's latency): the trials told them apart by their "
                "speed changes and turns, which a short or straight log has few of; if the antenna is known to sit "
                "where the vessel file puts it, the fixes' latency is the likelier cause")

    def sensed(self, v, out, t_s):
        lx, ly = v["forward_m"][:, None], v["starboard_m"][:, None]
        c, s = np.cos(out["psi_rad"]), np.sin(out["psi_rad"])
        return {**out, "north_m": out["north_m"] + lx * c - ly * s, "east_m": out["east_m"] + lx * s + ly * c}


class SensorDelay(Effect):
    name, kind, sensed_order = "sensor_delay", "sensor", 0
    params = (EffectParam("delay_s", "s", 0.0, 0.0, 5.0, 0.3, grid=(0.0, 0.5, 1.0, 1.5)),)
    doc = "position and heading reported late by a fixed delay"

    def sensed(self, v, out, t_s):
        out = {k: a.copy() for k, a in out.items()}
        for j, delay in enumerate(v["delay_s"]):
            if delay > 0:
                tq = np.maximum(t_s - delay, 0.0)
                for k in ("north_m", "east_m", "psi_rad"):
                    out[k][j] = np.interp(tq, t_s, out[k][j])
        return out


class FixDelay(Effect):
    name, kind, sensed_order = "fix_delay", "sensor", 0
    params = (EffectParam("delay_s", "s", 0.0, 0.0, 2.0, 0.1, grid=(0.0, 0.15, 0.4, 0.8)),)
    doc = ("GNSS fixes (the position, and the velocity over ground taken from it) dated late by a fixed delay, the "
           "heading on time: a receiver's output latency, or a fix that waited on the line behind the heading")

    def alias_at_speed(self, value, speed_m_s):
        delay_s = value["delay_s"]
        return (f"fixes {delay_s:.3g} s late are, on straight runs at the trials' typical {speed_m_s:.2g} m/s, an "
                f"antenna {delay_s * speed_m_s:.2g} m aft of where it is said to be: the trials told them apart by "
                "their speed changes and turns, which a short or straight log has few of; if the receiver's latency "
                "is known to be small, the antenna's position is the likelier cause")

    def sensed(self, v, out, t_s):
        out = {k: a.copy() for k, a in out.items()}
        for j, delay in enumerate(v["delay_s"]):
            if delay > 0:
                tq = np.maximum(t_s - delay, 0.0)
                for k in ("north_m", "east_m"):
                    out[k][j] = np.interp(tq, t_s, out[k][j])
        return out


class YawDampingQuadratic(Effect):
    name, kind, steady, vessel_fields = "yaw_damping_quadratic", "force", True, True
    params = (EffectParam("n_rr_nm_s2", "N m s^2", 0.0, -1e5, 1e5, 20.0, grid=(0.0, 15.0, 40.0)),)
    doc = "unmodelled quadratic yaw damping: extra moment -N_rr |r| r"

    def bounds(self, name, vessel):
        p = self.params[0]
        return max(p.lo, -vessel.yaw_damping_quadratic_nm_s2), p.hi

    field_limits: ClassVar[dict] = {"yaw_damping_quadratic_nm_s2": (0.0, math.inf)}

    def fields(self, v, vessel):
        return {"yaw_damping_quadratic_nm_s2": vessel.yaw_damping_quadratic_nm_s2 + float(v["n_rr_nm_s2"])}

    def force(self, v, vessel, water_ne_m_s=(0.0, 0.0)):
        n_rr = v["n_rr_nm_s2"]
        return lambda psi, u, vv, r: (0.0 * r, 0.0 * r, -n_rr * np.abs(r) * r)


class HydroRefit(Effect):
    name, kind, steady, vessel_fields = "hydro_refit", "hydro", True, True
    # screening grids: a yaw damping several times the model's turns every track by tens of degrees, where
    # one start at "no change" stopped at chi-square 17771 (seed 1571499928 of the reliability benchmark)
    params = (EffectParam("resistance_linear_n_s_m", "N s/m", 0.0, -1e3, 1e3, 1.0, grid=(-3.0, 0.0, 3.0)),
              EffectParam("n_r_nd", "-", 0.0, -50.0, 50.0, 0.02, grid=(-0.008, -0.003, 0.0)))
    doc = ("re-fit of existing hydrodynamic coefficients (linear resistance r1, MMG N'_r); "
           "parameters are the new values, fitted as changes from the base set")

    def bounds(self, name, vessel):
        p = next(p for p in self.params if p.name == name)
        if name == "resistance_linear_n_s_m":
            return max(p.lo, -vessel.resistance_linear_n_s_m), p.hi
        if name == "n_r_nd":
            return max(p.lo, -50.0 - vessel.n_r_nd), min(p.hi, -vessel.n_r_nd)
        return p.lo, p.hi

    def reported(self, name, value, vessel):
        return getattr(vessel, name) + value

    field_limits: ClassVar[dict] = {"n_r_nd": (-math.inf, 0.0), "resistance_linear_n_s_m": (0.0, math.inf)}

    def fields(self, v, vessel):
        """Any VesselParams field given as a change (the table mode re-fits more of them)."""
        return {name: getattr(vessel, name) + float(delta) for name, delta in v.items()}

    def force(self, v, vessel, water_ne_m_s=(0.0, 0.0)):
        d_r1 = v["resistance_linear_n_s_m"]
        k_nr = vessel.moment_scale_kg * vessel.length_m * v["n_r_nd"]

        def f(psi, u, vv, r):  # R = r1 u (SPEC 5); N_H term 1/2 rho L^2 d U N'_r L r (Eq 3.21); water-relative u, v
            return -d_r1 * u, 0.0 * u, k_nr * np.sqrt(u * u + vv * vv) * r

        return f


EFFECTS: tuple[Effect, ...] = (
    Current(), WindForce(), Wind(), ThrustAsymmetry(), WeakMotor(), ThrustLag(), ThrustDeadband(), HeadingBias(), AntennaOffset(),
    SensorDelay(), FixDelay(), YawDampingQuadratic(), HydroRefit(),
)

BY_NAME: dict[str, Effect] = {e.name: e for e in EFFECTS}
EFFECT_NAMES: tuple[str, ...] = tuple(BY_NAME)
ALL_KEYS: tuple[str, ...] = tuple(k for e in EFFECTS for k in e.keys)
PARAM_BY_KEY: dict[str, EffectParam] = {e.key(p): p for e in EFFECTS for p in e.params}
THRUST_EFFECTS = tuple(sorted((e for e in EFFECTS if e.thrust is not None), key=lambda e: e.order))
SENSED_EFFECTS = tuple(sorted((e for e in EFFECTS if e.sensed is not None), key=lambda e: e.sensed_order))


def split_key(key: str) -> tuple[Effect, str]:
    """"identifier.param" -> (effect, param name)."""
    name, _, pname = key.partition(".")
    return BY_NAME[name], pname


def bounds(key: str, vessel) -> tuple[float, float]:
    """Bounds of an effect parameter, tightened so the updated VesselParams stays in range."""
    eff, pname = split_key(key)
    return eff.bounds(pname, vessel)


def null_values() -> dict[str, float]:
    """Every effect parameter at its no-effect value."""
    return {k: p.null for k, p in PARAM_BY_KEY.items()}


def by_effect(values: dict) -> dict[Effect, dict]:
    """{"identifier.param": value} -> {effect: {param: value}} (only effects named in ``values``)."""
    out: dict[Effect, dict] = {}
    for key, value in values.items():
        eff, pname = split_key(key)
        out.setdefault(eff, {})[pname] = value
    return out
