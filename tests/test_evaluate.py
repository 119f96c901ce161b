"""Closed-loop evaluation (model + GNC, simulated time) on a short mission."""

import json
from pathlib import Path

import pytest

from autopilot.cli import main
from autopilot.evaluate import conditions, run_closed_loop
from autopilot.gnc import GncConfig
from autopilot.mission import load_mission
from autopilot.schema import load
from autopilot.sim import default_params_path, load_params

MISSIONS = Path(__file__).resolve().parent.parent / "config" / "missions"


@pytest.fixture(scope="module")
def params():
    return load_params(default_params_path())


@pytest.mark.parametrize("law", ["fuzzy", "los"])
def test_pond_9_3_calm_completes_close_without_circling(params, law):
    m = load_mission(MISSIONS / "pond-9.3.yaml")
    cfg = load(GncConfig, {"guidance": {"law": law}})
    r = run_closed_loop(params, m.waypoints_ne_m, config=cfg, env=conditions()["calm"])
    assert r.completed and not r.circled
    assert max(r.closest_approach_m) < 1.5
    assert 10.0 < r.time_s < 120.0 and r.energy_ns > 0.0


def test_current_from_the_east_still_completes(params):
    m = load_mission(MISSIONS / "pond-9.1.yaml")
    r = run_closed_loop(params, m.waypoints_ne_m, env=conditions()["current_e"])
    assert r.completed and max(r.closest_approach_m) < 2.5


def test_cli_json_fields(capsys):
    rc = main(["evaluate", "--json", "--mission", str(MISSIONS / "pond-9.2.yaml"), "--guidance", "fuzzy", "--condition", "calm"])
    assert rc == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert len(rows) == 1
    row = rows[0]
    for key in ("mission", "guidance", "condition", "completed", "closest_approach_m", "xte_rms_m", "xte_max_m", "time_s", "energy_ns"):
        assert key in row
    assert row["guidance"] == "fuzzy" and row["completed"] is True and len(row["closest_approach_m"]) == 2


def test_cli_refuses_unknown_condition(capsys):
    assert main(["evaluate", "--condition", "storm"]) == 2
    assert "storm" in capsys.readouterr().err
