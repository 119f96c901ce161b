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
