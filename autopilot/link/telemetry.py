"""Telemetry messages from the control loop's status of the last cycle (pure: a status dict in, messages out).

The status is :meth:`autopilot.daemon.loop.ControlLoop._status` (SI, degrees for people). What each
message carries, in MAVLink's units (1e7 degrees, centidegrees, cm/s, mV):

    HEARTBEAT             surface boat, ArduPilot Rover's mode number (autopilot.link.modes), armed flag,
                          state: BOOT until control starts (the mode then INITIALISING, or the one chosen
                          before it), CRITICAL failsafe, STANDBY stopped or disarmed, else ACTIVE
    SYS_STATUS            sensors present/healthy from the failsafe's view: GPS (position faults), compass
                          (heading faults), motor outputs (Mbed faults), battery (battery faults); voltage
    GLOBAL_POSITION_INT   the last fix (lat, lon), velocity from SOG/COG, heading
    ATTITUDE              yaw and yaw rate (roll and pitch 0: the SC-30's attitude is not used)
    GPS_RAW_INT           fix type from the GGA quality, SOG, COG
    VFR_HUD               ground speed, heading, throttle = the common thrust in % of the forward limit
    NAV_CONTROLLER_OUTPUT psi_d, bearing and distance to the waypoint, cross-track error, speed error
    MISSION_CURRENT       the waypoint being steered to, as a mission item number (item 0 is home)
    HOME_POSITION         the launch point (rtl returns there)
    STATUSTEXT            every fault, failsafe, mode change, refusal, link and mission event (event_text)
    AIS_VESSEL            each AIS target the boat sees (issue 18), 1 Hz, so the planners draw them
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.daemon.failsafe import FAULT_CLASS
from autopilot.link.modes import rover_mode, rover_mode_name
from autopilot.logschema import Mode

__all__ = ["heartbeat", "sys_status", "global_position_int", "attitude", "gps_raw_int", "vfr_hud",
           "nav_controller_output", "mission_current", "home_position", "autopilot_version", "statustext",
           "event_text", "SENSORS", "ais_vessel"]

SENSORS = {
    "position": mavlink.MAV_SYS_STATUS_SENSOR_GPS,
    "heading": mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG,  # the satellite compass stands in for a magnetometer
    "mbed": mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS,
    "battery_low": mavlink.MAV_SYS_STATUS_SENSOR_BATTERY,
    "battery_critical": mavlink.MAV_SYS_STATUS_SENSOR_BATTERY,
}
_AUTO_MODES = {Mode.AUTO, Mode.RTL, Mode.HOLD, Mode.PAUSED}


def _num(st: dict, key: str, default: float = 0.0) -> float:
    v = st.get(key)
    return default if v is None or not math.isfinite(v) else float(v)


def _e7(deg) -> int:
    return 0 if deg is None else int(round(float(deg) * 1e7))


def _cdeg(deg) -> int:
    return 65535 if deg is None else int(round(float(deg) % 360.0 * 100.0)) % 36000


def heartbeat(mav, st: dict):
    mode = Mode(st.get("mode", "waiting"))
    base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if st.get("armed", True):
        base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    if mode in _AUTO_MODES:
        base |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
    if mode is Mode.MANUAL:
        base |= mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    if mode is Mode.WAITING or not st.get("control_started", True):  # a mode chosen before the start, too
        state = mavlink.MAV_STATE_BOOT
    elif mode is Mode.FAILSAFE:
        state = mavlink.MAV_STATE_CRITICAL
    elif mode in (Mode.STOP, Mode.COMPLETE) or not st.get("armed", True):
        state = mavlink.MAV_STATE_STANDBY
    else:
        state = mavlink.MAV_STATE_ACTIVE
    return mav.heartbeat_encode(mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                rover_mode(mode, st.get("mode_cause")), state)


def sys_status(mav, st: dict):
    present = (SENSORS["position"] | SENSORS["heading"] | SENSORS["mbed"]
               | (SENSORS["battery_low"] if st.get("battery_v") is not None else 0))
    unhealthy = 0
    for cause in st.get("active_faults") or ():
        cls = FAULT_CLASS.get(cause)
        unhealthy |= SENSORS.get(cls, 0)
    volts = st.get("battery_v")
    return mav.sys_status_encode(present, present, present & ~unhealthy, 0,
                                 65535 if volts is None else int(round(volts * 1000.0)), -1, -1, 0, 0,
                                 int(st.get("nmea_dropped") or 0) % 65536, 0, 0, 0)


def global_position_int(mav, st: dict, time_boot_ms: int):
    """None before the first fix: a planner would draw the boat at 0 N 0 E."""
    if st.get("lat_deg") is None or st.get("lon_deg") is None:
        return None
    sog, cog = _num(st, "sog_m_s"), math.radians(_num(st, "cog_deg"))
    return mav.global_position_int_encode(int(time_boot_ms) % 2**32, _e7(st.get("lat_deg")), _e7(st.get("lon_deg")),
                                          0, 0, int(round(sog * math.cos(cog) * 100.0)),
                                          int(round(sog * math.sin(cog) * 100.0)), 0, _cdeg(st.get("heading_deg")))


def attitude(mav, st: dict, time_boot_ms: int):
    yaw = math.radians(_num(st, "heading_deg"))
    yaw = math.atan2(math.sin(yaw), math.cos(yaw))
    return mav.attitude_encode(int(time_boot_ms) % 2**32, 0.0, 0.0, yaw, 0.0, 0.0,
                               math.radians(_num(st, "yaw_rate_deg_s")))


def gps_raw_int(mav, st: dict, time_usec: int):
    q = int(st.get("fix_quality") or 0)
    fix = mavlink.GPS_FIX_TYPE_NO_FIX if q <= 0 else (mavlink.GPS_FIX_TYPE_DGPS if q == 2 else
                                                      mavlink.GPS_FIX_TYPE_3D_FIX)
    return mav.gps_raw_int_encode(int(time_usec), fix, _e7(st.get("lat_deg")), _e7(st.get("lon_deg")), 0, 65535,
                                  65535, int(round(_num(st, "sog_m_s") * 100.0)), _cdeg(st.get("cog_deg")), 255)


def vfr_hud(mav, st: dict):
    sog = _num(st, "sog_m_s")
    limit = _num(st, "max_forward_n", 1.0) or 1.0
    # the common thrust's size, as ArduPilot's abs(): VFR_HUD's throttle is a uint16, and a reverse one (braking in
    # a hold, backing) did not encode: the HUD froze on old values while the boat reversed (a GCS audit)
    throttle = int(round(min(100.0, abs(100.0 * _num(st, "tau_com_n") / limit))))
    return mav.vfr_hud_encode(sog, sog, int(round(_num(st, "heading_deg"))) % 360, throttle, 0.0, 0.0)


def nav_controller_output(mav, st: dict):
    dist = st.get("wp_distance_m")
    return mav.nav_controller_output_encode(
        0.0, 0.0, int(round(_num(st, "psi_d_deg"))) % 360, int(round(_num(st, "wp_bearing_deg"))) % 360,
        0 if dist is None else min(65535, int(round(dist))), 0.0,
        _num(st, "speed_cmd_m_s") - _num(st, "sog_m_s"), _num(st, "xte_m"))


def mission_current(mav, st: dict):
    # MAVLink's total is the last item's number (home, item 0, excluded: "on last item, sequence == total"), and
    # UINT16_MAX with no mission: it said the count with home (one more) and 0 after a clear, where the download
    # still gave home
    items = int(st.get("mission_items", 0))
    return mav.mission_current_encode(int(st.get("mission_item", 0)), items - 1 if items > 1 else 65535)


def home_position(mav, st: dict):
    lat, lon = st.get("launch_lat_deg"), st.get("launch_lon_deg")
    if lat is None:
        return None
    return mav.home_position_encode(_e7(lat), _e7(lon), 0, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0)


def autopilot_version(mav, version: str):
    caps = (mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2)
    parts = [int(p) if p.isdigit() else 0 for p in (version.split(".") + ["0", "0", "0"])[:3]]
    sw = (parts[0] << 24) | (parts[1] << 16) | (parts[2] << 8) | 255  # 255: FIRMWARE_VERSION_TYPE_OFFICIAL
    custom = list(b"wamv-ap\0")
    return mav.autopilot_version_encode(caps, sw, 0, 0, 0, custom, [0] * 8, [0] * 8, 0, 0, 0)


def ais_vessel(mav, target, now_s: float):
    """One :class:`autopilot.drivers.ais.AisTarget` as AIS_VESSEL (None without a position)."""
    if target.lat_deg is None or target.lon_deg is None:
        return None
    flags = 0

    def dim(v, big_flag, limit_m):
        # AIS carries bow and stern up to 511 m, the sides up to 63 m, each "or more" at its limit: MAVLink's
        # LARGE flags say exactly that (a 300-m bow was flagged larger than 511 m)
        nonlocal flags
        if v is None:
            return 0
        if v >= limit_m:
            flags |= big_flag
        return int(min(max(v, 0.0), limit_m))

    cog = 0
    if target.cog_rad is not None:
        flags |= mavlink.AIS_FLAGS_VALID_COG
        cog = int(round(math.degrees(target.cog_rad) % 360.0 * 100.0)) % 36000
    vel = 0
    if target.sog_m_s is not None:
        flags |= mavlink.AIS_FLAGS_VALID_VELOCITY
        vel = int(min(round(target.sog_m_s * 100.0), 65534))
    heading = 36000 if target.heading_rad is None else int(round(math.degrees(target.heading_rad) % 360.0 * 100)) % 36000
    dims = [dim(target.to_bow_m, mavlink.AIS_FLAGS_LARGE_BOW_DIMENSION, 511.0),
            dim(target.to_stern_m, mavlink.AIS_FLAGS_LARGE_STERN_DIMENSION, 511.0),
            dim(target.to_port_m, mavlink.AIS_FLAGS_LARGE_PORT_DIMENSION, 63.0),
            dim(target.to_starboard_m, mavlink.AIS_FLAGS_LARGE_STARBOARD_DIMENSION, 63.0)]
    turn = 0
    if target.turn_rad_s is not None:  # 0.1 deg/s in an int8
        flags |= mavlink.AIS_FLAGS_VALID_TURN_RATE
        turn = int(max(-127, min(127, round(math.degrees(target.turn_rad_s) * 10.0))))
    if any(dims):
        flags |= mavlink.AIS_FLAGS_VALID_DIMENSIONS
    name = (target.shipname or "").encode("ascii", "replace")[:20]
    if name:
        flags |= mavlink.AIS_FLAGS_VALID_NAME
    call = (target.callsign or "").encode("ascii", "replace")[:7]
    if call:
        flags |= mavlink.AIS_FLAGS_VALID_CALLSIGN
    tslc = int(min(max(now_s - target.last_t_s, 0.0), 65535))
    status = 15 if target.nav_status is None else int(target.nav_status)  # 0 is "under way using engine"
    return mav.ais_vessel_encode(int(target.mmsi), _e7(target.lat_deg), _e7(target.lon_deg), cog, heading, vel, turn,
                                 status % 256, int(target.ship_type or 0) % 256, *dims, call, name, tslc, flags)


def statustext(mav, severity: int, text: str) -> list:
    """One STATUSTEXT, or several chunks (MAVLink 2: 50 characters each, one id) for a longer text."""
    data = text.encode("ascii", "replace")
    if len(data) <= 50:
        return [mav.statustext_encode(severity, data)]
    statustext.counter = (getattr(statustext, "counter", 0) % 65535) + 1
    chunks = [data[k:k + 50] for k in range(0, len(data), 50)]
    if len(chunks[-1]) == 50:  # the last chunk ends with a NUL: a text of 100 characters waited for a third
        chunks.append(b"")
    return [mav.statustext_encode(severity, chunk, statustext.counter, n) for n, chunk in enumerate(chunks)]


def event_text(name: str, fields: dict) -> tuple[int, str] | None:
    """The STATUSTEXT of a log event, or None for events the operator does not need on screen."""
    f = fields
    if name == "fault":
        return mavlink.MAV_SEVERITY_WARNING, f"fault {f.get('cause')}: {f.get('detail')}"
    if name == "failsafe":
        extra = f" ({f['fallback']})" if f.get("fallback") else ""
        return mavlink.MAV_SEVERITY_CRITICAL, f"failsafe {f.get('cause')}: {f.get('action')}{extra}"
    if name == "fault_cleared":
        return mavlink.MAV_SEVERITY_INFO, f"cleared {f.get('cause')}"
    if name == "resume":
        return mavlink.MAV_SEVERITY_INFO, f"resumed after {f.get('cause')}"
    if name == "mode":  # with the planner's name of it: "mode hold" came for the LOITER chosen (a GCS audit)
        try:
            shown = f" ({rover_mode_name(f.get('mode'), f.get('cause'))})"
        except (ValueError, KeyError):
            shown = ""
        return mavlink.MAV_SEVERITY_INFO, f"mode {f.get('mode')}{shown}: {f.get('cause')}"
    if name == "command" and not f.get("accepted"):
        return mavlink.MAV_SEVERITY_WARNING, str(f.get("answer"))
    if name == "arming":
        return mavlink.MAV_SEVERITY_NOTICE, ("armed" if f.get("armed") else "disarmed") + f" ({f.get('cause')})"
    if name == "speed":  # every station sees it, and a new or cleared mission giving the planned speeds back
        v = f.get("speed_m_s")
        return mavlink.MAV_SEVERITY_NOTICE, (f"speed {v:g} m/s on every leg" if v is not None
                                             else "speed: the mission's planned speeds") + f" ({f.get('cause')})"
    if name == "gcs":
        action = f.get("action")
        return mavlink.MAV_SEVERITY_WARNING, f"ground station {f.get('state')}" + (f": {action}" if action else "")
    if name == "hold_off":
        if f.get("off"):
            return mavlink.MAV_SEVERITY_WARNING, (f"hold: {f.get('error_m')} m off the point for {f.get('for_s')} s "
                                                  f"(estimated disturbance {f.get('disturbance_n')} N a thruster)")
        if f.get("error_m") is None:
            return mavlink.MAV_SEVERITY_INFO, "hold ended off its point"
        return mavlink.MAV_SEVERITY_INFO, f"hold: back within {f.get('limit_m')} m of the point"
    if name == "speed_short":
        if f.get("short"):
            more = "thrusters at full" if f.get("thrusters_full") else f"speed trim at its {f.get('limit_n')} N limit"
            return mavlink.MAV_SEVERITY_WARNING, (f"speed {f.get('speed_m_s')} of {f.get('wanted_m_s')} m/s for "
                                                  f"{f.get('for_s')} s ({more})")
        return mavlink.MAV_SEVERITY_INFO, "speed: no longer short (made, or the course ended)"
    if name == "waypoint_occupied":
        return mavlink.MAV_SEVERITY_WARNING, (f"waypoint {f.get('wp_index')} occupied by vessel {f.get('target')}: "
                                              f"passed at {f.get('distance_m')} m")
    if name == "mission_replaced":
        return mavlink.MAV_SEVERITY_INFO, f"mission: {len(f.get('waypoints') or [])} waypoint(s)"
    if name == "param":
        return mavlink.MAV_SEVERITY_INFO, f"{f.get('param')} = {f.get('new')}"
    if name == "position_jump":
        if f.get("accepted"):
            return mavlink.MAV_SEVERITY_NOTICE, f"GPS position moved {f.get('distance_m', 0.0):.0f} m (two fixes agree)"
        if f.get("repeated"):  # once a second while the fixes disagree: the first said it, position_stale follows
            return None
        return mavlink.MAV_SEVERITY_WARNING, f"GPS jump of {f.get('distance_m', 0.0):.0f} m refused"
    if name == "hold_heading" and f.get("across"):
        return mavlink.MAV_SEVERITY_WARNING, (f"hold heading {f.get('heading_deg', 0.0):.0f}: current across it, "
                                              f"point not held (try {f.get('feasible_heading_deg', 0.0):.0f})")
    if name == "mission_complete":  # "mission complete" came before the mission's own RTL item ran (a GCS audit)
        return mavlink.MAV_SEVERITY_INFO, ("mission waypoints done: returning to launch" if f.get("rtl")
                                           else "mission complete")
    if name == "info" and f.get("message") == "log write failed":  # the boat's own record is going: say so
        return mavlink.MAV_SEVERITY_ERROR, f"log write failed: {f.get('error')}"
    if name == "info" and f.get("message") == "state not saved":  # a restart after a crash would not know the run
        return mavlink.MAV_SEVERITY_ERROR, f"state not saved (restart would not resume safely): {f.get('error')}"
    return None
