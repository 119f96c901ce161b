"""PID (Eq 7.1), allocation (Eq 8.5-8.6), LOS and proportional laws, the Autopilot contract."""

import dataclasses
import math

import pytest
from numpy.testing import assert_allclose

from autopilot.gnc import GUIDANCE_LAWS, Autopilot, GncConfig, NavInput, PidConfig
from autopilot.gnc.allocation import (
    AllocationConfig,
    Allocator,
    common_thrust_n,
    speed_for_common_thrust_m_s,
    table_thrusts_n,
)
from autopilot.gnc.config import LAWS
from autopilot.gnc.los import LosGuidance
from autopilot.gnc.pid import HeadingPid
from autopilot.gnc.proportional import ProportionalGuidance
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.measured import MEASURED_TABLE
from autopilot.schema import ConfigError, load

D = math.radians


def test_pid_terms_degrees_in_newtons_out():
    pid = HeadingPid(PidConfig(kp_n_per_deg=0.18, ki_n_per_deg_s=0.001, kd_n_s_per_deg=0.33))
    t = pid.terms(D(90), 0.0, D(10))
    assert_allclose([t.p_n, t.i_n, t.d_n], [16.2, 0.0, -3.3])  # SPEC 8: 90 deg asks ~16 N


@pytest.mark.parametrize("psi_d, psi, err", [(5, 355, 10), (355, 5, -10), (180, 0, 180), (0, 180, 180), (170, -170, -20)])
def test_pid_error_wraps_across_north(psi_d, psi, err):
    t = HeadingPid().terms(D(psi_d), D(psi), 0.0)
    assert_allclose(math.degrees(t.heading_error_rad), err, atol=1e-9)


def test_pid_anti_windup_stops_growth_towards_a_limited_turn():
    pid = HeadingPid(PidConfig(ki_n_per_deg_s=0.1, integral_limit_n=50.0))
    pid.integrate(D(10), 1.0)
    assert pid.integral_n == pytest.approx(1.0)
    pid.integrate(D(10), 1.0, turn_limit=+1)  # the starboard turn is cut: it may not grow that way
    assert pid.integral_n == pytest.approx(1.0)
    pid.integrate(D(-5), 1.0, turn_limit=+1)  # shrinks: allowed
    assert pid.integral_n == pytest.approx(0.5)
    pid.integrate(D(10), 1.0, turn_limit=-1)  # the port turn is cut: growing to starboard is fine
    assert pid.integral_n == pytest.approx(1.5)
    for _ in range(1000):
        pid.integrate(D(90), 1.0)
    assert pid.integral_n == pytest.approx(50.0)  # bounded


def test_allocation_reports_saturation_per_axis():
    """allocate(30, 5): the full 5 N differential is delivered, only the common thrust is cut. The old
    per-thruster report ('port_upper') froze the heading integral at full speed."""
    a = Allocator().allocate(30.0, 5.0)
    assert a.saturation == ("port_upper",)  # the per-thruster view, for the log
    assert a.thrust_port_n - a.thrust_stbd_n == pytest.approx(10.0)  # 2 x tau_order: the turn is whole
    assert (a.turn_limit, a.common_limit) == (0, 1)
    b = Allocator().allocate(10.0, 40.0)  # more differential than the thrusters have
    assert (b.turn_limit, b.common_limit) == (1, 1)
    c = Allocator().allocate(0.0, -40.0)
    assert c.turn_limit == -1


def test_allocator_eq_8_5_8_6_unsaturated():
    a = Allocator().allocate(10.0, 3.0)
    assert (a.thrust_port_n, a.thrust_stbd_n, a.saturation) == (13.0, 7.0, ())


@pytest.mark.parametrize(
    "tau_com, tau_order, port, stbd, sat",
    [
        (30.0, 10.0, 32.5, 12.5, ("port_upper",)),  # common mode gives way, the turn is kept
        (30.0, -10.0, 12.5, 32.5, ("stbd_upper",)),
        (0.0, 40.0, 32.5, -32.5, ("port_upper", "stbd_lower")),  # turn cut to half the span
        (-30.0, 5.0, -22.5, -32.5, ("stbd_lower",)),  # astern: common mode gives way too
    ],
)
def test_allocator_saturation_keeps_turn(tau_com, tau_order, port, stbd, sat):
    a = Allocator().allocate(tau_com, tau_order)
    assert_allclose([a.thrust_port_n, a.thrust_stbd_n], [port, stbd])
    assert a.saturation == sat
    assert a.sat_port == any(s.startswith("port") for s in sat)


def test_allocator_no_reverse():
    a = Allocator(AllocationConfig(allow_reverse=False)).allocate(2.0, 10.0)
    assert_allclose([a.thrust_port_n, a.thrust_stbd_n], [20.0, 0.0])
    assert a.saturation == ("stbd_lower",)


@pytest.mark.parametrize("thrust", [-32.5, -20.0, -2.3, -0.5, 0.0, 1.0, 2.3, 10.25, 15.0, 21.15, 32.5])
def test_thrust_pwm_round_trip(thrust):
    alloc, curve = Allocator(), ThrustCurve()
    duty = alloc.signed_duty_pct(thrust)
    assert_allclose(duty, curve.signed_duty_pct(thrust), atol=1e-12)
    assert_allclose(curve.thrust_from_signed_duty_n(duty), thrust, atol=1e-9)
    assert (duty < 0) == (thrust < 0)


@pytest.mark.parametrize("row", [r for r in MEASURED_TABLE if r.kind == "straight"], ids=lambda r: r.name)
def test_tau_com_from_measured_table(row):
    assert_allclose(common_thrust_n(row.speed_m_s), row.thrust_port_n)
    assert_allclose(speed_for_common_thrust_m_s(row.thrust_port_n), row.speed_m_s)


@pytest.mark.parametrize("row", [r for r in MEASURED_TABLE if r.kind == "turn"], ids=lambda r: r.name)
def test_inverse_table_returns_measured_rows(row):
    tp, ts = table_thrusts_n(row.speed_m_s, row.yaw_rate_rad_s)
    assert_allclose([tp, ts], [row.thrust_port_n, row.thrust_stbd_n], atol=1e-9)
    tp, ts = table_thrusts_n(row.speed_m_s, -row.yaw_rate_rad_s)  # mirrored: starboard turn
    assert_allclose([tp, ts], [row.thrust_stbd_n, row.thrust_port_n], atol=1e-9)


def nav(n, e, psi_deg, r=0.0, speed=1.0):
    return NavInput(north_m=n, east_m=e, psi_rad=D(psi_deg), speed_m_s=speed, yaw_rate_rad_s=r, course_rad=D(psi_deg))


def test_los_on_track_and_offset():
    cfg = GncConfig().guidance
    g = LosGuidance(cfg, [(50.0, 0.0)])
    assert g.update(nav(0, 0, 0), 0.1).psi_d_rad == pytest.approx(0.0)
    g = LosGuidance(cfg, [(50.0, 0.0)], start_index=0)
    g._leg_start = (0.0, 0.0)
    out = g.update(nav(10, cfg.los.lookahead_m, 0), 0.0)  # e = +Delta (starboard)
    assert_allclose(out.psi_d_rad, -math.atan(1.0))  # chi_r = -atan(1) = -45 deg: steer to port
    assert out.xte_m == pytest.approx(cfg.los.lookahead_m)


def test_los_integral_frozen_while_turning_and_bounded():
    cfg = GncConfig().guidance
    g = LosGuidance(cfg, [(50.0, 0.0)])
    g.update(nav(0, 0, 0), 0.1)
    g.update(nav(5, 2.0, 0, r=1.0), 10.0)  # turning hard: frozen
    assert g.integral_nd == 0.0
    for _ in range(200):
        g.update(nav(5, 2.0, 0), 10.0)
    assert 0.0 < g.integral_nd <= cfg.los.i_hard_max_nd


def test_los_passes_at_perpendicular():
    g = LosGuidance(GncConfig().guidance, [(20.0, 0.0), (20.0, 20.0)])
    g.update(nav(0, 0, 0), 0.1)
    assert g.update(nav(19.0, 3.0, 0), 0.1).reached_index is None
    out = g.update(nav(20.1, 3.0, 0), 0.1)  # 3 m off, but past the line through W_0: no circling
    assert out.reached_index == 0 and out.wp_index == 1


@pytest.mark.parametrize("wp, factor", [((30.0, 1.0), 1.0), ((-30.0, 0.0), 0.5), ((-5.0, 0.0), 0.25), ((-8.0, 0.0), 8 / 30)])
def test_proportional_thrust_schedule(wp, factor):
    cfg = dataclasses.replace(GncConfig().guidance, turn_speed_floor_nd=1.0, arrival_slowdown_m=0.0)
    g = ProportionalGuidance(cfg, [wp])
    out = g.update(nav(0, 0, 0), 0.1)
    assert_allclose(out.speed_cmd_m_s, cfg.default_speed_m_s * factor)


def test_registry_matches_config_choices():
    assert tuple(GUIDANCE_LAWS) == LAWS


def test_config_refuses_unknown_and_bad_values():
    with pytest.raises(ConfigError, match="guidance.law"):
        load(GncConfig, {"guidance": {"law": "magic"}})
    with pytest.raises(ConfigError, match="pid.kp_n_per_deg"):
        load(GncConfig, {"pid": {"kp_n_per_deg": float("nan")}})
    with pytest.raises(ConfigError, match="fuzzy"):
        load(GncConfig, {"guidance": {"fuzzy": {"tcpa_max": 2}}})


@pytest.mark.parametrize("law", LAWS)
def test_autopilot_contract(law):
    cfg = load(GncConfig, {"guidance": {"law": law}})
    ap = Autopilot(cfg, [(20.0, 0.0), (20.0, 20.0)], speeds_m_s=[None, 1.5])
    out = ap.step(nav(0, 0, 90), 0.1)  # waypoint on the port side: turn to port
    assert out.tau_order_n < 0 and out.thrust_stbd_n > out.thrust_port_n
    assert out.pid_p_n + out.pid_i_n + out.pid_d_n == pytest.approx(out.tau_order_n)
    assert (out.cdh is None) == (law != "fuzzy")
    assert ap.wp_index == 0 and not ap.complete
    ap.reset_integrator()


def test_autopilot_complete_means_zero_thrust():
    ap = Autopilot(GncConfig(), [(5.0, 0.0)])
    ap.step(nav(0, 0, 0), 0.1)
    out = ap.step(nav(4.5, 0.1, 0), 0.1)
    assert out.complete and ap.complete and out.reached_index == 0
    assert (out.thrust_port_n, out.thrust_stbd_n, out.pwm_port_pct, out.pwm_stbd_pct) == (0.0, 0.0, 0.0, 0.0)
