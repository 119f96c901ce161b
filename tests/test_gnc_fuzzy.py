"""Fuzzy engine and fuzzy guidance (thesis ch. 6): hand-computed cases."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.gnc import GncConfig, NavInput
from autopilot.gnc.fuzzy import tri, uniform_partition
from autopilot.gnc.fuzzy_guidance import RULE_TABLE, SETS, FuzzyConfig, FuzzyGuidance, cdh, cdh_engine, cpa_geometry

L = 4.0


@pytest.mark.parametrize(
    "wp, tcpa, dcpa",
    [
        ((20.0, 0.0), 5.0, 0.0),  # dead ahead: 20 m = 5 boat lengths along the bow
        ((0.0, 20.0), 0.0, 5.0),  # abeam to starboard
        ((0.0, -20.0), 0.0, 5.0),  # abeam to port
        ((-20.0, 0.0), -5.0, 0.0),  # behind
        ((3.0, 4.0), 3.0 / L, 4.0 / L),  # 3-4-5 triangle
    ],
)
def test_cpa_geometry_heading_north(wp, tcpa, dcpa):
    d, theta, alpha, t_nd, d_nd = cpa_geometry(0.0, 0.0, 0.0, wp[0], wp[1], L)
    assert_allclose(d, math.hypot(*wp))
    assert_allclose([t_nd, d_nd], [tcpa, dcpa], atol=1e-12)


def test_tri_shapes():
    assert_allclose(tri([0, 0.5, 1, 1.5, 2], 0, 1, 2), [0, 0.5, 1, 0.5, 0])
    assert_allclose(tri([0, 0.5, 1], 0, 0, 1), [1, 0.5, 0])  # left shoulder


@pytest.mark.parametrize("i", range(5))
@pytest.mark.parametrize("j", range(5))
def test_rule_table_at_set_peaks(i, j):
    """At the peak of DCPA' set i and TCPA' set j exactly one rule fires fully: CDH = its set's centre."""
    cfg = FuzzyConfig()
    d = cfg.dcpa_max_nd * i / 4
    t = cfg.tcpa_max_nd * j / 4
    want = SETS.index(RULE_TABLE[i][j]) / 4
    assert_allclose(float(cdh(t, d, cfg)), want, atol=1e-9)
    eng = cdh_engine(cfg.tcpa_max_nd, cfg.dcpa_max_nd, cfg.defuzz_points)
    assert_allclose(eng.evaluate_scalar(d, t), want, atol=1e-9)


def test_rule_table_corners_and_shape():
    assert RULE_TABLE[0][0] == "LA" and RULE_TABLE[0][4] == "SA" and RULE_TABLE[4][0] == "SA" and RULE_TABLE[4][4] == "SA"
    cfg = FuzzyConfig()
    assert float(cdh(10 * cfg.tcpa_max_nd, 10 * cfg.dcpa_max_nd, cfg)) == pytest.approx(0.0, abs=1e-12)  # beyond the universe: LA


def test_scalar_and_vector_paths_agree():
    cfg = FuzzyConfig(tcpa_max_nd=2.3, dcpa_max_nd=1.7)
    rng = np.random.default_rng(1)
    t = rng.uniform(-0.5, 3.0, 200)
    d = rng.uniform(0.0, 2.0, 200)
    eng = cdh_engine(cfg.tcpa_max_nd, cfg.dcpa_max_nd, cfg.defuzz_points)
    scalar = [eng.evaluate_scalar(dd, tt) for tt, dd in zip(t, d)]
    assert_allclose(eng.evaluate(d, t), scalar, atol=1e-12)


def test_cdh_decreases_with_distance():
    cfg = FuzzyConfig()
    t = np.linspace(0, cfg.tcpa_max_nd, 50)
    c = cdh(t, 0.0, cfg)
    assert np.all(np.diff(c) <= 1e-12) and c[0] == pytest.approx(1.0) and c[-1] == pytest.approx(0.0)


def test_uniform_partition_extend():
    parts = uniform_partition(0.0, 1.0, 5, extend=True)
    assert parts[0] == (-0.25, 0.0, 0.25) and parts[-1] == (0.75, 1.0, 1.25)


def nav(n, e, psi_deg, speed=1.0):
    psi = math.radians(psi_deg)
    return NavInput(north_m=n, east_m=e, psi_rad=psi, speed_m_s=speed, yaw_rate_rad_s=0.0, course_rad=psi)


def guidance(wps, **fuzzy):
    cfg = GncConfig().guidance
    if fuzzy:
        from dataclasses import replace

        cfg = replace(cfg, fuzzy=replace(cfg.fuzzy, **fuzzy))
    return FuzzyGuidance(cfg, wps, boat_length_m=L)


def test_far_waypoint_steers_to_it_only():
    g = guidance([(100.0, 0.0), (100.0, 100.0)])
    out = g.update(nav(0, 0, 0), 0.1)
    assert out.cdh == pytest.approx(0.0) and out.psi_d_rad == pytest.approx(0.0)


def test_blend_wraps_across_north():
    """psi_1 just west of north, psi_2 just east: psi_d must lie on the short arc through north."""
    g = guidance([(2.0, -0.3), (40.0, 6.0)])
    out = g.update(nav(0, 0, 0), 0.1)
    psi_1 = math.atan2(-0.3, 2.0)
    psi_2 = math.atan2(6.0, 40.0)
    assert 0.0 < out.cdh < 1.0
    assert psi_1 < out.psi_d_rad < psi_2  # not the long way round via south
    assert_allclose(out.psi_d_rad, psi_1 + (psi_2 - psi_1) * out.cdh)


def test_waypoint_behind_at_start_is_not_passed():
    g = guidance([(-10.0, 0.0), (-20.0, 5.0)])
    out = g.update(nav(0, 0, 0), 0.1)
    assert out.reached_index is None and out.wp_index == 0
    assert abs(out.psi_d_rad) == pytest.approx(math.pi)


def test_switch_when_tcpa_turns_negative():
    g = guidance([(10.0, 1.5), (20.0, 10.0)])
    assert g.update(nav(5, 0, 0), 0.1).reached_index is None
    assert g.update(nav(9.9, 0, 0), 0.1).reached_index is None
    out = g.update(nav(10.2, 0, 0), 0.1)  # the waypoint is now abaft the beam
    assert out.reached_index == 0 and out.wp_index == 1
    assert out.reached_how == "passed"  # 1.5 m abeam: outside the 1 m capture radius
    assert out.reached_distance_m == pytest.approx(math.hypot(0.2, 1.5))  # the distance at the switch


def test_no_switch_at_rest_or_far_away():
    g = guidance([(10.0, 1.5), (20.0, 10.0)])
    g.update(nav(5, 0, 0), 0.1)
    assert g.update(nav(10.2, 0, 0, speed=0.0), 0.1).reached_index is None  # TCPA undefined at rest
    g = guidance([(30.0, 0.0), (40.0, 10.0)])
    g.update(nav(0, 0, 0), 0.1)
    assert g.update(nav(0, 0, 180), 0.1).reached_index is None  # spun round 30 m away: not passed


def test_on_top_of_waypoint_counts_as_reached():
    g = guidance([(0.2, 0.1), (10.0, 0.0)])
    out = g.update(nav(0, 0, 90, speed=0.0), 0.1)
    assert out.reached_index == 0 and out.wp_index == 1 and math.isfinite(out.psi_d_rad)


def test_last_waypoint_stop():
    g = guidance([(10.0, 0.0)])
    g.update(nav(0, 0, 0), 0.1)
    out = g.update(nav(10.3, 0.2, 0), 0.1)
    assert out.complete and out.thrust_off and out.reached_index == 0
    assert g.update(nav(11, 0, 0), 0.1).thrust_off


def test_a_waypoint_abeam_at_the_switch_is_not_passed_by_the_turn():
    """The clean-clone failure of 08d271a: the next waypoint 10.8 m nearly abeam right after a capture armed the
    pass test on a TCPA' just above 0, and the course swinging past it two cycles later counted it "passed"."""
    g = guidance([(0.3, 10.8)])
    first = g.update(nav(0, 0, 0), 0.1)
    assert first.reached_index is None and 0.0 < first.tcpa_nd < 0.1  # abeam, a hair ahead
    out = g.update(nav(0.5, 0.0, 0), 0.1)  # the waypoint just abaft the beam, 10.8 m off: not passed
    assert out.reached_index is None and not out.complete and out.wp_index == 0
    assert out.psi_d_rad == pytest.approx(math.atan2(10.8, -0.2))  # turns back to it
    g.update(nav(0.5, 2.0, 90), 0.1)  # heading for it now: armed
    out = g.update(nav(0.5, 11.2, 90), 0.1)  # and by it, 0.45 m abeam
    assert out.reached_index == 0 and out.complete


def test_arming_at_ninety_degrees_is_the_old_tcpa_test():
    g = guidance([(0.3, 10.8)], arm_bearing_deg=90.0, pass_radius_nd=3.0)
    g.update(nav(0, 0, 0), 0.1)
    assert g.update(nav(0.5, 0.0, 0), 0.1).reached_how == "passed"


def test_a_boat_set_sideways_past_a_close_waypoint_passes_it():
    """Campaign run 242 (9.6 m/s of wind): the boat blown across its first waypoint, course 60 deg off its bearing
    but 1.4 m abeam, passes it; refused, it could never come back upwind to capture it."""
    g = guidance([(2.7, -1.2), (7.8, -3.4)])
    assert g.update(nav(1.49, 0.58, 4), 0.1).reached_index is None  # 60 deg off, 1.9 m abeam: ahead, close
    out = g.update(nav(2.7, 0.3, 4), 0.1)
    assert out.reached_index == 0 and out.reached_how == "passed" and out.wp_index == 1


def test_no_way_on_does_not_arm_the_pass_test():
    """Found by a review of fb51086: below min_speed_m_s the reference is the heading, which points at the target the
    law steers for, so a boat turning on the spot armed at once; a current then set its course 100 deg off and the
    waypoint, abaft that course's beam, was counted passed 10.8 m off."""
    g = guidance([(11.0, 0.0)])
    slow = NavInput(north_m=0.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.1, yaw_rate_rad_s=0.0, course_rad=math.pi)
    assert g.update(slow, 0.1).reached_index is None  # heading straight at it, no way on: not armed
    set_off = NavInput(north_m=0.2, east_m=0.3, psi_rad=math.radians(38), speed_m_s=0.27, yaw_rate_rad_s=0.0,
                       course_rad=math.radians(102))
    out = g.update(set_off, 0.1)  # the course set by the current: the waypoint abaft its beam, 10.8 m off
    assert out.tcpa_nd < 0.0 and out.reached_index is None and not out.complete


def test_a_waypoint_gone_by_more_than_a_boat_length_off_is_not_passed():
    """The pass radius (pass_radius_nd, 1 boat length; 3 before): a boat set past its waypoint 5 m off by a current
    has not visited it and turns back for it; 3 m off it has passed it."""
    for abeam_m, passed in ((5.0, False), (3.0, True)):
        g = guidance([(20.0, abeam_m), (40.0, abeam_m)])
        assert g.update(nav(0, 0, 0), 0.1).reached_index is None  # far ahead, 14 deg off the course: armed
        out = g.update(nav(20.3, 0, 0), 0.1)  # just by it
        assert (out.reached_index == 0) is passed, abeam_m
        if not passed:
            assert out.psi_d_rad == pytest.approx(math.atan2(abeam_m, -0.3))  # back for it


@pytest.mark.parametrize("law", ["fuzzy", "los", "proportional"])
def test_waypoints_reached_in_one_place_are_each_reached_and_said(law):
    """Found by a new-user audit: [[0, 0], [0.5, 0], [20, 0]] from the origin said "2 of 3 waypoint(s) reached":
    W1, within the capture radius of W0, was switched past in the same cycle, without a waypoint_reached line.
    One waypoint is reached per cycle, each said."""
    from dataclasses import replace

    from autopilot.gnc.registry import make_guidance

    cfg = replace(GncConfig().guidance, law=law)
    g = make_guidance(cfg, [(0.0, 0.0), (0.5, 0.0), (20.0, 0.0)], boat_length_m=L)
    first = g.update(nav(0.0, 0.0, 0), 0.1)
    second = g.update(nav(0.0, 0.0, 0), 0.1)
    assert (first.reached_index, first.wp_index) == (0, 1)
    assert (second.reached_index, second.wp_index) == (1, 2)
    assert g.update(nav(0.05, 0.0, 0), 0.1).reached_index is None and g.index == 2
