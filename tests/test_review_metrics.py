"""Scorecard numbers against hand-computed values and the synthetic mission's truth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.review.metrics import cross_track_m, hold_durations_s, score
from autopilot.review.reader import read_log
from autopilot.review.synthetic import write_synthetic_log

START = {"event": "mission_start", "t_s": 0.0, "rate_hz": 10.0, "origin_lat_deg": 59.0,
         "origin_lon_deg": 10.0, "waypoints": [[10.0, 0.0], [10.0, 10.0]], "mission_name": "hand"}


def _write(path, records):
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return path


def _cycles(n, **columns):
    out = []
    for k in range(n):
        rec = {"event": "cycle", "t_s": round(0.1 * k, 3), "mode": "auto"}
        for name, values in columns.items():
            v = values[k] if isinstance(values, (list, np.ndarray)) else values
            rec[name] = None if (isinstance(v, float) and math.isnan(v)) else v
        out.append(rec)
    return out


def test_thrust_energy_is_a_held_integral(tmp_path):
    # 100 cycles of 10 N + -5 N, each held 0.1 s: (10 + 5) * 10 s
    log = read_log(_write(tmp_path / "e.jsonl", [START] + _cycles(100, thrust_port_n=10.0, thrust_stbd_n=-5.0)))
    card = score(log)
    assert_allclose(card.thrust_energy_n_s, 150.0, rtol=1e-9)
    assert card.thrust_unknown_s == 0.0


def test_unknown_thrust_and_log_gaps_are_not_integrated(tmp_path):
    recs = _cycles(100, thrust_port_n=10.0, thrust_stbd_n=10.0)
    for r in recs[10:20]:
        r["thrust_port_n"] = None
    for r in recs[50:]:
        r["t_s"] += 30.0  # the log skips 30 s
    card = score(read_log(_write(tmp_path / "g.jsonl", [START] + recs)))
    assert_allclose(card.thrust_unknown_s, 1.0, atol=1e-9)
    assert_allclose(card.log_gap_s, 30.1, atol=1e-9)
    assert_allclose(card.thrust_energy_n_s, 20.0 * (100 - 10 - 1) * 0.1, rtol=1e-9)
    assert_allclose(card.mission_time_s, 39.9 + 0.0, atol=1e-9)


def test_hold_durations():
    hold, gap = hold_durations_s(np.array([0.0, 0.1, 0.2, 5.0, 5.1]), 0.1)
    assert_allclose(hold, [0.1, 0.1, 0.0, 0.1, 0.1], atol=1e-12)
    assert_allclose(gap, 4.8)


def test_cross_track_recomputed_from_legs(tmp_path):
    # leg 0 from the start (0, 0) to (10, 0), i.e. due north: east offset = starboard
    # leg 1 from (10, 0) to (10, 10), due east: south offset = starboard
    north = [0.0, 5.0, 8.0, 10.5, 12.0, 9.0]
    east = [0.0, 1.0, -2.0, 5.0, 8.0, 3.0]
    wp = [0, 0, 0, 1, 1, 1]
    log = read_log(_write(tmp_path / "x.jsonl", [START] + _cycles(6, north_m=north, east_m=east, wp_index=wp)))
    assert_allclose(cross_track_m(log), [0.0, 1.0, -2.0, -0.5, -2.0, 1.0], atol=1e-12)
    card = score(log)
    assert_allclose(card.xte_max_m, 2.0)
    assert_allclose(card.xte_rms_m, math.sqrt((1 + 4 + 0.25 + 4 + 1) / 6))
    assert math.isnan(card.logged_xte_rms_m)  # not logged: not invented


def test_synthetic_mission_scorecard(tmp_path):
    truth = write_synthetic_log(tmp_path / "m.jsonl", weave_m=1.0)
    log = read_log(tmp_path / "m.jsonl")
    card = score(log)
    assert card.complete and card.stop_reason == "complete" and not card.failsafes
    # the weave is the cross-track error by construction (away from the corners), at the fixes
    xte = cross_track_m(log)
    fixes = truth["fix_rows"]
    assert_allclose(xte[fixes], truth["weave_m"][fixes], atol=0.05)
    assert_allclose(card.xte_max_m, np.max(np.abs(truth["weave_m"][fixes])), atol=0.05)
    fn, fe = truth["north_m"][fixes], truth["east_m"][fixes]
    assert_allclose(card.distance_m, np.sum(np.hypot(np.diff(fn), np.diff(fe))), rtol=1e-3)  # through the fixes
    for w, expect in zip(card.waypoints, truth["closest_approach_m"]):
        assert_allclose(w.closest_approach_m, expect, atol=2e-3)  # recomputed: the pass's closest fix
        assert_allclose(w.logged_closest_approach_m, expect, atol=2e-3)  # as logged in waypoint_pass
        assert w.reached
    assert card.lateness_ms["p50"] < card.lateness_ms["p99"] <= card.lateness_ms["max"]
    stop = log.events_named("stop")[0]
    assert card.nmea_dropped == stop["nmea_dropped"] and card.ack_missing == stop["ack_missing"]


def test_failsafe_mission_scorecard(tmp_path):
    write_synthetic_log(tmp_path / "f.jsonl", failsafe_at_s=20.0)
    card = score(read_log(tmp_path / "f.jsonl"))
    assert [c for _, c in card.failsafes] == ["heading_stale"]
    assert_allclose(card.failsafes[0][0], 20.0)
    assert_allclose(card.failsafe_time_s, 3.1, atol=1e-6)  # 31 failsafe cycles of 0.1 s
    assert_allclose(card.heading_lost_s, 3.1, atol=1e-6)
    assert card.faults == {"heading_stale": {"count": 1, "time_s": pytest.approx(3.0)}}
    assert not card.complete and card.stop_reason == "signal"
    reached = [w.reached for w in card.waypoints]
    assert reached == [True, False, False]


def test_empty_log_scorecard(tmp_path):
    (tmp_path / "e.jsonl").write_text("")
    card = score(read_log(tmp_path / "e.jsonl"))
    assert card.cycles == 0 and math.isnan(card.distance_m) and math.isnan(card.thrust_energy_n_s)
    assert card.waypoints == [] and card.lateness_ms == {}
    json.dumps(card.to_dict(), allow_nan=False)  # NaN becomes null, never a number
