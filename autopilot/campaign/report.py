"""``report.html``: one self-contained page (plots as embedded PNG) of a campaign's summary and rows."""

from __future__ import annotations

import base64
import html
import io
import json
import math

import numpy as np

from autopilot.campaign.results import OUTCOMES

__all__ = ["write_report", "success_table_markdown"]

_UNITS = {"closest_max_m": "worst closest approach (m)", "xte_rms_m": "cross-track RMS (m)", "time_s": "time (s)",
          "energy_ns": "thrust energy (N s)"}


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    from autopilot.plotting import pyplot

    pyplot().close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _pct(x: float) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100.0 * x:.1f} %"


def _num(x, digits: int = 2) -> str:
    if x is None:
        return "-"
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    if isinstance(x, float) and math.isnan(x):
        return "-"
    return f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def success_table_markdown(summary: dict) -> str:
    """Success rate with its Wilson 95 % interval per law (rows) and condition spread (columns)."""
    conds = summary["conditions"]
    lines = ["| law | " + " | ".join(conds) + " | all |", "|---|" + "---|" * (len(conds) + 1)]
    for law in summary["laws"]:
        cells = []
        for c in conds:
            r = summary["by_law_condition"][f"{law}/{c}"]
            cells.append(_cell(r))
        cells.append(_cell(summary["by_law"][law]))
        lines.append(f"| {law} | " + " | ".join(cells) + " |")
    lines.append("| all | " + " | ".join(_cell(summary["by_condition"][c]) for c in conds) + " | "
                 + _cell(summary["overall"]) + " |")
    return "\n".join(lines)


def _cell(r: dict) -> str:
    if not r["runs"]:
        return "-"
    lo, hi = r["ci95"]
    return f"{100 * r['rate']:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] (n {r['runs']})"


def _rates_figure(summary: dict):
    from autopilot.plotting import pyplot

    plt = pyplot()
    conds, laws = summary["conditions"], summary["laws"]
    fig, ax = plt.subplots(figsize=(max(6.0, 1.3 * len(conds) * len(laws) / 2 + 3), 3.6))
    width = 0.8 / len(laws)
    x = np.arange(len(conds))
    for j, law in enumerate(laws):
        rs = [summary["by_law_condition"][f"{law}/{c}"] for c in conds]
        rate = np.array([100 * r["rate"] if r["runs"] else np.nan for r in rs])
        lo = np.array([100 * r["ci95"][0] if r["runs"] else np.nan for r in rs])
        hi = np.array([100 * r["ci95"][1] if r["runs"] else np.nan for r in rs])
        ax.bar(x + (j - (len(laws) - 1) / 2) * width, rate, width, yerr=[np.maximum(rate - lo, 0.0), np.maximum(hi - rate, 0.0)], capsize=3, label=law)
    ax.set_xticks(x, conds, rotation=20)
    ax.set_ylabel("success (%), Wilson 95 %")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=8, ncol=len(laws), loc="lower center", bbox_to_anchor=(0.5, 1.0), frameon=False)
    ax.grid(axis="y", alpha=0.3)
    return fig


def _distributions_figure(rows, laws):
    from autopilot.plotting import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, len(OUTCOMES), figsize=(4.0 * len(OUTCOMES), 3.2))
    for ax, o in zip(axes, OUTCOMES):
        allv = np.array([r[o] for r in rows], dtype=float)
        fin = allv[np.isfinite(allv)]
        if fin.size == 0:
            continue
        hi = np.percentile(fin, 99.5) if fin.size > 20 else fin.max()
        bins = np.linspace(fin.min(), max(hi, fin.min() + 1e-6), 40)
        for law in laws:
            v = np.array([r[o] for r in rows if r["law"] == law], dtype=float)
            v = np.clip(v[np.isfinite(v)], bins[0], bins[-1])
            ax.hist(v, bins=bins, histtype="step", label=law)
        ax.set_xlabel(_UNITS[o])
        ax.set_ylabel("runs")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _sensitivity_figure(sens):
    from autopilot.plotting import pyplot

    plt = pyplot()
    shown = [s for s in sens if not math.isnan(s["rho_success"]) or not math.isnan(s["rho_closest_max"])][:15]
    fig, ax = plt.subplots(figsize=(7, 0.35 * max(len(shown), 3) + 1))
    y = np.arange(len(shown))
    ax.barh(y - 0.2, [np.nan_to_num(s["rho_success"]) for s in shown], 0.4, label="with success")
    ax.barh(y + 0.2, [np.nan_to_num(s["rho_closest_max"]) for s in shown], 0.4, label="with worst closest approach")
    ax.set_yticks(y, [s["input"] + (" (circular, unsigned)" if s.get("circular") else "") for s in shown], fontsize=8)
    ax.invert_yaxis()
    ax.axvline(0, color="0.3", lw=0.8)
    ax.set_xlabel("Spearman rank correlation (a direction: circular-linear, 0..1)")
    ax.legend(fontsize=8)
    return fig


def _failsafes_text(run: dict) -> str:
    """A run's failsafes: those while its mission was flown, then those after it had completed, said so."""
    during, after = run["failsafe_causes"], run.get("failsafe_causes_after_completion", "")
    if not after:
        return during
    return (during + " " if during else "") + f"(after completion: {after})"


def _table(header, rows) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def write_report(summary: dict, rows, path, *, campaign_data: dict, run_info: dict) -> None:
    """Write report.html."""
    from autopilot.review.report import IMAGE_CHECK  # the review report's broken-image check, the same markers

    esc = html.escape
    laws, conds = summary["laws"], summary["conditions"]
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>campaign {esc(summary['campaign'])}</title>",
        "<style>body{font-family:sans-serif;max-width:1200px;margin:1em auto}table{border-collapse:collapse;"
        "display:block;overflow-x:auto;max-width:100%;"  # a wide table scrolls in itself, not the page
        "font-size:13px;margin:.5em 0}td,th{border:1px solid #bbb;padding:2px 6px;text-align:right}"
        "th{background:#eee}td:first-child{text-align:left}pre{font-size:11px;background:#f6f6f6;padding:6px;overflow-x:auto}"
        "img{max-width:100%;height:auto}</style>",
        "</head><body>",
        f"<h1>Robustness campaign {esc(summary['campaign'])}</h1>",
        f"<p>{esc(summary.get('description') or '')}</p>",
        f"<p>{summary['rows']} runs (seed {summary['seed']}, campaign {esc(summary['digest'])}); missions "
        f"{esc(', '.join(summary['missions']))}; success = {esc(summary['success'])} "
        f"({summary['success_radius_m']:g} m). {esc(run_info.get('text', ''))}</p>",
        "<h2>Success rate (Wilson 95 % interval)</h2>",
    ]
    if summary.get("cells_not_flown"):
        missing = summary["cells_not_flown"]
        parts.insert(-1, f"<p><b>{len(missing)} of {summary['cells']} cells (mission x law x condition) were not "
                         f"flown</b>: {summary['rows']} runs; give at least {summary['cells']} to fly each once "
                         f"({esc(', '.join(missing[:6]))}{', ...' if len(missing) > 6 else ''}).</p>")
    header = ["law"] + conds + ["all"]
    table_rows = []
    for law in laws:
        table_rows.append([law] + [_cell(summary["by_law_condition"][f"{law}/{c}"]) for c in conds]
                          + [_cell(summary["by_law"][law])])
    table_rows.append(["all"] + [_cell(summary["by_condition"][c]) for c in conds] + [_cell(summary["overall"])])
    parts.append(_table(header, table_rows))
    parts.append(f"<img src='data:image/png;base64,{_png(_rates_figure(summary))}'>")
    parts.append("<h3>By mission</h3>" + _table(["mission", "success"], [[m, _cell(r)] for m, r in
                                                                           summary["by_mission"].items()]))
    parts.append("<h3>By fault</h3>" + _table(["fault", "success"], [[k, _cell(r)] for k, r in
                                                                       summary["by_fault"].items()]))
    parts.append("<h2>Distributions</h2>")
    dist_rows = []
    for o in OUTCOMES:
        for who, q in summary["distributions"][o].items():
            if q.get("n"):
                dist_rows.append([_UNITS[o], who, q["n"], _num(q["p5"]), _num(q["median"]), _num(q["p95"]),
                                  _num(q["max"]), q["infinite"]])
    parts.append(_table(["outcome", "law", "runs", "p5", "median", "p95", "max", "infinite"], dist_rows))
    parts.append(f"<img src='data:image/png;base64,{_png(_distributions_figure(rows, laws))}'>")
    fs = summary["failsafes"]
    late = fs.get("after_completion") or {"runs": 0, "by_cause": {}}
    parts.append(f"<h2>Failsafes</h2><p>{fs['runs_with_failsafe']} of {summary['rows']} runs took at least one while "
                 f"the mission was flown. {late['runs']} took one after their mission had completed (in the final "
                 "pass, or a fault still in force then): counted apart, in <b>after completion</b>; such a run is a "
                 "success or not as its mission was (a latched fault's action that took the completed boat, battery_low's "
                 "rtl, is still how the run ended, as the daemon flies it).</p>")
    by_cause = {c: [n, late["by_cause"].get(c, 0)] for c, n in fs["by_cause"].items()}
    for c, n in late["by_cause"].items():
        by_cause.setdefault(c, [0, n])
    parts.append(_table(["cause", "times taken", "after completion"],
                        [[c, *n] for c, n in sorted(by_cause.items(), key=lambda kv: (-kv[1][0], -kv[1][1], kv[0]))]))
    parts.append(_table(["how runs ended", "runs"], sorted(summary["ends"].items(), key=lambda kv: -kv[1])))
    parts.append("<h2>Worst runs</h2><p>Re-fly one and review it: <code>autopilot campaign --replay DIR INDEX</code>, "
                 "then <code>autopilot review DIR/replay-INDEX.jsonl --out DIR/review-INDEX</code>.</p>")
    parts.append(_table(["index", "mission", "law", "condition", "success", "end", "worst closest (m)", "xte RMS (m)",
                         "time (s)", "failsafes", "faults"],
                        [[w["index"], w["mission"], w["law"], w["condition"], w["success"], w["end"],
                          _num(w["closest_max_m"]), _num(w["xte_rms_m"]), _num(w["time_s"], 1), _failsafes_text(w),
                          w["faults"]] for w in summary["worst_runs"]]))
    sens = summary["sensitivity"]
    parts.append("<h2>What moves the outcome</h2><p>Spearman's rank correlation of each drawn quantity with success "
                 "(1/0), the worst closest approach and the cross-track RMS, within the conditions where it varies "
                 "(ranks centred per condition, then pooled: a harder condition does not count for what it "
                 "draws); and the success rate in its lowest and highest quartile there. A direction has no low "
                 "and high end (359&deg; and 1&deg; are neighbours): its correlation is the circular-linear one "
                 "(0..1, unsigned), with the direction the outcome is worst from, and the success rate within a "
                 "quarter turn of that direction and of its opposite. <b>chance</b>: the |rho| a quantity that "
                 "moves nothing exceeds 1 time in 20 at these runs (the circular one's is higher): a rho below it "
                 "is noise, however it ranks.</p>")

    def low_high(s):
        if s.get("circular"):
            return (f"{_pct(s['success_low_quartile'])} (within a quarter turn centred on {_num(s['worst_direction'], 1)}, the worst)",
                    f"{_pct(s['success_high_quartile'])} (the opposite quarter)")
        return _pct(s["success_low_quartile"]), _pct(s["success_high_quartile"])

    parts.append(_table(["quantity", "conditions", "runs", "rho success", "rho worst closest", "rho xte RMS", "chance",
                         "success, low quartile", "success, high quartile"],
                        [[s["input"] + (" (circular)" if s.get("circular") else ""), ", ".join(s["conditions"]),
                          s["runs"], _num(s["rho_success"]), _num(s["rho_closest_max"]), _num(s["rho_xte_rms"]),
                          _num(s["rho_chance_95"]), *low_high(s)] for s in sens]))
    if sens:
        parts.append(f"<img src='data:image/png;base64,{_png(_sensitivity_figure(sens))}'>")
    parts.append("<h2>Sources</h2><ul>" + "".join(f"<li>{esc(s)}</li>" for s in summary["sources"]) + "</ul>")
    parts.append("<h2>campaign.json</h2><pre>" + esc(json.dumps(
        {"campaign": campaign_data, "seed": summary["seed"], "runs": summary["runs"]}, indent=1)) + "</pre>")
    parts.append(f"<footer>autopilot campaign &middot; <span id='image-check'>image check did not run</span></footer>"
                 f"{IMAGE_CHECK}</body></html>")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(parts))
