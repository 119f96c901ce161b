"""Review figures (thesis Fig 9.1-9.4 and more), drawn with matplotlib's Agg backend.

Long logs are decimated for drawing only: signals keep each block's minimum
and maximum (peaks and saturation stay visible), boolean masks keep "any in
the block", the track keeps every k-th point and breaks wherever a block
held a gap. Gaps (NaN) are drawn as breaks, never bridged. Every panel with
time on x has the daemon's mode as a coloured band underneath (``_time_figure``,
one colour per schema mode, one legend). Each function
writes one PNG and returns its path, or None when the log has nothing to
draw (the report then says so instead of showing an empty frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autopilot.gnc.encounter import Situation
from autopilot.logschema import Mode
from autopilot.plotting import pyplot, track_frame
from autopilot.review.metrics import (
    HOLD_ERROR_PERCENTILE,
    LATENESS_PERCENTILES,
    Scorecard,
    avoidance_logged,
    gap_after,
    nominal_period_s,
)
from autopilot.review.reader import MODES, SITUATIONS, UNKNOWN_CODE, MissionLog
from autopilot.userfile import writing

MAX_POINTS = 4000  # per signal on a time axis (min/max pairs)
MAX_TRACK_POINTS = 20000
PORT_COLOR, STBD_COLOR = "#c62828", "#2e7d32"  # red to port, green to starboard
_DPI = 100
# one colour per mode of the schema (a test fails when a mode has none); the time panels' band and the timeline
MODE_COLORS: dict[str, str] = {
    Mode.WAITING.value: "#9e9e9e",
    Mode.AUTO.value: "#1565c0",
    Mode.HOLD.value: "#f9a825",
    Mode.PAUSED.value: "#8e24aa",
    Mode.RTL.value: "#00897b",
    Mode.STOP.value: "#3e2723",
    Mode.FAILSAFE.value: "#d50000",
    Mode.COMPLETE.value: "#66bb6a",
    Mode.MANUAL.value: "#c2185b",
}
UNKNOWN_MODE_COLOR = "#e0e0e0"  # a cycle without a mode, or one the schema does not know
MODE_STRIP_IN = 0.28  # height of the mode band under the time panels
_LEGEND_IN = 0.35  # room under a time figure for the mode legend
_MIN_BAND_FRACTION = 0.002  # a mode shorter than this share of the log is widened to it: a 0.1 s failsafe in an hour stays visible
HOLD_COLOR = "#ef6c00"
MAX_LABELLED_HOLDS = 30  # more hold labels than this would hide the track (a long patrol of pauses)
LAUNCH_COLOR = MODE_COLORS[Mode.RTL.value]  # where rtl returns
OWN_TRACK_COLOR = "#1565c0"
AVOID_COLOR = "#ff6d00"  # stretches where collision avoidance changed the course or the speed
# one colour per AIS target, in order of first report (cycled beyond); none is own track's blue
TARGET_COLORS = ("#6d4c41", "#c2185b", "#00838f", "#7b1fa2", "#827717", "#455a64", "#e65100", "#283593")
# one colour per COLREGs situation (a test fails when one has none): give way warm, stand on yellow-blue
SITUATION_COLORS: dict[str, str] = {
    Situation.SAFE.value: "#c8e6c9",
    Situation.HEAD_ON.value: "#d32f2f",
    Situation.CROSSING_GIVE_WAY.value: "#f57c00",
    Situation.CROSSING_STAND_ON.value: "#fbc02d",
    Situation.OVERTAKING.value: "#8e24aa",
    Situation.OVERTAKEN.value: "#0288d1",
}
MAX_LABELLED_MANOEUVRES = 30  # as for the holds: more labels would hide the track


def time_scale(t_s: np.ndarray) -> tuple[float, str]:
    """Divisor and label of the time axis: seconds, minutes or hours."""
    span = float(t_s[-1] - t_s[0]) if len(t_s) > 1 else 0.0
    if span > 3 * 3600:
        return 3600.0, "mission time (h)"
    if span > 600:
        return 60.0, "mission time (min)"
    return 1.0, "mission time (s)"


def envelope(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Min/max decimation: at most ``max_points`` points, extremes kept, all-NaN blocks stay NaN.

    A hole in the log (rows missing for more than GAP_FACTOR periods) is a break in the
    line, never a ramp across it: a NaN point follows the row (or block) before the hole.
    """
    n = len(t)
    holes = gap_after(t)
    if n <= max_points:
        if not holes.any():
            return t, y
        at = np.nonzero(holes)[0] + 1
        return np.insert(t, at, t[at - 1]), np.insert(np.asarray(y, dtype=float), at, np.nan)
    k = int(math.ceil(n / (max_points // 2)))
    starts = np.arange(0, n, k)
    lo = np.fmin.reduceat(y, starts)
    hi = np.fmax.reduceat(y, starts)
    ends = np.minimum(starts + k - 1, n - 1)
    t2 = np.empty(2 * len(starts))
    y2 = np.empty(2 * len(starts))
    t2[0::2], t2[1::2] = t[starts], t[ends]
    y2[0::2], y2[1::2] = lo, hi
    broken = np.logical_or.reduceat(holes, starts)
    if broken.any():
        at = 2 * np.nonzero(broken)[0] + 2
        t2, y2 = np.insert(t2, at, t2[at - 1]), np.insert(y2, at, np.nan)
    return t2, y2


def block_any(t: np.ndarray, mask: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """Boolean decimation: a block is True when any of its samples is; False across a hole in the log."""
    holes = gap_after(t)
    if holes.any():  # a False sample just after the row before each hole: shading stops there
        at = np.nonzero(holes)[0] + 1
        t = np.insert(t, at, t[at - 1] + 0.5 * (t[np.minimum(at, len(t) - 1)] - t[at - 1]))
        mask = np.insert(np.asarray(mask, dtype=bool), at, False)
    n = len(t)
    if n <= max_points:
        return t, mask
    k = int(math.ceil(n / max_points))
    starts = np.arange(0, n, k)
    return t[starts], np.logical_or.reduceat(mask, starts)


def track_points(n: np.ndarray, e: np.ndarray, max_points: int = MAX_TRACK_POINTS):
    """Every k-th position; a block containing a gap becomes a break."""
    if len(n) <= max_points:
        return n, e
    k = int(math.ceil(len(n) / max_points))
    starts = np.arange(0, len(n), k)
    holes = np.add.reduceat((~np.isfinite(n) | ~np.isfinite(e)).astype(np.int32), starts) > 0
    n2, e2 = n[starts].copy(), e[starts].copy()
    n2[holes] = np.nan
    e2[holes] = np.nan
    return n2, e2


def _nearest_index(t: np.ndarray, t_event: float) -> int | None:
    if len(t) == 0 or not isinstance(t_event, (int, float)) or not math.isfinite(t_event):
        return None
    k = int(np.searchsorted(t, t_event))
    if k >= len(t):
        return len(t) - 1
    if k > 0 and abs(t[k - 1] - t_event) < abs(t[k] - t_event):
        return k - 1
    return k


def _event_position(log: MissionLog, ev: dict) -> tuple[float, float] | None:
    """Where an event happened: its own position, else the last known position at its time."""
    n, e = ev.get("north_m"), ev.get("east_m")
    if isinstance(n, (int, float)) and isinstance(e, (int, float)) and math.isfinite(n) and math.isfinite(e):
        return float(n), float(e)
    t = log.col("t_s")
    k = _nearest_index(t, ev.get("t_s"))
    if k is None:
        return None
    north, east = log.col("north_m")[: k + 1], log.col("east_m")[: k + 1]
    ok = np.nonzero(np.isfinite(north) & np.isfinite(east))[0]
    if len(ok) == 0:
        return None
    return float(north[ok[-1]]), float(east[ok[-1]])


def _shade(ax, t, mask, color, label=None):
    if not np.any(mask):
        return
    tt, mm = block_any(t, mask)
    ax.fill_between(tt, 0, 1, where=mm, step="post", color=color, alpha=0.18, lw=0,
                    transform=ax.get_xaxis_transform(), label=label)


def mode_runs(t_s: np.ndarray, mode: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mode code, start s, end s) of each run of one mode, spanning what the scorecard's mode times
    count (:func:`autopilot.review.metrics.hold_durations_s`): a run ends where the next begins, at its
    last cycle before a hole in the log (nothing is known in a hole), one period after the last cycle."""
    n = len(t_s)
    if n == 0:
        return np.zeros(0, dtype=int), np.zeros(0), np.zeros(0)
    holes = gap_after(t_s)
    starts = np.concatenate([[0], np.nonzero((np.diff(mode) != 0) | holes[:-1])[0] + 1])
    last = np.concatenate([starts[1:] - 1, [n - 1]])
    ends = np.where(holes[last], t_s[last], t_s[np.minimum(last + 1, n - 1)])
    ends[-1] = t_s[-1] + nominal_period_s(t_s)
    return mode[starts].astype(int), t_s[starts], ends


def _mode_name(code: int) -> str:
    return MODES[code] if 0 <= code < len(MODES) else "unknown"


def _mode_band(ax, log: MissionLog, scale: float, *, y0: float = 0.0, height: float = 1.0) -> list[str]:
    """The daemon's mode as coloured bars from ``y0``; returns the modes drawn, in schema order."""
    codes, start, end = mode_runs(log.col("t_s"), log.mode)
    if len(codes) == 0:
        return []
    min_width = _MIN_BAND_FRACTION * (end[-1] - start[0])
    drawn = []
    for code in sorted(set(codes.tolist()), key=lambda c: c if c >= 0 else len(MODES)):
        sel = codes == code
        name = _mode_name(code)
        bars = np.column_stack([start[sel] / scale, np.maximum(end[sel] - start[sel], min_width) / scale])
        ax.broken_barh(bars, (y0, height), color=MODE_COLORS.get(name, UNKNOWN_MODE_COLOR), lw=0)
        drawn.append(name)
    return drawn


def _mode_legend(fig, names: list[str]) -> None:
    """One legend of the mode colours, under the figure."""
    from matplotlib.patches import Patch

    if names:
        handles = [Patch(color=MODE_COLORS.get(m, UNKNOWN_MODE_COLOR), label=m) for m in names]
        fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False,
                   title="mode", title_fontsize=8, bbox_to_anchor=(0.5, 0.0))


def _time_figure(row_heights_in, *, top_heights_in=(), width_in: float = 11.0):
    """A figure of time panels sharing x, with the mode band under them (and optional panels above
    them that do not share the time axis). Returns (figure, top axes, time axes, mode axes)."""
    plt = pyplot()
    heights = [*row_heights_in, MODE_STRIP_IN]
    fig = plt.figure(figsize=(width_in, sum(heights) + sum(top_heights_in) + 1.2 + _LEGEND_IN))
    top = []
    if top_heights_in:  # its own grid: the top panels' x labels do not space out the time panels
        outer = fig.add_gridspec(2, 1, height_ratios=[sum(top_heights_in), sum(heights)])
        above = outer[0].subgridspec(len(top_heights_in), 1, height_ratios=top_heights_in)
        top = [fig.add_subplot(above[i]) for i in range(len(top_heights_in))]
        grid = outer[1].subgridspec(len(heights), 1, height_ratios=heights)
    else:
        grid = fig.add_gridspec(len(heights), 1, height_ratios=heights)
    first = fig.add_subplot(grid[0])
    rows = [first] + [fig.add_subplot(grid[i], sharex=first) for i in range(1, len(row_heights_in))]
    strip = fig.add_subplot(grid[-1], sharex=first)
    for ax in rows:
        ax.tick_params(labelbottom=False)
    return fig, top, rows, strip


def _finish_time_figure(fig, strip, log: MissionLog, scale: float, xlabel: str) -> None:
    """Mode band, its legend, the time label; then the layout with room for the legend."""
    names = _mode_band(strip, log, scale)
    strip.set_yticks([])
    strip.set_ylim(0.0, 1.0)
    strip.set_ylabel("mode", rotation=0, ha="right", va="center", fontsize=8)
    strip.set_xlabel(xlabel)
    _mode_legend(fig, names)
    fig.tight_layout(rect=(0.0, _LEGEND_IN / fig.get_figheight(), 1.0, 1.0), h_pad=0.4)


def _save(fig, path: Path) -> Path:
    with writing(path):  # a full disk names the file
        fig.savefig(path, dpi=_DPI)
    pyplot().close(fig)
    return path


def _has(*arrays) -> bool:
    return any(np.isfinite(a).any() for a in arrays)


def track_line(log: MissionLog) -> tuple[np.ndarray, np.ndarray]:
    """(north_m, east_m) of the track as drawn: the measured fixes, NaN between the stretches the exports
    break it into (:func:`autopilot.review.export.fix_stretches`)."""
    from autopilot.review.export import fix_stretches

    n, e = log.col("north_m"), log.col("east_m")
    rows, fix_t = log.fix_rows()
    gap = np.array([np.nan])
    stretches = fix_stretches(rows, fix_t, np.isfinite(n) & np.isfinite(e))
    return tuple(np.concatenate([x for a, b in stretches for x in (v[rows[a:b]], gap)] or [gap]) for v in (n, e))


def plot_track(log: MissionLog, card: Scorecard, path: Path) -> Path | None:
    """Track in the local frame with waypoints, closest approaches, start, faults, failsafes, holds and launch."""
    n, e = log.col("north_m"), log.col("east_m")
    wps = np.array([(wn, we) for _, wn, we in log.all_waypoints()]).reshape(-1, 2)  # every plan's
    if not _has(n, e) and len(wps) == 0:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 8))
    rows, _ = log.fix_rows()
    fix_n, fix_e = np.full(len(n), np.nan), np.full(len(n), np.nan)
    fix_n[rows], fix_e[rows] = n[rows], e[rows]
    n2, e2 = track_points(*track_line(log))
    _avoid_stretches(ax, log, card, fix_n, fix_e)
    ax.plot(e2, n2, color=OWN_TRACK_COLOR, lw=1.2, label="track (position fixes)")
    ok = np.nonzero(np.isfinite(n) & np.isfinite(e))[0]
    if len(ok):
        ax.plot(e[ok[0]], n[ok[0]], marker="^", color="#2e7d32", ms=11, ls="none", label="start")
        ax.plot(e[ok[-1]], n[ok[-1]], marker="s", color="#424242", ms=8, ls="none", label="end")
    if len(wps):
        ax.plot(wps[:, 1], wps[:, 0], marker="o", mfc="none", mec="black", ms=10, ls="none",
                label="waypoints")
        labelled = len(wps) <= 30
        near = [w for w in card.waypoints if math.isfinite(w.closest_approach_m)]
        if near:
            # one artist for all approach lines (NaN-separated) and one for their marks
            seg_e = np.array([[w.east_m, w.closest_east_m, np.nan] for w in near]).ravel()
            seg_n = np.array([[w.north_m, w.closest_north_m, np.nan] for w in near]).ravel()
            ax.plot(seg_e, seg_n, ls=":", color="#6a1b9a", lw=1)
            ax.plot(seg_e[1::3], seg_n[1::3], marker="x", color="#6a1b9a", ms=8, ls="none",
                    label="closest approach")
        if labelled:  # one label per waypoint (two, at the waypoint and its closest fix, overlapped)
            for w in card.waypoints:
                text = w.label + (f"  {w.closest_approach_m:.2f} m" if math.isfinite(w.closest_approach_m) else "")
                if not w.reached and math.isfinite(w.closest_approach_m):
                    text += " (not reached)"  # drawn as a reached one's, it read as a miss by metres (a review audit)
                elif w.in_hole:
                    text += " (passed in a hole in the log)"
                ax.annotate(text, (w.east_m, w.north_m), textcoords="offset points", xytext=(9, 4), fontsize=9,
                            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.75})
    for name, marker, color in (("fault", "X", "#ef6c00"), ("failsafe", "*", "#d50000")):
        pts = [p for p in (_event_position(log, ev) for ev in log.events_named(name)) if p]
        if pts:
            arr = np.asarray(pts)
            ax.plot(arr[:, 1], arr[:, 0], marker=marker, color=color, ms=13, ls="none", label=name)
    _hold_circles(ax, log, card)
    launch = log.launch_ne_m
    if launch is not None:
        ax.plot(launch[1], launch[0], marker="p", color=LAUNCH_COLOR, mec="black", ms=12, ls="none", label="launch")
    frame_n, frame_e = _target_tracks(ax, log, card)
    track_frame(ax, np.concatenate([n, frame_n]), np.concatenate([e, frame_e]), title=f"{log.name}: track")
    fig.tight_layout()
    return _save(fig, path)


def target_color(k: int) -> str:
    """The colour of the k-th target (order of first report): its track, its CPA and its table row."""
    return TARGET_COLORS[k % len(TARGET_COLORS)]


def _target_tracks(ax, log: MissionLog, card: Scorecard) -> tuple[np.ndarray, np.ndarray]:
    """Each AIS target's reported track (an arrow at its last report), where it was at own ship's closest
    approach and the line between the two, labelled with the distance. Returns the points drawn (for the frame)."""
    tracks = log.targets
    reviews = {r.target: r for r in card.targets}
    pts_n, pts_e = [], []
    for k, (mmsi, tr) in enumerate(tracks.items()):
        c = target_color(k)
        r = reviews.get(mmsi)
        met = r is not None and math.isfinite(r.closest_m)
        # the legend says who and when; the map only the distance, where the two were
        label = f"{tr.label} (AIS)" + (f": CPA {r.closest_m:.1f} m at {r.closest_t_s:.0f} s" + (
            f", required {r.required_m:.1f} m" if math.isfinite(r.required_m) else "") if met else "")
        n2, e2 = track_points(tr.north_m, tr.east_m)
        ax.plot(e2, n2, color=c, lw=1.1, marker=".", ms=3, label=label)
        pts_n.append(tr.north_m)
        pts_e.append(tr.east_m)
        if len(tr.t_s) > 1 and (tr.north_m[-1] != tr.north_m[-2] or tr.east_m[-1] != tr.east_m[-2]):
            ax.annotate("", xy=(tr.east_m[-1], tr.north_m[-1]), xytext=(tr.east_m[-2], tr.north_m[-2]),
                        arrowprops={"arrowstyle": "-|>", "color": c, "lw": 1.1})
        if not met:
            continue
        ax.plot([r.own_east_m, r.target_east_m], [r.own_north_m, r.target_north_m], color=c, ls="--", lw=1.0)
        ax.plot(r.target_east_m, r.target_north_m, marker="o", color=c, mec="black", mew=0.6, ms=8, ls="none")
        ax.plot(r.own_east_m, r.own_north_m, marker="o", color=OWN_TRACK_COLOR, mec="black", mew=0.6, ms=6, ls="none")
        ax.annotate(f"{r.closest_m:.1f} m", (0.5 * (r.own_east_m + r.target_east_m), 0.5 * (r.own_north_m + r.target_north_m)),
                    textcoords="offset points", xytext=(8, -4), fontsize=8, color=c,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})
    if not pts_n:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(pts_n), np.concatenate(pts_e)


def _avoid_stretches(ax, log: MissionLog, card: Scorecard, fix_n: np.ndarray, fix_e: np.ndarray) -> None:
    """Own track where avoidance changed the course or speed (a wide band under the track), with a marker
    where each manoeuvre began (filled) and ended (open)."""
    if not card.manoeuvres:
        return
    t = log.col("t_s")
    band_n, band_e = [], []
    for m in card.manoeuvres:
        sel = (t >= m.start_t_s) & (t <= m.end_t_s) & np.isfinite(fix_n)
        band_n += [m.start_north_m, *fix_n[sel], m.end_north_m, np.nan]
        band_e += [m.start_east_m, *fix_e[sel], m.end_east_m, np.nan]
    ax.plot(band_e, band_n, color=AVOID_COLOR, lw=6, alpha=0.45, solid_capstyle="round", label="avoidance active")
    starts = np.array([[m.start_east_m, m.start_north_m] for m in card.manoeuvres])
    ends = np.array([[m.end_east_m, m.end_north_m] for m in card.manoeuvres])
    ax.plot(starts[:, 0], starts[:, 1], marker="D", color=AVOID_COLOR, mec="black", mew=0.6, ms=8, ls="none",
            label="manoeuvre began")
    ax.plot(ends[:, 0], ends[:, 1], marker="D", mfc="white", mec=AVOID_COLOR, mew=1.5, ms=8, ls="none",
            label="manoeuvre ended")
    for m in card.manoeuvres[:MAX_LABELLED_MANOEUVRES]:
        ax.annotate(f"A{m.number}", (m.start_east_m, m.start_north_m), textcoords="offset points", xytext=(-18, 4),
                    fontsize=8, color="#bf360c")


def _hold_circles(ax, log: MissionLog, card: Scorecard) -> None:
    """Each hold point, the radius it held (the p95 of its error) and the configured drift radius (dashed)."""
    from matplotlib.patches import Circle

    if not card.holds:
        return
    drift_m = log.config_number("gnc", "hold", "radius_m")
    pts = np.array([[h.east_m, h.north_m] for h in card.holds])
    ax.plot(pts[:, 0], pts[:, 1], marker="P", color=HOLD_COLOR, mec="black", mew=0.5, ms=10, ls="none",
            label="hold point")
    achieved = drift = False
    for h in card.holds:
        if math.isfinite(h.error_p95_m):
            ax.add_patch(Circle((h.east_m, h.north_m), h.error_p95_m, fill=False, color=HOLD_COLOR, lw=1.4,
                                label=None if achieved else f"hold error p{HOLD_ERROR_PERCENTILE:g}"))
            achieved = True
        if drift_m is not None and drift_m > 0.0:  # 0 = hold precisely: no drift circle
            ax.add_patch(Circle((h.east_m, h.north_m), drift_m, fill=False, color=HOLD_COLOR, lw=1.0, ls="--",
                                label=None if drift else f"gnc.hold.radius_m = {drift_m:g} m"))
            drift = True
        if h.number <= MAX_LABELLED_HOLDS:
            text = (f"hold {h.number}: p{HOLD_ERROR_PERCENTILE:g} {h.error_p95_m:.2f} m"
                    if math.isfinite(h.error_p95_m) else f"hold {h.number}: closing only")
            ax.annotate(text, (h.east_m, h.north_m), textcoords="offset points", xytext=(9, -12), fontsize=9,
                        color="#bf360c",
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.75})


def plot_thrust(log: MissionLog, path: Path) -> Path | None:
    """Thrust and PWM per side with saturation shaded."""
    t = log.col("t_s")
    tp, ts = log.col("thrust_port_n"), log.col("thrust_stbd_n")
    pp, ps = log.col("pwm_port_pct"), log.col("pwm_stbd_pct")
    if not _has(tp, ts, pp, ps):
        return None
    scale, xlabel = time_scale(t)
    ts_x = t / scale
    fig, _, axes, strip = _time_figure((2.7, 2.7))
    sat_p, sat_s = log.col("sat_port") > 0.5, log.col("sat_stbd") > 0.5
    for ax, (port, stbd), unit in ((axes[0], (tp, ts), "thrust (N)"), (axes[1], (pp, ps), "PWM duty (%, - = reverse)")):
        ax.plot(*envelope(ts_x, port), color=PORT_COLOR, lw=0.9, label="port")
        ax.plot(*envelope(ts_x, stbd), color=STBD_COLOR, lw=0.9, label="starboard")
        _shade(ax, ts_x, sat_p, PORT_COLOR, "port saturated")
        _shade(ax, ts_x, sat_s, STBD_COLOR, "starboard saturated")
        ax.set_ylabel(unit)
        ax.grid(True, alpha=0.3)
        ax.axhline(0.0, color="black", lw=0.5)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[0].set_title(f"{log.name}: thrust and PWM per side")
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def _waypoint_lines(ax, log: MissionLog, scale: float) -> None:
    reached = [ev.get("t_s") for ev in log.events_named("waypoint_reached")]
    reached = [x for x in reached if isinstance(x, (int, float))]
    if len(reached) <= 50:
        for x in reached:
            ax.axvline(x / scale, color="#6a1b9a", ls="--", lw=0.7, alpha=0.6)


def plot_guidance(log: MissionLog, path: Path) -> Path | None:
    """TCPA', DCPA', CDH and heading error over time (thesis Fig 9.1-9.4 panel d)."""
    t = log.col("t_s")
    series = (("tcpa_nd", "TCPA' (-)"), ("dcpa_nd", "DCPA' (-)"), ("cdh", "CDH (-)"),
              ("heading_error_deg", "heading error (deg)"))
    if not _has(*(log.col(k) for k, _ in series)):
        return None
    scale, xlabel = time_scale(t)
    fig, _, axes, strip = _time_figure((1.8, 1.8, 1.8, 1.8))
    for ax, (key, label) in zip(axes, series):
        y = log.col(key)
        if np.isfinite(y).any():
            ax.plot(*envelope(t / scale, y), color="#1565c0", lw=0.9)
        else:
            ax.text(0.5, 0.5, "not logged (null for this guidance law)", ha="center", va="center",
                    transform=ax.transAxes, color="#757575")
        _waypoint_lines(ax, log, scale)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[2].set_ylim(-0.05, 1.05)
    # it said "fuzzy guidance" above a LOS run's three empty panels
    axes[0].set_title(f"{log.name}: {log.guidance_law or 'waypoint'} guidance (dashed: waypoint reached)")
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def plot_motion(log: MissionLog, path: Path) -> Path | None:
    """Speed over ground (with the commanded speed) and yaw rate."""
    t = log.col("t_s")
    sog, cmd, r = log.col("sog_m_s"), log.col("speed_cmd_m_s"), log.col("yaw_rate_deg_s")
    if not _has(sog, cmd, r):
        return None
    scale, xlabel = time_scale(t)
    fig, _, axes, strip = _time_figure((2.4, 2.4))
    axes[0].plot(*envelope(t / scale, sog), color="#1565c0", lw=0.9, label="speed over ground")
    axes[0].plot(*envelope(t / scale, cmd), color="#ef6c00", lw=0.9, ls="--", label="commanded")
    axes[0].set_ylabel("speed (m/s)")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[1].plot(*envelope(t / scale, r), color="#1565c0", lw=0.9)
    axes[1].set_ylabel("yaw rate (deg/s, + = starboard)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].set_title(f"{log.name}: speed and yaw rate")
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def plot_lateness(log: MissionLog, card: Scorecard, path: Path) -> Path | None:
    """Control-loop lateness: histogram with its percentiles, and over time (with the mode band)."""
    t = log.col("t_s")
    lat_all = log.col("lateness_ms")
    lat = lat_all[np.isfinite(lat_all)]
    if len(lat) == 0:
        return None
    scale, xlabel = time_scale(t)
    fig, (ax, ), (ax_t, ), strip = _time_figure((2.2, ), top_heights_in=(3.6, ), width_in=9.0)
    hi = max(float(lat.max()), 1e-3)
    ax.hist(lat, bins=np.linspace(min(0.0, float(lat.min())), hi, 80), color="#90a4ae", log=True)
    colors = ("#2e7d32", "#f9a825", "#ef6c00", "#d50000")
    for p, c in zip(LATENESS_PERCENTILES, colors):
        v = card.lateness_ms.get(f"p{p:g}")
        if v is not None:
            ax.axvline(v, color=c, lw=1.2, label=f"p{p:g} = {v:.2f} ms")
    ax.axvline(card.lateness_ms["max"], color="black", ls=":", label=f"max = {card.lateness_ms['max']:.2f} ms")
    ax.set_xlabel("cycle start after its deadline (ms)")
    ax.set_ylabel("cycles")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{log.name}: control-loop lateness ({len(lat)} cycles)")
    ax_t.plot(*envelope(t / scale, lat_all), color="#546e7a", lw=0.7)
    ax_t.set_ylabel("lateness (ms)")
    ax_t.grid(True, alpha=0.3)
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def plot_battery(log: MissionLog, path: Path) -> Path | None:
    """Battery voltage under load and the resting estimate the failsafe judges, its thresholds and faults.

    None when the log has no battery voltage (firmware that does not report it): no figure at all.
    """
    t = log.col("t_s")
    v_load, v_rest = log.col("battery_v"), log.col("battery_rest_v")
    if not _has(v_load):
        return None
    scale, xlabel = time_scale(t)
    fig, _, (ax, ), strip = _time_figure((4.0, ))
    ax.plot(*envelope(t / scale, v_load), color="#90a4ae", lw=0.8, label="battery_v (under load)")
    if _has(v_rest):
        ax.plot(*envelope(t / scale, v_rest), color="#1565c0", lw=1.3, label="battery_rest_v (resting estimate)")
    for key, cause, color in (("battery_low", "battery_low", "#ef6c00"),
                              ("battery_critical", "battery_critical", "#d50000")):
        limit_v = log.config_number("failsafe", f"{key}_v")
        if limit_v is not None and limit_v > 0.0:  # 0 = that failsafe is off
            for_s = log.config_number("failsafe", f"{key}_s")
            ax.axhline(limit_v, color=color, ls="--", lw=1.0,
                       label=f"{key}_v {limit_v:.2f} V" + (f" (for {for_s:g} s)" if for_s is not None else ""))
        marks = []
        for ev in log.events_named("fault"):
            k = _nearest_index(t, ev.get("t_s")) if ev.get("cause") == cause else None
            if k is not None:
                y = v_rest[k] if math.isfinite(v_rest[k]) else v_load[k]
                marks.append((float(ev["t_s"]) / scale, y if math.isfinite(y) else limit_v or math.nan))
        if marks:
            arr = np.asarray(marks, dtype=float)
            ax.plot(arr[:, 0], arr[:, 1], marker="X", ms=11, color=color, ls="none", mec="black", mew=0.6,
                    label=f"{cause} fault")
    ax.set_ylabel("battery (V)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{log.name}: battery voltage")
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def plot_avoidance(log: MissionLog, card: Scorecard, path: Path) -> Path | None:
    """Collision avoidance over time: the worst target's risk (with the give-way and stand-on thresholds),
    avoidance's share of psi_d (and the speed factor when it slowed), that target's range and DCPA, and its
    situation as a band; shaded where avoidance was active. None when the log has no avoidance data."""
    if not avoidance_logged(log):
        return None
    t = log.col("t_s")
    scale, xlabel = time_scale(t)
    tx = t / scale
    factor = log.col("avoid_speed_factor")
    slowed = bool(np.any(factor < 1.0 - 1e-6))
    fig, _, axes, strip = _time_figure((2.0, 2.2, 2.0, 0.45))
    ax_risk, ax_share, ax_range, ax_sit = axes
    active = log.col("avoid_active") > 0.5
    for ax in axes[:3]:
        _shade(ax, tx, active, AVOID_COLOR, "avoidance active" if ax is ax_risk else None)
        ax.grid(True, alpha=0.3)
    ax_risk.plot(*envelope(tx, log.col("avoid_risk")), color="#b71c1c", lw=1.0, label="risk of the worst target")
    for key, label, ls in (("give_way_risk", "give way at", "--"), ("stand_on_risk", "stand on below", ":")):
        v = log.config_number("gnc", "avoidance", key)
        if v is not None:
            ax_risk.axhline(v, color="#424242", ls=ls, lw=0.9, label=f"{label} {v:g} ({key})")
    ax_risk.set_ylim(-0.05, 1.05)
    ax_risk.set_ylabel("collision risk (-)")
    ax_risk.legend(loc="upper right", fontsize=8, ncol=2)
    ax_share.plot(*envelope(tx, log.col("avoid_psi_share_deg")), color=AVOID_COLOR, lw=1.2)
    ax_share.axhline(0.0, color="black", lw=0.5)
    ax_share.set_ylabel("share of psi_d (deg, + = stbd)")
    if slowed:
        twin = ax_share.twinx()
        twin.plot(*envelope(tx, factor), color="#546e7a", lw=0.9, ls="--")
        twin.set_ylim(0.0, 1.1)
        twin.set_ylabel("speed factor (-, dashed)", color="#546e7a")
    ax_range.plot(*envelope(tx, log.col("avoid_range_m")), color="#37474f", lw=1.0, label="range")
    ax_range.plot(*envelope(tx, log.col("avoid_dcpa_m")), color="#8e24aa", lw=1.0, label="DCPA")
    safe_m = log.config_number("gnc", "avoidance", "safe_distance_m")
    if safe_m is not None:
        ax_range.axhline(safe_m, color="#d50000", ls="--", lw=0.9, label=f"safe_distance_m {safe_m:g} m")
    ax_range.set_ylabel("worst target (m)")
    ax_range.set_yscale("symlog", linthresh=1.0)  # linear below 1 m: a DCPA of 0 (collision course) stays on the chart
    ax_range.set_ylim(bottom=0.0)
    ax_range.legend(loc="upper right", fontsize=8, ncol=3)
    drawn = _situation_band(ax_sit, log, scale)
    ax_sit.set_yticks([])
    ax_sit.set_ylim(0.0, 1.0)
    ax_sit.set_ylabel("situation", rotation=0, ha="right", va="center", fontsize=8)
    if drawn:
        from matplotlib.patches import Patch

        ax_sit.legend(handles=[Patch(color=SITUATION_COLORS.get(s, UNKNOWN_MODE_COLOR), label=s) for s in drawn],
                      loc="upper center", bbox_to_anchor=(0.5, -0.05), ncol=len(drawn), fontsize=7, frameon=False)
    marks = [ev.t_s / scale for ev in log.encounters]
    if len(marks) <= 50:  # an encounter line: a target's situation or acting changed
        for x in marks:
            ax_risk.axvline(x, color="#6a1b9a", ls="--", lw=0.6, alpha=0.6)
    ax_risk.set_title(f"{log.name}: collision avoidance, the target most at risk each cycle (dashed: encounter lines)")
    _finish_time_figure(fig, strip, log, scale, xlabel)
    return _save(fig, path)


def _situation_band(ax, log: MissionLog, scale: float) -> list[str]:
    """The worst target's situation (``avoid_situation``) as coloured bars; blank where not logged."""
    codes, start, end = mode_runs(log.col("t_s"), log.avoid_situation)
    drawn = []
    for code in sorted(set(codes.tolist())):
        if code == UNKNOWN_CODE:
            continue
        sel = codes == code
        name = SITUATIONS[code]
        bars = np.column_stack([start[sel] / scale, (end[sel] - start[sel]) / scale])
        ax.broken_barh(bars, (0.0, 1.0), color=SITUATION_COLORS.get(name, UNKNOWN_MODE_COLOR), lw=0)
        drawn.append(name)
    return drawn


_TIMELINE_ROWS = (
    ("waypoint_reached", "waypoint reached", "#6a1b9a", "o"),
    ("mission_complete", "mission complete", "#2e7d32", "D"),
    ("fault", "fault", "#ef6c00", "X"),
    ("fault_cleared", "fault cleared", "#ffb74d", "x"),
    ("failsafe", "failsafe", "#d50000", "*"),
    ("failsafe_cleared", "failsafe cleared", "#ef9a9a", "P"),
    ("resume", "resume", "#1565c0", ">"),
    ("mode", "mode change", "#455a64", "|"),
    ("command", "operator command", "#8e24aa", "v"),
    ("launch", "launch point set", LAUNCH_COLOR, "p"),
    ("position_jump", "GPS jump (refused / re-anchored)", "#00838f", "h"),
    ("encounter", "encounter (AIS target)", AVOID_COLOR, "d"),
    ("stop", "stop", "#212121", "s"),
    ("info", "info", "#757575", "."),
)
def plot_timeline(log: MissionLog, path: Path) -> Path | None:
    """Events on a time line, with the daemon's mode as a coloured band underneath."""
    t = log.col("t_s")
    ev_t = [ev.get("t_s") for ev in log.events]
    if len(t) == 0 and not any(isinstance(x, (int, float)) for x in ev_t):
        return None
    plt = pyplot()
    scale, xlabel = time_scale(t if len(t) else np.asarray([x for x in ev_t if isinstance(x, (int, float))]))
    fig, ax = plt.subplots(figsize=(11, 4.5 + _LEGEND_IN))
    labels = ["mode"]
    for row, (name, label, color, marker) in enumerate(_TIMELINE_ROWS, start=1):
        xs = [ev["t_s"] / scale for ev in log.events_named(name)
              if isinstance(ev.get("t_s"), (int, float)) and not isinstance(ev.get("t_s"), bool)]
        labels.append(label)
        if xs:
            ax.plot(xs, [row] * len(xs), marker=marker, color=color, ls="none", ms=9)
    _mode_legend(fig, _mode_band(ax, log, scale, y0=-0.35, height=0.7))
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels, fontsize=8)
    ax.set_ylim(-0.7, len(labels) - 0.3)
    ax.set_xlabel(xlabel)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title(f"{log.name}: events")
    fig.tight_layout(rect=(0.0, _LEGEND_IN / fig.get_figheight(), 1.0, 1.0))
    return _save(fig, path)


@dataclass(frozen=True)
class Track:
    """What the overlay needs of one mission: its (decimated) track and waypoints."""

    name: str
    north_m: np.ndarray
    east_m: np.ndarray
    waypoints_ne_m: np.ndarray

    @classmethod
    def of(cls, log: MissionLog) -> Track:
        """The log's track as its own chart draws it (:func:`track_line`: broken where fixes were lost)."""
        n, e = track_points(*track_line(log))
        return cls(log.name, n.copy(), e.copy(), np.array([(wn, we) for _, wn, we in log.all_waypoints()]).reshape(-1, 2))


def plot_overlay(tracks: list[Track], path: Path) -> Path | None:
    """Tracks of several missions on one chart, each with its waypoints."""
    if not any(_has(tr.north_m) for tr in tracks):
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 8))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, tr in enumerate(tracks):
        c = colors[i % len(colors)]
        n2, e2 = tr.north_m, tr.east_m
        ax.plot(e2, n2, color=c, lw=1.2, label=f"{i + 1}: {tr.name}")
        wps = tr.waypoints_ne_m
        if len(wps):
            ax.plot(wps[:, 1], wps[:, 0], marker="o", mfc="none", mec=c, ms=10, ls="none")
        ok = np.nonzero(np.isfinite(n2) & np.isfinite(e2))[0]
        if len(ok):
            ax.plot(e2[ok[0]], n2[ok[0]], marker="^", color=c, ms=9, ls="none")
    track_frame(ax, np.concatenate([tr.north_m for tr in tracks]), np.concatenate([tr.east_m for tr in tracks]),
                title="tracks (triangles: start, circles: waypoints)")
    fig.tight_layout()
    return _save(fig, path)
