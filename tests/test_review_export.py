"""Exports parsed back: GPX 1.1 and KML as XML, GeoJSON as JSON, the trial CSV with csv."""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.geo import latlon_to_local
from autopilot.review.export import (
    CSV_COLUMNS,
    GPX_NS,
    KML_NS,
    export,
    parse_formats,
    write_geojson,
    write_gpx,
    write_kml,
    write_trial_csv,
)
from autopilot.review.reader import read_log
from autopilot.review.synthetic import DEFAULT_ORIGIN_DEG, write_synthetic_log
from autopilot.schema import ConfigError


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    truth = write_synthetic_log(d / "m.jsonl", dropout_every_s=10.0, failsafe_at_s=30.0)
    return d, read_log(d / "m.jsonl"), truth


def _local(lat, lon):
    return latlon_to_local(np.asarray(lat), np.asarray(lon), *DEFAULT_ORIGIN_DEG)


def test_gpx_is_gpx_1_1_with_track_and_waypoints(mission):
    d, log, truth = mission
    root = ET.parse(write_gpx(log, d / "m.gpx")).getroot()
    ns = {"g": GPX_NS}
    assert root.tag == f"{{{GPX_NS}}}gpx" and root.get("version") == "1.1"
    wpts = root.findall("g:wpt", ns)
    n, e = _local([float(w.get("lat")) for w in wpts], [float(w.get("lon")) for w in wpts])
    assert_allclose(np.column_stack([n, e]), truth["waypoints_ne_m"], atol=0.01)
    segs = root.findall("g:trk/g:trkseg", ns)
    assert len(segs) > 1  # the drop-outs break the track
    pts = root.findall("g:trk/g:trkseg/g:trkpt", ns)
    rows, fix_t = log.fix_rows()
    assert len(pts) == len(rows) == len(truth["fix_rows"])  # one point per fix, not per 10 Hz cycle
    n, e = _local([float(p.get("lat")) for p in pts], [float(p.get("lon")) for p in pts])
    assert_allclose(n, truth["north_m"][truth["fix_rows"]], atol=0.01)
    assert_allclose(e, truth["east_m"][truth["fix_rows"]], atol=0.01)
    times = [p.find("g:time", ns).text for p in pts]
    # each at the time the fix was measured (50 ms before the cycle that first logged it)
    assert times[0] == "2024-05-21T09:29:59.950Z" and times[1] == "2024-05-21T09:30:00.950Z"
    assert len(set(times)) == len(times)


def test_kml_parses_with_lon_lat_order(mission):
    d, log, truth = mission
    root = ET.parse(write_kml(log, d / "m.kml")).getroot()
    ns = {"k": KML_NS}
    assert root.tag == f"{{{KML_NS}}}kml"
    points = root.findall(".//k:Placemark/k:Point/k:coordinates", ns)
    assert len(points) == len(truth["waypoints_ne_m"])
    lon, lat, _ = (float(x) for x in points[0].text.split(","))
    assert_allclose(_local(lat, lon), truth["waypoints_ne_m"][0], atol=0.01)
    lines = root.findall(".//k:LineString/k:coordinates", ns)
    coords = [ln.split(",") for c in lines for ln in c.text.split()]
    assert len(coords) == len(log.fix_rows()[0])  # one coordinate per fix


def test_geojson_feature_collection(mission):
    d, log, truth = mission
    doc = json.loads(write_geojson(log, d / "m.geojson").read_text())
    assert doc["type"] == "FeatureCollection"
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("track") == 1 and kinds.count("waypoint") == len(truth["waypoints_ne_m"])
    track = doc["features"][0]["geometry"]
    assert track["type"] == "MultiLineString"  # gaps break it, no line bridges a drop-out
    first = track["coordinates"][0][0]
    assert_allclose(first, [DEFAULT_ORIGIN_DEG[1], DEFAULT_ORIGIN_DEG[0]], atol=1e-7)  # [lon, lat]
    wp = doc["features"][1]
    assert wp["geometry"]["type"] == "Point"
    assert_allclose(_local(wp["geometry"]["coordinates"][1], wp["geometry"]["coordinates"][0]),
                    truth["waypoints_ne_m"][0], atol=0.01)


def test_geojson_single_segment_is_a_linestring(tmp_path):
    write_synthetic_log(tmp_path / "s.jsonl")
    doc = json.loads(write_geojson(read_log(tmp_path / "s.jsonl"), tmp_path / "s.geojson").read_text())
    assert doc["features"][0]["geometry"]["type"] == "LineString"


def test_trial_csv_round_trip_with_gaps(mission):
    d, log, truth = mission
    with open(write_trial_csv(log, d / "m.csv"), newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert len(rows) == log.n_cycles

    def col(name):
        return np.array([float(r[name]) if r[name] != "" else np.nan for r in rows])

    assert_allclose(col("t_s"), truth["t_s"], atol=1e-3)
    assert_allclose(col("thrust_port_n"), truth["thrust_port_n"], atol=1e-3)
    north = col("north_m")
    # each fix once, on the row it arrived, with its measurement time; held rows empty
    assert_allclose(np.nonzero(np.isfinite(north))[0], truth["fix_rows"])
    assert_allclose(north[truth["fix_rows"]], truth["north_m"][truth["fix_rows"]], atol=2e-3)
    assert_allclose(col("position_time_s")[truth["fix_rows"]], truth["fix_t_s"], atol=2e-3)
    assert np.array_equal(np.isfinite(col("position_time_s")), np.isfinite(north))
    assert np.isnan(col("heading_deg")[-1])  # heading lost in the failsafe: empty, not 0
    h = col("heading_deg")
    assert np.all((h[np.isfinite(h)] >= 0) & (h[np.isfinite(h)] < 360))
    assert np.array_equal(np.isfinite(col("heading_time_s")), np.isfinite(h))


def test_export_without_positions_is_refused(tmp_path):
    (tmp_path / "e.jsonl").write_text("")
    with pytest.raises(ConfigError, match="no latitude"):
        write_gpx(read_log(tmp_path / "e.jsonl"), tmp_path / "e.gpx")


@pytest.mark.parametrize("text, expect", [("gpx", ("gpx",)), ("csv, KML,csv", ("csv", "kml")), ("", ())])
def test_parse_formats(text, expect):
    assert parse_formats(text) == expect


def test_parse_formats_refuses_unknown():
    with pytest.raises(ConfigError, match="shp"):
        parse_formats("gpx,shp")


def test_sysid_accepts_the_trial_csv(mission, tmp_path):
    sysid_cli = pytest.importorskip("autopilot.sysid.cli", reason="autopilot sysid not built yet")
    del sysid_cli
    from autopilot.cli import main

    d, log, _ = mission
    csv_path = export(log, ("csv",), tmp_path)["csv"]
    rc = main(["sysid", str(csv_path), "--out", str(tmp_path / "sysid")])
    assert rc == 0
    summary = json.loads((tmp_path / "sysid" / "summary.json").read_text())
    assert "verdict" in summary and math.isfinite(summary["rmse_before"]["fitted"]["position_m"])
