"""Fuzz the AIS stream decoder and target table: >= 10^5 random and mutated lines, no exception may escape.

    python benchmarks/fuzz_ais.py [--lines N] [--seed S] [--json]

Lines are drawn from four families: real ``!AIVDM`` sentences from the
shared gpsd captures and sentences encoded by pyais (types 1, 5 in two
parts, 18, 19, 24 A/B, VDO), mutated (byte flips, insertions of delimiters
and armour characters, deletions, truncation, swapped fragments, non-ASCII,
overlong); pure random bytes; valid lines; and fragments out of order or
missing. They are fed in random-sized chunks on a simulated clock (10 ms a
line), so lines are also split across feeds and multi-part messages time out.
Each line also goes through ``parse_fragment`` alone, which may raise only
AisError. Every decoded message goes into a :class:`TargetTable`. Reports
lines/s and the counters; exits 1 if an exception escaped, parse_fragment
raised anything else, or a decoded value is out of range.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from autopilot.drivers.ais import AisError, AisStreamDecoder, TargetTable, parse_fragment  # noqa: E402
from autopilot.simdev.traffic import encode_ais  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "nmea"
if not SHARED.is_dir():
    SHARED = Path("/work/shared/nmea")


def corpus() -> list[bytes]:
    lines = []
    for name in ("ais-nmea.log", "ais-18-27.log"):
        p = SHARED / name
        if p.is_file():
            lines += [ln.rstrip(b"\r") + b"\r\n" for ln in p.read_bytes().split(b"\n") if ln.startswith(b"!")]
    for data, kind in (
        ({"type": 1, "mmsi": 244000001, "lat": 52.1, "lon": 5.2, "speed": 12.3, "course": 45.6, "heading": 46,
          "turn": 12.0}, "VDM"),
        ({"type": 5, "mmsi": 244000001, "shipname": "FUZZ", "callsign": "PA1234", "to_bow": 50, "to_stern": 10,
          "to_port": 5, "to_starboard": 5}, "VDM"),
        ({"type": 18, "mmsi": 338000001, "lat": -33.9, "lon": 151.2, "speed": 4.0, "course": 350.0}, "VDM"),
        ({"type": 19, "mmsi": 338000001, "lat": -33.9, "lon": 151.2, "shipname": "BEE", "to_bow": 5}, "VDM"),
        ({"type": 24, "mmsi": 338000001, "partno": 0, "shipname": "BEE"}, "VDM"),
        ({"type": 24, "mmsi": 338000001, "partno": 1, "callsign": "X", "to_bow": 5, "to_stern": 2}, "VDM"),
        ({"type": 1, "mmsi": 244999999, "lat": 52.0, "lon": 5.0, "speed": 1.0, "course": 1.0}, "VDO"),
    ):
        lines += [(s + "\r\n").encode() for s in encode_ais(data, sentence_type=kind)]
    return lines


def mutate(rng: random.Random, line: bytes) -> bytes:
    b = bytearray(line)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        i = rng.randrange(len(b)) if b else 0
        if op == 0 and b:
            b[i] = rng.randrange(256)
        elif op == 1:
            b.insert(i, rng.choice(b",!*\\0w`W@~"))
        elif op == 2 and b:
            del b[i]
        elif op == 3:
            b = b[: rng.randrange(len(b) + 1)]
        elif op == 4:
            b[i:i] = rng.choice([b",", b",,,", b"*", b"!", b"$", b"\r\n", b"9", b"2,1,", b"\\s:x*00\\"])
        elif op == 5:
            b[i:i] = bytes(rng.randrange(128, 256) for _ in range(rng.randint(1, 3)))
        else:
            b[i:i] = b"w" * rng.randint(50, 300)
    return bytes(b)


def check(m) -> bool:
    for name in ("lat_deg", "lon_deg", "heading_rad", "cog_rad", "sog_m_s", "turn_rad_s", "to_bow_m", "to_stern_m"):
        v = getattr(m, name)
        if v is not None and not math.isfinite(v):
            return False
    if m.lat_deg is not None and not (-90 <= m.lat_deg <= 90 and -180 <= m.lon_deg <= 180):
        return False
    for name in ("heading_rad", "cog_rad"):
        v = getattr(m, name)
        if v is not None and not 0 <= v < 2 * math.pi:
            return False
    if m.sog_m_s is not None and not 0 <= m.sog_m_s < 102.3 * 1852 / 3600:
        return False
    return 0 < m.mmsi <= 999_999_999


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=200_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    base = corpus()
    dec = AisStreamDecoder()
    table = TargetTable()
    escaped = bad_values = messages = n_bytes = unexpected = 0
    batch: list[bytes] = []
    t_s = 0.0
    t0 = time.perf_counter()
    for i in range(args.lines):
        r = rng.random()
        if r < 0.55:
            line = mutate(rng, rng.choice(base))
        elif r < 0.7:
            line = bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 120))) + b"\n"
        elif r < 0.75:
            line = b""  # a lost line: its message's other fragments wait and time out
        else:
            line = rng.choice(base)
        batch.append(line)
        try:
            parse_fragment(line.decode("latin-1"))
        except AisError:
            pass
        except Exception as exc:  # noqa: BLE001
            unexpected += 1
            if unexpected <= 5:
                print(f"parse_fragment raised {exc!r} on {line!r}", file=sys.stderr)
        if len(batch) >= 64 or i == args.lines - 1:
            data = b"".join(batch)
            batch.clear()
            n_bytes += len(data)
            pos = 0
            while pos < len(data):
                step = rng.randint(1, 2048)
                t_s += 0.01 * step / 60.0
                try:
                    out = dec.feed(data[pos : pos + step], t_s)
                    for m in out:
                        table.update(m, t_s)
                    table.prune(t_s)
                except Exception as exc:  # noqa: BLE001 - the point of the fuzzer
                    escaped += 1
                    print(f"escaped: {exc!r}", file=sys.stderr)
                    out = []
                pos += step
                messages += len(out)
                bad_values += sum(1 for m in out if not check(m))
    elapsed = time.perf_counter() - t0
    result = {
        "lines": args.lines,
        "bytes": n_bytes,
        "seconds": round(elapsed, 2),
        "lines_per_s": round(args.lines / elapsed),
        "messages": messages,
        "targets_at_end": len(table),
        "exceptions_escaped": escaped,
        "parse_fragment_non_ais_errors": unexpected,
        "out_of_range_values": bad_values,
        "stats": dec.stats.as_dict(),
    }
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>30}: {v}")
    return 1 if escaped or bad_values or unexpected else 0


if __name__ == "__main__":
    sys.exit(main())
