"""NMEA codec: literal lines, golden receiver captures (gpsd), and properties (hypothesis)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from autopilot.drivers.nmea import (
    ChecksumError,
    NmeaStreamDecoder,
    SentenceError,
    checksum,
    decode_line,
    make_sentence,
)
from tests.conftest import SHARED as SHARED_ROOT

SHARED = SHARED_ROOT / "nmea"
CAPTURES = sorted(SHARED.glob("*.log"))
KN_TO_M_S = 0.514444  # gpsd's knot
KNOT = 1852.0 / 3600.0  # the exact one
R = math.radians


# --------------------------------------------------------------------------- literal lines


@pytest.mark.parametrize(
    "line, expect",
    [
        ("$HEHDT,4.0,T*2B", dict(sentence="HDT", talker="HE", heading_rad=R(4.0), heading_valid=True)),
        ("$GPHDT,,T*1B", dict(sentence="HDT", heading_rad=None, heading_valid=False)),
        ("$GNTHS,244.28,A*11", dict(sentence="THS", talker="GN", heading_rad=R(244.28), ths_mode="A", heading_valid=True)),
        (make_sentence("GPTHS,12.3,V"), dict(sentence="THS", heading_rad=R(12.3), ths_mode="V", heading_valid=False)),
        (make_sentence("GPTHS,12.3,E"), dict(sentence="THS", heading_valid=True)),
        ("$HEROT,0.0,A*2B", dict(sentence="ROT", yaw_rate_rad_s=R(0.0) / 60, status_valid=True)),
        (make_sentence("HEROT,-12.5,V"), dict(sentence="ROT", yaw_rate_rad_s=R(-12.5) / 60, status_valid=False)),
        (
            make_sentence("PFEC,GPatt,123.4,-1.2,+3.4"),
            dict(sentence="PFEC_GPatt", heading_rad=R(123.4), pitch_rad=R(-1.2), roll_rad=R(3.4), heading_valid=True),
        ),
        (make_sentence("PFEC,GPatt,,,"), dict(sentence="PFEC_GPatt", heading_rad=None, heading_valid=False)),
        (make_sentence("PFEC,GPhve,-0.123,A"), dict(sentence="PFEC_GPhve", heave_m=-0.123, status_valid=True)),
        (
            "$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A",
            dict(sentence="GGA", lat_deg=50.21318, lon_deg=-8.11466, fix_quality=2, status_valid=True),
        ),
        # pynmea2 says latitude 0.0 here; an empty position must stay None
        ("$GPGGA,,,,,,0,,,,M,,M,,*66", dict(sentence="GGA", lat_deg=None, lon_deg=None, fix_quality=0, status_valid=False)),
        (
            "$GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,A*6A",
            dict(sentence="RMC", lat_deg=50.21318, sog_m_s=0.5 * KNOT, cog_rad=R(3.0), status_valid=True),
        ),
        (make_sentence("GPRMC,130711.00,V,,,,,,,010611,,,N"), dict(sentence="RMC", lat_deg=None, status_valid=False)),
        ("$GPVTG,3.0,T,,,0.50,N,,,D*16", dict(sentence="VTG", cog_rad=R(3.0), sog_m_s=0.5 * KNOT, status_valid=True)),
        ("$APHDM,218.634,M*39", dict(sentence="HDM", heading_mag_rad=R(218.634), heading_rad=None)),
        ("$APXDR,A,0.135,D,PTCH*7C", dict(sentence="XDR", pitch_rad=R(0.135), roll_rad=None)),
        ("$HEHDT,4.0,T*2b\r\n", dict(sentence="HDT", heading_rad=R(4.0))),  # lower-case hex accepted
        ("$GPHDT,360.0,T*" + checksum("GPHDT,360.0,T"), dict(heading_rad=R(0.0))),
    ],
)
def test_decode_literal(line, expect):
    u = decode_line(line)
    for key, value in expect.items():
        got = getattr(u, key)
        if isinstance(value, float):
            assert_allclose(got, value, atol=1e-9, err_msg=key)
        else:
            assert got == value, key


def test_zda_and_rmc_utc():
    u = decode_line("$GPZDA,193913.00,07,09,2018,00,00*63")
    assert u.utc.isoformat() == "2018-09-07T19:39:13+00:00"
    body = "GPRMC,130711.50,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,A"
    assert decode_line(make_sentence(body)).utc.isoformat() == "2011-06-01T13:07:11.500000+00:00"


def test_a_leap_second_is_read_as_the_second_occurrence_of_the_59th():
    leap = decode_line(make_sentence("GPGGA,235960.50,5012.790800,N,00806.879600,W,2,,,,,,,")).fix_time
    before = decode_line(make_sentence("GPGGA,235959.50,5012.790800,N,00806.879600,W,2,,,,,,,")).fix_time
    assert (leap.second, leap.microsecond, leap.fold) == (59, 500000, 1) and before.fold == 0
    rmc = decode_line(make_sentence("GPRMC,235960.00,A,5012.790800,N,00806.879600,W,0.5,3.0,311216,,A"))
    assert rmc.utc.isoformat() == "2016-12-31T23:59:59+00:00" and rmc.utc.fold == 1


@pytest.mark.parametrize(
    "line, error",
    [
        ("$GPHDT,4.0,T", ChecksumError),
        ("$GPHDT,4.0,T*2C", ChecksumError),
        ("$GPHDT,4.0,T*2", ChecksumError),
        ("$GPHDT,4.0,T*2BX", ChecksumError),
        ("GPHDT,4.0,T*2B", SentenceError),
        (make_sentence("GPHDT,nan,T"), SentenceError),
        (make_sentence("GPHDT,inf,T"), SentenceError),
        (make_sentence("GPHDT,1e2,T"), SentenceError),
        (make_sentence("GPHDT,361.0,T"), SentenceError),
        (make_sentence("GPHDT,-1.0,T"), SentenceError),
        (make_sentence("GPTHS,10.0,X"), SentenceError),
        (make_sentence("GPGGA,130711,5072.790800,N,00806.879600,W,2,,,,,,,"), SentenceError),  # 72 minutes
        (make_sentence("GPGGA,130711,9100.000000,N,00806.879600,W,2,,,,,,,"), SentenceError),
        (make_sentence("GPGGA,130711,5012.790800,X,00806.879600,W,2,,,,,,,"), SentenceError),
        (make_sentence("GPGGA,130711,5012.790800,N,,,2,,,,,,,"), SentenceError),
        (make_sentence("GPGGA,130711,abc,N,00806.879600,W,2,,,,,,,"), SentenceError),
        (make_sentence("GPRMC,130711.00,Q,5012.790800,N,00806.879600,W,0.5,3.0,010611,,A"), SentenceError),
        (make_sentence("GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,320611,,A"), SentenceError),
        (make_sentence("GPZDA,256161,01,06,2011,01,00"), SentenceError),
        (make_sentence("GPZDA,193944.00," + "9" * 300 + ",09,2018,00,00"), SentenceError),  # found by fuzz_nmea
        (make_sentence("GP"), SentenceError),
        (make_sentence("GPHDT"), SentenceError),
        # a 75th second was read as the 59th; a 60th outside 23:59 is no leap second
        (make_sentence("GPGGA,123575,5012.790800,N,00806.879600,W,2,,,,,,,"), SentenceError),
        (make_sentence("GPGGA,123560.00,5012.790800,N,00806.879600,W,2,,,,,,,"), SentenceError),
    ],
)
def test_decode_rejects(line, error):
    with pytest.raises(error):
        decode_line(line)


def test_unknown_valid_sentences_return_none():
    assert decode_line("$PFEC,AIcmd,0,35,A,01062011,130711*05") is None
    assert decode_line("$GNGSA,A,3,05,12,25,29,,,,,,,,,1.7,0.8,1.6,1*32") is None


def test_stream_counts_every_kind_of_bad_line():
    d = NmeaStreamDecoder()
    good = b"$HEHDT,4.0,T*2B\r\n"
    data = (
        b"4.0,T*2B\r\n"  # tail of a sentence cut by a reconnect
        + good
        + b"$HEHDT,4.0,T*2C\r\n"  # bad checksum
        + b"$HEHDT,4.\xff0,T*2B\r\n"  # non-ASCII
        + b"$" + b"A" * 300 + b"\r\n"  # too long, in one feed
        + make_sentence("GPHDT,nan,T").encode()  # invalid field
        + b"$GNGSA,A,3,05,12,25,29,,,,,,,,,1.7,0.8,1.6,1*32\r\n"  # unknown
        + b"\r\n\r\n"  # blank lines are not counted
    )
    updates = []
    for i in range(0, len(data), 7):  # fragments
        updates += d.feed(data[i : i + 7])
    updates += d.feed(b"x" * 1000)  # no newline: discarded, counted once
    updates += d.feed(b"y" * 1000 + b"\n" + good)
    s = d.stats.as_dict()
    assert [math.degrees(u.heading_rad) for u in updates] == pytest.approx([4.0, 4.0])
    assert s == dict(
        lines_ok=2, checksum_errors=1, garbage=1, invalid=1, unknown=1, too_long=2, non_ascii=1, dropped=6
    )


# --------------------------------------------------------------------------- golden captures


def _chk_pairs(path: Path):
    """(sentence, [JSON reports that followed it]) from a gpsfake ``.log.chk``."""
    pairs: list[tuple[str, list[dict]]] = []
    for line in path.read_text().splitlines():
        if line.startswith("{"):
            if pairs:
                pairs[-1][1].append(json.loads(line))
        elif line.strip():
            pairs.append((line, []))
    return pairs


def _compare(update, reports):
    """Field-by-field comparisons of one decoded sentence with gpsd's reports after it."""
    out = []
    for rep in reports:
        cls = rep.get("class")
        if cls == "TPV":
            if update.lat_deg is not None and "lat" in rep:
                out.append(("lat", update.lat_deg, rep["lat"], 1e-8))
                out.append(("lon", update.lon_deg, rep["lon"], 1e-8))
            if update.cog_rad is not None and "track" in rep:
                out.append(("track", math.degrees(update.cog_rad), rep["track"], 1e-3))
            if update.sog_m_s is not None and "speed" in rep and update.sentence == "RMC":
                out.append(("speed", update.sog_m_s / KNOT * KN_TO_M_S, rep["speed"], 1e-3))  # gpsd prints 3 decimals
        elif cls == "ATT":
            if update.heading_rad is not None and "heading" in rep:
                out.append(("heading", math.degrees(update.heading_rad), rep["heading"], 1e-3))
            if update.yaw_rate_rad_s is not None and "rot" in rep:
                out.append(("rot", math.degrees(update.yaw_rate_rad_s) * 60.0, rep["rot"], 1e-3))
            if update.heading_mag_rad is not None and "mheading" in rep:
                out.append(("mheading", math.degrees(update.heading_mag_rad), rep["mheading"], 1e-3))
            if update.pitch_rad is not None and "pitch" in rep:
                out.append(("pitch", math.degrees(update.pitch_rad), rep["pitch"], 1e-3))
            if update.roll_rad is not None and "roll" in rep:
                out.append(("roll", math.degrees(update.roll_rad), rep["roll"], 1e-3))
    return out


# minimum comparisons per file, so a decoder that returns nothing cannot pass
MIN_COMPARISONS = {
    "ais-18-27.log": 0,  # AIS only (no NMEA 0183 position or heading): its golden test is the AIS decoder's
    "ais-nmea.log": 200,
    "hemi.log": 4,
    "nmea-fuzzy-cases.log": 20,
    "pypilot.log": 25,
    "rst39.log": 20,
    "saab-r4.log": 20,
    "skytraq-PX1172RH_DS.log": 8,
}


@pytest.mark.parametrize("log", CAPTURES, ids=lambda p: p.name)
def test_golden_capture_matches_gpsd(log):
    compared = 0
    fields = set()
    for sentence, reports in _chk_pairs(log.with_name(log.name + ".chk")):
        if sentence.startswith("!"):  # AIS: not NMEA 0183 for us
            continue
        update = decode_line(sentence)  # real receivers' sentences must all be accepted
        if update is None:
            continue
        for name, ours, theirs, tol in _compare(update, reports):
            assert_allclose(ours, theirs, atol=tol, err_msg=f"{log.name}: {name} of {sentence}")
            compared += 1
            fields.add(name)
    assert compared >= MIN_COMPARISONS[log.name], (compared, fields)


@pytest.mark.parametrize("log", CAPTURES, ids=lambda p: p.name)
def test_golden_capture_stream_has_no_checksum_errors(log):
    """The whole file in odd-sized chunks: every sentence line is accounted for, none raises."""
    data = log.read_bytes()
    lines = [ln for ln in data.split(b"\n") if ln.strip(b"\r") and not ln.startswith(b"#")]
    d = NmeaStreamDecoder()
    n = 0
    for i in range(0, len(data), 13):
        n += len(d.feed(data[i : i + 13]))
    s = d.stats
    sentences = sum(1 for ln in lines if ln.startswith(b"$"))
    others = len(lines) - sentences  # '#' headers, gpsd's JSON echo, AIS '!' lines
    assert n == s.lines_ok
    assert (s.lines_ok > 0) == (sentences > 0)  # ais-18-27.log holds AIS ('!') lines only
    assert s.lines_ok + s.unknown == sentences
    assert s.invalid == 0
    assert s.dropped == others + sum(1 for ln in data.split(b"\n") if ln.startswith(b"#"))


# --------------------------------------------------------------------------- properties

_SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_SETTINGS
@given(st.lists(st.binary(max_size=300), max_size=10))
def test_random_bytes_never_raise(chunks):
    d = NmeaStreamDecoder()
    for c in chunks:
        d.feed(c)
    assert d.stats.dropped >= 0


_fixed = st.decimals(min_value=0, max_value="359.9", places=1).map(lambda x: f"{x:.1f}")
_signed = st.decimals(min_value="-89.9", max_value="89.9", places=1).map(lambda x: f"{x:+.1f}")


@st.composite
def valid_sentences(draw):
    talker = draw(st.sampled_from(["GP", "HE", "GN", "II"]))
    kind = draw(st.sampled_from(["HDT", "THS", "ROT", "GPatt", "GGA", "RMC", "VTG"]))
    h = draw(_fixed)
    lat = draw(st.integers(0, 89_999_999))
    lon = draw(st.integers(0, 179_999_999))
    lat_s = f"{lat // 1_000_000:02d}{(lat % 1_000_000) * 60 / 1e6:08.5f}"
    lon_s = f"{lon // 1_000_000:03d}{(lon % 1_000_000) * 60 / 1e6:08.5f}"
    ns = draw(st.sampled_from("NS"))
    ew = draw(st.sampled_from("EW"))
    if kind == "HDT":
        body = f"{talker}HDT,{h},T"
    elif kind == "THS":
        body = f"{talker}THS,{h},{draw(st.sampled_from('AEMSV'))}"
    elif kind == "ROT":
        body = f"{talker}ROT,{draw(_signed)},{draw(st.sampled_from('AV'))}"
    elif kind == "GPatt":
        body = f"PFEC,GPatt,{h},{draw(_signed)},{draw(_signed)}"
    elif kind == "GGA":
        body = f"{talker}GGA,123519.00,{lat_s},{ns},{lon_s},{ew},{draw(st.integers(0, 8))},08,0.9,545.4,M,46.9,M,,"
    elif kind == "RMC":
        body = f"{talker}RMC,123519.00,A,{lat_s},{ns},{lon_s},{ew},{draw(_fixed)},{h},230394,003.1,W,A"
    else:
        body = f"{talker}VTG,{h},T,,M,{draw(_fixed)},N,,K,A"
    return body


@_SETTINGS
@given(valid_sentences())
def test_valid_sentences_decode_and_roundtrip(body):
    line = make_sentence(body)
    u = decode_line(line)
    assert u is not None
    d = NmeaStreamDecoder()
    assert d.feed(line.encode()) == [u]
    fields = body.split(",")
    if u.heading_rad is not None and u.sentence in ("HDT", "THS"):
        assert_allclose(math.degrees(u.heading_rad), float(fields[1]) % 360.0, atol=1e-9)
    if u.lat_deg is not None:
        i = 2 if u.sentence == "GGA" else 3
        sign = 1 if fields[i + 1] == "N" else -1
        assert_allclose(u.lat_deg, sign * (int(fields[i][:2]) + float(fields[i][2:]) / 60), atol=1e-12)
        assert -90 <= u.lat_deg <= 90 and -180 <= u.lon_deg <= 180


@_SETTINGS
@given(valid_sentences(), st.data())
def test_single_byte_corruption_rejected_or_identical(body, data):
    line = make_sentence(body).encode()
    ref = NmeaStreamDecoder().feed(line)
    pos = data.draw(st.integers(0, len(line) - 1))
    byte = data.draw(st.integers(0, 255).filter(lambda b: b != line[pos]))
    bad = line[:pos] + bytes([byte]) + line[pos + 1 :] + b"\n"  # the next sentence's LF would end it
    d = NmeaStreamDecoder()
    got = d.feed(bad)
    assert got == [] or got == ref, (bad, got)
    if got == []:
        assert d.stats.dropped >= 1


def test_nan_never_decoded():
    for body in ("GPHDT,NaN,T", "GPROT,nan,A", "PFEC,GPatt,inf,0,0"):
        assert NmeaStreamDecoder().feed(make_sentence(body).encode()) == []
    u = decode_line(make_sentence("GPVTG,0.0,T,,M,0.0,N,,K,A"))
    assert math.isfinite(u.sog_m_s)


# --------------------------------------------------------------------------- the encoder, round trips

@_SETTINGS
@given(st.floats(0.0, 2 * math.pi, exclude_max=True), st.sampled_from(["HDT", "THS", "PFEC_GPatt"]))
def test_heading_round_trip(heading_rad, kind):
    from autopilot.drivers.nmea import encode_heading

    u = decode_line(make_sentence(encode_heading(kind, heading_rad)))
    assert u.sentence == kind and u.heading_valid
    err_deg = (math.degrees(u.heading_rad - heading_rad) + 180.0) % 360.0 - 180.0
    assert abs(err_deg) <= 0.05 + 1e-9  # the SC-30's 0.1 deg resolution
    assert decode_line(make_sentence(encode_heading(kind, None))).heading_valid is False


@_SETTINGS
@given(st.floats(-89.9, 89.9), st.floats(-179.9, 179.9), st.floats(0.0, 5.0), st.floats(0.0, 2 * math.pi, exclude_max=True),
       st.sampled_from(["GGA", "RMC", "GLL", "VTG"]), st.floats(0.0, 86399.0))
@example(0.0, 0.0, 0.0, 0.0, "GGA", 59.99609375)  # hypothesis found it: written "000060.00", read back as 00:00:59
@example(0.0, 0.0, 0.0, 0.0, "GGA", 0.975)  # 97.5 hundredths written .98; round(0.975, 2) is 0.97: both within 5 ms
def test_position_round_trip(lat, lon, sog, cog, kind, t_day):
    from autopilot.drivers.nmea import encode_position

    u = decode_line(make_sentence(encode_position(kind, t_of_day_s=t_day, lat_deg=lat, lon_deg=lon, sog_m_s=sog,
                                                  cog_rad=cog)))
    assert u.sentence == kind and u.status_valid
    if kind != "VTG":
        assert_allclose([u.lat_deg, u.lon_deg], [lat, lon], atol=1e-6)  # 1e-5 minutes
        assert u.fix_time is not None and abs(u.fix_time.hour * 3600 + u.fix_time.minute * 60 + u.fix_time.second
                                              + u.fix_time.microsecond / 1e6 - t_day) <= 0.005 + 1e-9  # hhmmss.ss
    if kind in ("RMC", "VTG"):
        assert abs(u.sog_m_s - sog) <= 0.005 * KNOT + 1e-9
        assert abs((math.degrees(u.cog_rad - cog) + 180) % 360 - 180) <= 0.05 + 1e-9
    lost = decode_line(make_sentence(encode_position(kind, t_of_day_s=t_day)))
    assert lost.status_valid is False and lost.lat_deg is None


def test_rot_round_trip():
    from autopilot.drivers.nmea import encode_rot

    for r in (-1.6, -0.01, 0.0, 0.35):
        u = decode_line(make_sentence(encode_rot(r)))
        assert u.yaw_rate_rad_s == pytest.approx(r, abs=math.radians(0.05) / 60)


@pytest.mark.parametrize("body, valid", [
    ("GPGGA,130711,5012.790800,N,00806.879600,W,1,08,1.0,10.0,M,,M,,", True),
    ("GPGGA,130711,5012.790800,N,00806.879600,W,5,08,1.0,10.0,M,,M,,", True),  # float RTK
    ("GPGGA,130711,5012.790800,N,00806.879600,W,6,08,1.0,10.0,M,,M,,", False),  # the receiver's dead reckoning
    ("GPGGA,130711,5012.790800,N,00806.879600,W,7,08,1.0,10.0,M,,M,,", False),  # typed in
    ("GPGGA,130711,5012.790800,N,00806.879600,W,8,08,1.0,10.0,M,,M,,", False),  # its simulator
    ("GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,,D", True),
    ("GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,", True),  # NMEA 2.2: no mode
    ("GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,,E", False),
    ("GPRMC,130711.00,A,5012.790800,N,00806.879600,W,0.5,3.0,010611,,,S", False),
    ("GPGLL,5012.790800,N,00806.879600,W,130711,A,M", False),
    ("GPGLL,5012.790800,N,00806.879600,W,130711,A,A", True),
])
def test_only_a_measured_position_is_a_valid_fix(body, valid):
    """A GGA of quality 6 (estimated) or a mode-E RMC was a valid fix: a receiver dead reckoning through an
    outage, or left in its simulator mode, would have steered the boat as if it knew where it was."""
    assert decode_line(make_sentence(body)).status_valid is valid
