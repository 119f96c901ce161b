"""Fuzz the NMEA stream decoder: >= 10^6 random and mutated lines, no exception may escape.

    python benchmarks/fuzz_nmea.py [--lines N] [--seed S] [--json]

Lines are drawn from four families: real sentences from the shared gpsd
captures and simulated SC-30 sentences mutated (byte flips, insertions,
deletions, truncation, duplication of fields, non-ASCII, overlong), pure
random bytes, and valid sentences. They are fed in random-sized chunks, so
lines are also split across feeds. Each line also goes through ``decode_line`` alone, which may raise only
NmeaError. Reports lines/s and the counters; exits 1 if an exception
escaped, decode_line raised anything else, or a decoded value is out of range.
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

from autopilot.drivers.nmea import NmeaError, NmeaStreamDecoder, decode_line, make_sentence  # noqa: E402

SHARED = Path("/work/shared/nmea")


def corpus() -> list[bytes]:
    lines = []
    for p in sorted(SHARED.glob("*.log")):
        lines += [ln.rstrip(b"\r") + b"\r\n" for ln in p.read_bytes().split(b"\n") if ln.startswith(b"$")]
    for body in (
        "GPHDT,123.4,T",
        "GPTHS,123.4,A",
        "PFEC,GPatt,123.4,+1.2,-0.4",
        "PFEC,GPhve,0.12,A",
        "GPROT,-12.3,A",
        "GPGGA,120000.00,3500.00000,N,13900.00000,E,1,10,0.9,1.0,M,30.0,M,,",
        "GPRMC,120000.00,A,3500.00000,N,13900.00000,E,1.23,45.6,010624,,,A",
        "GPVTG,45.6,T,,M,1.23,N,2.28,K,A",
        "GPZDA,120000.00,01,06,2024,00,00",
    ):
        lines.append(make_sentence(body).encode())
    return lines


def mutate(rng: random.Random, line: bytes) -> bytes:
    b = bytearray(line)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        i = rng.randrange(len(b)) if b else 0
        if op == 0 and b:
            b[i] = rng.randrange(256)
        elif op == 1:
            b.insert(i, rng.randrange(256))
        elif op == 2 and b:
            del b[i]
        elif op == 3:
            b = b[: rng.randrange(len(b) + 1)]
        elif op == 4:
            b[i:i] = rng.choice([b",", b",,,,", b"*", b"$", b"\r\n", b"nan", b"1e999", b"-", b"."])
        elif op == 5:
            b[i:i] = bytes(rng.randrange(128, 256) for _ in range(rng.randint(1, 3)))
        else:
            b[i:i] = b"9" * rng.randint(50, 400)
    return bytes(b)


def check(u) -> bool:
    for name in ("lat_deg", "lon_deg", "heading_rad", "cog_rad", "sog_m_s", "yaw_rate_rad_s", "pitch_rad", "roll_rad"):
        v = getattr(u, name)
        if v is not None and not math.isfinite(v):
            return False
    if u.lat_deg is not None and not (-90 <= u.lat_deg <= 90 and -180 <= u.lon_deg <= 180):
        return False
    for name in ("heading_rad", "cog_rad"):
        v = getattr(u, name)
        if v is not None and not 0 <= v < 2 * math.pi:
            return False
    return True


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    base = corpus()
    dec = NmeaStreamDecoder()
    escaped = bad_values = updates = n_bytes = unexpected = 0
    batch: list[bytes] = []
    t0 = time.perf_counter()
    for i in range(args.lines):
        r = rng.random()
        if r < 0.6:
            line = mutate(rng, rng.choice(base))
        elif r < 0.8:
            line = bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 120))) + b"\n"
        else:
            line = rng.choice(base)
        batch.append(line)
        # decode_line directly too: the stream decoder's last-resort guard must never be needed
        try:
            decode_line(line.decode("latin-1"))
        except NmeaError:
            pass
        except Exception as exc:  # noqa: BLE001
            unexpected += 1
            if unexpected <= 5:
                print(f"decode_line raised {exc!r} on {line!r}", file=sys.stderr)
        if len(batch) >= 64 or i == args.lines - 1:
            data = b"".join(batch)
            batch.clear()
            n_bytes += len(data)
            pos = 0
            while pos < len(data):
                step = rng.randint(1, 2048)
                try:
                    out = dec.feed(data[pos : pos + step])
                except Exception as exc:  # noqa: BLE001 - the point of the fuzzer
                    escaped += 1
                    print(f"escaped: {exc!r}", file=sys.stderr)
                    out = []
                pos += step
                updates += len(out)
                bad_values += sum(1 for u in out if not check(u))
    elapsed = time.perf_counter() - t0
    result = {
        "lines": args.lines,
        "bytes": n_bytes,
        "seconds": round(elapsed, 2),
        "lines_per_s": round(args.lines / elapsed),
        "mb_per_s": round(n_bytes / elapsed / 1e6, 2),
        "updates": updates,
        "exceptions_escaped": escaped,
        "decode_line_non_nmea_errors": unexpected,
        "out_of_range_values": bad_values,
        "stats": dec.stats.as_dict(),
    }
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:>20}: {v}")
    return 1 if escaped or bad_values or unexpected else 0


if __name__ == "__main__":
    sys.exit(main())
