"""`autopilot sysid` end to end: read, identify, locate, write summary.json, report.html, YAML files."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from autopilot.sim import VesselParams
from autopilot.sysid.effects import EFFECT_NAMES
from autopilot.sysid.identify import effect_report, identify
from autopilot.sysid.locate import locate
from autopilot.sysid.output import write_effects_yaml, write_json, write_vessel_updated
from autopilot.sysid.replay import predict


def _pred(ident, fit):
    n = len(fit.trials)
    values = {k: np.full(n, v) for k, v in fit.values().items()}
    return predict(ident.prep, ident.vessel, np.array(fit.trials), fit.x0, values)


def summarise(ident, *, params_file: str = "", seconds: float | None = None) -> dict:
    """summary.json content of an :class:`~autopilot.sysid.identify.Identification`."""
    base = ident.base
    base_pred = _pred(ident, base)
    cands = []
    for c in ident.candidates:
        entry = {k: v for k, v in c.items() if k != "fitted"}
        if c.get("screen_cost") is not None:
            entry["screen_delta"] = c["screen_cost"] - base.cost
        if "fitted" in c:
            entry["fitted_params"] = {name: {p["name"]: p["value"] for p in eff["params"]} for name, eff in c["fitted"].items()}
        entry["score"] = entry.get("delta_bic", entry.get("screen_delta"))
        cands.append(entry)
    prep = ident.prep
    return {
        "mode": "trials",
        "params_file": params_file,
        "trials": [t.name for t in prep.trials],
        # cross-validation: each fold's trials held out in turn; held_out RMSEs are over all folds
        "held_out_folds": [[prep.trials[i].name for i in fold] for fold in ident.held_out],
        "verdict": list(ident.verdict) or ["none"],
        "effects": effect_report(ident.chosen, ident.vessel) if ident.verdict else {},
        "candidates": cands,
        "score": "delta_bic: BIC of the fitted model minus the baseline's (chi-square + k ln m); screened-only "
        "candidates carry screen_delta, the change of chi-square predicted by one Gauss-Newton step",
        "rmse_before": ident.rmse_before,
        "rmse_after": ident.rmse_after,
        "cost_before": base.cost,
        "cost_after": ident.chosen.cost,
        "n_residuals": base.n_obs,
        "noise": {
            "position_m": [float(x) for x in prep.sigma_pos_m],
            "heading_deg": [math.degrees(x) for x in prep.sigma_psi_rad],
        },
        "locate": locate(prep, base_pred, base.trials, range(len(base.trials))),
        "notes": ident.notes,
        "seconds": seconds,
    }


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

        before = _pred(ident, ident.base)
        after = _pred(ident, ident.chosen) if ident.verdict else None
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
        top_k: int = 3, report: bool = True, log=None) -> dict:
    """Identify on trials and (with ``out_dir``) write the files; returns the summary."""
    t0 = time.perf_counter()
    ident = identify(trials, vessel, candidates=candidates, top_k=top_k, log=log)
    summary = summarise(ident, params_file=params_file, seconds=time.perf_counter() - t0)
    if out_dir is not None:
        write_outputs(ident, summary, out_dir, report=report, source=params_file)
    summary["_ident"] = ident
    return summary
