"""Bad input at every edge of `autopilot run` (issue 7.4): the exact message for each, as in docs/bad-inputs.md.

Configuration, mission and command-line cases go through `autopilot.cli.main` (what the
`autopilot` script runs) and must stop the start with exit code 2 and one line on stderr,
before any port is opened (the configured ports here do not exist). NMEA and Mbed replies never
stop the daemon: they are dropped and counted; the table records the decoder's verdict.
Regenerate the document with `python tests/test_daemon_bad_inputs.py > docs/bad-inputs.md`.
"""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

import pytest

from autopilot.cli import main
from autopilot.drivers.mbed_protocol import ProtocolError, decode_ack
from autopilot.drivers.nmea import NmeaStreamDecoder, checksum

ROOT = Path(__file__).resolve().parents[1]
GOOD_MISSION = "name: m\nframe: local\nwaypoints:\n  - {north_m: 10.0, east_m: 0.0}\n"
GOOD_CONFIG = "serial: {sc30_port: /nonexistent/sc30, mbed_port: /nonexistent/mbed}\norigin_lat_deg: 52.0\norigin_lon_deg: 4.4\n"

DIRECTORY = object()  # a directory where a file was expected
# (edge, what was tried, config text or bytes, mission text or bytes, extra argv, expected stderr with {dir} for the tmp dir)
CLI_CASES = [
    ("command line", "--mission missing", None, None, ["--config", "{dir}/c.yaml"],
     "autopilot run: error: the following arguments are required: --mission"),
    ("command line", "--speedup not a number", GOOD_CONFIG, GOOD_MISSION, ["--speedup", "fast"],
     "autopilot run: error: argument --speedup: invalid float value: 'fast' (or max)"),
    ("command line", "--speedup 0", GOOD_CONFIG, GOOD_MISSION, ["--speedup", "0"],
     "autopilot run: error: --speedup: 0.0 is outside the allowed range [0.01, 100], or max"),
    ("command line", "--speedup max without --sim", GOOD_CONFIG, GOOD_MISSION, ["--speedup", "max"],
     "autopilot run: error: --speedup max: lockstep runs only with --sim (the boat's devices keep real time)"),
    ("command line", "--speedup 10 without --sim", GOOD_CONFIG, GOOD_MISSION, ["--speedup", "10"],
     "autopilot run: error: --speedup 10: serial.sc30_port /nonexistent/sc30 is not a simulated device (a pseudo-terminal); "
     "real devices keep real time: --speedup is for --sim"),
    ("command line", "--mavlink to an address that is not one", GOOD_CONFIG, GOOD_MISSION,
     ["--mavlink", "udpout:999.1.1.1:14550"],
     "autopilot run: error: --mavlink: 'udpout:999.1.1.1:14550': 999.1.1.1 is not an IPv4 address"),
    ("command line", "log directory not writable", GOOD_CONFIG, GOOD_MISSION, ["--log-dir", "/proc/autopilot-logs"],
     "autopilot run: error: log directory /proc/autopilot-logs: cannot create (No such file or directory)"),
    ("command line", "log directory is a file", GOOD_CONFIG, GOOD_MISSION, ["--log-dir", "{dir}/c.yaml"],
     "autopilot run: error: log directory {dir}/c.yaml: is a file, not a directory"),
    # found by an on-boat audit: "control socket .../control.sock: cannot create (None)"
    ("command line", "a runtime directory too long for a socket", GOOD_CONFIG, GOOD_MISSION, ["--runtime-dir", "/tmp/" + "r" * 100],
     "autopilot run: error: control socket /tmp/" + "r" * 100 + "/control.sock: its path is 118 bytes, longer than the 107 a Unix socket's may be; give a shorter runtime directory (--runtime-dir, runtime_dir)"),
    ("command line", "runtime directory is a file", GOOD_CONFIG, GOOD_MISSION, ["--runtime-dir", "{dir}/c.yaml"],
     "autopilot run: error: runtime directory {dir}/c.yaml: is a file, not a directory"),
    ("command line", "--mavlink not an endpoint", GOOD_CONFIG, GOOD_MISSION, ["--mavlink", "tcp:1.2.3.4:5760"],
     "autopilot run: error: --mavlink: 'tcp:1.2.3.4:5760': not an endpoint (udpout:HOST:PORT, udpin:ADDR:PORT or /dev/PATH:BAUD)"),
    ("configuration", "file missing", None, GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: cannot read (No such file or directory)"),
    ("configuration", "not YAML", "rate_hz: [10,\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: not valid YAML (line 2, column 1: expected the node content, but found '<stream end>', while parsing a flow node)"),
    ("configuration", "a tab for indentation", "failsafe:\n\theading_stale_s: 1.0\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: not valid YAML (line 2, column 1: found character '\\t' that cannot start any token, while scanning for the next token (a tab: YAML indents with spaces only))"),
    ("configuration", "empty file (a copy cut short)", "\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: the configuration is empty (no setting at all); to run on every default say so with {} in the file, or start from config/autopilot.yaml"),
    ("configuration", "a key twice", GOOD_CONFIG + "rate_hz: 10\nrate_hz: 20\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: not valid YAML (rate_hz: duplicate key (lines 4 and 5))"),
    ("configuration", "unknown key (typo)", "rate_hx: 10\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: rate_hx: unknown key (allowed: ais, boat_length_m, dead_reckon_max_s, failsafe, geofence, gnc, log_dir, mavlink, max_mission_range_m, origin_lat_deg, origin_lon_deg, rate_hz, ready_timeout_s, runtime_dir, serial, sim, state_dir, stop_ack_timeout_s); did you mean rate_hz?"),
    ("configuration", "rate out of range", "rate_hz: 100\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: rate_hz: 100 is outside the allowed range [4, 50] Hz"),
    # found by an on-boat audit: at 1-2 Hz the Mbed's 0.5-s stop timeout cut the motors between every two commands
    ("configuration", "a rate the Mbed's stop timeout cuts", GOOD_CONFIG + "rate_hz: 2\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: rate_hz: 2 is outside the allowed range [4, 50] Hz"),
    # found by an on-boat audit: the daemon retried "cannot open : no such device" for ever, naming no key
    ("configuration", "an empty device port", "serial: {sc30_port: '', mbed_port: /nonexistent/mbed}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: serial.sc30_port: empty; the device's serial port, such as /dev/sc30 or /dev/serial/by-id/..."),
    # found by an on-boat audit: the radio glued telemetry in front of the thrust commands (mbed_ack_missing)
    ("command line", "a MAVLink radio on the Mbed's port", GOOD_CONFIG, GOOD_MISSION, ["--mavlink", "/nonexistent/mbed:57600"],
     "autopilot run: error: --mavlink: /nonexistent/mbed:57600 is serial.mbed_port (/nonexistent/mbed): the radio needs its own port (ls -l /dev/serial/by-id/ names each adapter)"),
    # found by an on-boat audit: the file's origin was replaced by the configuration's, the waypoints moved 200 m
    ("mission", "a local mission's own origin far from the configuration's", GOOD_CONFIG,
     "frame: local\norigin: {lat_deg: 52.0018, lon_deg: 4.4}\nwaypoints:\n  - [30.0, 0.0]\n", [],
     "autopilot run: error: {dir}/m.yaml: origin (52.0018000, 4.4000000) is 200 m from the configuration's origin (52.0000000, 4.4000000); the waypoints are metres from the file's origin: make the two the same, or remove one of them"),
    ("configuration", "wrong type", "failsafe: {heading_stale_s: one}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: failsafe.heading_stale_s: expected a number in [0.05, 10] s, got 'one'"),
    ("configuration", "NaN", "failsafe: {max_distance_m: .nan}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: failsafe.max_distance_m: nan is not a finite number; allowed range [1, 20000] m"),
    # YAML 1.1 read 1e9 as the string '1e9' and the message said "got '1e9'", not a number
    ("configuration", "exponent without a dot", "failsafe: {max_distance_m: 1e9}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: failsafe.max_distance_m: 1000000000.0 is outside the allowed range [1, 20000] m"),
    ("configuration", "baud rate the SC-30 cannot do", "serial: {sc30_baud: 5000}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: serial.sc30_baud: 5000 is not one of 4800, 9600, 19200, 38400"),
    ("configuration", "unknown guidance law", "gnc: {guidance: {law: pure_pursuit}}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: gnc.guidance.law: 'pure_pursuit' is not one of fuzzy, los, proportional"),
    ("configuration", "geofence with two vertices", "geofence: {frame: local, polygon: [[0, 0], [10, 0]]}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: geofence.polygon: needs at least 3 vertices for frame 'local', got 2"),
    ("configuration", "a geofence polygon under frame none (no fence)",
     GOOD_CONFIG + "geofence: {frame: none, polygon: [[-50, -50], [50, -50], [50, 50]]}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: geofence.polygon: 3 vertices given with frame 'none', which is no fence: set "
     "geofence.frame to local ([north_m, east_m]) or latlon ([lat_deg, lon_deg]), or leave the polygon out"),
    ("configuration", "no heading gain but the derivative", GOOD_CONFIG + "gnc: {pid: {kp_n_per_deg: 0, ki_n_per_deg_s: 0}}\n",
     GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: gnc.pid: kp_n_per_deg and ki_n_per_deg_s are both 0: the helm cannot turn the "
     "boat towards a heading (kd_n_s_per_deg only damps the turn); give kp_n_per_deg > 0"),
    ("configuration", "the compass and the Mbed on one port",
     "serial: {sc30_port: /nonexistent/usb0, mbed_port: /nonexistent/usb0}\norigin_lat_deg: 52.0\norigin_lon_deg: 4.4\n",
     GOOD_MISSION, [], "autopilot run: error: {dir}/c.yaml: serial.mbed_port: /nonexistent/usb0 is serial.sc30_port too: "
     "each device needs its own port"),
    ("configuration", "sim.vessel missing (--sim)", GOOD_CONFIG + "sim: {vessel: /nonexistent/vessel.yaml}\n", GOOD_MISSION,
     ["--sim"], "autopilot run: error: sim.vessel: /nonexistent/vessel.yaml: cannot read (No such file or directory)"),
    ("configuration", "a number with a leading zero (YAML 1.1 octal)", GOOD_CONFIG + "rate_hz: 010\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: not valid YAML (line 4, column 10: 010: a leading zero makes it octal in "
     "YAML (8); write 10)"),
    ("configuration", "geofence of no area", "geofence: {frame: local, polygon: [[0, 0], [0, 0], [0, 0]]}\n",
     GOOD_MISSION, [], "autopilot run: error: {dir}/c.yaml: geofence.polygon: encloses no area (its vertices lie on one line)"),
    ("configuration", "geofence vertices out of order (a bow tie)",
     "geofence: {frame: local, polygon: [[-20, -20], [20, 20], [20, -20], [-20, 20]]}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: geofence.polygon: edges 0-1 and 2-3 cross (vertices out of order?)"),
    ("configuration", "geofence with latitude and longitude swapped",
     GOOD_CONFIG + "geofence: {frame: latlon, polygon: [[4.4, 52.0], [4.4, 52.001], [4.401, 52.001], [4.401, 52.0]]}\n",
     GOOD_MISSION, [], "autopilot run: error: {dir}/m.yaml: the start (the origin) is beyond the geofence failsafe: "
     "position (0.0, 0.0) m is outside the geofence"),
    ("mission", "a waypoint outside the geofence", GOOD_CONFIG + "geofence: {frame: local, polygon: [[-5, -5], [-5, 5], [8, 5], [8, -5]]}\n",
     GOOD_MISSION, [], "autopilot run: error: {dir}/m.yaml: waypoint 1 is beyond the geofence failsafe: position (10.0, 0.0) m "
     "is outside the geofence"),
    ("mission", "a waypoint beyond failsafe.max_distance_m", GOOD_CONFIG + "failsafe: {max_distance_m: 100}\n",
     "name: m\nframe: local\nwaypoints:\n  - {north_m: 10.0, east_m: 0.0}\n  - {north_m: 150.0, east_m: 0.0}\n", [],
     "autopilot run: error: {dir}/m.yaml: waypoint 2 is beyond the max_distance failsafe: 150.0 m from the origin (limit 100 m)"),
    # found by a new-user audit: the waypoints were checked, not the legs between them
    ("mission", "a leg between two waypoints inside an L-shaped geofence that leaves it",
     GOOD_CONFIG + "geofence: {frame: local, polygon: [[-5, -5], [60, -5], [60, 10], [10, 10], [10, 60], [-5, 60]]}\n",
     "name: m\nframe: local\nwaypoints:\n  - {north_m: 50.0, east_m: 0.0}\n  - {north_m: 0.0, east_m: 50.0}\n", [],
     "autopilot run: error: {dir}/m.yaml: the leg from waypoint 1 to waypoint 2 leaves the geofence (at (25.0, 25.0) m): "
     "the geofence failsafe would turn the boat back there; add a waypoint inside the fence to go round"),
    # found by a new-user audit: a planner's home became the local origin, and the fence and the limit moved with it
    ("mission", "a home 512 m from the configuration's origin (a planner's map centre)",
     GOOD_CONFIG + "geofence: {frame: local, polygon: [[-60, -60], [-60, 60], [60, 60], [60, -60]]}\n",
     "name: m\nframe: latlon\nhome: {lat_deg: 52.0046, lon_deg: 4.4}\nwaypoints:\n  - {lat_deg: 52.0047, lon_deg: 4.4}\n",
     [], "autopilot run: error: {dir}/m.yaml: the start (the mission's home) is beyond the geofence failsafe: position "
     "(511.8, 0.0) m is outside the geofence"),
    ("configuration", "failsafe action not known", "failsafe: {actions: {geofence: drift}}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: failsafe.actions.geofence: 'drift' is not one of stop, hold, rtl"),
    ("configuration", "battery critical above low", "failsafe: {battery_low_v: 11.5, battery_critical_v: 12.0}\n",
     GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: failsafe.battery_critical_v: 12 V is above failsafe.battery_low_v (11.5 V)"),
    ("configuration", "hold radius out of range", "gnc: {hold: {radius_m: -1}}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: gnc.hold.radius_m: -1 is outside the allowed range [0, 100] m"),
    ("configuration", "MAVLink signing key missing",
     GOOD_CONFIG + "mavlink: {endpoints: ['udpout:127.0.0.1:14550'], signing_key_file: /nonexistent/mavlink.key}\n",
     GOOD_MISSION, [],
     "autopilot run: error: mavlink.signing_key_file: /nonexistent/mavlink.key: cannot read (No such file or directory)"),
    ("configuration", "half an origin", "origin_lat_deg: 52.0\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: origin_lat_deg, origin_lon_deg: give both or neither"),
    ("configuration", "saved as Latin-1", "# Bjørnøya\nrate_hz: 10\n".encode("latin-1"), GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: not UTF-8 text (byte 0xF8 at offset 4; Latin-1 or another encoding?): save the YAML file as UTF-8"),
    ("configuration", "a directory", DIRECTORY, GOOD_MISSION, [],
     "autopilot run: error: {dir}/c.yaml: is a directory, not a YAML file"),
    ("mission", "saved as UTF-16", GOOD_CONFIG, GOOD_MISSION.encode("utf-16"), [],
     "autopilot run: error: {dir}/m.yaml: UTF-16 text; save the mission file as UTF-8"),
    ("mission", "saved as UTF-16 without a byte-order mark", GOOD_CONFIG, GOOD_MISSION.encode("utf-16-le"), [],
     "autopilot run: error: {dir}/m.yaml: UTF-16 text (without a byte-order mark); save the mission file as UTF-8"),
    ("mission", "binary data", GOOD_CONFIG, bytes(range(256)), [],
     "autopilot run: error: {dir}/m.yaml: binary data, not a text mission file"),
    ("mission", "negative hold", GOOD_CONFIG, GOOD_MISSION.replace("east_m: 0.0}", "east_m: 0.0, hold_s: -5}"), [],
     "autopilot run: error: {dir}/m.yaml: waypoint 1: hold_s -5 s outside [0, 86400] s (or hold: true, until commanded)"),
    ("mission", "a hold of minus infinity", GOOD_CONFIG, GOOD_MISSION.replace("east_m: 0.0}", "east_m: 0.0, hold_s: -.inf}"),
     [], "autopilot run: error: {dir}/m.yaml: waypoint 1: hold_s is -inf, not a finite number"),
    ("mission", "waypoints twice", GOOD_CONFIG, GOOD_MISSION + "waypoints:\n  - {north_m: 20.0, east_m: 0.0}\n", [],
     "autopilot run: error: {dir}/m.yaml: not valid YAML (waypoints: duplicate key (lines 3 and 5))"),
    ("mission", "rtl not last", GOOD_CONFIG, GOOD_MISSION.replace("waypoints:\n", "waypoints:\n  - rtl\n"), [],
     "autopilot run: error: {dir}/m.yaml: waypoint 1: rtl must be the last item"),
    ("mission", "local mission, no origin anywhere (real devices)", "serial: {sc30_port: /nonexistent/sc30}\n", GOOD_MISSION, [],
     "autopilot run: error: {dir}/m.yaml: local-frame mission without an origin: the compass reports latitude/longitude, so set origin_lat_deg/origin_lon_deg in the configuration (the launch point) or add 'origin' to the mission"),
]


def _write(path: Path, content) -> None:
    if content is DIRECTORY:
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content)


def _run_cli(tmp_path: Path, config, mission, extra: list[str]) -> tuple[int, str]:
    _write(tmp_path / "c.yaml", config)
    _write(tmp_path / "m.yaml", mission)
    argv = ["run"]
    extra = [a.replace("{dir}", str(tmp_path)) for a in extra]
    if "--config" not in extra:
        argv += ["--config", str(tmp_path / "c.yaml")]
    if "--mission" not in extra and "--mission missing" not in extra and not (config is None and mission is None):
        argv += ["--mission", str(tmp_path / "m.yaml")]
    argv += extra + ["--state-dir", str(tmp_path / "state")]
    if "--log-dir" not in extra:
        argv += ["--log-dir", str(tmp_path / "logs")]
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse
            code = exc.code
    lines = err.getvalue().strip().splitlines()
    message = "\n".join(x for x in lines if not x.startswith("usage:") and not x.startswith("  ") or x.startswith("  in ")) if lines else ""
    return code, message


@pytest.mark.parametrize("edge, what, config, mission, extra, expected", CLI_CASES, ids=[c[1] for c in CLI_CASES])
def test_bad_start_input_is_refused_with_the_documented_message(tmp_path, edge, what, config, mission, extra, expected):
    code, message = _run_cli(tmp_path, config, mission, extra)
    assert code == 2
    expected = expected.replace("{dir}", str(tmp_path))
    assert message == expected
    assert not list((tmp_path / "logs").glob("*.jsonl")) if (tmp_path / "logs").exists() else True


# NMEA lines on the compass port: never raised into the loop, dropped and counted.
NMEA_CASES = [
    ("bad checksum", b"$GPHDT,123.4,T*00\r\n", "checksum_errors"),
    ("no checksum", b"$GPHDT,123.4,T\r\n", None),
    ("binary garbage", bytes(range(256)) + b"\r\n", None),
    ("non-ASCII", "$GPHDT,12\u00b03.4,T*11\r\n".encode("utf-8"), "non_ascii"),
    ("overlong line", b"$GPHDT," + b"1" * 200 + b"*00\r\n", "too_long"),
    ("unknown sentence", f"$GPXXX,1,2*{checksum('GPXXX,1,2')}\r\n".encode(), "unknown"),
]


@pytest.mark.parametrize("what, data, counter", NMEA_CASES, ids=[c[0] for c in NMEA_CASES])
def test_bad_nmea_is_dropped_and_counted(what, data, counter):
    dec = NmeaStreamDecoder()
    assert dec.feed(data) == [] or all(u.heading_deg is None for u in dec.feed(b""))
    stats = dec.stats.as_dict()
    assert stats["lines_ok"] == 0
    if counter:
        assert stats[counter] == 1


MBED_CASES = [
    ("wrong checksum", b"$MBACK,12,OK,F,10.0,F,10.0*00\r\n", "checksum 00 != 41"),
    ("no checksum", b"$MBACK,12,OK,F,10.0,F,10.0\r\n", "no '*hh' checksum"),
    ("not a protocol line", b"garbage\r\n", "does not start with '$'"),
    ("our own command echoed back", b"$MBCMD,1,F,1.0,F,1.0*41\r\n", "checksum 41 != 58"),
]


@pytest.mark.parametrize("what, line, message", MBED_CASES, ids=[c[0] for c in MBED_CASES])
def test_bad_mbed_reply_is_a_protocol_error_counted_by_the_driver(what, line, message):
    with pytest.raises(ProtocolError) as exc:
        decode_ack(line)
    assert str(exc.value) == message


def test_the_document_has_every_case_as_tested():
    """A case added without regenerating docs/bad-inputs.md (and so the README's table) went unnoticed:
    each case's row, built from the message the test above requires, must be in the document."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "bad-inputs.md").read_text(encoding="utf-8")
    for edge, what, _, _, _, expected in CLI_CASES:
        shown = " ".join(expected.replace("{dir}", "DIR").replace("|", "\\|").split())
        assert f"| {edge} | {what} | `{shown}` (exit 2) |" in doc.splitlines(), (
            f"{what}: not in docs/bad-inputs.md as tested; regenerate it: python tests/test_daemon_bad_inputs.py")


def render() -> str:
    """docs/bad-inputs.md, from the cases above (run in a temporary directory shown as DIR)."""
    import tempfile

    out = [
        "# Bad inputs and what `autopilot run` says",
        "",
        "Every row is a test case (tests/test_daemon_bad_inputs.py), so the messages below are exact.",
        "Start-up refusals exit with code 2 and print one message on stderr, before any serial port",
        "is opened and before any thruster is touched. `DIR` stands for the directory of the files.",
        "",
        "| edge | input | message (stderr) |",
        "|---|---|---|",
    ]
    for edge, what, config, mission, extra, _ in CLI_CASES:
        with tempfile.TemporaryDirectory() as tmp:
            code, msg = _run_cli(Path(tmp), config, mission, extra)
            msg = msg.replace(tmp, "DIR")
        shown = " ".join(msg.replace("|", "\\|").split())
        out.append(f"| {edge} | {what} | `{shown}` (exit {code}) |")
    out += [
        "",
        "While running, bad bytes never stop the daemon. NMEA lines that fail are dropped and counted",
        "(`nmea_dropped` in every cycle line). More than `failsafe.nmea_garbage_lines` (5) rejected lines, or",
        "more than `failsafe.garbage_bytes` (32) bytes that no NMEA line can hold, within 1 s is the",
        "`nmea_garbage` fault (likewise `mbed_garbage` on the Mbed line): zero thrust while garbage arrives",
        "and `failsafe.garbage_hold_s` after it, then until the data are valid for `failsafe.resume_valid_s`.",
        "",
        "| edge | input | result |",
        "|---|---|---|",
    ]
    for what, data, counter in NMEA_CASES:
        dec = NmeaStreamDecoder()
        dec.feed(data)
        st = {k: v for k, v in dec.stats.as_dict().items() if v}
        out.append(f"| NMEA | {what} | dropped; decoder counters {st} |")
    for what, line, message in MBED_CASES:
        out.append(f"| Mbed reply | {what} | dropped, counted in `bad_lines` (`ProtocolError: {message}`); "
                   "the command it should have acknowledged counts as missing after `serial.ack_timeout_s` |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.stdout.write(render())


@pytest.mark.parametrize("heading", ["400", "-10", "inf", "nan"])
def test_ctl_hold_heading_outside_0_360_is_refused_before_asking_the_daemon(tmp_path, heading):
    """400 was taken modulo 360 and held 40 deg; inf reached the daemon as nan."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["ctl", "hold", "--heading", heading, "--runtime-dir", str(tmp_path)])
    assert code == 2
    assert err.getvalue().strip() == f"autopilot ctl: error: --heading: {float(heading):g} is outside the allowed range [0, 360) deg"


def test_a_ctrl_c_while_the_commands_load_is_no_traceback(monkeypatch):
    """Building the parser imports every area (~0.5 s): a Ctrl-C then escaped main() as a traceback."""
    import autopilot.cli as cli

    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert cli.main(["files"]) == 130
    assert err.getvalue() == "autopilot: interrupted\n"


def test_a_local_mission_without_an_origin_is_flown_in_sim_with_a_note_of_what_the_boat_will_say(tmp_path):
    """Found by a new-user audit: systemd/INSTALL.md's --sim check passed with the shipped configuration (no origin)
    and a pond mission, then the boat refused the same pair at every start. The --sim run now says so first."""
    code, message = _run_cli(tmp_path, "sim: {vessel: /nonexistent/vessel.yaml}\n", GOOD_MISSION, ["--sim"])
    assert code == 2  # refused afterwards, for the vessel file: the note came before
    note, error = message.splitlines()
    assert note.startswith(f"note: {tmp_path}/m.yaml is in metres from an origin neither it nor the configuration "
                           "gives: flown from sim.origin (") and "without --sim it is refused" in note
    assert error.startswith("autopilot run: error: ") and "vessel" in error
