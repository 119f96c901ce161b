"""The failsafe state machine: when may the GNC drive, and what does a fault do? (issues 7, 15)

Pure: one :class:`Observation` (ages, flags, position and battery voltage already
read by the daemon from the drivers on its clock) in, one :class:`Decision` out, no
I/O and no clock. The daemon calls :meth:`Failsafe.update` once per control cycle.

Two kinds of fault:

- sensor and link faults (heading, position, ports, garbage, acknowledgements) are
  transient: zero thrust while they last, the mode before comes back when the data
  have been valid for ``resume_valid_s``::

      waiting  --(no such fault for start_valid_s)--> auto
      auto     --(any such fault)--------------------> failsafe (zero thrust)
      failsafe --(none for resume_valid_s)-----------> auto

- latched faults (geofence, max distance, max mission time, battery low and
  critical) never clear. Each asks once for its configured action
  (``failsafe.actions``: stop, hold or rtl; Mbed faults and battery_critical always
  stop) as a :class:`Request` for the helm; they do not themselves stop the GNC.
  A later fault's hold or rtl never replaces a stop a latched fault took before
  (:meth:`Failsafe._stop_taken`): a flat battery trips battery_critical (5 s) before
  battery_low (10 s), and battery_low's rtl drove the boat on after the critical stop.
  (Nor one the helm is in for any other reason: :func:`autopilot.daemon.cycle.answer_failsafe`.)

The guard (ArduPilot's ``requires_position()``): hold and rtl need a position and a
heading. A position or heading fault never takes them, and a latched fault that
trips while either is missing takes ``stop`` instead; the request says why.

While ``waiting``, missing data (WAITING_QUIET) is not reported as a fault event:
the devices are still starting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from autopilot.daemon.config import FailsafeConfig
from autopilot.logschema import FAULT_CAUSES, LATCHED_CAUSES

__all__ = ["CAUSES", "LATCHED", "WAITING_QUIET", "resting_voltage_v", "FAULT_CLASS", "NAV_CLASSES", "Observation", "Event", "Request",
           "Decision", "Failsafe", "detect", "inside_polygon", "position_limits", "first_beyond_limits",
           "segment_outside_polygon",
           "guarded_action"]

CAUSES = FAULT_CAUSES  # the log schema owns the causes' names and order
LATCHED = LATCHED_CAUSES
# before control first starts, missing data is expected (devices starting): shown in each cycle
# line's active_faults, but not logged as fault events
WAITING_QUIET = frozenset({"heading_stale", "heading_invalid", "position_stale", "no_fix"})
# the class of each cause: its action is failsafe.actions.<class>; "mbed" and "battery_critical" always stop
FAULT_CLASS: dict[str, str] = {
    "heading_stale": "heading", "heading_invalid": "heading", "heading_frozen": "heading", "compass_port_lost": "heading",
    "nmea_garbage": "heading", "position_stale": "position", "no_fix": "position",
    "mbed_ack_missing": "mbed", "mbed_port_lost": "mbed", "mbed_garbage": "mbed",
    "geofence": "geofence", "max_distance": "max_distance", "max_mission_time": "max_mission_time",
    "battery_low": "battery_low", "battery_critical": "battery_critical",
}
NAV_CLASSES = frozenset({"position", "heading"})  # faults of what hold and rtl need
ALWAYS_STOP = frozenset({"mbed", "battery_critical"})


@dataclass(frozen=True)
class Observation:
    """What the daemon knows at the start of a cycle (times on the daemon's clock)."""

    t_s: float
    heading_age_s: float = math.inf
    heading_valid: bool = False
    position_age_s: float = math.inf
    fix_quality: int = 0
    ack_consecutive_missing: int = 0
    ack_disobeyed: bool = False  # those include OKs whose echoed duties were not the ones sent
    compass_connected: bool = True
    mbed_connected: bool = True
    last_garbage_t_s: float | None = None
    last_mbed_garbage_t_s: float | None = None
    north_m: float | None = None
    east_m: float | None = None
    mission_time_s: float | None = 0.0  # None: no mission under way (it ended with stop: max_mission_time is moot)
    battery_v: float | None = None  # resting voltage estimate (resting_voltage_v); None: the firmware does not report it
    # the position agrees with the fix before it (Navigation.fix_confirmed): only such a position latches the
    # geofence or the distance limit (a first fix, or a jump just re-anchored to, may be a glitch)
    position_confirmed: bool = True
    # the turn (rad) the rate of turn reported while the compass heading stayed still (Navigation.still_turn_rad)
    heading_still_turn_rad: float = 0.0
    # since when the compass heading has stayed still (Navigation.heading_still_since_s); None: no heading yet
    heading_still_since_s: float | None = None
    # the heading error (rad) the helm steered by in the cycle before (None: it did not steer by the heading)
    steered_heading_error_rad: float | None = None


@dataclass(frozen=True)
class Event:
    """A log event the daemon must write: ``name`` is a log-schema event, ``fields`` its keys."""

    name: str
    fields: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Request:
    """A latched fault's action for the helm (logged by the daemon as ``failsafe`` once the helm answered)."""

    cause: str
    action: str  # the action to take: stop, hold or rtl (after the guard)
    configured: str  # the one configured for the cause
    fallback: str | None = None  # why the configured one is not taken
    # (cause, "stop") of the stop a latched fault took before: it stays in force, this action is not taken
    overruled_by: tuple[str, str] | None = None


@dataclass(frozen=True)
class Decision:
    mode: str  # "waiting", "auto" or "failsafe" (a transient fault: zero thrust)
    thrust_allowed: bool  # the GNC may drive (the helm's mode decides what it does)
    active: tuple[str, ...]  # causes active now, in CAUSES order (latched ones included)
    events: tuple[Event, ...] = ()
    requests: tuple[Request, ...] = ()


def resting_voltage_v(battery_v: float | None, duty_port_pct: float, duty_stbd_pct: float,
                      sag_v: float) -> float | None:
    """The battery's resting voltage estimated from the voltage under load and the duties it was under:
    a propeller's battery current grows about as the cube of the duty (autopilot/sim/battery.py), and
    ``sag_v`` is the drop at full duty on both sides."""
    if battery_v is None:
        return None
    dp, ds = abs(duty_port_pct) / 100.0, abs(duty_stbd_pct) / 100.0
    return battery_v + sag_v * 0.5 * (dp ** 3 + ds ** 3)


def guarded_action(configured: str, fault_class: str, nav_missing: str | None) -> tuple[str, str | None]:
    """(action taken, why not the configured one): hold and rtl need a position and a heading."""
    if fault_class in ALWAYS_STOP or configured == "stop":
        return "stop", None
    if fault_class in NAV_CLASSES:
        return "stop", f"{configured} needs a position and a heading: this is a {fault_class} fault"
    if nav_missing is not None:
        return "stop", f"{configured} needs a position and a heading: {nav_missing}"
    return configured, None


def inside_polygon(north_m: float, east_m: float, polygon_ne_m) -> bool:
    """Even-odd ray casting; points on an edge count as inside."""
    n = len(polygon_ne_m)
    inside = False
    for i in range(n):
        n1, e1 = polygon_ne_m[i]
        n2, e2 = polygon_ne_m[(i + 1) % n]
        # on the edge: collinear and within the segment's box
        cross = (n2 - n1) * (east_m - e1) - (e2 - e1) * (north_m - n1)
        if abs(cross) < 1e-9 and min(n1, n2) - 1e-9 <= north_m <= max(n1, n2) + 1e-9 and min(e1, e2) - 1e-9 <= east_m <= max(e1, e2) + 1e-9:
            return True
        if (e1 > east_m) != (e2 > east_m):
            n_cross = n1 + (east_m - e1) * (n2 - n1) / (e2 - e1)
            if north_m < n_cross:
                inside = not inside
    return inside


def position_limits(north_m: float, east_m: float, cfg: FailsafeConfig, fence_ne_m=None) -> dict[str, str]:
    """The latched position limits a point (local frame, m) is beyond: cause -> human detail. The failsafe
    judges the boat's position with it, the commands a point the boat is sent to (a point beyond a limit
    is refused up front, not flown to until the failsafe turns the boat back)."""
    out: dict[str, str] = {}
    if fence_ne_m is not None and not inside_polygon(north_m, east_m, fence_ne_m):
        out["geofence"] = f"position ({north_m:.1f}, {east_m:.1f}) m is outside the geofence"
    dist_m = math.hypot(north_m, east_m)
    if dist_m > cfg.max_distance_m:
        out["max_distance"] = f"{dist_m:.1f} m from the origin (limit {cfg.max_distance_m:g} m)"
    return out


def first_beyond_limits(points_ne_m, cfg: FailsafeConfig, fence_ne_m, name, *, legs: bool = False) -> str | None:
    """Why the first of ``points_ne_m`` beyond a latched position limit would trip it when the boat got there
    (``name(k)`` names point k: "waypoint 2 is beyond the max_distance failsafe: ..."), or None. With ``legs``,
    the straight legs between consecutive points too: a leg between two points inside a concave geofence may
    leave it (an upload of (50, 0) and (0, 50) inside an L-shaped fence was accepted, and the boat left the fence
    on the way and was turned back by its rtl; a new-user audit). The distance limit is a circle: a leg between
    two points inside it stays inside."""
    points = [(float(n), float(e)) for n, e in points_ne_m]
    for k, (north_m, east_m) in enumerate(points):
        beyond = position_limits(north_m, east_m, cfg, fence_ne_m)
        if beyond:
            cause, detail = next(iter(beyond.items()))
            return f"{name(k)} is beyond the {cause} failsafe: {detail}"
    if legs and fence_ne_m is not None:
        for k in range(len(points) - 1):
            out = segment_outside_polygon(points[k], points[k + 1], fence_ne_m)
            if out is not None:
                return (f"the leg from {name(k)} to {name(k + 1)} leaves the geofence (at ({out[0]:.1f}, {out[1]:.1f}) "
                        "m): the geofence failsafe would turn the boat back there; add a waypoint inside the fence "
                        "to go round")
    return None


def mission_beyond_limits(home_ne_m, waypoints_ne_m, rtl: bool, cfg: FailsafeConfig, fence_ne_m,
                          start: str) -> str | None:
    """Why a mission flown from ``home_ne_m`` (named ``start``) would trip a latched position failsafe: a waypoint,
    the start, or a leg between them (the start's to the first waypoint, an rtl's back to it) beyond the geofence
    or max_distance_m; None when it stays inside. The daemon refuses such a mission at start (and a campaign's
    spec), unless failsafe.allow_beyond_limits, which the callers check."""
    route = [home_ne_m, *waypoints_ne_m] + ([home_ne_m] if rtl else [])
    n = len(waypoints_ne_m)

    def name(k: int) -> str:
        return start if k == 0 else f"waypoint {k}" if k <= n else "the launch point (the mission's rtl)"

    return first_beyond_limits(route, cfg, fence_ne_m, name, legs=True)


def segment_outside_polygon(a_ne_m, b_ne_m, polygon_ne_m) -> tuple[float, float] | None:
    """A point of the segment from ``a_ne_m`` to ``b_ne_m`` outside the polygon (local frame, m), or None when the
    whole segment is inside or on the edge: the segment cut where it meets the polygon's edges, and the middle of
    each piece tested (exact for a simple polygon, a leg through a vertex included)."""
    (an, ae), (bn, be) = a_ne_m, b_ne_m
    dn, de = bn - an, be - ae
    cuts = [0.0, 1.0]
    n = len(polygon_ne_m)
    for i in range(n):
        (cn, ce), (en, ee) = polygon_ne_m[i], polygon_ne_m[(i + 1) % n]
        fn, fe = en - cn, ee - ce
        denom = dn * fe - de * fn
        if abs(denom) < 1e-12:
            continue  # parallel (an overlap lies on the edge: inside)
        t = ((cn - an) * fe - (ce - ae) * fn) / denom
        u = ((cn - an) * de - (ce - ae) * dn) / denom
        if -1e-12 <= t <= 1.0 + 1e-12 and -1e-12 <= u <= 1.0 + 1e-12:
            cuts.append(min(max(t, 0.0), 1.0))
    cuts.sort()
    for t0, t1 in zip(cuts, cuts[1:]):
        if t1 - t0 < 1e-9:
            continue
        t = 0.5 * (t0 + t1)
        pn, pe = an + t * dn, ae + t * de
        if not inside_polygon(pn, pe, polygon_ne_m):
            return pn, pe
    return None


def detect(obs: Observation, cfg: FailsafeConfig, fence_ne_m=None) -> dict[str, str]:
    """Every fault present in ``obs``: cause -> human detail."""
    faults: dict[str, str] = {}
    if not obs.compass_connected:
        faults["compass_port_lost"] = "SC-30 port closed; reconnecting"
    if obs.heading_age_s > cfg.heading_stale_s:
        age = "never received" if math.isinf(obs.heading_age_s) else f"{obs.heading_age_s:.2f} s old"
        faults["heading_stale"] = f"heading {age} (limit {cfg.heading_stale_s:g} s)"
    elif not obs.heading_valid:
        faults["heading_invalid"] = "compass reports its heading invalid"
    elif abs(obs.heading_still_turn_rad) >= math.radians(cfg.heading_frozen_deg):
        faults["heading_frozen"] = (f"compass heading unchanged while its rate of turn says the boat turned "
                                    f"{math.degrees(obs.heading_still_turn_rad):+.0f} deg (limit {cfg.heading_frozen_deg:g} deg)")
    if obs.position_age_s > cfg.position_stale_s:
        age = "never received" if math.isinf(obs.position_age_s) else f"{obs.position_age_s:.2f} s old"
        faults["position_stale"] = f"position {age} (limit {cfg.position_stale_s:g} s)"
    elif obs.fix_quality <= 0:
        faults["no_fix"] = "GNSS fix not valid (GGA quality 0, or RMC/GLL status V)"
    if obs.last_garbage_t_s is not None and obs.t_s - obs.last_garbage_t_s < cfg.garbage_hold_s:
        faults["nmea_garbage"] = "burst of rejected NMEA lines"
    if obs.last_mbed_garbage_t_s is not None and obs.t_s - obs.last_mbed_garbage_t_s < cfg.garbage_hold_s:
        faults["mbed_garbage"] = "burst of malformed lines from the Mbed"
    if not obs.mbed_connected:
        faults["mbed_port_lost"] = "Mbed port closed; reconnecting"
    if obs.ack_consecutive_missing >= cfg.ack_missing_n:
        how = "not obeyed (the board echoed other duties than sent)" if obs.ack_disobeyed else "unacknowledged"
        faults["mbed_ack_missing"] = f"{obs.ack_consecutive_missing} consecutive commands {how} (limit {cfg.ack_missing_n})"
    if obs.north_m is not None and obs.east_m is not None and obs.fix_quality > 0 and obs.position_confirmed:
        faults.update(position_limits(obs.north_m, obs.east_m, cfg, fence_ne_m))
    if obs.mission_time_s is not None and obs.mission_time_s >= cfg.max_mission_time_s:
        faults["max_mission_time"] = f"mission time {obs.mission_time_s:.1f} s (limit {cfg.max_mission_time_s:g} s)"
    return faults


def _nav_missing(faults: dict[str, str]) -> str | None:
    """The first position or heading fault, as a reason ("position stale"), or None."""
    for cause in CAUSES:
        if cause in faults and FAULT_CLASS[cause] in NAV_CLASSES:
            return cause.replace("_", " ")
    return None


class Failsafe:
    """Per-cycle decision with hysteresis on recovery. See the module docstring."""

    def __init__(self, cfg: FailsafeConfig, *, fence_ne_m=None) -> None:
        self.cfg = cfg
        self.fence_ne_m = None if fence_ne_m is None else tuple((float(n), float(e)) for n, e in fence_ne_m)
        self.mode = "waiting"
        self._active: dict[str, str] = {}
        self._reported: set[str] = set()
        self._latched: dict[str, str] = {}
        self._actions: dict[str, str] = {}  # latched cause -> the action it took
        self._restored: set[str] = set()  # latched before a restart (restore_latched)
        self._valid_since_s: float | None = None
        self._trip_cause: str | None = None
        self._low_since_s: dict[str, float] = {}
        self._still_since_s: float | None = None  # the still heading the steering time below is counted over
        self._steered_s = 0.0  # how long the helm steered heading_frozen_steer_error_deg off it meanwhile
        self._last_t_s: float | None = None

    @property
    def latched(self) -> tuple[str, ...]:
        return tuple(c for c in CAUSES if c in self._latched)

    @property
    def restored(self) -> tuple[str, ...]:
        """The latched causes carried over from the run before a restart (restore_latched), not seen in this one."""
        return tuple(c for c in CAUSES if c in self._restored)

    def action_of(self, cause: str) -> str | None:
        """The action a latched cause took in this run (None if it has not tripped, or tripped before a restart:
        a max_mission_time restored must not end the restarted daemon at its first cycle)."""
        return None if cause in self._restored else self._actions.get(cause)

    def restore_latched(self, causes) -> None:
        """Latched faults of the run before a restart (StateStore's progress): latched again, as having taken
        stop (the restarted daemon holds zero thrust): resume stays refused, a later milder action overruled."""
        for cause in causes:
            if cause in LATCHED and cause not in self._latched:
                self._latched[cause] = "latched before the restart"
                self._actions[cause] = "stop"
                self._restored.add(cause)

    def _stop_taken(self) -> str | None:
        """The first latched cause that took stop (ArduPilot Rover's failsafe priorities put Terminate and Hold,
        its stop, above RTL: a later, milder failsafe action does not replace them)."""
        return next((c for c in CAUSES if self._actions.get(c) == "stop"), None)

    def configured(self, cause: str) -> str:
        cls = FAULT_CLASS[cause]
        return "stop" if cls in ALWAYS_STOP else getattr(self.cfg.actions, cls)

    def _battery(self, obs: Observation) -> dict[str, str]:
        """battery_low / battery_critical once the voltage has stayed below its threshold long enough."""
        cfg, out = self.cfg, {}
        for cause, limit_v, hold_s in (("battery_low", cfg.battery_low_v, cfg.battery_low_s),
                                       ("battery_critical", cfg.battery_critical_v, cfg.battery_critical_s)):
            v = obs.battery_v
            if v is None or limit_v <= 0.0 or not v < limit_v:
                self._low_since_s.pop(cause, None)
                continue
            since = self._low_since_s.setdefault(cause, obs.t_s)
            if obs.t_s - since >= hold_s:
                out[cause] = f"battery (resting estimate) {v:.2f} V below {limit_v:g} V for {obs.t_s - since:.1f} s"
        return out

    def _steered_unanswered(self, obs: Observation, found: dict[str, str]) -> None:
        """heading_frozen when the helm has steered far off a compass heading that has not moved meanwhile.

        A stuck compass whose rate of turn froze too (at a rate below ROT_NOISE_RAD_S, going straight)
        reports no turn to sum: the PID then turns the boat, the heading does not answer, and it spins.
        The helm's own demand is the evidence: with heading_frozen_steer_error_deg of error a WAM-V
        turns within a second; one whose heading has not moved 0.5 deg after heading_frozen_steer_s of
        that is not answering (or cannot turn: pinned by more wind than its thrusters hold, or on a
        bench; it stops, and resumes once the heading moves)."""
        cfg = self.cfg
        since = obs.heading_still_since_s
        if cfg.heading_frozen_steer_s <= 0.0 or since is None:
            self._still_since_s, self._steered_s = since, 0.0
        elif since != self._still_since_s:  # the heading moved: count again from here
            self._still_since_s, self._steered_s = since, 0.0
        elif (obs.steered_heading_error_rad is not None and self._last_t_s is not None
              and abs(obs.steered_heading_error_rad) >= math.radians(cfg.heading_frozen_steer_error_deg)):
            self._steered_s += min(max(obs.t_s - self._last_t_s, 0.0), 1.0)  # the last cycle's demand, held since
        self._last_t_s = obs.t_s
        if (cfg.heading_frozen_steer_s > 0.0 and self._steered_s >= cfg.heading_frozen_steer_s - 1e-9
                and not {"heading_stale", "heading_invalid"} & found.keys()):
            found.setdefault("heading_frozen", (
                f"compass heading unchanged (within 0.5 deg) for {obs.t_s - since:.1f} s while the helm steered "
                f"{cfg.heading_frozen_steer_error_deg:g} deg or more off it for {self._steered_s:.1f} s "
                f"(limit {cfg.heading_frozen_steer_s:g} s)"))

    def within_limits(self, north_m: float, east_m: float) -> bool:
        """The point (local frame, m) is inside the latched position limits (:func:`position_limits`)."""
        return not position_limits(north_m, east_m, self.cfg, self.fence_ne_m)

    def update(self, obs: Observation) -> Decision:
        found = detect(obs, self.cfg, self.fence_ne_m)
        self._steered_unanswered(obs, found)
        found.update(self._battery(obs))
        requests: list[Request] = []
        for cause in CAUSES:
            if cause in found and cause in LATCHED and cause not in self._latched:
                self._latched[cause] = found[cause]
                configured = self.configured(cause)
                action, why = guarded_action(configured, FAULT_CLASS[cause], _nav_missing(found))
                stop = self._stop_taken() if action != "stop" else None
                self._actions[cause] = action
                if stop is not None:
                    why = f"{stop} took stop before: a failsafe does not drive a boat a failsafe stopped"
                requests.append(Request(cause, action, configured, why,
                                        overruled_by=None if stop is None else (stop, "stop")))
        now = dict(found)
        now.update({c: d for c, d in self._latched.items() if c not in now})
        events: list[Event] = []
        for cause in CAUSES:
            quiet = self.mode == "waiting" and cause in WAITING_QUIET
            if cause in now and cause not in self._reported and not quiet:
                self._reported.add(cause)
                events.append(Event("fault", {"cause": cause, "detail": now[cause]}))
            elif cause in self._reported and cause not in now:
                self._reported.discard(cause)
                events.append(Event("fault_cleared", {"cause": cause}))
        transient = {c: d for c, d in now.items() if c not in LATCHED}
        new_causes = [c for c in CAUSES if c in transient and c not in self._active]
        self._active = transient

        if transient:
            self._valid_since_s = None
            if self.mode == "auto":
                self._trip_cause = new_causes[0] if new_causes else next(c for c in CAUSES if c in transient)
                configured = self.configured(self._trip_cause)
                _, why = guarded_action(configured, FAULT_CLASS[self._trip_cause], None)
                events.append(Event("failsafe", {"cause": self._trip_cause, "action": "stop", "configured": configured,
                                                 "fallback": why}))
                self.mode = "failsafe"
        else:
            if self._valid_since_s is None:
                self._valid_since_s = obs.t_s
            valid_for_s = obs.t_s - self._valid_since_s
            # control starts on a confirmed position: the launch point (rtl's home) is set from it, and a first
            # fix may be a glitch (autopilot.gnc.navigation); a good first fix is confirmed by the next, 1 s on
            if self.mode == "waiting" and valid_for_s >= self.cfg.start_valid_s and obs.position_confirmed:
                self.mode = "auto"
                events.append(Event("info", {"message": "data valid: control starts", "valid_for_s": valid_for_s}))
            elif self.mode == "failsafe" and valid_for_s >= self.cfg.resume_valid_s:
                self.mode = "auto"
                fields = {"cause": self._trip_cause, "valid_for_s": valid_for_s}
                events.append(Event("failsafe_cleared", dict(fields)))
                events.append(Event("resume", dict(fields)))
                self._trip_cause = None
        active = tuple(c for c in CAUSES if c in now)
        return Decision(mode=self.mode, thrust_allowed=self.mode == "auto", active=active, events=tuple(events),
                        requests=tuple(requests))
