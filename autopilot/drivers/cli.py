"""``autopilot nmea PORT_OR_FILE [--json]``: print what the compass says, like gpspipe.

For wiring the SC-30: reads a serial port (or a pty, or a recorded ``.log``
file), validates and decodes every line with the driver's own decoder, and
prints one line per decoded sentence; with ``--json`` one JSON object per
line with ``t_s, lat_deg, lon_deg, heading_deg, rot_deg_min, sog_kn,
cog_deg, fix_quality, source`` (plus ``talker``, ``valid``, ``pitch_deg``,
``roll_deg``, ``utc``). AIS (``!AIVDM``/``!AIVDO``, an AIS receiver's port or
interleaved on the compass line) is decoded too (pyais, multi-part messages assembled) and
each target printed as it updates: ``ais mmsi=... name=... lat_deg lon_deg sog_kn cog_deg
heading_deg length_m`` (``--json``: ``{"t_s": ..., "ais": {...}}``). The line counters go to stderr at the end.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
import sys
from pathlib import Path

from autopilot.schema import ConfigError
from autopilot.units import m_s_to_knots, rad_s_to_deg_min
from autopilot.userfile import check_file, check_text_head

_CR_END = re.compile(rb"(?<=\r)(?!\n)")  # after a CR that no LF follows: a line end of its own
_FIELDS = ("lat_deg", "lon_deg", "heading_deg", "rot_deg_min", "sog_kn", "cog_deg", "fix_quality")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "nmea",
        help="print decoded NMEA from a serial port or a capture file (SC-30 wiring check)",
        description="Decode NMEA 0183 from a serial port / pty or a recorded file and print each update.",
    )
    p.add_argument("source", metavar="PORT_OR_FILE", help="serial device (e.g. /dev/sc30) or NMEA log file")
    p.add_argument("--json", action="store_true", help="one JSON object per decoded sentence")
    p.add_argument("--baud", type=int, default=4800, help="baud rate of a serial port (default 4800; SC-30: 4800 or 38400)")
    p.add_argument("--count", type=int, default=0, help="stop after this many decoded sentences (0 = no limit)")
    p.add_argument("--timeout", type=float, default=0.0, help="serial: stop after this many seconds without data (0 = never)")
    p.set_defaults(func=run_nmea)


def _deg(x_rad):
    return None if x_rad is None else round(math.degrees(x_rad), 6)


def update_record(u, t_s: float) -> dict:
    """The JSON object of one update, in the units a person reads off the compass (degrees, knots)."""
    valid = u.heading_valid if u.heading_valid is not None else u.status_valid
    rec = {"t_s": round(t_s, 6), "lat_deg": u.lat_deg, "lon_deg": u.lon_deg, "heading_deg": _deg(u.heading_rad),
           "rot_deg_min": None if u.yaw_rate_rad_s is None else round(rad_s_to_deg_min(u.yaw_rate_rad_s), 6),
           "sog_kn": None if u.sog_m_s is None else round(m_s_to_knots(u.sog_m_s), 6), "cog_deg": _deg(u.cog_rad),
           "fix_quality": u.fix_quality}
    # HDM's magnetic heading printed nothing ("APHDM" alone): a compass set to HDM looked dead while wiring it, and
    # the daemon, which steers by true heading only, waited for a heading it would never get (a new-user audit)
    rec["heading_mag_deg"] = _deg(u.heading_mag_rad)
    rec.update(
        source=u.sentence,
        talker=u.talker,
        valid=valid,
        pitch_deg=_deg(u.pitch_rad),
        roll_deg=_deg(u.roll_rad),
        utc=u.utc.isoformat() if u.utc is not None else None,
    )
    return rec


def _text(rec: dict) -> str:
    parts = [f"{rec['t_s']:10.3f}", f"{rec['talker']:>2}{rec['source']:<10}"]
    for k in (*_FIELDS, "pitch_deg", "roll_deg", "utc"):
        if rec[k] is not None:
            parts.append(f"{k}={rec[k]}")
    if rec.get("heading_mag_deg") is not None:
        parts.append(f"heading_mag_deg={rec['heading_mag_deg']} (magnetic: not steered by; the daemon needs THS, HDT or "
                     "$PFEC,GPatt)")
    if rec["valid"] is not None:
        parts.append("valid" if rec["valid"] else "INVALID")
    return " ".join(parts)


def _ais_updates(ais, before: dict, t_s: float) -> list[dict]:
    """The targets whose message count grew in this read: what a person reads off an AIS display."""
    out = []
    for t in ais.table.targets(with_position=False):
        if before.get(t.mmsi) == t.messages:
            continue
        out.append({"t_s": round(t_s, 6), "mmsi": t.mmsi, "class": t.ais_class, "name": t.shipname,
                    "lat_deg": t.lat_deg, "lon_deg": t.lon_deg,
                    "sog_kn": None if t.sog_m_s is None else round(m_s_to_knots(t.sog_m_s), 2),
                    "cog_deg": _deg(t.cog_rad), "heading_deg": _deg(t.heading_rad), "length_m": t.length_m})
    return out


def _ais_text(rec: dict) -> str:
    parts = [f"{rec.pop('t_s'):10.3f}", "  AIS      ", f"mmsi={rec['mmsi']}"]
    for k in ("name", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "length_m"):
        if rec[k] is not None:
            parts.append(f"{k}={rec[k]}")
    return " ".join(parts)


def run_nmea(args) -> int:
    from autopilot.clock import Clock
    from autopilot.drivers.nmea import NmeaStreamDecoder

    if args.count < 0 or args.timeout < 0:
        raise ConfigError("--count and --timeout must be >= 0")
    try:
        mode = os.stat(args.source).st_mode
    except OSError as exc:
        raise ConfigError(f"{args.source}: {exc.strerror}") from None
    from autopilot.drivers.ais import AisReceiver

    clock = Clock()
    ais = AisReceiver(clock_s=clock.now_s)
    decoder = NmeaStreamDecoder(encapsulated=ais.feed_line)
    printed = 0

    def emit(data: bytes) -> bool:
        nonlocal printed
        t_s = clock.now_s()
        before = {t.mmsi: t.messages for t in ais.table.targets(with_position=False)}
        records = [(json.dumps(update_record(u, t_s)) if args.json else _text(update_record(u, t_s)))
                   for u in decoder.feed(data)]
        records += [json.dumps({"t_s": r.pop("t_s"), "ais": r}) if args.json else _ais_text(r)
                    for r in _ais_updates(ais, before, t_s)]
        for rec in records:
            print(rec, flush=True)
            printed += 1
            if args.count and printed >= args.count:
                return False
        return True

    port = stat.S_ISCHR(mode)
    if not port:
        check_file(args.source, what="capture file or serial port")
        # a capture saved as UTF-16 by a Windows terminal, or gzipped, said only "no NMEA sentence decoded"; line
        # noise (a NUL as the port opened) is the decoder's to drop, not a reason to refuse the file
        with open(args.source, "rb") as f:
            check_text_head(Path(args.source), f.read(8192), what="NMEA capture", binary_ok=True)
    lines = 0
    try:
        if port:
            _read_port(args, emit)
        else:
            with open(args.source, "rb") as f:
                for chunk in f:
                    # a capture whose sentences end in CR alone is one "line" to Python: its comment header
                    # hid every sentence after it
                    for line in _CR_END.split(chunk):
                        if not line:
                            continue
                        lines += 1
                        if line.startswith(b"#"):  # comment header of gpsd-style captures
                            continue
                        if not emit(line):
                            break
                    else:
                        continue
                    break
                else:
                    emit(b"\n")  # the end of the file ends its last line (one without a line end, or a held lone CR)
    except KeyboardInterrupt:
        pass
    finally:
        print(f"nmea: {json.dumps(decoder.stats.as_dict())}", file=sys.stderr)
        if decoder.encapsulated_lines:
            print(f"ais: {json.dumps(ais.stats.as_dict())}, {len(ais.table)} target(s)", file=sys.stderr)
    if printed == 0:
        st = decoder.stats
        what = (f"{lines} line(s) read" if not port else f"{st.lines_ok + st.dropped + st.unknown} sentence(s) received")
        hint = ("check the wiring and the baud rate (--baud; the SC-30 sends at 4800 or 38400)" if port
                else "is it an NMEA 0183 capture?")
        raise ConfigError(f"{args.source}: no NMEA sentence decoded ({what}, {st.dropped} rejected, "
                          f"{st.unknown} of sentence types not used): {hint}")
    return 0


def _read_port(args, emit) -> None:
    import serial

    if args.baud <= 0:
        raise ConfigError(f"--baud: {args.baud} must be > 0")
    from autopilot.drivers.serial_link import open_port, open_problem

    try:
        port = open_port(args.source, args.baud, timeout=0.2)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise ConfigError(f"{args.source}: cannot open: {open_problem(args.source, exc)}") from None
    print(f"nmea: reading {args.source} at {args.baud} baud", file=sys.stderr, flush=True)
    idle_s = 0.0
    try:
        while True:
            try:
                data = port.read(max(1, port.in_waiting))  # returns as soon as bytes arrive
            except (serial.SerialException, OSError) as exc:
                print(f"nmea: {args.source}: port lost: {exc}", file=sys.stderr)
                return
            if not data:
                idle_s += 0.2
                if args.timeout and idle_s >= args.timeout:
                    return
                continue
            idle_s = 0.0
            if not emit(data):
                return
    finally:
        port.close()
