"""summary.json of an identification: the verdict, the effects with intervals, the candidates, the noise, adequacy."""

from __future__ import annotations

from autopilot.sysid.effects import BY_NAME
from autopilot.sysid.fit import Fit
from autopilot.sysid.identification import outlier_runs
from autopilot.sysid.judge import noise_summary, predict_fit
from autopilot.sysid.locate import locate


def effect_report(fit: Fit, vessel) -> dict:
    """Per effect: parameters with names, units, values and 95 % intervals (and the effect's derived rows)."""
    out = {}
    ci = fit.ci95()
    for name in fit.effects:
        eff = BY_NAME[name]
        params, value, sigma = [], {}, {}
        for p in eff.params:
            key = eff.key(p)
            k = fit.keys.index(key)
            v, s = float(fit.theta[k]), float(fit.sigma[k])
            value[p.name], sigma[p.name] = v, s
            shown = eff.reported(p.name, v, vessel)
            params.append({"name": p.name, "unit": p.unit, "value": shown,
                           "ci95": [ci[key][0] + shown - v, ci[key][1] + shown - v], "sigma": s})
        params += eff.derived(value, sigma)
        out[name] = {"doc": eff.doc, "params": params}
    return out


def _counts(prep) -> dict:
    """What the readers and the outlier rejection dropped, over all trials."""
    total: dict = {}
    for tr, m in zip(prep.trials, prep.measured):
        for k, v in tr.counts.items():
            total[k] = total.get(k, 0) + v
        for name, samples in m.series.items():
            key = f"rejected_{name}_outliers"
            total[key] = total.get(key, 0) + samples.rejected
            if name == "position":  # of those, the fixes the daemon's fix gate refuses (noise.gated_fixes)
                total["gated_position_fixes"] = total.get("gated_position_fixes", 0) + int(samples.gated.sum())
    return total


def summarise(ident, *, params_file: str = "", seconds: float | None = None) -> dict:
    """summary.json content of an :class:`~autopilot.sysid.identification.Identification`."""
    base = ident.base
    prep = ident.prep
    cands = []
    for c in ident.candidates:
        entry = {k: v for k, v in c.items() if k != "fitted"}
        if c.get("screen_cost") is not None:
            entry["screen_delta"] = c["screen_cost"] - base.cost
        if "fitted" in c:
            entry["fitted_params"] = {name: {p["name"]: p["value"] for p in eff["params"]} for name, eff in c["fitted"].items()}
        entry["score"] = entry.get("delta_bic", entry.get("screen_delta"))
        cands.append(entry)
    final = ident.chosen
    return {
        "mode": "trials",
        "params_file": params_file,
        "trials": [t.name for t in prep.trials],
        # cross-validation: each fold's trials held out in turn; held_out RMSEs are over all folds
        "held_out_folds": [[prep.trials[i].name for i in fold] for fold in ident.held_out],
        "verdict": list(ident.verdict) or [ident.status if ident.status in ("unexplained", "inconclusive") else "none"],
        "status": ident.status,
        "adequate": all(c["adequate"] for c in ident.adequacy.values()),
        "adequacy": ident.adequacy,
        "nearest": [{"effect": c["effect"], "delta_bic": c.get("delta_bic"), "adequacy": c.get("adequacy"),
                     "fitted_params": {n: {p["name"]: p["value"] for p in e["params"]} for n, e in c.get("fitted", {}).items()}}
                    for c in ident.nearest],
        "effects": effect_report(final, ident.vessel) if ident.verdict else {},
        "not_excluded": ident.not_excluded,
        "candidates": cands,
        "score": "delta_bic: BIC of the fitted model minus the baseline's (chi-square under the noise model + k ln m); "
        "screened-only candidates carry screen_delta, the change of chi-square predicted by the screening steps",
        "rmse_before": ident.rmse_before,
        "rmse_after": ident.rmse_after,
        "cost_before": base.cost,
        "cost_after": final.cost,
        "n_measurements": base.n_obs,
        "noise": noise_summary(prep.noise),
        "measurements": _counts(prep),
        # the position fixes left out as outliers, per trial in runs (t_s: the first and last, on the file's clock)
        "position_outliers": outlier_runs(prep),
        "locate": locate(prep, predict_fit(prep, ident.vessel, final), final.trials, range(len(final.trials))),
        "locate_baseline": locate(prep, predict_fit(prep, ident.vessel, base), base.trials, range(len(base.trials))),
        "notes": ident.notes,
        "seconds": seconds,
    }
