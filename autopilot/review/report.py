"""Static HTML report of one or several missions (PNGs beside it, relative paths).

One log: ``OUT/report.html``, its PNGs, ``OUT/summary.json`` and the
exports, all in OUT. Several logs: ``OUT/report.html`` holds the overlaid
tracks and the side-by-side scorecard, and each log gets the single-log
report in ``OUT/<k>-<stem>/``. The page needs no network; a small inline
script marks images that failed to load (``data-broken-images`` on the
body, used by the headless-browser test and visible in the footer).
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from autopilot.review import plots
from autopilot.review.export import export
from autopilot.review.metrics import Scorecard, score
from autopilot.review.reader import MissionLog, read_log

MAX_WAYPOINT_ROWS = 100

_CSS = """
body { font-family: sans-serif; margin: 1.5em; color: #212121; max-width: 1150px; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em 0; }
td, th { border: 1px solid #bdbdbd; padding: 0.25em 0.6em; text-align: left; font-size: 0.9em; }
th { background: #eceff1; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0 2em 0; }
figure img { max-width: 100%; border: 1px solid #e0e0e0; }
figcaption { font-size: 0.9em; color: #424242; }
.notes li { font-size: 0.9em; }
.warn { color: #b71c1c; }
footer { font-size: 0.8em; color: #757575; margin-top: 2em; }
"""

IMAGE_CHECK = """
<script>
window.addEventListener('load', function () {
  var imgs = document.images, broken = [];
  for (var i = 0; i < imgs.length; i++) {
    if (!imgs[i].complete || imgs[i].naturalWidth === 0) {
      broken.push(imgs[i].getAttribute('src'));
      imgs[i].setAttribute('data-broken', '1');
    }
  }
  document.body.setAttribute('data-images', String(imgs.length));
  document.body.setAttribute('data-broken-images', String(broken.length));
  document.getElementById('image-check').textContent = broken.length
    ? 'broken images: ' + broken.join(', ') : 'all ' + imgs.length + ' images loaded';
});
</script>
"""

# (file name, caption, function(log, card, path)); the time panels carry the mode band underneath
FIGURES = (
    ("track.png", "Track in the local frame: waypoints, closest approach to each (x, dotted), start, "
     "faults and failsafes where they happened, each hold point with the p95 of its error (circle) and the "
     "configured drift radius (dashed), and the launch point. With AIS traffic: each target's reported track "
     "(arrow: its last report), both vessels at own ship's closest approach to it joined by a dashed line "
     "labelled with that distance, and where collision avoidance changed the course or speed (wide band; "
     "diamonds: where each manoeuvre began, filled, and ended, open).", lambda lg, c, p: plots.plot_track(lg, c, p)),
    ("avoidance.png", "Collision avoidance: the collision risk of the target most at risk each cycle with the "
     "give-way and stand-on thresholds, avoidance's share of psi_d (+ = starboard), that target's range and "
     "DCPA against the safe distance, and its COLREGs situation; shaded where avoidance was active.",
     lambda lg, c, p: plots.plot_avoidance(lg, c, p)),
    ("thrust.png", "Thrust and PWM duty per side; shaded where that side was saturated.",
     lambda lg, c, p: plots.plot_thrust(lg, p)),
    ("guidance.png", "TCPA', DCPA', CDH and heading error (thesis Fig 9.1-9.4, panel d).",
     lambda lg, c, p: plots.plot_guidance(lg, p)),
    ("motion.png", "Speed over ground and yaw rate.", lambda lg, c, p: plots.plot_motion(lg, p)),
    ("battery.png", "Battery voltage under load and the resting estimate the battery failsafe judges, with "
     "its thresholds (dashed) and the battery faults.", lambda lg, c, p: plots.plot_battery(lg, p)),
    ("lateness.png", "Control-loop lateness: histogram and percentiles, and over time.",
     lambda lg, c, p: plots.plot_lateness(lg, c, p)),
    ("timeline.png", "Events and the daemon's mode over time.", lambda lg, c, p: plots.plot_timeline(lg, p)),
)


@dataclass
class LogReview:
    log: MissionLog | None  # dropped after a multi-log review to keep memory flat
    card: Scorecard
    out_dir: Path
    report: Path
    figures: dict = field(default_factory=dict)  # file name -> Path or None
    exports: dict = field(default_factory=dict)  # format -> Path
    export_errors: dict = field(default_factory=dict)  # format -> message


@dataclass
class Review:
    report: Path
    logs: list  # [LogReview]
    overlay: Path | None = None


def _href(name: str) -> str:
    """A file name as a relative URL: '#', '%', '?' and spaces are a name's, not the URL's (a log named
    "trial #3.jsonl" linked to "1-trial " and a fragment)."""
    from urllib.parse import quote

    return _e(quote(name))


def _e(x) -> str:
    return html.escape(str(x))


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{_e(title)}</title><style>{_CSS}</style></head>\n<body>\n{body}\n"
            f"<footer>autopilot review &middot; <span id=\"image-check\">image check did not run</span>"
            f"</footer>\n{IMAGE_CHECK}</body></html>\n")


def _table(header: list[str], rows: list[list[str]], numeric_from: int = 1) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td class=\"num\">{_e(c)}</td>" if j >= numeric_from else f"<td>{_e(c)}</td>"
                         for j, c in enumerate(r)) + "</tr>\n"
        for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>\n{body}</tbody></table>"


def _num(x: float, digits: int = 2) -> str:
    return f"{x:.{digits}f}" if isinstance(x, (int, float)) and math.isfinite(x) else "n/a"


def _waypoint_table(card: Scorecard) -> str:
    if not card.waypoints:
        return "<p>The log lists no waypoints.</p>"
    rows = [[w.label, _num(w.north_m, 1), _num(w.east_m, 1), "yes" if w.reached else "no",
             _num(w.closest_approach_m), _num(w.logged_closest_approach_m), _num(w.closest_t_s, 1)]
            for w in card.waypoints[:MAX_WAYPOINT_ROWS]]
    more = (f"<p>... and {len(card.waypoints) - MAX_WAYPOINT_ROWS} more waypoints (see summary.json).</p>"
            if len(card.waypoints) > MAX_WAYPOINT_ROWS else "")
    return _table(["waypoint", "north (m)", "east (m)", "reached", "closest approach (m), recomputed",
                   "closest approach (m), logged", "at t (s)"], rows) + more


def _hold_table(card: Scorecard) -> str:
    rows = [[f"hold {h.number}", _num(h.north_m, 1), _num(h.east_m, 1), ", ".join(h.modes) or "-",
             _num(h.first_t_s, 1), _num(h.hold_s, 1), _num(h.closing_s, 1), _num(h.error_rms_m),
             _num(h.error_p95_m), _num(h.error_max_m), _num(h.energy_n_s, 0)]
            for h in card.holds[:MAX_WAYPOINT_ROWS]]
    more = (f"<p>... and {len(card.holds) - MAX_WAYPOINT_ROWS} more hold points (see summary.json).</p>"
            if len(card.holds) > MAX_WAYPOINT_ROWS else "")
    return _table(["hold", "north (m)", "east (m)", "mode", "first at t (s)", "held (s)", "closing (s)",
                   "error RMS (m)", "error p95 (m)", "error max (m)", "energy (N s)"], rows) + more + (
        "<p>Held: the hold proper, as <code>autopilot evaluate</code> scores it; closing: station keeping "
        "only closing on the point (the last <code>gnc.hold.approach_m</code> of a return or of the way to a "
        "hold item). Errors are <code>hold_error_m</code> over the cycles held.</p>")


def _target_table(card: Scorecard) -> str:
    def side(t):
        if not t.acted:
            return "did not act"
        return f"acted from {_num(t.first_action_t_s, 1)} s, " + (
            f"{t.side} (up to {_num(t.max_alteration_deg, 0)} deg)" if t.side else "speed only")

    def kept(t):
        return "unknown" if t.distance_kept is None else ("yes" if t.distance_kept else "NO")

    rows = [[t.label + (f" ({t.target})" if t.name else ""), " > ".join(t.situations) or "-", side(t),
             ("yes" if t.rule_followed else "NO") + (f": {t.note}" if t.note else ""), kept(t),
             _num(t.closest_m, 1), _num(t.closest_t_s, 1), _num(t.logged_min_range_m, 1), _num(t.required_m, 1)]
            for t in card.targets[:MAX_WAYPOINT_ROWS]]
    more = (f"<p>... and {len(card.targets) - MAX_WAYPOINT_ROWS} more targets (see summary.json).</p>"
            if len(card.targets) > MAX_WAYPOINT_ROWS else "")
    return _table(["target (MMSI)", "situations met", "the boat", "rules followed", "distance kept",
                   "closest approach (m)", "at t (s)", "smallest range (m), logged", "required (m)"],
                  rows, numeric_from=5) + more + (
        "<p>Closest approach: recomputed from own fixes and the target's AIS reports (interpolated to the fix "
        "times); logged: the daemon's own ranges from the dead-reckoned AIS picture. Required: "
        "<code>gnc.avoidance.safe_distance_m</code> plus half the target's reported length (the daemon adds "
        "its farthest hull point from the AIS reference point, which the log does not carry). Side: the sign "
        "of <code>avoid_psi_share_deg</code> while acting for it.</p>")


def _manoeuvre_table(card: Scorecard) -> str:
    rows = [[f"A{m.number}", _num(m.start_t_s, 1), _num(m.end_t_s, 1), _num(m.duration_s, 1), m.side or "speed only",
             _num(m.max_alteration_deg, 0), _num(m.min_speed_factor, 2), ", ".join(str(x) for x in m.targets) or "-"]
            for m in card.manoeuvres[:MAX_WAYPOINT_ROWS]]
    more = (f"<p>... and {len(card.manoeuvres) - MAX_WAYPOINT_ROWS} more manoeuvres (see summary.json).</p>"
            if len(card.manoeuvres) > MAX_WAYPOINT_ROWS else "")
    return _table(["manoeuvre", "from t (s)", "to t (s)", "lasted (s)", "side", "largest share of psi_d (deg)",
                   "lowest speed factor", "target most at risk (MMSI)"], rows) + more


def review_one(log: MissionLog, out_dir, *, formats=(), with_plots: bool = True) -> LogReview:
    """Scorecard, figures, exports and report.html of one log in ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    card = score(log)
    result = LogReview(log=log, card=card, out_dir=out_dir, report=out_dir / "report.html")
    if with_plots:
        for name, _caption, fn in FIGURES:
            result.figures[name] = fn(log, card, out_dir / name)
    for fmt in formats:
        try:
            result.exports.update(export(log, (fmt,), out_dir))
        except Exception as exc:  # one failed export must not lose the report
            result.export_errors[fmt] = str(exc)
    (out_dir / "summary.json").write_text(json.dumps(card.to_dict(), indent=1), encoding="utf-8")
    result.report.write_text(_single_html(result), encoding="utf-8")
    return result


def _single_html(r: LogReview) -> str:
    log, card = r.log, r.card
    parts = [f"<h1>Mission review: {_e(log.name)}</h1>",
             f"<p>Log <code>{_e(log.path)}</code>"
             + (f", started {_e(log.first_timestamp)}" if log.first_timestamp else "")
             + (f", guidance {_e(log.start.get('guidance'))}" if log.start else "") + ".</p>"]
    if log.start is None:
        parts.append("<p class=\"warn\">No mission_start line: waypoints and origin unknown.</p>")
    notes = log.stats.describe()
    warn = log.stats.skipped or log.stats.bad_values or log.stats.bad_events or log.n_cycles == 0
    parts.append("<h2>What was read</h2><ul class=\"notes" + (" warn" if warn else "") + "\">"
                 + "".join(f"<li>{_e(n)}</li>" for n in notes)
                 + ("<li>no cycle lines: nothing to plot</li>" if log.n_cycles == 0 else "") + "</ul>")
    parts.append("<h2>Summary</h2>" + _table(["quantity", "value"], [list(x) for x in card.table_rows()]))
    parts.append("<h2>Closest approach per waypoint</h2>" + _waypoint_table(card))
    if card.holds:
        parts.append("<h2>Station keeping per hold point</h2>" + _hold_table(card))
    if card.targets:
        parts.append("<h2>AIS targets</h2>" + _target_table(card))
    if card.manoeuvres:
        parts.append("<h2>Avoidance manoeuvres</h2>" + _manoeuvre_table(card))
    if card.lateness_ms:
        parts.append("<h2>Control-loop lateness (ms)</h2>" + _table(
            list(card.lateness_ms), [[_num(v, 3) for v in card.lateness_ms.values()]], numeric_from=0))
    parts.append("<h2>Figures</h2>")
    missing = []
    for name, caption, _fn in FIGURES:
        if r.figures.get(name):
            parts.append(f"<figure><img src=\"{_href(name)}\" alt=\"{_e(caption)}\">"
                         f"<figcaption>{_e(caption)}</figcaption></figure>")
        else:
            missing.append(name)
    if missing:
        parts.append("<p>Not drawn (no data in the log" + ("" if r.figures else ", or plots disabled")
                     + "): " + _e(", ".join(missing)) + "</p>")
    if r.exports or r.export_errors:
        items = [f"<li><a href=\"{_href(p.name)}\">{_e(p.name)}</a> ({_e(fmt)})</li>" for fmt, p in r.exports.items()]
        items += [f"<li class=\"warn\">{_e(fmt)}: {_e(msg)}</li>" for fmt, msg in r.export_errors.items()]
        parts.append("<h2>Exports</h2><ul>" + "".join(items) + "</ul>")
    parts.append("<p><a href=\"summary.json\">summary.json</a></p>")
    return _page(f"review {log.name}", "\n".join(parts))


def _compare_html(results: list[LogReview], overlay: Path | None) -> str:
    parts = [f"<h1>Mission review: {len(results)} logs</h1>"]
    parts.append("<ol>" + "".join(
        f"<li><a href=\"{_href(r.report.parent.name)}/report.html\">{_e(r.card.name)}</a> "
        f"(<code>{_e(r.card.path)}</code>)" + (f" <span class=\"warn\">{r.card.skipped_lines} lines skipped</span>"
                                               if r.card.skipped_lines else "") + "</li>"
        for r in results) + "</ol>")
    if overlay:
        parts.append(f"<figure><img src=\"{_href(overlay.name)}\" alt=\"overlaid tracks\">"
                     "<figcaption>Tracks overlaid.</figcaption></figure>")
    labels: list[str] = []  # every log's rows (a log with traffic has rows others lack), each after its predecessor
    for r in results:
        at = 0
        for lab, _ in r.card.table_rows():
            if lab in labels:
                at = labels.index(lab) + 1
            else:
                labels.insert(at, lab)
                at += 1
    columns = [dict(r.card.table_rows()) for r in results]
    rows = [[lab] + [c.get(lab, "") for c in columns] for lab in labels]
    parts.append("<h2>Scorecards</h2>" + _table(
        ["quantity"] + [f"{k + 1}: {r.card.name}" for k, r in enumerate(results)], rows))
    return _page("review comparison", "\n".join(parts))


def review(paths, out_dir, *, formats=(), with_plots: bool = True) -> Review:
    """Review one or several logs into ``out_dir``; see the module docstring for the layout."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [Path(p) for p in paths]
    if len(paths) == 1:
        one = review_one(read_log(paths[0]), out_dir, formats=formats, with_plots=with_plots)
        return Review(report=one.report, logs=[one])
    results, tracks = [], []
    for k, p in enumerate(paths, start=1):
        one = review_one(read_log(p), out_dir / f"{k}-{p.stem}", formats=formats, with_plots=with_plots)
        tracks.append(plots.Track.of(one.log))
        one.log = None  # only the decimated track stays in memory between logs
        results.append(one)
    overlay = plots.plot_overlay(tracks, out_dir / "tracks.png") if with_plots else None
    report = out_dir / "report.html"
    report.write_text(_compare_html(results, overlay), encoding="utf-8")
    (out_dir / "summary.json").write_text(
        json.dumps([r.card.to_dict() for r in results], indent=1), encoding="utf-8")
    return Review(report=report, logs=results, overlay=overlay)
