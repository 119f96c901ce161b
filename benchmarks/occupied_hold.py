"""A mission hold at a waypoint a moored vessel occupies: how much the boat moves while it holds.

The scenario of ``tests/test_evaluate_traffic.py`` (a 10-m vessel stopped on the waypoint, 100 m ahead),
flown by ``autopilot.evaluate.run_closed_loop`` with a 120-s hold item there and a second waypoint after it,
the vessel seen through AIS, in calm water and in 0.2 m/s of current setting the boat onto the vessel or away from it.
Over the hold (15-120 s after the boat first comes within 30 m of the waypoint): the distance to the
vessel (least and most), the path the boat runs, and the share of cycles avoidance acts.

    python benchmarks/occupied_hold.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from autopilot.evaluate import run_closed_loop
from autopilot.sim import Environment, default_params_path, load_params
from autopilot.simdev.traffic import load_scenario
from autopilot.traffic.feed import TrafficFeed

SCENARIO = ("name: on-waypoint\nown: {north_m: 0.0, east_m: 0.0, course_deg: 0.0, speed_m_s: 1.0, goal_north_m: 100.0,"
            " goal_east_m: 0.0}\ntargets:\n  - {mmsi: 244000902, name: ON WP, north_m: 100.0, east_m: 0.0,"
            " course_deg: 90.0, speed_m_s: 0.0, length_m: 10.0, beam_m: 3.0}\n")
CONDITIONS = {"calm": Environment(),
              "current 0.2 m/s onto the vessel": Environment(current_speed_m_s=0.2, current_towards_deg=0.0),
              "current 0.2 m/s away from it": Environment(current_speed_m_s=0.2, current_towards_deg=180.0)}


def main() -> None:
    with tempfile.TemporaryDirectory() as work:
        path = Path(work) / "on-waypoint.yaml"
        path.write_text(SCENARIO)
        scenario = load_scenario(path)
    params = load_params(default_params_path())
    print("| condition | completed | distance to the vessel in the hold (m) | path in the hold (m) | avoidance acting |")
    print("|---|---|---|---|---|")
    for name, env in CONDITIONS.items():
        r = run_closed_loop(params, [(100.0, 0.0), (100.0, 80.0)], holds_s=[120.0, None], traffic=TrafficFeed(scenario),
                            record=True, x0=(0.0, 0.0, 0.0, 1.0, 0.0, 0.0), t_max_s=400.0, env=env)
        tr = r.trace
        t, n, e = (np.array(tr[k]) for k in ("t_s", "north_m", "east_m"))
        d = np.hypot(n - 100.0, e)
        acting = np.array([any(a.values()) for a in tr["acting"]])
        k0 = int(np.argmax(d < 30.0))
        sel = (t >= t[k0] + 15.0) & (t <= t[k0] + 120.0)
        path_m = float(np.sum(np.hypot(np.diff(n[sel]), np.diff(e[sel]))))
        print(f"| {name} | {r.completed} | {d[sel].min():.1f}-{d[sel].max():.1f} | {path_m:.1f} | "
              f"{100.0 * acting[sel].mean():.0f} % |")


if __name__ == "__main__":
    main()
