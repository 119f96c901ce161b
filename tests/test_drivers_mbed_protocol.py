"""Mbed line protocol (docs/mbed-protocol.md): literal lines, round trips, ack decoder properties."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autopilot.drivers.mbed_protocol import (
    Ack,
    Command,
    ProtocolError,
    decode_ack,
    decode_command,
    encode_ack,
    encode_command,
)
from autopilot.drivers.nmea import make_sentence


def test_doc_example():
    assert encode_command(42, 60.0, False, 20.0, True) == b"$MBCMD,42,F,60.0,R,20.0*7F\r\n"
    assert decode_command(b"$MBCMD,42,F,60.0,R,20.0*7F\r\n") == Command(42, 60.0, False, 20.0, True)
    assert decode_ack(encode_ack(42, "OK", 60.0, False, 20.0, True)) == Ack(42, "OK", 60.0, False, 20.0, True)


def test_seq_wraps_and_duty_rounds():
    assert encode_command(65536 + 3, 12.34, False, 0, False).startswith(b"$MBCMD,3,F,12.3,F,0.0*")
    assert decode_command(encode_command(65535, 100.0, True, 0.0, False)).seq == 65535


@pytest.mark.parametrize(
    "args",
    [
        (1, 100.1, False, 0.0, False),
        (1, -0.1, False, 0.0, False),
        (1, float("nan"), False, 0.0, False),
        (1, float("inf"), False, 0.0, False),
        (-1, 0.0, False, 0.0, False),
        (1.5, 0.0, False, 0.0, False),
    ],
)
def test_encode_command_refuses(args):
    with pytest.raises(ProtocolError):
        encode_command(*args)


@pytest.mark.parametrize(
    "line, reason",
    [
        (b"$MBACK,1,OK,F,10.0,F,10.0*00\r\n", None),  # checksum
        (b"MBACK,1,OK,F,10.0,F,10.0\r\n", None),
        (make_sentence("MBACK,1,OK,F,10.0,F").encode(), None),
        (make_sentence("MBACK,1,OK,X,10.0,F,10.0").encode(), None),
        (make_sentence("MBACK,1,OK,F,100.1,F,10.0").encode(), None),
        (make_sentence("MBACK,70000,OK,F,10.0,F,10.0").encode(), None),
        (make_sentence("MBACK,1,MAYBE").encode(), None),
        (make_sentence("MBACK,1,REJ,WHY").encode(), None),
        (make_sentence("GPHDT,1.0,T").encode(), None),
        (b"$MBACK,1,OK,F,10.0,F,1\xff.0*00\r\n", None),
        (make_sentence("MBACK,1,OK,F,10.0,F,10.0,12.4,1").encode(), None),  # one field too many
        (make_sentence("MBACK,1,OK,F,10.0,F,10.0,124.0").encode(), None),  # battery_v: 1-2 integer digits
        (make_sentence("MBACK,1,OK,F,10.0,F,10.0,-1.0").encode(), None),
        (make_sentence("MBACK,1,OK,F,10.0,F,10.0,12.345").encode(), None),
        (make_sentence("MBACK,1,OK,F,10.0,F,10.0,V").encode(), None),
    ],
)
def test_decode_ack_rejects(line, reason):
    with pytest.raises(ProtocolError):
        decode_ack(line)


def test_battery_voltage_field_is_optional_and_old_acks_still_decode():
    """docs/mbed-protocol.md: the 7th field of OK, volts; firmware without it sends six fields."""
    line = encode_ack(42, "OK", 60.0, False, 20.0, True, battery_v=12.43)
    assert line == make_sentence("MBACK,42,OK,F,60.0,R,20.0,12.43").encode()
    assert decode_ack(line).battery_v == 12.43
    assert decode_ack(make_sentence("MBACK,42,OK,F,60.0,R,20.0").encode()).battery_v is None  # old firmware
    assert decode_ack(make_sentence("MBACK,42,OK,F,60.0,R,20.0,").encode()).battery_v is None  # cannot measure
    assert decode_ack(make_sentence("MBACK,7,OK,F,0.0,F,0.0,9.8").encode()).battery_v == 9.8
    with pytest.raises(ProtocolError):
        encode_ack(1, "OK", battery_v=float("nan"))


def test_decode_ack_ignores_blank_and_status_lines():
    assert decode_ack(b"\r\n") is None
    assert decode_ack(make_sentence("MBRDY,1.0").encode()) is None
    assert decode_ack(encode_ack(5, "REJ", reason="RANGE")) == Ack(5, "REJ", reason="RANGE")


@pytest.mark.parametrize(
    "body, reason",
    [("MBCMD,9,F,150.0,F,0.0", "RANGE"), ("MBCMD,9,F,50.0,X,0.0", "FORMAT"), ("MBCMD,9,F,50.0", "FORMAT"),
     ("MBCMD,99999,F,50.0,F,0.0", "RANGE"), ("MBCMD,9,F,5.55,F,0.0", "FORMAT")],
)
def test_command_rejection_reasons(body, reason):
    with pytest.raises(ProtocolError) as exc:
        decode_command(make_sentence(body))
    assert exc.value.reason == reason


_duty = st.integers(0, 1000).map(lambda x: x / 10.0)


@settings(max_examples=300, deadline=None)
@given(st.integers(0, 10**6), _duty, st.booleans(), _duty, st.booleans())
def test_command_and_ack_roundtrip(seq, dp, rp, ds, rs):
    cmd = decode_command(encode_command(seq, dp, rp, ds, rs))
    assert cmd == Command(seq % 65536, dp, rp, ds, rs)
    assert decode_ack(encode_ack(cmd.seq, "OK", dp, rp, ds, rs)) == Ack(seq % 65536, "OK", dp, rp, ds, rs)


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.binary(max_size=100), st.text(max_size=100)))
def test_decode_ack_random_input_only_protocol_errors(data):
    try:
        ack = decode_ack(data)
    except ProtocolError:
        return
    assert ack is None or isinstance(ack, Ack)


@settings(max_examples=500, deadline=None)
@given(st.integers(0, 65535), _duty, st.booleans(), _duty, st.booleans(), st.data())
def test_ack_single_byte_corruption_rejected_or_identical(seq, dp, rp, ds, rs, data):
    line = encode_ack(seq, "OK", dp, rp, ds, rs)
    pos = data.draw(st.integers(0, len(line) - 3))  # CR LF excluded: the framer splits on LF
    byte = data.draw(st.integers(0, 255).filter(lambda b: b != line[pos]))
    bad = line[:pos] + bytes([byte]) + line[pos + 1 :]
    try:
        ack = decode_ack(bad)
    except ProtocolError:
        return
    assert ack == decode_ack(line)  # e.g. lower-case hex digit in the checksum
