"""A review audit of 2026-12-06 (autopilot review as a new user runs it on the real daemon's logs).

- ``review --export csv`` and the identification: every fix epoch's speed/course reading the log holds reaches the
  trial CSV, where sysid reads it at the same time as from the log itself (a stay at rest kept 1 of its readings
  when the export wrote a pair only where it changed);
- a mission uploaded over MAVLink on the boat's real clock: the daemon applies it inside a cycle, before that
  cycle's step, and dates its ``mission_replaced`` line by the clock, after the cycle's ``t_s``. The review counted
  that first cycle, already steered by the new mission, in the old one, and began the new mission's leg 0 from the
  held fix a cycle later instead of where the helm began it: the leg's cross-track RMS came out 3.61 m for the
  daemon's 3.17 m.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from autopilot.review.export import write_trial_csv
from autopilot.review.metrics import cross_track_m, leg_of_rows
from autopilot.review.reader import _INDEX, MODES, read_log
from autopilot.sysid import read_trial
from tests.test_link_audit_missions import _item, _upload
from tests.test_link_mavlink import Boat  # at the top: the module runs on the realtime worker (tests/conftest.py)


@pytest.fixture(scope="module")
def pond_log(tmp_path_factory):
    """pond-9.4 flown by the real daemon in lockstep (~2 s): 5 s at rest waiting for valid data, then the route."""
    d = tmp_path_factory.mktemp("pond")
    subprocess.run([sys.executable, "-m", "autopilot", "run", "--mission", "pond-9.4", "--sim", "--speedup", "max",
                    "--log-dir", str(d / "logs"), "--state-dir", str(d / "state"), "--runtime-dir", str(d / "run"),
                    "--fresh"], check=True, capture_output=True, timeout=120)
    (log,) = (d / "logs").glob("*.jsonl")
    return d, log


def test_the_trial_csv_has_each_fix_epochs_speed_reading_of_a_stay_at_rest(pond_log):
    d, path = pond_log
    log = read_log(path)
    csv = write_trial_csv(log, d / "trial.csv")
    trial = read_trial(csv)
    t0 = trial.t0_s
    rest_end = min(float(e["t_s"]) for e in log.events_named("launch"))  # control starts: the boat leaves its rest
    fix_t = trial.t0_s + trial.position_time_s[trial.fix_rows]
    vel_t = t0 + trial.velocity_time_s[trial.velocity_rows]
    at_rest = fix_t[(fix_t >= fix_t[0]) & (fix_t < rest_end - 1.0)]
    assert at_rest.size >= 3
    # one reading dated with each fix epoch of the stay (0.00 kn, the same course every epoch): changes only gave 1
    for t in at_rest:
        assert np.min(np.abs(vel_t - t)) < 2e-3, f"no speed/course reading for the fix at {t:.3f} s"
    # and over the route the CSV gives sysid the readings the log itself gives it, at the same times
    direct = read_trial(path)
    dt = direct.t0_s + direct.velocity_time_s[direct.velocity_rows]
    span = (vel_t > dt[0] + 0.5) & (vel_t <= dt[-1])
    inside = dt[dt > dt[0] + 0.5]  # the first: the direct trial's cut at control's start dates its first row anew
    assert inside.size > 30 and np.sum(span) == inside.size
    assert np.max(np.abs(vel_t[span] - inside)) < 2e-3


@pytest.fixture(scope="module")
def link_log(tmp_path_factory):
    """A route replaced over MAVLink mid-run (under way: the position the helm steers by runs ahead of the held fix),
    the daemon on a real clock (--speedup 10, the link tests' pace)."""
    d = tmp_path_factory.mktemp("link")
    boat = Boat(d, mission={"name": "short", "frame": "local", "waypoints": [[30.0, 0.0], [30.0, 30.0]]},
                speedup=10.0)
    try:
        boat.wait_log(lambda r: r["event"] == "cycle" and r["mode"] == "auto" and r["t_s"] > 9.0, timeout_s=30,
                      what="auto")
        _upload(boat, [_item(0, 0.0, 0.0), _item(1, 10.0, -20.0), _item(2, -5.0, -25.0)])
        n = boat.wait_log(lambda r: r["event"] == "mission_replaced", what="the upload")
        boat.wait_log(lambda r: r["event"] == "cycle" and r["t_s"] > n["t_s"] + 6.0, timeout_s=30, what="6 s more")
    finally:
        assert boat.stop() == 0
    (log,) = (d / "logs").glob("*.jsonl")
    return log


def test_a_replaced_missions_first_cycle_is_counted_in_it(link_log):
    lines = [json.loads(x) for x in link_log.read_text().splitlines()]
    k = next(i for i, r in enumerate(lines) if r["event"] == "mission_replaced")
    first = next(r for r in lines[k:] if r["event"] == "cycle")  # the cycle that applied it (wp_index 0 of the new)
    assert first["t_s"] < lines[k]["t_s"]  # the line is dated later than its cycle: the case reviewed here
    log = read_log(link_log)
    assert log.plan_at(first["t_s"]).number == 2
    row = int(np.searchsorted(log.col("t_s"), first["t_s"]))
    assert leg_of_rows(log)[row] == len(log.plans[0].waypoints_ne_m)  # M2's leg 0, not M1's


def test_a_replaced_missions_leg_0_starts_where_the_helm_began_it(link_log):
    """Judged at the position the helm steered by (``est_*``), the recomputed cross-track error is the daemon's
    ``xte_m`` on every cycle in auto, the replaced mission's legs included."""
    log = read_log(link_log)
    data = log.data.copy()
    data[_INDEX["north_m"]], data[_INDEX["east_m"]] = log.col("est_north_m"), log.col("est_east_m")
    steered = dataclasses.replace(log, data=data)
    xte, logged = cross_track_m(steered), log.col("xte_m")
    auto = (log.mode == MODES.index("auto")) & np.isfinite(logged)
    second = auto & log.plans[1].holds(log.col("t_s"))
    assert second.sum() > 40 and np.isfinite(xte[auto]).all()
    np.testing.assert_allclose(xte[auto], logged[auto], atol=1e-6)
    # from the fixes (the scorecard's): leg 0 runs from where the helm was on the new mission's first cycle, not
    # from the fix it held then (by how far it moved since the fix: 0.9 m in a 10x run: RMS 3.61 m for the daemon's 3.17 m)
    k0 = int(np.argmax(second))
    a = np.array([log.col("est_north_m")[k0], log.col("est_east_m")[k0]])
    assert np.hypot(*(a - [log.col("north_m")[k0], log.col("east_m")[k0]])) > 1e-6  # the case tested
    b = log.plans[1].waypoints_ne_m[0]
    leg0 = second & (log.col("wp_index") == 0) & np.isfinite(log.col("north_m"))
    d, n, e = b - a, log.col("north_m")[leg0] - a[0], log.col("east_m")[leg0] - a[1]
    np.testing.assert_allclose(cross_track_m(log)[leg0], (d[0] * e - d[1] * n) / np.hypot(*d), atol=1e-9)
