"""The MAVLink link through real UDP sockets on loopback, pymavlink as the ground station (issue 16).

`autopilot run --sim --mavlink udpout:127.0.0.1:PORT` in a subprocess, as a bench user runs it; this
process is the ground station (pymavlink's mavutil, as QGroundControl's and Mission Planner's
scripts use it) listening on PORT. What the boat does is read back from its own mission log.
"""

from __future__ import annotations

import json
import math
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.geo import local_to_latlon
from autopilot.link import telemetry as T

from .logtail import LogTail

ROOT = Path(__file__).resolve().parents[1]
ORIGIN = (52.0, 4.4)
SPEEDUP = 8.0  # the daemon's --sim speedup (4 until 2026-12-06: the link tests took ~25 s more of the suite's 10 minutes)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Boat:
    """A daemon under --sim with a MAVLink endpoint, and a ground station talking to it."""

    def __init__(self, tmp: Path, *, mission: dict | None = None, config: dict | None = None,
                 fresh: bool = True, speedup: float = SPEEDUP, extra_args: tuple[str, ...] = ()) -> None:
        # no key here: mavutil's link starts in MAVLink 1 and turns 2 at the boat's first frame, and a key set
        # before that signed nothing (sign_with after the first HEARTBEAT)
        self.tmp, self.port = tmp, _free_udp_port()
        cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
        cfg["sim"]["origin_lat_deg"], cfg["sim"]["origin_lon_deg"] = ORIGIN
        cfg["failsafe"]["position_confirm_s"] = 1.0  # the link's tests start as before the shipped 5 s (suite time)
        for k, v in (config or {}).items():
            if isinstance(v, dict):
                for k2, v2 in v.items():
                    if isinstance(v2, dict):
                        cfg[k][k2].update(v2)
                    else:
                        cfg[k][k2] = v2
            else:
                cfg[k] = v
        (tmp / "autopilot.yaml").write_text(yaml.safe_dump(cfg))
        mission = mission or {"name": "square", "frame": "local", "waypoints": [
            [30.0, 0.0], [30.0, 30.0], [0.0, 30.0], [0.0, 0.0]] * 3}
        (tmp / "mission.yaml").write_text(yaml.safe_dump(mission))
        self.gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=255, source_component=190)
        args = [sys.executable, "-m", "autopilot", "run", "--sim", "--speedup", str(speedup), "--config",
                str(tmp / "autopilot.yaml"), "--mission", str(tmp / "mission.yaml"), "--log-dir", str(tmp / "logs"),
                "--state-dir", str(tmp / "state"), "--runtime-dir", str(tmp / "run"),
                "--mavlink", f"udpout:127.0.0.1:{self.port}", *extra_args]
        if fresh:
            args.append("--fresh")
        self.err = open(tmp / "stderr.txt", "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(args, cwd=tmp, stdout=subprocess.DEVNULL, stderr=self.err)
        self.last_hb = 0.0
        self._log = LogTail(tmp / "logs")

    def sign_with(self, key: bytes | None) -> None:
        if key is None:
            self.gcs.mav.signing.secret_key = None
            self.gcs.mav.signing.sign_outgoing = False
            return
        self.gcs.setup_signing(key, sign_outgoing=True)

    def beat(self) -> None:
        """The ground station's heartbeat, once a second at most."""
        if time.monotonic() - self.last_hb >= 0.5:
            self.gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            self.last_hb = time.monotonic()

    def recv(self, types, timeout_s: float = 10.0, pred=lambda m: True):
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            self.beat()
            m = self.gcs.recv_match(type=types, blocking=True, timeout=0.2)
            if m is not None and pred(m):
                return m
            if self.proc.poll() is not None:
                raise AssertionError(f"daemon exited {self.proc.returncode}: {self.stderr()[-1500:]}")
        raise AssertionError(f"no {types} within {timeout_s} s")

    def wait_log(self, pred, timeout_s: float = 20.0, what: str = "", *, after: int = 0):
        """The first log line from line ``after`` on that satisfies ``pred``."""
        t_end = time.monotonic() + timeout_s
        while time.monotonic() < t_end:
            self.beat()
            self.gcs.recv_match(blocking=False)
            for r in self.log()[after:]:
                if pred(r):
                    return r
            time.sleep(0.05)
        raise AssertionError(f"log: no {what} within {timeout_s} s")

    def log(self) -> list[dict]:
        """Complete lines of the current daemon's log (tests.logtail: read as it grows)."""
        return self._log.lines(self.proc.pid)

    def cycles(self) -> list[dict]:
        return [r for r in self.log() if r["event"] == "cycle"]

    def drain(self) -> None:
        """Read what has arrived, as a planner does all the time: a test that slept let the ground station's UDP
        receive buffer fill with telemetry, and the kernel dropped the COMMAND_ACK that came next (seen under
        load: no ACK within 10 s for a command the daemon had accepted and acknowledged)."""
        while self.gcs.recv_match(blocking=False) is not None:
            pass

    def command(self, cmd: int, *params, use_int: bool = False, x: int = 0, y: int = 0):
        self.drain()
        p = list(params) + [0.0] * (7 - len(params))
        if use_int:
            self.gcs.mav.command_int_send(1, 1, mavlink.MAV_FRAME_GLOBAL, cmd, 0, 0, *p[:4], x, y, 0.0)
        else:
            self.gcs.mav.command_long_send(1, 1, cmd, 0, *p)
        return self.recv("COMMAND_ACK", pred=lambda m: m.command == cmd)

    def mode_is(self, mode: str, timeout_s: float = 10.0) -> None:
        """The mode of the latest cycle becomes ``mode``."""
        self.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == mode, timeout_s, f"mode {mode}",
                      after=max(0, len(self.log()) - 3))

    def stderr(self) -> str:
        self.err.flush()
        return (self.tmp / "stderr.txt").read_text()

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(2)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.err.close()
        self.gcs.close()
        return self.proc.returncode


def test_the_boat_appears_and_its_position_follows_the_simulated_track(tmp_path):
    boat = Boat(tmp_path)
    try:
        hb = boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1)
        assert (hb.type, hb.autopilot) == (mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA)
        boat.mode_is("auto")
        seen, positions = set(), []
        t_end = time.monotonic() + 4.0
        while time.monotonic() < t_end:
            boat.beat()
            m = boat.gcs.recv_match(blocking=True, timeout=0.2)
            if m is None:
                continue
            seen.add(m.get_type())
            if m.get_type() == "GLOBAL_POSITION_INT":
                positions.append((m.lat, m.lon))
        assert {"HEARTBEAT", "SYS_STATUS", "GLOBAL_POSITION_INT", "ATTITUDE", "GPS_RAW_INT", "VFR_HUD",
                "NAV_CONTROLLER_OUTPUT", "MISSION_CURRENT"} <= seen
        hb = boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1)
        assert hb.custom_mode == 10 and hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED  # AUTO, armed
        version = boat.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert version.result == mavlink.MAV_RESULT_ACCEPTED
        av = boat.recv("AUTOPILOT_VERSION")
        assert av.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    finally:
        assert boat.stop() == 0
    fixes = {(round(r["lat_deg"] * 1e7), round(r["lon_deg"] * 1e7)) for r in boat.cycles() if r["lat_deg"] is not None}
    assert len(positions) > 15 and len(set(positions)) > 3  # it moves
    missing = [p for p in positions if p not in fixes]
    assert not missing, (missing[:5], sorted(fixes)[:5])  # every position sent is a fix the daemon logged


def test_each_command_is_acknowledged_and_obeyed(tmp_path):
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        ack = boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 5)  # Rover LOITER: hold here
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("hold")
        assert boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1 and m.custom_mode == 5)
        # continue goes on only with what a pause stopped (ArduPilot): pressed in a hold it drove the boat into the
        # mission (a GCS audit)
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 1).result == mavlink.MAV_RESULT_DENIED
        assert boat.recv("STATUSTEXT", pred=lambda m: m.text.startswith("continue refused: mode hold is not paused"))
        boat.mode_is("hold")
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 10).result == mavlink.MAV_RESULT_ACCEPTED  # AUTO
        boat.mode_is("auto")
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 0).result == mavlink.MAV_RESULT_ACCEPTED  # pause
        boat.mode_is("paused")
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 1).result == mavlink.MAV_RESULT_ACCEPTED  # continue
        boat.mode_is("auto")
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("paused")
        before = len(boat.log())
        assert boat.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == mavlink.MAV_RESULT_ACCEPTED
        # a boat still within reach of its launch point holds at once (rtl and hold in one cycle, no cycle
        # line in rtl: a clean-clone run paused 0.5 m from it): the mode events say rtl was taken
        boat.wait_log(lambda r: r["event"] == "mode" and r["mode"] == "rtl" and r["cause"] == "mavlink rtl",
                      what="mode rtl", after=before)
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4).result == mavlink.MAV_RESULT_ACCEPTED  # HOLD: stop
        boat.mode_is("stop")
        lat, lon = local_to_latlon(12.0, -6.0, *ORIGIN)
        before = len(boat.log())
        ack = boat.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, use_int=True, x=round(lat * 1e7),
                           y=round(lon * 1e7))
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        held = boat.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "hold" and r["hold_north_m"] is not None,
                             what="hold at the reposition point", after=before)
        assert math.hypot(held["hold_north_m"] - 12.0, held["hold_east_m"] + 6.0) < 0.05
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "arming" and r["armed"] is False, what="disarmed")
        hb = boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1 and not m.base_mode & 128)
        assert hb.system_status == mavlink.MAV_STATE_STANDBY
        time.sleep(1.0)
        late = [r for r in boat.cycles() if not r["armed"]][-5:]
        assert late and all(r["thrust_port_n"] == 0.0 == r["thrust_stbd_n"] for r in late)
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "arming" and r["armed"] is True, what="armed")
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 3).result == mavlink.MAV_RESULT_DENIED  # STEERING
        text = boat.recv("STATUSTEXT", pred=lambda m: "not supported" in m.text)
        assert "mode 3 (STEERING) not supported" in text.text
        assert boat.command(mavlink.MAV_CMD_DO_SET_SERVO, 1, 1500).result == mavlink.MAV_RESULT_UNSUPPORTED
        assert boat.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("auto")
    finally:
        assert boat.stop() == 0
    modes = [(r["mode"], r["cause"]) for r in boat.log() if r["event"] == "mode"]
    commanded = [m for m, c in modes if c.startswith("mavlink ")]
    assert commanded[:8] == ["hold", "auto", "paused", "auto", "paused", "rtl", "stop", "hold"]
    # the only change of its own: the hold that ends an rtl begun within reach of the launch point
    assert all(c.startswith("mavlink ") or c == "rtl: at the launch point" for _, c in modes), modes


def test_a_manual_session_and_its_timeout(tmp_path):
    """Stick input drives a boat in MANUAL only and never changes the mode, as ArduPilot's (found by a GCS audit:
    a planner streams MANUAL_CONTROL whenever its joystick is on, and the packet after every accepted RTL, AUTO or
    LOITER took the boat back to manual); the ignored packets are said once a second, not 25 times."""
    boat = Boat(tmp_path, config={"mavlink": {"manual_timeout_s": 0.5, "manual_timeout_action": "hold"}})
    try:
        boat.mode_is("auto")
        t_end = time.monotonic() + 2.5
        while time.monotonic() < t_end:  # the joystick on, sticks centred, at 20 Hz
            boat.gcs.mav.manual_control_send(1, 0, 0, 0, 0, 0)
            boat.beat()
            time.sleep(0.05)
        assert not any(r["mode"] == "manual" for r in boat.cycles())
        ignored = [r for r in boat.log() if r["event"] == "command" and r["command"] == "manual"]
        assert 2 <= len(ignored) <= 4 and ignored[0]["answer"] == ("stick input ignored: mode auto (choose MANUAL to "
                                                                   "drive by stick)"), ignored
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 0).result == mavlink.MAV_RESULT_ACCEPTED  # MANUAL
        # a multicopter's pitch and yaw sticks (x, r) do not drive a Rover: they drove this boat, and the Rover's
        # throttle and steering (z, y) did nothing (a GCS audit)
        t_end = time.monotonic() + 1.5
        while time.monotonic() < t_end:
            boat.gcs.mav.manual_control_send(1, 1000, 0, 0, 1000, 0)
            boat.beat()
            time.sleep(0.05)
        still = [r for r in boat.cycles() if r["mode"] == "manual"]
        assert len(still) > 5 and all(r["thrust_port_n"] == r["thrust_stbd_n"] == 0.0 for r in still), still[-1]
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end:  # full ahead, a little to port, at 20 Hz like a joystick
            boat.gcs.mav.manual_control_send(1, 0, -300, 1000, 0, 0)
            boat.beat()
            time.sleep(0.05)
        manual = [r for r in boat.cycles() if r["mode"] == "manual"]
        assert len(manual) > 10
        last = manual[-1]
        assert last["thrust_port_n"] < last["thrust_stbd_n"] and last["thrust_stbd_n"] > 30.0  # turning to port
        # found by a new-user audit: armed in manual with the stick held forward, the boat went to full thrust at once;
        # as ArduPilot's "throttle not zero" check, arming needs the sticks at neutral
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.gcs.mav.manual_control_send(1, 0, -300, 1000, 0, 0)
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_DENIED
        boat.recv("STATUSTEXT", pred=lambda m: m.text.startswith("arm refused: in manual the sticks must be"))
        boat.gcs.mav.manual_control_send(1, 0, 0, 0, 0, 0)
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        t_quiet = time.monotonic()
        held = boat.wait_log(lambda r: r["event"] == "mode" and r["from"] == "manual", what="manual ends")
        assert held["mode"] == "hold" and held["cause"].startswith("manual: no input for")
        assert time.monotonic() - t_quiet < 3.0
    finally:
        assert boat.stop() == 0
    commands = [r for r in boat.log() if r["event"] == "command" and r["command"] == "manual" and r["accepted"]]
    assert len(commands) == 1  # the mode chosen; the stream itself is not logged line by line


def test_with_a_ground_station_the_daemon_stays_up_after_the_mission_s_stop(tmp_path):
    """Found by a new-user audit: with the default final_action stop the daemon ended at the mission's end, the
    ground station lost the boat (no heartbeat, no RTL) and systemd's Restart=on-failure does not restart an exit 0.
    With a link open it stays at zero thrust, reporting and taking commands, until stopped."""
    boat = Boat(tmp_path, mission={"name": "short", "frame": "local", "waypoints": [[8.0, 0.0]]}, speedup=10.0)
    try:
        boat.wait_log(lambda r: r["event"] == "info" and r["message"] == "mission complete: staying up", 60.0,
                      "the mission's end")
        assert boat.proc.poll() is None
        boat.mode_is("complete")
        assert boat.recv("HEARTBEAT").custom_mode == 4  # Rover's HOLD: motors stopped
        assert boat.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("rtl")
    finally:
        assert boat.stop() == 0
    assert boat.log()[-1]["event"] == "stop" and boat.log()[-1]["reason"] == "signal"


def test_with_a_ground_station_the_daemon_stays_up_after_the_mission_time_s_stop(tmp_path):
    """Found by a new-user audit: max_mission_time's stop still ended the daemon, link and all, where the mission's
    own stop no longer does. It now stays up at zero thrust, and the run is saved as ended by its time limit: the
    signal that ends the daemon later (a shutdown) does not make the next start fly the mission again."""
    boat = Boat(tmp_path, config={"failsafe": {"max_mission_time_s": 6.0}}, speedup=10.0)
    try:
        boat.wait_log(lambda r: r["event"] == "info" and r["message"] == "max_mission_time: stopped, staying up",
                      60.0, "the time limit's stop")
        assert boat.proc.poll() is None
        after = len(boat.log())
        assert boat.recv("HEARTBEAT").custom_mode == 4  # Rover's HOLD: motors stopped
        time.sleep(0.5)
        later = [r for r in boat.log()[after:] if r["event"] == "cycle"]
        assert len(later) > 10 and not any(r["thrust_port_n"] or r["thrust_stbd_n"] for r in later)
    finally:
        assert boat.stop() == 0
    assert boat.log()[-1]["event"] == "stop" and boat.log()[-1]["reason"] == "signal"
    progress = json.loads((tmp_path / "state" / "mission-progress.json").read_text())
    assert (progress["status"], progress["reason"]) == ("aborted", "max_mission_time"), progress
    assert "stopped by max_mission_time, then by SIGINT" in (tmp_path / "stderr.txt").read_text()


def test_parameters_read_set_and_a_bad_one_refused(tmp_path):
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        boat.gcs.mav.param_request_list_send(1, 1)
        values = {}
        while not values or len(values) < next(iter(values.values()))[1]:  # the whole list, as a planner loads it
            m = boat.recv("PARAM_VALUE")
            values[m.param_id] = (m.param_value, m.param_count)
        count = next(iter(values.values()))[1]
        assert count >= 30 and values.get("HDG_KP", (1.0,))[0] == pytest.approx(1.0)
        boat.gcs.mav.param_set_send(1, 1, b"HDG_KP", 2.5, mavlink.MAV_PARAM_TYPE_REAL32)
        m = boat.recv("PARAM_VALUE", pred=lambda m: m.param_id == "HDG_KP")
        assert m.param_value == pytest.approx(2.5)
        boat.gcs.mav.param_set_send(1, 1, b"HDG_KP", 50.0, mavlink.MAV_PARAM_TYPE_REAL32)
        m = boat.recv("PARAM_VALUE", pred=lambda m: m.param_id == "HDG_KP")
        assert m.param_value == pytest.approx(2.5)  # refused: unchanged
        text = boat.recv("STATUSTEXT", pred=lambda m: "HDG_KP" in m.text and "refused" not in m.text
                         and "=" not in m.text)
        assert "50.0 is outside the" in text.text and text.id > 0  # the first of its 50-character chunks
        # an INT32 1 sent bytewise: the float field reads 1.4e-45, inside HDG_KP's range (a new-user audit)
        bits = struct.unpack("<f", struct.pack("<i", 1))[0]
        boat.gcs.mav.param_set_send(1, 1, b"HDG_KP", bits, mavlink.MAV_PARAM_TYPE_INT32)
        m = boat.recv("PARAM_VALUE", pred=lambda m: m.param_id == "HDG_KP")
        assert m.param_value == pytest.approx(2.5) and m.param_type == mavlink.MAV_PARAM_TYPE_REAL32  # unchanged
        boat.gcs.mav.param_set_send(1, 1, b"FS_GCS_ACT", 2.0, mavlink.MAV_PARAM_TYPE_REAL32)  # rtl
        assert boat.recv("PARAM_VALUE", pred=lambda m: m.param_id == "FS_GCS_ACT").param_value == 2.0
        boat.gcs.mav.param_request_read_send(1, 1, b"LOIT_RADIUS", -1)
        assert boat.recv("PARAM_VALUE", pred=lambda m: m.param_id == "LOIT_RADIUS").param_value == 0.0
    finally:
        assert boat.stop() == 0
    params = [(r["param"], r["key"], r["old"], r["new"]) for r in boat.log() if r["event"] == "param"]
    assert params == [("HDG_KP", "gnc.pid.kp_n_per_deg", 1.0, 2.5), ("FS_GCS_ACT", "mavlink.gcs_lost_action",
                                                                       "continue", "rtl")]
    refused = [r for r in boat.log() if r["event"] == "command" and not r["accepted"]]
    assert any("HDG_KP" in r["answer"] and "[0, 10]" in r["answer"] for r in refused)
    assert any(r["answer"].startswith("HDG_KP (gnc.pid.kp_n_per_deg): param_type 6 (MAV_PARAM_TYPE_INT32) refused")
               for r in refused), refused


def test_malformed_commands_are_denied_naming_the_parameter_and_other_boats_sticks_are_ignored(tmp_path):
    """Found by fault injection through the link: DO_PAUSE_CONTINUE with param1 NaN or 7 resumed the mission;
    NaN in DO_SET_MISSION_CURRENT or REQUEST_MESSAGE got no answer and (after the first) no trace; a
    MANUAL_CONTROL to system 2 drove this boat (its addressee field is `target`, not `target_system`);
    FS_MAX_TIME set below the time already run ended the daemon, link and all."""
    nan = float("nan")
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("paused")
        for bad in (nan, 7.0, 0.5):
            # the ack and the refusal's STATUSTEXT may come in either order on a loaded machine (CI once saw the
            # 0.5's text first: the nan's had come before its ack, and boat.command drops what is not the ack)
            boat.gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 0, bad, 0, 0, 0, 0, 0, 0)
            got = {}
            while len(got) < 2:
                m = boat.recv(["COMMAND_ACK", "STATUSTEXT"], pred=lambda m: "DO_PAUSE_CONTINUE" in m.text
                              if m.get_type() == "STATUSTEXT" else m.command == mavlink.MAV_CMD_DO_PAUSE_CONTINUE)
                got.setdefault(m.get_type(), m)
            assert got["COMMAND_ACK"].result == mavlink.MAV_RESULT_DENIED
            # the first 50-character chunk names the parameter and its value
            assert got["STATUSTEXT"].text.startswith(f"DO_PAUSE_CONTINUE refused: param1 {bad:g}"), got["STATUSTEXT"].text
        for cmd, params in ((mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (0.5,)), (mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, (nan,)),
                            (mavlink.MAV_CMD_REQUEST_MESSAGE, (nan,)), (mavlink.MAV_CMD_DO_SET_MODE, (1, 4.7)),
                            (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (33, nan)),
                            (mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, (mavlink.MAVLINK_MSG_ID_HEARTBEAT, -1))):
            assert boat.command(cmd, *params).result == mavlink.MAV_RESULT_DENIED, cmd
        boat.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 2.5)  # refused, and said once (each refusal was said twice)
        said, t_end = [], time.monotonic() + 1.5
        while time.monotonic() < t_end:
            m = boat.gcs.recv_match(type="STATUSTEXT", blocking=True, timeout=0.1)
            if m is not None and m.text.startswith("SET_MESSAGE_INTERVAL refused: param1 (message id)"):
                said.append(m)
        assert len(said) == 1  # its first 50-character chunk
        t_end = time.monotonic() + 1.5
        while time.monotonic() < t_end:  # another boat's joystick, full ahead
            boat.gcs.mav.manual_control_send(2, 0, 0, 1000, 0, 0)
            boat.beat()
            time.sleep(0.05)
        boat.gcs.mav.param_set_send(1, 1, b"FS_MAX_TIME", 1.0, mavlink.MAV_PARAM_TYPE_REAL32)
        text = boat.recv("STATUSTEXT", pred=lambda m: "FS_MAX_TIME" in m.text)
        assert "refused: 1 s is not more than the" in text.text
        time.sleep(0.5)
        assert boat.proc.poll() is None  # still running
    finally:
        assert boat.stop() == 0
    cycles = boat.cycles()
    assert not any(r["mode"] == "manual" for r in cycles) and cycles[-1]["mode"] == "paused"
    refused = [r["answer"] for r in boat.log() if r["event"] == "command" and not r["accepted"]]
    assert sum("DO_PAUSE_CONTINUE refused" in a for a in refused) == 3
    assert "DO_PAUSE_CONTINUE refused: param1 7 is not 0 (pause) or 1 (continue)" in refused
    assert "SET_MESSAGE_INTERVAL refused: HEARTBEAT off (-1) is below rates.heartbeat_hz's minimum 0.2 Hz" in refused
    for what in ("COMPONENT_ARM_DISARM", "DO_SET_MISSION_CURRENT", "REQUEST_MESSAGE", "DO_SET_MODE",
                 "SET_MESSAGE_INTERVAL", "FS_MAX_TIME"):
        assert any(what in a for a in refused), (what, refused)
    assert not [r for r in boat.log() if r["event"] == "info" and r.get("message") == "mavlink message not handled"]


def test_a_flood_of_valid_commands_waits_or_is_refused_and_the_loop_carries_out_five_a_cycle(tmp_path):
    """Found by fault injection: 5000 valid DO_SET_MISSION_CURRENT a second were all carried out inside the
    cycles (each saving the progress file): cycles ran 80-100 ms late, deadlines were skipped and the log grew
    0.5 MB/s."""
    from autopilot.daemon.loop import COMMANDS_PER_CYCLE

    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        for _ in range(1500):  # a burst, faster than 5 a cycle can carry out
            boat.gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 0, 1, 0, 0, 0, 0, 0, 0)
        boat.wait_log(lambda r: r["event"] == "info" and r.get("message") == "commands refused: queue full",
                      what="the flood refused")
        # "busy, retry later", not DENIED (a planner takes that as final): found by a GCS audit
        busy = boat.recv("COMMAND_ACK", pred=lambda m: m.result == mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
        assert busy.command == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT
        time.sleep(3.0)  # the queue drains at 5 a cycle
        assert boat.command(mavlink.MAV_CMD_DO_PAUSE_CONTINUE, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("paused")
    finally:
        assert boat.stop() == 0
    log = boat.log()
    per_cycle: dict = {}
    for r in log:
        if r["event"] == "command" and r["command"] == "set_current":
            per_cycle[r["t_s"]] = per_cycle.get(r["t_s"], 0) + 1
    assert max(per_cycle.values()) == COMMANDS_PER_CYCLE and sum(per_cycle.values()) < 1500
    assert sum(1 for r in log if r["event"] == "info" and r.get("message") == "commands refused: queue full") == 1


def test_link_loss_takes_its_action(tmp_path):
    """Found by review: any heartbeat of type GCS counted, so a second planner on the same network (system id
    254 here) kept the link alive after the operator's station (gcs_system_id 255) went quiet."""
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    boat = Boat(tmp_path, config={"mavlink": {"gcs_timeout_s": 1.5, "gcs_lost_action": "hold"}})
    other = dialect.MAVLink(boat.gcs, srcSystem=254, srcComponent=190)
    try:
        boat.mode_is("auto", 20.0)
        boat.recv("HEARTBEAT")  # the ground station now knows the boat's address (UDP: it learns it from what it receives)
        # and beats for a second more, so that the boat has seen it (beats sent before the ground station knew the
        # address went nowhere: when the boat reached auto quickly, it had never seen one and had nothing to lose)
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            boat.beat()
            boat.gcs.recv_match(blocking=True, timeout=0.05)
        t_silent = time.monotonic()
        boat.last_hb = math.inf  # the ground station goes quiet; the other planner beats on
        lost = None
        while lost is None and time.monotonic() - t_silent < 20.0:
            other.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            boat.gcs.recv_match(blocking=True, timeout=0.2)
            lost = next((r for r in boat.log() if r["event"] == "gcs" and r["state"] == "lost"), None)
        assert lost is not None, "link never lost"
        assert lost["action"] == "hold" and lost["silent_s"] >= 1.5
        assert time.monotonic() - t_silent < 4.0
        boat.mode_is("hold")
        boat.last_hb = 0.0  # it comes back
        boat.wait_log(lambda r: r["event"] == "gcs" and r["state"] == "back", what="link back")
    finally:
        assert boat.stop() == 0
    causes = [r["cause"] for r in boat.log() if r["event"] == "mode"]
    assert "mavlink: ground station lost" in causes


def _upload(boat: Boat, items: list[tuple]) -> int:
    """The mission protocol as a ground station drives it; the MISSION_ACK type."""
    boat.gcs.mav.mission_count_send(1, 1, len(items))
    while True:
        m = boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
        if m.get_type() == "MISSION_ACK":
            return m.type
        cmd, frame, p1, lat, lon = items[m.seq]
        boat.gcs.mav.mission_item_int_send(1, 1, m.seq, frame, cmd, 0, 1, p1, 0, 0, 0, round(lat * 1e7),
                                           round(lon * 1e7), 0)


def test_a_second_ground_station_cannot_upload_into_another_ones_upload(tmp_path):
    """Found by fault injection: station A began an upload, station B sent MISSION_COUNT, A's items then
    filled B's upload and B got MISSION_ACK ACCEPTED for a mission it never sent (uploads were keyed by
    endpoint and items never checked their sender). Now B is refused while A uploads, and items from a
    station that is not uploading are ignored. Found by a link audit: QGC and Mission Planner are both
    system 255, component 190, so a second planner on another endpoint (C) was not seen as another: both
    uploads were acknowledged ACCEPTED and the first mission silently replaced."""
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    a_items = [local_to_latlon(n, e, *ORIGIN) for n, e in ((0.0, 0.0), (-15.0, 10.0), (-25.0, 0.0))]
    port_c = _free_udp_port()
    boat = Boat(tmp_path, extra_args=("--mavlink", f"udpout:127.0.0.1:{port_c}"))
    b = dialect.MAVLink(boat.gcs, srcSystem=254, srcComponent=190)  # another planner on the same radio link
    c = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port_c}", source_system=255, source_component=190)
    try:
        boat.mode_is("auto")
        assert c.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None  # C hears the boat

        def a_item(seq):
            lat, lon = a_items[seq]
            boat.gcs.mav.mission_item_int_send(1, 1, seq, 3 if seq else 0, 16, 0, 1, 0, 0, 0, 0, round(lat * 1e7),
                                               round(lon * 1e7), 0)

        boat.gcs.mav.mission_count_send(1, 1, 3)
        for seq in range(2):
            boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST"], pred=lambda m, s=seq: m.seq == s and m.target_system == 255)
            a_item(seq)
        b.mission_count_send(1, 1, 3)
        ack_b = boat.recv("MISSION_ACK", pred=lambda m: m.target_system == 254)
        assert ack_b.type == mavlink.MAV_MISSION_DENIED
        c.mav.mission_count_send(1, 1, 2)
        ack_c = c.recv_match(type="MISSION_ACK", blocking=True, timeout=10)
        assert ack_c is not None and ack_c.type == mavlink.MAV_MISSION_DENIED
        lat, lon = local_to_latlon(80.0, 80.0, *ORIGIN)
        b.mission_item_int_send(1, 1, 2, 3, 16, 0, 1, 0, 0, 0, 0, round(lat * 1e7), round(lon * 1e7), 0)  # ignored
        boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST"], pred=lambda m: m.seq == 2 and m.target_system == 255)
        a_item(2)
        ack_a = boat.recv("MISSION_ACK", pred=lambda m: m.target_system == 255)
        assert ack_a.type == mavlink.MAV_MISSION_ACCEPTED
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="mission replaced")
        # found by a new-user audit: A's own MISSION_ACK cancelling its upload was ignored; the boat went on asking
        # A for 9 s and refused C meanwhile. A cancels: C's upload is asked for at once
        boat.gcs.mav.mission_count_send(1, 1, 3)
        boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST"], pred=lambda m: m.seq == 0 and m.target_system == 255)
        boat.gcs.mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_OPERATION_CANCELLED)
        boat.wait_log(lambda r: r["event"] == "command" and "cancelled by the ground station" in str(r.get("answer")),
                      what="the cancel")
        c.mav.mission_count_send(1, 1, 2)
        asked = c.recv_match(type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=10)
        assert asked is not None and asked.get_type() == "MISSION_REQUEST_INT" and asked.seq == 0
        c.mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_OPERATION_CANCELLED)
    finally:
        c.close()
        assert boat.stop() == 0
    assert [[round(x, 1) for x in w] for w in replaced["waypoints"]] == [[-15.0, 10.0], [-25.0, 0.0]]


def test_a_go_here_across_a_concave_geofence_is_refused_and_one_along_it_taken(tmp_path):
    """Found by a new-user audit: a "go here" point was checked, not the way to it. Inside an L-shaped fence, a
    point in the other arm lay across the corner: the boat left the fence on its way and the fence's rtl took it."""
    fence = [[-10.0, -10.0], [60.0, -10.0], [60.0, 10.0], [10.0, 10.0], [10.0, 60.0], [-10.0, 60.0]]  # north, east
    boat = Boat(tmp_path, mission={"name": "up", "frame": "local", "waypoints": [[50.0, 0.0], [0.0, 0.0]]},
                config={"geofence": {"frame": "local", "polygon": fence}}, speedup=10.0)
    try:
        boat.wait_log(lambda r: r["event"] == "cycle" and (r["north_m"] or 0.0) > 20.0, 60.0, "up the north arm")
        across = local_to_latlon(-5.0, 40.0, *ORIGIN)  # inside, in the east arm: the straight way cuts the corner
        ack = boat.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, use_int=True, x=round(across[0] * 1e7),
                           y=round(across[1] * 1e7))
        assert ack.result == mavlink.MAV_RESULT_DENIED
        along = local_to_latlon(40.0, 0.0, *ORIGIN)  # up the same arm
        ack = boat.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, use_int=True, x=round(along[0] * 1e7),
                           y=round(along[1] * 1e7))
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("hold")
    finally:
        assert boat.stop() == 0
    refused = [r["answer"] for r in boat.log() if r["event"] == "command" and not r["accepted"]]
    assert any(a.startswith("go here refused: the leg from the boat to the point leaves the geofence") for a in refused), \
        refused
    assert not [r for r in boat.log() if r["event"] == "fault"]


def test_a_mission_or_a_reposition_beyond_a_failsafe_limit_is_refused_up_front(tmp_path):
    """Found by fault injection: a 'go here' 300 m out with max_distance_m 100 was accepted; the boat set off
    and its own failsafe turned it back at 101 m (latched: the mission lost). Now refused, saying why."""
    boat = Boat(tmp_path, config={"failsafe": {"max_distance_m": 100.0}})
    try:
        boat.mode_is("auto")
        far = local_to_latlon(300.0, 0.0, *ORIGIN)
        ack = boat.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, use_int=True, x=round(far[0] * 1e7),
                           y=round(far[1] * 1e7))
        assert ack.result == mavlink.MAV_RESULT_DENIED
        near = local_to_latlon(20.0, 0.0, *ORIGIN)
        items = [(16, 0, 0, *ORIGIN), (16, 3, 0, *near), (16, 3, 0, *far)]
        assert _upload(boat, items) == mavlink.MAV_MISSION_DENIED
        text = boat.recv("STATUSTEXT", pred=lambda m: m.text.startswith("mission refused"))
        assert "waypoint 2" in text.text
        boat.mode_is("auto")
    finally:
        assert boat.stop() == 0
    refused = [r["answer"] for r in boat.log() if r["event"] == "command" and not r["accepted"]]
    assert any(a.startswith("go here refused: the point is beyond the max_distance failsafe: 300.0 m") for a in refused)
    assert any(a.startswith("mission refused: waypoint 2 is beyond the max_distance failsafe") for a in refused)
    assert not [r for r in boat.log() if r["event"] == "fault"]


def test_an_upload_whose_leg_leaves_a_concave_geofence_is_refused(tmp_path):
    """Found by a new-user audit: an upload of (50, 0) and (0, 50), both inside an L-shaped fence, was accepted; the
    straight leg between them left the fence, and the boat's geofence failsafe turned it back 60 s later (rtl,
    the mission lost). The legs are checked as the waypoints are."""
    fence = [[-5, -5], [60, -5], [60, 10], [10, 10], [10, 60], [-5, 60]]
    boat = Boat(tmp_path, config={"geofence": {"frame": "local", "polygon": fence}},
                mission={"name": "in-the-l", "frame": "local", "waypoints": [[40.0, 0.0], [5.0, 0.0]] * 2})
    try:
        boat.recv("HEARTBEAT")
        across = [(16, 0, 0, *ORIGIN)] + [(16, 3, 0, *local_to_latlon(n, e, *ORIGIN)) for n, e in ((50.0, 0.0), (0.0, 50.0))]
        assert _upload(boat, across) == mavlink.MAV_MISSION_DENIED
        text = boat.recv("STATUSTEXT", pred=lambda m: m.text.startswith("mission refused"))
        assert text.text.startswith("mission refused: the leg from waypoint 1 to waypoi")  # a 50-character chunk
        round_the_corner = [(16, 0, 0, *ORIGIN)] + [(16, 3, 0, *local_to_latlon(n, e, *ORIGIN))
                                                   for n, e in ((50.0, 0.0), (5.0, 0.0), (0.0, 50.0))]
        assert _upload(boat, round_the_corner) == mavlink.MAV_MISSION_ACCEPTED
    finally:
        assert boat.stop() == 0


def test_a_mission_uploaded_mid_run_is_flown_saved_and_continued_after_a_restart(tmp_path):
    new_ne = [(-15.0, 10.0), (-25.0, 0.0)]
    new = [local_to_latlon(n, e, *ORIGIN) for n, e in new_ne]
    items = [(16, 0, 0, *ORIGIN), (16, 3, 0, *new[0]), (19, 3, 5.0, *new[1])]
    boat = Boat(tmp_path, config={"failsafe": {"resume_after_restart": True}})
    try:
        boat.mode_is("auto")
        bad = [(16, 0, 0, *ORIGIN), (16, 3, 0, 95.0, 4.4)]
        assert _upload(boat, bad) == mavlink.MAV_MISSION_INVALID_PARAM5_X
        assert "latitude 95" in boat.recv("STATUSTEXT", pred=lambda m: "item 1" in m.text).text
        assert _upload(boat, [(16, 0, 0, *ORIGIN), (183, 2, 0, 0.0, 0.0)]) == mavlink.MAV_MISSION_UNSUPPORTED
        assert _upload(boat, items) == mavlink.MAV_MISSION_ACCEPTED
        replaced = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="mission replaced")
        assert [[round(a, 2) for a in w] for w in replaced["waypoints"]] == [list(w) for w in new_ne]
        boat.wait_log(lambda r: r["event"] == "waypoint_reached" and r["t_s"] > replaced["t_s"] and r["wp_index"] == 0,
                      60.0, "the new mission's first waypoint")
        boat.gcs.mav.mission_request_list_send(1, 1)
        count = boat.recv("MISSION_COUNT").count
        assert count == 3
        got = []
        for k in range(count):
            boat.gcs.mav.mission_request_int_send(1, 1, k)
            got.append(boat.recv("MISSION_ITEM_INT", pred=lambda m, k=k: m.seq == k))
        assert [(m.command, round(m.x / 1e7, 6), round(m.y / 1e7, 6)) for m in got[1:]] == [
            (16, round(new[0][0], 6), round(new[0][1], 6)), (19, round(new[1][0], 6), round(new[1][1], 6))]
        assert got[2].param1 == 5.0
    finally:
        assert boat.stop() == 0
    saved = tmp_path / "state" / "uploaded-mission.waypoints"
    assert saved.exists() and replaced["path"] == str(saved)
    progress = json.loads((tmp_path / "state" / "mission-progress.json").read_text())
    assert progress["mission"] == str(saved)
    # a restart (systemd's, no --fresh) continues the uploaded mission, not the configured file
    again = Boat(tmp_path, config={"failsafe": {"resume_after_restart": True}}, fresh=False)
    try:
        start = again.wait_log(lambda r: r["event"] == "mission_start", what="start")
        assert start["mission"] == str(saved) and len(start["waypoints"]) == 2
        assert "continuing the mission uploaded over MAVLink" in again.stderr()
        again.recv("HEARTBEAT")  # the ground station learns where the boat is
        # stop 48's note: home alone (every waypoint deleted, as QGC uploads to an ArduPilot vehicle) was refused
        # "no waypoints"; it is a clear
        # ... but one item of another kind (a waypoint sent the PX4 way, in a relative frame) is still refused
        assert _upload(again, [(16, 6, 0, *ORIGIN)]) == mavlink.MAV_MISSION_INVALID
        assert _upload(again, [(16, 0, 0, *ORIGIN)]) == mavlink.MAV_MISSION_ACCEPTED
        again.wait_log(lambda r: r["event"] == "mission_replaced" and r["waypoints"] == [], what="cleared")
        assert json.loads((tmp_path / "state" / "mission-progress.json").read_text())["status"] == "cleared"
        again.gcs.mav.mission_count_send(1, 1, 0)  # an empty mission: MAVLink's other way to clear it (was "no space")
        assert again.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
        again.gcs.mav.mission_clear_all_send(1, 1)
        assert again.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
        assert json.loads((tmp_path / "state" / "mission-progress.json").read_text())["status"] == "cleared"
        again.proc.kill()  # a crash after the clear: no clean stop
        again.proc.wait(10)
    finally:
        again.stop()
    # found by a new-user audit: the restart flew the configured mission from its first waypoint under thrust,
    # though the ground station had cleared the mission; the operator's "no mission" stands: zero thrust, said why
    third = Boat(tmp_path, config={"failsafe": {"resume_after_restart": True}}, fresh=False)
    try:
        third.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "stop", 30.0, "held at the restart")
        _count(third, 1.0)  # the ground station with it for 1 s
        assert [r for r in third.cycles() if r["thrust_port_n"] or r["thrust_stbd_n"]] == []
        assert {r["mode"] for r in third.cycles()} <= {"waiting", "stop"}
        assert "cleared from the ground station (MISSION_CLEAR_ALL)" in third.stderr()
    finally:
        assert third.stop() == 0


def test_a_disarmed_boat_stays_disarmed_after_a_crash_and_restart(tmp_path):
    """Found by a link audit: a boat disarmed from the ground station, killed (kill -9) and restarted by systemd
    (no --fresh, resume_after_restart) came back armed and flew the mission under thrust: the disarm was not
    in the saved progress. Now it is: zero thrust whatever the mode until armed, said at the start."""
    cfg = {"failsafe": {"resume_after_restart": True}}
    boat = Boat(tmp_path, config=cfg)
    try:
        boat.mode_is("auto", 30.0)
        assert boat.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "cycle" and r["armed"] is False, what="disarmed")
        progress = json.loads((tmp_path / "state" / "mission-progress.json").read_text())
        assert progress["armed"] is False and progress["status"] == "running"
        boat.proc.kill()  # a crash: no clean stop
        boat.proc.wait(10)
    finally:
        boat.stop()
    again = Boat(tmp_path, config=cfg, fresh=False)
    try:
        again.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "auto", 30.0, "auto after the restart")
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:
            again.beat()
            again.gcs.recv_match(blocking=True, timeout=0.05)
        driven = [r for r in again.cycles() if r["thrust_port_n"] or r["thrust_stbd_n"]]
        assert driven == [] and all(r["armed"] is False for r in again.cycles())
        assert "disarmed when the last run ended" in again.stderr()
        assert again.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == mavlink.MAV_RESULT_ACCEPTED
        again.wait_log(lambda r: r["event"] == "cycle" and (r["thrust_port_n"] or r["thrust_stbd_n"]), 20.0,
                       "thrust once armed")
    finally:
        assert again.stop() == 0


def test_with_signing_unsigned_and_wrongly_signed_commands_are_refused_telemetry_flows(tmp_path):
    key = bytes(range(32))
    key_file = tmp_path / "mavlink.key"
    key_file.write_text(key.hex() + "\n")
    key_file.chmod(0o644)
    cfg = {"mavlink": {"signing_key_file": str(key_file)}}
    (tmp_path / "bad").mkdir()
    refused = Boat(tmp_path / "bad", config=cfg)
    assert refused.proc.wait(60) == 2 and "readable by others (mode 644); chmod 600" in refused.stderr()
    refused.stop()
    key_file.chmod(0o600)
    boat = Boat(tmp_path, config=cfg)
    try:
        hb = boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1)  # telemetry flows, signed
        assert hb.get_msgbuf()[2] & mavlink.MAVLINK_IFLAG_SIGNED  # MAVLink 2 incompat flags: signed
        boat.mode_is("auto")
        boat.gcs.mav.command_long_send(1, 1, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0, 0, 0, 0, 0)
        boat.wait_log(lambda r: r["event"] == "command" and not r["accepted"] and "COMMAND_LONG" in r["answer"],
                      what="unsigned command refused")
        boat.gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 0, 0)  # would stop the telemetry
        boat.wait_log(lambda r: r["event"] == "command" and not r["accepted"] and "REQUEST_DATA_STREAM" in r["answer"],
                      what="unsigned stream request refused")
        boat.recv("ATTITUDE", 2.0)
        boat.sign_with(bytes(32))  # the wrong key
        boat.gcs.mav.param_set_send(1, 1, b"HDG_KP", 2.0, mavlink.MAV_PARAM_TYPE_REAL32)
        boat.wait_log(lambda r: r["event"] == "command" and not r["accepted"] and "PARAM_SET" in r["answer"],
                      what="wrongly signed parameter write refused")
        boat.sign_with(key)
        ack = boat.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "mode" and r["mode"] == "rtl" and r["cause"] == "mavlink rtl",
                      what="rtl (signed)")
    finally:
        assert boat.stop() == 0
    assert not [r for r in boat.log() if r["event"] == "param"]
    assert os.stat(key_file).st_mode & 0o777 == 0o600


def test_a_state_that_cannot_be_saved_is_told_to_the_ground_station(tmp_path):
    """Found by review: a progress file that could not be written (here a directory in its place; on the boat a
    full disk) was only a line in the log, which nobody reads on the water: a crash and restart then would not
    know the run had been interrupted."""
    (tmp_path / "state" / "mission-progress.json").mkdir(parents=True)
    boat = Boat(tmp_path)
    try:
        text = boat.recv("STATUSTEXT", timeout_s=20.0, pred=lambda m: m.text.startswith("state not saved"))
        boat.mode_is("auto")  # the mission goes on
    finally:
        assert boat.stop() == 0
    assert text.severity == mavlink.MAV_SEVERITY_ERROR
    info = [r for r in boat.log() if r["event"] == "info" and r["message"] == "state not saved"]
    assert info and "Is a directory" in info[0]["error"]


def test_link_loss_settings_set_over_the_link_take_effect(tmp_path):
    """Found by a ground-station audit: FS_GCS_TIMEOUT and FS_GCS_ACT set over MAVLink were answered with their
    new values and logged, and a lost station still waited the configured 5 s and took the configured
    'continue' (the link kept the configuration it started with)."""
    boat = Boat(tmp_path)  # the shipped configuration: gcs_timeout_s 5, gcs_lost_action continue
    try:
        boat.mode_is("auto", 20.0)
        for name, value in ((b"FS_GCS_TIMEOUT", 1.5), (b"FS_GCS_ACT", 1.0)):  # 1 = hold
            boat.gcs.mav.param_set_send(1, 1, name, value, mavlink.MAV_PARAM_TYPE_REAL32)
            assert boat.recv("PARAM_VALUE", pred=lambda m, n=name: m.param_id == n.decode()).param_value == value
        boat.wait_log(lambda r: r["event"] == "param" and r["param"] == "FS_GCS_ACT", what="the set carried out")
        # beat for a second more, the boat's address known: a boat that never heard the station has nothing to lose
        # (a clean-clone run: the beats had all gone out before the station knew where the boat was)
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            boat.beat()
            boat.gcs.recv_match(blocking=True, timeout=0.05)
        t_silent = time.monotonic()
        boat.last_hb = math.inf  # the ground station goes quiet
        lost = boat.wait_log(lambda r: r["event"] == "gcs" and r["state"] == "lost", 20.0, "link lost")
        assert time.monotonic() - t_silent < 4.0 and lost["action"] == "hold"
        boat.mode_is("hold")
    finally:
        assert boat.stop() == 0


def test_a_mission_with_a_speed_item_keeps_the_planners_item_numbers(tmp_path):
    """Found by a ground-station audit: an uploaded DO_CHANGE_SPEED was folded into the legs and dropped from the
    numbering: the download lost it, MISSION_CURRENT and MISSION_ITEM_REACHED named the item before the right one,
    and MISSION_SET_CURRENT with the planner's number flew to the wrong waypoint. Also: MISSION_REQUEST (the float
    protocol) is answered with MISSION_ITEM, and a jump to home or past the mission is refused in item numbers."""
    wps = [local_to_latlon(n, e, *ORIGIN) for n, e in ((15.0, 0.0), (30.0, 0.0), (30.0, 20.0))]
    items = [(16, 0, 0, *ORIGIN), (16, 3, 0, *wps[0]), (178, 2, 0, 0.0, 0.0), (16, 3, 0, *wps[1]), (16, 3, 0, *wps[2])]
    boat = Boat(tmp_path, mission={"name": "far", "frame": "local", "waypoints": [[-40.0, 0.0]]})
    try:
        boat.mode_is("auto")
        boat.gcs.mav.mission_request_list_send(1, 1)
        assert boat.recv("MISSION_COUNT").count == 2  # home and the one waypoint
        boat.gcs.mav.mission_count_send(1, 1, len(items))
        while True:
            m = boat.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
            if m.get_type() == "MISSION_ACK":
                break
            cmd, frame, _, lat, lon = items[m.seq]
            p2 = 1.5 if cmd == 178 else 0.0
            boat.gcs.mav.mission_item_int_send(1, 1, m.seq, frame, cmd, 0, 1, 0, p2, 0, 0, round(lat * 1e7),
                                               round(lon * 1e7), 0)
        assert m.type == mavlink.MAV_MISSION_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "mission_replaced", what="mission replaced")
        # an item of the new mission, asked without a new list: served from it, not refused by the count of the
        # download before the upload (INVALID_SEQUENCE: a GCS audit)
        boat.drain()
        boat.gcs.mav.mission_request_int_send(1, 1, 3)
        got = boat.recv(["MISSION_ITEM_INT", "MISSION_ACK"])
        assert got.get_type() == "MISSION_ITEM_INT" and got.seq == 3, got
        assert (got.x, got.y) == (round(wps[1][0] * 1e7), round(wps[1][1] * 1e7))
        boat.gcs.mav.mission_request_list_send(1, 1)
        assert boat.recv("MISSION_COUNT").count == 5
        boat.gcs.mav.mission_request_send(1, 1, 2)  # the float protocol
        speed = boat.recv(["MISSION_ITEM", "MISSION_ITEM_INT"], pred=lambda m: m.seq == 2)
        assert (speed.get_type(), speed.command, speed.param2) == ("MISSION_ITEM", 178, 1.5)
        assert boat.recv("MISSION_CURRENT", pred=lambda m: m.seq == 1).total == 4  # the last item's number
        reached = boat.recv("MISSION_ITEM_REACHED", 60.0)
        assert reached.seq == 1
        boat.recv("MISSION_CURRENT", pred=lambda m: m.seq == 3)  # the waypoint after the speed item
        # the answer to MISSION_SET_CURRENT is the new current item (a link audit: it carried the one before,
        # the status of the cycle before the jump); the stream stopped so the only MISSION_CURRENT is that answer
        assert boat.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
                            -1).result == mavlink.MAV_RESULT_ACCEPTED
        time.sleep(0.5)
        while boat.gcs.recv_match(blocking=False) is not None:
            pass
        boat.gcs.mav.mission_set_current_send(1, 1, 4)
        assert boat.recv("MISSION_CURRENT").seq == 4
        jumped = boat.wait_log(lambda r: r["event"] == "command" and r["command"] == "set_current", what="the jump")
        # the third waypoint, item 4; said in both numberings (the STATUSTEXT said "waypoint 2" alone: a new-user audit)
        assert jumped["accepted"] and jumped["answer"] == "waypoint 2 (mission item 4)"
        # (its STATUSTEXT is the mode line's text, in 50-character chunks: telemetry.event_text; read from the log,
        # as wait_log above reads and drops what the ground station received meanwhile)
        mode = boat.wait_log(lambda r: r["event"] == "mode" and "set_current" in r["cause"], what="the jump's mode")
        assert T.event_text("mode", mode)[1] == "mode auto (AUTO): mavlink set_current: waypoint 2 (mission item 4)"
        # item 0 (home) restarts the mission at its first waypoint, as ArduPilot's: Mission Planner's Restart Mission
        # (it was refused, "item 0 is home": a GCS audit)
        boat.gcs.mav.mission_set_current_send(1, 1, 0)
        assert boat.recv("MISSION_CURRENT").seq == 1
        assert boat.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 4).result == mavlink.MAV_RESULT_ACCEPTED
        assert boat.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 0).result == mavlink.MAV_RESULT_ACCEPTED
        assert boat.command(mavlink.MAV_CMD_DO_SET_MISSION_CURRENT, 9).result == mavlink.MAV_RESULT_DENIED
        boat.gcs.mav.mission_write_partial_list_send(1, 1, 1, 2)  # unanswered once: the planner timed out
        assert boat.recv("MISSION_ACK").type == mavlink.MAV_MISSION_UNSUPPORTED
    finally:
        assert boat.stop() == 0
    refused = [r["answer"] for r in boat.log() if r["event"] == "command" and not r["accepted"]]
    assert refused[:1] == ["DO_SET_MISSION_CURRENT refused: item 9 is not a waypoint of the mission (waypoints are "
                           "items 1..4)"]
    assert refused[1].startswith("MISSION_WRITE_PARTIAL_LIST not supported: send the whole mission")
    jumps = [r["answer"] for r in boat.log() if r["event"] == "command" and r["command"] == "set_current"]
    assert jumps == ["waypoint 2 (mission item 4)", "waypoint 0 (mission item 1)", "waypoint 2 (mission item 4)",
                     "waypoint 0 (mission item 1)"]


def test_mode_changes_as_the_standard_says_a_broken_datagram_and_the_planners_shortcuts(tmp_path):
    """Found by a ground-station audit: a DO_SET_MODE or SET_MODE without MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (a
    standard mode, MAV_MODE_AUTO_ARMED) was taken as custom mode 0, MANUAL, and left the mission; SET_MODE got no
    COMMAND_ACK; a datagram cut inside a frame swallowed the next datagrams' commands for ~2 s; a message interval
    set back from once a minute waited out the minute; MISSION_CLEAR_ALL for all types (255) cleared nothing;
    Mission Planner's "fly to here" (a MISSION_ITEM with current 2) got no answer."""
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_AUTO_ARMED, 0).result == \
            mavlink.MAV_RESULT_DENIED
        boat.gcs.mav.set_mode_send(1, mavlink.MAV_MODE_AUTO_ARMED, 0)
        assert boat.recv("COMMAND_ACK", pred=lambda m: m.command == 11).result == mavlink.MAV_RESULT_DENIED
        time.sleep(0.5)
        assert boat.cycles()[-1]["mode"] == "auto"
        boat.gcs.mav.set_mode_send(1, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)  # LOITER
        assert boat.recv("COMMAND_ACK", pred=lambda m: m.command == 11).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("hold")
        # a datagram whose header announces 255 bytes of payload it does not carry, then a command at once
        boat.gcs.port.sendto(b"\xfd\xff\x00\x00\x00\xff\xbe\x4c\x00\x00", next(iter(boat.gcs.clients)))
        ack = boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 5)  # LOITER again: answered
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        sys_status = mavlink.MAVLINK_MSG_ID_SYS_STATUS
        assert boat.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, sys_status, 60e6).result == mavlink.MAV_RESULT_ACCEPTED
        assert boat.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, sys_status, 0).result == mavlink.MAV_RESULT_ACCEPTED
        boat.recv("SYS_STATUS", 2.5)
        here = local_to_latlon(-10.0, 8.0, *ORIGIN)
        boat.gcs.mav.mission_item_int_send(1, 1, 0, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 16, 2, 1, 0, 0, 0, 0,
                                           round(here[0] * 1e7), round(here[1] * 1e7), 0)
        assert boat.recv("MISSION_ACK").type == mavlink.MAV_MISSION_ACCEPTED
        held = boat.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "hold" and r["hold_north_m"] is not None
                             and abs(r["hold_north_m"] + 10.0) < 0.05, what="hold at the point")
        assert abs(held["hold_east_m"] - 8.0) < 0.05
        boat.gcs.mav.mission_clear_all_send(1, 1, mavlink.MAV_MISSION_TYPE_ALL)
        ack = boat.recv("MISSION_ACK")  # the request's type echoed, as ArduPilot (QGC ignored an ack of type 0)
        assert (ack.type, ack.mission_type) == (mavlink.MAV_MISSION_ACCEPTED, mavlink.MAV_MISSION_TYPE_ALL)
        boat.wait_log(lambda r: r["event"] == "mission_replaced" and r["waypoints"] == [], what="cleared")
        assert boat.recv("MISSION_CURRENT", pred=lambda m: m.total == 65535).seq == 0  # no mission (MAVLink's word)
    finally:
        assert boat.stop() == 0
    assert not [r for r in boat.log() if r["event"] == "info" and r.get("message") == "mavlink message not handled"]


def _count(boat: Boat, seconds: float) -> dict[str, int]:
    """How many of each message type the station hears from the boat in ``seconds`` of wall time (from now on: what
    waits in the socket's buffer is read and dropped first)."""
    while boat.gcs.recv_match(blocking=False) is not None:
        pass
    seen: dict[str, int] = {}
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        boat.beat()
        m = boat.gcs.recv_match(blocking=True, timeout=0.1)
        if m is not None and m.get_srcSystem() == 1:
            seen[m.get_type()] = seen.get(m.get_type(), 0) + 1
    return seen


def test_mission_planners_stream_rates_are_obeyed(tmp_path):
    """Mission Planner sets telemetry rates with REQUEST_DATA_STREAM (its SRn_ rates), not SET_MESSAGE_INTERVAL; it
    was ignored, so its rate settings did nothing. Streams group the messages as ArduPilot Rover does; HEARTBEAT
    keeps its rate; a stream with none of ours changes nothing."""
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        boat.gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_EXTENDED_STATUS, 0, 0)  # stop
        boat.gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_EXTRA1, 2, 1)  # ATTITUDE at 2 Hz
        boat.gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_RC_CHANNELS, 0, 0)  # none of ours
        time.sleep(0.5)
        seen = _count(boat, 4.0)
        assert not {"SYS_STATUS", "GPS_RAW_INT", "NAV_CONTROLLER_OUTPUT", "MISSION_CURRENT"} & set(seen), seen
        assert 6 <= seen["ATTITUDE"] <= 10, seen  # 2 Hz, was 10
        assert 16 <= seen["GLOBAL_POSITION_INT"] <= 24 and 12 <= seen["VFR_HUD"] <= 20, seen  # untouched
        assert 3 <= seen["HEARTBEAT"] <= 5, seen
        boat.gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 3, 1)
        time.sleep(0.5)
        seen = _count(boat, 4.0)
        for name in ("SYS_STATUS", "GPS_RAW_INT", "NAV_CONTROLLER_OUTPUT", "MISSION_CURRENT", "ATTITUDE",
                     "GLOBAL_POSITION_INT", "VFR_HUD"):
            assert 10 <= seen.get(name, 0) <= 14, (name, seen)  # 3 Hz each
        assert 3 <= seen["HEARTBEAT"] <= 5, seen
    finally:
        assert boat.stop() == 0


def _thrust_after(boat: Boat, t_s: float) -> list[tuple]:
    return [(round(r["t_s"], 1), r["mode"], r["thrust_port_n"], r["thrust_stbd_n"])
            for r in boat.cycles() if r["t_s"] > t_s and (r["thrust_port_n"] or r["thrust_stbd_n"])]


def test_the_ground_station_lost_does_not_drive_a_boat_a_failsafe_stopped(tmp_path):
    """Found by fault injection: a flat battery's critical stop, then the ground station lost with
    gcs_lost_action rtl: the link's action came as an operator's command, and the boat drove home on the empty
    battery (120 cycles of thrust)."""
    boat = Boat(tmp_path, config={"sim": {"battery_initial_soc": 0.0, "battery_capacity_ah": 1.0},
                                  "mavlink": {"gcs_timeout_s": 1.5, "gcs_lost_action": "rtl"}})
    try:
        crit = boat.wait_log(lambda r: r["event"] == "failsafe" and r["cause"] == "battery_critical", 40.0, "critical")
        boat.mode_is("stop")
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            boat.beat()
            boat.gcs.recv_match(blocking=True, timeout=0.05)
        boat.last_hb = math.inf  # the ground station goes quiet (out of radio range)
        boat.wait_log(lambda r: r["event"] == "gcs" and r["state"] == "lost", 20.0, "gcs lost")
        refused = boat.wait_log(lambda r: r["event"] == "command" and r["command"] == "rtl", 10.0, "the link's rtl")
        time.sleep(2.0)
    finally:
        boat.stop()
    assert refused["accepted"] is False and "the stop in force (failsafe battery_critical) stands" in refused["answer"]
    assert _thrust_after(boat, crit["t_s"] + 0.5) == []


def test_a_joystick_stream_does_not_undo_a_failsafe_stop(tmp_path):
    """Found by fault injection: a planner streams MANUAL_CONTROL while its joystick is on; the packet after
    battery_critical's stop took the boat back to manual, 26 N a side on the empty battery."""
    boat = Boat(tmp_path, config={"sim": {"battery_initial_soc": 0.11, "battery_capacity_ah": 1.0},
                                  "mavlink": {"manual_timeout_s": 0.5}})
    try:
        boat.mode_is("auto", 20.0)
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 0).result == mavlink.MAV_RESULT_ACCEPTED  # MANUAL
        crit = None
        t_end = time.monotonic() + 40.0
        while time.monotonic() < t_end and crit is None:  # driving by joystick at ~20 Hz until the battery trips
            boat.gcs.mav.manual_control_send(1, 0, 0, 800, 0, 0)
            boat.beat()
            boat.gcs.recv_match(blocking=False)
            time.sleep(0.05)
            crit = next((r for r in boat.log() if r["event"] == "failsafe" and r["cause"] == "battery_critical"), None)
        assert crit is not None, "battery_critical never tripped"
        t_end = time.monotonic() + 2.0  # the hand stays on the stick
        while time.monotonic() < t_end:
            boat.gcs.mav.manual_control_send(1, 0, 0, 800, 0, 0)
            boat.beat()
            time.sleep(0.05)
    finally:
        boat.stop()
    assert _thrust_after(boat, crit["t_s"] + 0.3) == []
    refused = [r for r in boat.log() if r["event"] == "command" and r["command"] == "manual" and not r["accepted"]
               and r["t_s"] > crit["t_s"]]  # (before, battery_low's rtl may have ignored them too)
    assert refused and refused[0]["answer"].startswith("stick input ignored: mode stop"), refused


def test_with_signing_an_unsigned_heartbeat_does_not_keep_the_station_alive(tmp_path):
    """Found by a GCS audit: with signing required, a second planner beating unsigned with the station's system
    id (QGC and Mission Planner are both 255) kept the lost-station failsafe from firing; and a command to another
    component of this system (target_component 99) was carried out by the autopilot."""
    key = bytes(range(32))
    key_file = tmp_path / "mavlink.key"
    key_file.write_text(key.hex() + "\n")
    key_file.chmod(0o600)
    boat = Boat(tmp_path, config={"mavlink": {"signing_key_file": str(key_file), "gcs_timeout_s": 2.0,
                                              "gcs_lost_action": "hold"}})
    try:
        boat.recv("HEARTBEAT")  # the planner's link is MAVLink 2 from the boat's first frame: signing from here
        boat.sign_with(key)
        boat.mode_is("auto")
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end:  # signed heartbeats, longer than the timeout: the station counts as there
            boat.beat()
            boat.gcs.recv_match(blocking=True, timeout=0.1)
        assert not [r for r in boat.log() if r["event"] == "gcs"]
        boat.gcs.mav.command_long_send(1, 99, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
        time.sleep(0.5)
        assert boat.cycles()[-1]["armed"] is True  # not for this component: not carried out
        boat.sign_with(None)  # the station's heartbeats now come unsigned
        lost = boat.wait_log(lambda r: r["event"] == "gcs" and r["state"] == "lost", 15.0, "gcs lost")
        assert lost["action"] == "hold"
        boat.mode_is("hold")
    finally:
        assert boat.stop() == 0


def test_guided_is_reported_as_guided_so_a_planners_start_mission_goes_through(tmp_path):
    """Found by a GCS audit: QGC's Start Mission on a Rover sets GUIDED, arms and sends MISSION_START; GUIDED was
    acknowledged but the heartbeats said LOITER, and QGC gave up after three tries. Found by a link audit: LOITER
    after GUIDED (and GUIDED after LOITER) was acknowledged while the heartbeats kept the mode before."""
    boat = Boat(tmp_path)
    try:
        boat.mode_is("auto")
        for custom in (15, 5, 15):  # GUIDED, LOITER, GUIDED: each a hold where the boat is
            assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, custom).result == mavlink.MAV_RESULT_ACCEPTED
            boat.recv("HEARTBEAT", pred=lambda m, c=custom: m.get_srcSystem() == 1 and m.custom_mode == c)
        assert boat.command(mavlink.MAV_CMD_MISSION_START).result == mavlink.MAV_RESULT_ACCEPTED
        boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1 and m.custom_mode == 10)
        for _ in range(20):  # Mission Planner's joystick: said once, not ignored without a word
            boat.gcs.mav.rc_channels_override_send(1, 1, 1500, 1500, 1900, 1500, 0, 0, 0, 0)
        said = boat.wait_log(lambda r: r["event"] == "command" and r["command"] == "rc_override", 10.0, "rc override")
        assert said["answer"].startswith("RC_CHANNELS_OVERRIDE not supported: drive by MANUAL_CONTROL")
    finally:
        assert boat.stop() == 0
    assert sum(1 for r in boat.log() if r["event"] == "command" and r["command"] == "rc_override") == 1


def test_a_review_scores_a_mission_uploaded_mid_run_against_its_own_waypoints(tmp_path):
    """Found by a review audit: a mission uploaded from the ground station mid-run was ignored by the review,
    which scored the whole log against mission_start's waypoints: "waypoints reached 1 of 1" and a closest
    approach of 17.8 m beside the daemon's "4 of 4 reached", cross-track 8.8 m for the logged 1.25 m."""
    from autopilot.review.metrics import score
    from autopilot.review.reader import read_log

    boat = Boat(tmp_path, mission={"name": "one", "frame": "local", "waypoints": [[40.0, -30.0]]}, speedup=10.0)
    uploaded = [(-8.0, 8.0), (-16.0, 0.0), (-8.0, -8.0)]
    try:
        boat.mode_is("auto")
        items = [(16, 0, 0, *ORIGIN)] + [(16, 3, 0, *local_to_latlon(n, e, *ORIGIN)) for n, e in uploaded]
        assert _upload(boat, items) == mavlink.MAV_MISSION_ACCEPTED
        boat.wait_log(lambda r: r["event"] == "mission_replaced", what="mission replaced")
        boat.wait_log(lambda r: r["event"] == "info" and r["message"] == "mission complete: staying up", timeout_s=60.0,
                      what="the mission's end")  # with a ground station link the daemon stays up after it
    finally:
        boat.stop()
    log = read_log(next((tmp_path / "logs").glob("mission-*.jsonl")))
    assert [p.number for p in log.plans] == [1, 2] and log.plans[1].source == "mavlink"
    card = score(log)
    logged = {ev["wp_index"]: ev["closest_approach_m"] for ev in log.events_named("waypoint_pass")}
    assert [w.label for w in card.waypoints] == ["M1 W0", "M2 W0", "M2 W1", "M2 W2"]
    assert [w.reached for w in card.waypoints] == [False, True, True, True]
    for w in card.waypoints[1:]:  # the same definition as the daemon's waypoint_pass, over the new mission's fixes
        assert w.closest_approach_m == pytest.approx(logged[w.index], abs=0.05)
        assert (w.north_m, w.east_m) == pytest.approx(uploaded[w.index], abs=0.01)
    rows = dict(card.table_rows())
    assert rows["waypoints reached"] == "3 of 4" and rows["missions"].startswith("M1: 1 waypoint(s) from mission_start; M2: 3")
    assert card.xte_max_m < 3.0 * max(card.logged_xte_max_m, 0.5)  # judged on the legs the boat flew


def test_a_radio_missing_at_start_is_retried_and_the_daemon_flies_meanwhile(tmp_path):
    """Found by an on-boat audit: a MAVLink endpoint that could not be opened at start (a radio not plugged in
    yet, udpin on an address DHCP has not given yet) stopped the daemon with exit 2, which the unit never
    restarts (RestartPreventExitStatus=2): the autopilot stayed down for the session. Now it flies and the
    endpoint is retried; plugged in, the radio gets the telemetry."""
    from autopilot.simdev import PtyEndpoint

    radio_path = tmp_path / "radio"
    cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
    cfg["sim"]["origin_lat_deg"], cfg["sim"]["origin_lon_deg"] = ORIGIN
    cfg["failsafe"]["position_confirm_s"] = 1.0  # real time: it starts a second after its first fix
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--sim", "--speedup", "1", "--config",
                          str(tmp_path / "c.yaml"), "--mission", "pond-9.4", "--log-dir", str(tmp_path / "logs"),
                          "--state-dir", str(tmp_path / "state"), "--runtime-dir", str(tmp_path / "run"),
                          "--mavlink", f"{radio_path}:57600"], cwd=tmp_path, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    radio = None
    try:
        tail = LogTail(tmp_path / "logs")
        t_end = time.monotonic() + 20.0
        while time.monotonic() < t_end and not any(r["event"] == "cycle" and r["mode"] == "auto"
                                                    for r in tail.lines(p.pid)):
            assert p.poll() is None, p.stderr.read()
            time.sleep(0.1)
        assert p.poll() is None  # flying without its radio
        radio = PtyEndpoint(tmp_path, "radio")  # plugged in
        got, t_end = b"", time.monotonic() + 10.0
        while time.monotonic() < t_end and b"\xfd" not in got and b"\xfe" not in got:
            got += radio.read()
            time.sleep(0.1)
        assert b"\xfd" in got or b"\xfe" in got, got[:200]  # MAVLink frames on the radio
        opened = [r.get("message") for r in tail.lines(p.pid) if r["event"] == "info"]
        assert any("cannot open" in m and "retried every" in m for m in opened if m)
        assert any(m == f"mavlink endpoint {radio_path}:57600: open" for m in opened if m)
    finally:
        p.terminate()
        p.communicate(timeout=30)
        if radio is not None:
            radio.close()


def test_an_endpoint_waiting_cannot_help_is_still_refused_at_start(tmp_path):
    """Found by a review of the retry above: every open error was retried for ever, an address in use or a
    permission the unit's DevicePolicy withholds too, with the boat flying without its ground station and one
    line in the log. Those still refuse the start, naming the endpoint."""
    taken = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    taken.bind(("127.0.0.1", 0))
    port = taken.getsockname()[1]
    cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
    cfg["sim"]["origin_lat_deg"], cfg["sim"]["origin_lon_deg"] = ORIGIN
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    try:
        p = subprocess.run([sys.executable, "-m", "autopilot", "run", "--sim", "--speedup", "max", "--config",
                            str(tmp_path / "c.yaml"), "--mission", "pond-9.4", "--log-dir", str(tmp_path / "logs"),
                            "--state-dir", str(tmp_path / "state"), "--runtime-dir", str(tmp_path / "run"),
                            "--mavlink", f"udpin:127.0.0.1:{port}"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=60)
    finally:
        taken.close()
    assert p.returncode == 2, p.stderr[-1500:]
    assert f"mavlink endpoint udpin:127.0.0.1:{port}: cannot open (" in p.stderr and "in use" in p.stderr, p.stderr[-1500:]


def test_the_planners_waypoint_is_where_the_mode_takes_the_boat(tmp_path):
    """Found by a GCS audit: NAV_CONTROLLER_OUTPUT gave the mission's waypoint in every mode: in rtl 21 m to item 3
    with home 46 m the other way, after a "go here" the bearing of the mission's waypoint. ArduPilot gives the
    mode's destination: rtl's launch point, the point held."""
    boat = Boat(tmp_path)
    try:
        boat.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "auto" and r["est_north_m"] is not None
                      and r["est_north_m"] > 15.0, what="the boat out on the first leg")
        launch = next(r for r in boat.log() if r["event"] == "launch")
        assert boat.command(mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH).result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("rtl")
        nco = boat.recv("NAV_CONTROLLER_OUTPUT")
        last = boat.cycles()[-1]
        dn, de = launch["north_m"] - last["est_north_m"], launch["east_m"] - last["est_east_m"]
        assert last["mode"] == "rtl" and math.hypot(dn, de) > 10.0
        assert abs(nco.wp_dist - math.hypot(dn, de)) < 3.0, (nco, last)
        assert abs((nco.target_bearing - math.degrees(math.atan2(de, dn)) + 180.0) % 360.0 - 180.0) < 10.0
        lat, lon = local_to_latlon(last["est_north_m"], last["est_east_m"] - 20.0, *ORIGIN)  # 20 m to the west

        def position_target(lat_deg, lon_deg):  # the type_mask of a position alone
            boat.gcs.mav.set_position_target_global_int_send(0, 1, 1, mavlink.MAV_FRAME_GLOBAL_INT, 0b110111111000,
                                                             round(lat_deg * 1e7), round(lon_deg * 1e7), 0.0,
                                                             0, 0, 0, 0, 0, 0, 0, 0)

        position_target(lat, lon)  # in rtl: not carried out, said (it was ignored without a word: the same audit)
        boat.wait_log(lambda r: r["event"] == "command" and r["answer"].startswith(
            "SET_POSITION_TARGET_GLOBAL_INT ignored: mode rtl is not GUIDED"), what="the position target refused")
        ack = boat.command(mavlink.MAV_CMD_DO_REPOSITION, -1, 0, 0, 0, use_int=True, x=round(lat * 1e7),
                           y=round(lon * 1e7))
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED
        boat.mode_is("hold")
        nco = boat.recv("NAV_CONTROLLER_OUTPUT")
        assert 15.0 < nco.wp_dist < 25.0 and abs((nco.target_bearing - 270.0 + 180.0) % 360.0 - 180.0) < 15.0, nco
        # in GUIDED a position target is a go-here, as ArduPilot Rover's
        target = (last["est_north_m"] + 15.0, last["est_east_m"] - 20.0)
        position_target(*local_to_latlon(*target, *ORIGIN))
        moved = boat.wait_log(lambda r: r["event"] == "cycle" and r["hold_north_m"] is not None
                              and abs(r["hold_north_m"] - target[0]) < 0.05, what="the hold moved")
        assert abs(moved["hold_east_m"] - target[1]) < 0.05
        assert boat.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4).result == mavlink.MAV_RESULT_ACCEPTED  # HOLD: stop
        boat.mode_is("stop")
        assert boat.recv("NAV_CONTROLLER_OUTPUT").wp_dist == 0  # nowhere to go
    finally:
        assert boat.stop() == 0


def test_a_missions_rtl_stays_rtl_and_its_item_at_home(tmp_path):
    """Found by a GCS audit: at home after the mission's RTL item the heartbeat said LOITER (unasked: Rover stays
    in RTL, a boat loitering there) and MISSION_CURRENT went back to the last waypoint's item."""
    boat = Boat(tmp_path, mission={"name": "out-and-home", "frame": "local", "waypoints": [[12.0, 0.0], "rtl"]},
                speedup=8.0)
    try:
        arrived = boat.wait_log(lambda r: r["event"] == "mode" and r["cause"] == "rtl: at the launch point", 60.0,
                                what="home")
        boat.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "hold", what="holding at home")
        hb = boat.recv("HEARTBEAT", pred=lambda m: m.get_srcSystem() == 1)
        current = boat.recv("MISSION_CURRENT")
        text = boat.recv("STATUSTEXT", pred=lambda m: "at the launch point" in m.text)
    finally:
        assert boat.stop() == 0
    assert arrived["mode"] == "hold" and hb.custom_mode == 11
    assert (current.seq, current.total) == (2, 2)  # home 0, the waypoint 1, the RTL item 2
    assert text.text == "mode hold (RTL): rtl: at the launch point"
    done = next(r for r in boat.log() if r["event"] == "mission_complete")
    assert done["rtl"] is True and T.event_text("mission_complete", done)[1] == "mission waypoints done: returning to launch"
