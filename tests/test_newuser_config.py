"""A new user's configuration (a new-user audit, 2026-12-06): YAML's own readings of a word, an emptied value,
degrees and minutes in the origin and the wrong file given as the configuration are refused naming the key and
what to write."""

from __future__ import annotations

import pytest

from autopilot.daemon.config import load_config
from autopilot.resources import default_params_path
from autopilot.schema import ConfigError


def _refusal(tmp_path, text: str) -> str:
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError) as info:
        load_config(tmp_path / "c.yaml")
    return str(info.value)


@pytest.mark.parametrize("text, expected", [
    # `no` and `off` are YAML's false: "expected a string, got False" named neither the choices nor why
    ("failsafe: {actions: {position: no}}\n",
     "failsafe.actions.position: expected one of stop, hold, rtl, got False (YAML reads yes/no/on/off as true/false: "
     "quote the word)"),
    ("geofence: {frame: }\n", "geofence.frame: expected one of none, local, latlon, got nothing"),
    # a key left with nothing after it is null: "expected a string, got None"
    ("serial:\n  sc30_port:\n", "serial.sc30_port: expected a string, got nothing (write '' for empty)"),
])
def test_a_word_yaml_reads_as_something_else_is_said(tmp_path, text, expected):
    assert _refusal(tmp_path, text).endswith(expected)


def test_an_origin_in_degrees_and_minutes_is_converted_in_the_refusal(tmp_path):
    message = _refusal(tmp_path, "origin_lat_deg: 4807.038\norigin_lon_deg: 11.5\n")
    assert message.endswith("origin_lat_deg: 4807.038 is outside the allowed range [-90, 90] deg (4807.038 is degrees "
                            "and minutes as NMEA writes them? that is 48.117300 deg)")


def test_a_plain_out_of_range_origin_has_no_hint(tmp_path):
    assert _refusal(tmp_path, "origin_lat_deg: 91.0\norigin_lon_deg: 0.0\n").endswith(
        "origin_lat_deg: 91.0 is outside the allowed range [-90, 90] deg")


def test_a_mission_given_as_the_configuration_is_named(tmp_path):
    message = _refusal(tmp_path, "name: m\nframe: local\nwaypoints:\n  - [10, 0]\n")
    assert message.startswith(f"{tmp_path / 'c.yaml'}: frame: unknown key (allowed: ")
    assert message.endswith(f"; {tmp_path / 'c.yaml'} is a mission (it has waypoints), not the daemon's configuration "
                            "(--config and --mission swapped?)")


def test_a_vessel_file_given_as_the_configuration_is_named(tmp_path):
    vessel = default_params_path()
    with pytest.raises(ConfigError) as info:
        load_config(vessel)
    assert str(info.value).endswith(f"; {vessel} is a vessel parameter set (it has mass_kg), not the daemon's "
                                    "configuration (sim.vessel names it)")


def test_a_typo_in_a_real_configuration_is_not_called_another_file(tmp_path):
    assert _refusal(tmp_path, "rate_hz: 10\nserial: {sc30_prot: /dev/x}\n").startswith(
        f"{tmp_path / 'c.yaml'}: serial.sc30_prot: unknown key (allowed: ")
    assert "not the daemon's configuration" not in _refusal(tmp_path, "rate_hz: 10\nserail: {}\n")


def test_a_misspelt_key_is_told_the_key_it_most_likely_means(tmp_path):
    """Stop 47's note: a misspelt key got "unknown key (allowed: ...)" and the whole list (34 keys in a vessel file),
    the user left to spot the right one; now the closest allowed key is named, in any file the schema reads and in
    a mission. A key like none of them gets the list alone."""
    import pytest

    from autopilot.mission import MissionError, load_mission
    from autopilot.schema import ConfigError
    from autopilot.sim import default_params_path, load_params

    vessel = default_params_path().read_text(encoding="utf-8")
    key = next(line.split(":")[0] for line in vessel.splitlines() if line.startswith("mass"))
    (tmp_path / "v.yaml").write_text(vessel.replace(f"{key}:", f"{key}s:", 1), encoding="utf-8")
    with pytest.raises(ConfigError) as exc:
        load_params(tmp_path / "v.yaml")
    assert str(exc.value).endswith(f"; did you mean {key}?"), str(exc.value)
    (tmp_path / "m.yaml").write_text("name: m\nwaypiont:\n  - [10, 0]\n", encoding="utf-8")
    with pytest.raises(MissionError) as exc:
        load_mission(tmp_path / "m.yaml")
    assert "waypiont: unknown key (allowed: " in str(exc.value) and "did you mean waypoints?" in str(exc.value)
    (tmp_path / "v.yaml").write_text(vessel + "\nzzz_colour: red\n", encoding="utf-8")
    with pytest.raises(ConfigError) as exc:
        load_params(tmp_path / "v.yaml")
    assert "zzz_colour: unknown key (allowed: " in str(exc.value) and "did you mean" not in str(exc.value)
