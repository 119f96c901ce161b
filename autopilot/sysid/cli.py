"""`autopilot sysid`: name the effect the model is missing, on trials, mission logs or a steady table."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

from autopilot.schema import ConfigError


def register(subparsers) -> None:
    from autopilot.sysid.trials import CSV_HELP, LONG_TRIAL_S, PIECE_MAX_S

    p = subparsers.add_parser(
        "sysid",
        help="find where simulation and measurements disagree, name the missing effect, fit it",
        description=(
            "Replay measured trials (CSV files, one per trial, columns below) or daemon mission logs (.jsonl) "
            "through the simulator, fit every candidate effect, choose by BIC confirmed on held-out "
            "trials, and write DIR/summary.json, DIR/report.html, DIR/vessel-updated.yaml, DIR/effects.yaml. "
            f"A trial longer than {LONG_TRIAL_S:g} s is cut into pieces of at most {PIECE_MAX_S:g} s, each replayed "
            "from its own state. With --table, examine a steady-state table (SPEC 6) instead."
        ),
        epilog=CSV_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("trials", nargs="*", metavar="TRIAL", help="trial CSV files or mission logs (.jsonl)")
    p.add_argument("--params", help="vessel parameter YAML (default: the shipped vessel.yaml, which `autopilot "
                   "files` shows; a config/vessel.yaml here is not read unless given)")
    p.add_argument("--table", help="steady-state table CSV: name,thrust_port_n,thrust_stbd_n,yaw_rate_rad_s,speed_m_s")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--effects", help="comma-separated candidate identifiers (default: all)")
    p.add_argument("--top-k", type=int, default=3, help="candidates fitted fully after screening (default 3)")
    p.add_argument("--gps-wander-max", type=float, metavar="M",
                   help="largest wandering GPS error your receiver has, 1 sigma per axis (m; default 3): a residual "
                        "needing more is model error (autopilot/sysid/noise.py NoiseBounds)")
    p.add_argument("--heading-wander-max", type=float, metavar="DEG",
                   help="largest wandering heading error of your compass (deg; default 1)")
    p.add_argument("--no-report", action="store_true",
                   help="skip report.html (faster; an earlier run's report.html in DIR is removed)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run_cli)


SYSID_OUTPUTS = ("summary.json", "report.html", "vessel-updated.yaml", "effects.yaml")  # what --out receives


def is_sysid_summary(summary) -> bool:
    """A summary.json this command wrote (of trials or of a table)."""
    return isinstance(summary, dict) and summary.get("mode") in ("trials", "table") and "verdict" in summary


def run_cli(args: argparse.Namespace) -> int:
    from autopilot.sim import default_params_path, load_params
    from autopilot.userfile import output_dir

    params_path = Path(args.params) if args.params else default_params_path()
    vessel = load_params(params_path)
    created = not Path(args.out).exists()
    output_dir(args.out, files=SYSID_OUTPUTS, summary_is_ours=is_sysid_summary,  # before the fit, not after it
               command="autopilot sysid")
    if args.no_report:  # an earlier run's report beside this run's summary showed the other verdict
        with contextlib.suppress(FileNotFoundError):
            (Path(args.out) / "report.html").unlink()
    try:
        return _run(args, vessel, params_path)
    except ConfigError:
        if created:  # a refused input left an empty --out behind
            with contextlib.suppress(OSError):
                Path(args.out).rmdir()
        raise


def _run(args: argparse.Namespace, vessel, params_path: Path) -> int:
    from autopilot.sysid.effects import EFFECT_NAMES

    log = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    candidates = tuple(EFFECT_NAMES)
    if args.effects is not None:
        candidates = tuple(dict.fromkeys(e.strip() for e in args.effects.split(",") if e.strip()))
        unknown = [e for e in candidates if e not in EFFECT_NAMES]
        if unknown:
            raise ConfigError(f"--effects: unknown effect {unknown[0]!r} (known: {', '.join(EFFECT_NAMES)})")
        if not candidates:  # "--effects ," tested nothing and answered `none` (a sysid audit)
            raise ConfigError(f"--effects {args.effects!r}: no effect named (known: {', '.join(EFFECT_NAMES)}; "
                              "leave --effects out for all)")
    if args.table:
        if args.trials:
            raise ConfigError("give either trial files or --table, not both")
        # a steady-state table has no sensor noise to bound: the option was taken and did nothing (a new user's test)
        given = [o for o, v in (("--gps-wander-max", args.gps_wander_max), ("--heading-wander-max",
                                                                           args.heading_wander_max)) if v is not None]
        if given:
            raise ConfigError(f"{' and '.join(given)}: bound the trials' sensor noise; a steady-state table (--table) "
                              "has none: leave them out")
        return _table(args, vessel, params_path, candidates if args.effects is not None else None, log)
    if not args.trials:
        raise ConfigError("no trial files (or use --table)")
    if args.top_k < 1:
        raise ConfigError("--top-k must be at least 1")
    from autopilot.sysid.trials import read_trial
    from autopilot.sysid.workflow import run

    bounds = _bounds(args)
    _distinct_files(args.trials)
    trials = _named_apart(args.trials, [read_trial(p) for p in args.trials])
    _distinct_trials(args.trials, trials)
    for path, trial in zip(args.trials, trials):
        for note in trial.read_notes:
            print(f"{path}: {note}", file=sys.stderr)
    summary = run(trials, vessel, args.out, params_file=str(params_path), candidates=candidates,
                  top_k=args.top_k, report=not args.no_report, log=log, bounds=bounds)
    _print(summary, args.out)
    return 0


def _bounds(args):
    """NoiseBounds from --gps-wander-max / --heading-wander-max (ConfigError naming the option and range)."""
    import dataclasses
    import math

    from autopilot.sysid.noise import NoiseBounds

    changes = {}
    for opt, value, name in (("--gps-wander-max", args.gps_wander_max, "position_wander_max_m"),
                             ("--heading-wander-max", args.heading_wander_max, "heading_wander_max_deg")):
        if value is None:
            continue
        meta = next(f for f in dataclasses.fields(NoiseBounds) if f.name == name).metadata
        if not (math.isfinite(value) and meta["lo"] <= value <= meta["hi"]):
            raise ConfigError(f"{opt}: {value!r} is outside the allowed range [{meta['lo']:g}, {meta['hi']:g}] {meta['unit']}")
        changes[name] = value
    return dataclasses.replace(NoiseBounds(), **changes)


def _named_apart(paths, trials) -> list:
    """Trials named by their files' stems, those sharing one (day1/zigzag.jsonl, day2/zigzag.jsonl) by their paths
    as given: cut into pieces, two logs of one name gave six pieces named alike in the notes, the folds and the
    report (a sysid audit)."""
    import collections
    import dataclasses

    named = list(trials)
    for _ in range(3):  # a path given may be another trial's name (zigzag.jsonl.gz is named zigzag.jsonl): again
        count = collections.Counter(t.name for t in named)
        named = [dataclasses.replace(t, name=str(p)) if count[t.name] > 1 else t for p, t in zip(paths, named)]
    return named


SAME_TRIAL_SHARE = 0.9  # two trials whose fixes coincide (to the centimetre) this often are one trial
NEAR = (-0.01, 0.0, 0.01)  # m: the centimetre either side a rounded step may fall


def _distinct_trials(paths, trials) -> None:
    """The same trial in two files of different bytes (a log and its gzip copy beside it, a log and its CSV
    export): fitted twice, it halved the intervals and each held-out trial had its twin in the fit. Told by
    the fixes: GPS noise never repeats a run of steps between them to the centimetre."""
    import numpy as np

    seen: list[tuple[str, set]] = []
    for p, tr in zip(paths, trials):
        rows = tr.fix_rows
        # each fix's step from the one before, to the centimetre: the same in any local frame (a lat/lon-only
        # CSV of a log is in metres from its own first fix, and was fitted beside the log as another trial)
        fixes = set(zip(np.round(np.diff(tr.north_m[rows]), 2).tolist(), np.round(np.diff(tr.east_m[rows]), 2).tolist()))
        if len(fixes) < 10:
            continue
        for q, other in seen:
            # a step matches one within a centimetre: a CSV export's millimetre positions round a step across a
            # centimetre now and then, and a log with its own export came out 39 of 44 alike (a new-user audit)
            alike = sum(any((round(n + dn, 2), round(e + de, 2)) in other for dn in NEAR for de in NEAR)
                        for n, e in fixes)
            if alike >= SAME_TRIAL_SHARE * min(len(fixes), len(other)):
                raise ConfigError(f"{p}: the same trial as {q} (its position fixes move alike, to the centimetre): "
                                  "give each trial once")
        seen.append((str(p), fixes))


def _distinct_files(paths) -> None:
    """The same trial twice (by name or a copy) would be fitted twice and held out against itself."""
    import hashlib

    seen: dict[str, str] = {}
    for p in paths:
        try:
            digest = hashlib.sha256(Path(p).read_bytes()).hexdigest()
        except OSError:
            continue  # read_trial says what is wrong with it
        if digest in seen:
            raise ConfigError(f"{p}: the same data as {seen[digest]}: give each trial once")
        seen[digest] = str(p)


def _table(args, vessel, params_path, candidates, log) -> int:
    from autopilot.sysid.output import (
        write_effects_yaml,
        write_json,
        write_vessel_updated,
    )
    from autopilot.sysid.table import (
        TABLE_CANDIDATES,
        identify_table,
        read_table_csv,
        table_figure,
    )

    rows = read_table_csv(args.table)
    t0 = time.perf_counter()
    summary = identify_table(rows, vessel, candidates=candidates or TABLE_CANDIDATES, log=log)
    summary["seconds"] = time.perf_counter() - t0
    summary["params_file"] = str(params_path)
    summary["table_file"] = str(args.table)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    verdict = tuple(v for v in summary["verdict"] if v != "none")
    write_vessel_updated(vessel, summary.pop("values"), verdict, out / "vessel-updated.yaml", source=str(args.table))
    write_effects_yaml(summary["effects"], out / "effects.yaml")
    summary["outputs"] = {"summary": "summary.json", "vessel": "vessel-updated.yaml", "effects": "effects.yaml"}
    if not args.no_report:
        import matplotlib

        matplotlib.use("Agg")
        from autopilot.sysid import report as rep

        figs = {"Steady states: measured, model before and after": rep.png(table_figure(summary))}
        rep.write_html(out / "report.html", summary, figs)
        summary["outputs"]["report"] = "report.html"
    write_json(summary, out / "summary.json")
    _print(summary, args.out)
    return 0


def _why_not_named(c: dict) -> str:
    """What a second effect beside the named model lacked (identification.beside's figures)."""
    why = []
    if c["delta_bic"] >= -c["bic_margin"]:
        why.append(f"BIC {c['delta_bic']:+.0f} against {c['beside']} alone")
    if c["z"] < c["z_limit"]:
        why.append(f"not clearly away from no effect ({c['z']:.1f} sigma, {c['z_limit']:.1f} needed)")
    if c["explained_nd"] < c["min_effect_size_nd"]:
        why.append(f"too small to matter: it moves the residual by {c['explained_nd']:.2f} of the noise "
                   f"({c['min_effect_size_nd']:g} needed)")
    # all three passed: the held-out trials dropped it (a review: "clearly away, 4.2 sigma" alone read as a reason
    # to name it)
    return "; ".join(why) or (f"BIC {c['delta_bic']:+.0f}, {c['z']:.1f} sigma, size {c['explained_nd']:.2f}: passed, and "
                              "dropped by the held-out trials (see the notes)")


def _why_not(a: dict) -> str:
    """Why a channel whose chi-square passes is still not adequate (judge.channels says)."""
    return f" ({a['why_not']})" if a.get("why_not") else ""


def _print(summary: dict, out) -> None:
    from autopilot.sysid.channels import BY_NAME as CHANNEL_BY_NAME

    print(f"verdict: {', '.join(summary['verdict'])}")
    for ch, a in (summary.get("adequacy") or {}).items():
        c = CHANNEL_BY_NAME[ch]
        unit, k = c.unit, c.key_unit
        print(f"  {ch}: residual {a[f'residual_rms_{k}']:.3g} {unit} against noise {a[f'noise_rms_{k}']:.3g} {unit}, "
              f"chi-square {a['chi2_per_measurement']:.3g} per measurement: {'adequate' if a['adequate'] else 'NOT adequate'}"
              + _why_not(a))
    for name, eff in summary.get("effects", {}).items():
        for p in eff["params"]:
            print(f"  {name}.{p['name']} = {p['value']:.4g} {p['unit']}  (95 %: {p['ci95'][0]:.4g} .. {p['ci95'][1]:.4g})")
    for c in summary.get("nearest") or []:
        worst = ", ".join(f"{ch} chi-square {a['chi2_per_measurement']:.3g}{_why_not(a)}"
                          for ch, a in (c.get("adequacy") or {}).items() if not a["adequate"])
        print(f"  nearest: {c['effect']} (delta BIC {c['delta_bic']:+.0f}; still not adequate: {worst or 'see summary.json'})")
    alone = [c for c in summary.get("not_excluded") or [] if not c.get("beside")]
    if alone:
        shown = ", ".join(f"{c['param']} <= {c['ci95'][1]:.3g} {c['unit']}" if c.get("upper_bound") else
                          f"{c['param']} {c['ci95'][0]:.3g}..{c['ci95'][1]:.3g} {c['unit']}" for c in alone[:6])
        print(f"  not ruled out (95 %): {shown}")
    for c in [c for c in summary.get("not_excluded") or [] if c.get("beside")][:4]:
        shown = (f"<= {c['ci95'][1]:.3g}" if c.get("upper_bound") else f"{c['ci95'][0]:.3g}..{c['ci95'][1]:.3g}")
        print(f"  beside {c['beside']}, fitted and not named (95 %): {c['param']} {shown} {c['unit']}: "
              f"{_why_not_named(c)}")
    for part in ("fitted", "held_out"):
        b, a = summary["rmse_before"][part], summary["rmse_after"][part]
        figures = ", ".join(f"{k} {b[k]:.4g} -> {a[k]:.4g}" for k in b if isinstance(b.get(k), float) and a.get(k) is not None)
        print(f"  {part}: {figures}")
    for note in summary.get("notes", []):
        print(f"  note: {note}")
    print(f"written to {out}/")
