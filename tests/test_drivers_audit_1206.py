"""Drivers audit 1206: the shared gpsd captures decoded as gpsd decodes them, and CR-only line ends."""

from __future__ import annotations

import json

from autopilot.cli import main
from autopilot.drivers.ais import AisStreamDecoder
from autopilot.drivers.framing import LineFramer
from autopilot.drivers.nmea import NmeaStreamDecoder, decode_line
from tests.conftest import SHARED

NMEA = SHARED / "nmea"


def _sentences(name: str) -> list[bytes]:
    """The capture's lines without their line ends (most captures end in LF alone, not the README's CRLF)."""
    return [ln for ln in (NMEA / name).read_bytes().splitlines() if ln and not ln.startswith(b"#")]


def test_gga_with_no_satellites_is_no_fix_as_gpsd_says():
    # hemi.log: the receiver lost its satellites and kept sending its last position with quality 1 and "00"
    # satellites for 7 s; gpsd reports mode 1 (no fix) for every one, and a fix again once 04 are used
    ggas = [ln.decode() for ln in _sentences("hemi.log") if b"GGA" in ln]
    none = [s for s in ggas if s.split(",")[6:8] == ["1", "00"]]
    four = [s for s in ggas if s.split(",")[6:8] == ["1", "04"]]
    assert len(none) == 15 and len(four) == 6
    for s in none:
        u = decode_line(s)
        assert u.lat_deg is not None and u.fix_quality == 1
        assert u.status_valid is False, s
    assert all(decode_line(s).status_valid for s in four)
    chk = (NMEA / "hemi.log.chk").read_text().splitlines()
    i = chk.index(none[0].strip())
    assert json.loads(chk[i + 1]) == {"class": "TPV", "mode": 1}
    # an empty satellite count is only not given (saab-r4's GGA): the quality decides
    assert decode_line("$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A").status_valid


def _decoded(data: bytes, chunk: int | None = None):
    d = NmeaStreamDecoder()
    out = []
    step = chunk or len(data)
    for i in range(0, len(data), step):
        out += d.feed(data[i : i + step])
    return out, d


def test_cr_only_line_ends_decode_like_crlf():
    crlf = b"\r\n".join(_sentences("saab-r4.log")) + b"\r\n"
    want, ref = _decoded(crlf)
    assert len(want) > 50
    cr = crlf.replace(b"\r\n", b"\r")
    got, d = _decoded(cr)
    # the last sentence waits for the byte after its CR (it may be a CRLF split between reads)
    assert got == want[:-1] or got == want
    assert d.stats.too_long == 0 and d.stats.dropped == ref.stats.dropped  # the AIS lines, no hook given
    got1, _ = _decoded(cr + b"$", chunk=1)
    assert got1 == want
    # CRLF split across reads, and CR CR LF, are still one line end
    assert _decoded(crlf, chunk=1)[0] == want
    assert _decoded(crlf.replace(b"\r\n", b"\r\r\n"), chunk=7)[0] == want
    assert _decoded(crlf.replace(b"\r\n", b"\n"), chunk=5)[0] == want


def test_cr_only_ais():
    data = b"\r\n".join(_sentences("ais-18-27.log")) + b"\r\n"
    want = AisStreamDecoder().feed(data, 0.0)
    got = AisStreamDecoder().feed(data.replace(b"\r\n", b"\r") + b"!", 0.0)
    assert len(want) > 100 and got == want


def test_framer_keeps_cr_only_lines_apart():
    f = LineFramer(200, cr_ends_line=True)
    assert f.feed(b"$A*00\r$B*00\r") == [b"$A*00"]
    assert f.feed(b"\n$C") == [b"$B*00\r"]
    assert LineFramer(200).feed(b"$A*00\r$B*00\r\n") == [b"$A*00\r$B*00\r"]  # the Mbed's framing: LF only


def test_cli_reads_a_cr_only_capture_with_its_header(tmp_path, capsys):
    raw = b"\r".join((NMEA / "saab-r4.log").read_bytes().splitlines()) + b"\r"
    p = tmp_path / "cr.log"
    p.write_bytes(raw)
    assert main(["nmea", "--json", str(p)]) == 0
    recs = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    hdt = [r for r in recs if r.get("source") == "HDT"]
    assert hdt and hdt[0]["heading_deg"] == 4.0


def test_a_sentence_cut_short_does_not_take_the_next_one_with_it():
    # the cut GGA lost its line end, so the whole HDT after it shared its line: the heading was dropped too
    d = NmeaStreamDecoder()
    out = d.feed(b"$GPGGA,130711,5012.79$HEHDT,4.0,T*2B\r\n")
    assert [u.sentence for u in out] == ["HDT"] and abs(out[0].heading_rad - 0.0698131700797731) < 1e-12
    assert d.stats.checksum_errors == 1 and d.stats.dropped == 1
    a = AisStreamDecoder()
    ais = _sentences("ais-18-27.log")[0]
    msgs = a.feed(b"!AIVDM,1,1,,A,B3KLeh" + ais + b"\r\n", 0.0)
    assert [m.mmsi for m in msgs] == [230108610]
    assert a.stats.checksum_errors == 1 and a.stats.dropped == 1


def test_cli_decodes_the_last_sentence_of_a_file_without_a_final_line_end(tmp_path, capsys):
    for end in (b"\r", b""):
        p = tmp_path / "last.log"
        p.write_bytes(b"$HEHDT,4.0,T*2B\r\n$HEHDT,5.0,T*2A" + end)
        assert main(["nmea", "--json", str(p)]) == 0
        recs = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
        assert [r["heading_deg"] for r in recs] == [4.0, 5.0]
    assert main(["nmea", "--json", "--count", "2", str(NMEA / "saab-r4.log")]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 2
