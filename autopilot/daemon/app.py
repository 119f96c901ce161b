"""Start-up and shut-down of ``autopilot run``: everything checked first, then ports, then the loop.

Order matters for safety: configuration and mission are loaded and checked
(ConfigError, exit 2) before any serial port is opened; the log is opened
before the devices so that everything they report is recorded; the loop
starts at zero thrust (failsafe ``waiting``) and the GNC drives only once
both data streams have been valid for ``failsafe.start_valid_s``.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import dataclasses
import math
import os
import shutil
import signal
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from autopilot.clock import Clock, SimClock
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.control import check_socket_path
from autopilot.daemon.failsafe import position_limits
from autopilot.daemon.loop import ControlLoop
from autopilot.daemon.missionlog import MissionLog, log_path
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import RESUME_REFUSED, StateStore, file_sha256
from autopilot.geo import latlon_to_local, local_to_latlon
from autopilot.logschema import Mode, started_at_words, time_stop_words
from autopilot.resources import package_version
from autopilot.schema import ConfigError, to_dict

__all__ = ["RunOptions", "prepare", "run_daemon"]


@dataclass(frozen=True)
class RunOptions:
    mission_path: str
    sim: bool = False
    speedup: float = 1.0
    log_dir: str | None = None
    state_dir: str | None = None
    runtime_dir: str | None = None
    fresh: bool = False
    mavlink: tuple[str, ...] = ()  # endpoints added on the command line (--mavlink)


def _console(text: str) -> None:
    """One plain sentence on stderr for the person who started the daemon (events go there as JSON too)."""
    try:
        print(f"autopilot run: {text}", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a closed stderr must not stop the boat logic
        pass


def _fence_ne_m(cfg: DaemonConfig, origin_lat_deg: float, origin_lon_deg: float):
    g = cfg.geofence
    if g.frame == "none":
        return None
    if g.frame == "local":
        return tuple(g.polygon)
    return tuple(latlon_to_local(lat, lon, origin_lat_deg, origin_lon_deg) for lat, lon in g.polygon)


def _within_limits(cfg: DaemonConfig, mission, mission_path) -> None:
    """Every waypoint, and the start (the mission's home, else the origin), inside the geofence and within
    max_distance_m, and the legs between them (the start's to the first waypoint, an rtl's back to it) inside the
    geofence, as an upload is checked: a mission beyond them started, flew, and was turned back by its
    own latched failsafe half way (a fence with lat/lon swapped stopped the boat at its first fix); unless
    failsafe.allow_beyond_limits (a test of those failsafes)."""
    from autopilot.daemon.failsafe import mission_beyond_limits

    if cfg.failsafe.allow_beyond_limits:
        return
    fence = _fence_ne_m(cfg, mission.origin_lat_deg, mission.origin_lon_deg)
    start = "the start (the mission's home)" if mission.home_latlon is not None else "the start (the origin)"
    why = mission_beyond_limits(mission.home_ne_m, mission.waypoints_ne_m, mission.rtl, cfg.failsafe, fence, start)
    if why is not None:
        raise ConfigError(f"{mission_path}: {why}")


def sim_params(cfg: DaemonConfig):
    """The simulated boat's vessel set (sim.vessel, else the calibrated default); ConfigError naming the key. Read in
    prepare(): a bad file was found after the control socket was announced, named neither the key nor the
    configuration, and left a 0-byte log and a stale socket behind."""
    from autopilot.sim import default_params_path, load_params

    try:
        return load_params(cfg.sim.vessel or default_params_path())
    except ConfigError as exc:
        raise ConfigError(f"sim.vessel: {exc}") from None


def sim_sentences(cfg: DaemonConfig) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(10 Hz, 1 Hz) sentences of the simulated SC-30 at ``serial.sc30_baud``; ConfigError if they do not fit."""
    from autopilot.drivers.sc30_output import check_sentences, default_sentences

    fast, slow = default_sentences(cfg.serial.sc30_baud)
    fast = cfg.sim.sc30_fast_sentences or fast
    slow = cfg.sim.sc30_slow_sentences or slow
    try:
        check_sentences(cfg.serial.sc30_baud, fast, slow)
    except ValueError as exc:
        raise ConfigError(f"sim.sc30_fast_sentences, sim.sc30_slow_sentences: {exc}") from None
    return fast, slow


def prepare(cfg: DaemonConfig, opts: RunOptions, claims: list | None = None):
    """Load and check the mission and the directories; no device is touched. Raises ConfigError."""
    from autopilot.mission import load_mission

    if math.isinf(opts.speedup) and opts.speedup > 0:
        if not opts.sim:
            raise ConfigError("--speedup max: lockstep runs only with --sim (the boat's devices keep real time)")
    elif not (math.isfinite(opts.speedup) and 0.01 <= opts.speedup <= 100.0):
        raise ConfigError(f"--speedup: {opts.speedup!r} is outside the allowed range [0.01, 100], or max")
    elif opts.speedup != 1.0 and not opts.sim:
        # on the boat a faster clock ran the loop at N x rate_hz against real devices: late acks, stale fixes.
        # Simulated devices in another process (the test rig, a bench simulator) sit on pseudo-terminals.
        for key in ("sc30_port", "mbed_port"):
            port = getattr(cfg.serial, key)
            if not os.path.realpath(port).startswith("/dev/pts/"):
                raise ConfigError(f"--speedup {opts.speedup:g}: serial.{key} {port} is not a simulated device (a "
                                  "pseudo-terminal); real devices keep real time: --speedup is for --sim")
    mission = load_mission(
        opts.mission_path,
        origin_lat_deg=cfg.origin_lat_deg,
        origin_lon_deg=cfg.origin_lon_deg,
        max_range_m=cfg.max_mission_range_m,
    )
    if mission.origin_lat_deg is None or mission.origin_lon_deg is None:
        if not opts.sim:
            raise ConfigError(
                f"{opts.mission_path}: local-frame mission without an origin: the compass reports latitude/longitude, "
                "so set origin_lat_deg/origin_lon_deg in the configuration (the launch point) or add 'origin' to the mission"
            )
        mission = load_mission(
            opts.mission_path,
            origin_lat_deg=cfg.sim.origin_lat_deg,
            origin_lon_deg=cfg.sim.origin_lon_deg,
            max_range_m=cfg.max_mission_range_m,
        )
        # the bench check of systemd/INSTALL.md passed this way, and the boat then refused the same pair at start
        print(f"note: {opts.mission_path} is in metres from an origin neither it nor the configuration gives: "
              f"flown from sim.origin ({cfg.sim.origin_lat_deg:g}, {cfg.sim.origin_lon_deg:g}); without --sim it "
              "is refused until origin_lat_deg/origin_lon_deg are set (the launch point)", file=sys.stderr)
    _within_limits(cfg, mission, opts.mission_path)
    if opts.sim:
        sim_sentences(cfg)  # refuses sets that do not fit in the line before anything starts
        sim_params(cfg)
    log_dir = Path(opts.log_dir or cfg.log_dir)
    state_dir = Path(opts.state_dir or cfg.state_dir)
    path = control_socket(cfg, opts)
    check_socket_path(path)  # before anything starts (it was said only after the devices were set up)
    if private_sim_dir(path.parent) and opts.state_dir is None:
        # the running daemon's progress is not this bench run's: read as an interrupted mission, it held this run
        # at zero thrust for max_mission_time_s; written, it would have been the other's to resume after a crash
        state_dir = path.parent / "state"
    for name, d in (("log directory", log_dir), ("state directory", state_dir)):
        if d.exists() and not d.is_dir():  # mkdir said "cannot create (File exists)"
            raise ConfigError(f"{name} {d}: is a file, not a directory")
        try:
            d.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"{name} {d}: cannot create ({exc.strerror})") from exc
        if not os.access(d, os.W_OK | os.X_OK):
            raise ConfigError(f"{name} {d}: not writable by this user")
    if _answers(path):
        raise ConfigError(f"another autopilot daemon is running: it answers on {path} (autopilot ctl status); "
                          "stop it first, or give this one its own --runtime-dir")
    _claim_state_dir(state_dir, claims)
    if not opts.sim:
        _claim_ports(cfg, claims)
    from autopilot.link.endpoint import parse_endpoint

    for url in opts.mavlink:
        try:
            parse_endpoint(url)
        except ValueError as exc:
            raise ConfigError(f"--mavlink: {exc}") from None
    if not opts.sim:
        _refuse_radio_on_a_device_port(cfg, [("--mavlink", u) for u in opts.mavlink]
                                       + [("mavlink.endpoints", u) for u in cfg.mavlink.endpoints])
    if cfg.mavlink.signing_key_file and (cfg.mavlink.endpoints or opts.mavlink):
        from autopilot.link.link import load_signing_key

        load_signing_key(cfg.mavlink.signing_key_file)
    if opts.sim and cfg.sim.traffic:
        from autopilot.daemon.traffic import load_traffic

        load_traffic(cfg.sim.traffic, origin_lat_deg=0.0, origin_lon_deg=0.0)
    uploaded = None if opts.fresh else StateStore(state_dir).uploaded_to_continue()
    if uploaded is not None:  # a mission uploaded over MAVLink was running: a restart continues it
        try:
            mission = load_mission(uploaded, max_range_m=cfg.max_mission_range_m)
        except ConfigError:
            uploaded = None
    return mission, log_dir, state_dir, uploaded


def _claim_state_dir(state_dir: Path, claims: list | None) -> None:
    """ConfigError when another running daemon keeps its mission progress in ``state_dir``; else it is claimed
    for this run, as the ports are (:func:`_claim_ports`). A second bench run given the live run's --state-dir
    read the live run's progress as an interrupted mission and waited for `ctl resume`; resumed, it would have
    written over the other's progress (a new-user audit)."""
    from autopilot.drivers.serial_link import claim_port

    claim = claim_port(str(state_dir.resolve()))
    if claim is None:
        raise ConfigError(f"state directory {state_dir}: another running autopilot daemon keeps its mission progress "
                          "there; give this one its own --state-dir (or stop the other)")
    _keep(claim, claims)


def _keep(claim: list, claims: list | None) -> None:
    """A claim kept for the run (``claims``, closed when it ends), or only checked (None: closed now)."""
    for c in claim:
        if claims is None:
            c.close()
        else:
            claims.append(c)


def _claim_ports(cfg: DaemonConfig, claims: list | None) -> None:
    """ConfigError when another ``autopilot run`` holds one of this daemon's ports; else they are claimed for
    this run (``claims`` keeps the claims open until the run ends; None: only checked). Refused by its socket
    only, a daemon started by hand with its own runtime directory beside the service waited for the ports and,
    once the operator had stopped the service, drove the mission again from W0. Each daemon claims its ports
    (:func:`autopilot.drivers.serial_link.claim_port`, which the service's sandbox does not hide); who holds
    one is told when /proc says. Another program holding a port (a terminal) is waited for, as before."""
    from autopilot.drivers.serial_link import autopilot_daemon, claim_port, lock_holders

    for key, port in cfg.device_ports():
        claim = claim_port(port)
        if claim is None:
            held = [f"pid {pid}: {cmd[:120]}" for pid in lock_holders(port) if (cmd := autopilot_daemon(pid))]
            raise ConfigError(f"another autopilot daemon{' (' + held[0] + ')' if held else ''} holds {key} {port}: "
                              "two daemons must never drive one boat; stop it first (autopilot ctl stop, then "
                              "systemctl stop wamv-autopilot, or end the one started by hand)")
        _keep(claim, claims)


def _refuse_radio_on_a_device_port(cfg: DaemonConfig, endpoints: list[tuple[str, str]]) -> None:
    """ConfigError when a MAVLink radio is given a device's port: on the Mbed's it glued telemetry in front of
    the thrust commands (the firmware drops such lines: mbed_ack_missing), on the SC-30's it wrote into the
    compass line. The devices' ports are checked against each other in the configuration (DaemonConfig)."""
    from autopilot.link.endpoint import parse_endpoint

    devices = cfg.device_ports()
    for where, url in endpoints:
        try:
            spec = parse_endpoint(url)
        except ValueError:
            continue  # said where the endpoints are checked
        if spec.kind != "serial":
            continue
        for key, port in devices:
            if port and os.path.realpath(port) == os.path.realpath(spec.path):
                raise ConfigError(f"{where}: {url} is {key} ({port}): the radio needs its own port "
                                  "(ls -l /dev/serial/by-id/ names each adapter)")


def control_socket(cfg: DaemonConfig, opts: RunOptions) -> Path:
    """The control socket's path. Two daemons must never drive the same thrusters, so a second one on
    the same runtime directory is refused; a second bench run (--sim, no directory given) takes its own."""
    from autopilot.daemon.control import SOCKET_NAME, daemon_runtime_dir

    given = opts.runtime_dir or cfg.runtime_dir or None
    path = daemon_runtime_dir(given) / SOCKET_NAME
    if opts.sim and given is None and _answers(path):
        path = path.parent.with_name(f"{path.parent.name}-sim-{os.getpid()}") / SOCKET_NAME
    return path


def private_sim_dir(directory: Path) -> bool:
    """A second bench run's own directory (:func:`control_socket`): this run's alone, removed at its exit."""
    return directory.name.endswith(f"-sim-{os.getpid()}")


def _answers(path: Path) -> bool:
    """A daemon is listening on this socket (a stale file from a killed one does not answer)."""
    import socket

    if not path.exists():
        return False
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        probe.settimeout(0.5)
        try:
            probe.connect(str(path))
        except OSError:
            return False
    return True


class DeviceEvents:
    """The event sink every driver is given (:data:`autopilot.devices.EventSink`): each event an
    ``info`` log line; a port that cannot be opened also told once, in words, at the terminal."""

    def __init__(self, log: MissionLog, clock, t0_s: float, cfg: DaemonConfig) -> None:
        self.log, self.clock, self.t0_s, self.cfg = log, clock, t0_s, cfg

    def __call__(self, name: str, *, device: str, **fields) -> None:
        if name == "port_open_failed":
            s = self.cfg.serial
            # the AIS receiver is not a thruster's or the compass's: without it the boat flies, seeing no traffic
            meaning = ("collision avoidance sees no AIS targets until it opens" if device == "ais"
                       else "thrust stays at zero")
            _console(f"{device}: cannot open {fields.get('path')}: {fields.get('why') or fields.get('error')}; "
                     f"{meaning}, and the port is retried every {s.reconnect_min_s:g}-{s.reconnect_max_s:g} s. "
                     "Stop with Ctrl-C (or: systemctl stop wamv-autopilot).")
        self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message=name, device=device, **fields)


def _compass_heard(compass) -> bool:
    """The compass has given a heading or a position (valid or not): what the loop's readiness asks of it."""
    sample = compass.sample()
    return sample.heading_rad is not None or sample.position is not None


def device_silence(compass, thrusters, cfg: DaemonConfig, waited_s: float) -> list[str]:
    """Plain sentences, one per device that has not answered after ``waited_s``: what arrived on its port and what
    that points at (nothing at all, bytes that are not its protocol, the other device's output). A port that opens
    but carries the wrong device, the wrong baud rate or nothing was one JSON line, ``devices not answering`` with
    two booleans, after ready_timeout_s, and an end summary that named the Mbed alone (a new-user audit: silent,
    garbage-sending and swapped ports looked alike). A port that never opened was said already (cannot open)."""
    s, lines = cfg.serial, []
    waited = f"{waited_s:.0f} s" if waited_s >= 1.0 else f"{waited_s:.1f} s"
    nmea_check = f"`autopilot nmea {compass.port_path} --baud {s.sc30_baud}` shows what arrives"
    compass_silent = False
    if compass.transport.opens and not _compass_heard(compass):
        st = compass.stats
        if st["bytes_in"] == 0:
            compass_silent = True
            lines.append(f"sc30: {compass.port_path} is open at {s.sc30_baud} baud but nothing arrived in {waited}: "
                         f"is the SC-30 powered, its NMEA output wired to this port? ({nmea_check})")
        elif st["lines_ok"] == 0:
            lines.append(f"sc30: {st['bytes_in']} bytes arrived on {compass.port_path} in {waited} but no NMEA "
                         f"sentence ({st['dropped']} line(s) rejected): the SC-30 at another baud rate than "
                         f"serial.sc30_baud ({s.sc30_baud}; it sends at 4800, 9600, 19200 or 38400), or another device "
                         f"on this port ({nmea_check})")
        else:
            lines.append(f"sc30: NMEA arrives on {compass.port_path} ({st['lines_ok']} sentence(s) in {waited}) but "
                         "none with a true heading (THS, HDT, $PFEC,GPatt) or a position (GGA, RMC, GLL): set the "
                         f"SC-30's output sentences (docs/sc30.md; {nmea_check})")
    if thrusters.transport.opens and not thrusters.answered:
        st, got = thrusters.stats, thrusters.transport.bytes_in
        asked = f"{st['sent']} command(s) sent"
        if got == 0:
            lines.append(f"mbed: {thrusters.port_path} is open at {s.mbed_baud} baud, {asked}, but nothing came back "
                         f"in {waited}: is it the Mbed (USB 0d28:0204) running the firmware of docs/mbed-protocol.md?")
        elif st["nmea_lines"]:
            lines.append(f"mbed: NMEA sentences arrive on {thrusters.port_path} ({st['nmea_lines']} line(s)): that "
                         "is the compass's output, so serial.sc30_port and serial.mbed_port are swapped?")
        elif st["commands_echoed"]:  # it said "another baud rate", which a loopback has right (stop 47's note)
            lines.append(f"mbed: the commands sent come back unchanged on {thrusters.port_path} "
                         f"({st['commands_echoed']} of {st['sent']}): the port echoes them (a loopback plug, RX wired "
                         "to TX, a terminal program's echo), no Mbed firmware answers on it (docs/mbed-protocol.md)")
        elif st["acks_late"]:  # valid MBACK lines at the right baud rate, after ack_timeout_s (a review)
            lines.append(f"mbed: the board on {thrusters.port_path} answers, but late ({st['acks_late']} "
                         f"acknowledgement(s) after serial.ack_timeout_s, {cfg.serial.ack_timeout_s:g} s): a slow USB "
                         "bridge or a busy firmware? (docs/mbed-protocol.md)")
        elif st["acks_mismatched"]:
            lines.append(f"mbed: the board on {thrusters.port_path} acknowledges other duties than those sent "
                         f"({st['acks_mismatched']} time(s)): its firmware speaks another version of "
                         "docs/mbed-protocol.md?")
        elif st["acks_unexpected"]:
            lines.append(f"mbed: acknowledgements arrive on {thrusters.port_path} for commands not sent "
                         f"({st['acks_unexpected']}): another program on this port?")
        elif st["acks_rejected"] and not st["acks_ok"]:
            lines.append(f"mbed: the board on {thrusters.port_path} rejects every command ({st['acks_rejected']} "
                         "REJ): its firmware speaks another version of docs/mbed-protocol.md?")
        else:
            swapped = ("; or the two ports swapped (the SC-30 port is silent and this one talks unasked)"
                       if compass_silent else "")
            lines.append(f"mbed: {got} bytes came back on {thrusters.port_path} in {waited} ({asked}) but no "
                         f"acknowledgement ({st['bad_lines']} malformed line(s)): another baud rate than "
                         f"serial.mbed_baud ({s.mbed_baud}), or another device on this port{swapped}")
    if lines:
        lines.append("thrust stays at zero until both devices answer")
    return lines


def _tell_silence(loop: ControlLoop, cfg: DaemonConfig):
    """A log listener that says :func:`device_silence` at the terminal when the loop logs `devices not answering`
    (after ready_timeout_s)."""
    def listener(name: str, t_s: float, fields: dict) -> None:
        if name == "info" and fields.get("message") == "devices not answering":
            for line in device_silence(loop.compass, loop.thrusters, cfg, t_s):
                _console(line)
    return listener


START_LIMIT_CAUSES = ("max_distance", "geofence")  # a position limit a boat can already be beyond where it starts


def started_beyond_limits(loop: ControlLoop) -> str | None:
    """A sentence when the boat's launch point (its position where control started) is beyond a position limit:
    most likely the configured origin is not the launch site. A configuration copied from another lake stopped the
    boat at once with a JSON fault line and an end summary saying only "failsafes: 1 (max_distance)" (a new-user
    audit)."""
    launch = loop.ap.launch_ne_m
    if launch is None:
        return None
    beyond = position_limits(launch[0], launch[1], loop.cfg.failsafe, loop.failsafe.fence_ne_m)
    if not beyond:
        return None
    lat, lon = local_to_latlon(launch[0], launch[1], loop.cfg.origin_lat_deg, loop.cfg.origin_lon_deg)
    cause = next(c for c in START_LIMIT_CAUSES if c in beyond)
    return (f"the boat started beyond the {cause} limit: at {lat:.6f}, {lon:.6f}, {beyond[cause]}. Is the "
            f"configuration's origin_lat_deg/origin_lon_deg ({loop.cfg.origin_lat_deg:g}, {loop.cfg.origin_lon_deg:g})"
            " the launch site" + (", and its geofence this water's?" if cause == "geofence" else "?"))


def _tell_start_limits(loop: ControlLoop):
    """A log listener that says :func:`started_beyond_limits` at the terminal when control starts beyond a limit."""
    said = []

    def listener(name: str, t_s: float, fields: dict) -> None:
        if name == "launch" and not said and not fields.get("carried"):
            text = started_beyond_limits(loop)
            if text is not None:
                said.append(text)
                _console(text)
    return listener


def _resume_index(cfg: DaemonConfig, opts: RunOptions, store: StateStore, sha: str, n_waypoints: int):
    """(waypoint to start at, reason to hold zero thrust or None) from the saved progress (StateStore.interrupted)."""
    if opts.fresh:
        return 0, None
    saved, hold = store.interrupted(sha, n_waypoints)
    if hold is not None:  # held at the waypoint the operator's mode found the run at, else at the first
        return saved or 0, hold + " (--fresh starts afresh)"
    if saved is None:
        return 0, None
    if cfg.failsafe.resume_after_restart:
        return saved, None
    # held at the waypoint the run was at, as the operator's case: `ctl resume` continues from there. It started
    # the mission from W0 while the kept progress said W1, and a stop then kept that progress (an operator audit)
    return saved, ("interrupted mission found in the state directory and failsafe.resume_after_restart is false "
                   "(--fresh starts afresh)")


def _armed_at_start(opts: RunOptions, store: StateStore) -> bool:
    """False when the last run ended disarmed, however it ended (a crash, systemctl restart) and whatever its
    mission: a disarm is the operator's "no thrust" for the boat, kept until armed; --fresh starts armed. A
    progress file that is there but cannot be read may have said disarmed: disarmed too (a review: a disarm
    given in the start it held could not be saved over it, and the next start came up armed)."""
    return _disarmed_at_start(opts, store) is None


def _disarmed_at_start(opts: RunOptions, store: StateStore) -> str | None:
    """Why the start is disarmed (:func:`_armed_at_start`), or None when it is armed; the file read once."""
    if opts.fresh:
        return None
    saved, problem = store.read()
    if problem is not None:
        return "the saved progress cannot be read (it may have said disarmed)"
    return None if saved is None or saved.armed else "disarmed when the last run ended"


def _run_before(opts: RunOptions, store: StateStore, sha: str):
    """The saved progress of this mission's last run when a restart carries it on (not --fresh; interrupted or
    aborted: StateStore.interrupted): its launch point (rtl's home) and latched faults are this run's too. A run
    that ended cleanly (complete, or stopped by a signal) is not carried on: the next is a new one."""
    saved = None if opts.fresh else store.load()
    if saved is None or saved.mission_sha256 != sha:
        return None
    return saved if saved.status in ("running", "aborted") else None


async def _sim_rig(cfg: DaemonConfig, mission, clock, directory: str, x0=None):
    """The simulated SC-30 and Mbed behind pseudo-terminals, and the boat behind them (``--sim``); the boat at ``x0``
    (a model state), or at rest at the mission's launch point."""
    from autopilot.sim import Environment
    from autopilot.sim.battery import BatteryConfig
    from autopilot.simdev import SimRig

    params = sim_params(cfg)
    home_ne = mission.home_ne_m
    env = Environment(current_speed_m_s=cfg.sim.current_speed_m_s, current_towards_deg=cfg.sim.current_towards_deg,
                      wind_speed_m_s=cfg.sim.wind_speed_m_s, wind_from_deg=cfg.sim.wind_from_deg)
    x0 = (home_ne[0], home_ne[1], 0.0, 0.0, 0.0, 0.0) if x0 is None else x0
    rig = SimRig(params, clock, directory=directory, env=env, x0=x0,
                 origin_lat_deg=mission.origin_lat_deg, origin_lon_deg=mission.origin_lon_deg,
                 heading_noise_deg=cfg.sim.heading_noise_deg, position_noise_m=cfg.sim.position_noise_m,
                 seed=cfg.sim.seed, sc30_baudrate=cfg.serial.sc30_baud,
                 sc30_options={**dict(zip(("fast_sentences", "slow_sentences"), sim_sentences(cfg))),
                               "position_error": cfg.sim.position_error_model,
                               "heading_error": cfg.sim.heading_error_model},
                 battery=BatteryConfig(capacity_ah=cfg.sim.battery_capacity_ah, initial_soc=cfg.sim.battery_initial_soc),
                 thrust_gains=(cfg.sim.thrust_gain_port, cfg.sim.thrust_gain_stbd))
    rig.mbed.report_battery = cfg.sim.mbed_reports_battery
    await rig.start()
    return rig, float(params.length_m)


def _drivers(cfg: DaemonConfig, clock, events: DeviceEvents, sc30_port: str, mbed_port: str, *, on_compass_line=None):
    from autopilot.drivers.mbed import MbedDriver
    from autopilot.drivers.sc30 import SC30Driver

    s, fs = cfg.serial, cfg.failsafe
    compass = SC30Driver(sc30_port, baudrate=s.sc30_baud, clock=clock, reconnect_min_s=s.reconnect_min_s,
                         reconnect_max_s=s.reconnect_max_s, events=events, garbage_burst_lines=fs.nmea_garbage_lines,
                         garbage_burst_bytes=fs.garbage_bytes, encapsulated=on_compass_line)
    thrusters = MbedDriver(mbed_port, baudrate=s.mbed_baud, clock=clock, reconnect_min_s=s.reconnect_min_s,
                           reconnect_max_s=s.reconnect_max_s, events=events, ack_timeout_s=s.ack_timeout_s,
                           garbage_burst_lines=fs.mbed_garbage_lines, garbage_burst_bytes=fs.garbage_bytes)
    return compass, thrusters


def _longer_than_allowed(cfg: DaemonConfig, mission, start_index: int, speed_m_s: float | None) -> str | None:
    """What to say when the route, at its speeds straight from point to point (a floor), takes longer than
    failsafe.max_mission_time_s; else None. A 1000-waypoint route started without a word and the time limit
    stopped the boat at W190, mid-route (a new user's test)."""
    fs = cfg.failsafe
    if speed_m_s is not None:  # the operator's speed on every leg
        mission = dataclasses.replace(mission, speeds_m_s=(speed_m_s,) * len(mission.waypoints_ne_m))
    planned_s = mission.planned_time_s(speed_m_s or cfg.gnc.guidance.default_speed_m_s, start_index)  # rtl's too
    if not math.isfinite(planned_s) or planned_s <= fs.max_mission_time_s:
        return None
    return (f"the route takes at least {planned_s:.0f} s at its speeds (straight legs and holds{', the return' if mission.rtl else ''}), "
            f"longer than failsafe.max_mission_time_s ({fs.max_mission_time_s:g} s): its "
            f"{fs.actions.max_mission_time} failsafe will take the boat before the end; raise the limit, or split the "
            "mission")


def _reached_at_once(cfg: DaemonConfig, mission, start_index: int) -> str | None:
    """What to say of waypoints within gnc.guidance.capture_radius_m of the start or of the waypoint before them,
    else None: with a 50-m radius a pond mission was "complete after 9 s: 3 of 3 reached" and the boat had not
    moved, its closest approaches 10-35 m (a new user's test)."""
    radius_m = cfg.gnc.guidance.capture_radius_m
    wps = [tuple(map(float, p)) for p in mission.waypoints_ne_m]
    close = []
    for i in range(start_index, len(wps)):
        before, name = (mission.home_ne_m, "the start") if i == 0 else (wps[i - 1], f"W{i - 1}")
        d_m = math.hypot(wps[i][0] - before[0], wps[i][1] - before[1])
        if d_m < radius_m:
            close.append(f"W{i} {d_m:.1f} m from {name}")
    if not close:
        return None
    return (f"{', '.join(close[:4])}{', ...' if len(close) > 4 else ''}: within gnc.guidance.capture_radius_m "
            f"({radius_m:g} m): each counts reached once the boat is that close, before it gets there (a smaller "
            "radius, or waypoints farther apart)")


def _log_start(log: MissionLog, cfg: DaemonConfig, opts: RunOptions, mission, mission_path: str, *, boat_length_m: float,
               start_index: int, ports: tuple[str, str], hold_zero: str | None) -> None:
    log.event(
        "mission_start", t_s=0.0, mission=mission_path, mission_name=mission.name, guidance=cfg.gnc.guidance.law,
        rate_hz=cfg.rate_hz, sim=opts.sim, speedup=opts.speedup if math.isfinite(opts.speedup) else "max",
        origin_lat_deg=mission.origin_lat_deg, origin_lon_deg=mission.origin_lon_deg,
        waypoints=[[float(n), float(e)] for n, e in mission.waypoints_ne_m],
        waypoint_speeds_m_s=list(mission.speeds_m_s) if mission.speeds_m_s is not None else None,
        boat_length_m=boat_length_m, config=to_dict(cfg), version=package_version(), start_index=start_index,
        sc30_port=ports[0], mbed_port=ports[1], pid=os.getpid(),
    )
    if hold_zero is not None:
        log.event("info", t_s=0.0, message=f"holding zero thrust: {hold_zero}")
    elif start_index:
        log.event("info", t_s=0.0, message=f"resuming interrupted mission at waypoint {start_index}")


async def _main(cfg: DaemonConfig, opts: RunOptions, mission, log_dir: Path, state_dir: Path) -> int:
    from autopilot.gnc import Autopilot

    lockstep = opts.sim and math.isinf(opts.speedup)
    clock = SimClock() if lockstep else Clock(opts.speedup)
    notifier = Notifier()
    mission_path = str(Path(opts.mission_path).resolve())
    sha = file_sha256(opts.mission_path)
    store = StateStore(state_dir)
    holder: dict = {}
    # a SIGTERM or SIGHUP in the start-up (before the loop's own handlers) killed the daemon outright, leaving a
    # 0-byte log and a stale control socket: it is held here and handed to the loop once there is one
    early: list[str] = []
    aio = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        aio.add_signal_handler(sig, early.append, sig.name)
    control = _control_server(control_socket(cfg, opts), holder)
    await control.start()  # before the log and the ports: a second daemon stops here
    if opts.sim:
        _console(f"control socket {control.path}: autopilot ctl --runtime-dir {control.path.parent} status"
                 + (f"; another daemon runs, so this bench run keeps its mission progress in {state_dir} too "
                    "(removed at exit)" if private_sim_dir(state_dir.parent) else ""))
    log = None
    try:
        log = MissionLog(log_path(log_dir, opts.mission_path))
        start_index, hold_zero = _resume_index(cfg, opts, store, sha, len(mission.waypoints_ne_m))
        before = _run_before(opts, store, sha)
        # the interrupted run was on its mission's own way home: it goes on home (resumed, or held for the operator's
        # rtl), never back out to the last waypoint first (stop 42's note; held, until a review of 2026-12-06)
        homeward = bool(before is not None and before.homeward and mission.rtl and start_index == before.wp_index)
        if hold_zero is not None:  # only a JSON line said so, and a bench run sat still for max_mission_time_s
            ctl = f"autopilot ctl --runtime-dir {control.path.parent}"
            # with a failsafe latched, resume is refused: "resume starts the mission" beside it (an operator audit)
            _console(f"holding zero thrust: {hold_zero}; " + (
                f"`{ctl} rtl`, `hold` or `stop` are what it takes" if RESUME_REFUSED in hold_zero
                else f"`{ctl} rtl` goes on home (the run was on its mission's way home)" if homeward
                else f"`{ctl} resume` continues the mission from waypoint {start_index}" if start_index
                else f"`{ctl} resume` starts the mission"))
        t0_s = clock.now_s()
        events = DeviceEvents(log, clock, t0_s, cfg)
        tasks, rig, tmpdir, said_boat = [], None, None, None
        if lockstep:
            tasks.append(asyncio.create_task(clock.drive(), name="lockstep"))
        ports, boat_length_m = (cfg.serial.sc30_port, cfg.serial.mbed_port), cfg.boat_length_m
        if opts.sim:
            try:
                tmpdir = tempfile.TemporaryDirectory(prefix="autopilot-sim-")
            except OSError as exc:  # "No usable temporary directory found": a full or read-only /tmp
                raise ConfigError(f"--sim: cannot create the simulated devices' directory in {os.environ.get('TMPDIR') or '/tmp'} "
                                  f"({exc.strerror or exc}; set TMPDIR to a writable directory)") from None
            from autopilot.simdev.saved_boat import SIM_BOAT_FILE, keep_boat, load_boat

            saved_boat = state_dir / SIM_BOAT_FILE
            x0 = None if before is None else load_boat(saved_boat, mission.origin_lat_deg, mission.origin_lon_deg)
            rig, boat_length_m = await _sim_rig(cfg, mission, clock, tmpdir.name, x0=x0)
            ports = (rig.sc30_path, rig.mbed_path)
            tasks.append(asyncio.create_task(keep_boat(saved_boat, rig.boat, clock), name="sim-boat"))
            if x0 is not None:  # a restart carrying the run on: the boat where the run before left it (said below,
                # after mission_start: a log's first line is its mission_start, which a reader looks for)
                off_m = math.hypot(x0[0] - mission.home_ne_m[0], x0[1] - mission.home_ne_m[1])
                said_boat = (f"--sim: the simulated boat starts where the run before left it, {off_m:.0f} m from the "
                             f"launch point, heading {round(math.degrees(x0[2])) % 360:03d} ({state_dir / SIM_BOAT_FILE}; "
                             "--fresh starts it at the launch point)")
        sim_traffic, ais_driver, ais = await _ais(cfg, opts, mission, clock, events, rig, tmpdir)
        compass, thrusters = _drivers(cfg, clock, events, *ports,
                                      on_compass_line=ais.receiver.feed_line if cfg.ais.on_compass_line else None)
        if lockstep:
            clock.set_quiet(_quiet_check(log, clock, t0_s, lambda: rig.quiet(compass, thrusters) and (
                ais_driver is None or sim_traffic is None or sim_traffic.quiet(ais_driver))))
        disarmed_why = _disarmed_at_start(opts, store)
        ap = Autopilot(cfg.gnc, mission.waypoints_ne_m, speeds_m_s=mission.speeds_m_s, holds_s=mission.holds_s,
                       rtl=mission.rtl, boat_length_m=boat_length_m, start_index=start_index,
                       launch_ne_m=None if before is None else before.launch_ne_m,
                       armed=disarmed_why is None)
        loop = ControlLoop(cfg, clock=clock, autopilot=ap, mission=mission, mission_path=mission_path, mission_sha256=sha,
                           compass=compass, thrusters=thrusters, log=log, notifier=notifier, store=store,
                           fence_ne_m=_fence_ne_m(cfg, mission.origin_lat_deg, mission.origin_lon_deg), hold_zero=hold_zero,
                           t0_s=t0_s, ais=ais if (ais_driver is not None or cfg.ais.on_compass_line) else None)
        if before is not None:
            loop.failsafe.restore_latched(before.latched)
            if before.speed_m_s is not None:
                ap.set_speed(before.speed_m_s, cause="restart: the operator's speed of the run before")
            if homeward:
                ap.resume_homeward()
        holder["loop"] = loop
        log.listeners.append(_tell_silence(loop, cfg))
        log.listeners.append(_tell_start_limits(loop))
    except BaseException:  # the start failed before the loop ran: no stale socket, no empty log left behind
        await control.close()
        if log is not None:
            log.close()
            with contextlib.suppress(OSError):
                if log.path.stat().st_size == 0:
                    log.path.unlink()
        raise
    loop.install_signal_handlers()  # from here a Ctrl-C or SIGTERM is a clean stop, even while the devices open
    if early:
        loop.request_stop(early[0])
    _log_start(log, cfg, opts, mission, mission_path, boat_length_m=boat_length_m, start_index=start_index, ports=ports,
               hold_zero=hold_zero)
    said: list[str] = [said_boat] if said_boat else []
    if cfg.ais.on_compass_line:
        said.append(_compass_line_share(cfg.serial.sc30_baud))
    if not ap.armed:
        why = disarmed_why or "disarmed when the last run ended"
        said.append(f"{why}: zero thrust whatever the mode until armed (`autopilot ctl arm`, or ARM from the ground "
                    "station; --fresh starts armed)")
    if (too_long := _longer_than_allowed(cfg, mission, start_index, ap.speed_m_s)) is not None:
        said.append(too_long)
    if (at_once := _reached_at_once(cfg, mission, start_index)) is not None:
        said.append(at_once)
    if ap.speed_m_s is not None:
        said.append(f"the run carried on keeps the operator's speed of the run before, {ap.speed_m_s:g} m/s on every leg "
                    "(`autopilot ctl speed mission` gives back the planned speeds; --fresh starts with them)")
    for text in said:  # in the log and on the console (the journal) alike
        log.event("info", t_s=0.0, message=text)
        _console(text)
    link, reason, refused = None, "error", None
    try:
        link = await _start_link(cfg, opts, loop)
        loop.stay_when_done = ("a ground station link is open" if link is not None
                               else "systemd runs the daemon" if notifier.enabled else None)
        tasks += [asyncio.create_task(compass.run(), name="sc30"), asyncio.create_task(thrusters.run(), name="mbed")]
        if ais_driver is not None:
            tasks.append(asyncio.create_task(ais_driver.run(), name="ais"))
        for _ in range(20):  # the drivers' first chance to open the ports, so a normal start logs no port fault
            if compass.connected and thrusters.connected:
                break
            await clock.sleep(cfg.period_s / 10.0)
        reason = await loop.run()
    except asyncio.CancelledError:  # a SIGINT that asyncio's own handler turned into a cancel: a stop all the same
        reason = "signal"
        loop.state.stop_signal = loop.state.stop_signal or "SIGINT"
    except ConfigError as exc:  # an endpoint that cannot be opened: stop as a bad configuration does
        refused = exc
        log.event("info", t_s=clock.now_s() - loop.t0_s, message="start refused", error=str(exc))
    except Exception as exc:  # noqa: BLE001 - logged, then the boat is stopped
        log.event("info", t_s=clock.now_s() - loop.t0_s, message="control loop error", error=repr(exc))
    finally:
        loop.zero_now()
        if link is not None:  # before the stop line: it is the log's last
            await link.close()
        control.end_log()
        code = await loop.stop(reason)
        await control.close()
        if sim_traffic is not None:
            await sim_traffic.stop()
        await _shut_down(tasks, tuple(d for d in (compass, thrusters, ais_driver) if d is not None), rig, tmpdir, clock)
        log.close()
        notifier.close()
        for line in end_summary(loop, str(log.path), sim=opts.sim):
            _console(line)
        # the boat is stopped and the run summarised: a second Ctrl-C has nothing left to stop, and landing in the
        # event loop's teardown or the interpreter's exit it killed the process by SIGINT (status 130 for a clean
        # run, 4 runs in 7); ignored from here to the exit (the loop would restore Python's handler on close)
        aio.remove_signal_handler(signal.SIGINT)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        for d in {control.path.parent, state_dir.parent}:
            if private_sim_dir(d):
                shutil.rmtree(d, ignore_errors=True)
    if refused is not None:
        raise refused
    return code


def _compass_line_share(baud: int) -> str:
    """What AIS on the SC-30's line (ais.on_compass_line) has left of it: said at the start, as the line is
    physics (an AIS audit: 5 moored vessels' reports at 4800 baud held the headings up into heading_stale)."""
    from autopilot.drivers.sc30_output import default_sentences, line_load_cps

    capacity_cps = baud / 10.0
    load_cps = line_load_cps(*default_sentences(baud))
    return (f"ais.on_compass_line: the SC-30's sentences (docs/sc30.md) take {load_cps:.0f} of the {capacity_cps:.0f} "
            f"characters a second at {baud} baud, leaving {max(capacity_cps - load_cps, 0.0):.0f} for AIS (a position "
            "report is ~50): more delays the headings into heading_stale (benchmarks/ais_compass_line.py: 5 moored "
            "vessels at 4800 baud); a receiver on its own port (ais.port) has no such limit")


def _quiet_check(log, clock, t0_s: float, quiet):
    """The lockstep clock's "every device has answered" check, never raising: a check that raised (an AIS port
    without simulated traffic: no traffic to ask) ended the clock's task without a word, simulated time stopped
    at 0 and the daemon ignored SIGTERM, its stop waiting on that clock. Said once; time goes on."""
    said = []

    def check() -> bool:
        try:
            return bool(quiet())
        except Exception as exc:  # noqa: BLE001 - any failure of the check: go on, said once
            if not said:
                said.append(exc)
                log.event("info", t_s=clock.now_s() - t0_s, message="lockstep: the devices' quiet check failed; "
                          "time goes on without it", error=f"{type(exc).__name__}: {exc}")
            return True
    return check


async def _ais(cfg: DaemonConfig, opts: RunOptions, mission, clock, events, rig, tmpdir):
    """(simulated traffic or None, the AIS port's driver or None, the AisSource the loop asks)."""
    from autopilot.daemon.traffic import AisSource, SimTraffic, load_traffic
    from autopilot.drivers.ais import AisReceiver
    from autopilot.drivers.ais_device import AisDriver

    sim_traffic, port = None, cfg.ais.port
    if opts.sim and cfg.sim.traffic:
        scenario = load_traffic(cfg.sim.traffic, origin_lat_deg=mission.origin_lat_deg,
                                origin_lon_deg=mission.origin_lon_deg)
        sim_traffic = SimTraffic(scenario, clock, tmpdir.name, boat=rig.boat, baudrate=cfg.ais.baud)
        await sim_traffic.start()
        port = sim_traffic.path
    driver = None
    if port:
        s = cfg.serial
        driver = AisDriver(port, clock=clock, baudrate=cfg.ais.baud, config=cfg.ais.receiver, events=events,
                           reconnect_min_s=s.reconnect_min_s, reconnect_max_s=s.reconnect_max_s)
        receiver = driver.receiver
    else:
        receiver = AisReceiver(cfg.ais.receiver, clock_s=clock.now_s)
    return sim_traffic, driver, AisSource(receiver, origin_lat_deg=mission.origin_lat_deg,
                                          origin_lon_deg=mission.origin_lon_deg)


async def _start_link(cfg: DaemonConfig, opts: RunOptions, loop):
    """The MAVLink link, when an endpoint is configured (nothing listens otherwise)."""
    urls = tuple(cfg.mavlink.endpoints) + tuple(opts.mavlink)
    if not urls:
        return None
    from autopilot.link.link import MavlinkLink

    link = MavlinkLink(cfg.mavlink, loop=loop, version=package_version(), endpoints=urls)
    await link.start()
    loop.log_event("info", message="mavlink link open", endpoints=list(urls), signing=link.key is not None)
    return link


def _control_server(path: Path, holder: dict):
    """The control socket, bound before the loop exists: requests reach ``holder["loop"]`` once it does."""
    from autopilot.daemon.control import ControlServer

    def submit(req, answer):
        if "loop" in holder:
            holder["loop"].submit(req, answer)
        else:
            answer({"ok": False, "answer": f"{req.get('command')} refused: the daemon is starting"})

    return ControlServer(path, submit=submit,
                         status=lambda: holder["loop"].state.status if "loop" in holder else {"mode": "starting"},
                         log=lambda name, **f: holder["loop"].log_event(name, **f) if "loop" in holder else None)


async def _shut_down(tasks, devices, rig, tmpdir, clock) -> None:
    for dev in devices:
        try:
            await dev.close()
        except Exception:  # noqa: BLE001 - closing best effort
            pass
    if rig is not None:
        await rig.stop()
    if isinstance(clock, SimClock):
        clock.stop()
    for t in tasks:
        t.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    if tmpdir is not None:
        tmpdir.cleanup()


def run_daemon(cfg: DaemonConfig, opts: RunOptions) -> int:
    """Check everything, then run until complete or signalled. Returns the process exit code."""
    claims: list = []  # this run's claims on its ports (_claim_ports), released when it ends
    try:
        mission, log_dir, state_dir, uploaded = prepare(cfg, opts, claims)
        if uploaded is not None:
            _console(f"continuing the mission uploaded over MAVLink ({uploaded}), not {opts.mission_path}; "
                     "--fresh starts the configured one")
            opts = dataclasses.replace(opts, mission_path=str(uploaded))
        return asyncio.run(_main(cfg, opts, mission, log_dir, state_dir))
    finally:
        for claim in claims:
            claim.close()


def failsafe_counts(causes) -> str:
    """The causes in the order first taken, each with its count: "heading_stale x51, max_mission_time" (the first
    five of 52 hid the time limit that ended the run: a new user's test)."""
    counts = collections.Counter(causes)
    return ", ".join(c if counts[c] == 1 else f"{c} x{counts[c]}" for c in dict.fromkeys(causes))


KEEP_UP_SKIPPED_SHARE = 0.01  # more deadlines skipped than this share: say the run could not keep up


def end_summary(loop: ControlLoop, log_path: str, *, sim: bool) -> list[str]:
    """What the person who started the run wants to know at the end, in a few lines."""
    st = loop.state
    t_s = st.stopped_t_s if st.stopped_t_s is not None else loop.clock.now_s() - loop.t0_s  # the stop line's time
    n_wps = len(loop.mission.waypoints_ne_m)
    reached = st.reached
    lines = [f"log: {log_path}"]
    lost = loop.log.lines_lost
    if lost:  # the summary pointed at a log cut short (disk full) as if it were whole
        lines.append(f"  the log lost {lost} line(s): a write failed (disk full?); it is incomplete"
                     + (", without its stop line" if loop.log.failing else ""))
    if st.stop_acknowledged is False and not loop.thrusters.answered:
        # the same WARNING for a board that never answered (its port never opened) sent an operator to check
        # thrusters that had never run
        lines.append("the Mbed never acknowledged a command in this run: its firmware never applied one (the motors "
                     "stay off until its first valid command)")
    elif st.stop_acknowledged is False:  # only a JSON field said so
        lines.append("WARNING: the Mbed did not acknowledge the final zero thrust: check that the thrusters stopped "
                     "(its own command timeout stops them)")
    # the route done but the run stopped by a signal in what follows it (the final hold, the way
    # home) is not "mission complete": a 300-s hold stopped at 153 s said so (a new-user audit)
    timed = loop.time_stop_from is not None  # max_mission_time stopped it (logschema.time_stop_words)
    cut = (bool(st.stop_signal) or timed) and st.complete and not st.finished
    done = ("route complete" if cut else "mission complete") if st.complete else "mission not complete"
    if not st.stop_signal:
        stopped = f"; {time_stop_words(*loop.time_stop_from)}" if cut else ""
    elif cut and timed:  # stayed up after the time limit's stop, then a signal
        stopped = (f"; {time_stop_words(*loop.time_stop_from)}; "
                   + ("" if st.mode == Mode.STOP.value else f"then in {st.mode}, ") + f"stopped by {st.stop_signal}")
    elif cut:
        stopped = f"; then in {st.mode}, stopped by {st.stop_signal}"
    elif st.complete:  # stayed up after the mission's stop
        stopped = f"; then stopped by {st.stop_signal}"
    elif loop.time_stop_stayed:  # stayed up after max_mission_time's stop
        stopped = f"; stopped by max_mission_time, then by {st.stop_signal}"
    else:
        stopped = f"; stopped by {st.stop_signal}"
    # a run resumed at W2 said "0 of 9 reached; W0: not reached": the run before had reached them (a new user's test)
    start = int(getattr(loop, "start_index", 0) or 0)
    lines.append(f"{done} after {t_s:.1f} s: {len(reached)} of {n_wps - start} waypoint(s) reached"
                 + started_at_words(start) + stopped
                 + ("; zero thrust acknowledged by the Mbed" if st.stop_acknowledged else ""))
    for i in range(n_wps):
        ca = st.closest_m.get(i)
        if i < start and i not in reached and ca is None:
            lines.append(f"  W{i}: an earlier run's")
            continue
        got = "reached" if i in reached else "not reached"
        lines.append(f"  W{i}: {got}, closest approach " + (f"{ca:.2f} m" if ca is not None and math.isfinite(ca) else "n/a"))
    compass = getattr(loop, "compass", None)
    if compass is not None and not st.ready:  # the devices never both answered: which one, and what came instead
        lines += ["  " + line for line in device_silence(compass, loop.thrusters, loop.cfg, t_s)[:-1]]
    if loop.hold_zero is not None and loop.ap.mode is Mode.STOP and not reached:
        lines.append(f"  the boat waited at zero thrust from the start: {loop.hold_zero}")
    causes = list(st.failsafe_causes)
    if any(c in START_LIMIT_CAUSES for c in causes) and (text := started_beyond_limits(loop)) is not None:
        lines.append("  " + text)
    lines.append(f"failsafes: {len(causes)}" + (f" ({failsafe_counts(causes)})" if causes else ""))
    total = st.cycles + st.skipped
    if total:
        held = loop.speedup_held()
        asked = "max (lockstep)" if math.isinf(loop.clock.speedup) else f"{loop.clock.speedup:g}"
        lines.append(f"cycles: {st.cycles} run, {st.skipped} deadline(s) skipped, {st.late_cycles} late by a period "
                     f"or more" + (f"; speedup held ~{held:.3g} of --speedup {asked}" if sim else ""))
        if st.skipped > KEEP_UP_SKIPPED_SHARE * total or (st.skipped and causes):
            msg = f"the loop could not keep up ({st.skipped} of {total} deadlines skipped)"
            if sim:
                msg += (": on a bench run the faults that late data raise may be the machine, not the mission; "
                        "run again with a lower --speedup")
            lines.append(msg)
    return lines
