"""Proportional waypoint logic of file 003 (Huang & Bucchi, section 2.3), for differential thrust.

File 003 steers a single vectored thruster: heading demand hd = bearing of
the waypoint, dhd = hd - z wrapped to [-pi, pi], and

    |dhd| <  pi/2 : b = b_max dhd / (pi/2),  F = F_max                (small turn)
    |dhd| >= pi/2 : b = b_max sign(dhd),     F = F_max / 2           (large turn)
                    F = (F_max / 3)(dst / wp_sh)  when dst <= wp_sh   (near the waypoint)
    dst <= wp_tol : waypoint reached

Adapted to the WAM-V's fixed twin thrusters: the demand heading goes to the
same heading PID as every other law (the thrust angle's proportional yaw
moment b_max dhd / (pi/2) is what the PID's P term does), and the thrust
force schedule becomes the wanted-speed factor (1, 1/2, (1/3) dst/wp_sh) on
the default speed. There is no "passed abeam" test in file 003: a boat that
cannot turn inside wp_tol circles the waypoint. That is the baseline's
known weakness and is kept, bounded only by the evaluation's time limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.geo import wrap_pi
from autopilot.gnc.waypoints import Steer, WaypointGuidance
from autopilot.schema import param


@dataclass(frozen=True)
class ProportionalConfig:
    """Parameters of file 003's navigation logic."""

    wp_tol_m: float = param(1.5, unit="m", lo=0.1, hi=100.0, source="file 003 (1 m for a 1 m boat; 1.5 m here)", doc="waypoint reached within this distance")
    wp_sh_m: float = param(10.0, unit="m", lo=0.1, hi=200.0, source="file 003 (10-20 m)", doc="distance below which large turns slow further")
    min_factor_nd: float = param(0.25, unit="-", lo=0.0, hi=1.0, source="guard (file 003 lets F reach 0 at the waypoint)", doc="floor of the large-turn speed factor")


class ProportionalGuidance(WaypointGuidance):
    """Baseline: file 003's proportional logic (bearing pursuit with a thrust schedule)."""

    law_name = "proportional"

    def _steer(self, nav, dt_s: float, i: int) -> Steer:
        cfg = self.config.proportional
        wn, we = self.waypoints[i]
        dn, de = wn - nav.north_m, we - nav.east_m
        dst = math.hypot(dn, de)
        hd = math.atan2(de, dn) if dst > 0.0 else nav.psi_rad
        dhd = wrap_pi(hd - nav.psi_rad)
        if abs(dhd) < 0.5 * math.pi:
            factor = 1.0
        elif dst <= cfg.wp_sh_m:
            factor = max(cfg.min_factor_nd, dst / cfg.wp_sh_m / 3.0)
        else:
            factor = 0.5
        return Steer(psi_d_rad=hd, passed=dst <= cfg.wp_tol_m, speed_factor_nd=factor)
