"""Injected time: the wall clock (sped up on the bench) or a simulated clock that the run steps.

Everything that needs "now" (drivers stamping received data, the control
loop's deadlines, the simulated devices) takes a clock, and pure code never
reads one. Two kinds, one interface (``now_s``, ``sleep_until``, ``sleep``,
``wait_for``, ``wall_elapsed_s``):

- :class:`Clock`: monotonic seconds since creation, scaled by ``speedup``
  (1 = real time; the boat runs on this, and ``--sim`` for timing work);
- :class:`SimClock`: simulated seconds that advance only when every task is
  waiting for a later time and the I/O in flight has been delivered
  (``quiet()``), jumping straight to the earliest wake-up. The daemon and the
  simulated devices then run in lockstep (ArduPilot SITL's lockstep): as fast
  as the machine allows, and the same run on a busy machine as on an idle one
  (``autopilot run --sim --speedup max``). Tests step it by hand with
  :meth:`SimClock.advance_to`.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import math
import time
from collections.abc import Awaitable, Callable
from typing import TypeVar

__all__ = ["Clock", "SimClock"]

T = TypeVar("T")


class Clock:
    """Monotonic seconds since creation, scaled by ``speedup`` (1 = real time)."""

    def __init__(self, speedup: float = 1.0) -> None:
        if not (speedup > 0) or not math.isfinite(speedup):
            raise ValueError(f"speedup: {speedup!r} must be a finite number > 0")
        self.speedup = float(speedup)
        self._t0 = time.monotonic()

    def now_s(self) -> float:
        """Seconds on this clock."""
        return (time.monotonic() - self._t0) * self.speedup

    def wall_elapsed_s(self) -> float:
        """Real seconds since the clock started."""
        return time.monotonic() - self._t0

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

    async def wait_for(self, aw: Awaitable[T], timeout_s: float) -> T:
        """``aw``'s result, or TimeoutError after ``timeout_s`` on this clock."""
        return await asyncio.wait_for(aw, self.to_wall_s(timeout_s))


class SimClock:
    """Simulated seconds, advanced in lockstep with the tasks that sleep on it (see the module docstring).

    ``quiet()``: True when nothing is in flight between the parties (every byte written to a
    pseudo-terminal has been read at the other end); time does not advance before it, up to
    ``settle_limit_s`` of wall time per step (then it advances anyway and counts a
    ``settle_timeouts``). Start :meth:`drive` as a task; it stops with :meth:`stop`.
    """

    speedup = math.inf  # as fast as the machine allows

    def __init__(self, *, quiet: Callable[[], bool] | None = None, settle_limit_s: float = 1.0) -> None:
        self._now = 0.0
        self._sleepers: list[tuple[float, int, asyncio.Future]] = []
        self._order = itertools.count()
        self._quiet = quiet or (lambda: True)
        self._settle_limit_s = float(settle_limit_s)
        self._stopped = False
        self._wall_t0 = time.monotonic()
        self.steps = 0
        self.settle_timeouts = 0

    def set_quiet(self, quiet: Callable[[], bool]) -> None:
        self._quiet = quiet

    def now_s(self) -> float:
        return self._now

    def wall_elapsed_s(self) -> float:
        return time.monotonic() - self._wall_t0

    def to_wall_s(self, duration_s: float) -> float:  # pragma: no cover - no fixed relation in lockstep
        return 0.0

    async def sleep_until(self, t_s: float) -> None:
        if t_s <= self._now:
            await asyncio.sleep(0)
            return
        fut = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (float(t_s), next(self._order), fut))
        await fut

    async def sleep(self, duration_s: float) -> None:
        await self.sleep_until(self._now + max(0.0, duration_s))

    async def wait_for(self, aw: Awaitable[T], timeout_s: float) -> T:
        task = asyncio.ensure_future(aw)
        timer = asyncio.ensure_future(self.sleep(timeout_s))
        try:
            done, _ = await asyncio.wait({task, timer}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            timer.cancel()
        if task in done:
            return task.result()
        task.cancel()
        raise asyncio.TimeoutError

    def advance_to(self, t_s: float) -> None:
        """Tests: move time on to ``t_s`` and wake every sleeper due by then (no settling)."""
        while self._sleepers and self._sleepers[0][0] <= t_s:
            t, _, fut = heapq.heappop(self._sleepers)
            self._now = max(self._now, t)
            if not fut.done():
                fut.set_result(None)
        self._now = max(self._now, float(t_s))

    async def _settle(self) -> None:
        for _ in range(3):  # let ready callbacks and the I/O the selector has for us run
            await asyncio.sleep(0)
        deadline = time.monotonic() + self._settle_limit_s
        while not self._quiet():
            if time.monotonic() > deadline:
                self.settle_timeouts += 1
                return
            await asyncio.sleep(0.0002)  # bytes still in the kernel's pty buffers
            for _ in range(2):
                await asyncio.sleep(0)

    async def drive(self) -> None:
        """Advance time sleeper by sleeper until :meth:`stop`."""
        while not self._stopped:
            await self._settle()
            while self._sleepers and self._sleepers[0][2].done():  # cancelled sleepers
                heapq.heappop(self._sleepers)
            if not self._sleepers:
                await asyncio.sleep(0.001)  # everyone is waiting on something else (a subprocess, a signal)
                continue
            t, _, fut = heapq.heappop(self._sleepers)
            self._now = max(self._now, t)
            self.steps += 1
            fut.set_result(None)

    def stop(self) -> None:
        self._stopped = True
