"""AIS codec: golden captures against gpsd's decodings, the assembler, the target table, the NMEA hook, fuzz."""

from __future__ import annotations

import json
import math
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from autopilot.drivers.ais import (
    AisChecksumError,
    AisConfig,
    AisDecodeError,
    AisReceiver,
    AisSentenceError,
    AisStreamDecoder,
    AisUnsupportedError,
    FragmentAssembler,
    TargetTable,
    decode_sentences,
    parse_fragment,
)
from autopilot.drivers.framing import xor_checksum
from autopilot.drivers.nmea import NmeaStreamDecoder, make_sentence
from autopilot.simdev.traffic import encode_ais
from tests.conftest import SHARED as SHARED_ROOT

SHARED = SHARED_ROOT / "nmea"
KNOT = 1852.0 / 3600.0

# gpsd's type 5 of SEA ENTERPRISE, two fragments (ais-nmea.log)
TYPE5 = (
    "!AIVDM,2,1,9,B,55R3Vn82=ILTQ3KKS>1<D60Dq@E918U<F222221J1`?164vc03S1CCAD,0*2A",
    "!AIVDM,2,2,9,B,`88888888888880,2*76",
)
TYPE1 = "!AIVDM,1,1,,B,13aDp<PP000IwSlN?Wm@0?wN2<1T,0*29"  # heading 511, turn -128: not available


def _frame(body: str) -> str:
    return f"!{body}*{xor_checksum(body)}"


# --------------------------------------------------------------------------- golden: gpsd's decodings


def _chk_ais(path):
    """(the '!' sentence, gpsd's AIS reports right after it) from a ``.log.chk``. gpsd repeats a report
    after later '$' sentences; only the one after the '!' line itself is its decoding."""
    out = []
    last = None
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("{"):
            rep = json.loads(line)
            if rep.get("class") == "AIS" and last is not None and last.startswith("!") and out and out[-1][0] == last:
                out[-1][1].append(rep)
        elif line.strip():
            last = line
            if line.startswith("!"):
                out.append((line, []))
    return out


def _raw_speed_m_s(v):  # gpsd unscaled: tenths of a knot, 1023 = not available
    return None if v == 1023 else v / 10.0 * KNOT


def _raw_course_rad(v):  # tenths of a degree, 3600 = not available
    return None if v >= 3600 else math.radians(v / 10.0)


def _raw_heading_rad(v):  # degrees, 511 = not available; gpsd passes 360..510 through, we call them invalid (None)
    return None if v >= 360 else math.radians(v)


def _raw_latlon(rep):  # 1/10000 minute; 91 / 181 degrees = not available
    lat, lon = rep["lat"] / 600000.0, rep["lon"] / 600000.0
    return (None, None) if abs(lat) > 90 or abs(lon) > 180 else (lat, lon)


def _raw_turn_rad_s(v):  # ROT_AIS: +-127 and -128 = no turn indicator
    if abs(v) >= 127:
        return None
    return math.radians(math.copysign((v / 4.733) ** 2, v)) / 60.0


def _raw_dim(v):
    return None if v == 0 else float(v)


def _compare(msg, target, rep):
    """(name, ours, gpsd's, tolerance) for the fields gpsd reports. None must match None."""
    out = [("mmsi", msg.mmsi, rep["mmsi"], 0)]
    if "lat" in rep and rep["type"] in (1, 2, 3, 18, 19):
        lat, lon = _raw_latlon(rep)
        out += [("lat", msg.lat_deg, lat, 1e-6), ("lon", msg.lon_deg, lon, 1e-6)]  # 1e-6 deg: pyais rounds there
        out += [("speed", msg.sog_m_s, _raw_speed_m_s(rep["speed"]), 1e-9)]
        out += [("course", msg.cog_rad, _raw_course_rad(rep["course"]), 1e-9)]
        out += [("heading", msg.heading_rad, _raw_heading_rad(rep["heading"]), 1e-9)]
    if "turn" in rep:
        # pyais rounds (raw / 4.733)^2 to whole degrees per minute
        out.append(("turn", msg.turn_rad_s, _raw_turn_rad_s(rep["turn"]), math.radians(0.5) / 60.0))
    src = target if rep["type"] == 24 else msg  # gpsd reports type 24 once it has both parts
    if "shipname" in rep:
        out.append(("shipname", src.shipname, rep["shipname"] or None, None))
    if "callsign" in rep:
        out.append(("callsign", src.callsign, rep["callsign"] or None, None))
    if "shiptype" in rep:
        out.append(("shiptype", src.ship_type, rep["shiptype"] or None, 0))  # 0 = not available
    for k in ("to_bow", "to_stern", "to_port", "to_starboard"):
        if k in rep:
            out.append((k, getattr(src, k + "_m"), _raw_dim(rep[k]), 0))
    return out


# a floor per file, well under what the decoder makes, so an empty or lazy decoder cannot pass
MIN_COMPARISONS = {"ais-nmea.log": 900, "ais-18-27.log": 400}
MIN_MESSAGES = {"ais-nmea.log": 150, "ais-18-27.log": 60}


@pytest.mark.parametrize("name", sorted(MIN_COMPARISONS))
def test_golden_capture_matches_gpsd(name):
    rx = AisReceiver()
    compared = messages = unsupported_seen = 0
    fields = set()
    for t, (sentence, reports) in enumerate(_chk_ais(SHARED / (name + ".chk"))):
        msgs = rx.feed_line(sentence, now_s=float(t))
        for rep in reports:
            if rep["type"] not in (1, 2, 3, 5, 18, 19, 24):
                assert not msgs, f"type {rep['type']} must not be decoded: {sentence}"
                unsupported_seen += 1
                continue
            assert len(msgs) == 1, f"gpsd decoded {sentence} (type {rep['type']}), we did not"
            msg = msgs[0]
            assert msg.msg_type == rep["type"]
            target = rx.table.get(msg.mmsi)
            for field, ours, theirs, tol in _compare(msg, target, rep):
                if theirs is None or ours is None or tol is None:
                    assert ours == theirs, f"{name}: {field} of {sentence}: {ours!r} != {theirs!r}"
                else:
                    assert_allclose(ours, theirs, atol=tol, rtol=0, err_msg=f"{name}: {field} of {sentence}")
                compared += 1
                fields.add(field)
            messages += 1
    assert compared >= MIN_COMPARISONS[name], (compared, sorted(fields))
    assert messages >= MIN_MESSAGES[name]
    assert unsupported_seen > 0  # both files hold types we do not use (8, 27): they were not decoded
    s = rx.stats
    assert s.checksum_errors == s.invalid == s.unassembled == 0


def test_golden_fields_cover_what_the_avoidance_needs():
    """Across both captures, every field the target table offers was compared at least once with a value."""
    seen = set()
    for name in MIN_COMPARISONS:
        rx = AisReceiver()
        for t, (sentence, reports) in enumerate(_chk_ais(SHARED / (name + ".chk"))):
            msgs = rx.feed_line(sentence, now_s=float(t))
            for rep in reports:
                if msgs:
                    for field, ours, theirs, _ in _compare(msgs[0], rx.table.get(msgs[0].mmsi), rep):
                        if ours is not None and theirs is not None:
                            seen.add(field)
    assert {"mmsi", "lat", "lon", "speed", "course", "heading", "turn", "shipname", "callsign", "shiptype",
            "to_bow", "to_stern", "to_port", "to_starboard"} <= seen


@pytest.mark.parametrize("name", sorted(MIN_COMPARISONS))
def test_golden_stream_in_odd_chunks(name):
    """The raw capture byte by byte in 13-byte chunks: the same messages as line by line, no rejections
    beyond the comment header, the other lines accounted for."""
    data = (SHARED / name).read_bytes()
    d = AisStreamDecoder()
    msgs = []
    for i in range(0, len(data), 13):
        msgs += d.feed(data[i : i + 13], now_s=i / 4800.0)
    lines = [ln for ln in data.split(b"\n") if ln.strip(b"\r")]
    bang = sum(1 for ln in lines if ln.startswith(b"!"))
    others = len(lines) - bang  # '#' header and '$' NMEA lines: garbage to an AIS-only decoder
    s = d.stats
    assert s.lines_ok == bang
    assert s.garbage == others
    assert s.messages == len(msgs) >= MIN_MESSAGES[name]
    assert s.checksum_errors == s.invalid == s.unassembled == s.non_ascii == 0


# --------------------------------------------------------------------------- literal sentences


def test_type5_two_fragments():
    m = decode_sentences(TYPE5)
    assert (m.msg_type, m.mmsi, m.ais_class, m.own_ship) == (5, 371255000, "A", False)
    assert (m.shipname, m.callsign, m.ship_type) == ("SEA ENTERPRISE", "HP6683", 90)
    assert (m.to_bow_m, m.to_stern_m, m.to_port_m, m.to_starboard_m) == (13.0, 15.0, 1.0, 6.0)
    assert m.lat_deg is None and m.sog_m_s is None


def test_type1_not_available_values_are_none():
    m = decode_sentences([TYPE1])
    assert m.heading_rad is None and m.turn_rad_s is None
    assert m.sog_m_s == 0.0 and m.cog_rad == 0.0
    assert_allclose((m.lat_deg, m.lon_deg), (52.855395, 5.678283), atol=1e-6)


@pytest.mark.parametrize(
    "fields, expect",
    [
        # lat 91 / lon 181: no position; speed 102.3 kn, course 360, heading 511: not available
        (dict(lat=91.0, lon=181.0, speed=102.3, course=360.0, heading=511), dict(lat_deg=None, sog_m_s=None,
                                                                                 cog_rad=None, heading_rad=None)),
        (dict(lat=-33.5, lon=151.25, speed=12.5, course=359.9, heading=359),
         dict(lat_deg=-33.5, lon_deg=151.25, sog_m_s=12.5 * KNOT, cog_rad=math.radians(359.9),
              heading_rad=math.radians(359))),
        (dict(lat=10.0, lon=20.0, speed=102.2, course=0.0, heading=0), dict(sog_m_s=102.2 * KNOT, cog_rad=0.0)),
    ],
)
@pytest.mark.parametrize("msg_type", [1, 18])
def test_position_report_values_in_si(msg_type, fields, expect):
    lines = encode_ais({"type": msg_type, "mmsi": 244000001, **fields}, channel="A",
                        sentence_type="VDM")
    m = decode_sentences(lines)
    assert m.ais_class == ("A" if msg_type == 1 else "B")
    for k, v in expect.items():
        got = getattr(m, k)
        if v is None:
            assert got is None, k
        else:
            assert_allclose(got, v, atol=1e-6, err_msg=k)


def test_turn_rate_sign_and_units():
    # ROT_AIS = 4.733 sqrt(deg/min): 30 deg/min to starboard is +26 (pyais rounds back to 30)
    lines = encode_ais({"type": 1, "mmsi": 244000001, "turn": 30.0, "lat": 1.0, "lon": 2.0}, sentence_type="VDM")
    assert_allclose(decode_sentences(lines).turn_rad_s, math.radians(30.0) / 60.0, rtol=0.05)
    lines = encode_ais({"type": 1, "mmsi": 244000001, "turn": -30.0, "lat": 1.0, "lon": 2.0}, sentence_type="VDM")
    assert decode_sentences(lines).turn_rad_s < 0


def test_type19_and_type24_parts():
    m19 = decode_sentences(encode_ais({"type": 19, "mmsi": 338000001, "lat": 1.0, "lon": 2.0, "speed": 5.0,
                                        "course": 90.0, "heading": 91, "shipname": "SLOOP", "to_bow": 7,
                                        "to_stern": 3, "to_port": 2, "to_starboard": 2}, sentence_type="VDM"))
    assert (m19.msg_type, m19.ais_class, m19.shipname, m19.to_bow_m) == (19, "B", "SLOOP", 7.0)
    assert_allclose(m19.cog_rad, math.pi / 2)
    a = decode_sentences(encode_ais({"type": 24, "mmsi": 338000002, "partno": 0, "shipname": "DINGHY"},
                                     sentence_type="VDM"))
    b = decode_sentences(encode_ais({"type": 24, "mmsi": 338000002, "partno": 1, "ship_type": 37,
                                      "callsign": "AB1234", "to_bow": 4, "to_stern": 1, "to_port": 1,
                                      "to_starboard": 1}, sentence_type="VDM"))
    assert (a.part, a.shipname, a.to_bow_m) == ("A", "DINGHY", None)
    assert (b.part, b.callsign, b.ship_type, b.to_bow_m, b.to_stern_m) == ("B", "AB1234", 37, 4.0, 1.0)


@pytest.mark.parametrize(
    "line, error",
    [
        (TYPE1[:-2] + "00", AisChecksumError),
        (TYPE1.split("*")[0], AisChecksumError),
        (_frame("AIVDM,1,1,,B,13aDp<PP000IwSlN?Wm@0?wN2<1T"), AisSentenceError),  # 6 fields
        (_frame("AIVDM,2,3,1,B,13aDp,0"), AisSentenceError),  # fragment 3 of 2
        (_frame("AIVDM,0,1,,B,13aDp,0"), AisSentenceError),
        (_frame("AIVDM,1,1,,C,13aDp,0"), AisSentenceError),  # channel C
        (_frame("AIVDM,1,1,,A,13aDp,6"), AisSentenceError),  # fill bits 6
        (_frame("AIVDM,1,1,,A,13a~p,0"), AisSentenceError),  # '~' is not in the 6-bit armouring
        (_frame("AIVDM,1,1,,A,,0"), AisSentenceError),
        (_frame("GPVDM,1,1,,A,13aD,0").replace("!", "$"), AisSentenceError),
        (_frame("AIABK,123456789,A,8,1,0"), AisSentenceError),  # valid, but not a VDM/VDO
    ],
)
def test_bad_fragments_are_refused(line, error):
    with pytest.raises(error):
        parse_fragment(line)


def test_unsupported_and_undecodable_payloads():
    with pytest.raises(AisUnsupportedError):  # type 4, base station report
        decode_sentences(encode_ais({"type": 4, "mmsi": 2442000, "lat": 1.0, "lon": 2.0}, sentence_type="VDM"))
    with pytest.raises(AisDecodeError):  # a type 1 cut to 60 bits
        decode_sentences([_frame("AIVDM,1,1,,A,13aDp<PP000I,0")])
    with pytest.raises(AisDecodeError):  # MMSI 0
        decode_sentences(encode_ais({"type": 1, "mmsi": 0, "lat": 1.0, "lon": 2.0}, sentence_type="VDM"))


# --------------------------------------------------------------------------- assembly


def test_assembler_out_of_order_duplicates_and_timeout():
    a, b = (parse_fragment(s) for s in TYPE5)
    asm = FragmentAssembler(timeout_s=2.0)
    assert asm.push(b, 0.0) is None  # second part first: no part 1 before it, dropped (IEC 61162-1 sends in order)
    assert asm.unassembled == 1 and asm.pending == 0
    assert asm.push(a, 0.5) is None
    assert [f.number for f in asm.push(b, 0.6)] == [1, 2]
    assert asm.unassembled == 1 and asm.pending == 0
    assert asm.push(a, 10.0) is None
    assert asm.push(a, 10.1) is None  # part 1 again: the first attempt is dropped
    assert asm.unassembled == 2
    assert asm.push(b, 12.5) is None  # 2.4 s after its part 1: that one timed out, and this one follows nothing
    assert asm.unassembled == 4 and asm.pending == 0
    assert asm.push(a, 13.0) is None
    asm.expire(20.0)
    assert asm.unassembled == 5 and asm.pending == 0


def test_a_lost_part_does_not_join_the_next_message_with_the_same_key():
    """Found by a review: with parts accepted in any order, the part 2 of a message whose part 1 was lost waited,
    and the part 1 of the next message under the same key (the sequence id comes round every ten messages; some
    receivers leave it empty) completed it: the second vessel's part 1 with the first's part 2 (its destination,
    not decoded here), nothing counted lost, and the second's own part 2 left waiting to join the next."""
    one = encode_ais({"type": 5, "mmsi": 244000001, "shipname": "ONE", "destination": "ROTTERDAM EUROPOORT"},
                     sentence_type="VDM", channel="A", seq_id=3)
    two = encode_ais({"type": 5, "mmsi": 244000002, "shipname": "TWO", "destination": "HAMBURG ALTONA HAFEN"},
                     sentence_type="VDM", channel="A", seq_id=3)
    assert len(one) == len(two) == 2 and one[1] != two[1]
    asm = FragmentAssembler(timeout_s=2.0)
    assert asm.push(parse_fragment(one[1]), 0.0) is None  # ONE's part 1 lost
    assert asm.push(parse_fragment(two[0]), 0.2) is None
    joined = asm.push(parse_fragment(two[1]), 0.4)
    assert [f.raw for f in joined] == two
    assert asm.unassembled == 1 and asm.pending == 0
    d = AisStreamDecoder()
    msgs = []
    for t, line in enumerate((one[1], two[0], two[1])):
        msgs += d.feed((line + "\r\n").encode(), now_s=0.2 * t)
    assert [(m.mmsi, m.shipname) for m in msgs] == [(244000002, "TWO")]
    assert d.stats.unassembled == 1 and d.pending_fragments == 0


def test_interleaved_multipart_messages_by_sequence_id_and_channel():
    """Two type 5 messages interleaved fragment by fragment (different sequence ids) both decode;
    the same sequence id on the other channel is another message."""
    one = encode_ais({"type": 5, "mmsi": 244000001, "shipname": "ONE", "to_bow": 10}, sentence_type="VDM",
                      channel="A", seq_id=1)
    two = encode_ais({"type": 5, "mmsi": 244000002, "shipname": "TWO", "to_bow": 20}, sentence_type="VDM",
                      channel="A", seq_id=2)
    three = encode_ais({"type": 5, "mmsi": 244000003, "shipname": "THREE"}, sentence_type="VDM",
                        channel="B", seq_id=1)
    assert len(one) == len(two) == len(three) == 2
    d = AisStreamDecoder()
    msgs = []
    for t, line in enumerate((one[0], two[0], three[0], one[1], three[1], two[1])):
        msgs += d.feed((line + "\r\n").encode(), now_s=0.1 * t)
    assert sorted(m.shipname for m in msgs) == ["ONE", "THREE", "TWO"]
    assert d.stats.unassembled == 0


def test_stream_counts_a_lost_fragment_as_unassembled_after_the_timeout():
    d = AisStreamDecoder(assembly_timeout_s=2.0)
    assert d.feed((TYPE5[0] + "\r\n").encode(), 0.0) == []
    assert d.pending_fragments == 1
    assert d.feed((TYPE1 + "\r\n").encode(), 3.0)  # any later line expires the orphan
    assert d.stats.unassembled == 1 and d.stats.dropped == 1 and d.pending_fragments == 0


# --------------------------------------------------------------------------- target table


def _pos(mmsi, t, table, *, lat=52.0, lon=5.0, speed=10.0, course=90.0, own=False, msg_type=1):
    lines = encode_ais({"type": msg_type, "mmsi": mmsi, "lat": lat, "lon": lon, "speed": speed, "course": course,
                         "heading": int(course)}, sentence_type="VDO" if own else "VDM")
    rx = AisReceiver()
    (m,) = rx.feed_line(lines[0], t)
    return table.update(m, t)


def test_table_keeps_targets_by_mmsi_with_age_and_drops_stale():
    table = TargetTable(AisConfig(stale_after_s=60.0))
    _pos(244000001, 0.0, table)
    _pos(244000002, 30.0, table, speed=3.0)
    _pos(244000001, 40.0, table, lat=52.001)
    t1 = table.get(244000001)
    assert t1.messages == 2 and t1.position_t_s == 40.0 and t1.age_s(45.0) == 5.0
    assert_allclose((t1.lat_deg, t1.sog_m_s, t1.cog_rad), (52.001, 10 * KNOT, math.pi / 2), atol=1e-6)
    assert [t.mmsi for t in table.targets(89.0)] == [244000001, 244000002]
    assert table.prune(90.5) == (244000002,)  # 60.5 s since its only report
    assert [t.mmsi for t in table.targets(100.0)] == [244000001]
    assert table.targets(100.1) == [] and table.dropped_stale == 2
    assert len(table) == 0


def test_table_merges_static_and_position_reports():
    rx = AisReceiver()
    rx.feed_line(TYPE5[0], 0.0)
    rx.feed_line(TYPE5[1], 0.0)
    assert rx.targets(1.0) == []  # known only by name: no position, not a target to avoid yet
    t = rx.table.targets(with_position=False)[0]
    assert (t.shipname, t.length_m, t.beam_m, t.extent_m) == ("SEA ENTERPRISE", 28.0, 7.0, 15.0)
    pos = encode_ais({"type": 1, "mmsi": 371255000, "lat": 52.8, "lon": 5.7, "speed": 8.0, "course": 45.0,
                       "heading": 44}, sentence_type="VDM")
    rx.feed_line(pos[0], 5.0)
    (t,) = rx.targets(6.0)
    assert t.shipname == "SEA ENTERPRISE" and t.length_m == 28.0 and t.static_t_s == 0.0 and t.position_t_s == 5.0
    assert_allclose(t.heading_rad, math.radians(44))
    # a later report with speed and course "not available" says so: they become None
    na = encode_ais({"type": 1, "mmsi": 371255000, "lat": 52.8, "lon": 5.7, "speed": 102.3, "course": 360.0,
                      "heading": 511}, sentence_type="VDM")
    rx.feed_line(na[0], 9.0)
    (t,) = rx.targets(9.0)
    assert t.sog_m_s is None and t.cog_rad is None and t.heading_rad is None and t.shipname == "SEA ENTERPRISE"


def test_table_class_b_name_from_24a_dimensions_from_24b():
    rx = AisReceiver()
    for line in (encode_ais({"type": 18, "mmsi": 338000002, "lat": 1.0, "lon": 2.0, "speed": 4.0, "course": 10.0},
                             sentence_type="VDM")
                 + encode_ais({"type": 24, "mmsi": 338000002, "partno": 0, "shipname": "DINGHY"}, sentence_type="VDM")
                 + encode_ais({"type": 24, "mmsi": 338000002, "partno": 1, "to_bow": 4, "to_stern": 1, "to_port": 1,
                                "to_starboard": 1}, sentence_type="VDM")):
        rx.feed_line(line, 1.0)
    (t,) = rx.targets(2.0)
    assert (t.ais_class, t.shipname, t.length_m, t.beam_m) == ("B", "DINGHY", 5.0, 2.0)


def test_own_ship_is_kept_apart():
    table = TargetTable(AisConfig(own_mmsi=244999999))
    _pos(244000001, 0.0, table)
    _pos(244123456, 0.0, table, own=True)  # VDO: own ship, whatever the MMSI
    assert table.own.mmsi == 244123456
    _pos(244999999, 1.0, table)  # VDM echo of the configured own MMSI
    assert table.own.mmsi == 244999999
    assert [t.mmsi for t in table.targets(2.0)] == [244000001]


def test_receiver_survives_a_failing_callback():
    def boom(msg):
        raise RuntimeError("log full")

    rx = AisReceiver(on_message=boom)
    assert len(rx.feed_line(TYPE1, 0.0)) == 1 and rx.callback_errors == 1 and len(rx.targets(0.0)) == 1


def test_table_is_bounded():
    table = TargetTable(AisConfig(max_targets=3))
    for k in range(5):
        _pos(244000001 + k, float(k), table)
    assert len(table) == 3 and table.evicted == 2
    assert [t.mmsi for t in table.targets()] == [244000003, 244000004, 244000005]


# --------------------------------------------------------------------------- the NMEA hook


def test_nmea_stream_hands_ais_lines_to_the_receiver():
    """AIS interleaved on the compass line: '$' lines to the NMEA decoder, '!' lines to the AIS receiver;
    neither counts the other's lines as garbage."""
    data = (SHARED / "ais-nmea.log").read_bytes()
    rx = AisReceiver(clock_s=lambda: 0.0)
    nmea = NmeaStreamDecoder(encapsulated=rx.feed_line)
    for i in range(0, len(data), 29):
        nmea.feed(data[i : i + 29])
    bang = sum(1 for ln in data.split(b"\n") if ln.startswith(b"!"))
    assert nmea.encapsulated_lines == bang == rx.stats.lines_ok
    assert nmea.stats.garbage == sum(1 for ln in data.split(b"\n") if ln.startswith(b"#"))
    assert rx.stats.messages >= MIN_MESSAGES["ais-nmea.log"] and rx.stats.dropped == 0
    assert len(rx.targets(0.0)) >= 10
    # without the hook the old behaviour stands: '!' lines are garbage to the compass decoder
    plain = NmeaStreamDecoder()
    plain.feed(data)
    assert plain.stats.garbage == nmea.stats.garbage + bang and plain.encapsulated_lines == 0


def test_nmea_hook_failure_does_not_stop_the_compass_line():
    def boom(line):
        raise RuntimeError("hook")

    d = NmeaStreamDecoder(encapsulated=boom)
    out = d.feed((TYPE1 + "\r\n" + make_sentence("GPHDT,12.3,T")).encode())
    assert [u.sentence for u in out] == ["HDT"] and d.encapsulated_lines == 1


def test_an_ais_line_that_lost_its_line_end_does_not_swallow_the_compass_sentence_after_it():
    """Found by fault injection: '!AIVDM...*hh$GPGGA...*hh' (the AIS line's CR LF lost) went whole to the AIS
    receiver: every GGA behind such a line vanished, counted nowhere (position_stale with no cause in the log)."""
    rx = AisReceiver(clock_s=lambda: 0.0)
    d = NmeaStreamDecoder(encapsulated=rx.feed_line)
    hdt = make_sentence("GPHDT,12.3,T")
    out = d.feed((TYPE1 + hdt + "\r\n" + TYPE1 + "\r\n").encode())
    assert [u.sentence for u in out] == ["HDT"] and out[0].heading_rad == pytest.approx(math.radians(12.3))
    assert d.encapsulated_lines == 2 and rx.stats.lines_ok == 2  # the AIS part was not lost either
    assert d.stats.garbage == 0 and d.stats.checksum_errors == 0



def test_an_ais_sentence_behind_a_cut_compass_sentence_is_read():
    """Found by fault injection: a compass sentence cut short ('$GPGGA,1235' with its line end lost) and the AIS
    sentence after it went together into one checksum error: the vessel report was lost, and the count blamed the
    compass line for two sentences."""
    rx = AisReceiver(clock_s=lambda: 0.0)
    d = NmeaStreamDecoder(encapsulated=rx.feed_line)
    gga = make_sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    out = d.feed((gga[:20] + TYPE1 + "\r\n" + make_sentence("GPHDT,12.3,T")).encode())
    assert [u.sentence for u in out] == ["HDT"]
    assert d.stats.checksum_errors == 1 and d.encapsulated_lines == 1
    assert rx.stats.lines_ok == 1 and rx.stats.messages == 1


def test_two_whole_compass_sentences_on_one_line_are_both_read():
    """A lost line end between two whole sentences: each has its checksum, so neither is a cut one."""
    d = NmeaStreamDecoder()
    hdt = make_sentence("GPHDT,12.3,T")
    rot = make_sentence("GPROT,-3.5,A")
    out = d.feed((hdt.strip() + rot).encode())
    assert [u.sentence for u in out] == ["HDT", "ROT"]
    assert d.stats.checksum_errors == 0 and d.stats.lines_ok == 2

# --------------------------------------------------------------------------- never raises

_GOOD = [ln for name in MIN_COMPARISONS for ln in (SHARED / name).read_bytes().split(b"\n") if ln.startswith(b"!")]
_SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)


def _mutate(rng: random.Random, line: bytes) -> bytes:
    b = bytearray(line)
    for _ in range(rng.randint(1, 3)):
        op = rng.randrange(4)
        i = rng.randrange(len(b)) if b else 0
        if op == 0 and b:
            b[i] = rng.randrange(256)
        elif op == 1:
            b.insert(i, rng.choice(b",!*0w`\x00\xff"))
        elif op == 2 and b:
            del b[i]
        else:
            b = b[: i or 1]
    return bytes(b)


@_SETTINGS
@given(st.lists(st.binary(max_size=200), max_size=8), st.floats(0, 1e6))
def test_random_bytes_never_raise(chunks, t0):
    d = AisStreamDecoder()
    for k, c in enumerate(chunks):
        for m in d.feed(c, t0 + k):
            assert 0 < m.mmsi <= 999_999_999
    assert d.stats.dropped >= 0


@_SETTINGS
@given(st.integers(0, 2**32 - 1), st.integers(1, 40))
def test_mutated_real_lines_never_raise_and_decode_in_range(seed, n):
    rng = random.Random(seed)
    d = AisStreamDecoder()
    stream = b"".join((_mutate(rng, ln) if rng.random() < 0.7 else ln) + b"\r\n" for ln in rng.sample(_GOOD, n))
    pos = 0
    while pos < len(stream):
        step = rng.randint(1, 90)
        for m in d.feed(stream[pos : pos + step], pos / 4800.0):
            if m.lat_deg is not None:
                assert abs(m.lat_deg) <= 90 and abs(m.lon_deg) <= 180
            assert m.sog_m_s is None or 0 <= m.sog_m_s < 102.3 * KNOT
            assert m.cog_rad is None or 0 <= m.cog_rad < 2 * math.pi
            assert m.heading_rad is None or 0 <= m.heading_rad < 2 * math.pi
        pos += step
    s = d.stats
    assert s.lines_ok + s.dropped + s.unknown >= 0


def test_the_receiver_loads_its_decoder_when_made_not_at_the_first_message():
    """Found by fault injection: the first AIS sentence on the compass line imported pyais inside the control
    loop (~0.25 s here) and the loop stalled 340 ms, two deadlines skipped."""
    import subprocess
    import sys

    code = ("import sys\nfrom autopilot.drivers.ais import AisReceiver\nassert 'pyais.messages' not in sys.modules\n"
            "AisReceiver()\nprint('pyais.messages' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "True"


def test_a_report_without_a_position_keeps_the_vessel_where_it_was_last_seen():
    """Found by a traffic audit: a report with "position not available" (lat 91, lon 181) from a vessel already placed
    wrote over its position, and the vessel vanished from collision avoidance at once, 60 m ahead on the track. Its
    last position stays, ageing from its last real report, until it is stale."""
    from pyais import encode_dict

    from autopilot.drivers.ais import AisReceiver

    def report(lat, lon):
        return encode_dict(dict(type=1, mmsi=211000003, lat=lat, lon=lon, speed=1.0, course=90.0, heading=90),
                           talker_id="AI", sentence_type="VDM")[0]

    rx = AisReceiver()
    rx.feed_line(report(52.8428, 5.7058), 0.0)
    rx.feed_line(report(91.0, 181.0), 10.0)
    (t,) = rx.targets(11.0)
    assert (round(t.lat_deg, 4), round(t.lon_deg, 4), t.position_t_s) == (52.8428, 5.7058, 0.0)
    assert t.messages == 2 and t.last_t_s == 10.0
    rx2 = AisReceiver()  # never placed: no position to keep, not a target to steer round
    rx2.feed_line(report(91.0, 181.0), 0.0)
    assert rx2.targets(1.0) == []


def test_a_vessel_without_course_or_speed_moves_by_its_heading_or_its_track():
    """Found by an AIS audit: course 360 or speed 102.3 kn ("not available") made a vessel at 3.9 kn a stopped one
    in collision avoidance. With a speed, its heading is its course; otherwise its track between two reports."""
    from autopilot.geo import local_to_latlon
    from autopilot.gnc.encounter import TargetState

    origin = (52.0, 5.0)
    rx = AisReceiver()

    def report(t_s, north_m, **fields):
        lat, lon = local_to_latlon(north_m, 0.0, *origin)
        rx.feed_line(encode_ais({"type": 1, "mmsi": 244000501, "lat": lat, "lon": lon, **fields},
                                sentence_type="VDM")[0], t_s)
        (t,) = rx.targets(t_s)
        return t, TargetState.from_ais(t, origin_lat_deg=origin[0], origin_lon_deg=origin[1], now_s=t_s)

    _, by_heading = report(0.0, 0.0, speed=3.9, course=360.0, heading=180)
    assert by_heading.motion_known and by_heading.speed_m_s == pytest.approx(3.9 * 1852 / 3600)
    assert by_heading.course_rad == pytest.approx(math.pi)
    t, by_track = report(10.0, -20.0, speed=102.3, course=360.0, heading=511)  # 20 m south in 10 s
    assert t.sog_m_s is None and t.cog_rad is None and t.track_ne_m_s == pytest.approx((-2.0, 0.0), abs=0.01)
    assert by_track.motion_known and by_track.speed_m_s == pytest.approx(2.0, abs=0.01)
    assert abs(by_track.course_rad) == pytest.approx(math.pi, abs=0.01)
    _, twice = report(10.4, -20.0, speed=102.3, course=360.0, heading=511)  # the same report on the other channel
    assert twice.speed_m_s == pytest.approx(2.0, abs=0.01)
    _, unknown = report(300.0, -20.0, speed=102.3, course=360.0, heading=511)  # 290 s after the last: no track
    assert not unknown.motion_known and unknown.speed_m_s == 0.0


def test_a_relayed_copy_of_a_report_is_not_a_new_position():
    """Found by a review: a repeater's copy (repeat indicator 1) of a report already heard, 2.5 s later, made a
    vessel moving at 2 m/s "known stopped" (its track 0) and its next real report 2.6 m/s (a short interval)."""
    from autopilot.geo import local_to_latlon

    origin = (52.0, 5.0)
    rx = AisReceiver()

    def report(t_s, north_m, repeat=0):
        lat, lon = local_to_latlon(north_m, 0.0, *origin)
        rx.feed_line(encode_ais({"type": 18, "mmsi": 244000501, "repeat": repeat, "lat": lat, "lon": lon,
                                 "speed": 102.3, "course": 360.0, "heading": 511}, sentence_type="VDM")[0], t_s)
        (t,) = rx.targets(t_s)
        return t

    report(0.0, 0.0)
    assert report(30.0, 60.0).track_ne_m_s == pytest.approx((2.0, 0.0), abs=0.05)
    copy = report(32.5, 60.0, repeat=1)
    assert copy.track_ne_m_s == pytest.approx((2.0, 0.0), abs=0.05) and copy.position_t_s == 30.0
    assert report(40.0, 80.0).track_ne_m_s == pytest.approx((2.0, 0.0), abs=0.05)
    moved = report(50.0, 100.0, repeat=1)  # a relayed report of a position not heard: the best there is
    assert moved.position_t_s == 50.0


def test_each_sentence_of_a_line_that_lost_its_line_end_has_its_own_span_on_the_wire():
    """Found by a review: every sentence of such a line was given the whole line's span, so the second heading was
    dated where the first began on the wire (the SC-30's tick clock then took it for a restarted device and reset);
    each now has its own: from its '$' to the next, the last with the line end."""
    d = NmeaStreamDecoder()
    h9, h10, tail = make_sentence("GPHDT,9.0,T").strip(), make_sentence("GPHDT,10.0,T"), b"$GPRO"
    spans = d.feed_spans((h9 + h10).encode() + tail)
    assert [(u.heading_rad, c, a) for u, c, a in spans] == [
        (pytest.approx(math.radians(9.0)), len(h9), len(h10) + len(tail)),
        (pytest.approx(math.radians(10.0)), len(h10), len(tail))]


def test_the_ais_port_reads_each_sentence_of_a_line_that_lost_its_line_end():
    """Found by a review: the AIS port's decoder read only from a line's last '!': the two parts of a type 5 on one
    line (the first's line end lost) were a checksum error and a part 2 without its part 1, and a fragment with a
    GPS sentence behind it was lost, counted invalid."""
    d = AisStreamDecoder()
    msgs = d.feed((TYPE5[0] + TYPE5[1] + "\r\n").encode(), 0.0)
    assert [m.msg_type for m in msgs] == [5]
    assert d.stats.checksum_errors == 0 and d.stats.unassembled == 0 and d.stats.lines_ok == 2
    msgs = d.feed((TYPE1 + make_sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")).encode(), 1.0)
    assert [m.msg_type for m in msgs] == [1]
    assert d.stats.unknown == 1 and d.stats.invalid == 0 and d.stats.checksum_errors == 0
    msgs = d.feed((TYPE1[:20] + TYPE1 + "\r\n").encode(), 2.0)  # a fragment cut short, a whole one after it
    assert [m.msg_type for m in msgs] == [1] and d.stats.checksum_errors == 1
