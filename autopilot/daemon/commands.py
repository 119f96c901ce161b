"""What the loop does with a command between two cycles: operator, link and failsafe requests to the helm.

Every request is a dict with ``command`` and ``source`` (``ctl``, ``mavlink``), validated by whoever
submitted it (the control socket: :func:`autopilot.daemon.control.check_request`; the MAVLink link
its own messages); :func:`apply` carries it out on the loop's helm and configuration and returns the
reply (``ok``, ``answer``, ``mode``). Each is logged as a ``command`` event, accepted or not.

    hold [heading_deg] [north_m, east_m]   station keeping here (or there: MAVLink reposition)
    pause | resume | rtl | stop | arm | disarm
    manual forward_nd turn_nd              the sticks (-1..1); the first puts the boat in manual
    set_current index                      fly the mission from that waypoint
    speed speed_m_s                        the legs' speed (None: the mission's planned ones)
    mission (a Mission) | mission_clear    replace the running mission at this safe point
    param_set key value name               a configuration value, already range-checked
"""

from __future__ import annotations

import dataclasses
import math

from autopilot.daemon.cycle import answer_failsafe, stop_in_force, stop_stands
from autopilot.gnc.modes import PendingHold
from autopilot.gnc.speed import SPEED_RANGE, is_speed
from autopilot.logschema import Mode

__all__ = ["apply", "failsafe_action", "replace_key"]

QUIET = {"manual"}  # sent tens of times a second: logged when it changes the mode, not each time


def failsafe_action(loop, req, helm_nav, unavailable: str, t_s: float) -> None:
    """A latched fault's action to the helm (:func:`autopilot.daemon.cycle.answer_failsafe`), logged."""
    action, fallback = answer_failsafe(loop.ap, req, helm_nav, unavailable)
    loop.log.event("failsafe", t_s=t_s, cause=req.cause, action=action, configured=req.configured, fallback=fallback)
    loop.state.failsafe_causes.append(req.cause)


def apply(loop, request: dict, helm_nav, unavailable: str, decision, t_s: float) -> dict:
    source = str(request.get("source", "ctl"))
    command = str(request.get("command", ""))[:32]
    heading = request.get("heading_deg")
    # the heading given is part of the cause: `ctl hold --heading 270` was logged and shown as "ctl hold" (an audit)
    cause = str(request.get("cause") or f"{source} {command}" + ("" if heading is None else f" --heading {heading:g}"))
    handler = _HANDLERS.get(command, _helm)
    try:
        ok, answer = handler(loop, request, helm_nav, unavailable, cause)
    except Exception as exc:  # noqa: BLE001 - a command that breaks is refused; the loop and the boat go on
        ok, answer = False, f"{command} failed: {type(exc).__name__}: {exc} (a bug: please report it)"
    if command == "manual" and not ok and not request.get("explicit"):
        _log_sticks_ignored(loop, source, answer, t_s)
    elif command not in QUIET or not ok or answer != "manual (held)":
        loop.log.event("command", t_s=t_s, command=command, source=source, accepted=ok, answer=answer)
    reply = {"ok": ok, "answer": answer, "mode": loop.ap.mode.value}
    if ok and not loop.ap.armed and command not in ("disarm", "status"):
        # "hold" answered "hold" of a disarmed boat, drifting with zero thrust (the operator thought it held)
        reply["note"] = "disarmed: zero thrust whatever the mode until armed (autopilot ctl arm)"
    elif ok and decision.mode != "auto" and loop.ap.mode is not Mode.MANUAL:
        reply["note"] = waiting_note(decision, loop.failsafe.cfg.resume_valid_s)
        pending = loop.ap.current
        if isinstance(pending, PendingHold) and pending.target_ne_m is None:  # the point is not known yet
            reply["note"] += "; it holds where the boat is when control starts"
    return reply


def waiting_note(decision, resume_valid_s: float) -> str:
    """Why an accepted command does not move the boat yet (the failsafe holds the thrust at zero)."""
    if decision.mode != "failsafe":
        return "waiting for valid data before control starts"
    if not decision.active:  # the fault has cleared, the data must stay good a while: it said "clears: " and nothing
        return f"zero thrust until the data has been valid for {resume_valid_s:g} s (the fault has cleared)"
    return "zero thrust until the failsafe clears: " + ", ".join(decision.active)


def _helm(loop, request, helm_nav, unavailable, cause):
    command = request["command"]
    stopped = stop_in_force(loop.ap)
    if request.get("failsafe") and stopped is not None and command != "stop":
        # the link's own failsafe (ground station lost) drove a boat battery_critical had stopped, found by fault
        # injection: a failsafe never replaces a stop in force, whoever's (cycle.answer_failsafe)
        return False, f"{command} not taken: {stop_stands(stopped)}"
    latched = list(loop.failsafe.latched)
    # ... but a failsafe's rtl paused goes on home on resume: it was refused, and the boat stayed paused (an audit)
    if command in ("resume", "continue", "auto") and latched and not (command != "auto" and loop.ap.paused_on_rtl):
        return False, (f"{command} refused: {', '.join(latched)} latched (a failsafe took the boat; "
                       "hold, rtl and stop are allowed)")
    heading = request.get("heading_deg")
    target = (request["north_m"], request["east_m"]) if "north_m" in request else None
    beyond = None if target is None else _beyond_limits(loop, *_way_to(loop, helm_nav, target), legs=True)
    if beyond:  # a point given is a planner's "go here" (it was said "hold refused" for one: a GCS audit)
        return False, f"{'go here' if command == 'hold' else command} refused: {beyond}"
    if target is not None and helm_nav is None and not loop.ap.started and loop.failsafe.fence_ne_m is not None:
        # before control starts there is no position to check the way there against a geofence (a concave one may
        # lie across it): taken, the boat crossed an L-shaped fence's corner once control started (a review)
        return False, ("go here refused: no position yet to check the way there against the geofence (control has "
                       "not started); ask again once it has, or hold here")
    return loop.ap.request(command, helm_nav, cause=cause, unavailable=unavailable, target_ne_m=target,
                           heading_rad=None if heading is None else math.radians(float(heading)))


def _log_sticks_ignored(loop, source: str, answer: str, t_s: float) -> None:
    """Stick input outside MANUAL, logged (and so shown on the planner) once a second with how many were not: a
    joystick's 25 packets a second were 25 command lines and 75 STATUSTEXT frames a second."""
    st, now = loop.state, loop.clock.wall_elapsed_s()
    if now - st.sticks_ignored_logged_wall_s < 1.0:
        st.sticks_ignored_unlogged += 1
        return
    more = f" ({st.sticks_ignored_unlogged} more since the last said)" if st.sticks_ignored_unlogged else ""
    loop.log.event("command", t_s=t_s, command="manual", source=source, accepted=False, answer=answer + more)
    st.sticks_ignored_logged_wall_s, st.sticks_ignored_unlogged = now, 0


def _manual(loop, request, helm_nav, unavailable, cause):
    loop.state.manual_input_wall_s = loop.clock.wall_elapsed_s()
    if loop.ap.mode is not Mode.MANUAL:
        if not request.get("explicit"):
            # stick input drives a boat in MANUAL only, never changes the mode (as ArduPilot's): a planner streams
            # MANUAL_CONTROL whenever a joystick is on, sticks centred or not, and the packet after every mode change
            # (rtl, auto, a failsafe's stop) took the boat back to manual (found by fault injection and a GCS audit)
            return False, f"stick input ignored: mode {loop.ap.mode.value} (choose MANUAL to drive by stick)"
        # disarmed, manual is chosen as ArduPilot Rover's sequence has it (MANUAL, then arm: the arming check wants
        # the sticks at neutral); refused, a user armed in AUTO or RTL, where the boat drove at once (a new user's
        # test of the link). Disarmed, the thrust stays zero whatever the mode
        loop.ap.request("manual", None, cause=cause)
        loop.ap.set_sticks(request.get("forward_nd", 0.0), request.get("turn_nd", 0.0))
        return True, "manual"
    loop.ap.set_sticks(request.get("forward_nd", 0.0), request.get("turn_nd", 0.0))
    return True, "manual (held)"


def _set_current(loop, request, helm_nav, unavailable, cause):
    item = request.get("item")  # a planner's mission item number (home is item 0, a speed item has one too)
    ok, answer = loop.ap.set_current(int(request["index"]), cause=cause,
                                     also="" if item is None else f"mission item {int(item)}")
    if ok:
        loop.passes_restart()
        # a jump back before where a resumed run began makes those waypoints this run's (it said "9 of 7": a review)
        loop.start_index = min(getattr(loop, "start_index", 0), loop.ap.wp_index)
        loop.save_progress("running")
    return ok, answer


def _way_to(loop, helm_nav, target_ne_m):
    """(the points, their names) of a "go here": the boat's position and the point, when the boat is inside the
    limits (a point inside a concave geofence may lie across it: the boat left the fence on its way there and the
    fence's rtl took it, a new-user audit); the point alone when it is not (an rtl bringing it back in)."""
    if helm_nav is not None and loop.failsafe.within_limits(helm_nav.north_m, helm_nav.east_m):
        return [(helm_nav.north_m, helm_nav.east_m), target_ne_m], lambda k: "the boat" if k == 0 else "the point"
    return [target_ne_m], lambda k: "the point"


def _beyond_limits(loop, points_ne_m, what, *, legs: bool = False) -> str | None:
    """Why a point the boat is sent to would trip a latched failsafe (the geofence, max_distance), or None."""
    from autopilot.daemon.failsafe import first_beyond_limits

    if loop.cfg.failsafe.allow_beyond_limits:
        return None
    return first_beyond_limits(points_ne_m, loop.cfg.failsafe, loop.failsafe.fence_ne_m, what, legs=legs)


def _mission(loop, request, helm_nav, unavailable, cause):
    mission = request["mission"]
    route = [*mission.waypoints_ne_m]
    launch = loop.ap.launch_ne_m
    if mission.rtl and launch is not None:  # its way home too
        route.append(launch)
    n = len(mission.waypoints_ne_m)
    beyond = _beyond_limits(loop, route, lambda k: f"waypoint {k + 1}" if k < n else "the launch point (its rtl)",
                            legs=True)
    if beyond:
        return False, f"mission refused: {beyond}"
    loop.replace_mission(request["mission"], source=str(request.get("source", "mavlink")), cause=cause)
    return True, f"mission of {len(request['mission'].waypoints_ne_m)} waypoint(s)"


def _mission_clear(loop, request, helm_nav, unavailable, cause):
    mode = loop.ap.clear_mission(helm_nav, cause=cause, unavailable=unavailable)
    loop.log.event("mission_replaced", t_s=loop.clock.now_s() - loop.t0_s, source=str(request.get("source")),
                   waypoints=[], path=None, sha256=None)
    loop.save_progress("cleared")
    return True, f"mission cleared ({mode})"


def replace_key(cfg, key: str, value):
    """The configuration with one dotted key replaced (a frozen dataclass tree)."""
    head, _, rest = key.partition(".")
    if not rest:
        return dataclasses.replace(cfg, **{head: value})
    return dataclasses.replace(cfg, **{head: replace_key(getattr(cfg, head), rest, value)})


def get_key(cfg, key: str):
    for part in key.split("."):
        cfg = getattr(cfg, part)
    return cfg


def _param_set(loop, request, helm_nav, unavailable, cause):
    from autopilot.schema import ConfigError

    key, value = request["key"], request["value"]
    old = get_key(loop.cfg, key)
    ran_s = loop.clock.now_s() - loop.t0_s
    if key == "failsafe.max_mission_time_s" and value <= ran_s:  # it would end the run at once, link and all
        return False, (f"{request.get('name', key)} refused: {value:g} s is not more than the {ran_s:.0f} s "
                       "the mission has already run")
    if key == "failsafe.max_distance_m" and helm_nav is not None \
            and value <= (away_m := math.hypot(helm_nav.north_m, helm_nav.east_m)):
        # it latched the max_distance failsafe at once, for the rest of the run (a new user's test of the link)
        return False, (f"{request.get('name', key)} refused: {value:g} m is not more than the boat's {away_m:.0f} m "
                       "from the origin now (the failsafe would take the boat at once, latched)")
    try:
        new_cfg = replace_key(loop.cfg, key, value)  # the dataclasses' own checks run again
    except (ConfigError, ValueError, TypeError) as exc:
        return False, f"{request.get('name', key)} refused: {exc}"
    loop.apply_config(new_cfg)
    loop.log.event("param", t_s=loop.clock.now_s() - loop.t0_s, param=request.get("name", key), key=key, old=old,
                   new=value, source=str(request.get("source")))
    return True, f"{request.get('name', key)} = {value:g}" if isinstance(value, float) else \
        f"{request.get('name', key)} = {value}"


def _speed(loop, request, helm_nav, unavailable, cause):
    """The operator's speed for the mission's and a return's legs (MAVLink DO_CHANGE_SPEED, `ctl speed`)."""
    speed = request.get("speed_m_s")
    if speed is not None and not is_speed(speed):
        return False, f"speed refused: speed_m_s {speed!r} is not a speed in {SPEED_RANGE}"
    flown = loop.ap.set_speed(speed, cause=cause)
    mode = loop.ap.mode
    # said when it does not move the boat now: a hold, a stop or manual keep their own speeds
    if speed is not None and loop.ap.mission_cleared:  # "once the mission goes on": an upload gives its own speeds
        later = ("" if mode is Mode.RTL else f"; flown on a return (now {mode.value})") + \
            ": the mission is cleared, and a new one is flown at its planned speeds"
    else:
        later = "" if mode in (Mode.AUTO, Mode.RTL) else f"; flown once the mission or a return goes on (now {mode.value})"
    return True, f"speed: {flown} on every leg{later}"


_HANDLERS = {"manual": _manual, "set_current": _set_current, "mission": _mission, "mission_clear": _mission_clear,
             "param_set": _param_set, "speed": _speed}
