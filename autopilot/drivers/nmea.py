"""NMEA 0183 codec for the Furuno SC-30 satellite compass: bytes in, updates out, no I/O.

SPEC section 10: the SC-30 speaks HDT/THS/ROT/``$PFEC,GPatt``/``$PFEC,GPhve``
at 10 Hz and GGA/RMC/VTG/GLL/ZDA at 1 Hz, any talker (GP, HE, GN ...).
Standard sentences go through pynmea2 with ``check=True``; THS and Furuno's
``$PFEC`` sentences are unknown to pynmea2 1.19 and are decoded here.

Every field is converted by this module, not by pynmea2: pynmea2 hands back
the raw string for a field it cannot convert and reports an empty latitude
as 0.0, either of which would put a boat at the equator. A number must look
like ``[+-]digits[.digits]``: ``nan``, ``inf`` and exponents are refused.

:class:`NmeaStreamDecoder` takes arbitrary byte chunks, keeps partial lines
between calls, and counts and drops every line it cannot accept. It never
raises, whatever the bytes (fuzzed in ``benchmarks/fuzz_nmea.py``).
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Callable
from dataclasses import dataclass

import pynmea2

from autopilot.drivers.framing import LineFramer, checked_body, xor_checksum
from autopilot.units import KNOT_M_S, deg_min_to_rad_s, knots_to_m_s

__all__ = [
    "NmeaError",
    "ChecksumError",
    "SentenceError",
    "NmeaUpdate",
    "NmeaStats",
    "NmeaStreamDecoder",
    "decode_line",
    "checksum",
    "make_sentence",
    "encode_heading",
    "encode_rot",
    "encode_position",
    "encode_zda",
    "MAX_LINE_CHARS",
]

# IEC 61162-1 caps a sentence at 82 characters, but real receivers exceed it
# (high-precision GGA, proprietary PSTI lines in the shared captures are ~100).
MAX_LINE_CHARS = 200

_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)\Z")
_ADDRESS = re.compile(r"(?:[A-Z0-9]{2}[A-Z]{3}|P[A-Z0-9]{3,5})\Z")

# sentences pynmea2 knows and we decode from its field list
_PYNMEA2_TYPES = frozenset({"GGA", "RMC", "VTG", "HDT", "HDM", "ROT", "ZDA", "GLL", "XDR"})


class NmeaError(ValueError):
    """A line that is not an acceptable NMEA sentence."""


class ChecksumError(NmeaError):
    """Missing, malformed or wrong ``*hh`` checksum."""


class SentenceError(NmeaError):
    """A correctly checksummed sentence whose framing or fields are invalid."""


@dataclass(frozen=True)
class NmeaUpdate:
    """What one sentence says, in SI (latitude/longitude in degrees). Fields it does not carry stay None.

    The sentence's degrees, knots and degrees per minute are converted here and go no further
    (:mod:`autopilot.units`). ``heading_valid``: HDT/THS/PFEC_GPatt carried a usable true heading
    (empty HDT field or THS mode other than A/E is invalid).
    ``status_valid``: the sentence's own validity flag (GGA quality > 0,
    RMC/GLL status A and mode not N, VTG mode not N, ROT status A,
    GPhve status A).
    """

    sentence: str
    talker: str
    lat_deg: float | None = None
    lon_deg: float | None = None
    fix_quality: int | None = None
    heading_rad: float | None = None  # true heading [0, 2 pi), clockwise from north
    heading_valid: bool | None = None
    ths_mode: str | None = None
    yaw_rate_rad_s: float | None = None  # ROT; + = turning to starboard
    sog_m_s: float | None = None
    cog_rad: float | None = None  # course over ground [0, 2 pi)
    pitch_rad: float | None = None
    roll_rad: float | None = None
    utc: _dt.datetime | None = None
    status_valid: bool | None = None
    heading_mag_rad: float | None = None  # HDM, magnetic: never used as heading
    heave_m: float | None = None  # PFEC_GPhve
    # GGA/RMC/GLL: UTC of the position's epoch (sentences of one epoch share it); a leap second
    # (23:59:60) is 23:59:59 with fold=1
    fix_time: _dt.time | None = None


# A position the receiver measured. GGA quality 6 is its own dead reckoning (ArduPilot's NMEA
# driver takes it as no fix), 7 a position typed in, 8 its simulator: none is where the boat is.
# RMC/GLL mode (NMEA 2.3+; empty before): A autonomous, D differential, P precise, R RTK, F float
# RTK; E estimated, M manual, S simulator and N not valid are refused alike.
MEASURED_QUALITIES = frozenset({1, 2, 3, 4, 5})
MEASURED_MODES = frozenset({"", "A", "D", "P", "R", "F"})


# --------------------------------------------------------------------------- helpers


checksum = xor_checksum  # the NMEA checksum (autopilot.drivers.framing owns it)


def make_sentence(body: str) -> str:
    """``$body*hh\\r\\n`` for a body without ``$`` (used by the simulated SC-30 and tests)."""
    return f"${body}*{checksum(body)}\r\n"


def _num(s: str, what: str, lo: float | None = None, hi: float | None = None) -> float | None:
    """A number field: None if empty, SentenceError if malformed or out of [lo, hi]."""
    if s == "":
        return None
    if not _NUMBER.match(s):
        raise SentenceError(f"{what}: not a number: {s!r}")
    x = float(s)
    if (lo is not None and x < lo) or (hi is not None and x > hi):
        raise SentenceError(f"{what}: {x} outside [{lo}, {hi}]")
    return x


def _rad(x_deg: float | None) -> float | None:
    return None if x_deg is None else math.radians(x_deg)


def _kn(x_kn: float | None) -> float | None:
    return None if x_kn is None else knots_to_m_s(x_kn)


def _heading(s: str, what: str = "heading") -> float | None:
    h = _num(s, what, 0.0, 360.0)
    return None if h is None else h % 360.0


def _angle(ddmm: str, hemi: str, deg_digits: int, limit: float, what: str) -> float | None:
    """``ddmm.mmmm`` / ``dddmm.mmmm`` + hemisphere to signed decimal degrees."""
    if ddmm == "" and hemi == "":
        return None
    if ddmm == "" or hemi == "":
        raise SentenceError(f"{what}: value {ddmm!r} with hemisphere {hemi!r}")
    if not _NUMBER.match(ddmm) or ddmm[0] in "+-" or len(ddmm.split(".")[0]) != deg_digits + 2:
        raise SentenceError(f"{what}: malformed {ddmm!r}")
    deg = int(ddmm[:deg_digits])
    minutes = float(ddmm[deg_digits:])
    if minutes >= 60.0:
        raise SentenceError(f"{what}: minutes {minutes} >= 60")
    value = deg + minutes / 60.0
    if value > limit:
        raise SentenceError(f"{what}: {value} beyond {limit}")
    pos, neg = ("N", "S") if deg_digits == 2 else ("E", "W")
    if hemi == pos:
        return value
    if hemi == neg:
        return -value
    raise SentenceError(f"{what}: hemisphere {hemi!r}")


def _latlon(f: list[str], i: int) -> tuple[float | None, float | None]:
    lat = _angle(f[i], f[i + 1], 2, 90.0, "latitude")
    lon = _angle(f[i + 2], f[i + 3], 3, 180.0, "longitude")
    if (lat is None) != (lon is None):
        raise SentenceError("latitude and longitude must both be present or both empty")
    return lat, lon


def _time(s: str) -> _dt.time | None:
    if s == "":
        return None
    m = re.match(r"(\d\d)(\d\d)(\d\d)(?:\.(\d{1,6}))?\Z", s)
    if not m:
        raise SentenceError(f"time: malformed {s!r}")
    hh, mm, ss = int(m[1]), int(m[2]), int(m[3])
    us = int((m[4] or "0").ljust(6, "0"))
    if ss == 60:
        # A leap second is inserted as 23:59:60 UTC. datetime.time has no 60th second, so it is
        # 23:59:59 with fold=1 (its second occurrence, as fold marks a repeated wall time): its own
        # epoch, not the one before it (sc30.py compares the fold too).
        if (hh, mm) != (23, 59):
            raise SentenceError(f"time: second 60 in {s!r} (a leap second is only 23:59:60)")
        return _dt.time(23, 59, 59, us, tzinfo=_dt.timezone.utc, fold=1)
    try:
        return _dt.time(hh, mm, ss, us, tzinfo=_dt.timezone.utc)
    except ValueError as exc:
        raise SentenceError(f"time: {exc} in {s!r} (hhmmss: hours 0-23, minutes and seconds 0-59)") from None


def _date(day: int, month: int, year: int) -> _dt.date:
    try:
        return _dt.date(year, month, day)
    except (ValueError, OverflowError) as exc:
        raise SentenceError(f"date: {exc}") from None


def _field(f: list[str], i: int) -> str:
    return f[i] if i < len(f) else ""


def _need(f: list[str], n: int, name: str) -> None:
    if len(f) < n:
        raise SentenceError(f"{name}: {len(f)} fields, need {n}")


# --------------------------------------------------------------------------- sentences


def _gga(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 6, "GGA")
    lat, lon = _latlon(f, 1)
    epoch = _time(f[0])
    q = f[5]
    if q == "":
        quality = 0
    elif q.isdigit() and len(q) == 1:
        quality = int(q)
    else:
        raise SentenceError(f"GGA fix quality: {q!r}")
    # a fix from no satellites is none: a receiver that lost them can go on sending its last position with quality 1
    # and "00" satellites (hemi.log, 7 s of it; gpsd reports no fix), an empty count is only not given
    sats = _field(f, 6)
    no_satellites = sats.isdigit() and int(sats) == 0
    return NmeaUpdate("GGA", t, lat_deg=lat, lon_deg=lon, fix_quality=quality,
                      status_valid=quality in MEASURED_QUALITIES and not no_satellites, fix_time=epoch)


def _rmc(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 9, "RMC")
    tm = _time(f[0])
    if f[1] not in ("A", "V"):
        raise SentenceError(f"RMC status: {f[1]!r}")
    lat, lon = _latlon(f, 2)
    sog = _num(f[6], "RMC speed", 0.0, 1000.0)
    cog = _heading(f[7], "RMC course")
    utc = None
    if f[8] != "":
        if not re.match(r"\d{6}\Z", f[8]):
            raise SentenceError(f"RMC date: {f[8]!r}")
        d = _date(int(f[8][:2]), int(f[8][2:4]), 2000 + int(f[8][4:]))
        if tm is not None:
            utc = _dt.datetime.combine(d, tm)
    mode = _field(f, 11)
    valid = f[1] == "A" and mode in MEASURED_MODES
    return NmeaUpdate("RMC", t, lat_deg=lat, lon_deg=lon, sog_m_s=_kn(sog), cog_rad=_rad(cog), utc=utc, status_valid=valid, fix_time=tm)


def _gll(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 6, "GLL")
    lat, lon = _latlon(f, 0)
    epoch = _time(f[4])
    if f[5] not in ("A", "V"):
        raise SentenceError(f"GLL status: {f[5]!r}")
    return NmeaUpdate("GLL", t, lat_deg=lat, lon_deg=lon, status_valid=f[5] == "A" and _field(f, 6) in MEASURED_MODES,
                      fix_time=epoch)


def _vtg(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 1, "VTG")
    cog = _heading(f[0], "VTG course")
    # NMEA 2.3 layout: course,T,course_mag,M,sog_kn,N,sog_kmh,K[,mode]
    sog = _num(_field(f, 4), "VTG speed", 0.0, 1000.0)
    mode = _field(f, 8)
    return NmeaUpdate("VTG", t, cog_rad=_rad(cog), sog_m_s=_kn(sog), status_valid=mode != "N")


def _hdt(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 1, "HDT")
    h = _heading(f[0])
    return NmeaUpdate("HDT", t, heading_rad=_rad(h), heading_valid=h is not None)


def _hdm(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 1, "HDM")
    return NmeaUpdate("HDM", t, heading_mag_rad=_rad(_heading(f[0])))


def _ths(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 2, "THS")
    h = _heading(f[0])
    mode = f[1]
    if mode not in ("A", "E", "M", "S", "V"):
        raise SentenceError(f"THS mode: {mode!r}")
    # A autonomous, E estimated (dead reckoning through a short GNSS outage) are usable;
    # M manual, S simulator, V not valid are not a heading to steer by.
    return NmeaUpdate("THS", t, heading_rad=_rad(h), ths_mode=mode, heading_valid=h is not None and mode in ("A", "E"))


def _rot(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 2, "ROT")
    rot = _num(f[0], "ROT", -10000.0, 10000.0)
    if f[1] not in ("A", "V"):
        raise SentenceError(f"ROT status: {f[1]!r}")
    return NmeaUpdate("ROT", t, yaw_rate_rad_s=None if rot is None else deg_min_to_rad_s(rot), status_valid=f[1] == "A" and rot is not None)


def _zda(t: str, f: list[str]) -> NmeaUpdate:
    _need(f, 4, "ZDA")
    tm = _time(f[0])
    utc = None
    if f[1] and f[2] and f[3]:
        if not (re.match(r"\d\d\Z", f[1]) and re.match(r"\d\d\Z", f[2]) and re.match(r"\d{4}\Z", f[3])):
            raise SentenceError(f"ZDA date: {f[1:4]!r}")
        d = _date(int(f[1]), int(f[2]), int(f[3]))
        if tm is not None:
            utc = _dt.datetime.combine(d, tm)
    return NmeaUpdate("ZDA", t, utc=utc, status_valid=utc is not None)


def _xdr(t: str, f: list[str]) -> NmeaUpdate | None:
    """Transducer quadruplets; only angular PTCH/PITCH/ROLL are used (pypilot, others)."""
    pitch = roll = None
    for i in range(0, len(f) - 3, 4):
        kind, value, unit, name = f[i : i + 4]
        if kind == "A" and unit == "D":
            if name.upper() in ("PTCH", "PITCH"):
                pitch = _num(value, "XDR pitch", -180.0, 180.0)
            elif name.upper() == "ROLL":
                roll = _num(value, "XDR roll", -180.0, 180.0)
    if pitch is None and roll is None:
        return None
    return NmeaUpdate("XDR", t, pitch_rad=_rad(pitch), roll_rad=_rad(roll))


def _pfec(f: list[str]) -> NmeaUpdate | None:
    """Furuno ``$PFEC,GPatt,yaw,pitch,roll`` and ``$PFEC,GPhve,heave_m,status``."""
    kind = _field(f, 0)
    if kind == "GPatt":
        _need(f, 4, "PFEC,GPatt")
        h = _heading(f[1], "GPatt yaw")
        pitch = _num(f[2], "GPatt pitch", -90.0, 90.0)
        roll = _num(f[3], "GPatt roll", -180.0, 180.0)
        return NmeaUpdate("PFEC_GPatt", "P", heading_rad=_rad(h), heading_valid=h is not None, pitch_rad=_rad(pitch),
                          roll_rad=_rad(roll))
    if kind == "GPhve":
        _need(f, 2, "PFEC,GPhve")
        heave = _num(f[1], "GPhve heave", -100.0, 100.0)
        status = _field(f, 2)
        return NmeaUpdate("PFEC_GPhve", "P", heave_m=heave, status_valid=status == "A" and heave is not None)
    return None  # AIcmd and other Furuno proprietary sentences: not ours


_DECODERS = {
    "GGA": _gga,
    "RMC": _rmc,
    "GLL": _gll,
    "VTG": _vtg,
    "HDT": _hdt,
    "HDM": _hdm,
    "THS": _ths,
    "ROT": _rot,
    "ZDA": _zda,
    "XDR": _xdr,
}


def decode_line(line: str) -> NmeaUpdate | None:
    """Decode one sentence (``$...*hh``, optional CR/LF around it).

    Returns None for a valid sentence we do not use (GSA, AIS, PSTI, ...).
    Raises :class:`ChecksumError` for a missing/wrong checksum and
    :class:`SentenceError` for bad framing or field values.
    """
    body = checked_body(line, "$", checksum_error=ChecksumError, sentence_error=SentenceError)
    fields = body.split(",")
    address = fields[0]
    if not _ADDRESS.match(address):
        raise SentenceError(f"bad address field {address!r}")
    if address.startswith("P"):
        return _pfec(fields[1:]) if address == "PFEC" else None
    talker, kind = address[:2], address[2:]
    decoder = _DECODERS.get(kind)
    if decoder is None:
        return None
    if kind in _PYNMEA2_TYPES:
        # pynmea2 with check=True is the reference for framing of standard sentences;
        # its field values are re-converted strictly below.
        try:
            msg = pynmea2.parse(f"${body}*{xor_checksum(body)}", check=True)
        except pynmea2.ChecksumError as exc:
            raise ChecksumError(str(exc)) from None
        except Exception as exc:  # pynmea2 raises several kinds on odd input
            raise SentenceError(f"pynmea2: {exc}") from None
        data = list(msg.data)
    else:
        data = fields[1:]
    return decoder(talker, data)


# --------------------------------------------------------------------------- encoding
# The other direction, for the simulated SC-30 and the tests: SI in, sentences out, through the
# same field formats the decoder reads (round trips are tested). Each returns the body between
# ``$`` and ``*``; :func:`make_sentence` frames it.


def _ddmm(value_deg: float, deg_digits: int) -> str:
    a = abs(value_deg)
    d = int(a)
    m = (a - d) * 60.0
    if m >= 59.999995:  # rounding would print 60.00000
        d, m = d + 1, 0.0
    return f"{d:0{deg_digits}d}{m:08.5f}"


def _utc_text(t_of_day_s: float) -> str:
    """hhmmss.ss of a time of day (s). Rounded to the hundredth before it is split: rounding the
    seconds alone wrote 59.996 s as "000060.00", which a decoder reads as 00:00:59 (the same
    epoch as the second before) instead of 00:01:00."""
    cs = round(t_of_day_s * 100.0) % 8_640_000
    hh, rest = divmod(cs, 360_000)
    mm, rest = divmod(rest, 6_000)
    return f"{hh:02d}{mm:02d}{rest // 100:02d}.{rest % 100:02d}"


def _heading_text(heading_rad: float) -> str:
    """Degrees with the SC-30's 0.1 deg resolution, [0, 360)."""
    return f"{round(math.degrees(heading_rad) % 360.0, 1) % 360.0:.1f}"


def _position_text(lat_deg: float, lon_deg: float) -> str:
    return f"{_ddmm(lat_deg, 2)},{'N' if lat_deg >= 0 else 'S'},{_ddmm(lon_deg, 3)},{'E' if lon_deg >= 0 else 'W'}"


def encode_heading(kind: str, heading_rad: float | None, talker: str = "GP") -> str:
    """HDT, THS or PFEC_GPatt; None = the sentence the compass sends without a heading."""
    if kind == "HDT":
        return f"{talker}HDT,,T" if heading_rad is None else f"{talker}HDT,{_heading_text(heading_rad)},T"
    if kind == "THS":
        return f"{talker}THS,,V" if heading_rad is None else f"{talker}THS,{_heading_text(heading_rad)},A"
    if kind == "PFEC_GPatt":
        return "PFEC,GPatt,,," if heading_rad is None else f"PFEC,GPatt,{_heading_text(heading_rad)},+0.0,+0.0"
    raise ValueError(f"not a heading sentence: {kind!r}")


def encode_rot(yaw_rate_rad_s: float, talker: str = "GP") -> str:
    return f"{talker}ROT,{math.degrees(yaw_rate_rad_s) * 60.0:.1f},A"


def encode_position(kind: str, *, t_of_day_s: float, lat_deg: float | None = None, lon_deg: float | None = None,
                    sog_m_s: float = 0.0, cog_rad: float = 0.0, talker: str = "GP") -> str:
    """GGA, RMC, GLL or VTG of one epoch (UTC ``t_of_day_s``); ``lat_deg`` None = no fix."""
    utc = _utc_text(t_of_day_s)
    fix = lat_deg is not None and lon_deg is not None
    pos = _position_text(lat_deg, lon_deg) if fix else ""
    sog_kn = f"{sog_m_s / KNOT_M_S:.2f}"
    cog = f"{math.degrees(cog_rad) % 360.0:.1f}"
    if kind == "GGA":
        return f"{talker}GGA,{utc},{pos},1,10,0.9,1.0,M,30.0,M,," if fix else f"{talker}GGA,{utc},,,,,0,00,,,M,,M,,"
    if kind == "RMC":
        return (f"{talker}RMC,{utc},A,{pos},{sog_kn},{cog},010624,,,A" if fix
                else f"{talker}RMC,{utc},V,,,,,,,010624,,,N")
    if kind == "GLL":
        return f"{talker}GLL,{pos},{utc},A,A" if fix else f"{talker}GLL,,,,,{utc},V,N"
    if kind == "VTG":
        return (f"{talker}VTG,{cog},T,,M,{sog_kn},N,{sog_m_s * 3.6:.2f},K,A" if fix
                else f"{talker}VTG,,T,,M,,N,,K,N")
    raise ValueError(f"not a position sentence: {kind!r}")


def encode_zda(t_of_day_s: float, talker: str = "GP") -> str:
    return f"{talker}ZDA,{_utc_text(t_of_day_s)},01,06,2024,00,00"


# --------------------------------------------------------------------------- stream


@dataclass
class NmeaStats:
    """Line counters of a :class:`NmeaStreamDecoder`.

    ``dropped`` = every rejected line (checksum, garbage, invalid fields,
    too long, non-ASCII); ``unknown`` valid sentences we do not use are not
    rejected and not in ``dropped``, nor are the lines handed to the
    ``encapsulated`` hook (the AIS decoder they go to counts its own rejections).
    """

    lines_ok: int = 0
    checksum_errors: int = 0
    garbage: int = 0
    invalid: int = 0
    unknown: int = 0
    too_long: int = 0
    non_ascii: int = 0

    @property
    def dropped(self) -> int:
        return self.checksum_errors + self.garbage + self.invalid + self.too_long + self.non_ascii

    def as_dict(self) -> dict[str, int]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["dropped"] = self.dropped
        return d


_DOLLAR = re.compile(rb"\$")  # where a sentence starts (IEC 61162-1: reserved inside one)
_STARTS = re.compile(rb"[$!]")  # ... or an encapsulated one (AIS)


class NmeaStreamDecoder:
    """Bytes in (any chunking), updates out; counts and drops what it cannot accept.

    Lines end at LF, CRLF or a lone CR (CR is stripped), framed by :class:`~autopilot.drivers.framing.LineFramer`.
    A line is resynchronised at its first ``$`` (with ``encapsulated``, or ``!``); bytes before it (the tail of a
    sentence cut by a reconnect) make no difference unless none follows, then the line counts as garbage. Each
    ``$`` (and, with ``encapsulated``, each ``!``) starts a sentence, judged by its own checksum: one cut
    short before the next is one checksum error, a whole one that lost its line end is read.
    A line longer than ``max_line_chars`` is discarded up to its LF, so a stream without
    newlines cannot grow memory. :attr:`invalid_bytes` counts bytes that no NMEA line can hold
    (the garbage detector's byte measure).

    ``encapsulated`` (optional): a callable given every sentence that starts with
    ``!`` (IEC 61162-1 encapsulation: AIS ``!AIVDM``/``!AIVDO`` interleaved on the
    compass line), from the ``!`` to the next start delimiter or the line end, as
    bytes without the line end; e.g. :meth:`autopilot.drivers.ais.AisReceiver.feed_line`.
    Without it a line of them counts as garbage. An exception in the callable is
    swallowed. :attr:`encapsulated_lines` counts the sentences handed over.
    """

    def __init__(self, max_line_chars: int = MAX_LINE_CHARS, *,
                 encapsulated: Callable[[bytes], object] | None = None) -> None:
        self.max_line_chars = int(max_line_chars)
        self.stats = NmeaStats()
        self._framer = LineFramer(self.max_line_chars, cr_ends_line=True)
        self.encapsulated = encapsulated
        self.encapsulated_lines = 0

    @property
    def invalid_bytes(self) -> int:
        return self._framer.invalid_bytes

    def feed(self, data: bytes) -> list[NmeaUpdate]:
        """Decode every complete line in ``data`` (plus what was held back). Never raises."""
        return [u for u, _, _ in self.feed_spans(data)]

    def feed_spans(self, data: bytes) -> list[tuple[NmeaUpdate, int, int]]:
        """:meth:`feed` with each update's span: (update, its sentence's characters (the last on its line with the
        line end), the characters of ``data`` after them) (framing.LineFramer.feed_spans). Each sentence of a line
        that lost its line end has its own span: with the line's, the second heading of such a line was dated
        where the first began, and its tick clock reset (a review)."""
        out: list[tuple[NmeaUpdate, int, int]] = []
        try:
            for line, chars, after in self._framer.feed_spans(data):
                for update, i, j in self._line(line):
                    end = chars if j is None else j
                    out.append((update, end - i, after + chars - end))
        except Exception:  # pragma: no cover - defensive: the loop must survive anything
            self._framer.clear()
            self.stats.garbage += 1
        self.stats.too_long = self._framer.too_long
        return out

    def _line(self, raw: bytes) -> list[tuple[NmeaUpdate, int, int | None]]:
        """The updates of one line, each with its sentence's offsets in ``raw`` (start, end; None: the line's end)."""
        raw = raw.rstrip(b"\r")
        if not raw:
            return []
        cuts = [m.start() for m in (_STARTS if self.encapsulated is not None else _DOLLAR).finditer(raw)]
        if not cuts:
            self.stats.garbage += 1
            return []
        # '$' and '!' are reserved inside a sentence, so each starts one: a line that lost its line end holds
        # several, each judged by its own checksum (a sentence cut short is the checksum error it is, the ones
        # after it are read). Found by fault injection: an AIS sentence behind a cut compass sentence went with
        # the cut head into one checksum error, and a whole sentence before another was counted as cut
        out = []
        for k, i in enumerate(cuts):
            j = cuts[k + 1] if k + 1 < len(cuts) else None
            part = raw[i:j]
            if part[:1] == b"!":
                self.encapsulated_lines += 1
                try:
                    self.encapsulated(part)
                except Exception:
                    pass  # the hook's failure is its own: the compass line goes on
                continue
            update = self._sentence(part)
            if update is not None:
                out.append((update, i, j))
        return out

    def _sentence(self, raw: bytes) -> NmeaUpdate | None:
        """One sentence from its ``$`` to the line end or the next start delimiter."""
        try:
            text = raw.decode("ascii")
        except UnicodeDecodeError:
            self.stats.non_ascii += 1
            return None
        try:
            update = decode_line(text)
        except ChecksumError:
            self.stats.checksum_errors += 1
            return None
        except SentenceError:
            self.stats.invalid += 1
            return None
        except Exception:
            self.stats.invalid += 1
            return None
        if update is None:
            self.stats.unknown += 1
            return None
        self.stats.lines_ok += 1
        return update
