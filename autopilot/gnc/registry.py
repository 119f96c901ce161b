"""Guidance laws by configuration name: one dict, no string comparisons elsewhere."""

from __future__ import annotations

from autopilot.gnc.fuzzy_guidance import FuzzyGuidance
from autopilot.gnc.los import LosGuidance
from autopilot.gnc.proportional import ProportionalGuidance
from autopilot.gnc.waypoints import WaypointGuidance
from autopilot.measured import HULL_LENGTH_M

GUIDANCE_LAWS: dict[str, type[WaypointGuidance]] = {
    "fuzzy": FuzzyGuidance,
    "los": LosGuidance,
    "proportional": ProportionalGuidance,
}


def make_guidance(config, waypoints_ne_m, *, speeds_m_s=None, boat_length_m: float = HULL_LENGTH_M, start_index: int = 0,
                  stop_indices=()) -> WaypointGuidance:
    """The guidance law named by ``config.law`` (a GuidanceConfig) for a route."""
    try:
        cls = GUIDANCE_LAWS[config.law]
    except KeyError:
        raise ValueError(f"unknown guidance law {config.law!r} (known: {', '.join(GUIDANCE_LAWS)})") from None
    return cls(config, waypoints_ne_m, speeds_m_s=speeds_m_s, boat_length_m=boat_length_m, start_index=start_index,
               stop_indices=stop_indices)
