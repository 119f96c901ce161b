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


def test_leg_0_runs_from_the_launch_point_where_the_helm_started_it(tmp_path):
    """Found by a new-user audit: leg 0 ran from the first fix, taken while the daemon waited for valid data; a boat
    that drifted 1.85 m across it in a 0.5 m/s current before control started (pond-9.4, --sim) scored 3.19 m RMS
    against the guidance's own 2.66 m (2.64 m now). The helm starts leg 0 where it launches."""
    north = [0.0, 0.0, 0.0, 5.0, 8.0]
    east = [0.0, 1.0, 2.0, 2.0, 2.0]  # drifted east before the launch at t 0.2 s, then north along x = 2
    wp = [0, 0, 0, 0, 0]
    recs = _cycles(5, north_m=north, east_m=east, wp_index=wp)
    launch = {"event": "launch", "t_s": 0.2, "north_m": 0.0, "east_m": 2.0}
    log = read_log(_write(tmp_path / "l.jsonl", [START] + recs[:3] + [launch] + recs[3:]))
    # leg 0 from (0, 2) to (10, 0): the boat on x = 2 is to port of it, by its distance to that line
    d = np.array([10.0, -2.0]) / math.hypot(10.0, -2.0)
    expected = [(d[0] * (e - 2.0) - d[1] * n) for n, e in zip(north, east)]
    assert_allclose(cross_track_m(log), expected, atol=1e-12)
    assert abs(cross_track_m(log)[2]) < 1e-12  # at the launch point: on the leg
    # an interrupted run's launch point carried over a restart is not where this run's helm started leg 0
    carried = read_log(_write(tmp_path / "c.jsonl", [START] + recs[:3] + [{**launch, "carried": True}] + recs[3:]))
    d0 = np.array([1.0, 0.0])  # from the first fix (0, 0) to (10, 0)
    assert_allclose(cross_track_m(carried), [d0[0] * e - d0[1] * n for n, e in zip(north, east)], atol=1e-12)


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
    path_m = np.sum(np.hypot(np.diff(truth["north_m"]), np.diff(truth["east_m"])))  # the path the boat ran
    assert_allclose(card.distance_m, path_m, rtol=0.02)  # speed over ground at 1 Hz, integrated
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


def _wandering_fixes(n_cycles: int, seed: int = 1, wander_m: float = 1.5, tau_s: float = 45.0):
    """A boat at rest seen by a 1 Hz receiver: Gauss-Markov wander of its position (as the SC-30 model
    and a real receiver show), each fix held on the 10 Hz cycle lines with its age, and the few cm/s of
    speed-over-ground noise a receiver at rest reports."""
    rng = np.random.default_rng(seed)
    fixes = n_cycles // 10 + 1
    a = math.exp(-1.0 / tau_s)
    w = np.zeros((fixes, 2))
    for k in range(1, fixes):
        w[k] = a * w[k - 1] + wander_m * math.sqrt(1 - a * a) * rng.normal(size=2)
    w += rng.normal(0.0, 0.3, size=w.shape)  # the white part
    k = np.arange(n_cycles) // 10
    return dict(north_m=w[k, 0], east_m=w[k, 1], position_age_s=np.round(0.1 * (np.arange(n_cycles) % 10), 3),
                sog_m_s=np.abs(rng.normal(0.0, 0.05, fixes))[k], cog_deg=rng.uniform(0, 360, fixes)[k])


def test_a_boat_at_rest_runs_no_distance_however_its_gps_wanders(tmp_path):
    """Found by a review audit: the distance run summed the steps between fixes, GPS wander included: 638 m for
    a boat held at its launch point for 20 min, 26 m for a held start that never moved."""
    cols = _wandering_fixes(6000)  # 10 min
    log = read_log(_write(tmp_path / "rest.jsonl", [START] + _cycles(6000, mode="hold", thrust_port_n=0.0,
                                                                           thrust_stbd_n=0.0, **cols)))
    n, e = cols["north_m"][::10], cols["east_m"][::10]
    assert np.sum(np.hypot(np.diff(n), np.diff(e))) > 100.0  # what the fixes' steps add up to
    assert score(log).distance_m < 1.0  # 10 min at rest (the fixes' steps: over 100 m)


def test_a_held_start_has_no_tracking_score_and_a_hold_is_not_a_leg(tmp_path):
    """Found by a review audit: a held restart (every cycle in `stop`) was scored 0.28 / 0.77 m of cross-track
    error, as if it had tracked well (the every-cycle fallback is for logs that state no mode); and a 300-s
    hold at a waypoint was scored as leg 0's cross-track error (the daemon logs none there)."""
    cols = _wandering_fixes(600)
    held = read_log(_write(tmp_path / "held.jsonl", [START] + _cycles(600, mode="stop", wp_index=0, **cols)))
    card = score(held)
    assert math.isnan(card.xte_rms_m) and math.isnan(card.xte_max_m)
    # 20 s along leg 0 (due north, 0.5 m to starboard), then 60 s holding 3 m off W0's side of the leg
    on_leg = _cycles(200, north_m=list(np.round(0.05 * np.arange(200), 3)), east_m=[0.0] + [0.5] * 199, wp_index=0)
    hold = _cycles(600, north_m=10.0, east_m=3.0, wp_index=0, holding=True, hold_north_m=10.0, hold_east_m=0.0)
    for k, r in enumerate(hold):
        r["t_s"] = round(20.0 + 0.1 * k, 3)
    card = score(read_log(_write(tmp_path / "hold.jsonl", [START] + on_leg + hold)))
    assert_allclose([card.xte_rms_m, card.xte_max_m], [0.5 * math.sqrt(199 / 200), 0.5], atol=1e-9)  # the leg only
    plain = score(read_log(_write(tmp_path / "plain.jsonl", [START] + _cycles(5, north_m=[0.0, 1, 2, 3, 4],
                                                                             east_m=[0.0, 2, 2, 2, 2], wp_index=0,
                                                                             mode=None))))
    assert_allclose(plain.xte_max_m, 2.0)  # a log that states no mode: every cycle is judged, as before


def test_stale_time_is_judged_by_the_daemons_own_limits(tmp_path):
    """Found by a review audit: the review counted a heading older than 0.5 s stale (its own constant), the
    daemon faults at failsafe.heading_stale_s = 1 s: 141.7 s "stale" beside 35 s of heading_stale faults."""
    ages = np.tile(np.round(np.arange(10) * 0.1, 3), 20)  # the heading ages 0..0.9 s, again and again
    recs = _cycles(200, heading_deg=10.0, heading_age_s=ages)
    default = score(read_log(_write(tmp_path / "a.jsonl", [START] + recs)))
    assert default.heading_stale_s == 0.0 and default.heading_stale_after_s == 1.0  # the daemon's default
    strict = dict(START, config={"failsafe": {"heading_stale_s": 0.45, "position_stale_s": 2.5}})
    card = score(read_log(_write(tmp_path / "b.jsonl", [strict] + recs)))
    assert_allclose(card.heading_stale_s, 20 * 5 * 0.1, atol=1e-9)  # ages 0.5 .. 0.9 s
    assert (card.heading_stale_after_s, card.position_stale_after_s) == (0.45, 2.5)
    assert "heading lost / stale (older than 0.45 s)" in dict(card.table_rows())


def test_mission_time_counts_from_mission_start_and_a_failsafes_rtl_is_time_in_failsafe(tmp_path):
    """Found by a review audit: the mission time ran from the first cycle (49.1 s for the daemon's 51.2 s; 89 s
    for a run the 90-s limit stopped), and "time in failsafe" counted the `failsafe` mode only: 0 s for a
    battery_low rtl that then held at launch for 20 min."""
    recs = _cycles(300, mode="auto")
    for r in recs:
        r["t_s"] = round(r["t_s"] + 1.2, 3)  # the first cycle once the sensors answer
    for r in recs[100:150]:
        r["mode"] = "rtl"
    for r in recs[150:250]:
        r["mode"] = "hold"
    for r in recs[250:]:
        r["mode"] = "manual"
    events = [{"event": "failsafe", "t_s": recs[100]["t_s"], "cause": "battery_low", "action": "rtl"},
              {"event": "mode", "t_s": recs[100]["t_s"], "mode": "rtl", "from": "auto", "cause": "failsafe battery_low"},
              {"event": "mode", "t_s": recs[150]["t_s"], "mode": "hold", "from": "rtl", "cause": "rtl: at the launch point"},
              {"event": "mode", "t_s": recs[250]["t_s"], "mode": "manual", "from": "hold", "cause": "ctl manual"}]
    card = score(read_log(_write(tmp_path / "fs.jsonl", [START] + recs[:100] + events[:2] + recs[100:150] + events[2:3]
                                 + recs[150:250] + events[3:] + recs[250:])))
    assert_allclose(card.mission_time_s, recs[-1]["t_s"], atol=1e-9)
    assert_allclose(card.failsafe_time_s, 15.0, atol=1e-6)  # rtl 5 s and its hold 10 s; not the operator's manual


def test_the_distance_run_counts_a_receivers_repeated_speeds_and_needs_no_course(tmp_path):
    """Found by a review: the first distance by speed over ground integrated only where the (speed, course) pair
    changed: a receiver rounding to 0.1 kn and 1 deg at a steady 1.5 m/s repeats its pair, and 300 s ran 56 m
    for 448; a speed without a course fell back to the fixes, saying "no speed over ground logged"."""
    n = 3000  # 300 s at 10 Hz, a fix a second held on the cycle lines
    t = np.round(0.1 * np.arange(n), 3)
    north = np.round(1.5 * np.floor(t), 3)
    knots = round(1.5 / 0.514444, 1)  # what the receiver says, every second
    sog = np.full(n, knots * 0.514444)
    for cog in (0.0, None):
        recs = _cycles(n, north_m=north, east_m=0.0, position_age_s=np.round(t - np.floor(t), 3), sog_m_s=sog,
                       cog_deg=cog if cog is not None else math.nan)
        card = score(read_log(_write(tmp_path / f"steady-{cog}.jsonl", [START] + recs)))
        assert card.distance_m == pytest.approx(1.5 * 300.0, rel=0.01), cog
        assert not any("through the fixes" in note for note in card.read_notes)


def test_an_undated_waypoint_line_counts_in_the_mission_it_was_written_under(tmp_path):
    """Found by a review: a waypoint_reached without t_s counted as reached in every mission of a log whose
    mission was replaced (M1 W0 and M2 W0 both reached for one line). Undated, a line belongs to the mission in
    force where it stands in the file."""
    recs = _cycles(200, north_m=list(np.round(0.1 * np.arange(200), 2)), east_m=0.0, wp_index=0)
    replaced = {"event": "mission_replaced", "t_s": 10.0, "source": "mavlink", "waypoints": [[30.0, 0.0], [30.0, 10.0]]}
    undated = {"event": "waypoint_reached", "wp_index": 0}
    card = score(read_log(_write(tmp_path / "m.jsonl", [START] + recs[:50] + [undated] + recs[50:100] + [replaced]
                                 + recs[100:])))
    assert [(w.label, w.reached) for w in card.waypoints] == [("M1 W0", True), ("M1 W1", False), ("M2 W0", False),
                                                              ("M2 W1", False)]


def test_a_boat_drifting_with_its_thrusters_off_runs_the_distance_it_drifts(tmp_path):
    """Found by a verification: with 0.3 m/s (the course's threshold) as rest, a boat stopped in a 0.3 m/s
    current drifted 28 m and the review said 0.6 m (its receiver said 0.27-0.30 m/s every fix)."""
    n = 1000  # 100 s
    t = np.round(0.1 * np.arange(n), 3)
    rng = np.random.default_rng(7)
    sog = (0.28 + rng.normal(0.0, 0.01, n // 10 + 1))[np.arange(n) // 10]
    recs = _cycles(n, mode="stop", north_m=0.0, east_m=np.round(0.28 * np.floor(t), 3), thrust_port_n=0.0,
                   thrust_stbd_n=0.0, position_age_s=np.round(t - np.floor(t), 3), sog_m_s=sog, cog_deg=90.0)
    assert score(read_log(_write(tmp_path / "drift.jsonl", [START] + recs))).distance_m == pytest.approx(28.0, rel=0.03)



def test_how_a_run_ended_is_said_as_the_daemon_says_it(tmp_path):
    """A run that ended on its own, and one stopped before its route was complete (the daemon's own run stopped in
    its final hold: tests/test_daemon_e2e.py)."""
    done = tmp_path / "done.jsonl"
    write_synthetic_log(done)
    card = score(read_log(done))
    assert card.finished and dict(card.table_rows())["stop"] == "complete: mission complete"
    cut = tmp_path / "cut.jsonl"
    write_synthetic_log(cut, failsafe_at_s=20.0)
    card = score(read_log(cut))
    assert not card.finished and not card.complete and dict(card.table_rows())["stop"] == "stopped by SIGTERM"


def test_the_closest_approach_summary_is_over_the_waypoints_reached(tmp_path):
    """Found by a review audit: a run stopped by a signal as its next pass began showed "closest approach, mean /
    max 5.47 / 20.24 m" for waypoints reached at 0.74 m at most: the unreached one's distance was in both."""
    write_synthetic_log(tmp_path / "full.jsonl")
    lines = (tmp_path / "full.jsonl").read_text().splitlines(keepends=True)
    cut = [ln for ln in lines[: len(lines) * 6 // 10] if '"event": "stop"' not in ln]
    (tmp_path / "cut.jsonl").write_text("".join(cut))
    card = score(read_log(tmp_path / "cut.jsonl"))
    reached = [w.closest_approach_m for w in card.waypoints if w.reached]
    short = [w for w in card.waypoints if not w.reached and math.isfinite(w.closest_approach_m)]
    assert reached and short and max(w.closest_approach_m for w in short) > max(reached)
    value = dict(card.table_rows())["closest approach of the waypoints reached, mean / max"]
    assert value.startswith(f"{np.mean(reached):.2f} / {np.max(reached):.2f} m; not reached: "), value
    assert f"{short[0].label} {short[0].closest_approach_m:.2f} m" in value


def test_waypoints_passed_in_a_hole_in_the_log_are_said_so_not_missed(tmp_path):
    """Found by a review audit: with 30 s of a log lost, two waypoints reached in the hole were "not reached", at
    6.73 and 3.58 m recomputed from the fixes left (0.17 and 0.34 m in truth), and the track plot drew them so."""
    write_synthetic_log(tmp_path / "full.jsonl")
    lines = (tmp_path / "full.jsonl").read_text().splitlines(keepends=True)
    kept = [ln for ln in lines if not 6.0 < (json.loads(ln).get("t_s") or 0.0) < 28.0]
    (tmp_path / "hole.jsonl").write_text("".join(kept))
    full, hole = (score(read_log(tmp_path / f"{n}.jsonl")) for n in ("full", "hole"))
    assert [w.reached for w in full.waypoints] == [True, True, True]
    assert [w.in_hole for w in hole.waypoints] == [True, True, False]
    assert [w.reached for w in hole.waypoints] == [False, False, True]
    assert all(math.isnan(w.closest_approach_m) for w in hole.waypoints[:2])  # nothing known: no invented miss
    rows = dict(hole.table_rows())
    assert rows["waypoints reached"] == "1 of 3; 2 passed in a hole in the log (W0, W1): not known"
    assert "not reached" not in rows["closest approach of the waypoints reached, mean / max"]


def test_absurd_values_in_cycle_lines_are_gaps_not_figures(tmp_path):
    """Found by a review audit: sog_m_s 1e308 and thrust_port_n 1e300 on a few cycles were summed into a distance
    of 9e307 m (printed as a 300-digit number) and an energy of 9e299 N s, without a note."""
    write_synthetic_log(tmp_path / "ok.jsonl")
    lines = (tmp_path / "ok.jsonl").read_text().splitlines(keepends=True)
    out, spoilt = [], 0
    for ln in lines:
        rec = json.loads(ln)
        if rec["event"] == "cycle" and 100 <= rec["cycle"] < 109:
            rec["sog_m_s"], rec["thrust_port_n"] = 1e308, 1e300
            spoilt += 1
        out.append(json.dumps(rec) + "\n")
    (tmp_path / "absurd.jsonl").write_text("".join(out))
    ok, bad = (score(read_log(tmp_path / f"{n}.jsonl")) for n in ("ok", "absurd"))
    assert spoilt == 9
    assert abs(bad.distance_m - ok.distance_m) < 2.0 and abs(bad.thrust_energy_n_s - ok.thrust_energy_n_s) < 0.1 * ok.thrust_energy_n_s
    notes = " ".join(bad.read_notes)
    assert "9 non-numeric, infinite or absurd (beyond 1e12) value(s) of sog_m_s" in notes
    assert "9 non-numeric, infinite or absurd (beyond 1e12) value(s) of thrust_port_n" in notes


def test_a_log_without_cycles_says_n_a_not_zero_for_times_over_cycles(tmp_path):
    """Found by a review audit: an empty log's heading and position lost, gaps and time in failsafe read "0.0 s",
    as a clean run's do."""
    rows = dict(score(read_log(_write(tmp_path / "none.jsonl", [START]))).table_rows())
    assert rows["cycles"] == "0"
    for label, value in rows.items():
        if label.startswith(("heading lost", "position lost", "gaps in the log", "time in failsafe")):
            assert value == "n/a (no cycles in the log)", (label, value)


@pytest.mark.parametrize("speedup, said", [(5.0, " (simulated ms: --speedup 5)"), ("max", " (simulated ms: --speedup max)"),
                                           (1.0, ""), (None, "")])
def test_the_loop_lateness_of_a_sped_up_run_is_said_to_be_simulated(tmp_path, speedup, said):
    """Found by a review audit: a `--speedup 5` bench run's lateness was labelled ms: simulated ms, 5 to the wall's."""
    start = dict(START) if speedup is None else {**START, "speedup": speedup}
    recs = [start] + _cycles(20, lateness_ms=1.0)
    rows = dict(score(read_log(_write(tmp_path / "s.jsonl", recs))).table_rows())
    assert f"loop lateness p50 / p99 / max{said}" in rows


@pytest.mark.parametrize("start_index, said", [(1, " (this run started at W1: W0 was an earlier run's)"), (0, ""),
                                               (7, "")])
def test_a_run_carried_on_after_a_restart_says_where_it_started(tmp_path, start_index, said):
    """Found by a review audit: a resumed run read "waypoints reached 6 of 9" beside "complete", without a word that
    it started at W3 (the rest were the interrupted run's). A start index the mission has not is not said."""
    recs = [{**START, "start_index": start_index}] + _cycles(20, wp_index=1)
    rows = dict(score(read_log(_write(tmp_path / "r.jsonl", recs))).table_rows())
    assert rows["waypoints reached"] == "0 of 2" + said


def test_cross_track_error_per_leg_by_hand(tmp_path):
    """Researchers asked for the cross-track error per leg (one figure for the run hid which leg was flown badly).
    Leg k runs from W_{k-1} (leg 0: from the start) to W_k, over the cycles steering to W_k in auto, a hold at its
    point left out as the run's figure leaves it; a leg without samples is n/a, never 0."""
    start = {**START, "waypoints": [[10.0, 0.0], [10.0, 10.0], [20.0, 10.0]]}
    north = [0.0, 5.0, 8.0, 10.5, 12.0, 9.0]
    east = [0.0, 1.0, -2.0, 5.0, 8.0, 3.0]  # xte 0, 1, -2 on leg 0; -0.5, -2, 1 on leg 1 (as above)
    recs = _cycles(6, north_m=north, east_m=east, wp_index=[0, 0, 0, 1, 1, 1])
    hold = _cycles(20, north_m=13.0, east_m=10.0, wp_index=1, holding=True, hold_north_m=10.0, hold_east_m=10.0)
    for k, r in enumerate(hold):  # a hold item at W1: 2 s of station keeping 3 m off leg 1, not leg 1's error
        r["t_s"] = round(0.6 + 0.1 * k, 3)
    card = score(read_log(_write(tmp_path / "legs.jsonl", [start] + recs + hold)))
    leg0, leg1, leg2 = card.legs
    assert [g.label for g in card.legs] == ["start->W0", "W0->W1", "W1->W2"]
    assert (leg0.cycles, leg0.fixes, leg1.cycles, leg1.fixes) == (3, 3, 3, 3)
    assert_allclose([leg0.xte_rms_m, leg0.xte_max_m, leg0.time_s], [math.sqrt(5 / 3), 2.0, 0.3], atol=1e-9)
    assert_allclose([leg1.xte_rms_m, leg1.xte_max_m, leg1.time_s], [math.sqrt(5.25 / 3), 2.0, 0.3], atol=1e-9)
    assert leg2.cycles == leg2.fixes == 0 and math.isnan(leg2.xte_rms_m) and math.isnan(leg2.xte_max_m)
    rows = dict(card.table_rows())
    assert rows["cross-track error, leg start->W0"] == "RMS 1.29 m, max 2.00 m over 0.3 s (3 fixes)"
    assert rows["cross-track error, leg W1->W2"] == "n/a (not flown)"
    legs = json.loads(json.dumps(card.to_dict(), allow_nan=False))["legs"]
    assert legs[1]["xte_rms_m"] == pytest.approx(math.sqrt(5.25 / 3)) and legs[2]["xte_rms_m"] is None
    # back to W1's hold item after a pause (the route already on leg 2, station keeping closing on W1, `holding`
    # false): not leg 2's tracking, 4 m off its line (a review of 2026-12-06: it was counted in leg 2)
    back = _cycles(10, north_m=10.0, east_m=14.0, wp_index=2, holding=False, hold_north_m=10.0, hold_east_m=10.0)
    for k, r in enumerate(back):
        r["t_s"] = round(2.6 + 0.1 * k, 3)
    card = score(read_log(_write(tmp_path / "back.jsonl", [start] + recs + hold + back)))
    assert card.legs[2].cycles == card.legs[2].fixes == 0 and math.isnan(card.legs[2].xte_rms_m)
    assert card.xte_max_m == pytest.approx(2.0)  # the run's figure leaves them out too
    # flown without a fix (the position lost all along the leg): n/a over its time, not 0
    lost = score(read_log(_write(tmp_path / "lost.jsonl", [start] + _cycles(10, wp_index=0))))
    assert lost.legs[0].cycles == 10 and lost.legs[0].fixes == 0
    assert dict(lost.table_rows())["cross-track error, leg start->W0"] == "n/a (no fix) over 1.0 s"


def _combined(legs, count, rms, peak):
    n = np.array([getattr(g, count) for g in legs])
    r = np.nan_to_num([getattr(g, rms) for g in legs])
    return math.sqrt(np.sum(n * r * r) / np.sum(n)), np.nanmax([getattr(g, peak) for g in legs])


def test_the_runs_cross_track_error_is_its_legs_combined(tmp_path):
    """The run's RMS is the legs' combined, each weighted by its samples (fixes recomputed, cycles of xte_m logged),
    and its maximum the largest leg's: one selection for both, on the synthetic mission (1 Hz fixes held on 10 Hz
    cycle lines, a weave off each leg) and on a mission replaced in flight (M1's and M2's legs)."""
    write_synthetic_log(tmp_path / "m.jsonl", weave_m=1.0, dropout_every_s=25.0)
    log = read_log(tmp_path / "m.jsonl")
    card = score(log)
    assert [g.label for g in card.legs] == ["start->W0", "W0->W1", "W1->W2"]
    assert all(g.fixes >= 5 and g.logged_cycles > 5 * g.fixes for g in card.legs)  # 1 Hz fixes, 10 Hz xte_m
    assert_allclose(_combined(card.legs, "fixes", "xte_rms_m", "xte_max_m"), [card.xte_rms_m, card.xte_max_m], rtol=1e-12)
    assert_allclose(_combined(card.legs, "logged_cycles", "logged_xte_rms_m", "logged_xte_max_m"),
                    [card.logged_xte_rms_m, card.logged_xte_max_m], rtol=1e-12)
    assert_allclose(sum(g.time_s for g in card.legs), card.mode_time_s["auto"], atol=1e-9)  # no hold item here
    # a mission replaced at 10 s: its legs are the new plan's, labelled M2
    recs = _cycles(200, north_m=list(np.round(0.1 * np.arange(200), 2)), east_m=[0.3, -0.4] * 100,
                   wp_index=[0] * 60 + [1] * 40 + [0] * 50 + [1] * 50)
    replaced = {"event": "mission_replaced", "t_s": 10.0, "source": "mavlink", "waypoints": [[30.0, 0.0], [30.0, 10.0]]}
    card = score(read_log(_write(tmp_path / "r.jsonl", [START] + recs[:100] + [replaced] + recs[100:])))
    assert [g.label for g in card.legs] == ["M1 start->W0", "M1 W0->W1", "M2 start->W0", "M2 W0->W1"]
    assert [g.cycles for g in card.legs] == [60, 40, 50, 50]
    assert_allclose(_combined(card.legs, "fixes", "xte_rms_m", "xte_max_m"), [card.xte_rms_m, card.xte_max_m], rtol=1e-12)


def _final_hold_then_time_stop(hold_s=1560.0, stop_s=10.0, after=None, mode_lines=True, signal="SIGTERM"):
    """A daemon run as it logs one (a --sim run under systemd: max_mission_time_s 90, final_action hold): the route
    flown, mission_complete and the final hold at W1, max_mission_time's stop (failsafe, mode stop, "staying up"),
    ``stop_s`` at zero thrust, then the signal. ``after``: a mode the operator commanded after the time stop."""
    start = {**START, "config": {"failsafe": {"max_mission_time_s": 20.0 + hold_s}}}
    legs = _cycles(200, north_m=list(np.round(np.minimum(0.1 * np.arange(200), 10.0), 2)),
                   east_m=list(np.round(np.maximum(0.1 * np.arange(200) - 10.0, 0.0), 2)), wp_index=[0] * 100 + [1] * 100)
    done_t, stop_t = 20.0, 20.0 + hold_s

    def later(n, t0, **cols):
        recs = _cycles(n, **cols)
        for r in recs:
            r["t_s"] = round(t0 + r["t_s"], 3)
        return recs

    hold = later(int(round(hold_s * 10)), done_t, mode="hold", wp_index=1, north_m=10.0, east_m=10.0, holding=True,
                 hold_north_m=10.0, hold_east_m=10.0, hold_error_m=0.1)
    stopped = later(int(round(stop_s * 10)), stop_t, mode="stop", wp_index=1, north_m=10.0, east_m=10.0,
                    thrust_port_n=0.0, thrust_stbd_n=0.0)
    events = [{"event": "waypoint_reached", "t_s": done_t, "wp_index": 1},
              {"event": "mission_complete", "t_s": done_t, "wp_count": 2, "rtl": False},
              {"event": "mode", "t_s": done_t, "mode": "hold", "from": "auto", "cause": "mission end: hold at the last waypoint"}]
    time_stop = [{"event": "fault", "t_s": stop_t, "cause": "max_mission_time", "detail": "mission time"},
                 {"event": "failsafe", "t_s": stop_t, "cause": "max_mission_time", "action": "stop", "configured": "stop",
                  "fallback": None},
                 {"event": "mode", "t_s": stop_t, "mode": "stop", "from": "hold", "cause": "failsafe max_mission_time"},
                 {"event": "info", "t_s": stop_t, "message": "max_mission_time: stopped, staying up",
                  "why": "systemd runs the daemon"}]
    if not mode_lines:
        events, time_stop = events[:2], [ev for ev in time_stop if ev["event"] != "mode"]
    tail = []
    if after:
        half = len(stopped) // 2
        for r in stopped[half:]:
            r["mode"] = after
        tail = [{"event": "mode", "t_s": stopped[half]["t_s"], "mode": after, "from": "stop", "cause": f"ctl {after}"}]
        stopped = stopped[:half] + tail + stopped[half:]
    stop = {"event": "stop", "t_s": stop_t + stop_s, "reason": "signal" if signal else "max_mission_time",
            "signal": signal, "ack_received": True}
    return [start] + legs + events + hold + time_stop + stopped + [stop]


def test_a_final_hold_until_the_mission_time_limit_is_said_before_the_signal(tmp_path):
    """Asked by researchers: a run whose route was complete, then held (final hold) until max_mission_time stopped
    it, the daemon staying up at zero thrust until a SIGTERM, was said "route complete; then in stop, stopped by
    SIGTERM": true, but its 1560 s of hold went unsaid. The mode before the time stop and how long it lasted come
    from the failsafe and mode lines, else from the cycles."""
    card = score(read_log(_write(tmp_path / "t.jsonl", _final_hold_then_time_stop())))
    assert card.complete and not card.finished and card.end_mode == "stop"
    assert dict(card.table_rows())["stop"] == (
        "route complete; then in hold for 1560 s until max_mission_time stopped it; stopped by SIGTERM")
    summary = card.to_dict()
    assert (summary["time_stop_t_s"], summary["time_stop_from_mode"]) == (1580.0, "hold")
    assert summary["time_stop_from_mode_s"] == pytest.approx(1560.0)
    # a log without mode lines: the mode and its time from the cycles (the first hold cycle at 20.0 s)
    card = score(read_log(_write(tmp_path / "c.jsonl", _final_hold_then_time_stop(hold_s=45.0, mode_lines=False))))
    assert dict(card.table_rows())["stop"] == (
        "route complete; then in hold for 45 s until max_mission_time stopped it; stopped by SIGTERM")
    # the operator took a mode after the time stop (rtl): where the signal found it is said as well
    card = score(read_log(_write(tmp_path / "r.jsonl", _final_hold_then_time_stop(hold_s=6.5, after="rtl"))))
    assert dict(card.table_rows())["stop"] == (
        "route complete; then in hold for 6.5 s until max_mission_time stopped it; then in rtl, stopped by SIGTERM")


def test_the_other_ends_keep_their_words(tmp_path):
    """The daemon's end summary's words: a signal in the final hold before any time stop; a run the time limit
    ended (no staying up) says the hold before it too; a time stop before the route was complete, then a signal,
    says both (it said only the signal: a review of 2026-12-06)."""
    recs = _final_hold_then_time_stop(hold_s=30.0)
    cut = [r for r in recs if r["t_s"] < 50.0 and r["event"] != "stop"] + [
        {"event": "stop", "t_s": 49.9, "reason": "signal", "signal": "SIGTERM"}]
    assert dict(score(read_log(_write(tmp_path / "h.jsonl", cut))).table_rows())["stop"] == (
        "route complete; then in hold, stopped by SIGTERM")
    ended = _final_hold_then_time_stop(hold_s=30.0, stop_s=0.1, signal=None)
    assert dict(score(read_log(_write(tmp_path / "e.jsonl", ended))).table_rows())["stop"].startswith(
        "route complete; then in hold for ")
    assert dict(score(read_log(_write(tmp_path / "e.jsonl", ended))).table_rows())["stop"].endswith(
        " s until max_mission_time stopped it")
    early = [r for r in recs if r.get("event") not in ("mission_complete", "waypoint_reached")]
    assert dict(score(read_log(_write(tmp_path / "n.jsonl", early))).table_rows())["stop"] == (
        "stopped by max_mission_time, then by SIGTERM")


def test_deadlines_the_loop_skipped_are_a_scorecard_row(tmp_path):
    """A review audit (2026-12-06): a 20x run skipped 25 deadlines (the daemon's summary said so) and its report showed
    only "gaps in the log 0.0 s". The cycles' `skipped_cycles` count (cumulative) and the stop line's are read."""
    path = tmp_path / "run.jsonl"
    write_synthetic_log(path, duration_s=30.0)
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    for k, rec in enumerate(lines):
        if rec["event"] == "cycle" and k > len(lines) // 2:
            rec["skipped_cycles"] = 3
        if rec["event"] == "stop":
            rec["skipped_cycles"] = 4  # one skipped after the last cycle line was written
    path.write_text("".join(json.dumps(rec) + "\n" for rec in lines))
    rows = dict(score(read_log(path)).table_rows())
    assert rows["deadlines skipped (the loop more than a period behind)"] == "4"
    for rec in lines:
        rec.pop("skipped_cycles", None)
    path.write_text("".join(json.dumps(rec) + "\n" for rec in lines))
    assert dict(score(read_log(path)).table_rows())["deadlines skipped (the loop more than a period behind)"] == "n/a (not logged)"
