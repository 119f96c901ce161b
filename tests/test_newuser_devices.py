"""`autopilot run` on the boat PC with ports that open but are not the devices they should be (a new-user audit,
2026-12-06): a silent port, a compass at another baud rate (garbage), the compass and the Mbed swapped. Each used to
be one JSON line, ``devices not answering`` with two booleans, after ready_timeout_s, and an end summary naming the
Mbed alone; now a plain sentence per device says what arrived and what that points at, then and at the end, while
every command written stays at zero thrust.

The devices are pseudo-terminals (the daemon's drivers open them as serial ports); the daemon runs as the user runs
it, ``python -m autopilot run``.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time

from autopilot.drivers.nmea import make_sentence
from autopilot.simdev import PtyEndpoint
from tests.test_daemon_bad_inputs import _write  # a realtime module's helper: this module flies daemons too

MISSION = "name: m\nframe: local\nwaypoints:\n  - {north_m: 10.0, east_m: 0.0}\n"
COMMAND = re.compile(rb"\$MBCMD,\d+,([FR]),([\d.]+),([FR]),([\d.]+)\*")
HEADING = make_sentence("HEHDT,45.0,T").encode()  # what an SC-30 sends ten times a second


def _fly(tmp_path, *, compass_sends: bytes, mbed_sends: bytes, seconds: float = 2.5) -> tuple[str, bytes]:
    """Run the daemon on two pseudo-terminals, each sending its bytes every 0.1 s; (stderr, what the daemon wrote to
    the Mbed's port) after a SIGTERM."""
    sc30, mbed = PtyEndpoint(tmp_path / "dev", "sc30"), PtyEndpoint(tmp_path / "dev", "mbed")
    _write(tmp_path / "c.yaml", f"serial: {{sc30_port: {sc30.path}, mbed_port: {mbed.path}}}\norigin_lat_deg: 52.0\n"
                                "origin_lon_deg: 4.4\nready_timeout_s: 0.5\n")
    _write(tmp_path / "m.yaml", MISSION)
    written = b""
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "autopilot", "run", "--config", str(tmp_path / "c.yaml"), "--mission",
             str(tmp_path / "m.yaml"), "--log-dir", str(tmp_path / "logs"), "--state-dir", str(tmp_path / "state"),
             "--runtime-dir", str(tmp_path / "rt")], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        end = time.monotonic() + seconds
        while time.monotonic() < end and proc.poll() is None:
            sc30.write(compass_sends)
            mbed.write(mbed_sends)
            written += mbed.read()
            time.sleep(0.1)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        written += mbed.read()
    finally:
        sc30.close()
        mbed.close()
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    commands = COMMAND.findall(written)
    assert commands and all(float(port) == 0.0 and float(stbd) == 0.0 for _, port, _, stbd in commands)
    return err, written


def _said(err: str) -> list[str]:
    """The plain lines (not the JSON events)."""
    return [ln for ln in err.splitlines() if ln.startswith("autopilot run: ")]


def test_compass_and_mbed_swapped_is_named(tmp_path):
    err, _ = _fly(tmp_path, compass_sends=b"", mbed_sends=HEADING)
    said = _said(err)
    path, dev = tmp_path / "dev", re.escape(str(tmp_path / "dev"))
    # said at ready_timeout_s (0.5 s), the cycle after it
    assert any(re.fullmatch(
        rf"autopilot run: sc30: {dev}/sc30 is open at 4800 baud but nothing arrived in [\d.]+ s: is the SC-30 "
        rf"powered, its NMEA output wired to this port\? \(`autopilot nmea {dev}/sc30 --baud 4800` shows what "
        r"arrives\)", ln) for ln in said)
    assert any(ln.startswith(f"autopilot run: mbed: NMEA sentences arrive on {path}/mbed (") and ln.endswith(
        "line(s)): that is the compass's output, so serial.sc30_port and serial.mbed_port are swapped?") for ln in said)
    assert "autopilot run: thrust stays at zero until both devices answer" in said
    # and again in the end summary, over the whole run
    assert any(ln.startswith("autopilot run:   mbed: NMEA sentences arrive on") for ln in said)
    assert any(ln.startswith(f"autopilot run:   sc30: {path}/sc30 is open at 4800 baud but nothing arrived") for ln in said)


def test_a_compass_at_another_baud_rate_and_a_silent_mbed(tmp_path):
    err, _ = _fly(tmp_path, compass_sends=b"\xf0\x0f\x87 x~\x81\x13\r\n" * 4, mbed_sends=b"")
    said = _said(err)
    dev = re.escape(str(tmp_path / "dev"))
    sc30 = [ln for ln in said if ln.startswith("autopilot run: sc30: ")]
    assert sc30 and re.fullmatch(
        rf"autopilot run: sc30: \d+ bytes arrived on {dev}/sc30 in [\d.]+ s but no NMEA sentence \(\d+ line\(s\) rejected\): "
        r"the SC-30 at another baud rate than serial.sc30_baud \(4800; it sends at 4800, 9600, 19200 or 38400\), or "
        rf"another device on this port \(`autopilot nmea {dev}/sc30 --baud 4800` shows what arrives\)", sc30[0])
    mbed = [ln for ln in said if ln.startswith("autopilot run: mbed: ")]
    assert mbed and re.fullmatch(
        rf"autopilot run: mbed: {dev}/mbed is open at 115200 baud, \d+ command\(s\) sent, but nothing came back in "
        r"[\d.]+ s: is it the Mbed \(USB 0d28:0204\) running the firmware of docs/mbed-protocol.md\?", mbed[0])
