"""Position jumps (autopilot.gnc.navigation.gate_fix): a GNSS glitch is refused, a real move re-anchors.

Pure: 1 Hz fixes as the SC-30 driver stamps them, assembled on the 10 Hz cycle; the failsafe judges the
position the assembly gives. Before: one fix 600 m away latched max_distance and ended the mission.
"""

import math

import numpy as np
import pytest

from autopilot.daemon.config import FailsafeConfig
from autopilot.daemon.cycle import observe
from autopilot.daemon.failsafe import Failsafe
from autopilot.devices import NavSample, Stamped
from autopilot.geo import local_to_latlon
from autopilot.gnc.navigation import NavMemory, NavRules, assemble

ORIGIN = (52.0, 4.4)
RULES = NavRules()  # position_jump_m 25 m, max_sog_m_s 10 m/s, jump_speed_margin_m_s 2 m/s


def _sample(north_m: float, east_m: float, fix_t_s: float, now_s: float, valid: bool = True,
            sog_m_s: float | None = 1.5) -> NavSample:
    lat, lon = local_to_latlon(north_m, east_m, *ORIGIN)
    return NavSample(
        heading_rad=Stamped(0.0, now_s - 0.05, "HDT", True),
        cog_rad=Stamped(0.0, fix_t_s, "RMC", True),
        sog_m_s=None if sog_m_s is None else Stamped(sog_m_s, fix_t_s, "RMC", True),
        yaw_rate_rad_s=None, position=Stamped((lat, lon), fix_t_s, "GGA", valid),
        fix_quality=Stamped(1 if valid else 0, fix_t_s, "GGA", True),
    )


def fly(fixes_ne_m, *, rules=RULES, cycles_per_fix=10, failsafe=None, sog_m_s: float | None = 1.5):
    """Each fix (north_m, east_m) or None (not received) held for a second of 10 Hz cycles; the navigations
    and the failsafe's active causes, one per cycle."""
    memory, navs, active = NavMemory(), [], []
    last_fix = None
    for k, fix in enumerate(fixes_ne_m):
        t_fix = float(k)
        if fix is not None:
            last_fix = (fix, t_fix)
        for c in range(cycles_per_fix):
            now = t_fix + 0.05 + c * 0.1
            if last_fix is None:
                continue
            (n, e), t_s = last_fix
            nav, memory = assemble(_sample(n, e, t_s, now, sog_m_s=sog_m_s), now, memory, rules,
                                   origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
            navs.append(nav)
            if failsafe is not None:
                active.append(failsafe.update(observe(
                    nav, mission_time_s=now, compass_connected=True, thrusters_connected=True, acks_missing_in_a_row=0,
                    compass_garbage_s=None, thruster_garbage_s=None)).active)
    return navs, active


def _track(n: int, speed_m_s: float = 1.5):
    return [(speed_m_s * k, 0.0) for k in range(n)]


def test_one_far_fix_is_refused_and_the_next_good_one_is_taken():
    fixes = _track(10)
    fixes[5] = (fixes[5][0], 600.0)  # 600 m east for one epoch
    navs, _ = fly(fixes)
    jumps = [n.jump for n in navs if n.jump is not None]
    assert len(jumps) == 1 and not jumps[0].accepted
    assert jumps[0].distance_m == pytest.approx(math.hypot(600.0, 1.5), abs=0.5)
    assert jumps[0].gate_m == pytest.approx(25.0 + (1.5 + 2.0) * 1.0)  # the receiver's 1.5 m/s and the margin
    assert max(abs(n.east_m) for n in navs) < 1e-6  # the steered and judged position never went east
    during = navs[50:60]  # the refused second: the fix of t = 4 s goes on, ageing
    assert all(n.north_m == pytest.approx(6.0, abs=1e-6) for n in during)
    assert during[-1].position_age_s == pytest.approx(1.95)
    assert not any(n.new_fix for n in during)
    after = navs[60]
    assert after.new_fix and after.north_m == pytest.approx(9.0, abs=1e-6) and after.position_age_s == pytest.approx(0.05)


def test_the_refused_fix_never_latches_the_distance_limit():
    """The failure found by the fault audit: one outlier fix beyond max_distance_m ended the mission."""
    fixes = _track(10)
    fixes[5] = (600.0, 0.0)
    _, active = fly(fixes, failsafe=Failsafe(FailsafeConfig(max_distance_m=500.0, start_valid_s=0.0)))
    assert not any(active), [a for a in active if a]
    # the same fix, believed (a gate wider than the jump), latches it: the test can fail
    _, active = fly(fixes, rules=NavRules(position_jump_m=1000.0),
                    failsafe=Failsafe(FailsafeConfig(max_distance_m=500.0, start_valid_s=0.0)))
    assert any("max_distance" in a for a in active)


def test_a_position_that_really_moved_is_taken_at_the_second_agreeing_fix():
    fixes = _track(4) + [(4.5 + 60.0, 0.0), (6.0 + 60.0, 0.0), (7.5 + 60.0, 0.0)]  # the receiver's solution moved 60 m
    navs, _ = fly(fixes)
    jumps = [(k, n.jump) for k, n in enumerate(navs) if n.jump is not None]
    assert [j.accepted for _, j in jumps] == [False, True]
    k_anchor = jumps[1][0]
    assert k_anchor == 50  # the second far fix, one second after the first
    assert navs[k_anchor].north_m == pytest.approx(66.0, abs=1e-6) and navs[k_anchor].new_fix
    assert navs[k_anchor - 1].position_age_s < RULES.dead_reckon_max_s + 0.5 < 3.0  # never stale meanwhile
    assert navs[-1].north_m == pytest.approx(67.5, abs=1e-6) and navs[-1].jump is None


def test_far_fixes_that_disagree_are_all_refused_until_the_position_is_stale():
    fixes = _track(3) + [(300.0, 0.0), (0.0, 300.0), (-300.0, 0.0), (0.0, -300.0)]
    navs, active = fly(fixes, failsafe=Failsafe(FailsafeConfig(start_valid_s=0.0)))
    assert [n.jump.accepted for n in navs if n.jump is not None] == [False] * 4
    assert [n.jump.repeated for n in navs if n.jump is not None] == [False, True, True, True]  # said once
    assert all(n.north_m == pytest.approx(3.0) for n in navs[20:])
    assert any("position_stale" in a for a in active)  # the failsafe is told: no position to trust


def test_after_an_outage_the_gate_grows_with_the_time_between_fixes():
    fixes = _track(3) + [None] * 20 + [(3.0 + 1.5 * 21, 80.0)]  # 21 s without a fix, then 90 m on: believable
    navs, _ = fly(fixes)
    assert all(n.jump is None for n in navs)
    assert navs[-1].east_m == pytest.approx(80.0, abs=1e-6)


def test_an_invalid_fix_is_not_gated_and_does_not_move_the_reference():
    memory = NavMemory()
    navs = []
    for k, (n, valid) in enumerate([(0.0, True), (900.0, False), (1.5, True)]):
        now = k + 0.05
        nav, memory = assemble(_sample(n, 0.0, float(k), now, valid=valid), now, memory, RULES,
                               origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
        navs.append(nav)
    assert navs[1].fix_quality == 0 and navs[1].north_m == pytest.approx(900.0, abs=1e-6)  # shown, judged no_fix
    assert navs[2].jump is None and navs[2].north_m == pytest.approx(1.5, abs=1e-6)


def test_gps_noise_and_the_simulators_10_m_outliers_pass_the_gate():
    """The gate is for glitches no boat makes: 2 m wander and 10 m single-fix outliers (issue 12) are left to
    the guidance as before, so evaluate and the campaigns fly as they did."""
    rng = np.random.default_rng(5)
    fixes = [(1.5 * k + rng.normal(0, 2.0), rng.normal(0, 2.0)) for k in range(120)]
    for k in range(5, 120, 17):
        a = rng.uniform(0, 2 * math.pi)
        fixes[k] = (fixes[k][0] + 10.0 * math.cos(a), fixes[k][1] + 10.0 * math.sin(a))
    navs, _ = fly(fixes, cycles_per_fix=1)
    assert all(n.jump is None for n in navs)


def _limits_failsafe():
    return Failsafe(FailsafeConfig(max_distance_m=500.0, start_valid_s=0.0))


def test_a_first_fix_that_is_a_glitch_latches_nothing_and_the_good_fixes_take_over():
    """Found in review: the first fix is believed unjudged (nothing to judge it by); 600 m off it latched
    max_distance on the first cycle. It is steered by but not confirmed until fixes have agreed with the
    one re-anchored to for fix_confirm_s (5 s)."""
    fixes = [(0.0, 600.0)] + _track(10)[1:]
    navs, active = fly(fixes, failsafe=_limits_failsafe())
    assert not any("max_distance" in a for a in active)
    assert [n.jump.accepted for n in navs if n.jump is not None] == [False, True]  # good fix refused, then agreed
    assert [n.fix_confirmed for n in navs[::10]] == [False] * 7 + [True] * 3  # re-anchored at 2 s, confirmed at 7
    assert navs[-1].east_m == pytest.approx(0.0, abs=1e-6)


def test_a_glitch_lasting_two_epochs_is_steered_by_for_a_while_but_latches_nothing():
    fixes = _track(14)
    fixes[4], fixes[5] = (fixes[4][0], 600.0), (fixes[5][0], 600.0)
    navs, active = fly(fixes, failsafe=_limits_failsafe())
    assert [n.jump.accepted for n in navs if n.jump is not None] == [False, True, False, True]
    assert max(n.east_m for n in navs) == pytest.approx(600.0, abs=1e-6)  # the limit of a two-fix rule
    assert not any("max_distance" in a for a in active)
    assert navs[-1].fix_confirmed and navs[-1].east_m == pytest.approx(0.0, abs=1e-6)


def test_a_valid_fix_with_the_stamp_of_an_invalid_one_is_still_judged():
    """Found in review: the driver keeps an epoch's first stamp when its validity changes (GGA quality 0, then
    the same epoch's RMC valid); the gate took the stamp as already judged and let a 600 m fix through."""
    memory, navs, active = NavMemory(), [], []
    fs = _limits_failsafe()
    seq = [(0.0, 0.0, 0.0, True), (1.5, 0.0, 1.0, True), (3.0, 0.0, 2.0, True), (4.5, 0.0, 3.0, False),
           (4.5, 600.0, 3.0, True), (6.0, 0.0, 4.0, True)]
    for k, (n, e, t_fix, valid) in enumerate(seq):
        now = 0.05 + 0.5 * k
        nav, memory = assemble(_sample(n, e, t_fix, now, valid=valid), now, memory, RULES,
                               origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
        navs.append(nav)
        active.append(fs.update(observe(nav, mission_time_s=now, compass_connected=True, thrusters_connected=True,
                                        acks_missing_in_a_row=0, compass_garbage_s=None,
                                        thruster_garbage_s=None)).active)
    assert navs[4].jump is not None and not navs[4].jump.accepted and navs[4].east_m == pytest.approx(0.0, abs=1e-6)
    assert not any("max_distance" in a for a in active)


def test_an_invalid_fix_far_away_latches_no_limit():
    """Found in review (older than the gate): an RMC 'V' or GGA quality 0 carrying a position 600 m off
    latched max_distance though the fix is known to be bad."""
    memory = NavMemory()
    fs = _limits_failsafe()
    active = []
    for k, (n, valid) in enumerate([(0.0, True), (1.5, True), (600.0, False), (4.5, True)]):
        now = k + 0.05
        nav, memory = assemble(_sample(n, 0.0, float(k), now, valid=valid), now, memory, RULES,
                               origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
        active.append(fs.update(observe(nav, mission_time_s=now, compass_connected=True, thrusters_connected=True,
                                        acks_missing_in_a_row=0, compass_garbage_s=None,
                                        thruster_garbage_s=None)).active)
    assert "no_fix" in active[2] and not any("max_distance" in a for a in active)


def test_the_simulated_cycle_reports_the_jump_as_the_daemon_logs_it():
    """Found in review: autopilot.closed_loop's cycle (evaluate, campaigns, --replay logs) left position_jump out
    of the events the daemon would log."""
    from autopilot.closed_loop import ControlCycle
    from autopilot.gnc import Autopilot, GncConfig

    cc = ControlCycle(Autopilot(GncConfig(), [(200.0, 0.0)]), period_s=0.1, origin_lat_deg=ORIGIN[0],
                      origin_lon_deg=ORIGIN[1], failsafe=_limits_failsafe())
    names = []
    for k, (n, e) in enumerate([(0.0, 0.0), (1.5, 0.0), (3.0, 600.0), (4.5, 0.0)]):
        cyc = cc.step(_sample(n, e, float(k), k + 0.05), k + 0.05)
        names += [(name, f.get("accepted")) for name, f in cyc.events if name == "position_jump"]
    assert names == [("position_jump", False)]


def test_control_starts_on_a_confirmed_position_so_a_first_glitch_is_never_the_launch_point():
    """Found in review: with a first fix 300 m off, control started (start_valid_s 1 s) before the good fixes
    re-anchored, and the launch point, rtl's home, was set 300 m away."""
    def start_position(fixes):
        memory, fs = NavMemory(), Failsafe(FailsafeConfig(start_valid_s=1.0))
        for k, (n, e) in enumerate(fixes):
            for c in range(10):
                now = k + 0.05 + 0.1 * c
                nav, memory = assemble(_sample(n, e, float(k), now), now, memory, RULES,
                                       origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
                if fs.update(observe(nav, mission_time_s=now, compass_connected=True, thrusters_connected=True,
                                     acks_missing_in_a_row=0, compass_garbage_s=None,
                                     thruster_garbage_s=None)).mode == "auto":
                    return now, (nav.north_m, nav.east_m)
        return None

    t_good, (n, e) = start_position(_track(8))
    assert t_good == pytest.approx(5.05) and (n, e) == (pytest.approx(7.5), pytest.approx(0.0, abs=1e-6))
    t_glitch, (n, e) = start_position([(0.0, 300.0)] + _track(10)[1:])
    assert t_glitch == pytest.approx(7.05) and e == pytest.approx(0.0, abs=1e-6)  # refused, re-anchored, confirmed


def test_a_30_m_glitch_at_rest_is_refused_and_never_the_launch_point():
    """Found by a review audit (daemon --sim with the simulator's 30-m, two-epoch outliers): the gate let a fix
    have moved 25 m + 10 m/s x 1 s whatever the receiver's speed, so a 30-m glitch of a boat at rest passed as
    a confirmed move; it came the second control started and became the launch point (rtl's home) 29 m
    from the boat. The receiver's speed over ground (0.1 m/s) now bounds the gate: 25 m + 2.1 m."""
    rest = [(0.0, 0.0), (0.2, -0.3), (-15.0, 26.0), (-15.2, 25.6), (0.1, -0.2), (0.0, 0.1), (0.2, 0.0), (0.1, 0.1)]
    navs, active = fly(rest, sog_m_s=0.1, failsafe=Failsafe(FailsafeConfig(start_valid_s=1.0, max_distance_m=20.0)))
    jumps = [n.jump for n in navs if n.jump is not None]
    assert [j.accepted for j in jumps] == [False, True, False, True]  # refused; two agree; back, refused; agreed
    assert jumps[0].gate_m == pytest.approx(25.0 + 2.1)
    assert not any("max_distance" in a for a in active)  # 30 m from launch with a 20-m limit: never latched
    assert not any(n.fix_confirmed and abs(n.east_m) > 1.0 for n in navs)  # the glitch is never a confirmed fix
    # without a speed over ground the gate stays as wide as before (max_sog_m_s): the glitch passes as a move
    navs, _ = fly(rest, sog_m_s=None)
    assert all(n.jump is None for n in navs)


def test_control_never_starts_on_a_30_m_glitch_at_rest():
    """The launch point is where control starts (autopilot.gnc.Autopilot): a confirmed fix, now never the glitch."""
    memory, fs = NavMemory(), Failsafe(FailsafeConfig(start_valid_s=1.0))
    rest = [(0.0, 0.0), (0.2, -0.3), (-15.0, 26.0), (-15.2, 25.6)] + [(0.1, -0.2), (0.0, 0.1), (0.2, 0.0)] * 3
    start = None
    for k, (n, e) in enumerate(rest[1:], start=1):  # control could start at the first good fix's second
        for c in range(10):
            now = k + 0.05 + 0.1 * c
            nav, memory = assemble(_sample(n, e, float(k), now, sog_m_s=0.1), now, memory, RULES,
                                   origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
            if start is None and fs.update(observe(nav, mission_time_s=now, compass_connected=True,
                                                   thrusters_connected=True, acks_missing_in_a_row=0,
                                                   compass_garbage_s=None, thruster_garbage_s=None)).mode == "auto":
                start = (nav.north_m, nav.east_m)
    assert start is not None and math.hypot(*start) < 1.0


def test_a_two_epoch_glitch_is_not_confirmed_by_the_gate_growing_while_it_is_refused():
    """Found by a verification on the auditors' bench (a receiver at 1.27 s a fix, speed over ground 0): the gate
    grows with the time since the last fix used, so the glitch's second fix, 2.5 s after the last good one,
    passed it (25 + 2 x 2.54 m > 30 m) as a confirmed move, and the launch point was set 30 m from the boat.
    A fix that agrees with a refused one now re-anchors, unconfirmed, whatever the gate."""
    memory, fs = NavMemory(), Failsafe(FailsafeConfig(start_valid_s=1.0))
    fixes = [(0.0, 0.0), (0.1, -0.1), (30.0, 0.0), (30.05, 0.1)] + [(0.0, 0.1), (0.1, 0.0), (0.0, -0.1)] * 3
    start, confirmed_far = None, False
    for k, (n, e) in enumerate(fixes):
        t_fix = 1.27 * k
        for c in range(12):
            now = t_fix + 0.05 + 0.1 * c
            nav, memory = assemble(_sample(n, e, t_fix, now, sog_m_s=0.0), now, memory, RULES,
                                   origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
            confirmed_far |= nav.fix_confirmed and nav.north_m > 1.0
            if start is None and fs.update(observe(nav, mission_time_s=now, compass_connected=True,
                                                   thrusters_connected=True, acks_missing_in_a_row=0,
                                                   compass_garbage_s=None, thruster_garbage_s=None)).mode == "auto":
                start = (nav.north_m, nav.east_m)
    assert not confirmed_far
    assert start is not None and math.hypot(*start) < 1.0


@pytest.mark.parametrize("epochs", [3, 4])
def test_a_glitch_of_three_or_four_epochs_at_rest_is_never_confirmed_nor_the_launch_point(epochs):
    """The two-fix rule believed a glitch lasting three epochs: its second fix re-anchored, its third passed the
    gate from the second and was confirmed, so the geofence could latch on it and control start there (the
    launch point, rtl's home, 30 m from the boat; README "What is still missed" until 2026-12-05). A chain is
    now confirmed only once its fixes have agreed for fix_confirm_s (5 s)."""
    def glitch_at(k0):
        fixes = [(0.1 * (k % 3), -0.1 * (k % 2)) for k in range(20)]
        for k in range(k0, k0 + epochs):
            fixes[k] = (30.0 + 0.1 * k, 0.1)
        return fixes

    for k0 in (0, 2):  # from the receiver's first fix, and once good fixes came
        fixes = glitch_at(k0)
        memory, fs = NavMemory(), Failsafe(FailsafeConfig(start_valid_s=1.0, max_distance_m=20.0))
        start, confirmed_far, active = None, False, []
        for k, (n, e) in enumerate(fixes):
            for c in range(10):
                now = k + 0.05 + 0.1 * c
                nav, memory = assemble(_sample(n, e, float(k), now, sog_m_s=0.05), now, memory, RULES,
                                       origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1])
                confirmed_far |= nav.fix_confirmed and nav.north_m > 1.0
                decision = fs.update(observe(nav, mission_time_s=now, compass_connected=True, thrusters_connected=True,
                                             acks_missing_in_a_row=0, compass_garbage_s=None, thruster_garbage_s=None))
                active.append(decision.active)
                if start is None and decision.mode == "auto":
                    start = (nav.north_m, nav.east_m)
        assert not confirmed_far, k0
        assert not any("max_distance" in a for a in active), k0
        assert start is not None and math.hypot(*start) < 1.0, (k0, start)


def test_a_chain_broken_by_a_gap_in_the_fixes_starts_anew():
    """Found by a review: the 5 s counted from the chain's first fix, not over fixes that agreed, so a glitch
    as the first fix, four lost epochs and the same glitch again was confirmed at once and became the launch
    point; mid-run, one far fix after a 20-s outage passed the grown gate confirmed and latched max_distance."""
    fixes = [(30.0, 0.0)] + [None] * 4 + [(30.1, 0.0)] + [(0.1 * (k % 2), 0.0) for k in range(12)]
    navs, active = fly(fixes, sog_m_s=0.05,
                       failsafe=Failsafe(FailsafeConfig(start_valid_s=1.0, max_distance_m=20.0)))
    assert not any(n.fix_confirmed and n.north_m > 1.0 for n in navs)
    assert not any("max_distance" in a for a in active)
    outage = [(0.1 * (k % 2), 0.0) for k in range(8)] + [None] * 20 + [(55.0, 0.0)] + [(0.0, 0.1)] * 8
    navs, active = fly(outage, sog_m_s=2.0, failsafe=Failsafe(FailsafeConfig(start_valid_s=1.0, max_distance_m=50.0)))
    assert not any(n.fix_confirmed and n.north_m > 1.0 for n in navs)
    assert not any("max_distance" in a for a in active)
