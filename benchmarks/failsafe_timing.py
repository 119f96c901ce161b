"""Time from each fault to zero thrust, at the real line rate, as a range over several runs.

Repeats the fault-injection scenario of ``tests/test_failsafe_faults.py``
(``recoverable_scenario``: the real daemon as a subprocess, without ``--sim``,
against the simulated SC-30 at 4800 baud and the simulated Mbed on
pseudo-terminals, speedup 10, 10 Hz) and prints, per fault, the time from the
fault reaching the wire to the first zero-thrust state the simulated Mbed
applied (min, median, max over the runs) and the budget the test allows. Where
in the 1 Hz cycle a position fault falls varies from run to run.

    python benchmarks/failsafe_timing.py --runs 5 [--markdown]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    from tests.test_failsafe_faults import recoverable_scenario

    per_fault: dict[str, list[float]] = {}
    budgets: dict[str, float] = {}
    for k in range(args.runs):
        with tempfile.TemporaryDirectory(prefix="failsafe-timing-") as tmp:
            _, results, code = asyncio.run(recoverable_scenario(Path(tmp)))
        for name, from_wire_s, budget_s, _ in results:
            per_fault.setdefault(name, []).append(from_wire_s)
            budgets[name] = budget_s
        print(f"run {k + 1}/{args.runs}: exit {code}", file=sys.stderr)
    if args.markdown:
        print(f"| fault | time to zero thrust, min / median / max over {args.runs} runs | budget |")
        print("|---|---|---|")
    for name, xs in per_fault.items():
        lo, med, hi = min(xs), statistics.median(xs), max(xs)
        over = " OVER BUDGET" if hi > budgets[name] else ""
        if args.markdown:
            print(f"| {name} | {lo:.2f} / {med:.2f} / {hi:.2f} s | {budgets[name]:.2f} s |")
        else:
            print(f"{name:22s} {lo:6.3f} {med:6.3f} {hi:6.3f} s   budget {budgets[name]:.3f} s{over}")


if __name__ == "__main__":
    main()
