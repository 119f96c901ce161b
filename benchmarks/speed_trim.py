"""The speed trim's integral (gnc/speed.py): learning from the wanted speed against a reference speed.

Every shipped route mission (not the station-keep hold) with the fuzzy law on the calibrated
model, in calm water, 5 m/s of wind, and 0.2 m/s of current from ahead and from astern: the
largest speed over ground against the mission's cruise speed (its largest wanted speed: the
overshoot, from rest the integral of the wanted speed's error wound up while the boat got going),
the mean |speed - wanted| while the cruise speed (95 %) is wanted once 15 s have passed, the time and
the cross-track RMS; the shipped reference time constant against 0
(the integral of the wanted speed itself, before 2026-12-04).

    python benchmarks/speed_trim.py [--markdown]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from station_keeping import _print  # benchmarks/ is on the path of a script run from it

from autopilot.evaluate import conditions, run_closed_loop
from autopilot.gnc import GncConfig
from autopilot.mission import load_mission
from autopilot.resources import shipped_missions
from autopilot.sim import default_params_path, load_params

CONDS = ("calm", "wind", "current_n", "current_s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    params = load_params(default_params_path())
    base = GncConfig()
    ways = {f"reference ({base.speed.reference_time_constant_s:g} s, shipped)": base,
            "wanted speed (0, before)": dataclasses.replace(base, speed=dataclasses.replace(
                base.speed, reference_time_constant_s=0.0))}
    missions = [load_mission(p) for p in shipped_missions() if p.stem != "station-keep"]
    header = ("condition", "integral of", "largest speed / cruise speed", "mean |speed - cruise| after 15 s (m/s)",
              "mean time (s)", "mean xte RMS (m)", "completed")
    out = []
    for cond in CONDS:
        for name, cfg in ways.items():
            over, err, times, xte, done = [], [], [], [], 0
            for m in missions:
                r = run_closed_loop(params, m.waypoints_ne_m, speeds_m_s=m.speeds_m_s, env=conditions()[cond],
                                    config=cfg, record=True)
                v, c, t = (np.asarray(r.trace[k], dtype=float) for k in ("speed_m_s", "speed_cmd_m_s", "t_s"))
                cruise = float(np.max(c))
                over.append(float(np.max(v)) / cruise)
                late = (c >= 0.95 * cruise) & (t > 15.0)
                if late.any():
                    err.append(float(np.mean(np.abs(v[late] - c[late]))))
                times.append(r.time_s)
                xte.append(r.xte_rms_m)
                done += r.completed
            out.append((cond, name, f"{min(over):.2f}-{max(over):.2f}", f"{np.mean(err):.3f}", f"{np.mean(times):.1f}",
                        f"{np.mean(xte):.2f}", f"{done}/{len(missions)}"))
    _print(header, out, args.markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
