"""The MAVLink 2 link to QGroundControl and Mission Planner, inside the daemon's asyncio process.

pymavlink encodes and decodes (one ``MAVLink`` codec per endpoint: its own sequence numbers and
signing state); the endpoints (:mod:`autopilot.link.endpoint`) only queue bytes. Two tasks:

- receive: takes at most ``RX_SLICE_BYTES`` of queued bytes at a time, parses them, handles each
  message, and yields to the event loop between slices, so a flood is parsed in the gaps of the
  control loop and beyond ``mavlink.rx_queue_bytes`` dropped (counted);
- send: every ``TICK_S`` of wall time, the telemetry that is due (``mavlink.rates``, built from the
  loop's last status: :mod:`autopilot.link.telemetry`), STATUSTEXT for the log's events, mission
  upload retries, and the ground station's heartbeat watch.

Everything that changes the boat is a request to the loop (:meth:`autopilot.daemon.loop.ControlLoop.submit`,
:mod:`autopilot.daemon.commands`), carried out between two cycles and answered (COMMAND_ACK,
MISSION_ACK, PARAM_VALUE) when it is. The link decides nothing itself. It runs on wall time: a
ground station, a joystick and a radio link are real-time, also under ``--speedup``.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import dataclasses
import errno
import math
import os
import stat
import time
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.geo import latlon_to_local
from autopilot.link import params as P
from autopilot.link import telemetry as T
from autopilot.link.config import MavlinkConfig, MavlinkRates
from autopilot.link.endpoint import Endpoint, open_endpoint, parse_endpoint
from autopilot.link.missions import MissionProtocol
from autopilot.link.modes import GUIDED_CAUSE, ROVER_MODES, command_for_rover_mode
from autopilot.logschema import Mode
from autopilot.schema import ConfigError

__all__ = ["MavlinkLink", "load_signing_key", "rate_for_interval", "rates_for_stream", "READ_ONLY_MESSAGES"]

TICK_S = 0.02
RX_SLICE_BYTES = 1024
RX_BUDGET_S = 0.0005  # the longest the link handles messages before the event loop gets a turn
PARAMS_PER_TICK = 8  # a parameter list goes out over a few ticks, not in one burst
MAX_AIS_TARGETS = 50  # AIS_VESSEL messages a second at most
SIGNING_EPOCH_S = 1420070400  # 2015-01-01: MAVLink 2 signing timestamps count 10 us from there
# messages a ground station may send unsigned when signing is required: they read, they change nothing
READ_ONLY_MESSAGES = frozenset({
    mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_PARAM_REQUEST_LIST,
    mavlink.MAVLINK_MSG_ID_PARAM_REQUEST_READ, mavlink.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
    mavlink.MAVLINK_MSG_ID_MISSION_REQUEST, mavlink.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
    mavlink.MAVLINK_MSG_ID_MISSION_ACK, mavlink.MAVLINK_MSG_ID_TIMESYNC, mavlink.MAVLINK_MSG_ID_SYSTEM_TIME,
})
_RATE_MESSAGES = {  # message id -> (rates field, builder)
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: "heartbeat_hz", mavlink.MAVLINK_MSG_ID_SYS_STATUS: "sys_status_hz",
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: "gps_raw_int_hz",
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: "global_position_int_hz",
    mavlink.MAVLINK_MSG_ID_ATTITUDE: "attitude_hz", mavlink.MAVLINK_MSG_ID_VFR_HUD: "vfr_hud_hz",
    mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: "nav_controller_output_hz",
    mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: "mission_current_hz",
}


# REQUEST_DATA_STREAM (Mission Planner's telemetry rates, its SRn_ parameters): the stream -> our messages in it,
# grouped as ArduPilot Rover groups them (GCS_Common.cpp STREAM_*_msgs); HEARTBEAT is in none, as there
_STREAM_MESSAGES = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink.MAVLINK_MSG_ID_SYS_STATUS, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT),
    mavlink.MAV_DATA_STREAM_POSITION: (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,),
    mavlink.MAV_DATA_STREAM_EXTRA1: (mavlink.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink.MAV_DATA_STREAM_EXTRA2: (mavlink.MAVLINK_MSG_ID_VFR_HUD,),
}


def rates_for_stream(rates: MavlinkRates, stream_id: int, rate_hz: int, start_stop: int) -> dict[int, float]:
    """REQUEST_DATA_STREAM: the new rate (Hz) of each message of stream ``stream_id`` (MAV_DATA_STREAM_ALL: of
    every stream); ``start_stop`` 0 stops them, 1 sets ``rate_hz``, anything else changes nothing (as ArduPilot).
    Each rate is held to its configured range; streams with none of our messages change nothing."""
    if start_stop not in (0, 1):
        return {}
    if stream_id == mavlink.MAV_DATA_STREAM_ALL:
        mids = [m for group in _STREAM_MESSAGES.values() for m in group]
    else:
        mids = list(_STREAM_MESSAGES.get(stream_id, ()))
    meta = {f.name: f.metadata for f in dataclasses.fields(rates)}
    hz = float(rate_hz) if start_stop == 1 else 0.0
    return {m: min(max(hz, meta[_RATE_MESSAGES[m]]["lo"]), meta[_RATE_MESSAGES[m]]["hi"]) for m in mids}


def rate_for_interval(rates: MavlinkRates, message_id: int, interval_us: float) -> tuple[float | None, str]:
    """MAV_CMD_SET_MESSAGE_INTERVAL: the new rate (Hz) of message ``message_id`` for ``interval_us`` (0: the
    configured default, -1: off), or None and why not. The configuration's range of that rate holds here too:
    a ground station once turned the HEARTBEAT off (-1), and then itself counted the boat lost."""
    field = _RATE_MESSAGES[message_id]
    meta = {f.name: f.metadata for f in dataclasses.fields(rates)}[field]
    if interval_us == 0:
        return getattr(rates, field), ""
    hz = 0.0 if interval_us < 0 else 1e6 / interval_us
    lo, hi = meta["lo"], meta["hi"]
    if hz >= lo:
        return min(hz, hi), ""  # faster than the link's limit: as fast as allowed (as before)
    name = mavlink.mavlink_map[message_id].msgname
    asked = "off (-1)" if interval_us < 0 else f"{hz:.6g} Hz ({interval_us:g} us)"
    return None, f"SET_MESSAGE_INTERVAL refused: {name} {asked} is below rates.{field}'s minimum {lo:g} Hz"


def load_signing_key(spec: str) -> bytes:
    """The 32-byte key from a file readable by its owner alone (64 hex digits, or 32 raw bytes);
    ``credential:NAME`` is ``$CREDENTIALS_DIRECTORY/NAME`` (systemd LoadCredential=). ConfigError otherwise."""
    if spec.startswith("credential:"):
        base = os.environ.get("CREDENTIALS_DIRECTORY")
        if not base:
            raise ConfigError(f"mavlink.signing_key_file: {spec}: no $CREDENTIALS_DIRECTORY (systemd LoadCredential=)")
        path = Path(base) / spec[len("credential:"):]
    else:
        path = Path(spec)
    try:
        st = path.stat()
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(f"mavlink.signing_key_file: {path}: cannot read ({exc.strerror})") from None
    if st.st_mode & (stat.S_IRWXG | stat.S_IRWXO) and not spec.startswith("credential:"):
        raise ConfigError(f"mavlink.signing_key_file: {path} is readable by others (mode {stat.S_IMODE(st.st_mode):o}); "
                          f"chmod 600 {path}")
    text = data.strip()
    if len(text) == 64:
        try:
            return bytes.fromhex(text.decode("ascii"))
        except ValueError:
            pass
    if len(data) == 32:
        return data
    raise ConfigError(f"mavlink.signing_key_file: {path}: expected 64 hexadecimal digits or 32 bytes")


def _drop_unfinished(mav) -> bool:
    """Forget a frame the parser holds unfinished (pymavlink keeps it to complete from the next bytes); True if
    there was one."""
    if mav.buf_len() == 0:
        return False
    mav.buf, mav.buf_index = bytearray(), 0
    mav.expected_length = mavlink.HEADER_LEN_V1 + 2
    mav.have_prefix_error = False
    return True


def _custom_mode_enabled(base_mode) -> bool:
    """SET_MODE's base_mode (DO_SET_MODE's param1) says the custom mode is meant, as ArduPilot requires: a
    standard mode such as MAV_MODE_AUTO_ARMED with custom mode 0 was taken as MANUAL and left the mission."""
    return (int(base_mode) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) != 0


# SET_POSITION_TARGET_GLOBAL_INT: the frames a latitude and longitude come in (the altitude is not used), and the
# type_mask bits that say x or y (the position) is not given
GLOBAL_FRAMES = frozenset({mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_INT,
                           mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
                           mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT})
POSITION_IGNORED = mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
# what an operator can do instead of a command that is not supported, said with its refusal
UNSUPPORTED_HINTS = {
    mavlink.MAV_CMD_DO_SET_SERVO: ": the boat's only outputs are its two thrusters",
}


class _Port:
    """One endpoint and its codec. ``on_unencodable(message type, exception)``: told of a message that does not
    encode (a VFR_HUD with a negative throttle went unsent for as long as the boat reversed, counted only in the
    closing statistics: a GCS audit)."""

    def __init__(self, endpoint: Endpoint, mav, on_unencodable=lambda kind, exc: None) -> None:
        self.endpoint, self.mav = endpoint, mav
        self.on_unencodable = on_unencodable

    def send(self, msg, to=None) -> None:
        """``to``: the source of the one station it answers (the endpoint's :meth:`send`); None: everyone."""
        try:
            data = msg.pack(self.mav)
        except Exception as exc:  # noqa: BLE001 - a message that does not encode is a bug here, never a stop
            self.endpoint.tx_errors += 1
            self.on_unencodable(msg.get_type(), exc)
            return
        try:
            if to is None:  # to everyone: any endpoint's send(data) (a stand-in one's too)
                self.endpoint.send(data)
            else:
                self.endpoint.send(data, to)
        except Exception:  # noqa: BLE001 - the endpoints count their own OSErrors; anything else, never a stop
            self.endpoint.tx_errors += 1


ENDPOINT_RETRY_S = 2.0  # an endpoint that could not be opened at start is tried again this often
# what an endpoint that is not there yet fails with (a radio not plugged in, an address not assigned yet)
NOT_THERE_YET = frozenset({errno.ENOENT, errno.ENODEV, errno.ENXIO, errno.EADDRNOTAVAIL, errno.ENETUNREACH,
                           errno.ENETDOWN})


class MavlinkLink:
    """The link of one daemon. ``start()``, then it runs until ``close()``."""

    def __init__(self, cfg: MavlinkConfig, *, loop, version: str, endpoints=None, clock=time.monotonic) -> None:
        self.cfg, self.loop, self.version = cfg, loop, version
        self.urls = tuple(endpoints if endpoints is not None else cfg.endpoints)
        self.clock = clock
        self.ports: list[_Port] = []
        self.key = load_signing_key(cfg.signing_key_file) if cfg.signing_key_file else None
        self.missions = MissionProtocol(self)
        self.rates = {mid: getattr(cfg.rates, name) for mid, name in _RATE_MESSAGES.items()}
        self._due = {mid: 0.0 for mid in self.rates}
        self._texts: collections.deque = collections.deque(maxlen=64)
        self._param_queue: collections.deque = collections.deque()  # (port, index) of PARAM_VALUEs to send
        self._reached: collections.deque = collections.deque(maxlen=16)
        self._refusals: dict = {}
        self._tasks: list[asyncio.Task] = []
        self._t0 = clock()
        self.gcs_last_s: float | None = None
        self._targets_due = 0.0
        self.gcs_lost = False
        self.stats = collections.Counter()

    # ---------------------------------------------------------------- lifecycle
    async def start(self) -> None:
        closed = []
        for url in self.urls:
            ep = open_endpoint(parse_endpoint(url), self.cfg.rx_queue_bytes)
            try:
                await ep.open()
            except OSError as exc:  # pyserial's SerialException is one
                if getattr(exc, "errno", None) not in NOT_THERE_YET:  # permission, in use: waiting cannot help
                    raise ConfigError(f"mavlink endpoint {url}: cannot open ({exc.strerror or exc})") from None
                # at boot the network (udpin's address) or a radio may not be there yet: refused, the service
                # (RestartPreventExitStatus=2) stayed down for the session; the devices' ports are retried too
                closed.append(ep)
                self.loop.log_event("info", message=f"mavlink endpoint {url}: cannot open "
                                    f"({exc.strerror or exc}); retried every {ENDPOINT_RETRY_S:g} s")
            mav = mavlink.MAVLink(None, srcSystem=self.cfg.system_id, srcComponent=self.cfg.component_id)
            mav.robust_parsing = True
            if self.key is not None:
                mav.signing.secret_key = self.key
                mav.signing.sign_outgoing = True
                mav.signing.link_id = len(self.ports)
                mav.signing.timestamp = int((time.time() - SIGNING_EPOCH_S) * 1e5)
                if self.cfg.signing_required:
                    mav.signing.allow_unsigned_callback = self._allow_unsigned
                else:
                    mav.signing.allow_unsigned_callback = lambda _mav, _msg_id: True
            self.ports.append(_Port(ep, mav, self._unencodable))
        self.loop.log.listeners.append(self.on_event)
        self._tasks = [asyncio.create_task(self._receive(p), name=f"mavlink-rx-{k}") for k, p in enumerate(self.ports)]
        self._tasks.append(asyncio.create_task(self._send_loop(), name="mavlink-tx"))
        self._tasks += [asyncio.create_task(self._reopen(ep), name=f"mavlink-open-{ep.spec}") for ep in closed]

    async def _reopen(self, ep) -> None:
        """Retry an endpoint that could not be opened at start until it opens (then it is used as the others)."""
        while True:
            await asyncio.sleep(ENDPOINT_RETRY_S)
            try:
                await ep.open()
            except OSError:
                continue
            self.loop.log_event("info", message=f"mavlink endpoint {ep.spec}: open")
            return

    async def close(self) -> None:
        rx = {k: v for k, v in self.stats.items()}
        rx["datagrams_dropped"] = sum(p.endpoint.rx_dropped for p in self.ports)
        rx["tx_errors"] = sum(p.endpoint.tx_errors for p in self.ports)
        self.loop.log_event("info", message="mavlink link closed", stats=rx)
        for t in self._tasks:
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        for p in self.ports:
            with contextlib.suppress(Exception):
                await p.endpoint.close()
        with contextlib.suppress(ValueError):
            self.loop.log.listeners.remove(self.on_event)

    # ---------------------------------------------------------------- what the helpers use
    def status(self) -> dict:
        return self.loop.state.status or {"mode": "waiting", "armed": True}

    def send_all(self, build) -> None:
        for p in self.ports:
            msg = build(p.mav)
            if msg is not None:  # nothing to say yet (no fix, no launch point)
                p.send(msg)

    def text(self, severity: int, text: str) -> None:
        self._texts.append((severity, text))

    def submit(self, request: dict, answer) -> None:
        self.loop.submit(request, answer)

    def _unencodable(self, kind: str, exc: Exception) -> None:
        """A message of ours that does not encode: logged once per kind (a bug to report, not a flood to log)."""
        key = f"unencodable {kind}"
        if key not in self._refusals:
            self._refusals[key] = 0.0
            self.loop.log_event("info", message="mavlink message not sent", kind=kind, error=repr(exc)[:200])

    def refused(self, what: str, why: str) -> None:
        """A refusal the link decides by itself (a malformed item, an unknown parameter): logged and shown."""
        self.loop.log_event("command", command=what, source="mavlink", accepted=False, answer=why)

    def origin(self) -> tuple[float, float]:
        return self.loop.mission.origin_lat_deg, self.loop.mission.origin_lon_deg

    def max_range_m(self) -> float:
        return self.loop.cfg.max_mission_range_m

    def mission_items(self) -> list[dict]:
        from autopilot.mission import mission_to_items

        if self.loop.ap.mission_cleared:
            return mission_to_items(self.loop.mission)[:1]
        st = self.status()
        home = (st.get("launch_lat_deg"), st.get("launch_lon_deg"))
        return mission_to_items(self.loop.mission, home_latlon=home if home[0] is not None else None)

    def reposition(self, lat, lon) -> dict | None:
        """The loop's request for "go here, hold there" (DO_REPOSITION, a guided MISSION_ITEM); None when the
        point is not valid or beyond max_mission_range_m (refused, logged, shown)."""
        if not (isinstance(lat, (int, float)) and math.isfinite(lat) and math.isfinite(lon)
                and abs(lat) <= 90 and abs(lon) <= 180 and (lat, lon) != (0, 0)):
            self.refused("reposition", f"reposition refused: position {lat}, {lon} is not valid")
            return None
        n, e = latlon_to_local(lat, lon, *self.origin())
        if math.hypot(n, e) > self.max_range_m():
            self.refused("reposition", f"reposition refused: {math.hypot(n, e):.0f} m from the "
                         f"origin (max_mission_range_m {self.max_range_m():g} m)")
            return None
        return {"command": "hold", "north_m": n, "east_m": e, "cause": GUIDED_CAUSE}  # ArduPilot: GUIDED

    def item_to_fly(self, seq: int) -> int:
        """The mission item a jump to ``seq`` means: item 0 (home) restarts the mission at its first waypoint, as
        ArduPilot's set_current_cmd (Mission Planner's Restart Mission sends it; it was refused: a GCS audit)."""
        numbers = self.loop.item_numbers
        if seq == 0 and numbers.waypoints and not self.loop.ap.mission_cleared:
            return int(numbers.waypoints[0])
        return seq

    def waypoint_of_item(self, seq: int, what: str) -> int | None:
        """The waypoint (index) a jump to mission item ``seq`` flies to; None (refused, logged, shown) when the
        item is not one: the texts number items as the planner does (home is 0)."""
        numbers = self.loop.item_numbers
        index = None if self.loop.ap.mission_cleared else numbers.waypoint_of(seq)
        if index is None:
            last = numbers.waypoints[-1] if numbers.waypoints and not self.loop.ap.mission_cleared else 0
            why = ("item 0 is home" if seq == 0 else "no mission" if not last
                   else f"item {seq} is not a waypoint of the mission (waypoints are items {numbers.waypoints[0]}..{last})")
            self.refused(what.lower(), f"{what} refused: {why}")
        return index

    def current_item(self) -> int:
        return int(self.status().get("mission_item", 0))

    def send_mission_current(self) -> None:
        item, items = self.loop.mission_item_now()
        st = {**self.status(), "mission_item": item, "mission_items": items}
        self.send_all(lambda mav: T.mission_current(mav, st))

    # ---------------------------------------------------------------- receive
    def _allow_unsigned(self, mav, msg_id: int) -> bool:
        if msg_id in READ_ONLY_MESSAGES:
            return True
        self.stats["unsigned_refused"] += 1
        now = self.clock()
        name = mavlink.mavlink_map[msg_id].msgname if msg_id in mavlink.mavlink_map else str(msg_id)
        if now - self._refusals.get(name, -math.inf) >= 1.0:  # a joystick's flood is logged once a second
            self._refusals[name] = now
            self.refused(name, f"unsigned or wrongly signed {name} refused: signing required")
        return False

    async def _receive(self, port: _Port) -> None:
        ep = port.endpoint
        while True:
            await ep.wakeup.wait()
            for data, source in ep.take(RX_SLICE_BYTES):
                try:
                    msgs = port.mav.parse_buffer(data) or []
                except Exception:  # noqa: BLE001 - robust parsing should not raise; a frame that does is dropped
                    self.stats["parse_errors"] += 1
                    msgs = []
                if ep.framed and _drop_unfinished(port.mav):
                    # a datagram ending inside a frame (its header announcing more than it holds) once swallowed
                    # the next datagrams' frames as that frame's payload: two seconds of commands went unanswered
                    self.stats["rx_unfinished_datagrams"] += 1
                t_slice = time.perf_counter()
                for msg in msgs:
                    if time.perf_counter() - t_slice > RX_BUDGET_S:  # the control loop's turn, even mid-slice
                        await asyncio.sleep(0)
                        t_slice = time.perf_counter()
                    try:
                        self._handle(port, msg, source)
                    except Exception as exc:  # noqa: BLE001 - one bad message must not end the link
                        self.stats["handler_errors"] += 1
                        kind = f"{msg.get_type()}: {type(exc).__name__}"
                        if kind not in self._refusals:  # once per kind: a bug to report, not a flood to log
                            self._refusals[kind] = 0.0
                            self.loop.log_event("info", message="mavlink message not handled", kind=kind,
                                                error=repr(exc)[:200])
            await asyncio.sleep(0)  # the control loop's turn between slices

    def _for_us(self, msg) -> bool:
        # MANUAL_CONTROL names its addressee `target`, the others `target_system`: reading only the latter let
        # a joystick meant for another boat on the same radio drive this one; a command to another component of
        # this system (a camera, a gimbal: target_component 99) disarmed the boat (MAVLink routing: ours or 0)
        target = getattr(msg, "target_system", getattr(msg, "target", 0))
        component = getattr(msg, "target_component", 0)
        return target in (0, self.cfg.system_id) and component in (0, self.cfg.component_id)

    def _handle(self, port: _Port, msg, source=None) -> None:
        """One message; ``source`` is where it came from on the port (the sender's UDP address, None on a radio)."""
        t = msg.get_type()
        self.stats["rx_" + t.lower()] += 1
        if t == "BAD_DATA":
            return
        if t == "HEARTBEAT":
            # only the configured station's (ArduPilot's SYSID_MYGCS): a second planner or a tablet's QGC on the
            # same network went on beating while the operator's station was gone, and the link never counted lost
            # ... and, with signing required, only a signed one: an unsigned source with the station's id (a
            # second planner: QGC and Mission Planner are both 255) kept the lost-station failsafe from firing
            if msg.get_srcSystem() == self.cfg.gcs_system_id and (not self.cfg.signing_required or self.key is None
                                                                  or getattr(msg, "_signed", False)):
                self._gcs_seen()
            return
        if not self._for_us(msg):
            return
        if t in ("COMMAND_LONG", "COMMAND_INT"):
            self._command(port, msg)
        elif t == "SET_MODE":
            if not _custom_mode_enabled(msg.base_mode):
                why = (f"SET_MODE refused: base_mode {msg.base_mode} lacks MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (1): "
                       f"the mode is the custom mode, with that flag set")
                self.refused("set_mode", why)
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
                return
            self._set_mode(port, msg, msg.custom_mode)
        elif t == "MANUAL_CONTROL":
            if msg.get_srcSystem() != self.cfg.gcs_system_id:
                # only the ground station's sticks drive, as ArduPilot's (SYSID_MYGCS): a second planner's joystick
                # (system 254) drove the boat in MANUAL, and its stream kept the manual timeout from ever firing once
                # the operator's station went quiet (a link audit)
                self._said_every_10_s("manual_other", "manual", f"MANUAL_CONTROL from system {msg.get_srcSystem()} "
                                      f"ignored: only the ground station's (mavlink.gcs_system_id "
                                      f"{self.cfg.gcs_system_id}) drives")
                return
            if msg.target != self.cfg.system_id:
                # sticks broadcast to system 0 drive every boat on the radio, as ArduPilot's do not: a planner flying
                # a fleet addresses one at a time (PX4 takes 0; a boat takes the stricter rule)
                self._said_every_10_s("manual_broadcast", "manual", f"MANUAL_CONTROL to system {msg.target} "
                                      f"ignored: sticks must name this boat (mavlink.system_id {self.cfg.system_id})")
                return
            # ArduPilot Rover's axes: z the throttle (0 stop, -1000 full astern), y the steering (+1000 full to
            # starboard). x and r (a multicopter's pitch and yaw) drove it before, and a planner's joystick set up for
            # a Rover did nothing while its pitch stick drove the boat (a GCS audit)
            z, y = (0 if v == 32767 else max(-1000, min(1000, v)) for v in (msg.z, msg.y))  # 32767: axis unused
            self.submit({"command": "manual", "forward_nd": z / 1000.0, "turn_nd": y / 1000.0, "source": "mavlink"},
                        lambda reply: None)  # a refusal is logged, and the log's listener shows it
        elif t.startswith("MISSION_"):
            self.missions.handle(port, msg, source)
        elif t in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            self._param(port, msg)
        elif t == "RC_CHANNELS_OVERRIDE":  # Mission Planner's joystick: ignored without a word before (a GCS audit)
            self._said_every_10_s(t, "rc_override", "RC_CHANNELS_OVERRIDE not supported: drive by MANUAL_CONTROL "
                                  "(QGroundControl's joystick) in MANUAL mode")
        elif t == "SET_POSITION_TARGET_GLOBAL_INT":
            self._position_target(msg)
        elif t == "REQUEST_DATA_STREAM":  # unanswered, as ArduPilot: the new rate shows in the telemetry itself
            for mid, hz in rates_for_stream(self.cfg.rates, msg.req_stream_id, msg.req_message_rate,
                                            msg.start_stop).items():
                self.rates[mid] = hz
                self._due[mid] = 0.0

    def _said_every_10_s(self, key: str, what: str, why: str) -> None:
        """A refusal of a message a planner streams, said once every 10 s, not each time."""
        now = self.clock()
        if now - self._refusals.get(key, -math.inf) >= 10.0:
            self._refusals[key] = now
            self.refused(what, why)

    def _position_target(self, msg) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT as ArduPilot Rover takes it: in GUIDED a position is a "go here" (as
        DO_REPOSITION); outside GUIDED, or without a position, it is not carried out, and said (the message has no
        ack). It was ignored without a word (a GCS audit)."""
        name = "SET_POSITION_TARGET_GLOBAL_INT"
        ap = self.loop.ap
        if not (ap.mode is Mode.HOLD and ap.mode_cause == GUIDED_CAUSE):
            self._said_every_10_s(name, "position_target", f"{name} ignored: mode {ap.mode.value} is not GUIDED "
                                  "(choose GUIDED, or use go here: DO_REPOSITION)")
            return
        if int(msg.coordinate_frame) not in GLOBAL_FRAMES:
            self._said_every_10_s(name, "position_target", f"{name} refused: coordinate_frame "
                                  f"{int(msg.coordinate_frame)} is not a global frame (0, 3, 5, 6, 10, 11)")
            return
        if int(msg.type_mask) & POSITION_IGNORED:
            self._said_every_10_s(name, "position_target", f"{name} refused: only a position target is supported "
                                  "(type_mask ignores x or y; velocity, acceleration and yaw targets are not)")
            return
        request = self.reposition(msg.lat_int / 1e7, msg.lon_int / 1e7)
        if request is not None:
            self.submit({**request, "source": "mavlink"}, lambda reply: None)  # a refusal is logged, and shown

    def _gcs_seen(self) -> None:
        now = self.clock()
        if self.gcs_lost:
            self.gcs_lost = False
            self.loop.log_event("gcs", state="back", silent_s=now - (self.gcs_last_s or now), action=None)
        self.gcs_last_s = now

    # ---------------------------------------------------------------- commands
    def _ack(self, port: _Port, msg, result: int) -> None:
        # SET_MODE is answered as ArduPilot answers it: COMMAND_ACK naming the message's id (11) as the command
        command = mavlink.MAVLINK_MSG_ID_SET_MODE if msg.get_type() == "SET_MODE" else msg.command
        port.send(port.mav.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

    def _ask_loop(self, port: _Port, msg, request: dict) -> None:
        def answer(reply: dict) -> None:
            # a full command queue is "busy, retry later" (TEMPORARILY_REJECTED): a planner takes DENIED as final
            result = (mavlink.MAV_RESULT_ACCEPTED if reply["ok"] else
                      mavlink.MAV_RESULT_TEMPORARILY_REJECTED if reply.get("busy") else mavlink.MAV_RESULT_DENIED)
            self._ack(port, msg, result)

        self.submit({**request, "source": "mavlink"}, answer)

    def _whole(self, port: _Port, msg, value, field: str, allowed: str, ok=lambda k: True) -> int | None:
        """A command's parameter as an int when it is a finite whole number ``ok`` accepts; else the command is
        denied with a text naming the parameter and what it may be (a NaN once went unanswered and unlogged,
        a DO_PAUSE_CONTINUE with param1 7 resumed the mission)."""
        if isinstance(value, (int, float)) and math.isfinite(value) and value == int(value) and ok(int(value)):
            return int(value)
        known = mavlink.enums["MAV_CMD"]
        name = known[msg.command].name.removeprefix("MAV_CMD_") if msg.command in known else f"command {msg.command}"
        why = f"{name} refused: {field} {value:g} is not {allowed}" if isinstance(value, (int, float)) else \
            f"{name} refused: {field} is not {allowed}"
        self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
        self.refused(name, why)
        return None

    def _command(self, port: _Port, msg) -> None:
        c, p1 = msg.command, msg.param1
        if msg.get_type() == "COMMAND_INT":
            lat, lon = msg.x / 1e7, msg.y / 1e7
        else:
            lat, lon = msg.param5, msg.param6
        if c == mavlink.MAV_CMD_DO_SET_MODE:
            base = self._whole(port, msg, p1, "param1 (base mode)", "a whole number with MAV_MODE_FLAG_CUSTOM_MODE_ENABLED "
                               "(1) set: the mode is the custom mode in param2", _custom_mode_enabled)
            mode = None if base is None else self._whole(port, msg, msg.param2, "param2 (custom mode)",
                                                         "a whole number >= 0", lambda k: k >= 0)
            if mode is not None:
                self._set_mode(port, msg, mode)
        elif c == mavlink.MAV_CMD_NAV_LOITER_UNLIM:
            self._ask_loop(port, msg, {"command": "hold"})
        elif c == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self._ask_loop(port, msg, {"command": "rtl"})
        elif c == mavlink.MAV_CMD_DO_PAUSE_CONTINUE:
            k = self._whole(port, msg, p1, "param1", "0 (pause) or 1 (continue)", lambda k: k in (0, 1))
            if k is not None:
                self._ask_loop(port, msg, {"command": "pause" if k == 0 else "continue"})
        elif c == mavlink.MAV_CMD_MISSION_START:
            self._ask_loop(port, msg, {"command": "auto"})
        elif c == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            k = self._whole(port, msg, p1, "param1", "0 (disarm) or 1 (arm)", lambda k: k in (0, 1))
            if k is not None:
                self._ask_loop(port, msg, {"command": "arm" if k == 1 else "disarm"})
        elif c == mavlink.MAV_CMD_DO_REPOSITION:
            request = self.reposition(lat, lon)
            if request is None:
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
                return
            self._ask_loop(port, msg, request)
        elif c == mavlink.MAV_CMD_DO_SET_MISSION_CURRENT:
            seq = self._whole(port, msg, p1, "param1 (mission item)", "a whole number >= 0", lambda k: k >= 0)
            seq = None if seq is None else self.item_to_fly(seq)
            index = None if seq is None else self.waypoint_of_item(seq, "DO_SET_MISSION_CURRENT")
            if index is not None:
                self._ask_loop(port, msg, {"command": "set_current", "index": index, "item": seq})
            elif seq is not None:
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
        elif c == mavlink.MAV_CMD_DO_CHANGE_SPEED:
            self._change_speed(port, msg)
        elif c == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            mid, interval_us = self._whole(port, msg, p1, "param1 (message id)", "a whole number"), msg.param2
            if mid is None:
                return
            if not math.isfinite(interval_us):
                self._whole(port, msg, interval_us, "param2 (interval, us)", "a number", lambda k: False)
                return
            if mid not in self.rates:
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
                return
            hz, why = rate_for_interval(self.cfg.rates, mid, interval_us)
            if hz is None:
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
                self.refused("SET_MESSAGE_INTERVAL", why)
                return
            self.rates[mid] = hz
            self._due[mid] = 0.0  # from now: a rate raised from once a minute waited out the old minute
            self._ack(port, msg, mavlink.MAV_RESULT_ACCEPTED)
        elif c in (mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
                   mavlink.MAV_CMD_GET_HOME_POSITION):
            wanted = {mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                      mavlink.MAV_CMD_GET_HOME_POSITION: mavlink.MAVLINK_MSG_ID_HOME_POSITION}.get(c)
            if wanted is None:
                wanted = self._whole(port, msg, p1, "param1 (message id)", "a whole number")
                if wanted is None:
                    return
            built = self._build(wanted)
            reply = None if built is None else built(port.mav)
            if reply is None:
                self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
                return
            self._ack(port, msg, mavlink.MAV_RESULT_ACCEPTED)
            port.send(reply)
        else:
            self._ack(port, msg, mavlink.MAV_RESULT_UNSUPPORTED)
            # said (once every 10 s a command): a planner's DO_CHANGE_SPEED or DO_SET_SERVO left no trace in the log
            # and no reason on the screen (a link audit); numbers MAVLink does not define share one turn, so that a
            # flood of them cannot fill the log
            known = mavlink.enums["MAV_CMD"]
            name = known[c].name.removeprefix("MAV_CMD_") if c in known else f"command {c}"
            self._said_every_10_s(f"unsupported {c if c in known else 'unknown'}", name,
                                  f"{name} not supported{UNSUPPORTED_HINTS.get(c, '')}")

    def _change_speed(self, port: _Port, msg) -> None:
        """DO_CHANGE_SPEED (Mission Planner's and QGroundControl's Change Speed): param2 the speed over ground for
        every leg of the mission and of a return (as ArduPilot Rover's desired speed), -1 no change, -2 the planned
        speeds; param1 the speed's kind, air (0) or ground (1) speed both taken as over ground (a boat has no
        airspeed to fly), a climb or descent speed refused. It was answered UNSUPPORTED (stop 47's note)."""
        from autopilot.gnc.speed import SPEED_RANGE, is_speed
        from autopilot.link.params import as_typed
        from autopilot.mission import DEFAULT_SPEED_CHANGE, NO_SPEED_CHANGE

        kind = self._whole(port, msg, msg.param1, "param1 (speed type)", "0 (airspeed) or 1 (ground speed): a boat "
                           "has no climb or descent", lambda k: k in (0, 1))
        if kind is None:
            return
        speed = as_typed(msg.param2) if math.isfinite(msg.param2) else msg.param2
        if speed == NO_SPEED_CHANGE:
            self._ack(port, msg, mavlink.MAV_RESULT_ACCEPTED)
            return
        if speed != DEFAULT_SPEED_CHANGE and not is_speed(speed):
            self._whole(port, msg, speed, "param2 (speed, m/s)", f"in {SPEED_RANGE}, -1 (no change) or -2 "
                        "(the planned speeds)", lambda k: False)
            return
        self._ask_loop(port, msg, {"command": "speed", "speed_m_s": None if speed == DEFAULT_SPEED_CHANGE else speed})

    def _set_mode(self, port: _Port, msg, custom_mode: int) -> None:
        """A mode change (DO_SET_MODE or SET_MODE ``msg``), answered with COMMAND_ACK."""
        command = command_for_rover_mode(custom_mode)
        if command is None:
            name = ROVER_MODES.get(int(custom_mode), "unknown")
            why = f"mode {int(custom_mode)} ({name}) not supported (MANUAL, HOLD, LOITER, AUTO, RTL, GUIDED)"
            self.refused("set_mode", why)
            self._ack(port, msg, mavlink.MAV_RESULT_DENIED)
            return
        if command == "manual":  # the sticks come as MANUAL_CONTROL; without them the manual timeout holds
            request = {"command": "manual", "forward_nd": 0.0, "turn_nd": 0.0, "explicit": True}
        elif int(custom_mode) == 15:  # GUIDED: a hold here, reported as GUIDED while it lasts (modes.GUIDED_CAUSE)
            request = {"command": command, "cause": GUIDED_CAUSE}
        else:
            request = {"command": command}
        self._ask_loop(port, msg, request)

    # ---------------------------------------------------------------- parameters
    def _param_value(self, port: _Port, p: P.Param, index: int) -> None:
        port.send(port.mav.param_value_encode(p.name.encode("ascii"), P.value_of(self.loop.cfg, p),
                                              P.WIRE_TYPE, len(P.PARAMS), index))

    def _param(self, port: _Port, msg) -> None:
        t = msg.get_type()
        if t == "PARAM_REQUEST_LIST":  # a new list replaces one still going out to the same port
            self._param_queue = collections.deque(q for q in self._param_queue if q[0] is not port)
            self._param_queue.extend((port, k) for k in range(len(P.PARAMS)))
            return
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode("ascii", "replace")
        name = name.rstrip("\x00")
        if t == "PARAM_REQUEST_READ":
            k = msg.param_index if 0 <= msg.param_index < len(P.PARAMS) else None
            p = P.PARAMS[k] if k is not None else P.by_name(name)
            if p is not None:
                self._param_value(port, p, P.PARAMS.index(p))
            return
        if t != "PARAM_SET":
            return
        p = P.by_name(name)
        if p is None:
            self.refused("param_set", f"parameter {name!r} unknown")
            return
        index = P.PARAMS.index(p)
        try:
            value = P.check_set(self.loop.cfg, p, float(msg.param_value), int(msg.param_type))
        except ConfigError as exc:
            self.refused("param_set", f"{exc}")
            self._param_value(port, p, index)  # the value stays: the ground station sees it unchanged
            return

        # The set is applied between cycles; a list still going out would send this parameter's old value
        # meanwhile, after the set, and a ground station that takes the first PARAM_VALUE of the name
        # as its answer shows the set undone. The answer carries the value to every port instead
        # (ArduPilot sends a changed parameter to all its links).
        self._param_queue = collections.deque(q for q in self._param_queue if q[1] != index)

        def answer(reply: dict) -> None:  # a refusal is logged, and the log's listener shows it
            for each in self.ports:
                self._param_value(each, p, index)

        self.submit({"command": "param_set", "key": p.key, "value": value, "name": p.name, "source": "mavlink"},
                    answer)

    # ---------------------------------------------------------------- send
    def on_event(self, name: str, t_s: float, fields: dict) -> None:
        """A log event (MissionLog's listener): shown as STATUSTEXT; a reached waypoint as MISSION_ITEM_REACHED."""
        if name == "waypoint_reached":
            seqs = self.loop.item_numbers.waypoints
            k = int(fields.get("wp_index", 0))
            if 0 <= k < len(seqs):
                self._reached.append(seqs[k])
        said = T.event_text(name, fields)
        if said is not None:
            self._texts.append(said)

    def _build(self, msg_id: int):
        st = self.status()
        ms = int((self.clock() - self._t0) * 1000)
        builders = {
            mavlink.MAVLINK_MSG_ID_HEARTBEAT: lambda mav: T.heartbeat(mav, st),
            mavlink.MAVLINK_MSG_ID_SYS_STATUS: lambda mav: T.sys_status(mav, st),
            mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: lambda mav: T.gps_raw_int(mav, st, ms * 1000),
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: lambda mav: T.global_position_int(mav, st, ms),
            mavlink.MAVLINK_MSG_ID_ATTITUDE: lambda mav: T.attitude(mav, st, ms),
            mavlink.MAVLINK_MSG_ID_VFR_HUD: lambda mav: T.vfr_hud(mav, st),
            mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: lambda mav: T.nav_controller_output(mav, st),
            mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: lambda mav: T.mission_current(mav, st),
            mavlink.MAVLINK_MSG_ID_HOME_POSITION: lambda mav: T.home_position(mav, st),
            mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: lambda mav: T.autopilot_version(mav, self.version),
        }
        return builders.get(msg_id)

    def tick(self, now_s: float) -> None:
        """One send step: due telemetry, texts, reached items, mission retries, the heartbeat watch."""
        for mid, hz in self.rates.items():
            if hz > 0.0 and now_s >= self._due[mid]:
                self._due[mid] = max(self._due[mid] + 1.0 / hz, now_s)
                self.send_all(self._build(mid))
        for _ in range(min(PARAMS_PER_TICK, len(self._param_queue))):
            port, k = self._param_queue.popleft()
            self._param_value(port, P.PARAMS[k], k)
        while self._reached:
            seq = self._reached.popleft()
            self.send_all(lambda mav, s=seq: mav.mission_item_reached_encode(s))
        while self._texts:
            severity, text = self._texts.popleft()
            for p in self.ports:
                for m in T.statustext(p.mav, severity, text):
                    p.send(m)
        self.missions.tick(now_s)
        self._watch_gcs(now_s)
        self._send_targets(now_s)

    def _send_targets(self, now_s: float) -> None:
        """AIS_VESSEL for every target the boat sees, once a second (the planners draw them)."""
        ais = getattr(self.loop, "ais", None)
        if ais is None or now_s < self._targets_due:
            return
        self._targets_due = now_s + 1.0
        t_loop = self.loop.clock.now_s()
        for target in ais.receiver.targets(t_loop)[:MAX_AIS_TARGETS]:
            self.send_all(lambda mav, t=target: T.ais_vessel(mav, t, t_loop))

    def _watch_gcs(self, now_s: float) -> None:
        # the loop's configuration, not the one the link started with: FS_GCS_TIMEOUT and FS_GCS_ACT set over the
        # link were answered with their new values and logged, and a lost station still waited the old timeout
        # and took the old action
        live = self.loop.cfg.mavlink
        if self.gcs_last_s is None or self.gcs_lost or now_s - self.gcs_last_s <= live.gcs_timeout_s:
            return
        self.gcs_lost = True
        action = live.gcs_lost_action
        self.loop.log_event("gcs", state="lost", silent_s=now_s - self.gcs_last_s, action=action)
        if action != "continue":
            self.submit({"command": action, "source": "mavlink", "cause": "mavlink: ground station lost",
                         "failsafe": True}, lambda reply: None)

    async def _send_loop(self) -> None:
        while True:
            try:
                self.tick(self.clock())
            except Exception:  # noqa: BLE001 - telemetry must never stop the daemon
                self.stats["tick_errors"] += 1
            await asyncio.sleep(TICK_S)
