"""Measured trials for identification: CSV trial files and daemon mission logs.

Trial CSV (one file per trial, header line, one row per sample, any order of
columns, unknown columns ignored; empty cells, ``nan`` or text are gaps)::

    t_s                              time (s), increasing
    thrust_port_n, thrust_stbd_n     commanded thrust (N, negative = astern), or
    pwm_port_pct, pwm_stbd_pct       signed duty (%, negative = reverse), converted
                                     with autopilot.gnc.thrust_curve.ThrustCurve (SPEC 4)
    north_m, east_m                  position (m, local frame), or
    lat_deg, lon_deg                 position, converted around the first fix (autopilot.geo)
    heading_deg                      heading from north, clockwise (deg)
    sog_m_s, cog_deg, rot_deg_s      optional: speed/course over ground, rate of turn

Rows without a usable time are dropped; a missing thrust keeps the previous
command (the motors hold their last command); missing position or heading
cells are gaps (NaN), never zeros.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autopilot.geo import latlon_to_local
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.schema import ConfigError

MIN_SAMPLES = 20


@dataclass(frozen=True)
class Trial:
    """One measured trial on its own time base (t_s starts at 0). NaN marks a gap."""

    name: str
    t_s: np.ndarray
    thrust_port_n: np.ndarray
    thrust_stbd_n: np.ndarray
    duty_port_pct: np.ndarray  # signed duty (%), negative = reverse
    duty_stbd_pct: np.ndarray
    north_m: np.ndarray
    east_m: np.ndarray
    heading_rad: np.ndarray
    sog_m_s: np.ndarray | None = None
    cog_rad: np.ndarray | None = None
    yaw_rate_rad_s: np.ndarray | None = None

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])


def _forward_fill(x: np.ndarray) -> np.ndarray:
    """Replace NaN by the last valid value (leading NaN by the first valid one)."""
    x = np.asarray(x, dtype=float).copy()
    ok = np.isfinite(x)
    if not ok.any():
        return np.zeros_like(x)
    idx = np.where(ok, np.arange(x.size), 0)
    np.maximum.accumulate(idx, out=idx)
    x = x[idx]
    first = np.flatnonzero(ok)[0]
    x[:first] = x[first]
    return x


def make_trial(
    name: str,
    t_s,
    *,
    north_m,
    east_m,
    heading_deg,
    thrust_port_n=None,
    thrust_stbd_n=None,
    pwm_port_pct=None,
    pwm_stbd_pct=None,
    sog_m_s=None,
    cog_deg=None,
    rot_deg_s=None,
    curve: ThrustCurve | None = None,
) -> Trial:
    """Build a clean :class:`Trial` from raw columns (degrees and duty only at this edge)."""
    curve = curve or ThrustCurve()
    t = np.asarray(t_s, dtype=float)
    keep = np.isfinite(t)
    # keep only strictly increasing times (a repeated or backwards stamp is a logging glitch)
    idx = np.flatnonzero(keep)
    good, last = [], -math.inf
    for i in idx:
        if t[i] > last:
            good.append(i)
            last = t[i]
    sel = np.asarray(good, dtype=int)
    if sel.size < MIN_SAMPLES:
        raise ConfigError(f"trial {name}: only {sel.size} samples with a usable t_s (need {MIN_SAMPLES})")

    def col(x):
        return None if x is None else np.asarray(x, dtype=float)[sel]

    if thrust_port_n is not None and thrust_stbd_n is not None:
        tp, ts = _forward_fill(col(thrust_port_n)), _forward_fill(col(thrust_stbd_n))
        dp, ds = curve.signed_duty_pct(tp), curve.signed_duty_pct(ts)
    elif pwm_port_pct is not None and pwm_stbd_pct is not None:
        dp, ds = _forward_fill(col(pwm_port_pct)), _forward_fill(col(pwm_stbd_pct))
        tp, ts = curve.thrust_from_signed_duty_n(dp), curve.thrust_from_signed_duty_n(ds)
    else:
        raise ConfigError(f"trial {name}: needs thrust_port_n/thrust_stbd_n or pwm_port_pct/pwm_stbd_pct")
    heading = col(heading_deg)
    n, e = col(north_m), col(east_m)
    if np.sum(np.isfinite(n) & np.isfinite(e)) < MIN_SAMPLES or np.sum(np.isfinite(heading)) < MIN_SAMPLES:
        raise ConfigError(f"trial {name}: fewer than {MIN_SAMPLES} valid positions or headings")
    t_sel = t[sel]
    return Trial(
        name=name,
        t_s=t_sel - t_sel[0],
        thrust_port_n=np.asarray(tp, dtype=float),
        thrust_stbd_n=np.asarray(ts, dtype=float),
        duty_port_pct=np.asarray(dp, dtype=float),
        duty_stbd_pct=np.asarray(ds, dtype=float),
        north_m=n,
        east_m=e,
        heading_rad=np.radians(heading),
        sog_m_s=col(sog_m_s),
        cog_rad=None if cog_deg is None else np.radians(col(cog_deg)),
        yaw_rate_rad_s=None if rot_deg_s is None else np.radians(col(rot_deg_s)),
    )


def _number(text: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        return math.nan
    return value if math.isfinite(value) else math.nan


def read_trial_csv(path, *, curve: ThrustCurve | None = None) -> Trial:
    """Read one trial CSV (columns in the module docstring)."""
    from autopilot.userfile import csv_rows, read_text

    path = Path(path)
    table = csv_rows(read_text(path, what="trial CSV"))
    header = table[0] if table else []
    rows = [[_number(c) for c in r] for r in table[1:]]
    if "t_s" not in header:
        raise ConfigError(f"{path}: no t_s column in the header ({', '.join(header) or 'empty file'})")
    width = len(header)
    data = np.full((len(rows), width), np.nan)
    for i, r in enumerate(rows):
        r = r[:width]
        data[i, : len(r)] = r
    cols = {h: data[:, k] for k, h in enumerate(header)}
    get = cols.get
    north, east = get("north_m"), get("east_m")
    if north is None or east is None:
        lat, lon = get("lat_deg"), get("lon_deg")
        if lat is None or lon is None:
            raise ConfigError(f"{path}: needs north_m/east_m or lat_deg/lon_deg columns")
        ok = np.isfinite(lat) & np.isfinite(lon)
        if not ok.any():
            raise ConfigError(f"{path}: no valid lat_deg/lon_deg")
        i0 = np.flatnonzero(ok)[0]
        north, east = latlon_to_local(lat, lon, float(lat[i0]), float(lon[i0]))
    if get("heading_deg") is None:
        raise ConfigError(f"{path}: needs a heading_deg column")
    try:
        return make_trial(
            path.stem,
            cols["t_s"],
            north_m=north,
            east_m=east,
            heading_deg=get("heading_deg"),
            thrust_port_n=get("thrust_port_n"),
            thrust_stbd_n=get("thrust_stbd_n"),
            pwm_port_pct=get("pwm_port_pct"),
            pwm_stbd_pct=get("pwm_stbd_pct"),
            sog_m_s=get("sog_m_s"),
            cog_deg=get("cog_deg"),
            rot_deg_s=get("rot_deg_s"),
            curve=curve,
        )
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from exc


def read_mission_log(path, *, curve: ThrustCurve | None = None) -> Trial:
    """A daemon mission log (docs/log-schema.md, cycle lines) as a trial."""
    from autopilot.review.reader import check_mission_log, read_log

    log = read_log(check_mission_log(path))
    if log.n_cycles < MIN_SAMPLES:
        raise ConfigError(f"{path}: only {log.n_cycles} cycle lines (need {MIN_SAMPLES})")
    c = log.col
    return make_trial(
        Path(path).stem,
        c("t_s"),
        north_m=c("north_m"),
        east_m=c("east_m"),
        heading_deg=c("heading_deg"),
        thrust_port_n=c("thrust_port_n"),
        thrust_stbd_n=c("thrust_stbd_n"),
        sog_m_s=c("sog_m_s"),
        cog_deg=c("cog_deg"),
        rot_deg_s=c("yaw_rate_deg_s"),
        curve=curve,
    )


def read_trial(path, *, curve: ThrustCurve | None = None) -> Trial:
    """A trial CSV (``.csv``) or a mission log (``.jsonl``/``.json``)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".jsonl", ".json", ".log"):
        return read_mission_log(path, curve=curve)
    return read_trial_csv(path, curve=curve)


def write_trial_csv(trial: Trial, path) -> None:
    """Write a trial in the CSV format above (thrust, local position, heading in degrees)."""
    cols = {
        "t_s": trial.t_s,
        "thrust_port_n": trial.thrust_port_n,
        "thrust_stbd_n": trial.thrust_stbd_n,
        "north_m": trial.north_m,
        "east_m": trial.east_m,
        "heading_deg": np.degrees(trial.heading_rad) % 360.0,
    }
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in data:
            w.writerow(["" if not math.isfinite(v) else f"{v:.6g}" for v in row])


def noise_sigma(x: np.ndarray, t_s: np.ndarray, *, floor: float) -> float:
    """White measurement noise of a smooth signal from second differences (robust, MAD).

    For a signal sampled evenly, x[k+1] - 2x[k] + x[k-1] removes the motion
    (its curvature is tiny at 10 Hz) and leaves 6 sigma^2 of white noise.
    """
    x = np.asarray(x, dtype=float)
    dt = np.diff(t_s)
    ok = np.isfinite(x[:-2]) & np.isfinite(x[1:-1]) & np.isfinite(x[2:])
    ok &= np.abs(dt[:-1] - dt[1:]) < 1e-6 * np.maximum(dt[1:], 1e-9) + 1e-9
    d2 = (x[2:] - 2 * x[1:-1] + x[:-2])[ok]
    if d2.size < 10:
        return floor
    mad = np.median(np.abs(d2 - np.median(d2)))
    return max(float(1.4826 * mad / math.sqrt(6.0)), floor)
