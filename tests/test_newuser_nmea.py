"""``autopilot nmea`` for a new user wiring the compass (a new-user audit, 2026-12-06): a magnetic heading (HDM) is
shown, not an empty line, and a capture saved as UTF-16 is refused saying so; line noise in a capture is not."""

from __future__ import annotations

import json

import pytest

from autopilot.cli import main
from tests.conftest import SHARED

PYPILOT = SHARED / "nmea" / "pypilot.log"  # APHDM, APROT, APXDR: a compass sending a magnetic heading


def test_a_magnetic_heading_is_printed_and_said_not_steered_by(capsys):
    # "APHDM" was printed with nothing after it: the compass looked dead while it sent 218.6 deg
    assert main(["nmea", str(PYPILOT)]) == 0
    hdm = [ln for ln in capsys.readouterr().out.splitlines() if "APHDM" in ln]
    assert hdm and hdm[0].split(None, 1)[1] == ("APHDM        heading_mag_deg=218.634 (magnetic: not steered by; the "
                                                 "daemon needs THS, HDT or $PFEC,GPatt)")


def test_a_magnetic_heading_in_json(capsys):
    assert main(["nmea", str(PYPILOT), "--json"]) == 0
    recs = [json.loads(ln) for ln in capsys.readouterr().out.splitlines()]
    hdm = [r for r in recs if r["source"] == "HDM"]
    assert hdm[0]["heading_mag_deg"] == 218.634 and hdm[0]["heading_deg"] is None


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le"])  # with and without a byte-order mark
def test_a_capture_saved_as_utf16_is_refused_saying_so(tmp_path, capsys, encoding):
    capture = tmp_path / "cap.log"
    capture.write_bytes(PYPILOT.read_text().encode(encoding))
    assert main(["nmea", str(capture)]) == 2
    err = capsys.readouterr().err
    assert "UTF-16 text" in err and "save the NMEA capture as UTF-8" in err
    assert "no NMEA sentence decoded" not in err


def test_line_noise_in_a_capture_is_dropped_not_refused(tmp_path, capsys):
    capture = tmp_path / "cap.log"
    capture.write_bytes(b"\x00\x00\xff" + PYPILOT.read_bytes())  # a port opened mid-byte
    assert main(["nmea", str(capture)]) == 0
    assert "APROT" in capsys.readouterr().out
