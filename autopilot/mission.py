"""Missions: waypoint files in four formats, checked and converted to the local frame.

Formats (chosen by file extension):

- ``.yaml`` / ``.yml``: ``name`` (optional), ``frame: local`` (``north_m``,
  ``east_m``) or ``frame: latlon`` (``lat_deg``, ``lon_deg``), optional
  ``origin: {lat_deg, lon_deg}`` and ``home: {lat_deg, lon_deg}``, and
  ``waypoints``: a list of mappings with those keys and an optional
  ``speed_m_s`` for the leg to that waypoint (or of bare ``[north, east]``
  pairs in the local frame). A waypoint may carry ``hold_s`` (hold station
  there that long, then go on) or ``hold: true`` (hold until an operator
  says ``resume``); the last item may be ``rtl`` (return to the launch point,
  then hold there).
- ``.csv``: a header naming ``north_m,east_m`` or ``lat_deg,lon_deg``, plus
  optional ``speed_m_s`` and ``hold_s`` (seconds held there; empty: none); other
  columns are labels, not read, but one named like a setting ('hold', 'Speed') is
  refused; ``#`` starts a comment line.
- ``.waypoints``: Mission Planner's "QGC WPL 110" text format; row 0 is home;
  MAV_CMD_NAV_WAYPOINT (16) rows are waypoints (param1, if not 0, seconds to
  hold there), MAV_CMD_DO_CHANGE_SPEED (178)
  sets the speed of the following legs, NAV_LOITER_TIME (19, param1 seconds)
  and NAV_LOITER_UNLIM (17) are waypoints with ``hold_s`` / ``hold: true`` (at
  latitude and longitude 0, "here": a hold at the waypoint before), and
  NAV_RETURN_TO_LAUNCH (20) ends the mission with ``rtl``; other commands are
  refused.
- ``.plan``: QGroundControl JSON; ``mission.plannedHomePosition`` is home,
  ``SimpleItem`` items of the same commands as above;
  ``mission.cruiseSpeed`` is the default speed of legs.

Latitude/longitude are converted to local (north_m, east_m) around an
origin: the file's home if it has one (the simulated boat starts there,
heading north, at rest), else the origin given by the caller (the
configuration's), else the file's ``origin``. A local-frame mission's
waypoints are metres from its own ``origin``, else from the caller's origin,
else from its ``home`` (where a simulated boat starts); its own origin and
the caller's more than ``ORIGIN_AGREE_M`` apart are refused (the waypoints
would move).

Refused, with a message naming the file, the waypoint (1-based) and the
problem: no waypoints, non-numbers or NaN, latitude outside +-90 or
longitude outside +-180, a waypoint farther than ``max_range_m`` from the
origin, two consecutive identical waypoints, a speed that is not > 0, a hold
outside [0, 86400] s, anything after a return to launch.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from autopilot.geo import latlon_to_local
from autopilot.gnc.speed import SPEED_RANGE, is_speed
from autopilot.schema import ConfigError, unknown_key
from autopilot.userfile import (
    DEGREES,
    METRES,
    METRES_PER_SECOND,
    SECONDS,
    coordinate_hint,
    csv_rows,
    degrees_minutes,
    known_names,
    other_file_kind,
    parse_yaml,
    read_text,
    too_many_fields,
    unique_header,
    units_row,
    units_row_refusal,
    yaml_problem,
)

DUPLICATE_TOLERANCE_M = 0.01
ORIGIN_AGREE_M = 1.0  # a local-frame file's own origin and the configuration's: farther apart, refused
NAV_WAYPOINT = 16
NAV_LOITER_UNLIM = 17  # hold at the point until commanded
NAV_LOITER_TIME = 19  # hold at the point for param1 seconds
LOITER_ITEMS = (NAV_LOITER_UNLIM, NAV_LOITER_TIME)  # at latitude and longitude 0: a hold at the waypoint before
NAV_RETURN_TO_LAUNCH = 20
DO_CHANGE_SPEED = 178
NO_SPEED_CHANGE = -1.0  # DO_CHANGE_SPEED param2 -1: "no change" (MAVLink common.xml)
DEFAULT_SPEED_CHANGE = -2.0  # ... -2: "return to the default speed" (the planned speeds, for the link's command)


def _speed_change(speed, value):
    """The leg speed after a DO_CHANGE_SPEED with ``value`` (its param2): unchanged for -1 (also as a file's text
    "-1" or "-1.0": a Mission Planner file with it was refused as a speed of -1 m/s)."""
    try:
        if float(value) == NO_SPEED_CHANGE:
            return speed
    except (TypeError, ValueError):
        pass
    return value
MAX_HOLD_S = 86400.0


class MissionError(ConfigError):
    """A mission file that cannot be flown as written."""


@dataclass(frozen=True)
class Mission:
    """A checked route in the local frame."""

    name: str
    waypoints_ne_m: np.ndarray  # (N, 2): north_m, east_m
    speeds_m_s: tuple  # one per waypoint: the speed of the leg to it, None = default
    home_latlon: tuple[float, float] | None
    origin_lat_deg: float | None
    origin_lon_deg: float | None
    holds_s: tuple = ()  # one per waypoint: hold there this long (s) before going on; inf = until commanded; None = no hold
    rtl: bool = False  # the last item returns to the launch point (then holds there)
    # the MAVLink items (after home) an uploaded mission came as: its item numbers are the planner's (see
    # mission_to_items); () for a mission from a file
    mavlink_items: tuple = ()

    @property
    def home_ne_m(self) -> tuple[float, float]:
        """Home in the local frame (m): where a simulated boat starts (the origin when the file has no home)."""
        if self.home_latlon is None or self.origin_lat_deg is None or self.origin_lon_deg is None:
            return 0.0, 0.0
        n, e = latlon_to_local(self.home_latlon[0], self.home_latlon[1], self.origin_lat_deg, self.origin_lon_deg)
        return float(n), float(e)

    def hold_s(self, i: int) -> float | None:
        return self.holds_s[i] if i < len(self.holds_s) else None

    def planned_time_s(self, default_speed_m_s: float, start_index: int = 0) -> float:
        """The route's time (s) from home (from waypoint ``start_index - 1`` when resumed there): each leg straight
        at its speed (``default_speed_m_s`` where it has none), the holds, and the way back with rtl; inf when a
        hold lasts until commanded. A floor: turns, the arrival slow-down and any current only add to it."""
        wps = [tuple(map(float, p)) for p in self.waypoints_ne_m]
        at = self.home_ne_m if start_index == 0 else wps[start_index - 1]
        total = 0.0
        for i in range(start_index, len(wps)):
            speed = self.speeds_m_s[i] if i < len(self.speeds_m_s) and self.speeds_m_s[i] else default_speed_m_s
            total += math.hypot(wps[i][0] - at[0], wps[i][1] - at[1]) / speed + (self.hold_s(i) or 0.0)
            at = wps[i]
        if self.rtl:
            total += math.hypot(self.home_ne_m[0] - at[0], self.home_ne_m[1] - at[1]) / default_speed_m_s
        return total


@dataclass(frozen=True)
class _RawPoint:
    a: Any  # north_m or lat_deg
    b: Any  # east_m or lon_deg
    speed: Any = None
    hold: Any = None  # seconds, or math.inf (until commanded)


_ANGLE_LIMIT_DEG = {"latitude": 90.0, "longitude": 180.0}


def _num(where: str, what: str, value: Any) -> float:
    if isinstance(value, bool):
        raise MissionError(f"{where}: {what} is not a number ({value!r})")
    try:
        x = float(value)
    except (TypeError, ValueError):
        # "4807.038N" or "52°00.006'N" copied from a receiver or a chart: say what to write instead
        hint = coordinate_hint(value, _ANGLE_LIMIT_DEG[what]) if what in _ANGLE_LIMIT_DEG else ""
        raise MissionError(f"{where}: {what} is not a number ({value!r}){hint}") from None
    if not math.isfinite(x):
        raise MissionError(f"{where}: {what} is {value!r}, not a finite number")
    return x


def _finish(
    path: Path,
    name: str,
    points: list[_RawPoint],
    *,
    latlon: bool,
    home: tuple[Any, Any] | None,
    origin: tuple[float | None, float | None],
    max_range_m: float,
    rtl: bool = False,
    labels: list[str] | None = None,
) -> Mission:
    """``labels``: what to call each point in an error (default "waypoint K"); a MissionError about a point
    carries its index (from 1) as ``point``."""
    if not points:
        raise MissionError(f"{path}: the mission has no waypoints")
    home_ll = None
    if home is not None:
        home_ll = (_num(f"{path}: home", "latitude", home[0]), _num(f"{path}: home", "longitude", home[1]))
        _check_latlon(f"{path}: home", *home_ll)
    if latlon:
        # the configuration's origin, when there is one, stays the local frame's: its local geofence and
        # max_distance_m are metres from it (a planner's home put there moved both silently: a new-user audit,
        # a QGroundControl plan whose home was 501 m off flew with the fence and the distance limit around it)
        if origin[0] is not None and origin[1] is not None:
            o_lat, o_lon = float(origin[0]), float(origin[1])
        elif home_ll is not None:
            o_lat, o_lon = home_ll  # no origin configured: home is the local origin
        else:
            raise MissionError(
                f"{path}: waypoints are latitude/longitude but there is no home or origin to convert them "
                "around (add 'origin' to the file or configure origin_lat_deg/origin_lon_deg)"
            )
        _check_latlon(f"{path}: origin", o_lat, o_lon)
    else:
        o_lat, o_lon = origin
        if home_ll is not None and (o_lat is None or o_lon is None):
            o_lat, o_lon = home_ll
    ne: list[tuple[float, float]] = []
    speeds: list[float | None] = []
    holds: list[float | None] = []
    for k, p in enumerate(points, start=1):
        try:
            n, e, speed, hold = _point(f"{path}: {labels[k - 1] if labels else f'waypoint {k}'}", p, k, latlon,
                                       (o_lat, o_lon), max_range_m, ne)
        except MissionError as exc:
            exc.point = k
            raise
        ne.append((n, e))
        speeds.append(speed)
        holds.append(hold)
    return Mission(
        name=name,
        waypoints_ne_m=np.asarray(ne, dtype=float),
        speeds_m_s=tuple(speeds),
        home_latlon=home_ll,
        origin_lat_deg=o_lat,
        origin_lon_deg=o_lon,
        holds_s=tuple(holds),
        rtl=bool(rtl),
    )


def _point(where: str, p: _RawPoint, k: int, latlon: bool, origin, max_range_m: float, before: list):
    """One point checked: (north_m, east_m, its leg's speed or None, its hold or None)."""
    o_lat, o_lon = origin
    a = _num(where, "latitude" if latlon else "north_m", p.a)
    b = _num(where, "longitude" if latlon else "east_m", p.b)
    if latlon:
        _check_latlon(where, a, b)
        n, e = latlon_to_local(a, b, o_lat, o_lon)
    else:
        n, e = a, b
    dist = math.hypot(n, e)
    if dist > max_range_m:
        raise MissionError(f"{where}: {dist:.6g} m from the origin, farther than the allowed range {max_range_m:g} m "
                           f"(the configuration's max_mission_range_m){_swapped_hint(a, b, origin, max_range_m, latlon)}")
    if before:
        apart_m = math.hypot(n - before[-1][0], e - before[-1][1])
        if apart_m < DUPLICATE_TOLERANCE_M:
            # two points a few millimetres apart, not equal, are degrees written as metres: [52.0001, 4.4001] and
            # [52.0002, 4.4001] were "the same position" and nothing said why (a new-user audit)
            hint = ("; latitude/longitude in a local-frame mission? give them as lat_deg, lon_deg with frame: latlon"
                    if apart_m > 0.0 and not latlon else "")
            raise MissionError(f"{where}: same position as waypoint {k - 1} (duplicate consecutive waypoint){hint}")
    speed = None
    if p.speed is not None:
        speed = _num(where, "speed_m_s", p.speed)
        if not is_speed(speed):
            raise MissionError(f"{where}: speed {speed:g} m/s outside {SPEED_RANGE}")
    return n, e, speed, _hold_s(where, p.hold)


def _swapped_hint(a: float, b: float, origin, max_range_m: float, latlon: bool) -> str:
    """"; latitude and longitude swapped? ..." when the point read the other way round lies within the range: the
    refusal sent the user to raise max_mission_range_m for a waypoint 6000 km off (a new-user audit)."""
    o_lat, o_lon = origin
    if not latlon or o_lat is None or o_lon is None or not -90.0 <= b <= 90.0:
        return ""
    n, e = latlon_to_local(b, a, o_lat, o_lon)
    if math.hypot(n, e) > max_range_m:
        return ""
    return f"; latitude and longitude swapped? ({b:g}, {a:g}) would be {math.hypot(n, e):.0f} m from the origin"


def _frames_agree(path, key: str, file_ll: tuple[float, float], given_ll) -> None:
    """MissionError when a local-frame file's own ``origin`` is not the origin it is loaded with
    (the configuration's origin_lat_deg/origin_lon_deg): its waypoints are metres from the file's point, and
    taken from the configuration's they were silently moved by the distance between the two (170 m)."""
    n, e = latlon_to_local(file_ll[0], file_ll[1], float(given_ll[0]), float(given_ll[1]))
    apart_m = math.hypot(n, e)
    if apart_m > ORIGIN_AGREE_M:
        raise MissionError(
            f"{path}: {key} ({file_ll[0]:.7f}, {file_ll[1]:.7f}) is {apart_m:.0f} m from the configuration's origin "
            f"({float(given_ll[0]):.7f}, {float(given_ll[1]):.7f}); the waypoints are metres from the file's {key}: "
            "make the two the same, or remove one of them")


def _hold_s(where: str, hold: Any) -> float | None:
    if hold is None:
        return None
    if hold is True or (isinstance(hold, float) and hold == math.inf):  # -inf is refused below, not "forever"
        return math.inf
    if hold is False:
        return None
    x = _num(where, "hold_s", hold)
    if not 0.0 <= x <= MAX_HOLD_S:
        raise MissionError(f"{where}: hold_s {x:g} s outside [0, {MAX_HOLD_S:g}] s (or hold: true, until commanded)")
    return x


def _unset_home(lat: Any, lon: Any) -> bool:
    """A planner's home at latitude 0, longitude 0: none was set."""
    try:
        return float(lat) == 0.0 and float(lon) == 0.0
    except (TypeError, ValueError):
        return False  # said as not a number where the home is checked


def _check_latlon(where: str, lat: float, lon: float) -> None:
    for what, value, limit in (("latitude", lat, 90.0), ("longitude", lon, 180.0)):
        if not -limit <= value <= limit:
            deg = degrees_minutes(value, limit)  # 4807.038: a GGA's ddmm.mmm copied as it is
            hint = (f" ({value:.10g} is degrees and minutes as NMEA writes them? that is {deg:.6f} deg: give "
                    "decimal degrees)") if deg is not None else ""
            raise MissionError(f"{where}: {what} {value:g} outside -{limit:g}..{limit:g} deg{hint}")


# ------------------------------------------------------------------------- YAML
_YAML_KEYS = {"name", "frame", "origin", "home", "waypoints", "description"}
_WAYPOINT_OPTIONS = ("speed_m_s", "name", "hold_s", "hold")


def _parse_yaml(path: Path, text: str, origin, max_range_m: float) -> Mission:
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as exc:
        raise MissionError(f"{path}: not valid YAML ({yaml_problem(exc)})") from exc
    if not isinstance(data, dict):
        raise MissionError(f"{path}: expected a mapping with 'waypoints'")
    unknown = sorted(set(data) - _YAML_KEYS)
    if unknown:
        # the daemon's configuration or a vessel file given as the mission said only "ais: unknown key"
        what = other_file_kind(path) if "waypoints" not in data else None
        where = "--config and --mission swapped?" if what and what.startswith("a daemon") else "sim.vessel names it"
        hint = f"; {path} is {what}, not a mission ({where})" if what else ""
        raise MissionError(f"{path}: {unknown[0]}: {unknown_key(unknown[0], _YAML_KEYS)}{hint}")
    frame = data.get("frame", "local")
    if frame not in ("local", "latlon"):
        raise MissionError(f"{path}: frame: {frame!r} is not 'local' or 'latlon'")
    latlon = frame == "latlon"
    keys = ("lat_deg", "lon_deg") if latlon else ("north_m", "east_m")
    wps = data.get("waypoints")
    if wps is None:
        raise MissionError(f"{path}: the mission has no waypoints")
    if not isinstance(wps, list):
        raise MissionError(f"{path}: waypoints: expected a list")
    points = []
    rtl = False
    for k, w in enumerate(wps, start=1):
        if isinstance(w, str) and w.strip().lower() == "rtl":  # 'RTL' said only "expected a mapping" (an audit)
            w = "rtl"
        if w == "rtl" or w == {"rtl": True}:  # return to launch: the last item only
            if k != len(wps):
                raise MissionError(f"{path}: waypoint {k}: rtl must be the last item")
            rtl = True
            continue
        if isinstance(w, dict):
            extra = sorted(set(w) - {*keys, *_WAYPOINT_OPTIONS})
            if extra:
                # the frame defaults to local: a latitude/longitude mission without `frame: latlon` said only
                # "unknown key 'lat_deg'" (a new-user audit)
                other = ({"lat_deg", "lon_deg"}, "frame: latlon") if not latlon else ({"north_m", "east_m"}, "frame: local")
                hint = (f"; the waypoints are read in frame {frame!r}: for {extra[0]} say {other[1]}"
                        if extra[0] in other[0] else "")
                raise MissionError(f"{path}: waypoint {k}: unknown key {extra[0]!r} (allowed: {', '.join(keys)}, "
                                   f"{', '.join(_WAYPOINT_OPTIONS)}){hint}")
            missing = [key for key in keys if key not in w]
            if missing:
                raise MissionError(f"{path}: waypoint {k}: missing {missing[0]}")
            if "hold" in w and "hold_s" in w:
                raise MissionError(f"{path}: waypoint {k}: give hold_s (seconds) or hold: true (until commanded), not both")
            if "hold" in w and not isinstance(w["hold"], bool):
                raise MissionError(f"{path}: waypoint {k}: hold: expected true or false, got {w['hold']!r}")
            points.append(_RawPoint(w[keys[0]], w[keys[1]], w.get("speed_m_s"), w.get("hold_s", w.get("hold"))))
        elif isinstance(w, (list, tuple)) and len(w) == 2:
            points.append(_RawPoint(*w))
        elif isinstance(w, (list, tuple)) and len(w) == 3:  # took the third as a speed, unsaid (an altitude?)
            raise MissionError(f"{path}: waypoint {k}: {list(w)}: a bare waypoint is a [{keys[0]}, {keys[1]}] pair; "
                               f"a speed goes in a mapping ({{{keys[0]}: ..., {keys[1]}: ..., speed_m_s: ...}})")
        else:
            raise MissionError(f"{path}: waypoint {k}: expected a mapping with {keys[0]}, {keys[1]} or a [{keys[0]}, {keys[1]}] pair")

    def _ll(key: str):
        v = data.get(key)
        if v is None:
            return None
        if not isinstance(v, dict) or set(v) != {"lat_deg", "lon_deg"}:
            raise MissionError(f"{path}: {key}: expected {{lat_deg: ..., lon_deg: ...}}")
        return v["lat_deg"], v["lon_deg"]

    home = _ll("home")
    file_origin = _ll("origin")
    if file_origin is not None:
        o = (_num(f"{path}: origin", "latitude", file_origin[0]), _num(f"{path}: origin", "longitude", file_origin[1]))
        if origin[0] is not None and not latlon:
            _check_latlon(f"{path}: origin", *o)
            _frames_agree(path, "origin", o, origin)
        origin = o if origin[0] is None else origin
    return _finish(path, str(data.get("name") or path.stem), points, latlon=latlon, home=home, origin=origin,
                   max_range_m=max_range_m, rtl=rtl)


# ------------------------------------------------------------------------- CSV
_CSV_OPTIONS = ("speed_m_s", "hold_s", "name")  # name: the spreadsheet's label, not read
_CSV_LOOKALIKE = ("hold", "speed", "north", "east", "lat", "lon", "loiter", "wait")
_CSV_COLUMNS = ("north_m", "east_m", "lat_deg", "lon_deg", *_CSV_OPTIONS)
# what a units row under the header may say of each column the mission reads
_CSV_UNITS = {"north_m": METRES, "east_m": METRES, "lat_deg": DEGREES, "lon_deg": DEGREES,
              "speed_m_s": METRES_PER_SECOND, "hold_s": SECONDS}


def _parse_csv(path: Path, text: str, origin, max_range_m: float) -> Mission:
    # rows of empty cells (';;;;' under the data, where Excel saw formatting) are no waypoints (a new-user audit)
    rows = [r for r in csv_rows(text) if any(c.strip() for c in r)]
    if not rows:
        raise MissionError(f"{path}: the mission has no waypoints")
    cols = known_names(rows[0], _CSV_COLUMNS)  # NORTH_M is north_m (an audit)
    try:  # north_m twice: the last copy flew, without a word (a new user's test)
        unique_header(cols, _CSV_COLUMNS)
    except ConfigError as exc:
        raise MissionError(f"{path}: {exc}") from None
    if {"north_m", "east_m", "lat_deg", "lon_deg"} <= set(cols):
        raise MissionError(f"{path}: the header names both north_m,east_m and lat_deg,lon_deg: keep one pair")
    if {"north_m", "east_m"} <= set(cols):
        keys, latlon = ("north_m", "east_m"), False
    elif {"lat_deg", "lon_deg"} <= set(cols):
        keys, latlon = ("lat_deg", "lon_deg"), True
    else:
        raise MissionError(f"{path}: header must name north_m,east_m or lat_deg,lon_deg (got {','.join(cols)})")
    # other columns are the spreadsheet's labels, not read; one named like a setting but not one ('hold', 'Speed')
    # is refused: a column the loader did not know was dropped unsaid, and a mission flew without its holds
    allowed = (*keys, *_CSV_OPTIONS)
    unknown = [c for c in cols if c not in allowed and re.sub(r"[^a-z]", "", c.lower()).startswith(_CSV_LOOKALIKE)]
    if unknown:
        raise MissionError(f"{path}: column {unknown[0]!r} is not one the mission reads (allowed: {', '.join(allowed)}; "
                           "other columns are labels, not read)")
    at = {c: k for k, c in enumerate(cols)}
    # "4807.038N" is not a unit: a row of coordinates with hemisphere letters was taken as a units row and refused
    # as "gives lat_deg in '4807.038N'" (a new-user audit); as data it is refused saying what to write instead
    if len(rows) > 1 and units_row(rows[1]) and not any(coordinate_hint(c, 180.0) for c in rows[1]):
        _check_units(path, rows[1], cols)
        del rows[1]  # a spreadsheet's units row under the header: no waypoint (it was "north_m is not a number ('m')")
    for k, r in enumerate(rows[1:], start=1):
        problem = too_many_fields(r, len(cols), k)
        if problem:
            raise MissionError(f"{path}: {problem}")

    def cell(row: list[str], name: str) -> str:
        k = at.get(name)
        return row[k] if k is not None and k < len(row) else ""

    points = [_RawPoint(cell(r, keys[0]), cell(r, keys[1]), cell(r, "speed_m_s") or None, cell(r, "hold_s") or None)
              for r in rows[1:]]
    return _finish(path, path.stem, points, latlon=latlon, home=None, origin=origin, max_range_m=max_range_m)


def _check_units(path: Path, units: list[str], cols: list[str]) -> None:
    """A units row's unit for each column the mission reads is the one the column's name says, or none: a north_m in
    ft or km read as metres would fly a different mission."""
    refusal = units_row_refusal(path, units, cols, _CSV_UNITS, "mission")
    if refusal is not None:
        raise MissionError(refusal)


# ------------------------------------------------------------------------- Mission Planner
_SUPPORTED = "supported: waypoint 16, loiter unlimited 17, loiter time 19, return to launch 20, change speed 178"
# MAV_FRAME_GLOBAL, _RELATIVE_ALT, their _INT forms and _TERRAIN_ALT(_INT): x, y are latitude, longitude in degrees
MAVLINK_GLOBAL_FRAMES = (0, 3, 5, 6, 10, 11)


def _global_frame(where: str, frame: Any) -> None:
    """A waypoint's frame must give latitude/longitude: a local frame (1, LOCAL_NED: metres) was read as degrees."""
    try:
        ok = float(frame) in MAVLINK_GLOBAL_FRAMES
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise MissionError(f"{where}: frame {frame} not supported: a waypoint's frame must be global latitude/"
                           f"longitude ({', '.join(map(str, MAVLINK_GLOBAL_FRAMES))}); 1 is MAV_FRAME_LOCAL_NED")


def _loiter(cmd: int, param1: Any):
    """The hold of a MAVLink item: loiter time (19) holds param1 seconds, loiter unlimited (17) until commanded,
    a waypoint (16) param1 seconds if not 0 (MAVLink's hold time, as ArduPilot Rover's delay at a waypoint: it was
    ignored while the download showed it); a waypoint's NaN (unset) is no hold."""
    if cmd == NAV_LOITER_UNLIM:
        return math.inf
    if cmd == NAV_LOITER_TIME:
        return param1
    if cmd == NAV_WAYPOINT:
        try:
            x = float(param1)
        except (TypeError, ValueError):
            return param1  # named by the hold's check
        return None if x == 0.0 or math.isnan(x) else x
    return None


def _loiter_here(cmd: int, lat: Any, lon: Any) -> bool:
    """A loiter item at latitude and longitude 0: MAVLink's "here", a hold at the waypoint before it."""
    try:
        return cmd in LOITER_ITEMS and float(lat) == 0.0 and float(lon) == 0.0
    except (TypeError, ValueError):
        return False


def _add_item(points: list, where: str, cmd: int, lat: Any, lon: Any, speed: Any, param1: Any) -> None:
    """A waypoint or loiter item. A loiter at latitude and longitude 0 (MAVLink: "here") holds at the
    waypoint before it, as Mission Planner and QGroundControl write it."""
    hold = _loiter(cmd, param1)
    if _loiter_here(cmd, lat, lon):
        if not points:
            raise MissionError(f"{where}: a loiter at the current position (latitude and longitude 0) needs a "
                               "waypoint before it")
        prev = points[-1]
        points[-1] = _RawPoint(prev.a, prev.b, prev.speed, hold)
        return
    points.append(_RawPoint(lat, lon, speed, hold))

def _parse_wpl(path: Path, text: str, origin, max_range_m: float) -> Mission:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines or not lines[0].startswith("QGC WPL 110"):
        raise MissionError(f"{path}: not a Mission Planner file (first line must be 'QGC WPL 110')")
    home = None
    points: list[_RawPoint] = []
    rows: list[list[str]] = []
    speed = None
    rtl = False
    for row_no, ln in enumerate(lines[1:]):
        f = ln.split("\t") if "\t" in ln else ln.split()
        if len(f) != 12:
            raise MissionError(f"{path}: row {row_no}: expected 12 fields, got {len(f)}")
        try:
            cmd = int(float(f[3]))
        except ValueError:
            raise MissionError(f"{path}: row {row_no}: command {f[3]!r} is not a number") from None
        if row_no == 0:
            # Mission Planner writes home 0, 0 when none was set: no home (taken as one, the waypoints were
            # 15 600 km "from the origin" and the message sent the user to max_mission_range_m; a new-user audit)
            home = None if _unset_home(f[8], f[9]) else (f[8], f[9])
            continue
        rows.append(f)
        if rtl:
            raise MissionError(f"{path}: row {row_no}: nothing may follow return to launch (20)")
        if cmd in (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM):
            _global_frame(f"{path}: row {row_no}", f[2])
            _add_item(points, f"{path}: row {row_no}", cmd, f[8], f[9], speed, f[4])
        elif cmd == DO_CHANGE_SPEED:
            speed = _speed_change(speed, f[5])
        elif cmd == NAV_RETURN_TO_LAUNCH:
            rtl = True
        else:
            raise MissionError(f"{path}: row {row_no}: command {cmd} not supported ({_SUPPORTED})")
    mission = _finish(path, path.stem, points, latlon=True, home=home, origin=origin, max_range_m=max_range_m, rtl=rtl)
    return dataclasses.replace(mission, mavlink_items=_wpl_items(rows))


def _wpl_items(rows: list[list[str]]) -> tuple:
    """The file's rows after home as the mission's MAVLink items, so the link numbers them as the file does (an
    uploaded mission saved for a restart came back renumbered: a speed item of -1, "no change", and a repeated
    one were dropped, and the planner's numbers no longer matched); () when a row's numbers cannot be read."""
    try:
        return tuple(dict(frame=int(float(f[2])), command=int(float(f[3])), param1=float(f[4]), param2=float(f[5]),
                          lat_deg=float(f[8]), lon_deg=float(f[9])) for f in rows)
    except ValueError:
        return ()


# ------------------------------------------------------------------------- QGroundControl
def _parse_plan(path: Path, text: str, origin, max_range_m: float) -> Mission:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MissionError(f"{path}: not valid JSON ({exc})") from exc
    mission = data.get("mission") if isinstance(data, dict) else None
    if not isinstance(mission, dict):
        raise MissionError(f"{path}: no 'mission' section (is it a QGroundControl .plan?)")
    fence = data.get("geoFence")
    if isinstance(fence, dict) and (fence.get("polygons") or fence.get("circles")):
        # flown without it, the plan's fence was silently not there (a new-user audit): the failsafe's is the config's
        raise MissionError(f"{path}: geoFence: the plan draws a fence, which is not read from a .plan: put it in the "
                           "configuration (geofence: {frame: latlon, polygon: [[lat, lon], ...]}) and delete it from "
                           "the plan")
    home = mission.get("plannedHomePosition")
    if home is not None:
        if not isinstance(home, list) or len(home) < 2:
            raise MissionError(f"{path}: plannedHomePosition: expected [lat, lon, alt]")
        home = None if _unset_home(home[0], home[1]) else (home[0], home[1])
    speed = mission.get("cruiseSpeed")
    speed = speed if speed else None
    if speed is not None:  # "waypoint 1: speed 15 m/s ..." named neither the setting nor where QGC keeps it
        cruise = _num(f"{path}: mission.cruiseSpeed", "the cruise speed", speed)
        if not is_speed(cruise):
            raise MissionError(f"{path}: mission.cruiseSpeed: {cruise:g} m/s outside {SPEED_RANGE} (the "
                               "speed of every leg without its own: set it in QGroundControl's Mission Start item)")
    points: list[_RawPoint] = []
    rtl = False
    for k, item in enumerate(mission.get("items") or [], start=1):
        if not isinstance(item, dict) or item.get("type") != "SimpleItem":
            raise MissionError(f"{path}: item {k}: only SimpleItem is supported (got {item.get('type') if isinstance(item, dict) else item!r})")
        cmd, params = item.get("command"), item.get("params") or []
        if rtl:
            raise MissionError(f"{path}: item {k}: nothing may follow return to launch (20)")
        if cmd in (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM):
            if len(params) < 6:
                raise MissionError(f"{path}: item {k}: command {cmd} needs 7 params")
            _global_frame(f"{path}: item {k}", item.get("frame", 3))  # absent: QGC's default, relative altitude
            _add_item(points, f"{path}: item {k}", cmd, params[4], params[5], speed, params[0])
        elif cmd == DO_CHANGE_SPEED:
            speed = _speed_change(speed, params[1]) if len(params) > 1 else None
        elif cmd == NAV_RETURN_TO_LAUNCH:
            rtl = True
        else:
            raise MissionError(f"{path}: item {k}: command {cmd} not supported ({_SUPPORTED})")
    return _finish(path, path.stem, points, latlon=True, home=home, origin=origin, max_range_m=max_range_m, rtl=rtl)


_PARSERS = {".yaml": _parse_yaml, ".yml": _parse_yaml, ".csv": _parse_csv, ".waypoints": _parse_wpl, ".plan": _parse_plan}


def load_mission(
    path,
    *,
    origin_lat_deg: float | None = None,
    origin_lon_deg: float | None = None,
    max_range_m: float = 2000.0,
) -> Mission:
    """Read, check and convert a mission file (format from its extension)."""
    path = Path(path)
    parser = _PARSERS.get(path.suffix.lower())
    if path.is_dir():  # it was "unknown mission format ''"
        raise MissionError(f"{path}: is a directory, not a mission file ({', '.join(_PARSERS)})")
    if parser is None:
        raise MissionError(f"{path}: unknown mission format {path.suffix!r} (known: {', '.join(_PARSERS)})")
    try:
        text = read_text(path, what="mission file", spreadsheet=path.suffix.lower() == ".csv")
    except ConfigError as exc:
        raise MissionError(str(exc)) from None
    return parser(path, text, (origin_lat_deg, origin_lon_deg), max_range_m)


# ------------------------------------------------------------------------- MAVLink items
MAVLINK_MISSION_FRAME = 2  # MAV_FRAME_MISSION: items without a position (RTL, change speed)


class MissionItemError(MissionError):
    """A refused MAVLink mission item: ``seq`` (the item number) and ``field`` (``command``, ``frame``,
    ``x``, ``y``, ``param1``, ``param2``, ``sequence`` or ``mission``) for the MISSION_ACK error code."""

    def __init__(self, message: str, *, seq: int, field: str) -> None:
        super().__init__(message)
        self.seq, self.field = seq, field


def mission_from_items(items, *, origin_lat_deg: float, origin_lon_deg: float, max_range_m: float = 2000.0,
                       name: str = "uploaded") -> Mission:
    """A mission from MAVLink mission items (dicts: seq, frame, command, param1, param2, lat_deg, lon_deg), item 0
    being home (ArduPilot's convention, ignored: the local frame stays the running mission's). The same
    checks as a mission file; MissionItemError names the item."""
    where = Path("uploaded mission")
    points: list[_RawPoint] = []
    point_items: list[int] = []  # the item number of each point (a loiter "here" is part of the one before)
    speed = None
    rtl = False
    for k, it in enumerate(items):
        seq = int(it.get("seq", k))
        if seq != k:
            raise MissionItemError(f"{where}: item {k} arrived as item {seq}", seq=k, field="sequence")
        if k == 0:
            continue
        cmd = int(it["command"])
        here = f"{where}: item {k}"
        if rtl:
            raise MissionItemError(f"{here}: nothing may follow return to launch (20)", seq=k, field="command")
        if cmd in (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM):
            if int(it.get("frame", 0)) not in MAVLINK_GLOBAL_FRAMES:
                raise MissionItemError(f"{here}: frame {it.get('frame')} not supported (global latitude/longitude "
                                       "frames 0, 3, 5, 6)", seq=k, field="frame")
            lat, lon = it.get("lat_deg"), it.get("lon_deg")
            for what, v, lim, fld in (("latitude", lat, 90.0, "x"), ("longitude", lon, 180.0, "y")):
                if not isinstance(v, (int, float)) or not math.isfinite(v) or abs(v) > lim:
                    raise MissionItemError(f"{here}: {what} {v!r} outside -{lim:g}..{lim:g} deg", seq=k, field=fld)
            hold = _loiter(cmd, it.get("param1"))
            # loiter unlimited's hold is +inf; a loiter time of -inf was taken as "until commanded" (a new user's test)
            if hold is not None and hold != math.inf and not (math.isfinite(hold) and 0.0 <= hold <= MAX_HOLD_S):
                what = "loiter time" if cmd == NAV_LOITER_TIME else "hold time"
                raise MissionItemError(f"{here}: {what} {hold:g} s outside [0, {MAX_HOLD_S:g}] s", seq=k,
                                       field="param1")
            try:
                before = len(points)
                _add_item(points, here, cmd, lat, lon, speed, it.get("param1"))
                if len(points) > before:
                    point_items.append(k)
            except MissionError as exc:
                raise MissionItemError(str(exc), seq=k, field="mission") from None
        elif cmd == DO_CHANGE_SPEED:
            speed = _speed_change(speed, it.get("param2"))
            if speed is not None and not is_speed(speed):
                raise MissionItemError(f"{here}: speed {speed!r} m/s outside {SPEED_RANGE} (-1: no "
                                       "change)", seq=k, field="param2")
        elif cmd == NAV_RETURN_TO_LAUNCH:
            rtl = True
        else:
            raise MissionItemError(f"{here}: command {cmd} not supported ({_SUPPORTED})", seq=k, field="command")
    try:
        mission = _finish(where, name, points, latlon=True, home=None, origin=(origin_lat_deg, origin_lon_deg),
                          max_range_m=max_range_m, rtl=rtl,
                          labels=[f"item {seq} (waypoint {i + 1})" for i, seq in enumerate(point_items)])
        kept = ("frame", "command", "param1", "param2", "lat_deg", "lon_deg")
        return dataclasses.replace(mission, mavlink_items=tuple({k: it.get(k, 0.0) for k in kept} for it in items[1:]))
    except MissionItemError:
        raise
    except MissionError as exc:  # about a point: named by its item, as the planner numbers it
        point = getattr(exc, "point", None)
        seq = point_items[point - 1] if point is not None and point <= len(point_items) else len(items) - 1
        raise MissionItemError(str(exc), seq=seq, field="mission") from None


NAV_ITEMS = (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM)  # the items that are waypoints of the mission


def mission_to_items(mission: Mission, home_latlon: tuple[float, float] | None = None) -> list[dict]:
    """The mission as MAVLink items: item 0 home, then an uploaded mission's items as they came (so the item
    numbers the link reports and takes are the planner's: a DO_CHANGE_SPEED dropped from the download shifted
    every later waypoint's number by one), or for a mission from a file one item per waypoint, with a
    DO_CHANGE_SPEED before each leg whose speed changes, and an RTL at the end."""
    from autopilot.geo import local_to_latlon

    o = (mission.origin_lat_deg, mission.origin_lon_deg)
    home = home_latlon or mission.home_latlon or o
    out = [dict(frame=0, command=NAV_WAYPOINT, param1=0.0, param2=0.0, lat_deg=home[0], lon_deg=home[1])]
    if mission.mavlink_items:
        out += [dict(it) for it in mission.mavlink_items]
    else:
        speeds = list(mission.speeds_m_s) or [None] * len(mission.waypoints_ne_m)
        last_speed = None
        for i, (n, e) in enumerate(mission.waypoints_ne_m):
            if i < len(speeds) and speeds[i] is not None and speeds[i] != last_speed:
                last_speed = speeds[i]
                out.append(dict(frame=MAVLINK_MISSION_FRAME, command=DO_CHANGE_SPEED, param1=0.0,
                                param2=float(last_speed), lat_deg=0.0, lon_deg=0.0))
            lat, lon = local_to_latlon(float(n), float(e), *o)
            hold = mission.hold_s(i)
            cmd = NAV_WAYPOINT if hold is None else (NAV_LOITER_UNLIM if math.isinf(hold) else NAV_LOITER_TIME)
            out.append(dict(frame=3, command=cmd, param1=0.0 if hold is None or math.isinf(hold) else hold,
                            param2=0.0, lat_deg=lat, lon_deg=lon))
        if mission.rtl:
            out.append(dict(frame=MAVLINK_MISSION_FRAME, command=NAV_RETURN_TO_LAUNCH, param1=0.0, param2=0.0,
                            lat_deg=0.0, lon_deg=0.0))
    return [{"seq": k, **it} for k, it in enumerate(out)]


@dataclass(frozen=True)
class ItemNumbers:
    """The MAVLink item numbers of a mission (mission_to_items): what MISSION_CURRENT, MISSION_ITEM_REACHED and
    MISSION_SET_CURRENT carry."""

    waypoints: tuple[int, ...]  # the item number of each waypoint
    rtl: int | None  # the return-to-launch item's
    count: int  # items, home (0) included

    @classmethod
    def of(cls, mission: Mission) -> ItemNumbers:
        items = mission_to_items(mission)
        # a loiter "here" is a hold at the waypoint before, not a waypoint: counted as one, every later
        # waypoint's number was one off (MISSION_SET_CURRENT flew to the waypoint after the one asked)
        return cls(tuple(it["seq"] for it in items[1:]
                         if it["command"] in NAV_ITEMS and not _loiter_here(it["command"], it["lat_deg"], it["lon_deg"])),
                     next((it["seq"] for it in items if it["command"] == NAV_RETURN_TO_LAUNCH), None), len(items))

    def waypoint_of(self, seq: int) -> int | None:
        """The waypoint (index) a jump to item ``seq`` flies to: that item's, or after a DO item the next one;
        None for home (0) and beyond the last waypoint."""
        if seq < 1:
            return None
        return next((i for i, s in enumerate(self.waypoints) if s >= seq), None)




def to_waypoints_text(mission: Mission) -> str:
    """The mission as a Mission Planner file (QGC WPL 110), home = its origin: read back, the same mission."""
    rows = ["QGC WPL 110"]
    for it in mission_to_items(mission, home_latlon=(mission.origin_lat_deg, mission.origin_lon_deg)):
        seq = it["seq"]
        rows.append(f"{seq}\t{1 if seq == 0 else 0}\t{it['frame']}\t{it['command']}\t{it['param1']!r}\t"
                    f"{it['param2']!r}\t0\t0\t{it['lat_deg']:.9f}\t{it['lon_deg']:.9f}\t0\t1")
    return "\n".join(rows) + "\n"
