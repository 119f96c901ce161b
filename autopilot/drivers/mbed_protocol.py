"""Boat PC <-> Mbed LPC1768 thruster-board line protocol (docs/mbed-protocol.md): pure codec.

One command per control cycle::

    $MBCMD,<seq>,<F|R>,<duty_port>,<F|R>,<duty_stbd>*hh\\r\\n

and one acknowledgement per accepted command::

    $MBACK,<seq>,OK,<F|R>,<duty_port>,<F|R>,<duty_stbd>*hh\\r\\n   (applied; echoes what it set)
    $MBACK,<seq>,REJ,<reason>*hh\\r\\n                              (checksum fine, values not)

``seq`` is 0-65535 and wraps; duty is 0.0-100.0 % with one decimal (PWM
duty = voltage / 12 V, thesis 4.3, SPEC section 4); F = anticlockwise
(forward, capital letters in thesis Table 4.2), R = clockwise (reverse).
The checksum is NMEA's: XOR of the characters between ``$`` and ``*``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from autopilot.drivers.framing import xor_checksum

FIRMWARE_STOP_TIMEOUT_S = 0.5  # the firmware stops both motors this long after the last valid command (docs/mbed-protocol.md)

__all__ = [
    "FIRMWARE_STOP_TIMEOUT_S",
    "ProtocolError",
    "Command",
    "Ack",
    "encode_command",
    "decode_command",
    "encode_ack",
    "decode_ack",
    "SEQ_MODULO",
    "MAX_LINE_CHARS",
    "ACK_REASONS",
]

SEQ_MODULO = 65536
MAX_LINE_CHARS = 64  # firmware buffer; longer lines are discarded up to their LF
ACK_REASONS = ("RANGE", "FORMAT")  # why a checksummed command was rejected

_DUTY = re.compile(r"\d{1,3}(?:\.\d)?\Z")
_SEQ = re.compile(r"\d{1,5}\Z")
_HEX2 = re.compile(r"[0-9A-Fa-f]{2}\Z")


class ProtocolError(ValueError):
    """A line that is not a valid command or acknowledgement.

    ``reason`` is None for a framing/checksum error (the firmware stays
    silent) and "FORMAT" or "RANGE" for a checksummed line with bad fields
    (the firmware answers ``REJ``); ``seq`` is the sequence number if it parsed.
    """

    def __init__(self, message: str, *, reason: str | None = None, seq: int = 0) -> None:
        super().__init__(message)
        self.reason = reason
        self.seq = seq


@dataclass(frozen=True)
class Command:
    seq: int
    duty_port_pct: float
    reverse_port: bool
    duty_stbd_pct: float
    reverse_stbd: bool


@dataclass(frozen=True)
class Ack:
    """``status`` "OK" (applied, duties echoed) or "REJ" (``reason`` set, duties None)."""

    seq: int
    status: str
    duty_port_pct: float | None = None
    reverse_port: bool | None = None
    duty_stbd_pct: float | None = None
    reverse_stbd: bool | None = None
    reason: str | None = None
    battery_v: float | None = None  # the optional 7th field of OK (firmware that measures it), volts

    @property
    def ok(self) -> bool:
        return self.status == "OK"


def _frame(body: str) -> bytes:
    return f"${body}*{xor_checksum(body)}\r\n".encode("ascii")


def _duty_text(duty_pct: float, what: str) -> str:
    if isinstance(duty_pct, bool) or not isinstance(duty_pct, (int, float)) or not math.isfinite(duty_pct):
        raise ProtocolError(f"{what}: duty must be a finite number, got {duty_pct!r}")
    if not 0.0 <= duty_pct <= 100.0:
        raise ProtocolError(f"{what}: duty {duty_pct} outside [0, 100] %")
    return f"{round(duty_pct, 1):.1f}"


BATTERY_MAX_V = 99.99  # the field's range: 0.00 to 99.99 V, 1-2 integer digits, up to two decimals
_BATTERY_RE = re.compile(r"\d{1,2}(\.\d{1,2})?\Z")


def _battery_text(v: float) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0.0 <= v <= BATTERY_MAX_V:
        raise ProtocolError(f"battery voltage must be in [0, {BATTERY_MAX_V}] V, got {v!r}")
    return f"{v:.2f}"


def _battery_field(text: str) -> float | None:
    """The optional battery field: empty = not measured."""
    if text == "":
        return None
    if not _BATTERY_RE.match(text):
        raise ProtocolError(f"battery voltage {text!r} is not 0.00-99.99 V")
    return float(text)


def _seq_value(seq: int) -> int:
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise ProtocolError(f"seq must be a non-negative integer, got {seq!r}")
    return seq % SEQ_MODULO


def encode_command(
    seq: int, duty_port_pct: float, reverse_port: bool, duty_stbd_pct: float, reverse_stbd: bool
) -> bytes:
    """``$MBCMD,...*hh\\r\\n``; seq wraps modulo 65536; duty rounded to 0.1 %, must be in [0, 100]."""
    p = _duty_text(duty_port_pct, "port")
    s = _duty_text(duty_stbd_pct, "stbd")
    dp = "R" if reverse_port else "F"
    ds = "R" if reverse_stbd else "F"
    return _frame(f"MBCMD,{_seq_value(seq)},{dp},{p},{ds},{s}")


def encode_ack(
    seq: int,
    status: str = "OK",
    duty_port_pct: float = 0.0,
    reverse_port: bool = False,
    duty_stbd_pct: float = 0.0,
    reverse_stbd: bool = False,
    *,
    reason: str = "RANGE",
    battery_v: float | None = None,
) -> bytes:
    """The firmware's reply (used by the simulated Mbed and tests); ``battery_v`` None = old firmware."""
    seq = _seq_value(seq)
    if status == "OK":
        p = _duty_text(duty_port_pct, "port")
        s = _duty_text(duty_stbd_pct, "stbd")
        v = "" if battery_v is None else f",{_battery_text(battery_v)}"
        return _frame(f"MBACK,{seq},OK,{'R' if reverse_port else 'F'},{p},{'R' if reverse_stbd else 'F'},{s}{v}")
    if status == "REJ":
        if reason not in ACK_REASONS:
            raise ProtocolError(f"reason must be one of {ACK_REASONS}, got {reason!r}")
        return _frame(f"MBACK,{seq},REJ,{reason}")
    raise ProtocolError(f"status must be OK or REJ, got {status!r}")


def _split(line: bytes | str) -> list[str] | None:
    """Checked fields of one framed line; None for a blank line."""
    if isinstance(line, (bytes, bytearray)):
        try:
            line = bytes(line).decode("ascii")
        except UnicodeDecodeError:
            raise ProtocolError("non-ASCII bytes") from None
    if not isinstance(line, str):
        raise ProtocolError(f"expected bytes or str, got {type(line).__name__}")
    s = line.strip("\r\n")
    if s == "":
        return None
    if len(s) > MAX_LINE_CHARS:
        raise ProtocolError(f"line longer than {MAX_LINE_CHARS} characters")
    if not s.startswith("$"):
        raise ProtocolError("does not start with '$'")
    star = s.rfind("*")
    if star < 0:
        raise ProtocolError("no '*hh' checksum")
    body, given = s[1:star], s[star + 1 :]
    if not _HEX2.match(given):
        raise ProtocolError(f"malformed checksum {given!r}")
    if not body.isascii() or not body.isprintable() or any(c in body for c in "$*"):
        raise ProtocolError("reserved or non-printable character")
    if given.upper() != xor_checksum(body):
        raise ProtocolError(f"checksum {given.upper()} != {xor_checksum(body)}")
    return body.split(",")


def _seq_field(s: str) -> int:
    if not _SEQ.match(s):
        raise ProtocolError(f"seq {s!r} not a number", reason="FORMAT")
    if int(s) >= SEQ_MODULO:
        raise ProtocolError(f"seq {s!r} not in 0-65535", reason="RANGE")
    return int(s)


def _dir_duty(d: str, duty: str, what: str, seq: int = 0) -> tuple[bool, float]:
    if d not in ("F", "R"):
        raise ProtocolError(f"{what}: direction {d!r} not F or R", reason="FORMAT", seq=seq)
    if not _DUTY.match(duty):
        raise ProtocolError(f"{what}: duty {duty!r} not a number with at most one decimal", reason="FORMAT", seq=seq)
    if float(duty) > 100.0:
        raise ProtocolError(f"{what}: duty {duty!r} above 100.0", reason="RANGE", seq=seq)
    return d == "R", float(duty)


def decode_command(line: bytes | str) -> Command:
    """Parse ``$MBCMD`` (the firmware's side, used by the simulated Mbed)."""
    f = _split(line)
    if f is None or f[0] != "MBCMD":
        raise ProtocolError("not an MBCMD line")
    seq = _seq_field(f[1]) if len(f) > 1 else 0
    if len(f) != 6:
        raise ProtocolError(f"MBCMD has {len(f) - 1} fields, need 5", reason="FORMAT", seq=seq)
    rp, dp = _dir_duty(f[2], f[3], "port", seq)
    rs, ds = _dir_duty(f[4], f[5], "stbd", seq)
    return Command(seq, dp, rp, ds, rs)


def decode_ack(line: bytes | str) -> Ack | None:
    """Parse ``$MBACK``; None for a blank line or another valid ``$MB...`` status line."""
    f = _split(line)
    if f is None:
        return None
    if f[0] != "MBACK":
        if re.match(r"MB[A-Z]{3}\Z", f[0]):
            return None  # a status line from newer firmware: not an ack
        raise ProtocolError(f"unknown sentence {f[0]!r}")
    if len(f) < 3:
        raise ProtocolError("MBACK needs seq and status")
    seq = _seq_field(f[1])
    if f[2] == "OK":
        if len(f) not in (7, 8):
            raise ProtocolError(f"MBACK OK has {len(f) - 1} fields, need 6 (or 7 with the battery voltage)")
        rp, dp = _dir_duty(f[3], f[4], "port")
        rs, ds = _dir_duty(f[5], f[6], "stbd")
        return Ack(seq, "OK", dp, rp, ds, rs, battery_v=_battery_field(f[7]) if len(f) == 8 else None)
    if f[2] == "REJ":
        if len(f) != 4 or f[3] not in ACK_REASONS:
            raise ProtocolError(f"MBACK REJ needs one reason in {ACK_REASONS}")
        return Ack(seq, "REJ", reason=f[3])
    raise ProtocolError(f"status {f[2]!r} not OK or REJ")
