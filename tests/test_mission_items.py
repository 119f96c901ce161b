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


# ---- uploaded missions: item numbers as the planner shows them (found by a link audit, 2026-12-05) ----
def _item(seq, cmd, lat=0.0, lon=0.0, p1=0.0, p2=0.0, frame=3):
    return dict(seq=seq, frame=frame, command=cmd, param1=p1, param2=p2, lat_deg=lat, lon_deg=lon)


def _ll(north_m, east_m):
    from autopilot.geo import local_to_latlon

    return local_to_latlon(north_m, east_m, *HOME)


def _upload(items):
    from autopilot.mission import mission_from_items

    return mission_from_items(items, origin_lat_deg=HOME[0], origin_lon_deg=HOME[1])


def test_a_loiter_here_is_not_counted_as_a_waypoint_in_the_item_numbers():
    """QGC's home, WP1, LOITER_TIME 10 s "here" (0, 0), WP2 (item 3), WP3 (item 4): the loiter was counted as a
    waypoint, so MISSION_SET_CURRENT 3 flew to WP3 and 4 was refused as beyond the mission."""
    from autopilot.mission import ItemNumbers

    w = [_ll(30, 0), _ll(30, 30), _ll(0, 30)]
    m = _upload([_item(0, 16, *HOME), _item(1, 16, *w[0]), _item(2, 19, p1=10.0), _item(3, 16, *w[1]),
                 _item(4, 16, *w[2])])
    numbers = ItemNumbers.of(m)
    assert m.holds_s == (10.0, None, None) and numbers.waypoints == (1, 3, 4)
    assert [numbers.waypoint_of(s) for s in (1, 2, 3, 4)] == [0, 1, 1, 2]  # a jump to the loiter: the next waypoint


def test_an_uploaded_mission_keeps_its_item_numbers_after_a_restart(tmp_path):
    """The uploaded mission is saved as a .waypoints file for a restart; read back, its items were generated anew:
    a speed item of -1 ("no change") and a repeated speed were dropped, and QGC's numbers no longer matched
    (MISSION_CURRENT 3 of 5 for 4 of 7; MISSION_SET_CURRENT 6 refused)."""
    from autopilot.daemon.state import save_uploaded_mission
    from autopilot.mission import ItemNumbers, mission_to_items

    w = [_ll(30, 0), _ll(30, 30), _ll(0, 30)]
    items = [_item(0, 16, *HOME), _item(1, 178, p1=1, p2=1.5, frame=2), _item(2, 16, *w[0]),
             _item(3, 178, p1=1, p2=-1, frame=2), _item(4, 16, *w[1]), _item(5, 178, p1=1, p2=1.5, frame=2),
             _item(6, 16, *w[2])]
    live = _upload(items)
    path, _ = save_uploaded_mission(tmp_path, live)
    again = load_mission(path, origin_lat_deg=HOME[0], origin_lon_deg=HOME[1])
    assert ItemNumbers.of(again) == ItemNumbers.of(live) and ItemNumbers.of(again).waypoints == (2, 4, 6)
    assert [(it["seq"], it["command"], it["param2"]) for it in mission_to_items(again)] == [
        (0, 16, 0.0), (1, 178, 1.5), (2, 16, 0.0), (3, 178, -1.0), (4, 16, 0.0), (5, 178, 1.5), (6, 16, 0.0)]
    assert again.speeds_m_s == live.speeds_m_s == (1.5, 1.5, 1.5)


def test_a_waypoints_hold_time_is_flown_not_only_shown():
    """MAVLink's NAV_WAYPOINT param1 is the hold time at the waypoint (ArduPilot Rover's delay): it was ignored
    while the download gave it back. NaN (unset) is no hold; a negative one is refused naming the item."""
    from autopilot.mission import MissionItemError

    w = [_ll(30, 0), _ll(30, 30)]
    m = _upload([_item(0, 16, *HOME), _item(1, 16, *w[0], p1=20.0), _item(2, 16, *w[1], p1=math.nan)])
    assert m.holds_s == (20.0, None)
    with pytest.raises(MissionItemError, match=r"item 1: hold time -5 s outside \[0, 86400\] s") as exc:
        _upload([_item(0, 16, *HOME), _item(1, 16, *w[0], p1=-5.0)])
    assert (exc.value.seq, exc.value.field) == (1, "param1")


def test_a_refused_upload_names_the_item_the_planner_shows():
    """A DO_CHANGE_SPEED of 5 m/s at item 3 was refused as "waypoint 3: speed 5 m/s" (neither its number nor the
    waypoint's); a waypoint too far is named by its item too."""
    from autopilot.mission import MissionItemError

    w = [_ll(30, 0), _ll(30, 30), _ll(0, 30)]
    with pytest.raises(MissionItemError, match=r"item 3: speed 5\.0 m/s outside \[0\.05, 3\.5\]") as exc:
        _upload([_item(0, 16, *HOME), _item(1, 16, *w[0]), _item(2, 16, *w[1]), _item(3, 178, p2=5.0, frame=2),
                 _item(4, 16, *w[2])])
    assert (exc.value.seq, exc.value.field) == (3, "param2")
    far = _ll(5000, 0)
    with pytest.raises(MissionItemError, match=r"item 3 \(waypoint 2\): 5000 m from the origin") as exc:
        _upload([_item(0, 16, *HOME), _item(1, 16, *w[0]), _item(2, 178, p2=1.0, frame=2), _item(3, 16, *far)])
    assert exc.value.seq == 3


def test_mission_current_names_the_rtl_item_only_once_the_mission_came_to_it():
    """Found by a review: while returning (an rtl commanded mid-mission), MISSION_SET_CURRENT's answer named the
    mission's RTL item, not the item jumped to, and the planner took the jump as refused. The RTL item is current
    once the mission has come to it, as ArduPilot reports the mission's own current item in any mode."""
    import types

    from autopilot.daemon.loop import ControlLoop
    from autopilot.gnc import Autopilot, GncConfig
    from autopilot.gnc.autopilot import NavInput
    from autopilot.mission import ItemNumbers

    m = _upload([_item(0, 16, *HOME), _item(1, 16, *_ll(30, 0)), _item(2, 16, *_ll(30, 30)), _item(3, 16, *_ll(0, 30)),
                 _item(4, 20, frame=2)])
    ap = Autopilot(GncConfig(), m.waypoints_ne_m, rtl=m.rtl)
    nav = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    ap.step(nav, 0.1)
    loop = types.SimpleNamespace(ap=ap, item_numbers=ItemNumbers.of(m))
    assert ap.request("rtl", nav, cause="mavlink")[0]
    assert ControlLoop.mission_item_now(loop) == (1, 5)  # returning mid-mission: the mission's item
    assert ap.set_current(1, cause="mavlink")[0]
    assert ControlLoop.mission_item_now(loop) == (2, 5)  # the jump, answered as made
    ap.guidance.complete = True  # the mission came to its RTL item
    assert ControlLoop.mission_item_now(loop) == (4, 5)
