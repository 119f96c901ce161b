"""Mission log lines: strict JSON, flushed per line, timestamp + event on each."""

import datetime as dt
import json
import math
import re

import numpy as np

from autopilot.daemon.missionlog import MissionLog, log_path


def test_each_line_is_on_disk_as_soon_as_it_is_written(tmp_path):
    log = MissionLog(tmp_path / "m.jsonl", console=None)
    log.event("mission_start", t_s=0.0, mission="x.yaml")
    # read through another file object without closing the writer: line-by-line flush
    lines = (tmp_path / "m.jsonl").read_text().splitlines()
    assert len(lines) == 1
    log.event("cycle", t_s=0.1, cycle=0, heading_deg=float("nan"), north_m=np.float64(1.5), seq=np.int64(7), saturation=("port_upper",))
    lines = (tmp_path / "m.jsonl").read_text().splitlines()
    rec = json.loads(lines[1])
    assert rec["event"] == "cycle" and rec["heading_deg"] is None and rec["north_m"] == 1.5 and rec["seq"] == 7
    assert rec["saturation"] == ["port_upper"]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d+Z", rec["timestamp"])
    log.close()


def test_log_path_format():
    p = log_path("/var/log/x", "config/missions/pond-9.3.yaml", dt.datetime(2024, 5, 6, 7, 8, 9, tzinfo=dt.timezone.utc))
    assert str(p) == "/var/log/x/mission-20240506T070809Z-pond-9.3.jsonl"


def test_infinite_values_become_null(tmp_path):
    log = MissionLog(tmp_path / "m.jsonl", console=None)
    log.event("cycle", t_s=0.0, heading_age_s=math.inf)
    log.close()
    assert json.loads((tmp_path / "m.jsonl").read_text())["heading_age_s"] is None
