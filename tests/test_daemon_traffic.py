"""AIS traffic through the real daemon (issue 18): simulated vessels as AIS sentences on a pseudo-terminal,
the real decoder, the avoidance in the loop, the log, and the MAVLink link forwarding the targets."""

from __future__ import annotations

import asyncio
import json
import math
import signal
import socket
import subprocess
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import yaml
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autopilot.geo import local_to_latlon
from autopilot.gnc.avoidance import AvoidanceConfig
from autopilot.simdev.traffic import encode_ais
from tests.logtail import LogTail
from tests.test_failsafe_faults import ORIGIN
from tests.test_failsafe_faults import Daemon as FaultRigDaemon

# these tests inject no heading or acknowledgement fault: those watchdogs at margins the loaded machine keeps
Daemon = partial(FaultRigDaemon, injects_link_faults=False)

ROOT = Path(__file__).resolve().parents[1]
HEAD_ON_MMSI = 244000101


def _log(d: Path) -> list[dict]:
    (path,) = list(d.glob("mission-*.jsonl"))
    return [json.loads(x) for x in path.read_text().splitlines()]


@pytest.fixture(scope="module")
def head_on(tmp_path_factory):
    """A lockstep --sim run of the head-on scenario, with a MAVLink ground station socket listening."""
    tmp = tmp_path_factory.mktemp("traffic")
    cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
    cfg["sim"]["traffic"] = "head-on"
    (tmp / "c.yaml").write_text(yaml.safe_dump(cfg))
    (tmp / "m.yaml").write_text(yaml.safe_dump({"name": "north300", "frame": "local", "waypoints": [[300.0, 0.0]]}))
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    with open(tmp / "stderr.txt", "w") as err:
        p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--sim", "--speedup", "max", "--config",
                              str(tmp / "c.yaml"), "--mission", str(tmp / "m.yaml"), "--log-dir", str(tmp / "logs"),
                              "--state-dir", str(tmp / "state"), "--runtime-dir", str(tmp / "run"), "--fresh",
                              "--mavlink", f"udpout:127.0.0.1:{gcs.getsockname()[1]}"], stderr=err)
        # with a ground station link the daemon stays up after the mission's stop, for the ground station
        tail, deadline = LogTail(tmp / "logs"), time.monotonic() + 300.0
        while p.poll() is None and time.monotonic() < deadline and not any(
                r.get("message") == "mission complete: staying up" for r in tail.lines(p.pid)):
            time.sleep(0.1)
        p.send_signal(signal.SIGTERM)
        p.wait(60)
    assert p.returncode == 0, (tmp / "stderr.txt").read_text()[-2000:]
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    gcs.setblocking(False)
    msgs = []
    while True:
        try:
            data = gcs.recv(65536)
        except BlockingIOError:
            break
        msgs += mav.parse_buffer(data) or []
    gcs.close()
    return _log(tmp / "logs"), msgs, tmp / "logs"


def test_the_boat_gives_way_to_starboard_and_keeps_its_distance(head_on):
    log, _, log_dir = head_on
    enc = [r for r in log if r["event"] == "encounter" and r["target"] == HEAD_ON_MMSI]
    assert enc[0]["situation"] == "head-on" and enc[0]["acting"] and enc[0]["rule"] == "14"
    assert enc[-1]["situation"] == "safe"
    cycles = [r for r in log if r["event"] == "cycle"]
    active = [c for c in cycles if c["avoid_active"]]
    assert len(active) > 100 and min(c["avoid_psi_share_deg"] for c in active) > 0.0  # to starboard only
    assert [r["wp_count"] for r in log if r["event"] == "mission_complete"] == [1]  # the mission went on to its waypoint
    assert log[-1]["reason"] == "signal" and any(r.get("message") == "mission complete: staying up" for r in log)
    from autopilot.review.metrics import score
    from autopilot.review.reader import read_log

    card = score(read_log(next(log_dir.glob("mission-*.jsonl"))))  # the review: finished, stopped after it
    assert card.finished and dict(card.table_rows())["stop"] == "mission complete; then stopped by SIGTERM"
    # the closest approach from what the log recorded: own fixes against the target's reported track
    tgt = [r for r in log if r["event"] == "target" and r["target"] == HEAD_ON_MMSI]
    assert len(tgt) > 10
    tt = np.array([r["t_s"] - r["age_s"] for r in tgt])
    tn, te = np.array([r["north_m"] for r in tgt]), np.array([r["east_m"] for r in tgt])
    tc, ts = np.radians([r["course_deg"] for r in tgt]), np.array([r["speed_m_s"] for r in tgt])
    fixes, last = [], None  # each fix once, at the time it was measured (held on the cycles after it)
    for c in cycles:
        if c["north_m"] is not None and c["position_age_s"] is not None:
            when = round(c["t_s"] - c["position_age_s"], 6)
            if when != last:
                fixes.append((when, c["north_m"], c["east_m"]))
                last = when
    assert len(fixes) > 50
    dist = []
    for t, n, e in fixes:
        k = int(np.searchsorted(tt, t)) - 1
        if k < 0:
            continue
        dt = t - tt[k]  # the target dead-reckoned from its last report, as the daemon sees it
        dist.append(math.hypot(tn[k] + ts[k] * math.cos(tc[k]) * dt - n, te[k] + ts[k] * math.sin(tc[k]) * dt - e))
    length = next(r["length_m"] for r in tgt if r["length_m"])
    assert min(dist) >= AvoidanceConfig().safe_distance_m + length / 2 - 1.0, min(dist)


def test_the_targets_reach_the_ground_station_as_ais_vessel(head_on):
    _, msgs, _ = head_on
    ais = [m for m in msgs if m.get_type() == "AIS_VESSEL"]
    assert ais and {m.MMSI for m in ais} == {HEAD_ON_MMSI}
    m = ais[-1]
    assert m.name == "FERRY ONE" and m.flags & mavlink.AIS_FLAGS_VALID_VELOCITY and m.velocity > 0


def test_a_sim_run_with_a_real_ais_port_and_no_simulated_traffic_flies_and_stops_on_sigterm(tmp_path):
    """Found by an AIS audit: `--sim --speedup max` with ais.port set (a receiver plugged in on the bench) and no
    sim.traffic: the lockstep clock's quiet check asked the simulated traffic that was not there, the clock's task
    died without a word at t = 0, and SIGTERM was ignored (the stop waited on that clock): kill -9 after 10 s."""
    import signal
    import time

    from autopilot.simdev import PtyEndpoint

    ais = PtyEndpoint(tmp_path, "ais")  # a receiver that says nothing
    try:
        cfg = yaml.safe_load((ROOT / "config" / "autopilot.yaml").read_text())
        cfg["ais"]["port"] = ais.path
        (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
        (tmp_path / "m.yaml").write_text(yaml.safe_dump({"name": "far", "frame": "local",
                                                           "waypoints": [[400.0, 0.0]]}))
        proc = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--sim", "--speedup", "max", "--config",
                                 str(tmp_path / "c.yaml"), "--mission", str(tmp_path / "m.yaml"), "--log-dir",
                                 str(tmp_path / "logs"), "--state-dir", str(tmp_path / "state"), "--runtime-dir",
                                 str(tmp_path / "run"), "--fresh"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            t_end = time.monotonic() + 60.0
            flown = 0.0
            while time.monotonic() < t_end and flown < 30.0:
                time.sleep(0.5)
                paths = list((tmp_path / "logs").glob("mission-*.jsonl"))
                lines = paths[0].read_text().splitlines() if paths else []
                flown = max((json.loads(x)["t_s"] for x in lines[-20:] if x.endswith("}")), default=0.0)
            proc.send_signal(signal.SIGTERM)
            err = proc.communicate(timeout=30)[1].decode()
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    finally:
        ais.close()
    assert flown >= 30.0  # simulated time went on
    assert proc.returncode == 0, err[-2000:]
    log = _log(tmp_path / "logs")
    assert log[-1]["event"] == "stop" and log[-1]["reason"] == "signal"
    assert any(r["event"] == "cycle" and r["thrust_port_n"] > 0 for r in log)
    assert not [r for r in log if r.get("message", "").startswith("lockstep: the devices' quiet check failed")]


def test_ais_interleaved_on_the_compass_line_is_seen(tmp_path):
    """ais.on_compass_line: !AIVDM among the SC-30's sentences, at its 4800 baud, reaches the avoidance."""
    lat, lon = local_to_latlon(120.0, 40.0, *ORIGIN)
    lines = encode_ais({"msg_type": 1, "mmsi": 211000777, "lat": lat, "lon": lon, "speed": 3.0, "course": 270.0,
                        "heading": 270, "status": 0})

    async def scenario():
        d = Daemon(tmp_path, {"name": "n", "frame": "local", "waypoints": [[40.0, 0.0]]},
                   config={"ais": {"on_compass_line": True}})
        try:
            await d.start()
            await d.steady_thrust(1.0)
            for _ in range(3):
                d.rig.sc30.inject(("\r\n".join(lines) + "\r\n").encode())
                await d.clock.sleep(2.0)
            await d.wait(lambda: any(r["event"] == "target" and r["target"] == 211000777 for r in d.log()), 10.0,
                         "the target logged")
            await d.wait(lambda: any(r["event"] == "cycle" and (r["avoid_targets"] or 0) >= 1 for r in d.log()), 5.0,
                         "the avoidance sees it")
            d.proc.send_signal(2)
            assert await d.finish(30.0) == 0
        finally:
            await d.close()
        return d

    d = asyncio.run(scenario())
    # the line's share is said at the start (an AIS audit: 5 moored vessels at 4800 baud tripped heading_stale)
    said = [r["message"] for r in d.log() if r["event"] == "info" and r["message"].startswith("ais.on_compass_line")]
    assert said and "take 434 of the 480 characters a second at 4800 baud, leaving 46 for AIS" in said[0]


def test_the_lockstep_quiet_check_never_raises_and_says_its_failure_once():
    """The wrapper behind the fix above: any check that raises is taken as quiet (time goes on), said once."""
    import types

    from autopilot.daemon.app import _quiet_check

    said = []
    log = types.SimpleNamespace(event=lambda name, **f: said.append((name, f)))
    clock = types.SimpleNamespace(now_s=lambda: 12.5)

    def broken():
        raise AttributeError("'NoneType' object has no attribute 'quiet'")

    check = _quiet_check(log, clock, 2.5, broken)
    assert check() is True and check() is True
    assert len(said) == 1 and said[0][1]["t_s"] == 10.0
    assert "AttributeError" in said[0][1]["error"] and said[0][1]["message"].startswith("lockstep:")
    assert _quiet_check(log, clock, 2.5, lambda: False)() is False
