"""Thrust allocation (thesis Eq 8.5-8.6, SPEC section 8) and thrust -> PWM (SPEC section 4).

    T_port      = tau_com + tau_order                     (Eq 8.5)
    T_starboard = tau_com - tau_order                     (Eq 8.6)

tau_com keeps the speed: it is the common-mode thrust that the measured
free-running table (thesis Fig 8.2, ``autopilot.measured.MEASURED_TABLE``)
gives for the wanted speed on a straight course. tau_order comes from the
heading PID; tau_order > 0 turns to starboard (SPEC 2).

Saturation keeps the turn: the differential part is only cut when it alone
exceeds half the thrusters' span, and the common part gives way first. The
result reports, per axis, whether the turn and the common thrust were cut
(:class:`Allocation`), so the heading PID stops winding up only when the turn
is limited, and which limit each side's request hit (``port_upper`` ...) for
the log.

The per-cycle path is plain Python (numpy's per-call overhead is larger
than the arithmetic for two scalars); the table inverse that takes a
wanted speed AND yaw rate is a planning helper and may use numpy/scipy.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.mathutil import clamp
from autopilot.measured import MAX_THRUST_N, MEASURED_TABLE
from autopilot.schema import param

# Straight, forward rows of Fig 8.2: speed (m/s) <-> thrust per thruster (N), monotonic.
_STRAIGHT = sorted((r.speed_m_s, r.thrust_port_n) for r in MEASURED_TABLE if r.kind == "straight")
SPEED_TABLE_M_S: tuple[float, ...] = tuple(s for s, _ in _STRAIGHT)
THRUST_TABLE_N: tuple[float, ...] = tuple(t for _, t in _STRAIGHT)


def interp1(x: float, xs, ys) -> float:
    """Piecewise-linear interpolation, clamped at the ends (plain floats; xs increasing)."""
    if x <= xs[0]:
        return float(ys[0])
    if x >= xs[-1]:
        return float(ys[-1])
    k = bisect.bisect_right(xs, x)
    x0, x1 = xs[k - 1], xs[k]
    return ys[k - 1] + (ys[k] - ys[k - 1]) * (x - x0) / (x1 - x0)


def common_thrust_n(speed_m_s: float) -> float:
    """tau_com: thrust per thruster that holds ``speed_m_s`` straight ahead (Fig 8.2 table)."""
    return interp1(speed_m_s, SPEED_TABLE_M_S, THRUST_TABLE_N) if speed_m_s > 0.0 else 0.0


def speed_for_common_thrust_m_s(thrust_n: float) -> float:
    """The table read backwards: steady straight speed for a common thrust per thruster."""
    return interp1(thrust_n, THRUST_TABLE_N, SPEED_TABLE_M_S) if thrust_n > 0.0 else 0.0


def table_thrusts_n(speed_m_s, yaw_rate_rad_s):
    """The thesis's inverse use of the whole table: (U, r) wanted -> (T_port, T_stbd).

    Linear interpolation over a triangulation of the measured (U, r) points
    (the turning rows, their mirror images for starboard turns, and the
    straight rows); outside the measured envelope, the nearest measured row.
    Vectorised; for planning and feed-forward, not on the per-cycle path.
    """
    import numpy as np
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

    pts, vals = [], []
    for r in MEASURED_TABLE:
        if r.kind == "reverse":
            continue
        pts.append((r.speed_m_s, r.yaw_rate_rad_s))
        vals.append((r.thrust_port_n, r.thrust_stbd_n))
        if r.kind == "turn":  # mirror: swap sides, opposite turn
            pts.append((r.speed_m_s, -r.yaw_rate_rad_s))
            vals.append((r.thrust_stbd_n, r.thrust_port_n))
    pts_a, vals_a = np.asarray(pts), np.asarray(vals)
    q = np.stack(np.broadcast_arrays(np.asarray(speed_m_s, float), np.asarray(yaw_rate_rad_s, float)), axis=-1)
    lin = LinearNDInterpolator(pts_a, vals_a)(q)
    near = NearestNDInterpolator(pts_a, vals_a)(q)
    out = np.where(np.isnan(lin), near, lin)
    if out.shape[:-1] == (1,) and np.ndim(speed_m_s) == 0 and np.ndim(yaw_rate_rad_s) == 0:
        return float(out[0, 0]), float(out[0, 1])
    return out[..., 0], out[..., 1]


@dataclass(frozen=True)
class AllocationConfig:
    """Thruster limits used by the allocator (the thrust curve's own ends if larger)."""

    max_forward_n: float = param(MAX_THRUST_N, unit="N", lo=0.0, hi=500.0, source="Table 4.2 level F", doc="largest forward thrust per thruster commanded")
    max_reverse_n: float = param(MAX_THRUST_N, unit="N", lo=0.0, hi=500.0, source="Table 4.2 level f", doc="largest reverse thrust magnitude per thruster commanded")
    allow_reverse: bool = param(True, source="Table 4.2 (reverse levels exist)", doc="let a thruster run astern to turn harder")

    def __post_init__(self) -> None:
        if self.max_forward_n == 0.0:  # the boat sat at the start for 30 minutes (a new user's test)
            from autopilot.schema import ConfigError

            raise ConfigError("gnc.allocation: max_forward_n is 0: the boat can never go ahead; give the thrust a thruster "
                              "may make ahead (N)")


@dataclass(frozen=True)
class Allocation:
    """One allocation: thrusts after saturation and what limited them.

    ``turn_limit``: +1 when a turn to starboard (tau_order > 0) was cut, -1 a turn to port, 0 when
    the whole differential was delivered; ``common_limit``: +1 when the common thrust was cut down
    (the speed cannot be delivered), -1 cut up, 0 delivered. Per axis, as ArduPilot's skid-steer
    mixer reports ``steer_left/right`` and ``throttle_upper/lower``: the heading PID's anti-windup
    looks at the turn, the speed trim at the common thrust (a speed limit alone must not freeze the
    heading integral that holds the course in a current). ``saturation`` lists, per thruster, the
    limit its request went past (the log's and the review's view).
    """

    tau_com_n: float
    tau_order_n: float
    thrust_port_n: float
    thrust_stbd_n: float
    pwm_port_pct: float
    pwm_stbd_pct: float
    sat_port: bool
    sat_stbd: bool
    saturation: tuple[str, ...]
    tau_order_applied_n: float  # differential thrust actually delivered
    turn_limit: int = 0
    common_limit: int = 0


class Allocator:
    """Eq 8.5-8.6 with turn-keeping saturation and thrust -> signed PWM duty (SPEC 4)."""

    def __init__(self, config: AllocationConfig = AllocationConfig(), curve: ThrustCurve = ThrustCurve()) -> None:
        self.config = config
        self.curve = curve
        self.upper_n = min(config.max_forward_n, curve.max_forward_n)
        self.lower_n = -min(config.max_reverse_n, curve.max_reverse_n) if config.allow_reverse else 0.0
        self._fwd = (tuple(curve.forward_thrust_n), tuple(curve.forward_duty_pct))
        self._rev = (tuple(curve.reverse_thrust_n), tuple(curve.reverse_duty_pct))

    def signed_duty_pct(self, thrust_n: float) -> float:
        """Signed PWM duty (%) for a thrust (N), negative = reverse (same as ThrustCurve.signed_duty_pct)."""
        if thrust_n >= 0.0:
            return interp1(thrust_n, *self._fwd)
        return -interp1(-thrust_n, *self._rev)

    def allocate(self, tau_com_n: float, tau_order_n: float) -> Allocation:
        hi, lo = self.upper_n, self.lower_n
        port_req, stbd_req = tau_com_n + tau_order_n, tau_com_n - tau_order_n
        half_span = 0.5 * (hi - lo)
        d = clamp(tau_order_n, -half_span, half_span)
        ad = abs(d)
        c_lo, c_hi = lo + ad, hi - ad
        c = clamp(tau_com_n, c_lo, c_hi)
        port, stbd = c + d, c - d
        eps = 1e-9
        turn_limit = 0 if abs(d) >= abs(tau_order_n) - eps else (1 if tau_order_n > 0 else -1)
        common_limit = 1 if c < tau_com_n - eps else -1 if c > tau_com_n + eps else 0
        sat: list[str] = []
        if port_req > hi + eps:
            sat.append("port_upper")
        elif port_req < lo - eps:
            sat.append("port_lower")
        if stbd_req > hi + eps:
            sat.append("stbd_upper")
        elif stbd_req < lo - eps:
            sat.append("stbd_lower")
        return Allocation(
            tau_com_n=tau_com_n,
            tau_order_n=tau_order_n,
            thrust_port_n=port,
            thrust_stbd_n=stbd,
            pwm_port_pct=self.signed_duty_pct(port),
            pwm_stbd_pct=self.signed_duty_pct(stbd),
            sat_port=bool(sat and sat[0].startswith("port")),
            sat_stbd=any(s.startswith("stbd") for s in sat),
            saturation=tuple(sat),
            tau_order_applied_n=d,
            turn_limit=turn_limit,
            common_limit=common_limit,
        )
