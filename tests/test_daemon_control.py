"""The control socket's request parsing (autopilot.daemon.control): pure, bytes in, request or refusal out."""


def test_a_ctl_request_with_a_field_given_twice_is_refused():
    """Found by fault injection: {"command": "status", "command": "pause"} paused the boat (JSON's last key wins)."""
    from autopilot.daemon.control import parse_request

    assert parse_request(b'{"command": "status", "command": "pause"}') == (
        None, "malformed request: field 'command' given twice")
    assert parse_request(b'{"command": "hold", "heading_deg": 90}') == ({"command": "hold", "heading_deg": 90}, None)


def _server_exchange(tmp_path, payload: bytes, *, close_write: bool = True,
                     linger_s: float = 0.0) -> tuple[list[dict], list[dict], list]:
    """``payload`` sent on one connection to a real ControlServer on a Unix socket; the answers read, the
    requests the loop was given, and the events logged."""
    import asyncio
    import json
    import socket

    from autopilot.daemon.control import ControlServer

    submitted, logged = [], []

    def submit(req, answer):
        submitted.append(req)
        answer({"ok": True, "answer": req["command"], "mode": req["command"]})

    async def scenario():
        server = ControlServer(tmp_path / "control.sock", submit=submit, status=lambda: {"mode": "auto"},
                               log=lambda name, **f: logged.append((name, f)))
        await server.start()
        try:
            def client():
                with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                    s.settimeout(10.0)
                    s.connect(str(tmp_path / "control.sock"))
                    s.sendall(payload)
                    if close_write:
                        s.shutdown(socket.SHUT_WR)
                    data = b""
                    while chunk := s.recv(65536):
                        data += chunk
                return data

            data = await asyncio.get_running_loop().run_in_executor(None, client)
            await asyncio.sleep(linger_s)
            logged.append(("closing", {}))
        finally:
            await server.close()
        return [json.loads(x) for x in data.decode().splitlines()]

    return asyncio.run(scenario()), submitted, logged


def test_every_request_on_one_connection_is_served_in_order(tmp_path):
    """Found by fault injection: `printf 'status\\nstop\\n' | socat - UNIX:control.sock` answered the status and
    dropped the stop without a word (one request per connection): the boat went on."""
    answers, submitted, logged = _server_exchange(tmp_path, b'status\n{"command": "stop"}\n\npause')
    assert [a["answer"] for a in answers] == ["status", "stop", "pause"]
    assert answers[0]["status"] == {"mode": "auto"}
    assert [r["command"] for r in submitted] == ["stop", "pause"]
    assert logged == [("closing", {})]  # the blank line between requests and the closed connection are not refusals


def test_a_bad_line_is_refused_and_the_next_still_served_and_a_quiet_connection_ends_without_a_refusal(tmp_path):
    answers, submitted, logged = _server_exchange(tmp_path, b'launch\nstop\n', close_write=False)
    assert answers[0]["ok"] is False and "command 'launch' is not one of" in answers[0]["answer"]
    assert answers[1] == {"ok": True, "answer": "stop", "mode": "stop"}
    assert [r["command"] for r in submitted] == ["stop"]
    assert logged == [("command", {"command": "launch", "source": "ctl", "accepted": False, "answer": answers[0]["answer"]}),
                      ("closing", {})]  # the silence after the stop is not an incomplete request


def test_a_flood_of_refusals_is_answered_in_full_but_logged_five_a_second_and_counted(tmp_path):
    """Found by benchmarks/loop_timing.py --link ctl: a client looping on a bad request wrote every refusal into
    the mission log, 30 400 lines in 40 s (~750 a second: a disk filled in hours)."""
    from autopilot.daemon.control import REFUSALS_LOGGED_PER_S

    answers, submitted, logged = _server_exchange(tmp_path, b"launch\n" * 40 + b"stop\n", linger_s=1.2)
    assert len(answers) == 41 and all(not a["ok"] for a in answers[:40]) and answers[40]["ok"]
    refusals = [f for name, f in logged if name == "command"]
    assert len(refusals) == REFUSALS_LOGGED_PER_S and all(f["command"] == "launch" for f in refusals)
    said = [f for name, f in logged if name == "info"]
    assert said == [{"message": "ctl refusals not logged", "count": 40 - REFUSALS_LOGGED_PER_S,
                     "limit_per_s": REFUSALS_LOGGED_PER_S}]
    assert logged[-1] == ("closing", {})  # said when the second was over, not only when the server closed


def test_ctl_against_a_socket_that_is_not_a_daemons_says_so(tmp_path, capsys):
    """Found by an operator audit: a socket answering {"ok": true, "answer": "status", "status": 5} (not the
    daemon's) made `autopilot ctl status` an 'internal error: AttributeError'."""
    import json
    import socket
    import threading

    from autopilot.cli import main

    path = tmp_path / "control.sock"
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(str(path))
    server.listen()

    def answer():
        conn, _ = server.accept()
        with conn:
            conn.recv(65536)
            conn.sendall((json.dumps({"ok": True, "answer": "status", "status": 5}) + "\n").encode())

    t = threading.Thread(target=answer, daemon=True)
    t.start()
    try:
        assert main(["ctl", "status", "--runtime-dir", str(tmp_path)]) == 3
    finally:
        t.join(5)
        server.close()
    err = capsys.readouterr().err
    assert f"autopilot ctl: the answer on {path} is not a daemon's" in err and "internal error" not in err


def test_plain_status_says_why_the_helm_is_in_its_mode():
    """Found by a new-user audit: a start held at zero thrust showed only "mode: stop" (`--json` said why)."""
    from autopilot.daemon.cli import _status_lines

    held = {"mode": "stop", "helm_mode": "stop", "mode_cause": "start: interrupted mission found in the state "
            "directory and failsafe.resume_after_restart is false (--fresh starts afresh)", "armed": True, "t_s": 1.0}
    assert _status_lines(held)[0] == ("mode: stop (planner: HOLD) - start: interrupted mission found in the state directory and "
                                      "failsafe.resume_after_restart is false (--fresh starts afresh)")
    assert _status_lines({"mode": "auto", "helm_mode": "auto", "mode_cause": "start", "t_s": 1.0})[0] == "mode: auto"
    # a given hold heading the current is across: said by ctl status too, not only in the log (an operator audit)
    across = {"mode": "hold", "mode_cause": "ctl hold --heading 0", "hold_north_m": 1.0, "hold_east_m": 2.0,
              "hold_error_m": 4.97, "hold_heading_deg": 0.0, "hold_across_feasible_deg": 265.4}
    assert ("hold heading 0 deg cannot keep the point: the current or wind is across it, from about 265 deg; hold "
            "without --heading to face it") in _status_lines(across)
    assert not any("cannot keep" in x for x in _status_lines({**across, "hold_across_feasible_deg": None}))
    assert _status_lines({"mode": "hold", "mode_cause": "ctl hold", "armed": False})[0] == (
        "mode: hold (planner: LOITER) - ctl hold - DISARMED: zero thrust whatever the mode (autopilot ctl arm)")


def test_status_names_the_planners_mode_and_a_fault_latched_before_a_restart():
    """An operator audit: `ctl status` said "hold" where the planner beside it showed LOITER (and its HOLD is our
    stop); and a latched fault restored from the run before a restart was listed as a fault of now."""
    from autopilot.daemon.cli import _status_lines
    from autopilot.logschema import RTL_ARRIVED_CAUSE

    assert _status_lines({"mode": "hold", "mode_cause": RTL_ARRIVED_CAUSE})[0].startswith(
        "mode: hold (planner: RTL)")
    assert _status_lines({"mode": "paused", "mode_cause": "ctl pause"})[0] == "mode: paused (planner: LOITER) - ctl pause"
    assert _status_lines({"mode": "rtl", "mode_cause": "ctl rtl"})[0] == "mode: rtl - ctl rtl"  # the same name
    assert _status_lines({"mode": "no-such-mode"})[0] == "mode: no-such-mode"  # a newer daemon's: shown as it is
    st = {"mode": "stop", "active_faults": ["heading_stale", "geofence", "battery_low"],
          "latched_faults": ["geofence", "battery_low"], "latched_before_restart": ["geofence"]}
    assert _status_lines(st)[-1] == "faults: heading_stale; latched: geofence (before the restart), battery_low"
    assert _status_lines({"mode": "auto", "active_faults": []})[-1] == "faults: none"
