"""Where the baseline replay disagrees with the measurements, and how the gap grows.

Measurements are classed by what the boat was doing (model state of the baseline
replay, commands): straight or turning, port or starboard turn, low or high
speed, the seconds after a thrust step. For each class: heading residual RMS
and mean, and the rate at which the position error grows (m/s). Patterns:
an earth-fixed drift (the same drift velocity in every trial, current-like),
a steady heading offset, a lag (heading residual proportional to yaw rate).
"""

from __future__ import annotations

import math

import numpy as np

TURN_RATE_RAD_S = 0.05
LOW_SPEED_M_S = 1.0
STEP_N = 3.0
AFTER_STEP_S = 5.0
GROWTH_WINDOW_S = 2.0


def _classes(u, r, tp, ts, t, dt):
    step = np.zeros(t.size, dtype=bool)
    jumps = np.flatnonzero((np.abs(np.diff(tp)) > STEP_N) | (np.abs(np.diff(ts)) > STEP_N)) + 1
    for k in jumps:
        step[k : k + int(AFTER_STEP_S / dt)] = True
    turning = np.abs(r) > TURN_RATE_RAD_S
    return {
        "straight": ~turning,
        "turn_port": turning & (r < 0),
        "turn_starboard": turning & (r > 0),
        "low_speed": np.abs(u) < LOW_SPEED_M_S,
        "high_speed": np.abs(u) >= LOW_SPEED_M_S,
        "after_thrust_step": step,
        "steady_thrust": ~step,
    }


def _at(grid_t, series, t):
    return np.interp(t, grid_t, series)


def _growth(m, rn, re) -> np.ndarray:
    """Growth rate (m/s) of the position error between fixes at least GROWTH_WINDOW_S apart (NaN at the end)."""
    later = np.searchsorted(m.t_pos_s, m.t_pos_s + GROWTH_WINDOW_S - 1e-9)
    has = later < m.t_pos_s.size
    growth = np.full(m.t_pos_s.size, np.nan)
    lk = later[has]
    growth[has] = np.hypot(rn[lk] - rn[has], re[lk] - re[has]) / (m.t_pos_s[lk] - m.t_pos_s[has])
    return growth


def _accumulate(acc: dict, cls: dict, k_h, k_p, rh, rn, re, growth) -> None:
    for name, mask in cls.items():
        mh, mp = mask[k_h], mask[k_p]
        a = acc.setdefault(name, {"n": 0, "h2": 0.0, "h1": 0.0, "np": 0, "p2": 0.0, "g": 0.0, "ng": 0})
        a["n"] += int(mh.sum())
        a["h2"] += float(np.sum(rh[mh] ** 2))
        a["h1"] += float(np.sum(rh[mh]))
        a["np"] += int(mp.sum())
        a["p2"] += float(np.sum(rn[mp] ** 2 + re[mp] ** 2))
        gm = mp & np.isfinite(growth)
        a["g"] += float(np.sum(growth[gm]))
        a["ng"] += int(gm.sum())


def locate(prep, pred, trials_idx, runs) -> dict:
    """Residual statistics per class and the growth patterns (``pred`` from prediction.predict), each
    measurement at the time it was taken (prediction.raw_residuals)."""
    from autopilot.sysid.prediction import raw_residuals

    dt, g = prep.dt_s, prep.t_grid
    acc = {}
    drift_v, lag_x, lag_y, head_all = [], [], [], []
    for i, j in zip(trials_idx, runs):
        m = prep.measured[i]
        rn, re, rh = (x[0] for x in raw_residuals(prep, i, pred, [j]))
        cls = _classes(pred["u_m_s"][j], pred["r_rad_s"][j], prep.thrust_port_n[i], prep.thrust_stbd_n[i], g, dt)
        k_p = np.clip(np.rint(m.t_pos_s / dt).astype(int), 0, g.size - 1)
        k_h = np.clip(np.rint(m.t_psi_s / dt).astype(int), 0, g.size - 1)
        _accumulate(acc, cls, k_h, k_p, rh, rn, re, _growth(m, rn, re))
        if m.t_pos_s.size > 10:
            drift_v.append([np.polyfit(m.t_pos_s, rn, 1)[0], np.polyfit(m.t_pos_s, re, 1)[0]])
        lag_x.append(_at(g, pred["r_rad_s"][j], m.t_psi_s))
        lag_y.append(rh)
        head_all.append(rh)
    return _summarise(acc, drift_v, lag_x, lag_y, head_all)


def _summarise(acc, drift_v, lag_x, lag_y, head_all) -> dict:
    segments = {}
    for name, a in acc.items():
        if a["n"] == 0:
            continue
        segments[name] = {
            "samples": a["n"],
            "position_fixes": a["np"],
            "position_rms_m": math.sqrt(a["p2"] / a["np"]) if a["np"] else None,
            "heading_rms_deg": math.degrees(math.sqrt(a["h2"] / a["n"])),
            "heading_mean_deg": math.degrees(a["h1"] / a["n"]),
            "position_error_growth_m_s": a["g"] / a["ng"] if a["ng"] else None,
        }
    patterns = []
    dv = np.asarray(drift_v)
    if dv.size:
        mean_v = dv.mean(axis=0)
        speed = float(np.hypot(*mean_v))
        spread = float(np.sqrt(np.mean(np.sum((dv - mean_v) ** 2, axis=1))))
        kind = "earth-fixed (same in every trial: current- or wind-like)" if speed > 0.03 and spread < 0.5 * speed else "varies between trials"
        patterns.append({
            "pattern": "drift", "north_m_s": float(mean_v[0]), "east_m_s": float(mean_v[1]), "speed_m_s": speed,
            "spread_m_s": spread, "kind": kind,
        })
    h = np.concatenate(head_all) if head_all else np.zeros(0)
    if h.size:
        mean, std = float(np.mean(h)), float(np.std(h))
        patterns.append({"pattern": "steady_heading_offset", "mean_deg": math.degrees(mean), "std_deg": math.degrees(std),
                         "steady": bool(abs(mean) > 2 * std)})
        x, y = np.concatenate(lag_x), np.concatenate(lag_y)
        if np.sum(x * x) > 0:
            k = float(np.sum(x * (y - mean)) / np.sum(x * x))
            corr = float(np.corrcoef(x, y)[0, 1]) if np.std(x) > 0 and np.std(y) > 0 else 0.0
            patterns.append({"pattern": "lag", "heading_residual_per_yaw_rate_s": k, "correlation": corr,
                             "lag_like": bool(k < 0 and corr < -0.5),
                             "note": "negative: the measured heading trails the model by about -k seconds"})
    return {"segments": segments, "patterns": patterns, "text": describe(segments, patterns)}


def describe(segments: dict, patterns: list) -> list[str]:
    """Plain sentences for the report."""
    out = []
    def seg(name):
        return segments.get(name, {})
    pairs = (("straight", "turn_port"), ("turn_port", "turn_starboard"), ("low_speed", "high_speed"),
             ("steady_thrust", "after_thrust_step"))
    for a, b in pairs:
        sa, sb = seg(a), seg(b)
        if sa and sb:
            out.append(
                f"{a}: heading residual {sa['heading_rms_deg']:.2f} deg rms, position error grows "
                f"{(sa['position_error_growth_m_s'] or 0):.3f} m/s; {b}: {sb['heading_rms_deg']:.2f} deg rms, "
                f"{(sb['position_error_growth_m_s'] or 0):.3f} m/s"
            )
    for p in patterns:
        if p["pattern"] == "drift":
            out.append(f"drift of the track: {p['speed_m_s']:.3f} m/s towards "
                       f"{math.degrees(math.atan2(p['east_m_s'], p['north_m_s'])) % 360:.0f} deg, {p['kind']}")
        elif p["pattern"] == "steady_heading_offset":
            out.append(f"heading residual mean {p['mean_deg']:+.2f} deg, std {p['std_deg']:.2f} deg"
                       + (" (a steady offset)" if p["steady"] else ""))
        elif p["pattern"] == "lag":
            out.append(f"heading residual vs yaw rate: {p['heading_residual_per_yaw_rate_s']:+.2f} s "
                       f"(correlation {p['correlation']:+.2f})" + (" - lag-like" if p["lag_like"] else ""))
    return out
