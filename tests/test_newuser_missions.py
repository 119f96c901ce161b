"""A new user's mission files (a new-user audit, 2026-12-06): the mistakes people make with coordinates are refused
saying what was wrong and what to write, not only that a number is out of range.

Latitude and longitude swapped, degrees and minutes copied from a GGA sentence (4807.038), hemisphere letters
from a chart ("4807.038N"), latitude/longitude keys in a mission read in the local frame, degrees written as
metres, and the daemon's configuration given as the mission.
"""

from __future__ import annotations

import pytest

from autopilot.mission import MissionError, load_mission

ORIGIN = {"origin_lat_deg": 52.0, "origin_lon_deg": 4.4}


def _refusal(path, **kw) -> str:
    with pytest.raises(MissionError) as info:
        load_mission(path, **{**ORIGIN, **kw})
    return str(info.value)


@pytest.mark.parametrize("name, text", [
    ("m.yaml", "frame: latlon\nwaypoints:\n  - {lat_deg: 4.4001, lon_deg: 52.0001}\n"),
    ("m.csv", "lat_deg,lon_deg\n4.4001,52.0001\n"),
])
def test_latitude_and_longitude_swapped_is_said_with_where_the_point_would_be(tmp_path, name, text):
    # it said only "6.22397e+06 m from the origin, farther than the allowed range", sending the user to raise the range
    (tmp_path / name).write_text(text)
    message = _refusal(tmp_path / name)
    assert "waypoint 1: 6.22397e+06 m from the origin, farther than the allowed range 2000 m" in message
    assert message.endswith("; latitude and longitude swapped? (52.0001, 4.4001) would be 13 m from the origin")


def test_a_far_waypoint_not_swapped_has_no_swap_hint(tmp_path):
    (tmp_path / "m.yaml").write_text("frame: latlon\nwaypoints:\n  - {lat_deg: 52.5, lon_deg: 4.4}\n")
    assert "swapped" not in _refusal(tmp_path / "m.yaml")


@pytest.mark.parametrize("name, text", [
    ("m.yaml", "frame: latlon\nwaypoints:\n  - {lat_deg: 4807.038, lon_deg: 11.5}\n"),
    ("m.csv", "lat_deg;lon_deg\n4807,038;11,5\n"),
])
def test_degrees_and_minutes_as_nmea_writes_them_are_converted_in_the_refusal(tmp_path, name, text):
    (tmp_path / name).write_text(text)
    message = _refusal(tmp_path / name, origin_lat_deg=48.1, origin_lon_deg=11.5)
    assert message.endswith("waypoint 1: latitude 4807.04 outside -90..90 deg (4807.038 is degrees and minutes as "
                            "NMEA writes them? that is 48.117300 deg: give decimal degrees)")


def test_a_longitude_in_degrees_and_minutes_too(tmp_path):
    (tmp_path / "m.yaml").write_text("frame: latlon\nwaypoints:\n  - {lat_deg: 48.1, lon_deg: 1131.0}\n")
    assert "longitude 1131 outside -180..180 deg (1131 is degrees and minutes as NMEA writes them? that is " \
           "11.516667 deg" in _refusal(tmp_path / "m.yaml", origin_lat_deg=48.1, origin_lon_deg=11.5)


def test_hemisphere_letters_in_a_csv_are_data_not_a_units_row(tmp_path):
    # the row was taken for a units row: "the units row under the header gives lat_deg in '4807.038N'"
    (tmp_path / "m.csv").write_text("lat_deg,lon_deg\n4807.038N,01131.000E\n")
    message = _refusal(tmp_path / "m.csv")
    assert "units row" not in message
    assert message.endswith("waypoint 1: latitude is not a number ('4807.038N') (write decimal degrees, negative for "
                            "south and west: 4807.038N is 48.117300)")


def test_a_degree_sign_says_the_decimal_value(tmp_path):
    (tmp_path / "m.yaml").write_text("frame: latlon\nwaypoints:\n  - {lat_deg: \"52°00.006'S\", lon_deg: 4.4}\n")
    assert _refusal(tmp_path / "m.yaml").endswith("(write decimal degrees, negative for south and west: "
                                                  "52°00.006'S is -52.000100)")


def test_latitude_keys_without_frame_latlon_say_which_frame(tmp_path):
    (tmp_path / "m.yaml").write_text("name: x\nwaypoints:\n  - {lat_deg: 52.0001, lon_deg: 4.4001}\n")
    assert _refusal(tmp_path / "m.yaml").endswith(
        "waypoint 1: unknown key 'lat_deg' (allowed: north_m, east_m, speed_m_s, name, hold_s, hold); the waypoints "
        "are read in frame 'local': for lat_deg say frame: latlon")


def test_degrees_written_as_metres_are_not_only_a_duplicate(tmp_path):
    # [52.0001, 4.4001] and [52.0002, 4.4001] as metres are 0.1 mm apart: "same position as waypoint 1" said no more
    (tmp_path / "m.yaml").write_text("frame: local\nwaypoints:\n  - [52.0001, 4.4001]\n  - [52.0002, 4.4001]\n")
    assert _refusal(tmp_path / "m.yaml").endswith(
        "waypoint 2: same position as waypoint 1 (duplicate consecutive waypoint); latitude/longitude in a local-frame "
        "mission? give them as lat_deg, lon_deg with frame: latlon")


def test_a_true_duplicate_has_no_frame_hint(tmp_path):
    (tmp_path / "m.yaml").write_text("frame: local\nwaypoints:\n  - [10, 0]\n  - [10, 0]\n")
    assert _refusal(tmp_path / "m.yaml").endswith("(duplicate consecutive waypoint)")


def test_the_configuration_given_as_the_mission_is_named(tmp_path):
    (tmp_path / "c.yaml").write_text("rate_hz: 10\nserial: {sc30_port: /dev/sc30}\n")
    assert _refusal(tmp_path / "c.yaml").endswith(
        "rate_hz: unknown key (allowed: description, frame, home, name, origin, waypoints); "
        f"{tmp_path / 'c.yaml'} is a daemon configuration (it has serial), not a mission (--config and --mission "
        "swapped?)")
