"""Control-loop timing of the real daemon: `autopilot run --sim` in real time (issue 4, Show).

Runs the daemon as a subprocess at speedup 1 on a looping mission long enough for the
duration, stops it with SIGTERM, and reports from its own log and from the kernel:

- loop lateness (cycle start after its absolute deadline): median and 99th percentile;
- latency from a heading's measurement (its compass tick, as the driver dates it:
  drivers/line_timing.py) to the first command that used it, 99th percentile; and the age of the
  heading each command used (both from the cycle lines' heading_latency_ms: measurement = cycle
  time - latency, so commands sharing a measurement are grouped);
- CPU seconds per wall second and peak RSS of the daemon process (wait4 rusage). Under --sim
  the simulated SC-30, Mbed and boat model run in the same process, so these are upper bounds
  of the daemon alone.

    python benchmarks/loop_timing.py                       # 5 min at 10 Hz, then 1 min at 50 Hz
    python benchmarks/loop_timing.py --duration-s 60 --rate-hz 10 [--json]
    python benchmarks/loop_timing.py --duration-s 120 --link compare   # no link, then a flooding ground station

--link flood: the daemon has a MAVLink endpoint (udpin on loopback) and a ground station in this
process floods it with valid traffic: heartbeats, parameter lists (each answered with every
parameter), mission downloads and message requests, ~1000 messages a second, reading every reply.
--link compare runs the same duration without the link and with the flood, one after the other.
--link commands floods it with ~5000 valid state-changing commands a second instead (MISSION_SET_CURRENT,
PARAM_SET, DO_SET_MISSION_CURRENT), which the loop carries out 5 a cycle and refuses past 100 waiting.
--link ctl floods the control socket instead (autopilot ctl's Unix socket, no MAVLink): a local client in
bursts of 50 connections (environment CTL_FLOOD_BURST), half asking status, half sending a line that is no request.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]


def looping_mission(duration_s: float, speed_m_s: float = 1.0) -> dict:
    """A 20 m square, repeated often enough that the boat is still under way at the end."""
    side_m = 20.0
    laps = int(math.ceil(duration_s * speed_m_s / (4 * side_m))) + 2
    wps = []
    for _ in range(laps):
        wps += [[side_m, 0.0], [side_m, side_m], [0.0, side_m], [2.0, 2.0]]
    return {"name": "timing-square", "frame": "local", "waypoints": wps}


def flood(port: int, stop: threading.Event, counts: dict, kind: str = "flood") -> None:
    """A ground station that never rests, every reply read: ``flood``, ~1000 valid requests a second (reads);
    ``commands``, ~5000 valid state-changing commands a second (set the current item, set a parameter),
    each of which the loop must carry out inside a cycle."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setblocking(False)
    if kind == "commands":
        requests = [mav.heartbeat_encode(6, 8, 0, 0, 0), mav.mission_set_current_encode(1, 1, 2),
                    mav.param_set_encode(1, 1, b"HDG_KP", 1.0, 9), mav.param_set_encode(1, 1, b"HDG_KP", 1.5, 9),
                    mav.command_long_encode(1, 1, 224, 0, 2, 0, 0, 0, 0, 0, 0)]
    else:
        requests = [mav.heartbeat_encode(6, 8, 0, 0, 0), mav.param_request_list_encode(1, 1),
                    mav.mission_request_list_encode(1, 1), mav.param_request_read_encode(1, 1, b"HDG_KP", -1),
                    mav.command_long_encode(1, 1, 512, 0, 148, 0, 0, 0, 0, 0, 0)]
    frames = [m.pack(mav) for m in requests]
    k = 0
    burst = 50 if kind == "commands" else 10
    while not stop.is_set():
        for _ in range(burst):
            sock.sendto(frames[k % len(frames)], ("127.0.0.1", port))
            k += 1
        counts["sent"] = k
        try:
            while True:
                data = sock.recv(65536)
                counts["received_bytes"] = counts.get("received_bytes", 0) + len(data)
        except BlockingIOError:
            pass
        time.sleep(0.01)


def ctl_flood(path: Path, stop: threading.Event, counts: dict) -> None:
    """A local client that never rests on the control socket: bursts of 50 connections, half asking
    status, half sending a line that is not a request (each refused and logged), every answer read."""
    burst = int(os.environ.get("CTL_FLOOD_BURST", "50"))
    k = 0
    while not stop.is_set():
        socks = []
        for i in range(burst):
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.settimeout(2.0)
            try:
                s.connect(str(path))
                s.sendall(b"status\n" if i % 2 else b"launch the boat\n")
                s.shutdown(socket.SHUT_WR)
                socks.append(s)
            except OSError:
                s.close()
                counts["connect_failed"] = counts.get("connect_failed", 0) + 1
        for s in socks:
            try:
                while chunk := s.recv(65536):
                    counts["received_bytes"] = counts.get("received_bytes", 0) + len(chunk)
            except OSError:
                pass
            s.close()
        k += len(socks)
        counts["sent"] = k
        time.sleep(0.01)


def run(duration_s: float, rate_hz: float, sc30_baud: int = 4800, link: str = "none") -> dict:
    with tempfile.TemporaryDirectory(prefix="loop-timing-") as tmp:
        tmp_path = Path(tmp)
        cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
        cfg["rate_hz"] = rate_hz
        cfg["serial"]["sc30_baud"] = sc30_baud
        cfg["failsafe"]["max_mission_time_s"] = max(duration_s * 2 + 60, 60.0)
        (tmp_path / "autopilot.yaml").write_text(yaml.safe_dump(cfg))
        (tmp_path / "mission.yaml").write_text(yaml.safe_dump(looping_mission(duration_s)))
        cmd = [sys.executable, "-m", "autopilot", "run", "--config", str(tmp_path / "autopilot.yaml"),
               "--mission", str(tmp_path / "mission.yaml"), "--sim", "--log-dir", str(tmp_path / "logs"),
               "--state-dir", str(tmp_path / "state"), "--runtime-dir", str(tmp_path / "run")]
        stop_flood, counts = threading.Event(), {}
        if link in ("flood", "commands"):
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.bind(("127.0.0.1", 0))
                port = s.getsockname()[1]
            cmd += ["--mavlink", f"udpin:127.0.0.1:{port}"]
        t0 = time.monotonic()
        err = open(tmp_path / "stderr.txt", "w+")  # noqa: SIM115 - read below
        proc = subprocess.Popen(cmd, cwd=tmp, stdout=subprocess.DEVNULL, stderr=err)
        flooder = None
        if link in ("flood", "commands", "ctl"):
            time.sleep(2.0)
            flooder = (threading.Thread(target=ctl_flood, args=(tmp_path / "run" / "control.sock", stop_flood, counts),
                                        daemon=True) if link == "ctl" else
                       threading.Thread(target=flood, args=(port, stop_flood, counts, link), daemon=True))
            flooder.start()
            time.sleep(duration_s - 2.0)
        else:
            time.sleep(duration_s)
        stop_flood.set()
        # os.kill, not proc.send_signal: that polls, and a poll would reap the child before wait4 sees it
        try:
            os.kill(proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        _, status, usage = os.wait4(proc.pid, 0)
        if os.waitstatus_to_exitcode(status) != 0:
            err.seek(0)
            raise RuntimeError(f"the daemon exited with {os.waitstatus_to_exitcode(status)}: {err.read()[-2000:]}")
        wall_s = time.monotonic() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        (log_file,) = list((tmp_path / "logs").glob("mission-*.jsonl"))
        recs = [json.loads(line) for line in log_file.read_text().splitlines()]
    cycles = [r for r in recs if r["event"] == "cycle"]
    auto = [r for r in cycles if r["mode"] == "auto"]
    late_ms = np.array([c["lateness_ms"] for c in cycles])
    age_ms = np.array([c["heading_latency_ms"] for c in auto if c["heading_latency_ms"] is not None])
    # Each command's heading was measured at (cycle time - latency); commands whose estimates lie
    # within a few ms used the same heading (the estimate jitters by the cycle's compute time, and
    # headings are measured 100 ms apart). Keep the first use of each.
    uses = sorted((c["t_s"] * 1e3 - c["heading_latency_ms"], c["heading_latency_ms"]) for c in auto if c["heading_latency_ms"] is not None)
    first_use = []
    last_arrival_ms = -np.inf
    for arrival_ms, latency_ms in uses:
        if arrival_ms - last_arrival_ms > 5.0:
            first_use.append(latency_ms)
        else:
            first_use[-1] = min(first_use[-1], latency_ms)
        last_arrival_ms = arrival_ms
    lat_ms = np.array(first_use)
    stop = recs[-1]
    return {
        "link": link,
        "flood_sent": counts.get("sent", 0),
        "flood_received_mb": round(counts.get("received_bytes", 0) / 1e6, 2),
        "rate_hz": rate_hz,
        "sc30_baud": sc30_baud,
        "duration_s": round(wall_s, 1),
        "exit_code": proc.returncode,
        "cycles": len(cycles),
        "skipped_cycles": stop.get("skipped_cycles"),
        "late_cycles_over_period": int(np.sum(late_ms >= 1e3 / rate_hz)),
        "lateness_p50_ms": round(float(np.percentile(late_ms, 50)), 3),
        "lateness_p99_ms": round(float(np.percentile(late_ms, 99)), 3),
        "lateness_max_ms": round(float(late_ms.max()), 3),
        "heading_to_command_p99_ms": round(float(np.percentile(lat_ms, 99)), 1) if lat_ms.size else None,
        "heading_age_at_command_p99_ms": round(float(np.percentile(age_ms, 99)), 1) if age_ms.size else None,
        "headings_used": int(lat_ms.size),
        "cpu_s_per_wall_s": round((usage.ru_utime + usage.ru_stime) / wall_s, 4),
        "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1),
        "stop_ack_received": stop.get("ack_received"),
        "waypoints_reached": sum(r["event"] == "waypoint_reached" for r in recs),
        "log_lines": len(recs),
        "refusals_logged": sum(r["event"] == "command" and r.get("accepted") is False for r in recs),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=None, help="one run of this length (default: 300 s at 10 Hz and 60 s at 50 Hz)")
    ap.add_argument("--rate-hz", type=float, default=10.0)
    ap.add_argument("--sc30-baud", type=int, default=4800, help="SC-30 line speed (4800 or 38400): sets how late headings arrive")
    ap.add_argument("--link", choices=("none", "flood", "commands", "compare", "ctl"), default="none")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    plan = [(args.duration_s, args.rate_hz)] if args.duration_s else [(300.0, 10.0), (60.0, 50.0)]
    links = ("none", "flood") if args.link == "compare" else (args.link,)
    results = [run(d, r, args.sc30_baud, link) for d, r in plan for link in links]
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        for res in results:
            print(f"--sim, real time, {res['rate_hz']:g} Hz, SC-30 at {res['sc30_baud']} baud, {res['duration_s']:g} s, {res['cycles']} cycles "
                  f"({res['skipped_cycles']} skipped), exit {res['exit_code']}, link {res['link']}"
                  + (f" ({res['flood_sent']} messages sent, {res['flood_received_mb']} MB of replies)"
                     if res["link"] in ("flood", "commands") else
                     f" ({res['flood_sent']} connections, {res['flood_received_mb']} MB of answers)" if res["link"] == "ctl"
                     else ""))
            print(f"  lateness p50 {res['lateness_p50_ms']:.3f} ms, p99 {res['lateness_p99_ms']:.3f} ms, max {res['lateness_max_ms']:.3f} ms")
            print(f"  heading arrival -> first command using it p99 {res['heading_to_command_p99_ms']} ms "
                  f"({res['headings_used']} headings); age of the heading a command used p99 {res['heading_age_at_command_p99_ms']} ms")
            print(f"  CPU {res['cpu_s_per_wall_s'] * 100:.2f} % of one core, peak RSS {res['peak_rss_mb']:.1f} MB "
                  f"(daemon + in-process simulator); log {res['log_lines']} lines, {res['refusals_logged']} refusals")
    return 0


if __name__ == "__main__":
    sys.exit(main())
