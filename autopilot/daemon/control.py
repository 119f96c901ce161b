"""The operator's control socket: ``autopilot ctl`` talks to the running daemon (issue 15).

One Unix stream socket, ``<runtime dir>/control.sock`` (systemd ``RuntimeDirectory=``:
``/run/wamv-autopilot``), mode 0660: the service's user and group may command the boat,
nobody else. One JSON line each way per request; a connection may carry several, answered in
order (``printf 'status\nstop\n' | socat - UNIX:.../control.sock`` stops the boat)::

    -> {"command": "hold", "heading_deg": 90}        (or the bare word: hold)
    <- {"ok": true, "answer": "hold", "mode": "hold"}
    <- {"ok": false, "answer": "rtl refused: position stale", "mode": "auto"}

``status`` is answered at once from the last cycle. Every other command is queued for
the control loop, which carries it out between the steps of its next cycle and answers
then (:meth:`autopilot.daemon.loop.ControlLoop.submit`): the socket never runs inside
the loop's timing and never blocks it. A request larger than ``MAX_REQUEST_BYTES``, not
finished within ``READ_TIMEOUT_S``, not JSON, or with an unknown command or field is
refused with the reason and logged (``command`` event, ``accepted: false``). The MAVLink
link (issue 16) drives the same :meth:`~autopilot.daemon.loop.ControlLoop.submit`.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import os
import socket
from pathlib import Path

from autopilot.daemon.missionlog import json_ready
from autopilot.gnc.speed import SPEED_RANGE, is_speed
from autopilot.logschema import COMMANDS, NEVER_REFUSED
from autopilot.schema import ConfigError

__all__ = ["SOCKET_NAME", "MAX_REQUEST_BYTES", "READ_TIMEOUT_S", "SYSTEMD_RUNTIME_DIR", "daemon_runtime_dir",
           "socket_candidates", "check_request", "parse_request", "ControlServer", "request"]

SOCKET_NAME = "control.sock"
MAX_REQUEST_BYTES = 1024
READ_TIMEOUT_S = 2.0
ANSWER_TIMEOUT_S = 5.0  # the loop answers within a cycle; this only bounds a stalled daemon
MAX_CLIENTS = 8
REFUSALS_LOGGED_PER_S = 10  # beyond: counted, and said in one line a second (a looping client filled the disk)
SYSTEMD_RUNTIME_DIR = Path("/run/wamv-autopilot")  # RuntimeDirectory=wamv-autopilot in the unit
FIELDS = {"command": "one of " + ", ".join(COMMANDS), "heading_deg": "hold: the heading to keep, [0, 360) deg",
          "speed_m_s": f"speed: the legs' speed, {SPEED_RANGE}, or null for the mission's planned ones"}


def daemon_runtime_dir(configured: str | None = None) -> Path:
    """Where the daemon puts its socket: --runtime-dir / ``runtime_dir``, else systemd's
    $RUNTIME_DIRECTORY, else $XDG_RUNTIME_DIR/autopilot, else /tmp/autopilot-<uid>."""
    if configured:
        return Path(configured)
    if os.environ.get("RUNTIME_DIRECTORY"):
        return Path(os.environ["RUNTIME_DIRECTORY"].split(":")[0])
    if os.environ.get("XDG_RUNTIME_DIR"):
        return Path(os.environ["XDG_RUNTIME_DIR"]) / "autopilot"
    return Path(f"/tmp/autopilot-{os.getuid()}")


def socket_candidates(runtime_dir: str | None = None) -> list[Path]:
    """Where ``autopilot ctl`` looks, in order: the given directory; else the service's
    (/run/wamv-autopilot), then a daemon started by this user."""
    if runtime_dir:
        return [Path(runtime_dir) / SOCKET_NAME]
    out = [SYSTEMD_RUNTIME_DIR / SOCKET_NAME, daemon_runtime_dir() / SOCKET_NAME]
    return list(dict.fromkeys(out))


SOCKET_PATH_MAX_BYTES = 107  # sun_path holds 108 bytes with its terminating NUL (Linux)


def check_socket_path(path: Path) -> None:
    """ConfigError when the socket's path is too long for a Unix socket (it said "cannot create (None)")."""
    size = len(os.fsencode(str(path)))
    if size > SOCKET_PATH_MAX_BYTES:
        raise ConfigError(f"control socket {path}: its path is {size} bytes, longer than the {SOCKET_PATH_MAX_BYTES} a "
                          "Unix socket's may be; give a shorter runtime directory (--runtime-dir, runtime_dir)")


def check_request(req) -> str | None:
    """Why a request is refused (naming the field and what is allowed), or None."""
    if not isinstance(req, dict):
        return "malformed request: expected a JSON object"
    extra = sorted(set(req) - set(FIELDS) - {"source"})
    if extra:
        return f"malformed request: unknown field {extra[0]!r} (allowed: {', '.join(FIELDS)})"
    cmd = req.get("command")
    if cmd not in COMMANDS:
        return f"malformed request: command {str(cmd)[:32]!r} is not one of {', '.join(COMMANDS)}"
    if cmd == "speed" and "speed_m_s" not in req:
        return "malformed request: speed needs speed_m_s (a speed in m/s, or null for the mission's planned ones)"
    if "speed_m_s" in req:
        v = req["speed_m_s"]
        if cmd != "speed":
            return f"malformed request: speed_m_s is for speed only, not {cmd}"
        if v is not None and not is_speed(v):
            return f"malformed request: speed_m_s {repr(v)[:32]} is not a speed in {SPEED_RANGE}"
    h = req.get("heading_deg")
    if h is not None:
        if cmd != "hold":
            return f"malformed request: heading_deg is for hold only, not {cmd}"
        # the range alone: NaN and infinities fail it, and math.isfinite raised OverflowError on a 400-digit integer
        if isinstance(h, bool) or not isinstance(h, (int, float)) or not 0.0 <= h < 360.0:
            return f"malformed request: heading_deg {repr(h)[:32]} outside [0, 360) deg"
    return None


class _DuplicateKey(Exception):
    pass


def _no_duplicate_keys(pairs) -> dict:
    """A JSON object whose keys are each given once: {"command": "status", "command": "pause"} once did pause,
    logged as such, while the operator's screen showed status (as the YAML files refuse a key given twice)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def parse_request(line: bytes) -> tuple[dict | None, str | None]:
    """(request, refusal): a JSON object, or a bare command word."""
    try:
        text = line.decode("utf-8").strip()
    except UnicodeDecodeError:
        return None, "malformed request: not UTF-8 text"
    if not text:
        return None, "malformed request: empty"
    if text.startswith("{"):
        try:
            req = json.loads(text, object_pairs_hook=_no_duplicate_keys)
        except _DuplicateKey as exc:
            return None, f"malformed request: field {str(exc)[:32]!r} given twice"
        except ValueError as exc:
            return None, f"malformed request: not JSON ({exc.msg} at character {exc.pos})"
    else:
        req = {"command": text}
    problem = check_request(req)
    return (None, problem) if problem else (req, None)


class ControlServer:
    """The socket's server in the daemon's event loop. ``submit(request, answer)`` queues a command for
    the loop; ``status()`` is the last cycle's; ``log(name, **fields)`` writes an event."""

    def __init__(self, path: Path, *, submit, status, log) -> None:
        self.path = Path(path)
        self._submit, self._status, self._log = submit, status, log
        self._server: asyncio.AbstractServer | None = None
        self._clients = 0
        self._refusal_window_s = -math.inf  # start of the current second of refusals (event-loop time)
        self._refusals_in_window = 0
        self._refusals_unlogged = 0

    async def start(self) -> None:
        """Bind the socket (0660). Refuses to start when another daemon answers on it (two daemons
        must never drive the same thrusters); a stale socket from a killed daemon is replaced."""
        if self.path.parent.exists() and not self.path.parent.is_dir():  # mkdir said "cannot create (File exists)"
            raise ConfigError(f"runtime directory {self.path.parent}: is a file, not a directory")
        check_socket_path(self.path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True, mode=0o750)
        except OSError as exc:
            raise ConfigError(f"runtime directory {self.path.parent}: cannot create ({exc.strerror})") from exc
        if self.path.exists() or self.path.is_symlink():
            probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            probe.settimeout(0.5)
            try:
                probe.connect(str(self.path))
            except OSError:
                with contextlib.suppress(OSError):
                    self.path.unlink()
            else:
                raise ConfigError(f"another autopilot daemon is running: it answers on {self.path} "
                                  "(stop it first: autopilot ctl stop, then systemctl stop wamv-autopilot)")
            finally:
                probe.close()
        try:
            self._server = await asyncio.start_unix_server(self._handle, path=str(self.path),
                                                           limit=MAX_REQUEST_BYTES)
            os.chmod(self.path, 0o660)
        except OSError as exc:
            raise ConfigError(f"control socket {self.path}: cannot create ({exc.strerror})") from exc

    def end_log(self) -> None:
        """Say what is not said yet, and log nothing more: the daemon's stop line is the log's last."""
        self._say_unlogged()
        self._log = lambda name, **fields: None

    async def close(self) -> None:
        self.end_log()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 1.0)
            self._server = None
        with contextlib.suppress(OSError):
            self.path.unlink()

    def _refuse(self, what: str, why: str) -> dict:
        now_s = asyncio.get_running_loop().time()
        if now_s - self._refusal_window_s >= 1.0:
            self._say_unlogged()
            self._refusal_window_s, self._refusals_in_window = now_s, 0
        self._refusals_in_window += 1
        if self._refusals_in_window <= REFUSALS_LOGGED_PER_S:
            self._log("command", command=what[:32], source="ctl", accepted=False, answer=why)
        else:
            if not self._refusals_unlogged:  # said when the second is over, not at the next flood
                asyncio.get_running_loop().call_at(self._refusal_window_s + 1.0, self._say_unlogged)
            self._refusals_unlogged += 1
        return {"ok": False, "answer": why}

    def _say_unlogged(self) -> None:
        if self._refusals_unlogged:
            self._log("info", message="ctl refusals not logged", count=self._refusals_unlogged,
                      limit_per_s=REFUSALS_LOGGED_PER_S)
            self._refusals_unlogged = 0

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self._clients += 1
        try:
            first = True
            while True:
                # after the first request a connection that goes quiet or closes simply ends: only the first
                # line's absence or lateness is the client's mistake
                reply, more = await self._reply(reader, first=first)
                first = False
                if reply is not None:
                    writer.write((json.dumps(reply, allow_nan=False, default=str) + "\n").encode("utf-8"))
                    await asyncio.wait_for(writer.drain(), READ_TIMEOUT_S)
                if not more:
                    break
        except (OSError, asyncio.TimeoutError, ValueError):
            pass  # the client went away: nothing to answer
        finally:
            self._clients -= 1
            writer.close()
            with contextlib.suppress(Exception):
                await writer.wait_closed()

    async def _reply(self, reader: asyncio.StreamReader, *, first: bool = True) -> tuple[dict | None, bool]:
        """The answer to the connection's next request (None: nothing to answer), and whether another
        request may follow on the connection (a line was served whole: the client may have sent more)."""
        try:
            line = await asyncio.wait_for(reader.readuntil(b"\n"), READ_TIMEOUT_S)
            more = True
        except asyncio.LimitOverrunError:  # the rest of the oversized line is still unread: no resync
            return self._refuse("", f"request too large (limit {MAX_REQUEST_BYTES} bytes)"), False
        except asyncio.IncompleteReadError as exc:
            line, more = exc.partial, False  # no newline before the client closed its side: take what came
            if not line or (not first and not line.strip()):  # connected and went (a daemon probing), or done
                return None, False
            if len(line) > MAX_REQUEST_BYTES:
                return self._refuse("", f"request too large (limit {MAX_REQUEST_BYTES} bytes)"), False
        except asyncio.TimeoutError:
            if not first:
                return None, False
            return self._refuse("", f"incomplete request: no line within {READ_TIMEOUT_S:g} s"), False
        if not first and not line.strip():
            return None, more  # a blank line between requests (a trailing newline from a script)
        return await self._serve(line), more

    async def _serve(self, line: bytes) -> dict:
        req, problem = parse_request(line)
        if problem:
            return self._refuse(line[:32].decode("utf-8", "replace").strip(), problem)
        # the limit is judged on the request read, and never on stopping the boat: 8 idle connections held
        # open once refused every `ctl stop`
        if self._clients > MAX_CLIENTS and req["command"] not in NEVER_REFUSED:
            return self._refuse(req["command"], f"busy: more than {MAX_CLIENTS} requests at once")
        if req["command"] == "status":
            return {"ok": True, "answer": "status", "status": json_ready(self._status())}
        done = asyncio.get_running_loop().create_future()

        def answer(reply: dict) -> None:
            if not done.done():
                done.set_result(reply)

        self._submit({**req, "source": "ctl"}, answer)
        try:
            return await asyncio.wait_for(done, ANSWER_TIMEOUT_S)
        except asyncio.TimeoutError:
            return {"ok": False, "answer": f"{req['command']}: no answer from the control loop within "
                                          f"{ANSWER_TIMEOUT_S:g} s (it stays queued)"}


def request(path: Path, req: dict, timeout_s: float = ANSWER_TIMEOUT_S + 1.0) -> dict:
    """One request to a daemon (blocking; for ``autopilot ctl`` and tests). Raises OSError."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(timeout_s)
        s.connect(str(path))
        s.sendall((json.dumps(req) + "\n").encode("utf-8"))
        data = b""
        while not data.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    return json.loads(data.decode("utf-8"))
