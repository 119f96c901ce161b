"""`autopilot model manoeuvre` with the durations a user tries (a model-user audit, 2026-12-06): a run too
short for what it reports is said on stderr, the shortest run is one simulation step, the JSON stays JSON, and
the plot of a boat spinning in place shows a point, not floating-point noise."""

import json

import numpy as np
import pytest

from autopilot.cli import main
from autopilot.sim.manoeuvres import run
from autopilot.sim.params import default_params_path, load_params


@pytest.fixture(scope="module")
def params():
    return load_params(default_params_path())


def test_a_zigzag_shorter_than_a_step_is_refused_not_an_internal_error(capsys):
    """--duration-s 0.01 was let through the (0, 3600] check: "internal error: IndexError: index -2 is out of
    bounds" (the speed test printed "time_constant_s": NaN, which is not JSON)."""
    assert main(["model", "manoeuvre", "zigzag", "--duration-s", "0.01"]) == 2
    err = capsys.readouterr().err
    assert "--duration-s: 0.01 is outside the allowed range [0.05, 3600] s" in err and "internal error" not in err


def test_the_shortest_runs_give_json(capsys):
    for name in ("speed", "zigzag", "AF", "spin"):
        assert main(["model", "manoeuvre", name, "--duration-s", "0.05", "--json"]) == 0
        out = capsys.readouterr().out
        json.loads(out, parse_constant=lambda c: pytest.fail(f"{name}: {c} in {out}"))


def test_a_speed_test_of_a_boat_that_never_moved_has_no_time_constant(params):
    from dataclasses import replace

    figures = run(replace(params, max_thrust_n=0.0), "speed", duration_s=1.0).figures
    assert figures["time_constant_s"] is None
    json.dumps(figures, allow_nan=False)


@pytest.mark.parametrize("name, duration", [("speed", "5"), ("AF", "1"), ("AF", "60"), ("spin", "10")])
def test_figures_of_a_run_too_short_to_settle_are_said_not_steady(capsys, name, duration):
    """`manoeuvre speed --duration-s 5` printed final speed 0.80 m/s and time constant 3.05 s (settled: 3.46 m/s,
    19 s) and AF for 1 s a "steady" 0.045 m/s on a 2.78 m turning circle (1.50 m/s, 4.25 m), without a word."""
    assert main(["model", "manoeuvre", name, "--duration-s", duration]) == 0
    err = capsys.readouterr().err
    assert "still changing at the end of the" in err and "not a steady state" in err


@pytest.mark.parametrize("name", ["speed", "AF", "Fb", "spin", "zigzag"])
def test_the_documented_runs_carry_no_warning(params, name):
    """README's figures come from the default durations: none of them is flagged."""
    assert run(params, name).warnings == ()


def test_a_zigzag_with_fewer_reversals_than_it_reports_says_so(capsys):
    assert main(["model", "manoeuvre", "zigzag", "--duration-s", "10"]) == 0
    captured = capsys.readouterr()
    assert "overshoot_deg = []" in captured.out
    assert "warning: zigzag: 0 of 4 reversals completed in the 10 s run" in captured.err


def test_the_spin_track_is_drawn_round_its_point(tmp_path, monkeypatch, params):
    """The spin's track (1e-11 m of rounding) filled the panel as circles on axes scaled 1e-11."""
    from autopilot import plotting
    from autopilot.sim import manoeuvres

    axes = []
    real = plotting.track_frame

    def spy(ax, *a, **kw):
        axes.append(ax)
        return real(ax, *a, **kw)

    monkeypatch.setattr(plotting, "track_frame", spy)
    png = tmp_path / "spin.png"
    manoeuvres.plot(run(params, "spin"), str(png))
    assert png.stat().st_size > 10_000
    (ax,) = axes
    assert np.ptp(ax.get_xlim()) >= plotting.MIN_TRACK_SPAN_M - 1e-9
    assert np.ptp(ax.get_ylim()) >= plotting.MIN_TRACK_SPAN_M - 1e-9


def test_a_long_track_keeps_its_own_frame():
    from autopilot.plotting import pyplot, track_frame

    plt = pyplot()
    fig, ax = plt.subplots()
    ax.plot([0, 30], [0, 20])
    track_frame(ax, np.array([0.0, 20.0]), np.array([0.0, 30.0]))
    assert np.ptp(ax.get_xlim()) >= 30.0 and np.ptp(ax.get_xlim()) < 60.0
    plt.close(fig)


@pytest.mark.parametrize("argv", [
    ["model", "manoeuvre", "AF", "--plot", ""],
    ["gnc", "surface", "--plot", ""],
    ["evaluate", "--mission", "pond-9.1", "--guidance", "fuzzy", "--condition", "calm", "--plot", ""],
])
def test_an_empty_plot_path_is_refused(capsys, argv):
    """--plot "" (an unset shell variable) drew nothing and said nothing, exit 0: `if args.plot` read it as absent."""
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert "--plot: empty" in captured.err and captured.out == ""
