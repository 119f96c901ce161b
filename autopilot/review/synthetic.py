"""Synthetic mission logs in the schema of :mod:`autopilot.logschema` (every cycle key, schema values only).

For tests and the review benchmark: a kinematic boat that follows the legs
between waypoints with a slow sideways weave, so every cycle field has a
plausible value, cross-track error is non-zero and known (the weave), and a
24-hour 10 Hz log can be produced in seconds (vectorised, no simulator).
It is not a vessel model: use ``autopilot.sim`` for physics.

Options reproduce what the review must cope with: a mission stopped by a
failsafe (heading lost, thrust zeroed, then ``stop``), a looping mission
for long logs, periodic sensor drop-outs (null fields), saturation on turns.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from pathlib import Path

import numpy as np

from autopilot.geo import local_to_latlon, wrap_180, wrap_360
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.measured import HULL_LENGTH_M

THESIS_SIM_WAYPOINTS_NE_M = ((10.0, 5.0), (35.0, 20.0), (50.0, 16.0))  # SPEC section 7
DEFAULT_ORIGIN_DEG = (59.4370, 10.5880)
START_TIMESTAMP = _dt.datetime(2024, 5, 21, 9, 30, 0, tzinfo=_dt.timezone.utc)
_CHUNK_ROWS = 20_000


def _iso(t_s: float) -> str:
    stamp = START_TIMESTAMP + _dt.timedelta(seconds=t_s)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _line(event: str, t_s: float, **fields) -> str:
    record = {"event": event, "t_s": round(t_s, 3), **fields, "timestamp": _iso(t_s)}
    return json.dumps(record) + "\n"


def write_synthetic_log(
    path,
    *,
    duration_s: float = 120.0,
    rate_hz: float = 10.0,
    waypoints_ne_m=THESIS_SIM_WAYPOINTS_NE_M,
    speed_m_s: float = 1.5,
    weave_m: float = 1.0,
    boat_length_m: float = HULL_LENGTH_M,
    origin_deg: tuple[float, float] = DEFAULT_ORIGIN_DEG,
    loop: bool = False,
    failsafe_at_s: float | None = None,
    dropout_every_s: float | None = None,
    fix_rate_hz: float = 1.0,
    seed: int = 0,
) -> dict:
    """Write a mission log; return the truth it was made from.

    The boat starts at (0, 0) and runs the legs start -> W0 -> W1 ... at
    ``speed_m_s`` with a sideways weave of amplitude ``weave_m``. With
    ``loop`` the waypoint list is repeated until ``duration_s`` (a long
    patrol); otherwise the mission completes at the last waypoint.
    ``failsafe_at_s`` loses the heading there, zeroes thrust, coasts 3 s and
    stops. ``dropout_every_s`` blanks position and heading for 1 s that often.
    Positions are GPS fixes at ``fix_rate_hz`` (1 Hz, as the SC-30 sends GGA/RMC),
    each repeated on the cycle lines until the next one with its growing
    ``position_age_s``, as the daemon logs them; the heading is new every cycle.

    Returns ``{"t_s", "north_m", "east_m", "thrust_port_n", "thrust_stbd_n",
    "waypoints_ne_m", "cycles", "failsafe_at_s", "complete"}``.
    """
    rng = np.random.default_rng(seed)
    wps = np.asarray(waypoints_ne_m, dtype=float).reshape(-1, 2)
    dt_s = 1.0 / rate_hz
    if loop:
        lap_m = float(np.sum(np.hypot(*np.diff(np.vstack([wps, wps[:1]]), axis=0).T)))
        laps = int(math.ceil(duration_s * speed_m_s / max(lap_m, 1e-6))) + 1
        wps = np.tile(wps, (laps, 1))
    nodes = np.vstack([[0.0, 0.0], wps])
    seg = np.diff(nodes, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    path_end_s = cum[-1] / speed_m_s
    end_s = duration_s if loop else min(duration_s, path_end_s)
    if failsafe_at_s is not None:
        end_s = min(end_s, failsafe_at_s + 3.0)
    n = int(round(end_s * rate_hz)) + 1
    t = np.arange(n) * dt_s

    moving = np.ones(n, dtype=bool)
    if failsafe_at_s is not None:
        moving = t < failsafe_at_s
    # arc length: constant speed, then coasting to a stop after a failsafe
    s = np.minimum(t * speed_m_s, cum[-1])
    if failsafe_at_s is not None:
        t_f = failsafe_at_s
        s_f = min(t_f * speed_m_s, cum[-1])
        tau_s = 2.0
        coast = s_f + speed_m_s * tau_s * (1.0 - np.exp(-(t - t_f) / tau_s))
        s = np.where(moving, s, np.minimum(coast, cum[-1]))
    leg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - cum[leg]) / np.maximum(seg_len[leg], 1e-9)
    unit = seg / np.maximum(seg_len, 1e-9)[:, None]
    base = nodes[leg] + frac[:, None] * seg[leg]
    normal = np.stack([-unit[leg, 1], unit[leg, 0]], axis=1)  # starboard of the leg
    w_rad_s = 2.0 * math.pi / 40.0
    weave = weave_m * np.sin(w_rad_s * t)
    pos = base + weave[:, None] * normal
    north, east = pos[:, 0], pos[:, 1]
    leg_bearing_deg = np.degrees(np.arctan2(unit[leg, 1], unit[leg, 0]))
    weave_rate = weave_m * w_rad_s * np.cos(w_rad_s * t)
    psi_deg = wrap_360(leg_bearing_deg + np.degrees(np.arctan2(weave_rate, speed_m_s)))
    heading = wrap_360(psi_deg + rng.normal(0.0, 0.3, n))
    yaw_rate = np.gradient(np.unwrap(np.radians(psi_deg)), dt_s)
    yaw_rate_deg_s = np.degrees(yaw_rate)
    sog = np.where(moving, speed_m_s, np.gradient(s, dt_s)) + rng.normal(0.0, 0.02, n)

    wp_index = leg.copy()
    target = wps[np.minimum(wp_index, len(wps) - 1)]
    d_n, d_e = target[:, 0] - north, target[:, 1] - east
    dist = np.hypot(d_n, d_e)
    alpha = np.arctan2(d_e, d_n) - np.radians(psi_deg)
    dcpa_nd = np.abs(dist * np.sin(alpha)) / boat_length_m  # Eq 6.5, 6.7
    tcpa_nd = dist * np.cos(alpha) / boat_length_m  # Eq 6.6, 6.8 (U cancels)
    cdh = np.clip(1.0 - tcpa_nd / 4.0, 0.0, 1.0)
    psi_d_deg = wrap_360(np.degrees(np.arctan2(d_e, d_n)))
    err_deg = wrap_180(psi_d_deg - psi_deg)
    curve = ThrustCurve()
    tau_com = np.full(n, 16.0)
    tau_order = np.clip(0.3 * err_deg, -30.0, 30.0)  # Eq 7.1 form, P term only (a stiff gain: saturates on turns)
    port = np.clip(tau_com + tau_order, -curve.max_reverse_n, curve.max_forward_n)
    stbd = np.clip(tau_com - tau_order, -curve.max_reverse_n, curve.max_forward_n)
    sat_port = (port >= curve.max_forward_n) | (port <= -curve.max_reverse_n)
    sat_stbd = (stbd >= curve.max_forward_n) | (stbd <= -curve.max_reverse_n)
    port = np.where(moving, port, 0.0)
    stbd = np.where(moving, stbd, 0.0)
    sat_port &= moving
    sat_stbd &= moving
    pwm_port = curve.signed_duty_pct(port)
    pwm_stbd = curve.signed_duty_pct(stbd)
    lateness = rng.exponential(0.6, n)
    lateness[rng.random(n) < 0.001] += 15.0
    nmea_dropped = np.cumsum(rng.random(n) < 0.002)
    ack_missing = np.cumsum(rng.random(n) < 0.0005)

    # what the daemon logs: the last fix held (and ageing) until the next one arrives
    every = max(1, int(round(rate_hz / fix_rate_hz)))
    fix_row = (np.arange(n) // every) * every
    fix_latency_s = 0.05
    position_age = t - t[fix_row] + fix_latency_s
    north_true, east_true = north, east
    north, east = north[fix_row], east[fix_row]
    sog_fix, cog_fix = sog[fix_row], psi_deg[fix_row]
    lat, lon = local_to_latlon(north, east, *origin_deg)
    valid_heading = moving.copy()
    valid_pos = np.ones(n, dtype=bool)
    if dropout_every_s:
        phase = np.mod(t, dropout_every_s)
        gap = (phase >= dropout_every_s / 2) & (phase < dropout_every_s / 2 + 1.0)
        valid_heading &= ~gap
        valid_pos &= ~gap
    complete_idx = None
    if not loop and failsafe_at_s is None and end_s >= path_end_s:
        complete_idx = n - 1

    # waypoint passages: the cycle where the leg changes; the closest fix of each pass (fixes
    # while on the leg to W_i and on the next one) is logged when the pass ends, as the daemon does
    reached = np.nonzero(np.diff(leg))[0] + 1
    events_at: dict[int, list[str]] = {}
    is_fix = (np.arange(n) % every == 0) & valid_pos
    end_of_pass = {int(leg[k - 1]) - 1: int(k) for k in reached}  # W_{i+1} reached ends W_i's pass
    passes = {}
    for i in range(len(wps)):
        sel = is_fix & ((leg == i) | (leg == i + 1)) & (np.arange(n) <= end_of_pass.get(i, n - 1))
        if sel.any():
            d = np.hypot(north[sel] - wps[i, 0], east[sel] - wps[i, 1])
            j = int(np.argmin(d))
            passes[i] = (round(float(d[j]), 3), float(t[sel][j] - fix_latency_s))
    for k in reached:
        i = int(leg[k - 1])
        events_at.setdefault(k, []).append(
            _line("waypoint_reached", t[k], wp_index=i, north_m=round(float(north_true[k]), 3),
                  east_m=round(float(east_true[k]), 3), distance_m=round(float(abs(weave[k])), 3),
                  how="passed"))
        if i - 1 in passes:
            ca, ct = passes[i - 1]
            events_at[k].append(_line("waypoint_pass", t[k], wp_index=i - 1, closest_approach_m=ca, closest_t_s=ct))
    fs_idx = None
    if failsafe_at_s is not None:
        fs_idx = int(np.argmax(~moving)) if (~moving).any() else None
        if fs_idx is not None:
            events_at.setdefault(fs_idx, []).extend([
                _line("fault", t[fs_idx], cause="heading_stale", detail="no heading for 0.5 s"),
                _line("failsafe", t[fs_idx], cause="heading_stale", action="stop", configured="stop", fallback=None),
            ])

    mode = np.where(moving, "auto", "failsafe")
    battery_rest = 12.65 - 0.3 * t / max(float(t[-1]), 1.0)
    fields = {
        "lat_deg": (lat, "%.8f", valid_pos), "lon_deg": (lon, "%.8f", valid_pos),
        "north_m": (north, "%.3f", valid_pos), "east_m": (east, "%.3f", valid_pos),
        "heading_deg": (heading, "%.2f", valid_heading),
        "yaw_rate_deg_s": (yaw_rate_deg_s, "%.3f", valid_heading),
        "sog_m_s": (sog_fix, "%.3f", valid_pos), "cog_deg": (cog_fix, "%.2f", valid_pos),
        "fix_quality": (np.where(valid_pos, 1, 0), "%d", None),
        "heading_age_s": (np.full(n, 0.05), "%.3f", valid_heading),
        "position_age_s": (position_age, "%.3f", valid_pos),
        "wp_index": (wp_index, "%d", None),
        "tcpa_nd": (tcpa_nd, "%.4f", valid_heading), "dcpa_nd": (dcpa_nd, "%.4f", valid_heading),
        "cdh": (cdh, "%.4f", valid_heading), "psi_d_deg": (psi_d_deg, "%.2f", valid_heading),
        "heading_error_deg": (err_deg, "%.2f", valid_heading),
        "xte_m": (weave, "%.3f", valid_pos), "speed_cmd_m_s": (np.full(n, speed_m_s), "%.2f", None),
        "pid_p_n": (np.where(moving, tau_order, 0.0), "%.3f", None),
        "pid_i_n": (np.zeros(n), "%.3f", None), "pid_d_n": (np.zeros(n), "%.3f", None),
        "tau_com_n": (np.where(moving, tau_com, 0.0), "%.3f", None),
        "tau_order_n": (np.where(moving, tau_order, 0.0), "%.3f", None),
        "thrust_port_n": (port, "%.3f", None), "thrust_stbd_n": (stbd, "%.3f", None),
        "pwm_port_pct": (pwm_port, "%.2f", None), "pwm_stbd_pct": (pwm_stbd, "%.2f", None),
        "lateness_ms": (lateness, "%.3f", None),
        "heading_latency_ms": (np.full(n, 4.2), "%.2f", valid_heading),
        "seq": (np.arange(n), "%d", None), "ack_missing": (ack_missing, "%d", None),
        "nmea_dropped": (nmea_dropped, "%d", None),
        "est_north_m": (north_true, "%.3f", moving), "est_east_m": (east_true, "%.3f", moving),
        "tau_com_trim_n": (np.zeros(n), "%.3f", moving), "skipped_cycles": (np.zeros(n, dtype=int), "%d", None),
        "turn_limit": (np.where(sat_port & ~sat_stbd & (tau_order > 0), 1, np.where(sat_stbd & ~sat_port & (tau_order < 0), -1, 0)), "%d", None),
        "common_limit": (np.zeros(n, dtype=int), "%d", None),
        "hold_north_m": (np.zeros(n), "%.3f", np.zeros(n, dtype=bool)),
        "hold_east_m": (np.zeros(n), "%.3f", np.zeros(n, dtype=bool)),
        "hold_error_m": (np.zeros(n), "%.3f", np.zeros(n, dtype=bool)),
        "holding": (np.full(n, "false"), "%s", None),
        "hold_heading_deg": (np.zeros(n), "%.2f", np.zeros(n, dtype=bool)),
        "hold_disturbance_n": (np.zeros(n), "%.3f", np.zeros(n, dtype=bool)),
        # a 105 Ah battery slowly discharging, sagging with the thrust (autopilot/sim/battery.py's shape)
        "battery_v": (battery_rest - 1.2 * 0.5 * ((np.abs(pwm_port) / 100) ** 3 + (np.abs(pwm_stbd) / 100) ** 3), "%.2f",
                      t > 0.5),
        "battery_rest_v": (battery_rest, "%.2f", t > 0.5),
        **{k: (np.zeros(n), "%.1f", np.zeros(n, dtype=bool)) for k in (
            "avoid_active", "avoid_psi_share_deg", "avoid_speed_factor", "avoid_targets", "avoid_target",
            "avoid_situation", "avoid_risk", "avoid_range_m", "avoid_dcpa_m", "avoid_tcpa_s", "avoid_reason")},
    }
    path = Path(path)
    origin_lat, origin_lon = origin_deg
    with path.open("w", encoding="utf-8") as f:
        f.write(_line(
            "mission_start", 0.0, mission="missions/synthetic.yaml", mission_name="synthetic",
            guidance="fuzzy", rate_hz=rate_hz, sim=True, speedup=1.0,
            origin_lat_deg=origin_lat, origin_lon_deg=origin_lon,
            waypoints=[[float(a), float(b)] for a, b in wps], waypoint_speeds_m_s=[None] * len(wps),
            boat_length_m=boat_length_m, config={"guidance": {"law": "fuzzy"}}, version="0.1.0"))
        names = list(fields)
        for a in range(0, n, _CHUNK_ROWS):
            b = min(a + _CHUNK_ROWS, n)
            cols = []
            for name in names:
                values, fmt, valid = fields[name]
                strs = [fmt % v for v in values[a:b].tolist()]
                if valid is not None:
                    strs = [s if ok else "null" for s, ok in zip(strs, valid[a:b].tolist())]
                cols.append(strs)
            t_strs = ["%.3f" % v for v in t[a:b].tolist()]
            head = '{"event": "cycle", "t_s": %s, "cycle": %d, "mode": "%s", "heading_source": %s, '
            for j in range(b - a):
                k = a + j
                for extra in events_at.get(k, ()):
                    f.write(extra)
                hs = '"HDT"' if valid_heading[k] else "null"
                body = ", ".join(f'"{nm}": {cols[c][j]}' for c, nm in enumerate(names))
                sat = []
                if sat_port[k]:
                    sat.append('"port_upper"' if port[k] > 0 else '"port_lower"')
                if sat_stbd[k]:
                    sat.append('"stbd_upper"' if stbd[k] > 0 else '"stbd_lower"')
                f.write(head % (t_strs[j], k, mode[k], hs) + body
                        + f', "sat_port": {"true" if sat_port[k] else "false"}'
                        + f', "sat_stbd": {"true" if sat_stbd[k] else "false"}'
                        + f', "saturation": [{", ".join(sat)}]'
                        + (', "active_faults": []' if moving[k] else ', "active_faults": ["heading_stale"]')
                        + ', "armed": true'
                        + f', "timestamp": "{_iso(t[k])}"}}\n')
        if complete_idx is not None:
            last = len(wps) - 1
            f.write(_line("waypoint_reached", t[-1], wp_index=last, north_m=round(float(north_true[-1]), 3),
                          east_m=round(float(east_true[-1]), 3), distance_m=round(float(abs(weave[-1])), 3),
                          how="capture"))
            f.write(_line("mission_complete", t[-1], wp_count=len(wps), rtl=False))
        for i in sorted(passes):  # the passes still open end with the log
            if i >= len(wps) - 2 or (i + 1) not in {int(leg[k - 1]) for k in reached}:
                ca, ct = passes[i]
                if not any(f'"wp_index": {i}, "closest_approach_m"' in x for v in events_at.values() for x in v):
                    f.write(_line("waypoint_pass", t[-1], wp_index=i, closest_approach_m=ca, closest_t_s=ct))
        reason = "complete" if complete_idx is not None else "signal"
        f.write(_line("stop", t[-1], reason=reason, signal=None if complete_idx is not None else "SIGTERM",
                      ack_received=True, cycles=n, nmea_dropped=int(nmea_dropped[-1]), ack_missing=int(ack_missing[-1]),
                      closest_approach_m=[passes.get(i, (None,))[0] for i in range(len(wps))]))
    return {
        "t_s": t, "north_m": north_true, "east_m": east_true, "thrust_port_n": port, "thrust_stbd_n": stbd,
        "fix_rows": np.nonzero(is_fix)[0], "fix_t_s": t[is_fix] - fix_latency_s,
        "logged_north_m": north, "logged_east_m": east,
        "closest_approach_m": [passes.get(i, (math.nan,))[0] for i in range(len(wps))],
        "waypoints_ne_m": wps, "cycles": n, "failsafe_at_s": failsafe_at_s,
        "complete": complete_idx is not None, "weave_m": weave,
    }
