"""Navigation assembly (autopilot.gnc.navigation): which heading the loop steers on, the yaw rate, the fix.

Pure: literal samples in, literal answers out (the same function ``autopilot evaluate`` uses).
"""

import math

import pytest

from autopilot.devices import NavSample, Stamped
from autopilot.gnc.navigation import NavMemory, NavRules, assemble, choose_heading

R = math.radians


def sample(heading=(90.0, 10.0, True), cog=(45.0, 9.5, True), sog_m_s=1.0, rot=None, fix=None) -> NavSample:
    return NavSample(
        heading_rad=None if heading is None else Stamped(R(heading[0]), heading[1], "HDT", heading[2]),
        cog_rad=None if cog is None else Stamped(R(cog[0]), cog[1], "RMC", cog[2]),
        sog_m_s=None if cog is None else Stamped(sog_m_s, cog[1], "RMC", True),
        yaw_rate_rad_s=None if rot is None else Stamped(R(rot[0]), rot[1], "ROT", True),
        position=None if fix is None else Stamped((fix[0], fix[1]), fix[2], "GGA", True),
        fix_quality=None if fix is None else Stamped(1, fix[2], "GGA", True),
    )


@pytest.mark.parametrize("fallback, data, now_s, expected", [
    (False, sample(), 10.5, (90.0, "HDT", 0.5, True)),
    (False, sample(), 11.5, (90.0, "HDT", 1.5, True)),  # stale: the failsafe sees the age
    (True, sample(), 11.5, (45.0, "COG", 2.0, True)),  # stale heading, moving: COG, logged as such
    (True, sample(sog_m_s=0.25), 11.5, (90.0, "HDT", 1.5, True)),  # too slow for COG to mean anything
    (True, sample(heading=(90.0, 10.0, False)), 10.2, (45.0, "COG", 0.7, True)),
    (False, sample(heading=(90.0, 10.0, False)), 10.2, (90.0, "HDT", pytest.approx(0.2), False)),
    (False, sample(heading=None), 10.2, (None, None, float("inf"), False)),
])
def test_heading_choice(fallback, data, now_s, expected):
    got = choose_heading(data, now_s, NavRules(cog_fallback=fallback, cog_fallback_min_sog_m_s=0.5))
    heading = None if got[0] is None else math.degrees(got[0])
    assert heading == pytest.approx(expected[0]) and got[1] == expected[1] and got[3] == expected[3]
    assert got[2] == pytest.approx(expected[2])


def test_yaw_rate_from_rot_else_differenced():
    rules = NavRules()
    nav, mem = assemble(sample(rot=(6.0, 10.0)), 10.05, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.yaw_rate_rad_s == pytest.approx(R(6.0))
    nav2, _ = assemble(sample(heading=(91.0, 10.1, True)), 10.15, mem, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav2.yaw_rate_rad_s == pytest.approx(R(1.0) / 0.1)  # no ROT: the heading differenced over the cycle
    across = sample(heading=(0.5, 10.1, True))
    mem_359 = NavMemory(heading_t_s=10.05, heading_rad=R(359.5))
    nav3, _ = assemble(across, 10.15, mem_359, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav3.yaw_rate_rad_s == pytest.approx(R(1.0) / 0.1)  # across north, the short way


def test_fix_is_new_once_then_held_and_dead_reckoned():
    rules = NavRules(dead_reckon_max_s=1.5)
    s = sample(fix=(52.0, 4.4, 10.0), sog_m_s=2.0, cog=(0.0, 10.0, True))
    nav, mem = assemble(s, 10.1, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.new_fix and nav.north_m == pytest.approx(0.0, abs=1e-9)
    assert nav.est_north_m == pytest.approx(0.2)  # 0.1 s at 2 m/s northwards
    nav, mem = assemble(s, 10.9, mem, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert not nav.new_fix and nav.est_north_m == pytest.approx(1.8) and nav.position_age_s == pytest.approx(0.9)
    nav, _ = assemble(s, 13.0, mem, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.est_north_m == pytest.approx(3.0)  # carried at most dead_reckon_max_s


def test_a_speed_no_wamv_reaches_is_not_used():
    """One checksum-valid RMC at 999 kn carried the steered position 570 m away (found by fault injection)."""
    rules = NavRules(dead_reckon_max_s=1.5)
    glitch = sample(fix=(52.0, 4.4, 10.0), sog_m_s=999.0 * 1852 / 3600, cog=(0.0, 10.0, True))
    nav, _ = assemble(glitch, 10.9, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.est_north_m == pytest.approx(nav.north_m) and nav.sog_m_s is None and nav.cog_rad is None
    fast = sample(fix=(52.0, 4.4, 10.0), sog_m_s=9.0, cog=(0.0, 10.0, True))  # fast, but a boat's
    nav, _ = assemble(fast, 10.5, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.est_north_m == pytest.approx(4.5) and nav.sog_m_s == 9.0


def test_an_old_or_invalid_speed_is_not_carried_forward():
    rules = NavRules(position_stale_s=3.0)
    old = sample(fix=(52.0, 4.4, 13.0), sog_m_s=2.0, cog=(0.0, 9.5, True))  # the RMCs stopped 4 s ago
    nav, _ = assemble(old, 13.5, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.sog_m_s is None and nav.est_north_m == pytest.approx(nav.north_m)
    s = sample(fix=(52.0, 4.4, 10.0))
    invalid = NavSample(**{**s.__dict__, "sog_m_s": Stamped(2.0, 10.0, "VTG", False)})
    nav, _ = assemble(invalid, 10.5, NavMemory(), rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.sog_m_s is None and nav.est_north_m == pytest.approx(nav.north_m)


def test_a_turn_rate_no_wamv_reaches_is_not_used():
    """One ROT at 9999 deg/min (166 deg/s) saturated the heading PID's derivative term: the heading differenced
    over the cycle stands in, as when no ROT comes."""
    rules = NavRules()
    mem = NavMemory(heading_t_s=10.0, heading_rad=R(89.0))
    nav, _ = assemble(sample(rot=(9999.0 / 60.0, 10.05)), 10.1, mem, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.yaw_rate_rad_s == pytest.approx(R(1.0) / 0.1)
    nav, _ = assemble(sample(rot=(-100.0, 10.05)), 10.1, mem, rules, origin_lat_deg=52.0, origin_lon_deg=4.4)
    assert nav.yaw_rate_rad_s == pytest.approx(R(-100.0))  # a hard spin is believed (< 2 rad/s)
