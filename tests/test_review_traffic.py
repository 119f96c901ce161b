"""The review of AIS traffic (issue 18): targets' tracks, closest approaches and manoeuvres, on a real daemon run.

The log is one ``autopilot run --sim --speedup max`` with the shipped head-on scenario (a ferry on the
reciprocal course 450 m ahead) and a waypoint 300 m north, made once for the module and cut at
190 s, after the pass. The numbers the
scorecard shows are checked against the raw JSON lines, parsed and interpolated here without the
review's reader.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from autopilot.review import plots
from autopilot.review.metrics import score
from autopilot.review.reader import SITUATIONS, TargetTrack, read_log
from autopilot.review.report import review, review_one
from autopilot.review.synthetic import write_synthetic_log
from tests.conftest import REPO, run_cli

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SCENARIO = "head-on"
FERRY = 244000101  # the scenario's target (autopilot/data/traffic/head-on.yaml)
MISSION_TIME_S = 190.0


def write_traffic_log(directory: Path, scenario: str = SCENARIO) -> Path:
    """Run the daemon on the simulator with a traffic scenario; return the mission log it wrote."""
    config = yaml.safe_load((REPO / "autopilot/data/autopilot.yaml").read_text())
    config["sim"]["traffic"] = scenario
    # the pass is over by ~160 s (CPA at ~158 s, the ferry past and clear): stop there, not at the goal
    config["failsafe"]["max_mission_time_s"] = MISSION_TIME_S
    (directory / "autopilot.yaml").write_text(yaml.safe_dump(config))
    # the scenarios put own ship at the origin heading north, the goal 300 m ahead
    (directory / "mission.yaml").write_text(yaml.safe_dump(
        {"name": "north300", "frame": "local", "waypoints": [[300.0, 0.0]]}))
    run_cli("run", "--sim", "--speedup", "max", "--config", str(directory / "autopilot.yaml"),
            "--mission", str(directory / "mission.yaml"), "--log-dir", str(directory / "log"),
            "--state-dir", str(directory / "state"), "--runtime-dir", str(directory / "rt"), "--fresh", timeout=120)
    (log,) = (directory / "log").glob("mission-*.jsonl")
    return log


@pytest.fixture(scope="module")
def traffic_log(tmp_path_factory):
    return write_traffic_log(tmp_path_factory.mktemp("traffic"))


@pytest.fixture(scope="module")
def traffic_review(traffic_log, tmp_path_factory):
    out = tmp_path_factory.mktemp("traffic-review")
    return review_one(read_log(traffic_log), out)


def _lines(path: Path) -> list[dict]:
    return [json.loads(raw) for raw in path.read_text().splitlines() if raw.strip()]


def _by_hand(path: Path):
    """Own fixes and the ferry's reports straight from the JSON lines, each dated when it was measured."""
    recs = _lines(path)
    cycles = [r for r in recs if r["event"] == "cycle" and r["north_m"] is not None]
    fixes, last = [], None
    for r in cycles:
        when = r["t_s"] - r["position_age_s"]
        if last is None or abs(when - last) > 1e-4:  # a held fix repeats until the next one arrives
            fixes.append((when, r["north_m"], r["east_m"]))
            last = when
    reports = sorted((r["t_s"] - r["age_s"], r["north_m"], r["east_m"])
                     for r in recs if r["event"] == "target" and r["target"] == FERRY)
    return np.array(fixes), np.array(reports), recs


def test_the_daemon_log_has_traffic(traffic_log):
    """Guard on the scenario itself: if the daemon's behaviour changes, say so here, not in a figure test."""
    recs = _lines(traffic_log)
    assert {r["target"] for r in recs if r["event"] == "target"} == {FERRY}
    encounters = [r for r in recs if r["event"] == "encounter"]
    assert encounters[0]["situation"] == "head-on" and encounters[0]["acting"] is True
    assert any(r["event"] == "cycle" and r["avoid_active"] for r in recs)
    assert encounters[-1]["situation"] == "safe"  # past and clear before the run was cut


def test_figures_exist_and_decode(traffic_review):
    import matplotlib.image

    html = traffic_review.report.read_text()
    for name in ("track.png", "avoidance.png", "timeline.png"):
        path = traffic_review.out_dir / name
        assert traffic_review.figures[name] == path and path.read_bytes()[:8] == PNG_MAGIC, name
        assert matplotlib.image.imread(path).shape[0] > 300, name
        assert f'src="{name}"' in html
    assert "<h2>AIS targets</h2>" in html and "<h2>Avoidance manoeuvres</h2>" in html and "FERRY ONE" in html
    summary = json.loads((traffic_review.out_dir / "summary.json").read_text())
    assert summary["targets"][0]["target"] == FERRY
    assert summary["targets"][0]["closest_m"] == pytest.approx(traffic_review.card.targets[0].closest_m)


def test_closest_approach_equals_one_by_hand(traffic_log, traffic_review):
    fixes, reports, _ = _by_hand(traffic_log)
    # both tracks linear between their own samples, on a 10 ms grid over the time both are known
    t0, t1 = max(fixes[0, 0], reports[0, 0]), min(fixes[-1, 0], reports[-1, 0])
    grid = np.arange(t0, t1, 0.01)
    d = np.hypot(np.interp(grid, fixes[:, 0], fixes[:, 1]) - np.interp(grid, reports[:, 0], reports[:, 1]),
                 np.interp(grid, fixes[:, 0], fixes[:, 2]) - np.interp(grid, reports[:, 0], reports[:, 2]))
    k = int(np.argmin(d))
    (ferry,) = traffic_review.card.targets
    assert ferry.target == FERRY and ferry.name == "FERRY ONE" and ferry.reports == len(reports)
    assert_allclose(ferry.closest_m, d[k], atol=2e-3)
    assert_allclose(ferry.closest_t_s, grid[k], atol=0.05)
    # the two positions on the map are that far apart, where the tracks were then
    assert_allclose(math.hypot(ferry.own_north_m - ferry.target_north_m, ferry.own_east_m - ferry.target_east_m),
                    ferry.closest_m, atol=1e-9)
    assert_allclose((ferry.target_north_m, ferry.target_east_m),
                    (np.interp(grid[k], reports[:, 0], reports[:, 1]), np.interp(grid[k], reports[:, 0], reports[:, 2])),
                    atol=0.2)
    # the daemon steered by a dead-reckoned AIS picture and its own fixes: it saw about the same pass
    assert abs(ferry.logged_min_range_m - ferry.closest_m) < 2.0


def test_head_on_gives_way_to_starboard(traffic_log, traffic_review):
    _, _, recs = _by_hand(traffic_log)
    (ferry,) = traffic_review.card.targets
    assert ferry.situations[0] == "head-on" and ferry.situation == "head-on"
    assert ferry.acted and ferry.side == "starboard" and ferry.rule_followed
    first_acting = next(r["t_s"] for r in recs if r["event"] == "encounter" and r["acting"])
    assert ferry.first_action_t_s == pytest.approx(first_acting)
    shares = np.array([r["avoid_psi_share_deg"] for r in recs if r["event"] == "cycle" and r["avoid_active"]])
    assert np.all(shares >= 0.0) and shares.max() > 1.0  # every alteration while avoiding is to starboard
    assert_allclose(ferry.max_alteration_deg, shares.max(), atol=1e-6)
    # required: the log's safe distance plus half the ferry's reported length (12 m)
    safe_m = recs[0]["config"]["gnc"]["avoidance"]["safe_distance_m"]
    assert_allclose(ferry.required_m, safe_m + 6.0)
    assert ferry.distance_kept is (ferry.closest_m >= safe_m + 6.0)


def test_manoeuvres_are_the_active_stretches(traffic_log, traffic_review):
    _, _, recs = _by_hand(traffic_log)
    cycles = [r for r in recs if r["event"] == "cycle"]
    active = [i for i, r in enumerate(cycles) if r["avoid_active"]]
    assert active == list(range(active[0], active[-1] + 1))  # one stretch in this scenario
    (m,) = traffic_review.card.manoeuvres
    assert m.start_t_s == cycles[active[0]]["t_s"] and m.end_t_s == cycles[active[-1] + 1]["t_s"]
    assert (m.start_north_m, m.start_east_m) == (cycles[active[0]]["north_m"], cycles[active[0]]["east_m"])
    assert m.side == "starboard" and m.targets == [FERRY]
    assert traffic_review.card.avoidance_s == pytest.approx(0.1 * len(active), abs=0.05)


def test_track_draws_the_target_its_cpa_and_the_manoeuvres(traffic_log, tmp_path, monkeypatch):
    log = read_log(traffic_log)
    card = score(log)
    drawn = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: drawn.append(fig) or path)
    plots.plot_track(log, card, tmp_path / "track.png")
    ax = drawn[0].axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    (ferry,) = card.targets
    (label,) = [lab for lab in lines if lab.startswith("FERRY ONE (AIS)")]
    assert f"CPA {ferry.closest_m:.1f} m" in label
    tr = log.targets[FERRY]
    assert_allclose(lines[label].get_ydata(), tr.north_m)  # every report drawn (a short log: not decimated)
    cpa = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--" and len(ln.get_xdata()) == 2]
    (seg,) = [ln for ln in cpa if ln.get_color() == plots.target_color(0)]
    x, y = seg.get_xdata(), seg.get_ydata()
    assert_allclose(math.hypot(x[1] - x[0], y[1] - y[0]), ferry.closest_m, atol=1e-9)
    assert any(t.get_text() == f"{ferry.closest_m:.1f} m" for t in ax.texts)
    assert "avoidance active" in lines and lines["avoidance active"].get_linewidth() > 3
    for name in ("manoeuvre began", "manoeuvre ended"):
        assert len(lines[name].get_xdata()) == len(card.manoeuvres)
    for name in ("track (position fixes)", "start", "end", "waypoints", "launch"):
        assert name in lines  # what the map showed before traffic is still there


def test_a_log_without_targets_has_no_avoidance_figure_nor_targets_table(tmp_path):
    write_synthetic_log(tmp_path / "old.jsonl")  # written as logs were before traffic
    log = read_log(tmp_path / "old.jsonl")
    card = score(log)
    assert log.targets == {} and log.encounters == [] and card.targets == [] and card.manoeuvres == []
    assert math.isnan(card.avoidance_s) and "AIS targets" not in dict(card.table_rows())
    result = review_one(log, tmp_path / "out")
    assert result.figures["avoidance.png"] is None and not (tmp_path / "out" / "avoidance.png").exists()
    html = result.report.read_text()
    assert "AIS targets" not in html and 'src="avoidance.png"' not in html and "avoidance.png" in html  # "not drawn"


def test_malformed_traffic_lines_are_counted_not_used(traffic_log, tmp_path):
    good = read_log(traffic_log)
    bad = tmp_path / "bad.jsonl"
    extra = [
        {"event": "target", "t_s": 50.0, "target": "244000101", "north_m": 1.0, "east_m": 1.0},  # MMSI a string
        {"event": "target", "t_s": 50.0, "target": FERRY, "north_m": None, "east_m": 1.0},  # no position
        {"event": "target", "t_s": "x", "target": FERRY, "north_m": 1.0, "east_m": 1.0},  # no time
        {"event": "target", "t_s": 50.0, "target": True, "north_m": 1.0, "east_m": 1.0},  # a bool is no MMSI
        {"event": "encounter", "t_s": 50.0, "target": FERRY, "situation": "head-on", "acting": "yes"},
        {"event": "encounter", "t_s": 50.0, "target": FERRY, "situation": None, "acting": False},
    ]
    bad.write_text(traffic_log.read_text() + "".join(json.dumps(x) + "\n" for x in extra))
    log = read_log(bad)
    assert log.stats.bad_events == {"target": 4, "encounter": 2}
    assert any("4 target line(s)" in s for s in log.stats.describe())
    assert_allclose(log.targets[FERRY].north_m, good.targets[FERRY].north_m)
    assert log.encounters == good.encounters
    assert score(log).targets[0].closest_m == score(good).targets[0].closest_m


def test_without_encounter_lines_the_cycles_say_who_was_acted_for(traffic_log, tmp_path):
    """A log with targets but no encounter lines (a cut file, a reader of a partial log): the worst
    target's fields of the cycles tell the situation and whether the boat acted."""
    p = tmp_path / "no-encounters.jsonl"
    p.write_text("".join(raw + "\n" for raw in traffic_log.read_text().splitlines() if '"encounter"' not in raw))
    (ferry,) = score(read_log(p)).targets
    assert ferry.acted and ferry.side == "starboard" and ferry.situation == "head-on"
    assert ferry.closest_m == score(read_log(traffic_log)).targets[0].closest_m


def test_each_target_its_colour_and_label(tmp_path, monkeypatch):
    """Two targets added to a log without avoidance: one named, one only known by its MMSI and no length."""
    write_synthetic_log(tmp_path / "s.jsonl")
    reports = []
    for k in range(30):
        t = 1.0 * k
        reports.append({"event": "target", "t_s": t, "target": 111, "name": "ALPHA", "north_m": 40.0 - t,
                        "east_m": 5.0, "length_m": 10.0, "age_s": 0.0})
        reports.append({"event": "target", "t_s": t, "target": 222, "name": None, "north_m": 10.0,
                        "east_m": -20.0 + t, "age_s": 0.0})
    with (tmp_path / "s.jsonl").open("a") as f:
        f.writelines(json.dumps(r) + "\n" for r in reports)
    log = read_log(tmp_path / "s.jsonl")
    card = score(log)
    assert [t.label for t in card.targets] == ["ALPHA", "222"]
    # no safe distance in this log's config: no required distance, no verdict on it
    assert all(math.isnan(t.required_m) and t.distance_kept is None for t in card.targets)
    assert all(not t.acted and t.side is None for t in card.targets) and card.manoeuvres == []
    drawn = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: drawn.append(fig) or path)
    plots.plot_track(log, card, tmp_path / "track.png")
    lines = {ln.get_label(): ln for ln in drawn[0].axes[0].get_lines()}
    alpha = next(v for k, v in lines.items() if k.startswith("ALPHA (AIS)"))
    other = next(v for k, v in lines.items() if k.startswith("222 (AIS)"))
    assert alpha.get_color() != other.get_color()
    assert plots.plot_avoidance(log, card, tmp_path / "avoidance.png") is None  # targets, but no avoidance data


def test_target_track_interpolates_only_inside_its_reports():
    evs = [{"t_s": 10.0, "north_m": 0.0, "east_m": 0.0, "age_s": 0.5, "name": "A", "length_m": 8.0},
           {"t_s": 20.0, "north_m": 10.0, "east_m": -5.0, "age_s": 0.5, "name": None},
           {"t_s": 20.0, "north_m": 10.0, "east_m": -5.0, "age_s": 0.5}]  # the same report logged twice
    tr = TargetTrack.from_events(1, evs)
    assert_allclose(tr.t_s, [9.5, 19.5]) and tr.name == "A" and tr.length_m == 8.0
    n, e = tr.position_at([9.0, 9.5, 14.5, 19.5, 20.0])
    assert_allclose(n, [np.nan, 0.0, 5.0, 10.0, np.nan])
    assert_allclose(e, [np.nan, 0.0, -2.5, -5.0, np.nan])


def test_every_situation_has_a_colour():
    assert set(plots.SITUATION_COLORS) == set(SITUATIONS)
    assert len(set(plots.SITUATION_COLORS.values())) == len(SITUATIONS)


def test_comparison_keeps_the_traffic_rows(traffic_log, tmp_path):
    write_synthetic_log(tmp_path / "old.jsonl")
    result = review([tmp_path / "old.jsonl", traffic_log], tmp_path / "cmp", with_plots=False)
    html = result.report.read_text()
    assert "AIS targets" in html and "closest approach to a target" in html
    # the traffic rows come where the traffic log has them, not after the last row
    assert html.index("AIS targets") < html.index("log lines skipped")


def test_the_report_loads_in_a_browser(traffic_review, tmp_path):
    from tests.test_review_browser import _image_check, _need_chromium

    _need_chromium()
    images, broken = _image_check(tmp_path, traffic_review.report)
    assert images == traffic_review.report.read_text().count("<img ") and broken == 0


def test_a_target_that_went_silent_while_closing_is_said_to_have_an_unknown_closest_approach(traffic_log, tmp_path):
    """Found by a traffic audit: a target whose AIS stopped while it closed in (a transponder switched off, out of
    range of the receiver) got the closest approach of its reported span, far off, said as the pass's without a
    word. The review now says how close it came after its last report is not in the log."""
    silent = tmp_path / "silent.jsonl"
    kept = [raw for raw in traffic_log.read_text().splitlines()
            if not ('"event":"target"' in raw.replace(" ", "") and json.loads(raw)["t_s"] > 100.0)]
    silent.write_text("\n".join(kept) + "\n")
    (ferry,) = score(read_log(silent)).targets
    assert re.search(r"its reports stopped \d+ s before the log ended, \d+ m away and closing at [\d.]+ m/s: how "
                     r"close it came after that is not in the log", ferry.note), ferry.note
    (whole,) = score(read_log(traffic_log)).targets
    assert "reports stopped" not in (whole.note or "") and whole.closest_m < ferry.closest_m
    # nor is the distance called kept (an AIS audit: "distance_kept": true of a pass it did not see)
    assert ferry.distance_kept is None and whole.distance_kept is True
