"""A mission log and its own ``review --export csv`` give sysid the same speed/course readings. Found by a review:
the export wrote a pair only where it changed, and of a stay at rest kept 1 of the log's 31 readings."""

from __future__ import annotations

import numpy as np

from autopilot.review.export import write_trial_csv
from autopilot.review.reader import read_log
from autopilot.sysid import read_trial
from tests.test_sysid_real_logs import _boat_at_rest, _write_mission_log


def test_the_export_of_a_mission_log_keeps_its_steady_readings(tmp_path):
    log = _boat_at_rest(duration_s=70.0, rest=(20.0, 50.0))
    _write_mission_log(log, tmp_path / "mission.jsonl")
    write_trial_csv(read_log(tmp_path / "mission.jsonl"), tmp_path / "export.csv")
    direct = read_trial(tmp_path / "mission.jsonl")
    exported = read_trial(tmp_path / "export.csv")
    rest_direct = int(np.sum(direct.sog_m_s[direct.velocity_rows] == 0.0))
    rest_export = int(np.sum(exported.sog_m_s[exported.velocity_rows] == 0.0))
    assert exported.fix_rows.size == direct.fix_rows.size
    assert exported.velocity_rows.size == direct.velocity_rows.size
    assert rest_export == rest_direct > 20
