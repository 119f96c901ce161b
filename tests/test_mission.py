"""Mission files: the four formats, home/origin handling and refusals naming the waypoint."""

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.geo import local_to_latlon
from autopilot.mission import MissionError, load_mission
from autopilot.schema import ConfigError

MISSIONS = Path(__file__).resolve().parent.parent / "config" / "missions"
HOME = (34.8225, 135.5245)


@pytest.mark.parametrize("path", sorted(MISSIONS.glob("*.yaml")) + sorted((MISSIONS / "examples").iterdir()), ids=lambda p: p.name)
def test_shipped_missions_load(path):
    m = load_mission(path)
    assert m.waypoints_ne_m.ndim == 2 and m.waypoints_ne_m.shape[1] == 2 and len(m.speeds_m_s) == len(m.waypoints_ne_m)


def test_thesis_and_pond_sets():
    assert_allclose(load_mission(MISSIONS / "thesis-sim.yaml").waypoints_ne_m, [(10, 5), (35, 20), (50, 16)])
    assert_allclose(load_mission(MISSIONS / "pond-9.3.yaml").waypoints_ne_m, [(2.7, -1.2), (7.8, -3.4), (11.9, -8.7)])
    assert len(load_mission(MISSIONS / "zigzag-003.yaml").waypoints_ne_m) == 9


def test_plan_and_waypoints_home_is_origin():
    for name in ("pond-9.4.plan", "pond-9.4.waypoints"):
        m = load_mission(MISSIONS / "examples" / name)
        assert m.home_latlon == pytest.approx(HOME) and (m.origin_lat_deg, m.origin_lon_deg) == pytest.approx(HOME)
        assert_allclose(m.waypoints_ne_m, [(10.2, -1.0), (22.0, -6.7), (34.5, -5.5)], atol=0.01)


def test_a_planner_home_does_not_move_the_configured_origin():
    """Found by a new-user audit: a QGroundControl plan's home (written wherever the map was centred) replaced the
    configuration's origin as the local frame's, and with it moved the local geofence and max_distance_m (metres
    from that origin): a plan whose home was 501 m off flew with both around it. The configured origin stays."""
    origin = local_to_latlon(-20.0, 5.0, *HOME)  # the configuration's origin, 20.6 m from the plan's home
    for name in ("pond-9.4.plan", "pond-9.4.waypoints"):
        m = load_mission(MISSIONS / "examples" / name, origin_lat_deg=origin[0], origin_lon_deg=origin[1])
        assert (m.origin_lat_deg, m.origin_lon_deg) == pytest.approx(origin)
        assert_allclose(m.home_ne_m, (20.0, -5.0), atol=0.01)  # home is where the boat starts, in that frame
        assert_allclose(m.waypoints_ne_m, [(30.2, -6.0), (42.0, -11.7), (54.5, -10.5)], atol=0.02)
    with pytest.raises(MissionError, match="waypoint 1: .* m from the origin, farther than the allowed range"):
        load_mission(MISSIONS / "examples" / "pond-9.4.plan", origin_lat_deg=0.0, origin_lon_deg=0.0)
    assert load_mission(MISSIONS / "examples" / "pond-9.4.waypoints").speeds_m_s == (1.2, 1.2, 1.2)


def test_csv_speeds_and_latlon_yaml(tmp_path):
    m = load_mission(MISSIONS / "examples" / "thesis-sim.csv")
    assert m.speeds_m_s == (None, 1.2, 0.8)
    lat, lon = local_to_latlon(30.0, -40.0, *HOME)
    p = tmp_path / "ll.yaml"
    p.write_text(f"frame: latlon\norigin: {{lat_deg: {HOME[0]}, lon_deg: {HOME[1]}}}\nwaypoints:\n  - {{lat_deg: {lat}, lon_deg: {lon}, speed_m_s: 0.9}}\n")
    m = load_mission(p)
    assert_allclose(m.waypoints_ne_m, [(30.0, -40.0)], atol=1e-6)
    assert m.speeds_m_s == (0.9,)


def _yaml(tmp_path, body):
    p = tmp_path / "m.yaml"
    p.write_text(body)
    return p


@pytest.mark.parametrize(
    "body, match",
    [
        ("waypoints: []\n", "no waypoints"),
        ("waypoints:\n  - [1, 2]\n  - [.nan, 3]\n", "waypoint 2: north_m is nan"),
        ("waypoints:\n  - [1, 2]\n  - [1, 2]\n", "waypoint 2: same position as waypoint 1"),
        ("waypoints:\n  - [1, 2]\n  - [3000, 0]\n", "waypoint 2: 3000 m from the origin"),
        ("waypoints:\n  - {north_m: 1, east_m: 2, speed_m_s: 0}\n", r"waypoint 1: speed 0 m/s outside"),
        ("waypoints:\n  - {north_m: 1}\n", "waypoint 1: missing east_m"),
        ("waypoints:\n  - {north_m: 1, east_m: x}\n", "waypoint 1: east_m is not a number"),
        ("frame: latlon\norigin: {lat_deg: 10, lon_deg: 10}\nwaypoints:\n  - {lat_deg: 10.001, lon_deg: 10}\n  - {lat_deg: 95, lon_deg: 10}\n", "waypoint 2: latitude 95 outside"),
        ("frame: latlon\nwaypoints:\n  - {lat_deg: 10, lon_deg: 10}\n", "no home or origin"),
        ("wayponts: []\n", "unknown key"),
        # a third value was taken as the leg's speed, unsaid (found as a new user)
        ("waypoints:\n  - [10, 5, 1.0]\n", r"waypoint 1: \[10, 5, 1.0\]: a bare waypoint is a \[north_m, east_m\] pair"),
    ],
)
def test_bad_yaml_missions_refused(tmp_path, body, match):
    with pytest.raises(MissionError, match=match):
        load_mission(_yaml(tmp_path, body))


def test_mission_error_is_config_error(tmp_path):
    with pytest.raises(ConfigError):
        load_mission(tmp_path / "missing.yaml")
    with pytest.raises(MissionError, match="unknown mission format"):
        load_mission(tmp_path / "m.txt")
    (tmp_path / "missions.yaml").mkdir()
    for d in (tmp_path, tmp_path / "missions.yaml"):  # was "unknown mission format ''" (or a read error)
        with pytest.raises(MissionError, match="is a directory, not a mission file"):
            load_mission(d)


def test_bad_waypoints_and_plan(tmp_path):
    p = tmp_path / "m.waypoints"
    p.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t10\t10\t0\t1\n1\t0\t3\t21\t0\t0\t0\t0\t10.0001\t10\t0\t1\n")
    with pytest.raises(MissionError, match="row 1: command 21 not supported"):
        load_mission(p)
    p = tmp_path / "m.plan"
    p.write_text(json.dumps({"mission": {"plannedHomePosition": [10, 10, 0], "items": [{"type": "SimpleItem", "command": 16, "params": [0, 0, 0, 0, 10.0001, 10, 0]}, {"type": "ComplexItem"}]}}))
    with pytest.raises(MissionError, match="item 2: only SimpleItem"):
        load_mission(p)
    p.write_text("{not json")
    with pytest.raises(MissionError, match="not valid JSON"):
        load_mission(p)


def test_csv_latlon_needs_origin(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("lat_deg,lon_deg\n10,10\n")
    with pytest.raises(MissionError, match="no home or origin"):
        load_mission(p)
    m = load_mission(p, origin_lat_deg=10.0, origin_lon_deg=10.0)
    assert_allclose(m.waypoints_ne_m, np.zeros((1, 2)), atol=1e-9)


def test_a_waypoint_in_a_local_frame_is_refused_not_read_as_degrees(tmp_path):
    """Frame 1 (MAV_FRAME_LOCAL_NED: x, y in metres) was read as latitude/longitude (found as a new user)."""
    p = tmp_path / "m.waypoints"
    p.write_text("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t10\t10\t0\t1\n1\t0\t1\t16\t0\t0\t0\t0\t20.0\t5.0\t0\t1\n")
    with pytest.raises(MissionError, match=r"row 1: frame 1 not supported: .* 1 is MAV_FRAME_LOCAL_NED"):
        load_mission(p)
    p = tmp_path / "m.plan"
    item = {"type": "SimpleItem", "command": 16, "frame": 1, "params": [0, 0, 0, 0, 20.0, 5.0, 0]}
    p.write_text(json.dumps({"mission": {"plannedHomePosition": [10, 10, 0], "items": [item]}}))
    with pytest.raises(MissionError, match=r"item 1: frame 1 not supported"):
        load_mission(p)
    item["frame"] = 10  # terrain-relative altitude: still latitude/longitude
    item["params"][4:6] = [10.0001, 10.0]
    p.write_text(json.dumps({"mission": {"plannedHomePosition": [10, 10, 0], "items": [item]}}))
    assert load_mission(p).waypoints_ne_m[0][0] == pytest.approx(11.1, abs=0.1)


def test_a_csv_row_with_more_fields_than_its_header_is_refused(tmp_path):
    """Found by a new-user audit: `north_m,east_m` over `10,5,20,3` (decimal commas, comma-separated) flew
    (10, 5) and (35, 2) instead of (10.5, 20.3) and (35.2, 20.1), without a word."""
    (tmp_path / "dc.csv").write_text("north_m,east_m\n10,5,20,3\n35,2,20,1\n")
    with pytest.raises(MissionError, match=r"data row 1 has 4 fields under a header of 2 \(decimal commas\?"):
        load_mission(tmp_path / "dc.csv")
    (tmp_path / "ok.csv").write_text("north_m,east_m,\n10,5,\n")  # a trailing empty column (Excel) is no field
    assert_allclose(load_mission(tmp_path / "ok.csv").waypoints_ne_m, [[10.0, 5.0]])


def test_a_mission_planner_change_speed_of_minus_one_keeps_the_speed(tmp_path):
    """Found by a new-user audit: DO_CHANGE_SPEED param2 -1 ("no change", as Mission Planner writes it) in a
    .waypoints file was refused as "speed -1 m/s outside (0, 3.5] m/s"."""
    from tests.conftest import REPO

    src = (REPO / "config" / "missions" / "examples" / "pond-9.4.waypoints").read_text().splitlines()
    rows = [r.split("\t") for r in src]
    k = next(i for i, r in enumerate(rows) if len(r) > 5 and r[3] == "178")
    rows.insert(k + 2, [str(k + 2), "0", "2", "178", "0", "-1", "0", "0", "0", "0", "0", "1"])
    for i, r in enumerate(rows[1:], start=0):
        r[0] = str(i)
    (tmp_path / "neg.waypoints").write_text("\n".join("\t".join(r) for r in rows) + "\n")
    m = load_mission(tmp_path / "neg.waypoints")
    base = load_mission(REPO / "config" / "missions" / "examples" / "pond-9.4.waypoints")
    assert m.speeds_m_s == base.speeds_m_s and len(m.waypoints_ne_m) == len(base.waypoints_ne_m)


def test_a_local_missions_own_origin_is_never_silently_replaced_by_the_configurations(tmp_path):
    """Found by an on-boat audit: a local-frame mission with its own origin, loaded with the configuration's
    origin 200 m away (as INSTALL asks to set it), kept its metres but took the configuration's origin: every
    waypoint moved by the 200 m between the two, without a word."""
    far = local_to_latlon(200.0, 0.0, *HOME)
    p = tmp_path / "lake.yaml"
    p.write_text(f"frame: local\norigin: {{lat_deg: {far[0]}, lon_deg: {far[1]}}}\nwaypoints:\n  - [30.0, 0.0]\n")
    with pytest.raises(MissionError, match=r"origin \(.*\) is 200 m from the configuration's origin"):
        load_mission(p, origin_lat_deg=HOME[0], origin_lon_deg=HOME[1])
    same = load_mission(p, origin_lat_deg=far[0], origin_lon_deg=far[1] + 1e-7)  # the same point: flown as written
    assert_allclose(same.waypoints_ne_m, [(30.0, 0.0)])
    alone = load_mission(p)  # no configured origin: the file's
    assert (alone.origin_lat_deg, alone.origin_lon_deg) == pytest.approx(far)
    h = tmp_path / "home.yaml"  # a home is where a simulated boat starts, not the frame's origin: not refused
    h.write_text(f"frame: local\nhome: {{lat_deg: {far[0]}, lon_deg: {far[1]}}}\nwaypoints:\n  - [30.0, 0.0]\n")
    assert load_mission(h, origin_lat_deg=HOME[0], origin_lon_deg=HOME[1]).home_ne_m[0] == pytest.approx(200.0, abs=0.1)


def test_a_csv_mission_holds_where_its_hold_s_column_says_and_refuses_columns_it_does_not_know(tmp_path):
    """Found by a new-user audit: a hold_s column was dropped without a word, and the boat did not stop there."""
    p = tmp_path / "holds.csv"
    p.write_text("name;north_m;east_m;hold_s\nbuoy;10;5;30\nquay;35;20;\n", encoding="cp1252")
    m = load_mission(p)
    assert m.holds_s == (30.0, None)
    assert_allclose(m.waypoints_ne_m, [(10.0, 5.0), (35.0, 20.0)])
    (tmp_path / "typo.csv").write_text("north_m,east_m,hold\n10,5,30\n")
    with pytest.raises(MissionError, match="column 'hold' is not one the mission reads \\(allowed: north_m, east_m, "
                                           "speed_m_s, hold_s, name; other columns are labels, not read\\)"):
        load_mission(tmp_path / "typo.csv")
    (tmp_path / "upper.csv").write_text("north_m,east_m,Speed\n10,5,1.2\n")
    with pytest.raises(MissionError, match="column 'Speed' is not one the mission reads"):
        load_mission(tmp_path / "upper.csv")
    (tmp_path / "both.csv").write_text("north_m,east_m,lat_deg,lon_deg\n10,5,52.0,4.4\n")
    with pytest.raises(MissionError, match="both north_m,east_m and lat_deg,lon_deg"):
        load_mission(tmp_path / "both.csv")
    (tmp_path / "bad.csv").write_text("north_m,east_m,hold_s\n10,5,-3\n")
    with pytest.raises(MissionError, match="hold_s -3 s outside"):
        load_mission(tmp_path / "bad.csv")


def test_a_plan_that_draws_a_geofence_is_refused_not_flown_without_it(tmp_path):
    """Found by a new-user audit: a .plan's geoFence polygons were silently not used; the operator thought the
    boat fenced. The failsafe's fence is the configuration's: the plan is refused, saying where the fence goes.
    QGroundControl writes an empty geoFence into every plan: that one is fine."""
    plan = json.loads((MISSIONS / "examples" / "pond-9.4.plan").read_text())
    assert plan["geoFence"]["polygons"] == [] and load_mission(MISSIONS / "examples" / "pond-9.4.plan")
    plan["geoFence"]["polygons"] = [{"inclusion": True, "polygon": [[52.0, 4.4], [52.001, 4.4], [52.001, 4.401]],
                                     "version": 1}]
    (tmp_path / "fenced.plan").write_text(json.dumps(plan))
    with pytest.raises(MissionError, match="geoFence: the plan draws a fence, which is not read from a .plan: put it "
                                           "in the configuration"):
        load_mission(tmp_path / "fenced.plan")


def test_excel_s_empty_rows_under_a_csv_mission_are_no_waypoints(tmp_path):
    """Found by a new-user audit: Excel writes ';;;;' rows under the data where cells were once formatted: they were
    read as waypoints ("waypoint 3: north_m is not a number ('')")."""
    p = tmp_path / "m.csv"
    p.write_bytes("north_m;east_m;speed_m_s;Notiz\r\n10;5;1,2;Boje\r\n35;20;;Br\u00fccke\r\n;;;\r\n;;;\r\n".encode("cp1252"))
    m = load_mission(p)
    assert_allclose(m.waypoints_ne_m, [(10.0, 5.0), (35.0, 20.0)])
    (tmp_path / "gap.csv").write_text("north_m,east_m\n10,5\n,7\n")  # a row with a cell missing is still refused
    with pytest.raises(MissionError, match="waypoint 2: north_m is not a number"):
        load_mission(tmp_path / "gap.csv")


def test_a_units_row_under_a_csv_mission_header_is_read_as_units(tmp_path):
    """Left in stop 42's note (a new-user audit): a spreadsheet's units row under the header was refused as
    "waypoint 1: north_m is not a number ('m')". It is skipped when its units are the columns' own, and refused
    naming the column when not: a north_m in feet read as metres would fly another mission."""
    p = tmp_path / "u.csv"
    p.write_bytes("north_m;east_m;hold_s;Bemerkung\r\n[m];[m];[s];\r\n10;5;30;Boje\r\n35;20;;\r\n".encode("cp1252"))
    m = load_mission(p)
    assert_allclose(m.waypoints_ne_m, [(10.0, 5.0), (35.0, 20.0)])
    assert tuple(m.holds_s) == (30.0, None)
    (tmp_path / "ll.csv").write_text("lat_deg,lon_deg,speed_m_s\n\u00b0,deg,m/s\n52.0001,4.4001,1.0\n")
    assert len(load_mission(tmp_path / "ll.csv", origin_lat_deg=52.0, origin_lon_deg=4.4).waypoints_ne_m) == 1
    (tmp_path / "ft.csv").write_text("north_m,east_m\nft,ft\n30,0\n")
    with pytest.raises(MissionError, match="units row under the header gives north_m in 'ft'; the mission reads "
                                           "north_m in m"):
        load_mission(tmp_path / "ft.csv")
    (tmp_path / "only.csv").write_text("north_m,east_m\nm,m\n")  # a units row is no waypoint
    with pytest.raises(MissionError, match="the mission has no waypoints"):
        load_mission(tmp_path / "only.csv")
    (tmp_path / "word.csv").write_text("north_m,east_m\n10,x\n")  # a row with a number in it is data, as before
    with pytest.raises(MissionError, match="waypoint 1: east_m is not a number"):
        load_mission(tmp_path / "word.csv")


def test_a_plan_s_cruise_speed_out_of_range_is_named_as_such(tmp_path):
    """Found by a new-user audit: QGroundControl's cruiseSpeed 15 (its default for aircraft) was refused as "waypoint
    1: speed 15 m/s outside (0, 3.5] m/s", naming neither the setting nor where QGroundControl keeps it."""
    plan = json.loads((MISSIONS / "examples" / "pond-9.4.plan").read_text())
    plan["mission"]["cruiseSpeed"] = 15
    (tmp_path / "fast.plan").write_text(json.dumps(plan))
    with pytest.raises(MissionError, match="mission.cruiseSpeed: 15 m/s outside \\[0.05, 3.5\\] m/s .*Mission Start item"):
        load_mission(tmp_path / "fast.plan")


def test_a_planner_home_at_zero_zero_is_no_home(tmp_path):
    """Found by a new-user audit: Mission Planner writes home 0, 0 when none was set; taken as the home (and so the
    origin), the waypoints were 15 600 km from it and the message sent the user to max_mission_range_m."""
    rows = (MISSIONS / "examples" / "pond-9.4.waypoints").read_text().splitlines()
    f = rows[1].split("\t")
    f[8], f[9] = "0.000000", "0.000000"
    (tmp_path / "nohome.waypoints").write_text("\n".join([rows[0], "\t".join(f), *rows[2:]]) + "\n")
    m = load_mission(tmp_path / "nohome.waypoints", origin_lat_deg=HOME[0], origin_lon_deg=HOME[1])
    assert m.home_latlon is None
    assert_allclose(m.waypoints_ne_m, [(10.2, -1.0), (22.0, -6.7), (34.5, -5.5)], atol=0.01)
    with pytest.raises(MissionError, match="no home or origin to convert them around"):
        load_mission(tmp_path / "nohome.waypoints")


def test_an_upper_case_header_and_rtl_in_capitals_are_read(tmp_path):
    """Found by a new-user audit: NORTH_M,EAST_M (a spreadsheet's header in capitals) was refused ("header must
    name north_m,east_m"), and `- RTL` in YAML said only "expected a mapping with north_m, east_m"."""
    (tmp_path / "up.csv").write_text("NORTH_M,East_M,Hold_S\n10,0,5\n")
    m = load_mission(tmp_path / "up.csv")
    assert_allclose(m.waypoints_ne_m, [(10.0, 0.0)]) and m.holds_s == (5.0,)
    (tmp_path / "rtl.yaml").write_text("name: m\nwaypoints:\n  - [10, 0]\n  - RTL\n")
    assert load_mission(tmp_path / "rtl.yaml").rtl
