"""Wall time of the whole `autopilot sysid` workflow on ten 120-second trials (issue 12, Build 5).

Realistic trials (autopilot.sysid.realistic: 1 Hz fixes held on 10 Hz rows, wandering GPS
error and outliers, a wandering quantised heading) with a hidden current and thrust lag; the
workflow runs end to end including report.html. ``--white`` uses the original white-noise 10 Hz
trials (autopilot.sysid.synthetic) instead.
Run: python benchmarks/sysid_speed.py [--json] [--trials 10] [--duration 120] [--white]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--duration", type=float, default=120.0)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--white", action="store_true", help="white-noise 10 Hz trials (the original benchmark)")
    args = ap.parse_args()

    from autopilot.sim import default_params_path, load_params
    from autopilot.sysid.realistic import make_realistic_trials
    from autopilot.sysid.synthetic import make_trials
    from autopilot.sysid.workflow import run

    vessel = load_params(default_params_path())
    hidden = {"current.north_m_s": 0.12, "current.east_m_s": -0.08, "thrust_lag.time_constant_s": 0.8}
    t0 = time.perf_counter()
    make = make_trials if args.white else make_realistic_trials
    trials = make(vessel, hidden, seed=args.seed, n_trials=args.trials, duration_s=args.duration)
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as out:
        summary = run(trials, vessel, out)
    t2 = time.perf_counter()
    figures = {
        "trials": args.trials,
        "trial_duration_s": args.duration,
        "trajectory_seconds": args.trials * args.duration,
        "generate_s": round(t1 - t0, 2),
        "workflow_wall_s": round(t2 - t1, 2),
        "trials_kind": "white" if args.white else "realistic",
        "verdict": summary["verdict"],
        "fitted": {k: round(v, 4) for k, v in summary["_ident"].values().items()},
        "hidden": hidden,
        "cpu_count": os.cpu_count(),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    if args.json:
        print(json.dumps(figures))
    else:
        for k, v in figures.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
