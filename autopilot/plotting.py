"""What every figure of the project shares: the headless backend and the frame of a track plot.

matplotlib is imported here, lazily, by the commands that draw (review, evaluate --plot,
model manoeuvre --plot, sysid reports); nothing else imports it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pyplot", "track_frame", "MAX_EQUAL_ASPECT", "MIN_TRACK_SPAN_M"]

MAX_EQUAL_ASPECT = 8.0  # a track longer than this many times its width is drawn stretched, not as a strip
# A track that stays within this (a boat spinning in place) is drawn in a square this wide round it: matplotlib
# scaled the axes to the data, and `model manoeuvre spin` showed floating-point noise as circles 1e-11 m across.
MIN_TRACK_SPAN_M = 2.0


def pyplot():
    """matplotlib.pyplot on the Agg backend (no screen on the boat PC or in CI)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def track_frame(ax, north_m, east_m, *, title: str = "") -> None:
    """North up, east right, metres on both axes at the same scale, unless the track is a long
    thin strip (a zig-zag run 160 m by 10 m): then each axis gets its own scale and the title
    says so. The legend goes where it covers the least data."""
    n = np.asarray(north_m, dtype=float)
    e = np.asarray(east_m, dtype=float)
    ok = np.isfinite(n) & np.isfinite(e)
    span_n = float(np.ptp(n[ok])) if ok.any() else 0.0
    span_e = float(np.ptp(e[ok])) if ok.any() else 0.0
    long_side, short_side = max(span_n, span_e), max(min(span_n, span_e), 1.0)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    if ok.any() and long_side < MIN_TRACK_SPAN_M:
        mid_n = 0.5 * (float(n[ok].min()) + float(n[ok].max()))
        mid_e = 0.5 * (float(e[ok].min()) + float(e[ok].max()))
        ax.set_xlim(mid_e - MIN_TRACK_SPAN_M / 2, mid_e + MIN_TRACK_SPAN_M / 2)
        ax.set_ylim(mid_n - MIN_TRACK_SPAN_M / 2, mid_n + MIN_TRACK_SPAN_M / 2)
        ax.set_aspect("equal", adjustable="box")
    elif long_side / short_side <= MAX_EQUAL_ASPECT:
        ax.set_aspect("equal", adjustable="datalim")
    else:
        title = (title + " " if title else "") + "(axes not to the same scale)"
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best", fontsize=8, framealpha=0.85)
