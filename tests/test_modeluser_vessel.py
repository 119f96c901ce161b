"""A marine-robotics user's vessel files in `autopilot model`, `autopilot evaluate` and `autopilot gnc` (a
model-user audit, 2026-12-06): every field within its range and still a set that cannot be simulated, the wrong
kind of file where a vessel or GNC file goes, the daemon's configuration for `gnc surface`. Each refused with
one line naming the file and what to change, exit 2, no "internal error ... a bug"."""

import json
import re

import pytest

from autopilot.cli import main
from autopilot.resources import data_dir

SHIPPED_VESSEL = data_dir() / "vessel.yaml"


def vessel_with(tmp_path, name: str = "v.yaml", **values) -> str:
    """The shipped calibrated set with ``values`` written over its own."""
    text = SHIPPED_VESSEL.read_text(encoding="utf-8")
    for key, value in values.items():
        text, n = re.subn(rf"(?m)^{key}: .*$", f"{key}: {value}", text)
        assert n == 1, key
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def refused(capsys, argv) -> str:
    """The one-line refusal of ``argv`` (exit 2, nothing called a bug)."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and "Traceback" not in err, err
    return err


def test_a_set_without_any_resistance_is_refused_naming_its_fields(tmp_path, capsys):
    """Both resistance terms 0 (each within [0, 1000]): `model manoeuvre speed` printed 21.8 m/s after 120 s, AF
    and `model check` stopped on "internal error: FloatingPointError ... (a bug)", the zig-zag on
    "ZeroDivisionError", and `evaluate` flew it with exit 0."""
    path = vessel_with(tmp_path, resistance_linear_n_s_m="0.0", resistance_quadratic_n_s2_m2="0.0")
    for argv in (["model", "manoeuvre", "speed", "--params", path], ["model", "manoeuvre", "zigzag", "--params", path],
                 ["model", "check", "--params", path],
                 ["evaluate", "--mission", "pond-9.1", "--guidance", "fuzzy", "--condition", "calm", "--vessel", path]):
        err = refused(capsys, argv)
        assert f"{path}: resistance_linear_n_s_m = 0, resistance_quadratic_n_s2_m2 = 0: nothing damps surge" in err


def test_a_set_without_yaw_damping_is_refused(tmp_path, capsys):
    """n_r_nd and both zero-speed yaw terms 0: a constant moment spun the model ever faster (-20 rad/s after
    1000 s of AC), silently."""
    path = vessel_with(tmp_path, n_r_nd="0.0", yaw_damping_linear_nm_s="0.0", yaw_damping_quadratic_nm_s2="0.0")
    err = refused(capsys, ["model", "manoeuvre", "AC", "--params", path])
    assert "nothing damps yaw" in err and "the damping at zero speed" in err


def test_a_set_with_quadratic_resistance_only_flies_the_zigzag(tmp_path, capsys):
    """The zig-zag's starting speed divided by the linear resistance alone: ZeroDivisionError, "internal error"."""
    path = vessel_with(tmp_path, resistance_linear_n_s_m="0.0", resistance_quadratic_n_s2_m2="5.0")
    assert main(["model", "manoeuvre", "zigzag", "--params", path, "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert len(figures["overshoot_deg"]) == 4 and all(o > 0 for o in figures["overshoot_deg"])


def test_the_zigzag_starts_at_the_steady_speed_of_a_quadratic_resistance():
    from dataclasses import replace

    from autopilot.sim.manoeuvres import steady_speed_m_s
    from autopilot.sim.params import load_params

    base = load_params(SHIPPED_VESSEL)
    quad = replace(base, resistance_linear_n_s_m=3.0, resistance_quadratic_n_s2_m2=5.0)
    speed = steady_speed_m_s(quad, 16.25)
    assert 3.0 * speed + 5.0 * speed**2 == pytest.approx((1 - quad.thrust_deduction) * 2 * 16.25)
    assert steady_speed_m_s(base, 16.25) == pytest.approx(0.75 * 32.5 / base.resistance_linear_n_s_m)


def test_nomoto_of_a_set_without_linear_sway_damping_names_the_file(tmp_path, capsys):
    """Y'_v = 0 and no linear sway damping (both in range): "internal error: ZeroDivisionError" from T3 = q5/q4."""
    path = vessel_with(tmp_path, y_v_nd="0.0", sway_damping_linear_n_s_m="0.0")
    err = refused(capsys, ["model", "nomoto", "--speed", "1.5", "--params", path])
    assert f"{path}: y_v_nd = 0 and sway_damping_linear_n_s_m = 0: the linear model has no sway damping" in err


@pytest.mark.parametrize("argv", [
    ["model", "check"],
    ["model", "manoeuvre", "AF"],
    ["model", "manoeuvre", "zigzag"],  # stepped by hand: it printed "overshoot_deg = []" with exit 0
    ["evaluate", "--mission", "pond-9.1", "--guidance", "fuzzy", "--condition", "calm"],
])
def test_a_set_too_stiff_for_the_step_is_the_sets_error_not_a_bug(tmp_path, capsys, argv):
    """mass_kg 1 (its range is [1, 10000] kg) under the shipped cross-flow damping: the fixed-step RK4 blows up.
    That was "internal error: FloatingPointError" (evaluate: "ValueError: NavInput ...") asking for a bug report."""
    path = vessel_with(tmp_path, mass_kg="1.0")
    option = "--vessel" if argv[0] == "evaluate" else "--params"
    err = refused(capsys, argv + [option, path])
    assert f"{path}: the simulation of this vessel set diverged" in err and "mass_kg" in err
    assert "RuntimeWarning" not in err  # numpy's overflow warnings no longer come first


@pytest.mark.parametrize("argv, kind, option", [
    (["model", "check", "--params"], "a daemon configuration", "autopilot.yaml"),
    (["evaluate", "--mission", "pond-9.1", "--vessel"], "a daemon configuration", "autopilot.yaml"),
    (["model", "nomoto", "--speed", "1", "--params"], "a mission", "missions/pond-9.1.yaml"),
    (["gnc", "surface", "--config"], "a vessel parameter set", "vessel.yaml"),
    (["evaluate", "--mission", "pond-9.1", "--config"], "a vessel parameter set", "vessel.yaml"),
])
def test_the_wrong_kind_of_file_is_named_as_what_it_is(capsys, argv, kind, option):
    """The daemon's configuration as --params said "ais: unknown key (allowed: " and the 34 vessel keys, the
    vessel file as --config "added_inertia_ratio: unknown key": not a word on what the file was."""
    path = str(data_dir() / option)
    err = refused(capsys, argv + [path])
    assert f"{path} is {kind}" in err and "(allowed: " not in err


def test_gnc_surface_reads_the_daemons_configuration(capsys, tmp_path):
    """`gnc surface --config` refused the shipped autopilot.yaml ("ais: unknown key") while `evaluate --config`
    read its gnc: section; a tuned universe there now changes the surface."""
    assert main(["gnc", "surface"]) == 0
    default = capsys.readouterr().out
    assert main(["gnc", "surface", "--config", str(data_dir() / "autopilot.yaml")]) == 0
    assert capsys.readouterr().out == default
    tuned = tmp_path / "c.yaml"
    tuned.write_text("gnc:\n  guidance:\n    fuzzy: {tcpa_max_nd: 2.0}\n", encoding="utf-8")
    assert main(["gnc", "surface", "--config", str(tuned)]) == 0
    out = capsys.readouterr().out
    assert out != default and out.splitlines()[0].split()[-1] == "2.00"
    (tmp_path / "bad.yaml").write_text("gnc:\n  guidance:\n    fuzzy: {tcpa_max_nd: -1}\n", encoding="utf-8")
    err = refused(capsys, ["gnc", "surface", "--config", str(tmp_path / "bad.yaml")])
    assert "gnc.guidance.fuzzy.tcpa_max_nd: -1" in err and "allowed range" in err


def test_calibrate_says_when_its_fit_misses_what_the_default_set_must_meet(tmp_path, capsys):
    """A 1000-kg base was fitted to 88 % turning-speed RMS and written with exit 0 and no word (README: turning
    rows within 10 % in speed and 20 % in yaw rate)."""
    base = vessel_with(tmp_path, "heavy.yaml", mass_kg="1000.0")
    out = tmp_path / "fitted.yaml"
    assert main(["model", "calibrate", "--base", base, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert out.exists() and "warning: the fitted set does not reproduce the measured table" in err
    assert "turning speed RMS" in err and "> 10 %" in err


def test_a_set_damped_in_yaw_only_by_n_r_nd_is_refused(tmp_path):
    """N'_r vanishes with the speed (params.py _ZERO_SPEED): a set whose only yaw damping it is spun in place to
    130 rad/s in 1000 s, and loaded (a review)."""
    import dataclasses

    import yaml

    from autopilot.schema import ConfigError, to_dict
    from autopilot.sim.params import load_params

    v = dataclasses.replace(load_params("config/vessel.yaml"), yaw_damping_linear_nm_s=0.0,
                            yaw_damping_quadratic_nm_s2=0.0)
    path = tmp_path / "vessel.yaml"
    path.write_text(yaml.safe_dump(to_dict(v)))
    with pytest.raises(ConfigError, match="nothing damps yaw"):
        load_params(path)
