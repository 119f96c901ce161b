"""One mission flown on simulated time: the daemon's control cycle over a simulated boat.

``autopilot evaluate`` and the campaigns (:mod:`autopilot.campaign`) fly every run
through the classes here, so both see the boat as the daemon does:

    SensorModel.observe --NavSample--> ControlCycle.step --ThrustCommand--> the plant (the caller's)
                                             |
                                             +--> Scorecard.update (evaluate's scorecard)

- :class:`ControlCycle` is :meth:`autopilot.daemon.loop.ControlLoop.cycle` without devices,
  log or clock: the navigation assembly, the failsafe's decision (``observe`` ->
  :meth:`Failsafe.update`), its latched actions handed to the helm, ``arbitrate``, one
  helm step (:class:`autopilot.gnc.Autopilot`: modes, guidance, PID, allocation) and
  ``command``, all from :mod:`autopilot.daemon.cycle`. The events the daemon would log come
  back as ``(name, fields)``. Without a failsafe (``autopilot evaluate``) the helm drives
  whenever there is a position and a heading.
- :class:`Scorecard` is evaluate's per-run score (completion, closest approach over each
  pass, cross-track error, energy, saturation, circling, the hold), fed once per cycle.
- :class:`Flight` puts the two together with the sensor model for one run; the caller
  moves the boat: one run at a time (``autopilot.evaluate.run_closed_loop``) or many in
  lockstep as arrays (:mod:`autopilot.campaign.lockstep`).

Pure apart from the sensor model's random generator, which the caller seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from autopilot.daemon import cycle as steps
from autopilot.daemon.failsafe import Failsafe, resting_voltage_v
from autopilot.devices import ZERO_THRUST, NavSample, ThrustCommand
from autopilot.geo import wrap_pi
from autopilot.gnc.navigation import Navigation, NavMemory, NavRules, assemble
from autopilot.gnc.passes import PassTracker
from autopilot.logschema import Mode

__all__ = ["LinkState", "LINK_OK", "Cycle", "ControlCycle", "Scorecard", "Flight", "TRACE_KEYS", "own_ship"]


@dataclass(frozen=True)
class LinkState:
    """What the simulated devices report besides navigation (the daemon reads it from its drivers)."""

    compass_connected: bool = True
    thrusters_connected: bool = True
    acks_missing_in_a_row: int = 0
    compass_garbage_s: float | None = None  # clock time of the last garbage burst on the compass line
    thruster_garbage_s: float | None = None
    battery_v: float | None = None  # under the last command's load; None: not reported


LINK_OK = LinkState()


@dataclass(slots=True)
class Cycle:
    """One control cycle: the mode, the navigation, the helm's output (None when it did not run), the command."""

    mode: Mode
    nav: Navigation
    out: object  # ControlOutput | None
    cmd: ThrustCommand
    active_faults: tuple[str, ...] = ()
    battery_v: float | None = None  # as the thruster link reported it this cycle
    battery_rest_v: float | None = None
    events: list = field(default_factory=list)  # (name, fields) the daemon would log this cycle, in order


class ControlCycle:
    """The daemon's control cycle on simulated time (see the module docstring). ``step`` once per period."""

    def __init__(self, autopilot, *, period_s: float, origin_lat_deg: float, origin_lon_deg: float,
                 rules: NavRules = NavRules(), failsafe: Failsafe | None = None) -> None:
        self.ap = autopilot
        self.period_s = float(period_s)
        self.origin = (float(origin_lat_deg), float(origin_lon_deg))
        self.rules = rules
        self.failsafe = failsafe
        self.memory = NavMemory()
        self.driving = False  # the helm drove in the last cycle
        self.last_step_s: float | None = None
        self.completed_t_s: float | None = None
        self.last_cmd: ThrustCommand = ZERO_THRUST
        self.steered_error_rad: float | None = None  # the heading error the helm steered by last cycle
        self.failsafe_causes: list[str] = []  # every failsafe taken, in order (transient and latched)
        self.failsafe_times_s: list[float] = []  # when each was taken (mission time)
        self.control_started_s: float | None = None  # the first cycle the helm drove (before it: waiting)

    @property
    def latched_action(self) -> str | None:
        """The first latched fault's cause once it has taken the boat (the mission cannot complete then)."""
        fs = self.failsafe
        if fs is None:
            return None
        for cause in fs.latched:
            if fs.action_of(cause) is not None:
                return cause
        return None

    def step(self, sample: NavSample, now_s: float, *, link: LinkState = LINK_OK, targets=()) -> Cycle:
        """One cycle at ``now_s`` (mission time; simulated time starts at 0) with the compass's latest sample and
        the other vessels the boat sees (``autopilot.gnc.encounter.Target``, as the daemon's AIS source gives)."""
        ap, events = self.ap, []
        nav, self.memory = assemble(sample, now_s, self.memory, self.rules, origin_lat_deg=self.origin[0],
                                    origin_lon_deg=self.origin[1])
        if nav.jump is not None:
            events.append(("position_jump", nav.jump.log_fields()))
        active: tuple[str, ...] = ()
        rest_v = None
        if self.failsafe is None:
            mode, drive = None, nav.steerable
        else:
            fs_cfg = self.failsafe.cfg
            rest_v = resting_voltage_v(link.battery_v, self.last_cmd.duty_port_pct, self.last_cmd.duty_stbd_pct,
                                       fs_cfg.battery_sag_v)
            decision = self.failsafe.update(steps.observe(
                nav, mission_time_s=None if ap.finished else now_s, compass_connected=link.compass_connected,
                thrusters_connected=link.thrusters_connected, acks_missing_in_a_row=link.acks_missing_in_a_row,
                compass_garbage_s=link.compass_garbage_s, thruster_garbage_s=link.thruster_garbage_s,
                battery_v=rest_v, steered_heading_error_rad=self.steered_error_rad))
            for ev in decision.events:
                events.append((ev.name, ev.fields))
                if ev.name == "failsafe":
                    self.failsafe_causes.append(ev.fields.get("cause"))
                    self.failsafe_times_s.append(now_s)
            if decision.requests:  # a latched fault's action (ControlLoop._failsafe_action)
                helm_nav, unavailable = steps.helm_nav(nav, decision)
            for req in decision.requests:
                action, fallback = steps.answer_failsafe(ap, req, helm_nav, unavailable)
                events.append(("failsafe", {"cause": req.cause, "action": action, "configured": req.configured,
                                            "fallback": fallback}))
                self.failsafe_causes.append(req.cause)
                self.failsafe_times_s.append(now_s)
            mode, drive = steps.arbitrate(decision, steerable=nav.steerable, manual=ap.mode is Mode.MANUAL)
            active = decision.active
        self.driving = self.driving and drive
        out = self._steer(nav, now_s, events, targets) if drive else None
        if out is not None:
            mode = out.mode
            if self.control_started_s is None:
                self.control_started_s = now_s
        self.steered_error_rad = steps.steered_error_rad(out)
        events.extend(ap.pop_events())
        cmd = steps.command(out)
        self.last_cmd = cmd
        return Cycle(mode=mode, nav=nav, out=out, cmd=cmd, active_faults=active, battery_v=link.battery_v,
                     battery_rest_v=rest_v, events=events)

    def _steer(self, nav: Navigation, now_s: float, events: list, targets):
        """One helm step (ControlLoop._steer): integrators reset when control (re)starts."""
        ap = self.ap
        if not self.driving:
            ap.restart_control()
            self.last_step_s = None
        # steps.step_dt_s on an exact clock: the cycles of simulated time are one period apart, and a restart
        # takes one period too (the difference of two accumulated times would only add rounding)
        dt_s = self.period_s
        self.last_step_s, self.driving = now_s, True
        out = ap.step(steps.nav_input(nav) if nav.steerable else None, dt_s, targets=targets, t_s=now_s)
        if out.reached_index is not None:
            events.append(("waypoint_reached", {"wp_index": out.reached_index, "north_m": nav.est_north_m,
                                                "east_m": nav.est_east_m, "distance_m": out.reached_distance_m,
                                                "how": out.reached_how}))
        if out.complete and self.completed_t_s is None:
            self.completed_t_s = now_s
            events.append(("mission_complete", {"wp_count": len(ap.guidance.waypoints), "rtl": bool(ap.auto.rtl)}))
        return out


TRACE_KEYS = ("t_s", "north_m", "east_m", "psi_rad", "psi_d_rad", "tcpa_nd", "dcpa_nd", "cdh", "thrust_port_n",
              "thrust_stbd_n", "wp_index", "heading_error_rad", "xte_m", "speed_m_s", "speed_cmd_m_s", "tau_com_n",
              "tau_com_trim_n", "pid_i_n", "mode", "hold_error_m", "avoid_share_rad", "situations", "acting")


class Scorecard:
    """``autopilot evaluate``'s score of one run, fed once per control cycle (see :mod:`autopilot.evaluate`)."""

    def __init__(self, waypoints_ne_m, *, final_pass_s: float, record: bool = False) -> None:
        from autopilot.evaluate import CirclingMonitor

        self.wps = [(float(n), float(e)) for n, e in waypoints_ne_m]
        self.final_pass_s = final_pass_s
        self.passes = PassTracker(self.wps)
        self.closest_by_wp: dict[int, float] = {}
        self.ended_passes: list = []  # every Pass closed, in order (the daemon logs each as waypoint_pass)
        self.passes_open = True
        self.xte_sq = self.xte_max = self.energy_ns = 0.0
        self.n_cycles = self.n_sat = self.n_track = 0  # n_track: cycles steering to a waypoint (the route not yet complete)
        self.circling = CirclingMonitor()
        self.completed_at: float | None = None
        # the helm's last word on whether the mission ended with stop, kept through cycles it does not run (the
        # daemon's ControlLoop.state.finished): a failsafe in force after completion (the Mbed lost in the final
        # pass) kept the run open to the time limit, where the daemon ends it complete
        self.finished = False
        self.hold_d: list[float] = []  # per cycle station keeping held: true distance, heading error, |T|+|T|
        self.hold_h: list[float] = []
        self.hold_t: list[float] = []
        self.record = record
        self.trace: dict[str, list] = {k: [] for k in TRACE_KEYS} if record else {}

    def _ended(self, passes) -> None:
        for p in passes:
            self.closest_by_wp[p.wp_index] = p.closest_approach_m
            self.ended_passes.append(p)

    def update(self, t_s: float, x, nav: Navigation, out, wp_index: int) -> bool:
        """One cycle: the true state ``x``, the navigation, the helm's output (None when it did not run) and the
        waypoint steered to. Returns True when the run is over (the mission ended with stop, last pass closed)."""
        n_m, e_m, psi = float(x[0]), float(x[1]), float(x[2])
        ended = self.passes.on_target(wp_index) if out is not None and out.reached_index is not None else []
        if nav.new_fix and self.passes_open:
            ended += self.passes.on_fix(nav.fix_t_s, nav.north_m, nav.east_m, wp_index)
        self._ended(ended)
        self.n_cycles += 1
        if out is not None:
            if out.saturation:
                self.n_sat += 1
            if out.holding:
                self.hold_d.append(math.hypot(n_m - out.hold_target_ne_m[0], e_m - out.hold_target_ne_m[1]))
                self.hold_h.append(wrap_pi(psi - out.hold_heading_rad))
                self.hold_t.append(abs(out.thrust_port_n) + abs(out.thrust_stbd_n))
            if not out.complete and out.xte_m is not None:
                self.n_track += 1
                self.xte_sq += out.xte_m * out.xte_m
                self.xte_max = max(self.xte_max, abs(out.xte_m))
                self.circling.update(out.wp_index, psi)
            if self.record:
                self._record(t_s, n_m, e_m, psi, float(x[3]), float(x[4]), out)
            if out.complete and self.completed_at is None:
                self.completed_at = t_s
        if self.passes_open and self.completed_at is not None and t_s - self.completed_at >= self.final_pass_s - 1e-9:
            self.passes_open = False  # the last pass has ended (autopilot.gnc.passes)
            self._ended(self.passes.finish())
        if out is not None:
            self.finished = out.finished
        return not self.passes_open and self.finished

    def _record(self, t, n_m, e_m, psi, u, v, out) -> None:
        for k, val in (("t_s", t), ("north_m", n_m), ("east_m", e_m), ("psi_rad", psi), ("psi_d_rad", out.psi_d_rad),
                       ("tcpa_nd", out.tcpa_nd), ("dcpa_nd", out.dcpa_nd), ("cdh", out.cdh),
                       ("thrust_port_n", out.thrust_port_n), ("thrust_stbd_n", out.thrust_stbd_n),
                       ("wp_index", out.wp_index), ("heading_error_rad", out.heading_error_rad),
                       ("xte_m", math.nan if out.xte_m is None else out.xte_m), ("speed_m_s", math.hypot(u, v)),
                       ("speed_cmd_m_s", out.speed_cmd_m_s), ("tau_com_n", out.tau_com_n),
                       ("tau_com_trim_n", out.tau_com_trim_n), ("pid_i_n", out.pid_i_n), ("mode", out.mode.value),
                       ("hold_error_m", out.hold_error_m)):
            self.trace[k].append(val)
        a = out.avoidance  # per target: the situation and whether the boat gives way to it (traffic.score)
        self.trace["avoid_share_rad"].append(0.0 if a is None else a.psi_d_share_rad)
        self.trace["situations"].append({} if a is None else {t.target_id: t.situation.value for t in a.targets})
        self.trace["acting"].append({} if a is None else {t.target_id: bool(t.acting) for t in a.targets})

    def add_energy(self, thrust_port_n: float, thrust_stbd_n: float, dt_s: float, substeps: int) -> None:
        """|T_port| + |T_stbd| integrated over ``substeps`` simulator steps of ``dt_s`` with this command held."""
        e = (abs(thrust_port_n) + abs(thrust_stbd_n)) * dt_s
        for _ in range(substeps):
            self.energy_ns += e

    def finish(self) -> None:
        """The run ended: the passes still open end with it."""
        if self.passes_open:
            self.passes_open = False
            self._ended(self.passes.finish())

    def result(self, *, t_end_s: float, dt_ctrl_s: float, mission: str, guidance: str, condition: str):
        """The :class:`autopilot.evaluate.RunResult` (call :meth:`finish` first)."""
        from autopilot.evaluate import RunResult, hold_score

        closest = [self.closest_by_wp.get(i, math.inf) for i in range(len(self.wps))]
        return RunResult(
            mission=mission,
            guidance=guidance,
            condition=condition,
            completed=self.completed_at is not None,
            closest_approach_m=closest,
            xte_rms_m=math.sqrt(self.xte_sq / max(self.n_track, 1)),
            xte_max_m=self.xte_max,
            time_s=self.completed_at if self.completed_at is not None else t_end_s,
            energy_ns=self.energy_ns,
            saturation_pct=100.0 * self.n_sat / max(self.n_cycles, 1),
            circled=self.circling.circled,
            hold=hold_score(self.hold_d, self.hold_h, self.hold_t, dt_ctrl_s),
            trace={**self.trace, "waypoints": self.wps} if self.record else {},
        )


class Flight:
    """One mission on simulated time: the sensor model, the control cycle and the scorecard.

    The caller owns the boat's state and time: each control period it calls :meth:`control`
    with the true state, gets the thrusts to hold (None when the run is over) and integrates
    the plant ``substeps`` steps of ``dt_s``. ``link(t_s) -> LinkState`` and
    ``sample_filter(t_s, sample) -> sample`` let a campaign inject faults and dropouts
    between the sensors and the daemon's steps. ``traffic`` (an :class:`autopilot.traffic.feed.TrafficFeed`)
    moves other vessels that watch the boat's true state and are seen as the daemon sees them (through AIS).
    """

    def __init__(self, autopilot, sensors, *, dt_s: float, rate_hz: float, t_max_s: float, final_pass_s: float,
                 origin_lat_deg: float, origin_lon_deg: float, rules: NavRules = NavRules(),
                 failsafe: Failsafe | None = None, record: bool = False, link=None, sample_filter=None,
                 end_on_latched: bool = False, traffic=None) -> None:
        self.ap = autopilot
        self.sensors = sensors
        self.dt_s = float(dt_s)
        self.substeps = max(1, round(1.0 / (rate_hz * dt_s)))
        self.dt_ctrl_s = self.substeps * dt_s
        self.t_max_s = float(t_max_s)
        self.cycle = ControlCycle(autopilot, period_s=self.dt_ctrl_s, origin_lat_deg=origin_lat_deg,
                                  origin_lon_deg=origin_lon_deg, rules=rules, failsafe=failsafe)
        self.score = Scorecard(autopilot.guidance.waypoints, final_pass_s=final_pass_s, record=record)
        self.link = link
        self.sample_filter = sample_filter
        self.end_on_latched = end_on_latched
        self.traffic = traffic
        self.end_reason: str | None = None  # "finished", "time", "failsafe <cause>"
        self.last: Cycle | None = None
        self.cycles = 0

    def control(self, t_s: float, x):
        """One control cycle at ``t_s`` with the boat in ``x``: the thrusts (port, starboard) to hold for the next
        period, or None when the run is over."""
        if t_s >= self.t_max_s:
            self.end_reason = "time"
            return None
        sample = self.sensors.observe(t_s, x)
        if self.sample_filter is not None:
            sample = self.sample_filter(t_s, sample)
        link = LINK_OK if self.link is None else self.link(t_s)
        targets = () if self.traffic is None else self.traffic.step(t_s, own_ship(x))
        c = self.cycle.step(sample, t_s, link=link, targets=targets)
        self.last = c
        self.cycles += 1
        if self.score.update(t_s, x, c.nav, c.out, self.ap.wp_index):
            self.end_reason = "finished"  # the mission ended with stop: thrust has been zero since
            return None
        if (self.end_on_latched and c.active_faults and (self.score.completed_at is None or not self.score.passes_open)
                and (cause := self.cycle.latched_action) is not None):
            # a latched fault took the boat: the mission cannot complete (or it has, and its last pass has ended)
            self.end_reason = f"failsafe {cause}"
            return None
        tp, ts = c.cmd.thrust_port_n, c.cmd.thrust_stbd_n
        self.score.add_energy(tp, ts, self.dt_s, self.substeps)
        return tp, ts

    def result(self, t_end_s: float, *, mission: str = "", condition: str = ""):
        """The run's :class:`autopilot.evaluate.RunResult`."""
        self.score.finish()
        return self.score.result(t_end_s=t_end_s, dt_ctrl_s=self.dt_ctrl_s, mission=mission,
                                 guidance=self.ap.config.guidance.law, condition=condition)


def own_ship(x):
    """The boat's true state ``x`` (north, east, psi, u, v, r) as the simulated traffic's reactive targets watch it."""
    from autopilot.gnc.encounter import OwnShip

    n, e, psi, u, v = (float(c) for c in x[:5])
    return OwnShip(n, e, psi + math.atan2(v, u) if u or v else psi, math.hypot(u, v), psi)
