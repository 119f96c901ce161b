"""A simulated Mbed thruster board behind a pseudo-terminal (firmware of docs/mbed-protocol.md).

Parses ``$MBCMD`` lines, applies them to the boat through the thrust curve,
acknowledges them, and stops both motors when no valid command arrived for
``stop_timeout_s`` (default 0.5 s), the firmware's safety duty. Bad lines are
counted and ignored; checksummed commands with bad fields get ``REJ``.

Records for tests: ``commands`` (every applied command:
``(t_s, seq, duty_port_pct, reverse_port, duty_stbd_pct, reverse_stbd)``)
and ``thrust_log`` (every change of the outputs:
``(t_s, duty_port_pct, reverse_port, duty_stbd_pct, reverse_stbd, cause)``,
cause "command" or "timeout"). Faults: ``silent`` (obeys, never acks), ``deaf`` (hears nothing: its receive
wire broken, a hung USB adapter; the firmware's stop follows),
``ack_delay_s``, ``stuck`` (commands no longer change the outputs and every ``OK`` echoes
the outputs as they are, as a firmware whose PWM hung would), ``swapped`` (miswired: the port
command drives the starboard motor and the other way round; the ``OK`` echoes the outputs as
set), ``unplug()``, ``replug()``. The battery (:mod:`autopilot.sim.battery`)
drains with the duties applied and its voltage, sagging under load, is in every ``OK``
acknowledgement; ``report_battery = False`` is old firmware without the field.
"""

from __future__ import annotations

import asyncio

from autopilot.clock import Clock
from autopilot.drivers.framing import LineFramer
from autopilot.drivers.mbed_protocol import (
    FIRMWARE_STOP_TIMEOUT_S,
    MAX_LINE_CHARS,
    ProtocolError,
    decode_command,
    encode_ack,
)
from autopilot.sim.battery import Battery, BatteryConfig
from autopilot.simdev.boat import SimBoat
from autopilot.simdev.pty import PtyEndpoint

__all__ = ["SimulatedMbed"]


class SimulatedMbed:
    def __init__(
        self,
        boat: SimBoat,
        clock: Clock,
        *,
        directory,
        stop_timeout_s: float = FIRMWARE_STOP_TIMEOUT_S,
        name: str = "mbed",
        battery: BatteryConfig = BatteryConfig(),
    ) -> None:
        self.boat = boat
        self.clock = clock
        self.stop_timeout_s = float(stop_timeout_s)
        self._endpoint = PtyEndpoint(directory, name)
        self.path = self._endpoint.path
        self.silent = False
        self.deaf = False
        self.stuck = False
        self.swapped = False
        self.ack_delay_s = 0.0
        self.commands: list[tuple[float, int, float, bool, float, bool]] = []
        self.thrust_log: list[tuple[float, float, bool, float, bool, str]] = []
        self.outputs: tuple[float, bool, float, bool] = (0.0, False, 0.0, False)
        self.battery = Battery(battery)
        self.report_battery = True
        self._battery_t_s: float | None = None
        self._malformed = 0
        self.rejected = 0
        self.timeouts = 0
        self.last_valid_s = -float("inf")
        self._framer = LineFramer(MAX_LINE_CHARS)
        self._fd: int | None = None
        self._armed = asyncio.Event()
        self._tasks: list[asyncio.Task] = []

    # ------------------------------------------------------------------ lifecycle
    async def start(self) -> None:
        self._attach()
        self._tasks.append(asyncio.get_running_loop().create_task(self._watchdog()))

    async def stop(self) -> None:
        for t in self._tasks:
            t.cancel()
        for t in self._tasks:
            try:
                await t
            except (asyncio.CancelledError, Exception):
                pass
        self._tasks.clear()
        self._detach()
        self._endpoint.close()

    def unplug(self) -> None:
        """USB cable pulled: the link is gone; the firmware's timeout will stop the motors."""
        self._detach()
        self._endpoint.unplug()
        self._framer.clear()

    def replug(self) -> None:
        self._endpoint.replug()
        self._attach()

    @property
    def plugged(self) -> bool:
        return self._endpoint.plugged

    @property
    def endpoint(self) -> PtyEndpoint:
        """The pseudo-terminal underneath (its byte counters)."""
        return self._endpoint

    @property
    def thrusting(self) -> bool:
        return self.outputs[0] > 0 or self.outputs[2] > 0

    def first_stop_after(self, t_s: float) -> float | None:
        """Clock time of the first zero-output state at or after ``t_s`` (None if none yet)."""
        if not self._nonzero_at(t_s):
            return t_s
        for entry in self.thrust_log:
            if entry[0] >= t_s and entry[1] == 0 and entry[3] == 0:
                return entry[0]
        return None

    def _nonzero_at(self, t_s: float) -> bool:
        state = (0.0, False, 0.0, False)
        for entry in self.thrust_log:
            if entry[0] > t_s:
                break
            state = entry[1:5]
        return state[0] > 0 or state[2] > 0

    # ------------------------------------------------------------------ I/O
    def _attach(self) -> None:
        fd = self._endpoint.master_fd
        if fd is not None:
            asyncio.get_running_loop().add_reader(fd, self._readable)
            self._fd = fd

    def _detach(self) -> None:
        if self._fd is not None:
            try:
                asyncio.get_running_loop().remove_reader(self._fd)
            except Exception:  # noqa: BLE001
                pass
            self._fd = None

    def _readable(self) -> None:
        data = self._endpoint.read()
        if not data:
            return
        now_s = self.clock.now_s()
        if self.deaf:  # the bytes never reach the firmware
            return
        for line in self._framer.feed(data):
            self._line(line, now_s)

    @property
    def bad_lines(self) -> int:
        """Lines that were not commands (bad framing or checksum, or too long), cumulative."""
        return self._malformed + self._framer.too_long

    def _line(self, line: bytes, now_s: float) -> None:
        if not line.strip(b"\r"):
            return
        try:
            cmd = decode_command(line)
        except ProtocolError as exc:
            if exc.reason is None:
                self._malformed += 1
            else:
                self.rejected += 1
                self._reply(encode_ack(exc.seq, "REJ", reason=exc.reason))
            return
        self.last_valid_s = now_s
        self.commands.append((now_s, cmd.seq, cmd.duty_port_pct, cmd.reverse_port, cmd.duty_stbd_pct, cmd.reverse_stbd))
        if self.swapped:
            self._set((cmd.duty_stbd_pct, cmd.reverse_stbd, cmd.duty_port_pct, cmd.reverse_port), now_s, "command")
        elif not self.stuck:
            self._set((cmd.duty_port_pct, cmd.reverse_port, cmd.duty_stbd_pct, cmd.reverse_stbd), now_s, "command")
        self._armed.set()
        port, rev_port, stbd, rev_stbd = self.outputs  # what it set, echoed (docs/mbed-protocol.md)
        volts = self.battery.voltage_v(port, stbd) if self.report_battery else None
        self._reply(encode_ack(cmd.seq, "OK", port, rev_port, stbd, rev_stbd,
                               battery_v=None if volts is None else min(volts, 99.99)))

    def _reply(self, line: bytes) -> None:
        if self.silent:
            return
        if self.ack_delay_s > 0:
            self._tasks.append(asyncio.get_running_loop().create_task(self._delayed(line)))
        else:
            self._endpoint.write(line)

    async def _delayed(self, line: bytes) -> None:
        await self.clock.sleep(self.ack_delay_s)
        self._endpoint.write(line)

    def _set(self, outputs: tuple[float, bool, float, bool], now_s: float, cause: str) -> None:
        self.boat.advance_to(now_s)  # the old thrust acted until now
        if self._battery_t_s is not None:  # ... and drew its current until now
            self.battery.drain(self.outputs[0], self.outputs[2], now_s - self._battery_t_s)
        self._battery_t_s = now_s
        if outputs != self.outputs or not self.thrust_log:
            self.thrust_log.append((now_s, *outputs, cause))
        self.outputs = outputs
        self.boat.set_duty(*outputs)

    async def _watchdog(self) -> None:
        """Stop both motors ``stop_timeout_s`` after the last valid command."""
        while True:
            if not self.thrusting:
                await self._armed.wait()
                self._armed.clear()
                continue
            deadline_s = self.last_valid_s + self.stop_timeout_s
            await self.clock.sleep_until(deadline_s)
            now_s = self.clock.now_s()
            if self.thrusting and now_s >= self.last_valid_s + self.stop_timeout_s:
                self.timeouts += 1
                self._set((0.0, False, 0.0, False), now_s, "timeout")
            self._armed.clear()
