"""Injected time: a monotonic clock that can run faster than the wall clock.

Everything that needs "now" (drivers stamping received data, the control
loop's deadlines, the simulated devices) takes a :class:`Clock`, so bench
tests can run simulated time ``speedup`` times faster and pure code never
reads a clock at all.
"""

from __future__ import annotations

import asyncio
import time


class Clock:
    """Monotonic seconds since creation, scaled by ``speedup`` (1 = real time)."""

    def __init__(self, speedup: float = 1.0) -> None:
        if not (speedup > 0):
            raise ValueError(f"speedup: {speedup!r} must be > 0")
        self.speedup = float(speedup)
        self._t0 = time.monotonic()

    def now_s(self) -> float:
        """Seconds on this clock."""
        return (time.monotonic() - self._t0) * self.speedup

    def to_wall_s(self, duration_s: float) -> float:
        """A duration on this clock in real seconds."""
        return duration_s / self.speedup

    async def sleep_until(self, t_s: float) -> None:
        """Sleep until this clock reads ``t_s`` (returns at once if already past)."""
        delay_s = (t_s - self.now_s()) / self.speedup
        if delay_s > 0:
            await asyncio.sleep(delay_s)

    async def sleep(self, duration_s: float) -> None:
        """Sleep a duration measured on this clock."""
        await asyncio.sleep(max(0.0, duration_s) / self.speedup)
