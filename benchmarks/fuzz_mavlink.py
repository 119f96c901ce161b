"""Fuzz the MAVLink endpoint of a running daemon: random and mutated frames at it, the loop must stay on time.

`autopilot run --sim` (real time, 10 Hz) with `--mavlink udpin:127.0.0.1:PORT`; this script sends N
datagrams at it: a third random bytes, a third valid frames of random message types with random payloads
(right CRC: they reach the handlers, with NaNs, huge numbers and nonsense ids), a third valid frames with
bytes flipped, cut or repeated. Then it checks that the daemon is alive, answers a heartbeat, stops with
exit 0 on SIGTERM, logged no loop error, and compares the loop's lateness during the flood with before it.

    python benchmarks/fuzz_mavlink.py [--frames 1000000] [--seed 1] [--rate 20000]
"""

from __future__ import annotations

import argparse
import json
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from pymavlink.dialects.v20 import ardupilotmega as mavlink

ROOT = Path(__file__).resolve().parents[1]


def frames(n: int, seed: int):
    rng = random.Random(seed)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    ids = sorted(mavlink.mavlink_map)
    for k in range(n):
        kind = k % 3
        if kind == 0:
            yield rng.randbytes(rng.randint(1, 300))
            continue
        cls = mavlink.mavlink_map[rng.choice(ids)]
        payload = rng.randbytes(cls.unpacker.size)
        # a frame with the right CRC for a random payload: it decodes and reaches the handler
        hdr = bytes([mavlink.PROTOCOL_MARKER_V2, len(payload), 0, 0, k % 256, 255, 190,
                     cls.id & 0xFF, (cls.id >> 8) & 0xFF, cls.id >> 16])
        crc = mavlink.x25crc(hdr[1:] + payload)
        crc.accumulate(bytes([cls.crc_extra]))
        frame = hdr + payload + bytes([crc.crc & 0xFF, crc.crc >> 8])
        if kind == 2:
            b = bytearray(frame)
            for _ in range(rng.randint(1, 4)):
                what = rng.random()
                if what < 0.5 and b:
                    b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
                elif what < 0.75:
                    b = b[: rng.randrange(len(b) + 1)]
                else:
                    b = b + b[: rng.randint(1, 20)]
            frame = bytes(b)
        yield frame
    del mav


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rate", type=float, default=20000.0, help="datagrams per second sent (a flood the kernel "
                    "would otherwise mostly drop before the daemon sees it)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="fuzz-mavlink-") as tmp:
        tmp = Path(tmp)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
        cfg["failsafe"]["max_mission_time_s"] = 3600.0
        (tmp / "c.yaml").write_text(yaml.safe_dump(cfg))
        wps = [[20.0, 0.0], [20.0, 20.0], [0.0, 20.0], [2.0, 2.0]] * 30
        (tmp / "m.yaml").write_text(yaml.safe_dump({"name": "fuzz", "frame": "local", "waypoints": wps}))
        err = open(tmp / "err.txt", "w")  # noqa: SIM115
        proc = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--sim", "--config", str(tmp / "c.yaml"),
                                 "--mission", str(tmp / "m.yaml"), "--log-dir", str(tmp / "logs"), "--state-dir",
                                 str(tmp / "state"), "--runtime-dir", str(tmp / "run"), "--fresh",
                                 "--mavlink", f"udpin:127.0.0.1:{port}"], stdout=subprocess.DEVNULL, stderr=err)
        time.sleep(8.0)  # the mission under way: the lateness before the flood
        t_flood = time.monotonic()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sent = nbytes = 0
        for f in frames(args.frames, args.seed):
            try:
                sock.sendto(f, ("127.0.0.1", port))
            except OSError:
                pass
            sent += 1
            nbytes += len(f)
            if sent % 200 == 0:
                ahead = t_flood + sent / args.rate - time.monotonic()
                if ahead > 0:
                    time.sleep(ahead)
        flood_s = time.monotonic() - t_flood
        time.sleep(2.0)
        # still there and answering: a heartbeat gets the boat's heartbeats back
        hb = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        sock.settimeout(3.0)
        sock.sendto(hb.heartbeat_encode(6, 8, 0, 0, 0).pack(hb), ("127.0.0.1", port))
        answered = False
        t_end = time.monotonic() + 5.0
        while time.monotonic() < t_end and not answered:
            try:
                data, _ = sock.recvfrom(4096)
            except socket.timeout:
                break
            answered = any(m.get_type() == "HEARTBEAT" for m in (hb.parse_buffer(data) or []))
        alive = proc.poll() is None
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(30)
        (log_file,) = list((tmp / "logs").glob("*.jsonl"))
        rows = [json.loads(x) for x in log_file.read_text().splitlines()]
    cycles = [r for r in rows if r["event"] == "cycle"]
    t0 = next(r["t_s"] for r in rows if r["event"] == "mission_start")
    wall0 = rows[0]["timestamp"]
    del wall0
    t_start = cycles[0]["t_s"]
    before = np.array([c["lateness_ms"] for c in cycles if 2.0 < c["t_s"] - t_start < 8.0])
    during = np.array([c["lateness_ms"] for c in cycles if 8.0 < c["t_s"] - t_start < 8.0 + flood_s])
    errors = [r for r in rows if r["event"] == "info" and r.get("message") == "control loop error"]
    stats = next((r["stats"] for r in rows if r.get("message") == "mavlink link closed"), {})
    print(f"sent {sent} datagrams ({nbytes / 1e6:.1f} MB) in {flood_s:.1f} s ({sent / flood_s:,.0f}/s)")
    print(f"daemon alive after the flood: {alive}; answered a heartbeat: {answered}; exit on SIGTERM: {code}; "
          f"loop errors logged: {len(errors)}; t0 {t0}")
    print(f"lateness before: p50 {np.percentile(before, 50):.2f} ms, p99 {np.percentile(before, 99):.2f} ms; "
          f"during the flood: p50 {np.percentile(during, 50):.2f} ms, p99 {np.percentile(during, 99):.2f} ms, "
          f"max {during.max():.2f} ms; skipped cycles {cycles[-1]['skipped_cycles']}")
    keep = {k: v for k, v in stats.items() if k in ("rx_bad_data", "datagrams_dropped", "parse_errors",
                                                      "handler_errors", "unsigned_refused")}
    print(f"link: {sum(v for k, v in stats.items() if k.startswith('rx_'))} messages parsed "
          f"({stats.get('rx_bad_data', 0)} bad), {keep}")
    for r in rows:
        if r.get("message") == "mavlink message not handled":
            print(f"  not handled: {r['kind']}: {r['error']}")
    ok = alive and answered and code == 0 and not errors
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
