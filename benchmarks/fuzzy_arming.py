"""The fuzzy law's pass arming (``gnc.guidance.fuzzy.arm_bearing_deg`` / ``arm_abeam_nd``) over the shipped campaign.

TCPA' < 0 counts a waypoint "passed" only once the pass test is armed. Armed on TCPA' >= 0 alone (the
old test; ``arm_bearing_deg`` 90 and ``arm_abeam_nd`` 0), a waypoint nearly abeam at a sharp corner
armed on a TCPA' just above 0 and was counted passed 10.8 m off as the turn swung the course. This
flies the fuzzy runs of ``config/campaigns/pond-robustness.yaml`` (the same draws for every setting:
vessel spread, current, wind, gusts, thruster faults, sensor dropouts) with each setting and prints
the success rate, how many runs complete, circle or run out of time, and the spread of the worst
closest approach of the runs that complete.

    python benchmarks/fuzzy_arming.py [--runs 1440] [--jobs 2] [--markdown]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

from autopilot.campaign.backends import run_chunks
from autopilot.campaign.cli import load_campaign
from autopilot.campaign.results import wilson
from autopilot.resources import campaigns_dir

# (arm bearing deg, arm abeam L, pass radius L); (90, 0, 3) arms as before: TCPA' >= 0 (but with way on)
SETTINGS = ((90.0, 0.0, 3.0), (45.0, 1.0, 3.0), (45.0, 0.5, 3.0), (60.0, 1.0, 3.0),
            (45.0, 1.0, 2.0), (45.0, 1.0, 1.5), (45.0, 1.0, 1.0))
SHIPPED = (45.0, 1.0, 1.0)


def campaign_with(bearing_deg: float, abeam_nd: float, pass_radius_nd: float = 3.0):
    c = load_campaign(campaigns_dir() / "pond-robustness.yaml")
    g = c.spec.gnc
    fuzzy = replace(g.guidance.fuzzy, arm_bearing_deg=bearing_deg, arm_abeam_nd=abeam_nd, pass_radius_nd=pass_radius_nd)
    return replace(c, spec=replace(c.spec, laws=("fuzzy",), gnc=replace(g, guidance=replace(g.guidance, fuzzy=fuzzy))))


def quantile(values: list[float], q: float) -> float:
    v = sorted(values)
    return v[int(round(q * (len(v) - 1)))] if v else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1440, help="fuzzy runs per setting (default 1440, the shipped campaign's)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args(argv)
    lines = ["| arm bearing (deg) | arm abeam (L) | pass radius (L) | success | completed | out of time | circled | "
             "worst closest approach p50 / p95 / p99 / max (m) | passes > 2.5 m |", "|---|---|---|---|---|---|---|---|---|"]
    for bearing, abeam, radius in SETTINGS:
        c = campaign_with(bearing, abeam, radius)
        t0 = time.perf_counter()
        rows = run_chunks(c, c.spec.seed, args.runs, jobs=args.jobs)
        ok = sum(r["success"] for r in rows)
        lo, hi = wilson(ok, len(rows))
        done = [r["closest_max_m"] for r in rows if r["completed"]]
        q = " / ".join(f"{quantile(done, p):.2f}" for p in (0.5, 0.95, 0.99, 1.0))
        mark = " (shipped)" if (bearing, abeam, radius) == SHIPPED else ""
        far = sum(1 for r in rows for d in r["closest_approach_m"].split(";") if d and 2.5 < float(d) < float("inf"))
        lines.append(f"| {bearing:g}{mark} | {abeam:g} | {radius:g} | {100 * ok / len(rows):.1f} % [{100 * lo:.1f}, "
                     f"{100 * hi:.1f}] | {len(done)} | {sum(r['end'] == 'time' for r in rows)} | "
                     f"{sum(r['circled'] for r in rows)} | {q} | {far} |")
        if not args.markdown:
            print(lines[-1], f"({time.perf_counter() - t0:.0f} s)", flush=True)
    if args.markdown:
        print(f"{len(rows)} fuzzy runs of pond-robustness per setting, {time.strftime('%Y-%m-%d')}\n")
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
