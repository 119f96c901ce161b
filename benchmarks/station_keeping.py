"""Station keeping compared: the precise hold, ArduPilot's drift-and-return (radius 2 m), and zero thrust.

The shipped mission config/missions/station-keep.yaml (drive 28 m out, hold 300 s) on the
calibrated model, through `autopilot evaluate`'s closed loop (the SC-30's rates, the daemon's
navigation): the hold scored from the true position and heading over the 300 s. Zero thrust
is the boat left at rest on the point for 300 s with both thrusters off (the drift). With
--noise the SC-30's position (0.5 m) and heading (0.5 deg) are noisy, several seeds.

    python benchmarks/station_keeping.py [--markdown] [--noise --seeds 5]
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from autopilot.evaluate import CONDITION_NAMES, conditions, hold_score, run_closed_loop
from autopilot.gnc import GncConfig
from autopilot.mission import load_mission
from autopilot.resources import shipped_missions
from autopilot.sim import default_params_path, load_params, step

HOLD_S = 300.0
CONDS = ("calm", "current_n", "current_e", "current_s", "current_w", "wind", "current_wind")


def drift(params, env, hold_s: float = HOLD_S, dt_s: float = 0.05):
    """Zero thrust from rest on the point: the hold's score of doing nothing."""
    x = np.zeros(6)
    d, h, t = [], [], 0.0
    k = 0
    while t < hold_s:
        x = step(params, x, 0.0, 0.0, dt_s, t_s=t, env=env)
        t += dt_s
        k += 1
        if k % 2 == 0:  # the 10 Hz control cycles
            d.append(math.hypot(x[0], x[1]))
            h.append(0.0)  # no heading to hold: scored on position only
    return hold_score(d, h, [0.0] * len(d), 0.1)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--noise", action="store_true", help="noisy SC-30 (0.5 m, 0.5 deg)")
    ap.add_argument("--seeds", type=int, default=1)
    args = ap.parse_args()
    params = load_params(default_params_path())
    mission = load_mission(next(p for p in shipped_missions() if p.stem == "station-keep"))
    envs = conditions()
    base = GncConfig()
    ways = {"hold (radius 0)": base,
            "drift-and-return (radius 2 m)": dataclasses.replace(base, hold=dataclasses.replace(base.hold, radius_m=2.0))}
    noise = dict(position_noise_m=0.5, heading_noise_deg=0.5) if args.noise else {}
    rows = []
    for cond in CONDS:
        assert cond in CONDITION_NAMES
        for name, cfg in ways.items():
            scores = [run_closed_loop(params, mission.waypoints_ne_m, holds_s=mission.holds_s, env=envs[cond],
                                      config=cfg, seed=s, **noise).hold for s in range(args.seeds)]
            rows.append((cond, name, scores))
        rows.append((cond, "zero thrust (drift)", [drift(params, envs[cond])]))
    header = ("condition", "hold", "position RMS (m)", "p95 (m)", "max (m)", "heading RMS (deg)", "energy (N s)", "VRX")

    def rng(vals, fmt):
        lo, hi = min(vals), max(vals)
        return f"{lo:{fmt}}" if abs(hi - lo) < 0.5 * 10 ** -int(fmt[-2]) else f"{lo:{fmt}}-{hi:{fmt}}"

    out = []
    for cond, name, scores in rows:
        heading = "-" if name.startswith("zero") else rng([s.heading_error_rms_deg for s in scores], ".1f")
        out.append((cond, name, rng([s.position_error_rms_m for s in scores], ".2f"),
                    rng([s.position_error_p95_m for s in scores], ".2f"), rng([s.position_error_max_m for s in scores], ".2f"),
                    heading, rng([s.energy_n_s for s in scores], ".0f"), rng([s.vrx_score for s in scores], ".2f")))
    if args.markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for r in out:
            print("| " + " | ".join(r) + " |")
    else:
        print("  ".join(f"{h:>18}" for h in header))
        for r in out:
            print("  ".join(f"{c:>18}" for c in r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
