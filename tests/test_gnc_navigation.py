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
