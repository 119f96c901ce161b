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


def test_a_mission_with_a_long_name_gets_a_log_file_that_can_be_created(tmp_path):
    """Found by a new-user audit: a mission named 'Pond_mission_' + 225 x 'x' stopped the start with "internal error:
    OSError: [Errno 36] File name too long". The name is cut (whole UTF-8 characters) to fit."""
    when = dt.datetime(2024, 5, 6, 7, 8, 9, tzinfo=dt.timezone.utc)
    for stem in ("Pond_mission_" + "x" * 225, "Teich_Br\u00fccke_" + "\u00e4" * 200):
        p = log_path(tmp_path, f"missions/{stem}.yaml", when)
        assert len(p.name.encode("utf-8")) <= 200 and p.name.startswith("mission-20240506T070809Z-" + stem[:10])
        MissionLog(p, console=None).close()  # it can be created
        assert p.exists()


def test_infinite_values_become_null(tmp_path):
    log = MissionLog(tmp_path / "m.jsonl", console=None)
    log.event("cycle", t_s=0.0, heading_age_s=math.inf)
    log.close()
    assert json.loads((tmp_path / "m.jsonl").read_text())["heading_age_s"] is None


_FULL_DISK = r"""
import io, json, resource, sys
from autopilot.daemon.missionlog import MissionLog

path, limit = sys.argv[1], int(sys.argv[2])
console, told = io.StringIO(), []
log = MissionLog(path, console=console)
log.listeners.append(lambda name, t_s, fields: told.append([name, fields.get("message")]))
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))  # the disk fills at `limit` bytes
for k in range(40):
    log.event("cycle", t_s=k * 0.1, cycle=k, pad="x" * 50)
log.event("fault", t_s=4.0, cause="position_stale")  # lost too, but the operator hears of it
resource.setrlimit(resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))  # room again
log.event("cycle", t_s=4.1, cycle=40)
log.close()
print(json.dumps({"lost": log.lines_lost, "told": told, "console": console.getvalue().count("log write failed")}))
"""


def test_a_full_disk_loses_lines_without_raising_and_the_log_says_how_many(tmp_path):
    """Each write a line of its own, nothing kept in a buffer: the lines the full disk lost are lost (not
    written out of order later), the line it cut is ended before the next, and when there is room
    again the log says how many went missing. The old log raised out of the control loop."""
    import subprocess
    import sys

    path = tmp_path / "m.jsonl"
    out = subprocess.run([sys.executable, "-c", _FULL_DISK, str(path), "1000"], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    recs = [json.loads(line) for line in path.read_text().splitlines() if line.startswith("{") and line.endswith("}")]
    written = [r["cycle"] for r in recs if r["event"] == "cycle"]
    assert 5 <= len(written) < 40 and written[:-1] == list(range(len(written) - 1)) and written[-1] == 40
    resumed = [r for r in recs if r["event"] == "info" and r["message"] == "log writes resumed"]
    assert len(resumed) == 1 and resumed[0]["lines_lost"] == res["lost"] == 41 - (len(written) - 1)
    assert "File too large" in resumed[0]["error"]
    assert res["told"].count(["info", "log write failed"]) == 1 and ["fault", None] in res["told"]  # the link hears
    assert res["console"] == 1
    lines = path.read_text().split("\n")
    assert sum(1 for line in lines if line and not line.endswith("}")) == 1  # the line the limit cut, ended


def test_the_console_does_not_echo_each_ais_report(tmp_path):
    """Found by a traffic audit: every `target` line (one per AIS report and vessel, up to one a second each) went
    to stderr and the journal too; a port's 1500 vessels made 1500 journal lines a second, faults among them.
    The log keeps them, the listeners (the link) hear them, the console does not."""
    import io

    console, told = io.StringIO(), []
    log = MissionLog(tmp_path / "m.jsonl", console=console)
    log.listeners.append(lambda name, t_s, fields: told.append(name))
    log.event("target", t_s=1.0, mmsi=244000001, north_m=10.0)
    log.event("fault", t_s=1.1, cause="position_stale", detail="x")
    log.close()
    names = [json.loads(x)["event"] for x in (tmp_path / "m.jsonl").read_text().splitlines()]
    assert names == ["target", "fault"] and told == ["target", "fault"]
    assert '"event":"fault"' in console.getvalue().replace(" ", "") and "target" not in console.getvalue()
