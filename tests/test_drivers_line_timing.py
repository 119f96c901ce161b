"""Measurement times of sentences on a paced serial line (drivers/line_timing.py): pure rules, then the
SC-30 driver against the simulated SC-30 on a real pseudo-terminal at 4800 baud, where a heading waits
up to a quarter of a second behind the 1 Hz sentences."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from autopilot.drivers.line_timing import IDLE_GAP_S, TickClock, WireClock

CHAR_4800_S = 10.0 / 4800


def test_a_line_began_its_own_characters_before_its_end():
    wire = WireClock(4800)
    start, idle = wire.line(10.0, 19, 0)  # an HDT alone in its read
    assert start == pytest.approx(10.0 - 19 * CHAR_4800_S) and idle
    # two lines in one read (the loop was late): the first ended where the second began
    start_a, _ = wire.line(11.0, 72, 19)
    start_b, idle_b = wire.line(11.0, 19, 0)
    assert start_a == pytest.approx(11.0 - 91 * CHAR_4800_S)
    assert start_b == pytest.approx(11.0 - 19 * CHAR_4800_S) and not idle_b  # it followed the GGA: busy


def test_idle_means_a_gap_longer_than_read_jitter():
    wire = WireClock(4800)
    wire.line(1.0, 19, 0)
    _, idle = wire.line(1.0 + 19 * CHAR_4800_S + 0.5 * IDLE_GAP_S, 19, 0)
    assert not idle
    _, idle = wire.line(2.0, 19, 0)
    assert idle


def test_queued_headings_belong_to_consecutive_ticks_and_an_idle_one_re_anchors():
    ticks = TickClock(0.1)
    assert ticks.measured(0.004, idle=True) == pytest.approx(0.004)  # the first marks the grid
    # the next four waited behind 1 Hz sentences: made 0.1 s apart whatever their start
    assert [round(ticks.measured(s, idle=False), 6) for s in (0.19, 0.38, 0.48, 0.60)] == [0.104, 0.204, 0.304, 0.404]
    # idle again, read 0.5 ms late: the tick is the grid's, not the late read
    assert ticks.measured(0.5045, idle=True) == pytest.approx(0.504)
    # an idle one read earlier than any before moves the grid to it (reads are never early)
    assert ticks.measured(0.6032, idle=True) == pytest.approx(0.6032)
    assert ticks.measured(0.7051, idle=True) == pytest.approx(0.7032)


def test_late_reads_do_not_move_the_ticks():
    """A device ticking every 100 ms, read with 0-20 ms of random latency (a loaded machine): every tick
    recovered within the least latency seen, where the reads themselves are up to 20 ms late."""
    rng = np.random.default_rng(1)
    ticks = TickClock(0.1)
    made = 7.0123 + 0.1 * np.arange(300)
    err = [ticks.measured(t + rng.exponential(0.004), idle=True) - t for t in made]
    assert max(abs(e) for e in err[20:]) < 0.002, max(err[20:])


def test_a_tick_never_comes_after_its_sentence_began_and_a_long_gap_re_anchors():
    ticks = TickClock(0.1)
    ticks.measured(1.0, idle=True)
    assert ticks.measured(1.05, idle=False) == pytest.approx(1.05)  # 1.1 would be after it began, 1.0 is taken: here
    assert ticks.measured(3.0, idle=False) == pytest.approx(2.95)  # lost for two seconds: the last grid tick


@pytest.mark.parametrize("baud", [4800, 38400])
def test_the_driver_stamps_each_heading_with_its_tick_not_its_arrival(tmp_path, baud):
    """The simulated SC-30 records the tick each sentence was made at; the driver, reading the pseudo-
    terminal, stamps every heading within a few milliseconds of it (the read jitter of a sped-up clock),
    where its arrival is up to ~0.26 s late at 4800 baud."""
    from autopilot.clock import Clock
    from autopilot.drivers.sc30 import SC30Driver
    from autopilot.sim import default_params_path, load_params
    from autopilot.simdev.boat import SimBoat
    from autopilot.simdev.sc30 import SimulatedSC30

    boat = SimBoat(load_params(default_params_path()), origin_lat_deg=52.0, origin_lon_deg=4.4,
                   x0=(0.0, 0.0, 0.3, 1.0, 0.0, 0.2))  # turning: every heading differs
    clock = Clock(4.0)
    sc30 = SimulatedSC30(boat, clock, directory=tmp_path, seed=4, baudrate=baud)
    stamped: list[tuple[float, float, float]] = []  # (stamp, arrival, heading)

    async def fly():
        await sc30.start()
        drv = SC30Driver(sc30.endpoint.path, baudrate=baud, clock=clock)
        apply = drv.apply

        def spy(u, t_s):
            if u.sentence == "HDT":
                stamped.append((t_s, clock.now_s(), round(math.degrees(u.heading_rad), 1)))
            apply(u, t_s)

        drv.apply = spy
        task = asyncio.create_task(drv.run())
        await clock.sleep_until(clock.now_s() + 6.0)
        task.cancel()
        await drv.close()
        await sc30.stop()

    asyncio.run(fly())
    made_all = [(round(float(line.split(",")[1]), 1), t) for t, line in sc30.made_log if line[3:6] == "HDT"]
    counts: dict[float, int] = {}
    for h, _ in made_all:
        counts[h] = counts.get(h, 0) + 1
    made = {h: t for h, t in made_all if counts[h] == 1}  # a heading value sent once names its sentence
    err_stamp = np.array([s - made[h] for s, _, h in stamped if h in made])
    err_arrival = np.array([a - made[h] for _, a, h in stamped if h in made])
    assert err_stamp.size >= 40
    assert np.percentile(np.abs(err_stamp), 95) < 0.012, np.sort(err_stamp)[-5:]
    if baud == 4800:
        assert np.percentile(err_arrival, 95) > 0.15  # what the old stamps were off by
