"""Byte streams to lines, and garbage bursts on a serial line: shared by every line-based driver.

:class:`LineFramer` (no I/O) cuts a byte stream at LF into lines, keeps a
partial line between calls, discards a line longer than its limit up to the
next LF (a stream with no newline cannot grow memory), and counts the bytes
that can never appear in an NMEA-style line (anything but printable ASCII,
CR and LF), as they arrive, before any line is complete. The NMEA decoder,
the Mbed driver and the simulated Mbed all frame with it.

:class:`GarbageDetector` (no clock: times are passed in) decides when a line
carries a burst of garbage: more than ``max_lines`` rejected lines, or more
than ``max_bytes`` non-line bytes, within ``window_s``. The byte count is what
catches garbage at the real line rate: at 4800 baud random bytes contain a
line end only every ~256 bytes, about two rejected lines a second, which a
line count alone never calls a burst, while ~300 of the 480 bytes a second
are not ASCII. Clean NMEA has none; a single flipped bit gives one.
"""

from __future__ import annotations

import math
import re
from collections import deque

__all__ = ["LineFramer", "GarbageDetector", "LINE_BYTES", "xor_checksum", "checked_body"]

LINE_BYTES = bytes(range(0x20, 0x7F)) + b"\r\n"  # what a line-based protocol may carry


def xor_checksum(body: str) -> str:
    """NMEA 0183's checksum (also the Mbed protocol's): XOR of the characters between ``$`` and ``*``,
    as two upper-case hex digits."""
    c = 0
    for ch in body.encode("ascii"):
        c ^= ch
    return f"{c:02X}"


_HEX2 = re.compile(r"[0-9A-Fa-f]{2}\Z")
_BODY = re.compile(r"[\x20-\x7e]*\Z")


def checked_body(line: str, lead: str, *, checksum_error: type[Exception], sentence_error: type[Exception]) -> str:
    """The body of ``<lead>body*hh`` (CR/LF around it allowed) once its framing and checksum are right:
    NMEA's ``$`` and AIS's ``!`` sentences alike. Raises ``checksum_error`` for a missing, malformed or
    wrong checksum, ``sentence_error`` for the wrong lead or a reserved or non-printable character."""
    s = line.strip("\r\n")
    if not s.startswith(lead):
        raise sentence_error(f"does not start with {lead!r}")
    star = s.rfind("*")
    if star < 0:
        raise checksum_error("no '*hh' checksum")
    body, given = s[1:star], s[star + 1 :]
    if not _HEX2.match(given):
        raise checksum_error(f"malformed checksum {given!r}")
    if not _BODY.match(body) or any(c in body for c in "$!*\\"):
        raise sentence_error("reserved or non-printable character in sentence")
    if given.upper() != xor_checksum(body):
        raise checksum_error(f"checksum {given.upper()} != {xor_checksum(body)}")
    return body


class LineFramer:
    """Bytes in (any chunking), complete lines out (without the LF; a CR before it is kept; with ``cr_ends_line``
    a CR not followed by LF ends a line too, and is left out of it)."""

    def __init__(self, max_line_chars: int, *, cr_ends_line: bool = False) -> None:
        self.max_line_chars = int(max_line_chars)
        # a CR followed by anything but CR or LF ends a line too: receivers that end sentences with CR alone (set so,
        # or a terminal program's capture) ran every sentence into one overlong line, all discarded as too long.
        # A CR as the last byte read waits for the next byte (CRLF split between two reads stays one line end).
        self.cr_ends_line = bool(cr_ends_line)
        self._buf = bytearray()
        self._overflow = False
        self.too_long = 0  # lines discarded for their length
        self.invalid_bytes = 0  # bytes outside printable ASCII, CR, LF, counted on arrival

    def feed(self, data: bytes) -> list[bytes]:
        return [line for line, _, _ in self.feed_spans(data)]

    def feed_spans(self, data: bytes) -> list[tuple[bytes, int, int]]:
        """Complete lines with where they sat in the stream: (line, its characters with the LF, the characters
        of ``data`` after its LF). A serial driver times a line from them (line_timing.py)."""
        self.invalid_bytes += len(data.translate(None, LINE_BYTES))
        self._buf += data
        lines: list[tuple[bytes, int, int]] = []
        start = 0
        while True:
            nl = self._buf.find(b"\n", start)
            if self.cr_ends_line:
                limit = nl if nl >= 0 else len(self._buf)
                cr = self._buf.find(b"\r", start, limit)
                while cr >= 0:
                    if cr + 1 < len(self._buf) and self._buf[cr + 1] not in b"\r\n":
                        nl = cr
                        break
                    cr = self._buf.find(b"\r", cr + 1, limit)
            if nl < 0:
                break
            line = bytes(self._buf[start:nl])
            chars, after = nl + 1 - start, len(self._buf) - nl - 1
            start = nl + 1
            if self._overflow:  # the tail of an overlong line: already counted
                self._overflow = False
                continue
            if len(line.rstrip(b"\r")) > self.max_line_chars:
                self.too_long += 1
                continue
            lines.append((line, chars, after))
        del self._buf[:start]
        if len(self._buf) > self.max_line_chars + 1:  # + 1: a CR may precede the LF
            if not self._overflow:
                self.too_long += 1
            self._overflow = True
            self._buf.clear()
        return lines

    def clear(self) -> None:
        """Forget a partial line (the port was reopened)."""
        self._buf.clear()
        self._overflow = False


class GarbageDetector:
    """Burst of garbage: > ``max_lines`` rejected lines or > ``max_bytes`` non-line bytes within ``window_s``.

    Feed it the cumulative counters after every read. :attr:`last_garbage_s` is the time the
    latest garbage was seen during a burst (None before the first burst): the failsafe holds
    its fault for ``garbage_hold_s`` after that, so one short burst holds it that long, and a
    line that keeps spewing garbage holds it until it stops. A burst ends when no garbage has
    been seen for ``window_s``.
    """

    def __init__(self, *, max_lines: int, max_bytes: int, window_s: float = 1.0) -> None:
        self.max_lines = int(max_lines)
        self.max_bytes = int(max_bytes)
        self.window_s = float(window_s)
        self._events: deque[tuple[float, int, int]] = deque()  # (t_s, new bad lines, new bad bytes)
        self._lines_seen = 0
        self._bytes_seen = 0
        self._in_burst = False
        self._last_bad_s = -math.inf
        self.last_garbage_s: float | None = None
        self.bursts = 0

    def feed(self, now_s: float, bad_lines_total: int, bad_bytes_total: int) -> bool:
        """Update with the cumulative counters; True when a new burst starts now."""
        d_lines = bad_lines_total - self._lines_seen
        d_bytes = bad_bytes_total - self._bytes_seen
        self._lines_seen, self._bytes_seen = bad_lines_total, bad_bytes_total
        if d_lines > 0 or d_bytes > 0:
            self._events.append((now_s, d_lines, d_bytes))
            self._last_bad_s = now_s
        while self._events and self._events[0][0] <= now_s - self.window_s:
            self._events.popleft()
        if self._in_burst and now_s - self._last_bad_s > self.window_s:
            self._in_burst = False
        started = False
        if not self._in_burst:
            lines = sum(e[1] for e in self._events)
            bad_bytes = sum(e[2] for e in self._events)
            if lines > self.max_lines or bad_bytes > self.max_bytes:
                self._in_burst = started = True
                self.bursts += 1
        if self._in_burst and (d_lines > 0 or d_bytes > 0 or started):
            self.last_garbage_s = now_s
        return started

    @property
    def in_burst(self) -> bool:
        return self._in_burst

    def window_counts(self) -> tuple[int, int]:
        """(rejected lines, non-line bytes) in the current window."""
        return sum(e[1] for e in self._events), sum(e[2] for e in self._events)
