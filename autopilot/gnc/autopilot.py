"""The helm: the operator's modes over the double-loop autopilot (thesis ch. 7-8).

    nav --> the current mode (autopilot.gnc.modes) --> a course (psi_d, speed), a force (psi_d, tau_com) or off
    course: psi_d, psi, r            --> PID (Eq 7.1)  --> tau_order
            speed cmd, speed over ground --> Fig 8.2 table + PI trim --> tau_com (never astern)
    force:  psi_d, psi, r            --> PID (Eq 7.1)  --> tau_order;  tau_com from station keeping (ahead or astern)
    tau_com, tau_order               --> Eq 8.5-8.6, saturation --> T_port, T_stbd --> PWM

Every mode shares the one PID, allocation and thrust curve. Commands
(:meth:`Autopilot.request`: hold, pause, resume, rtl, stop) come from the operator
or a failsafe; each answer is the new mode or a refusal, and every change of
mode is an event with its cause (:meth:`Autopilot.pop_events`).

Pure: the caller (daemon, simulator, evaluation) supplies the navigation
data and the time step; nothing here reads a clock or a device.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from autopilot.gnc.allocation import Allocator, common_thrust_n
from autopilot.gnc.avoidance import Avoidance, AvoidanceOutput
from autopilot.gnc.config import GncConfig
from autopilot.gnc.encounter import OwnShip
from autopilot.gnc.modes import (
    AutoMode,
    CompleteMode,
    Handover,
    HoldMode,
    ManualMode,
    PausedMode,
    PendingHold,
    RtlMode,
    Steering,
    StopMode,
)
from autopilot.gnc.pid import HeadingPid
from autopilot.gnc.speed import SpeedShort, SpeedTrim, along_heading_m_s
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.logschema import FAILSAFE_CAUSE_PREFIX, Mode
from autopilot.measured import HULL_LENGTH_M


@dataclass(frozen=True)
class NavInput:
    """What the autopilot needs to know each cycle (SI, local frame)."""

    north_m: float
    east_m: float
    psi_rad: float  # heading from north, clockwise
    speed_m_s: float  # speed over ground
    yaw_rate_rad_s: float  # > 0 turning to starboard
    course_rad: float  # course over ground (may equal psi when unknown)


@dataclass(frozen=True)
class ControlOutput:
    """One cycle's command and the reasons for it (the GNC fields of a log `cycle` line)."""

    mode: Mode  # the helm's mode this cycle (after any hand-over)
    wp_index: int
    tcpa_nd: float | None
    dcpa_nd: float | None
    cdh: float | None
    psi_d_rad: float
    heading_error_rad: float
    xte_m: float | None  # None when no leg is followed (holding, stopped)
    speed_cmd_m_s: float
    pid_p_n: float
    pid_i_n: float
    pid_d_n: float
    tau_com_n: float
    tau_order_n: float
    thrust_port_n: float
    thrust_stbd_n: float
    pwm_port_pct: float
    pwm_stbd_pct: float
    sat_port: bool
    sat_stbd: bool
    saturation: tuple[str, ...]
    turn_limit: int  # the allocation's: +1 a starboard turn cut, -1 a port turn, 0 delivered
    common_limit: int  # +1 the common thrust cut down (speed not delivered), -1 cut up, 0 delivered
    reached_index: int | None
    reached_distance_m: float | None  # distance to the reached waypoint at the switch (m)
    reached_how: str | None  # "capture" or "passed" (autopilot.gnc.waypoints)
    complete: bool
    tau_com_trim_n: float = 0.0  # speed-over-ground trim inside tau_com_n (tau_com_n = table + trim)
    thrust_off: bool = False  # zero thrust on both sides (stopped, complete, drifting inside the hold radius)
    finished: bool = False  # the mission ended with stop (mode complete): the run may end
    hold_target_ne_m: tuple[float, float] | None = None  # station keeping's point, when it ran
    holding: bool = False  # the hold proper (timed and scored), not station keeping closing on the point
    hold_error_m: float | None = None
    hold_heading_rad: float | None = None  # the heading it holds (given or least effort)
    hold_disturbance_n: float | None = None  # its estimate of the steady thrust the disturbance takes
    avoidance: AvoidanceOutput | None = None  # collision avoidance's view this cycle (None: no targets, or not steering)


_MODE_OF_COMMAND = {"hold": Mode.HOLD, "pause": Mode.PAUSED, "rtl": Mode.RTL, "stop": Mode.STOP}
START_CAUSE = "start"  # the mode cause of the mission the helm starts in, nobody having chosen another


def _own_ship(nav: NavInput) -> OwnShip:
    """Own ship for the encounter assessment, from the helm's navigation."""
    return OwnShip(nav.north_m, nav.east_m, nav.course_rad, max(nav.speed_m_s, 0.0), nav.psi_rad)


# eight points round a hold, pushed out by 1 / cos(22.5 deg) so that a straight limit passing between two of them
# is still the whole radius away (on the radius itself, such an edge could come within 0.92 of it: a review)
ARM_STICK_NEUTRAL_ND = 0.05  # arming in manual needs both sticks within this of neutral (-1..1)
_RING = tuple((math.cos(k * math.pi / 4.0) / math.cos(math.pi / 8.0), math.sin(k * math.pi / 4.0) / math.cos(math.pi / 8.0))
              for k in range(8))


class Autopilot:
    """The helm for one mission: modes, then PID and allocation. ``step`` once per control cycle."""

    def __init__(
        self,
        config: GncConfig,
        waypoints_ne_m,
        *,
        speeds_m_s=None,
        holds_s=None,
        rtl: bool = False,
        launch_ne_m: tuple[float, float] | None = None,
        boat_length_m: float = HULL_LENGTH_M,
        thrust_curve: ThrustCurve = ThrustCurve(),
        start_index: int = 0,
        armed: bool = True,
        within_limits=None,
    ) -> None:
        self.config = config
        self.boat_length_m = float(boat_length_m)
        self.auto = AutoMode(config, waypoints_ne_m, speeds_m_s=speeds_m_s, holds_s=holds_s, rtl=rtl,
                             boat_length_m=boat_length_m, start_index=start_index)
        self.guidance = self.auto.guidance  # the mission's route (wp_index, waypoints)
        self.mission_cleared = False  # MAVLink MISSION_CLEAR_ALL: no mission to resume until a new one
        self.armed = bool(armed)  # False: zero thrust whatever the mode asks, until armed
        # (north_m, east_m) -> bool: inside the latched position limits (the daemon's geofence and max distance);
        # None: no limits (evaluate, the campaigns). Points and courses the helm chooses itself (the hold off an
        # occupied waypoint, avoidance's alterations) are kept inside them.
        self.within_limits = within_limits
        self.current = self.auto
        self.started = False  # control has started: the helm has stepped with a position (commands before it wait)
        self.mode_cause = START_CAUSE  # why the helm is in its mode (a mode event's cause: "failsafe geofence", "ctl stop")
        self.paused_from = None  # the mode a pause interrupted (resume goes back to it)
        self.launch_ne_m = None if launch_ne_m is None else (float(launch_ne_m[0]), float(launch_ne_m[1]))
        self.pid = HeadingPid(config.pid)
        self.allocator = Allocator(config.allocation, thrust_curve)
        self.speed_trim = SpeedTrim(config.speed)
        self.speed_short = SpeedShort(config.speed)
        self._events: list[tuple[str, dict]] = []
        if self.launch_ne_m is not None:  # given (a restart carrying on the run before): said as when it is set
            self._events.append(("launch", {"north_m": self.launch_ne_m[0], "east_m": self.launch_ne_m[1],
                                            "carried": True}))
        self._last_kind: str | None = None
        self.avoidance = Avoidance(config.avoidance)
        self._situations: dict[int, tuple[str, bool]] = {}  # target -> (situation, acting) last logged
        self._hold_across = False  # the last hold_heading event said the given heading cannot be kept
        # the heading the disturbance lies along while a hold's given heading cannot be kept across it (rad), else None
        self.hold_across_feasible_rad: float | None = None
        self._hold_off_s = 0.0  # how long the hold has been farther than hold.off_warn_m from its point
        self._hold_off_said = False
        # the operator's speed over ground (m/s) for the legs of the mission and of the return, in place of the
        # planned ones, until given back or a new mission comes (MAVLink DO_CHANGE_SPEED, `ctl speed`); None: planned
        self.speed_m_s: float | None = None
        # a new or cleared mission came while the boat was on a return: the operator's speed stays the return's, and
        # the planned speeds come back when the new mission is flown (Autopilot._mission_speeds)
        self._speed_until_mission = False

    # ---------------------------------------------------------------- state
    @property
    def mode(self) -> Mode:
        return self.current.mode

    @property
    def mode_chosen(self) -> bool:
        """The helm is not in the mission it starts in, untouched: a command, a failsafe or a held start chose its
        mode (before control starts, that mode is the one reported, not INITIALISING)."""
        return (self.current.mode, self.mode_cause) != (Mode.AUTO, START_CAUSE)

    @property
    def wp_index(self) -> int:
        """Index of the mission waypoint being steered to."""
        return self.guidance.index

    @property
    def complete(self) -> bool:
        """The mission's route is done: its last waypoint reached and that waypoint's hold item (if it has one)
        over. Complete at the hold item's start, the daemon logged mission_complete and `ctl status` said
        "complete" while the boat held there under thrust for the item's time (an operator audit)."""
        return self.guidance.complete and self.auto.item_keeper is None

    @property
    def resume_index(self) -> int:
        """The waypoint a restart takes the mission up at: a hold item's under way, else the one steered to (saved
        as the next, a crash in a hold item skipped the rest of it: a review of 2026-12-06)."""
        return self.auto.item_index if self.auto.item_keeper is not None else self.guidance.index

    @property
    def finished(self) -> bool:
        """The mission ended with stop: nothing more to do."""
        return self.current.mode is Mode.COMPLETE

    def hold_target(self) -> tuple[float, float] | None:
        keeper = getattr(self.current, "keeper", None) or (self.auto.item_keeper if self.current is self.auto else None)
        return None if keeper is None else keeper.target

    def resume_homeward(self) -> None:
        """A restart of a run that was on the mission's own way home: the route counts as done, so the mission's
        end (its rtl) follows at once; the last waypoint was flown out to first, then home (stop 42's note)."""
        self.guidance.finish()

    def pop_events(self) -> list[tuple[str, dict]]:
        """(event name, fields) since the last call: ``mode`` {mode, from, cause}, ``launch`` {north_m, east_m}."""
        out, self._events = self._events, []
        return out

    def reset_integrator(self) -> None:
        """Zero the heading and speed integrals (after a failsafe, before resuming)."""
        self.pid.reset()
        self.speed_trim.reset()

    def restart_control(self) -> None:
        """The helm drives again after cycles it did not (a failsafe, a lost fix): the integrals are zeroed, and
        the route's "passed abeam" test must see its target ahead again, as after a pause. The boat drifted
        meanwhile: a fix lost 4.5 m short of a waypoint came back with the boat coasted past it, and the waypoint
        was logged reached ("passed", 10 m off) though the boat never came near it under control."""
        self.reset_integrator()
        self.speed_short.restart()
        for g in (self.guidance, getattr(self.current, "guidance", None)):
            if g is not None:
                g.disarm_pass()

    # ---------------------------------------------------------------- commands
    def request(self, command: str, nav: NavInput | None, *, cause: str, heading_rad: float | None = None,
                unavailable: str = "no position and heading",
                target_ne_m: tuple[float, float] | None = None) -> tuple[bool, str]:
        """An operator's or a failsafe's command -> (accepted, the new mode or the refusal).

        ``nav`` is None when the position or the heading cannot be trusted (``unavailable`` says why):
        then only ``stop``, ``arm``, ``disarm`` and ``manual`` are accepted, once control has started; before it
        (no step with a position yet) a hold or a pause waits for it (:class:`PendingHold`), and the mission,
        resume and rtl (given a launch point) need none. ``heading_rad``: the heading a
        ``hold`` keeps (None = least effort); ``target_ne_m``: where it holds (None = here; MAVLink's
        reposition, "go here").
        """
        if command == "stop":
            if self.current.mode is not Mode.STOP:
                self._switch(StopMode(), cause)
            return True, Mode.STOP.value
        if command in ("arm", "disarm"):
            armed = command == "arm"
            sticks = self.current if isinstance(self.current, ManualMode) else None
            if armed and not self.armed and sticks is not None and max(abs(sticks.forward_nd),
                                                                      abs(sticks.turn_nd)) > ARM_STICK_NEUTRAL_ND:
                # ArduPilot's "throttle not zero" arming check: armed in manual with the stick held forward, the boat
                # went to full thrust at once (a new-user audit)
                return False, (f"arm refused: in manual the sticks must be at neutral to arm (forward "
                               f"{sticks.forward_nd:+.2f}, turn {sticks.turn_nd:+.2f}; within "
                               f"{ARM_STICK_NEUTRAL_ND:g})")
            if armed != self.armed:
                self.armed = armed
                self._events.append(("arming", {"armed": armed, "cause": cause}))
            return True, "armed" if armed else "disarmed"
        if command == "manual":  # needs no position: the operator sees the boat
            if self.current.mode is not Mode.MANUAL:
                self._switch(ManualMode(), cause)
            return True, Mode.MANUAL.value
        if command not in ("hold", "pause", "resume", "continue", "rtl", "auto"):
            return False, (f"{command} refused: unknown command (hold, pause, resume, auto, rtl, stop, arm, disarm, "
                           "manual)")
        # before control starts an operator's hold waits for it (PendingHold); a failsafe's never does: a fault's
        # hold or rtl without a position takes stop (the guard, ArduPilot's requires_position)
        if nav is None and (self.started or cause.startswith(FAILSAFE_CAUSE_PREFIX)):
            return False, f"{command} refused: {unavailable}"
        mode = self.current.mode
        if command == "resume":
            return self._resume(nav, cause)
        if command == "continue":
            return self._continue(nav, cause)
        if command == "auto":
            return self._auto(cause)
        if command == "pause" and mode is Mode.PAUSED:  # as every other command of the mode it is in (an audit)
            return True, mode.value
        if command == "pause" and mode not in (Mode.AUTO, Mode.RTL):
            return False, f"pause refused: mode {mode.value} (pause holds a running mission or return)"
        if command == "rtl" and self.launch_ne_m is None:
            return False, "rtl refused: no launch point yet (control has not started)"
        if not self.started and command in ("hold", "pause"):
            return self._pending(command, cause, heading_rad=heading_rad, target_ne_m=target_ne_m)
        given = getattr(getattr(self.current, "keeper", None), "heading_rad", None)
        if (command == "hold" and mode is Mode.HOLD and heading_rad is None and target_ne_m is None
                and given is not None):
            # a plain hold while holding a given heading: the heading is no longer given (it was answered "hold"
            # and ignored, the boat held across a current it could not, 10 m off; a modes audit)
            self._switch(HoldMode(self.config.hold, self.current.keeper.target, heading_rad=None,
                                  initial_heading_rad=nav.psi_rad,
                                  keeper=self.current.keeper.least_effort(nav.psi_rad)), cause)
            return True, Mode.HOLD.value
        if mode is _MODE_OF_COMMAND[command] and not (command == "hold" and (heading_rad is not None or
                                                                             target_ne_m is not None)):
            self._same_mode(cause)
            return True, mode.value
        if command == "hold":  # (before control starts rtl has no nav: only a hold and a pause need it, pending)
            point = self._stopping_point(nav) if target_ne_m is None else (float(target_ne_m[0]), float(target_ne_m[1]))
            keeper = getattr(self.current, "keeper", None) if mode in (Mode.HOLD, Mode.PAUSED) else None
            if (target_ne_m is None and keeper is not None and math.hypot(
                    nav.north_m - keeper.target[0], nav.east_m - keeper.target[1]) <= self.config.hold.approach_m):
                # a new heading for the hold the boat is at keeps its point, as ArduPilot turns the loiter without
                # moving it: taken where the current had swept the boat, the point jumped 5 m downstream (an
                # operator audit); a go-here still far off (GUIDED) is not the hold asked for: here it is
                point = keeper.target
            self._switch(HoldMode(self.config.hold, point, heading_rad=heading_rad, initial_heading_rad=nav.psi_rad),
                         cause)
        elif command == "pause":
            self.paused_from = self.current
            self._switch(PausedMode(self.config.hold, self._stopping_point(nav), heading_rad=None,
                                    initial_heading_rad=nav.psi_rad), cause)
        else:
            self._switch(RtlMode(self.config, self.launch_ne_m, boat_length_m=self.boat_length_m), cause)
        return True, self.current.mode.value

    def _pending(self, command: str, cause: str, *, heading_rad: float | None,
                 target_ne_m: tuple[float, float] | None) -> tuple[bool, str]:
        """A hold or pause before control starts: taken now, reported as that mode, placed when control starts
        (:class:`PendingHold`). Refused before the first fix ("position stale"), LOITER and GUIDED were lost and the
        boat flew the mission when control started; taken after it, the planner was shown INITIALISING."""
        cur = self.current
        if (isinstance(cur, PendingHold) and cur.mode is _MODE_OF_COMMAND[command] and cur.heading_rad == heading_rad
                and cur.target_ne_m == (None if target_ne_m is None else tuple(map(float, target_ne_m)))):
            self._same_mode(cause)  # a planner repeats its LOITER until the heartbeat shows it
            return True, cur.mode.value
        if command == "pause":
            self.paused_from = cur
        self._switch(PendingHold(_MODE_OF_COMMAND[command], heading_rad=heading_rad, target_ne_m=target_ne_m), cause)
        return True, self.current.mode.value

    def _same_mode(self, cause: str) -> None:
        """The mode the helm is in, asked for again for another reason: the cause is the new one (a planner's
        LOITER after its GUIDED is reported as LOITER from then on; it kept showing GUIDED, the change "failed")."""
        if cause != self.mode_cause:
            self._events.append(("mode", {"mode": self.current.mode.value, "from": self.current.mode.value,
                                          "cause": cause}))
            self.mode_cause = cause

    def _stopping_point(self, nav: NavInput) -> tuple[float, float]:
        """Where the boat can stop from its ground speed at station keeping's braking (ArduPilot's loiter
        target): a hold "here" at speed does not reverse the boat back onto the point it passed."""
        v = nav.speed_m_s if math.isfinite(nav.speed_m_s) else 0.0
        d = v * v / (2.0 * self.config.hold.brake_m_s2)
        return nav.north_m + d * math.cos(nav.course_rad), nav.east_m + d * math.sin(nav.course_rad)

    def _resume(self, nav: NavInput, cause: str) -> tuple[bool, str]:
        if self.current is self.auto:
            if self.auto.item_keeper is not None and self.auto.item_returning:
                # on the way back to a hold item's point: a second resume (the first brought the boat back into
                # the mission from a stop) ended the hold 22 m short, then the mission, and the daemon exited with
                # the boat adrift (an operator audit)
                return True, f"{Mode.AUTO.value} (on the way back to waypoint {self.auto.item_index}'s hold: resume " \
                             "there ends it)"
            if self.auto.end_item_hold():
                self._events.append(("mode", {"mode": Mode.AUTO.value, "from": Mode.AUTO.value,
                                              "cause": f"{cause}: the waypoint's hold ended"}))
                return True, Mode.AUTO.value
            return True, Mode.AUTO.value
        if self.current.mode is Mode.PAUSED and self.paused_from is not None:
            back, self.paused_from = self.paused_from, None
            self._switch(back, cause)
            return True, back.mode.value
        return self._to_mission("resume", cause)

    @property
    def paused_on_rtl(self) -> bool:
        """Paused on a return to launch: resume (or continue) goes on home, never into the mission."""
        return self.current.mode is Mode.PAUSED and self.paused_from is not None and self.paused_from.mode is Mode.RTL

    def _continue(self, nav: NavInput, cause: str) -> tuple[bool, str]:
        """A planner's DO_PAUSE_CONTINUE 1: what a pause stopped goes on, nothing else moves (ArduPilot's resume of
        the mode it is in). As ``resume`` it drove the boat into the mission from a hold, a stop, an rtl, the
        hold after a manual timeout (a GCS audit: Mission Planner's Resume pressed in HOLD started the
        thrusters); in the mission it ended a waypoint's hold early."""
        mode = self.current.mode
        if mode is Mode.PAUSED and self.paused_from is not None:
            return self._resume(nav, cause)
        if self.current is self.auto:
            return True, Mode.AUTO.value  # running: nothing paused to continue
        return False, (f"continue refused: mode {mode.value} is not paused (continue goes on with what a pause "
                       "stopped; AUTO starts the mission)")

    def _auto(self, cause: str) -> tuple[bool, str]:
        """The mission (a planner's AUTO, MISSION_START): unlike resume, never back to what a pause interrupted. AUTO
        chosen while paused on an rtl was acknowledged and took the boat home; after a clear, home too (a new-user
        audit). Already in the mission: nothing changes (a hold item goes on)."""
        if self.current is self.auto:
            if not self.started:  # chosen before control starts: reported as AUTO, not the start's INITIALISING
                self._same_mode(cause)
            return True, Mode.AUTO.value
        ok, answer = self._to_mission("auto", cause)
        if ok:
            self.paused_from = None
        return ok, answer

    def _to_mission(self, command: str, cause: str) -> tuple[bool, str]:
        """Into the mission from another mode, or why not (none, or one complete)."""
        if self.mission_cleared:
            return False, f"{command} refused: no mission (it was cleared; upload one)"
        if self.complete:
            return False, f"{command} refused: the mission is complete (hold, rtl and stop are available)"
        self._switch(self.auto, cause)
        return True, Mode.AUTO.value

    def _switch(self, new, cause: str) -> None:
        old = self.current.mode
        if new.mode is not Mode.PAUSED:  # a pause ends with whatever replaces it
            self.paused_from = None
        if new is self.auto and self.current is not self.auto:  # back to the mission: no stale "passed"
            self.auto.guidance.disarm_pass()
            self.auto.back_to_item()
            if self._speed_until_mission:  # a mission that came on a return is flown at its planned speeds
                self.set_speed(None, cause=f"{cause}: the mission uploaded on a return")
        self.current = new
        self.mode_cause = cause
        self.reset_integrator()
        self._last_kind = None
        self._hold_off_s = 0.0  # a new hold's time off its point counts afresh
        self._events.append(("mode", {"mode": new.mode.value, "from": old.value, "cause": cause}))

    def _hand_over(self, h: Handover, nav: NavInput) -> None:
        if h.mode is Mode.HOLD:
            target = h.target_ne_m if h.target_ne_m is not None else (nav.north_m, nav.east_m)
            new = HoldMode(self.config.hold, target, heading_rad=None, initial_heading_rad=nav.psi_rad, keeper=h.keeper)
        elif h.mode is Mode.RTL:
            if self.launch_ne_m is None:  # pragma: no cover - set on the first step
                self.launch_ne_m = (nav.north_m, nav.east_m)
            new = RtlMode(self.config, self.launch_ne_m, boat_length_m=self.boat_length_m)
        elif h.mode is Mode.COMPLETE:
            new = CompleteMode()
        else:  # pragma: no cover - the modes hand over to these only
            raise ValueError(f"no hand-over to {h.mode}")
        self._switch(new, h.cause)

    # ---------------------------------------------------------------- the mission and the settings
    def set_sticks(self, forward_nd: float, turn_nd: float) -> bool:
        """Manual input (-1..1 each); False when not in manual (the input is not used)."""
        if isinstance(self.current, ManualMode):
            self.current.set_sticks(forward_nd, turn_nd)
            return True
        return False

    def replace_mission(self, waypoints_ne_m, *, speeds_m_s=None, holds_s=None, rtl: bool = False,
                        cause: str) -> None:
        """A new mission from its first waypoint. In ``auto`` (or paused in it) the boat flies the new one at
        once; in another mode it waits there for ``resume``."""
        old = self.auto
        self.auto = AutoMode(self.config, waypoints_ne_m, speeds_m_s=speeds_m_s, holds_s=holds_s, rtl=rtl,
                             boat_length_m=self.boat_length_m)
        self.guidance = self.auto.guidance
        self.mission_cleared = False
        self._mission_speeds(cause)  # the new mission's own speeds
        if self.paused_from is old:
            self.paused_from = self.auto
        if self.current is old:
            self._switch(self.auto, cause)

    def clear_mission(self, nav: NavInput | None, *, cause: str, unavailable: str = "no position") -> str:
        """No mission: running it, the boat holds where it is (stops without a position)."""
        self.mission_cleared = True
        self._mission_speeds(cause)
        if self.current is self.auto or self.paused_from is self.auto:
            self.paused_from = None
            ok, _ = self.request("hold", nav, cause=cause, unavailable=unavailable)
            if not ok:
                self.request("stop", None, cause=cause)
        return self.current.mode.value

    def set_current(self, index: int, *, cause: str, also: str = "") -> tuple[bool, str]:
        """Fly the mission from waypoint ``index`` (MAVLink set current); ``also``: how the asker numbers it, said
        beside the waypoint (a planner's mission item: its STATUSTEXT said "waypoint 2" for item 4)."""
        n = len(self.guidance.waypoints)
        if self.mission_cleared:
            return False, "set current refused: the mission was cleared (upload one first)"
        if not 0 <= index < n:
            return False, f"set current refused: waypoint {index} is not in the mission (0..{n - 1})"
        g = self.guidance
        g.index, g.complete = int(index), False
        g._leg_start = g.waypoints[index - 1] if index > 0 else None  # from where the boat is, for the first
        g.reset()
        g.disarm_pass()
        self.auto.end_item_hold()
        said = f"waypoint {index}" + (f" ({also})" if also else "")
        self._events.append(("mode", {"mode": self.current.mode.value, "from": self.current.mode.value,
                                      "cause": f"{cause}: {said}"}))
        return True, said

    def set_speed(self, speed_m_s: float | None, *, cause: str) -> str:
        """The operator's speed (m/s, > 0; checked by the caller against the mission's limit) for every leg of the
        mission and of a return, from the next step on, through pauses, holds and resumes (the daemon saves it with the
        progress: a restart carrying the run on sets it again); None:
        the mission's planned speeds again. Turns and arrivals still slow the boat below it. A new or cleared
        mission gives the planned speeds back (ArduPilot's AUTO starts at WP_SPEED; on a return, once the new mission
        is flown: _mission_speeds). Returns what is flown."""
        speed = None if speed_m_s is None else float(speed_m_s)
        self._speed_until_mission = False
        if speed != self.speed_m_s:
            self.speed_m_s = speed
            self._events.append(("speed", {"speed_m_s": speed, "cause": cause}))
        return "the mission's planned speeds" if speed is None else f"{speed:g} m/s"

    def _mission_speeds(self, cause: str) -> None:
        """A new or cleared mission gives the planned speeds back: now, or, on a return (rtl, or paused on one), once
        the new mission is flown. A mission uploaded or cleared on the way home sped the boat the operator had slowed
        near swimmers up to WP_SPEED for the rest of the way home, which no mission's speed is for (a review)."""
        if self.speed_m_s is not None and (self.current.mode is Mode.RTL or self.paused_on_rtl):
            self._speed_until_mission = True
            return
        self.set_speed(None, cause=cause)

    def _route_speed(self) -> None:
        """The operator's speed to the routes the helm may steer this cycle (the mission's, a return's)."""
        self.auto.guidance.speed_override_m_s = self.speed_m_s
        guidance = getattr(self.current, "guidance", None)
        if guidance is not None:
            guidance.speed_override_m_s = self.speed_m_s

    def set_config(self, config: GncConfig) -> None:
        """New gains and limits, from the next step on (a parameter set between cycles)."""
        self.config = config
        self.pid.config, self.speed_trim.config, self.speed_short.config = config.pid, config.speed, config.speed
        self.allocator = Allocator(config.allocation, self.allocator.curve)
        for mode in (self.auto, self.current, self.paused_from):
            if mode is None:
                continue
            if hasattr(mode, "config"):
                mode.config = config
            guidance = getattr(mode, "guidance", None)
            if guidance is not None:
                guidance.config = config.guidance
            for keeper in (getattr(mode, "keeper", None), getattr(mode, "item_keeper", None)):
                if keeper is not None:
                    keeper.config = config.hold
            closing = getattr(mode, "closing", None)
            if closing is not None:
                closing.config = config.hold
                if closing.keeper is not None:
                    closing.keeper.config = config.hold

    # ---------------------------------------------------------------- the cycle
    def step(self, nav: NavInput | None, dt_s: float, *, targets=(), t_s: float = 0.0) -> ControlOutput:
        """One control cycle: navigation data and the time since the last cycle -> command. ``nav`` may be
        None only in a mode that needs no position (manual, stop). ``targets``: other vessels
        (:class:`autopilot.gnc.encounter.TargetState`, from AIS) that collision avoidance weighs against
        the mode's course; ``t_s`` the time of this cycle (the encounters' hysteresis counts on it)."""
        if nav is None:
            if self.current.requires_position:
                raise ValueError(f"mode {self.current.mode.value} needs a position and a heading")
            return self._inner(None, dt_s, self.current.update(None, dt_s), None)
        if not (math.isfinite(nav.north_m) and math.isfinite(nav.east_m) and math.isfinite(nav.psi_rad)):
            raise ValueError("NavInput position and heading must be finite")
        if self.launch_ne_m is None:
            self.launch_ne_m = (nav.north_m, nav.east_m)
            self._events.append(("launch", {"north_m": nav.north_m, "east_m": nav.east_m, "carried": False}))
        if not self.started:
            self.started = True
            if isinstance(self.current, PendingHold):  # asked for before: it holds from here (said when it was taken)
                self.current = self.current.begin(self.config.hold, self._stopping_point(nav), nav)
        occupied = self._occupied(nav, targets)
        self._end_hold_off(nav, targets)
        self._route_speed()
        s = self.current.update(nav, dt_s)
        reached = s.guidance if self.current is self.auto else None  # rtl's own arrival is not a mission waypoint
        if occupied is not None and reached is not None and reached.reached_how == "occupied":
            self._events.append(("waypoint_occupied", {
                "wp_index": reached.reached_index, "target": occupied.target.target_id, "name": occupied.target.name,
                "distance_m": round(reached.reached_distance_m, 1), "need_m": round(occupied.need_m, 1),
                "target_to_waypoint_m": round(occupied.target_to_point_m, 1)}))
        for _ in range(3):  # a hand-over steers with the new mode in the same cycle (rtl -> hold, auto -> rtl)
            if s.then is None:
                break
            self._hand_over(s.then, nav)
            self._route_speed()
            s = self.current.update(nav, dt_s)
        self._check_hold_heading(s)
        self._check_hold_off(s, dt_s)
        s, avoid = self._avoid(nav, s, targets, t_s)
        out = self._inner(nav, dt_s, s, reached)
        return out if avoid is None else dataclasses.replace(out, avoidance=avoid)

    def _occupied(self, nav: NavInput, targets):
        """Tell the mission's guidance whether its waypoint is occupied (Avoidance.occupying), this cycle."""
        g = self.auto.guidance
        occ = None
        if targets and self.current is self.auto and not g.complete:
            occ = self.avoidance.occupying(_own_ship(nav), g.waypoints[g.index], targets,
                                           allowed=None if self.within_limits is None else self._may_hold_at)
        g.occupied_reach_m = None if occ is None else occ.reach_m
        self.auto.occupied = occ
        return occ

    def _end_hold_off(self, nav: NavInput, targets) -> None:
        """The hold kept off a waypoint a stopped vessel occupied (AutoMode.holding_off) goes to the waypoint itself
        once that vessel is reported clear of it (by avoidance's resume margin: Avoidance.clear_of). Kept off, the
        boat never went on to the waypoint after the vessel sailed away (a final hold sat 26 m short for good: an
        operator audit). Silence is no proof the point is free: a vessel no longer reported (its AIS off, the receiver
        unplugged, dropped from the table after ais.receiver.stale_after_s) may still lie there, and the hold there
        went onto it with avoidance blind (a review); the operator may move the hold. A hold the operator chose there
        is theirs (another keeper): it stays."""
        if self.auto.holding_off is None:
            return
        index, keeper = self.auto.holding_off
        in_force = getattr(self.current, "keeper", None) or (self.auto.item_keeper if self.current is self.auto
                                                             else None)
        off = self.auto.held_off.get(index)
        if keeper is not in_force or off is None:
            return
        waypoint = self.auto.guidance.waypoints[index]
        vessel = next((t for t in targets if t.target_id == off.target_id), None)
        if vessel is None or not self.avoidance.clear_of(vessel, waypoint):
            return
        free = keeper.least_effort(nav.psi_rad, target_ne_m=(float(waypoint[0]), float(waypoint[1])))
        if self.current is self.auto:
            self.auto.item_keeper = free
        else:
            self.current.keeper = free
        self.auto.holding_off = None
        del self.auto.held_off[index]
        # the same mode with a new point (as a jump to a waypoint is said): its cause stays the mode's own
        self._events.append(("mode", {"mode": self.current.mode.value, "from": self.current.mode.value,
                                      "cause": f"waypoint {index} free: vessel {off.target_id} reported clear of it: "
                                               "holding at the waypoint"}))

    def _may_hold_at(self, north_m: float, east_m: float) -> bool:
        """A hold the helm places itself may be kept here: the point, and the ring of hold.off_warn_m round it (what
        a hold may wander before it is said to be off), inside the position limits."""
        r_m = self.config.hold.off_warn_m
        return all(self.within_limits(north_m + r_m * c, east_m + r_m * sn) for c, sn in _RING) and \
            self.within_limits(north_m, east_m)

    def _check_hold_off(self, s: Steering, dt_s: float) -> None:
        """Say when a hold has been off its point by more than hold.off_warn_m for hold.off_warn_s (a current or wind
        it cannot stem, or cannot settle against: one swept the boat 18 m off and back every 80 s for 500 s, status
        saying only the error; found by a modes audit), and when it is back within that distance."""
        cfg = self.config.hold
        # holding, not closing on the point from afar (a "go here" 100 m off is no hold that failed)
        off = (s.hold is not None and not s.hold.approach and math.isfinite(s.hold.error_m)
               and s.hold.error_m > cfg.off_warn_m)
        self._hold_off_s = self._hold_off_s + dt_s if off else 0.0
        if off and not self._hold_off_said and self._hold_off_s >= cfg.off_warn_s:
            self._hold_off_said = True
            self._events.append(("hold_off", {"off": True, "error_m": round(s.hold.error_m, 1),
                                              "for_s": round(self._hold_off_s, 1), "limit_m": cfg.off_warn_m,
                                              "disturbance_n": round(s.hold.disturbance_n, 1)}))
        elif self._hold_off_said and (s.hold is None or not off):
            self._hold_off_said = False
            fields = {"off": False, "limit_m": cfg.off_warn_m}
            if s.hold is not None:
                fields["error_m"] = round(s.hold.error_m, 1)
            self._events.append(("hold_off", fields))

    def _check_hold_heading(self, s: Steering) -> None:
        """Say when a hold's given heading cannot be kept on the point (the current or wind across it), and when
        it can again: the operator chose it, so it is kept, but the boat will sit off the point."""
        feasible = s.hold.feasible_heading_rad if s.hold is not None else None
        across = feasible is not None
        self.hold_across_feasible_rad = feasible
        if across == self._hold_across:
            return
        self._hold_across = across
        if s.hold is not None:  # (across implies a hold; a hold that ended says nothing)
            fields = {"across": across, "heading_deg": round(math.degrees(s.hold.psi_ref_rad) % 360.0, 1)}
            if across:
                fields["feasible_heading_deg"] = round(math.degrees(feasible) % 360.0, 1)
                fields["limit_deg"] = self.config.hold.max_correction_deg
            self._events.append(("hold_heading", fields))

    def _avoid(self, nav: NavInput, s: Steering, targets, t_s: float):
        """Collision avoidance on the mode's course (autopilot.gnc.avoidance): one more input to the same PID
        and allocation. A boat holding station avoids too: it leaves the point on the cheapest clearing
        course and station keeping brings it back. Its alterations keep inside the position limits (within_limits,
        the failsafe's: one that left the geofence latched its rtl mid-encounter)."""
        if s.kind not in ("course", "force") or (not targets and not self._situations):
            return s, None
        own = _own_ship(nav)
        if s.kind == "course":
            a = self.avoidance.step(own, list(targets), s.psi_d_rad, s.speed_cmd_m_s, t_s, self.within_limits)
            if a.active:
                s = dataclasses.replace(s, psi_d_rad=a.psi_d_rad, speed_cmd_m_s=a.speed_cmd_m_s)
        else:
            ref = s.hold.psi_ref_rad if s.hold is not None else nav.psi_rad
            speed = self.config.hold.approach_speed_m_s
            if self.speed_m_s is not None and self.current.mode in (Mode.AUTO, Mode.RTL):  # closing on a stop there
                speed = min(speed, self.speed_m_s)  # (station keeping's approach is kept to it too: modes.keep_station)
            a = self.avoidance.step(own, list(targets), ref, speed, t_s, self.within_limits)
            if a.active:
                s = dataclasses.replace(s, kind="course", psi_d_rad=a.psi_d_rad, speed_cmd_m_s=a.speed_cmd_m_s)
        self._log_encounters(a)
        return s, a

    def _log_encounters(self, a: AvoidanceOutput) -> None:
        seen = set()
        for t in a.targets:
            seen.add(t.target_id)
            key = (t.situation.value, bool(t.acting))
            if self._situations.get(t.target_id) != key:
                self._situations[t.target_id] = key
                self._events.append(("encounter", {
                    "target": t.target_id, "name": t.name, "situation": t.situation.value, "rule": t.rule,
                    "acting": bool(t.acting), "risk": round(t.risk, 3), "range_m": round(t.range_m, 1),
                    "dcpa_m": round(t.dcpa_m, 1), "tcpa_s": round(t.tcpa_s, 1), "reason": t.reason}))
        for gone in set(self._situations) - seen:
            del self._situations[gone]

    def _inner(self, nav: NavInput | None, dt_s: float, s: Steering, reached) -> ControlOutput:
        if not self.armed:  # disarmed: zero thrust whatever the mode asks
            s = Steering("off", psi_d_rad=s.psi_d_rad, guidance=s.guidance, hold=s.hold,
                         hold_target_ne_m=s.hold_target_ne_m, holding=s.holding)
        if s.kind != self._last_kind:  # a new kind of demand: nothing integrated for the old one counts
            self.reset_integrator()
            self._last_kind = s.kind
        psi = s.psi_d_rad if nav is None else nav.psi_rad
        terms = self.pid.terms(s.psi_d_rad, psi, 0.0 if nav is None else nav.yaw_rate_rad_s)
        trim_n = 0.0
        if s.kind == "off":
            alloc = self.allocator.allocate(0.0, 0.0)
            p_n = i_n = d_n = 0.0
        elif s.kind == "manual":  # the sticks: full forward = the forward limit, full turn = all of it differential
            alloc_cfg = self.allocator
            tau_com = s.forward_nd * (alloc_cfg.upper_n if s.forward_nd >= 0.0 else -alloc_cfg.lower_n)
            alloc = self.allocator.allocate(tau_com, s.turn_nd * alloc_cfg.upper_n)
            p_n = i_n = d_n = 0.0
        else:
            p_n, i_n, d_n = terms.p_n, terms.i_n, terms.d_n
            floor = False
            if s.kind == "course":
                speed_n = along_heading_m_s(nav) if math.isfinite(nav.speed_m_s) else s.speed_cmd_m_s  # none: table only
                trim_n = self.speed_trim.terms(s.speed_cmd_m_s, speed_n).trim_n
                tau_com = common_thrust_n(s.speed_cmd_m_s) + trim_n
                floor = tau_com <= 0.0
                if floor:  # never astern common mode on a course (see autopilot.gnc.speed)
                    trim_n -= tau_com
                    tau_com = 0.0
            else:  # force: station keeping's own along-hull thrust, ahead or astern
                tau_com = s.tau_com_n
            alloc = self.allocator.allocate(tau_com, p_n + i_n + d_n)
            self.pid.integrate(terms.heading_error_rad, dt_s, turn_limit=alloc.turn_limit)
            if s.kind == "course":  # the allocator cut the common mode: more speed cannot be delivered
                self.speed_trim.integrate(s.speed_cmd_m_s, speed_n, dt_s, block_up=alloc.common_limit > 0,
                                          block_down=floor)
        short = (self.speed_short.update(s.speed_cmd_m_s, speed_n, dt_s, trim_n=trim_n,
                                         integral_n=self.speed_trim.integral_n, thrusters_full=alloc.common_limit > 0)
                 if s.kind == "course" else self.speed_short.update(None, 0.0, dt_s))
        if short is not None:
            self._events.append(("speed_short", short))
        g, h = s.guidance, s.hold
        return ControlOutput(
            mode=self.current.mode,
            wp_index=self.guidance.index,
            tcpa_nd=None if g is None else g.tcpa_nd,
            dcpa_nd=None if g is None else g.dcpa_nd,
            cdh=None if g is None else g.cdh,
            psi_d_rad=s.psi_d_rad,
            heading_error_rad=terms.heading_error_rad,
            xte_m=None if g is None or s.kind != "course" else g.xte_m,
            speed_cmd_m_s=s.speed_cmd_m_s if s.kind == "course" else 0.0,
            pid_p_n=p_n,
            pid_i_n=i_n,
            pid_d_n=d_n,
            tau_com_n=alloc.tau_com_n,
            tau_order_n=alloc.tau_order_n,
            thrust_port_n=alloc.thrust_port_n,
            thrust_stbd_n=alloc.thrust_stbd_n,
            pwm_port_pct=alloc.pwm_port_pct,
            pwm_stbd_pct=alloc.pwm_stbd_pct,
            sat_port=alloc.sat_port,
            sat_stbd=alloc.sat_stbd,
            saturation=alloc.saturation,
            turn_limit=alloc.turn_limit,
            common_limit=alloc.common_limit,
            reached_index=None if reached is None else reached.reached_index,
            reached_distance_m=None if reached is None else reached.reached_distance_m,
            reached_how=None if reached is None else reached.reached_how,
            complete=self.complete,
            tau_com_trim_n=trim_n,
            thrust_off=s.kind == "off",
            finished=self.finished,
            hold_target_ne_m=s.hold_target_ne_m,
            holding=s.holding,
            hold_error_m=None if h is None else h.error_m,
            hold_heading_rad=None if h is None else h.psi_ref_rad,
            hold_disturbance_n=None if h is None else h.disturbance_n,
        )
