"""Trial files with the mistakes a new user makes, and Excel's other ways of saving them (a new user's test of
``autopilot sysid`` from the wheel, 2026-12-07).

Each file is a daemon-flown pond log's CSV export (``tests/data/closed-loop-wind-weak-motor/from-087``, written
by ``autopilot review --export csv``) changed as the user's tools or fingers changed it. Before: fix times on
another clock stopped the identification with an internal error or were fitted as a sensor delay; a heading in
radians, a log without commands and crossed position columns were identified without a word; an empty north_m
column hid full lat/lon columns; ``--out`` into a review's folder wrote over its summary and removed its report.
"""

from __future__ import annotations

import csv
import json
import math

import pytest

from autopilot.schema import ConfigError
from autopilot.sysid.trials import read_trial
from tests.conftest import REPO, run_cli

BASE = REPO / "tests" / "data" / "closed-loop-wind-weak-motor" / "from-087" / "0-pond-9.1.csv"


def _table():
    with BASE.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def _write(path, header, rows, *, encoding="utf-8", delimiter=","):
    with path.open("w", newline="", encoding=encoding) as f:
        csv.writer(f, delimiter=delimiter).writerows([header, *rows])
    return path


def _changed(tmp_path, name, column, change):
    """The base file with ``change(cell) -> cell`` applied to every non-empty cell of ``column``."""
    header, rows = _table()
    k = header.index(column)
    for r in rows:
        if r[k] != "":
            r[k] = change(r[k])
    return _write(tmp_path / name, header, rows)


def _refusal(path) -> str:
    with pytest.raises(ConfigError) as info:
        read_trial(path)
    return str(info.value)


@pytest.mark.parametrize("shift_s", [49000.0, 10.0, 2.0])
def test_fix_times_after_their_rows_are_refused_naming_the_column(tmp_path, shift_s):
    path = _changed(tmp_path, "late.csv", "position_time_s", lambda c: f"{float(c) + shift_s:.3f}")
    msg = _refusal(path)
    assert "position_time_s" in msg and "after the row's t_s" in msg and "clock" in msg, msg


def test_fix_times_far_before_their_rows_are_refused(tmp_path):
    path = _changed(tmp_path, "early.csv", "position_time_s", lambda c: f"{float(c) - 10.0:.3f}")
    msg = _refusal(path)
    assert "position_time_s" in msg and "a median 10" in msg and "older than the rows" in msg, msg


def test_heading_times_on_another_clock_are_refused_by_the_command_without_a_traceback(tmp_path):
    path = _changed(tmp_path, "utc.csv", "heading_time_s", lambda c: f"{float(c) + 49000.0:.3f}")
    proc = run_cli("sysid", str(path), "--out", str(tmp_path / "out"), "--no-report", check=False)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    assert "heading_time_s" in proc.stderr and "clock" in proc.stderr, proc.stderr


def test_real_fix_and_heading_times_pass(tmp_path):
    trial = read_trial(BASE)
    assert trial.counts["position_fixes"] > 30 and trial.read_notes == ()


@pytest.mark.parametrize("wrap", ["pm_pi", "two_pi"])
def test_a_heading_in_radians_is_refused(tmp_path, wrap):
    def to_rad(c):
        deg = float(c) % 360.0
        if wrap == "pm_pi" and deg > 180.0:
            deg -= 360.0
        return f"{math.radians(deg):.5f}"

    msg = _refusal(_changed(tmp_path, "rad.csv", "heading_deg", to_rad))
    assert "heading_deg" in msg and "radians" in msg, msg


def test_crossed_position_columns_are_named_in_a_note(tmp_path):
    header, rows = _table()
    keep = [k for k, h in enumerate(header) if h not in ("north_m", "east_m")]
    header = [header[k] for k in keep]
    rows = [[r[k] for k in keep] for r in rows]
    lat, lon = header.index("lat_deg"), header.index("lon_deg")
    header[lat], header[lon] = "lon_deg", "lat_deg"
    trial = read_trial(_write(tmp_path / "swapped.csv", header, rows))
    assert any("does not follow the track's course" in n and "swapped" in n for n in trial.read_notes), trial.read_notes
    assert not any("track" in n for n in read_trial(BASE).read_notes)


def test_a_thrust_column_empty_in_every_row_is_refused(tmp_path):
    msg = _refusal(_changed(tmp_path, "nothrust.csv", "thrust_port_n", lambda c: ""))
    assert "thrust_port_n is empty in every row" in msg, msg


def test_a_mission_log_without_commands_is_refused(tmp_path):
    from autopilot.review.synthetic import write_synthetic_log

    src = tmp_path / "ok.jsonl"
    write_synthetic_log(src)
    lines = []
    for line in src.read_text().splitlines():
        rec = json.loads(line)
        if rec.get("event") == "cycle":
            rec["thrust_port_n"] = rec["thrust_stbd_n"] = None
        lines.append(json.dumps(rec))
    path = tmp_path / "no-commands.jsonl"
    path.write_text("\n".join(lines) + "\n")
    assert read_trial(src).counts["position_fixes"] > 8
    msg = _refusal(path)
    assert "thrust_port_n and thrust_stbd_n are empty in every row" in msg, msg


def test_empty_north_east_columns_fall_back_to_full_lat_lon(tmp_path):
    header, rows = _table()
    for r in rows:
        r[header.index("north_m")] = r[header.index("east_m")] = ""
    trial = read_trial(_write(tmp_path / "latlon.csv", header, rows))
    assert trial.counts["position_fixes"] == read_trial(BASE).counts["position_fixes"]


def test_headers_in_other_letter_case_and_excels_na_are_read(tmp_path):
    header, rows = _table()
    header = [h.upper() if h in ("t_s", "heading_deg") else h.title() if h == "north_m" else h for h in header]
    rows[40][header.index("SOG_M_S" if "SOG_M_S" in header else "sog_m_s")] = "#N/A"
    trial = read_trial(_write(tmp_path / "case.csv", header, rows))
    assert trial.counts == {**read_trial(BASE).counts, "velocities": trial.counts["velocities"]}


def test_excels_unicode_text_is_read(tmp_path):
    header, rows = _table()
    path = _write(tmp_path / "unicode.txt", header, rows, encoding="utf-16", delimiter="\t")
    assert read_trial(path).counts == read_trial(BASE).counts


def test_quoted_decimal_commas_in_a_comma_separated_file_are_named(tmp_path):
    header, rows = _table()
    rows = [[c.replace(".", ",") for c in r] for r in rows]
    path = tmp_path / "quoted.csv"
    with path.open("w", newline="") as f:
        csv.writer(f, quoting=csv.QUOTE_ALL).writerows([header, *rows])
    msg = _refusal(path)
    assert "data row 1" in msg and "decimal comma" in msg, msg


def test_sysid_does_not_write_over_a_reviews_folder_nor_review_over_a_sysid_one(tmp_path):
    review = tmp_path / "review"
    review.mkdir()
    (review / "summary.json").write_text(json.dumps({"cycles": 600, "name": "pond"}))
    (review / "report.html").write_text("<html>the review</html>")
    proc = run_cli("sysid", str(BASE), "--out", str(review), "--no-report", check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "summary.json that autopilot sysid did not write" in proc.stderr, proc.stderr
    assert (review / "report.html").read_text() == "<html>the review</html>"
    assert json.loads((review / "summary.json").read_text())["cycles"] == 600

    ident = tmp_path / "sysid"
    ident.mkdir()
    (ident / "summary.json").write_text(json.dumps({"mode": "trials", "verdict": ["wind"]}))
    from autopilot.review.synthetic import write_synthetic_log

    log = tmp_path / "ok.jsonl"
    write_synthetic_log(log)
    proc = run_cli("review", str(log), "--out", str(ident), "--no-plots", check=False)
    assert proc.returncode == 2 and "summary.json that autopilot review did not write" in proc.stderr, proc.stderr
    assert json.loads((ident / "summary.json").read_text())["verdict"] == ["wind"]


def test_noise_bounds_with_a_steady_state_table_are_refused(tmp_path):
    """--gps-wander-max beside --table was taken and did nothing: a table has no sensor noise to bound."""
    proc = run_cli("sysid", "--table", str(REPO / "config" / "measured-table.csv"), "--out", str(tmp_path / "o"),
                   "--gps-wander-max", "2", check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert "--gps-wander-max: bound the trials' sensor noise; a steady-state table (--table) has none" in proc.stderr


def _straight(heading_deg: float, course_deg: float, thrust_n: float, *, fix_lag_s: float = 0.0):
    """60 s at 1.2 m/s along ``course_deg`` with the bow at ``heading_deg``, a fix a second, 10 rows a second."""
    import numpy as np

    from autopilot.sysid.trials import make_trial

    t = np.round(np.arange(0.0, 60.0, 0.1), 3)
    c = np.radians(course_deg)
    fix = np.isclose(t % 1.0, 0.0) | np.isclose(t % 1.0, 1.0)
    n = np.where(fix, 1.2 * t * np.cos(c), np.nan)
    e = np.where(fix, 1.2 * t * np.sin(c), np.nan)
    return make_trial("t", t, north_m=n, east_m=e, heading_deg=np.full(t.size, heading_deg),
                      thrust_port_n=np.full(t.size, thrust_n), thrust_stbd_n=np.full(t.size, thrust_n),
                      position_time_s=np.where(fix, t + fix_lag_s, np.nan))


def test_a_run_astern_or_a_drift_with_the_bow_near_north_is_not_taken_for_radians():
    """A review of the radians refusal: a run astern at 1.2 m/s with the bow steady at 3 deg (3 rad is 172 deg) and
    a drift east with the bow at 1.5 deg were refused as radians, with no way round. The track is compared with
    the heading only while the thrust is ahead."""
    assert _straight(3.0, 180.0, -15.0).counts["position_fixes"] > 50  # astern
    assert _straight(1.5, 90.0, 0.0).counts["position_fixes"] > 50  # a drift at zero thrust
    with pytest.raises(ConfigError, match="radians"):
        _straight(math.radians(90.0), 90.0, 15.0)  # ahead: the same values are radians


def test_a_row_clock_a_little_behind_the_receivers_is_not_another_clock():
    """A review: a row clock 50 ms behind the receiver's time of fix was refused as another clock (10 ms allowed)."""
    assert _straight(90.0, 90.0, 15.0, fix_lag_s=0.05).counts["position_fixes"] > 50
    with pytest.raises(ConfigError, match="after the row's t_s"):
        _straight(90.0, 90.0, 15.0, fix_lag_s=2.0)
