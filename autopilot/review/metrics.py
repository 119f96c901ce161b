"""Scorecard of one mission, computed from the columns of a :class:`MissionLog`.

Pure numbers: no I/O, no plotting. Quantities are recomputed from the
recorded positions and the mission's legs where possible rather than taken
from what the daemon logged about itself (its ``xte_m`` and
``closest_approach_m`` are shown beside the recomputed values).

Time integrals treat each cycle's command as held until the next cycle
(zero-order hold, as the thrusters see it); a gap in the log longer than
``GAP_FACTOR`` nominal periods is not integrated over (nothing is known
about it) and is reported as log-gap time.

Station keeping is scored over the hold proper, as ``autopilot evaluate``
scores it (``autopilot.evaluate.HoldScore``): not while it only closes on the point, the last
``gnc.hold.approach_m`` of a return to launch or of the mission's way to a
hold item (autopilot/gnc/modes.py ``Closing``). The log has no flag for that,
so it is told by the mode: ``hold`` and ``paused`` hold; ``auto`` holds at a
point once the waypoint there was reached (a hold item); ``rtl``, and ``auto``
before that, close on it.

Traffic (issue 18) is scored per AIS target by :func:`autopilot.traffic.score.score_target`,
the scorer of ``autopilot evaluate --traffic``, on what the log recorded: own
positions at the fixes, the target's reported track interpolated to the fix
times, its situation and whether the boat acted for it from the ``encounter``
lines, avoidance's share of psi_d from the cycles (:func:`target_reviews`).
The stretches where avoidance changed the course or speed are
:class:`Manoeuvre` s (:func:`manoeuvres`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from autopilot.gnc.encounter import EncounterConfig
from autopilot.gnc.passes import closest_per_pass
from autopilot.logschema import (
    FAILSAFE_CAUSE_PREFIX,
    RTL_ARRIVED_CAUSE,
    TIME_STOP_CAUSE,
    Mode,
    started_at_words,
    time_stop_words,
)
from autopilot.review.reader import MODES, SITUATIONS, UNKNOWN_CODE, MissionLog, Plan, TargetTrack, _is_number
from autopilot.traffic.score import score_target

GAP_FACTOR = 5.0  # dt above this many nominal periods is a hole in the log
# speed over ground below this is a receiver's noise at rest, not distance run: 0.05 m/s of velocity noise is
# above it in 1 % of fixes; 0.3 m/s (the course's threshold) dropped a boat drifting 28 m at 0.28 m/s
AT_REST_SOG_M_S = 0.15
LATENESS_PERCENTILES = (50.0, 90.0, 99.0, 99.9)
HOLD_POINT_TOLERANCE_M = 1e-3  # logged hold points closer than this are one point (the daemon logs the target's own floats)
HOLD_ERROR_PERCENTILE = 95.0  # the hold's achieved radius: this percentile of hold_error_m over its cycles
UNKNOWN_MODE = "unknown"  # mode_time_s key of cycles whose mode is missing or not in the schema
SIDE_TOLERANCE_DEG = 1.0  # a manoeuvre whose share of psi_d never exceeds this was a change of speed only
MAX_LEG_ROWS = 20  # per-leg cross-track rows in the summary table; summary.json has every leg


@dataclass
class WaypointScore:
    index: int
    north_m: float
    east_m: float
    reached: bool
    closest_approach_m: float  # recomputed from the fixes over the pass (NaN if never steered to / no data)
    closest_t_s: float  # when that fix was measured
    closest_north_m: float
    closest_east_m: float
    logged_closest_approach_m: float  # from waypoint_reached (NaN if absent)
    mission: int = 1  # the plan it belongs to (MissionLog.plans: 1 is mission_start's)
    label: str = ""  # W3, or M2 W3 in a log of several missions
    in_hole: bool = False  # steering moved past it inside a hole in the log: whether and how near, unknown

    def __post_init__(self) -> None:
        if not self.label:
            self.label = f"W{self.index}"


@dataclass
class LegScore:
    """Cross-track error over one leg: the track from the waypoint before (leg 0: from the start) to ``index``.

    Its cycles are those of :func:`cross_track_scores`' selection steering to the waypoint (``wp_index``) in the
    plan's time: in ``auto``, not holding at a point. The recomputed error is over their fixes, the logged over
    the leg's ``auto`` cycles with ``xte_m`` (as the run's logged figure); both NaN (never 0) without samples.
    """

    index: int  # the waypoint the leg ends at
    label: str  # "start->W0", "W0->W1"; "M2 W0->W1" in a log of several missions
    mission: int  # the plan it belongs to (MissionLog.plans)
    cycles: int
    time_s: float  # the cycles' durations (:func:`hold_durations_s`)
    fixes: int  # the samples of the recomputed error
    xte_rms_m: float
    xte_max_m: float
    logged_cycles: int  # the samples of the logged error (cycles with xte_m)
    logged_xte_rms_m: float
    logged_xte_max_m: float


@dataclass
class HoldStats:
    """Station keeping at one point of the log (every stretch at that point together)."""

    number: int  # 1, 2, ... in order of first appearance (the track plot's "hold 2")
    north_m: float
    east_m: float
    first_t_s: float  # first cycle at the point, closing included
    hold_s: float  # time of the hold proper
    closing_s: float  # time station keeping only closed on the point
    cycles: int  # cycles of the hold proper
    error_rms_m: float  # of hold_error_m over those cycles (NaN: never held proper)
    error_p95_m: float
    error_max_m: float
    energy_n_s: float  # (|T_port| + |T_stbd|) dt over the hold proper
    modes: list  # the modes it held in ("auto": a hold item; "hold", "paused")


@dataclass
class TargetReview:
    """One AIS target: what it was, how close it came, what the boat did about it (module docstring).

    The closest approach is recomputed from the log (own fixes against the target's reports interpolated
    to the fix times, linear in between, as ``autopilot.traffic.score.closest_approach`` takes it); NaN when
    the two were never both known at once. ``logged_min_range_m`` is the daemon's own smallest range to it
    (``avoid_range_m`` while it was the target most at risk, and the ``encounter`` lines' ``range_m``),
    from the dead-reckoned AIS picture it steered by.

    ``required_m`` is ``gnc.avoidance.safe_distance_m`` (mission_start's config) plus the target's extent.
    The daemon adds ``TargetState.extent_m``, the farthest hull point from the reported position (AIS
    to_bow / to_stern / to_port / to_starboard), which the log does not carry: it is approximated here by
    half the reported length, exact for a reference point amidships (the simulated traffic) and an
    underestimate otherwise, and taken as 0 without a length (as the daemon takes unknown dimensions).
    NaN, and ``distance_kept`` None, when the log does not state the safe distance.
    """

    target: int  # MMSI
    name: str | None
    length_m: float | None
    reports: int  # `target` lines used
    first_report_t_s: float
    last_report_t_s: float
    situations: list  # every situation it was in, in order of first appearance ("safe" among them)
    situation: str  # the first other than "safe": what the rules are judged by ("safe" if none)
    closest_m: float
    closest_t_s: float
    own_north_m: float  # both positions at the closest approach (for the map)
    own_east_m: float
    target_north_m: float
    target_east_m: float
    logged_min_range_m: float
    required_m: float
    distance_kept: bool | None
    acted: bool
    first_action_t_s: float | None  # the first encounter line acting for it (else the first such fix)
    side: str | None  # "starboard" / "port": the sign of avoid_psi_share_deg while acting for it
    max_alteration_deg: float  # largest |avoid_psi_share_deg| while acting for it
    rule_followed: bool
    note: str

    @property
    def label(self) -> str:
        return self.name or str(self.target)


@dataclass
class Manoeuvre:
    """A stretch of cycles with ``avoid_active``: collision avoidance changed the course or the speed.

    It ends at the first cycle without it (the mission's course given back), at a hole in the log or at
    the log's end; positions are the fixes the daemon held at its first and last cycle.
    """

    number: int  # 1, 2, ... in time order (the track plot's and the table's "A1")
    start_t_s: float
    end_t_s: float
    start_north_m: float
    start_east_m: float
    end_north_m: float
    end_east_m: float
    side: str | None  # "starboard" / "port" of the largest share of psi_d; None: speed only
    max_alteration_deg: float  # that share, signed (+ = starboard)
    min_speed_factor: float  # NaN when not logged
    targets: list  # MMSI(s) most at risk (avoid_target) during it, in order

    @property
    def duration_s(self) -> float:
        return self.end_t_s - self.start_t_s


@dataclass
class Scorecard:
    name: str
    path: str
    cycles: int
    mission_time_s: float
    distance_m: float
    thrust_energy_n_s: float
    thrust_unknown_s: float
    xte_rms_m: float
    xte_max_m: float
    logged_xte_rms_m: float
    logged_xte_max_m: float
    heading_lost_s: float  # no compass heading: none at all, or the course over ground steered on (cog_fallback)
    heading_stale_s: float
    position_lost_s: float
    position_stale_s: float
    log_gap_s: float
    failsafe_time_s: float
    failsafes: list  # [(t_s, cause)]
    faults: dict  # cause -> {"count": n, "time_s": s}
    nmea_dropped: float
    ack_missing: float
    lateness_ms: dict  # "p50" ... "max" -> ms
    stop_reason: str | None
    complete: bool  # the route was complete (a mission_complete line): every waypoint reached or passed, the last's hold item over
    # the run ended on its own (stop reason "complete"); a route complete but not finished was stopped by a signal (or
    # killed) in what follows the route: the final hold, the way home of an rtl
    finished: bool = False
    stop_signal: str | None = None
    end_mode: str | None = None  # the mode of the last cycle
    waypoints: list = field(default_factory=list)  # [WaypointScore]
    skipped_lines: int = 0
    read_notes: list = field(default_factory=list)
    mode_time_s: dict = field(default_factory=dict)  # every schema mode (0 when absent), "unknown" if any
    holds: list = field(default_factory=list)  # [HoldStats]; empty when the log has no hold point
    battery_v: dict = field(default_factory=dict)  # "min", "max" under load; empty when not logged
    battery_rest_v: dict = field(default_factory=dict)  # "min", "max" of the resting estimate; empty when not logged
    targets: list = field(default_factory=list)  # [TargetReview]; empty when the log has no `target` lines
    manoeuvres: list = field(default_factory=list)  # [Manoeuvre]
    avoidance_s: float = math.nan  # time avoidance changed the course or speed (NaN: avoidance not logged)
    gps_jumps_refused: int = 0  # position_jump lines: fixes refused as glitches
    gps_jumps_reanchored: int = 0  # and re-anchorings (two far fixes agreed)
    missions: list = field(default_factory=list)  # one per plan when the mission was replaced: number, from_t_s, source, waypoints
    heading_stale_after_s: float = math.nan  # the ages above which a sample counted stale (stale_limits_s)
    speedup: str = ""  # mission_start's --speedup when not real time ("10", "max"): the log's times are simulated
    # deadlines the loop skipped, more than a period behind (the cycles' skipped_cycles and the stop line's; NaN: not
    # logged). The daemon's summary said 25 for a 20x run whose report showed only "gaps in the log 0.0 s" (an audit)
    skipped_cycles: float = math.nan
    start_index: int = 0  # the waypoint this run started at (mission_start's: a restart that carried a run on)
    position_stale_after_s: float = math.nan
    legs: list = field(default_factory=list)  # [LegScore], every plan's legs in order
    # max_mission_time's stop (its failsafe, action stop): when, the mode it stopped and since when the boat was in
    # it (the daemon stays up after it for a ground station or systemd: the signal that ends the run comes later)
    time_stop_t_s: float = math.nan  # NaN: no such stop
    time_stop_from_mode: str | None = None
    time_stop_from_mode_s: float = math.nan  # how long the boat had been in that mode then
    heading_on_course_s: float = 0.0  # of heading_lost_s: the course over ground steered on (failsafe.cog_fallback)

    def to_dict(self) -> dict:
        d = asdict(self)
        return _json_safe(d)

    def table_rows(self) -> list[tuple[str, str]]:
        """(label, value) rows for a human-readable summary table."""
        wp_reached = sum(w.reached for w in self.waypoints)
        in_hole = [w.label for w in self.waypoints if w.in_hole]
        # over the waypoints reached: a pass stopped short (a run ended by a signal, a skipped waypoint) once made a
        # stopped run look like it missed its waypoints by metres (a review audit: 5.47 / 20.24 m for 0.55 / 0.74)
        ca = [w.closest_approach_m for w in self.waypoints if w.reached and math.isfinite(w.closest_approach_m)]
        short = [w for w in self.waypoints if not w.reached and math.isfinite(w.closest_approach_m)]
        ca_text = f"{np.mean(ca):.2f} / {np.max(ca):.2f} m" if ca else "n/a"
        if short:
            ca_text += "; not reached: " + ", ".join(f"{w.label} {w.closest_approach_m:.2f} m" for w in short[:5]) + (
                f" and {len(short) - 5} more" if len(short) > 5 else "")
        lat = self.lateness_ms
        rows = [
            ("cycles", f"{self.cycles}"),
            ("mission time", _fmt_duration(self.mission_time_s)),
            ("distance run", _fmt(self.distance_m, "m", 1)),
            ("thrust energy (|T_port|+|T_stbd|) dt", _fmt(self.thrust_energy_n_s, "N s", 0)),
            *([("missions", "; ".join(
                f"M{m['number']}: {m['waypoints']} waypoint(s) "
                + ("from mission_start" if m["from_t_s"] is None else f"from {m['from_t_s']:.1f} s ({m['source'] or 'replaced'})")
                for m in self.missions))] if len(self.missions) > 1 else []),
            ("waypoints reached", f"{wp_reached} of {len(self.waypoints)}" + (
                # a restart that carried a run on: the waypoints before it were the earlier run's (it read "6 of 9"
                # beside "complete" for a run that flew its 6: a review audit)
                started_at_words(self.start_index)) + (
                f"; {len(in_hole)} passed in a hole in the log ({', '.join(in_hole[:5])}"
                + (", ..." if len(in_hole) > 5 else "") + "): not known" if in_hole else "")),
            ("closest approach of the waypoints reached, mean / max", ca_text),
            ("cross-track error RMS / max (recomputed)",
             f"{_fmt(self.xte_rms_m, 'm', 2)} / {_fmt(self.xte_max_m, 'm', 2)}"),
            ("cross-track error RMS / max (logged xte_m)",
             f"{_fmt(self.logged_xte_rms_m, 'm', 2)} / {_fmt(self.logged_xte_max_m, 'm', 2)}"),
            *self._leg_rows(),
            (f"heading lost / stale{_older_than(self.heading_stale_after_s)}",
             f"{_fmt(self.heading_lost_s, 's', 1)}" + (
                 f" ({_fmt(self.heading_on_course_s, 's', 1)} of it steered on the course over ground)"
                 if self.heading_on_course_s > 0 else "") + f" / {_fmt(self.heading_stale_s, 's', 1)}"),
            (f"position lost / stale{_older_than(self.position_stale_after_s)}",
             f"{_fmt(self.position_lost_s, 's', 1)} / {_fmt(self.position_stale_s, 's', 1)}"),
            ("gaps in the log", _fmt(self.log_gap_s, "s", 1)),
            ("failsafes", f"{len(self.failsafes)}" + (
                " (" + ", ".join(f"{c} at {t:.1f} s" for t, c in self.failsafes[:5])
                + (", ..." if len(self.failsafes) > 5 else "") + ")" if self.failsafes else "")),
            ("time in failsafe", _fmt(self.failsafe_time_s, "s", 1)),
            ("faults", ", ".join(f"{c} x{v['count']} ({v['time_s']:.1f} s)" for c, v in sorted(self.faults.items())) or "none"),
            ("dropped NMEA lines", _fmt_count(self.nmea_dropped)),
            ("missing Mbed acks", _fmt_count(self.ack_missing)),
            ("GPS jumps refused / re-anchored", f"{self.gps_jumps_refused} / {self.gps_jumps_reanchored}"),
            ("loop lateness p50 / p99 / max" + (f" (simulated ms: --speedup {self.speedup})" if self.speedup else ""),
             f"{_fmt(lat.get('p50'), 'ms', 2)} / {_fmt(lat.get('p99'), 'ms', 2)} / {_fmt(lat.get('max'), 'ms', 2)}"),
            ("deadlines skipped (the loop more than a period behind)", _fmt_count(self.skipped_cycles)),
            ("thrust unknown (not logged)", _fmt(self.thrust_unknown_s, "s", 1)),
            ("time per mode", ", ".join(f"{m} {v:.1f} s" for m, v in self.mode_time_s.items() if v > 0) or "n/a"),
            ("station keeping", _fmt_holds(self.holds)),
            ("battery under load, min / max", _fmt_range(self.battery_v, "V")),
            ("battery resting estimate, min / max", _fmt_range(self.battery_rest_v, "V")),
            *self._traffic_rows(),
            ("stop", self._stop_words()),
            ("log lines skipped", f"{self.skipped_lines}"),
        ]
        if self.cycles == 0:  # times over no cycles read "0.0 s", as a clean run's do (a review audit: an empty log)
            over_cycles = ("heading lost", "position lost", "gaps in the log", "time in failsafe", "dropped NMEA",
                           "missing Mbed acks", "loop lateness", "deadlines skipped", "thrust unknown")
            rows = [(label, "n/a (no cycles in the log)" if label.startswith(over_cycles) else value)
                    for label, value in rows]
        return rows


    def _stop_words(self) -> str:
        """How the run ended, in the daemon's end summary's words: a run stopped by a signal in its final hold said
        "mission complete" here where the daemon said "route complete" (a new-user audit)."""
        if self.stop_reason == "complete":
            return "complete: mission complete"
        if self.stop_reason == "failsafe":  # a campaign's replay ends a run there (logschema.STOP_REASONS)
            return (("route complete; then " if self.complete else "")
                    + "ended where a latched failsafe took the boat (a campaign's run)")
        if self.finished:  # stayed up after the mission's stop, for a ground station, until stopped
            return f"mission complete; then stopped by {self.stop_signal or self.stop_reason or 'a kill (no stop line)'}"
        how = self.stop_reason or "no stop line (killed?)"
        if self.stop_signal:
            how = f"stopped by {self.stop_signal}"
        if self.complete and self.time_stop_from_mode:
            # max_mission_time stopped what followed the route: "then in stop" left the final hold before it, 1560 s
            # of it, unsaid; the daemon may have stayed up after it at zero thrust until a signal
            words = f"route complete; {time_stop_words(self.time_stop_from_mode, self.time_stop_from_mode_s)}"
            if not self.stop_signal:
                return words
            after = "" if self.end_mode == Mode.STOP.value else f"then in {self.end_mode or 'an unknown mode'}, "
            return f"{words}; {after}{how}"
        if not self.complete and self.stop_signal and math.isfinite(self.time_stop_t_s):
            return f"stopped by {TIME_STOP_CAUSE}, then by {self.stop_signal}"  # the daemon's words
        if self.complete:
            return f"route complete; then in {self.end_mode or 'an unknown mode'}, {how}"
        return how

    def _leg_rows(self) -> list[tuple[str, str]]:
        """A row per leg (the first MAX_LEG_ROWS; the rest are in summary.json's ``legs``)."""
        rows = [(f"cross-track error, leg {leg.label}", _fmt_leg(leg)) for leg in self.legs[:MAX_LEG_ROWS]]
        if len(self.legs) > MAX_LEG_ROWS:
            rows.append(("cross-track error, more legs", f"{len(self.legs) - MAX_LEG_ROWS} (see summary.json)"))
        return rows

    def _traffic_rows(self) -> list[tuple[str, str]]:
        """Rows only for a log with traffic (a log without keeps its summary as it was)."""
        if not self.targets and not self.manoeuvres:
            return []
        rows = [("AIS targets", f"{len(self.targets)}" + (
            " (" + ", ".join(t.label for t in self.targets[:5]) + (", ..." if len(self.targets) > 5 else "") + ")"
            if self.targets else ""))]
        met = [t for t in self.targets if math.isfinite(t.closest_m)]
        if met:
            worst = min(met, key=lambda t: t.closest_m)
            rows.append(("closest approach to a target", f"{worst.closest_m:.1f} m ({worst.label} at "
                         f"{worst.closest_t_s:.1f} s" + (f", required {worst.required_m:.1f} m"
                                                         if math.isfinite(worst.required_m) else "") + ")"))
        rows.append(("avoidance manoeuvres", f"{len(self.manoeuvres)}, {_fmt(self.avoidance_s, 's', 1)} altered"))
        return rows


def _json_safe(x):
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, np.generic):
        return _json_safe(x.item())
    return x


def _fmt(x, unit: str, digits: int) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:.{digits}f} {unit}"


def _fmt_range(d: dict, unit: str) -> str:
    return f"{d['min']:.2f} / {d['max']:.2f} {unit}" if d else "n/a (not logged)"


def _fmt_holds(holds: list) -> str:
    if not holds:
        return "none"
    held = [h for h in holds if h.cycles]
    text = f"{len(holds)} point(s), {sum(h.hold_s for h in holds):.1f} s held"
    if held:
        text += "; p95 error " + ", ".join(f"hold {h.number}: {h.error_p95_m:.2f} m" for h in held[:5])
        text += ", ..." if len(held) > 5 else ""
    return text


def _fmt_leg(leg: LegScore) -> str:
    """"RMS 0.31 m, max 0.92 m over 41.0 s (41 fixes; logged xte_m 0.30 m / 0.88 m)"; n/a without samples."""
    if not leg.cycles:
        return "n/a (not flown)"
    text = (f"RMS {_fmt(leg.xte_rms_m, 'm', 2)}, max {_fmt(leg.xte_max_m, 'm', 2)}" if leg.fixes else "n/a (no fix)")
    text += f" over {leg.time_s:.1f} s"
    if leg.fixes or leg.logged_cycles:
        text += f" ({leg.fixes} fixes" + (f"; logged xte_m {_fmt(leg.logged_xte_rms_m, 'm', 2)} / "
                                          f"{_fmt(leg.logged_xte_max_m, 'm', 2)}" if leg.logged_cycles else "") + ")"
    return text


def _older_than(limit_s: float) -> str:
    return f" (older than {limit_s:g} s)" if math.isfinite(limit_s) else ""


def _fmt_count(x) -> str:
    return "n/a (not logged)" if x is None or not math.isfinite(x) else f"{int(x)}"


def _fmt_duration(t_s: float) -> str:
    if not math.isfinite(t_s):
        return "n/a"
    h, rem = divmod(t_s, 3600.0)
    m, s = divmod(rem, 60.0)
    return f"{t_s:.1f} s ({int(h)}:{int(m):02d}:{s:04.1f})"


def nominal_period_s(t_s: np.ndarray, nominal_dt_s: float | None = None) -> float:
    """The log's cycle period: the one given, else the median positive interval (0.1 s if none)."""
    if nominal_dt_s is not None and nominal_dt_s > 0:
        return float(nominal_dt_s)
    dt = np.diff(t_s)
    pos = dt[dt > 0]
    return float(np.median(pos)) if len(pos) else 0.1


def gap_after(t_s: np.ndarray, nominal_dt_s: float | None = None) -> np.ndarray:
    """True for each row followed by a hole in the log (more than GAP_FACTOR periods, or time going back)."""
    out = np.zeros(len(t_s), dtype=bool)
    if len(t_s) > 1:
        dt = np.diff(t_s)
        out[:-1] = (dt > GAP_FACTOR * nominal_period_s(t_s, nominal_dt_s)) | (dt < 0)
    return out


def hold_durations_s(t_s: np.ndarray, nominal_dt_s: float | None = None) -> tuple[np.ndarray, float]:
    """Duration each cycle's values hold (to the next cycle), and the log-gap time.

    The last cycle holds for one nominal period; intervals longer than
    ``GAP_FACTOR`` nominal periods (or negative) count as 0 and their
    length is returned as gap time.
    """
    n = len(t_s)
    if n == 0:
        return np.zeros(0), 0.0
    dt = np.diff(t_s)
    nominal_dt_s = nominal_period_s(t_s, nominal_dt_s)
    hold = np.empty(n)
    hold[:-1] = dt
    hold[-1] = nominal_dt_s
    gap = (hold > GAP_FACTOR * nominal_dt_s) | (hold < 0)
    gap_s = float(np.sum(hold[gap & (hold > 0)]))
    hold[gap] = 0.0
    return hold, gap_s


def leg_starts(wps: np.ndarray, first_ne_m) -> np.ndarray:
    """Start point of each leg: leg 0 from ``first_ne_m`` (the first position recorded under the plan), leg i
    from W_{i-1}."""
    return np.vstack([[first_ne_m], wps[:-1]]) if len(wps) else np.zeros((0, 2))


def _first_launch_ne_m(log: MissionLog, plan: Plan) -> tuple[float, float] | None:
    """(north, east) of the first ``launch`` event dated inside ``plan``: where the helm started leg 0. Not one
    carried over a restart (the interrupted run's: the helm starts a leg 0 flown again where the boat is)."""
    for ev in log.events_named("launch"):
        t, n, e = ev.get("t_s"), ev.get("north_m"), ev.get("east_m")
        if ev.get("carried") is True:
            continue
        if _is_number(t) and _is_number(n) and _is_number(e) and plan.holds(float(t)):
            return float(n), float(e)
    return None


def _first_steered_ne_m(log: MissionLog, seen: np.ndarray) -> tuple[float, float]:
    """Where the helm began leg 0 of a plan without a launch point (a mission replaced in flight): the position it
    steered by (``est_north_m``/``est_east_m``, the fix carried forward) on the plan's first cycle in ``auto``, else
    on its first cycle with a position (``seen``). Taken from the held fix, a leg 0 uploaded at 10x began 0.9 m
    behind the guidance's and its cross-track RMS came out 3.61 m for the daemon's 3.17 m (a review audit)."""
    n, e = log.col("north_m"), log.col("east_m")
    en, ee = log.col("est_north_m"), log.col("est_east_m")
    steered = seen & (log.mode == MODES.index("auto"))
    k0 = int(np.argmax(steered)) if steered.any() else int(np.argmax(seen))
    if np.isfinite(en[k0]) and np.isfinite(ee[k0]):
        return float(en[k0]), float(ee[k0])
    return float(n[k0]), float(e[k0])


def cross_track_m(log: MissionLog) -> np.ndarray:
    """Signed cross-track error (+ = starboard of the leg) per row from positions and legs; NaN when unknown.

    Each row is judged on the legs of the plan in force then (:attr:`MissionLog.plans`); leg 0 of a plan runs
    from where the helm started it, the plan's launch point (a new-user audit: from the first fix, taken while the
    daemon waited for valid data, a pond run's RMS was 3.25 m against the guidance's and the campaign's 2.38 m),
    else from where it steered on the plan's first cycle in auto (a mission replaced in flight:
    :func:`_first_steered_ne_m`). The scorecard takes it
    at the rows where a fix first appears (a held fix is not a new measurement).
    """
    t, n, e, idx = log.col("t_s"), log.col("north_m"), log.col("east_m"), log.col("wp_index")
    out = np.full(len(n), np.nan)
    for plan in log.plans:
        wps = plan.waypoints_ne_m
        if len(wps) == 0:
            continue
        mine = plan.holds(t)
        seen = mine & np.isfinite(n) & np.isfinite(e)
        if not seen.any():
            continue
        ok = seen & np.isfinite(idx) & (idx >= 0) & (idx < len(wps))
        i = idx[ok].astype(int)
        a = leg_starts(wps, _first_launch_ne_m(log, plan) or _first_steered_ne_m(log, seen))[i]
        b = wps[i]
        d = b - a
        length = np.hypot(d[:, 0], d[:, 1])
        length = np.where(length > 1e-9, length, np.nan)  # a zero-length leg has no direction
        pn, pe = n[ok] - a[:, 0], e[ok] - a[:, 1]
        out[ok] = (d[:, 0] * pe - d[:, 1] * pn) / length
    return out


def leg_of_rows(log: MissionLog) -> np.ndarray:
    """Per cycle: the leg it steered on, an index into every plan's legs in order (plan 1's W0, W1, ..., then plan
    2's); -1 without one (no ``wp_index``, or one the plan in force has not). The rows :func:`cross_track_m` judges."""
    t, idx = log.col("t_s"), log.col("wp_index")
    out = np.full(len(t), -1, dtype=np.int64)
    first = 0
    for plan in log.plans:
        count = len(plan.waypoints_ne_m)
        ok = plan.holds(t) & np.isfinite(idx) & (idx >= 0) & (idx < count)
        out[ok] = first + idx[ok].astype(np.int64)
        first += count
    return out


def cross_track_scores(log: MissionLog, cycle_s: np.ndarray) -> tuple[tuple[float, float], tuple[float, float], list]:
    """The run's cross-track error, recomputed and logged (RMS, max each), and each leg's (:class:`LegScore`).

    One selection for the run and its legs, so the run's RMS is its legs' combined, weighted by their samples.
    The legs are judged in ``auto``, not at a hold item's point (station keeping, scored in its own rows; the
    daemon logs no ``xte_m`` there either); a log whose cycles state no mode at all: every cycle. A log with
    modes but never in auto (a held start) has no tracking to score. Recomputed: at the fixes (each measured
    once: a held fix is not a new measurement); logged: every such cycle's ``xte_m`` (the run's also those
    without a leg). ``cycle_s`` is each cycle's duration (:func:`hold_durations_s`).
    """
    t = log.col("t_s")
    in_auto = log.mode == MODES.index("auto")
    if not np.any(log.mode != UNKNOWN_CODE):
        in_auto = np.ones(len(t), dtype=bool)
    leg = leg_of_rows(log)
    n_legs = sum(len(plan.waypoints_ne_m) for plan in log.plans)
    # station keeping closing on a point that is not the leg's end (back to a hold item left for a pause, the route
    # already on the next leg) is not tracking that leg: its distance from the leg's line was counted in it
    ends = np.array([wp for plan in log.plans for wp in plan.waypoints_ne_m] or [(math.nan, math.nan)], dtype=float)
    hn, he = log.col("hold_north_m"), log.col("hold_east_m")
    end = ends[np.clip(leg, 0, None)]
    elsewhere = (np.isfinite(hn) & np.isfinite(he) & (leg >= 0)
                 & (np.hypot(hn - end[:, 0], he - end[:, 1]) > HOLD_POINT_TOLERANCE_M))
    on_leg = in_auto & ~holding_proper(log) & ~elsewhere
    fix = np.zeros(len(t), dtype=bool)
    fix[log.fix_rows()[0]] = True
    xte, logged = cross_track_m(log), log.col("xte_m")
    sample = on_leg & fix & np.isfinite(xte)  # a finite xte has a leg (leg_of_rows)
    logged_sample = in_auto & np.isfinite(logged)

    def per_leg(rows, values):  # samples, RMS and max of |values| per leg, over the rows with a leg
        rows = rows & (leg >= 0)
        count = np.bincount(leg[rows], minlength=n_legs)
        sum_sq = np.bincount(leg[rows], weights=values[rows] ** 2, minlength=n_legs)
        peak = np.full(n_legs, -np.inf)
        np.maximum.at(peak, leg[rows], np.abs(values[rows]))
        with np.errstate(invalid="ignore", divide="ignore"):
            return count, np.where(count > 0, np.sqrt(sum_sq / count), np.nan), np.where(count > 0, peak, np.nan)

    flown = on_leg & (leg >= 0)
    cycles = np.bincount(leg[flown], minlength=n_legs)
    time_s = np.bincount(leg[flown], weights=cycle_s[flown], minlength=n_legs)
    fixes, rms, peak = per_leg(sample, xte)
    logged_n, logged_rms, logged_peak = per_leg(logged_sample, logged)
    several = len(log.plans) > 1
    legs, k = [], 0
    for plan in log.plans:
        prefix = f"M{plan.number} " if several else ""
        for i in range(len(plan.waypoints_ne_m)):
            legs.append(LegScore(
                index=i, label=prefix + ("start" if i == 0 else f"W{i - 1}") + f"->W{i}", mission=plan.number,
                cycles=int(cycles[k]), time_s=float(time_s[k]), fixes=int(fixes[k]), xte_rms_m=float(rms[k]),
                xte_max_m=float(peak[k]), logged_cycles=int(logged_n[k]), logged_xte_rms_m=float(logged_rms[k]),
                logged_xte_max_m=float(logged_peak[k])))
            k += 1
    return _rms_max(xte[sample]), _rms_max(logged[logged_sample]), legs


def time_stop(log: MissionLog) -> tuple[float, str | None, float]:
    """(when, the mode it stopped, how long the boat had been in that mode then) of max_mission_time's stop: its
    ``failsafe`` line with action stop; (NaN, None, NaN) without one.

    The mode is the ``from`` of the stop's own ``mode`` line, else the last cycle's before it. Since when: the
    first of the ``mode`` lines into it that lead up to the stop, else the first cycle of the run of that mode up
    to it (control's start in ``auto`` has no ``mode`` line).
    """
    cause = TIME_STOP_CAUSE
    when = next((float(ev["t_s"]) for ev in log.events_named("failsafe")
                 if ev.get("cause") == cause and ev.get("action") == Mode.STOP.value and _is_number(ev.get("t_s"))), None)
    if when is None:
        return math.nan, None, math.nan
    changes = sorted((float(ev["t_s"]), k, ev) for k, ev in enumerate(log.events_named("mode")) if _is_number(ev.get("t_s")))
    own = next((ev for at, _, ev in changes if at == when and ev.get("cause") == FAILSAFE_CAUSE_PREFIX + cause), {})
    t = log.col("t_s")
    before = np.nonzero(t < when)[0]
    mode = own.get("from")
    if mode not in MODES:
        code = int(log.mode[before[-1]]) if len(before) else UNKNOWN_CODE
        mode = MODES[code] if 0 <= code < len(MODES) else None
    if mode is None:
        return when, None, math.nan
    since = math.nan
    for at, _, ev in changes:
        if at >= when:
            break
        since = (since if math.isfinite(since) else at) if ev.get("mode") == mode else math.nan
    if not math.isfinite(since) and len(before):
        other = np.nonzero(log.mode[before] != MODES.index(mode))[0]
        first = int(other[-1]) + 1 if len(other) else 0
        since = float(t[before[first]]) if first < len(before) else math.nan
    return when, mode, when - since


def _logged_passes(log: MissionLog, plan: Plan) -> tuple[set, dict]:
    """Waypoints of ``plan`` the daemon reported reached, and the closest approach it logged per waypoint.

    ``waypoint_pass`` events carry the closest approach over the pass; logs written before
    them carried a ``closest_approach_m`` in ``waypoint_reached`` (the guidance's own figure).
    A replacement's passes close after the replacement (its ``mission_replaced`` line, then theirs).
    """
    reached, logged = set(), {}
    replaced = 0  # mission_replaced lines so far in the file: where an undated line falls
    for ev in log.events:
        name = ev.get("event")
        if name == "mission_replaced" and isinstance(ev.get("waypoints"), list) and _is_number(ev.get("t_s")):
            replaced += 1  # as MissionLog.plans counts them
        if name not in ("waypoint_reached", "waypoint_pass"):
            continue
        i = ev.get("wp_index")
        if not isinstance(i, int) or isinstance(i, bool):
            continue
        dated = _is_number(ev.get("t_s"))
        if (dated and not plan.holds(float(ev["t_s"]))) or (not dated and replaced != plan.number - 1):
            continue
        if ev.get("event") == "waypoint_reached":
            reached.add(i)
        ca = ev.get("closest_approach_m")
        if isinstance(ca, (int, float)) and not isinstance(ca, bool) and (ev.get("event") == "waypoint_pass" or i not in logged):
            logged[i] = float(ca)
    return reached, logged


def closest_approaches(log: MissionLog) -> list[WaypointScore]:
    """Closest approach to each waypoint over its pass, from the logged fixes (autopilot.gnc.passes); every
    plan's waypoints in order (:attr:`MissionLog.plans`), each over the fixes of its own time.

    The same definition the daemon logs in ``waypoint_pass``: fixes while steering to W_i
    and to W_{i+1}; the last waypoint's pass ends ``final_pass_s`` after mission_complete
    (fixes up to the ``waypoint_pass`` event that closed it, else to the end of the plan's time).
    """
    several = len(log.plans) > 1
    rows_all, fix_t_all = log.fix_rows()
    t, n, e, idx = log.col("t_s"), log.col("north_m"), log.col("east_m"), log.col("wp_index")
    out = []
    for plan in log.plans:
        wps = plan.waypoints_ne_m
        reached, logged = _logged_passes(log, plan)
        rows, fix_t = rows_all, fix_t_all
        ok = np.isfinite(n[rows]) & np.isfinite(e[rows]) & np.isfinite(idx[rows]) & plan.holds(t[rows])
        ends = [ev.get("t_s") for ev in log.events_named("waypoint_pass")
                if ev.get("wp_index") == len(wps) - 1 and _is_number(ev.get("t_s")) and plan.holds(float(ev["t_s"]))]
        if ends:  # the last pass was closed by the daemon: later fixes are not part of it
            ok &= t[rows] <= float(ends[0])
        rows, fix_t = rows[ok], fix_t[ok]
        start = int(idx[rows[0]]) if len(rows) else 0
        passes = closest_per_pass(fix_t, n[rows], e[rows], idx[rows].astype(int), wps,
                                  start_index=min(start, max(len(wps) - 1, 0)))
        hidden = _passed_in_holes(t, idx, plan) - reached
        out += [WaypointScore(i, float(wn), float(we), i in reached,
                              math.nan if i in hidden else p.closest_approach_m, p.t_s, p.north_m, p.east_m,
                              logged.get(i, math.nan), mission=plan.number, label=plan.label(i, several),
                              in_hole=i in hidden)
                for i, ((wn, we), p) in enumerate(zip(wps, passes))]
    return out


def _passed_in_holes(t: np.ndarray, idx: np.ndarray, plan: Plan) -> set:
    """Waypoints of ``plan`` the steering moved past inside a hole in the log (``wp_index`` before it, beyond it
    after). Their reaching and their pass's fixes are in the hole: a review of what is left once called two
    waypoints reached there "not reached", at 6.73 and 3.58 m for 0.17 and 0.34 m (a review audit)."""
    out: set = set()
    holes = np.nonzero(gap_after(t))[0]
    for k in holes:
        a, b = idx[k], idx[k + 1]
        if np.isfinite(a) and np.isfinite(b) and b > a and plan.holds(t[k]) and plan.holds(t[k + 1]):
            out.update(range(int(a), int(b)))
    return out


def _start_index(log: MissionLog) -> int:
    """mission_start's start_index when it is a waypoint of the mission, else 0."""
    k = (log.start or {}).get("start_index")
    n = len(log.plans[0].waypoints_ne_m) if log.plans else 0
    return k if isinstance(k, int) and not isinstance(k, bool) and 0 < k < n else 0


def _speedup_words(value) -> str:
    """mission_start's speedup as said beside a figure in its times: "" for real time (1) or none logged."""
    if isinstance(value, str):
        return value[:16]
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value != 1.0:
        return f"{value:g}"
    return ""


def _fault_times(log: MissionLog, t_end_s: float) -> dict:
    """cause -> count and time between fault and fault_cleared (or the end of the log)."""
    open_at: dict = {}
    out: dict = {}
    for ev in log.events:
        name, cause, t = ev.get("event"), ev.get("cause"), ev.get("t_s")
        if not isinstance(cause, str) or not isinstance(t, (int, float)):
            continue
        if name == "fault":
            rec = out.setdefault(cause, {"count": 0, "time_s": 0.0})
            rec["count"] += 1
            open_at.setdefault(cause, float(t))
        elif name == "fault_cleared" and cause in open_at:
            out[cause]["time_s"] += max(0.0, float(t) - open_at.pop(cause))
    for cause, t0 in open_at.items():
        out[cause]["time_s"] += max(0.0, t_end_s - t0)
    return out


def holding_proper(log: MissionLog) -> np.ndarray:
    """Per cycle: station keeping held its point (the hold proper), rather than closing on it (module docstring)."""
    t = log.col("t_s")
    hn, he = log.col("hold_north_m"), log.col("hold_east_m")
    at_point = np.isfinite(hn) & np.isfinite(he)
    flag = log.col("holding")
    if np.isfinite(flag).any():  # the daemon says so (logs since the `holding` field); older logs: inferred below
        return at_point & (flag > 0.5)
    mode = log.mode
    held = at_point & ((mode == MODES.index(Mode.HOLD.value)) | (mode == MODES.index(Mode.PAUSED.value)))
    in_auto = at_point & (mode == MODES.index(Mode.AUTO.value))
    reached = []  # (when, north, east) of each waypoint reached, in the plan in force then
    for ev in log.events_named("waypoint_reached"):
        i = ev.get("wp_index")
        if _is_number(ev.get("t_s")) and isinstance(i, int) and not isinstance(i, bool):
            wps = log.plan_at(float(ev["t_s"])).waypoints_ne_m
            if 0 <= i < len(wps):
                reached.append((float(ev["t_s"]), *wps[i]))
    if in_auto.any() and reached:
        reached.sort()
        when = np.array([r[0] for r in reached])
        where = np.array([r[1:] for r in reached])
        last = np.searchsorted(when, t, side="right") - 1  # the waypoint reached last, at or before each cycle
        ok = in_auto & (last >= 0)
        k = last[ok]
        held[ok] |= np.hypot(where[k, 0] - hn[ok], where[k, 1] - he[ok]) < HOLD_POINT_TOLERANCE_M
    return held


def hold_stats(log: MissionLog, cycle_s: np.ndarray) -> list[HoldStats]:
    """One :class:`HoldStats` per distinct hold point; ``cycle_s`` is each cycle's duration (:func:`hold_durations_s`)."""
    hn, he = log.col("hold_north_m"), log.col("hold_east_m")
    rows = np.nonzero(np.isfinite(hn) & np.isfinite(he))[0]
    if len(rows) == 0:
        return []
    key = np.round(np.column_stack([hn[rows], he[rows]]) / HOLD_POINT_TOLERANCE_M).astype(np.int64)
    _, first, point_of = np.unique(key, axis=0, return_index=True, return_inverse=True)
    point_of = point_of.ravel()
    proper = holding_proper(log)[rows]
    t, err = log.col("t_s"), log.col("hold_error_m")
    thrust = np.abs(log.col("thrust_port_n")) + np.abs(log.col("thrust_stbd_n"))
    out = []
    for number, p in enumerate(np.argsort(first), start=1):
        here = rows[point_of == p]
        held = here[proper[point_of == p]]
        e = err[held]
        e = e[np.isfinite(e)]
        known = held[np.isfinite(thrust[held])]
        out.append(HoldStats(
            number=number, north_m=float(hn[here[0]]), east_m=float(he[here[0]]), first_t_s=float(t[here[0]]),
            hold_s=float(np.sum(cycle_s[held])),
            closing_s=float(np.sum(cycle_s[here])) - float(np.sum(cycle_s[held])),
            cycles=len(held),
            error_rms_m=float(np.sqrt(np.mean(e * e))) if len(e) else math.nan,
            error_p95_m=float(np.percentile(e, HOLD_ERROR_PERCENTILE)) if len(e) else math.nan,
            error_max_m=float(np.max(e)) if len(e) else math.nan,
            energy_n_s=float(np.sum(thrust[known] * cycle_s[known])) if len(known) else math.nan,
            modes=[m for i, m in enumerate(MODES) if np.any(log.mode[held] == i)],
        ))
    return out


def mode_times_s(log: MissionLog, cycle_s: np.ndarray) -> dict:
    """Seconds per mode (each cycle's duration to its mode); every schema mode, "unknown" only when present.

    With the log-gap time they add up to the time the cycles cover: ``mission_time_s`` plus the
    last cycle's period.
    """
    out = {m: float(np.sum(cycle_s[log.mode == i])) for i, m in enumerate(MODES)}
    unknown = log.mode == UNKNOWN_CODE
    if unknown.any():
        out[UNKNOWN_MODE] = float(np.sum(cycle_s[unknown]))
    return out


def _min_max(x: np.ndarray) -> dict:
    x = x[np.isfinite(x)]
    return {"min": float(x.min()), "max": float(x.max())} if len(x) else {}


def _max_count(log: MissionLog, column: str, stop_key: str) -> float:
    values = log.col(column)
    best = float(np.nanmax(values)) if np.isfinite(values).any() else math.nan
    for ev in log.events_named("stop"):
        v = ev.get(stop_key)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            best = v if not math.isfinite(best) else max(best, float(v))
    return best


def _rms_max(x: np.ndarray) -> tuple[float, float]:
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return math.nan, math.nan
    return float(np.sqrt(np.mean(x * x))), float(np.max(np.abs(x)))


def stale_limits_s(log: MissionLog) -> tuple[float, float]:
    """(heading, position) age (s) above which the scorecard counts a sample stale: the daemon's own
    ``failsafe.heading_stale_s`` and ``position_stale_s`` as the log's configuration states them, else the
    daemon's defaults (the review once used 0.5 s and 2 s of its own and told 141.7 s of stale heading
    beside the daemon's 35 s of heading_stale faults)."""
    from autopilot.daemon.config import FailsafeConfig

    default = FailsafeConfig()
    heading = log.config_number("failsafe", "heading_stale_s")
    position = log.config_number("failsafe", "position_stale_s")
    return (heading if heading is not None and heading > 0 else default.heading_stale_s,
            position if position is not None and position > 0 else default.position_stale_s)


def distance_run_m(log: MissionLog, position_ok: np.ndarray, later: np.ndarray,
                   nominal_dt_s: float | None) -> tuple[float, str | None]:
    """The distance the boat ran (m) and, when it could not be measured so, how it was.

    The receiver's speed over ground as each cycle held it, integrated over the cycle's duration
    (:func:`hold_durations_s` over the cycles ``later`` than every one before: not across a hole in the log,
    and a block of lines written twice is not run twice), a speed below :data:`AT_REST_SOG_M_S` counted as
    rest (a receiver at rest reports a few cm/s of noise); only rows with a position (``position_ok``: a receiver without a fix has no speed
    either). Summing the steps between fixes added the GPS's wander:
    638 m for a boat held at its launch point for 20 min (89 m by speed over ground, all of it creeping under
    0.3 m/s), 44 m for a 36.6-m pond mission (36.7 m by speed over ground). A log without speed over ground:
    through the fixes, said so.
    """
    sog = log.col("sog_m_s")
    held = position_ok & np.isfinite(sog)
    if held.any():
        cycle_s = np.zeros(len(sog))
        cycle_s[later] = hold_durations_s(log.col("t_s")[later], nominal_dt_s)[0]
        moving = np.where(sog[held] >= AT_REST_SOG_M_S, sog[held], 0.0)
        return float(np.sum(moving * cycle_s[held])), None
    n, e = log.col("north_m")[position_ok], log.col("east_m")[position_ok]
    if len(n) < 2:
        return (0.0 if len(n) else math.nan), None
    return (float(np.sum(np.hypot(np.diff(n), np.diff(e)))),
            "distance run through the fixes (no speed over ground logged): it includes the GPS's wander")


def failsafe_cycles(log: MissionLog) -> np.ndarray:
    """Per cycle: the boat was under a failsafe's action. The ``failsafe`` mode (a stop), and a mode a failsafe
    took (``rtl``, ``hold``: its ``mode`` line's cause ``failsafe ...``) with the hand-overs of that action (rtl's
    hold at the launch point), until a mode line of anyone else (the operator's, the link's). Counting only the
    ``failsafe`` mode gave 0 s for a battery_low rtl that held at launch for 20 min."""
    t = log.col("t_s")
    under = log.mode == MODES.index("failsafe")
    changes = sorted((float(ev["t_s"]), str(ev.get("cause") or "")) for ev in log.events_named("mode")
                     if _is_number(ev.get("t_s")))
    since = None
    for when, cause in changes + [(math.inf, "")]:
        if since is not None and cause == RTL_ARRIVED_CAUSE and when < math.inf:
            continue  # the action's own hand-over: still the failsafe's
        if since is not None:
            under |= (t >= since) & (t < when)
            since = None
        if cause.startswith(FAILSAFE_CAUSE_PREFIX):
            since = when
    return under


def score(log: MissionLog) -> Scorecard:
    """Compute the scorecard of one mission."""
    stale_heading_s, stale_position_s = stale_limits_s(log)
    t = log.col("t_s")
    rate = (log.start or {}).get("rate_hz")
    nominal = 1.0 / rate if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate > 0 else None
    hold, gap_s = hold_durations_s(t, nominal)
    times = [float(ev["t_s"]) for ev in log.events if isinstance(ev.get("t_s"), (int, float))
             and not isinstance(ev.get("t_s"), bool) and math.isfinite(ev["t_s"])]
    # t_s counts from mission_start (docs/log-schema.md): the mission's time runs from it, as the daemon's
    # summary says it, to the last line (the first cycle comes a second or so later, once the sensors answer)
    t_first = 0.0 if log.start is not None else (float(t[0]) if len(t) else (min(times) if times else math.nan))
    if len(t) or times:
        t_end = float(t[-1]) if len(t) else max(times)
        mission_time = t_end - t_first
    else:
        mission_time, t_end = math.nan, 0.0

    n, e = log.col("north_m"), log.col("east_m")
    # only cycles later than every one before: a block of lines written twice (a copy glitch) added its jump back
    # and its second pass to the distance (67.7 m for a 43.3 m mission)
    with np.errstate(invalid="ignore"):
        later = t > np.maximum.accumulate(np.r_[-np.inf, t[:-1]]) if len(t) else np.zeros(0, dtype=bool)
    ok = np.isfinite(n) & np.isfinite(e) & later
    distance, distance_note = distance_run_m(log, ok, later, nominal)

    tp, ts = log.col("thrust_port_n"), log.col("thrust_stbd_n")
    known = np.isfinite(tp) & np.isfinite(ts)
    # (the reader makes a value beyond ABSURD a gap: a corrupt 1e308 N no longer overflows the sum)
    energy = float(np.sum((np.abs(tp[known]) + np.abs(ts[known])) * hold[known])) if known.any() else math.nan
    read_notes = log.stats.describe()
    starts = len(log.events_named("mission_start"))
    if starts > 1:  # logs joined with cat: one mission of twice the cycles, a jump back to the start in its distance
        read_notes.append(f"{starts} missions in one file (a mission_start line each): reviewed as one, the cycles "
                          "of a later one that restart its clock left out; give each mission's log as a file of its own")
    thrust_unknown = float(np.sum(hold[~known]))
    if distance_note:
        read_notes.append(distance_note)

    (xte_rms, xte_max), (lxte_rms, lxte_max), legs = cross_track_scores(log, hold)
    stop_t, stop_from, stop_from_s = time_stop(log)

    # the course over ground a cog_fallback steered on is no compass: counted lost, said apart (it looked like a
    # fresh heading, and a 6-s compass loss read "heading lost 0.1 s")
    heading = log.compass_heading_deg()
    on_course = np.isfinite(log.col("heading_deg")) & ~np.isfinite(heading)
    h_age = log.col("heading_age_s")
    p_age = log.col("position_age_s")
    fixq = log.col("fix_quality")
    heading_lost = ~np.isfinite(heading)
    position_lost = ~ok | (fixq == 0)
    heading_stale = ~heading_lost & (h_age > stale_heading_s)
    position_stale = ~position_lost & (p_age > stale_position_s)

    lat = log.col("lateness_ms")
    lat = lat[np.isfinite(lat)]
    lateness = {}
    if len(lat):
        for p in LATENESS_PERCENTILES:
            lateness[f"p{p:g}"] = float(np.percentile(lat, p))
        lateness["max"] = float(lat.max())
        lateness["mean"] = float(lat.mean())

    failsafes = [(float(ev.get("t_s")) if isinstance(ev.get("t_s"), (int, float)) else math.nan,
                  str(ev.get("cause")))
                 for ev in log.events_named("failsafe")]
    stops = log.events_named("stop")
    stop_reason = stops[-1].get("reason") if stops else None
    stop_signal = stops[-1].get("signal") if stops else None
    end_code = int(log.mode[-1]) if len(log.mode) else None
    end_mode = (MODES[end_code] if end_code is not None and 0 <= end_code < len(MODES)
                else UNKNOWN_MODE if end_code is not None else None)
    return Scorecard(
        name=log.name, path=str(log.path), cycles=log.n_cycles, mission_time_s=mission_time,
        distance_m=distance, thrust_energy_n_s=energy, thrust_unknown_s=thrust_unknown,
        xte_rms_m=xte_rms, xte_max_m=xte_max, logged_xte_rms_m=lxte_rms, logged_xte_max_m=lxte_max,
        heading_lost_s=float(np.sum(hold[heading_lost])), heading_on_course_s=float(np.sum(hold[on_course])),
        heading_stale_s=float(np.sum(hold[heading_stale])),
        position_lost_s=float(np.sum(hold[position_lost])),
        position_stale_s=float(np.sum(hold[position_stale])),
        log_gap_s=gap_s,
        failsafe_time_s=float(np.sum(hold[failsafe_cycles(log)])),
        failsafes=failsafes, faults=_fault_times(log, t_end),
        nmea_dropped=_max_count(log, "nmea_dropped", "nmea_dropped"),
        ack_missing=_max_count(log, "ack_missing", "ack_missing"),
        skipped_cycles=_max_count(log, "skipped_cycles", "skipped_cycles"),
        lateness_ms=lateness, stop_reason=stop_reason if isinstance(stop_reason, str) else None,
        speedup=_speedup_words((log.start or {}).get("speedup")),
        start_index=_start_index(log),
        # a run that stayed up after the mission's stop (a ground station link, systemd) ends by a signal in complete
        complete=bool(log.events_named("mission_complete")),
        finished=stop_reason == "complete" or (bool(log.events_named("mission_complete")) and end_mode == "complete"),
        stop_signal=stop_signal if isinstance(stop_signal, str) else None, end_mode=end_mode,
        waypoints=closest_approaches(log), skipped_lines=log.stats.skipped,
        read_notes=read_notes,
        mode_time_s=mode_times_s(log, hold), holds=hold_stats(log, hold),
        battery_v=_min_max(log.col("battery_v")), battery_rest_v=_min_max(log.col("battery_rest_v")),
        targets=target_reviews(log), manoeuvres=manoeuvres(log),
        avoidance_s=float(np.sum(hold[log.col("avoid_active") > 0.5])) if avoidance_logged(log) else math.nan,
        gps_jumps_refused=sum(ev.get("accepted") is False for ev in log.events_named("position_jump")),
        gps_jumps_reanchored=sum(ev.get("accepted") is True for ev in log.events_named("position_jump")),
        heading_stale_after_s=stale_heading_s, position_stale_after_s=stale_position_s,
        missions=[{"number": p.number, "from_t_s": p.from_t_s if math.isfinite(p.from_t_s) else None,
                   "source": p.source, "waypoints": len(p.waypoints_ne_m)} for p in log.plans] if len(log.plans) > 1 else [],
        legs=legs, time_stop_t_s=stop_t, time_stop_from_mode=stop_from, time_stop_from_mode_s=stop_from_s,
    )


def _acting_per_fix(log: MissionLog, mmsi: int, row_t: np.ndarray, rows: np.ndarray):
    """(situation, acting) of one target at the cycle times ``row_t`` (of the cycle ``rows``): the state of
    its latest ``encounter`` line at or before each, "safe" and not acting before the first. Logs without
    encounter lines for it: the cycle's worst target (``avoid_target``) fields where it was that target."""
    evs = [ev for ev in log.encounters if ev.target == mmsi]
    if evs:
        when = np.array([ev.t_s for ev in evs])
        k = np.searchsorted(when, row_t, side="right") - 1
        sit = np.array(["safe"] + [ev.situation for ev in evs], dtype=object)[k + 1]
        act = np.array([False] + [ev.acting for ev in evs])[k + 1]
        return list(sit), act
    worst = log.col("avoid_target")[rows] == mmsi
    codes = log.avoid_situation[rows]
    sit = [SITUATIONS[c] if w and c != UNKNOWN_CODE else "safe" for w, c in zip(worst, codes)]
    return sit, worst & (log.col("avoid_active")[rows] > 0.5)


def _situations_met(log: MissionLog, mmsi: int, sampled: list) -> list:
    """Every situation in order of first appearance: from the encounter lines (every change, however
    short), else as sampled at the fixes."""
    seen: list = []
    for s in [ev.situation for ev in log.encounters if ev.target == mmsi] or sampled:
        if s not in seen:
            seen.append(s)
    return seen


def _logged_min_range_m(log: MissionLog, mmsi: int) -> float:
    r = log.col("avoid_range_m")[log.col("avoid_target") == mmsi]
    r = np.concatenate([r, [ev.range_m for ev in log.encounters if ev.target == mmsi]])
    r = r[np.isfinite(r)]
    return float(r.min()) if len(r) else math.nan


def target_review(log: MissionLog, track: TargetTrack) -> TargetReview:
    """The :class:`TargetReview` of one target (its docstring and the module's)."""
    rows, fix_t = log.fix_rows()
    n, e = log.col("north_m")[rows], log.col("east_m")[rows]
    own_ok = np.isfinite(n) & np.isfinite(e)
    rows, fix_t, n, e = rows[own_ok], fix_t[own_ok], n[own_ok], e[own_ok]
    tn, te = track.position_at(fix_t)
    both = np.isfinite(tn) & np.isfinite(te)  # own fixes inside the target's reported span
    rows, fix_t, n, e, tn, te = rows[both], fix_t[both], n[both], e[both], tn[both], te[both]
    sit, act = _acting_per_fix(log, track.target, log.col("t_s")[rows], rows)
    share = np.radians(np.nan_to_num(log.col("avoid_psi_share_deg")[rows], nan=0.0))
    safe_m = log.config_number("gnc", "avoidance", "safe_distance_m")
    extent_m = 0.5 * track.length_m if track.length_m is not None else 0.0
    required = safe_m + extent_m if safe_m is not None else math.nan
    first_act = next((ev.t_s for ev in log.encounters if ev.target == track.target and ev.acting), None)
    common = dict(target=track.target, name=track.name, length_m=track.length_m, reports=len(track.t_s),
                  first_report_t_s=float(track.t_s[0]), last_report_t_s=float(track.t_s[-1]),
                  logged_min_range_m=_logged_min_range_m(log, track.target), required_m=required)
    if len(fix_t) == 0:  # never both known at once: nothing to score
        met = _situations_met(log, track.target, [])
        return TargetReview(**common, situations=met, situation=next((s for s in met if s != "safe"), "safe"),
                            closest_m=math.nan, closest_t_s=math.nan, own_north_m=math.nan, own_east_m=math.nan,
                            target_north_m=math.nan, target_east_m=math.nan, distance_kept=None,
                            acted=first_act is not None, first_action_t_s=first_act, side=None,
                            max_alteration_deg=math.nan, rule_followed=True, note="never known at the same time as own ship")
    # unknown safe distance: judged against 0 (no "distance not kept" verdict), reported as NaN
    sc = score_target(track.target, fix_t, n, e, tn, te, situation=sit, acting=act, psi_share_rad=share,
                      required_m=required if math.isfinite(required) else 0.0)
    t_min = sc.t_min_s
    ptn, pte = track.position_at([t_min])
    note = sc.note
    silent = _silent_while_closing(log, track, fix_t, n, e, tn, te)
    if silent:
        note = f"{note}; {silent}" if note else silent
    kept = sc.distance_kept if math.isfinite(required) else None
    if silent and kept:  # kept while it reported; how close it came after is not known (an audit: "kept" said)
        kept = None
    return TargetReview(
        **common, situations=_situations_met(log, track.target, list(sc.situations)), situation=sc.situation,
        closest_m=sc.min_distance_m, closest_t_s=t_min,
        own_north_m=float(np.interp(t_min, fix_t, n)), own_east_m=float(np.interp(t_min, fix_t, e)),
        target_north_m=float(ptn[0]), target_east_m=float(pte[0]),
        distance_kept=kept,
        acted=sc.acted or first_act is not None, first_action_t_s=first_act if first_act is not None else sc.first_action_t_s,
        side=sc.side, max_alteration_deg=sc.max_alteration_deg, rule_followed=sc.rule_followed, note=note,
    )


SILENT_AFTER_S = 30.0  # a target under way reports every 2-10 s (ITU-R M.1371, class A): three lost reports and more


def _silent_while_closing(log: MissionLog, track: TargetTrack, fix_t, n, e, tn, te) -> str | None:
    """What to say when the target's reports stopped well before the log's end while it was closing in: its closest
    approach after the last report is not in the log (the closest figure is only that of its reported span)."""
    end_t = float(log.col("t_s")[-1]) if len(log.col("t_s")) else math.nan
    last_t = float(track.t_s[-1])
    usual_s = float(np.median(np.diff(track.t_s))) if len(track.t_s) > 2 else 0.0
    # a ship slower than the avoidance's "stationary" (the log's setting) reports every 3 min and stays where it was
    stationary = log.config_number("gnc", "avoidance", "encounter", "stationary_speed_m_s")
    under_way = track.speed_m_s[-1] > (EncounterConfig().stationary_speed_m_s if stationary is None else stationary)
    if not (under_way and end_t - last_t > max(SILENT_AFTER_S, 3.0 * usual_s)) or len(fix_t) < 2:
        return None
    d = np.hypot(tn - n, te - e)
    k = len(d) - 1
    j = int(np.searchsorted(fix_t, fix_t[k] - 5.0))  # the range ~5 s before the last known one
    if j >= k or not d[k] < d[j]:
        return None
    rate = (d[j] - d[k]) / (fix_t[k] - fix_t[j])
    return (f"its reports stopped {end_t - last_t:.0f} s before the log ended, {d[k]:.0f} m away and closing at "
            f"{rate:.1f} m/s: how close it came after that is not in the log")


def target_reviews(log: MissionLog) -> list[TargetReview]:
    """One :class:`TargetReview` per target of the log, in order of first report (empty without targets)."""
    return [target_review(log, track) for track in log.targets.values()]


def manoeuvres(log: MissionLog) -> list[Manoeuvre]:
    """The stretches with ``avoid_active`` (:class:`Manoeuvre`), in time order."""
    t = log.col("t_s")
    active = log.col("avoid_active") > 0.5
    if not active.any():
        return []
    holes = gap_after(t)
    edge = np.diff(active.astype(np.int8), prepend=0, append=0)
    starts = list(np.nonzero(edge == 1)[0])
    ends = list(np.nonzero(edge == -1)[0] - 1)  # last active row of each run
    runs = []
    for a, b in zip(starts, ends):  # a hole in the log ends a run: nothing is known inside it
        cut = a + np.nonzero(holes[a:b])[0]
        for c in cut:
            runs.append((a, int(c)))
            a = int(c) + 1
        runs.append((a, b))
    n, e = log.col("north_m"), log.col("east_m")
    share, factor, worst = log.col("avoid_psi_share_deg"), log.col("avoid_speed_factor"), log.col("avoid_target")
    out = []
    for number, (a, b) in enumerate(runs, start=1):
        end = b + 1 if b + 1 < len(t) and not holes[b] else b  # the cycle that gave the course back
        sh = share[a : b + 1]
        sh = sh[np.isfinite(sh)]
        k = int(np.argmax(np.abs(sh))) if len(sh) else None
        big = k is not None and abs(sh[k]) > SIDE_TOLERANCE_DEG
        f = factor[a : b + 1]
        ids: list = []
        for m in worst[a : b + 1][np.isfinite(worst[a : b + 1])].astype(np.int64).tolist():
            if m not in ids:
                ids.append(m)
        out.append(Manoeuvre(
            number=number, start_t_s=float(t[a]), end_t_s=float(t[end]),
            start_north_m=float(n[a]), start_east_m=float(e[a]), end_north_m=float(n[end]), end_east_m=float(e[end]),
            side=("starboard" if sh[k] > 0 else "port") if big else None,
            max_alteration_deg=float(sh[k]) if k is not None else math.nan,
            min_speed_factor=float(np.nanmin(f)) if np.isfinite(f).any() else math.nan, targets=ids,
        ))
    return out


def avoidance_logged(log: MissionLog) -> bool:
    """The log has collision avoidance's cycle fields (it had targets while steering)."""
    return bool(np.isfinite(log.col("avoid_active")).any())
