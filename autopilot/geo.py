"""Angles and the local north-east frame (SPEC section 2).

Heading is measured from north, clockwise positive. The local frame is a
flat-earth tangent plane at an origin (the launch point): north_m, east_m.
Over a pond or a harbour (a few km) the equirectangular approximation on the
WGS-84 ellipsoid is accurate to centimetres.
"""

from __future__ import annotations

import math

import numpy as np

WGS84_A_M = 6378137.0  # semi-major axis (m)
WGS84_F = 1.0 / 298.257223563  # flattening (-)
_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared (-)


_TWO_PI = 2.0 * math.pi


def wrap_pi(angle_rad):
    """An angle (rad) wrapped to (-pi, pi]; a float for a Python number (fast: the GNC's per-cycle
    path), an array for an array. The one wrap of the project: every angle difference goes through it."""
    if isinstance(angle_rad, (float, int)):
        a = math.fmod(angle_rad + math.pi, _TWO_PI)
        if a <= 0.0:
            a += _TWO_PI
        return a - math.pi
    wrapped = np.mod(np.asarray(angle_rad, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    wrapped = np.where(wrapped == -np.pi, np.pi, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def wrap_180(angle_deg):
    """An angle in degrees wrapped to (-180, 180] (float or array, as :func:`wrap_pi`)."""
    if isinstance(angle_deg, (float, int)):
        a = math.fmod(angle_deg + 180.0, 360.0)
        if a <= 0.0:
            a += 360.0
        return a - 180.0
    wrapped = np.mod(np.asarray(angle_deg, dtype=float) + 180.0, 360.0) - 180.0
    wrapped = np.where(wrapped == -180.0, 180.0, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def wrap_360(angle_deg):
    """An angle in degrees wrapped to [0, 360) (float or array)."""
    if isinstance(angle_deg, (float, int)):
        a = math.fmod(angle_deg, 360.0)
        if a < 0.0:
            a += 360.0
        return 0.0 if a >= 360.0 else a
    wrapped = np.mod(np.asarray(angle_deg, dtype=float), 360.0)
    wrapped = np.where(wrapped >= 360.0, 0.0, wrapped)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def _radii_m(lat0_deg: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature at a latitude (m)."""
    s = math.sin(math.radians(lat0_deg))
    w = math.sqrt(1.0 - _E2 * s * s)
    meridian_m = WGS84_A_M * (1.0 - _E2) / w**3
    prime_vertical_m = WGS84_A_M / w
    return meridian_m, prime_vertical_m


def latlon_to_local(lat_deg, lon_deg, origin_lat_deg: float, origin_lon_deg: float):
    """Latitude/longitude (deg) to local (north_m, east_m) around an origin."""
    meridian_m, prime_m = _radii_m(origin_lat_deg)
    if isinstance(lat_deg, (float, int)) and isinstance(lon_deg, (float, int)):  # one fix a cycle: plain floats,
        dlat = math.radians(lat_deg - origin_lat_deg)  # the same operations as below (the same bits), no numpy
        dlon = math.radians(wrap_180(lon_deg - origin_lon_deg))
        return dlat * meridian_m, dlon * prime_m * math.cos(math.radians(origin_lat_deg))
    dlat = np.radians(np.asarray(lat_deg, dtype=float) - origin_lat_deg)
    dlon = np.radians(wrap_180(np.asarray(lon_deg, dtype=float) - origin_lon_deg))
    north_m = dlat * meridian_m
    east_m = dlon * prime_m * math.cos(math.radians(origin_lat_deg))
    if np.ndim(north_m) == 0:
        return float(north_m), float(east_m)
    return north_m, east_m


def local_to_latlon(north_m, east_m, origin_lat_deg: float, origin_lon_deg: float):
    """Local (north_m, east_m) around an origin to latitude/longitude (deg)."""
    meridian_m, prime_m = _radii_m(origin_lat_deg)
    if isinstance(north_m, (float, int)) and isinstance(east_m, (float, int)):  # plain floats, the same bits
        lat = origin_lat_deg + math.degrees(north_m / meridian_m)
        lon = origin_lon_deg + math.degrees(east_m / (prime_m * math.cos(math.radians(origin_lat_deg))))
        return lat, wrap_180(lon)
    lat = origin_lat_deg + np.degrees(np.asarray(north_m, dtype=float) / meridian_m)
    lon = origin_lon_deg + np.degrees(
        np.asarray(east_m, dtype=float) / (prime_m * math.cos(math.radians(origin_lat_deg)))
    )
    lon = wrap_180(lon)
    if np.ndim(lat) == 0:
        return float(lat), float(lon)
    return lat, lon
