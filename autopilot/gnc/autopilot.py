"""The double-loop autopilot (thesis ch. 7-8): guidance -> heading PID -> thrust allocation.

    nav (position, heading, speed, yaw rate) --> guidance law --> psi_d, speed
    psi_d, psi, r                            --> PID (Eq 7.1)  --> tau_order
    speed cmd, speed over ground             --> Fig 8.2 table + PI trim --> tau_com
    tau_com, tau_order                       --> Eq 8.5-8.6, saturation --> T_port, T_stbd --> PWM

Pure: the caller (daemon, simulator, evaluation) supplies the navigation
data and the time step; nothing here reads a clock or a device.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.gnc.allocation import Allocator, common_thrust_n
from autopilot.gnc.config import GncConfig
from autopilot.gnc.pid import HeadingPid
from autopilot.gnc.registry import make_guidance
from autopilot.gnc.speed import SpeedTrim
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.measured import HULL_LENGTH_M


@dataclass(frozen=True)
class NavInput:
    """What the autopilot needs to know each cycle (SI, local frame)."""

    north_m: float
    east_m: float
    psi_rad: float  # heading from north, clockwise
    speed_m_s: float  # speed over ground
    yaw_rate_rad_s: float  # > 0 turning to starboard
    course_rad: float  # course over ground (may equal psi when unknown)


@dataclass(frozen=True)
class ControlOutput:
    """One cycle's command and the reasons for it (the GNC fields of a log `cycle` line)."""

    wp_index: int
    tcpa_nd: float | None
    dcpa_nd: float | None
    cdh: float | None
    psi_d_rad: float
    heading_error_rad: float
    xte_m: float
    speed_cmd_m_s: float
    pid_p_n: float
    pid_i_n: float
    pid_d_n: float
    tau_com_n: float
    tau_order_n: float
    thrust_port_n: float
    thrust_stbd_n: float
    pwm_port_pct: float
    pwm_stbd_pct: float
    sat_port: bool
    sat_stbd: bool
    saturation: tuple[str, ...]
    turn_limit: int  # the allocation's: +1 a starboard turn cut, -1 a port turn, 0 delivered
    common_limit: int  # +1 the common thrust cut down (speed not delivered), -1 cut up, 0 delivered
    reached_index: int | None
    reached_distance_m: float | None  # distance to the reached waypoint at the switch (m)
    reached_how: str | None  # "capture" or "passed" (autopilot.gnc.waypoints)
    complete: bool
    tau_com_trim_n: float = 0.0  # speed-over-ground trim inside tau_com_n (tau_com_n = table + trim)
    thrust_off: bool = False  # the guidance asks for zero thrust (mission over, or holding inside the radius)
    finished: bool = False  # the last waypoint is reached and the final action is to stop: the run may end


class Autopilot:
    """Guidance + PID + allocation for one route. ``step`` once per control cycle."""

    def __init__(
        self,
        config: GncConfig,
        waypoints_ne_m,
        *,
        speeds_m_s=None,
        boat_length_m: float = HULL_LENGTH_M,
        thrust_curve: ThrustCurve = ThrustCurve(),
        start_index: int = 0,
    ) -> None:
        self.config = config
        self.guidance = make_guidance(
            config.guidance, waypoints_ne_m, speeds_m_s=speeds_m_s, boat_length_m=boat_length_m, start_index=start_index
        )
        self.pid = HeadingPid(config.pid)
        self.allocator = Allocator(config.allocation, thrust_curve)
        self.speed_trim = SpeedTrim(config.speed)

    @property
    def wp_index(self) -> int:
        """Index of the waypoint being steered to."""
        return self.guidance.index

    @property
    def complete(self) -> bool:
        """The last waypoint has been reached."""
        return self.guidance.complete

    def reset_integrator(self) -> None:
        """Zero the heading and speed integrals (after a failsafe, before resuming)."""
        self.pid.reset()
        self.speed_trim.reset()

    def step(self, nav: NavInput, dt_s: float) -> ControlOutput:
        """One control cycle: navigation data and the time since the last cycle -> command."""
        if not (math.isfinite(nav.north_m) and math.isfinite(nav.east_m) and math.isfinite(nav.psi_rad)):
            raise ValueError("NavInput position and heading must be finite")
        g = self.guidance.update(nav, dt_s)
        terms = self.pid.terms(g.psi_d_rad, nav.psi_rad, nav.yaw_rate_rad_s)
        if g.thrust_off:
            self.pid.reset()
            self.speed_trim.reset()
            alloc = self.allocator.allocate(0.0, 0.0)
            p_n = i_n = d_n = trim_n = 0.0
        else:
            p_n, i_n, d_n = terms.p_n, terms.i_n, terms.d_n
            speed_n = nav.speed_m_s if math.isfinite(nav.speed_m_s) else g.speed_cmd_m_s  # no speed: table only
            trim_n = self.speed_trim.terms(g.speed_cmd_m_s, speed_n).trim_n
            tau_com = common_thrust_n(g.speed_cmd_m_s) + trim_n
            floor = tau_com <= 0.0
            if floor:  # never astern common mode (see autopilot.gnc.speed)
                trim_n -= tau_com
                tau_com = 0.0
            alloc = self.allocator.allocate(tau_com, p_n + i_n + d_n)
            self.pid.integrate(terms.heading_error_rad, dt_s, turn_limit=alloc.turn_limit)
            # the allocator cut the common mode: more speed cannot be delivered
            self.speed_trim.integrate(g.speed_cmd_m_s, speed_n, dt_s, block_up=alloc.common_limit > 0,
                                      block_down=floor)
        return ControlOutput(
            wp_index=g.wp_index,
            tcpa_nd=g.tcpa_nd,
            dcpa_nd=g.dcpa_nd,
            cdh=g.cdh,
            psi_d_rad=g.psi_d_rad,
            heading_error_rad=terms.heading_error_rad,
            xte_m=g.xte_m,
            speed_cmd_m_s=g.speed_cmd_m_s,
            pid_p_n=p_n,
            pid_i_n=i_n,
            pid_d_n=d_n,
            tau_com_n=alloc.tau_com_n,
            tau_order_n=alloc.tau_order_n,
            thrust_port_n=alloc.thrust_port_n,
            thrust_stbd_n=alloc.thrust_stbd_n,
            pwm_port_pct=alloc.pwm_port_pct,
            pwm_stbd_pct=alloc.pwm_stbd_pct,
            sat_port=alloc.sat_port,
            sat_stbd=alloc.sat_stbd,
            saturation=alloc.saturation,
            turn_limit=alloc.turn_limit,
            common_limit=alloc.common_limit,
            reached_index=g.reached_index,
            reached_distance_m=g.reached_distance_m,
            reached_how=g.reached_how,
            complete=g.complete,
            tau_com_trim_n=trim_n,
            thrust_off=g.thrust_off,
            finished=g.finished,
        )
