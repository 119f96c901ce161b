"""The systemd unit verifies, is hardened to exposure <= 2.0, and the udev rules name both devices."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
UNIT = ROOT / "systemd" / "wamv-autopilot.service"
ANALYZE = shutil.which("systemd-analyze")
needs_systemd = pytest.mark.skipif(ANALYZE is None, reason="systemd-analyze not installed (.ci/run installs it)")


def _installed_copy(tmp_path: Path) -> Path:
    """The unit with ExecStart pointing at this environment's `autopilot` script (verify checks it exists)."""
    exe = shutil.which("autopilot") or str(Path(sys.executable).with_name("autopilot"))
    assert Path(exe).exists(), "pip install -e . must provide the autopilot script"
    text = UNIT.read_text().replace("/opt/wamv-autopilot/bin/autopilot", exe)
    out = tmp_path / UNIT.name
    out.write_text(text)
    return out


@needs_systemd
def test_systemd_analyze_verify_is_clean(tmp_path):
    unit = _installed_copy(tmp_path)
    r = subprocess.run([ANALYZE, "verify", str(unit)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "wamv-autopilot" not in r.stderr, r.stderr


@needs_systemd
def test_security_exposure_is_ok(tmp_path):
    r = subprocess.run([ANALYZE, "security", "--offline=true", str(_installed_copy(tmp_path))],
                       capture_output=True, text=True, timeout=60)
    m = re.search(r"Overall exposure level for \S+: (\d+\.\d+) (\w+)", r.stdout)
    assert m, r.stdout[-2000:] + r.stderr
    assert float(m.group(1)) <= 2.0, m.group(0)
    assert m.group(2) in ("OK", "SAFE")


def _directives(text: str) -> dict[str, list[str]]:
    d: dict[str, list[str]] = {}
    for line in text.splitlines():
        line = line.strip()
        if line and not line.startswith(("#", "[")) and "=" in line:
            k, v = line.split("=", 1)
            d.setdefault(k, []).append(v)
    return d


def test_unit_has_the_required_settings():
    d = _directives(UNIT.read_text())
    assert d["Type"] == ["notify"]
    assert d["Restart"] == ["on-failure"]
    assert d["WatchdogSec"] and d["LogsDirectory"] and d["StateDirectory"]
    assert d["ProtectSystem"] == ["strict"]
    assert d["DevicePolicy"] == ["closed"]
    assert sorted(d["DeviceAllow"]) == ["/dev/mbed rw", "/dev/sc30 rw"]
    # the network for the MAVLink link only: everything denied but the boat itself (a drop-in allows the
    # ground station's network), and no address family but UNIX and IP
    assert "PrivateNetwork" not in d and d["IPAddressDeny"] == ["any"] and d["IPAddressAllow"] == ["localhost"]
    assert d["RestrictAddressFamilies"] == ["AF_UNIX AF_INET AF_INET6"]
    assert d["RuntimeDirectory"] == ["wamv-autopilot"] and "--runtime-dir ${RUNTIME_DIRECTORY}" in d["ExecStart"][0]
    assert "dialout" in d["SupplementaryGroups"][0]
    assert d["User"] == ["wamv-autopilot"]
    assert "--log-dir ${LOGS_DIRECTORY}" in d["ExecStart"][0] and "--state-dir ${STATE_DIRECTORY}" in d["ExecStart"][0]


def test_udev_rules_name_both_devices():
    rules = (ROOT / "systemd" / "99-wamv.rules").read_text()
    active = [ln for ln in rules.splitlines() if ln.strip() and not ln.startswith("#")]
    mbed = [ln for ln in active if 'SYMLINK+="mbed"' in ln]
    sc30 = [ln for ln in active if 'SYMLINK+="sc30"' in ln]
    assert len(mbed) == 1 and len(sc30) == 1
    assert 'ATTRS{idVendor}=="0d28"' in mbed[0] and 'ATTRS{idProduct}=="0204"' in mbed[0]
    for ln in mbed + sc30:
        assert 'SUBSYSTEM=="tty"' in ln and 'GROUP="dialout"' in ln and 'TAG+="systemd"' in ln


def test_sysusers_puts_the_user_in_dialout():
    conf = (ROOT / "systemd" / "wamv-autopilot.sysusers.conf").read_text()
    assert re.search(r"^u wamv-autopilot ", conf, re.M)
    assert re.search(r"^m wamv-autopilot dialout$", conf, re.M)
