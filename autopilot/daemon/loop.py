"""The fixed-rate control loop: wiring and timing over the pure steps of :mod:`autopilot.daemon.cycle`.

One asyncio process. The loop runs on absolute deadlines of the injected clock
(``next_due += period``: no drift); when it falls behind by more than a period
it skips to the next deadline and counts the skipped cycles. Each cycle reads
the compass's latest :class:`~autopilot.devices.NavSample`, assembles the
navigation, asks the failsafe whether thrust is allowed, hands the failsafe's
actions and the operator's queued commands to the helm (:class:`autopilot.gnc.Autopilot`,
between cycles' steps, never waiting on a socket), steps the helm when allowed, sends
exactly one :class:`~autopilot.devices.ThrustCommand` and writes exactly one
``cycle`` line (:mod:`autopilot.logschema`). Everything it remembers between cycles
is in one :class:`LoopState`.

SIGTERM/SIGINT/SIGHUP end the loop at the next cycle: zero thrust is sent and its
acknowledgement awaited (bounded), ``stop`` logged, the log closed, exit 0.
"""

from __future__ import annotations

import asyncio
import collections
import math
import signal
from dataclasses import dataclass, field, replace

from autopilot.daemon import commands
from autopilot.daemon import cycle as steps
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.failsafe import Failsafe, resting_voltage_v
from autopilot.daemon.missionlog import MissionLog
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import OPERATOR_MODES, Progress, StateStore
from autopilot.devices import ZERO_THRUST, Compass, ThrustCommand, ThrusterLink
from autopilot.gnc import Autopilot
from autopilot.gnc.navigation import NavMemory, assemble
from autopilot.gnc.passes import PassTracker
from autopilot.logschema import (
    COG_HEADING_SOURCE,
    COMPASS_BACK,
    COURSE_FOR_HEADING,
    FAILSAFE_CAUSE_PREFIX,
    NEVER_REFUSED,
    RTL_ARRIVED_CAUSE,
    TIME_STOP_CAUSE,
    Mode,
)
from autopilot.mission import ItemNumbers, Mission

__all__ = ["LoopState", "ControlLoop", "watchdog_due", "COMMANDS_PER_CYCLE", "COMMANDS_QUEUED_MAX"]

# Operator commands carried out per cycle, and waiting at most: a ground station flooding valid commands
# (5000 MISSION_SET_CURRENT a second, each saving the progress file) once made cycles 80-100 ms late and
# skipped deadlines, with a log growing 0.5 MB/s; the loop's timing comes first, a command waits or is refused.
COMMANDS_PER_CYCLE = 5
COMMANDS_QUEUED_MAX = 100
# one command's waiting at most from one source: a station sending 2000 DO_CHANGE_SPEED a second filled the whole
# queue, and the operator's DISARM, HOLD and `autopilot ctl stop` were refused while the boat drove on (a new
# user's test of the link). Every station's requests come as source "mavlink": the cap is per command too
COMMANDS_QUEUED_PER_SOURCE_MAX = 20


def watchdog_due(*, ready: bool, lateness_s: float, period_s: float, since_last_s: float, interval_s: float) -> bool:
    """WATCHDOG=1 is due: only once ready, only from a cycle that started on time (later than its
    deadline by less than one period), and at most every ``interval_s`` (half of WatchdogSec).
    A loop that runs late every cycle therefore stops feeding systemd, which restarts it."""
    return ready and lateness_s < period_s and since_last_s >= interval_s


@dataclass
class LoopState:
    """Everything the control loop remembers from one cycle to the next."""

    nav: NavMemory = field(default_factory=NavMemory)
    cycles: int = 0
    skipped: int = 0  # deadlines skipped because the loop fell more than a period behind
    late_cycles: int = 0  # cycles that started a period or more after their deadline
    seq: int = -1  # the last Mbed command's sequence number
    driving: bool = False  # the GNC drove in the last cycle
    last_step_s: float | None = None  # clock time of the last GNC step
    completed_t_s: float | None = None  # mission time the route was complete (Autopilot.complete)
    finished: bool = False  # the mission's final action is to stop and it has
    passes_done: bool = False  # the last pass has ended (final_pass_s after completion)
    # mission time of the stop line (the end summary's; under --speedup max the clock went on through the shutdown:
    # the console said 54.0 s for a stop line's 53.11, a new user's test)
    stopped_t_s: float | None = None
    reached: list[int] = field(default_factory=list)
    failsafe_causes: list[str] = field(default_factory=list)
    closest_m: dict[int, float] = field(default_factory=dict)  # wp -> closest approach of its ended pass
    ready: bool = False  # READY=1 sent
    ready_warned: bool = False
    last_watchdog_s: float = -math.inf
    stop_signal: str | None = None
    mode: str = "waiting"  # the last cycle's
    last_cmd: ThrustCommand = ZERO_THRUST
    steered_error_rad: float | None = None  # the heading error the helm steered by last cycle (failsafe)
    on_course: bool = False  # the heading is the course over ground (the compass lost, failsafe.cog_fallback)
    stop_acknowledged: bool | None = None  # the Mbed acknowledged the zero thrust of the stop (None: not stopped yet)
    manual_input_wall_s: float = -math.inf  # wall time of the last manual input (a human's link runs on wall time)
    sticks_ignored_logged_wall_s: float = -math.inf  # stick input outside MANUAL: logged once a second (commands.py)
    sticks_ignored_unlogged: int = 0
    status: dict = field(default_factory=dict)  # the last cycle's, for `autopilot ctl status`

    @property
    def complete(self) -> bool:
        return self.completed_t_s is not None


class ControlLoop:
    """Wires the devices, the failsafe, the GNC, the log and the notifier (see the module docstring)."""

    def __init__(self, cfg: DaemonConfig, *, clock, autopilot: Autopilot, mission, mission_path: str,
                 mission_sha256: str, compass: Compass, thrusters: ThrusterLink, log: MissionLog,
                 notifier: Notifier, store: StateStore, fence_ne_m=None, hold_zero: str | None = None,
                 t0_s: float | None = None, ais=None) -> None:
        self.cfg, self.clock, self.ap, self.mission = cfg, clock, autopilot, mission
        self.mission_path, self.mission_sha256 = mission_path, mission_sha256
        self.compass, self.thrusters = compass, thrusters
        self.log, self.notifier, self.store = log, notifier, store
        self.failsafe = Failsafe(cfg.failsafe, fence_ne_m=fence_ne_m)
        autopilot.within_limits = self.failsafe.within_limits  # the holds the helm places stay inside them
        self.rules = steps.nav_rules(cfg)
        self.hold_zero = hold_zero  # an interrupted mission not to be resumed: start stopped (ctl resume starts it)
        self._saved_running = False  # this run's progress is the saved one (a held start keeps the old until then)
        self._saved_homeward = False  # what the saved progress says of the way home (Progress.homeward)
        self._saved_index = autopilot.wp_index  # the waypoint the saved progress takes the mission up at
        # the mode the operator took the boat off the mission with (Progress.operator); a held start is a stop of
        # theirs until they say otherwise: a jump or an upload saved while held, then a crash, flew the mission
        self.operator_mode = "stop" if hold_zero is not None else ""
        # why the loop goes on after the mission ended stopped (a ground station link, systemd), or None: it ends there
        self.stay_when_done: str | None = None
        self.time_stop_stayed = False  # max_mission_time's stop taken, and the loop went on for stay_when_done
        # (mode, s in it) the time stop ended, for the end summary (logschema.time_stop_words); the helm's mode
        # changes are followed for it: (from, s in it, cause) of the last, and since when the mode now is in force
        self.time_stop_from: tuple[str, float] | None = None
        self._last_mode_change: tuple[str, float, str] | None = None
        self._mode_entered_s: float | None = None  # mission time; the first helm step for the mode control starts in
        self._said_staying = False
        self.ais = ais  # autopilot.daemon.traffic.AisSource: other vessels for collision avoidance (None: no AIS)
        self.passes = PassTracker(mission.waypoints_ne_m, start_index=autopilot.wp_index)
        self.start_index = autopilot.wp_index  # the waypoint this run began at (a resumed run's earlier ones were not its)
        self._numbered: Mission | None = None
        self._item_numbers: ItemNumbers | None = None
        self.state = LoopState()
        self.commands: collections.deque = collections.deque()  # (request, answer callback), from the socket
        self._queued: collections.Counter = collections.Counter()  # (source, command) -> waiting in self.commands
        self._flooded = False  # commands were refused since the queue was last empty
        if hold_zero is not None:
            self.ap.request("stop", None, cause=f"start: {hold_zero}")
        self.t0_s = clock.now_s() if t0_s is None else t0_s  # mission time 0
        self._wall_start_s = clock.wall_elapsed_s()

    def request_stop(self, signame: str) -> None:
        if self.state.stop_signal is None:
            self.state.stop_signal = signame

    def install_signal_handlers(self) -> None:
        loop = asyncio.get_running_loop()
        # SIGHUP too: an ssh session or terminal that hangs up would otherwise kill the daemon outright,
        # leaving the last command on the Mbed until its firmware times out, with no stop line
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            loop.add_signal_handler(sig, self.request_stop, sig.name)

    # ---- one cycle ----------------------------------------------------------------------
    def cycle(self, now_s: float, lateness_s: float) -> None:
        st, t_s = self.state, now_s - self.t0_s
        sample = self.compass.sample()
        nav, st.nav = assemble(sample, now_s, st.nav, self.rules,
                               origin_lat_deg=self.mission.origin_lat_deg, origin_lon_deg=self.mission.origin_lon_deg)
        if nav.jump is not None:
            self.log.event("position_jump", t_s=t_s, **nav.jump.log_fields())
        on_course = nav.heading_source == COG_HEADING_SOURCE
        if on_course != st.on_course:  # the compass lost and the course steered on (or back): no fault says it
            st.on_course = on_course
            self.log.event("info", t_s=t_s, message=COURSE_FOR_HEADING if on_course else COMPASS_BACK,
                           heading_age_s=nav.heading_age_s)
        battery_v = self.thrusters.battery_v  # under the load the board had applied when it measured it
        load = self.thrusters.battery_load_pct or (st.last_cmd.duty_port_pct, st.last_cmd.duty_stbd_pct)
        battery_rest_v = resting_voltage_v(battery_v, *load, self.cfg.failsafe.battery_sag_v)
        decision = self.failsafe.update(steps.observe(
            # a mission ended with stop has no time to run out: the daemon staying up after it (systemd, a ground
            # station) tripped max_mission_time at zero thrust, saved the run aborted, and the next boot held the
            # boat for it (a review of 2026-12-06)
            nav, mission_time_s=None if st.finished else t_s, compass_connected=self.compass.connected,
            thrusters_connected=self.thrusters.connected, acks_missing_in_a_row=self.thrusters.consecutive_missing,
            compass_garbage_s=self.compass.last_garbage_s, thruster_garbage_s=self.thrusters.last_garbage_s,
            battery_v=battery_rest_v, thrusters_disobeying=self.thrusters.disobeying,
            steered_heading_error_rad=st.steered_error_rad))
        self._log_events(decision.events, t_s)
        helm_nav, unavailable = steps.helm_nav(nav, decision)
        for req in decision.requests:
            commands.failsafe_action(self, req, helm_nav, unavailable, t_s)
        if decision.requests and self._saved_running:  # a latched fault is remembered across a restart
            self._save("running")
        armed_before, mode_before, cause_before = self.ap.armed, self.ap.mode, self.ap.mode_cause
        speed_before = self.ap.speed_m_s
        for _ in range(min(len(self.commands), COMMANDS_PER_CYCLE)):
            request, answer = self.next_command()
            answer(commands.apply(self, request, helm_nav, unavailable, decision, t_s))
        if (self.ap.armed, self.ap.speed_m_s) != (armed_before, speed_before):  # remembered across a restart
            self._save_operator_settings()
        if (self.ap.mode, self.ap.mode_cause) != (mode_before, cause_before):  # the operator's mode, likewise
            self._operator_chose()
        self._flooded = self._flooded and bool(self.commands)
        self._manual_timeout(helm_nav, unavailable, t_s)
        mode, drive = steps.arbitrate(decision, steerable=nav.steerable, manual=self.ap.mode is Mode.MANUAL)
        st.driving = st.driving and drive
        out = self._steer(nav, now_s, t_s) if drive else None
        if out is not None:
            mode = out.mode
        st.steered_error_rad = steps.steered_error_rad(out)
        self._log_helm_events(t_s)
        if self.ais is not None:
            for report in self.ais.new_reports(now_s):
                self.log.event("target", t_s=t_s, **report)
        cmd = steps.command(out)
        st.seq = self.thrusters.send(cmd)
        st.last_cmd = cmd
        self._track_pass(nav, t_s)
        heading = sample.heading_rad
        self.log.event("cycle", t_s=t_s, **steps.cycle_record(
            cycle=st.cycles, t_s=t_s, mode=mode, nav=nav, out=out, cmd=cmd, wp_index=self.ap.wp_index,
            steering=drive, lateness_s=lateness_s, skipped=st.skipped,
            heading_latency_s=None if heading is None else self.clock.now_s() - heading.t_s, seq=st.seq,
            ack_missing=self.thrusters.ack_missing, nmea_dropped=self.compass.lines_dropped,
            active_faults=decision.active, battery_v=battery_v, battery_rest_v=battery_rest_v, armed=self.ap.armed))
        st.mode = mode.value
        st.status = self._status(t_s, mode, nav, out, decision, battery_v)
        st.cycles += 1
        self._notify(now_s, lateness_s)

    def _steer(self, nav, now_s: float, t_s: float):
        """One GNC step and what follows from it (waypoint events, completion, saved progress)."""
        st = self.state
        if not st.driving:  # control (re)starts: nothing integrated while the boat was stopped counts
            self.ap.restart_control()
            st.last_step_s = None
        dt_s = steps.step_dt_s(now_s, st.last_step_s, self.cfg.period_s)
        st.last_step_s, st.driving = now_s, True
        targets = () if self.ais is None else self.ais.targets(now_s)
        launch_before = self.ap.launch_ne_m
        if self._mode_entered_s is None:
            self._mode_entered_s = t_s
        out = self.ap.step(steps.nav_input(nav) if nav.steerable else None, dt_s, targets=targets, t_s=t_s)
        if self._saved_running and (self.ap.launch_ne_m != launch_before  # rtl's home, for a restart too
                                    or self._homeward() != self._saved_homeward  # the way home begun
                                    or self.ap.resume_index != self._saved_index):  # a hold item begun or over
            self._save("running")
        # saved before it is logged: a kill between the two must not leave a log that runs ahead of the state
        if out.reached_index is not None:
            st.reached.append(out.reached_index)
            self._save("running")
            self.log.event("waypoint_reached", t_s=t_s, wp_index=out.reached_index, north_m=nav.est_north_m,
                           east_m=nav.est_east_m, distance_m=out.reached_distance_m, how=out.reached_how)
            self._log_passes(self.passes.on_target(self.ap.wp_index), t_s)
        if out.complete and not st.complete:
            st.completed_t_s = t_s
            # the route is done, the run is not (a final hold, a return to launch, the last pass): saved as
            # running until the loop ends; saved "complete" here, a crash in the final hold came back and flew the
            # mission again from its first waypoint, unasked (a new-user audit)
            self._save("running")
            self.log.event("mission_complete", t_s=t_s, wp_count=len(self.mission.waypoints_ne_m),
                           rtl=bool(self.mission.rtl))
        st.finished = out.finished
        return out

    # ---- the helm's commands: failsafe actions, the operator's, the link's ----------------
    def log_event(self, name: str, /, **fields) -> None:
        """An event from outside the cycle (the control socket's refusals, the link), on mission time."""
        self.log.event(name, t_s=self.clock.now_s() - self.t0_s, **fields)

    def submit(self, request: dict, answer) -> None:
        """Queue a command (``{"command": ..., "source": ..., ...}``, see :mod:`autopilot.daemon.commands`);
        ``answer(reply dict)`` is called from the next cycle, between its steps: the caller never runs inside
        the loop's timing. The joystick's stream keeps only its latest input; beyond COMMANDS_QUEUED_MAX
        waiting, a command is refused at once (answered here, not in a cycle)."""
        # an explicit choice of manual (a mode change) is not a stick position: superseded by the next stick packet
        # it was answered ok and never made, with QGC's joystick on (a new user's test of the link)
        if request.get("command") == "manual" and self.commands and self.commands[-1][0].get("command") == "manual" \
                and self.commands[-1][0].get("source") == request.get("source") \
                and not self.commands[-1][0].get("explicit"):
            _, superseded = self.commands[-1]
            self.commands[-1] = (request, answer)  # the newer stick position replaces the one not yet applied
            superseded({"ok": True, "answer": "manual (superseded by a newer input)", "mode": self.ap.mode.value})
            return
        source, command = request.get("source"), request.get("command")
        if command in NEVER_REFUSED or request.get("failsafe"):
            # never refused for a full queue (each only takes thrust away, or is a failsafe's: the link-loss rtl
            # was refused and never asked again); the same request waiting already is not queued twice (20,000
            # disarms took 6.7 s of the event loop and held the queue for minutes: a review)
            if any(queued == request for queued, _ in self.commands):
                answer({"ok": True, "answer": f"{command}: the same request is waiting already",
                        "mode": self.ap.mode.value})
                return
            self._enqueue(request, answer)
            return
        mine = self._queued[(source, command)]
        full = len(self.commands) >= COMMANDS_QUEUED_MAX or mine >= COMMANDS_QUEUED_PER_SOURCE_MAX
        if full:
            if not self._flooded:  # once per flood: until the queue has drained
                self._flooded = True
                self.log_event("info", message="commands refused: queue full", queued=len(self.commands),
                               source=str(request.get("source")))
            answer({"ok": False, "busy": True, "answer": f"{command} refused: "
                    + (f"{mine} {command} commands of {source} already waiting" if mine >= COMMANDS_QUEUED_PER_SOURCE_MAX
                       else f"{len(self.commands)} commands already waiting") + " (a flood?)",
                    "mode": self.ap.mode.value})
            return
        self._enqueue(request, answer)

    def _enqueue(self, request: dict, answer) -> None:
        self.commands.append((request, answer))
        self._queued[(request.get("source"), request.get("command"))] += 1

    def next_command(self):
        """The oldest command waiting (request, answer), taken off the queue."""
        request, answer = self.commands.popleft()
        self._queued[(request.get("source"), request.get("command"))] -= 1
        return request, answer

    def replace_mission(self, mission, *, source: str, cause: str) -> None:
        """A new mission (same local origin) from its first waypoint, saved so that a restart continues it."""
        from autopilot.daemon.state import save_uploaded_mission

        path, sha = save_uploaded_mission(self.store.dir, mission)
        self.mission, self.mission_path, self.mission_sha256 = mission, str(path), sha
        self.ap.replace_mission(mission.waypoints_ne_m, speeds_m_s=mission.speeds_m_s, holds_s=mission.holds_s,
                                rtl=mission.rtl, cause=cause)
        st = self.state
        st.completed_t_s, st.finished, st.passes_done, st.reached, st.closest_m = None, False, False, [], {}
        self.passes_restart()
        self.start_index = self.ap.wp_index
        # a mission uploaded on the old one's own way home (or in its final hold) is not flown yet: the return is no
        # longer the mission's (homeward), so it is the operator's. Saved with no operator's mode, a crash and a
        # restart with resume_after_restart flew the new mission from its first waypoint (a review of c235c48)
        self._operator_chose()
        self.log.event("mission_replaced", t_s=self.clock.now_s() - self.t0_s, source=source,
                       waypoints=[[float(n), float(e)] for n, e in mission.waypoints_ne_m], path=str(path),
                       sha256=sha)
        self.save_progress("running")

    def passes_restart(self) -> None:
        """The closest-approach passes start again at the helm's waypoint (a new mission, a jump)."""
        self.state.passes_done = False
        self.passes = PassTracker(self.mission.waypoints_ne_m, start_index=self.ap.wp_index)

    @property
    def item_numbers(self) -> ItemNumbers:
        """The running mission's MAVLink item numbers (worked out once per mission)."""
        if self._numbered is not self.mission:
            self._numbered, self._item_numbers = self.mission, ItemNumbers.of(self.mission)
        return self._item_numbers

    def apply_config(self, cfg: DaemonConfig) -> None:
        """A new configuration from the next cycle on (a parameter set over the link)."""
        self.cfg = cfg
        self.failsafe.cfg = cfg.failsafe
        self.rules = steps.nav_rules(cfg)
        self.ap.set_config(cfg.gnc)

    def save_progress(self, status: str) -> None:
        self._save(status)

    def _manual_timeout(self, helm_nav, unavailable: str, t_s: float) -> None:
        """A manual source gone quiet: the configured hold (or stop), never the last stick position."""
        st, link = self.state, self.cfg.mavlink
        if self.ap.mode is not Mode.MANUAL:
            return
        if not self.ap.armed:
            # disarmed nothing drives, and the silence counts from the arm: MANUAL chosen disarmed went to the hold
            # half a second later, and the arm then ran the thrusters keeping station (a review)
            st.manual_input_wall_s = self.clock.wall_elapsed_s()
            return
        silent_s = self.clock.wall_elapsed_s() - st.manual_input_wall_s
        if silent_s <= link.manual_timeout_s:
            return
        cause = f"manual: no input for {silent_s:.2f} s"
        ok, _ = self.ap.request(link.manual_timeout_action, helm_nav, cause=cause, unavailable=unavailable)
        if not ok:
            self.ap.request("stop", None, cause=cause)

    def _log_helm_events(self, t_s: float) -> None:
        for name, fields in self.ap.pop_events():
            if name == "mode":
                entered = t_s if self._mode_entered_s is None else self._mode_entered_s
                self._last_mode_change = (str(fields.get("from")), t_s - entered, str(fields.get("cause")))
                if fields.get("mode") != fields.get("from"):  # a mode taken again (set_current, a new hold point)
                    self._mode_entered_s = t_s  # goes on: the review counts from the first line into it too
            self.log.event(name, t_s=t_s, **fields)

    def _status(self, t_s: float, mode, nav, out, decision, battery_v) -> dict:
        """The last cycle for `autopilot ctl status` and the MAVLink telemetry: SI, degrees for people."""
        from autopilot.geo import local_to_latlon

        hold = None if out is None else out.hold_target_ne_m
        ap, origin = self.ap, (self.mission.origin_lat_deg, self.mission.origin_lon_deg)
        goal = self._destination_ne_m(hold)
        dist = brg = None
        if nav.est_north_m is not None and goal is not None:
            dn, de = goal[0] - nav.est_north_m, goal[1] - nav.est_east_m
            dist, brg = math.hypot(dn, de), math.degrees(math.atan2(de, dn)) % 360.0
        launch = ap.launch_ne_m
        launch_ll = (None, None) if launch is None else local_to_latlon(launch[0], launch[1], *origin)
        item, n_items = self.mission_item_now()
        return {
            "t_s": round(t_s, 2), "mode": steps.reported_mode(mode, ap).value, "helm_mode": ap.mode.value,
            "mode_cause": ap.mode_cause, "armed": ap.armed,
            "control_started": mode is not Mode.WAITING,  # False: zero thrust, waiting for valid data
            "cycle": self.state.cycles, "wp_index": int(ap.wp_index), "wp_count": len(self.mission.waypoints_ne_m),
            "mission_complete": bool(ap.complete), "mission_cleared": ap.mission_cleared,
            "mission_item": item, "mission_items": n_items,
            "north_m": nav.north_m, "east_m": nav.east_m, "lat_deg": nav.lat_deg, "lon_deg": nav.lon_deg,
            "heading_deg": None if nav.heading_rad is None else round(math.degrees(nav.heading_rad) % 360.0, 1),
            "yaw_rate_deg_s": None if nav.yaw_rate_rad_s is None else math.degrees(nav.yaw_rate_rad_s),
            "sog_m_s": nav.sog_m_s, "cog_deg": None if nav.cog_rad is None else math.degrees(nav.cog_rad) % 360.0,
            "fix_quality": nav.fix_quality, "battery_v": battery_v, "active_faults": list(decision.active),
            "latched_faults": list(self.failsafe.latched), "latched_before_restart": list(self.failsafe.restored),
            "nmea_dropped": self.compass.lines_dropped,
            "hold_north_m": None if hold is None else hold[0], "hold_east_m": None if hold is None else hold[1],
            "hold_error_m": None if hold is None else out.hold_error_m,
            "hold_heading_deg": None if hold is None or out.hold_heading_rad is None
            else round(math.degrees(out.hold_heading_rad) % 360.0, 1),
            "hold_across_feasible_deg": None if hold is None or ap.hold_across_feasible_rad is None
            else round(math.degrees(ap.hold_across_feasible_rad) % 360.0, 1),
            "launch_ne_m": None if launch is None else list(launch),
            "launch_lat_deg": launch_ll[0], "launch_lon_deg": launch_ll[1],
            "wp_distance_m": dist, "wp_bearing_deg": brg,
            "psi_d_deg": None if out is None else math.degrees(out.psi_d_rad) % 360.0,
            "xte_m": None if out is None else out.xte_m,
            "speed_cmd_m_s": None if out is None else out.speed_cmd_m_s,
            "speed_set_m_s": ap.speed_m_s,  # the operator's for every leg (ctl speed, DO_CHANGE_SPEED); None: planned
            "tau_com_n": None if out is None else out.tau_com_n, "max_forward_n": ap.allocator.upper_n,
            "thrust_port_n": None if out is None else out.thrust_port_n,
            "thrust_stbd_n": None if out is None else out.thrust_stbd_n,
        }

    def _destination_ne_m(self, hold_ne_m) -> tuple[float, float] | None:
        """Where the helm takes the boat now, as ArduPilot's mode destination (a planner's distance to the waypoint
        and its bearing): the point held (a hold, a pause, GUIDED, a hold item, rtl closing on its end), rtl's launch
        point, the mission's waypoint; none when stopped, in manual or with the route done. The mission's
        waypoint in every mode said the boat in rtl 21 m from item 3 with home 46 m the other way (a GCS audit)."""
        ap = self.ap
        if hold_ne_m is not None:
            return hold_ne_m
        if ap.mode is Mode.RTL:
            return ap.current.launch
        if ap.mode is Mode.AUTO and not ap.guidance.complete:
            return ap.guidance.waypoints[ap.wp_index]
        return None

    def mission_item_now(self) -> tuple[int, int]:
        """(the MAVLink item number the helm steers to now, the mission's item count), (0, 0) when cleared: from
        the helm, not the last cycle's status (a MISSION_SET_CURRENT's answer is sent before the next cycle)."""
        ap, numbers = self.ap, self.item_numbers
        if ap.mission_cleared:
            return 0, 0
        # the RTL item once the mission has come to it; an rtl mid-mission, or a jump while returning, leaves the
        # mission's own current item (as ArduPilot reports it): a MISSION_SET_CURRENT answered with the RTL item
        # looked refused to the planner (a review)
        # ... and the hold at home it ends in (it went back to the last waypoint's item: a GCS audit)
        returning = (numbers.rtl is not None and ap.guidance.complete
                     and (ap.mode is Mode.RTL or ap.mode_cause == RTL_ARRIVED_CAUSE))
        item = numbers.rtl if returning else numbers.waypoints[ap.wp_index]
        return int(item), int(numbers.count)

    def _track_pass(self, nav, t_s: float) -> None:
        """A new fix goes to the pass tracker (autopilot.gnc.passes), attributed to the waypoint steered
        to now; the last pass ends ``final_pass_s`` after the last waypoint is reached."""
        st = self.state
        if st.complete and not st.passes_done and t_s - st.completed_t_s >= self.cfg.gnc.guidance.final_pass_s:
            st.passes_done = True
            self._log_passes(self.passes.finish(), t_s)
        if nav.new_fix and not st.passes_done and nav.north_m is not None:
            self._log_passes(self.passes.on_fix(nav.fix_t_s - self.t0_s, nav.north_m, nav.east_m, self.ap.wp_index), t_s)

    def _log_passes(self, passes, t_s: float) -> None:
        for p in passes:
            self.state.closest_m[p.wp_index] = p.closest_approach_m
            self.log.event("waypoint_pass", t_s=t_s, wp_index=p.wp_index, closest_approach_m=p.closest_approach_m,
                           closest_t_s=p.t_s, closest_north_m=p.north_m, closest_east_m=p.east_m, fixes=p.fixes)

    def _log_events(self, events, t_s: float) -> None:
        for ev in events:
            self.log.event(ev.name, t_s=t_s, **ev.fields)
            if ev.name == "failsafe":
                self.state.failsafe_causes.append(ev.fields.get("cause"))

    def _notify(self, now_s: float, lateness_s: float) -> None:
        st = self.state
        if not st.ready:
            sample = self.compass.sample()
            heard_compass = sample.heading_rad is not None or sample.position is not None
            if heard_compass and self.thrusters.answered:
                st.ready = True
                self.notifier.ready(status="both devices answer")
                self.log.event("info", t_s=now_s - self.t0_s, message="ready: SC-30 and Mbed answer")
            elif not st.ready_warned and now_s - self.t0_s > self.cfg.ready_timeout_s:
                st.ready_warned = True
                self.log.event("info", t_s=now_s - self.t0_s, message="devices not answering",
                               sc30_heard=heard_compass, mbed_heard=self.thrusters.answered)
        if lateness_s >= self.cfg.period_s:
            st.late_cycles += 1
        interval_s = (Notifier.watchdog_interval_s() or 0.5) * self.clock.speedup / 2.0
        if watchdog_due(ready=st.ready, lateness_s=lateness_s, period_s=self.cfg.period_s,
                        since_last_s=now_s - st.last_watchdog_s, interval_s=interval_s):
            self.notifier.watchdog()
            st.last_watchdog_s = now_s

    def _save(self, status: str, reason: str = "") -> None:
        launch = self.ap.launch_ne_m
        if status == "running":
            self._saved_running = True
            if self.time_stop_stayed:
                # the run ended at its time limit, the daemon staying up: an arm or a speed saved after it wrote
                # "running" over "aborted" (stop 48's note), as a later signal's stop does not (stop())
                status, reason = "aborted", "max_mission_time"
            elif self.ap.mission_cleared:
                # the run goes on without a mission: still "cleared" (a restart holds, and does not fly it again).
                # An operator's speed given back by the clear, a speed, an arm or the clear's own hold then saved
                # "running" over it, and a restart with resume_after_restart flew the cleared mission (a review)
                status = "cleared"
        self._saved_homeward = self._homeward()
        self._saved_index = self.ap.resume_index
        try:
            self.store.save(Progress(self.mission_path, self.mission_sha256, int(self._saved_index), status,
                                     latched=self.failsafe.latched,
                                     launch_ne_m=None if launch is None else (float(launch[0]), float(launch[1])),
                                     reason=reason, armed=bool(self.ap.armed), homeward=self._saved_homeward,
                                     operator=self.operator_mode, speed_m_s=self.ap.speed_m_s))
        except OSError as exc:
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="state not saved", error=str(exc))

    def _operator_chose(self) -> None:
        """A command changed the helm's mode: the operator's mode (Progress.operator) is it, or none for the mission."""
        mode = self.ap.mode
        # the mission's own way home (an rtl resumed after a pause too) is the mission's: homeward carries it over.
        # Its end (complete) is the mission's only while its route is done: a mission uploaded after the old one
        # ended stopped waits there for resume, the boat stopped; saved with no operator's mode, a crash and a
        # restart with resume_after_restart flew the new mission unasked (a review of 1503182)
        ended = mode is Mode.COMPLETE and self.ap.complete
        chosen = ("" if mode is Mode.AUTO or ended or self._homeward()
                  else "stop" if mode is Mode.COMPLETE else mode.value)
        if chosen not in OPERATOR_MODES or chosen == self.operator_mode:
            return
        self.operator_mode = chosen
        # a held start taken into the mission is this run from now: its progress is saved (a stop kept the
        # interrupted run's, and the next start held the boat for a run that had since gone on)
        if self._saved_running or (chosen == "" and self.hold_zero is not None and not self.failsafe.latched):
            self._save("running")

    def _homeward(self) -> bool:
        """The mission's route is done and its own return to launch under way, or the hold at home it ends in
        (Progress.homeward)."""
        # any rtl once the route is done goes to the same launch point: the mission's own, or resumed after a pause
        # (its cause then "ctl resume": a crash after it flew back out to the last waypoint)
        return bool(self.state.complete and self.mission.rtl and (
            self.ap.mode is Mode.RTL or (self.ap.mode is Mode.HOLD and self.ap.mode_cause == RTL_ARRIVED_CAUSE)))

    def _save_operator_settings(self) -> None:
        """The operator's arm or disarm (and speed), saved now. In a held start the file is still the interrupted
        run's (kept for a resume): only its ``armed`` and ``speed_m_s`` change, or a crash before this run saves
        would bring back the state the file had."""
        if self._saved_running:
            self._save("running")
            return
        saved = self.store.load()
        if saved is None:  # unreadable, kept as it is: the next start holds zero over it, disarmed (app._armed_at_start)
            return
        try:
            self.store.save(replace(saved, armed=bool(self.ap.armed), speed_m_s=self.ap.speed_m_s))
        except OSError as exc:
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="state not saved", error=str(exc))

    def speedup_held(self) -> float:
        """Simulated control time per wall second over the run (deadlines skipped count against it)."""
        wall_s = self.clock.wall_elapsed_s() - self._wall_start_s
        sim_s = self.state.cycles * self.cfg.period_s
        return sim_s / wall_s if wall_s > 0 else math.inf

    # ---- the loop -----------------------------------------------------------------------
    async def run(self) -> str:
        """Cycle until a stop reason appears; returns it (``signal``, ``complete``, ``max_mission_time``)."""
        period_s = self.cfg.period_s
        next_due = self.clock.now_s()
        self._wall_start_s = self.clock.wall_elapsed_s()
        if self.hold_zero is None:
            self._save("running")
        while True:
            await self.clock.sleep_until(next_due)
            now_s = self.clock.now_s()
            lateness_s = now_s - next_due
            if lateness_s > period_s:
                skip = int(lateness_s // period_s)
                self.state.skipped += skip
                next_due += skip * period_s
                lateness_s = now_s - next_due
            if self.state.stop_signal is not None:
                return "signal"
            self.cycle(now_s, lateness_s)
            next_due += period_s
            if self.state.finished and self.state.passes_done:
                if self.stay_when_done is None:
                    return "complete"
                if not self._said_staying:
                    # the process ended at the mission's stop, and a ground station lost the boat: no telemetry, no
                    # rtl, and systemd's Restart=on-failure does not restart an exit 0 (a new-user audit)
                    self._said_staying = True
                    self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="mission complete: staying up",
                                   why=self.stay_when_done)
            else:
                self._said_staying = False
            if self.failsafe.action_of("max_mission_time") == "stop" and not self.time_stopped():
                return "max_mission_time"

    def time_stopped(self) -> bool:
        """max_mission_time's stop is in force: dated from the helm's stop, and when the daemon stays up
        (stay_when_done) saved aborted and said, once; False when the run must end here."""
        change = self._last_mode_change
        if self.time_stop_from is None and change is not None and change[2] == FAILSAFE_CAUSE_PREFIX + TIME_STOP_CAUSE:
            self.time_stop_from = change[:2]
        if self.stay_when_done is None:
            return False
        if not self.time_stop_stayed:  # as at the mission's end: a ground station kept, at zero thrust
            self.time_stop_stayed = True
            self._save("aborted", "max_mission_time")  # a restart does not fly the mission again
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s,
                           message="max_mission_time: stopped, staying up", why=self.stay_when_done)
        return True

    def zero_now(self) -> None:
        """Zero thrust at once, no wait and no log: the first thing on any way out, before anything that
        could fail (the link's last report, the log) stands between the boat and its stop."""
        try:
            self.thrusters.send(ZERO_THRUST)
        except Exception:  # noqa: BLE001 - stop() tries again and says so
            pass

    async def stop(self, reason: str) -> int:
        """Zero thrust, bounded wait for its ack, ``stop`` line, STOPPING=1. Returns the exit code."""
        st = self.state
        self.notifier.stopping(status=f"stopping: {reason}")
        ack = False
        try:
            seq = self.thrusters.send(ZERO_THRUST)
            if seq >= 0:
                ack = bool(await self.thrusters.wait_ack(seq, self.cfg.stop_ack_timeout_s))
        except Exception as exc:  # noqa: BLE001 - stopping must finish
            self.log.event("info", t_s=self.clock.now_s() - self.t0_s, message="zero-thrust on stop failed", error=repr(exc))
        if not st.passes_done:  # the passes still open end with the mission
            st.passes_done = True
            self._log_passes(self.passes.finish(), self.clock.now_s() - self.t0_s)
        st.stop_acknowledged = ack
        status = {"complete": "complete", "signal": "stopped"}.get(reason, "aborted")
        saved_reason = reason if status == "aborted" else ""
        if status == "stopped" and self.time_stop_stayed:  # the run ended at its time limit: a signal later (a
            status, saved_reason = "aborted", "max_mission_time"  # shutdown) does not make a reboot fly it again
        # a held start stopped cleanly, never taken up (this run saved no progress of its own: a resume, a waypoint set
        # or a mission uploaded saves it), keeps the interrupted run's (ctl resume may continue it later), unless that
        # run had latched a failsafe: then resume is refused, and kept it left the boat held at every
        # start until someone with a shell passed --fresh
        if self._saved_running or self.hold_zero is None or status != "stopped" or self.failsafe.latched:
            self._save(status, saved_reason)
        st.stopped_t_s = self.clock.now_s() - self.t0_s
        self.log.event(
            "stop", t_s=st.stopped_t_s, reason=reason, signal=st.stop_signal, ack_received=ack,
            cycles=st.cycles, skipped_cycles=st.skipped, late_cycles=st.late_cycles,
            speedup_held=self.speedup_held(), nmea_dropped=self.compass.lines_dropped,
            ack_missing=int(self.thrusters.ack_missing),
            closest_approach_m=[st.closest_m.get(i) for i in range(len(self.mission.waypoints_ne_m))],
        )
        return 1 if reason == "error" else 0
