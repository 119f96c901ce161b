"""report.html: plots of the identification (matplotlib, Agg), embedded as PNG."""

from __future__ import annotations

import base64
import html
import io
import json
import math

import numpy as np

from autopilot.sysid.channels import BY_NAME as CHANNEL_BY_NAME


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def track_figure(prep, before, after, trials_idx, max_trials: int = 6):
    """Measured vs simulated tracks, before and after (before/after: predict() outputs, run = position)."""
    import matplotlib.pyplot as plt

    shown = list(trials_idx)[:max_trials]
    cols = min(3, len(shown))
    rows = math.ceil(len(shown) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 4.0 * rows), squeeze=False)
    for ax, (j, i) in zip(axes.ravel(), enumerate(shown)):
        tr, m = prep.trials[i], prep.measured[i]
        inside = prep.t_grid <= tr.t_s[-1]
        ax.plot(m.east_m, m.north_m, ".", ms=2.5, color="0.5", label="measured fixes")
        ax.plot(before["east_m"][j][inside], before["north_m"][j][inside], "-", color="tab:red", lw=1, label="model before")
        if after is not None:
            ax.plot(after["east_m"][j][inside], after["north_m"][j][inside], "-", color="tab:blue", lw=1, label="model after")
        ax.set_title(tr.name, fontsize=9)
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_aspect("equal", adjustable="datalim")
    for ax in axes.ravel()[len(shown):]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=7)
    return fig


def residual_figure(prep, before, after, trials_idx, max_trials: int = 6):
    """Each channel's error over time (position and velocity: the horizontal size), before and after."""
    import matplotlib.pyplot as plt

    from autopilot.sysid.prediction import channel_residuals

    chans = prep.channels
    fig, axes = plt.subplots(len(chans), 1, figsize=(12, 3 * len(chans)), sharex=True, squeeze=False)
    axes = axes[:, 0]
    for j, i in enumerate(list(trials_idx)[:max_trials]):
        tr, m = prep.trials[i], prep.measured[i]
        for pred, style, label in ((before, "-", "before"), (after, "--", "after")):
            if pred is None:
                continue
            for ax, c in zip(axes, chans):
                parts = channel_residuals(prep, i, pred, [j], c)
                if not parts:
                    continue
                size = np.sqrt(sum(r[0] ** 2 for r in parts)) if c.horizontal else parts[0][0]
                ax.plot(m.get(c.name).t_s, c.shown(1.0) * size, style, lw=0.8, color=f"C{j}",
                        label=f"{tr.name} {label}" if c is chans[0] else None)
    for ax, c in zip(axes, chans):
        ax.set_ylabel(f"{c.name} error ({c.unit})")
    axes[-1].set_xlabel("time (s)")
    # beside the panels, not over the data (six trials before and after: twelve entries)
    axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    return fig


def ranking_figure(candidates: list[dict]):
    """Candidates: change of BIC when fitted, else the screening's predicted change of chi-square."""
    import matplotlib.pyplot as plt

    names, values, fitted = [], [], []
    base = None
    for c in candidates:
        if c.get("delta_bic") is not None:
            names.append(c["effect"])
            values.append(c["delta_bic"])
            fitted.append(True)
    for c in candidates:
        if c.get("delta_bic") is None and c.get("screen_delta") is not None:
            names.append(c["effect"])
            values.append(c["screen_delta"])
            fitted.append(False)
    fig, ax = plt.subplots(figsize=(8, 0.35 * max(len(names), 3) + 1))
    y = np.arange(len(names))
    ax.barh(y, values, color=["tab:blue" if f else "0.7" for f in fitted])
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlabel("change of BIC (blue: fitted) / predicted change of cost (grey: screened only); lower is better")
    del base
    return fig


def write_html(path, summary: dict, figures: dict) -> None:
    """The page: verdict, effects with intervals, RMSE table, locate text, plots, the JSON."""
    esc = html.escape
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>autopilot sysid</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}td,th{padding:2px 8px;border-bottom:1px solid #ddd}"
        "pre{background:#f6f6f6;padding:8px;overflow:auto;font-size:11px}</style></head><body>",
        "<h1>System identification</h1>",
        f"<p><b>Verdict:</b> {esc(', '.join(summary['verdict']))}</p>",
    ]
    for note in summary.get("notes", []):
        parts.append(f"<p><i>{esc(note)}</i></p>")
    if summary.get("adequacy"):
        parts.append("<h2>Is the model adequate?</h2><table><tr><th>channel</th><th>chi-square per measurement</th>"
                     "<th>residual RMS</th><th>noise RMS</th><th>beyond the noise</th><th>adequate</th></tr>")
        for ch, a in summary["adequacy"].items():
            c = CHANNEL_BY_NAME[ch]
            unit, k = c.unit, c.key_unit
            parts.append(f"<tr><td>{esc(ch)}</td><td>{a['chi2_per_measurement']:.3g}</td><td>{a[f'residual_rms_{k}']:.3g} {unit}</td>"
                         f"<td>{a[f'noise_rms_{k}']:.3g} {unit}</td><td>{a[f'beyond_noise_{k}']:.3g} {unit}</td>"
                         f"<td>{'yes' if a['adequate'] else 'no'}</td></tr>")
        parts.append("</table>")
    if summary.get("effects"):
        parts.append("<h2>Effects</h2><table><tr><th>effect</th><th>parameter</th><th>value</th><th>95 % interval</th><th>unit</th></tr>")
        for name, eff in summary["effects"].items():
            for p in eff["params"]:
                parts.append(f"<tr><td>{esc(name)}</td><td>{esc(p['name'])}</td><td>{p['value']:.4g}</td>"
                             f"<td>[{p['ci95'][0]:.4g}, {p['ci95'][1]:.4g}]</td><td>{esc(p['unit'])}</td></tr>")
        parts.append("</table>")
    parts.append("<h2>Gap before and after</h2><table><tr><th></th><th>set</th>")
    metrics = list(summary["rmse_before"]["fitted"])
    parts.append("".join(f"<th>{esc(m)}</th>" for m in metrics) + "</tr>")
    for label in ("rmse_before", "rmse_after"):
        for part in ("fitted", "held_out"):
            row = summary[label][part]
            parts.append(f"<tr><td>{label}</td><td>{part}</td>" + "".join(
                f"<td>{row[m]:.4g}</td>" if row.get(m) is not None else "<td>-</td>" for m in metrics) + "</tr>")
    parts.append("</table>")
    if summary.get("locate", {}).get("text"):
        parts.append("<h2>Where the residuals are</h2><ul>")
        parts.extend(f"<li>{esc(t)}</li>" for t in summary["locate"]["text"])
        parts.append("</ul>")
    for title, b64 in figures.items():
        parts.append(f"<h2>{esc(title)}</h2><img src='data:image/png;base64,{b64}' style='max-width:100%'>")
    parts.append("<h2>summary.json</h2><pre>" + esc(json.dumps(summary, indent=1, default=str)) + "</pre></body></html>")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("\n".join(parts))


def png(fig) -> str:
    return _png(fig)
