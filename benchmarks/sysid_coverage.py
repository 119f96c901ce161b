"""Do the identification's 95 % intervals cover the truth? A hidden current under wandering GPS error.

Each seed: ``--trials`` realistic trials of ``--duration`` s (autopilot.sysid.realistic: the issue-12
sensor, here with ``--wander`` m of Gauss-Markov wander per axis, 45 s correlation time, 0.15 m white,
1 % single-fix outliers; positions and heading only unless ``--velocity``), a hidden current of
(0.12, -0.16) m/s, identified among current, wind_force and hydro_refit. Printed per seed: the verdict,
the estimate, its sigma and z = (estimate - truth) / sigma; at the end how many of the current's
parameters the intervals (estimate +- 1.96 sigma) covered, and the RMS of z (1 when the sigmas are
right). Seeds run ``--jobs`` at a time.

    python benchmarks/sysid_coverage.py [--trials 2] [--seeds 16] [--first-seed 1] [--wander 1.5] [--jobs 2]
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

HIDDEN = {"current.north_m_s": 0.12, "current.east_m_s": -0.16}


def one(seed: int, trials: int, duration_s: float, wander_m: float, velocity: bool):
    from autopilot.sim import default_params_path, load_params
    from autopilot.sim.gps_error import GpsErrorModel
    from autopilot.sysid import identify
    from autopilot.sysid.realistic import make_realistic_trials

    vessel = load_params(default_params_path())
    gps = GpsErrorModel(wander_m=wander_m, wander_time_s=45.0, white_m=0.15, outlier_rate=0.01,
                        velocity_white_m_s=0.05)
    data = make_realistic_trials(vessel, HIDDEN, seed, n_trials=trials, duration_s=duration_s, gps=gps,
                                 velocity=velocity)
    r = identify(data, vessel, candidates=("current", "wind_force", "hydro_refit"))
    f = r.chosen
    if f is None or "current.north_m_s" not in f.keys:
        return seed, r.status, r.verdict, None, r.notes
    est = [f.values()[k] for k in HIDDEN]
    sig = [float(f.sigma[f.keys.index(k)]) for k in HIDDEN]
    return seed, r.status, r.verdict, (est, sig), r.notes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=2)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--wander", type=float, default=1.5)
    ap.add_argument("--velocity", action="store_true")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    zs, covered, named = [], 0, 0
    seeds = range(a.first_seed, a.first_seed + a.seeds)
    with ProcessPoolExecutor(a.jobs) as pool:
        for seed, status, verdict, fit, notes in pool.map(one, seeds, *zip(*[(a.trials, a.duration, a.wander,
                                                                                 a.velocity)] * a.seeds)):
            if fit is None:
                print(f"seed {seed}: {status} {verdict} (no current fitted)", flush=True)
                continue
            named += verdict == ("current",)
            est, sig = fit
            z = [(e - t) / s for e, t, s in zip(est, HIDDEN.values(), sig)]
            zs += z
            covered += sum(abs(x) <= 1.96 for x in z)
            print(f"seed {seed}: {status} {verdict} estimate {est[0]:+.3f} {est[1]:+.3f} sigma {sig[0]:.3f} "
                  f"{sig[1]:.3f} z {z[0]:+.2f} {z[1]:+.2f}" + (f"  [{notes[-1][:80]}]" if notes else ""), flush=True)
    if zs:
        print(f"{a.trials} trials x {a.duration:g} s, wander {a.wander:g} m: current named in {named} of {a.seeds}; "
              f"intervals covered {covered} of {len(zs)} parameters ({100 * covered / len(zs):.0f} %), "
              f"RMS z {math.sqrt(sum(x * x for x in zs) / len(zs)):.2f}")


if __name__ == "__main__":
    main()
