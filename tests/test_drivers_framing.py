"""Line framing and garbage bursts (autopilot.drivers.framing), and one GNSS epoch = one fix in the SC-30 driver."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.drivers.framing import GarbageDetector, LineFramer
from autopilot.drivers.nmea import make_sentence
from autopilot.drivers.sc30 import SC30Driver


def test_framer_keeps_partial_lines_and_counts_bad_bytes():
    f = LineFramer(20)
    assert f.feed(b"$A*00\r") == []
    assert f.feed(b"\n$B") == [b"$A*00\r"]
    assert f.feed(b"*11\r\n\xff\x00ok\n") == [b"$B*11\r", b"\xff\x00ok"]
    assert f.invalid_bytes == 2  # 0xff and NUL; CR and LF are line bytes


def test_framer_discards_overlong_lines_once():
    f = LineFramer(10)
    assert f.feed(b"x" * 25) == [] and f.too_long == 1
    assert f.feed(b"yyy\n$OK\n") == [b"$OK"] and f.too_long == 1  # the tail of the long line is dropped with it
    assert f.feed(b"z" * 11 + b"\n") == [] and f.too_long == 2


def test_random_bytes_at_4800_baud_are_a_burst_within_a_tenth_of_a_second():
    """At the real line rate: 48 bytes every 0.1 s; ~2 line ends a second, so the line count alone never fires."""
    rng = np.random.default_rng(5)
    det, f = GarbageDetector(max_lines=5, max_bytes=32), LineFramer(200)
    rejected = 0
    started_at = None
    for k in range(100):  # 10 s
        t = 0.1 * k
        rejected += len(f.feed(rng.integers(0, 256, 48, dtype=np.uint8).tobytes())) + 0
        if det.feed(t, rejected + f.too_long, f.invalid_bytes) and started_at is None:
            started_at = t
    assert started_at is not None and started_at <= 0.1
    assert det.bursts == 1 and det.last_garbage_s == pytest.approx(9.9)  # held while it lasts


def test_line_count_alone_misses_line_rate_noise():
    rng = np.random.default_rng(5)
    det, f = GarbageDetector(max_lines=5, max_bytes=10**9), LineFramer(200)
    lines = 0
    fired = False
    for k in range(100):
        lines += len(f.feed(rng.integers(0, 256, 48, dtype=np.uint8).tobytes()))
        fired |= det.feed(0.1 * k, lines + f.too_long, f.invalid_bytes)
    assert not fired  # the old detector's blind spot


def test_one_burst_holds_from_its_last_garbage_not_a_window_later():
    det = GarbageDetector(max_lines=5, max_bytes=32)
    assert det.feed(10.0, 20, 0)  # 20 malformed lines at once
    for t in np.arange(10.1, 12.0, 0.1):
        assert not det.feed(t, 20, 0)
    assert det.last_garbage_s == 10.0  # the failsafe holds garbage_hold_s from here, not from 11.0
    assert not det.in_burst


def test_a_single_flipped_bit_is_not_a_burst():
    det = GarbageDetector(max_lines=5, max_bytes=32)
    assert not det.feed(1.0, 1, 1) and det.last_garbage_s is None


class _Clock:
    def __init__(self):
        self.t = 0.0

    def now_s(self):
        return self.t


def test_gga_and_rmc_of_one_epoch_are_one_fix():
    clock = _Clock()
    drv = SC30Driver("/dev/null", clock=clock)
    gga = make_sentence("GPGGA,120000.00,5200.00000,N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,")
    rmc = make_sentence("GPRMC,120000.00,A,5200.00000,N,00424.00000,E,2.00,90.0,010624,,,A")
    gga2 = make_sentence("GPGGA,120001.00,5200.00100,N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,")
    clock.t = 10.15
    drv._on_bytes(gga.encode())
    clock.t = 10.35
    drv._on_bytes(rmc.encode())
    # the RMC repeats the epoch; the fix is dated when its GGA began on the 4800 baud line (drivers/line_timing.py)
    assert drv.sample().position.t_s == pytest.approx(10.15 - len(gga) * 10 / 4800) and drv.sample().position.source == "GGA"
    assert drv.sample().sog_m_s.value == pytest.approx(2.0 * 1852 / 3600)  # what only the RMC carries is still taken
    clock.t = 11.15
    drv._on_bytes(gga2.encode())
    assert drv.sample().position.t_s == pytest.approx(11.15 - len(gga2) * 10 / 4800)  # the next epoch is a new fix


def test_a_leap_second_is_its_own_epoch_and_not_merged_with_the_second_before():
    """23:59:60 (a leap second, as the receiver sends it) was read as 23:59:59 and folded into that
    epoch's fix: the boat's position went a second without a fresh fix."""
    clock = _Clock()
    drv = SC30Driver("/dev/null", clock=clock)
    stamps = []
    for k, (hms, lat_min) in enumerate([("235959.00", "00.00000"), ("235960.00", "00.00100"), ("000000.00", "00.00200")]):
        gga = make_sentence(f"GPGGA,{hms},52{lat_min},N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,")
        clock.t = 10.15 + 0.98 * k  # a 1 Hz receiver's epochs arrive a little under a second apart at times
        drv._on_bytes(gga.encode())
        stamps.append(drv.sample().position.t_s)
        assert drv.sample().position.value[0] == pytest.approx(52.0 + float(lat_min) / 60.0)
    assert np.all(np.diff(stamps) > 0.9)  # three fixes, each dated by its own GGA


def _gga(hms: str, lat_min: str = "00.00000") -> bytes:
    return make_sentence(f"GPGGA,{hms},52{lat_min},N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,").encode()


class _Events:
    def __init__(self):
        self.seen = []

    def __call__(self, event, **fields):
        self.seen.append((event, fields))


def test_a_held_fix_repeated_every_second_ages_instead_of_looking_fresh():
    """A receiver (or a multiplexer) that keeps sending its last solution, UTC time and all, was re-stamped
    as a new fix each second once the last stamp was a second old: the failsafe never saw the position age."""
    clock = _Clock()
    drv = SC30Driver("/dev/null", clock=clock)
    for k in range(6):
        clock.t = 10.0 + k
        drv._on_bytes(_gga("120000.00"))
    assert drv.sample().position.t_s == pytest.approx(10.0 - len(_gga("120000.00")) * 10 / 4800)
    clock.t = 16.0
    drv._on_bytes(_gga("120001.00", "00.00100"))  # the receiver moves on: a new fix
    assert drv.sample().position.t_s == pytest.approx(16.0 - len(_gga("120001.00")) * 10 / 4800)


def test_a_held_fix_without_a_utc_time_ages_too():
    """Found by fault injection: a receiver repeating its last solution with the GGA time field empty looked fresh
    for as long as it repeated it (10 s at full thrust, the real boat 9 m on): without a time every sentence was a
    new epoch. Now the very position of the last fix, without a time to tell, is the same fix."""
    clock = _Clock()
    drv = SC30Driver("/dev/null", clock=clock)
    timeless = make_sentence("GPGGA,,5200.00000,N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,").encode()
    for k in range(6):
        clock.t = 10.0 + k
        drv._on_bytes(timeless)
    assert drv.sample().position.t_s == pytest.approx(10.0 - len(timeless) * 10 / 4800)
    clock.t = 16.0
    moved = make_sentence("GPGGA,,5200.00100,N,00424.00000,E,1,10,0.9,1.0,M,30.0,M,,").encode()
    drv._on_bytes(moved)  # a different position: a new fix (nothing else to go by)
    assert drv.sample().position.t_s == pytest.approx(16.0 - len(moved) * 10 / 4800)


def test_a_receiver_whose_rmc_says_not_valid_beside_a_valid_gga_keeps_the_fix_not_valid():
    """Found by fault injection: RMC status V with a position, beside GGA quality 1, made the fix valid (GGA) and
    not valid (RMC) by turns: a no_fix fault and its clearing twice a second for as long as it lasted."""
    clock = _Clock()
    drv = SC30Driver("/dev/null", clock=clock)
    validity = []
    for k in range(5):
        hms = f"1200{k:02d}.00"
        clock.t = 10.0 + k
        drv._on_bytes(_gga(hms))
        validity.append(drv.sample().position.valid)
        clock.t += 0.1
        drv._on_bytes(make_sentence(f"GPRMC,{hms},V,5200.00000,N,00424.00000,E,0.0,0.0,010624,,,N").encode())
        validity.append(drv.sample().position.valid)
    assert validity == [True] + [False] * 9  # the first GGA, before any RMC had spoken; then never valid
    clock.t = 15.0
    drv._on_bytes(_gga("120005.00"))
    drv._on_bytes(make_sentence("GPRMC,120005.00,A,5200.00000,N,00424.00000,E,0.0,0.0,010624,,,A").encode())
    clock.t = 16.0
    drv._on_bytes(_gga("120006.00"))
    assert drv.sample().position.valid  # both agree again


def test_an_epoch_before_the_last_is_refused_once_noted_and_a_receiver_reset_is_accepted():
    clock = _Clock()
    events = _Events()
    drv = SC30Driver("/dev/null", clock=clock, events=events)
    clock.t = 10.0
    drv._on_bytes(_gga("120005.00", "00.00500"))
    first = drv.sample().position
    for k, hms in enumerate(("120003.00", "120004.00")):  # a replayed recording of the seconds before
        clock.t = 11.0 + k
        drv._on_bytes(_gga(hms, "00.00300"))
        assert drv.sample().position == first
    assert drv.stats["old_epochs"] == 2
    assert [e for e, _ in events.seen if e == "nmea_old_epoch"] == ["nmea_old_epoch"]  # once per run of them
    clock.t = 13.0
    drv._on_bytes(_gga("115000.00", "00.00900"))  # 15 min back: the receiver's clock started over
    assert drv.sample().position.value[0] == pytest.approx(52.0 + 0.009 / 60.0) and drv.sample().position.t_s > 12.8
    clock.t = 14.0
    drv._on_bytes(_gga("000000.00", "00.00800"))  # and the day rolls over forward
    assert drv.sample().position.t_s > 13.8


@pytest.mark.parametrize("last, new, order", [
    ("235959.50", "235960.00", "new"), ("235960.90", "000000.00", "new"), ("235960.00", "235959.00", "old"),
    ("120000.00", "120000.00", "same"), ("120001.00", "120000.00", "old"), ("122000.00", "120000.00", "new"),
    ("235959.00", "000001.00", "new"), ("000001.00", "235958.00", "old")])
def test_epoch_order_across_midnight_and_the_leap_second(last, new, order):
    from autopilot.drivers.nmea import decode_line
    from autopilot.drivers.sc30 import epoch_order

    def t(hms):
        return decode_line(_gga(hms).decode()).fix_time

    assert epoch_order(t(new), t(last)) == order
