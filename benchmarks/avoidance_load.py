"""Collision avoidance under a busy port's AIS: time of one ``Avoidance.step`` with N targets (pure, one core).

Two pictures of a busy port: N vessels 5-30 km away under way at 0-7.7 m/s (``far``), and N moored
within 40-400 m of the boat (``moored``), each with one crossing target on a collision course from
starboard. Before the relevance filter (2026-12-03) every target was assessed every cycle: ~70 ms at
1500 targets, most of a 10 Hz cycle. Reported: median and max of --repeats steps, and targets assessed.

    python benchmarks/avoidance_load.py [--targets 1500] [--repeats 30]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from autopilot.gnc.avoidance import Avoidance
from autopilot.gnc.encounter import OwnShip, TargetState

OWN = OwnShip(north_m=0.0, east_m=0.0, course_rad=0.0, speed_m_s=1.0, heading_rad=0.0)
THREAT = TargetState(target_id=1, north_m=60.0, east_m=90.0, course_rad=math.radians(270.0), speed_m_s=1.5)


def port(kind: str, n: int, seed: int = 7) -> list[TargetState]:
    rng = np.random.default_rng(seed)
    if kind == "far":
        r, speed = rng.uniform(5000.0, 30000.0, n), rng.uniform(0.0, 7.7, n)
    else:
        r, speed = rng.uniform(40.0, 400.0, n), np.zeros(n)
    b, course = rng.uniform(0.0, 2 * math.pi, n), rng.uniform(0.0, 2 * math.pi, n)
    return [TargetState(target_id=1000 + k, north_m=float(r[k] * math.cos(b[k])), east_m=float(r[k] * math.sin(b[k])),
                        course_rad=float(course[k]), speed_m_s=float(speed[k])) for k in range(n)] + [THREAT]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=1500)
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    print(f"{'port':8} {'targets':>7} {'assessed':>8} {'median_ms':>9} {'max_ms':>7} acting_on_threat")
    for kind in ("far", "moored"):
        targets = port(kind, args.targets)
        av = Avoidance()
        times, out = [], None
        for k in range(args.repeats):
            t0 = time.perf_counter()
            out = av.step(OWN, targets, 0.0, 1.0, 0.1 * k)
            times.append((time.perf_counter() - t0) * 1e3)
        acting = any(r.target_id == 1 and r.acting for r in out.targets)
        print(f"{kind:8} {len(targets):7d} {len(out.targets):8d} {statistics.median(times):9.2f} {max(times):7.2f} {acting}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
