"""Streaming, tolerant reader of mission logs (the schema: :mod:`autopilot.logschema`, docs/log-schema.md).

One pass, line by line, constant work per line: each line is decoded with
``json.loads`` and a ``cycle`` line's numeric fields go into a block of
rows that is turned into a numpy array every few thousand lines and copied
into columnar float64 storage sized from the file length (pages that are
never written are never resident, so over-estimating costs nothing).

Nothing is invented: a missing, null or non-numeric field is NaN (a gap,
never a zero); lines that cannot be used are skipped and counted by reason
(a cut last line, corrupt JSON, a line without ``event`` or ``t_s``,
unknown events); keys that are not in the schema are ignored, as the
schema asks of readers.

Traffic (issue 18): the ``target`` lines (AIS position reports) become one
:class:`TargetTrack` per MMSI and the ``encounter`` lines
:class:`EncounterEvent` records (:attr:`MissionLog.targets`,
:attr:`MissionLog.encounters`); a line of either without a usable MMSI, time
or position is kept among the events but counted (``bad_events``) and left
out of both. Logs written before traffic was logged simply have none.
"""

from __future__ import annotations

import codecs
import json
import math
import operator
from collections import Counter
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from autopilot.gnc.encounter import Situation
from autopilot.logschema import COG_HEADING_SOURCE, CYCLE, EVENT_NAMES, HEADING_SOURCES, MODES
from autopilot.schema import ConfigError

# numeric (or boolean) cycle fields of the schema, stored as float64 columns; NaN = absent
CYCLE_FIELDS: tuple[str, ...] = ("t_s",) + tuple(f.name for f in CYCLE if f.numeric)
EVENTS: frozenset[str] = frozenset(EVENT_NAMES)
UNKNOWN_CODE = -1  # mode / heading source / situation absent or not in the schema
SITUATIONS: tuple[str, ...] = tuple(s.value for s in Situation)  # the codes of the avoid_situation column
_BLOCK_ROWS = 8192
_MIN_BYTES_PER_CYCLE = 160  # a full cycle line is ~900 B; only a size estimate
_MAX_EXAMPLES = 10


@dataclass
class ReadStats:
    """What the reader used and what it skipped, and why."""

    lines: int = 0
    cycles: int = 0
    events: int = 0
    blank: int = 0
    truncated_last_line: bool = False
    corrupt: int = 0  # not JSON or not a JSON object
    no_event: int = 0
    no_time: int = 0  # a cycle without a numeric t_s: it cannot be placed in time
    unknown_events: Counter = field(default_factory=Counter)
    bad_values: Counter = field(default_factory=Counter)  # field -> non-numeric/infinite values
    bad_events: Counter = field(default_factory=Counter)  # "target" / "encounter" lines that cannot be placed
    unknown_modes: int = 0
    time_reversals: int = 0  # cycles not later than every one before: left out
    not_utf8: int = 0  # lines read as Windows-1252 (or Latin-1): not UTF-8
    examples: list = field(default_factory=list)  # (line number, reason) of the first skips

    @property
    def skipped(self) -> int:
        return (self.corrupt + self.no_event + self.no_time + int(self.truncated_last_line)
                + sum(self.unknown_events.values()))

    def _skip(self, lineno: int, reason: str) -> None:
        if len(self.examples) < _MAX_EXAMPLES:
            self.examples.append((lineno, reason))

    def describe(self) -> list[str]:
        """Plain sentences for the report and the terminal."""
        out = [f"{self.lines} lines: {self.cycles} cycles, {self.events} events"]
        if self.truncated_last_line:
            out.append("last line cut off mid-write: skipped")
        if self.corrupt:
            out.append(f"{self.corrupt} corrupt line(s) (not a JSON object): skipped")
        if self.no_event:
            out.append(f"{self.no_event} line(s) without an event name: skipped")
        if self.no_time:
            out.append(f"{self.no_time} cycle line(s) without a numeric t_s: skipped")
        for name, count in sorted(self.unknown_events.items()):
            out.append(f"{count} line(s) of unknown event {name!r}: skipped")
        for name, count in sorted(self.bad_values.items()):
            out.append(f"{count} non-numeric, infinite or absurd (beyond 1e12) value(s) of {name}: treated as gaps")
        for name, count in sorted(self.bad_events.items()):
            out.append(f"{count} {name} line(s) without a usable MMSI, time or position: not drawn or scored")
        if self.unknown_modes:
            out.append(f"{self.unknown_modes} cycle(s) with an unknown or missing mode")
        if self.time_reversals:
            out.append(f"{self.time_reversals} cycle(s) not later than one before (a block written twice, or another "
                       "run appended): left out of every figure")
        if self.not_utf8:
            out.append(f"{self.not_utf8} line(s) not UTF-8 (a log re-saved by an editor?): read as Windows-1252")
        if self.blank:
            out.append(f"{self.blank} blank line(s)")
        if self.examples:
            out.append("first skipped: " + "; ".join(f"line {n}: {r}" for n, r in self.examples))
        return out


@dataclass(frozen=True)
class Plan:
    """A mission the boat was given in the log: ``mission_start``'s, then each ``mission_replaced`` (an upload
    over the link, or a clear: no waypoints). The cycles from ``from_t_s`` until ``until_t_s`` steer by it and
    their ``wp_index`` counts in it, as do the waypoint events of that time."""

    number: int  # 1: mission_start's; 2, 3, ...: the replacements in order
    from_t_s: float  # -inf for mission_start's
    until_t_s: float  # +inf for the last
    waypoints_ne_m: np.ndarray  # (N, 2)
    source: str | None = None  # who replaced it (`mavlink`); None for mission_start's

    def holds(self, t_s):
        """Whether (each of) ``t_s`` falls in this plan's time."""
        return (np.asarray(t_s) >= self.from_t_s) & (np.asarray(t_s) < self.until_t_s)

    def label(self, index: int, several: bool) -> str:
        """W3, or M2 W3 in a log of several missions."""
        return f"M{self.number} W{index}" if several else f"W{index}"


def _waypoint_array(value) -> np.ndarray:
    try:
        wps = np.asarray(value or [], dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        return np.zeros((0, 2))
    return wps[np.all(np.isfinite(wps), axis=1)]


@dataclass
class MissionLog:
    """One mission log in columns.

    ``col(name)`` gives a float64 array over cycles (NaN where absent);
    ``mode`` / ``heading_source`` / ``avoid_situation`` are int8 codes into
    :data:`MODES` / :data:`HEADING_SOURCES` / :data:`SITUATIONS`
    (``UNKNOWN_CODE`` when absent). ``events`` holds every non-cycle line in
    file order (they are few).
    """

    path: Path
    start: dict | None
    events: list[dict]
    data: np.ndarray  # (len(CYCLE_FIELDS), n) float64
    mode: np.ndarray
    heading_source: np.ndarray
    stats: ReadStats
    first_timestamp: str | None = None
    last_timestamp: str | None = None
    avoid_situation: np.ndarray | None = None  # None: all UNKNOWN_CODE (a log built by hand)
    line_numbers: np.ndarray | None = None  # each cycle's line in the file (1-based; None: a log built by hand)
    event_lines: list[int] | None = None  # each event's line in the file, as ``events`` (None: a log built by hand)

    def __post_init__(self) -> None:
        if self.avoid_situation is None:
            self.avoid_situation = np.full(self.data.shape[1], UNKNOWN_CODE, dtype=np.int8)

    @property
    def n_cycles(self) -> int:
        return int(self.data.shape[1])

    def col(self, name: str) -> np.ndarray:
        return self.data[_INDEX[name]]

    @property
    def name(self) -> str:
        if self.start and isinstance(self.start.get("mission_name"), str):
            return self.start["mission_name"]
        return self.path.stem

    @property
    def guidance_law(self) -> str | None:
        """The guidance law ``mission_start`` names (None when it names none)."""
        law = (self.start or {}).get("guidance")
        return law if isinstance(law, str) and law else None

    @property
    def waypoints_ne_m(self) -> np.ndarray:
        """(N, 2) waypoints from ``mission_start`` ((0, 2) when absent or malformed); a log whose mission was
        replaced has more (:attr:`plans`)."""
        return _waypoint_array((self.start or {}).get("waypoints"))

    @cached_property
    def plans(self) -> list[Plan]:
        """Every mission the boat was given, in order: ``mission_start``'s, then each ``mission_replaced``.
        Reviewed against the first alone, a mission uploaded from QGroundControl mid-run was scored against
        waypoints the boat no longer steered to ("1 of 1 reached" for the daemon's "4 of 4")."""
        lines = self.event_lines if self.event_lines is not None and len(self.event_lines) == len(self.events) \
            else [None] * len(self.events)
        changes = sorted((self._applied_at(float(ev["t_s"]), line), k, ev)
                         for k, (ev, line) in enumerate(zip(self.events, lines))
                         if ev.get("event") == "mission_replaced" and _is_number(ev.get("t_s"))
                         and isinstance(ev.get("waypoints"), list))
        starts = [-math.inf] + [t for t, _, _ in changes]
        ends = starts[1:] + [math.inf]
        sources = [None] + [str(ev.get("source") or "") or None for _, _, ev in changes]
        waypoints = [self.waypoints_ne_m] + [_waypoint_array(ev["waypoints"]) for _, _, ev in changes]
        return [Plan(k + 1, a, b, w, src) for k, (a, b, w, src) in enumerate(zip(starts, ends, waypoints, sources))]

    def _applied_at(self, event_t_s: float, line: int | None) -> float:
        """When a ``mission_replaced`` took effect: the ``t_s`` of the cycle that applied it, the first cycle line
        after it in the file, when that is earlier than the line's own time. The daemon applies the replacement
        inside a cycle, before its step, and dates the line by the clock, later than the cycle's ``t_s`` (the
        cycle's start): on the boat's real clock (a MAVLink upload at 10x: 13 ms later; at 20x even after the next
        cycle's start, the upload's saving having delayed it) the first cycle steered by the new mission, its
        ``wp_index`` already the new one's, was counted in the old one, and the new mission's leg 0 began a cycle
        late (a review audit, 2026-12-06). Under the simulated clock of ``--speedup max`` the two are equal; a
        line before a hole in the log keeps its own time."""
        if line is None or self.line_numbers is None or len(self.line_numbers) != self.n_cycles:
            return event_t_s
        k = int(np.searchsorted(self.line_numbers, line))
        if k >= self.n_cycles:
            return event_t_s
        return min(event_t_s, float(self.col("t_s")[k]))

    def plan_at(self, t_s: float) -> Plan:
        """The plan in force at ``t_s``."""
        return next(p for p in reversed(self.plans) if t_s >= p.from_t_s)

    def all_waypoints(self) -> list[tuple[str, float, float]]:
        """(label, north_m, east_m) of every plan's waypoints in order (W0 ..., or M1 W0 ..., M2 W0 ...)."""
        several = len(self.plans) > 1
        return [(p.label(i, several), float(n), float(e)) for p in self.plans for i, (n, e) in enumerate(p.waypoints_ne_m)]

    @property
    def origin_deg(self) -> tuple[float, float] | None:
        """(lat, lon) of the local frame's origin, if the log states it."""
        s = self.start or {}
        lat, lon = s.get("origin_lat_deg"), s.get("origin_lon_deg")
        if _is_number(lat) and _is_number(lon) and abs(lat) <= 90 and abs(lon) <= 180:
            return float(lat), float(lon)
        return None

    @property
    def launch_ne_m(self) -> tuple[float, float] | None:
        """(north, east) of the last ``launch`` event (where ``rtl`` returns), if the log has one."""
        for ev in reversed(self.events_named("launch")):
            n, e = ev.get("north_m"), ev.get("east_m")
            if _is_number(n) and _is_number(e):
                return float(n), float(e)
        return None

    def config_number(self, *keys: str) -> float | None:
        """A number of the configuration in ``mission_start`` (``config_number("gnc", "hold", "radius_m")``);
        None when the log does not state it (older logs, a partial config)."""
        node = (self.start or {}).get("config")
        for k in keys:
            if not isinstance(node, dict):
                return None
            node = node.get(k)
        return float(node) if _is_number(node) else None

    def events_named(self, *names: str) -> list[dict]:
        return [e for e in self.events if e.get("event") in names]

    @cached_property
    def targets(self) -> dict[int, TargetTrack]:
        """Each AIS target's reported track, by MMSI in order of first report (empty: no ``target`` lines)."""
        by: dict[int, list[dict]] = {}
        for ev in self.events:
            if ev.get("event") == "target" and _usable_target(ev):
                by.setdefault(ev["target"], []).append(ev)
        return {mmsi: TargetTrack.from_events(mmsi, evs) for mmsi, evs in by.items()}

    @cached_property
    def encounters(self) -> list[EncounterEvent]:
        """The ``encounter`` lines in file order (empty in logs without them)."""
        return [EncounterEvent.from_event(ev) for ev in self.events
                if ev.get("event") == "encounter" and _usable_encounter(ev)]

    def fix_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(row indices, fix times) of the cycles where a new position fix first appears.

        A cycle line repeats the last fix until the next one arrives (1 Hz GGA/RMC in a
        10 Hz log): a held fix is not a new measurement. The fix was measured at
        ``t_s - position_age_s``; logs without ages count a row as a new fix when its
        position differs from the previous row's (and date it at the row).
        """
        n, e = self.col("north_m"), self.col("east_m")
        lat, lon = self.col("lat_deg"), self.col("lon_deg")
        have = (np.isfinite(n) & np.isfinite(e)) | (np.isfinite(lat) & np.isfinite(lon))
        return _new_samples(self.col("t_s"), self.col("position_age_s"), have, (n, e, lat, lon))

    def velocity_rows(self) -> np.ndarray:
        """Row indices of the cycles with a new speed and course over ground, by the identification's one rule
        (:func:`autopilot.sysid.trials.new_velocities`: where the pair changes, and once an epoch where it stays
        the same through epochs with their own fixes). Where it changed only, the export of a stay at rest kept
        1 of its 31 readings (0.00 kn every epoch), which the log itself gave sysid (a review)."""
        from autopilot.sysid.trials import new_velocities

        fix, fix_t = self.fix_rows()
        fix_new, fix_time_s = np.zeros(self.n_cycles, dtype=bool), np.full(self.n_cycles, np.nan)
        fix_new[fix], fix_time_s[fix] = True, fix_t
        is_new, _ = new_velocities(self.col("sog_m_s"), self.col("cog_deg"), fix_new, fix_time_s, self.col("t_s"))
        return np.flatnonzero(is_new)

    def undelivered_rows(self) -> np.ndarray:
        """Per cycle: True where its command may never have reached the motors, in a stretch the identification
        cannot bridge (:func:`autopilot.sysid.trials.undelivered_stretch`): the Mbed driver could not write it
        (``seq`` -1), or its acknowledgement was counted missing (``ack_missing`` grew), which happens
        ``serial.ack_timeout_s`` after the command (the mission_start's configuration, else 0.3 s). A log holds
        what the daemon sent; the motors then held an older command or the firmware's stop. Found by a sysid audit:
        4 s of an Mbed link lost, replayed on the logged commands, gave `unexplained` for a plain current. A board
        that answers late now and then (each late answer counted missing) leaves lone misses apart: none is cut."""
        from autopilot.sysid.trials import undelivered_stretch

        n, t = self.n_cycles, self.col("t_s")
        serial = ((self.start or {}).get("config") or {}).get("serial") or {}
        timeout_s = serial.get("ack_timeout_s")
        timeout_s = float(timeout_s) if isinstance(timeout_s, (int, float)) and timeout_s > 0 else 0.3
        seq, missing = self.col("seq"), self.col("ack_missing")
        not_written = np.isfinite(seq) & (seq < 0)
        # the count so far, from the log's first value (misses before the log began are not this log's)
        known = np.flatnonzero(np.isfinite(missing))
        counted = np.zeros(n)
        if known.size:
            held = np.fmax.accumulate(np.where(np.isfinite(missing), missing, -np.inf))
            held[: known[0]] = missing[known[0]]
            counted[1:] = np.maximum(np.diff(held), 0.0)
        period_s = float(np.median(np.diff(t))) if n > 1 else 0.1
        maybe = not_written.copy()
        for k in np.flatnonzero(counted > 0):
            # the commands counted missing at cycle k were sent a timeout before it (and one period each before that)
            sent_until = t[k] - timeout_s
            maybe |= (t >= sent_until - (counted[k] + 0.5) * period_s) & (t <= sent_until)
        out = np.zeros(n, dtype=bool)
        edges = np.flatnonzero(np.diff(np.r_[0, maybe.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2]):  # runs [a, b)
            misses = int(np.sum(not_written[a:b])) + int(np.sum(counted[(t >= t[a] + timeout_s) &
                                                                         (t <= t[b - 1] + timeout_s + period_s)]))
            before = t[a - 1] if a > 0 else t[a] - period_s
            after = t[b] if b < n else t[b - 1] + period_s
            out[a:b] = undelivered_stretch(misses, after - before)
        return out

    def heading_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(row indices, measurement times) of the cycles with a new heading sample (see :meth:`fix_rows`).

        Without ``heading_age_s`` every row with a heading counts (it comes at the cycle rate). A row whose heading
        is the course over ground (``heading_source`` COG: the compass lost, ``failsafe.cog_fallback``) holds no
        compass heading (:meth:`compass_heading_deg`).
        """
        h = self.compass_heading_deg()
        return _new_samples(self.col("t_s"), self.col("heading_age_s"), np.isfinite(h), None)

    def compass_heading_deg(self) -> np.ndarray:
        """``heading_deg`` where it is the compass's; NaN where the daemon steered on its course over ground (the
        two differ by the drift angle: read as headings, a current's drift looked like a compass error)."""
        h = self.col("heading_deg")
        return np.where(self.heading_source == _SOURCE_CODES[COG_HEADING_SOURCE], np.nan, h)


@dataclass(frozen=True)
class TargetTrack:
    """One AIS target's position reports (``target`` lines), in time order, in the mission's local frame.

    ``t_s`` is when each report was made, the line's ``t_s`` minus its ``age_s`` (the position was measured
    then, as a fix was at ``t_s - position_age_s``); a line without ``age_s`` is dated at the line. Course
    and speed are NaN where not reported; ``name`` and ``length_m`` are the last ones reported (None: none).
    """

    target: int  # MMSI
    name: str | None
    length_m: float | None
    t_s: np.ndarray
    north_m: np.ndarray
    east_m: np.ndarray
    course_deg: np.ndarray
    speed_m_s: np.ndarray

    @property
    def label(self) -> str:
        return self.name or str(self.target)

    @classmethod
    def from_events(cls, mmsi: int, events: list[dict]) -> TargetTrack:
        rows = []
        name = length = None
        for ev in events:
            age = ev.get("age_s")
            t = float(ev["t_s"]) - (float(age) if _is_number(age) and age >= 0.0 else 0.0)
            rows.append((t, float(ev["north_m"]), float(ev["east_m"]), _number_or_nan(ev.get("course_deg")),
                         _number_or_nan(ev.get("speed_m_s"))))
            if isinstance(ev.get("name"), str) and ev["name"].strip():
                name = ev["name"].strip()
            if _is_number(ev.get("length_m")) and ev["length_m"] > 0:
                length = float(ev["length_m"])
        arr = np.array(rows, dtype=float).reshape(-1, 5)
        arr = arr[np.argsort(arr[:, 0], kind="stable")]
        # one report logged twice (a re-read port) is one report: the later line wins
        keep = np.append(np.diff(arr[:, 0]) > _SAME_SAMPLE_S, True)
        arr = arr[keep]
        return cls(target=mmsi, name=name, length_m=length, t_s=arr[:, 0], north_m=arr[:, 1], east_m=arr[:, 2],
                   course_deg=arr[:, 3], speed_m_s=arr[:, 4])

    def position_at(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """(north, east) at the times ``t_s``, linear between reports; NaN outside the reported span
        (nothing is known of the target before its first report or after its last)."""
        t = np.asarray(t_s, dtype=float)
        inside = (t >= self.t_s[0]) & (t <= self.t_s[-1])
        n = np.where(inside, np.interp(t, self.t_s, self.north_m), np.nan)
        e = np.where(inside, np.interp(t, self.t_s, self.east_m), np.nan)
        return n, e


@dataclass(frozen=True)
class EncounterEvent:
    """One ``encounter`` line: a target's situation, or whether the boat acts for it, changed at ``t_s``."""

    t_s: float
    target: int  # MMSI
    name: str | None
    situation: str  # a Situation value (or whatever a newer daemon writes)
    rule: str
    acting: bool
    risk: float  # NaN when not logged
    range_m: float
    dcpa_m: float
    tcpa_s: float
    reason: str

    @classmethod
    def from_event(cls, ev: dict) -> EncounterEvent:
        def text(key):
            return ev[key] if isinstance(ev.get(key), str) else ""

        return cls(t_s=float(ev["t_s"]), target=ev["target"], name=ev.get("name") if isinstance(ev.get("name"), str)
                   else None, situation=ev["situation"], rule=text("rule"), acting=ev["acting"],
                   risk=_number_or_nan(ev.get("risk")), range_m=_number_or_nan(ev.get("range_m")),
                   dcpa_m=_number_or_nan(ev.get("dcpa_m")), tcpa_s=_number_or_nan(ev.get("tcpa_s")),
                   reason=text("reason"))


def _is_mmsi(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x > 0


def _usable_target(ev: dict) -> bool:
    return (_is_mmsi(ev.get("target")) and _is_number(ev.get("t_s")) and _is_number(ev.get("north_m"))
            and _is_number(ev.get("east_m")))


def _usable_encounter(ev: dict) -> bool:
    return (_is_mmsi(ev.get("target")) and _is_number(ev.get("t_s")) and isinstance(ev.get("situation"), str)
            and isinstance(ev.get("acting"), bool))


def _number_or_nan(x) -> float:
    return float(x) if _is_number(x) else math.nan


_SAME_SAMPLE_S = 1e-4  # two rows whose measurement times differ by less hold the same sample


def _new_samples(t, age, have, values) -> tuple[np.ndarray, np.ndarray]:
    rows = np.nonzero(have)[0]
    if len(rows) == 0:
        return rows, np.zeros(0)
    when = t[rows] - age[rows]
    dated = np.isfinite(when)
    new = np.ones(len(rows), dtype=bool)
    if dated.all():
        new[1:] = np.abs(np.diff(when)) > _SAME_SAMPLE_S
    elif values is None:  # no ages logged, a sample every cycle (the 10 Hz heading)
        when = t[rows]
    else:  # no ages logged: a repeated position is a held fix (GPS noise never repeats exactly)
        stack = np.stack([v[rows] for v in values])
        same = np.all((stack[:, 1:] == stack[:, :-1]) | (np.isnan(stack[:, 1:]) & np.isnan(stack[:, :-1])), axis=0)
        new[1:] = ~same
        when = np.where(dated, when, t[rows])
    return rows[new], when[new]


_INDEX = {name: i for i, name in enumerate(CYCLE_FIELDS)}
_MODE_CODES = {m: i for i, m in enumerate(MODES)}
_SOURCE_CODES = {s: i for i, s in enumerate(HEADING_SOURCES)}
_SITUATION_CODES = {s: i for i, s in enumerate(SITUATIONS)}


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _to_float(x) -> float:
    """One value to float; NaN for absent; TypeError for anything not a finite number."""
    if x is None:
        return math.nan
    if isinstance(x, bool):
        return 1.0 if x else 0.0
    try:
        if isinstance(x, (int, float)) and math.isfinite(x):
            return float(x)
    except OverflowError:  # a 400-digit integer: not a float at all (it escaped read_log: a review)
        pass
    raise TypeError  # strings, lists, objects, infinities, integers beyond a float


class _Columns:
    """Growable (fields, rows) float64 storage filled block by block."""

    def __init__(self, capacity: int) -> None:
        self.buf = np.empty((len(CYCLE_FIELDS), max(capacity, _BLOCK_ROWS)))
        self.mode = np.empty(self.buf.shape[1], dtype=np.int8)
        self.source = np.empty(self.buf.shape[1], dtype=np.int8)
        self.situation = np.empty(self.buf.shape[1], dtype=np.int8)
        self.n = 0

    def append(self, block: np.ndarray, mode: np.ndarray, source: np.ndarray, situation: np.ndarray) -> None:
        m = block.shape[0]
        if self.n + m > self.buf.shape[1]:
            cap = max(self.n + m, int(self.buf.shape[1] * 1.5))
            buf = np.empty((self.buf.shape[0], cap))
            buf[:, : self.n] = self.buf[:, : self.n]
            self.buf = buf
            self.mode = np.resize(self.mode, cap)
            self.source = np.resize(self.source, cap)
            self.situation = np.resize(self.situation, cap)
        self.buf[:, self.n : self.n + m] = block.T
        self.mode[self.n : self.n + m] = mode
        self.source[self.n : self.n + m] = source
        self.situation[self.n : self.n + m] = situation
        self.n += m


ABSURD = 1e12  # |value| above this in a cycle line is corrupt (a position 1e12 m off is 25 000 times round the Earth)


def _block_to_array(rows: list, stats: ReadStats) -> np.ndarray:
    try:
        arr = np.array(rows, dtype=np.float64)
        if arr.shape != (len(rows), len(CYCLE_FIELDS)):
            raise ValueError
    except (TypeError, ValueError, OverflowError):
        # slow path only for blocks holding something odd (strings, lists)
        arr = np.empty((len(rows), len(CYCLE_FIELDS)))
        for i, row in enumerate(rows):
            for j, value in enumerate(row):
                try:
                    arr[i, j] = _to_float(value)
                except TypeError:
                    arr[i, j] = math.nan
                    stats.bad_values[CYCLE_FIELDS[j]] += 1
    # no quantity of a mission log comes near ABSURD: 1e308 m/s was summed into a 300-digit distance (a review audit)
    with np.errstate(invalid="ignore"):
        bad = (~np.isfinite(arr) & ~np.isnan(arr)) | (np.abs(arr) > ABSURD)
    if bad.any():
        for j in np.nonzero(bad.any(axis=0))[0]:
            stats.bad_values[CYCLE_FIELDS[j]] += int(bad[:, j].sum())
        arr[bad] = np.nan
    return arr


_SNIFF_BYTES = 65536
_FIRST_LINE_MAX_BYTES = 64 * 1024 * 1024  # a first line longer than this is not a mission log's
GZIP_MAGIC = b"\x1f\x8b"


def open_log(path: Path):
    """The log's bytes: a gzip-compressed log (logrotate's .gz, or one compressed to mail) read as it is."""
    import gzip

    with path.open("rb") as f:
        compressed = f.read(2) == GZIP_MAGIC
    return gzip.open(path, "rb") if compressed else path.open("rb")


def check_mission_log(path) -> Path:
    """``path`` if it can be a mission log; ConfigError naming the file when it plainly is not.

    An empty file passes (a daemon killed before its first line leaves one; the review says
    so). A file with bytes in it must hold at least one JSON line with an ``event`` the daemon
    writes (docs/log-schema.md) among its first 64 kB (and its first line, however long): a README,
    a CSV, a binary file or another program's JSON log given by mistake is refused, not reviewed as
    "0 cycles".
    """
    from autopilot.userfile import check_file, check_text_head

    p = check_file(path, what="mission log")
    head = bytearray()
    whole = False
    line_ended = False
    try:
        with open_log(p) as f:
            # the first line whole, however long: a survey's mission_start (1400 waypoints) is ~67 kB
            while len(head) < _SNIFF_BYTES or (not line_ended and len(head) < _FIRST_LINE_MAX_BYTES):
                chunk = f.read(65536)
                if not chunk:
                    whole = True
                    break
                line_ended = line_ended or b"\n" in chunk  # only the new bytes looked at: linear, not quadratic
                head += chunk
    except (OSError, EOFError) as exc:  # a compressed log cut short: what could be read is judged
        if not head:
            raise ConfigError(f"{p}: a gzip file that cannot be read ({exc})") from None
        whole = True
    head = bytes(head)
    if not head.strip():
        return p
    check_text_head(p, head, what="mission log")
    lines = head.removeprefix(codecs.BOM_UTF8).splitlines()
    if not whole and len(lines) > 1:
        lines = lines[:-1]  # the last one may be cut by the sniff
    named = []
    for raw in lines:
        try:
            rec = json.loads(raw)
        except ValueError:
            continue
        if isinstance(rec, dict) and isinstance(rec.get("event"), str):
            if rec["event"] in EVENTS:
                return p
            named.append(rec["event"])
    other = (f"; its lines' events ({', '.join(sorted(set(named))[:3])}) are none of the daemon's"
             if named else "")
    raise ConfigError(f"{p}: no mission-log line in it (none of its first {len(lines)} line(s) is a JSON object "
                      f"with an 'event' the daemon writes{other}): not a mission log (docs/log-schema.md)")


def _lines(f, stats: ReadStats):
    """The file's lines; a compressed log cut short (a copy interrupted) ends where it can be read, noted."""
    lineno = 0
    it = iter(f)
    while True:
        try:
            raw = next(it)
        except StopIteration:
            return
        except (EOFError, OSError):  # gzip: "Compressed file ended before the end-of-stream marker", a bad CRC
            stats.truncated_last_line = True
            stats._skip(lineno + 1, "the compressed file ends early")
            return
        lineno += 1
        yield raw


def _in_time_order(t: np.ndarray) -> np.ndarray:
    """The cycles to keep: those later than every one kept before. A lone cycle whose t_s is ahead of both
    neighbours while they are in order (a corrupt value) is one bad cycle: taken as the clock, it once left the
    322 cycles after it out (a review of the change that began leaving cycles out)."""
    n = len(t)
    spike = np.zeros(n, dtype=bool)
    if n >= 3:
        spike[1:-1] = (t[1:-1] > t[2:]) & (t[2:] > t[:-2])
    if n >= 2 and t[0] > t[1]:
        spike[0] = n == 2 or t[1] < t[2]  # the first, ahead of an ordered rest
    keep = ~spike
    kept = t[keep]
    ordered = kept > np.maximum.accumulate(np.r_[-np.inf, kept[:-1]]) if len(kept) else np.zeros(0, dtype=bool)
    keep[np.flatnonzero(keep)[~ordered]] = False
    return keep


def _cp1252_ok(raw: bytes) -> bool:
    try:
        raw.decode("cp1252")
    except UnicodeDecodeError:  # the five bytes Windows-1252 leaves undefined: Latin-1 reads every byte
        return False
    return True


def read_log(path, *, keep_reversals: bool = False) -> MissionLog:
    """Read one mission log in a single streaming pass.

    Raises ``ConfigError`` only when the file cannot be opened; anything
    wrong inside the file is skipped and counted in ``stats``. Cycles not later than every one before are left
    out (counted) unless ``keep_reversals`` (the identification refuses such a log, naming the line).
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        f = open_log(path)
    except OSError as exc:
        raise ConfigError(f"cannot read log {str(path)!r}: {exc.strerror or exc}") from exc
    stats = ReadStats()
    cols = _Columns(size // _MIN_BYTES_PER_CYCLE + 16)
    start: dict | None = None
    events: list[dict] = []
    event_lines: list[int] = []
    rows: list = []
    modes: list = []
    sources: list = []
    situations: list = []
    linenos: list = []
    first_ts = last_ts = None
    fields = CYCLE_FIELDS
    take = operator.itemgetter(*fields)
    # A NaN literal (not strict JSON: the daemon writes null) counts as a bad value, as an infinity does,
    # not as a silent gap (a log of NaN positions gave "nan m" and no note)
    decode = json.JSONDecoder(parse_constant=lambda _name: math.inf).decode

    def loads(raw):  # bytes, as json.loads takes them (a line that is not JSON: ValueError, a corrupt line)
        if not isinstance(raw, bytes):
            return decode(raw)
        try:
            return decode(raw.decode("utf-8"))
        except UnicodeDecodeError:
            # a log re-saved by an editor in Windows-1252 / Latin-1: its mission_start line (an accented mission
            # name) was skipped as "not JSON", and the report had no waypoints (a review audit)
            text = raw.decode("cp1252", errors="strict") if _cp1252_ok(raw) else raw.decode("latin-1")
            rec = decode(text)
            stats.not_utf8 += 1
            return rec

    def first_loads(raw):  # the first line: a byte-order mark (a log saved by a Windows editor) is not data
        return loads(raw.removeprefix(codecs.BOM_UTF8) if isinstance(raw, bytes) else raw.removeprefix("\ufeff"))
    mode_codes, source_codes, situation_codes = _MODE_CODES, _SOURCE_CODES, _SITUATION_CODES

    def flush() -> None:
        block = _block_to_array(rows, stats)
        mode = np.fromiter((mode_codes.get(m, UNKNOWN_CODE) for m in modes), np.int8, len(modes))
        src = np.fromiter((source_codes.get(s, UNKNOWN_CODE) if type(s) is str else UNKNOWN_CODE
                           for s in sources), np.int8, len(sources))
        sit = np.fromiter((situation_codes.get(s, UNKNOWN_CODE) if type(s) is str else UNKNOWN_CODE
                           for s in situations), np.int8, len(situations))
        cols.append(block, mode, src, sit)
        rows.clear()
        modes.clear()
        sources.clear()
        situations.clear()

    with f:
        lineno = 0
        for raw in _lines(f, stats):
            lineno += 1
            try:
                rec = first_loads(raw) if lineno == 1 else loads(raw)
            except ValueError:  # JSONDecodeError and UnicodeDecodeError
                if not raw.strip():
                    stats.blank += 1
                elif not raw.endswith(b"\n"):
                    stats.truncated_last_line = True
                    stats._skip(lineno, "cut off mid-line")
                else:
                    stats.corrupt += 1
                    stats._skip(lineno, "not JSON")
                continue
            if type(rec) is not dict:
                stats.corrupt += 1
                stats._skip(lineno, "not a JSON object")
                continue
            event = rec.get("event")
            if event == "cycle":
                t = rec.get("t_s")
                if type(t) is not float and (type(t) is not int or not math.isfinite(t)):
                    stats.no_time += 1
                    stats._skip(lineno, "cycle without t_s")
                    continue
                try:
                    rows.append(take(rec))  # all fields present: one C call
                except KeyError:
                    rows.append([rec.get(k) for k in fields])
                modes.append(rec.get("mode"))
                linenos.append(lineno)
                sources.append(rec.get("heading_source"))
                situations.append(rec.get("avoid_situation"))
                if len(rows) == _BLOCK_ROWS:
                    flush()
                ts = rec.get("timestamp")
            elif type(event) is not str:
                stats.no_event += 1
                stats._skip(lineno, "no event name")
                continue
            elif event in EVENTS:
                stats.events += 1
                if event == "mission_start" and start is None:
                    start = rec
                elif (event == "target" and not _usable_target(rec)) or (
                        event == "encounter" and not _usable_encounter(rec)):
                    stats.bad_events[event] += 1
                    stats._skip(lineno, f"{event} line without a usable MMSI, time or position")
                events.append(rec)
                event_lines.append(lineno)
                ts = rec.get("timestamp")
            else:
                stats.unknown_events[event] += 1
                continue
            if type(ts) is str:
                if first_ts is None:
                    first_ts = ts
                last_ts = ts
    stats.lines = lineno
    if rows:
        flush()
    data = cols.buf[:, : cols.n]
    t = data[_INDEX["t_s"]]
    line_numbers = np.asarray(linenos, dtype=np.int64)
    nan_t = np.isnan(t)  # t_s was NaN/Infinity in the file
    if nan_t.any():
        keep = ~nan_t
        line_numbers = line_numbers[keep]
        stats.no_time += int(nan_t.sum())
        data, mode, source = data[:, keep], cols.mode[: cols.n][keep], cols.source[: cols.n][keep]
        situation = cols.situation[: cols.n][keep]
        t = data[_INDEX["t_s"]]
    else:
        mode, source, situation = cols.mode[: cols.n], cols.source[: cols.n], cols.situation[: cols.n]
    # a cycle not later than every one before is a block written twice (a copy glitch) or another run appended:
    # left out of every figure. Kept, its energy, mode times, "position lost" and fixes counted twice while only
    # the distance left it out (a review audit: 20 s of position lost in a log with a fix throughout)
    later = _in_time_order(t)
    if keep_reversals:
        stats.time_reversals = int(np.count_nonzero(np.diff(t) < 0))
    elif not later.all():
        stats.time_reversals = int(np.count_nonzero(~later))
        line_numbers = line_numbers[later]
        data, mode, source, situation = data[:, later], mode[later], source[later], situation[later]
    stats.cycles = int(data.shape[1])
    stats.unknown_modes = int(np.count_nonzero(mode == UNKNOWN_CODE))
    return MissionLog(path=path, start=start, events=events, event_lines=event_lines, data=data, mode=mode,
                      heading_source=source, stats=stats, first_timestamp=first_ts,
                      last_timestamp=last_ts, avoid_situation=situation, line_numbers=line_numbers)
