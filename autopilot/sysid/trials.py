"""Measured trials for identification: CSV trial files (and, via mission_log.py, daemon mission logs).

Trial CSV: one file per trial, its columns in :data:`CSV_HELP` (what ``autopilot sysid --help`` shows).

Measurements as they were taken (issue 12, "Build" 1; the rules agreed with
``review --export csv``): a trial holds only *new* measurements, each at the
time it was measured (``position_time_s`` / ``heading_time_s`` of the
:class:`Trial`, NaN on the rows that carry none):

- a row whose position cells are empty is not a new fix, nor is one whose fix
  time (``position_time_s``) did not advance, nor, on a row without a fix time,
  one that repeats the previous fix (a GPS gives a fix a second; a 10 Hz log
  repeats it on every row between: a held fix is ~0.45 s old on average and
  fitted as new it mimics an antenna aft of the centre). With a fix time the time
  alone decides: at rest a receiver gives new fixes with the same coordinates.
  The fix was measured at ``position_time_s`` when the file
  has it, else half a row before the row where it first appears (it arrived at
  some moment since the row before: dated at the row, a fix is on average half a
  row late, which the speed and course over ground measured with it feel most:
  a turning boat's velocity changes by a few cm/s in 50 ms);
- with a ``heading_time_s`` column, a heading whose time did not advance is
  held, not new; without it every heading cell is a measurement at its row;
- a speed and course over ground are new where they change or follow an empty cell (a
  receiver sends them once an epoch, in RMC/VTG, often a sentence after the epoch's GGA:
  the row of a new fix may still hold the last epoch's), and once each epoch where they
  stay unchanged through STEADY_EPOCHS epochs (at rest, or steady), measured with the latest fix at or before
  their row (one epoch, one solution), or, a whole epoch or more after that fix, in their own epoch
  (its fix was lost: the latest fix's time plus whole epochs); fewer than MIN_VELOCITIES: no velocity channel;
- rows the caller excludes (``make_trial(exclude=...)``: a mission log's
  failsafe stretches and the cycles after skipped deadlines) keep their
  commands (the motors had them) but contribute no measurement.

Rows without a usable time are dropped; a missing thrust keeps the previous
command (the motors hold their last command). What was dropped is counted in
``Trial.counts`` (shown in summary.json).
"""

from __future__ import annotations

import csv
import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from autopilot.geo import latlon_to_local
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.schema import ConfigError
from autopilot.userfile import DEGREES, DEGREES_PER_SECOND, METRES, METRES_PER_SECOND, NEWTONS, PERCENT, SECONDS

MIN_SAMPLES = 20  # rows with a usable time
MIN_FIXES = 8  # new position fixes (a 1 Hz GPS: eight seconds)
MIN_HEADINGS = 20
MIN_VELOCITIES = 8  # new speed/course pairs for a velocity channel (eight seconds of a 1 Hz receiver)
SAME_TIME_S = 1e-4  # a measurement time that moved less than this did not advance
STEADY_EPOCHS = 2  # a speed/course pair unchanged through this many epochs is a reading each epoch (new_velocities)
OPTIONAL_ROW_COLUMNS = ("sog_m_s", "cog_deg", "rot_deg_s")


@dataclass(frozen=True)
class Trial:
    """One measured trial on its own time base (t_s starts at 0).

    Commands (thrust, duty) are per row. Measurements are per row too, but a row
    carries a position (heading) only where it holds a *new* measurement, taken at
    ``position_time_s`` (``heading_time_s``); NaN everywhere else.
    """

    name: str
    t_s: np.ndarray
    thrust_port_n: np.ndarray
    thrust_stbd_n: np.ndarray
    duty_port_pct: np.ndarray  # signed duty (%), negative = reverse
    duty_stbd_pct: np.ndarray
    north_m: np.ndarray
    east_m: np.ndarray
    heading_rad: np.ndarray
    position_time_s: np.ndarray
    heading_time_s: np.ndarray
    sog_m_s: np.ndarray | None = None
    cog_rad: np.ndarray | None = None
    velocity_time_s: np.ndarray | None = None  # when a row's new speed/course was measured (NaN: none new)
    yaw_rate_rad_s: np.ndarray | None = None
    # a row missing between two rows: the motors held the command (mission logs)
    commands_held: bool = False
    # per row: the loop stalled after it (a mission log: the next cycle ran late, no line lost), so the motors had its
    # command until the firmware's stop (prediction.firmware_stops); None: no stall known
    stalled_after: np.ndarray | None = None
    counts: dict = field(default_factory=dict)
    read_notes: tuple = ()  # what reading the file skipped, in words (a mission log's damaged lines)
    t0_s: float = 0.0  # the file's t_s of the first row (t_s here starts at 0): how notes name a time in the file
    # (last row before, first row after) on t_s of each stretch whose rows were lost (a mission log's lines a failed
    # write lost: the daemon sent commands then, none known here); cut_at_lost (in cut_long) cuts the trial there
    lost_s: tuple = ()
    # the same for each stretch of rows whose commands never reached the motors (a mission log's Mbed link lost:
    # MissionLog.undelivered_rows): the rows are there, the thrust they name is not what the motors had
    undelivered_s: tuple = ()

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def fix_rows(self) -> np.ndarray:
        """Rows that carry a new position fix."""
        return np.flatnonzero(np.isfinite(self.north_m) & np.isfinite(self.east_m) & np.isfinite(self.position_time_s))

    @property
    def heading_rows(self) -> np.ndarray:
        """Rows that carry a new heading."""
        return np.flatnonzero(np.isfinite(self.heading_rad) & np.isfinite(self.heading_time_s))

    @property
    def velocity_rows(self) -> np.ndarray:
        """Rows that carry a new speed and course over ground."""
        if self.velocity_time_s is None or self.sog_m_s is None or self.cog_rad is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(np.isfinite(self.sog_m_s) & np.isfinite(self.cog_rad) & np.isfinite(self.velocity_time_s))


def _held_commands(x: np.ndarray) -> np.ndarray:
    """A command column with its empty cells filled: each holds the command before it, and those before the
    first command are zero (the firmware keeps the motors off until its first valid command,
    docs/mbed-protocol.md). Filled with the first command instead, a logger that writes thrust only once
    commanded gave 1.3 s of phantom thrust per trial and a current interval that missed the truth."""
    x = np.asarray(x, dtype=float)
    return np.nan_to_num(_forward_fill_after(x), nan=0.0)


# t_s going back to more than this after the first row's is a clock stepped back, not a second trial's start
CLOCK_STEP_BACK_S = 5.0
GAP_MIN_S = 5.0  # a step in t_s longer than this and than GAP_STEPS typical steps is a gap in the record
GAP_STEPS = 10.0
# rows a median interval outside these apart are not seconds: milliseconds (a 10 Hz log's rows 100 "s" apart,
# which flew as an 'unexplained' trial of 13 hours) or Excel's serial days (rows 1e-6 "s" apart)
ROW_INTERVAL_S = (1e-3, 10.0)
# a commanded thrust beyond the thrust curve's largest by more than this share of it is a typo, not a measurement
# (less may be another boat's thrusters, or a log's rounding)
THRUST_SLACK = 0.5


def check_times(t: np.ndarray, row_name, *, wall_clock: bool = True) -> None:
    """ConfigError naming the row when the times of one trial are not one record: a row without a time, a time
    repeated or going back, or a gap (the logger stopped). Each was once dropped or flown over without a word:
    a 60-s gap replayed as one trial came out 'unexplained' (heading 5 deg against noise 0.9), a time going
    back in a mission log kept only the rows before it. ``row_name(i)``: how the user finds row i. ``wall_clock``:
    the times may come from a clock that can be set back (another tool's; the daemon's are monotonic)."""
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ConfigError(f"{row_name(bad[0])}, t_s: no time (every row needs one)")
    if t.size < 2:
        return
    dt = np.diff(t)
    stuck = np.flatnonzero(dt <= 0.0)
    if stuck.size:
        i = stuck[0]
        if dt[i] == 0.0:
            raise ConfigError(f"t_s repeats {t[i]:g} s at {row_name(i)} and {row_name(i + 1)}: each row is a moment "
                              "of its own (a row written twice? delete one)")
        if wall_clock and t[i + 1] > t[0] + CLOCK_STEP_BACK_S:  # not back to the start: a clock stepped
            # the times to the digit: a wall clock's (Unix seconds) read "from 1.765e+09 s to 1.765e+09 s"
            raise ConfigError(f"t_s goes back {t[i] - t[i + 1]:.3g} s, from {t[i]:.12g} s ({row_name(i)}) to "
                              f"{t[i + 1]:.12g} s ({row_name(i + 1)}), not to the start: the logger's clock set back "
                              "(a wall clock stepped by NTP or GPS time?); one trial's rows in time order: shift the "
                              "rows after it by the step, or split the file there, each part a trial of its own")
        raise ConfigError(f"t_s goes back from {t[i]:.12g} s ({row_name(i)}) to {t[i + 1]:.12g} s ({row_name(i + 1)}): one "
                          "trial's rows in time order (two trials in one file? give each its own file)")
    median_s = float(np.median(dt))
    if not ROW_INTERVAL_S[0] <= median_s <= ROW_INTERVAL_S[1]:
        hint = ("milliseconds? divide by 1000" if median_s > ROW_INTERVAL_S[1] else
                "days (a spreadsheet's date-time)? multiply by 86400, or export seconds")
        raise ConfigError(f"t_s: the rows are a median {median_s:.3g} s apart ({row_name(0)} at {t[0]:.10g}, "
                          f"{row_name(1)} at {t[1]:.10g}); t_s is in seconds, rows {ROW_INTERVAL_S[0]:g}-"
                          f"{ROW_INTERVAL_S[1]:g} s apart: {hint}")
    limit_s = max(GAP_MIN_S, GAP_STEPS * median_s)
    gaps = np.flatnonzero(dt > limit_s)
    if gaps.size:
        i = gaps[0]
        raise ConfigError(f"t_s jumps {dt[i]:.1f} s from {t[i]:g} s ({row_name(i)}) to {t[i + 1]:g} s "
                          f"({row_name(i + 1)}): a gap in the record (the logger stopped?); split the file there, "
                          "each part a trial of its own")


# a measurement dated this far after the row that carries it (or two rows' steps, if more) is on another clock: the
# shifts found were seconds; 10 ms refused a row clock 50 ms behind the receiver's, or t_s cut to 0.1 s (a review)
MEASURED_AFTER_ROW_S = 0.5
# the median age of the measurements where they first appear, beyond this: another clock, not a slow sensor (a fix
# reaches a 10 Hz logger within ~0.2 s of its time)
ARRIVAL_AGE_MAX_S = 3.0


def check_measurement_times(t_row_s: np.ndarray, times_s: np.ndarray | None, column: str, row_name) -> None:
    """ConfigError when ``column`` (position_time_s, heading_time_s) is not on t_s's clock: a time after its row,
    or measurements a median of more than ARRIVAL_AGE_MAX_S old where they first appear. Fix times shifted by 10 s
    or more stopped the identification with an internal error; shifted by 2 s they were fitted as a 0.52-s fix
    delay, by -10 s as 2 m of GPS wander, each 'adequate' (a new user's test, 2026-12-07)."""
    if times_s is None:
        return
    rows = np.flatnonzero(np.isfinite(t_row_s) & np.isfinite(times_s))
    if rows.size == 0:
        return
    age = t_row_s[rows] - times_s[rows]
    steps = np.diff(t_row_s[np.isfinite(t_row_s)])
    tolerance_s = max(MEASURED_AFTER_ROW_S, 2.0 * float(np.median(steps))) if steps.size else MEASURED_AFTER_ROW_S
    late = np.flatnonzero(age < -tolerance_s)
    same_clock = f"{column} is when the row's measurement was taken, on t_s's clock (another clock? a column shifted?)"
    if late.size:
        i = rows[late[0]]
        raise ConfigError(f"{row_name(i)}, {column}: {times_s[i]:.10g} s is {-age[late[0]]:.4g} s after the row's "
                          f"t_s ({t_row_s[i]:.10g} s): {same_clock}"
                          + (f"; {late.size} rows like it" if late.size > 1 else ""))
    arrived = np.concatenate(([True], np.diff(times_s[rows]) != 0.0))  # where each measurement first appears
    median_s = float(np.median(age[arrived]))
    if median_s > ARRIVAL_AGE_MAX_S:
        i = rows[0]
        raise ConfigError(f"{column}: the measurements are a median {median_s:.3g} s older than the rows they first "
                          f"appear in ({row_name(i)}: {times_s[i]:.10g} s at t_s {t_row_s[i]:.10g} s), at most "
                          f"{ARRIVAL_AGE_MAX_S:g} s expected: {same_clock}")


def check_range(values: np.ndarray, column: str, lo: float, hi: float, unit: str, row_name, *, slack: float = 0.0,
                why: str = "") -> None:
    """ConfigError naming the first row whose ``column`` is outside [lo, hi] by more than ``slack`` (empty cells
    are gaps, not errors). A typed 2000 N among thrusts of at most 32.5 N was replayed as given, 'unexplained',
    and a latitude of 152 deg counted as two more fixes."""
    bad = np.flatnonzero(np.isfinite(values) & ((values < lo - slack) | (values > hi + slack)))
    if bad.size:
        i = bad[0]
        span = f"below {lo:g} {unit}" if math.isinf(hi) else f"outside {lo:g} to {hi:g} {unit}"
        raise ConfigError(f"{row_name(i)}, {column}: {values[i]:g} {unit} is {span}{why}"
                          + (f"; {bad.size} rows like it" if bad.size > 1 else ""))


def _increasing_rows(t: np.ndarray) -> np.ndarray:
    """Rows with a finite time later than every earlier one (a repeated or backwards stamp is a glitch)."""
    good, last = [], -math.inf
    for i in np.flatnonzero(np.isfinite(t)):
        if t[i] > last:
            good.append(i)
            last = t[i]
    return np.asarray(good, dtype=int)


def new_fixes(north_m: np.ndarray, east_m: np.ndarray, t_row_s: np.ndarray, fix_time_s: np.ndarray | None):
    """(is_new, fix_time_s) per row: a fix is new when its cells are set and its fix time advanced past the last
    fix's; on a row without a fix time, when its cells differ from the last fix (and its row is later).

    With a fix time the time alone decides: a boat at rest at the dock or keeping station, its receiver's
    coordinates printed to a finite resolution (or pinned by a static hold), gives new fixes with the
    coordinates of the one before. Dropped as held, a 30-s stay's 30 fixes were one, 39 fixes of a 70-s trial's 70
    kept (tests/test_sysid_real_logs.py)."""
    is_new = np.zeros(t_row_s.size, dtype=bool)
    times = np.full(t_row_s.size, np.nan)
    last_ne, last_t = None, -math.inf
    for k in np.flatnonzero(np.isfinite(north_m) & np.isfinite(east_m)):
        ne = (north_m[k], east_m[k])
        timed = fix_time_s is not None and math.isfinite(fix_time_s[k])
        if timed:
            t = fix_time_s[k]
        else:  # it arrived at some moment since the row before: the middle, not the row's end
            t = t_row_s[k] - 0.5 * (t_row_s[k] - t_row_s[k - 1] if k > 0 else 0.0)
        if (ne == last_ne and not timed) or t <= last_t + SAME_TIME_S:
            continue
        is_new[k], times[k] = True, t
        last_ne, last_t = ne, t
    return is_new, times


def new_headings(heading: np.ndarray, t_row_s: np.ndarray, heading_time_s: np.ndarray | None):
    """(is_new, heading_time_s) per row: without a time column every heading cell is new."""
    ok = np.isfinite(heading)
    if heading_time_s is None:
        return ok, np.where(ok, t_row_s, np.nan)
    t = np.where(np.isfinite(heading_time_s), heading_time_s, t_row_s)
    is_new = np.zeros(t.size, dtype=bool)
    last = -math.inf
    for k in np.flatnonzero(ok):
        if t[k] > last + SAME_TIME_S:
            is_new[k] = True
            last = t[k]
    return is_new, np.where(is_new, t, np.nan)


def new_velocities(sog: np.ndarray | None, cog: np.ndarray | None, fix_new: np.ndarray, fix_time_s: np.ndarray,
                   t_row_s: np.ndarray):
    """(is_new, time_s) per row: a speed/course pair is new where it changes, or where it follows an empty cell (a
    log that writes each pair once), measured in the epoch of the latest fix at or before its row (module
    docstring); none before the first fix.

    A pair that arrives a whole epoch (the median interval between fixes) or more after the latest fix is of a
    later epoch whose fix was lost (a GGA garbled on the line, the RMC after it intact): it is dated on the
    epochs' grid, the latest fix's time plus whole epochs. Given the lost fix's time, one course measured at
    38.1 s was fitted as if at 37.1 s, a degree off in a turn, and the sensor delay came out 0.10 s for 0.14 s.

    A pair held unchanged through STEADY_EPOCHS epochs or more is a steady reading, one measurement each epoch
    that has its fix (dated with it, on the epoch's last row): a boat at rest (a receiver prints 0.00 kn and holds its
    course) or at a speed and course steady to the print's resolution reports the same pair every epoch. Taken
    only where it changed, a 30-s stay gave one pair (tests/test_sysid_real_logs.py). Unchanged through one
    epoch only, it is not taken: there a lost RMC (the pair of the epoch before, held) is likelier than a
    repeat (0.01 kn and 0.1 deg repeat by chance about once in a thousand epochs at cruise), and dated an
    epoch late it is a turn's second of course wrong.
    """
    n = fix_new.size
    is_new, times = np.zeros(n, dtype=bool), np.full(n, np.nan)
    if sog is None or cog is None:
        return is_new, times
    fix_times = fix_time_s[fix_new]
    epoch_s = float(np.median(np.diff(fix_times))) if fix_times.size >= 3 else math.inf
    last_fix_t = _forward_fill_after(np.where(fix_new, fix_time_s, np.nan))
    has_pair = np.isfinite(sog) & np.isfinite(cog)
    last, taken_epoch = None, None
    steady: list[list] = []  # [epoch time, its last row] of the epochs since the last pair taken, the pair unchanged

    def take(k: int, epoch_t: float) -> None:
        is_new[k], times[k] = True, min(epoch_t, t_row_s[k])

    def end_steady(changed_in: float | None) -> None:
        run = [e for e in steady if e[0] != changed_in]  # the epoch of a change had its own pair
        if len(run) >= STEADY_EPOCHS:
            for epoch_t, k in run:
                take(k, epoch_t)
        steady.clear()

    for k in np.flatnonzero(has_pair & np.isfinite(last_fix_t)):
        epochs_later = math.floor((t_row_s[k] - last_fix_t[k]) / epoch_s) if epoch_s > 0.0 else 0
        epoch_t = last_fix_t[k] + max(epochs_later, 0) * epoch_s
        pair = (sog[k], cog[k])
        if pair != last or k == 0 or not has_pair[k - 1]:
            end_steady(epoch_t)
            take(k, epoch_t)
            last, taken_epoch = pair, epoch_t
        elif steady and steady[-1][0] == epoch_t:
            steady[-1][1] = k
        elif epoch_t != taken_epoch and epochs_later <= 0:  # an epoch without its fix: its sentences lost?
            steady.append([epoch_t, k])
    end_steady(None)
    taken = np.flatnonzero(is_new)
    if taken.size >= 2 and times[taken[0]] == times[taken[1]] and taken[0] == np.flatnonzero(has_pair)[0]:
        # the trial's first pair and the next one dated in one epoch: the first was there before the trial began
        # (a mission log cut at its first cycle in auto, whose row still held the epoch before's pair), not a
        # reading of this epoch: dated with it, a second's speed and course late (a sysid audit, 2026-12-06)
        is_new[taken[0]], times[taken[0]] = False, np.nan
    return is_new, times


def _forward_fill_after(x: np.ndarray) -> np.ndarray:
    """NaN replaced by the last valid value; NaN stays before the first one."""
    ok = np.isfinite(x)
    idx = np.where(ok, np.arange(x.size), -1)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, x[np.maximum(idx, 0)], np.nan)


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
    position_time_s=None,
    heading_time_s=None,
    exclude=None,
    stalled_after=None,
    sog_m_s=None,
    cog_deg=None,
    rot_deg_s=None,
    curve: ThrustCurve | None = None,
    commands_held: bool = False,
    row_name=lambda i: f"data row {i + 1}",
    wall_clock: bool = True,
) -> Trial:
    """Build a :class:`Trial` from raw per-row columns (degrees and duty only at this edge).

    ``exclude``: rows whose measurements are not used (their commands are); ``stalled_after``: rows after which the
    loop stalled (Trial.stalled_after). ``row_name(i)``: row i as the
    user finds it in the file (check_times' messages); ``wall_clock``: check_times'.
    """
    curve = curve or ThrustCurve()
    t = np.asarray(t_s, dtype=float)
    check_times(t, row_name, wall_clock=wall_clock)
    sel = _increasing_rows(t)
    if sel.size < MIN_SAMPLES:
        raise ConfigError(f"trial {name}: only {sel.size} samples with a usable t_s (need {MIN_SAMPLES})")

    def col(x):
        return None if x is None else np.asarray(x, dtype=float)[sel]

    slack_n = THRUST_SLACK * max(curve.max_forward_n, curve.max_reverse_n)
    thrusters = (" (the thrusters' thrust curve; refused beyond half as much again: a typo? a thrust column in "
                 "other units?)")
    for column, values, lo, hi, unit, slack, why in (
            ("thrust_port_n", thrust_port_n, -curve.max_reverse_n, curve.max_forward_n, "N", slack_n, thrusters),
            ("thrust_stbd_n", thrust_stbd_n, -curve.max_reverse_n, curve.max_forward_n, "N", slack_n, thrusters),
            ("pwm_port_pct", pwm_port_pct, -100.0, 100.0, "%", 0.0, ""),
            ("pwm_stbd_pct", pwm_stbd_pct, -100.0, 100.0, "%", 0.0, ""),
            ("sog_m_s", sog_m_s, 0.0, math.inf, "m/s", 0.0, "")):
        if values is not None:
            check_range(np.asarray(values, dtype=float)[sel], column, lo, hi, unit, lambda i: row_name(sel[i]),
                        slack=slack, why=why)
    tp, ts, dp, ds = _commands(name, col(thrust_port_n), col(thrust_stbd_n), col(pwm_port_pct), col(pwm_stbd_pct), curve)
    t_sel = t[sel]
    t0 = t_sel[0]
    for column, times in (("position_time_s", position_time_s), ("heading_time_s", heading_time_s)):
        check_measurement_times(t_sel, col(times), column, lambda i: row_name(sel[i]))
    n, e, heading = col(north_m), col(east_m), col(heading_deg)
    drop = np.zeros(sel.size, dtype=bool) if exclude is None else np.asarray(exclude, dtype=bool)[sel]
    fix_new, fix_t = new_fixes(n, e, t_sel, col(position_time_s))
    hdg_new, hdg_t = new_headings(heading, t_sel, col(heading_time_s))
    sog, cog = col(sog_m_s), None if cog_deg is None else np.radians(col(cog_deg))
    vel_new, vel_t = new_velocities(sog, cog, fix_new, fix_t, t_sel)
    counts = _counts(n, e, heading, fix_new, hdg_new, drop)
    fix_new &= ~drop
    hdg_new &= ~drop
    vel_new &= ~drop
    if vel_new.sum() < MIN_VELOCITIES:
        vel_new[:] = False
    counts["velocities"] = int(vel_new.sum())
    if fix_new.sum() < MIN_FIXES or hdg_new.sum() < MIN_HEADINGS:
        raise ConfigError(f"trial {name}: {int(fix_new.sum())} position fixes and {int(hdg_new.sum())} headings "
                          f"usable (need {MIN_FIXES} and {MIN_HEADINGS})")
    try:
        forward = tp + ts >= AHEAD_MIN_N

        def ahead(times_s):
            return forward[np.clip(np.searchsorted(t_sel, times_s, side="right") - 1, 0, t_sel.size - 1)]

        track_note = check_heading_units(np.where(fix_new, fix_t, np.nan), n, e, np.where(hdg_new, hdg_t, np.nan),
                                         heading, ahead)
    except ConfigError as exc:
        raise ConfigError(f"trial {name}: {exc}") from None
    return Trial(
        name=name,
        t_s=t_sel - t0,
        thrust_port_n=tp, thrust_stbd_n=ts, duty_port_pct=dp, duty_stbd_pct=ds,
        north_m=np.where(fix_new, n, np.nan),
        east_m=np.where(fix_new, e, np.nan),
        heading_rad=np.where(hdg_new, np.radians(heading), np.nan),
        position_time_s=np.where(fix_new, fix_t - t0, np.nan),
        heading_time_s=np.where(hdg_new, hdg_t - t0, np.nan),
        sog_m_s=sog,
        cog_rad=cog,
        velocity_time_s=np.where(vel_new, vel_t - t0, np.nan),
        yaw_rate_rad_s=None if rot_deg_s is None else np.radians(col(rot_deg_s)),
        commands_held=commands_held,
        stalled_after=None if stalled_after is None else np.asarray(stalled_after, dtype=bool)[sel],
        counts=counts,
        read_notes=_coarse_rows_note(t_sel, heading_time_s is not None) + track_note,
        t0_s=float(t0),
    )


# the track's course from fixes at least this far apart in time and space, the boat moving at least this fast
TRACK_SPAN_S, TRACK_MIN_M, TRACK_MIN_SPEED_M_S = 5.0, 5.0, 0.5
TRACK_MIN_STRETCHES = 5
HEADING_AGREES_DEG, HEADING_DISAGREES_DEG = 30.0, 60.0  # median |course - heading| for a heading that follows or not
RADIANS_CLOSER = 0.5  # a heading read as radians this much closer to the course than read as degrees is in radians
AHEAD_MIN_N = 10.0  # the two thrusters' sum at least this ahead: the boat moves along its bow (no drift, no astern)


def heading_against_track(fix_t_s, north_m, east_m, heading_t_s, heading_deg, ahead=None) -> tuple[float, float, int] | None:
    """(median |course over ground - heading| with the heading read as degrees, the same read as radians (deg;
    NaN when a value lies outside -pi..2*pi), stretches compared) over the stretches where the fixes show the
    boat moving and ``ahead(t_s) -> bool`` (the thrust ahead, None: always) holds at their ends and middle (a
    boat astern, or drifting with its bow steady near 3 deg, matched 3 rad: a review); None with fewer than
    TRACK_MIN_STRETCHES. A WAM-V moves along its bow: a heading that does not
    follow its track is in other units or the track's columns are crossed."""
    from autopilot.geo import wrap_pi

    ok = np.isfinite(fix_t_s) & np.isfinite(north_m) & np.isfinite(east_m)
    tf, nf, ef = fix_t_s[ok], north_m[ok], east_m[ok]
    okh = np.isfinite(heading_t_s) & np.isfinite(heading_deg)
    th, h = heading_t_s[okh], heading_deg[okh]
    if tf.size < 2 or th.size == 0:
        return None
    j = np.searchsorted(tf, tf + TRACK_SPAN_S)
    i = np.flatnonzero(j < tf.size)
    j = j[i]
    dn, de, dt = nf[j] - nf[i], ef[j] - ef[i], tf[j] - tf[i]
    dist = np.hypot(dn, de)
    moving = (dist >= TRACK_MIN_M) & (dist >= TRACK_MIN_SPEED_M_S * dt)
    if ahead is not None:
        moving &= ahead(tf[i]) & ahead(tf[j]) & ahead(0.5 * (tf[i] + tf[j]))
    if moving.sum() < TRACK_MIN_STRETCHES:
        return None
    course = np.arctan2(de[moving], dn[moving])
    mid = 0.5 * (tf[i][moving] + tf[j][moving])
    k = np.clip(np.searchsorted(th, mid), 0, th.size - 1)
    near = h[k]

    def median_deg(heading_rad):
        return float(np.degrees(np.median(np.abs([wrap_pi(c - x) for c, x in zip(course, heading_rad)]))))

    as_rad = median_deg(near) if np.all((h >= -math.pi - 0.01) & (h <= 2.0 * math.pi + 0.01)) else math.nan
    return median_deg(np.radians(near)), as_rad, int(moving.sum())


def check_heading_units(fix_t_s, north_m, east_m, heading_t_s, heading_deg, ahead=None) -> tuple:
    """ConfigError when heading_deg is in radians (every value within -pi..2*pi, and read as radians it follows the
    track's course while read as degrees it does not); a note when the heading does not follow the track at all.
    A heading in radians was fitted as a yaw damping 500 times the boat's, 'adequate' (a new user's test)."""
    found = heading_against_track(fix_t_s, north_m, east_m, heading_t_s, heading_deg, ahead)
    if found is None:
        return ()
    as_deg, as_rad, stretches = found
    # read as radians, far closer than read as degrees: a boat heading near north all along agrees with its
    # compressed radians read as degrees too (8 deg off against 3 deg in pond-9.4)
    if as_rad <= HEADING_AGREES_DEG and as_rad < RADIANS_CLOSER * as_deg:
        raise ConfigError(f"heading_deg: every value lies within -3.15 to 6.29 and, read as radians, the heading "
                          f"follows the track's course (a median {as_rad:.0f} deg off over {stretches} stretches the "
                          f"boat moved; read as degrees, {as_deg:.0f} deg off): radians? heading_deg is in degrees "
                          "(multiply by 57.2958)")
    if as_deg > HEADING_DISAGREES_DEG:
        return (f"the heading does not follow the track's course: a median {as_deg:.0f} deg apart over {stretches} "
                "stretches the boat moved (a WAM-V moves along its bow): the position columns crossed (lat_deg and "
                "lon_deg, or north_m and east_m, swapped?), a compass mounted off the bow, a trial run astern, or a "
                "drift at low thrust in a current or wind? The identification fits whatever it is given",)
    return ()


COARSE_ROWS_S = 0.15  # rows further apart than this (median) are coarser than the daemon's 10 Hz cycle


def _coarse_rows_note(t_row_s: np.ndarray, heading_times: bool) -> tuple:
    """A note when the rows are coarser than the control cycle: a 1 Hz logger's trials were `unexplained` or
    gained a sensor_delay (subsampled 10 Hz logs), and the answer said nothing of why; at the cycle's rate, when
    the headings have no times of their own."""
    dt = np.diff(t_row_s)
    step = float(np.median(dt)) if dt.size else 0.0
    if not step > COARSE_ROWS_S:
        if heading_times or not dt.size:
            return ()
        # a 10 Hz export without the column came out `unexplained` beside a current, nearest sensor_delay + current,
        # its headings 0.11-0.31 s older than their rows, and nothing said why (a sysid audit, 2026-12-06)
        return ("each heading is dated at its row (no heading_time_s column): a compass the logger samples, not one "
                "that drives it, is older than its row by a varying 0.1-0.3 s, which no constant sensor delay explains, "
                "and a trial can come out `unexplained`; give the heading's own time in heading_time_s (`autopilot "
                "review --export csv` writes it)",)
    dated = "" if heading_times else (" and each heading is dated at its row (no heading_time_s column), up to a row "
                                      "late: a sensor delay")
    return (f"rows every {step:.2g} s: the commands are known only at the rows (the controller changes them every "
            f"0.1 s){dated}; a trial this coarse can be `unexplained`, or show effects of its sampling",)


def _counts(n, e, heading, fix_new, hdg_new, drop) -> dict:
    """What the rules kept and dropped (summary.json ``measurements``)."""
    return {
        "rows": int(drop.size),
        "position_fixes": int(np.sum(fix_new & ~drop)),
        "held_fix_rows": int(np.sum(np.isfinite(n) & np.isfinite(e) & ~fix_new)),
        "headings": int(np.sum(hdg_new & ~drop)),
        "held_heading_rows": int(np.sum(np.isfinite(heading) & ~hdg_new)),
        "excluded_rows": int(drop.sum()),
    }


def _commands(name, tp, ts, dp, ds, curve: ThrustCurve):
    """(thrust_port_n, thrust_stbd_n, duty_port_pct, duty_stbd_pct), the missing ones from the thrust curve. A
    column empty in every row is no command: read as zero thrust, a log without commands came out 'unexplained'
    (chi-square 60 000) with no word of why (a new user's test)."""
    given = {"thrust_port_n": tp, "thrust_stbd_n": ts, "pwm_port_pct": dp, "pwm_stbd_pct": ds}
    empty = [k for k, v in given.items() if v is not None and not np.isfinite(v).any()]
    tp, ts, dp, ds = (None if k in empty else v for k, v in given.items())
    if empty and not ((tp is not None and ts is not None) or (dp is not None and ds is not None)):
        raise ConfigError(f"trial {name}: {' and '.join(empty)} {'is' if len(empty) == 1 else 'are'} empty in every "
                          "row: the commands are needed (thrust_port_n/thrust_stbd_n in N, or pwm_port_pct/"
                          "pwm_stbd_pct in %)")
    if tp is not None and ts is not None:
        tp, ts = _held_commands(tp), _held_commands(ts)
        return tp, ts, curve.signed_duty_pct(tp), curve.signed_duty_pct(ts)
    if dp is not None and ds is not None:
        dp, ds = _held_commands(dp), _held_commands(ds)
        return (np.asarray(curve.thrust_from_signed_duty_n(dp), dtype=float),
                np.asarray(curve.thrust_from_signed_duty_n(ds), dtype=float), dp, ds)
    raise ConfigError(f"trial {name}: needs thrust_port_n/thrust_stbd_n or pwm_port_pct/pwm_stbd_pct")


def trial_from_columns(name: str, cols: dict, *, curve: ThrustCurve | None = None,
                       row_name=lambda i: f"data row {i + 1}") -> Trial:
    """A trial from the CSV's columns (name -> per-row values, NaN = empty cell); ConfigError names what is missing."""
    # a column empty in every row is no column: a north_m left empty beside full lat_deg/lon_deg refused the trial
    # for want of fixes (a new user's test)
    rows = np.isfinite(cols["t_s"]).any()  # a file of a header alone is refused for want of rows (make_trial)
    empty = {k for k, v in cols.items() if k != "t_s" and rows and not np.isfinite(v).any()}
    get = {k: v for k, v in cols.items() if k not in empty}.get
    north, east = get("north_m"), get("east_m")
    if north is None or east is None:
        lat, lon = get("lat_deg"), get("lon_deg")
        if lat is None or lon is None:
            raise ConfigError("needs north_m/east_m or lat_deg/lon_deg columns")
        check_range(lat, "lat_deg", -90.0, 90.0, "deg", row_name)
        check_range(lon, "lon_deg", -180.0, 180.0, "deg", row_name)
        ok = np.isfinite(lat) & np.isfinite(lon)
        if not ok.any():
            raise ConfigError("no valid lat_deg/lon_deg")
        i0 = np.flatnonzero(ok)[0]
        north, east = latlon_to_local(lat, lon, float(lat[i0]), float(lon[i0]))
    if get("heading_deg") is None:
        raise ConfigError("heading_deg is empty in every row" if "heading_deg" in empty else "needs a heading_deg column")
    trial = make_trial(
        name, cols["t_s"], north_m=north, east_m=east, heading_deg=get("heading_deg"),
        thrust_port_n=cols.get("thrust_port_n"), thrust_stbd_n=cols.get("thrust_stbd_n"),
        pwm_port_pct=cols.get("pwm_port_pct"), pwm_stbd_pct=cols.get("pwm_stbd_pct"),
        position_time_s=get("position_time_s"), heading_time_s=get("heading_time_s"),
        sog_m_s=get("sog_m_s"), cog_deg=get("cog_deg"), rot_deg_s=get("rot_deg_s"), curve=curve, row_name=row_name,
    )
    lost = rows_lost(trial.t_s)
    return dataclasses.replace(trial, lost_s=lost) if lost else trial


LOST_MIN_S = 0.5  # a CSV's rows this far apart, and LOST_STEPS typical steps, were lost: the commands then unknown
LOST_STEPS = 4.0


UNDELIVERED_MIN = 3  # commands the motors may not have had in a stretch of more than LOST_MIN_S: cut there
CSV_TIME_RESOLUTION_S = 0.001  # review --export csv writes t_s to the millisecond


def undelivered_stretch(misses: int, span_s: float) -> bool:
    """A stretch of commands that may not have reached the motors is cut (as rows lost) when it holds
    UNDELIVERED_MIN or more of them and its neighbours are more than LOST_MIN_S apart, by more than the CSV's
    millisecond: the CSV export leaves such rows out, and its gap must be one rows_lost cuts at too (0.5 s in the
    log was 0.500 in the CSV: cut in one, bridged in the other, a review). Shorter, the motors held a command a
    step or two longer, as a missing row or two is interpolated."""
    return misses >= UNDELIVERED_MIN and span_s > LOST_MIN_S + 2.0 * CSV_TIME_RESOLUTION_S


def typical_step_s(dt_s: np.ndarray) -> float:
    """The step that holds the middle of the record's time (the median weighted by time), not the median step: a
    logger that writes a row per sentence (the GGA, the RMC 0.1 s later, then 0.9 s to the next epoch) has a
    median step of 0.1 s when the short steps outnumber the long, and every epoch's 0.9 s counted as rows lost
    (the trial cut at each, every part too short: replayed whole under a note naming 59 stretches; stop 48's
    note); an 80th percentile still failed five sentences an epoch (a review). Rows lost take less time than the
    rows kept."""
    steps = np.sort(dt_s)
    return float(steps[np.searchsorted(np.cumsum(steps), 0.5 * steps.sum())])


def rows_lost(t_s: np.ndarray) -> tuple:
    """(t_s before, t_s after) of each step between a CSV's rows longer than LOST_MIN_S and LOST_STEPS typical
    steps (:func:`typical_step_s`): rows lost (a mission log's lines a failed write lost, exported), over which
    the commands are unknown and a replay on them interpolated drifts (cut_at_lost). A missing row or two is
    interpolated (_commands)."""
    dt = np.diff(t_s)
    if dt.size == 0:
        return ()
    limit_s = max(LOST_MIN_S, LOST_STEPS * typical_step_s(dt))
    return tuple((float(t_s[k]), float(t_s[k + 1])) for k in np.flatnonzero(dt > limit_s))


# the trial CSV's columns, once: ``autopilot sysid --help`` shows them (an installed user has no source to read)
CSV_HELP = """trial CSV: a header line, one row per sample, any column order, unknown columns ignored,
empty cells are gaps (Excel's ';' and decimal commas, a BOM, Windows-1252 are read too):
  t_s                              time (s), increasing
  thrust_port_n, thrust_stbd_n     commanded thrust (N, negative = astern), or
  pwm_port_pct, pwm_stbd_pct       signed duty (%, negative = reverse); an empty cell holds the
                                   command before it (before the first command: zero)
  north_m, east_m                  position (m, local frame), or
  lat_deg, lon_deg                 position (deg)
  heading_deg                      heading from north, clockwise (deg)
  position_time_s, heading_time_s  optional: when the row's fix / heading was measured (s)
  sog_m_s, cog_deg                 optional: speed (m/s) and course (deg) over ground
  rot_deg_s                        optional: rate of turn (deg/s)
`autopilot review LOG --export csv` writes a mission log in this form."""
TRIAL_COLUMNS = ("t_s", "north_m", "east_m", "lat_deg", "lon_deg", "heading_deg", "thrust_port_n", "thrust_stbd_n",
                 "pwm_port_pct", "pwm_stbd_pct", "position_time_s", "heading_time_s", "sog_m_s", "cog_deg", "rot_deg_s")
# what a units row under the header may say of each column read: a sog_m_s in knots or a heading in radians was
# skipped as a units row and read as m/s and degrees, 'unexplained' (a sysid audit)
TRIAL_UNITS = {"t_s": SECONDS, "position_time_s": SECONDS, "heading_time_s": SECONDS, "north_m": METRES,
               "east_m": METRES, "lat_deg": DEGREES, "lon_deg": DEGREES, "heading_deg": DEGREES, "cog_deg": DEGREES,
               "thrust_port_n": NEWTONS, "thrust_stbd_n": NEWTONS, "pwm_port_pct": PERCENT, "pwm_stbd_pct": PERCENT,
               "sog_m_s": METRES_PER_SECOND, "rot_deg_s": DEGREES_PER_SECOND}


def read_trial_csv(path, *, curve: ThrustCurve | None = None) -> Trial:
    """Read one trial CSV (columns in the module docstring); a cell that is not a number, a time going back
    or a last row cut off mid-write is refused naming the row."""
    from autopilot.userfile import (
        csv_rows,
        known_names,
        number_cell,
        read_text,
        too_many_fields,
        unique_header,
        units_row,
        units_row_refusal,
    )

    path = Path(path)
    text = read_text(path, what="trial CSV", spreadsheet=True)
    table = csv_rows(text)
    header = known_names(table[0], TRIAL_COLUMNS) if table else []
    if "t_s" not in header:
        raise ConfigError(f"{path}: no t_s column in the header ({', '.join(header) or 'empty file'})")
    try:
        unique_header(header, TRIAL_COLUMNS)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    width = len(header)
    units = len(table) > 1 and units_row(table[1])  # a row of units under the header (s, m, deg, N): no data
    if units and (refusal := units_row_refusal(path, table[1], header, TRIAL_UNITS, "trial CSV")) is not None:
        raise ConfigError(refusal)
    if len(table) > 1 and len(table[-1]) < width and not text.endswith(("\n", "\r")):
        raise ConfigError(f"{path}: data row {len(table) - 1} has {len(table[-1])} of {width} fields and the file does "
                          "not end with a new line: cut off mid-write? delete that row")
    data = np.full((len(table) - 1, width), np.nan)
    try:
        for i, r in enumerate(table[1:]):
            if i == 0 and units:
                continue  # left empty: dropped below with the empty rows, the rows keep their numbers
            problem = too_many_fields(r, width, i + 1)
            if problem:
                raise ConfigError(problem)
            for k, c in enumerate(r[:width]):
                if header[k] in TRIAL_COLUMNS:  # other columns (a note, a label) are the user's own
                    data[i, k] = number_cell(c, i + 1, header[k], header)
        kept = np.flatnonzero(~np.all(np.isnan(data), axis=1))  # rows of empty cells (Excel's ",,,,,") are no rows
        data = data[kept]
        cols = {h: data[:, k] for k, h in enumerate(header) if h in TRIAL_COLUMNS}
        return trial_from_columns(path.stem, cols, curve=curve, row_name=lambda i: f"data row {kept[i] + 1}")
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from exc


def read_trial(path, *, curve: ThrustCurve | None = None) -> Trial:
    """A trial CSV or a mission log (``.jsonl``/``.json``/``.log``, either gzip-compressed: ``.jsonl.gz``; or
    whatever its name, a file whose first line is a JSON object)."""
    suffixes = [x.lower() for x in Path(path).suffixes]
    if suffixes[-1:] == [".gz"]:
        suffixes = suffixes[:-1]
    if (suffixes and suffixes[-1] in (".jsonl", ".json", ".log")) or _starts_as_json(path):
        from autopilot.sysid.mission_log import read_mission_log

        return read_mission_log(path, curve=curve)
    return read_trial_csv(path, curve=curve)


def _starts_as_json(path) -> bool:
    """The file (gzip-compressed or not) begins with a JSON object: a mission log renamed, or saved without its
    ``.jsonl`` (read as a CSV, it was refused with its whole first line as 'the header')."""
    from autopilot.review.reader import open_log

    try:
        with open_log(Path(path)) as f:
            head = f.read(256)
    except (OSError, EOFError):
        return False  # the CSV reader says what is wrong with it
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{")


def write_trial_csv(trial: Trial, path) -> None:
    """Write a trial in the CSV format above: the new measurements only, each with its time."""
    cols = {
        "t_s": trial.t_s,
        "thrust_port_n": trial.thrust_port_n,
        "thrust_stbd_n": trial.thrust_stbd_n,
        "north_m": trial.north_m,
        "east_m": trial.east_m,
        "position_time_s": trial.position_time_s,
        "heading_deg": np.degrees(trial.heading_rad) % 360.0,
        "heading_time_s": trial.heading_time_s,
    }
    rows = trial.velocity_rows
    if rows.size:  # each new speed/course on its own row (read back with the latest fix's time)
        for name, values in (("sog_m_s", trial.sog_m_s), ("cog_deg", np.degrees(trial.cog_rad) % 360.0)):
            cols[name] = np.full(trial.t_s.size, np.nan)
            cols[name][rows] = values[rows]
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in data:
            w.writerow(["" if not math.isfinite(v) else f"{v:.9g}" for v in row])


def window(tr: Trial, start: float, window_s: float) -> Trial | None:
    """The rows of ``tr`` in [start, start + window_s), on a time base starting at 0, or None
    when it holds too little (3 positions and headings in its first 3 s, 6 positions in all)."""
    sel = (tr.t_s >= start) & (tr.t_s < start + window_s)
    first = sel & (tr.t_s < start + 3.0)
    fixes = np.isfinite(tr.position_time_s) & (tr.position_time_s >= start)
    heads = np.isfinite(tr.heading_time_s) & (tr.heading_time_s >= start)
    if sel.sum() < 20 or (fixes & sel).sum() < 6 or (fixes & first).sum() < 2 or (heads & first).sum() < 3:
        return None
    fields = {f.name: getattr(tr, f.name)[sel] for f in dataclasses.fields(tr)
              if isinstance(getattr(tr, f.name), np.ndarray) and getattr(tr, f.name).shape == tr.t_s.shape}
    fields["north_m"] = np.where(fixes[sel], fields["north_m"], np.nan)
    fields["heading_rad"] = np.where(heads[sel], fields["heading_rad"], np.nan)
    times = ["t_s", "position_time_s", "heading_time_s"]
    if tr.velocity_time_s is not None:
        fields["velocity_time_s"] = np.where(fields["velocity_time_s"] >= start, fields["velocity_time_s"], np.nan)
        times.append("velocity_time_s")
    for name in times:
        fields[name] = fields[name] - start
    return dataclasses.replace(tr, name=f"{tr.name}@{start - tr.t_s[0]:.0f}s", t0_s=tr.t0_s + start, **fields)


LONG_TRIAL_S = 150.0  # a trial longer than this is cut into pieces (cut_long)
PIECE_MAX_S = 75.0
PIECE_MIN_S = 20.0  # a piece's start moves past a dropout at most until this is left of it


def _first_window(tr: Trial, a: float, b: float) -> tuple[float, Trial] | None:
    """(start, piece) of the rows in [a, b): the piece beginning at ``a``, or after a dropout at its edge at the
    first whole second that begins with fixes and headings (window), at most until PIECE_MIN_S is left; None when
    none does."""
    s = a
    while True:
        piece = window(tr, s, b - s)
        if piece is not None:
            return s, piece
        if s + 1.0 + PIECE_MIN_S >= b:
            return None
        s += 1.0


def cut_at_lost(trials) -> tuple[list[Trial], list[str]]:
    """The trials, each with rows lost (``Trial.lost_s``) or commands the motors may not have had
    (``Trial.undelivered_s``) cut there into parts, each ending at the last row before a stretch and the next
    beginning at the first row after it, each replayed from its own initial state; and a note per trial cut.

    The commands over lost lines are unknown: held open loop across them (the motors' last logged command, while
    the daemon went on steering), 2-2.5 s of a mission log's lines lost to failed writes in each of three pond
    logs turned a current into 'unexplained', heading 8.6 deg against noise 0.9 (a sysid audit, 2026-12-06).
    A part too short to fit (window) is left out, said in the note."""
    out, notes = [], []
    for tr in trials:
        if not tr.lost_s and not tr.undelivered_s:
            out.append(tr)
            continue
        stretches = sorted((*tr.lost_s, *tr.undelivered_s))
        end_s = float(tr.t_s[-1]) + 1.0
        edges = [float(tr.t_s[0])] + [float(after) for _, after in stretches]
        # each part ends at its stretch's last row before (an undelivered stretch's own rows belong to neither)
        ends = [float(before) + 1e-6 for before, _ in stretches] + [end_s]
        parts = [_first_window(tr, a, b) for a, b in zip(edges, ends)]
        kept = [p for _, p in filter(None, parts)]
        said = []
        for what, why, pairs in (
                ("rows lost at t_s", " (lines the log never got, a logger that stalled, or an export leaving out "
                 "commands the Mbed may not have had: the commands then are not in the file)", tr.lost_s),
                ("commands the motors may not have had at t_s", " (not written to the Mbed, or not acknowledged by "
                 "it: the log holds what the daemon sent)", tr.undelivered_s)):
            if pairs:
                said.append(f"{what} " + ", ".join(f"{tr.t0_s + before:.1f}-{tr.t0_s + after:.1f} s"
                                                   for before, after in pairs) + why)
        lost = "; ".join(said)
        if not kept:
            out.append(tr)
            notes.append(f"{tr.name}: {lost}; no part between long enough to fit alone: replayed whole, the "
                         "verdict may show it")
            continue
        # the fixes of the parts left out and before a part's moved start: counted, as cut_long counts its own
        # (the summary said every fix of the trial was used)
        fixes_out = len(tr.fix_rows) - sum(len(p.fix_rows) for p in kept)
        kept = [dataclasses.replace(p, counts={**tr.counts, "lost_rows_parts": len(kept),
                                               "lost_rows_fixes_left_out": fixes_out}) if k == 0
                else dataclasses.replace(p, counts={}, read_notes=()) for k, p in enumerate(kept)]
        out += kept
        left = (f"; {len(parts) - len(kept)} too short to fit left out" if len(kept) < len(parts) else "") + (
            f"; {fixes_out} fixes left out" if fixes_out > 0 else "")
        notes.append(f"{tr.name}: {lost}: cut there into {len(kept)} part(s), each replayed from its own "
                     f"state{left}")
    return out, notes


def cut_long(trials) -> tuple[list[Trial], list[str]]:
    """The trials, each longer than LONG_TRIAL_S cut into even pieces of at most PIECE_MAX_S, each replayed from
    its own initial state; and a note per trial cut.

    A replay holds the logged thrusts open loop from the trial's first state: over minutes of a closed-loop
    mission (the helm turning all the while) a small error of the wind's yaw moment grows into degrees of
    heading, and a 4-minute zigzag-003 log in 6 m/s of wind came out ``unexplained`` (a sysid audit,
    2026-12-05), its nearest candidate wind within 0.2 m/s of the truth, while the same log cut into ~60-s
    pieces was named wind. The pieces are trials of their own: held out in turn, and their jackknife widens
    the intervals. Their counts stay on the first piece (the summary adds them up)."""
    trials, notes = cut_at_lost(trials)
    out = []
    for tr in trials:
        span = float(tr.t_s[-1] - tr.t_s[0])
        if span <= LONG_TRIAL_S:
            out.append(tr)
            continue
        n = math.ceil(span / PIECE_MAX_S)
        piece_s = span / n
        end_s = float(tr.t_s[-1]) + 1.0
        edges = [float(tr.t_s[0]) + k * piece_s for k in range(n)] + [end_s]
        starts = []
        for a, b in zip(edges[:-1], edges[1:]):
            # a piece must begin with fixes and headings (window): after a dropout at its edge it begins at the
            # first second that does, the rows before it going to the piece before (a review: a 2-s outage at
            # a cut threw the whole 67-s piece away)
            s = a
            fits = window(tr, s, b - s) is not None
            while not fits and s + PIECE_MIN_S < b:
                s += 1.0
                fits = window(tr, s, b - s) is not None
            if fits:
                starts.append((a, s, b))
        # a piece ends where the next begins, or at its own edge when the next was left out (replayed open loop
        # over both, it was as long as the cut is there to prevent: a review)
        ends = [nxt[1] if nxt[0] == b else b for (_, _, b), nxt in zip(starts, starts[1:] + [(end_s, end_s, end_s)])]
        pieces = [window(tr, s, e - s) for (_, s, _), e in zip(starts, ends)]
        if len(pieces) < 2:  # too little in the pieces to fit them: the whole trial, as it is
            out.append(tr)
            continue
        fixes_out = len(tr.fix_rows) - sum(len(p.fix_rows) for p in pieces)  # before a piece's moved start
        pieces = [dataclasses.replace(p, counts={**tr.counts, "long_trial_pieces": len(pieces),
                                                 "long_trial_fixes_left_out": fixes_out}) if k == 0
                  else dataclasses.replace(p, counts={}, read_notes=()) for k, p in enumerate(pieces)]
        out += pieces
        left = (f"; {n - len(pieces)} of {n} without fixes and headings at its start left out" if len(pieces) < n
                else "") + (f"; {fixes_out} fixes left out" if fixes_out > 0 else "")
        notes.append(f"{tr.name} ({span:.0f} s) cut into {len(pieces)} pieces of {piece_s:.0f} s, each replayed from "
                     f"its own state (a replay of logged thrusts over minutes drifts; longer than {LONG_TRIAL_S:g} s{left})")
    return out, notes
