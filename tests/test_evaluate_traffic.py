"""`autopilot evaluate --traffic`: the encounter suite on the calibrated model, targets through AIS (issue 18)."""

from __future__ import annotations

import json

import pytest

from autopilot.cli import main


def test_head_on_in_calm_gives_way_to_starboard_and_keeps_the_distance(capsys):
    assert main(["evaluate", "--traffic", "head-on", "--condition", "calm", "--json"]) == 0
    (run,) = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert run["completed"] and run["distance_kept"] and run["rules_followed"]
    (t,) = run["targets"]
    assert t["situation"] == "head-on" and t["acted"] and t["side"] == "starboard"
    assert t["min_distance_m"] >= t["required_m"] and 0.0 < run["delay_s"] < 60.0


def test_a_safe_crossing_costs_nothing(capsys):
    assert main(["evaluate", "--traffic", "crossing-port-gives-way", "--condition", "current_n"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("scenario") and len(out) == 2
    f = out[1].split()
    assert f[:3] == ["crossing-port-gives-way", "current_n", "yes"] and f[6] == "0.0"  # no delay


def test_an_unknown_scenario_is_refused_naming_the_shipped_ones(capsys):
    assert main(["evaluate", "--traffic", "collision-course"]) == 2
    err = capsys.readouterr().err
    assert "--traffic: 'collision-course' is neither a file nor a shipped scenario (crossing-port-gives-way" in err


@pytest.mark.parametrize("bad, words", [("own: {speed_m_s: -1}\ntargets: []", "speed_m_s"),
                                        ("targetz: []", "targetz")])
def test_a_bad_scenario_file_is_refused_naming_the_key(tmp_path, capsys, bad, words):
    p = tmp_path / "s.yaml"
    p.write_text(bad)
    assert main(["evaluate", "--traffic", str(p)]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


@pytest.mark.parametrize("scenario, situation", [("overtaken", "overtaken"), ("crossing-starboard", "crossing-give-way")])
@pytest.mark.parametrize("missing", ["course", "speed"])
def test_a_vessel_reporting_its_course_or_speed_not_available_is_not_taken_as_stopped(tmp_path, capsys, scenario,
                                                                                     situation, missing):
    """Found by an AIS audit: a vessel at 3.9 kn whose reports say course 360 or speed 102.3 kn ("not available", as
    many class B transponders send) was taken as stopped: judged overtaking either side, the boat turned to port
    and the vessel passed 0.5-1.2 m off (20.8-23.8 m required). Now its heading is its course, or its track
    between reports its motion."""
    import yaml

    from autopilot.resources import data_dir

    d = yaml.safe_load((data_dir() / "traffic" / f"{scenario}.yaml").read_text())
    for t in d["targets"]:
        t["not_available"] = [missing]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(d))
    assert main(["evaluate", "--traffic", str(tmp_path / "s.yaml"), "--condition", "calm", "--json"]) == 0
    (run,) = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    (t,) = run["targets"]
    assert t["situation"] == situation and t["side"] == "starboard"
    assert t["min_distance_m"] >= t["required_m"] and run["distance_kept"] and run["rules_followed"]


def test_a_vessel_moored_on_the_waypoint_does_not_keep_the_boat_circling_it(tmp_path, capsys):
    """Found by an AIS audit: the boat circled a stopped vessel on its only waypoint at 21-25 m until the time
    limit; now the waypoint is counted reached at the vessel's safe distance and the mission completes."""
    (tmp_path / "s.yaml").write_text(
        "name: on-waypoint\nown: {north_m: 0.0, east_m: 0.0, course_deg: 0.0, speed_m_s: 1.0, goal_north_m: 300.0,"
        " goal_east_m: 0.0}\ntargets:\n  - {mmsi: 244000902, name: ON WP, north_m: 300.0, east_m: 0.0,"
        " course_deg: 90.0, speed_m_s: 0.0, length_m: 10.0, beam_m: 3.0}\n")
    assert main(["evaluate", "--traffic", str(tmp_path / "s.yaml"), "--condition", "calm", "--json"]) == 0
    (run,) = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    (t,) = run["targets"]
    assert run["completed"] and run["distance_kept"] and t["min_distance_m"] >= t["required_m"]
    assert run["extra_distance_m"] < 50.0  # not a circle (350 m more before)
