"""An installed copy runs: a wheel built from this checkout, installed in a fresh venv outside it.

INSTALL.md step 1 installs with ``pip install .`` (not ``-e``): every file a command needs by
default (vessel sets, measured table, missions, the default configuration) must be inside the
package. The commands run from a directory outside the checkout, with that venv's ``autopilot``,
as INSTALL.md's check does.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


USER_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}  # a user's: bytecode is written


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    base = tmp_path_factory.mktemp("install")
    wheels = base / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(wheels)],
                   check=True, capture_output=True, text=True, timeout=600)
    (wheel,) = wheels.glob("wamv_autopilot-*.whl")
    venv = base / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    # without compiling every dependency's bytecode up front (13 of the install's 19 s): the commands below write
    # what they import as they import it, as a user's first runs do
    r = subprocess.run([str(venv / "bin" / "pip"), "install", "-q", "--no-compile", str(wheel)], capture_output=True,
                       text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    work = base / "work"  # a user's directory: no checkout anywhere near
    work.mkdir()
    return venv / "bin", work


def run(bin_dir: Path, cwd: Path, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([str(bin_dir / "autopilot"), *args], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=USER_ENV)


def shipped(bin_dir: Path, cwd: Path) -> dict[str, Path]:
    out = run(bin_dir, cwd, "files")
    assert out.returncode == 0, out.stderr
    paths = [Path(line.split("  (")[0]) for line in out.stdout.splitlines()]
    return {p.name: p for p in paths}


@pytest.mark.slow
def test_the_installed_package_is_the_wheel_and_ships_its_files(installed):
    bin_dir, work = installed
    r = subprocess.run([str(bin_dir / "python"), "-c", "import autopilot; print(autopilot.__file__)"], cwd=work, env=USER_ENV,
                       capture_output=True, text=True, check=True)
    location = Path(r.stdout.strip())
    assert bin_dir.parent in location.parents and ROOT not in location.parents
    files = shipped(bin_dir, work)
    for name in ("autopilot.yaml", "vessel.yaml", "vessel-thesis.yaml", "measured-table.csv", "pond-9.4.yaml",
                 "pond-9.4.plan", "pond-robustness.yaml", "wamv-autopilot.service", "99-wamv.rules",
                 "wamv-autopilot.sysusers.conf", "INSTALL.md"):  # INSTALL.md from a wheel, without a checkout
        assert files[name].is_file() and bin_dir.parent in files[name].parents, name
    assert run(bin_dir, work, "--version").stdout.startswith("autopilot ")


@pytest.mark.slow
def test_install_md_check_runs_a_simulated_mission(installed, tmp_path):
    bin_dir, work = installed
    files = shipped(bin_dir, work)
    etc = tmp_path / "etc"  # INSTALL.md step 2 copies these two files to /etc/wamv-autopilot
    etc.mkdir()
    shutil.copy(files["autopilot.yaml"], etc / "autopilot.yaml")
    shutil.copy(files["pond-9.4.yaml"], etc / "mission.yaml")
    check = tmp_path / "ap-check"
    r = run(bin_dir, work, "run", "--config", str(etc / "autopilot.yaml"), "--mission", str(etc / "mission.yaml"),
            "--sim", "--speedup", "20", "--log-dir", str(check), "--state-dir", str(check))
    assert r.returncode == 0, r.stderr[-3000:]
    (log,) = check.glob("mission-*.jsonl")
    assert f"log: {log}" in r.stderr and "mission complete" in r.stderr
    assert json.loads(log.read_text().splitlines()[-1])["reason"] == "complete"


@pytest.mark.slow
def test_a_new_user_flies_a_shipped_mission_by_name_without_a_checkout(installed, tmp_path):
    """From an installed wheel there is no config/ to point at: the Quick start's paths did not exist there.
    With --sim the shipped configuration is the default and a shipped mission is found by its name; on the
    boat (no --sim) the configuration stays required, and a name that is nothing says what is shipped."""
    bin_dir, work = installed
    logs = tmp_path / "logs"
    r = run(bin_dir, work, "run", "--mission", "pond-9.4", "--sim", "--speedup", "max", "--log-dir", str(logs),
            "--state-dir", str(tmp_path / "state"))
    assert r.returncode == 0, r.stderr[-3000:]
    files = shipped(bin_dir, work)
    assert f"note: --sim without --config: the shipped configuration ({files['autopilot.yaml']})" in r.stderr
    assert f"note: --mission pond-9.4: the shipped mission {files['pond-9.4.yaml']}" in r.stderr
    assert "mission complete" in r.stderr and len(list(logs.glob("mission-*.jsonl"))) == 1
    r = run(bin_dir, work, "run", "--mission", "pond-9.4")
    assert r.returncode == 2 and r.stderr.strip().endswith("--config is required without --sim (the boat's serial "
                                                           "ports and origin; `autopilot files` lists the shipped "
                                                           "configuration to copy and edit)"), r.stderr
    r = run(bin_dir, work, "run", "--mission", "pond-9.9", "--sim")
    assert r.returncode == 2 and "--mission pond-9.9: no such file, nor a shipped mission (pond-9.1" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.slow
def test_model_check_evaluate_and_sysid_table_run_from_the_install(installed, tmp_path):
    bin_dir, work = installed
    r = run(bin_dir, work, "model", "check")
    assert r.returncode == 0 and "turning rows" in r.stdout, r.stderr
    r = run(bin_dir, work, "evaluate", "--guidance", "fuzzy", "--condition", "calm", "--json")
    assert r.returncode == 0, r.stderr
    rows = [json.loads(x) for x in r.stdout.splitlines()]
    assert len(rows) == 7 and all(row["completed"] for row in rows)  # the seven shipped missions
    assert any("hold_position_error_rms_m" in row for row in rows)  # station-keep.yaml, scored on its hold
    table = shipped(bin_dir, work)["measured-table.csv"]
    r = run(bin_dir, work, "sysid", "--table", str(table), "--out", str(tmp_path / "sysid"), "--no-report")
    assert r.returncode == 0 and r.stdout.startswith("verdict:"), r.stderr


@pytest.mark.slow
def test_a_campaign_flies_and_replays_from_the_install_and_says_what_dask_needs(installed, tmp_path):
    """The shipped campaign spec, as a user copies it, flown on a process pool by the installed package (the
    workers import it too), a run re-flown, and --scheduler without the [campaign] extra refused in words."""
    bin_dir, work = installed
    spec = work / "my-campaign.yaml"
    spec.write_text(shipped(bin_dir, work)["pond-robustness.yaml"].read_text(encoding="utf-8"), encoding="utf-8")
    out = tmp_path / "campaign"
    r = run(bin_dir, work, "campaign", str(spec), "--runs", "24", "--jobs", "2", "--out", str(out), "--quiet")
    assert r.returncode == 0 and "24 runs" in r.stdout, r.stdout + r.stderr
    assert len((out / "runs.csv").read_text().splitlines()) == 25 and (out / "report.html").stat().st_size > 0
    r = run(bin_dir, work, "campaign", "--replay", str(out), "7")
    assert r.returncode == 0 and "identical to its row in runs.csv" in r.stdout, r.stdout + r.stderr
    r = run(bin_dir, work, "campaign", str(spec), "--runs", "24", "--scheduler", "local", "--out",
            str(tmp_path / "dask"))
    assert r.returncode == 2 and "pip install 'wamv-autopilot[campaign]'" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
