"""A "go here" (hold at a point) asked before control starts, with a geofence: there is no position yet to check
the way there against it. Found by a review of 06e0cae: it was checked as the point alone and placed when control
started without the leg check; inside an L-shaped geofence the go here refused once control had started ("the leg
from the boat to the point leaves the geofence") was taken before it, and the boat station-kept straight across the
corner, out of the fence. Now it is refused until control has started.
"""

from __future__ import annotations

import numpy as np

from autopilot.clock import SimClock
from autopilot.daemon import commands
from autopilot.daemon.config import DaemonConfig
from autopilot.daemon.failsafe import Decision, segment_outside_polygon
from autopilot.daemon.loop import ControlLoop
from autopilot.daemon.missionlog import MissionLog
from autopilot.daemon.sd_notify import Notifier
from autopilot.daemon.state import StateStore
from autopilot.gnc import Autopilot, NavInput
from autopilot.gnc.modes import PendingHold
from autopilot.mission import Mission
from tests.test_daemon_cycle import ORIGIN, FakeCompass, FakeThrusters

FENCE = ((-10.0, -10.0), (60.0, -10.0), (60.0, 10.0), (10.0, 10.0), (10.0, 60.0), (-10.0, 60.0))
BOAT = NavInput(north_m=50.0, east_m=0.0, psi_rad=0.0, speed_m_s=0.0, yaw_rate_rad_s=0.0, course_rad=0.0)
ACROSS = (-5.0, 40.0)  # inside the fence, in the east arm: the straight way from BOAT cuts the corner


def _loop(tmp_path, name):
    cfg = DaemonConfig()
    mission = Mission("up", np.array([(50.0, 0.0), (0.0, 0.0)]), (None, None), None, *ORIGIN)
    ap = Autopilot(cfg.gnc, mission.waypoints_ne_m)
    return ControlLoop(cfg, clock=SimClock(), autopilot=ap, mission=mission, mission_path="m.yaml",
                       mission_sha256="x", compass=FakeCompass(SimClock()), thrusters=FakeThrusters(),
                       log=MissionLog(tmp_path / f"{name}.jsonl", console=None), notifier=Notifier(None),
                       store=StateStore(tmp_path / name), fence_ne_m=FENCE)


def test_a_go_here_across_a_concave_fence_is_refused_after_the_start_and_before_it(tmp_path):
    request = {"command": "hold", "source": "mavlink", "cause": "mavlink reposition", "north_m": ACROSS[0],
               "east_m": ACROSS[1]}
    after = _loop(tmp_path, "after")
    after.ap.step(BOAT, 0.1)  # control has started, the boat at BOAT
    running = Decision(mode="auto", thrust_allowed=True, active=())
    reply = commands.apply(after, dict(request), BOAT, "", running, 0.0)
    assert not reply["ok"] and "leaves the geofence" in reply["answer"], reply

    before = _loop(tmp_path, "before")
    waiting = Decision(mode="waiting", thrust_allowed=False, active=())
    reply = commands.apply(before, dict(request), None, "position stale", waiting, 0.0)
    assert not reply["ok"] and "no position yet to check the way there against the geofence" in reply["answer"], reply
    assert not isinstance(before.ap.current, PendingHold) and before.ap.current is before.ap.auto
    out = before.ap.step(BOAT, 0.1)  # control starts with the boat where it was: the mission, not across the fence
    assert out.hold_target_ne_m is None and segment_outside_polygon((BOAT.north_m, BOAT.east_m), (0.0, 0.0), FENCE) is None
    # a plain hold before the start is still taken (no point given: where the boat is when control starts)
    plain = _loop(tmp_path, "plain")
    reply = commands.apply(plain, {"command": "hold", "source": "ctl", "cause": "ctl hold"}, None, "position stale",
                           waiting, 0.0)
    assert reply["ok"] and isinstance(plain.ap.current, PendingHold), reply
