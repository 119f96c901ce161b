"""The mission log's schema: every line, field, unit, mode, heading source, event and stop reason, once.

The daemon writes its lines from these declarations, the review's reader and
sysid's log reader read by them, the synthetic log writer writes them, and
``docs/log-schema.md`` is generated from this module (``python -m
autopilot.logschema > docs/log-schema.md``; a test keeps the two equal).
Readers ignore keys they do not know, so adding a field is compatible.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

__all__ = [
    "Field",
    "EventSpec",
    "Mode",
    "MODES",
    "TIME_STOP_CAUSE",
    "time_stop_words", "started_at_words",
    "HEADING_SOURCES",
    "COG_HEADING_SOURCE",
    "COURSE_FOR_HEADING",
    "COMPASS_BACK",
    "FAULT_CAUSES",
    "LATCHED_CAUSES",
    "FAILSAFE_ACTIONS",
    "COMMANDS",
    "STOP_REASONS",
    "INFO_MESSAGES",
    "CYCLE",
    "CYCLE_KEYS",
    "EVENTS",
    "EVENT_NAMES",
    "render_markdown",
]


@dataclass(frozen=True)
class Field:
    """One key of a log line: its JSON type, unit ("-" for none) and meaning."""

    name: str
    type: str  # "float", "int", "bool", "string", "list", "mapping", "any"
    unit: str
    doc: str

    @property
    def numeric(self) -> bool:
        """Stored by the review's reader as a float column (bools as 0/1)."""
        return self.type in ("float", "int", "bool")


@dataclass(frozen=True)
class EventSpec:
    name: str
    doc: str
    fields: tuple[Field, ...] = ()


class Mode(str, enum.Enum):
    """What the daemon is doing in a cycle (the ``mode`` of every cycle line)."""

    WAITING = "waiting"  # waiting for valid data before control starts (zero thrust)
    AUTO = "auto"  # flying the mission (a hold item holds station inside it)
    HOLD = "hold"  # station keeping at a point (commanded, a failsafe action, or the mission's end)
    PAUSED = "paused"  # holding where it was; resume continues from the same waypoint
    RTL = "rtl"  # returning to the launch point, then hold there
    STOP = "stop"  # zero thrust, latched until commanded
    FAILSAFE = "failsafe"  # a sensor or link fault: zero thrust until the data are valid again
    COMPLETE = "complete"  # the mission ended with stop: zero thrust, the run ends
    MANUAL = "manual"  # the operator's sticks (MAVLink MANUAL_CONTROL) through the allocation

    def __str__(self) -> str:
        return self.value


MODES: tuple[str, ...] = tuple(m.value for m in Mode)
# causes of `mode` lines that the review reads back (time under a failsafe's action)
FAILSAFE_CAUSE_PREFIX = "failsafe "  # a mode a failsafe took: "failsafe battery_low"
RTL_ARRIVED_CAUSE = "rtl: at the launch point"  # rtl's own hand-over to the hold at launch
TIME_STOP_CAUSE = "max_mission_time"  # the latched failsafe whose stop a daemon may stay up after


def time_stop_words(mode: str | None, held_s: float) -> str:
    """How a run that stayed up after max_mission_time's stop spent the time before it, in the daemon's end summary
    and the review's alike: "then in hold for 1560 s until max_mission_time stopped it" (whole seconds, tenths
    under 10 s); "then in stop" alone left a 26-min final hold unsaid (a review audit)."""
    held = ("an unknown time" if held_s is None or not math.isfinite(held_s)
            else f"{held_s:.0f} s" if held_s >= 10.0 else f"{held_s:.1f} s")
    return f"then in {mode or 'an unknown mode'} for {held} until {TIME_STOP_CAUSE} stopped it"


def started_at_words(start_index: int) -> str:
    """How a run carried on from an earlier one is said, in the daemon's end summary and the review's alike:
    " (this run started at W2: W0-W1 were an earlier run's)"; "" for a run from its first waypoint."""
    if not start_index:
        return ""
    before = "W0 was" if start_index == 1 else f"W0-W{start_index - 1} were"
    return f" (this run started at W{start_index}: {before} an earlier run's)"


MISSION_RTL_CAUSE = "mission: return to launch"  # a mission's own rtl, after its route (a restart resumes it)
COG_HEADING_SOURCE = "COG"  # the heading steered on is the course over ground (failsafe.cog_fallback): no compass
COURSE_FOR_HEADING = "steering on course over ground: compass lost"  # the info lines that say it begins and ends
COMPASS_BACK = "compass heading back"
HEADING_SOURCES: tuple[str, ...] = ("THS", "HDT", "PFEC_GPatt", COG_HEADING_SOURCE)  # the driver's priority, then the fallback
FAULT_CAUSES: tuple[str, ...] = (
    "heading_stale",
    "heading_invalid",
    "heading_frozen",
    "position_stale",
    "no_fix",
    "mbed_ack_missing",
    "compass_port_lost",
    "mbed_port_lost",
    "nmea_garbage",
    "mbed_garbage",
    "geofence",
    "max_mission_time",
    "max_distance",
    "battery_low",
    "battery_critical",
)
LATCHED_CAUSES = frozenset({"geofence", "max_mission_time", "max_distance", "battery_low", "battery_critical"})
# what a failsafe may do (ArduPilot's FS_ACTION); "stop" needs nothing, the others a position and a heading
FAILSAFE_ACTIONS: tuple[str, ...] = ("stop", "hold", "rtl")
COMMANDS: tuple[str, ...] = ("status", "hold", "pause", "resume", "rtl", "stop", "arm", "disarm", "speed")  # autopilot ctl's
# served and queued whatever the load (the control socket's connections, the loop's queue): each only takes thrust away
NEVER_REFUSED: frozenset[str] = frozenset({"stop", "disarm"})
# "failsafe": a campaign's replay only (autopilot campaign --replay), a run the campaign ended where a latched failsafe
# took the boat (the daemon stays up at zero thrust there); its log said "signal", with no signal (a new user's test)
STOP_REASONS: tuple[str, ...] = ("signal", "complete", "error", "max_mission_time", "failsafe")
INFO_MESSAGES: tuple[tuple[str, str], ...] = (
    ("port_opened, port_lost, port_open_failed, nmea_garbage, mbed_garbage, nmea_old_epoch, mbed_echo_mismatch",
     "device events from the drivers, with `device` (`sc30` or `mbed`) and their context"),
    ("mbed_ack_late", "an acknowledgement came after `serial.ack_timeout_s` (its command was already counted missing): the board answers, late (`seq`, `late_ms`); once until an answer comes in time"),
    ("mbed_unexpected_ack", "an acknowledgement for no command sent recently (a stray line, another program on the port): ignored, its battery voltage too (`seq`, `battery_v`); once until an answer comes in time"),
    (COURSE_FOR_HEADING, "`failsafe.cog_fallback`: the compass's heading lost, the "
     "course over ground is the heading steered on (`heading_source` COG in the cycle lines) until the compass "
     "answers again"),
    (COMPASS_BACK, "the compass's heading steered on again after a course over ground"),
    ("data valid: control starts", "first transition out of `waiting` (`valid_for_s`)"),
    ("ready: SC-30 and Mbed answer", "READY=1 sent to systemd"),
    ("devices not answering", "after `ready_timeout_s` (`sc30_heard`, `mbed_heard`)"),
    ("holding zero thrust: ...", "an interrupted mission found in the state directory and resuming is not configured"),
    ("resuming interrupted mission at waypoint N", "`failsafe.resume_after_restart: true`"),
    ("control loop error", "an exception in the loop (`error`); the boat is stopped"),
    ("mavlink link open", "the MAVLink endpoints are open (`endpoints`, `signing`)"),
    ("mavlink message not handled", "a message that broke its handler (`kind`, `error`), once per kind: a bug to report"),
    ("mavlink message not sent", "a message of ours that did not encode (`kind`, `error`), once per kind: a bug to report"),
    ("mavlink link closed", "at the end: what the link received (`stats`: messages by type, bad frames, dropped datagrams, refusals)"),
    ("start refused", "an endpoint could not be opened (`error`); the run stops, exit 2"),
    ("state not saved", "the progress file could not be written (`error`; a full disk, a read-only state directory): a restart after a crash would not know this run was interrupted; also said to the ground station"),
    ("log write failed", "not in the file: on the console (journal) and to the ground station, once, when the log's writes start failing (a full disk; `path`, `error`); the boat goes on being controlled"),
    ("log writes resumed", "the first line after writes failed: how many lines were lost (`lines_lost`) and why (`error`)"),
    ("commands refused: queue full", "operator commands arrived faster than the loop carries them out (5 a cycle) and 100 were waiting: the next are refused at once (`queued`, `source`), once per flood"),
    ("ctl refusals not logged", "more than 10 refused control-socket requests in a second (a looping client): the rest were answered but not logged one by one; how many (`count`), said once the second is over"),
    ("zero-thrust on stop failed", "the final command could not be sent (`error`)"),
    ("mission complete: staying up", "the mission ended stopped, and a ground station link is open or systemd runs the "
     "daemon (`why`): it goes on at zero thrust, reporting and taking commands (rtl, hold, a new mission), until "
     "stopped; without either it ends there"),
    ("max_mission_time: stopped, staying up", "`failsafe.max_mission_time_s` ran out with its action stop, and a "
     "ground station link is open or systemd runs the daemon (`why`): as at a mission's end it goes on at zero "
     "thrust, reporting and taking commands, until stopped; the run is saved as ended by max_mission_time, so a "
     "restart does not fly it again; without either the daemon ends there (stop reason `max_mission_time`)"),
)


def _f(name: str, type_: str, unit: str, doc: str) -> Field:
    return Field(name, type_, unit, doc)


COMMON: tuple[Field, ...] = (
    _f("timestamp", "string", "-", "wall-clock UTC, ISO 8601 with `Z`"),
    _f("event", "string", "-", "the line's event name (below)"),
    _f("t_s", "float", "s", "mission time: seconds since `mission_start` on the daemon's (possibly sped-up, simulated) monotonic clock"),
)

CYCLE: tuple[Field, ...] = (
    _f("cycle", "int", "-", "cycle counter from 0"),
    _f("mode", "string", "-", "one of " + ", ".join(f"`{m}`" for m in MODES) + " (see Modes)"),
    _f("lat_deg", "float", "deg", "latitude of the last position fix (null when none yet)"),
    _f("lon_deg", "float", "deg", "longitude of the last position fix"),
    _f("north_m", "float", "m", "the last fix in the local frame around the origin (null when none)"),
    _f("east_m", "float", "m", "see `north_m`"),
    _f("est_north_m", "float", "m", "position the guidance used: the fix dead-reckoned by SOG/COG over its age, at most `dead_reckon_max_s` (null when not steering)"),
    _f("est_east_m", "float", "m", "see `est_north_m`"),
    _f("heading_deg", "float", "deg", "heading used this cycle, [0, 360) (null when none)"),
    _f("heading_source", "string", "-", "one of " + ", ".join(f"`{s}`" for s in HEADING_SOURCES) + " (fallback), or null"),
    _f("yaw_rate_deg_s", "float", "deg/s", "rate of turn (ROT, or differentiated heading); + = to starboard"),
    _f("sog_m_s", "float", "m/s", "speed over ground"),
    _f("cog_deg", "float", "deg", "course over ground"),
    _f("fix_quality", "int", "-", "GGA fix quality (0 = no fix)"),
    _f("heading_age_s", "float", "s", "age of the heading used: it was measured at `t_s - heading_age_s`"),
    _f("position_age_s", "float", "s", "age of the last fix: it was measured at `t_s - position_age_s`; a row repeating a held fix is not a new measurement"),
    _f("wp_index", "int", "-", "index of the waypoint being steered to (0-based)"),
    _f("tcpa_nd", "float", "-", "TCPA' of the fuzzy guidance (null for other laws)"),
    _f("dcpa_nd", "float", "-", "DCPA' of the fuzzy guidance (null for other laws)"),
    _f("cdh", "float", "-", "CDH of the fuzzy guidance (null for other laws)"),
    _f("psi_d_deg", "float", "deg", "desired heading [0, 360)"),
    _f("heading_error_deg", "float", "deg", "psi_d - psi wrapped to (-180, 180]"),
    _f("xte_m", "float", "m", "signed cross-track error from the current leg (+ = starboard of the leg)"),
    _f("speed_cmd_m_s", "float", "m/s", "wanted speed"),
    _f("pid_p_n", "float", "N", "PID proportional term (tau_order = p + i + d)"),
    _f("pid_i_n", "float", "N", "PID integral term"),
    _f("pid_d_n", "float", "N", "PID derivative term"),
    _f("tau_com_n", "float", "N", "common-mode thrust (Eq 8.5-8.6)"),
    _f("tau_com_trim_n", "float", "N", "the speed-over-ground trim inside `tau_com_n` (table feed-forward = `tau_com_n - tau_com_trim_n`)"),
    _f("tau_order_n", "float", "N", "differential thrust asked of the allocation (Eq 8.5-8.6)"),
    _f("thrust_port_n", "float", "N", "commanded thrust after saturation (negative = reverse)"),
    _f("thrust_stbd_n", "float", "N", "see `thrust_port_n`"),
    _f("pwm_port_pct", "float", "%", "commanded duty, signed: negative = reverse (clockwise)"),
    _f("pwm_stbd_pct", "float", "%", "see `pwm_port_pct`"),
    _f("sat_port", "bool", "-", "that side hit its thrust limit"),
    _f("sat_stbd", "bool", "-", "see `sat_port`"),
    _f("saturation", "list", "-", "limits the thrusters' requests went past: `port_upper`, `port_lower`, `stbd_upper`, `stbd_lower`"),
    _f("turn_limit", "int", "-", "the turn the allocation could not deliver in full: +1 to starboard, -1 to port, 0 none (the heading integral may not grow towards it)"),
    _f("common_limit", "int", "-", "the common thrust cut: +1 down (the speed cannot be delivered), -1 up, 0 none"),
    _f("hold_north_m", "float", "m", "the point station keeping holds (null when not holding)"),
    _f("hold_east_m", "float", "m", "see `hold_north_m`"),
    _f("hold_error_m", "float", "m", "distance from the estimated position to that point"),
    _f("holding", "bool", "-", "the hold proper (what `hold_s` times and the scores count); false while station keeping only closes on the point (the last `gnc.hold.approach_m`)"),
    _f("hold_heading_deg", "float", "deg", "the heading station keeping holds: the given one, or the least-effort one it chose"),
    _f("hold_disturbance_n", "float", "N", "station keeping's estimate of the thrust per thruster the current and wind take (along `hold_heading_deg`)"),
    _f("battery_v", "float", "V", "battery voltage from the Mbed's last acknowledgement, under load (null: the firmware does not report it)"),
    _f("battery_rest_v", "float", "V", "the resting voltage estimate the battery failsafe judges: `battery_v` + `failsafe.battery_sag_v` x (d_port^3 + d_stbd^3) / 2"),
    _f("lateness_ms", "float", "ms", "how late this cycle started after its absolute deadline"),
    _f("skipped_cycles", "int", "-", "deadlines skipped so far because the loop fell more than a period behind (cumulative)"),
    _f("heading_latency_ms", "float", "ms", "time from the heading's measurement (its compass tick: drivers/line_timing.py) to this command"),
    _f("seq", "int", "-", "Mbed command sequence number sent (-1: the command could not be written)"),
    _f("ack_missing", "int", "-", "Mbed acknowledgements missing so far (cumulative)"),
    _f("nmea_dropped", "int", "-", "NMEA lines dropped so far (bad checksum, garbage; cumulative)"),
    _f("active_faults", "list", "-", "failsafe causes active this cycle (empty when none)"),
    _f("avoid_active", "bool", "-", "collision avoidance changed the course or the speed this cycle (null: no targets, or not steering)"),
    _f("avoid_psi_share_deg", "float", "deg", "avoidance's share of psi_d: psi_d minus the mode's own, + = to starboard"),
    _f("avoid_speed_factor", "float", "-", "the wanted speed over the mode's own (1: unchanged)"),
    _f("avoid_targets", "int", "-", "targets assessed (AIS, fresh, able to come within the safe distance inside the encounter horizon; at most 48 besides those in an encounter)"),
    _f("avoid_target", "int", "-", "the target most at risk (MMSI)"),
    _f("avoid_situation", "string", "-", "its COLREGs situation: `head-on`, `crossing-give-way`, `crossing-stand-on`, `overtaking`, `overtaken`, `safe`"),
    _f("avoid_risk", "float", "-", "its fuzzy collision risk (0..1, from DCPA' and TCPA')"),
    _f("avoid_range_m", "float", "m", "its range"),
    _f("avoid_dcpa_m", "float", "m", "its distance at the closest point of approach"),
    _f("avoid_tcpa_s", "float", "s", "time to that point"),
    _f("avoid_reason", "string", "-", "why the avoidance does what it does, one sentence"),
    _f("armed", "bool", "-", "armed: false = disarmed (MAVLink or `autopilot ctl disarm`): zero thrust whatever the mode, latched until armed"),
)
CYCLE_KEYS: tuple[str, ...] = tuple(f.name for f in CYCLE)

_CAUSE = _f("cause", "string", "-", "one of " + ", ".join(f"`{c}`" for c in FAULT_CAUSES))
_RECOVERY = (_CAUSE, _f("valid_for_s", "float", "s", "how long the data have been valid"))

EVENTS: tuple[EventSpec, ...] = (
    EventSpec("mission_start", "first line of every log", (
        _f("mission", "string", "-", "mission file path"),
        _f("mission_name", "string", "-", "the mission's name"),
        _f("guidance", "string", "-", "guidance law (`fuzzy`, `los`, `proportional`)"),
        _f("rate_hz", "float", "Hz", "control rate"),
        _f("sim", "bool", "-", "bench run against simulated devices"),
        _f("speedup", "float", "-", "simulated time runs this many times faster than real time"),
        _f("origin_lat_deg", "float", "deg", "local-frame origin"),
        _f("origin_lon_deg", "float", "deg", "local-frame origin"),
        _f("waypoints", "list", "m", "list of `[north_m, east_m]`"),
        _f("waypoint_speeds_m_s", "list", "m/s", "speed of the leg to each waypoint (null = default)"),
        _f("boat_length_m", "float", "m", "L of the fuzzy guidance"),
        _f("config", "mapping", "-", "the whole configuration"),
        _f("version", "string", "-", "package version"),
        _f("start_index", "int", "-", "waypoint the mission starts at: 0, or the saved one after a restart"),
        _f("sc30_port", "string", "-", "compass port path"),
        _f("mbed_port", "string", "-", "thruster board port path"),
        _f("pid", "int", "-", "process id"),
    )),
    EventSpec("cycle", "one per control cycle (the table above)", CYCLE),
    EventSpec("waypoint_reached", "the guidance counted a waypoint reached and switched to the next", (
        _f("wp_index", "int", "-", "the waypoint"),
        _f("north_m", "float", "m", "the position the guidance used (as `est_north_m`)"),
        _f("east_m", "float", "m", "see `north_m`"),
        _f("distance_m", "float", "m", "distance to the waypoint at the switch"),
        _f("how", "string", "-", "`capture` (within `capture_radius_m`), `passed` (the law's own test: TCPA' < 0 for the fuzzy law) or `occupied` (a stopped vessel's safe distance covers it and the boat came as near as it may: `waypoint_occupied`)"),
    )),
    EventSpec("waypoint_occupied", "the waypoint lies inside a (nearly) stopped vessel's safe distance (plus its extent) and the boat came as near as the rules allow: counted reached (`how` `occupied`) and the mission goes on", (
        _f("wp_index", "int", "-", "the waypoint"),
        _f("target", "int", "-", "the vessel's MMSI"),
        _f("name", "string", "-", "its name, if known"),
        _f("distance_m", "float", "m", "the boat's distance to the waypoint then"),
        _f("need_m", "float", "m", "the distance the rules keep from the vessel (safe distance + its extent)"),
        _f("target_to_waypoint_m", "float", "m", "the vessel's distance to the waypoint"),
    )),
    EventSpec("waypoint_pass", "a waypoint's pass ended: its closest approach (autopilot.gnc.passes)", (
        _f("wp_index", "int", "-", "the waypoint"),
        _f("closest_approach_m", "float", "m", "smallest distance of a position fix measured during the pass (null: no fix)"),
        _f("closest_t_s", "float", "s", "mission time that fix was measured"),
        _f("closest_north_m", "float", "m", "that fix"),
        _f("closest_east_m", "float", "m", "that fix"),
        _f("fixes", "int", "-", "fixes in the pass"),
    )),
    EventSpec("mission_complete", "the route done: the last waypoint reached and its hold item, if it has one, over "
              "(before 2026-12-06 logged when that hold item began)", (
        _f("wp_count", "int", "-", "waypoints in the mission"),
        _f("rtl", "bool", "-", "the mission ends with its return to launch, which begins now (a planner is told the "
           "waypoints are done, not the mission; null in logs before 2026-12-06)"),
    )),
    EventSpec("fault", "a failsafe cause appeared (once per cause until it clears)", (
        _CAUSE, _f("detail", "string", "-", "what was seen"))),
    EventSpec("fault_cleared", "a cause went away", (_CAUSE,)),
    EventSpec("failsafe", "a fault took the boat out of the operator's mode, or (`stop`) stopped it", (
        _CAUSE,
        _f("action", "string", "-", "the action taken: " + ", ".join(f"`{a}`" for a in FAILSAFE_ACTIONS)),
        _f("configured", "string", "-", "the action configured for the cause (`failsafe.actions`)"),
        _f("fallback", "string", "-", "why the configured action was not taken (it needs a position and a heading; a stronger action a fault took before stands), or null"),
    )),
    EventSpec("failsafe_cleared", "no cause for `failsafe.resume_valid_s`", _RECOVERY),
    EventSpec("resume", "the GNC drives again (integrators reset)", _RECOVERY),
    EventSpec("mode", "the mode changed (the mission's own steps, an operator command, a failsafe)", (
        _f("mode", "string", "-", "the new mode"),
        _f("from", "string", "-", "the mode before"),
        _f("cause", "string", "-", "why: `ctl hold`, `failsafe battery_low`, `mission: hold at waypoint 2`, ..."),
    )),
    EventSpec("command", "an operator command arrived (`autopilot ctl`, the MAVLink link)", (
        _f("command", "string", "-", "one of " + ", ".join(f"`{c}`" for c in COMMANDS) + ", or what was sent when malformed"),
        _f("source", "string", "-", "`ctl` (the Unix socket) or `mavlink`"),
        _f("accepted", "bool", "-", "the command was carried out"),
        _f("answer", "string", "-", "the new mode, or the refusal (`rtl refused: position stale`)"),
    )),
    EventSpec("speed", "the operator's speed for the legs of the mission and of a return set, or the planned speeds given back", (
        _f("speed_m_s", "float", "m/s", "the speed over ground wanted on every leg (turns and arrivals still slow it); null: the mission's planned speeds"),
        _f("cause", "string", "-", "who: `ctl speed`, `mavlink speed` (DO_CHANGE_SPEED), `mavlink mission` (a new mission gives its own back), a restart carrying the run on"),
    )),
    EventSpec("arming", "armed or disarmed (disarmed: zero thrust, latched until armed)", (
        _f("avoid_active", "bool", "-", "collision avoidance changed the course or the speed this cycle (null: no targets, or not steering)"),
    _f("avoid_psi_share_deg", "float", "deg", "avoidance's share of psi_d: psi_d minus the mode's own, + = to starboard"),
    _f("avoid_speed_factor", "float", "-", "the wanted speed over the mode's own (1: unchanged)"),
    _f("avoid_targets", "int", "-", "targets assessed (AIS, fresh, able to come within the safe distance inside the encounter horizon; at most 48 besides those in an encounter)"),
    _f("avoid_target", "int", "-", "the target most at risk (MMSI)"),
    _f("avoid_situation", "string", "-", "its COLREGs situation: `head-on`, `crossing-give-way`, `crossing-stand-on`, `overtaking`, `overtaken`, `safe`"),
    _f("avoid_risk", "float", "-", "its fuzzy collision risk (0..1, from DCPA' and TCPA')"),
    _f("avoid_range_m", "float", "m", "its range"),
    _f("avoid_dcpa_m", "float", "m", "its distance at the closest point of approach"),
    _f("avoid_tcpa_s", "float", "s", "time to that point"),
    _f("avoid_reason", "string", "-", "why the avoidance does what it does, one sentence"),
    _f("armed", "bool", "-", "the new state"),
        _f("cause", "string", "-", "who: `ctl disarm`, `mavlink disarm`, ..."),
    )),
    EventSpec("mission_replaced", "a new mission replaced the running one between two cycles (MAVLink upload, or cleared)", (
        _f("source", "string", "-", "`mavlink`"),
        _f("waypoints", "list", "m", "the new waypoints, `[north_m, east_m]` (empty: cleared)"),
        _f("path", "string", "-", "where it was saved (the state directory), so a restart continues it; null when cleared"),
        _f("sha256", "string", "-", "its content's hash (the progress file names it)"),
    )),
    EventSpec("param", "a parameter was set over the link (applied between two cycles)", (
        _f("param", "string", "-", "MAVLink parameter name"),
        _f("key", "string", "-", "the configuration key it is (`gnc.pid.kp_n_per_deg`)"),
        _f("old", "float", "-", "value before, in the key's unit"),
        _f("new", "float", "-", "value after"),
        _f("source", "string", "-", "`mavlink`"),
    )),
    EventSpec("gcs", "the ground station's heartbeat was lost or came back (`mavlink.gcs_timeout_s`)", (
        _f("state", "string", "-", "`lost` or `back`"),
        _f("silent_s", "float", "s", "how long its heartbeat had been silent (wall time)"),
        _f("action", "string", "-", "lost: the configured `mavlink.gcs_lost_action` (`continue`, `hold`, `rtl`)"),
    )),
    EventSpec("encounter", "a target's COLREGs situation, or whether the boat acts for it, changed", (
        _f("target", "int", "-", "MMSI"),
        _f("name", "string", "-", "the vessel's name from its static report (null before one)"),
        _f("situation", "string", "-", "as `avoid_situation`"),
        _f("rule", "string", "-", "the rule that applies (`rule 14`, `rule 15/16`, ...)"),
        _f("acting", "bool", "-", "the boat alters course or speed for it"),
        _f("risk", "float", "-", "fuzzy collision risk"),
        _f("range_m", "float", "m", "range"),
        _f("dcpa_m", "float", "m", "distance at the closest point of approach"),
        _f("tcpa_s", "float", "s", "time to it"),
        _f("reason", "string", "-", "why"),
    )),
    EventSpec("target", "an AIS position report of another vessel arrived (at most one line a second per target)", (
        _f("target", "int", "-", "MMSI"),
        _f("name", "string", "-", "name (null before its static report)"),
        _f("north_m", "float", "m", "its reported position in the local frame"),
        _f("east_m", "float", "m", "see `north_m`"),
        _f("course_deg", "float", "deg", "course over ground"),
        _f("speed_m_s", "float", "m/s", "speed over ground"),
        _f("heading_deg", "float", "deg", "heading (null when not reported)"),
        _f("length_m", "float", "m", "length from its static report (null when unknown)"),
        _f("age_s", "float", "s", "age of the report when logged"),
    )),
    EventSpec("position_jump", "a new fix was too far from the last one used (`failsafe.position_jump_m`): refused, or re-anchored to when the next fix agreed with it", (
        _f("lat_deg", "float", "deg", "the fix as the receiver gave it"),
        _f("lon_deg", "float", "deg", "see `lat_deg`"),
        _f("distance_m", "float", "m", "its distance from the last fix used"),
        _f("gate_m", "float", "m", "the farthest it could have been: `position_jump_m` + the speed bound x the time between the two fixes (autopilot.gnc.navigation.jump_speed_bound_m_s: the receiver's speed over ground + a margin, or `max_sog_m_s` without one)"),
        _f("accepted", "bool", "-", "false: refused, the last fix is kept (and ages); true: a second fix agreed, the position moved there"),
        _f("repeated", "bool", "-", "refused while another refused fix was waiting: far fixes that do not agree (the ground station is told of the first only)"),
    )),
    EventSpec("hold_heading", "a hold at a given heading (`autopilot ctl hold --heading`, MAVLink's yaw) cannot keep its point: the current and wind it has learned lie across that heading by more than `gnc.hold.max_correction_deg` (the boat cannot push sideways; it keeps the heading and sits off the point); or it can again", (
        _f("across", "bool", "-", "true: cannot keep the point at this heading; false: can again (or a new hold took its place)"),
        _f("heading_deg", "float", "deg", "the heading held"),
        _f("feasible_heading_deg", "float", "deg", "(across) the direction of the disturbance: bow (or stern) this way holds the point (a hold without a heading faces it)"),
        _f("limit_deg", "float", "deg", "(across) the heading correction station keeping may use"),
    )),
    EventSpec("hold_off", "a hold (station keeping: `hold`, a pause, a mission's hold, rtl's arrival) has been farther than `gnc.hold.off_warn_m` from its point for `gnc.hold.off_warn_s`: it is not keeping it (a current or wind it cannot stem or settle against); or it is back within that distance, or the hold ended", (
        _f("off", "bool", "-", "true: off its point; false: back (or the hold ended)"),
        _f("error_m", "float", "m", "the distance from the point now (absent when the hold ended)"),
        _f("for_s", "float", "s", "(off) how long it has been that far"),
        _f("limit_m", "float", "m", "`gnc.hold.off_warn_m`"),
        _f("disturbance_n", "float", "N", "(off) station keeping's estimate of the thrust per thruster the current and wind take"),
    )),
    EventSpec("speed_short", "on a course (`auto`, `rtl`, `guided`), the boat has been slower than its wanted speed by more than `gnc.speed.short_margin_m_s` for `gnc.speed.short_warn_s` with nothing more to give: the speed trim or its integral at its bound (`trim_limit_n`, `integral_limit_n`), or the thrusters at full (a headwind or current more than it may stem; it may be losing ground); or it makes its speed again (within half the margin), or the course ended. With `thrusters_full` false the thrusters had more to give: larger `trim_limit_n` and `integral_limit_n` would use it", (
        _f("short", "bool", "-", "true: short of its speed; false: it makes it again (or the course ended)"),
        _f("speed_m_s", "float", "m/s", "(short) the speed over ground made along the heading (negative: going astern)"),
        _f("wanted_m_s", "float", "m/s", "(short) the speed the guidance asks for"),
        _f("for_s", "float", "s", "(short) how long it has been short with nothing more to give"),
        _f("limit_n", "float", "N", "`gnc.speed.trim_limit_n`"),
        _f("thrusters_full", "bool", "-", "(short) the allocator cut the common thrust: the thrusters give all they have"),
    )),
    EventSpec("launch", "the launch point was set: where the boat was when control first started (`rtl` returns there; after a restart that carries on an interrupted run, that run's)", (
        _f("north_m", "float", "m", "local frame"),
        _f("east_m", "float", "m", "local frame"),
        _f("carried", "bool", "-", "true: an interrupted run's launch point, carried over a restart, not where this "
           "run's control started (the review measures leg 0 from a launch point that is not carried)"),
    )),
    EventSpec("stop", "the last line of a log unless the process was killed (SIGKILL, power loss)", (
        _f("reason", "string", "-", "one of " + ", ".join(f"`{r}`" for r in STOP_REASONS)),
        _f("signal", "string", "-", "`SIGTERM`, `SIGINT`, `SIGHUP` or null"),
        _f("ack_received", "bool", "-", "the final zero-thrust command was acknowledged within `stop_ack_timeout_s`"),
        _f("cycles", "int", "-", "cycles run"),
        _f("skipped_cycles", "int", "-", "deadlines missed by more than a period and skipped"),
        _f("late_cycles", "int", "-", "cycles that started a period or more after their deadline"),
        _f("speedup_held", "float", "-", "simulated seconds per wall second over the run (the `--speedup` actually kept)"),
        _f("nmea_dropped", "int", "-", "NMEA lines dropped"),
        _f("ack_missing", "int", "-", "Mbed acknowledgements missing"),
        _f("closest_approach_m", "list", "m", "closest approach of each waypoint's pass (null: no fix, or never reached)"),
    )),
    EventSpec("info", "`message` plus context", (
        _f("message", "string", "-", "one of the messages listed below"),
    )),
)
EVENT_NAMES: tuple[str, ...] = tuple(e.name for e in EVENTS)
_BY_NAME = {e.name: e for e in EVENTS}


def event_spec(name: str) -> EventSpec:
    return _BY_NAME[name]


def _table(fields, *, header=("key", "type", "unit", "meaning")) -> list[str]:
    rows = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    rows += [f"| `{f.name}` | {f.type} | {f.unit} | {f.doc} |" for f in fields]
    return rows


_MODE_DOCS = {
    Mode.WAITING: "waiting for valid data before control starts; zero thrust",
    Mode.AUTO: "flying the mission; a waypoint with `hold_s` or `hold: true` holds station there inside `auto`",
    Mode.HOLD: "station keeping (`autopilot/gnc/station_keeping.py`): `autopilot ctl hold`, a failsafe action, "
               "the mission's end (`gnc.guidance.final_action: hold`), or `rtl` arrived",
    Mode.PAUSED: "`autopilot ctl pause`: holding where it was; `resume` continues from the same waypoint",
    Mode.RTL: "returning to the launch point (`launch` event) with the mission's guidance law, then `hold` there",
    Mode.STOP: "zero thrust, latched until an operator command (`autopilot ctl stop`, or a failsafe action)",
    Mode.FAILSAFE: "a sensor or Mbed-link fault: zero thrust on both sides, every cycle while it lasts; the mode "
                   "before it comes back when the data have been valid for `failsafe.resume_valid_s`",
    Mode.COMPLETE: "the mission ended with `stop`: zero thrust; the run ends",
    Mode.MANUAL: "the operator drives (MAVLink `MANUAL_CONTROL`, a ground station's joystick): forward and turn "
                 "through the allocation and its limits; no input for `mavlink.manual_timeout_s` gives "
                 "`mavlink.manual_timeout_action` (hold or stop)",
}


def render_markdown() -> str:
    """docs/log-schema.md."""
    out = [
        "# Mission log schema",
        "",
        "<!-- generated by `python -m autopilot.logschema > docs/log-schema.md` from autopilot/logschema.py; edit that -->",
        "",
        "One file per mission, `<log_dir>/mission-<UTC YYYYmmddTHHMMSSZ>-<mission stem>.jsonl`,",
        "JSON lines written and flushed line by line by structlog, so a killed process loses",
        "at most the line it was writing. Every line has:",
        "",
        *_table(COMMON),
        "",
        "Readers must ignore keys they do not know. Non-finite numbers are written as `null`.",
        "",
        "## `cycle` (one per control cycle)",
        "",
        *_table(CYCLE),
        "",
        "Every key is present on every `cycle` line; values that do not exist this cycle are `null`",
        "(no position yet, no heading, GNC terms while the GNC is not stepped, `cdh`/`tcpa_nd`/`dcpa_nd`",
        "for the non-fuzzy laws). Outside `auto` and `hold` the command is zero thrust on both sides",
        "(`pwm_*_pct` = 0). `lateness_ms`, `heading_latency_ms` and the ages are measured on the daemon's",
        "clock: with `--speedup N` they are simulated milliseconds.",
        "",
        "Measurements: the SC-30 sends position at 1 Hz and heading at 10 Hz, and every cycle line",
        "repeats the latest of each. A position is a new measurement only on the first row it appears",
        "in; it was measured at `t_s - position_age_s` (likewise the heading). The driver dates each",
        "measurement, not its arrival: a heading at the compass tick it was made at, a fix when its",
        "sentence began on the line (at 4800 baud a heading waits up to ~0.25 s behind the 1 Hz",
        "sentences). Speed and course over ground are new where they change, measured with the",
        "latest fix. The review's exports and the identification use each measurement once, at its time.",
        "",
        "## Modes",
        "",
        "| mode | meaning |",
        "|---|---|",
        *[f"| `{m.value}` | {_MODE_DOCS[m]} |" for m in Mode],
        "",
        "## Events",
        "",
    ]
    for spec in EVENTS:
        if spec.name == "cycle":
            continue
        out += [f"### `{spec.name}`", "", spec.doc[0].upper() + spec.doc[1:] + ".", ""]
        if spec.fields:
            out += [*_table(spec.fields), ""]
    out += [
        "`info` messages:",
        "",
        "| message | when |",
        "|---|---|",
        *[f"| `{m}` | {w} |" for m, w in INFO_MESSAGES],
        "",
        "## Failsafe sequence",
        "",
        "A fault appears: `fault` (per cause, once). Sensor and Mbed-link faults (heading, position,",
        "ports, garbage, acknowledgements) stop the boat: one `failsafe` (action `stop`) with the first",
        "cause, mode `failsafe`, zero thrust from that cycle on. Each cause that goes away gets",
        "`fault_cleared`. When no such cause has been active for `failsafe.resume_valid_s`:",
        "`failsafe_cleared` and `resume` (same fields), the mode before comes back and the GNC drives",
        "again (integrators reset).",
        "",
        ", ".join(f"`{c}`" for c in FAULT_CAUSES if c in LATCHED_CAUSES) + " are latched: they never",
        "clear. Each takes its configured action once (`failsafe.actions`: `stop`, `hold` or `rtl`;",
        "`battery_critical` always `stop`), logged as `failsafe` and `mode`. An action that needs a",
        "position and a heading falls back to `stop` when either is missing, or when the fault is a",
        "position or heading fault (`fallback` says why). While one is latched the operator may still",
        "command `hold`, `rtl` or `stop`, but not `resume` the mission. `max_mission_time` with action",
        "`stop` ends the run (`stop`, reason `max_mission_time`).",
        "",
        "## Closest approach",
        "",
        "The pass of waypoint W_i begins with the first fix taken while W_i is the target and ends",
        "when W_{i+1} is reached, or, for the last waypoint, `gnc.guidance.final_pass_s` after",
        "`mission_complete` (or when the mission stops). Its closest approach is the smallest distance",
        "from W_i of the position fixes measured during the pass (`waypoint_pass`). The daemon logs it,",
        "`autopilot evaluate` scores it and `autopilot review` recomputes it from the logged fixes, all",
        "with `autopilot/gnc/passes.py`.",
        "",
    ]
    return "\n".join(out)


if __name__ == "__main__":  # pragma: no cover
    print(render_markdown(), end="")
