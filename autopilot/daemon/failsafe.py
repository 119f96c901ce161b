"""The failsafe state machine: when is it safe to let the GNC drive the thrusters? (issue 7)

Pure: one :class:`Observation` (ages, flags and position already read by the
daemon from the drivers on its clock) in, one :class:`Decision` out, no I/O
and no clock. The daemon calls :meth:`Failsafe.update` once per control
cycle and sends zero thrust on both sides whenever ``thrust_allowed`` is
false.

States::

    waiting --(no fault for start_valid_s)--> auto
    auto    --(any fault)--------------------> failsafe
    failsafe --(no fault for resume_valid_s)-> auto
    any     --(latched fault)----------------> failsafe, for good

While ``waiting``, missing data (WAITING_QUIET) is not reported as a fault
event: the devices are still starting. Latched faults (geofence, max distance, max mission time) never clear: the
boat stays stopped until an operator restarts the daemon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from autopilot.daemon.config import FailsafeConfig
from autopilot.logschema import FAULT_CAUSES, LATCHED_CAUSES

__all__ = ["CAUSES", "LATCHED", "WAITING_QUIET", "Observation", "Event", "Decision", "Failsafe", "detect", "inside_polygon"]

CAUSES = FAULT_CAUSES  # the log schema owns the causes' names and order
LATCHED = LATCHED_CAUSES
# before control first starts, missing data is expected (devices starting): shown in each cycle
# line's active_faults, but not logged as fault events
WAITING_QUIET = frozenset({"heading_stale", "heading_invalid", "position_stale", "no_fix"})


@dataclass(frozen=True)
class Observation:
    """What the daemon knows at the start of a cycle (times on the daemon's clock)."""

    t_s: float
    heading_age_s: float = math.inf
    heading_valid: bool = False
    position_age_s: float = math.inf
    fix_quality: int = 0
    ack_consecutive_missing: int = 0
    compass_connected: bool = True
    mbed_connected: bool = True
    last_garbage_t_s: float | None = None
    last_mbed_garbage_t_s: float | None = None
    north_m: float | None = None
    east_m: float | None = None
    mission_time_s: float = 0.0


@dataclass(frozen=True)
class Event:
    """A log event the daemon must write: ``name`` is a log-schema event, ``fields`` its keys."""

    name: str
    fields: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Decision:
    mode: str  # "waiting", "auto" or "failsafe"
    thrust_allowed: bool
    active: tuple[str, ...]  # causes active now, in CAUSES order
    events: tuple[Event, ...] = ()


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
    if obs.position_age_s > cfg.position_stale_s:
        age = "never received" if math.isinf(obs.position_age_s) else f"{obs.position_age_s:.2f} s old"
        faults["position_stale"] = f"position {age} (limit {cfg.position_stale_s:g} s)"
    elif obs.fix_quality <= 0:
        faults["no_fix"] = "GNSS fix quality 0"
    if obs.last_garbage_t_s is not None and obs.t_s - obs.last_garbage_t_s < cfg.garbage_hold_s:
        faults["nmea_garbage"] = "burst of rejected NMEA lines"
    if obs.last_mbed_garbage_t_s is not None and obs.t_s - obs.last_mbed_garbage_t_s < cfg.garbage_hold_s:
        faults["mbed_garbage"] = "burst of malformed lines from the Mbed"
    if not obs.mbed_connected:
        faults["mbed_port_lost"] = "Mbed port closed; reconnecting"
    if obs.ack_consecutive_missing >= cfg.ack_missing_n:
        faults["mbed_ack_missing"] = f"{obs.ack_consecutive_missing} consecutive commands unacknowledged (limit {cfg.ack_missing_n})"
    if obs.north_m is not None and obs.east_m is not None:
        if fence_ne_m is not None and not inside_polygon(obs.north_m, obs.east_m, fence_ne_m):
            faults["geofence"] = f"position ({obs.north_m:.1f}, {obs.east_m:.1f}) m is outside the geofence"
        dist_m = math.hypot(obs.north_m, obs.east_m)
        if dist_m > cfg.max_distance_m:
            faults["max_distance"] = f"{dist_m:.1f} m from the origin (limit {cfg.max_distance_m:g} m)"
    if obs.mission_time_s >= cfg.max_mission_time_s:
        faults["max_mission_time"] = f"mission time {obs.mission_time_s:.1f} s (limit {cfg.max_mission_time_s:g} s)"
    return faults


class Failsafe:
    """Per-cycle decision with hysteresis on recovery. See the module docstring."""

    def __init__(self, cfg: FailsafeConfig, *, fence_ne_m=None) -> None:
        self.cfg = cfg
        self.fence_ne_m = None if fence_ne_m is None else tuple((float(n), float(e)) for n, e in fence_ne_m)
        self.mode = "waiting"
        self._active: dict[str, str] = {}
        self._reported: set[str] = set()
        self._latched: dict[str, str] = {}
        self._valid_since_s: float | None = None
        self._trip_cause: str | None = None

    @property
    def latched(self) -> tuple[str, ...]:
        return tuple(c for c in CAUSES if c in self._latched)

    def update(self, obs: Observation) -> Decision:
        found = detect(obs, self.cfg, self.fence_ne_m)
        for cause, detail in found.items():
            if cause in LATCHED:
                self._latched.setdefault(cause, detail)
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
        new_causes = [c for c in CAUSES if c in now and c not in self._active]
        self._active = now

        if now:
            self._valid_since_s = None
            if self.mode == "auto" or (self.mode == "waiting" and self._latched):
                self._trip_cause = new_causes[0] if new_causes else next(c for c in CAUSES if c in now)
                events.append(Event("failsafe", {"cause": self._trip_cause, "action": "zero_thrust"}))
                self.mode = "failsafe"
        else:
            if self._valid_since_s is None:
                self._valid_since_s = obs.t_s
            valid_for_s = obs.t_s - self._valid_since_s
            if self.mode == "waiting" and valid_for_s >= self.cfg.start_valid_s:
                self.mode = "auto"
                events.append(Event("info", {"message": "data valid: control starts", "valid_for_s": valid_for_s}))
            elif self.mode == "failsafe" and valid_for_s >= self.cfg.resume_valid_s:
                self.mode = "auto"
                fields = {"cause": self._trip_cause, "valid_for_s": valid_for_s}
                events.append(Event("failsafe_cleared", dict(fields)))
                events.append(Event("resume", dict(fields)))
                self._trip_cause = None
        active = tuple(c for c in CAUSES if c in now)
        return Decision(mode=self.mode, thrust_allowed=self.mode == "auto", active=active, events=tuple(events))
