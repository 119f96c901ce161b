"""sd_notify against a real AF_UNIX datagram socket, as systemd provides it."""

import os
import socket

from autopilot.daemon.sd_notify import Notifier


def _server(path):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    s.bind(path)
    s.settimeout(2.0)
    return s


def test_ready_watchdog_stopping_reach_the_socket(tmp_path):
    path = str(tmp_path / "notify")
    srv = _server(path)
    n = Notifier(path)
    assert n.enabled
    assert n.ready(status="both devices answer")
    assert n.watchdog()
    assert n.stopping()
    got = [srv.recv(4096).decode() for _ in range(3)]
    assert got == ["READY=1\nSTATUS=both devices answer", "WATCHDOG=1", "STOPPING=1"]
    n.close()
    srv.close()


def test_abstract_namespace_address():
    name = f"autopilot-test-{os.getpid()}"
    srv = _server("\0" + name)
    n = Notifier("@" + name)
    assert n.watchdog()
    assert srv.recv(100) == b"WATCHDOG=1"
    srv.close()


def test_without_notify_socket_everything_is_a_no_op(monkeypatch):
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    n = Notifier()
    assert not n.enabled
    assert n.ready() is False and n.watchdog() is False


def test_a_vanished_socket_is_counted_not_raised(tmp_path):
    n = Notifier(str(tmp_path / "gone"))
    assert n.watchdog() is False
    assert n.errors == 1


def test_watchdog_interval_from_environment(monkeypatch):
    monkeypatch.setenv("WATCHDOG_USEC", "2000000")
    monkeypatch.setenv("WATCHDOG_PID", str(os.getpid()))
    assert Notifier.watchdog_interval_s() == 1.0
    monkeypatch.setenv("WATCHDOG_PID", "1")  # meant for another process
    assert Notifier.watchdog_interval_s() is None


def test_watchdog_is_fed_only_by_cycles_on_time():
    from autopilot.daemon.loop import watchdog_due

    common = dict(period_s=0.1, interval_s=1.0)
    assert watchdog_due(ready=True, lateness_s=0.002, since_last_s=1.0, **common)
    assert not watchdog_due(ready=True, lateness_s=0.1, since_last_s=5.0, **common)  # a period late
    assert not watchdog_due(ready=True, lateness_s=0.35, since_last_s=5.0, **common)
    assert not watchdog_due(ready=False, lateness_s=0.0, since_last_s=5.0, **common)  # before READY=1
    assert not watchdog_due(ready=True, lateness_s=0.0, since_last_s=0.4, **common)  # rate-limited
    # a loop late on every cycle never feeds the watchdog, however long it runs
    assert not any(watchdog_due(ready=True, lateness_s=0.1 + k * 1e-3, since_last_s=k, **common) for k in range(100))
