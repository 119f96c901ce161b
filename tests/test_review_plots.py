"""The review's figures: a hole in the log is a break in every time panel, never a ramp across it."""

from __future__ import annotations

import numpy as np

from autopilot.review.plots import block_any, envelope


def _segments(t, y):
    """Runs of finite points as drawn by matplotlib (a NaN breaks the line)."""
    ok = np.isfinite(y)
    out, cur = [], []
    for ti, yi, k in zip(t, y, ok):
        if k:
            cur.append(ti)
        elif cur:
            out.append(cur)
            cur = []
    if cur:
        out.append(cur)
    return out


def test_a_log_gap_breaks_the_line_short_log():
    t = np.concatenate([np.arange(0.0, 10.0, 0.1), np.arange(20.0, 30.0, 0.1)])  # 10 s without cycle lines
    y = np.concatenate([np.full(100, 30.0), np.full(100, -30.0)])
    t2, y2 = envelope(t, y)
    segs = _segments(t2, y2)
    assert len(segs) == 2 and segs[0][-1] < 10.0 and segs[1][0] >= 20.0  # no segment spans the hole


def test_a_log_gap_breaks_the_line_decimated_log():
    t = np.concatenate([np.arange(0.0, 1000.0, 0.1), np.arange(1100.0, 2000.0, 0.1)])  # 19000 rows, decimated
    y = np.sin(t)
    t2, y2 = envelope(t, y)
    assert len(t2) < len(t)
    segs = _segments(t2, y2)
    assert len(segs) == 2 and segs[0][-1] < 1001.0 and segs[1][0] >= 1000.0


def test_saturation_shading_stops_at_a_gap():
    t = np.concatenate([np.arange(0.0, 5.0, 0.1), np.arange(15.0, 20.0, 0.1)])
    mask = np.ones(len(t), dtype=bool)
    tt, mm = block_any(t, mask)
    # drawn with step="post": the sample before the hole must be followed by a False inside it
    k = int(np.nonzero(tt > 4.95)[0][0])
    assert tt[k] < 15.0 and not mm[k]


def test_no_gap_no_change():
    t = np.arange(0.0, 10.0, 0.1)
    y = np.cos(t)
    t2, y2 = envelope(t, y)
    assert np.array_equal(t2, t) and np.array_equal(y2, y)


def test_the_guidance_figure_names_the_law_the_log_flew(tmp_path, monkeypatch):
    """Found by a new-user audit: the figure was titled "fuzzy guidance" above a LOS run's empty TCPA/DCPA/CDH."""
    from autopilot.review import plots
    from autopilot.review.reader import read_log
    from autopilot.review.synthetic import write_synthetic_log

    path = tmp_path / "los.jsonl"
    write_synthetic_log(path, duration_s=20.0)
    path.write_text(path.read_text().replace('"guidance": "fuzzy"', '"guidance": "los"', 1))
    log = read_log(path)
    assert log.guidance_law == "los"
    titles = []
    monkeypatch.setattr(plots, "_save", lambda fig, p: titles.append(fig.axes[0].get_title()) or p)
    plots.plot_guidance(log, tmp_path / "g.png")
    assert titles == ["synthetic: los guidance (dashed: waypoint reached)"]


def test_the_track_drawn_breaks_where_the_gps_was_lost_as_the_exports_do(tmp_path):
    """Found by a new-user audit: through an 8-s GPS outage the daemon holds the last fix (its age growing); the
    GPX and GeoJSON broke the track there, the track plot drew a straight line across."""
    import json

    from autopilot.review.export import track_fixes
    from autopilot.review.plots import track_line
    from autopilot.review.reader import read_log
    from autopilot.review.synthetic import write_synthetic_log

    path = tmp_path / "m.jsonl"
    write_synthetic_log(path, duration_s=60.0)
    out, held = [], None
    for line in path.read_text().splitlines():
        rec = json.loads(line)
        if rec.get("event") == "cycle" and 20.0 <= rec["t_s"] < 28.0:
            if held is None:  # the last fix before the outage, held from here on with its age growing
                held = {k: rec[k] for k in ("north_m", "east_m", "lat_deg", "lon_deg")}
                held["fix_t_s"] = rec["t_s"] - rec["position_age_s"]
            rec.update({k: v for k, v in held.items() if k != "fix_t_s"}, position_age_s=rec["t_s"] - held["fix_t_s"])
        out.append(json.dumps(rec))
    path.write_text("\n".join(out) + "\n")
    log = read_log(path)
    n, _ = track_line(log)
    assert len(track_fixes(log)[3]) == 2
    breaks = np.flatnonzero(np.isnan(n))
    assert len(breaks) == 2 and breaks[-1] == len(n) - 1  # one break inside, the end
    _, fix_t = log.fix_rows()
    assert fix_t[breaks[0] - 1] < 20.0 and fix_t[breaks[0]] >= 27.0  # across the outage, nothing drawn


def test_the_overlay_of_several_logs_breaks_a_track_where_the_log_has_a_hole(tmp_path, monkeypatch):
    """Found by a review audit: a daemon stopped for 2 s (SIGSTOP) left a 20-s hole in its log; the log's own
    track broke there, the overlay of several logs drew a straight line across it (raw rows, not fixes)."""
    import json

    from autopilot.review import plots
    from autopilot.review.report import review
    from autopilot.review.synthetic import write_synthetic_log

    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    write_synthetic_log(a, duration_s=60.0, loop=True)
    write_synthetic_log(b, duration_s=60.0, loop=True)
    kept = [line for line in a.read_text().splitlines()
            if not (json.loads(line).get("event") == "cycle" and 20.0 <= json.loads(line)["t_s"] < 40.0)]
    a.write_text("\n".join(kept) + "\n")
    drawn = {}
    real = plots.plot_overlay
    monkeypatch.setattr(plots, "plot_overlay", lambda tracks, path: drawn.setdefault("tracks", tracks) and real(tracks, path))
    review([a, b], tmp_path / "out")
    north = drawn["tracks"][0].north_m
    assert np.isnan(north[:-1]).sum() == 1  # one break inside: across the hole
    from autopilot.review.reader import read_log

    n_own, _ = plots.track_line(read_log(a))  # the log's own chart
    assert np.array_equal(np.isnan(north), np.isnan(n_own)) and np.array_equal(north[~np.isnan(north)], n_own[~np.isnan(n_own)])
