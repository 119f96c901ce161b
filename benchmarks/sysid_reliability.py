"""How often the identification tells the truth (issue 12, "Show"), over many random draws.

Cases (autopilot/sysid/cases.py): each listed effect alone, nothing hidden, pairs (current +
thrust_lag, heading_bias + wind_force, thrust_asymmetry + thrust_deadband), an effect outside the
list (a thrust that fades as the battery sags), all in realistic trials (issue 12's measurement
model: 1 Hz fixes held on 10 Hz rows or empty cells, wandering GPS error, outliers, a wandering
quantised heading); closed-loop mission logs flown by `autopilot run --sim` over the pond missions,
with a hidden 0.2 m/s current and with nothing hidden (4800 baud, the SC-30's speed and course over ground
with a 0.03-0.1 m/s velocity error); the realistic trials again with speed and course over ground
(``velocity``); the original white-noise 10 Hz trials; and each listed effect again in the realistic
trials but drawn below what the GPS wander lets one see (``small``, ranges in cases.SMALL_RANGES).

Per draw it records: the right verdict (the exact set of listed effects; `none` when nothing is
hidden; `unexplained` or a model flagged not adequate for the unlisted effect), whether each hidden
parameter's 95 % interval covers the truth, and the held-out error beyond the noise before and
after (the cut is checked where the effect moved the track by more than twice the noise). A small
effect may rightly be missed: its draws are scored by outcome (exact, none, inconclusive, a wrong
effect named, unexplained) and, beside none and inconclusive, whether the effect is among what the
trials cannot rule out (its 95 % interval in ``not_excluded`` covering the truth).

    python benchmarks/sysid_reliability.py --seeds 20                      # every group, ~2 h on 1 core
    python benchmarks/sysid_reliability.py --seeds 10 --groups single,none --jobs 2
    python benchmarks/sysid_reliability.py --seeds 5 --groups closed_loop   # flies 5 pond logs per draw
    python benchmarks/sysid_reliability.py --seeds 10 --groups closed_loop_wind --jobs 1
    python benchmarks/sysid_reliability.py --seeds 2 --groups small --jsonl small.jsonl
    python benchmarks/sysid_reliability.py --summarise draws.jsonl           # the tables of a run so far

Every draw's record is appended to ``--jsonl`` as it completes, so a sweep that is stopped (or
loses its machine) keeps what it measured: ``--summarise`` prints the tables of those draws. The
seeds are drawn from the master seed in the order of the groups given, so a sweep over the first
groups of GROUPS, in that order, draws the same seeds as the full one.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # a checkout's own package, installed or not
# one BLAS thread per worker, as the `autopilot` command runs, set there before numpy is imported (the workers are
# forked from this process: set in the worker, it came too late and two draws at once ran 3x slower)
import autopilot.cli  # noqa: F401,E402

GROUPS = ("single", "none", "pairs", "unlisted", "closed_loop", "velocity", "white", "small", "closed_loop_wind",
          "closed_loop_motor", "closed_loop_pairs")
# new groups last: the earlier groups keep their seeds. A new effect in cases.VISIBLE is a new case of single,
# velocity, white and small, and shifts the seeds of every case after it (weak_motor, 2026-12-06)


def cases_of(groups):
    from autopilot.sysid.cases import DRAWS, PAIRS, UNLISTED, Case

    out = []
    for g in groups:
        if g == "single":
            out += [Case((e,)) for e in DRAWS]
        elif g == "none":
            out.append(Case(()))
        elif g == "pairs":
            out += [Case(p) for p in PAIRS]
        elif g == "unlisted":
            out += [Case((e,)) for e in UNLISTED]
        elif g == "closed_loop":
            out += [Case(("current",), kind="closed_loop", n_trials=5), Case((), kind="closed_loop", n_trials=5)]
        elif g == "closed_loop_wind":  # the simulator's windage (cases.CLOSED_LOOP_WIND_M_S) in five pond logs
            out.append(Case(("wind",), kind="closed_loop", n_trials=5))
        elif g == "closed_loop_motor":  # a weak motor (the simulated Mbed's sim.thrust_gain_*) in three pond logs
            out.append(Case(("weak_motor",), kind="closed_loop", n_trials=3))
        elif g == "closed_loop_pairs":  # two effects at once in three pond logs (a sysid audit, 2026-12-06)
            out += [Case(p, kind="closed_loop", n_trials=3)
                    for p in (("current", "weak_motor"), ("current", "wind"), ("wind", "weak_motor"))]
        elif g == "velocity":  # the realistic trials with the receiver's speed and course over ground too
            out += [Case((e,), velocity=True) for e in DRAWS] + [Case((), velocity=True)]
        elif g == "white":
            out += [Case((e,), kind="white") for e in DRAWS] + [Case((), kind="white")]
        elif g == "small":  # the single group's trials, each effect below its visible range
            out += [Case((e,), small=True) for e in DRAWS]
    return out


def one(case, seed: int) -> dict:
    """One draw of one case, scored (a pure function of (case, seed))."""
    sys.path.insert(0, str(ROOT))
    from autopilot.sim import default_params_path, load_params
    from autopilot.sysid import identify
    from autopilot.sysid.cases import make, score

    vessel = load_params(default_params_path())
    t0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="sysid-bench-") as work:
            hidden, trials, desc = make(case, seed, vessel, work_dir=work)
            t1 = time.perf_counter()
            result = identify(trials, vessel)
        s = score(case, hidden, result)
        s.update(hidden=hidden, fitted=result.chosen.values() if result.verdict else {}, measurement=desc,
                 identify_s=time.perf_counter() - t1, notes=result.notes)
    except Exception as exc:  # a crash counts as a miss, with its reason
        s = {"right": False, "error": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc(limit=3)}
    s.update(case=case.label, seed=seed, wall_s=time.perf_counter() - t0)
    return s


def table(results: list[dict]) -> str:
    rows = ["| case | right | 95 % intervals cover | cut >= 70 % where moved > 2 noise | median identify (s) |",
            "|---|---|---|---|---|"]
    for label in dict.fromkeys(r["case"] for r in results):
        mine = [r for r in results if r["case"] == label]
        right = sum(bool(r.get("right")) for r in mine)
        cov = [c for r in mine for c in r.get("covered95", {}).values()]
        cuts = [ch["cut"] for r in mine for ch in r.get("error_cut", {}).values()
                if ch.get("cut") is not None and ch["moved_noise"] > 2.0 and r.get("right") and r.get("verdict")]
        walls = sorted(r.get("identify_s", r["wall_s"]) for r in mine)
        rows.append(f"| {label} | {right}/{len(mine)} | {f'{sum(cov)}/{len(cov)}' if cov else '-'} | "
                    f"{f'{sum(c >= 0.7 for c in cuts)}/{len(cuts)}' if cuts else '-'} | {walls[len(walls) // 2]:.0f} |")
    return "\n".join(rows)


# issue 12's aims: (what, the draws it counts, the rate aimed at)
AIMS = (
    ("a listed effect alone named exactly", lambda c: c.kind == "realistic" and len(c.effects) == 1 and not c.unlisted
     and not c.velocity and not c.small, 0.95),
    ("a pair named exactly", lambda c: len(c.effects) == 2, 0.90),
    ("nothing hidden: none (realistic trials)", lambda c: c.kind == "realistic" and not c.effects, 0.95),
    ("nothing hidden: none (closed-loop logs)", lambda c: c.kind == "closed_loop" and not c.effects, 0.95),
    ("0.2 m/s current named from five pond logs", lambda c: c.kind == "closed_loop" and c.effects == ("current",), None),
    ("3-6 m/s of wind named from five pond logs", lambda c: c.kind == "closed_loop" and c.effects == ("wind",), None),
    ("an effect outside the list: unexplained or flagged not adequate", lambda c: c.unlisted, 0.80),
    ("with speed and course over ground: named exactly (or none)", lambda c: c.velocity, 0.95),
    ("white-noise 10 Hz trials: named exactly (or none)", lambda c: c.kind == "white", None),
    # no aim in issue 12: the README asks only that a small effect is never a confident wrong name
    ("a small effect: named exactly, none or inconclusive (no other effect, not unexplained)", lambda c: c.small, None),
)


def aims(results: list[dict], cases: dict) -> str:
    """The rates issue 12 aims at, over the draws run (a row per aim that had draws)."""
    rows = ["| aim | rate | draws |", "|---|---|---|"]
    for what, counts, aim in AIMS:
        mine = [r for r in results if counts(cases[r["case"]])]
        if mine:
            right = sum(bool(r.get("right")) for r in mine)
            rows.append(f"| {what}{f' (aim >= {aim:.0%})' if aim else ''} | {right / len(mine):.0%} | {right}/{len(mine)} |")
    cov = [c for r in results for c in r.get("covered95", {}).values()]
    if cov:
        rows.append(f"| 95 % intervals covering the truth (aim 90-99 %) | {sum(cov) / len(cov):.0%} | {sum(cov)}/{len(cov)} parameters |")
    cuts = [ch["cut"] for r in results for ch in r.get("error_cut", {}).values()
            if ch.get("cut") is not None and ch["moved_noise"] > 2.0 and r.get("right") and r.get("verdict")]
    if cuts:
        ok = sum(c >= 0.7 for c in cuts)
        rows.append(f"| held-out error beyond the noise cut >= 70 % where the effect moved the track > 2 noise "
                    f"| {ok / len(cuts):.0%} | {ok}/{len(cuts)} channels |")
    return "\n".join(rows)


def small_table(results: list[dict]) -> str:
    """The small effects' outcomes per case (draws out of all); "interval misses": named exactly with a
    95 % interval missing the truth; "not ruled out": none or inconclusive with the effect in
    not_excluded, every interval covering the truth."""
    mine = [r for r in results if r["case"].endswith("+small")]
    if not mine:
        return ""
    kinds = ("exact", "none", "inconclusive", "wrong", "unexplained")
    rows = ["| case | draws | " + " | ".join(kinds) + " | interval misses | not ruled out (of none + inconclusive) |",
            "|---|---|" + "---|" * (len(kinds) + 2)]
    for label in dict.fromkeys(r["case"] for r in mine):
        rs = [r for r in mine if r["case"] == label]
        count = {k: sum(r.get("outcome", "error") == k for r in rs) for k in kinds}
        misses = sum(not all(r.get("covered95", {}).values()) for r in rs if r.get("outcome") == "exact")
        quiet = [r for r in rs if r.get("outcome") in ("none", "inconclusive")]
        kept = sum(_not_ruled_out(r) for r in quiet)
        errors = len(rs) - sum(count.values())
        rows.append(f"| {label} | {len(rs)}{f' ({errors} crashed)' if errors else ''} | "
                    + " | ".join(str(count[k]) for k in kinds) + f" | {misses} | {kept}/{len(quiet)} |")
    return "\n".join(rows)


def _not_ruled_out(r: dict) -> bool:
    ne = r.get("not_excluded") or {}
    return bool(ne.get("listed")) and bool(ne.get("covers")) and all(ne["covers"].values())


def summarise(path: Path) -> int:
    """The tables of the draws recorded in a --jsonl file (a sweep stopped early included)."""
    results = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    if not results:
        print(f"{path}: no draws recorded", file=sys.stderr)
        return 1
    cases = {c.label: c for c in cases_of(GROUPS)}
    unknown = sorted({r["case"] for r in results} - set(cases))
    if unknown:
        print(f"{path}: cases not in this benchmark: {', '.join(unknown)}", file=sys.stderr)
        return 1
    print(f"{len(results)} draws from {path}")
    print("\n" + table(results))
    print("\n" + aims(results, cases))
    if small_table(results):
        print("\n" + small_table(results))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="random draws per case")
    ap.add_argument("--groups", default=",".join(GROUPS), help=f"comma-separated: {', '.join(GROUPS)}")
    ap.add_argument("--only", default="", help="comma-separated case labels (e.g. current/realistic)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--master-seed", type=int, default=None, help="seed of the seeds (default: random, printed)")
    ap.add_argument("--json", help="write every draw's record here (a JSON list, at the end)")
    ap.add_argument("--jsonl", help="append every draw's record here as it completes (one JSON object a line)")
    ap.add_argument("--summarise", metavar="JSONL", help="print the tables of the draws recorded in JSONL and stop")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    if args.summarise:
        return summarise(Path(args.summarise))
    groups = [g for g in args.groups.split(",") if g]
    bad = [g for g in groups if g not in GROUPS]
    if bad:
        ap.error(f"unknown group(s) {bad}; allowed: {', '.join(GROUPS)}")
    cases = cases_of(groups)
    if args.only:
        cases = [c for c in cases if c.label in args.only.split(",")]
    master = args.master_seed if args.master_seed is not None else random.SystemRandom().getrandbits(31)
    rnd = random.Random(master)
    jobs = [(c, rnd.getrandbits(31)) for c in cases for _ in range(args.seeds)]
    print(f"{len(jobs)} draws, master seed {master}, {args.jobs} process(es), {time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    results = []
    jsonl = open(args.jsonl, "a", encoding="utf-8") if args.jsonl else None  # noqa: SIM115 (open for the sweep)
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for r in pool.map(one, *zip(*jobs)):
            results.append(r)
            flag = "ok " if r.get("right") else "MISS"
            print(f"  {flag} {r['case']:36s} seed {r['seed']:10d} {r['wall_s']:5.1f} s  {r.get('status', '')} "
                  f"{r.get('verdict', '')} {r.get('outcome', '')} {r.get('error', '')}", flush=True)
            if jsonl:
                jsonl.write(json.dumps(r, default=str) + "\n")
                jsonl.flush()
    if jsonl:
        jsonl.close()
    print("\n" + table(results))
    print("\n" + aims(results, {c.label: c for c in cases}))
    if small_table(results):
        print("\n" + small_table(results))
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
