"""The mission log a running daemon writes, read as it grows (the tests that watch a daemon poll it)."""

from __future__ import annotations

import json
from pathlib import Path


class LogTail:
    """Complete lines of the log that the daemon with a given pid writes in ``log_dir``.

    Read incrementally: a test's loop that also runs the simulated SC-30, Mbed and boat polls it every
    few tens of milliseconds, and parsing the whole log at every poll held them up for 13-28 ms a poll
    once the log was long (130-280 ms of simulated time at 10x); incrementally a poll takes ~0.04 ms.
    A line being written is left out; a new pid (a restarted daemon writes a new log) starts afresh."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = Path(log_dir)
        self._pid: int | None = None
        self._path: Path | None = None
        self._pos = 0
        self._lines: list[dict] = []

    def lines(self, pid: int) -> list[dict]:
        """Every complete line so far, as a new list (a caller may keep it)."""
        if self._pid != pid:
            self._pid, self._path, self._pos, self._lines = pid, None, 0, []
        if self._path is None:
            for path in self.log_dir.glob("mission-*.jsonl"):
                with path.open("rb") as f:
                    first = f.readline()
                if first.endswith(b"\n") and json.loads(first).get("pid") == pid:
                    self._path = path
                    break
            else:
                return []
        with self._path.open("rb") as f:
            f.seek(self._pos)
            data = f.read()
        end = data.rfind(b"\n") + 1  # only newline-terminated lines are complete
        self._pos += end
        self._lines.extend(json.loads(x) for x in data[:end].split(b"\n")[:-1])
        return list(self._lines)
