"""A configuration whose origin is not the launch site (copied from another lake): the boat starts beyond
max_distance_m and the failsafe stops it at once. Found by a new-user audit: the only word was a JSON fault line
and an end summary saying "failsafes: 1 (max_distance)". Now the terminal says where the boat is and asks whether
the origin is the launch site, when control starts and in the end summary. The real daemon on the fault rig's
simulated SC-30 and Mbed (pseudo-terminals)."""

from __future__ import annotations

import asyncio
import re

from tests.test_failsafe_faults import ORIGIN, square_mission
from tests.test_failsafe_faults import Daemon as FaultRigDaemon

FAR_ORIGIN_LAT_DEG = ORIGIN[0] + 0.02  # ~2.2 km north of where the simulated boat lies


def test_a_boat_started_beyond_max_distance_is_told_to_check_the_origin(tmp_path):
    async def fly() -> tuple[str, list[dict]]:
        d = FaultRigDaemon(tmp_path, square_mission(), config={"origin_lat_deg": FAR_ORIGIN_LAT_DEG},
                           injects_link_faults=False)
        try:
            await d.start()
            await d.wait(lambda: bool(d.events("launch")), 30.0, "control to start")
            await asyncio.sleep(0.3)
            return await d.interrupt(), d.log()
        finally:
            await d.close()

    err, log = asyncio.run(fly())
    said = [line for line in err.splitlines() if "the boat started beyond the max_distance limit" in line]
    assert len(said) == 2, err[-3000:]  # when control started, and in the end summary
    assert "from the origin (limit 500 m)" in said[0]
    assert f"origin_lat_deg/origin_lon_deg ({FAR_ORIGIN_LAT_DEG:g}, {ORIGIN[1]:g}) the launch site?" in said[0]
    at = re.search(r"at (-?\d+\.\d+), (-?\d+\.\d+),", said[0])  # the boat's own position, latitude and longitude
    assert at and abs(float(at[1]) - ORIGIN[0]) < 1e-4 and abs(float(at[2]) - ORIGIN[1]) < 1e-4, said[0]
    assert [r["cause"] for r in log if r.get("event") == "failsafe"] == ["max_distance"]
    assert all(r.get("thrust_port_n", 0.0) == 0.0 and r.get("thrust_stbd_n", 0.0) == 0.0
               for r in log if r.get("event") == "cycle")


def test_a_boat_started_inside_the_limits_is_told_nothing_of_the_origin(tmp_path):
    async def fly() -> str:
        d = FaultRigDaemon(tmp_path, square_mission(), injects_link_faults=False)
        try:
            await d.start()
            await d.wait(lambda: bool(d.events("launch")), 30.0, "control to start")
            await asyncio.sleep(0.3)
            return await d.interrupt()
        finally:
            await d.close()

    assert "started beyond" not in asyncio.run(fly())
