"""AIS in the daemon (issue 18): where the targets come from, and the simulated traffic of ``--sim``.

    ais.port              an AIS receiver on its own serial port (AisDriver, 38400 baud usually)
    ais.on_compass_line   !AIVDM interleaved on the SC-30's line: the compass's decoder hands them over
    sim.traffic           --sim: a traffic scenario's vessels sent as AIS sentences at AIS rates by a
                          simulated receiver on a pseudo-terminal of its own (TrafficEmitter), the
                          scenario's reactive vessels watching the simulated boat

:class:`AisSource` is what the loop asks each cycle: the fresh targets as
:class:`autopilot.gnc.encounter.TargetState` in the mission's local frame, dead-reckoned for their age,
and which of them sent a new position since it last asked (for the log's ``target`` lines).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import math
from pathlib import Path

from autopilot.gnc.encounter import OwnShip, TargetState
from autopilot.schema import ConfigError

__all__ = ["AisSource", "load_traffic", "SimTraffic"]

TARGET_LOG_PERIOD_S = 1.0  # a target's position goes to the log at most this often


def load_traffic(name: str, *, origin_lat_deg: float, origin_lon_deg: float):
    """The scenario of ``sim.traffic`` (a shipped name or a YAML file), placed around the mission's origin."""
    from autopilot.evaluate import shipped_scenarios
    from autopilot.simdev.traffic import load_scenario

    shipped = {p.stem: p for p in shipped_scenarios()}
    path = shipped.get(name) or Path(name)
    if not path.exists():
        raise ConfigError(f"sim.traffic: {name!r} is neither a file nor a shipped scenario ({', '.join(shipped)})")
    try:
        sc = load_scenario(path)
    except (ConfigError, ValueError) as exc:
        raise ConfigError(f"sim.traffic: {path}: {exc}") from None
    return dataclasses.replace(sc, origin_lat_deg=origin_lat_deg, origin_lon_deg=origin_lon_deg)


class AisSource:
    """The targets of one AIS receiver (:class:`autopilot.drivers.ais.AisReceiver`) for the loop."""

    def __init__(self, receiver, *, origin_lat_deg: float, origin_lon_deg: float) -> None:
        self.receiver = receiver
        self.origin = (origin_lat_deg, origin_lon_deg)
        self._logged: dict[int, float] = {}  # mmsi -> report time last logged

    def targets(self, now_s: float) -> list[TargetState]:
        return [TargetState.from_ais(t, origin_lat_deg=self.origin[0], origin_lon_deg=self.origin[1], now_s=now_s)
                for t in self.receiver.targets(now_s)]

    def new_reports(self, now_s: float) -> list[dict]:
        """``target`` log lines for the targets whose position report is newer than the one last logged."""
        from autopilot.geo import latlon_to_local

        out = []
        for t in self.receiver.targets(now_s):
            last = self._logged.get(t.mmsi)
            if t.position_t_s is None or (last is not None and (t.position_t_s <= last
                                                                or t.position_t_s - last < TARGET_LOG_PERIOD_S)):
                continue
            self._logged[t.mmsi] = t.position_t_s
            n, e = latlon_to_local(t.lat_deg, t.lon_deg, *self.origin)
            out.append({"target": t.mmsi, "name": t.shipname, "north_m": n, "east_m": e,
                        "course_deg": None if t.cog_rad is None else math.degrees(t.cog_rad) % 360.0,
                        "speed_m_s": t.sog_m_s,
                        "heading_deg": None if t.heading_rad is None else math.degrees(t.heading_rad) % 360.0,
                        "length_m": t.length_m, "age_s": now_s - t.position_t_s})
        return out


class SimTraffic:
    """``--sim``'s traffic: an emitter on a pty of its own and the scenario's vessels moving with the boat."""

    def __init__(self, scenario, clock, directory, *, boat, baudrate: int = 38400) -> None:
        from autopilot.simdev.pty import PtyEndpoint
        from autopilot.simdev.traffic import TrafficEmitter, TrafficSim

        self.scenario, self.clock, self.boat = scenario, clock, boat
        self.endpoint = PtyEndpoint(directory, "ais")
        self.path = self.endpoint.path
        self.sim = TrafficSim(scenario)
        self.emitter = TrafficEmitter(scenario, clock, self.endpoint, baudrate=baudrate, sim=self.sim)
        self._task: asyncio.Task | None = None

    async def start(self) -> None:
        await self.emitter.start()
        self._task = asyncio.get_running_loop().create_task(self._move())

    async def _move(self) -> None:
        t0 = self.clock.now_s()
        while True:  # the reactive vessels watch the boat (the emitter reports what the sim says)
            x = self.boat.state
            u, v = float(x[3]), float(x[4])
            own = OwnShip(float(x[0]), float(x[1]), float(x[2]) + math.atan2(v, u), math.hypot(u, v), float(x[2]))
            self.sim.step(self.clock.now_s() - t0, own)
            await self.clock.sleep(0.1)

    def quiet(self, driver) -> bool:
        return self.endpoint.bytes_written == driver.transport.bytes_in + driver.transport.bytes_discarded

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        await self.emitter.stop()
        self.endpoint.close()
