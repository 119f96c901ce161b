"""`autopilot sysid` end to end: read, identify, locate, write summary.json, report.html, YAML files."""

from __future__ import annotations

import time
from pathlib import Path

from autopilot.sim import VesselParams
from autopilot.sysid.effects import EFFECT_NAMES
from autopilot.sysid.identification import identify
from autopilot.sysid.judge import predict_fit
from autopilot.sysid.output import write_effects_yaml, write_json, write_vessel_updated
from autopilot.sysid.summary import summarise


def write_outputs(ident, summary: dict, out_dir, *, report: bool = True, source: str = "") -> dict:
    """summary.json, report.html, vessel-updated.yaml, effects.yaml in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    values = ident.values()
    write_vessel_updated(ident.vessel, values, ident.verdict, out / "vessel-updated.yaml", source=source)
    write_effects_yaml(summary["effects"], out / "effects.yaml")
    files = {"summary": "summary.json", "vessel": "vessel-updated.yaml", "effects": "effects.yaml"}
    if report:
        import matplotlib

        matplotlib.use("Agg")
        from autopilot.sysid import report as rep

        before = predict_fit(ident.prep, ident.vessel, ident.base)
        after = predict_fit(ident.prep, ident.vessel, ident.chosen) if ident.verdict else None
        trials = ident.base.trials
        figures = {
            "Tracks: measured, model before (red) and after (blue)": rep.png(rep.track_figure(ident.prep, before, after, trials)),
            "Residuals over time (solid: before, dashed: after)": rep.png(rep.residual_figure(ident.prep, before, after, trials)),
            "Candidate ranking": rep.png(rep.ranking_figure(summary["candidates"])),
        }
        rep.write_html(out / "report.html", summary, figures)
        files["report"] = "report.html"
    summary["outputs"] = files
    write_json(summary, out / "summary.json")
    return files


def run(trials, vessel: VesselParams, out_dir=None, *, params_file: str = "", candidates=EFFECT_NAMES,
        top_k: int = 3, report: bool = True, log=None, bounds=None) -> dict:
    """Identify on trials and (with ``out_dir``) write the files; returns the summary."""
    t0 = time.perf_counter()
    ident = identify(trials, vessel, candidates=candidates, top_k=top_k, log=log, bounds=bounds)
    summary = summarise(ident, params_file=params_file, seconds=time.perf_counter() - t0)
    if out_dir is not None:
        write_outputs(ident, summary, out_dir, report=report, source=params_file)
    summary["_ident"] = ident
    return summary
