"""Robustness campaigns (issue 17): the same table from every backend, a killed worker costs only its chunk,
--replay reproduces a run, and a bad spec is refused naming the key."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import threading
import time
from pathlib import Path

import pytest

from autopilot.campaign.backends import run_chunks
from autopilot.campaign.draw import draw_run
from autopilot.campaign.lockstep import chunk_indices
from autopilot.campaign.results import columns, read_runs_csv, wilson, write_runs_csv
from autopilot.campaign.spec import _load_spec, resolve
from autopilot.cli import main

RUNS = 50
ROOT_SPEC = Path(__file__).resolve().parents[1] / "config" / "campaigns" / "pond-robustness.yaml"
SPEC = {
    "name": "test", "missions": ["pond-9.1", "pond-9.2"], "laws": ["fuzzy", "los"], "runs": RUNS, "seed": 5,
    "chunk_runs": 10,
    "vessel": {"fields": {"mass_kg": {"scale": [0.9, 1.1]}, "n_r_nd": {"scale": [0.7, 1.3]}}},
    "conditions": {
        "calm": {"position_noise_m": 0.3},
        "current": {"current_speed_m_s": {"uniform": [0.0, 0.3]}, "current_towards_deg": {"uniform": [0, 360]},
                    "thrust_lag_s": {"uniform": [0.0, 0.5]}, "thrust_asymmetry_nd": {"uniform": [-0.1, 0.1]}},
        "faults": {"position_noise_m": 0.3, "position_dropouts_per_min": 1.0,
                   "faults": {"kinds": ["gnss_lost", "mbed_lost", "battery_low", "thruster_failure"],
                              "at_s": {"uniform": [3.0, 20.0]}}},
    },
}


@pytest.fixture(scope="module")
def campaign():
    return resolve(_load_spec(SPEC))


def _csv(campaign, rows, path) -> bytes:
    write_runs_csv(rows, path, columns(campaign))
    return Path(path).read_bytes()


@pytest.fixture(scope="module")
def pool_table(campaign, tmp_path_factory):
    rows = run_chunks(campaign, 5, RUNS, jobs=2)
    return rows, _csv(campaign, rows, tmp_path_factory.mktemp("pool") / "runs.csv")


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=50) as c:
        yield c


def test_a_run_is_drawn_from_seed_and_index_alone(campaign):
    a, b = draw_run(campaign, 5, 37), draw_run(campaign, 5, 37)
    assert a == b
    assert draw_run(campaign, 6, 37) != a and draw_run(campaign, 5, 38) != a
    cells = {(draw_run(campaign, 5, i).mission.name, draw_run(campaign, 5, i).law, draw_run(campaign, 5, i).condition)
             for i in range(campaign.cells)}
    assert len(cells) == campaign.cells == 12  # every block of `cells` runs covers each cell once


def test_the_pool_and_a_dask_local_cluster_give_identical_tables(campaign, pool_table, cluster, tmp_path):
    rows, pool_bytes = pool_table
    assert [r["index"] for r in rows] == list(range(RUNS))
    dask_rows = run_chunks(campaign, 5, RUNS, scheduler=cluster.scheduler_address)
    assert _csv(campaign, dask_rows, tmp_path / "dask.csv") == pool_bytes
    # the faults did something: failsafes were taken and some runs failed
    assert any(r["failsafes"] for r in rows) and any(r["fault_kind"] for r in rows)


def test_a_killed_dask_worker_costs_only_its_chunk(campaign, pool_table, cluster, tmp_path):
    from distributed import Client

    _, pool_bytes = pool_table
    killed: dict = {}
    with Client(cluster.scheduler_address, set_as_default=False) as watcher:
        pids = watcher.run(os.getpid)

        def kill_a_busy_worker():
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and not killed:
                for addr, keys in watcher.processing().items():
                    busy = [k for k in keys if str(k).startswith("autopilot-campaign-")]
                    if busy and addr in pids:
                        killed.update(addr=addr, keys=busy)
                        os.kill(pids[addr], signal.SIGKILL)
                        return
                time.sleep(0.005)

        killer = threading.Thread(target=kill_a_busy_worker)
        killer.start()
        rows = run_chunks(campaign, 5, RUNS, scheduler=cluster.scheduler_address)
        killer.join()
        watcher.wait_for_workers(2, timeout=60)  # the nanny restarted it
        assert watcher.run(os.getpid).get(killed["addr"]) != pids[killed["addr"]]
    assert killed, "no worker was seen flying a chunk"
    lost = {int(re.search(r"-c(\d+)-a\d+$", str(k)).group(1)) for k in killed["keys"]}
    assert {r["index"] for r in rows} >= {i for k in lost for i in chunk_indices(campaign, RUNS, k)}
    assert _csv(campaign, rows, tmp_path / "killed.csv") == pool_bytes


def _grandchildren(pid: int) -> list[int]:
    """The live processes whose parent is a child of ``pid`` (the pool's workers, forked by the fork server)."""
    parent: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parent[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
    return [p for p, pp in parent.items() if parent.get(pp) == pid]


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="finds the pool's workers in /proc")
def test_a_killed_pool_worker_costs_only_its_chunk(campaign, pool_table, tmp_path):
    from autopilot.campaign.backends import Progress

    _, pool_bytes = pool_table
    before = set(_grandchildren(os.getpid()))
    killed, finished = [], threading.Event()

    def kill_a_worker():
        while not finished.is_set():
            workers = [p for p in _grandchildren(os.getpid()) if p not in before]
            if len(workers) >= 2:  # both workers are up and flying their first chunks
                time.sleep(0.1)
                os.kill(max(workers), signal.SIGKILL)
                killed.append(max(workers))
                return
            time.sleep(0.005)

    killer = threading.Thread(target=kill_a_worker)
    killer.start()
    progress = Progress(RUNS, 5, enabled=False)
    try:
        rows = run_chunks(campaign, 5, RUNS, jobs=2, progress=progress)
    finally:
        finished.set()
        killer.join()
    assert killed and progress.retries >= 1
    assert _csv(campaign, rows, tmp_path / "killed.csv") == pool_bytes


def test_replay_reproduces_a_runs_scorecard_and_review_reads_its_log(tmp_path, capsys):
    from autopilot.review.metrics import score
    from autopilot.review.reader import read_log

    spec = tmp_path / "spec.yaml"
    spec.write_text(json.dumps({**SPEC, "runs": 24, "chunk_runs": 12}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["campaign", str(spec), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    assert {p.name for p in out.iterdir()} >= {"campaign.json", "runs.csv", "summary.json", "report.html"}
    table = read_runs_csv(out / "runs.csv")
    # the second chunk; a LOS run if one took a failsafe (the spec's own law is fuzzy)
    faulty = min((r for r in table if r["failsafes"] > 0 and r["index"] >= 12), key=lambda r: r["law"] != "los")
    capsys.readouterr()
    assert main(["campaign", "--replay", str(out), str(faulty["index"])]) == 0
    assert "identical to its row in runs.csv" in capsys.readouterr().out
    log = read_log(out / f"replay-{faulty['index']}.jsonl")
    assert log.stats.skipped == 0 and log.n_cycles == faulty["cycles"]
    # the configuration in the log is the one flown: the run's law (it was the spec's, "fuzzy", beside "los")
    start = log.events[0]
    assert start["config"]["gnc"]["guidance"]["law"] == start["guidance"] == faulty["law"]
    names = [e["event"] for e in log.events]
    assert names[0] == "mission_start" and names[-1] == "stop" and "failsafe" in names and "fault" in names
    card = score(log)
    # the review recomputes the passes from the logged fixes; a waypoint never passed is inf in the table, nan there
    ours = [float(x) if math.isfinite(float(x)) else None for x in faulty["closest_approach_m"].split(";")]
    review = [w.closest_approach_m if math.isfinite(w.closest_approach_m) else None for w in card.waypoints]
    assert review == pytest.approx(ours, abs=1e-6)


@pytest.mark.parametrize("change, named", [
    ({"bogus_key": 1}, ["bogus_key", "unknown key"]),
    ({"conditions": {"c": {"curent_speed_m_s": {"uniform": [0, 0.2]}}}}, ["conditions.c.curent_speed_m_s", "unknown"]),
    ({"vessel": {"fields": {"mass_kgs": {"scale": [0.9, 1.1]}}}}, ["vessel.fields.mass_kgs", "unknown VesselParams"]),
    ({"vessel": {"fields": {"mass_kg": {"uniform": [0.0, 300.0]}}}}, ["vessel.fields.mass_kg", "[1, 10000] kg"]),
    ({"vessel": {"fields": {"n_r_nd": {"scale": [-1.0, 1.0]}}}}, ["vessel.fields.n_r_nd", "[-50, 0]"]),
    ({"conditions": {"c": {"current_speed_m_s": {"uniform": [0.0, 9.0]}}}}, ["conditions.c.current_speed_m_s",
                                                                             "[0, 5] m/s"]),
    ({"conditions": {"c": {"thrust_lag_s": {"normal": [0.5, 5.0]}}}}, ["conditions.c.thrust_lag_s", "[0, 10] s"]),
    ({"conditions": {"c": {"faults": {"kinds": ["meteor"]}}}}, ["conditions.c.faults.kinds[0]", "meteor"]),
    ({"laws": ["fuzzy", "pure_pursuit"]}, ["laws[1]", "pure_pursuit"]),
    ({"missions": ["pond-9.9"]}, ["missions[0]", "pond-9.9"]),
    # found by a new-user audit: accepted, and the tables misled
    ({"laws": ["fuzzy", "fuzzy"]}, ["laws[1]: fuzzy is given twice"]),
    ({"missions": ["pond-9.1", "pond-9.1"]}, ["missions[1]: pond-9.1 is named pond-9.1, as missions[0]"]),
    ({"conditions": {"all": {}}}, ["conditions.all: 'all' names the results' column"]),
    ({"conditions": {"c": {"position_noise_m": {"scale": [0.5, 2.0]}}}}, ["conditions.c.position_noise_m.scale",
                                                                          "no nominal value to scale"]),
    ({"conditions": {"c": {"faults": {"kinds": ["gnss_lost"], "at_s": {"scale": [1, 2]}}}}},
     ["conditions.c.faults.at_s.scale"]),
    ({"seed": -1}, ["seed: -1 is outside the allowed range [0, 9223372036854775807]\n"]),  # was [0, 9.22337e+18] -
    # found by an audit: a blank name titled the report "Robustness campaign "; an empty kinds list was named
    # without its place ("kinds: give at least one fault kind")
    ({"name": " "}, ["name: give the campaign a name"]),
    ({"conditions": {"c": {"faults": {"kinds": []}}}}, ["conditions.c.faults.kinds: give at least one fault kind"]),
    # found by a new-user audit: flown, every run the max_distance failsafe's, a mission the daemon refuses at start
    ({"failsafe": {"max_distance_m": 10}}, ["missions[0]: pond-9.1: waypoint 1 is beyond the max_distance failsafe: "
                                            "26.7 m from the origin (limit 10 m) (the daemon refuses"]),
    # found by a new-user audit: a file that is not there was named without the key that gave it
    ({"vessel": {"sysid": "nothere/summary.json"}}, ["vessel.sysid: ", "nothere/summary.json: cannot read"]),
    ({"vessel": {"file": "nope.yaml"}}, ["vessel.file: ", "nope.yaml: cannot read"]),
])
def test_a_bad_spec_is_refused_naming_the_key_and_range(tmp_path, capsys, change, named):
    spec = tmp_path / "bad.yaml"
    spec.write_text(json.dumps({**SPEC, **change}), encoding="utf-8")
    assert main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(spec) in err
    for text in named:
        assert text in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name, said", [("1", "YAML reads this name as the number 1; quote it (\"1\":)"),
                                        ("on", "YAML reads this name as True (yes, no, on, off, true, false); quote")])
def test_a_condition_name_yaml_reads_as_no_text_is_said_so(tmp_path, capsys, name, said):
    """Found by a new-user audit: `1:` was refused as not 'letters, digits, ...', which it is."""
    spec = tmp_path / "bad.yaml"
    spec.write_text(f"missions: [pond-9.1]\nconditions:\n  {name}: {{}}\n", encoding="utf-8")
    assert main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err, err


def test_a_campaign_of_the_distance_failsafe_says_so_and_is_flown_as_the_daemon_would():
    """failsafe.allow_beyond_limits lets a spec fly missions beyond max_distance_m, as it lets the daemon."""
    from autopilot.schema import ConfigError

    limited = {"max_distance_m": 10.0}
    with pytest.raises(ConfigError, match=r"missions\[0\]: pond-9.1: waypoint 1 is beyond the max_distance"):
        resolve(_load_spec({**SPEC, "failsafe": limited}))
    c = resolve(_load_spec({**SPEC, "failsafe": {**limited, "allow_beyond_limits": True}}))
    assert c.spec.failsafe.max_distance_m == 10.0 and [m.name for m in c.missions] == ["pond-9.1", "pond-9.2"]


def test_a_nan_spread_is_refused_without_a_made_up_range(tmp_path, capsys):
    """A spread's own numbers have no range (the quantity's is checked after): the message said
    'allowed range [-inf, inf] -', a range that is not one."""
    spec = tmp_path / "bad.yaml"
    spec.write_text(json.dumps({k: v for k, v in SPEC.items() if k != "conditions"})[:-1]
                    + ', "conditions": {"c": {"wind_speed_m_s": {"uniform": [.nan, 3]}}}}', encoding="utf-8")
    assert main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.endswith("conditions.c.wind_speed_m_s.uniform[0]: nan is not a finite number\n"), err


def test_sysid_intervals_become_spreads_and_are_range_checked(tmp_path):
    summary = {"effects": {
        "hydro_refit": {"params": [{"name": "resistance_linear_n_s_m", "value": 13.0, "ci95": [12.0, 14.0]},
                                   {"name": "n_r_nd", "value": -0.1, "ci95": [-0.15, -0.05]}]},
        "thrust_asymmetry": {"params": [{"name": "asymmetry_nd", "value": 0.03, "ci95": [0.01, 0.05]}]},
        "heading_bias": {"params": [{"name": "bias_deg", "value": 1.0, "ci95": [0.5, 1.5]}]},
    }}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    c = resolve(_load_spec({**SPEC, "vessel": {"sysid": "summary.json"}}), base_dir=tmp_path)
    spreads = dict(c.vessel_spreads)
    assert spreads["resistance_linear_n_s_m"].uniform == (12.0, 14.0) and spreads["n_r_nd"].uniform == (-0.15, -0.05)
    assert dict(c.sysid_thrust)["thrust_asymmetry_nd"].uniform == (0.01, 0.05)
    assert any("heading_bias.bias_deg" in s for s in c.sources)
    run = draw_run(c, 5, 3)
    assert 12.0 <= run.params.resistance_linear_n_s_m <= 14.0 and 0.01 <= run.thrust_asymmetry_nd <= 0.05
    summary["effects"]["hydro_refit"]["params"][1]["ci95"] = [-0.15, 0.02]  # N'_r must stay <= 0
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(Exception, match=r"hydro_refit\.n_r_nd.*\[-50, 0\]"):
        resolve(_load_spec({**SPEC, "vessel": {"sysid": "summary.json"}}), base_dir=tmp_path)
    from autopilot.schema import ConfigError

    # found by a new-user audit: params null was an internal error; a summary with nothing to spread (verdict none,
    # or a renamed key) flew the nominal vessel with only a line in summary.json; a ci95 of booleans was taken
    for bad, words in ((
            {"effects": {"hydro_refit": {"params": None}}}, "effects.hydro_refit.params is not a list"), (
            {"effects": {}}, "no identified parameter to spread"), (
            {"effects": {"heading_bias": {"params": [{"name": "bias_deg", "ci95": [0.5, 1.5]}]}}},
            "no identified parameter to spread (verdict none, or no effect the campaign's plant has: heading_bias.bias"), (
            {"effects": {"thrust_asymmetry": {"params": [{"name": "asymmetry_nd", "ci95": [True, 0.05]}]}}},
            "ci95 is not a finite [lo, hi]")):
        (tmp_path / "summary.json").write_text(json.dumps(bad))
        with pytest.raises(ConfigError, match=re.escape(words)):
            resolve(_load_spec({**SPEC, "vessel": {"sysid": "summary.json"}}), base_dir=tmp_path)


def test_a_weak_motor_sysid_named_is_spread_and_flown(tmp_path):
    """A boat whose identification named `weak_motor` (one motor short of the thrust table, added 2026-12-06): its
    interval is spread as weak_motor_loss_nd (the derived gain row not said as "not spread"), and the campaign's
    plant flies it, batched and on the scalar path alike: the same commands on both sides turn the boat towards
    the weak side, a starboard motor short as much the other way."""
    import dataclasses

    from autopilot.campaign.lockstep import _Batch, _Singles

    summary = {"effects": {"weak_motor": {"params": [
        {"name": "loss_nd", "value": 0.06, "ci95": [0.05, 0.07]},
        {"name": "port_gain_nd", "value": 0.94, "ci95": [0.93, 0.95]}]}}}
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    c = resolve(_load_spec({**SPEC, "vessel": {"sysid": "summary.json"}}), base_dir=tmp_path)
    assert dict(c.sysid_thrust)["weak_motor_loss_nd"].uniform == (0.05, 0.07)
    assert not any("port_gain_nd" in s for s in c.sources)
    run = draw_run(c, 5, 3)
    assert 0.05 <= run.weak_motor_loss_nd <= 0.07 and ("weak_motor_loss_nd", run.weak_motor_loss_nd) in run.drawn
    setups = [dataclasses.replace(run, weak_motor_loss_nd=w) for w in (0.3, 0.0, -0.3)]
    home = [*run.mission.home_ne_m, 0.0, 0.0, 0.0, 0.0]
    for plant in (_Batch(setups, [0, 1, 2]), _Singles(setups, [0, 1, 2], [home] * 3, [(0.0, 0.0)] * 3)):
        t_s = 0.0
        for _ in range(50):  # 5 s of 20 N a side
            t_s = plant.move(t_s, [20.0] * 3, [20.0] * 3, 2)
        r = [float(x[5]) for x in plant.states()]
        assert r[0] < -0.01 and abs(r[1]) < 1e-12 and r[2] > 0.01 and r[0] == pytest.approx(-r[2], rel=1e-6), r


def test_sysid_changes_are_added_to_the_vessel_they_were_identified_on_and_another_boat_is_refused(tmp_path):
    """Found by a new-user audit: yaw_damping_quadratic's N_rr (a change from the summary's params_file) was added to
    the campaign's vessel, so a campaign of sysid's own vessel-updated.yaml, where it is written in already, drew the
    damping twice (70 N m s^2 for 40 identified); a summary of another boat was spread onto this one unsaid."""
    import dataclasses

    import yaml

    from autopilot.schema import ConfigError, to_dict
    from autopilot.sim import default_params_path, load_params

    base = load_params(default_params_path())
    updated = dataclasses.replace(base, yaw_damping_quadratic_nm_s2=base.yaw_damping_quadratic_nm_s2 + 30.0)
    (tmp_path / "vessel-updated.yaml").write_text(yaml.safe_dump(to_dict(updated)), encoding="utf-8")
    (tmp_path / "summary.json").write_text(json.dumps({"params_file": str(default_params_path()), "effects": {
        "yaw_damping_quadratic": {"params": [{"name": "n_rr_nm_s2", "value": 30.0, "ci95": [29.0, 31.0]}]}}}))
    for vessel_file in ("", "vessel-updated.yaml"):
        c = resolve(_load_spec({**SPEC, "vessel": {"file": vessel_file, "sysid": "summary.json"}}), base_dir=tmp_path)
        n_rr = base.yaw_damping_quadratic_nm_s2
        assert dict(c.vessel_spreads)["yaw_damping_quadratic_nm_s2"].uniform == (n_rr + 29.0, n_rr + 31.0)
    thesis = default_params_path().with_name("vessel-thesis.yaml")
    with pytest.raises(ConfigError, match=r"identified on another vessel, .*vessel\.yaml \(params_file\): it differs "
                                          r"from the campaign.s in resistance_linear_n_s_m, y_v_nd"):
        resolve(_load_spec({**SPEC, "vessel": {"file": str(thesis), "sysid": "summary.json"}}), base_dir=tmp_path)
    # sysid keeps params_file as it was given: relative to the spec's directory, it is found there too; nowhere,
    # the change is not added to the campaign's vessel (counted twice again for vessel-updated.yaml): refused
    (tmp_path / "vessel.yaml").write_text(default_params_path().read_text())
    (tmp_path / "sid").mkdir()
    for params_file, found in (("vessel.yaml", True), ("gone/vessel.yaml", False)):
        (tmp_path / "sid" / "summary.json").write_text(json.dumps({"params_file": params_file, "effects": {
            "yaw_damping_quadratic": {"params": [{"name": "n_rr_nm_s2", "value": 30.0, "ci95": [29.0, 31.0]}]}}}))
        spec = _load_spec({**SPEC, "vessel": {"file": "vessel-updated.yaml", "sysid": "sid/summary.json"}})
        if found:
            c = resolve(spec, base_dir=tmp_path)
            assert dict(c.vessel_spreads)["yaw_damping_quadratic_nm_s2"].uniform == (n_rr + 29.0, n_rr + 31.0)
        else:
            with pytest.raises(ConfigError, match=r"params_file gone/vessel\.yaml, the vessel the yaw damping's "
                                                  r"change was identified from, is not found"):
                resolve(spec, base_dir=tmp_path)


@pytest.mark.slow
def test_a_campaign_spreads_what_autopilot_sysid_wrote(tmp_path):
    """The test above writes summary.json by hand, so it shares the reader's idea of the file. Here the file is
    the real one: a pond-like trial (1 Hz held fixes, wandering GPS error) of a boat whose linear resistance is
    6 N s/m above the calibrated set, identified by `autopilot sysid`; the campaign must fly each run inside
    the identified interval (hydro_refit reports the new value, not the change). The other parameters the
    reader takes must be ones sysid has, under those names."""
    import dataclasses

    import numpy as np

    from autopilot.sim import default_params_path, load_params
    from autopilot.sysid.effects import EFFECTS
    from autopilot.sysid.realistic import Measurement, draw_models, measure, write_columns_csv
    from autopilot.sysid.truth import simulate_truth

    names = {e.name: {p.name for p in e.params} for e in EFFECTS}
    assert {"asymmetry_nd"} <= names["thrust_asymmetry"] and {"time_constant_s"} <= names["thrust_lag"]
    assert {"n_rr_nm_s2"} <= names["yaw_damping_quadratic"]
    vessel = load_params(default_params_path())
    assert names["hydro_refit"] <= {f.name for f in dataclasses.fields(vessel)}
    rng = np.random.default_rng(5)
    gps, heading = draw_models(rng)
    trial = tmp_path / "trial.csv"
    write_columns_csv(measure(simulate_truth(vessel, {"hydro_refit.resistance_linear_n_s_m": 6.0}, rng, duration_s=60.0),
                              Measurement(gps=gps, heading=heading, cells="held"), rng), trial)
    assert main(["sysid", str(trial), "--effects", "hydro_refit", "--out", str(tmp_path / "sid"), "--quiet"]) == 0
    identified = {f"{e}.{p['name']}": p["ci95"]
                  for e, body in json.loads((tmp_path / "sid" / "summary.json").read_text())["effects"].items()
                  for p in body["params"]}
    r1_lo, r1_hi = identified["hydro_refit.resistance_linear_n_s_m"]
    assert r1_lo < vessel.resistance_linear_n_s_m + 6.0 < r1_hi  # the identification itself worked

    spec = tmp_path / "spec.yaml"
    spec.write_text(json.dumps({**SPEC, "missions": ["pond-9.1"], "runs": 12, "chunk_runs": 12,
                                "vessel": {"sysid": "sid/summary.json"},
                                "conditions": {"calm": {"position_noise_m": 0.3}}}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["campaign", str(spec), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    table = read_runs_csv(out / "runs.csv")
    assert len(table) == 12
    for row in table:
        assert r1_lo <= row["vessel.resistance_linear_n_s_m"] <= r1_hi, row
    assert len({row["vessel.resistance_linear_n_s_m"] for row in table}) == 12  # drawn, not one value


@pytest.mark.parametrize("k, n, lo, hi", [(0, 10, 0.0, 0.2775), (5, 10, 0.2366, 0.7634), (10, 10, 0.7225, 1.0),
                                          (95, 100, 0.8882, 0.9785)])
def test_wilson_interval(k, n, lo, hi):
    a, b = wilson(k, n)
    assert a == pytest.approx(lo, abs=5e-5) and b == pytest.approx(hi, abs=5e-5)
    assert math.isnan(wilson(0, 0)[0])


def test_every_wilson_interval_contains_its_rate_and_ends_exactly_at_0_and_1():
    """Found by a new-user audit: wilson(10, 10) ended at 0.9999999999999999, an interval that did not contain its
    own rate of 1 (969 of the 3998 cases k = 0 or k = n below n = 2000)."""
    for n in range(1, 2000):
        for k in range(n + 1):
            lo, hi = wilson(k, n)
            assert 0.0 <= lo <= k / n <= hi <= 1.0, (k, n, lo, hi)
    assert wilson(10, 10)[1] == 1.0 and wilson(0, 3)[0] == 0.0


def test_the_sensitivity_ranking_says_what_chance_reaches_at_its_runs():
    """Found by a new-user audit: 60 runs ranked the wind's direction first (circular 0.61) above thrust asymmetry
    (-0.59), and the report gave no way to tell that both were what quantities that move nothing reach at 12 runs."""
    import numpy as np

    from autopilot.campaign.results import sensitivity

    rng = np.random.default_rng(4)
    rows = [{"condition": f"c{i % 2}", "success": bool(rng.random() < 0.8), "closest_max_m": float(rng.random()),
             "xte_rms_m": float(rng.random()), "x": float(rng.random()), "wind_from_deg": float(rng.uniform(0, 360))}
            for i in range(50)]
    chance = {e["input"]: e["rho_chance_95"] for e in sensitivity(rows, ["x", "wind_from_deg"])}
    assert chance["x"] == pytest.approx(1.959964 / math.sqrt(48), rel=1e-6)
    assert chance["wind_from_deg"] == pytest.approx(math.sqrt(5.991465 / 48), rel=1e-6)


def test_a_direction_that_hurts_across_north_is_found_on_the_circle_not_the_line():
    """Found by a new-user audit: the wind's direction went through Spearman's rho on 0..360, where a wind that
    fails the mission from the north (350..10 deg) is at both ends and correlates with nothing."""
    import numpy as np

    from autopilot.campaign.results import sensitivity

    rng = np.random.default_rng(3)
    rows = []
    for i in range(600):
        wind_from = float(rng.uniform(0.0, 360.0))
        gusty = float(rng.uniform(0.0, 1.0))  # a linear quantity with no effect
        off_north = abs((wind_from + 180.0) % 360.0 - 180.0)
        fails = off_north < 40.0 or rng.uniform() < 0.05
        rows.append({"condition": "weather" if i % 2 else "wind", "success": not fails,
                     "closest_max_m": (4.0 if fails else 1.0) + float(rng.uniform(0, 0.5)), "xte_rms_m": 1.0,
                     "wind_from_deg": wind_from, "gust_nd": gusty})
    by_input = {s["input"]: s for s in sensitivity(rows, ["wind_from_deg", "gust_nd"])}
    wind = by_input["wind_from_deg"]
    assert wind["circular"] and wind["rho_success"] > 0.4 and wind["rho_closest_max"] > 0.4
    assert min(wind["worst_direction"], 360.0 - wind["worst_direction"]) < 15.0
    assert wind["success_low_quartile"] < 0.6 and wind["success_high_quartile"] > 0.9
    assert abs(by_input["gust_nd"]["rho_success"]) < 0.15
    assert list(by_input) == ["wind_from_deg", "gust_nd"]  # strongest first
    # the line would have missed it: the same rows, the direction taken as a plain number
    line = sensitivity([{**r, "wind_linear": r["wind_from_deg"]} for r in rows], ["wind_linear"])[0]
    assert abs(line["rho_success"]) < 0.15


def test_geo_float_path_gives_the_array_paths_bits():
    """The per-cycle conversions take plain floats without numpy: the same operations, the same bits."""
    import numpy as np

    from autopilot import geo

    rng = np.random.default_rng(3)
    for _ in range(2000):
        olat, olon = rng.uniform(-80, 80), rng.uniform(-180, 180)
        lat, lon = olat + rng.uniform(-0.05, 0.05), (olon + rng.uniform(-0.05, 0.05) + 180.0) % 360.0 - 180.0
        n, e = geo.latlon_to_local(float(lat), float(lon), float(olat), float(olon))
        na, ea = geo.latlon_to_local(np.array([lat]), np.array([lon]), float(olat), float(olon))
        assert (n, e) == (na[0], ea[0])
        la, lo = geo.local_to_latlon(float(n), float(e), float(olat), float(olon))
        laa, loa = geo.local_to_latlon(np.array([n]), np.array([e]), float(olat), float(olon))
        assert (la, lo) == (laa[0], loa[0])


def test_the_campaigns_control_cycle_is_the_daemons(tmp_path):
    """The daemon's loop (SimClock, test doubles, a heading lost at 6 s) and closed_loop.ControlCycle fed the
    same samples at the same times: the same modes, faults, failsafes and thrusts."""
    from autopilot.closed_loop import ControlCycle, LinkState
    from autopilot.daemon.config import DaemonConfig
    from autopilot.daemon.cycle import nav_rules
    from autopilot.daemon.failsafe import Failsafe
    from autopilot.gnc import Autopilot
    from tests.test_daemon_cycle import ORIGIN, FakeCompass, _run_loop

    cmds, st = _run_loop(tmp_path, quiet_from_s=6.0, until_s=10.0)
    lines = [json.loads(x) for x in (tmp_path / "log.jsonl").read_text().splitlines()]
    logged = [x for x in lines if x["event"] == "cycle"]
    cfg = DaemonConfig()
    cc = ControlCycle(Autopilot(cfg.gnc, [(200.0, 0.0)]), period_s=cfg.period_s, origin_lat_deg=ORIGIN[0],
                      origin_lon_deg=ORIGIN[1], rules=nav_rules(cfg), failsafe=Failsafe(cfg.failsafe))

    class At:  # the compass double reads the time from its clock
        t = 0.0

        def now_s(self):
            return self.t

    clock = At()
    compass = FakeCompass(clock)
    compass.quiet_from_s = 6.0
    assert len(logged) == len(cmds) == 100
    for rec, cmd in zip(logged, cmds):
        clock.t = rec["t_s"]
        c = cc.step(compass.sample(), rec["t_s"], link=LinkState(battery_v=12.6))
        assert c.mode.value == rec["mode"] and list(c.active_faults) == rec["active_faults"]
        assert c.cmd.thrust_port_n == pytest.approx(cmd.thrust_port_n, abs=1e-9)
        assert c.cmd.thrust_stbd_n == pytest.approx(cmd.thrust_stbd_n, abs=1e-9)
    assert cc.failsafe_causes == st.failsafe_causes == ["heading_stale"]


@pytest.mark.parametrize("backend", [["--jobs", "2"], ["--scheduler", "local"]], ids=["pool", "local-cluster"])
def test_ctrl_c_stops_a_campaign_at_once_quietly_its_workers_gone(tmp_path, backend):
    """With --jobs 2 a Ctrl-C waited for the pool to fly every chunk already queued (38-110 s for 480-1200 runs)
    and only then said interrupted. 4000 runs are minutes of work: it must stop within seconds, its workers gone.
    On a local Dask cluster each worker process took the terminal's Ctrl-C too and printed a KeyboardInterrupt
    traceback (and Dask a warning per cancelled chunk) above the campaign's own word."""
    import subprocess
    import sys

    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "campaign", str(ROOT_SPEC), "--runs", "4000", *backend,
                          "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: (signal.signal(signal.SIGINT, signal.SIG_DFL), os.setpgrp()))
    try:
        deadline = time.monotonic() + 60
        while not (out / "campaign.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(4.0)  # the workers are flying
        os.killpg(p.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole foreground group
        _, err = p.communicate(timeout=45)
        deadline = time.monotonic() + 10
        while _live_in_group(p.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = _live_in_group(p.pid)
    finally:
        if p.poll() is None or _live_in_group(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    # the progress lines of chunks done before the Ctrl-C (a fast machine finishes one in the 4 s), then the word
    lines = err.strip().splitlines()
    assert p.returncode == 130 and lines[-1] == "autopilot campaign: interrupted", err[-3000:]
    assert all(re.fullmatch(r"campaign: \d+/\d+ chunks, .*", ln) for ln in lines[:-1]), err[-3000:]
    assert not left, f"worker processes outlived the campaign: {left}"
    assert not (out / "runs.csv").exists()


def test_a_local_cluster_says_nothing_of_its_own_when_another_dask_holds_the_port(tmp_path):
    """--scheduler local started the scheduler's HTTP routes on 8787: with another Dask (or a second campaign)
    on the machine, every campaign began with a 'Port 8787 is already in use' warning from inside Dask."""
    import socket
    import subprocess
    import sys

    with socket.socket() as other:
        try:
            other.bind(("127.0.0.1", 8787))
            other.listen()
        except OSError:
            pass  # someone holds it already: the same condition
        p = subprocess.run([sys.executable, "-m", "autopilot", "campaign", str(ROOT_SPEC), "--runs", "24",
                            "--scheduler", "local", "--out", str(tmp_path / "out"), "--quiet"],
                           capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and p.stderr == "", p.stderr[-2000:]
    assert len(read_runs_csv(tmp_path / "out" / "runs.csv")) == 24


def test_runs_on_the_command_line_read_as_the_spec_reads_them(tmp_path, capsys):
    """`runs: 2.4e1` in a spec is 24 runs (YAML 1.2); `--runs 2.4e1` was refused as 'invalid int value'."""
    assert main(["campaign", str(ROOT_SPEC), "--runs", "2.4e1", "--jobs", "1", "--out", str(tmp_path / "a"),
                 "--quiet", "--no-report"]) == 0
    assert len(read_runs_csv(tmp_path / "a" / "runs.csv")) == 24
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["campaign", str(ROOT_SPEC), "--runs", "2.5", "--out", str(tmp_path / "b")])
    assert exc.value.code == 2 and "argument --runs: '2.5' is not a whole number" in capsys.readouterr().err


def _live_in_group(pgid: int) -> list[int]:
    """Processes of process group ``pgid`` that are not zombies (a container's init may not reap them)."""
    live = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if int(fields[2]) == pgid and fields[0] != "Z":
            live.append(int(d.name))
    return live


def test_sigterm_to_the_campaign_alone_stops_its_workers_too(tmp_path):
    """Found by a new-user audit: `kill PID` (SIGTERM to the main process only, as a service manager may send it)
    left the pool's workers, the forkserver and the resource tracker flying for a minute, orphaned."""
    import subprocess
    import sys

    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "campaign", str(ROOT_SPEC), "--runs", "4000", "--jobs", "2",
                          "--out", str(out), "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=os.setpgrp)
    try:
        deadline = time.monotonic() + 60
        while not (out / "campaign.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(3.0)  # the pool's workers are flying
        assert len(_live_in_group(p.pid)) >= 3  # this process, the forkserver, workers
        os.kill(p.pid, signal.SIGTERM)
        _, err = p.communicate(timeout=45)
        deadline = time.monotonic() + 10
        while _live_in_group(p.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = _live_in_group(p.pid)
    finally:
        if p.poll() is None or _live_in_group(p.pid):
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 128 + signal.SIGTERM and "Traceback" not in err, err[-2000:]
    assert left == []
    assert not (out / "runs.csv").exists()


def test_an_earlier_campaigns_directory_is_refused_or_replaced_whole_and_command_line_limits_hold(tmp_path, capsys):
    """Found by a new-user audit: a new campaign into a directory holding an old one rewrote campaign.json beside
    the old summary.json and report.html (complete-looking, of other runs) and --replay then compared with the
    old runs.csv; --replay ignored --out; --runs on the command line skipped the spec's limit; --jobs 1000
    started 40 processes on 2 cores and the report said 'a pool of 1000'."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(json.dumps({**SPEC, "runs": 12, "chunk_runs": 12}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["campaign", str(spec), "--out", str(out), "--jobs", "1", "--quiet", "--no-report"]) == 0
    assert main(["campaign", "--replay", str(out), "3"]) == 0
    assert main(["campaign", "--replay", str(out), "3", "--out", str(tmp_path / "x")]) == 2
    assert "--out is for a new campaign" in capsys.readouterr().err
    (out / "mine.txt").write_text("the user's own file")
    before = (out / "runs.csv").read_bytes()
    assert main(["campaign", str(spec), "--out", str(out), "--seed", "9", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds a campaign's results already (campaign.json, runs.csv, summary.json, replay-3.jsonl)" in err
    assert "--overwrite" in err and (out / "runs.csv").read_bytes() == before
    assert main(["campaign", str(spec), "--out", str(out), "--seed", "9", "--quiet", "--overwrite", "--no-report",
                 "--jobs", "1000"]) == 0
    err = capsys.readouterr().err
    assert "--jobs 1000: this machine gives this process" in err
    assert not (out / "replay-3.jsonl").exists() and (out / "mine.txt").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["seed"] == 9 and "1000" not in summary["run"]["backend"]
    assert main(["campaign", str(spec), "--out", str(tmp_path / "big"), "--runs", "20000000"]) == 2
    assert "--runs: 20000000 is outside [1, 10,000,000] runs" in capsys.readouterr().err
    # fewer runs than cells (2 missions x 2 laws x 3 conditions): said, not left for the reader to find
    assert main(["campaign", str(spec), "--out", str(tmp_path / "few"), "--runs", "5", "--jobs", "1", "--quiet"]) == 0
    assert "note: 7 of 12 cells (mission x law x condition) not flown with 5 runs" in capsys.readouterr().out
    summary = json.loads((tmp_path / "few" / "summary.json").read_text())
    assert summary["cells"] == 12 and len(summary["cells_not_flown"]) == 7
    report = (tmp_path / "few" / "report.html").read_text()
    assert "7 of 12 cells (mission x law x condition) were not flown" in report
    assert "&quot;seed&quot;: 5,\n &quot;runs&quot;: 5\n}" in report  # the campaign.json shown is the one flown


def test_a_fault_due_after_the_run_ended_is_not_counted_for_that_fault(tmp_path):
    """Found by a new-user audit: by_fault counted every run drawn with a fault, also those that ended before it
    was due (11 of 60 in a 400-run campaign); faults at 5000 s reported gnss_lost at 100 % with no failsafe."""
    spec = tmp_path / "spec.yaml"
    conditions = {"late": {"faults": {"kinds": ["gnss_lost"], "at_s": {"uniform": [4000.0, 5000.0]}}},
                  # after control starts (the boat waits for valid data first) and long enough to be noticed
                  # (position_stale_s, 3 s: a shorter loss is not reached either)
                  "soon": {"faults": {"kinds": ["gnss_lost"], "at_s": {"uniform": [15.0, 18.0]},
                                      "duration_s": {"uniform": [3.5, 6.0]}}}}
    spec.write_text(json.dumps({**SPEC, "runs": 16, "chunk_runs": 16, "conditions": conditions}), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["campaign", str(spec), "--out", str(out), "--jobs", "1", "--quiet", "--no-report"]) == 0
    rows = read_runs_csv(out / "runs.csv")
    assert {r["fault_kind"] for r in rows if r["condition"] == "late"} == {"not reached"}
    assert {r["fault_kind"] for r in rows if r["condition"] == "soon"} == {"gnss_lost"}
    by_fault = json.loads((out / "summary.json").read_text())["by_fault"]
    assert by_fault["gnss_lost"]["runs"] == 8 and by_fault["not reached"]["runs"] == 8


def test_a_fault_too_near_the_end_for_the_failsafe_to_notice_is_not_counted_for_it():
    """Found by a campaign audit (left in stop 40's note): a battery_low due 0.5 s before a run completed counted
    as a success under battery_low (100 %), though the failsafe needs battery_low_s (10 s) below the threshold
    to notice it; a lost GNSS is noticed when the last fix is position_stale_s old."""
    from autopilot.campaign.draw import Fault
    from autopilot.campaign.results import _fault_kind
    from autopilot.daemon.config import FailsafeConfig

    fs = FailsafeConfig()
    battery = Fault("battery_low", at_s=40.0, duration_s=0.0, battery_rest_v=11.0)
    assert _fault_kind([battery], 40.5, fs) == "not reached"
    assert _fault_kind([battery], 40.0 + fs.battery_low_s - 0.1, fs) == "not reached"
    assert _fault_kind([battery], 40.0 + fs.battery_low_s + 0.1, fs) == "battery_low"
    gnss = Fault("gnss_lost", at_s=40.0, duration_s=5.0)
    assert _fault_kind([gnss], 42.0, fs) == "not reached"
    assert _fault_kind([gnss], 44.0, fs) == "gnss_lost"
    assert _fault_kind([Fault("mbed_lost", at_s=40.0, duration_s=2.0)], 40.2, fs) == "mbed_lost"  # at once
    # over before the failsafe could notice it (noticed beside dfa05b3's fix): a GNSS loss shorter than position_stale_s
    short = Fault("gnss_lost", at_s=40.0, duration_s=fs.position_stale_s - 0.5)
    assert _fault_kind([short], 80.0, fs) == "not reached"
    assert _fault_kind([Fault("gnss_lost", at_s=40.0, duration_s=fs.position_stale_s)], 80.0, fs) == "gnss_lost"
    assert _fault_kind([], 40.0, fs) == ""


def test_a_scheduler_address_that_is_not_one_is_refused_at_once_and_a_silent_port_in_time(tmp_path):
    """Found by a new-user audit: 'nonsense', 'http://x' or an SSH port as --scheduler gave 'internal error:
    MemoryError: Unable to allocate 2.82 EiB', a 40 s wait and a traceback; a port that accepted and stayed
    silent hung the campaign with no output for as long as one waited."""
    import socket
    import subprocess
    import sys
    import threading

    from autopilot.campaign.backends import check_scheduler_address, probe_scheduler
    from autopilot.schema import ConfigError

    assert check_scheduler_address("127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    for bad in ("nonsense", "http://x", "tcp://host:99999"):
        with pytest.raises(ConfigError, match="not a Dask scheduler address"):
            check_scheduler_address(bad)

    def listener(banner: bytes | None):
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        s.listen(4)
        held = []

        def run():
            while True:
                try:
                    c, _ = s.accept()
                except OSError:
                    return
                held.append(c)
                if banner:
                    c.sendall(banner)
        threading.Thread(target=run, daemon=True).start()
        return s, held

    ssh, held_a = listener(b"SSH-2.0-OpenSSH_9.6\r\n")
    silent, held_b = listener(None)
    try:
        with pytest.raises(ConfigError, match="does not speak Dask's protocol"):
            probe_scheduler(f"tcp://127.0.0.1:{ssh.getsockname()[1]}", 5.0)
        t0 = time.monotonic()
        with pytest.raises(ConfigError, match="no Dask scheduler answered within 2 s"):
            probe_scheduler(f"tcp://127.0.0.1:{silent.getsockname()[1]}", 2.0)
        assert time.monotonic() - t0 < 10.0
        spec = tmp_path / "spec.yaml"
        spec.write_text(json.dumps({**SPEC, "runs": 12, "chunk_runs": 12}), encoding="utf-8")
        r = subprocess.run([sys.executable, "-m", "autopilot", "campaign", str(spec), "--out", str(tmp_path / "o"),
                            "--scheduler", f"tcp://127.0.0.1:{ssh.getsockname()[1]}"],
                           capture_output=True, text=True, timeout=120)
    finally:
        for c in (*held_a, *held_b, ssh, silent):
            c.close()
    assert r.returncode == 2 and "Traceback" not in r.stderr and "internal error" not in r.stderr, r.stderr
    assert "does not speak Dask's protocol" in r.stderr


def test_a_refused_scheduler_leaves_nothing_behind_and_says_when_nothing_listens(tmp_path, capsys):
    """Found by a new-user audit: a refused --scheduler (a closed port: 21 s, then "does not speak Dask's protocol")
    left DIR/campaign.json behind, and the rerun with --jobs was refused as "holds a campaign's results already"."""
    import time as _time

    out = tmp_path / "c"
    t0 = _time.monotonic()
    assert main(["campaign", str(ROOT_SPEC), "--runs", "4", "--out", str(out), "--scheduler", "tcp://127.0.0.1:1"]) == 2
    assert _time.monotonic() - t0 < 10.0
    assert "nothing listens at 127.0.0.1:1 (connection refused)" in capsys.readouterr().err
    assert not (out / "campaign.json").exists()
    out.mkdir(exist_ok=True)
    (out / "campaign.json").write_text("{}")  # what an interrupted campaign leaves: no results, not kept
    assert main(["campaign", str(ROOT_SPEC), "--runs", "4", "--jobs", "1", "--out", str(out), "--quiet",
                 "--no-report"]) == 0


def test_log_is_for_replay_and_never_replaces_a_file_unasked(tmp_path, capsys):
    """Found by a new-user audit: `--log x.jsonl` without --replay was ignored without a word; `--replay DIR I --log
    FILE` replaced an existing file (a mission log of the boat) without asking."""
    out = tmp_path / "c"
    assert main(["campaign", str(ROOT_SPEC), "--runs", "3", "--out", str(out), "--log", str(tmp_path / "x.jsonl")]) == 2
    assert "--log FILE is for --replay DIR INDEX" in capsys.readouterr().err
    assert main(["campaign", str(ROOT_SPEC), "--runs", "3", "--jobs", "1", "--out", str(out), "--quiet",
                 "--no-report"]) == 0
    keep = tmp_path / "keep.jsonl"
    keep.write_text("precious\n")
    assert main(["campaign", "--replay", str(out), "1", "--log", str(keep)]) == 2
    assert "exists; give a new file, or --overwrite to replace it" in capsys.readouterr().err
    assert keep.read_text() == "precious\n"
    assert main(["campaign", "--replay", str(out), "1", "--log", str(keep), "--overwrite"]) == 0
    assert keep.read_text() != "precious\n"


def test_the_shipped_spec_is_found_by_its_name_and_its_readme_path_from_anywhere(tmp_path, monkeypatch):
    """Found by a new-user audit: from an installed wheel the README's `autopilot campaign
    config/campaigns/pond-robustness.yaml` could not be read (missions are found by name, specs were not)."""
    from autopilot.campaign.cli import load_campaign

    monkeypatch.chdir(tmp_path)
    for name in ("pond-robustness", "config/campaigns/pond-robustness.yaml"):
        assert load_campaign(name).spec.name == "pond-robustness"


@pytest.mark.parametrize("out, message", [("", "--out: empty; give a directory (. for this one)"),
                                          ("{tmp}/file.txt", "--out {tmp}/file.txt: is a file, not a directory")])
def test_an_out_that_is_no_directory_is_refused_saying_so(tmp_path, capsys, monkeypatch, out, message):
    """Found by a new-user audit: `--out ''` wrote runs.csv, summary.json and report.html into the working
    directory; `--out existing.txt` said 'cannot create the directory (File exists)'."""
    monkeypatch.chdir(tmp_path)  # where an empty --out would write
    (tmp_path / "file.txt").write_text("notes\n")
    out = out.replace("{tmp}", str(tmp_path))
    assert main(["campaign", str(ROOT_SPEC), "--runs", "3", "--jobs", "1", "--out", out, "--quiet"]) == 2
    assert capsys.readouterr().err.strip() == f"autopilot campaign: error: {message.replace('{tmp}', str(tmp_path))}"


def test_distribution_percentiles_count_the_runs_that_never_reached_their_waypoint():
    """Found by a campaign audit: the percentiles left out the infinite closest approaches (a waypoint never
    reached) while the run count held them, so the tail looked better than it was (p95 2.22 m for 2.57 m)."""
    import math

    import numpy as np

    from autopilot.campaign.results import _quantiles

    finite = list(np.linspace(1.0, 2.5, 142))
    q = _quantiles(finite + [math.inf] * 2)
    assert q["n"] == 144 and q["infinite"] == 2 and q["max"] == math.inf
    assert q["p95"] == pytest.approx(np.percentile(finite + [3.5, 3.5], 95))  # ranked among all 144
    assert q["p95"] > np.percentile(finite, 95)
    assert _quantiles(finite + [math.inf] * 10)["p95"] == math.inf  # the 95th run never got there
    assert _quantiles([1.0, 2.0, 3.0, 4.0])["p95"] == pytest.approx(3.85)  # all finite: as before


@pytest.mark.parametrize("text", ["", "# a spec to write\n\n"])
def test_an_empty_spec_is_said_empty_not_missing_its_missions(tmp_path, capsys, text):
    """Found by a campaign audit: an empty file was answered "missions: name at least one mission"."""
    spec = tmp_path / "empty.yaml"
    spec.write_text(text, encoding="utf-8")
    assert main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"{spec}: the file is empty (or comments only)" in err and "Traceback" not in err


def test_a_normal_spread_that_ends_at_its_bound_is_taken():
    """Found by a new-user audit: current_speed_m_s normal [0.15, 0.05] reaches 0.15 - 3 x 0.05, -2.8e-17 in floating
    point, and was refused as "outside the allowed range [0, 5]"; a hair past the bound is still refused."""
    from autopilot.campaign.spec import Spread, _check_support
    from autopilot.schema import ConfigError
    from autopilot.sim import Environment

    meta = Environment.__dataclass_fields__["current_speed_m_s"].metadata
    _check_support("current_speed_m_s", Spread(normal=(0.15, 0.05)), meta)
    with pytest.raises(ConfigError, match="outside the allowed range"):
        _check_support("current_speed_m_s", Spread(normal=(0.15, 0.0501)), meta)


def test_an_interrupted_replay_leaves_no_log_a_review_would_take_for_a_run(tmp_path):
    """A campaign audit: a Ctrl-C during --replay left replay-N.jsonl without its stop line, which `autopilot
    review` reads as a run cut short. The log is written aside and put in place when the run ends."""
    import subprocess
    import sys

    out = tmp_path / "c"
    spec = tmp_path / "spec.yaml"  # one chunk of 48 runs: the replay flies them all, run 40 among them (~2 s)
    spec.write_text(json.dumps({**SPEC, "runs": 48, "chunk_runs": 48}), encoding="utf-8")
    assert main(["campaign", str(spec), "--jobs", "1", "--out", str(out), "--quiet", "--no-report"]) == 0
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "campaign", "--replay", str(out), "40"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: (signal.signal(signal.SIGINT, signal.SIG_DFL), os.setpgrp()))
    try:
        part = out / ".replay-40.jsonl.part"
        deadline = time.monotonic() + 60
        while not part.exists() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert part.exists(), "the replay wrote nothing aside"
        time.sleep(0.5)  # it flies the chunk's 48 runs, run 40 among them
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == 130, err[-2000:]
    assert not (out / "replay-40.jsonl").exists() and not part.exists()
    assert main(["campaign", "--replay", str(out), "40"]) == 0  # uninterrupted, it is put in place
    last = json.loads((out / "replay-40.jsonl").read_text().rstrip().splitlines()[-1])
    assert last["event"] == "stop" and not part.exists()


def test_a_mission_not_found_says_where_it_was_looked_for(tmp_path, capsys, monkeypatch):
    """A campaign audit: a mission given relative to the working directory, the spec elsewhere, was refused as "no
    such file" without the folder it was looked for in."""
    (tmp_path / "specs").mkdir()
    (tmp_path / "missions").mkdir()
    (tmp_path / "missions" / "mine.yaml").write_text("frame: local\nwaypoints:\n  - {north_m: 10, east_m: 0}\n")
    spec = tmp_path / "specs" / "s.yaml"
    spec.write_text(json.dumps({**SPEC, "missions": ["missions/mine.yaml"]}), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    assert main(["campaign", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "missions[0]: missions/mine.yaml: no such file" in err and f"directory, {tmp_path / 'specs'}," in err, err


def test_a_fault_over_before_control_started_is_not_counted_and_one_the_failsafe_acted_on_is():
    """Found by a new user's test: faults at 3-5 s hit while the daemon was still waiting for valid data (control
    starts at 5-14 s), the failsafe never took them, and they were filed as successes under their fault (11 % of
    the shipped spread's fault runs); a 2.3-s GNSS loss that made the failsafe stop the boat was not counted."""
    from autopilot.campaign.draw import Fault
    from autopilot.campaign.results import _fault_kind
    from autopilot.daemon.config import FailsafeConfig

    fs = FailsafeConfig()
    early = Fault("compass_lost", at_s=3.0, duration_s=2.0)
    assert _fault_kind([early], 60.0, fs, control_from_s=8.0) == "not reached"
    assert _fault_kind([early], 60.0, fs, control_from_s=4.0) == "compass_lost"  # 1 s of it in control: at once
    assert _fault_kind([early], 60.0, fs, control_from_s=None) == "not reached"  # control never started
    gnss = Fault("gnss_lost", at_s=12.9, duration_s=2.3)
    assert _fault_kind([gnss], 60.0, fs, control_from_s=8.0) == "not reached"  # shorter than position_stale_s
    assert _fault_kind([gnss], 60.0, fs, control_from_s=8.0, causes=[(15.0, "position_stale")]) == "gnss_lost"
    assert _fault_kind([gnss], 60.0, fs, control_from_s=8.0, causes=[(15.0, "heading_stale")]) == "not reached"
    # a position_stale of a dropout long before the loss is not the loss's (a review)
    assert _fault_kind([gnss], 60.0, fs, control_from_s=8.0, causes=[(9.0, "position_stale")]) == "not reached"
    # half of it before control: what is left (3.5 s) is long enough to notice
    assert _fault_kind([Fault("gnss_lost", at_s=5.0, duration_s=6.5)], 60.0, fs, control_from_s=8.0) == "gnss_lost"


def test_overwrite_never_deletes_another_commands_results(tmp_path):
    """Found by a new user's test: --out into a review's folder was "a campaign's results already", and with
    --overwrite the campaign deleted the review's report.html and wrote over its summary.json."""
    review = tmp_path / "review"
    review.mkdir()
    (review / "summary.json").write_text('{"cycles": 600}')
    (review / "report.html").write_text("<html>the review</html>")
    from autopilot.campaign.run import check_out_dir
    from autopilot.schema import ConfigError

    for overwrite in (False, True):
        with pytest.raises(ConfigError, match="holds another command's results .*not a campaign's"):
            check_out_dir(review, overwrite=overwrite)
    assert (review / "report.html").read_text() == "<html>the review</html>"
    assert (review / "summary.json").read_text() == '{"cycles": 600}'


def test_runs_csv_says_no_value_one_way(tmp_path):
    """Found by a new user's test: the hold's columns read the text "nan" in every run without a hold, while an
    input a run did not draw was an empty cell."""
    from autopilot.campaign.results import read_runs_csv, write_runs_csv

    rows = [{"index": 0, "hold_time_s": math.nan, "vrx_score": 0.5, "wind_speed_m_s": math.nan, "closest_max_m": math.inf}]
    write_runs_csv(rows, tmp_path / "runs.csv", ["index", "hold_time_s", "vrx_score", "wind_speed_m_s", "closest_max_m"])
    text = (tmp_path / "runs.csv").read_text()
    assert text.splitlines()[1] == "0,,0.5,,inf" and "nan" not in text
    back = read_runs_csv(tmp_path / "runs.csv")[0]
    assert math.isnan(back["hold_time_s"]) and back["vrx_score"] == 0.5 and back["closest_max_m"] == math.inf


def test_replay_refuses_the_options_it_has_no_use_for(tmp_path, capsys):
    """Found by a new user's test: --seed and --runs beside --replay were taken and ignored without a word."""
    out = tmp_path / "camp"
    out.mkdir()
    for extra, named in ((["--seed", "7"], "--seed has no say"), (["--runs", "5", "--jobs", "2"], "--runs, --jobs have")):
        assert main(["campaign", "--replay", str(out), "0", *extra]) == 2
        assert named in capsys.readouterr().err
