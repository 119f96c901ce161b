"""A pseudo-terminal that stands in for a USB serial device, under a stable path.

``os.openpty()`` gives a master (the simulated device's end) and a slave
(a real tty that pyserial opens like ``/dev/ttyUSB0``). The endpoint exposes
the slave through a symlink (``<directory>/<name>``, like udev's
``/dev/sc30``), so the daemon is configured with a fixed path. ``unplug()``
closes the master and removes the symlink: a driver holding the slave open
then reads EIO, as from a vanished USB adapter. ``replug()`` makes a new pty
and re-points the symlink, so a reconnecting driver finds the device again.
"""

from __future__ import annotations

import os
import tty
from pathlib import Path

__all__ = ["PtyEndpoint"]


class PtyEndpoint:
    """The device side of a simulated serial port."""

    def __init__(self, directory: str | os.PathLike, name: str) -> None:
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.path = str(self.directory / name)
        self.master_fd: int | None = None
        self._slave_fd: int | None = None
        self.slave_name: str | None = None
        self.plugs = 0
        self.bytes_written = 0  # to the driver (lockstep: compared with what it read)
        self.bytes_read = 0  # from the driver
        self._plug()

    @property
    def plugged(self) -> bool:
        return self.master_fd is not None

    def _plug(self) -> None:
        master, slave = os.openpty()
        # raw on both ends: no echo of the device's output back to itself, no CR/LF mangling
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master_fd, self._slave_fd = master, slave
        self.slave_name = os.ttyname(slave)
        tmp = f"{self.path}.tmp{os.getpid()}"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(self.slave_name, tmp)
        os.replace(tmp, self.path)  # atomic re-point, like udev renaming
        self.plugs += 1

    def unplug(self) -> None:
        """Remove the device: close the pty and the symlink."""
        if os.path.lexists(self.path):
            os.unlink(self.path)
        for fd in (self.master_fd, self._slave_fd):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.master_fd = self._slave_fd = None

    def replug(self) -> None:
        """A new pty behind the same path."""
        if self.plugged:
            self.unplug()
        self._plug()

    def close(self) -> None:
        self.unplug()

    def write(self, data: bytes) -> int:
        """Bytes written (0 when unplugged or the pty buffer is full: the bytes are lost)."""
        fd = self.master_fd
        if fd is None:
            return 0
        try:
            n = os.write(fd, data)
        except (BlockingIOError, OSError):
            return 0
        self.bytes_written += n
        return n

    def read(self) -> bytes:
        """What the driver wrote, b'' if nothing (or unplugged)."""
        fd = self.master_fd
        if fd is None:
            return b""
        try:
            data = os.read(fd, 65536)
        except (BlockingIOError, OSError):
            return b""
        self.bytes_read += len(data)
        return data
