"""The mission log: structlog JSON lines, one file per mission, flushed line by line.

See docs/log-schema.md. structlog's ``WriteLogger`` writes each rendered
line and flushes it at once, so a SIGKILL loses at most the line being
written. Non-finite floats become ``null`` and numpy scalars plain numbers,
so every line is strict JSON.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import sys
from pathlib import Path
from typing import IO, Any

import structlog

__all__ = ["MissionLog", "log_path", "to_json", "json_ready"]


def json_ready(value: Any) -> Any:
    """``value`` as JSON can hold it: NaN and infinity as null (JSON has neither; strict readers refuse them),
    numpy values as plain ones, paths and other objects as text."""
    if isinstance(value, bool) or value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return json_ready(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return str(value)


def to_json(event_dict: dict, **_: Any) -> str:
    """Strict JSON for one line (NaN/inf -> null)."""
    return json.dumps(json_ready(event_dict), separators=(",", ":"), allow_nan=False)


def _render(_logger: Any, _name: str, event_dict: dict) -> str:
    return to_json(event_dict)


MAX_STEM_BYTES = 120  # of the mission's name in a log's file name


def log_path(log_dir: str | Path, mission_path: str | Path, now_utc: _dt.datetime | None = None) -> Path:
    """``<log_dir>/mission-<UTC YYYYmmddTHHMMSSZ>-<mission stem>.jsonl``."""
    now_utc = now_utc or _dt.datetime.now(_dt.timezone.utc)
    # a file name holds 255 bytes: a mission named longer stopped the start with "File name too long" (a new-user
    # audit); the stem is cut to leave room for the stamp, a restart's "-N", and what review adds to the name
    stem = Path(mission_path).stem.encode("utf-8")[:MAX_STEM_BYTES].decode("utf-8", "ignore")
    base = f"mission-{now_utc.strftime('%Y%m%dT%H%M%SZ')}-{stem}"
    path = Path(log_dir) / f"{base}.jsonl"
    n = 1
    while path.exists():  # a restart within the same second gets its own file
        n += 1
        path = Path(log_dir) / f"{base}-{n}.jsonl"
    return path


class _LineFile:
    """An append-only file written a whole line per ``os.write``, nothing kept in a buffer: a line a
    failed write lost is lost (not written later, out of order, when the disk has room again), and
    a line cut by it is ended before the next, so every other line stays one JSON object."""

    def __init__(self, path: Path) -> None:
        self._fd: int | None = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
        self._cut = False  # the last write left part of a line in the file

    @property
    def closed(self) -> bool:
        return self._fd is None

    def write(self, text: str) -> None:
        if self._fd is None:
            raise ValueError("write to a closed mission log")
        prefix = b"\n" if self._cut else b""
        data = memoryview(prefix + text.encode("utf-8"))
        written = 0
        try:
            while written < len(data):
                written += os.write(self._fd, data[written:])
        finally:
            if written == len(data):
                self._cut = False
            elif written > 0:  # the cut line's end went out; part of this one did too, or none of it
                self._cut = written > len(prefix)

    def flush(self) -> None:  # structlog's WriteLogger flushes after each line: every write is already out
        pass

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


# events the log keeps but the console (stderr, the journal) does not: one per AIS report and target, up to one a
# second each; a port's 1500 vessels were 1500 journal lines a second and hid every fault among them
CONSOLE_QUIET = frozenset({"target"})


class MissionLog:
    """``log.event(name, t_s=..., **fields)`` writes one line; ``console`` gets non-cycle events too."""

    def __init__(self, path: str | Path, *, console: IO[str] | None = sys.stderr) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = _LineFile(self.path)
        processors = [structlog.processors.TimeStamper(fmt="iso", utc=True, key="timestamp"), _render]
        self._log = structlog.wrap_logger(
            structlog.WriteLogger(self._file), processors=processors, cache_logger_on_first_use=True
        )
        self._console = (
            structlog.wrap_logger(structlog.WriteLogger(console), processors=processors) if console is not None else None
        )
        self.lines = 0
        self.lines_lost = 0  # lines a write failed on (disk full, card gone), over the whole mission
        self._failing: str | None = None  # the error while writes fail; None when they succeed
        self._lost_in_run = 0
        self.listeners: list = []  # callables (name, t_s, fields) told every event but cycle lines (the link)

    @property
    def failing(self) -> bool:
        """The last write failed (writes have not worked since): the lines after it, the stop line too, are lost."""
        return self._failing is not None

    def event(self, name: str, /, *, t_s: float, **fields: Any) -> None:
        """Write one line. A failed write (a full disk, a storage card gone) never raises: the boat must
        keep being controlled and stopped without its log. The operator hears of it on the console and
        the listeners once when writes start failing, and the log gets a line saying how many were lost
        when they work again."""
        if self._write(name, t_s, fields):
            self.lines += 1
        if name != "cycle":
            self._tell(name, t_s, fields)

    def _write(self, name: str, t_s: float, fields: dict) -> bool:
        try:
            if self._failing is not None and self._lost_in_run:  # retry: say first what the gap lost
                self._log.msg("info", t_s=t_s, message="log writes resumed", lines_lost=self._lost_in_run,
                              error=self._failing)
            self._failing, self._lost_in_run = None, 0
            self._log.msg(name, t_s=t_s, **fields)
            return True
        except (OSError, ValueError) as exc:  # ValueError: the file was closed under us
            self.lines_lost += 1
            self._lost_in_run += 1
            if self._failing is None:
                self._failing = f"{type(exc).__name__}: {exc}"
                self._tell("info", t_s, {"message": "log write failed", "path": str(self.path), "error": self._failing})
            return False

    def _tell(self, name: str, t_s: float, fields: dict) -> None:
        """The listeners (the link) and the console: every event but cycle lines, and the log's own failure."""
        for listener in self.listeners:
            try:
                listener(name, t_s, fields)
            except Exception:  # noqa: BLE001 - a listener must never stop the log or the loop
                pass
        if self._console is not None and name not in CONSOLE_QUIET:
            try:
                self._console.msg(name, t_s=t_s, **{k: v for k, v in fields.items() if k != "config"})
            except (OSError, ValueError):  # a closed stderr must not stop the boat logic
                pass

    def close(self) -> None:
        self._file.close()
