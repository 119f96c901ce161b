"""A compass stuck whole: how soon the failsafe calls it, and how far that is from a false call.

``failsafe.heading_frozen_steer_s`` (3 s) and ``heading_frozen_steer_error_deg`` (20 deg): the helm
steering that far off a compass heading that has not moved 0.5 deg, for that long, is
``heading_frozen``. This script measures both sides of that choice on the daemon's own cycle
(``autopilot.campaign.lockstep``: navigation assembly, failsafe, helm, allocation):

1. The margin: over the runs of ``config/campaigns/pond-robustness.yaml`` with every shipped mission
   (the pond missions, station keeping, the zigzag, the thesis's simulation; model spread, current,
   wind up to 10 m/s, unmatched and slow thrusters, noisy and dropping sensors, faults), the longest
   time the helm steered at least ``--error-deg`` (several values) off a still compass heading, as
   the failsafe counts it (``Navigation.heading_still_since_s``, ``steered_error_rad``). A value
   below 3 s at 20 deg is the margin; none may reach it (it would stop a healthy boat).
2. The catch: ``--inject`` runs (nominal, current, weather) with the compass stuck whole (heading and
   rate of turn repeating the values of the moment it stuck) at a random time: the time to
   ``heading_frozen`` and how far the boat turned meanwhile.

    python benchmarks/heading_frozen_margin.py [--runs 1400] [--inject 60] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from autopilot.campaign.cli import load_campaign
from autopilot.campaign.draw import draw_run
from autopilot.campaign.lockstep import SIM_DT_S, _flight, fly
from autopilot.daemon.cycle import steered_error_rad
from autopilot.resources import campaigns_dir, shipped_missions

ERRORS_DEG = (10.0, 15.0, 20.0, 30.0)


def campaign_all_missions():
    """pond-robustness with every shipped mission."""
    data = yaml.safe_load((campaigns_dir() / "pond-robustness.yaml").read_text(encoding="utf-8"))
    data["missions"] = sorted(p.stem for p in shipped_missions())
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "all-missions.yaml"
        path.write_text(yaml.safe_dump(data), encoding="utf-8")
        return load_campaign(path)


class Unanswered:
    """Per run: the longest steering time off a still heading, per error threshold (the failsafe's count)."""

    def __init__(self) -> None:
        self.since = None
        self.last_t = None
        self.count = dict.fromkeys(ERRORS_DEG, 0.0)
        self.worst = dict.fromkeys(ERRORS_DEG, 0.0)

    def __call__(self, t_s, flight, cycle) -> None:
        if cycle is None:
            return
        since = cycle.nav.heading_still_since_s
        err = steered_error_rad(cycle.out)
        if since != self.since:
            self.since, self.count = since, dict.fromkeys(ERRORS_DEG, 0.0)
        elif err is not None and self.last_t is not None:
            for e in ERRORS_DEG:
                if abs(err) >= math.radians(e):
                    self.count[e] += min(t_s - self.last_t, 1.0)
                    self.worst[e] = max(self.worst[e], self.count[e])
        self.last_t = t_s


def margin(c, runs: int) -> dict:
    watch = {i: Unanswered() for i in range(runs)}
    chunk = c.spec.chunk_runs
    for k in range(0, runs, chunk):
        fly(c, c.spec.seed, range(k, min(k + chunk, runs)), watch=watch)
    out = {}
    for e in ERRORS_DEG:
        worst = sorted(((w.worst[e], i) for i, w in watch.items()), reverse=True)[:3]
        out[f"{e:g}"] = [{"s": round(s, 2), "run": i, "mission": draw_run(c, c.spec.seed, i).mission.name,
                          "condition": draw_run(c, c.spec.seed, i).condition} for s, i in worst]
    return out


def inject(c, n: int) -> list[dict]:
    """Stick the compass whole in ``n`` runs of the nominal, current and weather conditions."""
    rng = np.random.default_rng(5)
    found, i = [], 0
    while len(found) < n:
        s = draw_run(c, c.spec.seed, i)
        i += 1
        if s.condition not in ("nominal", "current", "weather"):
            continue
        flight, _ = _flight(c, s)
        t_stuck = float(rng.uniform(5.0, 0.6 * s.t_max_s))
        stuck = {}

        def stick(t_s, sample, stuck=stuck, t_stuck=t_stuck):
            if t_s < t_stuck:
                return sample
            if not stuck:
                stuck.update(h=sample.heading_rad, r=sample.yaw_rate_rad_s)
            return replace(sample, heading_rad=replace(stuck["h"], t_s=t_s), yaw_rate_rad_s=replace(stuck["r"], t_s=t_s))

        flight.sample_filter = stick
        from autopilot.sim import step

        x, t, psi0, caught = np.array([*s.mission.home_ne_m, 0.0, 0.0, 0.0, 0.0]), 0.0, None, None
        while (thrust := flight.control(t, x)) is not None:
            if t >= t_stuck and psi0 is None:
                psi0 = float(x[2])
            if psi0 is not None and "heading_frozen" in flight.last.active_faults:
                caught = t
                break
            for _ in range(flight.substeps):
                x = step(s.params, x, thrust[0], thrust[1], SIM_DT_S, t_s=t, env=s.env)
                t += SIM_DT_S
        if psi0 is None:
            continue  # the mission ended before the compass stuck
        rate = stuck["r"].value if stuck.get("r") is not None else None
        found.append({"run": s.index, "mission": s.mission.name, "condition": s.condition, "stuck_at_s": round(t_stuck, 1),
                      "stuck_rot_deg_s": None if rate is None else round(math.degrees(rate), 1),
                      "caught_after_s": None if caught is None else round(caught - t_stuck, 1),
                      "turned_deg": round(abs(math.degrees(float(x[2]) - psi0)), 1),
                      "ended": flight.end_reason})
    return found


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1400)
    ap.add_argument("--inject", type=int, default=60)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    c = campaign_all_missions()
    t0 = time.perf_counter()
    out = {"date": time.strftime("%Y-%m-%d"), "runs": args.runs, "missions": list(c.spec.missions),
           "longest_unanswered_steering_s": margin(c, args.runs)}
    caught = inject(c, args.inject)
    after = [r["caught_after_s"] for r in caught if r["caught_after_s"] is not None]
    turned = [r["turned_deg"] for r in caught if r["caught_after_s"] is not None]
    out["inject"] = {"runs": len(caught), "caught": len(after), "not_caught": [r for r in caught if r["caught_after_s"] is None],
                     "caught_after_s": [min(after), float(np.median(after)), max(after)] if after else None,
                     "turned_deg": [min(turned), float(np.median(turned)), max(turned)] if turned else None}
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"{args.runs} runs of pond-robustness over {', '.join(out['missions'])}")
    for e, worst in out["longest_unanswered_steering_s"].items():
        print(f"  steering >= {e:>2} deg off a still heading: longest " +
              ", ".join(f"{w['s']:.1f} s (run {w['run']}, {w['mission']}, {w['condition']})" for w in worst))
    inj = out["inject"]
    print(f"compass stuck whole in {inj['runs']} runs: caught in {inj['caught']}; after (min/median/max) "
          f"{inj['caught_after_s']} s, turned meanwhile {inj['turned_deg']} deg")
    for r in inj["not_caught"]:
        print(f"  not caught: {r}")
    print(f"({out['wall_s']} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
