"""A serial port opened by path, read through the event loop, reopened when it vanishes.

Shared transport of the SC-30 and Mbed drivers (SPEC section 10): pyserial
opens the port non-blocking (never blocking I/O in the loop), bytes arrive
through ``loop.add_reader`` and go to ``on_bytes``. A USB device that
vanishes makes ``read`` fail with EIO/ENXIO (or return EOF): the link then
closes the port, reports ``port_lost`` and tries to reopen the path with
exponential back-off (``reconnect_min_s`` doubling to ``reconnect_max_s``),
for as long as it runs. Nothing but CancelledError leaves :meth:`run`.
"""

from __future__ import annotations

import asyncio
import errno
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import serial

from autopilot.clock import Clock
from autopilot.devices import EventSink

__all__ = ["SerialLink", "open_port", "open_problem"]

_READ_CHUNK = 65536


def _pending(fd: int) -> int:
    """Bytes waiting to be read on a tty (FIONREAD)."""
    import fcntl
    import struct
    import termios

    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def open_port(path: str, baudrate: int, **kwargs) -> serial.Serial:
    """The port opened with an exclusive lock (flock): two daemons once both drove one Mbed, their commands
    interleaved, and a wiring check (``autopilot nmea``) on a running boat's port took bytes from its daemon."""
    ser = serial.Serial(baudrate=baudrate, exclusive=True, **kwargs)
    ser.port = path
    ser.open()  # POSIX pyserial opens with O_NONBLOCK
    return ser


CLAIM_PREFIX = "wamv-autopilot-port:"


def claim_port(path: str):
    """Claim a device port for this process: abstract Unix sockets (Linux) named after the port's name as
    configured and its real path now, released when the process exits however it ends. Returns the sockets
    to keep open while the port is this process's; None when another process holds a claim. Unlike
    /proc/locks (which the unit's ProcSubset=pid hides) they are seen across users and mount namespaces. The
    name as configured because a USB re-enumeration moves /dev/sc30 to another ttyUSB: claimed by its real
    path alone, a second daemon started after a hub reset was not refused. An error other than "in use" (no
    abstract sockets here) returns []: nothing known, nothing refused."""
    import hashlib
    import socket

    claims = []
    for name in dict.fromkeys((os.path.abspath(path), os.path.realpath(path))):
        claim = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            claim.bind("\0" + CLAIM_PREFIX + hashlib.sha256(name.encode()).hexdigest()[:32])
        except OSError as exc:
            claim.close()
            if exc.errno == errno.EADDRINUSE:
                for c in claims:
                    c.close()
                return None
            continue
        claims.append(claim)
    return claims


def lock_holders(path: str) -> list[int]:
    """The processes holding a flock on ``path`` (the lock :func:`open_port` takes), from Linux's /proc/locks;
    empty where the file or the table cannot be read."""
    try:
        st = os.stat(path)
        table = Path("/proc/locks").read_text()
    except OSError:
        return []
    inode = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    pids = []
    for line in table.splitlines():
        f = line.split()
        if len(f) >= 6 and f[1] == "FLOCK" and f[5] == inode and f[4].isdigit():
            pids.append(int(f[4]))
    return pids


def autopilot_daemon(pid: int) -> str | None:
    """The command line of process ``pid`` when it is an ``autopilot run`` (console script or ``-m
    autopilot``), else None."""
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return None
    args = [a.decode(errors="replace") for a in argv if a]
    for k, a in enumerate(args[:-1]):
        named = a == "autopilot" or a.endswith("/autopilot")
        if named and args[k + 1] == "run":
            return " ".join(args)
    return None


def open_problem(path: str, exc: BaseException) -> str:
    """Why ``path`` could not be opened, in words an operator can act on (pyserial says 'Could not configure
    port: (25, ...)' of a regular file and 'Errno 13' of a port the user may not open)."""
    import stat

    code, text = getattr(exc, "errno", None), str(exc)
    if code in (errno.EAGAIN, errno.EWOULDBLOCK) or "exclusively lock" in text:
        return "in use by another program (another autopilot daemon, or a terminal program, has it open)"
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "no such device (not plugged in, or another name: ls -l /dev/serial/by-id/)"
    except OSError as err:
        return err.strerror or text
    if stat.S_ISDIR(st.st_mode):
        return "a directory, not a serial device"
    if not stat.S_ISCHR(st.st_mode):
        return "a regular file, not a serial device"
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return "permission denied (add the user to the dialout group and log in again; the service: SupplementaryGroups)"
    if code == errno.ENOTTY or "Inappropriate ioctl" in text:
        return "not a serial device (a character device without a serial line, such as /dev/null)"
    return text


class SerialLink:
    """One serial port, reconnecting. ``on_bytes(data)`` runs in the event loop."""

    def __init__(
        self,
        port_path: str,
        *,
        baudrate: int,
        clock: Clock,
        on_bytes: Callable[[bytes], None],
        reconnect_min_s: float = 0.2,
        reconnect_max_s: float = 5.0,
        events: EventSink | None = None,
        name: str = "serial",
    ) -> None:
        if not (0 < reconnect_min_s <= reconnect_max_s):
            raise ValueError("need 0 < reconnect_min_s <= reconnect_max_s")
        self.port_path = port_path
        self.baudrate = int(baudrate)
        self.name = name
        self._clock = clock
        self._on_bytes = on_bytes
        self._events = events
        self._min_s = float(reconnect_min_s)
        self._max_s = float(reconnect_max_s)
        self._serial: serial.Serial | None = None
        self._fd: int | None = None
        self._lost: asyncio.Event | None = None
        self._closing = False
        self._failure_announced = False
        self.opens = 0
        self.losses = 0
        self.open_failures = 0
        self.write_errors = 0
        self.bytes_in = 0
        self.bytes_out = 0
        self.bytes_discarded = 0  # queued before the port was (re)opened: stale, thrown away

    # ------------------------------------------------------------------ state
    @property
    def connected(self) -> bool:
        return self._fd is not None

    def emit(self, event: str, **fields: Any) -> None:
        """Report an event to the sink (``sink(name, device=..., **fields)``); its failure must not stop the link."""
        if self._events is None:
            return
        try:
            self._events(event, device=self.name, **fields)
        except Exception:  # noqa: BLE001 - a logging bug must not stop the thrusters' link
            pass

    # ------------------------------------------------------------------ loop
    async def run(self) -> None:
        """Open, read until lost, reopen with back-off; until :meth:`close` or cancellation."""
        backoff_s = self._min_s
        try:
            while not self._closing:
                try:
                    opened = self._open()
                except Exception as exc:  # noqa: BLE001 - any open failure means "retry later"
                    opened = False
                    self.open_failures += 1
                    if not self._failure_announced:  # once per outage, not every retry
                        self._failure_announced = True
                        self.emit("port_open_failed", path=self.port_path, error=str(exc),
                                  why=open_problem(self.port_path, exc))
                if not opened:
                    await self._clock.sleep(backoff_s)
                    backoff_s = min(2.0 * backoff_s, self._max_s)
                    continue
                backoff_s = self._min_s
                self._failure_announced = False
                assert self._lost is not None
                await self._lost.wait()
                reason = getattr(self._lost, "reason", "")
                self._teardown()
                if self._closing:
                    break
                self.losses += 1
                self.emit("port_lost", path=self.port_path, error=reason)
                await self._clock.sleep(backoff_s)
        finally:
            self._teardown()

    async def close(self) -> None:
        self._closing = True
        if self._lost is not None:
            self._lost.set()
        self._teardown()

    def _open(self) -> bool:
        ser = open_port(self.port_path, self.baudrate, timeout=0, write_timeout=0)
        try:
            self.bytes_discarded += _pending(ser.fileno())
            ser.reset_input_buffer()  # bytes queued while nobody listened are stale
        except Exception:  # noqa: BLE001
            pass
        fd = ser.fileno()
        loop = asyncio.get_running_loop()
        self._serial, self._fd = ser, fd
        self._lost = asyncio.Event()
        loop.add_reader(fd, self._readable)
        self.opens += 1
        self.emit("port_opened", path=self.port_path, baudrate=self.baudrate)
        return True

    def _teardown(self) -> None:
        fd, ser = self._fd, self._serial
        self._fd = self._serial = None
        if fd is not None:
            try:
                asyncio.get_running_loop().remove_reader(fd)
            except Exception:  # noqa: BLE001 - loop already closed
                pass
        if ser is not None:
            try:
                ser.close()
            except Exception:  # noqa: BLE001 - closing a vanished device may fail; it is gone anyway
                pass

    def _mark_lost(self, reason: str) -> None:
        if self._fd is not None:
            try:
                asyncio.get_running_loop().remove_reader(self._fd)
            except Exception:  # noqa: BLE001
                pass
        if self._lost is not None and not self._lost.is_set():
            self._lost.reason = reason  # type: ignore[attr-defined]
            self._lost.set()

    def _readable(self) -> None:
        fd = self._fd
        if fd is None:
            return
        try:
            data = os.read(fd, _READ_CHUNK)
        except BlockingIOError:
            return
        except OSError as exc:
            self._mark_lost(f"{errno.errorcode.get(exc.errno, exc.errno)}: {exc.strerror}")
            return
        if not data:
            self._mark_lost("EOF")
            return
        self.bytes_in += len(data)
        try:
            self._on_bytes(data)
        except Exception as exc:  # noqa: BLE001 - decoders do not raise; this is a last guard
            self.emit("driver_error", error=repr(exc))

    # ------------------------------------------------------------------ write
    def write(self, data: bytes) -> bool:
        """Write without blocking; False (and counted) if not connected or the write fails."""
        fd = self._fd
        if fd is None:
            return False
        try:
            n = os.write(fd, data)
            if n < len(data):
                n += os.write(fd, data[n:])
            self.bytes_out += n
            if n < len(data):
                self.write_errors += 1
                return False
            return True
        except BlockingIOError:
            self.write_errors += 1
            return False
        except OSError as exc:
            self.write_errors += 1
            self._mark_lost(f"{errno.errorcode.get(exc.errno, exc.errno)}: {exc.strerror}")
            return False
