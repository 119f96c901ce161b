"""Daemon configuration: the shipped file loads, bad values are refused naming key and range."""

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from autopilot.daemon.config import DaemonConfig, load_config
from autopilot.schema import ConfigError, load, to_dict

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "config" / "autopilot.yaml"


def test_shipped_config_is_complete_and_equals_the_defaults():
    cfg = load_config(SHIPPED)
    assert cfg == DaemonConfig()
    # every setting is written out in the file (no hidden defaults)
    assert yaml.safe_load(SHIPPED.read_text()) == to_dict(DaemonConfig())


BAD = [
    ({"rate_hz": 0.5}, "rate_hz: 0.5 is outside the allowed range [4, 50] Hz"),
    ({"rate_hz": 2}, "rate_hz: 2 is outside the allowed range [4, 50] Hz"),  # the Mbed would cut the motors between commands
    ({"rate_hz": 51}, "rate_hz: 51 is outside the allowed range [4, 50] Hz"),
    ({"rate_hz": "fast"}, "rate_hz: expected a number in [4, 50] Hz, got 'fast'"),
    ({"rate_hz": float("nan")}, "rate_hz: nan is not a finite number"),
    ({"rate": 10}, "rate: unknown key (allowed: "),
    ({"serial": {"sc30_baud": 4801}}, "serial.sc30_baud: 4801 is not one of 4800, 9600, 19200, 38400"),
    ({"serial": {"mbed_port": 5}}, "serial.mbed_port: expected a string, got 5"),
    ({"serial": {"sc30_prot": "/dev/x"}}, "serial.sc30_prot: unknown key"),
    ({"failsafe": {"heading_stale_s": 0}}, "failsafe.heading_stale_s: 0 is outside the allowed range [0.05, 10] s"),
    ({"failsafe": {"resume_after_restart": "yes"}}, "failsafe.resume_after_restart: expected true or false, got 'yes'"),
    ({"failsafe": {"ack_missing_n": 2.5}}, "failsafe.ack_missing_n: expected an integer in [1, 100] commands, got 2.5"),
    ({"rate_hz": 4, "failsafe": {"heading_stale_s": 0.1}}, "failsafe.heading_stale_s: 0.1 s is shorter than one control period (0.25 s)"),
    ({"geofence": {"frame": "utm"}}, "geofence.frame: 'utm' is not one of none, local, latlon"),
    ({"geofence": {"frame": "local", "polygon": [[0, 0], [1, 1]]}}, "geofence.polygon: needs at least 3 vertices"),
    ({"geofence": {"frame": "latlon", "polygon": [[95, 0], [0, 1], [1, 1]]}}, "geofence.polygon[0]: [95.0, 0.0] is not a latitude"),
    ({"origin_lat_deg": 52.0}, "origin_lat_deg, origin_lon_deg: give both or neither"),
    ({"origin_lat_deg": 91.0, "origin_lon_deg": 0.0}, "origin_lat_deg: 91.0 is outside the allowed range [-90, 90] deg"),
    ({"gnc": {"pid": {"kq": 1}}}, "gnc.pid.kq: unknown key"),
    ({"serial": "x"}, "serial: expected its settings as 'key: value' lines below it, got str 'x'"),  # not 'SerialConfig'
]


@pytest.mark.parametrize("data, message", BAD, ids=[str(i) for i in range(len(BAD))])
def test_bad_settings_are_refused_with_key_and_range(data, message):
    with pytest.raises(ConfigError) as exc:
        load(DaemonConfig, data)
    assert message in str(exc.value)


def test_battery_low_v_zero_turns_battery_low_off_as_documented():
    """Found by a new-user audit: `battery_low_v: 0` ("0 = off") was refused as below battery_critical_v."""
    cfg = load(DaemonConfig, {"failsafe": {"battery_low_v": 0}})
    assert cfg.failsafe.battery_low_v == 0.0 and cfg.failsafe.battery_critical_v == 11.7
    with pytest.raises(ConfigError, match="battery_critical_v: 12 V is above failsafe.battery_low_v"):
        load(DaemonConfig, {"failsafe": {"battery_low_v": 11.5, "battery_critical_v": 12}})


def test_geofence_accepts_local_and_latlon_polygons():
    cfg = load(DaemonConfig, {"geofence": {"frame": "latlon", "polygon": [[52.0, 4.0], [52.0, 4.1], [52.1, 4.1]]}})
    assert cfg.geofence.polygon[1] == (52.0, 4.1)


def _run(*argv, cwd):
    return subprocess.run([sys.executable, "-m", "autopilot", *argv], cwd=cwd, capture_output=True, text=True, timeout=60)


def test_cli_refuses_a_bad_config_before_opening_any_port(tmp_path):
    cfg = tmp_path / "bad.yaml"
    # the ports do not exist: a refusal must come from the check, not from an open attempt
    cfg.write_text("rate_hz: 80\nserial: {sc30_port: /nonexistent/sc30, mbed_port: /nonexistent/mbed}\n")
    mission = tmp_path / "m.yaml"
    mission.write_text("name: x\n")
    r = _run("run", "--config", str(cfg), "--mission", str(mission), "--log-dir", str(tmp_path / "logs"), cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip() == f"autopilot run: error: {cfg}: rate_hz: 80 is outside the allowed range [4, 50] Hz"
    assert not (tmp_path / "logs").exists()


def test_cli_reports_a_missing_config_file(tmp_path):
    r = _run("run", "--config", str(tmp_path / "nope.yaml"), "--mission", "m.yaml", cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.strip() == f"autopilot run: error: {tmp_path / 'nope.yaml'}: cannot read (No such file or directory)"


def test_cli_reports_invalid_yaml(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("rate_hz: [1,\n")
    r = _run("run", "--config", str(cfg), "--mission", "m.yaml", cwd=tmp_path)
    assert r.returncode == 2 and "not valid YAML" in r.stderr


@pytest.mark.parametrize("text", ["", "\n\n", "# every key commented out\n#rate_hz: 10\n"])
def test_an_empty_config_is_refused_and_an_explicit_empty_mapping_means_the_defaults(tmp_path, text):
    """Found by review: an empty file (a copy cut short) flew on every shipped default without a word."""
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError, match=r"c.yaml: the configuration is empty \(no setting at all\); to run on "
                                          r"every default say so with \{\} in the file"):
        load_config(tmp_path / "c.yaml")
    (tmp_path / "d.yaml").write_text("{}\n")
    assert load_config(tmp_path / "d.yaml") == DaemonConfig()


def test_the_shipped_configuration_is_the_one_the_settings_render():
    """config/autopilot.yaml (shipped as autopilot/data/autopilot.yaml) is generated from the settings' dataclasses
    (render_yaml): a setting added, or a range's text changed, without regenerating it left the file users copy
    without the new key or with the old text (it had drifted: four range comments read '2.14748e+09' and '[0, 1] -')."""
    from autopilot.daemon.config import render_yaml
    from autopilot.resources import default_config_path

    assert default_config_path().read_text(encoding="utf-8") == render_yaml()
