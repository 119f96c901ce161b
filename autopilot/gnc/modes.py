"""The operator's modes, each a small object with one ``update`` (ArduPilot Rover's mode classes).

A mode turns one cycle's navigation into a :class:`Steering` for the inner loop
(:class:`autopilot.gnc.autopilot.Autopilot`): a course and a speed (the waypoint
path), a heading and a common thrust (station keeping), or nothing (zero thrust).
A mode may hand over to another (``then``): the mission ends in a hold or a return
to launch, a return to launch ends holding at the launch point. ``requires_position``:
the mode cannot run without a position and a heading (ArduPilot's
``requires_position()``); a failsafe never chooses such a mode for a position or
heading fault. The names are :class:`autopilot.logschema.Mode`'s. Pure.

    auto      the mission: waypoint guidance; a waypoint's hold_s / hold holds station there,
              then the mission goes on; at its end: complete (stop), hold, or rtl
    hold      station keeping at a point, at a given heading or the least-effort one
    paused    hold where the boat was; resume continues the mission at the same waypoint
    rtl       steer to the launch point with the mission's guidance law, then hold there
    stop      zero thrust, latched until commanded
    complete  the mission ended with stop: zero thrust, the run may end
    manual    the operator's sticks (MAVLink MANUAL_CONTROL): forward and turn straight to the allocation

A hold or pause asked for before control starts is :class:`PendingHold`: reported as the mode asked for,
placed when control starts (the helm's first step with a position).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.gnc.registry import make_guidance
from autopilot.gnc.station_keeping import HoldOutput, StationKeeper
from autopilot.gnc.waypoints import GuidanceOutput
from autopilot.logschema import MISSION_RTL_CAUSE, RTL_ARRIVED_CAUSE, Mode

__all__ = ["Steering", "Handover", "HeldOff", "AutoMode", "HoldMode", "PausedMode", "PendingHold", "RtlMode", "StopMode",
           "CompleteMode", "ManualMode"]


@dataclass(frozen=True)
class Handover:
    """A mode's request to be replaced (the helm makes the new mode)."""

    mode: Mode
    cause: str
    target_ne_m: tuple[float, float] | None = None  # where a hold holds (None: where the boat is)
    keeper: StationKeeper | None = None  # the keeper that closed on that point (the hold goes on with it)


@dataclass(frozen=True)
class HeldOff:
    """Where a hold at a waypoint a stopped vessel occupies is kept (Avoidance.occupying's hold_ne_m), and the
    vessel's identity (AIS MMSI; None: not known), so that the hold can go to the waypoint once it is gone."""

    point_ne_m: tuple[float, float]
    target_id: int | None


@dataclass(frozen=True)
class Steering:
    """What a mode asks of the inner loop this cycle."""

    kind: str  # "course" (psi_d, speed), "force" (psi_d, signed tau_com), "off" (zero thrust), "manual" (sticks)
    psi_d_rad: float = 0.0
    speed_cmd_m_s: float = 0.0
    tau_com_n: float = 0.0
    guidance: GuidanceOutput | None = None  # the waypoint guidance's own terms, when it ran
    hold: HoldOutput | None = None  # station keeping's, when it ran
    hold_target_ne_m: tuple[float, float] | None = None
    holding: bool = False  # the hold proper (scored, timed); False while station keeping only closes on the point
    then: Handover | None = None
    forward_nd: float = 0.0  # manual: the forward stick, -1 (full astern) .. 1 (full ahead)
    turn_nd: float = 0.0  # manual: the turn stick, -1 (full to port) .. 1 (full to starboard)


def keep_station(keeper: StationKeeper, nav, dt_s: float, guidance: GuidanceOutput | None = None, *,
                 holding: bool = True, max_speed_m_s: float | None = None) -> Steering:
    """One station-keeping step as a Steering. ``max_speed_m_s``: the operator's speed, which a closing on a point
    the mission or a return stops at, and a hold item, do not exceed (they went up to hold.approach_speed_m_s, 1 m/s,
    in the last approach_m of a boat slowed to 0.5 m/s near swimmers: a review of the operator's speed)."""
    h = keeper.step(nav.north_m, nav.east_m, nav.psi_rad, nav.speed_m_s, nav.course_rad, dt_s,
                    max_speed_m_s=max_speed_m_s)
    kind = "off" if h.drifting else "course" if h.approach else "force"
    return Steering(kind, psi_d_rad=h.psi_d_rad, speed_cmd_m_s=h.speed_cmd_m_s, tau_com_n=h.tau_com_n,
                    guidance=guidance, hold=h, hold_target_ne_m=keeper.target, holding=holding)


class Closing:
    """The last ``hold.approach_m`` to a point the boat will hold: station keeping steers (it brakes
    astern, on the braking-limited speed profile) while the route's guidance still decides when the
    point is reached. The same keeper then holds, its disturbance estimate already learning."""

    def __init__(self, hold_config) -> None:
        self.config = hold_config
        self.keeper: StationKeeper | None = None

    def near(self, nav, point) -> bool:
        return math.hypot(point[0] - nav.north_m, point[1] - nav.east_m) < self.config.approach_m

    def keeper_for(self, point, nav) -> StationKeeper:
        p = (float(point[0]), float(point[1]))
        if self.keeper is None or self.keeper.target != p:
            self.keeper = StationKeeper(self.config, p, initial_heading_rad=nav.psi_rad)
        return self.keeper

    def take(self, point, nav) -> StationKeeper:
        """The keeper for the point (the closing one if it was closing on it); closing ends."""
        k, self.keeper = self.keeper_for(point, nav), None
        return k


class StopMode:
    mode = Mode.STOP
    requires_position = False

    def update(self, nav, dt_s: float) -> Steering:
        return Steering("off", psi_d_rad=0.0 if nav is None else nav.psi_rad)


class ManualMode:
    """The operator drives: the sticks go to the allocation (and its limits), no guidance, no PID."""

    mode = Mode.MANUAL
    requires_position = False

    def __init__(self) -> None:
        self.forward_nd = 0.0
        self.turn_nd = 0.0

    def set_sticks(self, forward_nd: float, turn_nd: float) -> None:
        self.forward_nd = max(-1.0, min(1.0, float(forward_nd)))
        self.turn_nd = max(-1.0, min(1.0, float(turn_nd)))

    def update(self, nav, dt_s: float) -> Steering:
        return Steering("manual", psi_d_rad=0.0 if nav is None else nav.psi_rad, forward_nd=self.forward_nd,
                        turn_nd=self.turn_nd)


class CompleteMode(StopMode):
    mode = Mode.COMPLETE


class HoldMode:
    """Station keeping at ``target_ne_m`` (:mod:`autopilot.gnc.station_keeping`)."""

    mode = Mode.HOLD
    requires_position = True

    def __init__(self, hold_config, target_ne_m, *, heading_rad: float | None, initial_heading_rad: float,
                 keeper: StationKeeper | None = None) -> None:
        self.keeper = keeper if keeper is not None and heading_rad is None else StationKeeper(
            hold_config, target_ne_m, heading_rad=heading_rad, initial_heading_rad=initial_heading_rad)

    def update(self, nav, dt_s: float) -> Steering:
        return keep_station(self.keeper, nav, dt_s)


class PausedMode(HoldMode):
    mode = Mode.PAUSED


class PendingHold:
    """A hold (or a pause) asked for before control starts, kept until it does. Before the first confirmed fix
    there is no position to hold at (a first fix may be a glitch: the launch point waits for it too), so the
    point is taken where control starts: the boat's stopping point then, or the point given (a "go here").
    Refused, the boat flew the mission from its start as if the operator had said nothing (QGroundControl saw
    "position stale"); taken with the unconfirmed fix it was held there and reported as INITIALISING."""

    requires_position = True

    def __init__(self, mode: Mode, *, heading_rad: float | None = None,
                 target_ne_m: tuple[float, float] | None = None) -> None:
        self.mode = mode  # Mode.HOLD or Mode.PAUSED
        self.heading_rad = heading_rad
        self.target_ne_m = None if target_ne_m is None else (float(target_ne_m[0]), float(target_ne_m[1]))

    def begin(self, hold_config, stopping_point_ne_m, nav) -> HoldMode:
        """The hold itself, now that control starts (``stopping_point_ne_m``: where the boat can stop)."""
        point = stopping_point_ne_m if self.target_ne_m is None else self.target_ne_m
        kind = PausedMode if self.mode is Mode.PAUSED else HoldMode
        return kind(hold_config, point, heading_rad=self.heading_rad, initial_heading_rad=nav.psi_rad)

    def update(self, nav, dt_s: float) -> Steering:  # pragma: no cover - the helm begins it before a step
        raise RuntimeError("a pending hold begins at the helm's first step")


class RtlMode:
    """Back to the launch point with the mission's guidance law, then a hold there."""

    mode = Mode.RTL
    requires_position = True

    def __init__(self, config, launch_ne_m, *, boat_length_m: float) -> None:
        self.launch = (float(launch_ne_m[0]), float(launch_ne_m[1]))
        self.guidance = make_guidance(config.guidance, [self.launch], boat_length_m=boat_length_m)
        self.closing = Closing(config.hold)
        self.arrived_keeper: StationKeeper | None = None  # handed to the hold at the launch point

    def update(self, nav, dt_s: float) -> Steering:
        g = self.guidance.update(nav, dt_s)
        if g.complete:
            self.arrived_keeper = self.closing.take(self.launch, nav)
            return Steering("off", psi_d_rad=nav.psi_rad, guidance=g,
                            then=Handover(Mode.HOLD, RTL_ARRIVED_CAUSE, self.launch, self.arrived_keeper))
        if self.closing.near(nav, self.launch):
            return keep_station(self.closing.keeper_for(self.launch, nav), nav, dt_s, guidance=g, holding=False,
                                max_speed_m_s=self.guidance.speed_override_m_s)
        return Steering("course", psi_d_rad=g.psi_d_rad, speed_cmd_m_s=g.speed_cmd_m_s, guidance=g)


class AutoMode:
    """The mission: its guidance (kept across pauses and holds), its hold items, its end."""

    mode = Mode.AUTO
    requires_position = True

    def __init__(self, config, waypoints_ne_m, *, speeds_m_s=None, holds_s=None, rtl: bool = False,
                 boat_length_m: float, start_index: int = 0) -> None:
        self.config = config
        self.holds_s = tuple(holds_s or ())
        stops = [i for i in range(len(self.holds_s)) if self._hold_s(i) is not None]
        self.guidance = make_guidance(config.guidance, waypoints_ne_m, speeds_m_s=speeds_m_s,
                                      boat_length_m=boat_length_m, start_index=start_index, stop_indices=stops)
        self.rtl = rtl
        self.closing = Closing(config.hold)
        self.item_keeper: StationKeeper | None = None  # holding at a waypoint of the mission
        self.item_returning = False  # ... on the way back to it after the mission was left (back_to_item)
        self.item_left_s = 0.0
        self.item_index: int | None = None
        self.held_off: dict[int, HeldOff] = {}  # waypoint reached "occupied" -> where it is held, off which vessel
        self.occupied = None  # this cycle's Avoidance.occupying (an Occupied, or None), set by the helm
        # (waypoint, the keeper made to hold off it) while that hold is the one made: the helm moves it onto the
        # waypoint once the vessel is gone (Autopilot._end_hold_off)
        self.holding_off: tuple[int, StationKeeper] | None = None

    def end_item_hold(self) -> bool:
        """Resume: end a hold item early (True if there was one)."""
        held = self.item_keeper is not None
        self.item_keeper = self.item_index = None
        self.item_returning = False
        return held

    def _hold_s(self, i: int) -> float | None:
        h = self.holds_s[i] if i < len(self.holds_s) else None
        return None if h is None or h <= 0.0 else h

    def back_to_item(self) -> None:
        """The mission is taken up again (after a stop, a pause, an rtl, a hold elsewhere): a hold item under way is
        returned to, its time stopped until the boat is within ``approach_m`` of its point again."""
        self.item_returning = self.item_keeper is not None

    def update(self, nav, dt_s: float) -> Steering:
        if self.item_keeper is not None:
            # the item's time runs while it is held: it ran on the way back to the point too, 22 m off (an audit);
            # once back it runs on, however far a current then sets the boat (it must end)
            if self.item_returning and self.closing.near(nav, self.item_keeper.target):
                self.item_returning = False
            if not self.item_returning:
                self.item_left_s -= dt_s
            if self.item_left_s > 0.0:  # held (and gone back to) no faster than the operator's speed
                return keep_station(self.item_keeper, nav, dt_s, holding=not self.item_returning,
                                    max_speed_m_s=self.guidance.speed_override_m_s)
            self.end_item_hold()
        if self.guidance.complete:
            return self._end(nav)
        g = self.guidance.update(nav, dt_s)
        i = g.reached_index
        if i is not None and g.reached_how == "occupied":
            occ = self.occupied
            self.held_off[i] = (HeldOff((nav.north_m, nav.east_m), None) if occ is None
                                else HeldOff(occ.hold_ne_m, occ.target.target_id))
        elif i is not None:  # reached as any other (a mission set back to it, the vessel gone)
            self.held_off.pop(i, None)
        if i is not None and self._hold_s(i) is not None:
            self.item_index, self.item_left_s = i, self._hold_s(i)
            self.item_keeper = self._keeper_at(i, nav)
            return keep_station(self.item_keeper, nav, dt_s, guidance=g, max_speed_m_s=self.guidance.speed_override_m_s)
        if g.complete:
            return self._end(nav, g)
        target = self.guidance.waypoints[g.wp_index]
        if self._stops_at(g.wp_index) and self.closing.near(nav, target):
            return keep_station(self.closing.keeper_for(target, nav), nav, dt_s, guidance=g, holding=False,
                                max_speed_m_s=self.guidance.speed_override_m_s)
        return Steering("course", psi_d_rad=g.psi_d_rad, speed_cmd_m_s=g.speed_cmd_m_s, guidance=g)

    def _keeper_at(self, i: int, nav) -> StationKeeper:
        """The keeper of a hold at waypoint ``i``, reached. One a stopped vessel occupied (reached "occupied", as
        near as the rules allow) is held on the boat's side of it, where avoidance lets go of the vessel
        (Occupied.hold_ne_m): held at the waypoint, the boat left and came back at the vessel's safe distance for
        the whole hold (found by an AIS audit)."""
        keeper = self.closing.take(self.guidance.waypoints[i], nav)
        off = self.held_off.get(i)
        if off is None:
            return keeper
        keeper = keeper.least_effort(nav.psi_rad, target_ne_m=off.point_ne_m)
        self.holding_off = (i, keeper)
        return keeper

    def _stops_at(self, i: int) -> bool:
        """The boat holds at waypoint i: a hold item, or the last waypoint when the mission ends holding."""
        last = i == len(self.guidance.waypoints) - 1
        return self._hold_s(i) is not None or (last and not self.rtl and self.config.guidance.final_action == "hold")

    def _end(self, nav, g: GuidanceOutput | None = None) -> Steering:
        if self.rtl:
            then = Handover(Mode.RTL, MISSION_RTL_CAUSE)
        elif self.config.guidance.final_action == "hold":
            keeper = self._keeper_at(len(self.guidance.waypoints) - 1, nav)
            then = Handover(Mode.HOLD, "mission end: hold at the last waypoint", keeper.target, keeper)
        else:
            then = Handover(Mode.COMPLETE, "mission end: stop")
        return Steering("off", psi_d_rad=nav.psi_rad, guidance=g, then=then)
