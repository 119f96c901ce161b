"""Boat + simulated SC-30 + simulated Mbed, as the daemon's ``--sim`` and the tests use them."""

from __future__ import annotations

import asyncio

from autopilot.clock import Clock
from autopilot.drivers.mbed_protocol import FIRMWARE_STOP_TIMEOUT_S
from autopilot.simdev.boat import SimBoat
from autopilot.simdev.mbed import SimulatedMbed
from autopilot.simdev.sc30 import SimulatedSC30

__all__ = ["SimRig"]


class SimRig:
    """Builds the boat and both devices in ``directory``; ``sc30_path`` / ``mbed_path`` for the drivers."""

    def __init__(
        self,
        params,
        clock: Clock,
        *,
        directory,
        env=None,
        x0=None,
        origin_lat_deg: float,
        origin_lon_deg: float,
        thrust_curve=None,
        sc30_baudrate: int = 4800,
        heading_noise_deg: float = 0.1,
        position_noise_m: float = 0.3,
        seed: int = 0,
        stop_timeout_s: float = FIRMWARE_STOP_TIMEOUT_S,
        advance_period_s: float = 0.05,
        sc30_options: dict | None = None,
        battery=None,
        thrust_gains: tuple[float, float] = (1.0, 1.0),
    ) -> None:
        self.clock = clock
        self.boat = SimBoat(
            params,
            env=env,
            x0=x0,
            thrust_curve=thrust_curve,
            origin_lat_deg=origin_lat_deg,
            origin_lon_deg=origin_lon_deg,
            t0_s=clock.now_s(),
            thrust_gain_port=thrust_gains[0],
            thrust_gain_stbd=thrust_gains[1],
        )
        self.sc30 = SimulatedSC30(
            self.boat,
            clock,
            directory=directory,
            baudrate=sc30_baudrate,
            heading_noise_deg=heading_noise_deg,
            position_noise_m=position_noise_m,
            seed=seed,
            **(sc30_options or {}),
        )
        self.mbed = SimulatedMbed(self.boat, clock, directory=directory, stop_timeout_s=stop_timeout_s,
                                  **({} if battery is None else {"battery": battery}))
        self.advance_period_s = float(advance_period_s)
        self._task: asyncio.Task | None = None

    @property
    def sc30_path(self) -> str:
        return self.sc30.path

    @property
    def mbed_path(self) -> str:
        return self.mbed.path

    def quiet(self, compass, thrusters) -> bool:
        """Nothing in flight on either line: every byte one end wrote, the other has read (lockstep).

        ``compass``, ``thrusters``: the daemon's drivers on these devices' paths.
        """
        c, t = compass.transport, thrusters.transport
        sc30, mbed = self.sc30.endpoint, self.mbed.endpoint
        return (sc30.bytes_written == c.bytes_in + c.bytes_discarded and t.bytes_out == mbed.bytes_read
                and mbed.bytes_written == t.bytes_in + t.bytes_discarded)

    async def start(self) -> None:
        await self.mbed.start()
        await self.sc30.start()
        self._task = asyncio.get_running_loop().create_task(self._advance())

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass
            self._task = None
        await self.sc30.stop()
        await self.mbed.stop()

    async def _advance(self) -> None:
        t_s = self.clock.now_s()
        while True:
            t_s += self.advance_period_s
            await self.clock.sleep_until(t_s)
            self.boat.advance_to(t_s)
