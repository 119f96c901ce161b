import gc
import os
import sys
from pathlib import Path

# Multi-threaded BLAS on a shared 2-core machine makes small least-squares SVDs ~40x slower
# (measured in the identification fits); the suite's work is many small problems.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import pytest

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


def run_cli(*args: str, check: bool = True, timeout: float = 300, **kw):
    """Run the installed ``autopilot`` entry point as a user would (python -m, same interpreter)."""
    import subprocess

    proc = subprocess.run(
        [sys.executable, "-m", "autopilot", *args], capture_output=True, text=True, timeout=timeout, cwd=REPO, **kw
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"autopilot {' '.join(args)} exited {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    return proc


def _shared_dir() -> Path:
    """../shared beside the checkout (as CI lays it out), else the workplace's copy."""
    for candidate in (REPO.parent / "shared", Path("/work/shared")):
        if (candidate / "nmea").is_dir():
            return candidate
    return REPO.parent / "shared"


SHARED = _shared_dir()


def lowest_cpu_priority() -> None:
    """Run only when no other process wants the CPU (Linux's SCHED_IDLE: a waking daemon or simulator preempts
    at once; inherited by the threads and processes started after), else at nice 19."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):
        os.nice(19)


def _background_modules(session):
    """Test modules that start work of their own when collection ends (``start_background(items)``)."""
    seen = {}
    for item in session.items:
        mod = getattr(item, "module", None)
        if mod is not None and hasattr(mod, "start_background"):
            seen[mod.__name__] = mod
    return list(seen.values())


# The suite runs on two pytest-xdist workers (pyproject's addopts): one flies these modules' daemons, simulators,
# sockets and pseudo-terminals on the wall clock (x speedup), one after another as alone (and the campaigns' and
# the install's process trees, which a starved worker would make balk); the other computes
# everything else at the lowest CPU priority, in the time the first leaves idle, so it cannot make a daemon late.
REALTIME_MODULES = frozenset({
    "test_campaign.py", "test_install.py",  # process pools, Dask clusters and a venv: a starved worker balks
    "test_daemon_bad_inputs.py", "test_daemon_config.py", "test_daemon_control.py", "test_daemon_cycle.py",
    "test_daemon_e2e.py", "test_daemon_log.py", "test_daemon_modes.py", "test_daemon_notify.py",
    "test_daemon_traffic.py", "test_drivers_ais.py", "test_drivers_cli.py", "test_drivers_line_timing.py",
    "test_failsafe_faults.py", "test_link_mavlink.py", "test_link_params.py", "test_sc30_output.py",
    "test_simdev_contract.py", "test_simdev_traffic.py", "test_systemd_unit.py",
})


def _group(item) -> str:
    return "realtime" if item.path.name in REALTIME_MODULES or _flies_a_rig(getattr(item, "module", None)) else "compute"


def _flies_a_rig(module) -> bool:
    """The module uses a realtime module's rig (its daemon, boat or fault rig, imported from it): realtime too.
    Three new daemon modules left off the list ran on the computing worker, under load, and one failed there."""
    if module is None:
        return False
    return any(isinstance(getattr(v, "__module__", None), str) and v.__module__.startswith("tests.")
               and v.__module__.rsplit(".", 1)[-1] + ".py" in REALTIME_MODULES for v in vars(module).values())


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook reads the mark
def pytest_collection_modifyitems(config, items):
    for item in items:
        item.add_marker(pytest.mark.xdist_group(_group(item)))


_lowered = False


def pytest_runtest_setup(item):
    global _lowered
    if _group(item) == "realtime":
        # The simulated SC-30 and Mbed run in this process, at the tests' speedup: a full collection of the
        # suite's heap paused it 10-30 ms (0.1-0.3 s simulated, an ack timeout's worth: a spurious
        # mbed_ack_missing seen). The collector is off for the test (a test lasts seconds: its cyclic garbage
        # waits for the next test's start); a freeze once a module still saw one ~0.1-s stall, cause not proven.
        gc.collect()
        gc.disable()
        return
    if not os.environ.get("PYTEST_XDIST_WORKER") or _lowered:
        return
    _lowered = True  # this worker runs the compute group only (loadgroup gives a group to one worker whole)
    lowest_cpu_priority()
    for mod in _background_modules(item.session):
        mod.start_background(item.session.items)


def pytest_runtest_teardown(item):
    gc.enable()


def pytest_collection_finish(session):
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return  # every worker collects every test: the compute worker starts the background at its first test
    for mod in _background_modules(session):
        mod.start_background(session.items)


def pytest_sessionfinish(session):
    for mod in _background_modules(session):
        mod.stop_background()
