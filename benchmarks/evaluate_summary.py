"""Guidance scorecard summary: `autopilot evaluate --json` over every shipped mission, law and condition.

Prints, per law and condition: missions completed, worst closest approach to a waypoint (m),
mean cross-track RMS (m), mean time (s) and energy (N s), runs flagged as circling; then the
runs where LOS beats fuzzy on cross-track RMS.

    python benchmarks/evaluate_summary.py [--markdown]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections import defaultdict


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    proc = subprocess.run([sys.executable, "-m", "autopilot", "evaluate", "--json"], capture_output=True, text=True, check=True)
    runs = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    groups = defaultdict(list)
    for r in runs:
        groups[(r["guidance"], r["condition"])].append(r)
    header = ("law", "condition", "completed", "worst closest approach (m)", "mean xte RMS (m)", "mean time (s)", "mean energy (N s)", "circled")
    rows = []
    for (law, cond), rs in groups.items():
        worst = max((c for r in rs for c in r["closest_approach_m"] if c is not None), default=float("nan"))
        rows.append(
            (
                law,
                cond,
                f"{sum(r['completed'] for r in rs)}/{len(rs)}",
                f"{worst:.2f}",
                f"{sum(r['xte_rms_m'] for r in rs) / len(rs):.2f}",
                f"{sum(r['time_s'] for r in rs) / len(rs):.0f}",
                f"{sum(r['energy_ns'] for r in rs) / len(rs):.0f}",
                str(sum(bool(r.get("circled")) for r in rs)),
            )
        )
    if args.markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for row in rows:
            print("| " + " | ".join(row) + " |")
    else:
        widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
        for row in (header, *rows):
            print("  ".join(str(x).ljust(w) for x, w in zip(row, widths)))
    by_key = {(r["mission"], r["condition"], r["guidance"]): r for r in runs}
    wins = [
        (m, c) for (m, c, g) in by_key if g == "fuzzy" and (m, c, "los") in by_key and by_key[(m, c, "los")]["xte_rms_m"] < by_key[(m, c, "fuzzy")]["xte_rms_m"]
    ]
    print(f"\nLOS has the lower cross-track RMS in {len(wins)} of {sum(1 for k in by_key if k[2] == 'fuzzy')} mission x condition runs:")
    print(", ".join(f"{m}/{c}" for m, c in sorted(wins)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
