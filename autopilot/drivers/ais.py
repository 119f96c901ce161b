"""AIS over NMEA 0183 (``!AIVDM`` / ``!AIVDO``): bytes in, decoded messages and a target table out, no I/O.

Layers, each pure (times are passed in, nothing reads a clock):

- :func:`parse_fragment`: one line -> one :class:`AisFragment` (framing and
  checksum checked here, strictly: ``!ccVDM|VDO,count,number,seq,channel,payload,fill*hh``);
- :class:`FragmentAssembler`: multi-part messages put together by
  (VDM/VDO, talker, sequence id, channel, fragment count), with a timeout:
  a message whose parts do not all arrive within ``assembly_timeout_s`` is
  dropped and its fragments counted as ``unassembled``;
- :func:`decode_fragments`: the 6-bit payload decoded by pyais (types 1-3,
  5, 18, 19, 24 A and B) into one :class:`AisMessage` in SI: radians, m/s,
  metres; the "not available" codes (latitude 91, longitude 181, speed
  102.3 kn, course 360, heading 511, dimension 0, turn -128) become None;
- :class:`AisStreamDecoder`: byte chunks -> messages; counts and drops every
  line it cannot accept; never raises, whatever the bytes (fuzzed in
  ``benchmarks/fuzz_ais.py`` and a hypothesis property);
- :class:`TargetTable`: targets by MMSI (position, course and speed over
  ground, heading, name, dimensions, class A/B, last update and age), stale
  targets dropped after ``stale_after_s``; own ship (``!AIVDO``, or a
  configured own MMSI) kept apart in :attr:`TargetTable.own`;
- :class:`AisReceiver`: a stream decoder feeding a table: what a driver or the
  NMEA hook (:class:`autopilot.drivers.nmea.NmeaStreamDecoder`'s
  ``encapsulated`` callback) holds.

Counters (:class:`AisStats`) follow the NMEA decoder's: ``dropped`` counts
every rejected line (checksum, garbage, invalid framing, unassembled,
undecodable payload, too long, non-ASCII) and is what a
:class:`~autopilot.drivers.framing.GarbageDetector` takes as its bad-line
count; a correct message of a type we do not use (4 base station, 8 binary,
21 aids to navigation, 27 long range, ...) counts as ``unsupported`` and is
not garbage, as the NMEA decoder's ``unknown`` is not: a busy channel is full
of them.

Degrees and knots exist only here, at the codec edge (:mod:`autopilot.units`),
except latitude/longitude, which the project keeps in degrees until
:func:`autopilot.geo.latlon_to_local`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from autopilot.drivers.framing import LineFramer, checked_body, xor_checksum
from autopilot.geo import latlon_to_local
from autopilot.schema import param
from autopilot.units import knots_to_m_s

__all__ = [
    "AisError",
    "AisChecksumError",
    "AisSentenceError",
    "AisDecodeError",
    "AisUnsupportedError",
    "AisFragment",
    "AisMessage",
    "AisStats",
    "AisConfig",
    "AisTarget",
    "FragmentAssembler",
    "AisStreamDecoder",
    "TargetTable",
    "AisReceiver",
    "parse_fragment",
    "decode_fragments",
    "decode_sentences",
    "payload_type",
    "SUPPORTED_TYPES",
    "MAX_LINE_CHARS",
]

MAX_LINE_CHARS = 200  # as the NMEA decoder: IEC 61162-1 says 82, receivers with TAG blocks send more
SUPPORTED_TYPES = frozenset({1, 2, 3, 5, 18, 19, 24})
CLASS_A_TYPES = frozenset({1, 2, 3, 5})
# least payload bits for the fields we use (ITU-R M.1371-5 Annex 8; type 5 is 424 bits, some
# transponders send 420 with the final DTE/spare cut, which gpsd accepts too; 24 A is 160 or 168)
MIN_BITS = {1: 168, 2: 168, 3: 168, 5: 420, 18: 168, 19: 312, 24: 160}

_ADDRESS = re.compile(r"![A-Z]{2}VD[MO]\Z")
_ANY_ADDRESS = re.compile(r"![A-Z0-9]{2,7}\Z")
_ARMOUR = re.compile(r"[0-W`-w]*\Z")  # the 6-bit armouring: '0'..'W' and '`'..'w' (ITU-R M.1371 / IEC 61162-1)

# "not available" codes (ITU-R M.1371-5 Annex 2 / 8, as gpsd's AIVDM document lists them)
LAT_NA_DEG = 91.0
LON_NA_DEG = 181.0
SPEED_NA_KN = 102.3
COURSE_NA_DEG = 360.0
HEADING_NA = 511


class AisError(ValueError):
    """A line or message that cannot be accepted."""


class AisChecksumError(AisError):
    """Missing, malformed or wrong ``*hh`` checksum."""


class AisSentenceError(AisError):
    """A checksummed line whose framing or fields are not a VDM/VDO fragment."""


class AisDecodeError(AisError):
    """A complete message whose payload cannot be decoded (too short, bad values, pyais refused it)."""


class AisUnsupportedError(AisError):
    """A correct message of a type this decoder does not use."""


# --------------------------------------------------------------------------- fragments


@dataclass(frozen=True)
class AisFragment:
    """One VDM/VDO sentence: a fragment of an AIS message."""

    talker: str  # "AI", "AB", "BS", ...
    own_ship: bool  # VDO: our own transponder's report
    count: int  # fragments in the message, 1..9
    number: int  # this one, 1..count
    seq_id: int | None  # sequential message id 0..9 (multi-part only)
    channel: str  # "A", "B", "1", "2" or "" (receivers differ)
    payload: str
    fill_bits: int
    raw: str  # the sentence without CR/LF


def _sixbit(c: str) -> int:
    """The 6 bits one armoured payload character carries."""
    v = ord(c) - 48
    return v - 8 if v > 40 else v


def payload_type(payload: str) -> int | None:
    """Message type (the first 6 bits) of an armoured payload; None for an empty one."""
    return _sixbit(payload[0]) if payload else None


def parse_fragment(line: str) -> AisFragment:
    """Check and split one ``!..VDM`` / ``!..VDO`` sentence (CR/LF around it allowed).

    Raises :class:`AisChecksumError` for a missing/wrong checksum and :class:`AisSentenceError`
    for anything else that is not a fragment (another encapsulated sentence included).
    """
    body = checked_body(line, "!", checksum_error=AisChecksumError, sentence_error=AisSentenceError)
    f = body.split(",")
    address = "!" + f[0]
    if not _ADDRESS.match(address):
        raise AisSentenceError(f"not a VDM/VDO sentence: {f[0]!r}")
    if len(f) != 7:
        raise AisSentenceError(f"{len(f)} fields, a VDM/VDO has 7")
    count_s, number_s, seq_s, channel, payload, fill_s = f[1:]
    if not (len(count_s) == 1 and count_s in "123456789"):
        raise AisSentenceError(f"fragment count {count_s!r}")
    if not (len(number_s) == 1 and number_s in "123456789") or int(number_s) > int(count_s):
        raise AisSentenceError(f"fragment number {number_s!r} of {count_s}")
    if seq_s and not (len(seq_s) == 1 and seq_s.isdigit()):
        raise AisSentenceError(f"sequential message id {seq_s!r}")
    if channel not in ("", "A", "B", "1", "2"):
        raise AisSentenceError(f"channel {channel!r}")
    if not payload or not _ARMOUR.match(payload):
        raise AisSentenceError("empty payload or a character outside the 6-bit armouring")
    if not (len(fill_s) == 1 and fill_s in "012345"):
        raise AisSentenceError(f"fill bits {fill_s!r}")
    return AisFragment(
        talker=f[0][:2], own_ship=f[0][2:] == "VDO", count=int(count_s), number=int(number_s),
        seq_id=int(seq_s) if seq_s else None, channel=channel, payload=payload, fill_bits=int(fill_s), raw=line.strip("\r\n"),
    )


class FragmentAssembler:
    """Multi-part messages put together (pure: the caller passes the time).

    Fragments belong together when they share (VDM/VDO, talker, sequence id, channel,
    count); IEC 61162-1 sends them back to back and in order, so a message still incomplete
    ``timeout_s`` after its first fragment is dropped, and a fragment joins only the message
    whose every earlier fragment came before it (gpsd's rule too): a part 1 starts a message
    anew, a part that does not follow on is dropped with what waited under its key. Accepting
    parts in any order joined the part 2 of a message whose part 1 was lost to the part 1 of
    the next message with the same key (the sequence id is left empty by some receivers and
    comes round every ten messages): one vessel's name on another's MMSI. Dropped fragments
    are counted in :attr:`unassembled`. At most ``max_pending`` messages wait at once
    (the oldest is dropped), so memory stays bounded whatever arrives.
    """

    def __init__(self, timeout_s: float = 2.0, max_pending: int = 16) -> None:
        self.timeout_s = float(timeout_s)
        self.max_pending = int(max_pending)
        self._pending: dict[tuple, tuple[float, dict[int, AisFragment]]] = {}
        self.unassembled = 0

    def expire(self, now_s: float) -> None:
        """Drop what has waited longer than the timeout."""
        for key in [k for k, (t0, _) in self._pending.items() if now_s - t0 > self.timeout_s]:
            self.unassembled += len(self._pending.pop(key)[1])

    def push(self, frag: AisFragment, now_s: float) -> list[AisFragment] | None:
        """The message's fragments in order once complete, else None."""
        if frag.count == 1:
            return [frag]
        self.expire(now_s)
        key = (frag.own_ship, frag.talker, frag.seq_id, frag.channel, frag.count)
        entry = self._pending.get(key)
        follows = len(entry[1]) + 1 if entry is not None else 1
        if frag.number != follows:  # not the next part of what waits: neither belongs to a whole message
            if entry is not None:
                self.unassembled += len(self._pending.pop(key)[1])
                entry = None
            if frag.number != 1:
                self.unassembled += 1
                return None
        if entry is None:
            if len(self._pending) >= self.max_pending:
                oldest = min(self._pending, key=lambda k: self._pending[k][0])
                self.unassembled += len(self._pending.pop(oldest)[1])
            entry = (now_s, {})
            self._pending[key] = entry
        entry[1][frag.number] = frag
        if len(entry[1]) == frag.count:
            del self._pending[key]
            return [entry[1][n] for n in range(1, frag.count + 1)]
        return None

    @property
    def pending(self) -> int:
        """Fragments waiting for the rest of their message."""
        return sum(len(p) for _, p in self._pending.values())

    def clear(self) -> None:
        self._pending.clear()


# --------------------------------------------------------------------------- messages


@dataclass(frozen=True)
class AisMessage:
    """One decoded AIS message in SI. What it does not carry, or carries as "not available", is None.

    ``cog_rad`` / ``heading_rad`` are true, clockwise from north, in [0, 2 pi); ``sog_m_s`` over
    ground; ``turn_rad_s`` the rate of turn (+ = to starboard, types 1-3 only, None when the
    sender has no turn indicator); ``to_bow_m`` ... ``to_starboard_m`` the reference point's
    distances to the hull's ends and sides (types 5, 19, 24 B). ``part`` is "A" or "B" for type 24.
    """

    msg_type: int
    mmsi: int
    own_ship: bool
    ais_class: str  # "A" (types 1-3, 5) or "B" (18, 19, 24)
    channel: str = ""
    repeat: int = 0  # the repeat indicator: > 0, a copy a repeater relayed
    lat_deg: float | None = None
    lon_deg: float | None = None
    sog_m_s: float | None = None
    cog_rad: float | None = None
    heading_rad: float | None = None
    turn_rad_s: float | None = None
    nav_status: int | None = None
    shipname: str | None = None
    callsign: str | None = None
    ship_type: int | None = None
    to_bow_m: float | None = None
    to_stern_m: float | None = None
    to_port_m: float | None = None
    to_starboard_m: float | None = None
    part: str | None = None

    @property
    def has_position(self) -> bool:
        return self.lat_deg is not None


def _int(v) -> int | None:
    if v is None or isinstance(v, bool):
        return None
    try:
        return int(v)
    except (TypeError, ValueError):
        return None


def _float(v) -> float | None:
    if v is None or isinstance(v, bool):
        return None
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _text(v) -> str | None:
    if not isinstance(v, str):
        return None
    s = v.replace("@", " ").strip()  # '@' is the 6-bit text's padding
    return s or None


def _ship_type(v) -> int | None:
    t = _int(v)
    return None if t is None or t <= 0 else t  # 0 = not available


def _dimension(v) -> float | None:
    d = _int(v)
    return None if d is None or d <= 0 else float(d)  # 0 = not available


def _position(msg) -> tuple[float | None, float | None]:
    lat, lon = _float(getattr(msg, "lat", None)), _float(getattr(msg, "lon", None))
    if lat is None or lon is None or abs(lat) > 90.0 or abs(lon) > 180.0:
        return None, None  # 91 / 181 = not available; anything else beyond is invalid
    return lat, lon


def _motion(msg) -> tuple[float | None, float | None, float | None]:
    sog_kn = _float(getattr(msg, "speed", None))
    sog = None if sog_kn is None or sog_kn >= SPEED_NA_KN - 1e-6 or sog_kn < 0.0 else knots_to_m_s(sog_kn)
    cog_deg = _float(getattr(msg, "course", None))
    cog = None if cog_deg is None or not 0.0 <= cog_deg < COURSE_NA_DEG else math.radians(cog_deg)
    hdg = _int(getattr(msg, "heading", None))
    heading = None if hdg is None or not 0 <= hdg < 360 else math.radians(hdg)
    return sog, cog, heading


def _turn(msg) -> float | None:
    """ROT_AIS as pyais converts it (deg/min, (raw / 4.733)^2 signed); +-127 and -128 are no turn indicator."""
    t = getattr(msg, "turn", None)
    if t is None or type(t) is not float and type(t) is not int:  # pyais's TurnRate enum: no rate given
        return None
    if abs(t) > 720.0:  # ROT_AIS 126 = 708 deg/min is the largest rate
        return None
    return math.radians(t) / 60.0


def decode_fragments(fragments: list[AisFragment]) -> AisMessage:
    """Decode one complete message (its fragments in order) with pyais.

    Raises :class:`AisUnsupportedError` for a type outside :data:`SUPPORTED_TYPES` and
    :class:`AisDecodeError` for a payload that is too short or that pyais cannot decode.
    """
    from pyais.messages import NMEAMessage

    payload = "".join(f.payload for f in fragments)
    kind = payload_type(payload)
    if kind not in SUPPORTED_TYPES:
        raise AisUnsupportedError(f"message type {kind}")
    n_bits = 6 * len(payload) - fragments[-1].fill_bits
    if n_bits < MIN_BITS[kind]:
        raise AisDecodeError(f"type {kind}: {n_bits} bits, need {MIN_BITS[kind]}")
    if kind == 24 and (_sixbit(payload[6]) >> 2) & 3 > 1:  # bits 38-39: parts 2 and 3 are reserved
        raise AisUnsupportedError(f"type 24 part number {(_sixbit(payload[6]) >> 2) & 3} (reserved)")
    try:
        parts = [NMEAMessage(f.raw.encode("ascii")) for f in fragments]
        msg = NMEAMessage.assemble_from_iterable(parts).decode() if len(parts) > 1 else parts[0].decode()
    except Exception as exc:  # pyais raises its own exceptions and others on odd payloads
        raise AisDecodeError(f"pyais: {type(exc).__name__}: {exc}") from None
    mmsi = _int(getattr(msg, "mmsi", None))
    if mmsi is None or not 0 < mmsi <= 999_999_999:
        raise AisDecodeError(f"MMSI {getattr(msg, 'mmsi', None)!r}")
    common = dict(msg_type=kind, mmsi=mmsi, own_ship=fragments[0].own_ship, channel=fragments[0].channel,
                  ais_class="A" if kind in CLASS_A_TYPES else "B", repeat=_int(getattr(msg, "repeat", 0)) or 0)
    if kind in (1, 2, 3, 18, 19):
        lat, lon = _position(msg)
        sog, cog, heading = _motion(msg)
        extra = {}
        if kind in (1, 2, 3):
            extra = dict(turn_rad_s=_turn(msg), nav_status=_int(getattr(msg, "status", None)))
        if kind == 19:
            extra = dict(shipname=_text(msg.shipname), ship_type=_ship_type(msg.ship_type), **_dims(msg))
        return AisMessage(**common, lat_deg=lat, lon_deg=lon, sog_m_s=sog, cog_rad=cog, heading_rad=heading, **extra)
    if kind == 5:
        return AisMessage(**common, shipname=_text(msg.shipname), callsign=_text(msg.callsign),
                          ship_type=_ship_type(msg.ship_type), **_dims(msg))
    # type 24: part A the name, part B type, call sign and dimensions (an auxiliary craft's part B
    # carries its mother ship's MMSI instead of dimensions: those stay None)
    partno = _int(getattr(msg, "partno", None))
    if partno == 0:
        return AisMessage(**common, part="A", shipname=_text(msg.shipname))
    if partno == 1:
        return AisMessage(**common, part="B", callsign=_text(getattr(msg, "callsign", None)),
                          ship_type=_ship_type(getattr(msg, "ship_type", None)), **_dims(msg))
    raise AisDecodeError(f"type 24 part number {partno!r}")  # pragma: no cover - pyais refuses these itself


def _dims(msg) -> dict:
    return dict(to_bow_m=_dimension(getattr(msg, "to_bow", None)), to_stern_m=_dimension(getattr(msg, "to_stern", None)),
                to_port_m=_dimension(getattr(msg, "to_port", None)),
                to_starboard_m=_dimension(getattr(msg, "to_starboard", None)))


def decode_sentences(lines: Iterable[str]) -> AisMessage:
    """Decode one message from its sentence(s) (a convenience for tests and tools; raises AisError)."""
    frags = [parse_fragment(s) for s in lines]
    if not frags or len(frags) != frags[0].count or [f.number for f in frags] != list(range(1, len(frags) + 1)):
        raise AisSentenceError("not the complete, ordered fragments of one message")
    return decode_fragments(frags)


# --------------------------------------------------------------------------- stream


@dataclass
class AisStats:
    """Line and message counters of an :class:`AisStreamDecoder`.

    ``dropped`` = every rejected line: checksum errors, garbage (no ``!``), invalid framing,
    fragments that never made a message (``unassembled``), lines of messages whose payload
    could not be decoded (``undecodable``), too long, non-ASCII. ``unsupported`` (a correct
    message of a type we do not use) and ``unknown`` (another encapsulated sentence, e.g.
    ``!AIABK``) are not rejections.
    """

    lines_ok: int = 0  # fragments accepted
    messages: int = 0  # messages decoded
    own_messages: int = 0  # of which VDO
    checksum_errors: int = 0
    garbage: int = 0
    invalid: int = 0
    unassembled: int = 0
    undecodable: int = 0
    unsupported: int = 0
    unknown: int = 0
    too_long: int = 0
    non_ascii: int = 0

    @property
    def dropped(self) -> int:
        return (self.checksum_errors + self.garbage + self.invalid + self.unassembled + self.undecodable
                + self.too_long + self.non_ascii)

    def as_dict(self) -> dict[str, int]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["dropped"] = self.dropped
        return d


_STARTS = re.compile(rb"[!$]")  # where a sentence starts (IEC 61162-1: reserved inside one)


class AisStreamDecoder:
    """Bytes (any chunking) or whole lines in, :class:`AisMessage` out; never raises.

    A line is resynchronised at its first ``!`` (a TAG block ``\\s:..*hh\\`` before it is
    skipped); each ``!`` or ``$`` starts a sentence judged by its own checksum: a fragment cut short before the
    next is one checksum error, whole ones on a line that lost its line end are each read.
    ``now_s`` (any monotonic seconds) only times multi-part assembly.
    """

    def __init__(self, *, assembly_timeout_s: float = 2.0, max_line_chars: int = MAX_LINE_CHARS) -> None:
        self.stats = AisStats()
        self._framer = LineFramer(int(max_line_chars), cr_ends_line=True)
        self._assembler = FragmentAssembler(assembly_timeout_s)

    @property
    def invalid_bytes(self) -> int:
        """Bytes no line can hold (the garbage detector's byte measure; bytes fed by :meth:`feed`)."""
        return self._framer.invalid_bytes

    @property
    def pending_fragments(self) -> int:
        return self._assembler.pending

    def feed(self, data: bytes, now_s: float) -> list[AisMessage]:
        """Decode every complete line in ``data`` (plus what was held back)."""
        out: list[AisMessage] = []
        try:
            for line in self._framer.feed(data):
                out += self.feed_line(line, now_s)
        except Exception:  # pragma: no cover - defensive: the loop must survive anything
            self._framer.clear()
            self.stats.garbage += 1
        self.stats.too_long = self._framer.too_long
        return out

    def feed_line(self, raw: bytes | str, now_s: float) -> list[AisMessage]:
        """One line (without or with CR/LF): the messages it completes (0 or 1). Never raises."""
        try:
            return self._line(raw, now_s)
        except Exception:  # pragma: no cover - defensive
            self.stats.invalid += 1
            return []

    def _line(self, raw: bytes | str, now_s: float) -> list[AisMessage]:
        st = self.stats
        self._assembler.expire(now_s)
        st.unassembled = self._assembler.unassembled
        if isinstance(raw, str):
            try:
                raw = raw.encode("ascii")
            except UnicodeEncodeError:
                st.non_ascii += 1
                return []
        raw = raw.strip(b"\r\n")
        if not raw:
            return []
        cuts = [m.start() for m in _STARTS.finditer(raw)]
        if not any(raw[i:i + 1] == b"!" for i in cuts):
            st.garbage += 1
            return []
        # '!' and '$' are reserved inside a sentence, so each starts one: a line that lost its line end holds
        # several, each judged by its own checksum (a fragment cut short is the checksum error it is). Found by a
        # review: the last '!' alone was read, so two whole fragments on one line were a checksum error and a part
        # without its first, and a fragment with another talker's '$' sentence behind it was lost
        out: list[AisMessage] = []
        for k, i in enumerate(cuts):
            part = raw[i:cuts[k + 1]] if k + 1 < len(cuts) else raw[i:]
            if part[:1] == b"$":
                if _checksum_ok(part.decode("ascii", "replace")):
                    st.unknown += 1  # another talker's sentence on the AIS line: valid, not ours
                else:
                    st.checksum_errors += 1
                continue
            out += self._fragment(part, now_s)
        return out

    def _fragment(self, raw: bytes, now_s: float) -> list[AisMessage]:
        """One '!' sentence: the message it completes, if any."""
        st = self.stats
        try:
            text = raw.decode("ascii")
        except UnicodeDecodeError:
            st.non_ascii += 1
            return []
        try:
            frag = parse_fragment(text)
        except AisChecksumError:
            st.checksum_errors += 1
            return []
        except AisSentenceError:
            head = text.split(",", 1)[0]
            if _ANY_ADDRESS.match(head) and not head.endswith(("VDM", "VDO")) and _checksum_ok(text):
                st.unknown += 1  # another encapsulated sentence (ABK, ALR, ...): valid, not ours
            else:
                st.invalid += 1
            return []
        st.lines_ok += 1
        frags = self._assembler.push(frag, now_s)
        st.unassembled = self._assembler.unassembled
        if frags is None:
            return []
        try:
            msg = decode_fragments(frags)
        except AisUnsupportedError:
            st.unsupported += 1
            return []
        except Exception:
            st.undecodable += len(frags)
            return []
        st.messages += 1
        st.own_messages += msg.own_ship
        return [msg]

    def clear(self) -> None:
        """Forget partial lines and messages (the port was reopened)."""
        self._framer.clear()
        self._assembler.clear()


def _checksum_ok(text: str) -> bool:
    star = text.rfind("*")
    return star > 0 and text[star + 1 :].upper() == xor_checksum(text[1:star])


# --------------------------------------------------------------------------- targets


@dataclass(frozen=True)
class AisConfig:
    """AIS reception settings (YAML keys are the field names)."""

    stale_after_s: float = param(
        360.0, unit="s", lo=10.0, hi=3600.0,
        source="ITU-R M.1371-5 Annex 1 Tables 1-2: the longest nominal reporting interval is 3 min "
        "(class A at anchor or < 3 kn, class B CS < 2 kn)",
        doc="a target with no position report for this long is dropped (two of the longest reporting "
        "intervals, so one lost report of a slow or anchored ship keeps it)",
    )
    assembly_timeout_s: float = param(
        2.0, unit="s", lo=0.1, hi=60.0,
        source="IEC 61162-1: the fragments of a message are sent back to back",
        doc="a multi-part message still incomplete this long after its first fragment is dropped",
    )
    max_targets: int = param(
        2000, unit="-", lo=1, hi=100000, source="memory bound",
        doc="at most this many targets are kept; beyond, the one heard from longest ago is dropped",
    )
    own_mmsi: int = param(
        0, unit="-", lo=0, hi=999999999, source="the boat's own transponder, if it has one",
        doc="reports with this MMSI (VDM echoes of our own transponder) are own ship, as every VDO is; 0 = none",
    )


@dataclass(frozen=True)
class AisTarget:
    """What is known of one vessel, SI (latitude/longitude in degrees). Times are the caller's seconds.

    ``position_t_s``: when the last position report arrived (None: none yet); ``static_t_s``:
    the last static report (types 5, 19, 24); ``last_t_s``: the last message of any kind.
    """

    mmsi: int
    ais_class: str
    last_t_s: float
    lat_deg: float | None = None
    lon_deg: float | None = None
    sog_m_s: float | None = None
    cog_rad: float | None = None
    heading_rad: float | None = None
    turn_rad_s: float | None = None
    nav_status: int | None = None
    position_t_s: float | None = None
    shipname: str | None = None
    callsign: str | None = None
    ship_type: int | None = None
    to_bow_m: float | None = None
    to_stern_m: float | None = None
    to_port_m: float | None = None
    to_starboard_m: float | None = None
    static_t_s: float | None = None
    messages: int = 0
    # velocity over ground (north, east; m/s) from its last two position reports, TRACK_MIN_S to TRACK_MAX_S apart:
    # what moves it when its report says course or speed "not available" (None: no such pair)
    track_ne_m_s: tuple[float, float] | None = None

    def age_s(self, now_s: float) -> float:
        """Seconds since the last position report (inf without one)."""
        return math.inf if self.position_t_s is None else now_s - self.position_t_s

    @property
    def has_position(self) -> bool:
        return self.lat_deg is not None

    @property
    def length_m(self) -> float | None:
        """Overall length from the dimensions (None unless both bow and stern are known)."""
        if self.to_bow_m is None or self.to_stern_m is None:
            return None
        return self.to_bow_m + self.to_stern_m

    @property
    def beam_m(self) -> float | None:
        if self.to_port_m is None or self.to_starboard_m is None:
            return None
        return self.to_port_m + self.to_starboard_m

    @property
    def extent_m(self) -> float:
        """Farthest hull point from the reported position (0 when the dimensions are unknown): what a
        safe distance measured between reference points must add for this vessel."""
        d = [v for v in (self.to_bow_m, self.to_stern_m, self.to_port_m, self.to_starboard_m) if v is not None]
        return max(d) if d else 0.0


_POSITION_FIELDS = ("lat_deg", "lon_deg", "sog_m_s", "cog_rad", "heading_rad")
TRACK_MIN_S = 1.0  # closer reports (the same one on both channels) leave the track as it was
TRACK_MAX_S = 180.0  # the longest nominal report interval (ITU-R M.1371-5 Annex 1 Tables 1-2)


def _track(old: AisTarget, msg: AisMessage, now_s: float) -> tuple[float, float] | None:
    """The velocity over ground between ``old``'s position and ``msg``'s (see AisTarget.track_ne_m_s)."""
    if msg.lat_deg is None or msg.lon_deg is None or not old.has_position or old.position_t_s is None:
        return None
    dt = now_s - old.position_t_s
    if dt < TRACK_MIN_S:
        return old.track_ne_m_s
    if dt > TRACK_MAX_S:
        return None
    north_m, east_m = latlon_to_local(msg.lat_deg, msg.lon_deg, old.lat_deg, old.lon_deg)
    return north_m / dt, east_m / dt
_STATIC_FIELDS = ("shipname", "callsign", "ship_type", "to_bow_m", "to_stern_m", "to_port_m", "to_starboard_m")


class TargetTable:
    """Targets by MMSI, updated from :class:`AisMessage` (pure: times are passed in).

    A position report (types 1-3, 18, 19) replaces position, course, speed and heading
    together ("not available" replaces a known value with None: the sender says it does not
    know); a static report (5, 19, 24) fills what it carries and keeps the rest. Own-ship
    reports (VDO, or ``own_mmsi``) go to :attr:`own` and never into the targets.
    """

    def __init__(self, config: AisConfig = AisConfig()) -> None:
        self.config = config
        self._targets: dict[int, AisTarget] = {}
        self.own: AisTarget | None = None
        self.dropped_stale = 0
        self.evicted = 0
        self.updates = 0

    def __len__(self) -> int:
        return len(self._targets)

    def __contains__(self, mmsi: int) -> bool:
        return mmsi in self._targets

    def get(self, mmsi: int) -> AisTarget | None:
        return self._targets.get(mmsi)

    def update(self, msg: AisMessage, now_s: float) -> AisTarget:
        """Fold one message in; the target's new record."""
        self.updates += 1
        own = msg.own_ship or (self.config.own_mmsi and msg.mmsi == self.config.own_mmsi)
        old = self.own if own else self._targets.get(msg.mmsi)
        if old is None or (own and old.mmsi != msg.mmsi):
            old = AisTarget(mmsi=msg.mmsi, ais_class=msg.ais_class, last_t_s=now_s)
        changes: dict = {"last_t_s": now_s, "messages": old.messages + 1, "ais_class": msg.ais_class}
        if msg.msg_type in (1, 2, 3, 18, 19):
            # "position not available" (lat 91, lon 181) from a vessel already placed made it vanish from collision
            # avoidance at once; its last position and motion stay, dead-reckoned and ageing until it is stale
            relayed = (msg.repeat > 0 and old.has_position and msg.lat_deg == old.lat_deg
                       and msg.lon_deg == old.lon_deg)
            # a repeater's copy of a report already heard is no new position: taken as one, 2.5 s after the
            # original it made a moving vessel's track "stopped", and the next report's speed too high
            if not relayed and (msg.lat_deg is not None or not old.has_position):
                changes.update({k: getattr(msg, k) for k in _POSITION_FIELDS})
                changes["position_t_s"] = now_s
                changes["track_ne_m_s"] = _track(old, msg, now_s)
            changes["turn_rad_s"] = msg.turn_rad_s
            if msg.nav_status is not None:
                changes["nav_status"] = msg.nav_status
        if msg.msg_type in (5, 19, 24):
            changes.update({k: getattr(msg, k) for k in _STATIC_FIELDS if getattr(msg, k) is not None})
            if msg.msg_type == 5 or msg.msg_type == 19:  # complete static reports: absent = not available
                changes.update({k: getattr(msg, k) for k in _STATIC_FIELDS if k.startswith("to_")})
            changes["static_t_s"] = now_s
        new = dataclasses.replace(old, **changes)
        if own:
            self.own = new
            return new
        if msg.mmsi not in self._targets and len(self._targets) >= self.config.max_targets:
            oldest = min(self._targets.values(), key=lambda t: t.last_t_s)
            del self._targets[oldest.mmsi]
            self.evicted += 1
        self._targets[msg.mmsi] = new
        return new

    def prune(self, now_s: float) -> tuple[int, ...]:
        """Drop targets without a position report for ``stale_after_s`` (or, never positioned, without
        any message that long); the MMSIs dropped."""
        limit = self.config.stale_after_s
        gone = tuple(
            m for m, t in self._targets.items()
            if now_s - (t.position_t_s if t.position_t_s is not None else t.last_t_s) > limit
        )
        for m in gone:
            del self._targets[m]
        self.dropped_stale += len(gone)
        if self.own is not None and now_s - self.own.last_t_s > limit:
            self.own = None
        return gone

    def targets(self, now_s: float | None = None, *, with_position: bool = True) -> list[AisTarget]:
        """Targets (by MMSI); with ``now_s`` stale ones are pruned first."""
        if now_s is not None:
            self.prune(now_s)
        return [t for _, t in sorted(self._targets.items()) if t.has_position or not with_position]


class AisReceiver:
    """A stream decoder feeding a target table: bytes or lines in, targets out (pure, times passed in).

    ``on_message`` (optional) is called with each decoded message after it is folded in (for a
    log). Hand :meth:`feed_line` to :class:`autopilot.drivers.nmea.NmeaStreamDecoder` as its
    ``encapsulated`` callback to take AIS interleaved on the compass line; use :meth:`feed`
    for a port of its own.
    """

    def __init__(self, config: AisConfig = AisConfig(), *, on_message: Callable[[AisMessage], None] | None = None,
                 clock_s: Callable[[], float] | None = None) -> None:
        # pyais is imported now, when the daemon starts, not at the first message: that import (~0.25 s)
        # once ran inside the control loop and stalled it 340 ms (two deadlines skipped, 0.5 s is the
        # Mbed's own stop)
        import pyais.messages  # noqa: F401

        self.config = config
        self.decoder = AisStreamDecoder(assembly_timeout_s=config.assembly_timeout_s)
        self.table = TargetTable(config)
        self.on_message = on_message
        self.callback_errors = 0  # exceptions raised by on_message (swallowed)
        self._clock_s = clock_s  # only for the NMEA hook, which passes no time

    def feed(self, data: bytes, now_s: float) -> list[AisMessage]:
        msgs = self.decoder.feed(data, now_s)
        self._apply(msgs, now_s)
        return msgs

    def feed_line(self, line: bytes | str, now_s: float | None = None) -> list[AisMessage]:
        """One line; without ``now_s`` the ``clock_s`` given at construction stamps it."""
        if now_s is None:
            now_s = self._clock_s() if self._clock_s is not None else 0.0
        msgs = self.decoder.feed_line(line, now_s)
        self._apply(msgs, now_s)
        return msgs

    def _apply(self, msgs: list[AisMessage], now_s: float) -> None:
        for m in msgs:
            self.table.update(m, now_s)
            if self.on_message is not None:
                try:
                    self.on_message(m)
                except Exception:  # a failing log must not stop reception
                    self.callback_errors += 1

    def targets(self, now_s: float) -> list[AisTarget]:
        return self.table.targets(now_s)

    @property
    def stats(self) -> AisStats:
        return self.decoder.stats
