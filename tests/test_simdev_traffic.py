"""Simulated traffic: scenarios, kinematics, report schedule, and the AIS round trip (pure and through a pty)."""

from __future__ import annotations

import asyncio
import math

import pytest
from numpy.testing import assert_allclose

from autopilot.clock import SimClock
from autopilot.drivers.ais import AisReceiver
from autopilot.drivers.ais_device import AisDriver
from autopilot.evaluate import _scenario_paths, shipped_scenarios
from autopilot.geo import latlon_to_local
from autopilot.gnc.encounter import OwnShip
from autopilot.schema import ConfigError
from autopilot.simdev.pty import PtyEndpoint
from autopilot.simdev.traffic import (
    STATIC_INTERVAL_S,
    TrafficEmitter,
    TrafficSim,
    kinematics_at,
    load_scenario,
    report_times,
    sentences_between,
)

SCENARIO = {
    "name": "mixed",
    "targets": [
        {"mmsi": 244000001, "name": "FERRY", "north_m": 200.0, "east_m": 10.0, "course_deg": 180.0, "speed_m_s": 3.0,
         "length_m": 30.0, "beam_m": 8.0},
        {"mmsi": 338000002, "name": "SLOOP", "ais_class": "B", "north_m": 50.0, "east_m": -100.0, "course_deg": 90.0,
         "speed_m_s": 1.5, "behaviour": "turn", "turn_rate_deg_s": 2.0, "turn_from_s": 10.0, "turn_until_s": 40.0},
        {"mmsi": 244000003, "name": "FAST", "lat_deg": 34.8210, "lon_deg": 135.5230, "course_deg": 45.0,
         "speed_m_s": 8.0, "report_interval_s": 2.0},
    ],
}


def test_scenario_is_checked():
    sc = load_scenario(SCENARIO)
    assert [t.mmsi for t in sc.targets] == [244000001, 338000002, 244000003]
    with pytest.raises(ConfigError, match="one pair"):
        load_scenario({"targets": [{"mmsi": 1, "north_m": 1.0}]})
    with pytest.raises(ConfigError, match="share an MMSI"):
        load_scenario({"targets": [{"mmsi": 1, "north_m": 1.0, "east_m": 0.0}, {"mmsi": 1, "north_m": 2.0, "east_m": 0.0}]})
    with pytest.raises(ConfigError, match="unknown key"):
        load_scenario({"targets": [{"mmsi": 1, "north_m": 1.0, "east_m": 0.0, "colour": "red"}]})
    with pytest.raises(ConfigError, match="behaviour"):
        load_scenario({"targets": [{"mmsi": 1, "north_m": 1.0, "east_m": 0.0, "behaviour": "zigzag"}]})


def test_turning_kinematics_closed_form_matches_integration():
    sc = load_scenario(SCENARIO)
    spec = sc.targets[1]
    n, e, chi, dt = 50.0, -100.0, math.radians(90.0), 0.001
    t = 0.0
    while t < 60.0 - 1e-9:
        rate = math.radians(2.0) if 10.0 <= t < 40.0 else 0.0
        n += 1.5 * math.cos(chi + rate * dt / 2) * dt
        e += 1.5 * math.sin(chi + rate * dt / 2) * dt
        chi += rate * dt
        t += dt
    k = kinematics_at(sc, spec, 60.0)
    assert_allclose((k.north_m, k.east_m), (n, e), atol=5e-3)  # the integration steps 1 ms across the turn edges
    assert_allclose(math.degrees(k.course_rad), 150.0, atol=1e-6)  # 90 + 2 deg/s x 30 s
    assert kinematics_at(sc, spec, 20.0).turn_rate_rad_s == pytest.approx(math.radians(2.0))
    assert kinematics_at(sc, spec, 50.0).turn_rate_rad_s == 0.0


def test_report_intervals_follow_itu_r_m1371():
    sc = load_scenario(SCENARIO)
    ferry, sloop, fast = sc.targets

    def gaps(spec, t1):
        ts = [t for t, k in report_times(sc, spec, -1.0, t1) if k == "position"]
        return [round(b - a, 6) for a, b in zip(ts, ts[1:])]

    assert set(gaps(ferry, 100.0)) == {10.0}  # class A at 5.8 kn: 10 s
    assert set(gaps(fast, 20.0)) == {2.0}  # the scenario's override
    sloop_gaps = gaps(sloop, 200.0)
    assert set(sloop_gaps) == {30.0}  # class B CS above 2 kn: 30 s (the turn does not change class B's rate)
    statics = [t for t, k in report_times(sc, ferry, -1.0, 800.0) if k == "static"]
    assert len(statics) == 3 and statics[0] < 0.1 and statics[1] - statics[0] == STATIC_INTERVAL_S
    # a class A that turns reports every 3.3 s while turning
    turner = load_scenario({"targets": [{"mmsi": 5, "north_m": 0.0, "east_m": 0.0, "speed_m_s": 3.0,
                                         "behaviour": "turn", "turn_rate_deg_s": 1.0, "turn_from_s": 0.0}]})
    ts = [t for t, k in report_times(turner, turner.targets[0], -1.0, 30.0) if k == "position"]
    assert_allclose([b - a for a, b in zip(ts, ts[1:])], 3.3)


def test_sentences_are_pure_and_windowed():
    sc = load_scenario(SCENARIO)
    whole = sentences_between(sc, -1.0, 60.0)
    split = sentences_between(sc, -1.0, 25.0) + sentences_between(sc, 25.0, 60.0)
    assert whole == split == sentences_between(sc, -1.0, 60.0)
    assert all(s.startswith("!AIVDM,") for _, s in whole)
    assert any(s.startswith("!AIVDM,2,1,") for _, s in whole)  # type 5 in two parts


def test_round_trip_decoded_targets_are_the_scenario():
    sc = load_scenario(SCENARIO)
    rx = AisReceiver()
    last: dict[int, float] = {}
    for t, s in sentences_between(sc, -1.0, 95.0):
        for m in rx.feed_line(s, t):
            if m.has_position:
                last[m.mmsi] = t
    s = rx.stats
    assert s.dropped == 0 and s.lines_ok > s.messages  # every line accepted; multi-part assembled
    targets = {t.mmsi: t for t in rx.targets(95.0)}
    assert set(targets) == {t.mmsi for t in sc.targets}
    for spec in sc.targets:
        tg = targets[spec.mmsi]
        k = kinematics_at(sc, spec, last[spec.mmsi])
        n, e = latlon_to_local(tg.lat_deg, tg.lon_deg, sc.origin_lat_deg, sc.origin_lon_deg)
        assert_allclose((n, e), (k.north_m, k.east_m), atol=0.15)  # 1e-6 deg in the sentence
        assert_allclose(tg.sog_m_s, k.speed_m_s, atol=0.03)  # 0.1 kn
        assert_allclose(math.degrees(tg.cog_rad), math.degrees(k.course_rad), atol=0.06)  # 0.1 deg
        assert tg.shipname == spec.name and tg.ais_class == spec.ais_class
        assert tg.length_m == round(spec.length_m) and tg.beam_m == round(spec.beam_m)


def test_gives_way_target_turns_to_starboard_for_us_and_comes_back():
    sc = load_scenario({"targets": [{"mmsi": 9, "north_m": 100.0, "east_m": -150.0, "course_deg": 90.0,
                                     "speed_m_s": 1.5, "behaviour": "gives_way"}]})
    sim = TrafficSim(sc)
    courses = []
    for k in range(0, 1200):
        t = k * 0.25
        own = OwnShip(north_m=min(t, 60.0), east_m=0.0, course_rad=0.0, speed_m_s=1.0 if t < 60 else 0.0,
                      heading_rad=0.0)
        (kin,) = sim.step(t, own)
        courses.append(math.degrees(kin.course_rad))
    assert max(courses) == pytest.approx(90.0 + 40.0, abs=0.5)  # its give-way alteration, to starboard
    assert courses[-1] == pytest.approx(90.0, abs=0.5)  # and back once past
    straight = TrafficSim(load_scenario({"targets": [{**sc.targets[0].__dict__, "behaviour": "straight"}]}))
    assert all(k.course_rad == pytest.approx(math.pi / 2) for k in [straight.step(10.0, OWN_AT_ORIGIN)[0]])


OWN_AT_ORIGIN = OwnShip(0.0, 0.0, 0.0, 1.0, 0.0)


def test_emitter_through_a_pty_to_the_ais_driver(tmp_path):
    """The emitter on a pty at 38400 baud, the AIS driver on the other end, lockstep simulated time:
    the driver's targets are the scenario's, and the line was never faster than 3840 characters a second."""
    sc = load_scenario(SCENARIO)

    async def main():
        clock = SimClock()
        ep = PtyEndpoint(tmp_path, "ais")
        drv = AisDriver(ep.path, clock=clock)
        clock.set_quiet(lambda: drv.transport.bytes_in >= ep.bytes_written)
        em = TrafficEmitter(sc, clock, ep)
        tasks = [asyncio.create_task(drv.run()), asyncio.create_task(clock.drive())]
        await em.start()
        await clock.sleep_until(45.0)
        targets = {t.mmsi: t for t in drv.targets()}
        now = clock.now_s()
        await em.stop()
        clock.stop()
        await drv.close()
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        ep.close()
        return targets, now, em, drv

    targets, now, em, drv = asyncio.run(asyncio.wait_for(main(), 60))
    assert set(targets) == {t.mmsi for t in sc.targets}
    assert drv.receiver.stats.dropped == 0 and em.sentences_sent >= 20
    for spec in sc.targets:
        tg = targets[spec.mmsi]
        k = kinematics_at(sc, spec, tg.position_t_s)  # scenario time 0 = clock time 0 here
        n, e = latlon_to_local(tg.lat_deg, tg.lon_deg, sc.origin_lat_deg, sc.origin_lon_deg)
        # received at most a tick (0.1 s) plus the line time after it was due
        assert math.hypot(n - k.north_m, e - k.east_m) <= spec.speed_m_s * 0.2 + 0.15
        assert tg.shipname == spec.name
    # pacing: consecutive writes are at least their own line time apart
    for (t0, s0), (t1, s1) in zip(em.sent_log, em.sent_log[1:]):
        assert t1 - t0 >= (len(s1) + 2) * 10.0 / 38400 - 1e-9


def test_a_scenario_without_targets_is_refused_and_traffic_takes_no_plot_or_mission(tmp_path, capsys):
    """Found by a new-user audit: an empty scenario file was scored (a blank name, closest distance inf, "kept
    yes", exit 0); `evaluate --traffic` ignored --plot and --mission without a word."""
    from autopilot.cli import main
    from autopilot.schema import ConfigError

    (tmp_path / "empty.yaml").write_text("")
    with pytest.raises(ConfigError, match="the scenario is empty"):
        load_scenario(tmp_path / "empty.yaml")
    with pytest.raises(ConfigError, match="targets: a traffic scenario needs at least one target"):
        load_scenario({"name": "nothing", "targets": []})
    assert main(["evaluate", "--traffic", str(tmp_path / "empty.yaml"), "--condition", "calm"]) == 2
    assert main(["evaluate", "--traffic", "head-on", "--condition", "calm", "--plot", str(tmp_path / "p")]) == 2
    assert "--plot is not for --traffic" in capsys.readouterr().err and not (tmp_path / "p").exists()
    assert main(["evaluate", "--traffic", "head-on", "--condition", "calm", "--guidance", "los"]) == 2
    assert "--guidance is not for --traffic" in capsys.readouterr().err
    assert [p.name for p in _scenario_paths(["all", "head-on", "head-on"])] == [p.name for p in shipped_scenarios()]


def test_a_name_outside_ais_text_is_refused_naming_the_characters():
    """Found by a traffic audit: a target named "FÄHRE €" was an internal error (KeyError: 'Ä') in evaluate, and
    under --sim the simulated transmitter died without a word: the boat sailed through a vessel it never saw."""
    with pytest.raises(ConfigError, match=r"target 7: name 'FÄHRE €': 'Ä', '€' not in AIS's 6-bit text"):
        load_scenario({"name": "x", "targets": [{"mmsi": 7, "name": "FÄHRE €", "north_m": 100.0, "east_m": 0.0,
                                                 "course_deg": 180.0, "speed_m_s": 1.0}]})
    load_scenario({"name": "x", "targets": [{"mmsi": 7, "name": "Ferry 2", "north_m": 100.0, "east_m": 0.0,
                                             "course_deg": 180.0, "speed_m_s": 1.0}]})  # lower case is sent as upper


def test_a_turn_that_ends_before_it_starts_is_refused():
    """Found by a traffic audit: turn_until_s before turn_from_s was accepted and the target went straight, a
    scenario that did not test the turn it said it did."""
    target = {"mmsi": 7, "name": "T", "north_m": 100.0, "east_m": 0.0, "course_deg": 180.0, "speed_m_s": 1.0,
              "behaviour": "turn", "turn_rate_deg_s": 2.0, "turn_from_s": 60.0}
    with pytest.raises(ConfigError, match=r"target 7: turn_until_s 30 s is not after turn_from_s 60 s"):
        load_scenario({"name": "x", "targets": [{**target, "turn_until_s": 30.0}]})
    load_scenario({"name": "x", "targets": [{**target, "turn_until_s": 90.0}]})
    load_scenario({"name": "x", "targets": [target]})  # for ever
