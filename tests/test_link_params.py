"""The link's parameter protocol while a set waits for the cycle that applies it.

The link (real UDP on loopback, pymavlink as the ground station) runs against a stand-in for the
daemon's loop that holds each submitted command until the test applies it: the window between a
PARAM_SET's arrival and the cycle that applies it is then as long as the test wants, instead of a
race the end-to-end tests (tests/test_link_mavlink.py) win or lose by chance.
"""

from __future__ import annotations

import asyncio
import socket
import time
from types import SimpleNamespace

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.daemon.commands import replace_key
from autopilot.daemon.config import DaemonConfig
from autopilot.link import params as P
from autopilot.link.config import MavlinkConfig
from autopilot.link.link import MavlinkLink


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class HeldLoop:
    """What the link uses of the daemon's loop; submitted commands wait in ``held``."""

    def __init__(self) -> None:
        self.cfg = DaemonConfig()
        self.held: list = []
        self.events: list = []
        self.log = SimpleNamespace(listeners=[])
        self.state = SimpleNamespace(status=None)
        self.mission = SimpleNamespace(origin_lat_deg=52.0, origin_lon_deg=4.4)
        self.ap = SimpleNamespace(mission_cleared=False)
        self.clock = SimpleNamespace(now_s=time.monotonic)

    def submit(self, request: dict, answer) -> None:
        self.held.append((request, answer))

    def log_event(self, name: str, **fields) -> None:
        self.events.append((name, fields))

    def apply_held(self) -> None:
        for request, answer in self.held:
            assert request["command"] == "param_set"
            self.cfg = replace_key(self.cfg, request["key"], request["value"])
            answer({"ok": True, "answer": "applied"})
        self.held.clear()


def _param_values(gcs, name: str, seconds: float) -> list[float]:
    out, t_end = [], time.monotonic() + seconds
    while time.monotonic() < t_end:
        m = gcs.recv_match(type="PARAM_VALUE", blocking=False)
        if m is None:
            time.sleep(0.005)
        elif m.param_id == name:
            out.append(m.param_value)
    return out


def test_a_list_going_out_does_not_send_the_old_value_after_a_set():
    port = _free_udp_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, source_component=190)
    loop = HeldLoop()
    name = "FS_GCS_ACT"  # late in the list: its entry is still queued when the set arrives
    assert P.PARAMS.index(P.by_name(name)) >= len(P.PARAMS) - 8

    async def scenario() -> tuple[list[float], list[float], float]:
        link = MavlinkLink(MavlinkConfig(endpoints=(f"udpout:127.0.0.1:{port}",)), loop=loop, version="test")
        await link.start()
        try:
            await asyncio.sleep(0.2)  # the link's heartbeats reach the ground station: it knows the address
            gcs.recv_match(type="HEARTBEAT", blocking=False)
            old = P.value_of(loop.cfg, P.by_name(name))
            gcs.mav.param_request_list_send(1, 1)
            gcs.mav.param_set_send(1, 1, name.encode(), 2.0, mavlink.MAV_PARAM_TYPE_REAL32)  # rtl
            await asyncio.sleep(0.5)  # the whole list has gone out (8 a tick, 20 ms a tick); the set is held
            before = await asyncio.to_thread(_param_values, gcs, name, 0.3)
            assert len(loop.held) == 1, loop.held
            loop.apply_held()
            await asyncio.sleep(0.2)
            after = await asyncio.to_thread(_param_values, gcs, name, 0.3)
            return before, after, old
        finally:
            await link.close()

    before, after, old = asyncio.run(scenario())
    assert old == 0.0  # continue
    # the old code sent the list's entry (the old value) while the set waited: before == [0.0]
    assert before == [], f"{name} sent as {before} after its PARAM_SET arrived, before it was applied"
    assert after == [2.0]
    assert loop.cfg.mavlink.gcs_lost_action == "rtl"
