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
