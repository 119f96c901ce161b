"""Where the simulated boat was, kept in the state directory so a ``--sim`` restart finds it there.

A real boat is where it drifted when the daemon comes back after a crash; ``--sim`` put its boat back at the
launch point, so a bench test of resume-after-restart flew the resumed leg from home (stop 49's note). The
daemon's ``--sim`` keeps the boat's position and heading in ``<state_dir>/sim-boat.json`` once a simulated
second, and a restart that carries the run on (not ``--fresh``) starts the boat there, at rest: the motors
stopped with the daemon (the firmware's stop), and the seconds a restart takes are not simulated.

Latitude and longitude, not the mission's local frame: the file says where, whatever frame reads it.
Written by rename, not fsync'd: a bench run's file, which a kill -9 leaves in the page cache.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from autopilot.geo import latlon_to_local

__all__ = ["SIM_BOAT_FILE", "save_boat", "load_boat", "keep_boat"]

SIM_BOAT_FILE = "sim-boat.json"
SAVE_PERIOD_S = 1.0  # simulated seconds between saves


def save_boat(path: Path, boat) -> None:
    """The boat's position (degrees) and heading (degrees) to ``path``, replaced whole."""
    lat, lon = boat.latlon_deg()
    data = {"lat_deg": lat, "lon_deg": lon, "heading_deg": boat.heading_deg}
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data), encoding="utf-8")
    os.replace(tmp, path)


def load_boat(path: Path, origin_lat_deg: float, origin_lon_deg: float) -> tuple[float, ...] | None:
    """The saved boat as a model state at rest ``(north_m, east_m, psi_rad, 0, 0, 0)`` in the frame of the origin
    given, or None when there is no file or it cannot be read (then the boat starts at the launch point)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        lat, lon, heading = (float(data[k]) for k in ("lat_deg", "lon_deg", "heading_deg"))
    except (OSError, ValueError, KeyError, TypeError, RecursionError):  # RecursionError: '[' * 100000
        return None
    if not (abs(lat) <= 90.0 and abs(lon) <= 180.0 and math.isfinite(heading)):
        return None
    north, east = latlon_to_local(lat, lon, origin_lat_deg, origin_lon_deg)
    return float(north), float(east), math.radians(heading) % (2.0 * math.pi), 0.0, 0.0, 0.0


async def keep_boat(path: Path, boat, clock) -> None:
    """Save the boat now (a file an older run left is not this one's) and every SAVE_PERIOD_S of the clock until
    cancelled (a task of the daemon's ``--sim``)."""
    t_s = clock.now_s()
    while True:
        try:
            save_boat(path, boat)
        except OSError:  # a full disk: the bench run goes on, a restart starts at the launch point
            pass
        t_s += SAVE_PERIOD_S
        await clock.sleep_until(t_s)
