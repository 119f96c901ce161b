"""Collision avoidance beside a geofence: does the boat keep inside the fence and its distance from every vessel?

Each shipped traffic scenario whose give-way turn is to starboard, flown by ``autopilot.evaluate.run_encounter``
(the calibrated model, the whole GNC stack, targets seen through AIS) with a straight geofence edge parallel to the
track, ``EDGE`` m to starboard of it, handed to the helm as the daemon's failsafe hands it (``within_limits``), and
once without it ("none"; the fence is then only measured against). Per run: the furthest the boat went to starboard,
whether it left the fence, each target's closest approach against the distance it needs, whether the
avoidance departed to port (rule 2(b)), and how often its alteration changed (a flicker shows there).

    python benchmarks/avoidance_limits.py [--edges 40 30 20 12] [--scenarios head-on two-targets ...] [--lookahead S]
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from autopilot.daemon.failsafe import inside_polygon
from autopilot.evaluate import run_encounter, shipped_scenarios
from autopilot.gnc import GncConfig
from autopilot.sim import default_params_path, load_params
from autopilot.simdev.traffic import load_scenario

STARBOARD_SCENARIOS = ("head-on", "crossing-starboard", "two-targets", "three-targets", "overtaken", "turning-target")


def fence_east_of(edge_east_m: float):
    poly = ((-500.0, -500.0), (1000.0, -500.0), (1000.0, edge_east_m), (-500.0, edge_east_m))
    return lambda n, e: inside_polygon(n, e, poly)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edges", type=float, nargs="+", default=[40.0, 30.0, 25.0, 20.0, 12.0])
    ap.add_argument("--scenarios", nargs="+", default=list(STARBOARD_SCENARIOS))
    ap.add_argument("--lookahead", type=float, help="gnc.avoidance.limits_lookahead_s (s; default: the shipped one)")
    args = ap.parse_args(argv)
    params = load_params(default_params_path())
    config = GncConfig()
    if args.lookahead is not None:
        config = dataclasses.replace(config, avoidance=dataclasses.replace(config.avoidance,
                                                                           limits_lookahead_s=args.lookahead))
    paths = {p.stem: p for p in shipped_scenarios()}
    print("| scenario | fence edge (m east) | furthest east (m) | left the fence | closest / needed (m) | port departure "
          "| alteration changes |")
    print("|---|---|---|---|---|---|---|")
    for name in args.scenarios:
        sc = load_scenario(paths[name])
        for edge in [None, *args.edges]:
            allowed = None if edge is None else fence_east_of(edge)
            r = run_encounter(params, sc, config=config, within_limits=allowed, record=True, reference=False)
            east = np.asarray(r.trace["east_m"])
            share = np.asarray(r.trace["avoid_share_rad"])
            passes = ", ".join(f"{t.min_distance_m:.1f} / {t.required_m:.1f}" + ("" if t.distance_kept else " **short**")
                               for t in r.score.targets)
            left = "-" if edge is None else ("**yes**" if east.max() > edge else "no")
            changes = int(np.count_nonzero(np.diff(np.round(np.degrees(share), 1))))
            print(f"| {name} | {'none' if edge is None else f'{edge:g}'} | {east.max():.1f} | {left} | {passes} | "
                  f"{'yes' if share.min() < -math.radians(1.0) else 'no'} | {changes} |", flush=True)


if __name__ == "__main__":
    main()
