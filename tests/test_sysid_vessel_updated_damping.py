"""sysid's vessel-updated.yaml when a fit lands on a bound that leaves an axis undamped (hydro_refit's linear
resistance at 0 on the shipped set, which has no quadratic term). Found by a review: the file said "Loadable by
autopilot.sim.load_params", which then refused it. Now it says it is not, and why, and a warning says so."""

from __future__ import annotations

from autopilot.sim.params import default_params_path, load_params
from autopilot.sysid.output import write_vessel_updated


def test_an_undamped_fit_is_written_saying_it_is_not_loadable(tmp_path, capsys):
    vessel = load_params(default_params_path())
    assert vessel.resistance_quadratic_n_s2_m2 == 0.0
    path = tmp_path / "vessel-updated.yaml"
    change = {"hydro_refit.resistance_linear_n_s_m": -vessel.resistance_linear_n_s_m, "hydro_refit.n_r_nd": 0.0}
    write_vessel_updated(vessel, change, ("hydro_refit",), path)  # the change that takes it to its bound, 0
    text = path.read_text()
    assert "Loadable by" not in text and "# NOT LOADABLE as it stands" in text and "nothing damps surge" in text
    assert "load_params refuses this file" in capsys.readouterr().err


def test_a_damped_fit_is_written_loadable(tmp_path):
    vessel = load_params(default_params_path())
    path = tmp_path / "vessel-updated.yaml"
    write_vessel_updated(vessel, {"hydro_refit.resistance_linear_n_s_m": 1.0, "hydro_refit.n_r_nd": 0.0},
                         ("hydro_refit",), path)
    assert "# Loadable by autopilot.sim.load_params" in path.read_text()
    assert abs(load_params(path).resistance_linear_n_s_m - (vessel.resistance_linear_n_s_m + 1.0)) < 1e-4
