"""A vessel moored on the last waypoint, then gone: through the real daemon, AIS on a pseudo-terminal of its own.

The daemon is a subprocess without --sim (tests/test_failsafe_faults.py's rig, clock 10x), its AIS receiver
a pseudo-terminal this test writes position reports to, decoded by the daemon's own driver and target table.
The mission ends holding at its one waypoint; a vessel moored on it makes the boat hold off, on its side of
the vessel. Found by an operator audit: when the vessel sailed off, the hold stayed off and the boat never went
on to the waypoint. Now it goes there once the vessel is reported clear of it; a vessel that falls silent, even
dropped from the AIS table (``ais.receiver.stale_after_s``, shortened here), may still lie there: the hold stays
off (a review: released on silence, the hold went onto a vessel whose AIS was off).
The pure part: tests/test_avoidance_occupied_gone.py.
"""

from __future__ import annotations

import asyncio
import math
from functools import partial

from autopilot.geo import local_to_latlon
from autopilot.simdev import PtyEndpoint
from autopilot.simdev.traffic import encode_ais
from tests.test_failsafe_faults import ORIGIN
from tests.test_failsafe_faults import Daemon as FaultRigDaemon

Daemon = partial(FaultRigDaemon, injects_link_faults=False)

WAYPOINT = (40.0, 0.0)
MMSI = 244000902
STALE_AFTER_S = 12.0  # ais.receiver.stale_after_s (shipped 360 s, twice the longest AIS reporting interval)
REPORT_EVERY_S = 5.0


def _cycles(d) -> list[dict]:
    return [r for r in d.log() if r["event"] == "cycle"]


def _hold_point(d) -> tuple[float, float] | None:
    c = _cycles(d)[-1] if _cycles(d) else {}
    return None if c.get("hold_north_m") is None else (c["hold_north_m"], c["hold_east_m"])


def test_the_hold_off_a_moored_vessel_stays_while_it_is_silent_and_goes_to_the_waypoint_once_it_sails_off(tmp_path):
    def report_at(north_m: float, speed_kn: float, status: int) -> bytes:
        lat, lon = local_to_latlon(north_m, WAYPOINT[1], *ORIGIN)
        return ("\r\n".join(encode_ais({"msg_type": 1, "mmsi": MMSI, "lat": lat, "lon": lon, "speed": speed_kn,
                                         "course": 0.0, "heading": 0, "status": status})) + "\r\n").encode()

    moored = report_at(WAYPOINT[0], 0.0, 5)  # status 5: moored
    sailed = report_at(WAYPOINT[0] + 60.0, 4.0, 0)  # under way, 60 m on: clear of the waypoint

    async def scenario():
        ais = PtyEndpoint(tmp_path / "ais-dev", "ais")
        d = Daemon(tmp_path, {"name": "to-the-mooring", "frame": "local", "waypoints": [list(WAYPOINT)]},
                   config={"gnc": {"guidance": {"final_action": "hold"}},
                           "ais": {"port": ais.path, "receiver": {"stale_after_s": STALE_AFTER_S}}})

        async def send_until(stop, report=moored) -> float:
            """The vessel reports every REPORT_EVERY_S until ``stop()``; the time of its last report."""
            last = -math.inf
            while not stop():
                ais.write(report)
                last = d.clock.now_s()
                await d.clock.sleep(REPORT_EVERY_S)
            return last

        try:
            await d.start()
            t_limit = d.clock.now_s() + 120.0
            await send_until(lambda: d.events("waypoint_occupied") or d.clock.now_s() > t_limit)
            assert any(r["event"] == "target" and r["target"] == MMSI for r in d.log())  # seen through the driver
            occ = d.events("waypoint_occupied")[0]
            assert occ["wp_index"] == 0 and occ["target"] == MMSI
            await d.wait(lambda: _last_mode(d) == "hold" and _hold_point(d) is not None, 10.0, "the final hold")
            spot = _hold_point(d)
            off_m = math.hypot(spot[0] - WAYPOINT[0], spot[1] - WAYPOINT[1])
            assert off_m > occ["need_m"]  # held off, on the boat's side of the vessel
            # reported for 10 s more: off; then silent, past the AIS table's stale_after_s: still off
            t_quiet = d.clock.now_s() + 10.0
            last = await send_until(lambda: d.clock.now_s() >= t_quiet)
            await d.clock.sleep(STALE_AFTER_S + 5.0 - (d.clock.now_s() - last))
            assert _hold_point(d) == spot  # dropped from the table, never reported clear: no proof the point is free
            assert not [r for r in d.events("mode") if r["cause"].startswith("waypoint 0 free")]
            # it reports again, under way and 60 m on: clear of the waypoint
            t_sailed = d.clock.now_s()
            ais.write(sailed)
            t_free = await d.wait(lambda: _hold_point(d) == WAYPOINT, 30.0, "the hold at the waypoint")
            assert t_free - t_sailed <= 3.0, t_free - t_sailed
            freed = [r for r in d.events("mode") if r["cause"].startswith("waypoint 0 free")]
            assert [(r["from"], r["mode"], r["cause"]) for r in freed] == [
                ("hold", "hold", f"waypoint 0 free: vessel {MMSI} reported clear of it: holding at the waypoint")]

            def boat_off_m() -> float:
                return math.hypot(float(d.rig.boat.state[0]) - WAYPOINT[0], float(d.rig.boat.state[1]) - WAYPOINT[1])

            await d.wait(lambda: boat_off_m() < 2.0, 150.0, "the boat at the waypoint")
            assert _last_mode(d) == "hold"
            d.proc.send_signal(2)
            assert await d.finish(30.0) == 0
        finally:
            await d.close()
            ais.close()

    asyncio.run(scenario())


def _last_mode(d) -> str | None:
    c = _cycles(d)
    return c[-1]["mode"] if c else None
