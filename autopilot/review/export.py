"""Exports of a mission log to tools people already have.

- GPX 1.1 (http://www.topografix.com/GPX/1/1): waypoints as ``wpt``, the
  track as ``trk`` with one ``trkseg`` per unbroken stretch, times from the
  ``mission_start`` timestamp plus mission time.
- KML 2.2 (Google Earth): a waypoint Placemark each, the track as a
  LineString (a MultiGeometry of LineStrings when it has gaps).
- GeoJSON (RFC 7946, lon/lat order): a FeatureCollection of the track
  (LineString, or MultiLineString when it has gaps) and one Point per
  waypoint.
- The trial CSV read by the identification workflow (issue 5): columns
  ``t_s, thrust_port_n, thrust_stbd_n, north_m, east_m, heading_deg,
  lat_deg, lon_deg, sog_m_s, cog_deg, rot_deg_s``; a gap is an empty field.

Positions come from the logged latitude/longitude; where a cycle has only
the local position, the log's origin converts it (SPEC section 2). Gaps are
never filled: a track breaks where the position is missing.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from autopilot.geo import local_to_latlon, wrap_360
from autopilot.review.metrics import closest_approaches
from autopilot.review.reader import MissionLog
from autopilot.schema import ConfigError

FORMATS = ("gpx", "kml", "geojson", "csv")
GPX_NS = "http://www.topografix.com/GPX/1/1"
KML_NS = "http://www.opengis.net/kml/2.2"
CSV_COLUMNS = ("t_s", "thrust_port_n", "thrust_stbd_n", "north_m", "east_m", "heading_deg",
               "lat_deg", "lon_deg", "sog_m_s", "cog_deg", "rot_deg_s")
_CSV_FORMATS = ("%.3f", "%.3f", "%.3f", "%.3f", "%.3f", "%.2f", "%.8f", "%.8f", "%.3f", "%.2f", "%.3f")
_CHUNK = 20000


def parse_formats(text: str) -> tuple[str, ...]:
    """'gpx,kml' -> ('gpx', 'kml'); ConfigError naming an unknown format."""
    out = []
    for item in (x.strip().lower() for x in text.split(",")):
        if not item:
            continue
        if item not in FORMATS:
            raise ConfigError(f"--export: unknown format {item!r}; choose from {', '.join(FORMATS)}")
        if item not in out:
            out.append(item)
    return tuple(out)


def track_latlon(log: MissionLog) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude per cycle (NaN where unknown)."""
    lat, lon = log.col("lat_deg").copy(), log.col("lon_deg").copy()
    missing = ~(np.isfinite(lat) & np.isfinite(lon))
    origin = log.origin_deg
    if missing.any() and origin is not None:
        n, e = log.col("north_m")[missing], log.col("east_m")[missing]
        la, lo = local_to_latlon(n, e, *origin)
        lat[missing], lon[missing] = la, lo
    bad = ~(np.isfinite(lat) & np.isfinite(lon)) | (np.abs(lat) > 90) | (np.abs(lon) > 180)
    lat[bad] = np.nan
    lon[bad] = np.nan
    return lat, lon


def waypoints_latlon(log: MissionLog) -> np.ndarray:
    """(N, 2) waypoint latitude/longitude; (0, 2) when the log has no origin."""
    wps = log.waypoints_ne_m
    if log.origin_deg is None or len(wps) == 0:
        return np.zeros((0, 2))
    lat, lon = local_to_latlon(wps[:, 0], wps[:, 1], *log.origin_deg)
    return np.column_stack([np.atleast_1d(lat), np.atleast_1d(lon)])


def segments(valid: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of consecutive True values."""
    if len(valid) == 0:
        return []
    v = np.concatenate([[False], valid, [False]]).astype(np.int8)
    d = np.diff(v)
    return list(zip(np.nonzero(d == 1)[0].tolist(), np.nonzero(d == -1)[0].tolist()))


def _start_time(log: MissionLog) -> _dt.datetime | None:
    stamp = (log.start or {}).get("timestamp") or log.first_timestamp
    if not isinstance(stamp, str):
        return None
    try:
        when = _dt.datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    except ValueError:
        return None
    return when if when.tzinfo else when.replace(tzinfo=_dt.timezone.utc)


def _mission_t0(log: MissionLog) -> float:
    t = (log.start or {}).get("t_s")
    return float(t) if isinstance(t, (int, float)) and not isinstance(t, bool) else 0.0


def _need_track(log: MissionLog, lat: np.ndarray, fmt: str) -> None:
    if not np.isfinite(lat).any() and len(waypoints_latlon(log)) == 0:
        raise ConfigError(f"{log.path}: no latitude/longitude (and no origin) to export as {fmt}")


def write_gpx(log: MissionLog, path) -> Path:
    """GPX 1.1: waypoints and the track, one segment per unbroken stretch."""
    lat, lon = track_latlon(log)
    _need_track(log, lat, "GPX")
    t0 = _start_time(log)
    tm0 = _mission_t0(log)
    t = log.col("t_s")
    path = Path(path)
    with path.open("w", encoding="utf-8") as f:
        f.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        f.write(f'<gpx version="1.1" creator="autopilot review" xmlns="{GPX_NS}">\n')
        f.write(f"  <metadata><name>{escape(log.name)}</name>")
        if t0 is not None:
            f.write(f"<time>{t0.strftime('%Y-%m-%dT%H:%M:%SZ')}</time>")
        f.write("</metadata>\n")
        for i, (la, lo) in enumerate(waypoints_latlon(log)):
            f.write(f'  <wpt lat="{la:.8f}" lon="{lo:.8f}"><name>W{i}</name></wpt>\n')
        f.write(f"  <trk><name>{escape(log.name)}</name>\n")
        for a, b in segments(np.isfinite(lat)):
            f.write("    <trkseg>\n")
            for k0 in range(a, b, _CHUNK):
                k1 = min(b, k0 + _CHUNK)
                if t0 is not None:
                    base = t0.timestamp()
                    stamps = [_dt.datetime.fromtimestamp(base + x - tm0, _dt.timezone.utc)
                              .strftime("%Y-%m-%dT%H:%M:%S.%fZ")[:-4] + "Z"
                              for x in t[k0:k1].tolist()]
                    f.write("".join(
                        f'      <trkpt lat="{la:.8f}" lon="{lo:.8f}"><time>{s}</time></trkpt>\n'
                        for la, lo, s in zip(lat[k0:k1].tolist(), lon[k0:k1].tolist(), stamps)))
                else:
                    f.write("".join(f'      <trkpt lat="{la:.8f}" lon="{lo:.8f}"/>\n'
                                    for la, lo in zip(lat[k0:k1].tolist(), lon[k0:k1].tolist())))
            f.write("    </trkseg>\n")
        f.write("  </trk>\n</gpx>\n")
    return path


def write_kml(log: MissionLog, path) -> Path:
    """KML 2.2 for Google Earth: waypoints and the track."""
    lat, lon = track_latlon(log)
    _need_track(log, lat, "KML")
    path = Path(path)
    with path.open("w", encoding="utf-8") as f:
        f.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        f.write(f'<kml xmlns="{KML_NS}"><Document><name>{escape(log.name)}</name>\n')
        f.write('<Style id="track"><LineStyle><color>ffc06515</color><width>3</width></LineStyle></Style>\n')
        for i, (la, lo) in enumerate(waypoints_latlon(log)):
            f.write(f"<Placemark><name>W{i}</name><Point><coordinates>{lo:.8f},{la:.8f},0"
                    "</coordinates></Point></Placemark>\n")
        segs = [(a, b) for a, b in segments(np.isfinite(lat)) if b - a >= 2]
        if segs:
            f.write(f"<Placemark><name>track</name><styleUrl>#track</styleUrl><MultiGeometry>\n")
            for a, b in segs:
                f.write("<LineString><tessellate>1</tessellate><coordinates>\n")
                for k0 in range(a, b, _CHUNK):
                    k1 = min(b, k0 + _CHUNK)
                    f.write("".join(f"{lo:.8f},{la:.8f},0\n"
                                    for la, lo in zip(lat[k0:k1].tolist(), lon[k0:k1].tolist())))
                f.write("</coordinates></LineString>\n")
            f.write("</MultiGeometry></Placemark>\n")
        f.write("</Document></kml>\n")
    return path


def write_geojson(log: MissionLog, path) -> Path:
    """GeoJSON FeatureCollection: the track and the waypoints, [lon, lat] order."""
    lat, lon = track_latlon(log)
    _need_track(log, lat, "GeoJSON")
    features = []
    lines = []
    for a, b in segments(np.isfinite(lat)):
        if b - a >= 2:
            lines.append([[round(x, 8), round(y, 8)] for x, y in zip(lon[a:b].tolist(), lat[a:b].tolist())])
    if lines:
        geometry = ({"type": "LineString", "coordinates": lines[0]} if len(lines) == 1
                    else {"type": "MultiLineString", "coordinates": lines})
        features.append({"type": "Feature", "geometry": geometry,
                         "properties": {"kind": "track", "name": log.name, "segments": len(lines)}})
    scores = closest_approaches(log)
    for i, (la, lo) in enumerate(waypoints_latlon(log)):
        ca = scores[i].closest_approach_m if i < len(scores) else math.nan
        features.append({"type": "Feature",
                         "geometry": {"type": "Point", "coordinates": [round(lo, 8), round(la, 8)]},
                         "properties": {"kind": "waypoint", "index": i, "name": f"W{i}",
                                        "closest_approach_m": ca if math.isfinite(ca) else None}})
    path = Path(path)
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}), encoding="utf-8")
    return path


def trial_columns(log: MissionLog) -> dict[str, np.ndarray]:
    """The trial CSV's columns (NaN = gap)."""
    lat, lon = track_latlon(log)
    heading = log.col("heading_deg")
    return {
        "t_s": log.col("t_s"), "thrust_port_n": log.col("thrust_port_n"),
        "thrust_stbd_n": log.col("thrust_stbd_n"), "north_m": log.col("north_m"),
        "east_m": log.col("east_m"), "heading_deg": np.where(np.isfinite(heading), wrap_360(heading), np.nan),
        "lat_deg": lat, "lon_deg": lon, "sog_m_s": log.col("sog_m_s"), "cog_deg": log.col("cog_deg"),
        "rot_deg_s": log.col("yaw_rate_deg_s"),
    }


def write_trial_csv(log: MissionLog, path) -> Path:
    """The identification workflow's trial CSV (issue 5 Inputs), one row per cycle."""
    cols = trial_columns(log)
    data = np.column_stack([cols[k] for k in CSV_COLUMNS])
    fmt = ",".join(_CSV_FORMATS) + "\n"
    path = Path(path)
    with path.open("w", encoding="utf-8") as f:
        f.write(",".join(CSV_COLUMNS) + "\n")
        for a in range(0, len(data), _CHUNK):
            text = "".join(fmt % tuple(row) for row in data[a:a + _CHUNK].tolist())
            f.write(text.replace("nan", ""))  # a gap is an empty field
    return path


WRITERS = {"gpx": (write_gpx, ".gpx"), "kml": (write_kml, ".kml"),
           "geojson": (write_geojson, ".geojson"), "csv": (write_trial_csv, ".csv")}


def export(log: MissionLog, formats, out_dir, *, stem: str | None = None) -> dict[str, Path]:
    """Write each requested format to ``out_dir/<stem>.<ext>``; return {format: path}."""
    out_dir = Path(out_dir)
    stem = stem or log.path.stem
    written = {}
    for fmt in formats:
        writer, ext = WRITERS[fmt]
        written[fmt] = writer(log, out_dir / f"{stem}{ext}")
    return written
