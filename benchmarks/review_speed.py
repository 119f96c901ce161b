"""Review speed: a 24-hour mission log at 10 Hz (864,000 cycle lines) through `autopilot review`.

Generates the log in a temporary directory (synthetic patrol in the
documented schema, autopilot.review.synthetic), then runs the review in a
child process and reports its wall time and peak resident memory
(getrusage RUSAGE_CHILDREN ru_maxrss). Aim (issue 6): under 60 s, under 1 GB.

    python benchmarks/review_speed.py [--hours 24] [--rate-hz 10] [--export gpx,kml,geojson,csv] [--json]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from autopilot.review.synthetic import write_synthetic_log

PATROL_NE_M = ((0.0, 150.0), (150.0, 150.0), (150.0, 0.0), (0.0, 0.0))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hours", type=float, default=24.0)
    p.add_argument("--rate-hz", type=float, default=10.0)
    p.add_argument("--export", default="", help="also write these exports (e.g. gpx,kml,geojson,csv)")
    p.add_argument("--keep", metavar="DIR", help="work in DIR and keep the log and the report")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.keep or tmp)
        work.mkdir(parents=True, exist_ok=True)
        log = work / "mission-24h.jsonl"
        t0 = time.perf_counter()
        truth = write_synthetic_log(log, duration_s=args.hours * 3600.0, rate_hz=args.rate_hz,
                                    waypoints_ne_m=PATROL_NE_M, loop=True, dropout_every_s=600.0,
                                    seed=1)
        gen_s = time.perf_counter() - t0
        cmd = [sys.executable, "-m", "autopilot", "review", str(log), "--out", str(work / "review")]
        if args.export:
            cmd += ["--export", args.export]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        wall_s = time.perf_counter() - t0
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0  # KiB on Linux
        if proc.returncode != 0:
            print(proc.stdout, proc.stderr, file=sys.stderr)
            return 1
        figures = {
            "cycles": int(truth["cycles"]),
            "log_mb": round(log.stat().st_size / 1e6, 1),
            "generate_s": round(gen_s, 1),
            "review_wall_s": round(wall_s, 1),
            "review_peak_rss_mb": round(peak_mb, 0),
            "exports": args.export or "none",
        }
    if args.json:
        print(json.dumps(figures))
    else:
        print(f"log: {figures['cycles']} cycle lines, {figures['log_mb']} MB (generated in {figures['generate_s']} s)")
        print(f"review (report + plots, exports: {figures['exports']}): "
              f"{figures['review_wall_s']} s wall, peak RSS {figures['review_peak_rss_mb']:.0f} MB "
              f"(aim: < 60 s, < 1024 MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
