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
import sys
from pathlib import Path
from typing import IO, Any

import structlog

__all__ = ["MissionLog", "log_path", "to_json"]


def _clean(value: Any) -> Any:
    if isinstance(value, bool) or value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return _clean(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return str(value)


def to_json(event_dict: dict, **_: Any) -> str:
    """Strict JSON for one line (NaN/inf -> null)."""
    return json.dumps(_clean(event_dict), separators=(",", ":"), allow_nan=False)


def _render(_logger: Any, _name: str, event_dict: dict) -> str:
    return to_json(event_dict)


def log_path(log_dir: str | Path, mission_path: str | Path, now_utc: _dt.datetime | None = None) -> Path:
    """``<log_dir>/mission-<UTC YYYYmmddTHHMMSSZ>-<mission stem>.jsonl``."""
    now_utc = now_utc or _dt.datetime.now(_dt.timezone.utc)
    base = f"mission-{now_utc.strftime('%Y%m%dT%H%M%SZ')}-{Path(mission_path).stem}"
    path = Path(log_dir) / f"{base}.jsonl"
    n = 1
    while path.exists():  # a restart within the same second gets its own file
        n += 1
        path = Path(log_dir) / f"{base}-{n}.jsonl"
    return path


class MissionLog:
    """``log.event(name, t_s=..., **fields)`` writes one line; ``console`` gets non-cycle events too."""

    def __init__(self, path: str | Path, *, console: IO[str] | None = sys.stderr) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "a", encoding="utf-8", buffering=1)  # noqa: SIM115 - closed in close()
        processors = [structlog.processors.TimeStamper(fmt="iso", utc=True, key="timestamp"), _render]
        self._log = structlog.wrap_logger(
            structlog.WriteLogger(self._file), processors=processors, cache_logger_on_first_use=True
        )
        self._console = (
            structlog.wrap_logger(structlog.WriteLogger(console), processors=processors) if console is not None else None
        )
        self.lines = 0
        self.listeners: list = []  # callables (name, t_s, fields) told every event but cycle lines (the link)

    def event(self, name: str, /, *, t_s: float, **fields: Any) -> None:
        self._log.msg(name, t_s=t_s, **fields)
        self.lines += 1
        if name != "cycle":
            for listener in self.listeners:
                try:
                    listener(name, t_s, fields)
                except Exception:  # noqa: BLE001 - a listener must never stop the log or the loop
                    pass
        if self._console is not None and name != "cycle":
            try:
                self._console.msg(name, t_s=t_s, **{k: v for k, v in fields.items() if k != "config"})
            except (OSError, ValueError):  # a closed stderr must not stop the boat logic
                pass

    def close(self) -> None:
        if not self._file.closed:
            self._file.flush()
            self._file.close()
