"""Review figures (thesis Fig 9.1-9.4 and more), drawn with matplotlib's Agg backend.

Long logs are decimated for drawing only: signals keep each block's minimum
and maximum (peaks and saturation stay visible), boolean masks keep "any in
the block", the track keeps every k-th point and breaks wherever a block
held a gap. Gaps (NaN) are drawn as breaks, never bridged. Each function
writes one PNG and returns its path, or None when the log has nothing to
draw (the report then says so instead of showing an empty frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autopilot.plotting import pyplot, track_frame
from autopilot.review.metrics import LATENESS_PERCENTILES, Scorecard, gap_after
from autopilot.review.reader import MODES, MissionLog

MAX_POINTS = 4000  # per signal on a time axis (min/max pairs)
MAX_TRACK_POINTS = 20000
PORT_COLOR, STBD_COLOR = "#c62828", "#2e7d32"  # red to port, green to starboard
_DPI = 100


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


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=_DPI)
    pyplot().close(fig)
    return path


def _has(*arrays) -> bool:
    return any(np.isfinite(a).any() for a in arrays)


def plot_track(log: MissionLog, card: Scorecard, path: Path) -> Path | None:
    """Track in the local frame with waypoints, closest approaches, start, faults and failsafes."""
    n, e = log.col("north_m"), log.col("east_m")
    wps = log.waypoints_ne_m
    if not _has(n, e) and len(wps) == 0:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 8))
    rows, _ = log.fix_rows()  # the measured fixes, a break wherever the position was lost
    fix_n, fix_e = np.full(len(n), np.nan), np.full(len(n), np.nan)
    fix_n[rows], fix_e[rows] = n[rows], e[rows]
    lost = ~(np.isfinite(n) & np.isfinite(e))
    keep = np.isfinite(fix_n) | lost
    n2, e2 = track_points(fix_n[keep], fix_e[keep])
    ax.plot(e2, n2, color="#1565c0", lw=1.2, label="track (position fixes)")
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
                text = f"W{w.index}" + (f"  {w.closest_approach_m:.2f} m" if math.isfinite(w.closest_approach_m) else "")
                ax.annotate(text, (w.east_m, w.north_m), textcoords="offset points", xytext=(9, 4), fontsize=9,
                            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.75})
    for name, marker, color in (("fault", "X", "#ef6c00"), ("failsafe", "*", "#d50000")):
        pts = [p for p in (_event_position(log, ev) for ev in log.events_named(name)) if p]
        if pts:
            arr = np.asarray(pts)
            ax.plot(arr[:, 1], arr[:, 0], marker=marker, color=color, ms=13, ls="none", label=name)
    track_frame(ax, n, e, title=f"{log.name}: track")
    fig.tight_layout()
    return _save(fig, path)


def plot_thrust(log: MissionLog, path: Path) -> Path | None:
    """Thrust and PWM per side with saturation shaded."""
    t = log.col("t_s")
    tp, ts = log.col("thrust_port_n"), log.col("thrust_stbd_n")
    pp, ps = log.col("pwm_port_pct"), log.col("pwm_stbd_pct")
    if not _has(tp, ts, pp, ps):
        return None
    plt = pyplot()
    scale, xlabel = time_scale(t)
    ts_x = t / scale
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True)
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
    axes[1].set_xlabel(xlabel)
    axes[0].set_title(f"{log.name}: thrust and PWM per side")
    fig.tight_layout()
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
    plt = pyplot()
    scale, xlabel = time_scale(t)
    fig, axes = plt.subplots(4, 1, figsize=(11, 9), sharex=True)
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
    axes[-1].set_xlabel(xlabel)
    axes[0].set_title(f"{log.name}: fuzzy guidance (dashed: waypoint reached)")
    fig.tight_layout()
    return _save(fig, path)


def plot_motion(log: MissionLog, path: Path) -> Path | None:
    """Speed over ground (with the commanded speed) and yaw rate."""
    t = log.col("t_s")
    sog, cmd, r = log.col("sog_m_s"), log.col("speed_cmd_m_s"), log.col("yaw_rate_deg_s")
    if not _has(sog, cmd, r):
        return None
    plt = pyplot()
    scale, xlabel = time_scale(t)
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    axes[0].plot(*envelope(t / scale, sog), color="#1565c0", lw=0.9, label="speed over ground")
    axes[0].plot(*envelope(t / scale, cmd), color="#ef6c00", lw=0.9, ls="--", label="commanded")
    axes[0].set_ylabel("speed (m/s)")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[1].plot(*envelope(t / scale, r), color="#1565c0", lw=0.9)
    axes[1].set_ylabel("yaw rate (deg/s, + = starboard)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[1].set_xlabel(xlabel)
    axes[0].set_title(f"{log.name}: speed and yaw rate")
    fig.tight_layout()
    return _save(fig, path)


def plot_lateness(log: MissionLog, card: Scorecard, path: Path) -> Path | None:
    """Histogram of control-loop lateness with its percentiles."""
    lat = log.col("lateness_ms")
    lat = lat[np.isfinite(lat)]
    if len(lat) == 0:
        return None
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 5))
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
    fig.tight_layout()
    return _save(fig, path)


_TIMELINE_ROWS = (
    ("waypoint_reached", "waypoint reached", "#6a1b9a", "o"),
    ("mission_complete", "mission complete", "#2e7d32", "D"),
    ("fault", "fault", "#ef6c00", "X"),
    ("fault_cleared", "fault cleared", "#ffb74d", "x"),
    ("failsafe", "failsafe", "#d50000", "*"),
    ("failsafe_cleared", "failsafe cleared", "#ef9a9a", "P"),
    ("resume", "resume", "#1565c0", ">"),
    ("stop", "stop", "#212121", "s"),
    ("info", "info", "#757575", "."),
)
_MODE_COLORS = {"auto": "#1565c0", "failsafe": "#d50000", "complete": "#2e7d32", "hold": "#f9a825",
                "waiting": "#9e9e9e"}


def plot_timeline(log: MissionLog, path: Path) -> Path | None:
    """Events on a time line, with the daemon's mode as a coloured band underneath."""
    t = log.col("t_s")
    ev_t = [ev.get("t_s") for ev in log.events]
    if len(t) == 0 and not any(isinstance(x, (int, float)) for x in ev_t):
        return None
    plt = pyplot()
    scale, xlabel = time_scale(t if len(t) else np.asarray([x for x in ev_t if isinstance(x, (int, float))]))
    fig, ax = plt.subplots(figsize=(11, 4.5))
    labels = ["mode"]
    for row, (name, label, color, marker) in enumerate(_TIMELINE_ROWS, start=1):
        xs = [ev["t_s"] / scale for ev in log.events_named(name)
              if isinstance(ev.get("t_s"), (int, float)) and not isinstance(ev.get("t_s"), bool)]
        labels.append(label)
        if xs:
            ax.plot(xs, [row] * len(xs), marker=marker, color=color, ls="none", ms=9)
    if len(t):
        k = max(1, int(math.ceil(len(t) / MAX_POINTS)))
        tm, mm = t[::k] / scale, log.mode[::k]
        change = np.nonzero(np.diff(mm))[0] + 1
        bounds = np.concatenate([[0], change, [len(mm)]])
        for a, b in zip(bounds[:-1], bounds[1:]):
            code = int(mm[a])
            name = MODES[code] if 0 <= code < len(MODES) else "unknown"
            end = tm[b] if b < len(tm) else t[-1] / scale
            ax.broken_barh([(tm[a], max(end - tm[a], 0.0))], (-0.35, 0.7),
                           color=_MODE_COLORS.get(name, "#e0e0e0"))
        for name, color in _MODE_COLORS.items():
            ax.plot([], [], color=color, lw=6, label=name)
        ax.legend(loc="upper right", fontsize=7, ncol=5, title="mode", title_fontsize=7)
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels, fontsize=8)
    ax.set_ylim(-0.7, len(labels) + 0.8)
    ax.set_xlabel(xlabel)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title(f"{log.name}: events")
    fig.tight_layout()
    return _save(fig, path)


@dataclass(frozen=True)
class Track:
    """What the overlay needs of one mission: its (decimated) track and waypoints."""

    name: str
    north_m: np.ndarray
    east_m: np.ndarray
    waypoints_ne_m: np.ndarray


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
