"""Lookahead line-of-sight path following with a bounded integral (file 004, Eq 9-10).

The path is the straight leg from the previous waypoint (or where the boat
started) to the target waypoint, at path angle chi_p. With the cross-track
error e measured positive to STARBOARD of the leg (docs/log-schema.md), the
correction must steer to port for e > 0, so Eq 10's chi_r = atan(P - I) is
written here with that sign folded in:

    chi_d = chi_p + chi_r,  chi_r = -atan(P + I)              (Eq 10)
    P = K_p e,  K_p = 1 / Delta_s                              (Eq 9)
    I = integral K_i e_i dt, with
        e_i = 0                              if |r| > r_lim or |e| > e_lim  (frozen while turning / far off)
        e_i = e / (k_1 + k_2 |I| / I_max)    if |I| > I_max and e pushes I further out (soft limit)
        e_i = e                              otherwise
    and |I| <= i_hard_max (hard bound, anti-windup).

The integral is what lets LOS hold the line in a current: the boat then
crabs with a heading offset. The waypoint is passed when the boat crosses
the line through it perpendicular to the leg (along-track distance >= leg
length), so an offset track still switches and never circles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.gnc.waypoints import Steer, WaypointGuidance
from autopilot.mathutil import clamp
from autopilot.schema import param


@dataclass(frozen=True)
class LosConfig:
    """Parameters of Eq 9-10 (file 004)."""

    lookahead_m: float = param(8.0, unit="m", lo=0.5, hi=200.0, source="file 004 Eq 9; ~2 L, chosen in simulation", doc="Delta_s; K_p = 1 / Delta_s")
    ki_per_m_s: float = param(0.02, unit="1/(m s)", lo=0.0, hi=10.0, source="chosen in simulation", doc="K_i of the cross-track integral")
    r_lim_rad_s: float = param(0.1, unit="rad/s", lo=0.0, hi=5.0, source="file 004 Eq 10", doc="integral frozen while |r| exceeds this (turning)")
    e_lim_m: float = param(5.0, unit="m", lo=0.0, hi=500.0, source="file 004 Eq 10", doc="integral frozen while |e| exceeds this (far off track)")
    i_max_nd: float = param(0.5, unit="-", lo=0.0, hi=10.0, source="file 004 Eq 10", doc="soft limit of I (beyond it the integral slows down)")
    k1_nd: float = param(1.0, unit="-", lo=0.1, hi=100.0, source="file 004 Eq 10", doc="k_1 of the soft-limit divisor")
    k2_nd: float = param(4.0, unit="-", lo=0.0, hi=100.0, source="file 004 Eq 10", doc="k_2 of the soft-limit divisor")
    i_hard_max_nd: float = param(1.0, unit="-", lo=0.0, hi=10.0, source="bounded integral (SPEC 9)", doc="hard bound of |I|")


class LosGuidance(WaypointGuidance):
    """Baseline: lookahead LOS along each leg (file 004)."""

    law_name = "los"

    def reset(self) -> None:
        self.integral_nd = 0.0

    def _steer(self, nav, dt_s: float, i: int) -> Steer:
        cfg = self.config.los
        (n0, e0), (n1, e1) = self.leg(i)
        dn, de = n1 - n0, e1 - e0
        length = math.hypot(dn, de)
        if length < 1e-6:  # degenerate leg (started on the previous waypoint): pure pursuit
            return Steer(psi_d_rad=math.atan2(e1 - nav.east_m, n1 - nav.north_m), passed=False)
        cos_p, sin_p = dn / length, de / length
        chi_p = math.atan2(de, dn)
        rn, re = nav.north_m - n0, nav.east_m - e0
        along_m = rn * cos_p + re * sin_p
        e_m = -rn * sin_p + re * cos_p  # + starboard of the leg
        i_val = self.integral_nd
        if abs(nav.yaw_rate_rad_s) > cfg.r_lim_rad_s or abs(e_m) > cfg.e_lim_m:
            e_i = 0.0
        elif (i_val > cfg.i_max_nd and e_m > 0.0) or (i_val < -cfg.i_max_nd and e_m < 0.0):
            e_i = e_m / (cfg.k1_nd + cfg.k2_nd * abs(i_val) / max(cfg.i_max_nd, 1e-9))
        else:
            e_i = e_m
        i_val += cfg.ki_per_m_s * e_i * dt_s
        lim = cfg.i_hard_max_nd
        self.integral_nd = clamp(i_val, -lim, lim)
        chi_r = -math.atan(e_m / cfg.lookahead_m + self.integral_nd)
        return Steer(psi_d_rad=chi_p + chi_r, passed=along_m >= length)
