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
   and sends them in order. The grid of its ticks is held by the sentences that found the line idle
   (each began at its tick plus a read latency that is never negative: the least-delayed of the recent
   ones marks the grid). One that waited belongs to the tick after the previous one's; one that found
   the line idle to the last tick before it began. A sentence lost inside the device while the line is
   busy puts the next ones a tick early until the next idle one (at 4800 baud, within the second).

What a sentence that is not periodic (the 1 Hz fix) is stamped with: the time it began on the wire,
which removes its own transmission (~150 ms for a GGA at 4800 baud) but not the wait before it.
"""

from __future__ import annotations

import math
from collections import deque

__all__ = ["WireClock", "TickClock", "IDLE_GAP_S"]

# a gap this long before a line means the line was idle. Reads are late by a few milliseconds on a busy
# machine, and more with a sped-up clock: a queued heading read 10 ms later than the line before it
# looked idle and was put on a tick two periods late (a pseudo-terminal at 4x). At 4800 baud the idle
# gaps before a heading are ~18 and ~60 ms (docs/sc30.md's load), at 38400 ~60-80 ms.
IDLE_GAP_S = 0.030
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
    """The measurement ticks of one periodic sentence (module docstring, 2).

    The ticks lie on a grid ``period_s`` apart. Its phase is held by the sentences that found the line
    idle: each began at its tick plus the daemon's read latency, which is never negative, so the grid sits
    at the least-delayed of the last ``phase_window`` of them (a late read on a busy machine moves
    nothing). A sentence's tick is the tick after the previous one's while that is not after it began;
    an idle one, or one that waited longer than ``max_wait_s``, takes the last grid tick at or before it
    began (an idle line sends within a period of the tick)."""

    def __init__(self, period_s: float, *, max_wait_s: float = 0.5, phase_window: int = 16) -> None:
        self.period_s = float(period_s)
        self.max_wait_s = float(max_wait_s)  # a device's output buffer holds no more (docs/sc30.md)
        self._grid_s: float | None = None  # a time on the grid
        self._residuals: deque[float] = deque(maxlen=int(phase_window))  # idle starts minus their grid tick
        self._last_tick_s: float | None = None

    def _offset(self, start_s: float) -> float:
        """``start_s`` minus the grid tick nearest below it (a start a hair before a tick: that tick)."""
        p = self.period_s
        off = (start_s - self._grid_s) % p
        return off - p if off > p - TICK_SLACK_S else off

    def _hold_phase(self, start_s: float) -> None:
        if self._grid_s is None:
            self._grid_s = start_s
        p = self.period_s
        self._residuals.append(((start_s - self._grid_s + 0.5 * p) % p) - 0.5 * p)
        shift = min(self._residuals)  # the least-delayed idle start defines the tick
        if shift:
            self._grid_s += shift
            for k in range(len(self._residuals)):
                self._residuals[k] -= shift
            if self._last_tick_s is not None:  # the previous tick was on the old grid
                self._last_tick_s += shift

    def measured(self, start_s: float, idle: bool) -> float:
        """The tick at which the sentence that began on the wire at ``start_s`` was made."""
        if idle or self._grid_s is None:
            self._hold_phase(start_s)
        latest = start_s - self._offset(start_s)  # the last grid tick at or before it began
        nxt = None if self._last_tick_s is None else self._last_tick_s + self.period_s
        if nxt is None or nxt > start_s + TICK_SLACK_S or start_s - nxt > self.max_wait_s:
            tick = latest
        elif idle:
            tick = max(latest, nxt)  # made within a period before it began, and after the previous one
        else:
            tick = nxt
        if self._last_tick_s is not None and tick <= self._last_tick_s + TICK_SLACK_S:
            # not after the previous one's: the grid no longer fits (a device restarted its clock): it began here
            tick, self._grid_s = start_s, start_s
            self._residuals.clear()
        tick = min(tick, start_s + TICK_SLACK_S)
        self._last_tick_s = tick
        return tick
