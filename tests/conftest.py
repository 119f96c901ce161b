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


def _background_modules(session):
    """Test modules that start work of their own when collection ends (``start_background(items)``)."""
    seen = {}
    for item in session.items:
        mod = getattr(item, "module", None)
        if mod is not None and hasattr(mod, "start_background"):
            seen[mod.__name__] = mod
    return list(seen.values())


def pytest_collection_finish(session):
    for mod in _background_modules(session):
        mod.start_background(session.items)


def pytest_sessionfinish(session):
    for mod in _background_modules(session):
        mod.stop_background()
