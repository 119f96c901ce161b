"""Operator mistakes a new user's test of the wheel found (2026-12-07), each refused or done right now.

Before: a geofence polygon under ``frame: none`` flew with no fence and no word; a hold of minus infinity
was "until commanded"; ``autopilot evaluate`` flew a mission without its final return to launch and wrote
``Infinity`` into its JSON; a mission CSV naming a column twice flew the last copy; extra arguments were
answered with the top level's usage, which never said what the command takes.
"""

from __future__ import annotations

import json
import math

import pytest

from autopilot.cli import main
from autopilot.daemon.config import GeofenceConfig, load_config
from autopilot.mission import MissionError, load_mission, mission_from_items
from autopilot.schema import ConfigError


def test_a_geofence_polygon_under_frame_none_is_refused(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("geofence:\n  frame: none\n  polygon: [[-50, -50], [50, -50], [50, 50]]\n")
    with pytest.raises(ConfigError, match=r"geofence.polygon: 3 vertices given with frame 'none'.*local.*latlon"):
        load_config(cfg)
    assert GeofenceConfig().frame == "none"  # no fence, no polygon: still the default
    cfg.write_text("geofence:\n  frame: local\n  polygon: [[-50, -50], [50, -50], [50, 50]]\n")
    assert len(load_config(cfg).geofence.polygon) == 3


@pytest.mark.parametrize("hold", ["-.inf", "-1e400"])
def test_a_hold_of_minus_infinity_is_refused(tmp_path, hold):
    path = tmp_path / "m.yaml"
    path.write_text(f"name: t\nframe: local\nwaypoints:\n  - {{north_m: 10, east_m: 0, hold_s: {hold}}}\n")
    with pytest.raises(MissionError, match="hold_s"):
        load_mission(path)
    path.write_text("name: t\nframe: local\nwaypoints:\n  - {north_m: 10, east_m: 0, hold_s: .inf}\n")
    assert load_mission(path).holds_s[0] == math.inf  # plus infinity: until commanded, as hold: true


def test_a_planners_loiter_time_of_minus_infinity_is_refused():
    items = [{"seq": 0, "command": 16, "frame": 0, "lat_deg": 52.0, "lon_deg": 4.4, "param1": 0.0},
             {"seq": 1, "command": 19, "frame": 3, "lat_deg": 52.0001, "lon_deg": 4.4, "param1": -math.inf}]
    with pytest.raises(MissionError, match=r"item 1: loiter time -inf s outside"):
        mission_from_items(items, origin_lat_deg=52.0, origin_lon_deg=4.4)


def test_evaluate_flies_the_missions_return_to_launch(tmp_path, capsys):
    (tmp_path / "rtl.yaml").write_text("name: rtl\nframe: local\nwaypoints:\n  - [10, 0]\n  - rtl\n")
    (tmp_path / "one.yaml").write_text("name: one\nframe: local\nwaypoints:\n  - [10, 0]\n")
    rows = {}
    for name in ("rtl", "one"):
        assert main(["evaluate", "--mission", str(tmp_path / f"{name}.yaml"), "--guidance", "los", "--condition",
                     "calm", "--json"]) == 0
        rows[name] = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert rows["one"]["completed"] and rows["rtl"]["completed"]
    # the return: 10 m more under thrust, then the hold at the launch point (before: the same run as "one")
    assert rows["rtl"]["energy_ns"] > 3.0 * rows["one"]["energy_ns"], rows


def test_evaluate_json_has_no_infinity(tmp_path, capsys):
    from autopilot.daemon.missionlog import json_ready

    assert json.dumps(json_ready({"closest_approach_m": [6.5, math.inf, math.nan]})) == (
        '{"closest_approach_m": [6.5, null, null]}')
    # a waypoint never approached (the run ends first: a derivative gain five times the proportional one flips
    # the thrust every few cycles and the boat makes no headway): its closest approach was written as Infinity
    (tmp_path / "kd50.yaml").write_text("gnc:\n  pid:\n    kp_n_per_deg: 10\n    kd_n_s_per_deg: 50\n")
    main(["evaluate", "--mission", "pond-9.4", "--guidance", "los", "--condition", "calm", "--config",
          str(tmp_path / "kd50.yaml"), "--json"])
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "Infinity" not in line and "NaN" not in line
    row = json.loads(line)
    assert not row["completed"] and None in row["closest_approach_m"]


def test_a_mission_csv_naming_a_column_twice_is_refused(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("north_m,east_m,north_m\n10,5,3\n20,5,4\n")
    with pytest.raises(MissionError, match="column north_m appears 2 times"):
        load_mission(path)


@pytest.mark.parametrize("argv, usage", [
    (["nmea", "a.log", "b.log"], "usage: autopilot nmea"),
    (["files", "--json"], "usage: autopilot files"),
    (["ctl", "speed", "2.0", "extra"], "usage: autopilot ctl"),
])
def test_extra_arguments_are_refused_with_the_commands_own_usage(capsys, argv, usage):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert usage in err and f"autopilot {argv[0]}: error: unrecognized arguments" in err, err


def test_one_speed_range_for_missions_the_operator_and_the_configuration(tmp_path, capsys):
    """ctl speed 0.01 was taken (the boat sat still while the status said auto) while the configuration's
    default_speed_m_s refused below 0.05 and above 3.4, and missions took up to 3.5: one range now."""
    from autopilot.gnc import GncConfig
    from autopilot.gnc.speed import MAX_SPEED_M_S, MIN_SPEED_M_S, SPEED_RANGE

    assert main(["ctl", "speed", "0.01"]) == 2
    assert f"is not a speed in {SPEED_RANGE}" in capsys.readouterr().err
    path = tmp_path / "m.yaml"
    path.write_text("name: t\nframe: local\nwaypoints:\n  - {north_m: 10, east_m: 0, speed_m_s: 0.01}\n")
    with pytest.raises(MissionError, match=r"speed 0.01 m/s outside \[0.05, 3.5\] m/s"):
        load_mission(path)
    for speed in (MIN_SPEED_M_S, MAX_SPEED_M_S):
        path.write_text(f"name: t\nframe: local\nwaypoints:\n  - {{north_m: 10, east_m: 0, speed_m_s: {speed}}}\n")
        assert load_mission(path).speeds_m_s[0] == speed
        cfg = tmp_path / "c.yaml"
        cfg.write_text(f"gnc:\n  guidance:\n    default_speed_m_s: {speed}\n")
        assert load_config(cfg).gnc.guidance.default_speed_m_s == speed
    assert GncConfig().guidance.default_speed_m_s == 1.0


def test_the_planned_time_of_a_route():
    from autopilot.mission import Mission

    m = Mission(name="m", waypoints_ne_m=[[30.0, 0.0], [30.0, 40.0]], speeds_m_s=(None, 2.0), home_latlon=None,
                origin_lat_deg=None, origin_lon_deg=None, holds_s=(10.0, None))
    assert m.planned_time_s(1.0) == pytest.approx(30.0 + 10.0 + 40.0 / 2.0)
    assert m.planned_time_s(1.0, start_index=1) == pytest.approx(20.0)  # resumed: from W0 to W1
    rtl = Mission(**{**m.__dict__, "rtl": True})
    assert rtl.planned_time_s(1.0) == pytest.approx(60.0 + 50.0)  # back home from (30, 40) at the default speed
    forever = Mission(**{**m.__dict__, "holds_s": (math.inf, None)})
    assert forever.planned_time_s(1.0) == math.inf


def test_a_route_longer_than_the_time_limit_is_said_at_start(tmp_path):
    from tests.conftest import run_cli

    (tmp_path / "c.yaml").write_text("failsafe:\n  max_mission_time_s: 20\n")
    (tmp_path / "m.yaml").write_text("name: long\nframe: local\nwaypoints:\n  - [30, 0]\n  - [30, 30]\n  - [0, 30]\n")
    argv = ["run", "--config", str(tmp_path / "c.yaml"), "--mission", str(tmp_path / "m.yaml"), "--sim", "--speedup",
            "max", "--log-dir", str(tmp_path / "logs"), "--state-dir", str(tmp_path / "st"), "--fresh"]
    proc = run_cli(*argv, check=False)
    assert ("the route takes at least 90 s at its speeds (straight legs and holds), longer than "
            "failsafe.max_mission_time_s (20 s): its stop failsafe will take the boat") in proc.stderr, proc.stderr
    log = next((tmp_path / "logs").glob("*.jsonl")).read_text()
    assert "the route takes at least 90 s" in log  # in the log too, for the review
    (tmp_path / "m.yaml").write_text("name: short\nframe: local\nwaypoints:\n  - [5, 0]\n")
    proc = run_cli(*argv, check=False)
    assert "the route takes" not in proc.stderr and "mission complete" in proc.stderr, proc.stderr


def test_evaluates_table_says_n_a_for_a_waypoint_never_approached():
    from autopilot.evaluate import RunResult, format_row

    r = RunResult(mission="m", guidance="los", condition="calm", completed=False, closest_approach_m=[1.0, math.inf],
                  xte_rms_m=0.0, xte_max_m=0.0, time_s=1.0, energy_ns=0.0, saturation_pct=0.0, circled=False)
    row = format_row(r)
    assert row.endswith("1.00  n/a") and "inf" not in row, row


@pytest.mark.parametrize("text, says", [
    ("gnc:\n  pid:\n    kp_n_per_deg: 0\n    ki_n_per_deg_s: 0\n", "gnc.pid: kp_n_per_deg and ki_n_per_deg_s are both 0"),
    ("gnc:\n  allocation:\n    max_forward_n: 0\n", "gnc.allocation: max_forward_n is 0: the boat can never go ahead"),
])
def test_settings_that_cannot_drive_the_boat_are_refused(tmp_path, text, says):
    """A helm with no gain towards the heading flew 30 minutes unsteered; no forward thrust sat at the start."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    with pytest.raises(ConfigError, match=says):
        load_config(cfg)


def test_waypoints_within_the_capture_radius_are_said_at_start(tmp_path):
    from autopilot.daemon.app import _reached_at_once

    (tmp_path / "m.yaml").write_text("name: t\nframe: local\nwaypoints:\n  - [30, 0]\n  - [30, 60]\n  - [40, 60]\n")
    mission = load_mission(tmp_path / "m.yaml", origin_lat_deg=52.0, origin_lon_deg=4.4)
    (tmp_path / "c.yaml").write_text("gnc:\n  guidance:\n    capture_radius_m: 35\n")
    said = _reached_at_once(load_config(tmp_path / "c.yaml"), mission, 0)
    assert said.startswith("W0 30.0 m from the start, W2 10.0 m from W1: within gnc.guidance.capture_radius_m (35 m)")
    assert _reached_at_once(load_config(tmp_path / "c.yaml"), mission, 2) == (  # resumed at W2
        "W2 10.0 m from W1: within gnc.guidance.capture_radius_m (35 m): each counts reached once the boat is "
        "that close, before it gets there (a smaller radius, or waypoints farther apart)")
    (tmp_path / "c.yaml").write_text("gnc:\n  guidance:\n    capture_radius_m: 5\n")
    assert _reached_at_once(load_config(tmp_path / "c.yaml"), mission, 0) is None
