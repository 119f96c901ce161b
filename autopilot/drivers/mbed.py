"""Mbed thruster-board driver: send one command per cycle, match acknowledgements, reconnect.

Implements :class:`autopilot.devices.ThrusterLink`.

Protocol in docs/mbed-protocol.md (codec: :mod:`autopilot.drivers.mbed_protocol`).
:meth:`MbedDriver.send` never blocks and never raises for a transport
problem: a command that cannot be written returns -1 and is counted, and the
firmware's own stop timeout (0.5 s) stops the motors while the link is down.
"""

from __future__ import annotations

import asyncio
import re
from collections import OrderedDict
from typing import Any

from autopilot.clock import Clock
from autopilot.devices import EventSink, ThrustCommand
from autopilot.drivers.framing import LineFramer
from autopilot.drivers.line_device import LineDevice
from autopilot.drivers.mbed_protocol import (
    MAX_LINE_CHARS,
    Ack,
    ProtocolError,
    decode_ack,
    decode_command,
    encode_command,
)

__all__ = ["MbedDriver"]

ECHO_RUNS_DISTRUSTED = 2  # from the second run of disobeyed commands on, zero commands clear nothing
_SENT_RECENT = 1024  # sequence numbers remembered as ours (~100 s at 10 Hz)
_MAX_PENDING = 256  # commands awaiting an ack; older ones are counted missing
BATTERY_STALE_S = 2.0  # a battery voltage older than this is not reported
_ECHO_TOLERANCE_PCT = 0.05  # half the line's 0.1 %: an echo of what was sent matches exactly
# an NMEA 0183 sentence's start ($GPGGA, $HEHDT, !AIVDM): on the Mbed's port it is the compass (or an AIS receiver)
# talking, the two ports swapped in the configuration; "$MB" lines are the board's own
_NMEA_START = re.compile(rb"^[$!](?!MB)[A-Z][A-Z0-9]{4,5},")


def _is_command(line: bytes) -> bool:
    """A whole $MBCMD line (what the daemon sends), coming back."""
    try:
        decode_command(line)
    except ProtocolError:
        return False
    return True


def _signed_duty_pct(duty_pct: float, reverse: bool) -> float:
    """A duty as the line carries it (0.1 %), negative in reverse; 0 % is 0 either way."""
    d = round(float(duty_pct), 1)
    return -d if reverse and d else d


class MbedDriver(LineDevice):
    """Commands to the Mbed on ``port_path``; counts acks missing after ``ack_timeout_s``."""

    name = "mbed"
    garbage_event = "mbed_garbage"

    def __init__(
        self,
        port_path: str,
        *,
        baudrate: int = 115200,
        clock: Clock,
        reconnect_min_s: float = 0.2,
        reconnect_max_s: float = 5.0,
        events: EventSink | None = None,
        ack_timeout_s: float = 0.3,
        garbage_burst_lines: int = 5,
        garbage_burst_bytes: int = 32,
    ) -> None:
        self.ack_timeout_s = float(ack_timeout_s)
        super().__init__(port_path, baudrate=baudrate, clock=clock, reconnect_min_s=reconnect_min_s,
                         reconnect_max_s=reconnect_max_s, events=events, garbage_burst_lines=garbage_burst_lines,
                         garbage_burst_bytes=garbage_burst_bytes)
        self._seq = -1
        # seq -> (send time (Clock s), the signed duties sent (%), as the line carries them)
        self._pending: OrderedDict[int, tuple[float, float, float]] = OrderedDict()
        self._waiters: dict[int, list[asyncio.Future[bool]]] = {}
        self._acked_recent: OrderedDict[int, bool] = OrderedDict()  # seq -> applied (OK)
        self._framer = LineFramer(MAX_LINE_CHARS)
        self._malformed = 0
        self.nmea_lines = 0  # malformed lines that are NMEA sentences: another device's output on this port
        self.commands_echoed = 0  # our own $MBCMD lines coming back: a port that echoes (a loopback, a terminal)
        self._ack_missing = 0
        self._consecutive_missing = 0
        self.last_ack_seq: int | None = None
        self.last_ack: Ack | None = None
        self.last_ack_rx_s: float | None = None
        self._battery: tuple[float, float, float, float] | None = None  # (volts, received at, duties echoed, %)
        self.sent = 0
        self.send_failures = 0
        self.acks_ok = 0
        self.acks_rejected = 0
        self.acks_late = 0  # for a command of ours, after ack_timeout_s (already counted missing)
        self.acks_unexpected = 0  # for no command sent recently (a stray line, another program on the port)
        self.acks_mismatched = 0  # OK, but the duties echoed are not the ones sent
        self._mismatching = False  # the current run of missing acknowledgements includes such an OK
        self._echo_runs = 0  # runs of them this session
        self._sent_recent: OrderedDict[int, float] = OrderedDict()  # seq -> send time, the last _SENT_RECENT sent
        self._late_run = False  # a late ack was told since the last one in time
        self._unexpected_run = False

    # ------------------------------------------------------------------ properties
    @property
    def ack_missing(self) -> int:
        """Commands not acknowledged (OK) within ``ack_timeout_s``, cumulative."""
        self._expire(self._clock.now_s())
        return self._ack_missing

    @property
    def consecutive_missing(self) -> int:
        """Missing acks since the last command acknowledged in time."""
        self._expire(self._clock.now_s())
        return self._consecutive_missing

    @property
    def stats(self) -> dict[str, int]:
        return dict(
            sent=self.sent,
            send_failures=self.send_failures,
            acks_ok=self.acks_ok,
            acks_rejected=self.acks_rejected,
            acks_late=self.acks_late,
            acks_unexpected=self.acks_unexpected,
            acks_mismatched=self.acks_mismatched,
            ack_missing=self.ack_missing,
            bad_lines=self.bad_lines,
            nmea_lines=self.nmea_lines,
            commands_echoed=self.commands_echoed,
            reconnects=self._link.losses,
            opens=self._link.opens,
        )

    # ------------------------------------------------------------------ lifecycle
    async def close(self) -> None:
        await super().close()
        for futs in self._waiters.values():
            for f in futs:
                if not f.done():
                    f.set_result(False)
        self._waiters.clear()

    # ------------------------------------------------------------------ commands
    def send(self, command: ThrustCommand) -> int:
        """Encode and write one command (its signed duties); its seq, or -1 (counted) if it could not be written.

        Raises :class:`ProtocolError` only for a duty outside -100..100 % (a caller bug).
        """
        now_s = self._clock.now_s()
        self._expire(now_s)
        seq = (self._seq + 1) % 65536
        port, stbd = command.duty_port_pct, command.duty_stbd_pct
        line = encode_command(seq, abs(port), port < 0, abs(stbd), stbd < 0)
        self._seq = seq
        if not self._link.write(line):
            self.send_failures += 1
            return -1
        self.sent += 1
        self._pending.pop(seq, None)
        self._pending[seq] = (now_s, _signed_duty_pct(abs(port), port < 0), _signed_duty_pct(abs(stbd), stbd < 0))
        self._sent_recent.pop(seq, None)
        self._sent_recent[seq] = now_s
        while len(self._sent_recent) > _SENT_RECENT:
            self._sent_recent.popitem(last=False)
        self._acked_recent.pop(seq, None)
        while len(self._pending) > _MAX_PENDING:
            self._pending.popitem(last=False)
            self._count_missing()
        return seq

    async def wait_ack(self, seq: int, timeout_s: float) -> bool:
        """True when ``seq`` is acknowledged OK within ``timeout_s`` (Clock seconds)."""
        if seq < 0:
            return False
        if seq in self._acked_recent:
            return self._acked_recent[seq]
        fut: asyncio.Future[bool] = asyncio.get_running_loop().create_future()
        self._waiters.setdefault(seq, []).append(fut)
        # the timeout runs on the driver's clock (a lockstep clock has no fixed relation to wall time)
        timer = asyncio.ensure_future(self._clock.sleep(timeout_s))
        try:
            await asyncio.wait({fut, timer}, return_when=asyncio.FIRST_COMPLETED)
            return bool(fut.result()) if fut.done() and not fut.cancelled() else False
        finally:
            timer.cancel()
            futs = self._waiters.get(seq)
            if futs and fut in futs:
                futs.remove(fut)
                if not futs:
                    del self._waiters[seq]

    # ------------------------------------------------------------------ acks
    def _count_missing(self) -> None:
        self._ack_missing += 1
        self._consecutive_missing += 1

    def _expire(self, now_s: float) -> None:
        while self._pending:
            seq, (t_s, _, _) = next(iter(self._pending.items()))
            if now_s - t_s <= self.ack_timeout_s:
                break
            self._pending.popitem(last=False)
            self._count_missing()

    def _on_bytes(self, data: bytes) -> None:
        now_s = self._clock.now_s()
        for line in self._framer.feed(data):
            self._line(line, now_s)
        self._check_garbage(now_s, self.bad_lines, self._framer.invalid_bytes)

    @property
    def bad_lines(self) -> int:
        """Lines from the Mbed that are not valid protocol lines (malformed or too long), cumulative."""
        return self._malformed + self._framer.too_long

    def _line(self, line: bytes, now_s: float) -> None:
        try:
            ack = decode_ack(line)
        except ProtocolError:
            self._malformed += 1
            if _NMEA_START.match(line):
                self.nmea_lines += 1
            return
        if ack is None:
            if _is_command(line):  # another $MB line is a newer firmware's status: ignored, as the protocol says
                self.commands_echoed += 1
            return
        self._expire(now_s)
        if ack.seq not in self._pending:
            self._not_pending(ack, now_s)
            return
        # only an answer to a command waiting for one is believed, its battery voltage included: stray OKs
        # claiming 12.6 V once hid a battery at 10.5 V (and ones claiming 9 V stopped a mission)
        self.last_ack, self.last_ack_rx_s = ack, now_s
        if ack.battery_v is not None:
            self._battery = (ack.battery_v, now_s, float(ack.duty_port_pct or 0.0), float(ack.duty_stbd_pct or 0.0))
        self._late_run = self._unexpected_run = False
        applied = ack.ok
        if ack.ok and not self._echo_matches(ack, *self._pending[ack.seq][1:]):
            # the board says OK but set something else (a hung PWM, a firmware bug): not obeyed, so
            # counted as missing, which the failsafe acts on as on silence
            _, sent_port, sent_stbd = self._pending.pop(ack.seq)
            self.acks_mismatched += 1
            self._count_missing()
            applied = False
            if not self._mismatching:
                self._echo_runs += 1
                self._link.emit("mbed_echo_mismatch", seq=ack.seq, sent_pct=[sent_port, sent_stbd],
                                echoed_pct=[_signed_duty_pct(ack.duty_port_pct, ack.reverse_port),
                                            _signed_duty_pct(ack.duty_stbd_pct, ack.reverse_stbd)])
            self._mismatching = True
        elif ack.ok:
            _, sent_port, sent_stbd = self._pending.pop(ack.seq)
            self.acks_ok += 1
            self.last_ack_seq = ack.seq
            if not self._mismatching or sent_port != sent_stbd:
                self._consecutive_missing = 0
                self._mismatching = False
            elif sent_port == 0.0 and self._echo_runs < ECHO_RUNS_DISTRUSTED:
                self._consecutive_missing = 0  # a first run is forgiven on zeros: the failsafe's stop clears it
                self._mismatching = False
            # else: equal duties echo right even from a board with its channels swapped, so they prove nothing.
            # A board that has disobeyed twice is not cleared by zero commands: it was judged healthy on zeros,
            # resumed, drove the boat wrong for half a second and tripped again, every ~3 s for as long as it
            # lasted. Nor does an equal pair end a run: one (56.7 %, 56.7 %) among a swapped board's first
            # disobeyed commands made them two runs, and the first trip already held for good
        else:
            del self._pending[ack.seq]
            self.acks_rejected += 1
            self._count_missing()
        self._acked_recent[ack.seq] = applied
        while len(self._acked_recent) > _MAX_PENDING:
            self._acked_recent.popitem(last=False)
        for fut in self._waiters.pop(ack.seq, []):
            if not fut.done():
                fut.set_result(applied)

    def _not_pending(self, ack: Ack, now_s: float) -> None:
        """An acknowledgement for no command waiting: ours but late (already counted missing: the count stands,
        the log says the board answers late, not that it is silent), or for nothing sent recently. Neither's
        content is used; each kind is told once until an answer comes in time."""
        sent_s = self._sent_recent.get(ack.seq)
        if sent_s is not None:
            self.acks_late += 1
            if not self._late_run:
                self._late_run = True
                self._link.emit("mbed_ack_late", seq=ack.seq, late_ms=round((now_s - sent_s) * 1e3, 1),
                                ack_timeout_ms=round(self.ack_timeout_s * 1e3, 1))
            self._acked_recent[ack.seq] = ack.ok  # a stop waiting longer than ack_timeout_s takes it (as before)
            while len(self._acked_recent) > _MAX_PENDING:
                self._acked_recent.popitem(last=False)
            for fut in self._waiters.pop(ack.seq, []):
                if not fut.done():
                    fut.set_result(ack.ok)
            return
        self.acks_unexpected += 1
        if not self._unexpected_run:
            self._unexpected_run = True
            self._link.emit("mbed_unexpected_ack", seq=ack.seq, battery_v=ack.battery_v)

    @staticmethod
    def _echo_matches(ack: Ack, sent_port_pct: float, sent_stbd_pct: float) -> bool:
        """The OK's echoed duties are the ones sent (both carried with 0.1 % on the line)."""
        return (abs(_signed_duty_pct(ack.duty_port_pct, ack.reverse_port) - sent_port_pct) < _ECHO_TOLERANCE_PCT
                and abs(_signed_duty_pct(ack.duty_stbd_pct, ack.reverse_stbd) - sent_stbd_pct) < _ECHO_TOLERANCE_PCT)

    @property
    def battery_v(self) -> float | None:
        """The battery voltage of the last acknowledgement that carried one (V), if younger than
        BATTERY_STALE_S; None when the firmware does not report it (old firmware) or the line went quiet."""
        if self._battery is None or self._clock.now_s() - self._battery[1] > BATTERY_STALE_S:
            return None
        return self._battery[0]

    @property
    def battery_load_pct(self) -> tuple[float, float] | None:
        """(port, starboard) duty (%) the board had applied when it measured :attr:`battery_v`: the voltage's load.
        Found by fault injection: with the board silent, its last voltage under full thrust was judged against
        the zero command sent since, as a resting voltage, and tripped battery_critical on a full battery."""
        return None if self.battery_v is None else (self._battery[2], self._battery[3])

    @property
    def disobeying(self) -> bool:
        """The acknowledgements missing now include OKs that echoed other duties than sent."""
        return self._mismatching and self._consecutive_missing > 0

    @property
    def answered(self) -> bool:
        """At least one command was acknowledged OK (the board is there and obeys)."""
        return self.last_ack_seq is not None

    def describe(self) -> dict[str, Any]:
        return dict(path=self.port_path, connected=self.connected, **self.stats)
