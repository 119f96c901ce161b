"""`autopilot ctl hold` before control starts, through the real daemon over pseudo-terminals.

The daemon is a subprocess without --sim, as on the boat (tests/test_failsafe_faults.py's rig, clock 10x),
its simulated SC-30 sending headings but no position until the test lets it. Found by an operator audit:
a hold asked for before the first fix was refused ("hold refused: position stale") and, once control
started, the boat went off on the mission; asked for after it, `ctl status` said "mode: waiting (helm:
hold) (planner: INITIALISING)". The pure part: tests/test_modes_before_start.py.
"""

from __future__ import annotations

import asyncio
import math
from functools import partial

from autopilot.drivers.sc30_output import default_sentences
from tests.test_failsafe_faults import Daemon as FaultRigDaemon
from tests.test_failsafe_faults import square_mission

Daemon = partial(FaultRigDaemon, injects_link_faults=False)
BAUD = 4800
NO_POSITION = ("ROT", "ZDA")  # the compass's slow sentences without the position ones: no fix yet


def _cycles(d) -> list[dict]:
    return [r for r in d.log() if r["event"] == "cycle"]


def test_a_hold_asked_for_before_the_first_fix_is_taken_shown_and_held_where_control_starts(tmp_path):
    async def scenario():
        d = Daemon(tmp_path, square_mission(side_m=25.0), rig_options={"sc30_options": {"slow_sentences": NO_POSITION}})
        try:
            await d.start()
            await d.wait(lambda: len(_cycles(d)) >= 10, 30.0, "the daemon cycling")
            assert {c["mode"] for c in _cycles(d)} == {"waiting"} and _cycles(d)[-1]["lat_deg"] is None  # no fix

            code, text = await d.ctl("hold")
            assert (code, text) == (0, "hold (waiting for valid data before control starts; it holds where the boat "
                                       "is when control starts)"), text
            code, text = await d.ctl("status")
            assert code == 0 and text.splitlines()[0] == (
                "mode: hold (planner: LOITER) - ctl hold - control has not started (waiting for valid data)"), text
            await d.clock.sleep(3.0)
            assert {c["mode"] for c in _cycles(d)} == {"waiting"} and not d.rig.mbed.thrusting  # still no fix

            d.rig.sc30.slow_sentences = default_sentences(BAUD)[1]  # the fixes come
            await d.wait(lambda: _cycles(d)[-1]["mode"] != "waiting", 30.0, "control starting")
            await d.clock.sleep(20.0)
            held = [c for c in _cycles(d) if c["mode"] != "waiting"]
            assert {c["mode"] for c in held} == {"hold"}  # never the mission
            launch = d.events("launch")[0]
            first = held[0]
            # the point is where control started (the boat at rest), not the mission's first waypoint 25 m north
            assert math.hypot(first["hold_north_m"] - launch["north_m"], first["hold_east_m"] - launch["east_m"]) < 1.0
            n, e = float(d.rig.boat.state[0]), float(d.rig.boat.state[1])
            assert math.hypot(n - first["hold_north_m"], e - first["hold_east_m"]) < 2.0
            assert not d.events("waypoint_reached")
            assert [(r["from"], r["mode"], r["cause"]) for r in d.events("mode")] == [("auto", "hold", "ctl hold")]
            code, text = await d.ctl("status")
            assert text.splitlines()[0] == "mode: hold (planner: LOITER) - ctl hold", text  # driving now
            d.proc.send_signal(2)
            assert await d.finish(30.0) == 0
        finally:
            await d.close()

    asyncio.run(scenario())
