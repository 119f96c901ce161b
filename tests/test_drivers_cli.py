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
    """The NMEA records (AIS targets, {"t_s", "ais"}, are the other kind of line)."""
    out = []
    for ln in lines:
        rec = json.loads(ln)
        assert isinstance(rec.pop("t_s"), float)
        if "ais" not in rec:
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
    lines = capsys.readouterr().out.splitlines()
    from_file = _strip_t(lines)

    pty = PtyEndpoint(tmp_path, "sc30")
    try:
        proc = subprocess.Popen(
            [sys.executable, "-m", "autopilot", "nmea", pty.path, "--json", "--count", str(len(lines)),
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


def test_nmea_cli_shows_ais_targets(capsys):
    """A capture with AIS only (no NMEA 0183 at all) now decodes: each target as it updates, assembled parts."""
    assert main(["nmea", "--json", str(SHARED / "nmea" / "ais-18-27.log")]) == 0
    out = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    ais = [r["ais"] for r in out if "ais" in r]
    assert len(ais) > 60 and all(r["class"] == "B" for r in ais)  # type 18/24: class B CS
    named = {r["mmsi"]: r["name"] for r in ais if r["name"]}
    assert named  # type 24 part A gives the names
    assert main(["nmea", str(SHARED / "nmea" / "ais-nmea.log")]) == 0
    text = capsys.readouterr()
    assert "AIS" in text.out and "mmsi=" in text.out and "target(s)" in text.err
