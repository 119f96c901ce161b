"""Furuno SC-30 satellite compass driver: serial NMEA in, one stamped navigation sample in SI out.

Each quantity is kept with the sentence it came from, the Clock time it was
received and its validity (fix quality, THS mode, A/V status); the daemon
decides when it is stale. Heading comes only from true-heading sentences,
in priority THS > HDT > PFEC_GPatt (SPEC section 10: THS replaces HDT on
later firmware); course over ground is never copied into the heading: the
daemon may fall back to it explicitly and log that it did. The GGA, RMC and
GLL of one GNSS epoch (the same UTC time) are one fix. Units: SI from the
codec on (:class:`autopilot.devices.NavSample`); latitude/longitude in degrees.
Implements :class:`autopilot.devices.Compass`.
"""

from __future__ import annotations

from autopilot.clock import Clock
from autopilot.devices import EventSink, NavSample, Stamped
from autopilot.drivers.line_device import LineDevice
from autopilot.drivers.line_timing import TickClock, WireClock
from autopilot.drivers.nmea import NmeaStreamDecoder, NmeaUpdate

__all__ = ["SC30Driver", "HEADING_PRIORITY", "epoch_order"]

HEADING_PRIORITY = ("THS", "HDT", "PFEC_GPatt")
POSITION_SENTENCES = ("GGA", "RMC", "GLL")


# a position sentence's "not valid" (GGA quality 0, RMC/GLL status V) stands this long against the other kinds'
# "valid": a receiver whose RMC said V beside a GGA of quality 1 made the fix valid and invalid by turns, a
# no_fix fault and its clearing twice a second
VERDICT_WINDOW_S = 1.5
OLD_EPOCH_WINDOW_S = 600.0  # an epoch at most this far before the last is a replay; farther, a receiver reset
_DAY_S = 86400.0


def _time_of_day_s(t) -> float:
    """Seconds since midnight; a leap second (23:59:60, ``fold=1`` from the decoder) is the 86401st."""
    return t.hour * 3600.0 + t.minute * 60.0 + t.second + t.microsecond * 1e-6 + t.fold


def epoch_order(fix_time, last_fix_time) -> str:
    """``"same"``, ``"old"`` or ``"new"``: a position sentence's UTC epoch against the last one's.

    Times of day wrap at midnight (a day with a leap second is a second longer), so "before" is at
    most ``OLD_EPOCH_WINDOW_S`` behind on the circle; a jump farther back is taken as the receiver's
    clock starting over (new), or its fixes would be refused until the clock caught up. Without a
    time on either, every sentence is new (nothing to compare)."""
    if fix_time is None or last_fix_time is None:
        return "new"
    day_s = _DAY_S + 1.0 if fix_time.fold or last_fix_time.fold else _DAY_S
    behind_s = (_time_of_day_s(last_fix_time) - _time_of_day_s(fix_time)) % day_s
    if behind_s == 0.0:
        return "same"
    return "old" if behind_s <= OLD_EPOCH_WINDOW_S else "new"


class SC30Driver(LineDevice):
    """Reads the SC-30 on ``port_path``; :meth:`sample` is the latest of everything it said.

    ``heading_window_s``: a lower-priority heading sentence is used only when
    no higher-priority one arrived within this time (so a compass sending
    THS and HDT is steered by THS, and HDT takes over if THS stops).
    Every quantity is stamped with the time it was measured, not the time it
    arrived (:mod:`autopilot.drivers.line_timing`): a heading at its tick
    (``heading_period_s`` apart, SPEC 10: 100 ms), the rest when its sentence
    began on the line.
    ``garbage_burst_lines`` / ``garbage_burst_bytes``: more rejected lines, or
    more bytes that no NMEA line can hold, than these within 1 s are a garbage
    burst (:class:`~autopilot.drivers.framing.GarbageDetector`): one
    ``nmea_garbage`` event when it starts, and :attr:`last_garbage_s` for the
    failsafe while it lasts.
    """

    name = "sc30"
    garbage_event = "nmea_garbage"

    def __init__(
        self,
        port_path: str,
        *,
        baudrate: int = 4800,
        clock: Clock,
        reconnect_min_s: float = 0.2,
        reconnect_max_s: float = 5.0,
        events: EventSink | None = None,
        heading_window_s: float = 0.5,
        heading_period_s: float = 0.1,
        garbage_burst_lines: int = 5,
        garbage_burst_bytes: int = 32,
        encapsulated=None,
    ) -> None:
        # encapsulated: AIS (!AIVDM) interleaved on the compass line goes there (an AisReceiver's feed_line)
        self._decoder = NmeaStreamDecoder(encapsulated=encapsulated)
        super().__init__(port_path, baudrate=baudrate, clock=clock, reconnect_min_s=reconnect_min_s,
                         reconnect_max_s=reconnect_max_s, events=events, garbage_burst_lines=garbage_burst_lines,
                         garbage_burst_bytes=garbage_burst_bytes)
        self._latest: dict[str, Stamped | None] = {}  # NavSample field -> value
        self.attitude: Stamped | None = None  # (pitch_rad, roll_rad), logged by nothing yet
        self._verdicts: dict[str, tuple[bool, float]] = {}  # position sentence kind -> (said valid, when)
        self.utc: Stamped | None = None
        self.updates = 0
        self._heading_window_s = float(heading_window_s)
        self._by_source: dict[str, Stamped] = {}
        self._fix_time = None  # UTC time of the epoch of the last position sentence
        self.old_epochs = 0  # position sentences refused for an epoch before the last one
        self._in_old_epochs = False
        self._wire = WireClock(baudrate)
        self._heading_period_s = float(heading_period_s)
        self._ticks: dict[str, TickClock] = {}  # heading sentence -> its measurement ticks

    # ------------------------------------------------------------------ public
    @property
    def stats(self) -> dict[str, int]:
        """Decoder line counters plus link counters (``reconnects`` = losses of the port)."""
        d = self._decoder.stats.as_dict()
        d.update(
            reconnects=self._link.losses,
            opens=self._link.opens,
            open_failures=self._link.open_failures,
            bytes_in=self._link.bytes_in,
            updates=self.updates,
            old_epochs=self.old_epochs,
        )
        return d

    # ------------------------------------------------------------------ decoding
    def _on_bytes(self, data: bytes) -> None:
        now_s = self._clock.now_s()
        for u, chars, after in self._decoder.feed_spans(data):
            self.apply(u, self.measured_s(u, now_s, chars, after))
        self._check_garbage(now_s, self._decoder.stats.dropped, self._decoder.invalid_bytes, stats=self.stats)

    def measured_s(self, u: NmeaUpdate, read_s: float, chars: int, after: int) -> float:
        """When the sentence was measured (line_timing.py): a heading at its tick, anything else when it began
        on the wire."""
        start_s, idle = self._wire.line(read_s, chars, after)
        if u.sentence not in HEADING_PRIORITY:
            return start_s
        ticks = self._ticks.get(u.sentence)
        if ticks is None:
            ticks = self._ticks[u.sentence] = TickClock(self._heading_period_s)
        return ticks.measured(start_s, idle)

    def sample(self) -> NavSample:
        """The latest of each quantity (:class:`autopilot.devices.NavSample`)."""
        return NavSample(**self._latest)

    @property
    def lines_dropped(self) -> int:
        return self._decoder.stats.dropped

    def apply(self, u: NmeaUpdate, now_s: float) -> None:
        """Fold one decoded sentence into the sample (public so a file replay can use it)."""
        self.updates += 1
        latest = self._latest
        src = u.sentence
        if src in HEADING_PRIORITY:
            self._by_source[src] = Stamped(u.heading_rad, now_s, src, bool(u.heading_valid))
            latest["heading_rad"] = self._best_heading(now_s)
        if u.lat_deg is not None or (src in POSITION_SENTENCES and u.status_valid is False):
            pos = None if u.lat_deg is None else (u.lat_deg, u.lon_deg)
            self._verdicts[src] = (bool(u.status_valid), now_s)
            valid = bool(u.status_valid) and pos is not None and all(
                ok for ok, t_s in self._verdicts.values() if now_s - t_s <= VERDICT_WINDOW_S)
            old = latest.get("position")
            order = epoch_order(u.fix_time, self._fix_time) if old is not None else "new"
            if order == "new" and u.fix_time is None and old is not None and old.value == pos:
                # no UTC time to tell epochs apart, and the very position of the last fix: a receiver repeating
                # its last solution (a time-less held fix looked fresh for as long as it was repeated)
                order = "same"
            if order == "same":
                # GGA, RMC and GLL of one epoch (same UTC time) are one measurement, dated by its first
                # sentence, however late a repeat of it comes (a held fix must age, not look fresh)
                if old.valid != valid:
                    latest["position"] = Stamped(pos, old.t_s, src, valid)
            elif order == "old":
                # an epoch before the last one (a replayed or buffered fix) is not news: refused
                self.old_epochs += 1
                if not self._in_old_epochs:
                    self._link.emit("nmea_old_epoch", sentence=src, epoch=u.fix_time.isoformat(),
                                    last_epoch=self._fix_time.isoformat())
                self._in_old_epochs = True
            else:
                latest["position"] = Stamped(pos, now_s, src, valid)
            if order != "old":
                self._in_old_epochs = False
                self._fix_time = u.fix_time
        if u.fix_quality is not None:
            latest["fix_quality"] = Stamped(u.fix_quality, now_s, src, bool(u.status_valid))
        if u.yaw_rate_rad_s is not None or src == "ROT":
            latest["yaw_rate_rad_s"] = Stamped(u.yaw_rate_rad_s, now_s, src, bool(u.status_valid))
        if u.sog_m_s is not None:
            latest["sog_m_s"] = Stamped(u.sog_m_s, now_s, src, bool(u.status_valid))
        if u.cog_rad is not None:
            latest["cog_rad"] = Stamped(u.cog_rad, now_s, src, bool(u.status_valid))
        if u.pitch_rad is not None or u.roll_rad is not None:
            self.attitude = Stamped((u.pitch_rad, u.roll_rad), now_s, src, True)
        if u.utc is not None:
            self.utc = Stamped(u.utc, now_s, src, True)

    def _best_heading(self, now_s: float) -> Stamped | None:
        for src in HEADING_PRIORITY:
            s = self._by_source.get(src)
            if s is not None and now_s - s.t_s <= self._heading_window_s:
                return s
        return None
