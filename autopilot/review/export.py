"""Exports of a mission log to tools people already have.

- GPX 1.1 (http://www.topografix.com/GPX/1/1): waypoints as ``wpt``, the
  track as ``trk`` with one ``trkseg`` per unbroken stretch, times from the
  ``mission_start`` timestamp plus mission time.
- KML 2.2 (Google Earth): a waypoint Placemark each, the track as a
  LineString (a MultiGeometry of LineStrings when it has gaps).
- GeoJSON (RFC 7946, lon/lat order): a FeatureCollection of the track
  (LineString, or MultiLineString when it has gaps) and one Point per
  waypoint.
- The trial CSV read by the identification workflow: columns ``t_s,
  thrust_port_n, thrust_stbd_n, north_m, east_m, position_time_s, heading_deg,
  heading_time_s, lat_deg, lon_deg, sog_m_s, cog_deg, rot_deg_s``; a command on
  every cycle row, each position fix and heading sample once, on the row where
  it arrived, with the time it was measured; every other cell is empty.

Positions are measurements: the track is one point per position fix at the
time the fix was measured (``t_s - position_age_s``), never the held fix
repeated on every 10 Hz cycle. They come from the logged latitude/longitude;
where a cycle has only the local position, the log's origin converts it (SPEC
section 2). Gaps are never filled: a track breaks where the position is
missing.
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
CSV_COLUMNS = ("t_s", "thrust_port_n", "thrust_stbd_n", "north_m", "east_m", "position_time_s", "heading_deg",
               "heading_time_s", "lat_deg", "lon_deg", "sog_m_s", "cog_deg", "rot_deg_s")
_CSV_FORMATS = ("%.3f", "%.3f", "%.3f", "%.3f", "%.3f", "%.3f", "%.2f", "%.3f", "%.8f", "%.8f", "%.3f", "%.2f", "%.3f")
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


FIX_GAP_FACTOR = 5.0  # fixes further apart than this many typical fix intervals are separate segments


def track_fixes(log: MissionLog) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[int, int]]]:
    """The track as measured: one point per position fix, at the fix's time.

    Returns fix times (mission s), latitudes, longitudes and the [start, stop) index ranges of
    unbroken stretches: a stretch breaks where the position was lost between two fixes or
    the fixes are more than FIX_GAP_FACTOR typical intervals apart (nothing is drawn across).
    """
    lat_row, lon_row = track_latlon(log)
    rows, fix_t = log.fix_rows()
    keep = np.isfinite(lat_row[rows])
    rows, fix_t = rows[keep], fix_t[keep]
    lat, lon = lat_row[rows], lon_row[rows]
    if len(rows) == 0:
        return fix_t, lat, lon, []
    return fix_t, lat, lon, fix_stretches(rows, fix_t, np.isfinite(lat_row))


def fix_stretches(rows: np.ndarray, fix_t: np.ndarray, has_position: np.ndarray) -> list[tuple[int, int]]:
    """The [start, stop) index ranges (into ``rows``, the fixes' rows, measured at ``fix_t``) of unbroken
    stretches: a stretch breaks where a row between two fixes has no position (``has_position``, per row) or
    the fixes are more than FIX_GAP_FACTOR typical intervals apart (the daemon holds the last fix through an
    outage: drawn as measured, the track crossed 8 s without a fix in a straight line)."""
    if len(rows) == 0:
        return []
    lost = np.cumsum(~has_position)  # rows without a position so far
    dt = np.diff(fix_t)
    typical = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    brk = (lost[rows[1:]] != lost[rows[:-1]]) | (dt > FIX_GAP_FACTOR * typical) | (dt <= 0)
    cuts = np.concatenate([[0], np.nonzero(brk)[0] + 1, [len(rows)]])
    return list(zip(cuts[:-1].tolist(), cuts[1:].tolist()))


def waypoints_latlon(log: MissionLog) -> list[tuple[str, float, float]]:
    """(label, lat, lon) of every waypoint of every plan (``MissionLog.all_waypoints``); empty when the log has
    no origin."""
    named = log.all_waypoints()
    if log.origin_deg is None or not named:
        return []
    wps = np.array([(wn, we) for _, wn, we in named])
    lat, lon = local_to_latlon(wps[:, 0], wps[:, 1], *log.origin_deg)
    return [(label, float(la), float(lo)) for (label, _, _), la, lo in zip(named, np.atleast_1d(lat), np.atleast_1d(lon))]


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
    """GPX 1.1: waypoints and the track (one point per fix, at its time), a segment per unbroken stretch."""
    fix_t, lat, lon, segs = track_fixes(log)
    _need_track(log, lat, "GPX")
    t0 = _start_time(log)
    tm0 = _mission_t0(log)
    path = Path(path)
    with path.open("w", encoding="utf-8") as f:
        f.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        f.write(f'<gpx version="1.1" creator="autopilot review" xmlns="{GPX_NS}">\n')
        f.write(f"  <metadata><name>{escape(log.name)}</name>")
        if t0 is not None:
            f.write(f"<time>{t0.strftime('%Y-%m-%dT%H:%M:%SZ')}</time>")
        f.write("</metadata>\n")
        for label, la, lo in waypoints_latlon(log):
            f.write(f'  <wpt lat="{la:.8f}" lon="{lo:.8f}"><name>{escape(label)}</name></wpt>\n')
        f.write(f"  <trk><name>{escape(log.name)}</name>\n")
        for a, b in segs:
            f.write("    <trkseg>\n")
            for k0 in range(a, b, _CHUNK):
                k1 = min(b, k0 + _CHUNK)
                if t0 is not None:
                    base = t0.timestamp()
                    stamps = [_dt.datetime.fromtimestamp(base + x - tm0, _dt.timezone.utc)
                              .strftime("%Y-%m-%dT%H:%M:%S.%fZ")[:-4] + "Z"
                              for x in fix_t[k0:k1].tolist()]
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
    """KML 2.2 for Google Earth: waypoints and the track (one point per fix)."""
    _, lat, lon, stretches = track_fixes(log)
    _need_track(log, lat, "KML")
    path = Path(path)
    with path.open("w", encoding="utf-8") as f:
        f.write('<?xml version="1.0" encoding="UTF-8"?>\n')
        f.write(f'<kml xmlns="{KML_NS}"><Document><name>{escape(log.name)}</name>\n')
        f.write('<Style id="track"><LineStyle><color>ffc06515</color><width>3</width></LineStyle></Style>\n')
        for label, la, lo in waypoints_latlon(log):
            f.write(f"<Placemark><name>{escape(label)}</name><Point><coordinates>{lo:.8f},{la:.8f},0"
                    "</coordinates></Point></Placemark>\n")
        segs = [(a, b) for a, b in stretches if b - a >= 2]
        if segs:
            f.write("<Placemark><name>track</name><styleUrl>#track</styleUrl><MultiGeometry>\n")
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
    """GeoJSON FeatureCollection: the track (one point per fix) and the waypoints, [lon, lat] order."""
    _, lat, lon, stretches = track_fixes(log)
    _need_track(log, lat, "GeoJSON")
    features = []
    lines = []
    for a, b in stretches:
        if b - a >= 2:
            lines.append([[round(x, 8), round(y, 8)] for x, y in zip(lon[a:b].tolist(), lat[a:b].tolist())])
    if lines:
        geometry = ({"type": "LineString", "coordinates": lines[0]} if len(lines) == 1
                    else {"type": "MultiLineString", "coordinates": lines})
        features.append({"type": "Feature", "geometry": geometry,
                         "properties": {"kind": "track", "name": log.name, "segments": len(lines)}})
    scores = closest_approaches(log)  # one per waypoint of every plan, in the same order
    for k, (label, la, lo) in enumerate(waypoints_latlon(log)):
        w = scores[k] if k < len(scores) else None
        ca = w.closest_approach_m if w is not None else math.nan
        features.append({"type": "Feature",
                         "geometry": {"type": "Point", "coordinates": [round(lo, 8), round(la, 8)]},
                         "properties": {"kind": "waypoint", "index": w.index if w is not None else k, "name": label,
                                        "mission": w.mission if w is not None else 1,
                                        "closest_approach_m": ca if math.isfinite(ca) else None}})
    path = Path(path)
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}), encoding="utf-8")
    return path


def trial_columns(log: MissionLog) -> dict[str, np.ndarray]:
    """The trial CSV's columns (NaN = gap): the cycle's command on every row, each measurement once.

    A position appears on the row where its fix first reached the daemon, with
    ``position_time_s`` the time it was measured (``t_s - position_age_s``); the rows that
    only repeat a held fix leave it empty. Likewise the heading and ``heading_time_s``. Speed
    and course over ground appear once per reading, by sysid's own rule (``MissionLog.velocity_rows``:
    where they change, and once each fix epoch where they stay the same through STEADY_EPOCHS epochs),
    each after an empty cell, so that ``autopilot sysid`` reads the CSV's readings at the times it reads
    the log's.
    """
    lat_row, lon_row = track_latlon(log)
    n = log.n_cycles

    def once(rows, values):
        out = np.full(n, np.nan)
        out[rows] = values[rows]
        return out

    fix, fix_t = log.fix_rows()
    head, head_t = log.heading_rows()
    vel = log.velocity_rows()
    heading = log.compass_heading_deg()  # not the course over ground a COG fallback steered on
    heading = np.where(np.isfinite(heading), wrap_360(heading), np.nan)
    position_time_s, heading_time_s = np.full(n, np.nan), np.full(n, np.nan)
    position_time_s[fix], heading_time_s[head] = fix_t, head_t
    return {
        "t_s": log.col("t_s"), "thrust_port_n": log.col("thrust_port_n"),
        "thrust_stbd_n": log.col("thrust_stbd_n"),
        "north_m": once(fix, log.col("north_m")), "east_m": once(fix, log.col("east_m")),
        "position_time_s": position_time_s,
        "heading_deg": once(head, heading), "heading_time_s": heading_time_s,
        "lat_deg": once(fix, lat_row), "lon_deg": once(fix, lon_row),
        "sog_m_s": once(vel, log.col("sog_m_s")), "cog_deg": once(vel, log.col("cog_deg")),
        "rot_deg_s": log.col("yaw_rate_deg_s"),
    }


def write_trial_csv(log: MissionLog, path) -> Path:
    """The identification workflow's trial CSV (issue 5 Inputs), one row per cycle, but for the cycles whose
    commands the motors may not have had (``MissionLog.undelivered_rows``: an Mbed link lost): left out, a gap
    that ``autopilot sysid`` cuts the trial at, as the log itself (the CSV has no column to say it)."""
    cols = trial_columns(log)
    data = np.column_stack([cols[k] for k in CSV_COLUMNS])[~log.undelivered_rows()]
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
