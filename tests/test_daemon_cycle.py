"""The control cycle's pure steps with literals, and the whole loop on a clock the test steps.

The loop runs deterministically on :class:`autopilot.clock.SimClock` against test doubles of the
two device interfaces (autopilot.devices.Compass / ThrusterLink): no ports, no sleeping.
"""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from autopilot.clock import SimClock
from autopilot.daemon import cycle as steps
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.failsafe import Decision
from autopilot.daemon.loop import ControlLoop
from autopilot.daemon.missionlog import MissionLog
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import StateStore
from autopilot.devices import ZERO_THRUST, Compass, NavSample, Stamped, ThrusterLink
from autopilot.geo import local_to_latlon
from autopilot.gnc import Autopilot
from autopilot.gnc.navigation import NavMemory, NavRules, assemble
from autopilot.logschema import CYCLE_KEYS, Mode
from autopilot.mission import Mission

ORIGIN = (52.0, 4.4)


def _nav(**kw):
    s = NavSample(heading_rad=Stamped(0.1, 9.95, "HDT", True), position=Stamped(ORIGIN, 9.5, "GGA", True),
                  fix_quality=Stamped(1, 9.5, "GGA", True), sog_m_s=Stamped(1.0, 9.5, "RMC", True),
                  cog_rad=Stamped(0.1, 9.5, "RMC", True))
    nav, _ = assemble(s, 10.0, NavMemory(), NavRules(), origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
    return nav


@pytest.mark.parametrize("fs_mode, allowed, steerable, expect", [
    ("waiting", False, True, (Mode.WAITING, False)),
    ("auto", True, True, (None, True)),  # the helm runs: its own mode is the cycle's
    ("auto", True, False, (Mode.FAILSAFE, False)),  # nothing to steer by
    ("failsafe", False, True, (Mode.FAILSAFE, False)),
])
def test_arbitrate(fs_mode, allowed, steerable, expect):
    d = Decision(mode=fs_mode, thrust_allowed=allowed, active=())
    assert steps.arbitrate(d, steerable=steerable) == expect


def test_helm_nav_names_the_missing_measurement():
    nav = _nav()
    ok = Decision(mode="auto", thrust_allowed=True, active=())
    assert steps.helm_nav(nav, ok)[0] is not None
    stale = Decision(mode="failsafe", thrust_allowed=False, active=("position_stale", "mbed_ack_missing"))
    assert steps.helm_nav(nav, stale) == (None, "position stale")
    latched = Decision(mode="auto", thrust_allowed=True, active=("geofence",))  # not a position fault
    assert steps.helm_nav(nav, latched)[0] is not None


def test_step_dt():
    assert steps.step_dt_s(5.0, None, 0.1) == 0.1
    assert steps.step_dt_s(5.0, 4.9, 0.1) == pytest.approx(0.1)
    assert steps.step_dt_s(50.0, 4.9, 0.1) == steps.MAX_STEP_DT_S


def test_command_and_mode_after_the_gnc():
    ap = Autopilot(DaemonConfig().gnc, [(0.5, 0.0)])
    nav = _nav()
    out = ap.step(steps.nav_input(nav), 0.1)  # within the capture radius: complete at once, final action stop
    assert out.complete and out.finished and out.thrust_off
    assert steps.command(out) is ZERO_THRUST and steps.command(None) is ZERO_THRUST
    assert out.mode is Mode.COMPLETE
    far = Autopilot(DaemonConfig().gnc, [(30.0, 0.0)]).step(steps.nav_input(nav), 0.1)
    cmd = steps.command(far)
    assert (cmd.duty_port_pct, cmd.duty_stbd_pct) == (far.pwm_port_pct, far.pwm_stbd_pct) and not cmd.is_zero


def test_cycle_record_has_exactly_the_schema_keys():
    nav = _nav()
    out = Autopilot(DaemonConfig().gnc, [(30.0, 0.0)]).step(steps.nav_input(nav), 0.1)
    for o, cmd in ((out, steps.command(out)), (None, ZERO_THRUST)):
        rec = steps.cycle_record(cycle=3, t_s=1.0, mode=Mode.AUTO, nav=nav, out=o, cmd=cmd, wp_index=0, steering=o is not None,
                                 lateness_s=0.001, skipped=0, heading_latency_s=0.05, seq=7, ack_missing=0, nmea_dropped=0,
                                 active_faults=())
        assert tuple(rec) == CYCLE_KEYS
    assert 0 <= rec["heading_deg"] < 360 and rec["est_north_m"] is None and rec["psi_d_deg"] is None


def test_observe_carries_what_the_failsafe_judges():
    nav = _nav()
    obs = steps.observe(nav, mission_time_s=12.0, compass_connected=True, thrusters_connected=False,
                        acks_missing_in_a_row=3, compass_garbage_s=None, thruster_garbage_s=9.0)
    assert obs.t_s == 10.0 and obs.heading_age_s == pytest.approx(0.05) and obs.position_age_s == pytest.approx(0.5)
    assert (obs.mbed_connected, obs.ack_consecutive_missing, obs.last_mbed_garbage_t_s) == (False, 3, 9.0)


# ---------------------------------------------------------------------------------------------- the loop


class FakeCompass:
    """A compass that reports a boat steaming north at 1 m/s from the origin, until told to go quiet."""

    def __init__(self, clock):
        self.clock, self.quiet_from_s = clock, math.inf
        self.connected, self.last_garbage_s, self.lines_dropped = True, None, 0

    def sample(self) -> NavSample:
        t = min(self.clock.now_s(), self.quiet_from_s)
        fix_t = math.floor(t)
        lat, lon = local_to_latlon(fix_t * 1.0, 0.0, *ORIGIN)
        return NavSample(heading_rad=Stamped(0.0, math.floor(t * 10) / 10, "HDT", True),
                         position=Stamped((lat, lon), fix_t, "GGA", True), fix_quality=Stamped(1, fix_t, "GGA", True),
                         sog_m_s=Stamped(1.0, fix_t, "RMC", True), cog_rad=Stamped(0.0, fix_t, "RMC", True))

    async def run(self):
        pass

    async def close(self):
        pass


class FakeThrusters:
    def __init__(self):
        self.connected, self.last_garbage_s, self.consecutive_missing, self.ack_missing = True, None, 0, 0
        self.answered, self.commands, self.battery_v, self.disobeying = True, [], 12.6, False
        self.battery_load_pct = (0.0, 0.0)  # at rest when the voltage was read

    def send(self, command):
        self.commands.append(command)
        return len(self.commands) - 1

    async def wait_ack(self, seq, timeout_s):
        return True

    async def run(self):
        pass

    async def close(self):
        pass


def _run_loop(tmp_path, quiet_from_s: float, until_s: float, waypoints=((200.0, 0.0),), listener=None, cfg=None,
              before_stop=None):
    cfg = cfg or DaemonConfig()
    mission = Mission("north", np.array(waypoints, dtype=float), (None,) * len(waypoints), None, *ORIGIN)

    async def main():
        clock = SimClock()
        compass, thrusters = FakeCompass(clock), FakeThrusters()
        assert isinstance(compass, Compass) and isinstance(thrusters, ThrusterLink)  # the interfaces, typed
        compass.quiet_from_s = quiet_from_s
        log = MissionLog(tmp_path / "log.jsonl", console=None)
        if listener is not None:
            log.listeners.append(listener)
        loop = ControlLoop(cfg, clock=clock, autopilot=Autopilot(cfg.gnc, mission.waypoints_ne_m), mission=mission,
                           mission_path="m.yaml", mission_sha256="x", compass=compass, thrusters=thrusters, log=log,
                           notifier=Notifier(None), store=StateStore(tmp_path / "state"))
        task = asyncio.create_task(loop.run())
        t = 0.0
        while t < until_s:  # the test is the clock: every deadline, by hand
            t = round(t + 0.05, 6)
            clock.advance_to(t)
            for _ in range(3):
                await asyncio.sleep(0)
        if before_stop is not None:
            before_stop(loop)
        loop.request_stop("SIGTERM")
        clock.advance_to(until_s + 1.0)
        assert await task == "signal"
        log.close()
        return thrusters.commands, loop.state

    return asyncio.run(main())


def test_the_loop_on_a_stepped_clock_is_deterministic_and_stops_on_a_stale_heading(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    cmds, st = _run_loop(tmp_path / "a", quiet_from_s=6.0, until_s=10.0)
    cmds2, _ = _run_loop(tmp_path / "b", quiet_from_s=6.0, until_s=10.0)
    assert cmds == cmds2  # the same commands, bit for bit
    assert len(cmds) == 100  # one per 0.1 s deadline, 0 to 9.9 s
    driving = [k for k, c in enumerate(cmds) if not c.is_zero]
    # control starts once the first fix has been confirmed by the fixes after it for failsafe.position_confirm_s
    # (5 s; start_valid_s, 1 s, of valid data is met before)
    assert driving[0] == 50
    # the last heading is from 6.0 s: stale once older than heading_stale_s (1 s), so zero thrust from
    # the cycle at 7.0 s (the deadline sum lands a hair past 7.0) or 7.1 s on, and it stays zero
    assert driving[-1] in (69, 70) and all(c.is_zero for c in cmds[71:])
    assert driving == list(range(50, driving[-1] + 1))
    assert st.failsafe_causes == ["heading_stale"] and st.cycles == 100


def test_a_waypoint_is_saved_as_reached_before_the_log_says_so(tmp_path):
    """A kill just after the log's waypoint_reached line must not restart at that waypoint: the progress file
    already steers to the next (the log is what an operator trusts; it may not run ahead of the state)."""
    seen = []

    def listener(name, t_s, fields):
        if name == "waypoint_reached":
            seen.append((fields["wp_index"], StateStore(tmp_path / "state").load()))

    _run_loop(tmp_path, quiet_from_s=math.inf, until_s=12.0, waypoints=((6.0, 0.0), (200.0, 0.0)), listener=listener)
    assert [i for i, _ in seen] == [0]
    assert seen[0][1] is not None and seen[0][1].wp_index == 1 and seen[0][1].status == "running"


def test_the_failsafe_is_told_the_heading_error_only_when_the_helm_steered_by_it():
    """steps.steered_error_rad: a stopped helm (thrust off: complete, stop, disarmed) keeps a heading error it
    does not steer by, and the operator's sticks steer by eye; neither is evidence of a heading that does not answer."""
    import dataclasses

    ap = Autopilot(DaemonConfig().gnc, [(0.0, 50.0)])  # the waypoint due east, the boat heading north
    out = ap.step(steps.nav_input(_nav()), 0.1)
    assert abs(out.heading_error_rad) > math.radians(60.0) and not out.thrust_off
    assert steps.steered_error_rad(out) == out.heading_error_rad
    assert steps.steered_error_rad(None) is None
    assert steps.steered_error_rad(dataclasses.replace(out, thrust_off=True)) is None
    assert steps.steered_error_rad(dataclasses.replace(out, mode=Mode.MANUAL)) is None


def test_the_loop_gives_the_helm_its_failsafe_s_position_limits(tmp_path):
    """The holds the helm places itself (off a waypoint a moored vessel occupies) are kept inside the failsafe's
    latched limits: the loop hands the helm its failsafe's check, the geofence and max_distance_m alike."""
    cfg = DaemonConfig()
    mission = Mission("north", np.array([(20.0, 0.0)]), (None,), None, *ORIGIN)
    ap = Autopilot(cfg.gnc, mission.waypoints_ne_m)
    fence = ((-10.0, -10.0), (40.0, -10.0), (40.0, 10.0), (-10.0, 10.0))
    ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml", mission_sha256="x",
                compass=FakeCompass(SimClock()), thrusters=FakeThrusters(), log=MissionLog(tmp_path / "l.jsonl", console=None),
                notifier=Notifier(None), store=StateStore(tmp_path / "state"), fence_ne_m=fence)
    assert ap.within_limits(20.0, 5.0) and ap.within_limits(-10.0, 10.0)  # inside, and on its edge
    assert not ap.within_limits(20.0, 12.0)  # beyond the fence
    far = cfg.failsafe.max_distance_m + 1.0
    ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml", mission_sha256="x",
                compass=FakeCompass(SimClock()), thrusters=FakeThrusters(), log=MissionLog(tmp_path / "m.jsonl", console=None),
                notifier=Notifier(None), store=StateStore(tmp_path / "state2"))
    assert ap.within_limits(20.0, 12.0) and not ap.within_limits(far, 0.0)  # no fence: the distance limit alone


def test_a_crash_in_the_final_hold_is_an_interrupted_run_not_a_completed_one(tmp_path):
    """Found by a new-user audit: the progress said "complete" from the moment the last waypoint was reached, and a
    kill -9 in the final hold (or on the way home of an rtl) came back as "no run interrupted" and flew the whole
    mission again from its first waypoint, unasked. Until the run ends it is saved running: a restart holds zero
    thrust (or, with resume_after_restart, goes back to the last waypoint and its hold)."""
    import dataclasses

    base = DaemonConfig()
    gnc = dataclasses.replace(base.gnc, guidance=dataclasses.replace(base.gnc.guidance, final_action="hold"))
    seen = {}

    def in_the_hold(loop):
        seen["mode"] = loop.ap.mode
        seen["complete"] = loop.state.complete
        seen["saved"] = loop.store.load()
        seen["interrupted"] = loop.store.interrupted(loop.mission_sha256, len(loop.mission.waypoints_ne_m))

    _run_loop(tmp_path, math.inf, 25.0, waypoints=((6.0, 0.0), (12.0, 0.0)),
              cfg=dataclasses.replace(base, gnc=gnc), before_stop=in_the_hold)
    assert seen["mode"] is Mode.HOLD and seen["complete"]  # the route done, holding at its end
    assert seen["saved"].status == "running" and seen["saved"].wp_index == 1
    assert seen["interrupted"] == (1, None)  # a crash now is an interrupted run (held at zero unless resumed)


def test_a_held_start_saves_a_stop_of_the_operators_until_they_say_otherwise(tmp_path):
    """Found reviewing 847bd84: a start held at zero thrust was no stop of the operator's, so a jump or an upload
    saved while held (status running, no operator's mode) and a crash after it flew the mission under thrust
    with resume_after_restart."""
    cfg = DaemonConfig()
    mission = Mission("north", np.array([(20.0, 0.0), (40.0, 0.0)]), (None, None), None, *ORIGIN)
    store = StateStore(tmp_path / "state")
    loop = ControlLoop(cfg, clock=SimClock(), autopilot=Autopilot(cfg.gnc, mission.waypoints_ne_m), mission=mission,
                       mission_path="m.yaml", mission_sha256="x", compass=FakeCompass(SimClock()),
                       thrusters=FakeThrusters(), log=MissionLog(tmp_path / "l.jsonl", console=None),
                       notifier=Notifier(None), store=store, hold_zero="an interrupted mission")
    loop.save_progress("running")  # what a jump (MISSION_SET_CURRENT) or an upload does while held
    saved = store.load()
    assert saved.status == "running" and saved.operator == "stop"
    assert store.interrupted("x", 2) == (0, "the operator's stop was in force when a run of this mission was "
                                            "interrupted (the boat had been taken off the mission): not flown again "
                                            "unasked")


def test_the_missions_own_way_home_paused_and_resumed_stays_the_missions(tmp_path):
    """Found reviewing 847bd84: pausing the mission's own rtl and resuming it saved the operator's mode "rtl" (a
    restart then held the boat adrift on its way home), and homeward went false (the cause was "ctl resume"): a
    restart with resume_after_restart flew back out to the last waypoint."""
    from autopilot.gnc.autopilot import NavInput

    cfg = DaemonConfig()
    mission = Mission("out-and-home", np.array([(10.0, 0.0)]), (None,), None, *ORIGIN, rtl=True)
    ap = Autopilot(cfg.gnc, mission.waypoints_ne_m, rtl=True)
    loop = ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml",
                       mission_sha256="x", compass=FakeCompass(SimClock()), thrusters=FakeThrusters(),
                       log=MissionLog(tmp_path / "l.jsonl", console=None), notifier=Notifier(None),
                       store=StateStore(tmp_path / "state"))
    home = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    there = NavInput(north_m=10.0, east_m=0.0, psi_rad=math.pi, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    ap.step(home, 0.1)  # the launch point
    for _ in range(3):
        out = ap.step(there, 0.1)
    assert ap.mode is Mode.RTL and out.complete
    loop.state.completed_t_s = 1.0  # the loop notes the route done when the helm says so
    assert loop._homeward()
    assert ap.request("pause", there, cause="ctl pause")[0]
    loop._operator_chose()
    assert loop.operator_mode == "paused" and not loop._homeward()
    assert ap.request("resume", there, cause="ctl resume") == (True, "rtl")
    loop._operator_chose()
    assert loop.operator_mode == "" and loop._homeward()


def test_a_mission_uploaded_on_the_missions_own_way_home_is_not_flown_by_a_restart(tmp_path):
    """Found reviewing c235c48: a mission uploaded while the boat went home on the old mission's own rtl was saved
    "running" with no operator's mode and homeward false (the new mission's route is not done), so a crash and a
    restart with resume_after_restart flew the new mission from its first waypoint, where the boat had been going
    home. The return is the operator's now: a restart holds zero thrust until told."""
    from autopilot.gnc.autopilot import NavInput

    cfg = DaemonConfig()
    mission = Mission("out-and-home", np.array([(10.0, 0.0)]), (None,), None, *ORIGIN, rtl=True)
    ap = Autopilot(cfg.gnc, mission.waypoints_ne_m, rtl=True)
    store = StateStore(tmp_path / "state")
    loop = ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml",
                       mission_sha256="x", compass=FakeCompass(SimClock()), thrusters=FakeThrusters(),
                       log=MissionLog(tmp_path / "l.jsonl", console=None), notifier=Notifier(None), store=store)
    home = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    there = NavInput(north_m=10.0, east_m=0.0, psi_rad=math.pi, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    ap.step(home, 0.1)
    for _ in range(3):
        ap.step(there, 0.1)
    loop.state.completed_t_s = 1.0
    assert ap.mode is Mode.RTL and loop._homeward()
    new = Mission("square", np.array([(30.0, 0.0), (30.0, 30.0)]), (None, None), None, *ORIGIN)
    loop.replace_mission(new, source="mavlink", cause="mavlink mission")
    assert ap.mode is Mode.RTL  # still going home: the new mission waits for resume
    saved = store.load()
    assert saved.status == "running" and saved.operator == "rtl" and not saved.homeward
    wp, why = store.interrupted(saved.mission_sha256, 2)
    assert wp == 0 and "operator's rtl was in force" in why, why


def test_a_mission_uploaded_after_the_old_one_ended_stopped_is_not_flown_by_a_restart(tmp_path):
    """Found reviewing 1503182: a mission uploaded after the old one ended with its stop (mode complete, zero thrust)
    waits there for resume, but was saved "running" with no operator's mode (complete counted as the mission's own
    end, though the new mission's route is not flown): a crash and a restart with resume_after_restart flew the new
    mission from its first waypoint, unasked. The stop is the operator's now: a restart holds zero thrust."""
    from autopilot.gnc.autopilot import NavInput

    cfg = DaemonConfig()
    mission = Mission("out", np.array([(10.0, 0.0)]), (None,), None, *ORIGIN)
    ap = Autopilot(cfg.gnc, mission.waypoints_ne_m)
    store = StateStore(tmp_path / "state")
    loop = ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml",
                       mission_sha256="x", compass=FakeCompass(SimClock()), thrusters=FakeThrusters(),
                       log=MissionLog(tmp_path / "l.jsonl", console=None), notifier=Notifier(None), store=store)
    home = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    there = NavInput(north_m=10.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
    ap.step(home, 0.1)
    for _ in range(3):
        ap.step(there, 0.1)
    loop.state.completed_t_s = 1.0
    assert ap.mode is Mode.COMPLETE
    loop._operator_chose()  # the old mission's own end: not the operator's
    assert loop.operator_mode == ""
    new = Mission("square", np.array([(30.0, 0.0), (30.0, 30.0)]), (None, None), None, *ORIGIN)
    loop.replace_mission(new, source="mavlink", cause="mavlink mission")
    assert ap.mode is Mode.COMPLETE and ap.step(there, 0.1).thrust_port_n == 0.0  # stopped: waits for resume
    saved = store.load()
    assert saved.status == "running" and saved.operator == "stop"
    wp, why = store.interrupted(saved.mission_sha256, 2)
    assert wp == 0 and "operator's stop was in force" in why, why
    assert ap.request("resume", there, cause="ctl resume") == (True, "auto")
    loop._operator_chose()  # resumed: the new mission's own again
    assert loop.operator_mode == "" and store.load().operator == ""
