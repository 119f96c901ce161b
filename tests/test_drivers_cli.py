"""``autopilot nmea``: a shared capture replayed through a pty gives the same updates as the file."""

from __future__ import annotations

import json
import subprocess
import sys
import time

from autopilot.cli import main
from autopilot.drivers.nmea import NmeaStreamDecoder
from autopilot.simdev import PtyEndpoint
from tests.conftest import SHARED

CAPTURE = SHARED / "nmea" / "saab-r4.log"


def _strip_t(lines):
    out = []
    for ln in lines:
        rec = json.loads(ln)
        assert isinstance(rec.pop("t_s"), float)
        out.append(rec)
    return out


def test_nmea_cli_file_json(capsys):
    assert main(["nmea", str(CAPTURE), "--json"]) == 0
    recs = _strip_t(capsys.readouterr().out.splitlines())
    expected = NmeaStreamDecoder().feed(CAPTURE.read_bytes())
    assert [r["source"] for r in recs] == [u.sentence for u in expected]
    hdt = [r for r in recs if r["source"] == "HDT"]
    assert hdt[0]["heading_deg"] == 4.0 and hdt[0]["valid"] is True
    keys = {"lat_deg", "lon_deg", "heading_deg", "rot_deg_min", "sog_kn", "cog_deg", "fix_quality", "source"}
    assert all(keys <= r.keys() for r in recs)


def test_nmea_cli_replay_through_pty(tmp_path, capsys):
    assert main(["nmea", str(CAPTURE), "--json"]) == 0
    from_file = _strip_t(capsys.readouterr().out.splitlines())

    pty = PtyEndpoint(tmp_path, "sc30")
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "autopilot", "nmea", pty.path, "--json", "--count", str(len(from_file)),
             "--timeout", "10"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        # pyserial flushes the input when it opens the port: write only once it is reading
        assert proc.stderr.readline().startswith(b"nmea: reading")
        data = CAPTURE.read_bytes()
        pos = 0
        while pos < len(data):  # a pty holds ~4 kB: write as the reader drains it
            n = pty.write(data[pos : pos + 512])
            pos += n
            if n == 0:
                time.sleep(0.01)
        out, err = proc.communicate(timeout=30)
    finally:
        pty.close()
    assert proc.returncode == 0, err
    assert _strip_t(out.decode().splitlines()) == from_file


def test_nmea_cli_bad_source():
    assert main(["nmea", "/nonexistent/sc30"]) == 2
