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

__all__ = ["SC30Driver", "HEADING_PRIORITY"]

HEADING_PRIORITY = ("THS", "HDT", "PFEC_GPatt")
POSITION_SENTENCES = ("GGA", "RMC", "GLL")


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
        self.utc: Stamped | None = None
        self.updates = 0
        self._heading_window_s = float(heading_window_s)
        self._by_source: dict[str, Stamped] = {}
        self._fix_time = None  # UTC time of the epoch of the last position sentence
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
            valid = bool(u.status_valid) and pos is not None
            old = latest.get("position")
            # GGA, RMC and GLL of one epoch (same UTC time) are one measurement: the first keeps its stamp
            same_epoch = (u.fix_time is not None and self._fix_time is not None and u.fix_time == self._fix_time
                          and u.fix_time.fold == self._fix_time.fold and old is not None
                          and old.valid == valid and now_s - old.t_s < 1.0)
            if not same_epoch:
                latest["position"] = Stamped(pos, now_s, src, valid)
            self._fix_time = u.fix_time
        if u.fix_quality is not None:
            latest["fix_quality"] = Stamped(u.fix_quality, now_s, src, u.fix_quality > 0)
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
