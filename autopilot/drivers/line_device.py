"""What the SC-30 and Mbed drivers share (python-can's ``BusABC`` idea): a serial link that reconnects,
its byte counters, and garbage-burst detection the same way on both lines.

A subclass gives ``name`` and implements ``_on_bytes(data)``; it calls :meth:`_check_garbage`
after each read with its cumulative rejected lines and non-line bytes.
"""

from __future__ import annotations

from autopilot.clock import Clock
from autopilot.devices import EventSink
from autopilot.drivers.framing import GarbageDetector
from autopilot.drivers.serial_link import SerialLink

__all__ = ["LineDevice"]


class LineDevice:
    name = "serial"
    garbage_event = "garbage"

    def __init__(self, port_path: str, *, baudrate: int, clock: Clock, reconnect_min_s: float = 0.2,
                 reconnect_max_s: float = 5.0, events: EventSink | None = None, garbage_burst_lines: int = 5,
                 garbage_burst_bytes: int = 32) -> None:
        self._clock = clock
        self._link = SerialLink(port_path, baudrate=baudrate, clock=clock, on_bytes=self._on_bytes,
                                reconnect_min_s=reconnect_min_s, reconnect_max_s=reconnect_max_s, events=events,
                                name=self.name)
        self._garbage = GarbageDetector(max_lines=garbage_burst_lines, max_bytes=garbage_burst_bytes)

    def _on_bytes(self, data: bytes) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def port_path(self) -> str:
        return self._link.port_path

    @property
    def connected(self) -> bool:
        return self._link.connected

    @property
    def transport(self) -> SerialLink:
        """The serial link underneath (its byte counters)."""
        return self._link

    @property
    def last_garbage_s(self) -> float | None:
        """Clock time of the latest garbage seen during a burst on this line (None: no burst yet)."""
        return self._garbage.last_garbage_s

    def _check_garbage(self, now_s: float, bad_lines: int, bad_bytes: int, **context) -> None:
        """Feed the detector; one ``<garbage_event>`` event when a burst starts."""
        if self._garbage.feed(now_s, bad_lines, bad_bytes):
            lines, bad = self._garbage.window_counts()
            self._link.emit(self.garbage_event, bad_lines=lines, bad_bytes=bad, window_s=self._garbage.window_s, **context)

    async def run(self) -> None:
        await self._link.run()

    async def close(self) -> None:
        await self._link.close()
