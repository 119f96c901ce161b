"""Dead reckoning between 1 Hz position fixes (autopilot.gnc.navigation)."""

import math

import pytest
from numpy.testing import assert_allclose

from autopilot.gnc.navigation import dead_reckon_ne


def test_carries_the_fix_along_the_course_over_ground():
    # 1.5 m/s on course 090 for 0.6 s: 0.9 m east, whatever the heading (crabbing)
    assert_allclose(dead_reckon_ne(10.0, 5.0, 0.6, 1.5, math.radians(90), math.radians(60), max_age_s=1.5), (10.0, 5.9), atol=1e-12)


def test_age_is_capped_and_zero_cap_disables():
    assert_allclose(dead_reckon_ne(0.0, 0.0, 10.0, 2.0, 0.0, 0.0, max_age_s=1.5), (3.0, 0.0), atol=1e-12)
    assert dead_reckon_ne(1.0, 2.0, 0.5, 2.0, 0.0, 0.0, max_age_s=0.0) == (1.0, 2.0)


@pytest.mark.parametrize("sog, cog", [(None, 0.0), (float("nan"), 0.0), (1.0, None)])
def test_unknown_velocity_keeps_the_fix_or_uses_heading(sog, cog):
    north, east = dead_reckon_ne(1.0, 2.0, 0.5, sog, cog, None, max_age_s=1.5)
    assert (north, east) == (1.0, 2.0)


def test_slow_boat_moves_along_its_heading_not_the_noisy_course():
    north, east = dead_reckon_ne(0.0, 0.0, 1.0, 0.1, math.radians(180), math.radians(90), max_age_s=1.5)
    assert_allclose((north, east), (0.0, 0.1), atol=1e-12)


def test_a_heading_that_stands_still_while_the_rate_of_turn_says_turning_sums_the_turn():
    """The frozen-compass evidence (autopilot.gnc.navigation.still_turn): new heading samples within 0.5 deg of
    where the sum began, the ROT beside each one summed over the time between samples."""
    from autopilot.gnc.navigation import HEADING_STILL_RAD, NavMemory, still_turn

    rot = math.radians(30.0)
    mem = NavMemory()
    anchor, t, turned = still_turn(1.0, 0.0, rot, mem)
    assert (anchor, t, turned) == (1.0, 0.0, 0.0)  # the first sample only anchors
    for k in range(1, 11):  # the same heading, 10 Hz, for 1 s, ROT 30 deg/s
        anchor, t, turned = still_turn(1.0 + 0.4 * HEADING_STILL_RAD, 0.1 * k, rot,
                                       NavMemory(still_heading_rad=anchor, still_t_s=t, still_turn_rad=turned))
    assert_allclose(math.degrees(turned), 30.0, rtol=1e-9)
    mem = NavMemory(still_heading_rad=anchor, still_t_s=t, still_turn_rad=turned)
    assert still_turn(1.0, t, rot, mem) == (anchor, t, turned)  # a held sample (no new sentence) adds nothing
    assert still_turn(1.0, t + 0.1, math.radians(1.5), mem)[2] == turned  # ROT noise at rest is not turning
    assert still_turn(1.0, t + 0.1, None, mem)[2] == turned  # no ROT: no evidence
    assert still_turn(1.0 + 2 * HEADING_STILL_RAD, t + 0.1, rot, mem) == (1.0 + 2 * HEADING_STILL_RAD, t + 0.1, 0.0)
    # across north: 359.9 deg and 0.1 deg are 0.2 deg apart
    north = NavMemory(still_heading_rad=math.radians(359.9), still_t_s=0.0, still_turn_rad=0.2)
    assert still_turn(math.radians(0.1), 0.1, rot, north)[2] == pytest.approx(0.2 + rot * 0.1)


def test_since_when_the_compass_heading_has_stood_still_is_kept_until_it_moves():
    """Navigation.heading_still_since_s: the time of the sample the still window began at (the failsafe counts
    the helm's steering over it); a heading within 0.5 deg keeps it, one that moves restarts it."""
    from autopilot.devices import NavSample, Stamped
    from autopilot.gnc.navigation import HEADING_STILL_RAD, NavMemory, NavRules, assemble

    mem, seen = NavMemory(), []
    for k, h in enumerate([None, 1.0, 1.0 + 0.9 * HEADING_STILL_RAD, 1.0, 1.0 + 3 * HEADING_STILL_RAD, 1.0]):
        t = 0.1 * k
        sample = NavSample(heading_rad=None if h is None else Stamped(h, t, "HDT", True))
        nav, mem = assemble(sample, t, mem, NavRules(), origin_lat_deg=0.0, origin_lon_deg=0.0)
        seen.append(nav.heading_still_since_s)
    assert seen == [None, 0.1, 0.1, 0.1, pytest.approx(0.4), pytest.approx(0.5)]
