"""A log written by the daemon's own writer from a simulated trial: read back, reviewed, fed to sysid.

Contract test between docs/log-schema.md's writer (autopilot.daemon.missionlog),
this reader, and the identification workflow's trial reader.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.geo import local_to_latlon, wrap_360
from autopilot.review.export import write_trial_csv
from autopilot.review.metrics import score
from autopilot.review.reader import read_log

missionlog = pytest.importorskip("autopilot.daemon.missionlog", reason="daemon log writer not built yet")
sim = pytest.importorskip("autopilot.sim", reason="simulator not built yet")

ORIGIN = (59.4370, 10.5880)
DT_S = 0.1


@pytest.fixture(scope="module")
def trial_log(tmp_path_factory):
    """The thesis's identification turn (T_P = 2.3 N, T_S = 18.56 N; SPEC section 6), 40 s at 10 Hz."""
    d = tmp_path_factory.mktemp("realistic")
    params = sim.load_params(sim.default_params_path())
    t = np.arange(0.0, 40.0, DT_S)
    tp = np.where(t < 5.0, 18.56, 2.3)
    ts = np.full_like(t, 18.56)
    run = sim.simulate(params, t, tp, ts, dt_s=0.05)
    lat, lon = local_to_latlon(run["north_m"], run["east_m"], *ORIGIN)
    heading = wrap_360(np.degrees(run["psi_rad"]))
    sog = np.hypot(run["u_m_s"], run["v_m_s"])
    log = missionlog.MissionLog(d / "trial.jsonl", console=None)
    log.event("mission_start", t_s=0.0, mission="trial.yaml", mission_name="turn", guidance="fuzzy",
              rate_hz=10.0, sim=True, speedup=1.0, origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1],
              waypoints=[[200.0, 0.0]], waypoint_speeds_m_s=[None], boat_length_m=3.96, config={},
              version="test")
    for k in range(len(t)):
        lost = 200 <= k < 210  # one second without a heading
        log.event("cycle", t_s=float(t[k]), cycle=k, mode="auto", lat_deg=float(lat[k]),
                  lon_deg=float(lon[k]), north_m=float(run["north_m"][k]), east_m=float(run["east_m"][k]),
                  heading_deg=None if lost else float(heading[k]), heading_source=None if lost else "HDT",
                  yaw_rate_deg_s=float(np.degrees(run["r_rad_s"][k])), sog_m_s=float(sog[k]),
                  cog_deg=float(heading[k]), fix_quality=1, wp_index=0, thrust_port_n=float(tp[k]),
                  thrust_stbd_n=float(ts[k]), sat_port=False, sat_stbd=False, saturation=[],
                  lateness_ms=0.5, nmea_dropped=0, ack_missing=0, tcpa_nd=math.nan)
    log.event("stop", t_s=float(t[-1]), reason="signal", signal="SIGINT", ack_received=True,
              cycles=len(t), nmea_dropped=0, ack_missing=0)
    log.close()
    return d, run, tp, ts


def test_reader_reads_the_daemon_writer(trial_log):
    d, run, tp, ts = trial_log
    log = read_log(d / "trial.jsonl")
    assert log.stats.skipped == 0 and not log.stats.bad_values
    assert log.n_cycles == len(run["t_s"])
    assert_allclose(log.col("north_m"), run["north_m"], atol=1e-9)
    assert_allclose(log.col("thrust_port_n"), tp)
    assert np.isnan(log.col("heading_deg")[200:210]).all() and np.isnan(log.col("tcpa_nd")).all()
    assert log.first_timestamp.endswith("Z")
    card = score(log)
    assert_allclose(card.heading_lost_s, 1.0, atol=1e-9)
    path_m = np.sum(np.hypot(np.diff(run["north_m"]), np.diff(run["east_m"])))
    assert_allclose(card.distance_m, path_m, rtol=0.02)  # speed over ground; its first 0.3 m/s not counted
    assert_allclose(card.thrust_energy_n_s, np.sum(np.abs(tp) + np.abs(ts)) * DT_S, rtol=1e-9)


def test_trial_csv_is_read_by_sysid(trial_log, tmp_path):
    trials = pytest.importorskip("autopilot.sysid.trials", reason="autopilot sysid not built yet")
    d, run, tp, _ = trial_log
    csv_path = write_trial_csv(read_log(d / "trial.jsonl"), tmp_path / "trial.csv")
    trial = trials.read_trial_csv(csv_path)
    assert_allclose(trial.north_m, run["north_m"], atol=1e-3)
    assert_allclose(trial.thrust_port_n, tp, atol=1e-3)
    psi = np.radians(wrap_360(np.degrees(run["psi_rad"])))
    ok = np.isfinite(trial.heading_rad)
    assert not ok[200:210].any() and ok.sum() == len(psi) - 10  # the lost second stays a gap
    assert_allclose(np.cos(trial.heading_rad[ok] - psi[ok]), 1.0, atol=1e-6)
