"""Dead reckoning between position fixes.

The SC-30 gives heading at 10 Hz but position (GGA/RMC) at 1 Hz on a 4800-baud
line (SPEC 10). Held between fixes, the position lags the boat by up to one
second -- 1.5 m at cruise, the size of a waypoint tolerance -- and TCPA'/DCPA'
move in steps. The guidance therefore uses the last fix carried forward by the
velocity over ground over the fix's age. Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math

MIN_SOG_FOR_COG_M_S = 0.3  # below this the GNSS course is noise: carry along the heading instead


def dead_reckon_ne(
    north_m: float,
    east_m: float,
    age_s: float,
    sog_m_s: float | None,
    cog_rad: float | None,
    heading_rad: float | None,
    *,
    max_age_s: float,
) -> tuple[float, float]:
    """The fix (north_m, east_m) carried forward ``min(age_s, max_age_s)`` seconds at the velocity over ground.

    The direction is the course over ground when the speed is at least
    MIN_SOG_FOR_COG_M_S (a crabbing boat moves along its course, not its bow),
    else the heading. Without a speed, or with ``max_age_s`` = 0, the fix is returned.
    """
    if sog_m_s is None or not math.isfinite(sog_m_s) or max_age_s <= 0 or not (age_s > 0):
        return north_m, east_m
    direction = cog_rad if (cog_rad is not None and sog_m_s >= MIN_SOG_FOR_COG_M_S) else heading_rad
    if direction is None or not math.isfinite(direction):
        return north_m, east_m
    travel_m = sog_m_s * min(age_s, max_age_s)
    return north_m + travel_m * math.cos(direction), east_m + travel_m * math.sin(direction)
