"""``autopilot campaign``: robustness campaigns, and ``--replay`` of one run."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from pathlib import Path

from autopilot.schema import ConfigError


def load_campaign(spec_path):
    """Read, check and resolve a spec file (every error names the file and the key); a shipped spec may be named
    (``pond-robustness``), as missions are: from an installed wheel the README's config/campaigns/... is not there."""
    from autopilot.campaign.spec import load_spec, resolve
    from autopilot.resources import shipped_campaigns

    if not Path(spec_path).exists():
        shipped = {p.stem: p for p in shipped_campaigns()}
        name = Path(spec_path).stem if Path(spec_path).suffix in (".yaml", ".yml", "") else None
        if name in shipped and (Path(spec_path).parent == Path(".") or Path(spec_path).parts[-2:-1] == ("campaigns",)):
            spec_path = shipped[name]
    spec = load_spec(spec_path)
    try:
        return resolve(spec, base_dir=Path(spec_path).resolve().parent)
    except ConfigError as exc:
        raise ConfigError(f"{spec_path}: {exc}") from None


def _whole_number(text: str) -> int:
    """An integer read as the spec reads one (its YAML: 4000, 4_000 or 4e3): ``runs: 4e3`` in a spec was read
    while ``--runs 4e3`` was refused as 'invalid int value'."""
    import yaml

    from autopilot.userfile import parse_yaml

    try:
        value = parse_yaml(text)
    except yaml.YAMLError:
        value = None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not float(value).is_integer():
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number")
    return int(value)


@contextlib.contextmanager
def _terminate_as_exit():
    """SIGTERM (``kill PID``, a service manager) unwinds as Ctrl-C does, through the backends' clean-up: the
    default action killed this process alone and left its pool's workers flying for a minute, orphaned."""
    def handler(signum, frame):
        raise SystemExit(128 + signum)

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (a test calling in): nothing to install
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _cmd(args: argparse.Namespace) -> int:
    if args.replay is not None:
        return _replay(args)
    if args.log is not None:  # it was ignored without a word
        raise ConfigError("--log FILE is for --replay DIR INDEX (a new campaign writes DIR/runs.csv)")
    if args.spec is None:
        raise ConfigError("give a spec file (autopilot campaign SPEC.yaml --out DIR) or --replay DIR INDEX")
    if args.out is None:
        raise ConfigError("--out DIR: where the campaign writes runs.csv, summary.json and report.html")
    if args.jobs is not None and args.scheduler is not None:
        raise ConfigError("--jobs and --scheduler: give one (--jobs: local processes; --scheduler: a Dask cluster)")
    if args.jobs is not None and args.jobs < 1:
        raise ConfigError(f"--jobs: {args.jobs} is not a positive number of processes")
    if args.seed is not None and not 0 <= args.seed < 2**63:
        raise ConfigError(f"--seed: {args.seed} is outside [0, 2^63 - 1]")
    from autopilot.campaign.report import success_table_markdown
    from autopilot.campaign.run import run_campaign

    campaign = load_campaign(args.spec)
    if args.jobs is not None:
        from autopilot.campaign.backends import default_jobs

        if args.jobs > default_jobs():
            print(f"autopilot campaign: --jobs {args.jobs}: this machine gives this process {default_jobs()} "
                  f"core(s); using {default_jobs()} (more processes than cores only slow the runs)", file=sys.stderr)
    with _terminate_as_exit():
        summary = run_campaign(campaign, args.out, seed=args.seed, runs=args.runs, jobs=args.jobs,
                               scheduler=args.scheduler, progress=not args.quiet, report=not args.no_report,
                               overwrite=args.overwrite)
    o = summary["overall"]
    print(f"{summary['campaign']}: {o['successes']}/{o['runs']} runs succeeded "
          f"({100 * o['rate']:.1f} %, Wilson 95 % [{100 * o['ci95'][0]:.1f}, {100 * o['ci95'][1]:.1f}] %); "
          f"{summary['run']['elapsed_s']:.1f} s on {summary['run']['backend']}")
    print(success_table_markdown(summary))
    if summary["cells_not_flown"]:
        print(f"note: {len(summary['cells_not_flown'])} of {summary['cells']} cells (mission x law x condition) "
              f"not flown with {o['runs']} runs: give --runs {summary['cells']} or more to fly each at least once")
    print(f"written: {Path(args.out) / 'runs.csv'}, summary.json" + ("" if args.no_report else ", report.html"))
    return 0


def _replay(args: argparse.Namespace) -> int:
    from autopilot.campaign.replay_run import replay, same_row, scorecard_text

    out_dir, index_text = args.replay
    try:
        index = int(index_text)
    except ValueError:
        raise ConfigError(f"--replay {out_dir} {index_text}: INDEX is a run's index (an integer)") from None
    if args.spec is not None:
        raise ConfigError("--replay re-flies a run from DIR/campaign.json: give no spec file")
    given = [o for o, v in (("--runs", args.runs), ("--seed", args.seed), ("--jobs", args.jobs),
                            ("--scheduler", args.scheduler)) if v is not None]
    if given:  # taken and ignored without a word (a new user's test): the run is the campaign's own
        raise ConfigError(f"--replay re-flies run INDEX as DIR/campaign.json flew it (its seed and runs): "
                          f"{', '.join(given)} {'has' if len(given) == 1 else 'have'} no say; leave "
                          f"{'it' if len(given) == 1 else 'them'} out")
    if args.out is not None:
        raise ConfigError("--replay writes the run's log to DIR/replay-INDEX.jsonl, or to --log FILE: --out is "
                          "for a new campaign")
    if args.log is not None:
        from autopilot.userfile import output_file

        output_file(args.log, what="--log", suffixes=(".jsonl",))
        if Path(args.log).exists() and not args.overwrite:  # a mission log of the boat was replaced without a word
            raise ConfigError(f"--log {args.log}: exists; give a new file, or --overwrite to replace it")
    row, path, table = replay(out_dir, index, log_path=args.log)
    print(scorecard_text(row))
    print(f"log: {path} (autopilot review {path} --out DIR)")
    if table is None:
        print("runs.csv: not found; nothing to compare with")
        return 0
    if same_row(row, table, keys=list(table)):
        print("identical to its row in runs.csv")
        return 0
    diff = [k for k in table if not same_row(row, table, keys=[k])]
    print(f"DIFFERS from its row in runs.csv: {', '.join(diff)}", file=sys.stderr)
    return 1


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "campaign",
        help="robustness campaign: thousands of simulated missions over parameter and disturbance spreads",
        description=(
            "Fly the spec's missions x guidance laws x condition spreads many times on simulated time, each run "
            "with its own vessel parameters, current, wind, sinusoidal force, thrust asymmetry, a weak motor and "
            "lag, sensor noise, dropouts and faults, drawn from (seed, index); every run goes through the daemon's own cycle "
            "(navigation assembly, failsafe, helm, allocation). Runs are flown in lockstep, chunk by chunk, in a "
            "local process pool (--jobs) or on a Dask cluster (--scheduler). Writes DIR/runs.csv, "
            "DIR/summary.json (success rate with its Wilson 95 % interval, distributions, failsafes, worst runs, "
            "sensitivity) and DIR/report.html. --replay DIR INDEX re-flies one run and writes its mission log "
            "(autopilot review reads it)."
        ),
    )
    p.add_argument("spec", nargs="?", metavar="SPEC.yaml", help="the campaign spec (e.g. config/campaigns/pond-robustness.yaml)")
    p.add_argument("--out", metavar="DIR", help="output directory")
    p.add_argument("--runs", type=_whole_number, metavar="N", help="number of runs (default: the spec's runs)")
    p.add_argument("--seed", type=_whole_number, metavar="S", help="campaign seed (default: the spec's seed)")
    p.add_argument("--jobs", type=int, metavar="J", help="local worker processes (default: this machine's cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a Dask scheduler, tcp://HOST:PORT (dask-jobqueue, dask-kubernetes, dask-scheduler), "
                        "or 'local' for a LocalCluster on this machine's cores")
    p.add_argument("--replay", nargs=2, metavar=("DIR", "INDEX"), help="re-fly run INDEX of the campaign in DIR and "
                   "write its mission log (DIR/replay-INDEX.jsonl)")
    p.add_argument("--log", metavar="FILE", help="with --replay: write the log here instead")
    p.add_argument("--overwrite", action="store_true", help="replace the results of an earlier campaign in DIR "
                   "(without it such a DIR is refused)")
    p.add_argument("--no-report", action="store_true", help="skip report.html")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=_cmd)
