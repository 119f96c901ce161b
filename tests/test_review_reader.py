"""The mission-log reader: columns match what was written; bad lines are skipped and counted."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from autopilot.review.reader import MODES, UNKNOWN_CODE, read_log
from autopilot.review.synthetic import write_synthetic_log
from autopilot.schema import ConfigError


def _write(path, records, tail: str = ""):
    with open(path, "w", encoding="utf-8") as f:
        for r in records:
            f.write((r if isinstance(r, str) else json.dumps(r)) + "\n")
        f.write(tail)
    return path


def _cycle(k, **extra):
    rec = {"event": "cycle", "t_s": 0.1 * k, "cycle": k, "mode": "auto", "north_m": float(k),
           "east_m": 2.0 * k, "heading_deg": 10.0, "thrust_port_n": 5.0, "thrust_stbd_n": 6.0,
           "timestamp": "2024-05-21T09:30:00Z"}
    rec.update(extra)
    return rec


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    path = tmp_path_factory.mktemp("logs") / "mission.jsonl"
    truth = write_synthetic_log(path, dropout_every_s=10.0)
    return path, truth


def test_columns_match_the_written_mission(synthetic):
    path, truth = synthetic
    log = read_log(path)
    assert log.n_cycles == truth["cycles"]
    assert log.stats.skipped == 0 and not log.stats.bad_values
    assert_allclose(log.col("t_s"), truth["t_s"], atol=1e-3)
    ok = np.isfinite(log.col("north_m"))
    assert 0 < ok.sum() < log.n_cycles  # the drop-outs are gaps
    assert_allclose(log.col("north_m")[ok], truth["logged_north_m"][ok], atol=1e-3)  # the held 1 Hz fix
    rows, fix_t = log.fix_rows()  # one row per fix, dated when it was measured
    assert_allclose(rows, truth["fix_rows"])
    assert_allclose(fix_t, truth["fix_t_s"], atol=2e-3)
    assert_allclose(log.col("thrust_port_n"), truth["thrust_port_n"], atol=1e-3)
    assert log.start["mission_name"] == "synthetic"
    assert_allclose(log.waypoints_ne_m, truth["waypoints_ne_m"])
    assert [e["event"] for e in log.events][:2] == ["mission_start", "waypoint_reached"]
    assert np.all(log.mode == MODES.index("auto"))


def test_missing_fields_are_gaps_not_zeros(tmp_path):
    rec = _cycle(0)
    del rec["thrust_stbd_n"]
    rec["heading_deg"] = None
    log = read_log(_write(tmp_path / "a.jsonl", [rec, _cycle(1)]))
    assert math.isnan(log.col("thrust_stbd_n")[0]) and log.col("thrust_stbd_n")[1] == 6.0
    assert math.isnan(log.col("heading_deg")[0])
    assert np.all(np.isnan(log.col("lateness_ms")))  # never logged at all


def test_cut_last_line_is_skipped_and_reported(tmp_path):
    full = json.dumps(_cycle(2))
    log = read_log(_write(tmp_path / "cut.jsonl", [_cycle(0), _cycle(1)], tail=full[: len(full) // 2]))
    assert log.n_cycles == 2
    assert log.stats.truncated_last_line and log.stats.corrupt == 0
    assert any("cut off" in line for line in log.stats.describe())


@pytest.mark.parametrize("bad, counter", [
    ("{this is not json", "corrupt"),
    ("[1, 2, 3]", "corrupt"),
    ('{"t_s": 1.0, "north_m": 3}', "no_event"),
    ('{"event": "cycle", "north_m": 3}', "no_time"),
    ('{"event": "cycle", "t_s": "soon"}', "no_time"),
    ('{"event": "cycle", "t_s": NaN}', "no_time"),
])
def test_corrupt_lines_are_skipped_and_counted(tmp_path, bad, counter):
    log = read_log(_write(tmp_path / "c.jsonl", [_cycle(0), bad, _cycle(1)]))
    assert log.n_cycles == 2
    assert getattr(log.stats, counter) == 1
    assert log.stats.skipped == 1
    assert_allclose(log.col("north_m"), [0.0, 1.0])


def test_unknown_events_and_keys_are_ignored(tmp_path):
    log = read_log(_write(tmp_path / "u.jsonl", [
        _cycle(0, new_field_from_the_future=3.0), {"event": "telemetry_v2", "t_s": 0.05}, _cycle(1)]))
    assert log.n_cycles == 2
    assert log.stats.unknown_events == {"telemetry_v2": 1}


def test_bad_values_become_gaps(tmp_path):
    log = read_log(_write(tmp_path / "b.jsonl", [
        _cycle(0, north_m="abc", east_m=[1, 2]), _cycle(1, heading_deg=math.inf), _cycle(2, mode="dancing")]))
    assert np.isnan(log.col("north_m")[0]) and np.isnan(log.col("east_m")[0])
    assert np.isnan(log.col("heading_deg")[1])
    assert log.stats.bad_values == {"north_m": 1, "east_m": 1, "heading_deg": 1}
    assert log.mode[2] == UNKNOWN_CODE and log.stats.unknown_modes == 1


def test_booleans_are_numbers(tmp_path):
    log = read_log(_write(tmp_path / "s.jsonl", [_cycle(0, sat_port=True, sat_stbd=False)]))
    assert log.col("sat_port")[0] == 1.0 and log.col("sat_stbd")[0] == 0.0


@pytest.mark.parametrize("content", ["", "\n\n", "\x00\x00garbage"])
def test_empty_or_garbage_file(tmp_path, content):
    path = tmp_path / "empty.jsonl"
    path.write_text(content)
    log = read_log(path)
    assert log.n_cycles == 0 and log.start is None and log.waypoints_ne_m.shape == (0, 2)


def test_many_blocks_are_assembled_in_order(tmp_path):
    # more rows than one block, with an odd value in a late block (slow path)
    recs = [_cycle(k) for k in range(20000)]
    recs[17000]["north_m"] = "x"
    log = read_log(_write(tmp_path / "big.jsonl", recs))
    expect = np.arange(20000, dtype=float)
    expect[17000] = np.nan
    assert_allclose(log.col("north_m"), expect)
    assert_allclose(log.col("cycle"), np.arange(20000))


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read log"):
        read_log(tmp_path / "nope.jsonl")


def _start(**extra):
    rec = {"event": "mission_start", "t_s": 0.0, "mission_name": "m", "waypoints": [[10.0, 0.0], [20.0, 5.0]],
           "timestamp": "2024-05-21T09:30:00Z"}
    rec.update(extra)
    return rec


def test_a_log_saved_with_a_byte_order_mark_keeps_its_mission_start(tmp_path):
    """Found by a review audit: a log saved by a Windows editor (UTF-8 with a BOM) lost its first line, the
    mission_start, as "not JSON", and the report said "waypoints and origin unknown" with exit 0."""
    from autopilot.review.reader import check_mission_log

    path = _write(tmp_path / "bom.jsonl", [_start(), _cycle(0), _cycle(1)])
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert check_mission_log(path) == path
    log = read_log(path)
    assert log.stats.skipped == 0 and log.start is not None
    assert_allclose(log.waypoints_ne_m, [[10.0, 0.0], [20.0, 5.0]])


def test_a_mission_start_longer_than_the_sniff_is_a_mission_log(tmp_path):
    """Found by a review audit: a survey of 1400 waypoints wrote a 67 kB mission_start; the check looked at
    the first 64 kB only and refused the log as "not a mission log" (exit 2)."""
    from autopilot.review.reader import check_mission_log

    wps = [[float(k), float(k % 7)] for k in range(1400)]
    path = _write(tmp_path / "survey.jsonl", [_start(waypoints=wps, pad="x" * 70000), _cycle(0)])
    assert path.stat().st_size > 65536 + 1000
    assert check_mission_log(path) == path
    assert len(read_log(path).waypoints_ne_m) == 1400


def test_another_programs_json_log_is_not_a_mission_log(tmp_path):
    """Found by a review audit: a structlog log of a web service (every line has an 'event') was reviewed as a
    mission log with no cycles (exit 1) rather than refused (exit 2), as the README says of other files."""
    from autopilot.review.reader import check_mission_log

    path = _write(tmp_path / "web.jsonl", [{"event": "request", "path": "/", "status": 200},
                                           {"event": "request served", "ms": 3}])
    with pytest.raises(ConfigError, match=r"not a mission log") as e:
        check_mission_log(path)
    assert "request" in str(e.value)


def test_a_log_re_saved_in_windows_1252_is_read_whole_and_said(tmp_path):
    """Found by a review audit: a log re-saved by an editor in Latin-1, an accented mission name on its first line,
    lost its mission_start as "not JSON": no waypoints in the report, yet "stop: complete"."""
    from autopilot.review.metrics import score

    write_synthetic_log(tmp_path / "ok.jsonl")
    lines = (tmp_path / "ok.jsonl").read_text().splitlines(keepends=True)
    first = json.loads(lines[0])
    first["mission"] = "étang nord"
    lines[0] = json.dumps(first, ensure_ascii=False) + "\n"
    (tmp_path / "cp.jsonl").write_bytes("".join(lines).encode("cp1252"))
    log = read_log(tmp_path / "cp.jsonl")
    assert log.start is not None and log.start["mission"] == "étang nord"
    assert log.stats.corrupt == 0 and log.stats.not_utf8 == 1
    assert "1 line(s) not UTF-8 (a log re-saved by an editor?): read as Windows-1252" in log.stats.describe()
    assert len(score(log).waypoints) == len(score(read_log(tmp_path / "ok.jsonl")).waypoints) > 0


def test_one_corrupt_t_s_ahead_of_its_neighbours_drops_that_cycle_not_the_rest(tmp_path):
    """Found reviewing d266692: a cycle whose t_s was raised by 1000 s (a corrupt value) was taken as the clock,
    and the 322 cycles after it were left out as "not later than one before"."""
    write_synthetic_log(tmp_path / "ok.jsonl")
    lines = (tmp_path / "ok.jsonl").read_text().splitlines(keepends=True)
    cycle_lines = [k for k, ln in enumerate(lines) if json.loads(ln)["event"] == "cycle"]
    k = cycle_lines[50]
    rec = json.loads(lines[k])
    rec["t_s"] += 1000.0
    lines[k] = json.dumps(rec) + "\n"
    (tmp_path / "spike.jsonl").write_text("".join(lines))
    ok, spike = read_log(tmp_path / "ok.jsonl"), read_log(tmp_path / "spike.jsonl")
    assert spike.stats.cycles == ok.stats.cycles - 1 and spike.stats.time_reversals == 1


def test_an_integer_too_large_for_a_float_is_a_bad_value_not_a_crash(tmp_path):
    """Found reviewing d266692: a 400-digit integer in a cycle line raised OverflowError out of read_log."""
    write_synthetic_log(tmp_path / "ok.jsonl")
    lines = (tmp_path / "ok.jsonl").read_text().splitlines(keepends=True)
    k = next(k for k, ln in enumerate(lines) if json.loads(ln)["event"] == "cycle")
    lines[k] = lines[k].replace('"sog_m_s": ', '"sog_m_s": ' + "9" * 400 + ", \"x\": ", 1)
    (tmp_path / "huge.jsonl").write_text("".join(lines))
    log = read_log(tmp_path / "huge.jsonl")
    assert log.stats.bad_values["sog_m_s"] == 1 and log.stats.cycles == read_log(tmp_path / "ok.jsonl").stats.cycles
