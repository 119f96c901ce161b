"""Unit conversions at the edges (NMEA knots and degrees per minute, people's degrees), written once.

Inside, everything is SI: metres, seconds, radians, newtons (STYLE.md).
"""

from __future__ import annotations

import math

__all__ = ["KNOT_M_S", "knots_to_m_s", "m_s_to_knots", "deg_min_to_rad_s", "rad_s_to_deg_min"]

KNOT_M_S = 1852.0 / 3600.0  # one knot in m/s (exact: a nautical mile is 1852 m)


def knots_to_m_s(speed_kn: float) -> float:
    return speed_kn * KNOT_M_S


def m_s_to_knots(speed_m_s: float) -> float:
    return speed_m_s / KNOT_M_S


def deg_min_to_rad_s(rate_deg_min: float) -> float:
    """NMEA ROT (degrees per minute) to rad/s."""
    return math.radians(rate_deg_min) / 60.0


def rad_s_to_deg_min(rate_rad_s: float) -> float:
    return math.degrees(rate_rad_s) * 60.0
