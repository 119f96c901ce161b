"""One control cycle as a short chain of pure steps (the loop in :mod:`autopilot.daemon.loop` wires them).

    NavSample --assemble--> Navigation --observe--> Observation --Failsafe.update--> Decision
    Decision.requests --answer_failsafe--> the helm's mode; operator commands --the helm (Autopilot.request)--> it
    Decision --arbitrate--> drive? --steer (the helm)--> ControlOutput --command--> ThrustCommand
    the cycle's mode, the helm --reported_mode--> the mode ctl status and the planner show
    everything --cycle_record--> the cycle line (autopilot.logschema.CYCLE)

Each step takes numbers and returns numbers: no I/O, no clock (times are arguments),
so each is tested with literals. ``assemble`` is :func:`autopilot.gnc.navigation.assemble`,
shared with ``autopilot evaluate`` and the campaigns.
"""

from __future__ import annotations

import math

from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.failsafe import Decision, Observation
from autopilot.devices import ZERO_THRUST, ThrustCommand
from autopilot.geo import wrap_180, wrap_360
from autopilot.gnc import ControlOutput, NavInput
from autopilot.gnc.navigation import Navigation, NavRules
from autopilot.logschema import CYCLE_KEYS, FAILSAFE_CAUSE_PREFIX, Mode

__all__ = ["nav_rules", "observe", "steered_error_rad", "arbitrate", "reported_mode", "answer_failsafe", "stop_in_force", "stop_stands", "step_dt_s", "nav_input", "helm_nav", "command", "cycle_record",
           "GNC_FIELDS"]

MAX_STEP_DT_S = 1.0  # a GNC step after a long pause integrates at most this much


def nav_rules(cfg: DaemonConfig) -> NavRules:
    """The navigation assembly's thresholds, from the configuration."""
    fs = cfg.failsafe
    return NavRules(heading_stale_s=fs.heading_stale_s, position_stale_s=fs.position_stale_s,
                    cog_fallback=fs.cog_fallback, cog_fallback_min_sog_m_s=fs.cog_fallback_min_sog_m_s,
                    dead_reckon_max_s=cfg.dead_reckon_max_s, position_jump_m=fs.position_jump_m,
                    fix_confirm_s=fs.position_confirm_s)


def observe(nav: Navigation, *, mission_time_s: float | None, compass_connected: bool, thrusters_connected: bool,
            acks_missing_in_a_row: int, compass_garbage_s: float | None, thruster_garbage_s: float | None,
            battery_v: float | None = None, thrusters_disobeying: bool = False,
            steered_heading_error_rad: float | None = None) -> Observation:
    """What the failsafe judges (times on the daemon's clock); ``mission_time_s`` None once the mission has ended
    with stop; ``steered_heading_error_rad``: the last cycle's (:func:`steered_error_rad`)."""
    return Observation(
        t_s=nav.t_s, heading_age_s=nav.heading_age_s, heading_valid=nav.heading_valid,
        position_age_s=nav.position_age_s, fix_quality=nav.fix_quality,
        ack_consecutive_missing=int(acks_missing_in_a_row), ack_disobeyed=bool(thrusters_disobeying),
        compass_connected=bool(compass_connected),
        mbed_connected=bool(thrusters_connected), last_garbage_t_s=compass_garbage_s,
        last_mbed_garbage_t_s=thruster_garbage_s, north_m=nav.north_m, east_m=nav.east_m,
        mission_time_s=mission_time_s, battery_v=battery_v, position_confirmed=nav.fix_confirmed,
        heading_still_turn_rad=nav.still_turn_rad, heading_still_since_s=nav.heading_still_since_s,
        steered_heading_error_rad=steered_heading_error_rad,
    )


def steered_error_rad(out: ControlOutput | None) -> float | None:
    """The heading error the helm's PID turned the boat by this cycle; None when it did not steer by the heading
    (no helm step, thrust off, the operator's sticks)."""
    if out is None or out.thrust_off or out.mode is Mode.MANUAL:
        return None
    return out.heading_error_rad


def arbitrate(decision: Decision, *, steerable: bool, manual: bool = False) -> tuple[Mode | None, bool]:
    """(the mode when the helm does not run, drive): the helm runs when the failsafe allows it and
    there is a heading and a position; then its own mode is the cycle's (None here). In ``manual`` the
    operator steers by eye: only a fault of the link to the thrusters stops the helm."""
    from autopilot.daemon.failsafe import FAULT_CLASS

    if manual:
        if any(FAULT_CLASS[c] == "mbed" for c in decision.active):
            return Mode.FAILSAFE, False
        return None, True
    if decision.mode == "waiting":
        return Mode.WAITING, False
    if not decision.thrust_allowed or not steerable:
        return Mode.FAILSAFE, False
    return None, True


def reported_mode(mode: Mode, ap) -> Mode:
    """The mode the operator is shown (``ctl status``, the planner's HEARTBEAT) for a cycle in ``mode``: before
    control starts, the helm's once something chose it (a LOITER or GUIDED asked for, waiting for control to
    start; a held start's stop), else WAITING (the planner's INITIALISING: the mission starts by itself). Shown
    WAITING, a LOITER or GUIDED set before the start looked refused on the planner, though accepted."""
    if mode is Mode.WAITING and ap.mode_chosen:
        return ap.mode
    return mode


def stop_in_force(ap) -> str | None:
    """Why the helm ``ap`` is stopped (its mode's cause: a failsafe's, the operator's, an interrupted mission's
    at start), or None when it is not: a stop is latched until an operator commands otherwise, so neither a
    failsafe's hold or rtl nor a stream of stick packets replaces it."""
    return ap.mode_cause if ap.mode is Mode.STOP else None


def stop_stands(stopped: str) -> str:
    """Why a failsafe's hold or rtl was not taken: the stop in force (its cause, :func:`stop_in_force`)."""
    return f"the stop in force ({stopped}) stands: a failsafe does not drive a stopped boat"


def answer_failsafe(ap, req, helm_nav: NavInput | None, unavailable: str) -> tuple[str, str | None]:
    """A latched fault's request to the helm ``ap``: (the action in force after it, why not the configured one).
    Overruled (a stop a fault took before stands), or the helm stopped for any other reason (``ctl stop``, an
    interrupted mission held at start) and the action not a stop: the helm is left as it is. Refused (rtl without
    a launch point): stop."""
    if req.overruled_by is not None:
        return req.overruled_by[1], req.fallback
    stopped = stop_in_force(ap)
    if stopped is not None and req.action != "stop":  # found by fault injection: ctl stop, then battery_low's rtl
        return "stop", stop_stands(stopped)
    ok, answer = ap.request(req.action, helm_nav, cause=f"{FAILSAFE_CAUSE_PREFIX}{req.cause}", unavailable=unavailable)
    if ok:
        return req.action, req.fallback
    ap.request("stop", None, cause=f"{FAILSAFE_CAUSE_PREFIX}{req.cause}")
    return "stop", answer


def helm_nav(nav: Navigation, decision: Decision) -> tuple[NavInput | None, str]:
    """What a command that needs a position and a heading may use: the navigation, or None and why not."""
    from autopilot.daemon.failsafe import FAULT_CLASS, NAV_CLASSES

    for cause in decision.active:
        if FAULT_CLASS[cause] in NAV_CLASSES:
            return None, cause.replace("_", " ")
    if not nav.steerable:
        return None, "no position and heading yet"
    return nav_input(nav), ""


def step_dt_s(now_s: float, last_step_s: float | None, period_s: float) -> float:
    """The time step of this GNC step: since the last one (a first step takes one period)."""
    if last_step_s is None:
        return period_s
    return min(max(now_s - last_step_s, 1e-3), MAX_STEP_DT_S)


def nav_input(nav: Navigation) -> NavInput:
    """The GNC's view of one cycle: the dead-reckoned position; no speed or yaw rate = 0; no course = the heading."""
    return NavInput(
        north_m=float(nav.est_north_m), east_m=float(nav.est_east_m), psi_rad=float(nav.heading_rad),
        speed_m_s=0.0 if nav.sog_m_s is None else float(nav.sog_m_s),
        yaw_rate_rad_s=0.0 if nav.yaw_rate_rad_s is None else float(nav.yaw_rate_rad_s),
        course_rad=float(nav.heading_rad) if nav.cog_rad is None else float(nav.cog_rad),
    )


def command(out: ControlOutput | None) -> ThrustCommand:
    """The thrusters' command: the GNC's, zero when it did not run or asks for none."""
    if out is None or out.thrust_off:
        return ZERO_THRUST
    return ThrustCommand(out.thrust_port_n, out.thrust_stbd_n, out.pwm_port_pct, out.pwm_stbd_pct)


AVOID_FIELDS = ("avoid_active", "avoid_psi_share_deg", "avoid_speed_factor", "avoid_targets", "avoid_target",
                "avoid_situation", "avoid_risk", "avoid_range_m", "avoid_dcpa_m", "avoid_tcpa_s", "avoid_reason")


def _avoid_fields(avoidance) -> dict:
    if avoidance is None:
        return dict.fromkeys(AVOID_FIELDS)
    f = avoidance.log_fields()
    f["avoid_active"] = bool(f["avoid_active"])
    return {k: f[k] for k in AVOID_FIELDS}


GNC_FIELDS = ("tcpa_nd", "dcpa_nd", "cdh", "xte_m", "speed_cmd_m_s", "pid_p_n", "pid_i_n", "pid_d_n", "tau_com_n",
              "tau_com_trim_n", "tau_order_n")


def _deg(x_rad: float | None, wrap) -> float | None:
    return None if x_rad is None or not math.isfinite(x_rad) else float(wrap(math.degrees(x_rad)))


def cycle_record(*, cycle: int, t_s: float, mode: Mode, nav: Navigation, out: ControlOutput | None,
                 cmd: ThrustCommand, wp_index: int, steering: bool, lateness_s: float, skipped: int,
                 heading_latency_s: float | None, seq: int, ack_missing: int, nmea_dropped: int,
                 active_faults, battery_v: float | None = None, battery_rest_v: float | None = None,
                 armed: bool = True) -> dict:
    """The cycle line: every key of :data:`autopilot.logschema.CYCLE`, in its units (degrees for people)."""
    gnc = {k: None for k in GNC_FIELDS} if out is None else {k: getattr(out, k) for k in GNC_FIELDS}
    hold = None if out is None else out.hold_target_ne_m
    rec = {
        "cycle": cycle, "mode": mode, "lat_deg": nav.lat_deg, "lon_deg": nav.lon_deg,
        "north_m": nav.north_m, "east_m": nav.east_m,
        "est_north_m": nav.est_north_m if steering else None, "est_east_m": nav.est_east_m if steering else None,
        "heading_deg": _deg(nav.heading_rad, wrap_360), "heading_source": nav.heading_source,
        "yaw_rate_deg_s": None if nav.yaw_rate_rad_s is None else math.degrees(nav.yaw_rate_rad_s),
        "sog_m_s": nav.sog_m_s, "cog_deg": _deg(nav.cog_rad, wrap_360), "fix_quality": nav.fix_quality,
        "heading_age_s": nav.heading_age_s, "position_age_s": nav.position_age_s, "wp_index": int(wp_index),
        **gnc,
        "psi_d_deg": None if out is None else _deg(out.psi_d_rad, wrap_360),
        "heading_error_deg": None if out is None else _deg(out.heading_error_rad, wrap_180),
        "thrust_port_n": float(cmd.thrust_port_n), "thrust_stbd_n": float(cmd.thrust_stbd_n),
        "pwm_port_pct": float(cmd.duty_port_pct), "pwm_stbd_pct": float(cmd.duty_stbd_pct),
        "sat_port": bool(out is not None and not out.thrust_off and out.sat_port),
        "sat_stbd": bool(out is not None and not out.thrust_off and out.sat_stbd),
        "saturation": [] if out is None or out.thrust_off else list(out.saturation),
        "turn_limit": 0 if out is None or out.thrust_off else int(out.turn_limit),
        "common_limit": 0 if out is None or out.thrust_off else int(out.common_limit),
        "hold_north_m": None if hold is None else hold[0], "hold_east_m": None if hold is None else hold[1],
        "hold_error_m": None if hold is None else out.hold_error_m,
        "holding": bool(out is not None and out.holding),
        "hold_heading_deg": None if hold is None else _deg(out.hold_heading_rad, wrap_360),
        "hold_disturbance_n": None if hold is None else out.hold_disturbance_n,
        "battery_v": battery_v, "battery_rest_v": battery_rest_v,
        **_avoid_fields(None if out is None else out.avoidance),
        "lateness_ms": lateness_s * 1e3, "skipped_cycles": int(skipped),
        "heading_latency_ms": None if heading_latency_s is None else heading_latency_s * 1e3,
        "seq": int(seq), "ack_missing": int(ack_missing), "nmea_dropped": int(nmea_dropped),
        "active_faults": list(active_faults), "armed": bool(armed),
    }
    return {k: rec[k] for k in CYCLE_KEYS}  # the schema's keys, in its order (a missing one is a KeyError here)
