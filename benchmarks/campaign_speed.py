"""Campaign speed (issue 17): runs per second per core, one at a time against lockstep, and Dask scaling.

1. The same runs of ``config/campaigns/pond-robustness.yaml`` (the conditions ``autopilot evaluate``
   can fly too: nominal, current, weather; each run with its own drawn vessel, current, wind,
   sinusoidal force and sensor noise) flown in this process, interleaved, best of ``--repeats`` each
   (the machine is shared; CPU time of this process, so others' load counts little):
   - by ``autopilot.evaluate.run_closed_loop``, one at a time (evaluate's loop: the scalar RK4, the
     helm without the failsafe);
   - by ``autopilot.campaign.lockstep.fly`` with every run on its own (the daemon's whole cycle,
     failsafe included, the scalar RK4): the campaign's work one at a time;
   - by ``fly`` in lockstep (one batched RK4 over all of them);
   and lockstep batches of other sizes.
2. The whole campaign's first ``--dask-runs`` runs on a Dask ``LocalCluster`` of 1 and of 2 worker
   processes (one thread each), the cluster started before the clock; wall time (what scaling is),
   so it shows what else the machine runs (the load average is printed).

    python benchmarks/campaign_speed.py [--runs 240] [--repeats 3] [--dask-runs 960] [--no-dask] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace

from autopilot.campaign.draw import cell_of, draw_run
from autopilot.campaign.lockstep import MIN_BATCH, fly
from autopilot.evaluate import run_closed_loop
from autopilot.resources import campaigns_dir

EVALUATE_CONDITIONS = ("nominal", "current", "weather")


def campaign(chunk_runs: int | None = None):
    from autopilot.campaign.cli import load_campaign

    c = load_campaign(campaigns_dir() / "pond-robustness.yaml")
    return c if chunk_runs is None else replace(c, spec=replace(c.spec, chunk_runs=chunk_runs))


def one_at_a_time(c, seed: int, indices) -> tuple[float, int]:
    """Wall seconds and control cycles for evaluate's loop over the runs."""
    cycles = 0
    t0 = time.process_time()
    for i in indices:
        s = draw_run(c, seed, i)
        cfg = replace(c.spec.gnc, guidance=replace(c.spec.gnc.guidance, law=s.law))
        m = s.mission
        r = run_closed_loop(s.params, m.waypoints_ne_m, config=cfg, speeds_m_s=m.speeds_m_s, holds_s=m.holds_s,
                            env=s.env, position_noise_m=s.position_noise_m, heading_noise_deg=s.heading_noise_deg,
                            seed=i, t_max_s=s.t_max_s, x0=(*m.home_ne_m, 0.0, 0.0, 0.0, 0.0))
        cycles += int(round(r.time_s * 10.0))
    return time.process_time() - t0, cycles


def lockstep(c, seed: int, indices, batch: int, min_batch: int = MIN_BATCH) -> tuple[float, int]:
    """Wall seconds and control cycles flying the runs in lockstep batches of ``batch`` (``min_batch`` larger
    than the batch: every run on its own, the model's scalar path, as one at a time)."""
    cycles = 0
    t0 = time.process_time()
    for k in range(0, len(indices), batch):
        cycles += sum(r["cycles"] for r in fly(c, seed, indices[k:k + batch], min_batch=min_batch))
    return time.process_time() - t0, cycles


def dask_rate(c, seed: int, runs: int, workers: int) -> float:
    from distributed import Client, LocalCluster

    from autopilot.campaign.backends import run_chunks

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=50) as cluster, Client(cluster, set_as_default=False) as client:
        client.wait_for_workers(workers)
        client.run(lambda: __import__("autopilot.campaign.lockstep"))  # imports paid before the clock
        t0 = time.perf_counter()
        rows = run_chunks(c, seed, runs, scheduler=client)
        elapsed = time.perf_counter() - t0
    assert len(rows) == runs
    return runs / elapsed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=240, help="runs flown both ways (default 240)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dask-runs", type=int, default=960)
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    c = campaign()
    seed = c.spec.seed
    conds = [name for name, _ in c.conditions]
    indices = [i for i in range(20 * args.runs) if conds[cell_of(c, i)[2]] in EVALUATE_CONDITIONS][:args.runs]
    fly(c, seed, indices[:4])  # warm the caches (the fuzzy engines, imports)
    n = len(indices)
    ways = {"evaluate": lambda: one_at_a_time(c, seed, indices),
            "campaign_single": lambda: lockstep(c, seed, indices, n, min_batch=n + 1),
            "campaign_lockstep": lambda: lockstep(c, seed, indices, n)}
    best: dict = {}
    for _ in range(args.repeats):  # interleaved: the machine's load falls on every way alike
        for name, fn in ways.items():
            wall, cycles = fn()
            if name not in best or wall < best[name][0]:
                best[name] = (wall, cycles)
    out = {"runs": n, "conditions": list(EVALUATE_CONDITIONS), "date": time.strftime("%Y-%m-%d")}
    for name, (wall, cycles) in best.items():
        out[name] = {"wall_s": wall, "runs_per_s": n / wall, "us_per_run_cycle": 1e6 * wall / cycles,
                     "cycles": cycles}
    out["lockstep_over_single"] = out["campaign_lockstep"]["runs_per_s"] / out["campaign_single"]["runs_per_s"]
    out["lockstep_over_evaluate"] = out["campaign_lockstep"]["runs_per_s"] / out["evaluate"]["runs_per_s"]
    out["batches"] = {}
    for batch in (1, 10, 60, n):
        wall, cycles = min(lockstep(c, seed, indices[:max(batch, 60)], batch) for _ in range(max(1, args.repeats - 1)))
        out["batches"][batch] = {"runs_per_s": max(batch, 60) / wall, "us_per_run_cycle": 1e6 * wall / cycles}
    if not args.no_dask:
        dc = campaign(chunk_runs=60)
        one = dask_rate(dc, seed, args.dask_runs, 1)
        two = dask_rate(dc, seed, args.dask_runs, 2)
        out["dask"] = {"runs": args.dask_runs, "chunk_runs": 60, "workers_1_runs_per_s": one,
                       "workers_2_runs_per_s": two, "scaling": two / one, "load_average": os.getloadavg()[0]}
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"{len(indices)} runs of pond-robustness ({', '.join(EVALUATE_CONDITIONS)}), one core (CPU time), best "
          f"of {args.repeats} ({out['date']}):")
    for name, label in (("evaluate", "evaluate's loop, one at a time"),
                        ("campaign_single", "campaign runs, one at a time"),
                        ("campaign_lockstep", "campaign runs, lockstep")):
        r = out[name]
        print(f"  {label:<32} {r['runs_per_s']:7.1f} runs/s  {r['us_per_run_cycle']:6.1f} us per run-cycle")
    print(f"  lockstep / one at a time (the same work): {out['lockstep_over_single']:.2f}x; "
          f"lockstep / evaluate's loop: {out['lockstep_over_evaluate']:.2f}x")
    print("  lockstep batch size: " + ", ".join(f"{b}: {r['runs_per_s']:.1f} runs/s" for b, r in out["batches"].items()))
    if "dask" in out:
        d = out["dask"]
        print(f"Dask LocalCluster, {d['runs']} runs in chunks of {d['chunk_runs']}: 1 worker "
              f"{d['workers_1_runs_per_s']:.1f} runs/s, 2 workers {d['workers_2_runs_per_s']:.1f} runs/s "
              f"({d['scaling']:.2f}x; load average {d['load_average']:.1f} on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
