"""Encounter geometry with literals, every COLREGs sector boundary, hysteresis, AIS targets in the local frame."""

from __future__ import annotations

import math
import random

import pytest
from numpy.testing import assert_allclose

from autopilot.drivers.ais import AisTarget
from autopilot.geo import local_to_latlon
from autopilot.gnc.encounter import (
    EncounterConfig,
    EncounterTracker,
    OwnShip,
    Situation,
    TargetState,
    classify,
    cpa,
    geometry,
)
from autopilot.measured import HULL_LENGTH_M

L = HULL_LENGTH_M
R = math.radians
OWN = OwnShip(north_m=0.0, east_m=0.0, course_rad=0.0, speed_m_s=1.0, heading_rad=0.0)  # north at 1 m/s


def tgt(n, e, course_deg, speed, tid=1, heading_deg=None):
    return TargetState(target_id=tid, north_m=n, east_m=e, course_rad=R(course_deg), speed_m_s=speed,
                       heading_rad=None if heading_deg is None else R(heading_deg))


# --------------------------------------------------------------------------- DCPA / TCPA by hand


@pytest.mark.parametrize(
    "target, dcpa_m, tcpa_s",
    [
        (tgt(100, 0, 180, 1.0), 0.0, 50.0),  # head-on, closing at 2 m/s over 100 m
        (tgt(100, 10, 180, 1.0), 10.0, 50.0),  # 10 m to starboard: passes at 10 m
        (tgt(100, 100, 270, 1.0), 0.0, 100.0),  # crossing from starboard: both at (100, 0) at t = 100 s
        (tgt(100, 150, 270, 1.5), 0.0, 100.0),  # the same with the target faster (v_rel = (-1, -1.5))
        (tgt(0, 50, 0, 1.0), 50.0, 0.0),  # abeam, same course and speed: no relative motion
        (tgt(3, 4, 0, 0.0), 4.0, 3.0),  # a buoy: v_rel = (-1, 0); CPA when it is abeam, 4 m off
        (tgt(-20, 0, 0, 1.5), 0.0, 40.0),  # overtaken from dead astern at 0.5 m/s
        (tgt(-20, 0, 0, 0.5), 0.0, -40.0),  # ... and one falling astern: the CPA was 40 s ago
    ],
)
def test_dcpa_tcpa_hand_computed(target, dcpa_m, tcpa_s):
    g = geometry(OWN, target)
    assert_allclose((g.dcpa_m, g.tcpa_s), (dcpa_m, tcpa_s), atol=1e-9)
    assert_allclose(g.dcpa_nd, dcpa_m / L, atol=1e-9)  # Eq 6.7
    assert_allclose(g.tcpa_nd, tcpa_s / (L / 1.0), atol=1e-9)  # Eq 6.8, U = own speed 1 m/s


def test_buoy_geometry_bearing_rate_and_range_rate():
    g = geometry(OWN, tgt(3, 4, 0, 0.0))
    assert_allclose(g.range_m, 5.0)
    assert_allclose(math.degrees(g.bearing_rad), math.degrees(math.atan2(4, 3)))
    assert_allclose(g.relative_bearing_rad, g.bearing_rad)  # heading north
    # (p_N v_E - p_E v_N) / r^2 = (3 * 0 - 4 * -1) / 25: drawing aft on the starboard side (clockwise)
    assert_allclose(g.bearing_rate_rad_s, 0.16)
    assert_allclose(g.range_rate_m_s, -0.6)


def test_constant_bearing_on_a_collision_course():
    g = geometry(OWN, tgt(100, 150, 270, 1.5))
    assert abs(g.bearing_rate_rad_s) < 1e-12 and g.range_rate_m_s < 0  # rule 7(d)(i)


def test_tcpa_nd_floor_at_rest():
    still = OwnShip(0.0, 0.0, 0.0, 0.0, 0.0)
    g = geometry(still, tgt(100, 0, 180, 2.0), tcpa_speed_floor_m_s=0.5)
    assert_allclose(g.tcpa_s, 50.0)
    assert_allclose(g.tcpa_nd, 50.0 * 0.5 / L)  # U floored at 0.5 m/s, not 0


def test_cpa_literal():
    assert cpa(10.0, 0.0, 0.0, 0.0) == (10.0, 0.0)
    assert_allclose(cpa(0.0, 10.0, 1.0, -1.0), (math.sqrt(50.0), 5.0))


# --------------------------------------------------------------------------- sectors


def toward_us(beta_deg, r=100.0, speed=1.0, course_offset_deg=0.0):
    """A target at relative bearing beta (own heads north) steering straight at us (+ an offset)."""
    b = R(beta_deg)
    return tgt(r * math.cos(b), r * math.sin(b), beta_deg + 180.0 + course_offset_deg, speed)


def sit(target, own=OWN, **cfg):
    return classify(geometry(own, target), EncounterConfig(**cfg))[0]


@pytest.mark.parametrize(
    "beta_deg, expect",
    [
        (0.0, Situation.HEAD_ON),
        (5.9, Situation.HEAD_ON),  # within 6 deg of dead ahead, course 5.9 deg off the reciprocal
        (-5.9, Situation.HEAD_ON),
        (6.1, Situation.CROSSING_GIVE_WAY),  # rule 14's "nearly ahead" ends: crossing from starboard
        (-6.1, Situation.CROSSING_STAND_ON),  # ... from port
        (112.4, Situation.CROSSING_GIVE_WAY),  # forward of 22.5 deg abaft the starboard beam
        (112.6, Situation.OVERTAKEN),  # abaft it: it is overtaking us (rule 13(b))
        (-112.4, Situation.CROSSING_STAND_ON),
        (-112.6, Situation.OVERTAKEN),
        (180.0, Situation.OVERTAKEN),
    ],
)
def test_relative_bearing_sector_boundaries(beta_deg, expect):
    assert sit(toward_us(beta_deg)) is expect


@pytest.mark.parametrize(
    "course_deg, expect",
    [
        (185.9, Situation.HEAD_ON),  # dead ahead, 5.9 deg off the reciprocal course
        (174.1, Situation.HEAD_ON),
        (186.1, Situation.CROSSING_GIVE_WAY),  # dead ahead (beta = 0) but crossing: in doubt, we give way
        (173.9, Situation.CROSSING_GIVE_WAY),
    ],
)
def test_head_on_course_boundary(course_deg, expect):
    assert sit(tgt(100, 0, course_deg, 1.0)) is expect


@pytest.mark.parametrize(
    "course_deg, expect",
    [
        (0.0, Situation.OVERTAKING),  # dead ahead on our course: we see its stern, aspect 180 deg
        (67.4, Situation.OVERTAKING),  # we are 112.6 deg from its bow: abaft its beam
        (67.6, Situation.CROSSING_GIVE_WAY),  # 112.4 deg: forward of it, a crossing (beta = 0: give way)
        (-67.4, Situation.OVERTAKING),
        (-67.6, Situation.CROSSING_GIVE_WAY),
    ],
)
def test_overtaking_aspect_boundary(course_deg, expect):
    assert sit(tgt(100, 0, course_deg, 0.5)) is expect


def test_heading_not_course_decides_the_aspect():
    # course 60 (crossing, aspect 120) but heading 70 (aspect 110): the hull is what 'abaft the beam' means
    assert sit(tgt(100, 0, 60.0, 0.5, heading_deg=60.0)) is Situation.OVERTAKING
    assert sit(tgt(100, 0, 60.0, 0.5, heading_deg=70.0)) is Situation.CROSSING_GIVE_WAY


def test_stopped_target_is_passed_as_overtaking():
    assert sit(tgt(50, 30, 270, 0.1)) is Situation.OVERTAKING
    assert sit(tgt(50, -30, 90, 0.1)) is Situation.OVERTAKING


@pytest.mark.parametrize(
    "current, beta_deg, kept",
    [
        (Situation.CROSSING_GIVE_WAY, -4.0, Situation.CROSSING_GIVE_WAY),  # within the 5 deg margin
        (Situation.CROSSING_GIVE_WAY, -8.0, Situation.CROSSING_STAND_ON),  # beyond it (not head-on: 8 > 6)
        (Situation.CROSSING_STAND_ON, 4.0, Situation.CROSSING_STAND_ON),
        (Situation.HEAD_ON, 10.0, Situation.HEAD_ON),  # 6 + 5 deg
        (Situation.HEAD_ON, 12.0, Situation.CROSSING_GIVE_WAY),
        (Situation.OVERTAKEN, 108.0, Situation.OVERTAKEN),  # 112.5 - 5
        (Situation.OVERTAKEN, 106.0, Situation.CROSSING_GIVE_WAY),
    ],
)
def test_sector_hysteresis(current, beta_deg, kept):
    g = geometry(OWN, toward_us(beta_deg))
    assert classify(g, EncounterConfig(), current=current)[0] is kept


# --------------------------------------------------------------------------- the tracker


def test_tracker_enters_on_risk_and_leaves_past_and_clear():
    tr = EncounterTracker()
    # far and safe: 80 m abeam on a parallel course
    (e,) = tr.assess(OWN, [tgt(200, 80, 180, 2.0)], 0.0)
    assert e.situation is Situation.SAFE and "DCPA" in e.reason
    # a head-on target: risk, head-on, and the reason says why
    t_s = 0.0
    own = OWN
    sits = []
    while t_s < 120.0:
        target = tgt(200 - 2.0 * t_s, 2.0, 180, 2.0, tid=7)  # closing at 3 m/s, passing 2 m off
        own = OwnShip(north_m=1.0 * t_s, east_m=0.0, course_rad=0.0, speed_m_s=1.0, heading_rad=0.0)
        (e,) = tr.assess(own, [target], t_s)
        sits.append(e.situation)
        t_s += 1.0
    assert sits[0] is Situation.HEAD_ON and "rule 14" in tr.assess(OWN, [tgt(200, 2, 180, 2.0, tid=8)], 0.0)[0].reason
    changes = [i for i in range(1, len(sits)) if sits[i] is not sits[i - 1]]
    assert len(changes) == 1 and sits[-1] is Situation.SAFE  # one change: head-on -> safe once past
    # it ended when past (CPA at t = 66.7 s) and 4 L clear, not before
    end_t = changes[0]
    assert 66.7 < end_t <= 66.7 + 4 * L / 3.0 + 1.0


def test_overtaking_is_kept_until_past_and_clear_whatever_the_bearing():
    """Rule 13(d): once overtaking, a later change of bearing does not make it a crossing."""
    tr = EncounterTracker()
    (e,) = tr.assess(OWN, [tgt(30, 2, 0, 0.3)], 0.0)
    assert e.situation is Situation.OVERTAKING
    # later the target is on our starboard beam, still closing: the geometry alone says crossing
    own = OwnShip(25.0, 0.0, R(10.0), 1.0, R(10.0))
    target = tgt(30, 8, 300, 0.3)
    assert classify(geometry(own, target))[0] is not Situation.OVERTAKING
    (e,) = tr.assess(own, [target], 20.0)
    assert e.situation is Situation.OVERTAKING and "13(d)" in e.reason


def test_no_flicker_with_noisy_ais_near_a_boundary():
    """A crossing target whose bearing and course jitter by +-3 deg around the head-on boundary (6 deg):
    one situation for the whole approach."""
    rng = random.Random(3)
    tr = EncounterTracker()
    seen = []
    for k in range(60):
        t_s = float(k)
        beta = R(6.0 + rng.uniform(-3, 3))
        r = 150.0 - 2.5 * t_s
        target = tgt(r * math.cos(beta), r * math.sin(beta), 180.0 + 6.0 + rng.uniform(-3, 3), 1.5)
        own = OwnShip(0.0, 0.0, 0.0, 1.0, 0.0)
        (e,) = tr.assess(own, [target], t_s)
        seen.append(e.situation)
    assert len(set(seen)) == 1 and seen[0] is not Situation.SAFE


def test_target_turning_into_us_changes_the_duty():
    """A target from port (we stand on) turns to a reciprocal course dead ahead: it becomes head-on."""
    tr = EncounterTracker()
    (e,) = tr.assess(OWN, [toward_us(-30.0, r=120.0)], 0.0)
    assert e.situation is Situation.CROSSING_STAND_ON
    (e,) = tr.assess(OWN, [tgt(110, -1, 180, 1.0)], 1.0)
    assert e.situation is Situation.HEAD_ON and e.changed


def test_tracker_forgets_absent_targets():
    tr = EncounterTracker(EncounterConfig(forget_after_s=10.0))
    tr.assess(OWN, [tgt(100, 0, 180, 1.0, tid=5)], 0.0)
    assert tr.situation_of(5) is Situation.HEAD_ON
    tr.assess(OWN, [], 11.0)
    assert tr.situation_of(5) is Situation.SAFE


# --------------------------------------------------------------------------- from AIS


def test_target_state_from_ais_dead_reckons_its_age():
    lat0, lon0 = 34.8, 135.5
    lat, lon = local_to_latlon(100.0, -50.0, lat0, lon0)
    t = AisTarget(mmsi=244000001, ais_class="A", last_t_s=10.0, lat_deg=lat, lon_deg=lon, sog_m_s=2.0,
                  cog_rad=R(90.0), heading_rad=R(92.0), position_t_s=10.0, shipname="X", to_bow_m=30.0,
                  to_stern_m=10.0, to_port_m=4.0, to_starboard_m=4.0)
    s = TargetState.from_ais(t, origin_lat_deg=lat0, origin_lon_deg=lon0, now_s=15.0)
    assert_allclose((s.north_m, s.east_m), (100.0, -50.0 + 2.0 * 5.0), atol=0.01)
    assert (s.target_id, s.extent_m, s.length_m, s.name, s.age_s) == (244000001, 30.0, 40.0, "X", 5.0)
    assert_allclose(s.heading_rad, R(92.0))
    # dead reckoning is bounded; unknown speed is 'stopped where reported'
    far = TargetState.from_ais(t, origin_lat_deg=lat0, origin_lon_deg=lon0, now_s=110.0, max_extrapolation_s=30.0)
    assert_allclose(far.east_m, -50.0 + 60.0, atol=0.01)
    blind = TargetState.from_ais(AisTarget(mmsi=1, ais_class="B", last_t_s=0.0, lat_deg=lat, lon_deg=lon,
                                           position_t_s=0.0), origin_lat_deg=lat0, origin_lon_deg=lon0, now_s=9.0)
    assert blind.speed_m_s == 0.0 and not blind.motion_known
    assert_allclose((blind.north_m, blind.east_m), (100.0, -50.0), atol=0.01)


def test_a_target_alongside_inside_the_safe_distance_is_a_risk_not_past():
    """Found by review: a boat 2 m abeam on our course and speed (a chase boat), or one first reported already
    beside us and opening, was 'no risk: CPA past, range 2 m opening' for as long as it stayed there. The
    module's own rule says past targets are safe only opening beyond clear_range_m."""
    cfg = EncounterConfig()
    tr = EncounterTracker(cfg)
    (beside,) = tr.assess(OWN, [tgt(0.0, 2.0, 0.0, 1.0, tid=3)], 0.0)  # no relative motion: TCPA 0
    assert beside.risk_exists and beside.situation is not Situation.SAFE
    (opening,) = EncounterTracker(cfg).assess(OWN, [tgt(-3.0, 4.0, 180.0, 1.0, tid=4)], 0.0)  # past, 5 m away
    assert opening.risk_exists and opening.situation is not Situation.SAFE
    (clear,) = EncounterTracker(cfg).assess(OWN, [tgt(-30.0, 4.0, 180.0, 1.0, tid=5)], 0.0)  # past, beyond 4 L
    assert not clear.risk_exists and clear.situation is Situation.SAFE and "CPA past" in clear.reason
    # it ends as any encounter does: past and clear
    t_s, sits = 0.0, []
    while t_s < 30.0:
        (e,) = tr.assess(OWN, [tgt(-2.0 * t_s, 2.0, 180.0, 1.0, tid=3)], t_s)  # the chase boat turns back
        sits.append(e.situation)
        t_s += 1.0
    assert sits[-1] is Situation.SAFE and sits[0] is not Situation.SAFE
