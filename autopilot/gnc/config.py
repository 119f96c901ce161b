"""Configuration of the whole GNC stack: guidance (with each law's own section), PID, allocation, hold.

Every field is declared once with unit, range and source; YAML keys are the
field names (``autopilot.schema.load(GncConfig, mapping)``).
"""

from __future__ import annotations

from dataclasses import dataclass

from autopilot.gnc.allocation import AllocationConfig
from autopilot.gnc.avoidance import AvoidanceConfig
from autopilot.gnc.fuzzy_guidance import FuzzyConfig
from autopilot.gnc.los import LosConfig
from autopilot.gnc.pid import PidConfig
from autopilot.gnc.proportional import ProportionalConfig
from autopilot.gnc.registry import GUIDANCE_LAWS
from autopilot.gnc.speed import MAX_SPEED_M_S, MIN_SPEED_M_S, SpeedTrimConfig
from autopilot.gnc.station_keeping import HoldConfig
from autopilot.schema import param

LAWS = tuple(GUIDANCE_LAWS)  # the registry owns the names


@dataclass(frozen=True)
class GuidanceConfig:
    """Outer loop: which law, how fast, what happens at the end."""

    law: str = param("fuzzy", choices=LAWS, source="thesis ch. 6 (fuzzy); files 004, 003 (baselines)", doc="guidance law")
    final_action: str = param("stop", choices=("stop", "hold"), source="thesis 9.1 (stops near the last waypoint)", doc="at the last waypoint (unless the mission ends with rtl): zero thrust and the run ends, or hold station on it (gnc.hold) until commanded")
    default_speed_m_s: float = param(1.0, unit="m/s", lo=MIN_SPEED_M_S, hi=MAX_SPEED_M_S, source="Fig 8.2 (CC ~ 1.09 m/s); chosen for pond-sized legs", doc="wanted speed where a leg has none")
    min_speed_m_s: float = param(0.3, unit="m/s", lo=0.0, hi=MAX_SPEED_M_S, source="Fig 8.2 (BB ~ 0.25 m/s)", doc="floor of the arrival slow-down (the boat must still arrive)")
    arrival_slowdown_m: float = param(6.0, unit="m", lo=0.0, hi=200.0, source="chosen in simulation", doc="speed falls linearly to min_speed over this distance before the last waypoint (0 = off)")
    turn_speed_floor_nd: float = param(0.5, unit="-", lo=0.0, hi=1.0, source="chosen in simulation", doc="speed is scaled by max(this, cos(heading error)); 1 = never slow for turns")
    capture_radius_m: float = param(1.0, unit="m", lo=0.0, hi=50.0, source="guard: bearing undefined on top of a waypoint", doc="a waypoint closer than this counts as reached")
    final_pass_s: float = param(3.0, unit="s", lo=0.0, hi=60.0, source="chosen: three 1 Hz fixes (autopilot.gnc.passes)", doc="after the route is complete (the last waypoint reached, its hold item over), fixes still count towards its closest approach for this long (zero thrust, or holding); then the mission ends")
    fuzzy: FuzzyConfig = param(default_factory=FuzzyConfig, doc="fuzzy guidance universes (thesis ch. 6)")
    los: LosConfig = param(default_factory=LosConfig, doc="line-of-sight baseline (file 004)")
    proportional: ProportionalConfig = param(default_factory=ProportionalConfig, doc="proportional baseline (file 003)")


@dataclass(frozen=True)
class GncConfig:
    """The double-loop controller: guidance -> PID -> allocation."""

    guidance: GuidanceConfig = param(default_factory=GuidanceConfig, doc="outer loop")
    pid: PidConfig = param(default_factory=PidConfig, doc="inner loop, Eq 7.1")
    allocation: AllocationConfig = param(default_factory=AllocationConfig, doc="Eq 8.5-8.6")
    speed: SpeedTrimConfig = param(default_factory=SpeedTrimConfig, doc="speed-over-ground trim on tau_com (SPEC 8: tau_com keeps the speed)")
    hold: HoldConfig = param(default_factory=HoldConfig, doc="station keeping (hold, paused, rtl's end, mission hold items)")
    avoidance: AvoidanceConfig = param(default_factory=AvoidanceConfig, doc="collision avoidance of AIS targets under COLREGs (issue 18)")
