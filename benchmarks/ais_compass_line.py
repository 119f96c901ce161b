"""How many AIS vessels the SC-30's line carries at 4800 baud (``ais.on_compass_line``) before the headings go stale.

The real daemon as a subprocess (no ``--sim``: the fault-injection rig of ``tests/test_failsafe_faults.py``,
the simulated SC-30 at 4800 baud and the simulated Mbed on pseudo-terminals, clock 10x) flies a short
mission while N moored class-A vessels around it send what a receiver hears (type 5 at the start, type 1
every ~3 min at rest and at ITU-R M.1371-5 rates, ``autopilot.simdev.traffic``), put on the compass line
at its baud rate behind the SC-30's own sentences (one queue, as a multiplexer's output). Per N: the AIS
characters a second, the heading age the cycles saw (median, 99th percentile, max) and the faults.
4800 baud carries 480 characters a second; the SC-30's own sentences take most of it.

    python benchmarks/ais_compass_line.py [--vessels 0 3 5 10] [--seconds 60]
"""

from __future__ import annotations

import argparse
import asyncio
import math
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


async def one(n_vessels: int, seconds: float) -> dict:
    from autopilot.simdev.traffic import TargetSpec, TrafficScenario, sentences_between
    from tests.test_failsafe_faults import ORIGIN, Daemon

    targets = tuple(TargetSpec(mmsi=211000100 + i, name=f"BOAT {i}", north_m=300 + 50 * math.cos(i),
                               east_m=300 + 50 * math.sin(i), course_deg=0.0, speed_m_s=0.0) for i in range(n_vessels))
    scenario = TrafficScenario(name="harbour", origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1], targets=targets)
    with tempfile.TemporaryDirectory(prefix="ais-line-") as tmp:
        d = Daemon(Path(tmp), {"name": "n", "frame": "local", "waypoints": [[40.0, 0.0], [0.0, 0.0]] * 4},
                   config={"ais": {"on_compass_line": n_vessels > 0}, "failsafe": {"max_mission_time_s": 1800}})
        try:
            await d.start()
            await d.steady_thrust(1.0)
            t0, t_prev, chars = d.clock.now_s(), -1e-9, 0
            while d.clock.now_s() - t0 < seconds and d.proc.returncode is None:
                t = d.clock.now_s() - t0
                lines = [s for _, s in sentences_between(scenario, t_prev, t)] if n_vessels else []
                t_prev = t
                if lines:
                    data = ("\r\n".join(lines) + "\r\n").encode()
                    chars += len(data)
                    d.rig.sc30.inject(data)
                await d.clock.sleep(0.1)
            t_end = d.clock.now_s() - t0
            log = d.log()
        finally:
            await d.close()
    cycles = [r for r in log if r["event"] == "cycle" and r.get("heading_age_s") is not None]
    ages = sorted(r["heading_age_s"] for r in cycles[len(cycles) // 4:])  # after the start
    faults = sorted({r["cause"] for r in log if r["event"] == "fault"})
    return {"vessels": n_vessels, "ais_chars_s": chars / max(t_end, 1e-9), "p50": ages[len(ages) // 2],
            "p99": ages[int(0.99 * (len(ages) - 1))], "max": ages[-1], "faults": faults}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vessels", type=int, nargs="+", default=[0, 3, 5, 10])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds of traffic per run")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    print("| vessels | AIS chars/s | heading age p50 / p99 / max (s) | faults |")
    print("|---|---|---|---|")
    for n in args.vessels:
        r = asyncio.run(one(n, args.seconds))
        print(f"| {r['vessels']} | {r['ais_chars_s']:.0f} | {r['p50']:.2f} / {r['p99']:.2f} / {r['max']:.2f} | "
              f"{', '.join(r['faults']) or 'none'} |", flush=True)


if __name__ == "__main__":
    main()
