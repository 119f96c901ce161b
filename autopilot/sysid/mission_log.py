"""A daemon mission log (docs/log-schema.md) as a trial: the one place sysid names the log's fields.

Read with :func:`autopilot.review.reader.read_log`. Per ``cycle`` line:

- commands: ``thrust_port_n``, ``thrust_stbd_n`` (what the motors had, every
  cycle, also in failsafe: zero), held between cycles (a skipped deadline sends
  nothing, so the motors keep the last command, until the firmware stops them 0.5 s
  after it: ``prediction.firmware_stops``); where the Mbed did not
  acknowledge them, or the driver could not write them (``ack_missing``, ``seq``:
  ``MissionLog.undelivered_rows``), what the motors had is not known and the
  trial is cut there, as where lines were lost;
- position fix measured at ``t_s - position_age_s`` (a fix whose cells repeat
  the previous one is held, not new: the SC-30 sends one fix a second in GGA
  and RMC, the daemon restamps it on each); heading measured at
  ``t_s - heading_age_s`` (new when that time advances; none where the daemon
  steered on its course over ground, ``heading_source`` COG);
- cycles whose ``mode`` is not ``auto`` (failsafe, waiting, complete, hold) and
  the cycle right after skipped deadlines are excluded from the fit: their
  commands stay, their measurements go; the leading and trailing stretches
  that are not ``auto`` (waiting for data, the stop at the end) are cut off.

Skipped deadlines come from ``skipped_cycles`` (cumulative) and from any gap
of more than 1.5 periods between cycles (``rate_hz`` of ``mission_start``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.schema import ConfigError
from autopilot.sysid.trials import MIN_SAMPLES, Trial, make_trial

# log field -> its meaning here (docs/log-schema.md, cycle line)
F_TIME = "t_s"
F_NORTH, F_EAST = "north_m", "east_m"
# the heading: heading_deg where it is the compass's (MissionLog.compass_heading_deg: not a course over ground)
F_POSITION_AGE, F_HEADING_AGE = "position_age_s", "heading_age_s"
F_THRUST_PORT, F_THRUST_STBD = "thrust_port_n", "thrust_stbd_n"
F_SOG, F_COG, F_RATE = "sog_m_s", "cog_deg", "yaw_rate_deg_s"
F_SKIPPED = "skipped_cycles"
F_CYCLE = "cycle"
LOST_CYCLES = 3  # this many cycle lines missing in a row (the counter jumped; skipped deadlines do not count): cut
MODE_FITTED = "auto"
GAP_PERIODS = 1.5  # a cycle this many periods after the previous one followed skipped deadlines


def _column(log, name: str) -> np.ndarray | None:
    try:
        return log.col(name)
    except KeyError:  # a field this reader does not keep
        return None


def after_skipped_deadlines(log, t_s: np.ndarray) -> np.ndarray:
    """Per cycle: it came right after one or more skipped deadlines (``skipped_cycles`` grew, or the cycle
    came more than GAP_PERIODS periods after the previous one: a log cut and pasted, or an older daemon's)."""
    rate_hz = (log.start or {}).get("rate_hz")
    period_s = 1.0 / rate_hz if isinstance(rate_hz, (int, float)) and rate_hz > 0 else float(np.median(np.diff(t_s)))
    after = np.r_[False, np.diff(t_s) > GAP_PERIODS * period_s]
    skipped = _column(log, F_SKIPPED)
    if skipped is not None and np.isfinite(skipped).any():
        after |= np.r_[False, np.diff(np.nan_to_num(skipped, nan=0.0)) > 0]
    return after


def stalls(log, t_s: np.ndarray) -> np.ndarray:
    """Per cycle: the loop stalled after it (the next cycle line is the next cycle, no line lost, and it came after
    skipped deadlines): no command went out in between (prediction.firmware_stops)."""
    after = np.r_[after_skipped_deadlines(log, t_s)[1:], False]
    cycle = _column(log, F_CYCLE)
    if cycle is not None:
        after &= np.r_[np.diff(cycle) == 1, False]
    return after


def lost_stretches(log, t_s: np.ndarray, rows: slice) -> tuple:
    """(t_s before, t_s after) of each stretch of LOST_CYCLES or more cycle lines missing between two rows of
    ``rows`` (the ``cycle`` counter jumped: the daemon ran those cycles and sent their commands, but their lines
    never reached the file, a write failed or the file was cut), on the trial's time base (its first row at 0)."""
    cycle = _column(log, F_CYCLE)
    if cycle is None:
        return ()
    cycle, t = cycle[rows], t_s[rows]
    jumps = np.flatnonzero(np.isfinite(cycle[1:]) & np.isfinite(cycle[:-1]) & (np.diff(cycle) > LOST_CYCLES))
    return tuple((float(t[k] - t[0]), float(t[k + 1] - t[0])) for k in jumps)


def undelivered_stretches(log, t_s: np.ndarray, rows: slice) -> tuple:
    """(t_s of the last row before, of the first row after) of each stretch of ``rows`` whose commands the motors
    may not have had (``MissionLog.undelivered_rows``), on the trial's time base; a stretch at an end reaches a
    period past it (that end's part is then empty)."""
    bad, t = log.undelivered_rows()[rows], t_s[rows]
    if not bad.any():
        return ()
    period_s = float(np.median(np.diff(t))) if t.size > 1 else 0.1
    edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):
        before = t[a - 1] if a > 0 else t[0] - period_s
        after = t[b] if b < t.size else t[-1] + period_s
        out.append((float(before - t[0]), float(after - t[0])))
    return tuple(out)


def _fitted_modes(log) -> np.ndarray:
    from autopilot.review.reader import MODES

    return log.mode == MODES.index(MODE_FITTED)


def read_mission_log(path, *, curve: ThrustCurve | None = None) -> Trial:
    """A daemon mission log as a trial (rules in the module docstring)."""
    from autopilot.review.reader import check_mission_log, read_log

    log = read_log(check_mission_log(path), keep_reversals=True)  # a step back is refused below, naming its line
    starts = log.events_named("mission_start")
    if len(starts) > 1:  # logs joined with cat: each mission's clock starts again at 0
        raise ConfigError(f"{path}: {len(starts)} missions in one file (a mission_start line each): "
                          "give each mission's log as a file of its own, each is a trial")
    if log.n_cycles < MIN_SAMPLES:
        raise ConfigError(f"{path}: only {log.n_cycles} cycle lines (need {MIN_SAMPLES})")
    c = log.col
    t = c(F_TIME)
    auto = _fitted_modes(log)
    if not auto.any():
        raise ConfigError(f"{path}: no cycle in mode {MODE_FITTED!r} (the boat never steered): nothing to fit")
    first, last = np.flatnonzero(auto)[[0, -1]]
    keep = slice(first, last + 1)
    exclude = (~auto | after_skipped_deadlines(log, t))[keep]
    try:
        trial = make_trial(
            Path(path).stem, t[keep],
            north_m=c(F_NORTH)[keep], east_m=c(F_EAST)[keep], heading_deg=log.compass_heading_deg()[keep],
            position_time_s=(t - c(F_POSITION_AGE))[keep], heading_time_s=(t - c(F_HEADING_AGE))[keep],
            thrust_port_n=c(F_THRUST_PORT)[keep], thrust_stbd_n=c(F_THRUST_STBD)[keep],
            exclude=exclude, stalled_after=stalls(log, t)[keep], sog_m_s=c(F_SOG)[keep], cog_deg=c(F_COG)[keep], rot_deg_s=c(F_RATE)[keep],
            curve=curve, commands_held=True, row_name=lambda i: _line_name(log, first + i), wall_clock=False,
        )
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from exc
    trial.counts["cut_not_auto_rows"] = int(log.n_cycles - (last + 1 - first))
    lost = lost_stretches(log, t, keep)
    if lost:
        trial = dataclasses.replace(trial, lost_s=lost)
    undelivered = undelivered_stretches(log, t, keep)
    if undelivered:
        trial = dataclasses.replace(trial, undelivered_s=undelivered)
    notes = []
    if log.stats.skipped:  # review said so of a damaged log; the identification said nothing
        trial.counts["log_lines_skipped"] = int(log.stats.skipped)
        notes += [s for s in log.stats.describe()[1:] if "skipped" in s or s.startswith("first")]
    start = log.start or {}
    if start.get("sim") is True and start.get("speedup") != "max":
        # a Quick-start log (--speedup 10) on a loaded machine gave a spurious yaw_damping_quadratic, written into
        # vessel-updated.yaml; the same mission at --speedup max gave fix_delay alone, the simulator's own
        notes.append(f"flown by autopilot run --sim at --speedup {start.get('speedup')} (the wall clock): the "
                     "simulator's timing jitter can be fitted as an effect; identify from --speedup max logs (lockstep)")
    if notes:
        trial = dataclasses.replace(trial, read_notes=tuple(notes))
    return trial


def _line_name(log, row: int) -> str:
    """A cycle row as an editor finds it: the file's line number (a count of cycle lines missed the header and
    the event lines: "cycle line 200" was line 206)."""
    lines = log.line_numbers
    return f"line {int(lines[row])}" if lines is not None and row < len(lines) else f"cycle line {row + 1}"
