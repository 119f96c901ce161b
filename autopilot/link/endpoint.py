"""MAVLink endpoints: UDP out, UDP in, a serial radio. Bytes in a bounded queue, bytes out without blocking.

    udpout:HOST:PORT   send to a ground station listening there (QGC's default 127.0.0.1:14550);
                       its replies come back to the same socket, and only its: datagrams from any other
                       address and port are dropped (read, a DISARM from any host disarmed the boat)
    udpin:ADDR:PORT    listen on that address only; reply to every peer heard in the last PEER_TIMEOUT_S
    /dev/PATH:BAUD     a telemetry radio (serial:/dev/PATH:BAUD too)

The datagram callback only queues bytes (dropping, and counting, beyond ``rx_queue_bytes``); the
link parses them in its own task, a slice at a time, so a flood never runs inside the control
loop's timing.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import ipaddress
import math
import os
import re
import socket
import threading
import time
from dataclasses import dataclass

__all__ = ["EndpointSpec", "parse_endpoint", "Endpoint", "UdpEndpoint", "SerialEndpoint", "open_endpoint"]

PEER_TIMEOUT_S = 10.0
STATION_RESOLVE_S = 10.0  # udpout: a datagram from elsewhere asks the station's name again, at most this often
SERIAL_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 921600)


@dataclass(frozen=True)
class EndpointSpec:
    kind: str  # "udpout", "udpin", "serial"
    host: str = ""
    port: int = 0
    path: str = ""
    baud: int = 0

    def __str__(self) -> str:
        return f"{self.path}:{self.baud}" if self.kind == "serial" else f"{self.kind}:{self.host}:{self.port}"


def parse_endpoint(url: str) -> EndpointSpec:
    """An endpoint from its URL; ValueError naming the URL and the forms allowed."""
    forms = "udpout:HOST:PORT, udpin:ADDR:PORT or /dev/PATH:BAUD"
    text = str(url).strip()
    if text.startswith("serial:"):
        text = text[len("serial:"):]
    if text.startswith(("udpout:", "udpin:")):
        kind, _, rest = text.partition(":")
        host, sep, port = rest.rpartition(":")
        if not sep or not host:
            raise ValueError(f"{url!r}: expected {kind}:HOST:PORT")
        try:
            port_n = int(port)
        except ValueError:
            raise ValueError(f"{url!r}: port {port!r} is not a number") from None
        if not 1 <= port_n <= 65535:
            raise ValueError(f"{url!r}: port {port_n} outside 1..65535")
        if re.fullmatch(r"[0-9.]+", host):  # a numeric address must be one (999.1.1.1 only failed every send)
            try:
                ipaddress.IPv4Address(host)
            except ValueError:
                raise ValueError(f"{url!r}: {host} is not an IPv4 address") from None
        return EndpointSpec(kind, host=host, port=port_n)
    if text.startswith("/"):
        path, sep, baud = text.rpartition(":")
        if not sep:
            raise ValueError(f"{url!r}: a serial radio needs its baud rate: /dev/PATH:BAUD")
        try:
            baud_n = int(baud)
        except ValueError:
            raise ValueError(f"{url!r}: baud rate {baud!r} is not a number") from None
        if baud_n not in SERIAL_BAUDS:
            raise ValueError(f"{url!r}: baud rate {baud_n} is not one of {', '.join(map(str, SERIAL_BAUDS))}")
        return EndpointSpec("serial", path=path, baud=baud_n)
    raise ValueError(f"{url!r}: not an endpoint ({forms})")


class Endpoint:
    """Received bytes queued (bounded), sends that never block."""

    # each received chunk holds whole frames (a datagram): a frame it leaves unfinished is damaged, and is not
    # completed from the next one; a byte stream (a radio) carries frames across reads
    framed = False

    def __init__(self, spec: EndpointSpec, rx_queue_bytes: int) -> None:
        self.spec = spec
        # (bytes, where they came from): the sender's UDP address, None for a radio. Two planners on one udpin port
        # may have the same system and component ids (QGC and Mission Planner are both 255/190): only the address
        # tells them apart
        self.rx: collections.deque[tuple[bytes, object]] = collections.deque()
        self.rx_bytes = 0
        self.rx_limit = int(rx_queue_bytes)
        self.rx_dropped = 0  # datagrams (or reads) dropped because the queue was full
        self.tx_errors = 0
        self.wakeup = asyncio.Event()

    def _queue(self, data: bytes, source=None) -> None:
        if self.rx_bytes + len(data) > self.rx_limit:
            self.rx_dropped += 1
            return
        self.rx.append((data, source))
        self.rx_bytes += len(data)
        self.wakeup.set()

    def take(self, max_bytes: int) -> list[tuple[bytes, object]]:
        """Up to about ``max_bytes`` of what was received, as it came (datagrams, or reads of a byte stream), each
        with its source (the sender's address; None for a radio)."""
        out = []
        n = 0
        while self.rx and n < max_bytes:
            chunk, source = self.rx.popleft()
            self.rx_bytes -= len(chunk)
            out.append((chunk, source))
            n += len(chunk)
        if not self.rx:
            self.wakeup.clear()
        return out

    async def open(self) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def send(self, data: bytes, to=None) -> None:  # pragma: no cover - interface
        """``to``: the source (from :meth:`take`) of the one station a reply is for; None: everyone."""
        raise NotImplementedError

    async def close(self) -> None:  # pragma: no cover - interface
        raise NotImplementedError


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, owner: UdpEndpoint) -> None:
        self.owner = owner

    def datagram_received(self, data: bytes, addr) -> None:
        if not self.owner.from_station(addr):
            return
        self.owner.peers[addr] = time.monotonic()
        self.owner._queue(data, addr)

    def error_received(self, exc: Exception) -> None:  # ICMP port unreachable: no ground station yet
        self.owner.tx_errors += 1


class UdpEndpoint(Endpoint):
    framed = True

    def __init__(self, spec: EndpointSpec, rx_queue_bytes: int) -> None:
        super().__init__(spec, rx_queue_bytes)
        self.transport: asyncio.DatagramTransport | None = None
        self.peers: dict = {}
        self.station: frozenset = frozenset()  # udpout: the ground station's addresses (_resolve_station)
        self.station_addr: tuple | None = None  # udpout: where to send (its first IPv4 address, the port)
        self._resolved_s = -math.inf
        self._resolving = False
        self.rx_foreign = 0  # udpout: datagrams dropped, not from the station

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        if self.spec.kind == "udpin":
            self.transport, _ = await loop.create_datagram_endpoint(
                lambda: _Datagrams(self), local_addr=(self.spec.host, self.spec.port))
        else:
            # not connected: a socket connected to HOST:PORT resolved the name once at start (a name not yet known
            # at boot stopped the daemon), took the resolver's first address (::1 for localhost on Debian, deaf to an
            # IPv4 station) and kept its source address across a network change (a review)
            self.transport, _ = await loop.create_datagram_endpoint(lambda: _Datagrams(self),
                                                                    local_addr=("0.0.0.0", 0))
            try:
                ipaddress.IPv4Address(self.spec.host)
                self._resolve_station()  # an address: at once
            except ValueError:
                self._resolve_later(now=True)  # a name: in its thread

    def _resolve_station(self) -> None:
        """The ground station's addresses (IPv4, as the socket: localhost is ::1 first on Debian, which an IPv4
        station never hears); none while its name cannot be resolved. Runs in a thread of its own for a name: on
        the event loop a resolver that does not answer stalls the control loop, and through asyncio's executor the
        lockstep bench (--speedup max) stalled after a few cycles."""
        self._resolved_s = time.monotonic()
        with contextlib.suppress(ValueError):  # an address already: nothing to ask
            self.station = frozenset({str(ipaddress.IPv4Address(self.spec.host))})
            self.station_addr = (self.spec.host, self.spec.port)
            return
        try:
            infos = socket.getaddrinfo(self.spec.host, self.spec.port, family=socket.AF_INET, type=socket.SOCK_DGRAM)
        except OSError:  # not known (yet): nothing sent or read until it is, asked again in STATION_RESOLVE_S
            self.station, self.station_addr = frozenset(), None
            return
        self.station = frozenset(info[4][0] for info in infos)
        self.station_addr = (infos[0][4][0], self.spec.port) if infos else None

    def _resolve_later(self, *, now: bool = False) -> None:
        """Ask the station's name again (at most every STATION_RESOLVE_S, in a thread): it may point elsewhere now
        (a DHCP lease), or be known at last (DNS up late at boot)."""
        if self._resolving or (not now and time.monotonic() - self._resolved_s <= STATION_RESOLVE_S):
            return
        self._resolving = True

        def work():
            try:
                self._resolve_station()
            finally:
                self._resolving = False

        threading.Thread(target=work, name="mavlink-resolve", daemon=True).start()

    def from_station(self, addr) -> bool:
        """A datagram from ``addr`` is read: udpin reads everyone's on its address; udpout only its station's (a
        DISARM from another host, or another port of this one, disarmed the boat: a new user's test of the link)."""
        if self.spec.kind != "udpout":
            return True
        if addr[0] in self.station and addr[1] == self.spec.port:
            return True
        self.rx_foreign += 1
        self._resolve_later()
        return False

    @property
    def local_port(self) -> int:
        return self.transport.get_extra_info("sockname")[1] if self.transport is not None else 0

    def send(self, data: bytes, to=None) -> None:
        if self.transport is None:
            return
        try:
            if self.spec.kind == "udpout":
                # to the resolved address: sent to the name, each datagram resolved it on the event loop (seconds
                # each while DNS did not answer: 11 cycles in a minute, a review)
                if self.station_addr is None:
                    self.tx_errors += 1
                    self._resolve_later()
                    return
                self.transport.sendto(data, self.station_addr)
            elif to is not None and to in self.peers:
                # a reply to one station of several on this port: a DENIED meant for a second planner went to the
                # one uploading too, with the same ids (both 255/190), and ended that station's upload
                self.transport.sendto(data, to)
            else:
                now = time.monotonic()
                for addr, seen in list(self.peers.items()):
                    if now - seen > PEER_TIMEOUT_S:
                        del self.peers[addr]
                    else:
                        self.transport.sendto(data, addr)
        except OSError:
            self.tx_errors += 1

    async def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
            self.transport = None


class SerialEndpoint(Endpoint):
    """A telemetry radio: pyserial, non-blocking, read by the event loop's reader callback."""

    def __init__(self, spec: EndpointSpec, rx_queue_bytes: int) -> None:
        super().__init__(spec, rx_queue_bytes)
        self.port = None

    async def open(self) -> None:
        import serial

        self.port = serial.Serial(self.spec.path, self.spec.baud, timeout=0, write_timeout=0)
        asyncio.get_running_loop().add_reader(self.port.fileno(), self._readable)

    def _readable(self) -> None:
        try:
            data = os.read(self.port.fileno(), 4096)
        except OSError:
            data = b""
        if data:
            self._queue(data)

    def send(self, data: bytes, to=None) -> None:  # a radio: one link, everyone on it hears
        if self.port is None:
            return
        try:
            os.write(self.port.fileno(), data)
        except (BlockingIOError, OSError):  # the radio's buffer is full: telemetry can wait, never the loop
            self.tx_errors += 1

    async def close(self) -> None:
        if self.port is not None:
            with contextlib.suppress(Exception):
                asyncio.get_running_loop().remove_reader(self.port.fileno())
            with contextlib.suppress(Exception):
                self.port.close()
            self.port = None


def open_endpoint(spec: EndpointSpec, rx_queue_bytes: int) -> Endpoint:
    return SerialEndpoint(spec, rx_queue_bytes) if spec.kind == "serial" else UdpEndpoint(spec, rx_queue_bytes)
