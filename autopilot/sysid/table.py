"""The workflow on a steady-state table (SPEC 6: thrust pair -> steady speed and yaw rate).

A table has no time series, so only effects that change the steady state can
be seen: ``thrust_asymmetry``, ``weak_motor``, ``yaw_damping_quadratic`` and ``hydro_refit``
(sensor effects, lags, current and wind do not change a steady speed/yaw
rate magnitude; a deadband is not resolvable between command levels 20 %
apart). Each row is solved algebraically (autopilot.sim.steady.solve_steady).
Residuals: relative speed error of every moving row, and yaw-rate error divided
by max(|r_measured|, 0.1 rad/s) (straight rows measure r = 0). Choice by BIC
with the noise level unknown (n ln(SSE/n) + k ln n), confirmed by 5-fold
cross-validation over rows.

Table CSV: header ``name,thrust_port_n,thrust_stbd_n,yaw_rate_rad_s,speed_m_s``,
speed as a magnitude (rows with both thrusts negative go astern).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import numpy as np

from autopilot.measured import SteadyRow
from autopilot.schema import ConfigError
from autopilot.sim import VesselParams
from autopilot.sim.calibrate import FREE as CALIBRATE_FREE
from autopilot.sim.steady import solve_steady
from autopilot.sysid.effects import BY_NAME, PARAM_BY_KEY, by_effect, param_row
from autopilot.sysid.effects import bounds as theta_bounds
from autopilot.sysid.output import updated_vessel

TABLE_CANDIDATES = ("thrust_asymmetry", "weak_motor", "yaw_damping_quadratic", "hydro_refit")
# hydro_refit on a table: the fields a steady table identifies (autopilot.sim.calibrate.FREE without the
# quadratic yaw damping, which is its own candidate), with calibrate's bounds; fitted as changes
HYDRO_FIELDS = tuple(f for f in CALIBRATE_FREE if f[0] != "yaw_damping_quadratic_nm_s2")
COLUMNS = ("name", "thrust_port_n", "thrust_stbd_n", "yaw_rate_rad_s", "speed_m_s")
_MAX_THRUST_N = next(f.metadata["hi"] for f in dataclasses.fields(VesselParams) if f.name == "max_thrust_n")
# what a steady row of a boat the model covers can hold: a typo (1e9 N) otherwise went into the fit
# and its residual alone chose the verdict
COLUMN_RANGES = {"thrust_port_n": (-_MAX_THRUST_N, _MAX_THRUST_N, "N, the vessel schema's max_thrust_n"),
                 "thrust_stbd_n": (-_MAX_THRUST_N, _MAX_THRUST_N, "N, the vessel schema's max_thrust_n"),
                 "yaw_rate_rad_s": (-math.pi, math.pi, "rad/s, half a turn a second"),
                 "speed_m_s": (0.0, 20.0, "m/s, a magnitude")}
YAW_RATE_FLOOR_RAD_S = 0.1
FAILED_RESIDUAL = 10.0  # a row whose steady state cannot be found (as autopilot.sim.calibrate)
BIC_MARGIN = 10.0
MIN_CV_GAIN = 0.05
FOLDS = 5
MIN_MOVING_ROWS = 3  # rows with a speed above 0: the rows table_residuals compares


def read_table_csv(path) -> tuple[SteadyRow, ...]:
    """Read a steady-state table CSV (a row of units under the header is checked against the columns' and skipped:
    it was refused as "data row 1, thrust_port_n: 'N' is not a number", where the trial CSV and the mission read it)."""
    from autopilot.userfile import (
        METRES_PER_SECOND,
        NEWTONS,
        RADIANS_PER_SECOND,
        csv_rows,
        number_cell,
        read_text,
        too_many_fields,
        unique_header,
        units_row,
        units_row_refusal,
    )

    path = Path(path)
    table = csv_rows(read_text(path, what="steady-state table CSV", spreadsheet=True))
    header = table[0] if table else []
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise ConfigError(f"{path}: missing column(s) {', '.join(missing)} (need {', '.join(COLUMNS)})")
    col = {c: header.index(c) for c in COLUMNS}
    allowed = {"thrust_port_n": NEWTONS, "thrust_stbd_n": NEWTONS, "yaw_rate_rad_s": RADIANS_PER_SECOND,
               "speed_m_s": METRES_PER_SECOND}
    units = len(table) > 1 and units_row([c for k, c in enumerate(table[1]) if k != col["name"]])
    if units and (refusal := units_row_refusal(path, table[1], header, allowed, "table")) is not None:
        raise ConfigError(refusal)
    rows = []
    for k, r in enumerate(table[1:], start=1):
        if k == 1 and units:
            continue
        try:
            unique_header(header, COLUMNS)
            if len(r) < len(header):
                raise ConfigError(f"data row {k} has {len(r)} of {len(header)} fields")
            problem = too_many_fields(r, len(header), k)
            if problem:
                raise ConfigError(problem)
            vals = [number_cell(r[col[c]], k, c, header) for c in COLUMNS[1:]]
        except ConfigError as exc:  # "data row 4, u_m_s: '1,98' is not a number (a decimal comma: ...)"
            raise ConfigError(f"{path}: {exc}") from None
        for c, v in zip(COLUMNS[1:], vals):
            if math.isnan(v):
                raise ConfigError(f"{path}: data row {k}, {c}: empty (every row needs every column)")
            lo, hi, what = COLUMN_RANGES[c]
            if not lo <= v <= hi:  # NaN fails too
                raise ConfigError(f"{path}: data row {k}, {c}: {v:g} is outside [{lo:g}, {hi:g}] ({what})")
        rows.append(SteadyRow(r[col["name"]], *vals))
    if len(rows) < 3:
        raise ConfigError(f"{path}: need at least 3 rows, got {len(rows)}")
    moving = sum(r.speed_m_s > 0.0 for r in rows)
    if moving < MIN_MOVING_ROWS:  # a table of zero speeds only was a ZeroDivisionError (a sysid audit)
        raise ConfigError(f"{path}: {moving} row(s) with a speed_m_s above 0 (need {MIN_MOVING_ROWS}): only a moving "
                          "row's speed and yaw rate are compared with the model")
    return tuple(rows)


def write_table_csv(rows, path) -> None:
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([r.name, r.thrust_port_n, r.thrust_stbd_n, r.yaw_rate_rad_s, r.speed_m_s])


def _thrusts(values: dict, rows) -> tuple[np.ndarray, np.ndarray]:
    """The rows' thrusts through the thrust hooks of the effects in ``values`` (a steady table has
    no duty series: only gain-type thrust effects, which is what TABLE_CANDIDATES holds)."""
    tp = np.array([[r.thrust_port_n for r in rows]])
    ts = np.array([[r.thrust_stbd_n for r in rows]])
    for eff, v in by_effect(values).items():
        if eff.thrust is not None:
            tp, ts = eff.thrust({k: np.atleast_1d(x) for k, x in v.items()}, tp, ts, {})
    return tp[0], ts[0]


def steady_response(vessel: VesselParams, values: dict, rows) -> np.ndarray:
    """(speed, yaw rate) of each row under the model with the effects; NaN where no steady state."""
    params = updated_vessel(vessel, values)
    tp, ts = _thrusts(values, rows)
    out = np.full((len(rows), 2), np.nan)
    for k, row in enumerate(rows):
        if row.speed_m_s == 0 and row.thrust_port_n == 0 and row.thrust_stbd_n == 0:
            out[k] = 0.0
            continue
        sign = -1.0 if row.thrust_port_n + row.thrust_stbd_n < 0 else 1.0
        sol = solve_steady(params, float(tp[k]), float(ts[k]), (sign * row.speed_m_s, 0.0, row.yaw_rate_rad_s))
        if sol is not None:
            u, v, r = sol
            out[k] = (math.hypot(u, v), r)
    return out


def table_residuals(vessel: VesselParams, values: dict, rows) -> np.ndarray:
    """Relative speed errors (moving rows) then scaled yaw-rate errors (moving rows)."""
    sim = steady_response(vessel, values, rows)
    rs, rr = [], []
    for row, (u, r) in zip(rows, sim):
        if row.speed_m_s == 0:
            continue
        if not math.isfinite(u):
            rs.append(FAILED_RESIDUAL)
            rr.append(FAILED_RESIDUAL)
            continue
        rs.append((u - row.speed_m_s) / row.speed_m_s)
        rr.append((r - row.yaw_rate_rad_s) / max(abs(row.yaw_rate_rad_s), YAW_RATE_FLOOR_RAD_S))
    return np.array(rs + rr)


def _gap(vessel, values, rows) -> dict:
    sim = steady_response(vessel, values, rows)
    moving = [k for k, r in enumerate(rows) if r.speed_m_s > 0]
    turning = [k for k, r in enumerate(rows) if r.kind == "turn"]
    def rel(k, j, meas):
        return (sim[k, j] - meas) / meas if math.isfinite(sim[k, j]) else FAILED_RESIDUAL
    sp = [rel(k, 0, rows[k].speed_m_s) for k in moving]
    yr = [rel(k, 1, rows[k].yaw_rate_rad_s) for k in turning]
    rms = lambda x: float(np.sqrt(np.mean(np.square(x)))) if len(x) else None
    return {"speed_rel_rms": rms(sp), "yaw_rate_rel_rms": rms(yr), "position_m": None, "heading_deg": None}


def table_keys(effect: str) -> list[str]:
    """Parameters of an effect in table mode (hydro_refit: the fields a table identifies, as calibrate.py)."""
    if effect == "hydro_refit":
        return [f"hydro_refit.{name}" for name, _, _ in HYDRO_FIELDS]
    return list(BY_NAME[effect].keys)


def _scale_bounds(key: str, vessel: VesselParams):
    if key.startswith("hydro_refit."):
        name = key.split(".", 1)[1]
        _, lo, hi = next(f for f in HYDRO_FIELDS if f[0] == name)
        base = getattr(vessel, name)
        return max(abs(base) * 0.1, 1e-2), lo - base, hi - base
    return PARAM_BY_KEY[key].scale, *theta_bounds(key, vessel)


def _fit(vessel, effects, rows, theta0=None):
    from scipy.optimize import least_squares

    keys = [k for e in effects for k in table_keys(e)]
    sb = [_scale_bounds(k, vessel) for k in keys]
    scale = np.array([x[0] for x in sb])
    lo = np.array([x[1] for x in sb]) / scale
    hi = np.array([x[2] for x in sb]) / scale
    z0 = np.zeros(len(keys)) if theta0 is None else np.asarray(theta0) / scale
    z0 = np.clip(z0, lo + 1e-9 * (np.abs(lo) + 1), hi - 1e-9 * (np.abs(hi) + 1))

    def fun(z):
        return table_residuals(vessel, dict(zip(keys, z * scale)), rows)

    sol = least_squares(fun, z0, bounds=(lo, hi), method="trf", diff_step=1e-4, xtol=1e-10, ftol=1e-10)
    sse = float(np.sum(sol.fun**2))
    m = sol.fun.size
    dof = max(m - len(keys), 1)
    try:
        cov = np.linalg.pinv(sol.jac.T @ sol.jac) * sse / dof
        sigma = np.sqrt(np.maximum(np.diag(cov), 0)) * scale
    except np.linalg.LinAlgError:
        sigma = np.full(len(keys), np.nan)
    theta = sol.x * scale
    bic = m * math.log(max(sse, 1e-300) / m) + len(keys) * math.log(m)
    return {"keys": keys, "theta": theta, "sigma": sigma, "sse": sse, "m": m, "bic": bic}


def _cv_sse(vessel, effects, rows, theta0) -> float:
    """Sum of squared residuals of rows predicted by fits on the other rows (5 folds)."""
    order = np.arange(len(rows))
    total = 0.0
    for f in range(FOLDS):
        test = [rows[k] for k in order if k % FOLDS == f]
        train = [rows[k] for k in order if k % FOLDS != f]
        if effects:
            fit = _fit(vessel, effects, train, theta0)
            values = dict(zip(fit["keys"], fit["theta"]))
        else:
            values = {}
        total += float(np.sum(table_residuals(vessel, values, test) ** 2))
    return total


def _report(vessel, fit, effects) -> dict:
    out = {}
    for e in effects:
        params, value, sigma = [], {}, {}
        for key in table_keys(e):
            name = key.split(".", 1)[1]
            k = fit["keys"].index(key)
            unit = PARAM_BY_KEY[key].unit if key in PARAM_BY_KEY else _field_unit(name)
            v, s = float(fit["theta"][k]), float(fit["sigma"][k])
            value[name], sigma[name] = v, s
            off = BY_NAME[e].reported(name, v, vessel) - v
            params.append(param_row(name, unit, v + off, s))
        params += BY_NAME[e].derived(value, sigma)  # as the trials' report (summary.effect_report): weak_motor's gain
        out[e] = {"doc": BY_NAME[e].doc, "params": params}
    return out


def identify_table(rows, vessel: VesselParams, *, candidates=TABLE_CANDIDATES, bic_margin: float = BIC_MARGIN,
                   min_cv_gain: float = MIN_CV_GAIN, log=None) -> dict:
    """Name the effect that closes the gap between the model and a steady-state table."""
    say = log or (lambda msg: None)
    rows = tuple(rows)
    bad = [c for c in candidates if c not in TABLE_CANDIDATES]
    if bad:
        raise ConfigError(f"effects {', '.join(bad)} do not change a steady state; a table can test {', '.join(TABLE_CANDIDATES)}")
    fits = _fits(vessel, rows, candidates, bic_margin, say)
    chosen = fits.pop("chosen")
    notes = []
    cv_before = _cv_sse(vessel, (), rows, None)
    cv_after = cv_before
    if chosen:
        cv_after = _cv_sse(vessel, chosen, rows, fits[chosen]["theta"])
        gain = 1 - cv_after / cv_before
        say(f"cross-validated SSE {cv_before:.3f} -> {cv_after:.3f} ({100 * gain:.0f} %)")
        if gain < min_cv_gain:
            notes.append(f"{'+'.join(chosen)} won on BIC but cut the cross-validated error by only {100 * gain:.1f} %: verdict none")
            chosen, cv_after = (), cv_before
    return _table_summary(vessel, rows, fits, chosen, cv_before, cv_after, notes)


def _fits(vessel, rows, candidates, bic_margin, say) -> dict:
    """The baseline, every single and (when a single wins) every pair with it; ``chosen`` by BIC."""
    r0 = table_residuals(vessel, {}, rows)
    m = r0.size
    base = {"keys": [], "theta": np.zeros(0), "sigma": np.zeros(0), "sse": float(np.sum(r0**2)), "m": m}
    base["bic"] = m * math.log(base["sse"] / m)
    fits = {(): base}
    for c in candidates:
        fits[(c,)] = _fit(vessel, (c,), rows)
        say(f"{c}: SSE {base['sse']:.3f} -> {fits[(c,)]['sse']:.3f}, BIC {fits[(c,)]['bic'] - base['bic']:+.1f}")
    best = min((k for k in fits if len(k) == 1), key=lambda k: fits[k]["bic"])
    chosen = best if fits[best]["bic"] < base["bic"] - bic_margin else ()
    if chosen:
        for c in candidates:
            if c in best:
                continue
            pair = best + (c,)
            fits[pair] = _fit(vessel, pair, rows, list(fits[best]["theta"]) + [0.0] * len(table_keys(c)))
            say(f"{'+'.join(pair)}: SSE {fits[pair]['sse']:.3f}, BIC {fits[pair]['bic'] - base['bic']:+.1f}")
        pairs = [k for k in fits if len(k) == 2]
        bp = min(pairs, key=lambda k: fits[k]["bic"]) if pairs else None
        if bp and fits[bp]["bic"] < fits[best]["bic"] - bic_margin:
            chosen = bp
    fits["chosen"] = chosen
    return fits


def _table_summary(vessel, rows, fits, chosen, cv_before, cv_after, notes) -> dict:
    base, m = fits[()], fits[()]["m"]
    values = dict(zip(fits[chosen]["keys"], fits[chosen]["theta"]))
    cands = []
    for key, f in sorted(fits.items(), key=lambda kv: kv[1]["bic"]):
        if not key:
            continue
        cands.append({"effect": "+".join(key), "params": f["keys"], "sse": f["sse"], "bic": f["bic"],
                      "delta_bic": f["bic"] - base["bic"], "score": f["bic"] - base["bic"],
                      "fitted_params": {e: {p["name"]: p["value"] for p in v["params"]} for e, v in _report(vessel, f, key).items()}})
    held_before = {"sse_cv": cv_before, "rms_cv": math.sqrt(cv_before / m), "position_m": None, "heading_deg": None}
    held_after = {"sse_cv": cv_after, "rms_cv": math.sqrt(cv_after / m), "position_m": None, "heading_deg": None}
    return {
        "mode": "table",
        "rows": [r.name for r in rows],
        "verdict": list(chosen) or ["none"],
        "effects": _report(vessel, fits[chosen], chosen) if chosen else {},
        "candidates": cands,
        "score": "delta_bic: n ln(SSE/n) + k ln n minus the baseline's (noise level unknown)",
        "rmse_before": {"fitted": _gap(vessel, {}, rows), "held_out": held_before},
        "rmse_after": {"fitted": _gap(vessel, values, rows), "held_out": held_after},
        "rows_before": _rows(vessel, {}, rows),
        "rows_after": _rows(vessel, values, rows),
        "values": values,
        "notes": notes + ["position_m and heading_deg are null: a steady-state table has no tracks; "
                          "held_out figures are 5-fold cross-validated over rows (rms_cv: relative residual RMS)"],
    }


def _rows(vessel, values, rows) -> list[dict]:
    sim = steady_response(vessel, values, rows)
    return [{"name": r.name, "thrust_port_n": r.thrust_port_n, "thrust_stbd_n": r.thrust_stbd_n,
             "speed_meas_m_s": r.speed_m_s, "speed_sim_m_s": float(s[0]),
             "yaw_rate_meas_rad_s": r.yaw_rate_rad_s, "yaw_rate_sim_rad_s": float(s[1])} for r, s in zip(rows, sim)]


def table_figure(summary: dict):
    """Measured vs simulated yaw rate and speed per row, before and after."""
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    names = [r["name"] for r in summary["rows_before"]]
    x = np.arange(len(names))
    for ax, meas, sim, label in ((a1, "speed_meas_m_s", "speed_sim_m_s", "speed (m/s)"),
                                 (a2, "yaw_rate_meas_rad_s", "yaw_rate_sim_rad_s", "yaw rate (rad/s)")):
        ax.plot(x, [r[meas] for r in summary["rows_before"]], "ko", label="measured")
        ax.plot(x, [r[sim] for r in summary["rows_before"]], "rx", label="model before")
        ax.plot(x, [r[sim] for r in summary["rows_after"]], "b+", label="model after")
        ax.set_xticks(x, names, rotation=90, fontsize=7)
        ax.set_ylabel(label)
    a1.legend(fontsize=7)
    return fig


def _field_unit(name: str) -> str:
    f = next(f for f in dataclasses.fields(VesselParams) if f.name == name)
    return f.metadata.get("unit", "-")
