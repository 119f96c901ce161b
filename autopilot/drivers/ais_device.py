"""An AIS receiver on a serial port of its own (38400 baud, IEC 61162-2): bytes in, a target table out.

The thin transport around :class:`autopilot.drivers.ais.AisReceiver` (the codec and the table,
no I/O), as :class:`autopilot.drivers.sc30.SC30Driver` is around the NMEA codec: it reconnects,
stamps every read with the injected clock and reports garbage bursts (``ais_garbage`` events,
:attr:`last_garbage_s`) from the AIS decoder's rejected lines and non-line bytes. When AIS comes
interleaved on the compass line instead, give an :class:`AisReceiver`'s ``feed_line`` to the
compass's :class:`~autopilot.drivers.nmea.NmeaStreamDecoder` as its ``encapsulated`` hook.
"""

from __future__ import annotations

from collections.abc import Callable

from autopilot.clock import Clock
from autopilot.devices import EventSink
from autopilot.drivers.ais import AisConfig, AisMessage, AisReceiver, AisTarget
from autopilot.drivers.line_device import LineDevice

__all__ = ["AisDriver"]


class AisDriver(LineDevice):
    """Reads an AIS receiver on ``port_path``; :meth:`targets` is the current traffic picture."""

    name = "ais"
    garbage_event = "ais_garbage"

    def __init__(
        self,
        port_path: str,
        *,
        clock: Clock,
        baudrate: int = 38400,
        config: AisConfig = AisConfig(),
        on_message: Callable[[AisMessage], None] | None = None,
        reconnect_min_s: float = 0.2,
        reconnect_max_s: float = 5.0,
        events: EventSink | None = None,
        garbage_burst_lines: int = 5,
        garbage_burst_bytes: int = 32,
    ) -> None:
        self.receiver = AisReceiver(config, on_message=on_message, clock_s=clock.now_s)
        super().__init__(port_path, baudrate=baudrate, clock=clock, reconnect_min_s=reconnect_min_s,
                         reconnect_max_s=reconnect_max_s, events=events, garbage_burst_lines=garbage_burst_lines,
                         garbage_burst_bytes=garbage_burst_bytes)

    def _on_bytes(self, data: bytes) -> None:
        now_s = self._clock.now_s()
        self.receiver.feed(data, now_s)
        self._check_garbage(now_s, self.receiver.stats.dropped, self.receiver.decoder.invalid_bytes, stats=self.stats)

    def targets(self) -> list[AisTarget]:
        """Targets with a position, stale ones dropped (now on the driver's clock)."""
        return self.receiver.targets(self._clock.now_s())

    @property
    def own(self) -> AisTarget | None:
        """Own ship as our transponder reports it (VDO), if it does."""
        return self.receiver.table.own

    @property
    def lines_dropped(self) -> int:
        return self.receiver.stats.dropped

    @property
    def stats(self) -> dict[str, int]:
        d = self.receiver.stats.as_dict()
        d.update(targets=len(self.receiver.table), reconnects=self._link.losses, opens=self._link.opens,
                 bytes_in=self._link.bytes_in)
        return d
