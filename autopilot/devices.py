"""The daemon's two devices as typed interfaces, and the values that cross them (SI, stamped).

A compass (the SC-30 driver over its serial port) publishes one :class:`NavSample`;
a thruster link (the Mbed driver) takes one :class:`ThrustCommand` per cycle. The
control loop knows them only through :class:`Compass` and :class:`ThrusterLink`
(``typing.Protocol``, as python-can's ``BusABC``), so a simulated twin or a test
double is built the same way as the real driver. Drivers report events (port
opened or lost, garbage bursts) to an :data:`EventSink` they are given at
construction: ``sink(name, device=..., **fields)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

__all__ = ["Stamped", "NavSample", "ThrustCommand", "ZERO_THRUST", "Compass", "ThrusterLink", "EventSink", "age_s"]

EventSink = Callable[..., Any]


@dataclass(frozen=True)
class Stamped:
    """A received value, the clock time it arrived (s), the sentence it came from, its validity."""

    value: Any
    t_s: float
    source: str
    valid: bool


def age_s(s: Stamped | None, now_s: float) -> float:
    """How old a stamped value is at ``now_s`` (inf when never received)."""
    return math.inf if s is None else now_s - s.t_s


@dataclass(frozen=True)
class NavSample:
    """The latest of each navigation quantity the compass gave, in SI (None until first received).

    heading_rad: true heading [0, 2 pi), clockwise from north (the driver's best source);
    position: (lat_deg, lon_deg) of the last fix, None in a no-fix sentence; fix_quality: GGA;
    yaw_rate_rad_s: ROT, + = to starboard; sog_m_s, cog_rad: over ground.
    """

    heading_rad: Stamped | None = None
    position: Stamped | None = None
    fix_quality: Stamped | None = None
    yaw_rate_rad_s: Stamped | None = None
    sog_m_s: Stamped | None = None
    cog_rad: Stamped | None = None


@dataclass(frozen=True)
class ThrustCommand:
    """One cycle's command to both thrusters: thrust (N, negative = astern) and the signed PWM duty
    (%, negative = reverse) that gives it (SPEC 4). What the allocation produces, the Mbed gets and
    the log records."""

    thrust_port_n: float = 0.0
    thrust_stbd_n: float = 0.0
    duty_port_pct: float = 0.0
    duty_stbd_pct: float = 0.0

    @property
    def is_zero(self) -> bool:
        return self.duty_port_pct == 0.0 and self.duty_stbd_pct == 0.0


ZERO_THRUST = ThrustCommand()


@runtime_checkable
class Compass(Protocol):
    """What the loop needs of the heading/position sensor."""

    @property
    def connected(self) -> bool: ...

    @property
    def last_garbage_s(self) -> float | None: ...  # latest garbage seen in a burst (clock s)

    @property
    def lines_dropped(self) -> int: ...  # rejected lines so far

    def sample(self) -> NavSample: ...

    async def run(self) -> None: ...

    async def close(self) -> None: ...


@runtime_checkable
class ThrusterLink(Protocol):
    """What the loop needs of the thruster board."""

    @property
    def connected(self) -> bool: ...

    @property
    def last_garbage_s(self) -> float | None: ...

    @property
    def consecutive_missing(self) -> int: ...  # acknowledgements missing since the last one in time

    @property
    def disobeying(self) -> bool: ...  # those include OKs echoing other duties than sent

    @property
    def ack_missing(self) -> int: ...  # acknowledgements missing so far

    @property
    def answered(self) -> bool: ...  # at least one command acknowledged

    @property
    def battery_v(self) -> float | None: ...  # the battery voltage the board reports (V), None if it does not

    @property
    def battery_load_pct(self) -> tuple[float, float] | None: ...  # (port, stbd) duty % it was measured under

    def send(self, command: ThrustCommand) -> int: ...  # the sequence number, -1 if it could not be written

    async def wait_ack(self, seq: int, timeout_s: float) -> bool: ...

    async def run(self) -> None: ...

    async def close(self) -> None: ...
