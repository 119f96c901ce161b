"""A whole campaign into a directory: fly every chunk, then write what it found.

    DIR/campaign.json   the resolved campaign, seed and run count (what --replay re-flies)
    DIR/runs.csv        one row per run (runs.parquet too when pyarrow is installed)
    DIR/summary.json    success rates with Wilson intervals, distributions, failsafes, worst runs, sensitivity
    DIR/report.html     the same with plots
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import time
from pathlib import Path

from autopilot.campaign.backends import Progress, check_backend, default_jobs, run_chunks
from autopilot.campaign.lockstep import chunks
from autopilot.campaign.results import columns, summarise, write_runs_csv, write_summary
from autopilot.campaign.spec import Campaign
from autopilot.schema import ConfigError

__all__ = ["run_campaign", "write_outputs", "load_run_dir", "OUTPUTS", "check_out_dir", "pool_size"]

OUTPUTS = ("campaign.json", "runs.csv", "runs.parquet", "summary.json", "report.html")  # and replay-*.jsonl


def _previous(out: Path) -> list[Path]:
    """A campaign's outputs already in ``out``. A campaign.json alone is a run that never finished (interrupted,
    or refused after it was written): not results to keep, it is written over."""
    found = [p for p in (*(out / n for n in OUTPUTS), *sorted(out.glob("replay-*.jsonl"))) if p.exists()]
    return [] if [p.name for p in found] == ["campaign.json"] else found


def check_out_dir(out_dir, *, overwrite: bool = False) -> Path:
    """Make ``out_dir`` ready before anything is flown: created, writable, no earlier campaign's results in it
    (a new campaign beside an old summary.json and report.html looked complete, and --replay compared runs
    with the old runs.csv), or with ``overwrite`` those removed first. ConfigError naming what is wrong."""
    from autopilot.userfile import output_dir

    out = output_dir(out_dir)
    old = _previous(out)
    if old and not any((out / n).exists() for n in ("campaign.json", "runs.csv", "runs.parquet")):
        # a review's or an identification's summary.json and report.html, which --overwrite deleted as a campaign's
        # (the sysid summary a campaign's vessel spreads pointed at, too: a new user's test)
        raise ConfigError(f"--out {out}: holds another command's results ({', '.join(p.name for p in old[:4])}), not a "
                          "campaign's: give a directory of its own")
    if old and not overwrite:
        raise ConfigError(f"--out {out}: holds a campaign's results already ({', '.join(p.name for p in old[:4])}"
                          f"{', ...' if len(old) > 4 else ''}): give a new directory, or --overwrite to replace them")
    for p in old:
        if p.is_dir():
            raise ConfigError(f"--out {out}: {p.name} is a directory; the campaign writes a file there")
        try:
            p.unlink()
        except OSError as exc:
            raise ConfigError(f"--out {out}: cannot remove the old {p.name} ({exc.strerror or exc})") from None
    probe = out / ".autopilot-write-test"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None
    return out


def pool_size(jobs: int | None, n_chunks: int) -> int:
    """The local processes a campaign uses: ``jobs`` (default: the cores), at most one per chunk and per core
    (``--jobs 1000`` started 40 processes on 2 cores and took 1.7 times as long)."""
    return max(1, min(jobs or default_jobs(), default_jobs(), n_chunks))


def _backend_text(jobs, scheduler) -> str:
    if scheduler is None:
        n = jobs
        return "this process" if n <= 1 else f"a pool of {n} local processes"
    if scheduler == "local":
        return f"a Dask LocalCluster of {default_jobs()} workers"
    return f"the Dask scheduler {scheduler}"


def run_campaign(campaign: Campaign, out_dir, *, seed: int | None = None, runs: int | None = None,
                 jobs: int | None = None, scheduler=None, progress: bool = False, report: bool = True,
                 overwrite: bool = False) -> dict:
    """Fly the campaign and write DIR; returns the summary."""
    seed = campaign.spec.seed if seed is None else int(seed)
    runs = campaign.spec.runs if runs is None else int(runs)
    max_runs = next(f.metadata["hi"] for f in dataclasses.fields(campaign.spec) if f.name == "runs")
    if not 1 <= runs <= max_runs:
        raise ConfigError(f"--runs: {runs} is outside [1, {max_runs:,}] runs (the spec's limit)")
    check_backend(scheduler)
    out = check_out_dir(out_dir, overwrite=overwrite)
    n_chunks = chunks(campaign, runs)
    if scheduler is None:
        jobs = pool_size(jobs, n_chunks)
    data = {"campaign": campaign.to_data(), "seed": seed, "runs": runs}
    (out / "campaign.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    started = _dt.datetime.now(_dt.timezone.utc)
    t0 = time.perf_counter()
    rows = run_chunks(campaign, seed, runs, jobs=jobs, scheduler=scheduler,
                      progress=Progress(runs, n_chunks, enabled=progress))
    elapsed = time.perf_counter() - t0
    info = {"started_utc": started.strftime("%Y-%m-%dT%H:%M:%SZ"), "elapsed_s": elapsed,
            "backend": _backend_text(jobs, scheduler), "runs_per_s": runs / elapsed if elapsed > 0 else None}
    info["text"] = (f"Flown {info['started_utc']} on {info['backend']} in {elapsed:.1f} s "
                    f"({runs / max(elapsed, 1e-9):.1f} runs/s).")
    return write_outputs(campaign, rows, out, seed=seed, runs=runs, info=info, report=report)


def write_outputs(campaign: Campaign, rows, out_dir, *, seed: int, runs: int, info: dict | None = None,
                  report: bool = True) -> dict:
    """runs.csv (and .parquet), summary.json, report.html from the rows."""
    from autopilot.userfile import writing

    out = Path(out_dir)
    cols = columns(campaign)
    with writing(out / "runs.csv"):
        write_runs_csv(rows, out / "runs.csv", cols)
    try:
        import pyarrow
        import pyarrow.parquet as pq
    except ImportError:
        pass
    else:  # pragma: no cover - pyarrow is optional
        pq.write_table(pyarrow.Table.from_pylist([{c: r.get(c) for c in cols} for r in rows]), out / "runs.parquet")
    summary = summarise(campaign, rows, seed=seed, runs=runs, cols=cols)
    summary["run"] = {k: v for k, v in (info or {}).items() if k != "text"}
    with writing(out / "summary.json"):
        write_summary(summary, out / "summary.json")
    if report:
        from autopilot.campaign.report import write_report

        with writing(out / "report.html"):
            write_report(summary, rows, out / "report.html", campaign_data=campaign.to_data(), run_info=info or {})
    return summary


def load_run_dir(out_dir) -> tuple[Campaign, int, int]:
    """(campaign, seed, runs) of a campaign directory (its campaign.json)."""
    from autopilot.userfile import read_text

    path = Path(out_dir) / "campaign.json"
    try:
        data = json.loads(read_text(path, what="campaign.json"))
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}: not JSON ({exc})") from None
    try:
        return Campaign.from_data(data["campaign"]), int(data["seed"]), int(data["runs"])
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise ConfigError(f"{path}: {exc}") from None
        raise ConfigError(f"{path}: not a campaign directory's campaign.json ({exc})") from None
