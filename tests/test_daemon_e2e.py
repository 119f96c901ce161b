"""End to end: `autopilot run --sim --speedup 20` flies each pond mission through the pseudo-terminals.

The daemon runs as a subprocess exactly as a user starts it; its simulated SC-30 and Mbed sit
behind real pseudo-terminals in the same process. The log is checked against docs/log-schema.md.
"""

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

from autopilot.logschema import CYCLE_KEYS
from autopilot.review.export import GPX_NS, write_gpx
from autopilot.review.metrics import score
from autopilot.review.reader import read_log as review_read_log

from .logtail import LogTail

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "autopilot.yaml"
MISSIONS = sorted((ROOT / "config" / "missions").glob("pond-9.*.yaml"))
SPEEDUP = 20


def read_log(log_dir: Path) -> list[dict]:
    (path,) = list(log_dir.glob("mission-*.jsonl"))
    return [json.loads(line) for line in path.read_text().splitlines()]


def start(mission: Path, tmp_path: Path, *extra: str) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission", str(mission),
           "--sim", "--speedup", str(SPEEDUP), "--log-dir", str(tmp_path / "logs"), "--state-dir", str(tmp_path / "state"), *extra]
    return subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
@pytest.mark.parametrize("mission", MISSIONS, ids=[m.stem for m in MISSIONS])
def test_pond_mission_runs_to_completion_with_a_complete_log(mission, tmp_path):
    assert MISSIONS, "config/missions/pond-9.*.yaml missing"
    p = start(mission, tmp_path)
    out, err = p.communicate(timeout=180)
    assert p.returncode == 0, err[-3000:]
    log = read_log(tmp_path / "logs")
    assert all({"timestamp", "event", "t_s"} <= rec.keys() for rec in log)
    assert all(rec["timestamp"].endswith("Z") for rec in log)
    assert log[0]["event"] == "mission_start" and log[-1]["event"] == "stop"
    start_rec = log[0]
    n_wp = len(start_rec["waypoints"])
    assert start_rec["sim"] is True and start_rec["speedup"] == SPEEDUP and start_rec["rate_hz"] == 10.0

    cycles = [r for r in log if r["event"] == "cycle"]
    keys = CYCLE_KEYS
    for rec in cycles:
        assert set(rec) == {"timestamp", "event", "t_s", *keys}, (rec["cycle"], set(rec) ^ {"timestamp", "event", "t_s", *keys})
    # a cycle line for every cycle: consecutive counters, one per period (skipped deadlines counted)
    assert [c["cycle"] for c in cycles] == list(range(len(cycles)))
    stop = log[-1]
    assert stop["reason"] == "complete" and stop["ack_received"] is True
    assert stop["cycles"] == len(cycles)
    period_s = 0.1
    # deadlines are exactly one period apart, except where skipped deadlines are counted
    assert all(0 <= c["lateness_ms"] < 1e3 * period_s for c in cycles)
    deadlines = np.array([c["t_s"] - c["lateness_ms"] / 1e3 for c in cycles])
    steps = np.diff(deadlines) / period_s
    skipped = np.diff([c["skipped_cycles"] for c in cycles])
    np.testing.assert_allclose(steps, 1 + skipped, atol=1e-6)
    assert stop["skipped_cycles"] == cycles[-1]["skipped_cycles"]

    reached = [r["wp_index"] for r in log if r["event"] == "waypoint_reached"]
    assert reached == list(range(n_wp))
    done = [r for r in log if r["event"] == "mission_complete"]
    assert len(done) == 1 and done[0]["wp_count"] == n_wp
    # one closest approach per waypoint, over its whole pass (autopilot.gnc.passes); the review
    # recomputes the same figures from the logged fixes (how close is the GNC's business)
    passes = {r["wp_index"]: r for r in log if r["event"] == "waypoint_pass"}
    assert sorted(passes) == list(range(n_wp))
    logged = [passes[i]["closest_approach_m"] for i in range(n_wp)]
    assert stop["closest_approach_m"] == logged and all(0 <= d < 20.0 for d in logged)
    (path,) = list((tmp_path / "logs").glob("mission-*.jsonl"))
    card = score(review_read_log(path))
    np.testing.assert_allclose([w.closest_approach_m for w in card.waypoints], logged, atol=1e-9)
    np.testing.assert_allclose([w.logged_closest_approach_m for w in card.waypoints], logged, atol=1e-9)
    reached_events = [r for r in log if r["event"] == "waypoint_reached"]
    assert all(r["how"] in ("capture", "passed") and r["distance_m"] >= 0 for r in reached_events)
    # the exports hold each 1 Hz fix once, at the time it was measured (they repeated every held fix
    # on each 10 Hz cycle, stamped with the cycle time: 352 GPX points for 71 distinct positions)
    fixes = sorted({round(c["t_s"] - c["position_age_s"], 6) for c in cycles
                    if c["north_m"] is not None and c["position_age_s"] is not None})
    gpx = ET.parse(write_gpx(review_read_log(path), tmp_path / "track.gpx")).getroot()
    pts = gpx.findall(f".//{{{GPX_NS}}}trkpt")
    flown_s = cycles[-1]["t_s"] - cycles[0]["t_s"]  # not len(cycles) / 10: a loaded machine skips cycles
    assert len(pts) == len(fixes) and 0.8 * flown_s <= len(fixes) <= 1.2 * flown_s + 1
    # what the person at the terminal is told at the end
    assert f"log: {path}" in err and f"{n_wp} of {n_wp} waypoint(s) reached" in err and "W0: reached" in err
    # steered cycles carry the GNC terms, and the fuzzy guidance's CDH
    auto = [c for c in cycles if c["mode"] == "auto"]
    assert len(auto) > 50
    assert all(c["psi_d_deg"] is not None and c["cdh"] is not None and c["seq"] >= 0 for c in auto)
    assert all(0 <= c["heading_deg"] < 360 and c["heading_source"] in ("HDT", "THS", "PFEC_GPatt", "PFEC") for c in auto)
    # no fault in a clean run; on a machine too slow for the speedup (the loop skipped deadlines, as the
    # log and the summary say) the Mbed's acks can time out on the accelerated clock: that fault only
    faults = [r for r in log if r["event"] in ("failsafe", "fault")]
    if stop["skipped_cycles"] > 0:
        faults = [r for r in faults if r["cause"] != "mbed_ack_missing"]
    assert not faults
    assert cycles[-1]["mode"] == "complete"
    assert cycles[-1]["pwm_port_pct"] == 0.0 and cycles[-1]["pwm_stbd_pct"] == 0.0
    state = json.loads((tmp_path / "state" / "mission-progress.json").read_text())
    assert state["status"] == "complete"


def _wait_for(predicate, log_dir: Path, proc: subprocess.Popen, limit_s: float = 60.0):
    """Poll the log (a subprocess is not on our clock) until predicate(records) holds."""
    tail = LogTail(log_dir)
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()[-3000:]
        recs = tail.lines(proc.pid)
        if recs and predicate(recs):
            return recs
        time.sleep(0.05)
    raise AssertionError("daemon never reached the awaited state")


@pytest.mark.slow
def test_a_port_that_does_not_exist_is_retried_and_the_user_is_told(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("origin_lat_deg: 52.0\norigin_lon_deg: 4.4\nserial:\n  sc30_port: /dev/nonexistent-sc30\n"
                   "  mbed_port: /dev/nonexistent-mbed\n")
    mission = ROOT / "config" / "missions" / "pond-9.1.yaml"
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", str(cfg), "--mission", str(mission),
                          "--log-dir", str(tmp_path / "logs"), "--state-dir", str(tmp_path / "state")],
                         cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for(lambda recs: sum(r["event"] == "cycle" for r in recs) >= 10, tmp_path / "logs", p)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 0
    told = [ln for ln in err.splitlines() if ln.startswith("autopilot run: sc30: cannot open /dev/nonexistent-sc30")]
    assert len(told) == 1 and "retried every" in told[0] and "Ctrl-C" in told[0]  # once, not per retry
    assert any(ln.startswith("autopilot run: mbed: cannot open /dev/nonexistent-mbed") for ln in err.splitlines())


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_signal_stops_with_zero_thrust_acknowledged_and_exit_0(signame, tmp_path):
    mission = ROOT / "config" / "missions" / "pond-9.4.yaml"
    p = start(mission, tmp_path)
    _wait_for(lambda recs: sum(r["event"] == "cycle" and r["mode"] == "auto" for r in recs) >= 30, tmp_path / "logs", p)
    p.send_signal(getattr(signal, signame))
    p.communicate(timeout=30)
    assert p.returncode == 0
    log = read_log(tmp_path / "logs")
    stop = log[-1]
    assert stop["event"] == "stop" and stop["reason"] == "signal" and stop["signal"] == signame
    assert stop["ack_received"] is True
    assert not [r for r in log if r["event"] == "mission_complete"]
    # stopped by the operator: not resumed by a later start
    assert json.loads((tmp_path / "state" / "mission-progress.json").read_text())["status"] == "stopped"


@pytest.mark.slow
def test_a_run_stopped_after_its_route_is_reviewed_as_the_daemon_ends_it(tmp_path):
    """Left in stop 42's note (a new-user audit): the daemon ends a run stopped by SIGTERM after its route (on the
    way home, in the hold that ends it) "route complete ...; then in MODE, stopped by SIGTERM", and the review of
    its log said "signal, mission complete". The review now says what the daemon said, and its summary.json says
    the run did not finish."""
    mission = tmp_path / "out-and-home.yaml"
    mission.write_text("name: out-and-home\nframe: local\nwaypoints:\n  - {north_m: 20.0, east_m: 20.0}\n  - rtl\n")
    p = start(mission, tmp_path, "--speedup", "max")
    _wait_for(lambda recs: any(r["event"] == "mission_complete" for r in recs)
                     and sum(r["event"] == "cycle" for r in recs) > 50 + next(
                         k for k, r in enumerate(x for x in recs if x["event"] in ("cycle", "mission_complete"))
                         if r["event"] == "mission_complete"), tmp_path / "logs", p)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 0
    said = next(ln for ln in err.splitlines() if "route complete" in ln)
    assert "stopped by SIGTERM" in said
    (path,) = (tmp_path / "logs").glob("mission-*.jsonl")
    card = score(review_read_log(path))
    assert card.complete and not card.finished and card.stop_signal == "SIGTERM"
    assert card.end_mode in ("rtl", "hold")
    row = dict(card.table_rows())["stop"]
    assert row == f"route complete; then in {card.end_mode}, stopped by SIGTERM"
    assert f"then in {card.end_mode}, stopped by SIGTERM" in said  # the daemon's words


def _under_systemd(tmp_path: Path, final_action: str, max_mission_time_s: float, until):
    """A run at --speedup max with NOTIFY_SOCKET set (so it stays up after its mission, as under systemd), a mission
    12 m out, SIGTERM once ``until(records)``: (its standard error, its log's path)."""
    import socket

    notify = tmp_path / "notify"
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(str(notify))
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg.setdefault("gnc", {}).setdefault("guidance", {})["final_action"] = final_action
    cfg.setdefault("failsafe", {})["max_mission_time_s"] = max_mission_time_s
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    mission = tmp_path / "out.yaml"
    mission.write_text("name: out\nframe: local\nwaypoints:\n  - {north_m: 12.0, east_m: 0.0}\n")
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", str(tmp_path / "c.yaml"), "--mission",
                          str(mission), "--sim", "--speedup", "max", "--log-dir", str(tmp_path / "logs"),
                          "--state-dir", str(tmp_path / "state")], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=dict(os.environ, NOTIFY_SOCKET=str(notify)))
    try:
        _wait_for(until, tmp_path / "logs", p, limit_s=120.0)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=30)
    finally:
        srv.close()
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err[-2000:]
    (path,) = (tmp_path / "logs").glob("mission-*.jsonl")
    return err, path


@pytest.mark.slow
def test_a_final_hold_the_time_limit_stopped_is_said_by_the_daemon_and_the_review_alike(tmp_path):
    """A review audit: a daemon that stayed up (systemd) after max_mission_time stopped its final hold, then got a
    SIGTERM, said "route complete; then in stop, stopped by SIGTERM", the hold before the stop unsaid."""
    err, path = _under_systemd(tmp_path, "hold", 60.0, lambda recs: any(
        r.get("message") == "max_mission_time: stopped, staying up" for r in recs))
    said = next(ln for ln in err.splitlines() if "route complete" in ln)
    held = re.search(r"; then in hold for (\d+) s until max_mission_time stopped it; stopped by SIGTERM", said)
    assert held and 20 <= int(held.group(1)) <= 60, said  # the hold from the waypoint (reached in ~10-30 s) to 60 s
    card = score(review_read_log(path))
    assert dict(card.table_rows())["stop"] == f"route complete; {held.group(0)[2:]}"  # the daemon's words


@pytest.mark.slow
def test_a_mission_ended_with_stop_is_not_stopped_again_by_the_time_limit(tmp_path):
    """A review of 2026-12-06: staying up after its mission's stop (systemd), the daemon tripped max_mission_time at
    zero thrust, saved the finished run aborted, and the next start held the boat for it."""
    err, path = _under_systemd(tmp_path, "stop", 40.0, lambda recs: any(
        r.get("message") == "mission complete: staying up" for r in recs) and recs[-1]["t_s"] > 50.0)
    recs = read_log(tmp_path / "logs")
    assert not [r for r in recs if r["event"] in ("fault", "failsafe")], [r for r in recs if r["event"] == "fault"]
    assert "mission complete after" in err and "then stopped by SIGTERM" in err, err[-2000:]
    saved = json.loads((tmp_path / "state" / "mission-progress.json").read_text())
    assert saved["status"] == "stopped", saved  # a run that finished: the next start is a new one


@pytest.mark.slow
def test_a_run_stopped_in_its_last_waypoints_hold_item_is_not_complete(tmp_path):
    """An operator audit: the last waypoint's hold item (station-keep: 300 s) began and the daemon logged
    mission_complete and `ctl status` said "complete", the boat holding there under thrust. The item is part of
    the mission: stopped in it, the run is not complete, for the daemon and the review alike."""
    p = start(ROOT / "config" / "missions" / "station-keep.yaml", tmp_path, "--speedup", "max")
    recs = _wait_for(lambda recs: sum(r["event"] == "cycle" and r["holding"] for r in recs) > 100,
                     tmp_path / "logs", p)
    assert not any(r["event"] == "mission_complete" for r in recs)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 0
    said = next(ln for ln in err.splitlines() if "waypoint(s) reached" in ln)
    assert said.startswith("autopilot run: mission not complete after") and "stopped by SIGTERM" in said, said
    (path,) = (tmp_path / "logs").glob("mission-*.jsonl")
    card = score(review_read_log(path))
    assert not card.complete and not card.finished and card.stop_signal == "SIGTERM"


@pytest.mark.slow
def test_the_flying_daemon_does_not_carry_the_review_and_identification_libraries(tmp_path):
    """The boat's PC runs the daemon for hours: scipy, matplotlib and dask are the review's, the
    identification's and the campaigns' (`autopilot` built every command's parser at start, and the
    campaign package's imports pulled the identification and scipy into the daemon: 67 MB instead of
    ~45 MB). Read from the running process's own memory map (their compiled modules)."""
    p = start(ROOT / "config" / "missions" / "pond-9.4.yaml", tmp_path)
    try:
        _wait_for(lambda recs: sum(r["event"] == "cycle" and r["mode"] == "auto" for r in recs) >= 10,
                  tmp_path / "logs", p)
        maps = Path(f"/proc/{p.pid}/maps").read_text()
    finally:
        p.send_signal(signal.SIGTERM)
        p.communicate(timeout=30)
    assert "/numpy/" in maps  # the map is the daemon's own (its model and GNC use numpy)
    for lib in ("scipy", "matplotlib", "pandas", "pyarrow"):
        assert f"/{lib}/" not in maps, f"the daemon loaded {lib}"


@pytest.mark.slow
def test_sd_notify_ready_watchdog_stopping_from_a_real_run(tmp_path):
    import socket

    path = str(tmp_path / "notify")
    srv = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    srv.bind(path)
    env = dict(os.environ, NOTIFY_SOCKET=path)
    mission = ROOT / "config" / "missions" / "pond-9.3.yaml"
    cmd = [sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission", str(mission), "--sim",
           "--speedup", str(SPEEDUP), "--log-dir", str(tmp_path / "logs"), "--state-dir", str(tmp_path / "state")]
    p = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    # under systemd the daemon stays up after the mission's stop (a new-user audit: it ended, and systemd's
    # Restart=on-failure does not restart an exit 0, so nothing could command the boat); the operator stops it
    _wait_for(lambda recs: any(r.get("message") == "mission complete: staying up" for r in recs), tmp_path / "logs", p,
              limit_s=180.0)
    assert any(r.get("why") == "systemd runs the daemon" for r in read_log(tmp_path / "logs"))
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 0, err[-2000:]
    srv.setblocking(False)
    msgs = []
    while True:
        try:
            msgs.append(srv.recv(4096).decode())
        except BlockingIOError:
            break
    srv.close()
    kinds = [m.split("\n")[0] for m in msgs]
    assert kinds.count("READY=1") == 1
    assert kinds[-1] == "STOPPING=1"
    assert kinds.index("READY=1") < kinds.index("WATCHDOG=1")  # no watchdog before the devices answer
    assert kinds.count("WATCHDOG=1") >= 3
    log = read_log(tmp_path / "logs")
    assert any(r.get("message") == "ready: SC-30 and Mbed answer" for r in log)


WALL_FIELDS = {"timestamp", "pid", "sc30_port", "mbed_port", "path", "speedup_held"}  # differ between two runs by nature


@pytest.mark.slow
def test_lockstep_runs_give_the_same_log_and_run_faster_than_real_time(tmp_path):
    """--sim --speedup max: the daemon and the simulated devices on one simulated clock, time moving only
    when every byte on the pseudo-terminals is delivered: two runs give the same log line for line."""
    mission = ROOT / "config" / "missions" / "pond-9.4.yaml"
    logs = []
    for k in range(2):
        d = tmp_path / f"run{k}"
        t0 = time.monotonic()
        p = subprocess.run(
            [sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission", str(mission), "--sim",
             "--speedup", "max", "--log-dir", str(d / "logs"), "--state-dir", str(d / "state")],
            cwd=tmp_path, capture_output=True, text=True, timeout=180)
        wall_s = time.monotonic() - t0
        assert p.returncode == 0, p.stderr[-2000:]
        log = read_log(d / "logs")
        logs.append([{k: v for k, v in r.items() if k not in WALL_FIELDS} for r in log])
        sim_s = log[-1]["t_s"]
        assert sim_s / wall_s > 5.0, (sim_s, wall_s)  # ~40 s of mission in a few seconds of wall time
        assert log[-1]["reason"] == "complete" and log[-1]["skipped_cycles"] == 0
        # the final zero thrust is acknowledged on the simulated clock too (it timed out at once in wall time)
        assert log[-1]["ack_received"] is True
        assert all(r["lateness_ms"] == 0.0 for r in log if r["event"] == "cycle")
    assert len(logs[0]) == len(logs[1]) > 300
    for a, b in zip(*logs):
        assert a == b


def test_a_ctrl_c_while_the_devices_open_is_a_clean_stop(tmp_path):
    """SIGINT the moment the mission log exists, before the devices have opened: the signal handlers came
    after the rig, the link and the ports, so the stop line said reason "error", signal null (found as a new
    user). Interrupting as a terminal does: SIGINT to a process whose SIGINT is at its default."""
    logs = tmp_path / "logs"
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission", str(MISSIONS[0]),
                          "--sim", "--speedup", "10", "--log-dir", str(logs), "--state-dir", str(tmp_path / "state"),
                          "--runtime-dir", str(tmp_path / "run")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60.0
        while not (logs.exists() and any(logs.glob("*.jsonl"))) and time.monotonic() < deadline:
            time.sleep(0.002)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    last = json.loads(next(logs.glob("*.jsonl")).read_text().splitlines()[-1])
    assert p.returncode == 0 and "Traceback" not in err, err[-2000:]
    assert (last["event"], last["reason"], last["signal"]) == ("stop", "signal", "SIGINT")


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_a_sigterm_or_sighup_in_the_start_up_is_a_clean_stop(tmp_path, signame):
    """Found by an operator audit: a SIGTERM or SIGHUP in the daemon's first ~0.3 s (before the loop's handlers)
    killed it outright (exit 143 / 129), no stop line, a 0-byte log and a stale control socket. Sent here the
    moment the control socket is announced, before the log, the rig and the loop exist."""
    logs, run = tmp_path / "logs", tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission", str(MISSIONS[0]),
                          "--sim", "--speedup", "10", "--log-dir", str(logs), "--state-dir", str(tmp_path / "state"),
                          "--runtime-dir", str(run)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        first = p.stderr.readline()
        while first.startswith("note: "):  # the shipped configuration has no origin: --sim says so first
            first = p.stderr.readline()
        assert first.startswith("autopilot run: control socket"), first
        p.send_signal(getattr(signal, signame))
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, (p.returncode, err[-2000:])
    last = json.loads(next(logs.glob("*.jsonl")).read_text().splitlines()[-1])
    assert (last["event"], last["reason"], last["signal"]) == ("stop", "signal", signame)
    assert not (run / "control.sock").exists()


def test_a_second_bench_run_keeps_its_own_progress_and_a_held_start_is_said(tmp_path, request):
    """Found by a new-user audit: a second `--sim` run (own socket) read the first's live mission progress as an
    interrupted mission and sat at zero thrust for max_mission_time_s, said only in a JSON line; after a kill -9
    the next bench run did the same, and the summary never said why."""
    import yaml

    # the default runtime directory, this test's; short, as /run/user/UID is (a socket's path has 107 bytes, and a
    # pytest-xdist worker's tmp_path leaves too few of them)
    xdg = Path(tempfile.mkdtemp(prefix="xdg-", dir="/tmp"))
    request.addfinalizer(lambda: shutil.rmtree(xdg, ignore_errors=True))
    env = {**os.environ, "XDG_RUNTIME_DIR": str(xdg)}
    work = tmp_path / "work"
    work.mkdir()
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg.setdefault("failsafe", {})["max_mission_time_s"] = 120.0
    cfg["failsafe"]["position_confirm_s"] = 1.0  # the first run (real time) starts a second after its first fix
    (work / "c.yaml").write_text(yaml.safe_dump(cfg))

    def run(speedup: str, **kw):
        return subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", "c.yaml", "--mission",
                                 str(MISSIONS[0]), "--sim", "--speedup", speedup], cwd=work, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)

    first = run("1")
    try:
        line = first.stderr.readline()
        while line.startswith("note: "):
            line = first.stderr.readline()
        assert line.startswith("autopilot run: control socket"), line
        progress = work / "state" / "mission-progress.json"
        deadline = time.monotonic() + 30.0
        while b'"launch_ne_m": [' not in (progress.read_bytes() if progress.exists() else b"") \
                and time.monotonic() < deadline:  # the first run's own progress, its launch point saved
            time.sleep(0.05)
        before = progress.read_bytes()
        second = run("max")
        _, err = second.communicate(timeout=120)
        assert second.returncode == 0, err[-2000:]
        assert "another daemon runs, so this bench run keeps its mission progress in" in err, err[-2000:]
        assert "mission complete" in err and "holding zero thrust" not in err, err[-2000:]
        private = [p for p in xdg.iterdir() if "-sim-" in p.name]
        assert private == []  # removed at exit
        assert progress.read_bytes() == before  # the first run's progress is its own
    finally:
        first.kill()  # as a crash: its progress says running
        first.wait(timeout=30)
    third = run("max")
    _, err = third.communicate(timeout=120)
    assert third.returncode == 0, err[-2000:]
    lines = [x for x in err.splitlines() if x.startswith("autopilot run: ")]
    assert any("holding zero thrust: interrupted mission found in the state directory and "
               "failsafe.resume_after_restart is false (--fresh starts afresh); `autopilot ctl --runtime-dir" in x
               and x.endswith("resume` starts the mission") for x in lines), lines
    assert any("the boat waited at zero thrust from the start: interrupted mission" in x for x in lines), lines


def test_a_second_ctrl_c_after_the_summary_is_no_kill(tmp_path):
    """Found by a new-user audit: a second Ctrl-C 0.1 s after the first killed the daemon by SIGINT (status 130,
    no message) in 4 runs of 7, after its summary, with the zero thrust acknowledged: a clean run looked failed."""
    codes = []
    for k in range(3):
        p = subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", str(CONFIG), "--mission",
                              str(MISSIONS[0]), "--sim", "--speedup", "1", "--log-dir", str(tmp_path / "logs"),
                              "--state-dir", str(tmp_path / "state"), "--runtime-dir", str(tmp_path / "run"),
                              "--fresh"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
        try:
            line = p.stderr.readline()
            while line and not line.startswith("autopilot run: control socket"):
                line = p.stderr.readline()
            time.sleep(1.0)  # it flies
            os.killpg(p.pid, signal.SIGINT)
            while line and not line.startswith("autopilot run: cycles:"):  # the summary's last line
                line = p.stderr.readline()
            os.killpg(p.pid, signal.SIGINT)  # as a Ctrl-C pressed twice
            p.communicate(timeout=60)
        finally:
            if p.poll() is None:
                p.kill()
        codes.append(p.returncode)
    assert codes == [0, 0, 0]


MISSION = ROOT / "config" / "missions" / "pond-9.4.yaml"


def test_a_sim_restart_finds_the_boat_where_the_run_before_left_it(tmp_path):
    """Left in stop 49's note: `--sim` put its boat back at the launch point on every start, so a bench test of
    resume-after-restart (kill -9, systemd's restart) flew the resumed run from home, as no real boat does. The
    boat is now kept in the state directory; a restart that carries the run on starts it there, at rest, and says
    so; --fresh starts it at the launch point."""
    work = tmp_path / "work"
    work.mkdir()
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg.setdefault("failsafe", {})["max_mission_time_s"] = 60.0  # the held restarts end soon at --speedup max
    (work / "c.yaml").write_text(yaml.safe_dump(cfg))

    def run(speedup: str, *extra):
        return subprocess.Popen([sys.executable, "-m", "autopilot", "run", "--config", "c.yaml", "--mission",
                                 str(MISSION), "--sim", "--speedup", speedup, "--log-dir", "logs", "--state-dir",
                                 "state", "--runtime-dir", "run", *extra], cwd=work, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)

    def cycles(log):
        # whole lines only: the daemon appends as we read, and a kill can cut its last line (a run on f44cc8e read
        # a line half written: JSONDecodeError)
        lines = log.read_text().split("\n")[:-1]
        return [r for r in map(json.loads, lines) if r.get("event") == "cycle" and r.get("north_m") is not None]

    from autopilot.mission import load_mission

    home = np.array(load_mission(MISSION, origin_lat_deg=cfg.get("origin_lat_deg"),
                                 origin_lon_deg=cfg.get("origin_lon_deg")).home_ne_m)
    first = run("10", "--fresh")
    try:
        logs, recs = [], []
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            logs = list((work / "logs").glob("mission-*.jsonl"))
            recs = cycles(logs[0]) if logs else []
            if recs and np.hypot(recs[-1]["north_m"] - home[0], recs[-1]["east_m"] - home[1]) > 15.0:
                break
            time.sleep(0.05)
    finally:
        first.kill()  # as a crash: its progress says running
        first.wait(timeout=30)
    recs = cycles(logs[0])  # all it wrote
    assert recs[-1]["mode"] == "auto"  # killed on the way, 34.5 m out
    killed = np.array([recs[-1]["north_m"], recs[-1]["east_m"]])
    assert np.hypot(*(killed - home)) > 15.0
    second = run("max")
    _, err = second.communicate(timeout=120)
    assert second.returncode == 0, err[-2000:]
    assert "--sim: the simulated boat starts where the run before left it" in err, err[-2000:]
    (log2,) = set((work / "logs").glob("mission-*.jsonl")) - set(logs)
    # said after the mission_start, a log's first line (said before it, a ground-station test's log reader lost the
    # restarted run's log)
    first, *rest = map(json.loads, log2.read_text().splitlines())
    assert first["event"] == "mission_start"
    assert any(r.get("message", "").startswith("--sim: the simulated boat starts where") for r in rest[:5])
    start = cycles(log2)[0]
    # where the kill found it: within a second's run (the boat saved once a simulated second) and the GPS noise
    assert np.hypot(start["north_m"] - killed[0], start["east_m"] - killed[1]) < 5.0, (start, killed)
    third = run("max", "--fresh")
    _, err = third.communicate(timeout=120)
    assert third.returncode == 0 and "where the run before left it" not in err, err[-2000:]
    (log3,) = set((work / "logs").glob("mission-*.jsonl")) - set(logs) - {log2}
    start = cycles(log3)[0]
    assert np.hypot(start["north_m"] - home[0], start["east_m"] - home[1]) < 3.0, start
