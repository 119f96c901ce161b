"""Simulator speed: simulated seconds per wall-clock second (issue 2).

One 600 s trajectory and a batch of 1000 such trajectories at dt 0.05 s, with
a plain per-step Python RK4 of the same model (numpy arrays for the state,
derivative as a function of the state vector, the way most simulators are
written) run in the same process for comparison.

    python benchmarks/sim_speed.py [--json] [--batch 1000] [--duration-s 600]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from autopilot.sim import load_params, simulate
from autopilot.sim.params import default_params_path


def plain_rk4(params, t_end_s: float, dt_s: float, thrust_port_n: float, thrust_stbd_n: float) -> np.ndarray:
    """A straightforward per-step RK4 of the same MMG equations (reference implementation)."""
    p = params
    kf, km, length = p.force_scale_kg_m, p.moment_scale_kg, p.length_m

    def f(x: np.ndarray) -> np.ndarray:
        n, e, psi, u, v, r = x
        speed = math.sqrt(u * u + v * v) + 1e-12
        fx = -p.resistance_linear_n_s_m * u + kf * p.x_vv_nd * v * v + (1 - p.thrust_deduction) * (thrust_port_n + thrust_stbd_n)
        fy = kf * speed * (p.y_v_nd * v + p.y_r_nd * length * r) + kf * p.y_vvv_nd * v**3 / speed
        fy -= (p.sway_damping_linear_n_s_m + p.sway_damping_quadratic_n_s2_m2 * abs(v)) * v
        mz = km * speed * (p.n_v_nd * v + p.n_r_nd * length * r) + km * p.n_vvv_nd * v**3 / speed
        mz -= (p.yaw_damping_linear_nm_s + p.yaw_damping_quadratic_nm_s2 * abs(r)) * r
        mz += (1 - p.moment_deduction) * p.y_p_m * (thrust_port_n - thrust_stbd_n)
        return np.array(
            [
                u * math.cos(psi) - v * math.sin(psi),
                u * math.sin(psi) + v * math.cos(psi),
                r,
                (fx + p.mass_y_kg * v * r) / p.mass_x_kg,
                (fy - p.mass_x_kg * u * r) / p.mass_y_kg,
                mz / p.inertia_z_kg_m2,
            ]
        )

    x = np.zeros(6)
    for _ in range(int(round(t_end_s / dt_s))):
        k1 = f(x)
        k2 = f(x + 0.5 * dt_s * k1)
        k3 = f(x + 0.5 * dt_s * k2)
        k4 = f(x + dt_s * k3)
        x = x + dt_s / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=600.0)
    ap.add_argument("--dt-s", type=float, default=0.05)
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    params = load_params(default_params_path())
    t = np.arange(0.0, args.duration_s + args.dt_s / 2, args.dt_s)
    tp, ts = np.full(t.size, 10.0), np.full(t.size, 32.5)

    single_s = best_of(lambda: simulate(params, t, tp, ts, dt_s=args.dt_s), 3)
    plain_s = best_of(lambda: plain_rk4(params, args.duration_s, args.dt_s, 10.0, 32.5), 1)
    tpb, tsb = np.tile(tp, (args.batch, 1)), np.tile(ts, (args.batch, 1))
    batch_s = best_of(lambda: simulate(params, t, tpb, tsb, dt_s=args.dt_s), 1)

    # the plain reference must agree with the fast path (same model)
    fast = simulate(params, t, tp, ts, dt_s=args.dt_s)
    ref = plain_rk4(params, args.duration_s, args.dt_s, 10.0, 32.5)
    agree_m = math.hypot(fast["north_m"][-1] - ref[0], fast["east_m"][-1] - ref[1])

    result = {
        "dt_s": args.dt_s,
        "duration_s": args.duration_s,
        "single_realtime_factor": round(args.duration_s / single_s),
        "plain_python_rk4_realtime_factor": round(args.duration_s / plain_s),
        "single_vs_plain_ratio": round(plain_s / single_s, 2),
        "batch_runs": args.batch,
        "batch_trajectory_s_per_s": round(args.batch * args.duration_s / batch_s),
        "batch_vs_plain_ratio": round((args.batch * args.duration_s / batch_s) / (args.duration_s / plain_s), 1),
        "fast_vs_plain_final_position_diff_m": agree_m,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"one {args.duration_s:.0f} s trajectory at dt {args.dt_s} s: {result['single_realtime_factor']:,}x real time")
        print(f"plain per-step Python RK4 (numpy state): {result['plain_python_rk4_realtime_factor']:,}x real time")
        print(f"  ratio fast / plain: {result['single_vs_plain_ratio']}x")
        print(f"batch of {args.batch}: {result['batch_trajectory_s_per_s']:,} trajectory-seconds per second ({result['batch_vs_plain_ratio']}x plain)")
        print(f"fast and plain agree to {agree_m:.2e} m after {args.duration_s:.0f} s")


if __name__ == "__main__":
    main()
