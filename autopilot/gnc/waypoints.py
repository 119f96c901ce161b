"""What every guidance law shares: the route, the waypoint index, the speed plan, the end.

A guidance law only answers, for the boat's state and the current target
waypoint, "which heading do I want, and is this waypoint passed?"
(:meth:`WaypointGuidance._steer`). This base class keeps the bookkeeping that
must be the same for every law so that laws can be compared fairly:

- waypoint ``i`` is reached when the law says it is passed, or when the boat
  is within ``capture_radius_m`` of it (the boat on top of the waypoint: the
  bearing is undefined there);
- when a waypoint is reached, how (``capture``: within the radius; ``passed``:
  the law's own test) and the distance then are reported (the closest approach
  over the whole pass is :mod:`autopilot.gnc.passes`' job);
- the wanted speed: the operator's (``speed_override_m_s``), else the per-leg speed or the default, slowed in large heading
  errors (``turn_speed_floor_nd``) and on the approach to the last waypoint and
  to every waypoint it stops at to hold (``stop_indices``);
- the last waypoint: zero thrust and ``complete``; what follows (stop, hold,
  return to launch) is the modes' business (:mod:`autopilot.gnc.modes`).
- the signed cross-track error from the current leg (+ = starboard of it);
  the first leg starts where the boat was at the first step.

Pure: numbers in, numbers out; plain Python floats on the per-step path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from autopilot.geo import wrap_pi
from autopilot.measured import HULL_LENGTH_M

if TYPE_CHECKING:  # pragma: no cover
    from autopilot.gnc.autopilot import NavInput

@dataclass(frozen=True)
class Steer:
    """A law's answer for one cycle."""

    psi_d_rad: float
    passed: bool
    speed_factor_nd: float = 1.0
    tcpa_nd: float | None = None
    dcpa_nd: float | None = None
    cdh: float | None = None


@dataclass(frozen=True)
class GuidanceOutput:
    """Guidance result of one cycle (fed to heading control and allocation)."""

    wp_index: int
    psi_d_rad: float
    speed_cmd_m_s: float
    xte_m: float
    tcpa_nd: float | None
    dcpa_nd: float | None
    cdh: float | None
    reached_index: int | None
    reached_distance_m: float | None  # distance to the reached waypoint at the switch (m)
    reached_how: str | None  # "capture" (within capture_radius_m) or "passed" (the law's test)
    complete: bool
    thrust_off: bool  # command zero thrust: the route is complete


class WaypointGuidance:
    """Route bookkeeping shared by every law; subclasses implement :meth:`_steer`."""

    law_name = "base"

    def __init__(
        self,
        config: Any,  # autopilot.gnc.config.GuidanceConfig
        waypoints_ne_m: Any,
        *,
        speeds_m_s: Any = None,
        boat_length_m: float = HULL_LENGTH_M,
        start_index: int = 0,
        stop_indices=(),
    ) -> None:
        wps = [(float(p[0]), float(p[1])) for p in waypoints_ne_m]
        if not wps:
            raise ValueError("a route needs at least one waypoint")
        if any(not (math.isfinite(n) and math.isfinite(e)) for n, e in wps):
            raise ValueError("waypoints must be finite numbers")
        if not 0 <= start_index < len(wps):
            raise ValueError(f"start_index {start_index} outside 0..{len(wps) - 1}")
        if not boat_length_m > 0:
            raise ValueError("boat_length_m must be > 0")
        speeds = list(speeds_m_s) if speeds_m_s is not None else [None] * len(wps)
        if len(speeds) != len(wps):
            raise ValueError("speeds_m_s must have one entry (or None) per waypoint")
        self.config = config
        self.waypoints = wps
        self.speeds = [None if s is None else float(s) for s in speeds]
        # the operator's speed (m/s) for every leg in place of the planned one (MAVLink DO_CHANGE_SPEED, `ctl
        # speed`), set by the helm each cycle; None: the route's own. Turns and the arrival still slow it
        self.speed_override_m_s: float | None = None
        self.boat_length_m = float(boat_length_m)
        # the boat slows on the approach to these (and to the last): it stops there to hold
        self.stop_indices = frozenset(int(i) for i in stop_indices) | {len(wps) - 1}
        self.index = start_index
        self.complete = False
        self._leg_start: tuple[float, float] | None = (
            wps[start_index - 1] if start_index > 0 else None
        )
        self._armed = False  # laws that switch on "passed abeam" only do so once the target was ahead
        # set by the helm each cycle: the current waypoint lies inside a stopped vessel's safe distance, and the
        # boat is as near as the rules allow within this distance of it (m): counted reached, "occupied"
        self.occupied_reach_m: float | None = None
        self.reset()

    def disarm_pass(self) -> None:
        """After an interruption (a pause, a hold, a jump): the boat may lie pointing away from its target,
        which the "passed abeam" tests would take for having passed it; it must see the target ahead again."""
        self._armed = False

    # ---------------------------------------------------------------- law hooks
    def reset(self) -> None:
        """Forget the law's internal state (integrals); called on waypoint switches too."""

    def _steer(self, nav: NavInput, dt_s: float, i: int) -> Steer:  # pragma: no cover - abstract
        raise NotImplementedError

    # ---------------------------------------------------------------- helpers
    def leg(self, i: int) -> tuple[tuple[float, float], tuple[float, float]]:
        """Start and end of the leg to waypoint i (start = previous waypoint or where the boat began)."""
        start = self._leg_start if self._leg_start is not None else self.waypoints[i]
        return start, self.waypoints[i]

    def _xte_m(self, north_m: float, east_m: float, i: int) -> float:
        (n0, e0), (n1, e1) = self.leg(i)
        dn, de = n1 - n0, e1 - e0
        length = math.hypot(dn, de)
        if length < 1e-9:
            return 0.0
        # starboard normal of the leg direction (cos chi, sin chi) is (-sin chi, cos chi)
        return ((north_m - n0) * (-de) + (east_m - e0) * dn) / length

    def _speed_m_s(self, i: int, distance_m: float, heading_error_rad: float, factor: float) -> float:
        cfg = self.config
        v = (self.speed_override_m_s if self.speed_override_m_s is not None
             else self.speeds[i] if self.speeds[i] is not None else cfg.default_speed_m_s)
        if cfg.turn_speed_floor_nd < 1.0:
            v *= max(cfg.turn_speed_floor_nd, math.cos(heading_error_rad))
        if i in self.stop_indices and cfg.arrival_slowdown_m > 0.0:
            v = min(v, max(cfg.min_speed_m_s, v * distance_m / cfg.arrival_slowdown_m))
        return v * factor

    # ---------------------------------------------------------------- main
    def finish(self) -> None:
        """Count the route done without flying it (a restart on the mission's way home): its end follows at once."""
        self.index = len(self.waypoints) - 1
        self.complete = True

    def update(self, nav: NavInput, dt_s: float, *, may_reach: bool = True) -> GuidanceOutput:
        """One guidance cycle. ``may_reach=False``: steer only (the new target right after a switch, which is judged
        reached the next cycle at the soonest: one reached per cycle, each said; cascaded in one cycle, a waypoint
        within the capture radius of the one before was skipped without a waypoint_reached line)."""
        if self._leg_start is None:
            self._leg_start = (nav.north_m, nav.east_m)
        if self.complete:
            return self._after_end(nav)
        i = self.index
        wn, we = self.waypoints[i]
        d_m = math.hypot(wn - nav.north_m, we - nav.east_m)
        xte = self._xte_m(nav.north_m, nav.east_m, i)
        steer = self._steer(nav, dt_s, i)
        captured = d_m <= self.config.capture_radius_m
        occupied = self.occupied_reach_m is not None and d_m <= self.occupied_reach_m
        if may_reach and (captured or steer.passed or occupied):
            how = "capture" if captured else "passed" if steer.passed else "occupied"
            self.occupied_reach_m = None  # it was this waypoint's: the next one is judged on its own
            self._armed = False
            self._leg_start = self.waypoints[i]
            self.reset()
            if i == len(self.waypoints) - 1:
                self.complete = True
                out = self._after_end(nav)
                return GuidanceOutput(
                    wp_index=i, psi_d_rad=out.psi_d_rad, speed_cmd_m_s=out.speed_cmd_m_s, xte_m=xte,
                    tcpa_nd=steer.tcpa_nd, dcpa_nd=steer.dcpa_nd, cdh=steer.cdh,
                    reached_index=i, reached_distance_m=d_m, reached_how=how, complete=True, thrust_off=True,
                )
            self.index = i + 1
            # steer to the new target in the same cycle: no cycle without a valid command
            nxt = self.update(nav, 0.0, may_reach=False)
            return GuidanceOutput(
                wp_index=nxt.wp_index, psi_d_rad=nxt.psi_d_rad, speed_cmd_m_s=nxt.speed_cmd_m_s,
                xte_m=nxt.xte_m, tcpa_nd=nxt.tcpa_nd, dcpa_nd=nxt.dcpa_nd, cdh=nxt.cdh,
                reached_index=i, reached_distance_m=d_m, reached_how=how, complete=False, thrust_off=False,
            )
        err = wrap_pi(steer.psi_d_rad - nav.psi_rad)
        speed = self._speed_m_s(i, d_m, err, steer.speed_factor_nd)
        return GuidanceOutput(
            wp_index=i, psi_d_rad=wrap_pi(steer.psi_d_rad), speed_cmd_m_s=speed, xte_m=xte,
            tcpa_nd=steer.tcpa_nd, dcpa_nd=steer.dcpa_nd, cdh=steer.cdh,
            reached_index=None, reached_distance_m=None, reached_how=None, complete=False, thrust_off=False,
        )

    def _after_end(self, nav: NavInput) -> GuidanceOutput:
        """Past the last waypoint: zero thrust (the modes decide what comes next)."""
        i = len(self.waypoints) - 1
        return GuidanceOutput(
            wp_index=i, psi_d_rad=nav.psi_rad, speed_cmd_m_s=0.0, xte_m=self._xte_m(nav.north_m, nav.east_m, i),
            tcpa_nd=None, dcpa_nd=None, cdh=None, reached_index=None, reached_distance_m=None, reached_how=None,
            complete=True, thrust_off=True,
        )
