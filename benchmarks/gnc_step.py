"""Microseconds per control step (guidance + PID + allocation + PWM), median and 99th percentile.

    python benchmarks/gnc_step.py [--json] [--steps N]

Each law drives a kinematic boat (unit speed along the commanded heading) round
the thesis simulation mission, again and again, so the waypoint switching and every branch
of the step are exercised; only ``Autopilot.step`` is timed.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time

from autopilot.gnc import GUIDANCE_LAWS, Autopilot, GncConfig, NavInput
from autopilot.schema import load

WAYPOINTS = [(10.0, 5.0), (35.0, 20.0), (50.0, 16.0), (10.0, 0.0)]


def bench(law: str, steps: int) -> list[float]:
    cfg = load(GncConfig, {"guidance": {"law": law}})
    ap = Autopilot(cfg, WAYPOINTS)
    n = e = psi = 0.0
    dt = 0.1
    times = []
    for _ in range(steps):
        nav = NavInput(north_m=n, east_m=e, psi_rad=psi, speed_m_s=1.0, yaw_rate_rad_s=0.05, course_rad=psi)
        t0 = time.perf_counter_ns()
        out = ap.step(nav, dt)
        times.append((time.perf_counter_ns() - t0) / 1000.0)
        psi += max(-0.05, min(0.05, out.heading_error_rad))  # crude turn-rate limit
        n += math.cos(psi) * dt
        e += math.sin(psi) * dt
        if ap.complete:  # fly the route again: time the guidance, not an idle finished autopilot
            ap = Autopilot(cfg, WAYPOINTS)
            n = e = psi = 0.0
    return times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args()
    rows = []
    for law in GUIDANCE_LAWS:
        bench(law, 500)  # warm-up
        t = sorted(bench(law, args.steps))
        rows.append({"law": law, "steps": len(t), "median_us": statistics.median(t), "p99_us": t[int(0.99 * (len(t) - 1))]})
    if args.json:
        print(json.dumps(rows))
    else:
        print(f"{'law':<13} {'steps':>6} {'median_us':>10} {'p99_us':>8}")
        for r in rows:
            print(f"{r['law']:<13} {r['steps']:>6} {r['median_us']:>10.1f} {r['p99_us']:>8.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
