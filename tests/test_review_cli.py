"""`autopilot review` end to end on intact and damaged logs, one and several at once."""

from __future__ import annotations

import json

import pytest

from autopilot.cli import main
from autopilot.review.synthetic import write_synthetic_log

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _damaged_logs(d):
    """An intact mission, one cut mid-line, one with a corrupt line, an empty one, a failsafe stop."""
    write_synthetic_log(d / "ok.jsonl")
    text = (d / "ok.jsonl").read_text()
    (d / "cut.jsonl").write_text(text[: len(text) - 700])  # through the last cycle line
    lines = text.splitlines(keepends=True)
    lines[50] = lines[50][:40] + "\x00#garbage#" + lines[50][40:]
    (d / "corrupt.jsonl").write_text("".join(lines))
    (d / "empty.jsonl").write_text("")
    write_synthetic_log(d / "failsafe.jsonl", failsafe_at_s=20.0, dropout_every_s=12.0)
    return ["ok", "cut", "corrupt", "empty", "failsafe"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    return d, _damaged_logs(d)


@pytest.mark.parametrize("name, skipped, note", [
    ("ok", 0, None),
    ("cut", 1, "cut off mid-write"),
    ("corrupt", 1, "corrupt line"),
    ("empty", 0, "no cycle lines"),
    ("failsafe", 0, None),
])
def test_review_runs_and_says_what_it_skipped(logs, tmp_path, capsys, name, skipped, note):
    d, _ = logs
    out = tmp_path / "out"
    assert main(["review", str(d / f"{name}.jsonl"), "--out", str(out), "--export", "gpx,kml,geojson,csv"]) in (0, 1)
    html = (out / "report.html").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["skipped_lines"] == skipped
    if note:
        assert note in html
    for img in html.split('<img src="')[1:]:
        src = img.split('"')[0]
        assert (out / src).read_bytes()[:8] == PNG_MAGIC
    printed = capsys.readouterr().out
    assert "report:" in printed


def test_failsafe_mission_is_reported(logs, tmp_path):
    d, _ = logs
    out = tmp_path / "fs"
    assert main(["review", str(d / "failsafe.jsonl"), "--out", str(out), "--export", "csv"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failsafes"] == [[20.0, "heading_stale"]]
    assert summary["stop_reason"] == "signal" and summary["complete"] is False  # a failsafe does not end the daemon
    assert summary["heading_lost_s"] > 3.0  # failsafe plus the drop-outs
    html = (out / "report.html").read_text()
    assert "heading_stale at 20.0 s" in html
    # per leg, in summary.json and the report's table: the leg the failsafe stopped it on, the one never flown
    assert [leg["label"] for leg in summary["legs"]] == ["start->W0", "W0->W1", "W1->W2"]
    assert summary["legs"][1]["fixes"] > 5 and summary["legs"][1]["xte_rms_m"] > 0.0
    assert summary["legs"][2]["cycles"] == 0 and summary["legs"][2]["xte_rms_m"] is None
    assert "<td>cross-track error, leg W1-&gt;W2</td><td class=\"num\">n/a (not flown)</td>" in html


def test_empty_log_exports_fail_but_report_is_written(logs, tmp_path, capsys):
    d, _ = logs
    out = tmp_path / "empty"
    assert main(["review", str(d / "empty.jsonl"), "--out", str(out), "--export", "gpx"]) == 1
    assert "gpx export failed" in capsys.readouterr().out
    html = (out / "report.html").read_text()
    assert "<img" not in html and "no cycle lines" in html


def test_several_logs_overlay_and_scorecard(logs, tmp_path):
    d, names = logs
    out = tmp_path / "many"
    assert main(["review", *(str(d / f"{n}.jsonl") for n in ("ok", "cut", "failsafe")), "--out", str(out)]) == 0
    html = (out / "report.html").read_text()
    assert 'src="tracks.png"' in html and (out / "tracks.png").read_bytes()[:8] == PNG_MAGIC
    for k, n in enumerate(("ok", "cut", "failsafe"), start=1):
        assert f'href="{k}-{n}/report.html"' in html
        assert (out / f"{k}-{n}" / "report.html").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert [s["path"].rsplit("/", 1)[-1] for s in summary] == ["ok.jsonl", "cut.jsonl", "failsafe.jsonl"]
    assert html.count("<tr>") >= 15  # one scorecard row per quantity, three columns


@pytest.mark.parametrize("argv, message", [
    (["review", "/nonexistent/log.jsonl"], "/nonexistent/log.jsonl: cannot read"),
    (["review", "LOG", "--export", "gpx,shapefile"], "unknown format 'shapefile'"),
])
def test_bad_input_exits_2(logs, capsys, argv, message):
    d, _ = logs
    argv = [str(d / "ok.jsonl") if a == "LOG" else a for a in argv]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def _rewritten(src, dst, change):
    """A copy of the log ``src`` with each cycle line's record changed by ``change`` (written as Python's json does,
    NaN literals and all)."""
    out = []
    for line in src.read_text().splitlines():
        rec = json.loads(line)
        if rec.get("event") == "cycle":
            change(rec)
        out.append(json.dumps(rec))
    dst.write_text("\n".join(out) + "\n")
    return dst


def test_nan_positions_huge_thrusts_and_a_utf16_log_are_said_so(tmp_path, capsys):
    """Found as a new user: NaN positions printed 'nan m' and no note; a thrust of 1e308 N leaked numpy's overflow
    warning and left the energy empty without a word; a UTF-16 log was called binary data."""
    src = tmp_path / "ok.jsonl"
    write_synthetic_log(src)
    nan = _rewritten(src, tmp_path / "nan.jsonl", lambda r: r.update(north_m=float("nan"), east_m=float("nan")))
    huge = _rewritten(src, tmp_path / "huge.jsonl", lambda r: r.update(thrust_port_n=1e308))
    assert main(["review", str(nan), "--out", str(tmp_path / "r1"), "--no-plots"]) == 0
    out = capsys.readouterr()
    assert "no position" in out.out
    assert "non-numeric, infinite or absurd (beyond 1e12) value(s) of north_m: treated as gaps" in out.out
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow warning reached the user's terminal
        assert main(["review", str(huge), "--out", str(tmp_path / "r2"), "--no-plots"]) == 0
    out = capsys.readouterr()
    # (an absurd value is a gap since a review audit: 1e308 was summed into a 300-digit distance)
    assert "373 non-numeric, infinite or absurd (beyond 1e12) value(s) of thrust_port_n: treated as gaps" in out.out
    utf16 = tmp_path / "u.jsonl"
    utf16.write_bytes(src.read_text().encode("utf-16"))
    assert main(["review", str(utf16), "--out", str(tmp_path / "r3")]) == 2
    assert f"{utf16}: UTF-16 text; save the mission log as UTF-8" in capsys.readouterr().err


def test_a_compressed_log_is_read_a_pipe_is_refused_and_an_output_taken_by_a_directory_is_named(logs, tmp_path, capsys):
    """Found by a new-user audit: `review <(zcat log.jsonl.gz)` lost the log's first 39 cycles and its mission_start
    (the look at the first bytes used them up) and exited 0; a .gz was refused as binary; a directory named
    report.html in --out was an 'internal error: IsADirectoryError'."""
    import gzip
    import os
    import subprocess
    import sys

    d, _ = logs
    plain = (d / "ok.jsonl").read_bytes()
    (tmp_path / "ok.jsonl.gz").write_bytes(gzip.compress(plain))
    assert main(["review", str(d / "ok.jsonl"), "--out", str(tmp_path / "a"), "--no-plots"]) == 0
    assert main(["review", str(tmp_path / "ok.jsonl.gz"), "--out", str(tmp_path / "b"), "--no-plots"]) == 0
    a, b = (json.loads((tmp_path / x / "summary.json").read_text()) for x in "ab")
    assert a["cycles"] == b["cycles"] > 100 and a["distance_m"] == b["distance_m"] and a["waypoints"] == b["waypoints"]
    capsys.readouterr()
    r, w = os.pipe()
    feeder = subprocess.Popen([sys.executable, "-c", f"import sys; sys.stdout.buffer.write(open({str(d / 'ok.jsonl')!r}, 'rb').read())"],
                              stdout=w)
    os.close(w)
    try:
        assert main(["review", f"/dev/fd/{r}", "--out", str(tmp_path / "c"), "--no-plots"]) == 2
    finally:
        os.close(r)
        feeder.wait()
    assert "a pipe or a device, not a file (read once, its start would be lost); save it to a file first" in \
        capsys.readouterr().err
    (tmp_path / "d" / "report.html").mkdir(parents=True)
    assert main(["review", str(d / "ok.jsonl"), "--out", str(tmp_path / "d"), "--no-plots"]) == 2
    assert f"{tmp_path / 'd' / 'report.html'} is a directory; the command writes a file of that name there" in \
        capsys.readouterr().err


def test_two_logs_joined_in_one_file_are_said_so(logs, tmp_path, capsys):
    """Found by a new-user audit: `cat a.jsonl b.jsonl` was reviewed as one mission of twice the cycles, its distance
    including the jump back to the start, with only "1 cycle(s) with t_s going backwards" to go by."""
    d, _ = logs
    text = (d / "ok.jsonl").read_text()
    (tmp_path / "two.jsonl").write_text(text + text)
    assert main(["review", str(tmp_path / "two.jsonl"), "--out", str(tmp_path / "r"), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "2 missions in one file (a mission_start line each): reviewed as one" in out
    assert "left out of every figure" in out


def test_a_block_of_lines_written_twice_is_left_out_of_every_figure(logs, tmp_path):
    """Found by a new-user audit: a log with lines 150-250 repeated (a copy glitch) gave a distance of 67.7 m for a
    43.3 m mission: the jump back and the second pass were added. Then (a review audit) only the distance left the
    block out: its energy, mode times, "position lost" (20 s in a log with a fix throughout) and exported fixes
    counted it. Cycles not later than every one before are left out of every figure, and said."""
    d, _ = logs
    lines = (d / "ok.jsonl").read_text().splitlines(keepends=True)
    (tmp_path / "dup.jsonl").write_text("".join(lines[:250] + lines[150:250] + lines[250:]))
    assert main(["review", str(d / "ok.jsonl"), "--out", str(tmp_path / "a"), "--no-plots", "--export", "gpx,csv"]) == 0
    assert main(["review", str(tmp_path / "dup.jsonl"), "--out", str(tmp_path / "b"), "--no-plots",
                 "--export", "gpx,csv"]) == 0
    a, b = (json.loads((tmp_path / x / "summary.json").read_text()) for x in "ab")
    assert b["distance_m"] == pytest.approx(a["distance_m"], rel=1e-9) and a["distance_m"] > 10.0
    assert {k: v for k, v in b.items() if k not in ("path", "read_notes")} == \
        {k: v for k, v in a.items() if k not in ("path", "read_notes")}
    assert any("100 cycle(s) not later than one before" in n for n in b["read_notes"]), b["read_notes"]
    assert (tmp_path / "b" / "dup.gpx").read_text().count("<trkpt") == \
        (tmp_path / "a" / "ok.gpx").read_text().count("<trkpt")
    assert len((tmp_path / "b" / "dup.csv").read_text().splitlines()) == \
        len((tmp_path / "a" / "ok.csv").read_text().splitlines())


def test_every_link_and_figure_of_a_report_resolves_whatever_the_log_is_called(tmp_path):
    """Found by a review audit: a log named "trial #3.jsonl" was linked as href="1-trial #3/report.html", which
    a browser reads as the page "1-trial " and a fragment (an error page); its export links likewise."""
    import re
    from urllib.parse import unquote, urlsplit

    names = ["trial #3.jsonl", "run 100%.jsonl", "what?.jsonl"]
    for name in names:
        write_synthetic_log(tmp_path / name)
    out = tmp_path / "out"
    assert main(["review", *(str(tmp_path / n) for n in names), "--out", str(out), "--export", "gpx"]) == 0
    pages = sorted(out.rglob("*.html"))
    assert len(pages) == 4
    seen = 0
    for page in pages:
        for ref in re.findall(r'(?:href|src)="([^"]+)"', page.read_text()):
            target = page.parent / unquote(urlsplit(ref).path)  # as a browser resolves it
            assert target.is_file(), (page.relative_to(out), ref)
            seen += 1
    assert seen >= 4 + 3 * 2  # the index's links and overlay; each page's figures and its export
