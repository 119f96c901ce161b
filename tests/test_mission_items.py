"""Mission items of issue 15: hold_s, hold: true, rtl; QGC/Mission Planner loiter (17, 19) and RTL (20)."""

from __future__ import annotations

import json
import math

import pytest

from autopilot.mission import MissionError, load_mission

HOME = (34.8225, 135.5245)


def _yaml(tmp_path, body: str):
    p = tmp_path / "m.yaml"
    p.write_text("frame: local\nwaypoints:\n" + body, encoding="utf-8")
    return p


def test_yaml_hold_items_and_rtl(tmp_path):
    m = load_mission(_yaml(tmp_path, "  - {north_m: 10, east_m: 0, hold_s: 30}\n  - {north_m: 10, east_m: 10, hold: true}\n"
                                     "  - {north_m: 0, east_m: 10}\n  - rtl\n"))
    assert len(m.waypoints_ne_m) == 3
    assert m.holds_s == (30.0, math.inf, None)
    assert m.rtl
    assert m.hold_s(5) is None


@pytest.mark.parametrize("body, words", [
    ("  - rtl\n  - {north_m: 1, east_m: 1}\n", "rtl must be the last item"),
    ("  - {north_m: 1, east_m: 1, hold_s: -5}\n", "hold_s -5 s outside [0, 86400]"),
    ("  - {north_m: 1, east_m: 1, hold_s: 1e9}\n", "outside [0, 86400]"),
    ("  - {north_m: 1, east_m: 1, hold_s: 10, hold: true}\n", "not both"),
    ("  - {north_m: 1, east_m: 1, hold: 10}\n", "hold: expected true or false"),
    ("  - {north_m: 1, east_m: 1, hold_s: abc}\n", "hold_s"),
    ("  - {north_m: 1, east_m: 1, hold_for: 3}\n", "unknown key 'hold_for'"),
])
def test_yaml_bad_hold_items_are_refused_with_the_reason(tmp_path, body, words):
    with pytest.raises(MissionError, match="waypoint") as exc:
        load_mission(_yaml(tmp_path, body))
    assert words in str(exc.value)


def _wpl(tmp_path, rows):
    lines = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{HOME[0]}\t{HOME[1]}\t0\t1"]
    for k, (cmd, p1, lat, lon) in enumerate(rows, start=1):
        lines.append(f"{k}\t0\t3\t{cmd}\t{p1}\t0\t0\t0\t{lat}\t{lon}\t0\t1")
    p = tmp_path / "m.waypoints"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def test_mission_planner_loiter_and_rtl(tmp_path):
    m = load_mission(_wpl(tmp_path, [(16, 0, 34.8226, 135.5245), (19, 45, 34.8227, 135.5245), (17, 0, 34.8228, 135.5246),
                                     (20, 0, 0, 0)]))
    assert m.holds_s == (None, 45.0, math.inf) and m.rtl


def test_a_loiter_at_zero_zero_holds_at_the_waypoint_before(tmp_path):
    m = load_mission(_wpl(tmp_path, [(16, 0, 34.8226, 135.5245), (19, 20, 0, 0), (16, 0, 34.8227, 135.5246)]))
    assert len(m.waypoints_ne_m) == 2 and m.holds_s == (20.0, None)
    with pytest.raises(MissionError, match="needs a waypoint before it"):
        load_mission(_wpl(tmp_path, [(19, 20, 0, 0)]))


def test_nothing_may_follow_rtl_and_other_commands_are_named(tmp_path):
    with pytest.raises(MissionError, match="nothing may follow return to launch"):
        load_mission(_wpl(tmp_path, [(16, 0, 34.8226, 135.5245), (20, 0, 0, 0), (16, 0, 34.8227, 135.5245)]))
    with pytest.raises(MissionError, match=r"command 21 not supported \(supported: waypoint 16, loiter unlimited 17"):
        load_mission(_wpl(tmp_path, [(16, 0, 34.8226, 135.5245), (21, 0, 0, 0)]))


def test_qgc_plan_loiter_time_and_rtl(tmp_path):
    def item(cmd, p1, lat, lon):
        return {"type": "SimpleItem", "command": cmd, "frame": 3, "params": [p1, 0, 0, None, lat, lon, 0]}

    plan = {"fileType": "Plan", "version": 1, "mission": {
        "plannedHomePosition": [HOME[0], HOME[1], 0], "cruiseSpeed": 1.0, "items": [
            item(16, 0, 34.8226, 135.5245), item(19, 120, 34.8227, 135.5246), item(20, 0, 0, 0)]}}
    p = tmp_path / "m.plan"
    p.write_text(json.dumps(plan), encoding="utf-8")
    m = load_mission(p)
    assert m.holds_s == (None, 120.0) and m.rtl
