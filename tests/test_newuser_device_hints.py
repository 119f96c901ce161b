"""Found by a review of d9f2b33 (app.device_silence): an Mbed that does acknowledge, but late (its acks arrive after
ack_timeout_s: a slow USB bridge, a busy firmware), is told "no acknowledgement ... another baud rate than
serial.mbed_baud, or another device on this port": both wrong (valid MBACK lines arrive at the right baud rate,
the driver counted them as acks_late), and it sends the user to change a baud rate that is right.
"""

from __future__ import annotations

import types

from autopilot.clock import SimClock
from autopilot.daemon.app import device_silence
from autopilot.daemon.config import DaemonConfig
from autopilot.devices import ZERO_THRUST
from autopilot.drivers.mbed import MbedDriver
from autopilot.drivers.mbed_protocol import encode_ack


def test_a_board_that_acks_late_is_not_told_to_check_its_baud_rate():
    clock = SimClock()
    drv = MbedDriver("/dev/ttyACM0", clock=clock, ack_timeout_s=0.3)
    drv._link.write = lambda line: True  # the port is open and takes the command
    drv._link.opens = 1
    for k in range(20):
        clock.advance_to(0.1 * k)
        seq = drv.send(ZERO_THRUST)
        clock.advance_to(0.1 * k + 0.05)
        if k >= 5:  # each ack 0.5 s after its command
            late = encode_ack(seq - 5) + b"\r\n"
            drv._link.bytes_in += len(late)
            drv._on_bytes(late)
    assert drv.stats["acks_late"] > 0 and not drv.answered and drv.bad_lines == 0
    compass = types.SimpleNamespace(transport=types.SimpleNamespace(opens=0), port_path="/dev/ttyUSB0")  # said apart; not opened here
    lines = device_silence(compass, drv, DaemonConfig(), 2.0)
    mbed = [ln for ln in lines if ln.startswith("mbed:")]
    assert mbed and "baud" not in mbed[0] and "no acknowledgement" not in mbed[0], mbed[0]
    assert "answers, but late" in mbed[0] and "serial.ack_timeout_s, 0.3 s" in mbed[0]


def test_a_port_that_echoes_the_commands_back_is_told_so(tmp_path):
    """Stop 47's note: a port that echoes what the daemon sends (a loopback plug on the bench, RX wired to TX, a
    terminal program's echo) got the generic "no acknowledgement: another baud rate than serial.mbed_baud, or
    another device on this port", sending the user to change a baud rate that was right. A real pseudo-terminal
    whose far end writes back every byte it reads."""
    import asyncio

    from autopilot.clock import Clock
    from autopilot.simdev.pty import PtyEndpoint

    async def scenario():
        loopback = PtyEndpoint(tmp_path, "mbed")
        drv = MbedDriver(loopback.path, clock=Clock(), reconnect_min_s=0.1, reconnect_max_s=0.4, ack_timeout_s=0.3)
        task = asyncio.get_running_loop().create_task(drv.run())
        try:
            for _ in range(200):
                if drv.connected:
                    break
                await asyncio.sleep(0.01)
            for _ in range(8):  # 10 Hz commands, each echoed as it arrives
                drv.send(ZERO_THRUST)
                await asyncio.sleep(0.05)
                loopback.write(loopback.read())
                await asyncio.sleep(0.05)
            compass = types.SimpleNamespace(transport=types.SimpleNamespace(opens=0), port_path="/dev/ttyUSB0")
            return drv.stats, device_silence(compass, drv,
                                             DaemonConfig(), 0.8)
        finally:
            await drv.close()
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
            loopback.close()

    stats, lines = asyncio.run(scenario())
    assert stats["commands_echoed"] >= 5 and stats["acks_ok"] == 0 and stats["bad_lines"] == 0, stats
    mbed = [ln for ln in lines if ln.startswith("mbed:")]
    assert mbed and "the port echoes them" in mbed[0] and "baud" not in mbed[0], mbed
