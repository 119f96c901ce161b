"""The hold off a waypoint a moored vessel occupies ends when the vessel is gone: pure (the helm and its targets).

A hold at a waypoint inside a stopped vessel's safe distance is kept on the boat's side of it, where avoidance
lets go (Avoidance.occupying). Found by an operator audit: the hold stayed there after the vessel had gone (its
AIS reports stopped and the target table dropped it, or it sailed off), so the boat never went on to the
waypoint: a final hold sat 26 m short for good. Gone is the vessel reported clear of the waypoint by avoidance's
resume margin; while it is silent, even dropped from the AIS table, the hold stays off (a review: released on
silence, the hold went onto a vessel whose AIS was off; released at the bare safe distance, one report 2 m off
freed a waypoint still occupied, for good). Through the real daemon, AIS on a
pseudo-terminal: tests/test_traffic_occupied_gone.py.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from autopilot.gnc import Autopilot, GncConfig, NavInput
from autopilot.gnc.avoidance import AvoidanceConfig
from autopilot.gnc.encounter import TargetState
from autopilot.logschema import Mode

WAYPOINT = (40.0, 0.0)
EXTENT_M = 5.2
VESSEL = TargetState(target_id=244000902, north_m=40.0, east_m=0.0, course_rad=0.0, speed_m_s=0.0, extent_m=EXTENT_M,
                     name="ON WP")
NEED_M = AvoidanceConfig().safe_distance_m + EXTENT_M
OFF_M = AvoidanceConfig().resume_margin * NEED_M  # the hold off is this far from the vessel, on the boat's side
# the boat 24 m south of the vessel, heading north at 0.5 m/s: as near as the rules let it come
NEAR = NavInput(north_m=16.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.5, yaw_rate_rad_s=0.0, course_rad=0.0)


def _helm(*, final_hold: bool, holds_s=None, waypoints=(WAYPOINT,)) -> Autopilot:
    g = GncConfig()
    if final_hold:
        g = dataclasses.replace(g, guidance=dataclasses.replace(g.guidance, final_action="hold"))
    return Autopilot(g, list(waypoints), holds_s=holds_s)


def _held_off(ap: Autopilot, targets, t_s: float) -> tuple[float, float]:
    out = ap.step(NEAR, 0.1, targets=targets, t_s=t_s)
    return out.hold_target_ne_m


def test_the_final_hold_off_an_occupied_waypoint_goes_to_it_once_the_vessel_is_reported_clear():
    ap = _helm(final_hold=True)
    out = ap.step(NEAR, 0.1, targets=[VESSEL], t_s=0.0)
    assert out.reached_how == "occupied" and ap.mode is Mode.HOLD
    spot = out.hold_target_ne_m
    assert spot == pytest.approx((40.0 - OFF_M, 0.0))  # off, on the boat's side
    for k in range(1, 50):  # silent (still in the AIS table): no proof the point is free, it stays off
        assert _held_off(ap, [VESSEL], 0.1 * k) == spot
    for k in range(50, 60):  # dropped from the table (stale): still no proof
        assert _held_off(ap, [], 0.1 * k) == spot
    # under way, past the safe distance but within the resume margin: not yet
    assert _held_off(ap, [dataclasses.replace(VESSEL, north_m=40.0 + NEED_M + 1.0, speed_m_s=2.0)], 6.0) == spot
    ap.pop_events()
    left = [dataclasses.replace(VESSEL, north_m=40.0 + OFF_M + 1.0, speed_m_s=2.0)]
    assert _held_off(ap, left, 6.1) == WAYPOINT  # the waypoint itself, from this cycle on
    assert _held_off(ap, [], 6.2) == WAYPOINT and ap.mode is Mode.HOLD
    said = [f for name, f in ap.pop_events() if name == "mode"]
    assert len(said) == 1 and said[0]["mode"] == said[0]["from"] == "hold"
    assert said[0]["cause"] == "waypoint 0 free: vessel 244000902 reported clear of it: holding at the waypoint"


def test_ais_jitter_of_a_vessel_still_moored_does_not_free_the_waypoint():
    moored = dataclasses.replace(VESSEL, north_m=40.0 + 19.5)  # the waypoint 1.5 m inside its safe distance
    ap = _helm(final_hold=True)
    boat = dataclasses.replace(NEAR, north_m=moored.north_m - 26.0)
    out = ap.step(boat, 0.1, targets=[moored], t_s=0.0)
    assert out.reached_how == "occupied"
    off = out.hold_target_ne_m
    jitter = dataclasses.replace(moored, north_m=moored.north_m + 2.0)  # one report 2 m farther
    assert ap.step(boat, 0.1, targets=[jitter], t_s=0.1).hold_target_ne_m == off
    for k in range(2, 40):
        out = ap.step(boat, 0.1, targets=[moored], t_s=0.1 * k)
    assert out.hold_target_ne_m == off


def test_a_hold_item_off_an_occupied_waypoint_goes_to_it_when_the_vessel_sails_off_and_the_mission_goes_on():
    ap = _helm(final_hold=False, holds_s=[60.0, None], waypoints=(WAYPOINT, (40.0, 60.0)))
    out = ap.step(NEAR, 0.1, targets=[VESSEL], t_s=0.0)
    assert out.reached_how == "occupied" and out.holding
    assert out.hold_target_ne_m == pytest.approx((40.0 - OFF_M, 0.0))
    gone = [dataclasses.replace(VESSEL, north_m=40.0 + OFF_M + 5.0, speed_m_s=2.0)]
    assert _held_off(ap, gone, 0.1) == WAYPOINT  # the vessel sailed off: the rest of the item is held at the waypoint
    assert ap.auto.item_keeper is not None and ap.mode is Mode.AUTO


def test_an_operator_s_own_hold_there_is_theirs_and_stays():
    ap = _helm(final_hold=True)
    spot = ap.step(NEAR, 0.1, targets=[VESSEL], t_s=0.0).hold_target_ne_m
    assert ap.request("hold", NEAR, cause="ctl hold --heading 10", heading_rad=math.radians(10.0)) == (True, "hold")
    mine = _held_off(ap, [], 0.1)
    assert mine != WAYPOINT and math.hypot(mine[0] - spot[0], mine[1] - spot[1]) < 8.0  # where they said
