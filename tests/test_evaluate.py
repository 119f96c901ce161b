"""Closed-loop evaluation (model + GNC, simulated time) on a short mission."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from autopilot.cli import main
from autopilot.evaluate import CirclingMonitor, circled, conditions, evaluate, run_closed_loop, shipped_missions
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


def test_a_shipped_mission_is_taken_by_its_name_as_run_takes_it(capsys):
    """Found by a new-user audit: `autopilot run --mission pond-9.4` flies, `autopilot evaluate --mission
    pond-9.4` said "unknown mission format '.4'"."""
    assert main(["evaluate", "--json", "--mission", "pond-9.4", "--guidance", "fuzzy", "--condition", "calm"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["mission"] for r in rows] == ["pond-9.4"] and rows[0]["completed"] is True
    assert main(["evaluate", "--mission", "pond-9.9", "--guidance", "fuzzy", "--condition", "calm"]) == 2
    assert "--mission pond-9.9: no such file, nor a shipped mission (pond-9.1" in capsys.readouterr().err


def test_cli_json_fields(capsys):
    # each option given twice (as pasted twice): the run was flown and printed twice
    rc = main(["evaluate", "--json", "--mission", str(MISSIONS / "pond-9.2.yaml"), "--guidance", "fuzzy", "--condition",
               "calm", "--guidance", "fuzzy", "--condition", "calm", "--mission", str(MISSIONS / "pond-9.2.yaml")])
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


AIM_CONDITIONS = {"calm": 1.5, "current_n": 2.5, "current_e": 2.5, "current_s": 2.5, "current_w": 2.5}


@pytest.mark.parametrize("mission", shipped_missions(), ids=lambda p: p.stem)
def test_fuzzy_aim_on_shipped_missions(params, mission):
    """Issue 3's aim with the default (fuzzy) configuration: every shipped mission completed,
    every waypoint passed within 1.5 m in calm water and 2.5 m in 0.2 m/s current, no circling."""
    for r in evaluate([mission], ["fuzzy"], list(AIM_CONDITIONS), params=params):
        assert r.completed, f"{r.mission}/{r.condition} not completed"
        assert not r.circled, f"{r.mission}/{r.condition} circled"
        assert max(r.closest_approach_m) <= AIM_CONDITIONS[r.condition], (r.condition, r.closest_approach_m)


def test_circling_flag_on_synthetic_heading_histories():
    loop = np.linspace(0.0, math.radians(400.0), 200)  # one waypoint, turned 400 deg to starboard
    assert circled([0] * 200, loop)
    assert circled([1] * 200, -loop)  # to port as well
    assert circled([0] * 200, np.angle(np.exp(1j * loop)))  # given wrapped, as a compass reports it
    assert not circled([0] * 200, loop * 0.85)  # 340 deg: not yet a circle
    assert not circled([0] * 100 + [1] * 100, loop)  # the turn is split over two targets
    weave = math.radians(170.0) * np.sin(np.linspace(0.0, 40.0 * math.pi, 2000))  # +-170 deg weave across south
    assert not circled([0] * 2000, weave + math.pi)


def test_circling_monitor_resets_on_target_change():
    m = CirclingMonitor()
    for k in range(60):
        m.update(0, math.radians(6.0 * k))  # 354 deg
    for k in range(60):
        m.update(1, math.radians(6.0 * k))  # new target: counting starts again
    assert not m.circled
    m.update(1, math.radians(360.0))
    m.update(1, math.radians(366.0))
    assert m.circled


def test_circling_flag_fires_closed_loop_with_guards_off(params):
    """A waypoint abeam inside the turning circle, file 003's law with its tolerance at 0.1 m and
    the capture radius off: the boat overshoots and loops round it. The default guards do not."""
    from autopilot.sim.sensors import SensorRates

    guards_off = {"law": "proportional", "capture_radius_m": 0.0, "proportional": {"wp_tol_m": 0.1}}
    # 10 Hz fixes (an RTK receiver): with the SC-30's 1 Hz fix the dead-reckoned position jumps and
    # happens to land within the 0.1 m tolerance
    fast_gps = SensorRates(fix_period_s=0.1, rot_period_s=0.1)
    # the speed trim's old law (the integral of the wanted speed): the boat a little faster than wanted, as this
    # geometry was found with; at exactly the wanted speed it happens to land within the tolerance on its first pass
    r = run_closed_loop(params, [(0.0, 4.0)], config=load(GncConfig, {"guidance": guards_off, "speed": {
                        "reference_time_constant_s": 0.0}}), t_max_s=90.0, sensor_rates=fast_gps)
    assert r.circled
    r = run_closed_loop(params, [(0.0, 4.0)], config=load(GncConfig, {"guidance": {"law": "fuzzy"}}), t_max_s=90.0)
    assert r.completed and not r.circled


def test_heading_integral_works_at_full_speed_in_a_beam_current(params):
    """At full speed the common thrust sits at its limit every cycle. The heading integral must still
    act (the allocation reports the turn and the common thrust apart): in a 0.3 m/s beam current with a
    steady 4 N m yaw moment (wind on the superstructure), a 600 m leg flown with the line-of-sight law.
    Measured with the per-thruster flag that froze the integral: I = 0 N, steady heading error -2.40
    deg, along-leg cross-track mean +0.12 m; now I ~ -1.35 N, -0.97 deg, -0.03 m."""
    import dataclasses

    from autopilot.sim import Environment

    base = GncConfig()
    cfg = dataclasses.replace(base, guidance=dataclasses.replace(
        base.guidance, law="los", default_speed_m_s=3.4, arrival_slowdown_m=0.0, turn_speed_floor_nd=1.0))

    def moment(t_s, state):
        zero = 0.0 * state[..., 0]
        return zero, zero, zero + 4.0

    r = run_closed_loop(params, [(600.0, 0.0)], config=cfg, env=Environment(current_speed_m_s=0.3, current_towards_deg=90.0),
                        external_force=moment, record=True)
    t = np.asarray(r.trace["t_s"])
    late = t > 60.0
    assert r.completed and r.saturation_pct > 90.0  # flown at the thrusters' limit
    i_n = np.asarray(r.trace["pid_i_n"])[late]
    he_deg = np.degrees(np.asarray(r.trace["heading_error_rad"]))[late]
    xte = np.asarray(r.trace["xte_m"])[late]
    xte = xte[np.isfinite(xte)]  # none once the leg is done
    assert i_n.mean() < -1.0  # the integral carries part of the moment (it was frozen at 0)
    assert abs(he_deg.mean()) < 1.5  # was 2.4 deg
    assert abs(xte.mean()) < 0.3 and r.xte_rms_m < 1.5


HOME_NORTH_MISSION = ("name: d\nframe: local\norigin: {lat_deg: 52, lon_deg: 4.4}\nhome: {lat_deg: 52.001, lon_deg: 4.4}\n"
                      "waypoints:\n  - {north_m: 10, east_m: 5}\n")


def test_evaluate_starts_at_the_missions_home_as_the_daemon_does(tmp_path, params):
    """A mission whose home is 111 m north of its origin: run --sim launched there, evaluate and the campaigns
    at the origin, scoring a different (shorter) mission than the daemon flies (found as a new user)."""
    path = tmp_path / "m.yaml"
    path.write_text(HOME_NORTH_MISSION)
    assert load_mission(path).home_ne_m[0] == pytest.approx(111.2, abs=0.5)
    (r,) = evaluate([path], ["fuzzy"], ["calm"], params=params, record=True)
    assert r.trace["north_m"][0] == pytest.approx(111.2, abs=0.5) and r.completed
    assert r.time_s > 40.0  # ~100 m back south, not the 11 m from the origin


def test_a_campaign_run_starts_at_the_missions_home(tmp_path):
    from autopilot.campaign.lockstep import fly
    from autopilot.campaign.spec import CampaignSpec, _load_spec, resolve

    (tmp_path / "m.yaml").write_text(HOME_NORTH_MISSION)
    c = resolve(_load_spec({"name": "home", "missions": ["m.yaml"], "laws": ["fuzzy"], "runs": 2, "seed": 1,
                            "chunk_runs": 2, "conditions": {"calm": {}}}), base_dir=tmp_path)
    assert isinstance(c.spec, CampaignSpec) and c.missions[0].home_ne_m[0] == pytest.approx(111.2, abs=0.5)
    first = {}
    fly(c, 1, [0], watch={0: lambda t_s, flight, cycle: first.setdefault("nav", cycle and cycle.nav)})
    assert first["nav"].north_m == pytest.approx(111.2, abs=0.5)
    back = type(c).from_data(json.loads(json.dumps(c.to_data())))  # what --replay reads from campaign.json
    assert back.missions[0].home_ne_m == c.missions[0].home_ne_m


def test_a_bad_mission_file_is_refused_before_any_output(tmp_path, capsys):
    """The table's header (and the good missions' rows) came out before a bad file was refused."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nwaypoints: [[1, 2], [1, 2]]\n")
    good = shipped_missions()[0]
    assert main(["evaluate", "--mission", str(good), "--mission", str(bad), "--guidance", "fuzzy", "--condition", "calm"]) == 2
    out = capsys.readouterr()
    assert out.out == "" and "waypoint 2: same position as waypoint 1" in out.err


def test_evaluate_takes_the_daemons_configuration_or_a_gnc_section(tmp_path, capsys):
    """Found by a new-user audit: `evaluate --config` refused the shipped daemon configuration ("ais: unknown key")
    and a file with a gnc: section, so a tuned gnc block could not be evaluated without copying it out."""
    from autopilot.cli import main
    from tests.conftest import REPO

    mission = str(REPO / "config" / "missions" / "pond-9.1.yaml")
    argv = ["evaluate", "--guidance", "fuzzy", "--condition", "calm", "--mission", mission, "--json", "--config"]
    assert main(argv + [str(REPO / "config" / "autopilot.yaml")]) == 0
    shipped = json.loads(capsys.readouterr().out.splitlines()[-1])
    (tmp_path / "g.yaml").write_text("gnc:\n  pid: {kp_n_per_deg: 2}\n")
    assert main(argv + [str(tmp_path / "g.yaml")]) == 0
    tuned = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert shipped["completed"] and tuned["completed"] and tuned["xte_rms_m"] != shipped["xte_rms_m"]
    (tmp_path / "bad.yaml").write_text("gnc:\n  pid: {kp_n_per_deg: 200}\n")
    assert main(argv + [str(tmp_path / "bad.yaml")]) == 2
    assert "gnc.pid.kp_n_per_deg: 200 is outside the allowed range" in capsys.readouterr().err


def test_the_table_columns_line_up_for_every_condition_and_law():
    """current_wind (12 characters) pushed its row's columns two places right of the header's."""
    from autopilot.evaluate import CONDITION_NAMES, HEADER, RunResult, format_row
    from autopilot.gnc import GUIDANCE_LAWS

    at = HEADER.index("done")
    for law in GUIDANCE_LAWS:
        for cond in CONDITION_NAMES:
            row = format_row(RunResult("pond-9.1", law, cond, True, [0.3], 0.1, 0.2, 28.0, 960.0, 6.8, False))
            assert row[at:at + 4] == "yes ", (law, cond, row)
