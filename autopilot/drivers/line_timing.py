"""When a sentence on a paced serial line was measured: its time on the wire, and the device's tick.

No I/O, no clock: read times come in. A device such as the SC-30 composes its sentences at measurement
ticks and sends them one after another at the baud rate. At 4800 baud its line is ~90 % busy
(docs/sc30.md), and the 10 Hz heading waits behind the 1 Hz sentences: it reaches the daemon 40-220 ms
after it was measured, by an amount that changes from tick to tick. Stamped on arrival, such a heading
is ~3 deg off during a 17 deg/s turn, a timing jitter the identification can only read as compass
noise (five calm closed-loop logs at 4800 baud came out ``unexplained``, the heading's wander at its
bound).

1. On the wire (:class:`WireClock`): a line's end came with the read that returned it, less the
   characters read after it; its characters took ``10 / baud`` s each (8N1), so it began at
   ``end - chars * char_s``. A line that began more than ``IDLE_GAP_S`` after the previous one ended
   found the line idle: the device sent it as soon as it had made it.
2. Periodic sentences (:class:`TickClock`): the device makes one every ``period_s`` on its own clock,
   and sends them in order. One that found the line idle was made when it began (an anchor); one that
   waited belongs to the tick after the previous one's, unless that tick would come after it began
   (then it too is an anchor). A sentence lost inside the device while the line is busy puts the next
   ones a tick early until the next anchor (at 4800 baud, within the second).

What a sentence that is not periodic (the 1 Hz fix) is stamped with: the time it began on the wire,
which removes its own transmission (~150 ms for a GGA at 4800 baud) but not the wait before it.
"""

from __future__ import annotations

import math

__all__ = ["WireClock", "TickClock", "IDLE_GAP_S"]

# a gap this long before a line means the line was idle (reads are late by a few milliseconds on a busy
# machine: a smaller gap is as likely to be read jitter as an idle line)
IDLE_GAP_S = 0.010
TICK_SLACK_S = 0.002  # a tick this much after the line began is read jitter, not a slipped grid


class WireClock:
    """The span on the wire of each line read from one serial line (module docstring, 1)."""

    def __init__(self, baudrate: int) -> None:
        self.char_s = 10.0 / float(baudrate)  # 8N1: ten bits a character
        self._last_end_s = -math.inf

    def line(self, read_s: float, chars: int, after: int) -> tuple[float, bool]:
        """(the time the line began on the wire, whether the line was idle before it) for a line of ``chars``
        characters (line end included) whose end was followed by ``after`` more characters in the read
        returned at ``read_s``."""
        end_s = read_s - after * self.char_s
        start_s = end_s - chars * self.char_s
        idle = start_s > self._last_end_s + IDLE_GAP_S
        self._last_end_s = max(self._last_end_s, end_s)
        return start_s, idle


class TickClock:
    """The measurement ticks of one periodic sentence (module docstring, 2)."""

    def __init__(self, period_s: float, *, max_wait_s: float = 0.5) -> None:
        self.period_s = float(period_s)
        self.max_wait_s = float(max_wait_s)  # a device's output buffer holds no more (docs/sc30.md)
        self._last_tick_s: float | None = None

    def measured(self, start_s: float, idle: bool) -> float:
        """The tick at which the sentence that began on the wire at ``start_s`` was made."""
        tick = None if self._last_tick_s is None else self._last_tick_s + self.period_s
        if idle or tick is None or tick > start_s + TICK_SLACK_S or start_s - tick > self.max_wait_s:
            tick = start_s
        tick = min(tick, start_s)
        self._last_tick_s = tick
        return tick
