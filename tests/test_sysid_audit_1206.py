"""A sysid audit (2026-12-06) with logs made the way a real boat makes them: the daemon's own mission logs
(``autopilot run --sim --speedup max``), then degraded as reality does."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from autopilot.cli import main
from autopilot.sim import default_params_path
from autopilot.sysid import read_trial
from autopilot.sysid.closed_loop import fly_pond_logs
from autopilot.sysid.trials import write_trial_csv


def _auto_cycles(lines, span_s: float):
    """A log's records; its auto cycle lines (index, record), their t_s and turn (port - starboard thrust, N); and
    which of them may start a ``span_s`` stretch 10 s away from both ends."""
    recs = [json.loads(s) for s in lines]
    cyc = [(i, r) for i, r in enumerate(recs) if r.get("event") == "cycle" and r.get("mode") == "auto"]
    t = np.array([r["t_s"] for _, r in cyc])
    turn = np.array([abs(r["thrust_port_n"] - r["thrust_stbd_n"]) for _, r in cyc])
    return recs, cyc, t, turn, (t > t[0] + 10.0) & (t < t[-1] - 10.0 - span_s)


def _lose_lines_in_a_turn(src, dst, span_s: float = 2.5) -> tuple[float, float]:
    """The mission log with ``span_s`` of cycle lines lost where the helm turns hardest (a failed write: the
    daemon goes on and says so with a 'log writes resumed' line, docs/log-schema.md); the lost stretch's t_s."""
    lines = src.read_text().splitlines()
    recs, cyc, t, turn, inside = _auto_cycles(lines, span_s)
    best = max(np.flatnonzero(inside), key=lambda k: turn[(t >= t[k]) & (t < t[k] + span_s)].sum())
    gone = {i for (i, r) in cyc if t[best] <= r["t_s"] < t[best] + span_s}
    out = []
    for i, s in enumerate(lines):
        if i in gone:
            continue
        if i - 1 in gone and i not in gone:
            out.append(json.dumps({"t_s": recs[i].get("t_s"), "message": "log writes resumed",
                                   "lines_lost": len(gone), "event": "info"}))
        out.append(s)
    dst.write_text("\n".join(out) + "\n")
    return float(t[best]), float(t[best] + span_s)


@pytest.fixture(scope="module")
def lost_log(tmp_path_factory):
    """A pond-9.1 mission flown by the daemon in a 0.25 m/s current towards 060, with 2.5 s of its cycle lines
    lost in a turn; (the log, the lost stretch's t_s)."""
    tmp = tmp_path_factory.mktemp("lost")
    (log,) = fly_pond_logs(tmp / "flown", 20261206, n_logs=1, current_speed_m_s=0.25,
                           current_towards_deg=60.0, speedup="max")
    damaged = tmp / "lost.jsonl"
    return damaged, _lose_lines_in_a_turn(log, damaged)


def _identify_current(path, out) -> dict:
    assert main(["sysid", str(path), "--params", str(default_params_path()), "--effects", "current",
                 "--out", str(out), "--no-report", "--quiet"]) == 0
    return json.loads((out / "summary.json").read_text())


def test_a_mission_log_with_lines_lost_is_cut_there_not_replayed_on_held_commands(lost_log, tmp_path):
    """2-2.5 s of a mission log's cycle lines lost (a failed write) in a turn: the commands then are unknown.
    Held open loop across the gap, a current in the daemon's own pond logs came out 'unexplained' (one pond-9.4
    log: heading 24 deg against noise 0.9; three: nearest wind+wind_force), and this pond-9.1 log's current
    left 2.5 deg of heading residual; the trial is now cut there, each part replayed from its own state, and
    the note says so."""
    damaged, (a, b) = lost_log
    summary = _identify_current(damaged, tmp_path / "out")
    assert summary["verdict"] == ["current"] and summary["adequate"] is True
    # held across the gap: 2.5 deg of heading residual, the heading wander at its 1-deg bound to swallow it
    assert summary["rmse_after"]["fitted"]["heading_deg"] < 0.5
    assert any("rows lost" in n and "cut there into 2 part(s)" in n for n in summary["notes"])
    speed = {p["name"]: p for p in summary["effects"]["current"]["params"]}["speed_m_s"]
    assert speed["ci95"][0] - 0.03 < 0.25 < speed["ci95"][1] + 0.03
    trial = read_trial(damaged)
    assert len(trial.lost_s) == 1
    before, after = (trial.t0_s + x for x in trial.lost_s[0])
    assert before < a and b <= after < b + 0.15


def test_a_trial_csv_with_rows_lost_is_cut_there_not_replayed_on_interpolated_commands(lost_log, tmp_path):
    """The same log's rows as a trial CSV (the rows the log kept, a 2.5-s step between two of them at 10 Hz): the
    commands across it were interpolated, 2.5 deg of heading left; now cut there as the mission log is."""
    damaged, _ = lost_log
    csv_path = tmp_path / "lost.csv"
    write_trial_csv(read_trial(damaged), csv_path)
    summary = _identify_current(csv_path, tmp_path / "out")
    assert summary["verdict"] == ["current"] and summary["adequate"] is True
    assert summary["rmse_after"]["fitted"]["heading_deg"] < 0.5
    assert any("rows lost" in n and "cut there into 2 part(s)" in n for n in summary["notes"])


def test_the_first_rows_speed_and_course_of_the_epoch_before_are_not_dated_with_the_first_fix():
    """A mission log is read from its first cycle in auto: there (as in the daemon's pond logs) the row holds a new
    fix while its speed and course are still the epoch before's, the RMC of the new epoch a few rows later. Both
    pairs were dated with the first fix: the first a second's speed and course late, two readings at one time."""
    from autopilot.sysid.trials import make_trial

    t = 0.05 + 0.1 * np.arange(300)
    fix_epoch = np.floor(t - 0.05 + 1e-9)  # epochs at k - 0.1 s, each fix on the wire at k + 0.05 s
    pair_epoch = np.floor(t - 0.25 + 1e-9)  # its RMC at k + 0.25 s
    trial = make_trial("first-row", t, north_m=fix_epoch * 1.0, east_m=np.zeros_like(t),
                       heading_deg=np.zeros_like(t), position_time_s=fix_epoch - 0.1, heading_time_s=t,
                       thrust_port_n=np.full_like(t, 10.0),
                       thrust_stbd_n=np.full_like(t, 10.0), sog_m_s=1.0 + 0.01 * pair_epoch,
                       cog_deg=(10.0 * pair_epoch) % 360.0, commands_held=True)
    rows = trial.velocity_rows
    when = trial.velocity_time_s[rows] + trial.t0_s
    assert np.all(np.diff(when) > 0.5)  # one reading an epoch
    # each reading dated in its own epoch: the speed says which
    assert np.allclose(when, (trial.sog_m_s[rows] - 1.0) / 0.01 - 0.1)


def test_a_csv_whose_clock_was_set_back_is_not_said_to_hold_two_trials(tmp_path):
    """Another tool's logger on a wall clock that NTP set back 0.8 s in the middle of a trial: refused (t_s must
    increase) as 'two trials in one file? give each its own file', which it is not; now the step is named."""
    from autopilot.schema import ConfigError

    t = 0.1 * np.arange(1, 401)
    t[200:] -= 0.8
    with pytest.raises(ConfigError) as err:
        read_trial(_clocked_csv(tmp_path / "stepped.csv", t))
    assert "two trials" not in str(err.value)
    assert "goes back 0.7 s" in str(err.value) and "clock set back" in str(err.value)
    assert "data row 200" in str(err.value) and "data row 201" in str(err.value)
    t[200:] -= 30.0  # back before the first row: a second trial's rows after the first's
    with pytest.raises(ConfigError, match="two trials in one file"):
        read_trial(_clocked_csv(tmp_path / "stepped.csv", t))


def _clocked_csv(path, t):
    """A trial CSV at times ``t`` (a logger's clock): the boat at 0.5 m/s north on steady thrust."""
    rows = ["t_s,thrust_port_n,thrust_stbd_n,north_m,east_m,heading_deg"]
    rows += [f"{x:.2f},10,10,{0.5 * (x - t[0]):.2f},0,0.0" for x in t]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_the_fixes_a_cut_at_lost_rows_leaves_out_are_counted(tmp_path):
    """Found reviewing 94737f3: a trial cut where its rows were lost left out a part too short to fit (and the fixes
    before a part's moved start), yet summary.json's measurements said every fix of the trial was used (cut_long
    counts its own: long_trial_fixes_left_out). The fixes left out are counted and said."""
    from autopilot.sim import load_params
    from autopilot.sysid.realistic import make_realistic_trials, write_columns_csv
    from autopilot.sysid.trials import cut_long

    tr, = make_realistic_trials(load_params(default_params_path()), {}, 11, n_trials=1, duration_s=60.0)
    keep = (tr.t_s < 55.0) | (tr.t_s >= 57.0)  # 2 s of rows lost, 3 s before the end: too short to fit
    cols = {"t_s": tr.t_s[keep], "thrust_port_n": tr.thrust_port_n[keep], "thrust_stbd_n": tr.thrust_stbd_n[keep],
            "north_m": tr.north_m[keep], "east_m": tr.east_m[keep], "position_time_s": tr.position_time_s[keep],
            "heading_deg": np.degrees(tr.heading_rad[keep]), "heading_time_s": tr.heading_time_s[keep]}
    path = tmp_path / "lost-near-the-end.csv"
    write_columns_csv(cols, path)
    trial = read_trial(path)
    assert len(trial.lost_s) == 1
    out, notes = cut_long([trial])
    used = sum(len(p.fix_rows) for p in out)
    assert used < len(trial.fix_rows)
    assert out[0].counts["lost_rows_fixes_left_out"] == len(trial.fix_rows) - used
    assert f"; {len(trial.fix_rows) - used} fixes left out" in notes[0]


def test_a_wall_clock_set_back_names_the_times_to_the_digit(tmp_path):
    """Found reviewing 94737f3: the new message is for loggers on a wall clock, whose t_s is often Unix seconds;
    printed with 6 digits both times read "1.765e+09 s" (a step back 0.7 s between two equal times)."""
    from autopilot.schema import ConfigError

    t = 1765000000.0 + 0.1 * np.arange(1, 401)
    t[200:] -= 0.8
    with pytest.raises(ConfigError) as err:
        read_trial(_clocked_csv(tmp_path / "unix.csv", t))
    assert "from 1765000020 s (data row 200) to 1765000019.3 s (data row 201)" in str(err.value), str(err.value)


def test_a_fine_csv_without_heading_times_is_told_what_the_missing_column_costs(tmp_path):
    """The audit: a 10 Hz CSV without heading_time_s (headings 0.11-0.31 s older than their rows) came out
    `unexplained` beside a current, and no note pointed at the missing column. A note says it; with the column, none."""
    from autopilot.sysid.trials import trial_from_columns

    t = np.arange(0.0, 60.0, 0.1)
    cols = {"t_s": t, "north_m": 0.5 * t, "east_m": np.zeros_like(t), "heading_deg": np.zeros_like(t),
            "thrust_port_n": np.full_like(t, 20.0), "thrust_stbd_n": np.full_like(t, 20.0),
            "position_time_s": np.floor(t)}
    notes = trial_from_columns("a", cols).read_notes
    assert any("no heading_time_s column" in n and "review --export csv" in n for n in notes), notes
    with_times = trial_from_columns("b", {**cols, "heading_time_s": t - 0.2}).read_notes
    assert not any("heading_time_s" in n for n in with_times), with_times


@pytest.mark.parametrize("per_epoch", [2, 5, 6])
def test_a_logger_writing_a_row_per_sentence_is_not_cut_at_every_epoch(tmp_path, per_epoch):
    """Stop 48's note: a logger writing a row per sentence (the GGA at the epoch, the RMC 0.1 s later, then 0.9 s to
    the next epoch) has a median step of 0.1 s when the short steps outnumber the long by one: every epoch's 0.9 s
    was taken for rows lost, the trial cut at each into parts too short to fit and replayed whole under a note
    naming 59 stretches. Rows really lost from such a log (4.9 s between rows; from 5 s a gap refuses the file) are
    still found."""
    from autopilot.sysid.trials import cut_at_lost

    # two: 60 steps of 0.1 s, 59 of 0.9 s; five or six (GGA, GSA, GSV, RMC, VTG ...): an 80th percentile failed them
    spacing_s = 0.1 if per_epoch == 2 else 0.02
    epochs = np.arange(60.0)
    t = np.sort(np.concatenate([epochs + k * spacing_s for k in range(per_epoch)]))
    trial = read_trial(_clocked_csv(tmp_path / "rows-an-epoch.csv", t))
    assert trial.lost_s == ()
    assert cut_at_lost([trial]) == ([trial], [])
    gone = (t < 30.0) | (t >= 34.0)  # 4 epochs of its rows lost
    trial = read_trial(_clocked_csv(tmp_path / "lost.csv", t[gone]))
    last = round(29.0 + (per_epoch - 1) * spacing_s, 2)
    assert [(round(a + trial.t0_s, 2), round(b + trial.t0_s, 2)) for a, b in trial.lost_s] == [(last, 34.0)]


# A daemon flying pond-9.1 at --speedup max in its own process in a 0.25 m/s current towards 060, a fault of its
# simulated devices on over a stretch of its time (``device.flag``: the Mbed ``deaf``, hearing nothing as with a broken receive
# wire, its firmware stopping the motors 0.5 s later; the SC-30's ``heading_dropout``), the failsafe as given.
_FLY_FAULT = """
import asyncio, math, sys
import numpy as np
import autopilot.daemon.app as app
from autopilot.daemon.config import DaemonConfig, FailsafeConfig
from autopilot.resources import missions_dir
from autopilot.sysid.closed_loop import realistic_sim

log_dir, state_dir, fault, failsafe, on_s, off_s = sys.argv[1], sys.argv[2], sys.argv[3], eval(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6])
device, flag = fault.split(".")
orig = app._sim_rig

async def faulty_rig(cfg, mission, clock, directory, **kw):
    rig, length_m = await orig(cfg, mission, clock, directory, **kw)
    t0 = clock.now_s()

    async def schedule():
        await clock.sleep_until(t0 + on_s)
        setattr(getattr(rig, device), flag, True)
        await clock.sleep_until(t0 + off_s)
        setattr(getattr(rig, device), flag, False)

    asyncio.ensure_future(schedule())
    return rig, length_m

app._sim_rig = faulty_rig
sim = realistic_sim(np.random.default_rng(7), seed=11, current_speed_m_s=0.25, current_towards_deg=60.0)
cfg = DaemonConfig(sim=sim, failsafe=FailsafeConfig(**failsafe))
opts = app.RunOptions(mission_path=str(missions_dir() / "pond-9.1.yaml"), sim=True, speedup=math.inf,
                      log_dir=log_dir, state_dir=state_dir, runtime_dir=state_dir, fresh=True)
sys.exit(app.run_daemon(cfg, opts))
"""


def _fly_fault(tmp, fault: str, failsafe: dict, on_s: float = 12.0, off_s: float = 16.0):
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", _FLY_FAULT, str(tmp / "logs"), str(tmp / "state"), fault,
                           repr(failsafe), str(on_s), str(off_s)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (log,) = (tmp / "logs").glob("mission-*.jsonl")
    return log


@pytest.fixture(scope="module")
def deaf_log(tmp_path_factory):
    """The Mbed deaf 12-16 s while the daemon goes on steering (the ack failsafe at 50 missed commands, the most the
    schema allows but two: the helm's commands are logged all along)."""
    return _fly_fault(tmp_path_factory.mktemp("deaf"), "mbed.deaf", {"ack_missing_n": 50})


def test_commands_the_mbed_never_heard_are_not_replayed_as_the_motors_thrust(deaf_log, tmp_path):
    """Found by a sysid audit: an Mbed link lost for 4 s in a mission (the board deaf, its firmware's stop after
    0.5 s) while the daemon went on steering: the log holds the commands it sent, not what the motors had, and sysid
    replayed them with nothing said (a plain 0.25 m/s current: `unexplained`, heading 9.3 deg against 0.75; its CSV
    export the same, nearest `weak_motor`). The log's ack_missing and seq say which commands went unheard: the
    trial is cut there, said, and the CSV export leaves those rows out, a gap sysid cuts at too."""
    trial = read_trial(deaf_log)
    ((before, after),) = trial.undelivered_s
    assert 11.0 < trial.t0_s + before < 12.0 and 16.0 <= trial.t0_s + after < 17.0, (trial.t0_s, before, after)
    summary = _identify_current(deaf_log, tmp_path / "out")
    assert summary["verdict"] == ["current"] and summary["adequate"] is True, summary["notes"]
    assert any("commands the motors may not have had at t_s" in n and "not acknowledged" in n and "cut there" in n
               for n in summary["notes"])
    speed = {p["name"]: p for p in summary["effects"]["current"]["params"]}["speed_m_s"]
    assert speed["ci95"][0] - 0.02 < 0.25 < speed["ci95"][1] + 0.02, speed
    assert main(["review", str(deaf_log), "--out", str(tmp_path / "rev"), "--export", "csv", "--no-plots"]) == 0
    (csv_path,) = (tmp_path / "rev").glob("*.csv")
    exported = read_trial(csv_path)
    assert [(round(exported.t0_s + a, 1), round(exported.t0_s + b, 1)) for a, b in exported.lost_s] == [
        (round(trial.t0_s + before, 1), round(trial.t0_s + after, 1))]
    from_csv = _identify_current(csv_path, tmp_path / "csv-out")
    assert from_csv["verdict"] == ["current"] and from_csv["adequate"] is True, from_csv["notes"]


def test_a_lone_missed_acknowledgement_or_two_unwritten_commands_do_not_cut_the_trial(deaf_log, tmp_path):
    """One reply lost on a noisy line, a board answering late every fourth command for 7 s (each late answer counted
    missing: the first version merged their windows and cut 35 s of a flight, a review), or two commands the
    driver could not write (the motors held the command before for 0.1-0.2 s more, as a missing row or two is
    interpolated): no cut. The deaf stretch is still the one cut."""
    lines = [json.loads(s) for s in deaf_log.read_text().splitlines()]
    cycles = [r for r in lines if r.get("event") == "cycle"]
    lone = next(r["t_s"] for r in cycles if r["t_s"] > 25.0)
    late = [r["t_s"] for r in cycles if 17.0 < r["t_s"] < 24.0][::4]
    unwritten = [r["t_s"] for r in cycles if r["t_s"] > 30.0][:2]
    for r in cycles:
        r["ack_missing"] += int(r["t_s"] >= lone) + sum(r["t_s"] >= x for x in late)
        if r["t_s"] in unwritten:
            r["seq"] = -1
    edited = tmp_path / "edited.jsonl"
    edited.write_text("\n".join(json.dumps(r) for r in lines) + "\n")
    assert len(read_trial(edited).undelivered_s) == 1


def test_a_course_over_ground_steered_on_is_not_read_as_the_compass(tmp_path):
    """A boat with cog_fallback steers on its course over ground while the compass is lost, and logs it as the
    heading (heading_source COG). Course is not heading: in a 0.25 m/s current they differ by the drift angle, and
    sysid read those rows as compass headings. They are no heading measurement now, for the log and its CSV."""
    # 30-36 s: the boat over cog_fallback_min_sog_m_s (0.5 m/s), a second after the last heading steered on course
    log = _fly_fault(tmp_path / "fly", "sc30.heading_dropout", {"cog_fallback": True, "heading_stale_s": 1.0}, 30.0, 36.0)
    recs = [json.loads(s) for s in log.read_text().splitlines()]
    cog_rows = [r for r in recs if r.get("event") == "cycle" and r.get("heading_source") == "COG"]
    assert len(cog_rows) > 10 and {r["mode"] for r in cog_rows} == {"auto"}  # steered on it
    said = [(r["t_s"], r["message"]) for r in recs if r.get("event") == "info" and "compass" in r.get("message", "")]
    assert [m for _, m in said] == ["steering on course over ground: compass lost", "compass heading back"], said
    assert said[0][0] == cog_rows[0]["t_s"] and said[1][0] == pytest.approx(cog_rows[-1]["t_s"] + 0.1), said
    inside = (cog_rows[0]["t_s"], cog_rows[-1]["t_s"] - 0.1)  # the compass silent (a heading at 36.0 s is its own)
    trial = read_trial(log)
    heading_t = trial.t0_s + trial.heading_time_s[trial.heading_rows]
    assert not np.any((heading_t > inside[0]) & (heading_t < inside[1]))
    summary = _identify_current(log, tmp_path / "out")
    assert summary["verdict"] == ["current"] and summary["adequate"] is True, summary["notes"]
    assert main(["review", str(log), "--out", str(tmp_path / "rev"), "--export", "csv", "--no-plots"]) == 0
    # the review counted those seconds as fresh headings ("heading lost 0.1 s" for 5 s of compass lost): lost now,
    # said as steered on the course over ground
    card = json.loads((tmp_path / "rev" / "summary.json").read_text())
    assert card["heading_lost_s"] >= 4.5 and card["heading_on_course_s"] >= 4.5, card["heading_lost_s"]
    (csv_path,) = (tmp_path / "rev").glob("*.csv")
    exported = read_trial(csv_path)
    heading_t = exported.t0_s + exported.heading_time_s[exported.heading_rows]
    assert not np.any((heading_t > inside[0]) & (heading_t < inside[1]))


def _stall_in_a_turn(src, dst, span_s: float = 1.5) -> tuple[float, float]:
    """The mission log as the daemon writes it when its loop stalls ``span_s`` in a turn: no cycle ran, so no
    line and no command; the next cycle counts the deadlines it skipped (``skipped_cycles``) and the cycle and
    command counters go on from the last (docs/log-schema.md). (t_s of the last cycle before, of the first after.)"""
    recs, cyc, t, turn, inside = _auto_cycles(src.read_text().splitlines(), span_s)
    best = max(np.flatnonzero(inside), key=lambda k: turn[k])
    gone = {i for (i, r) in cyc if t[best] < r["t_s"] <= t[best] + span_s}
    out, after = [], None
    for i, r in enumerate(recs):
        if i in gone:
            continue
        if r.get("event") == "cycle" and i > max(gone):
            after = r["t_s"] if after is None else after
            r = {**r, "cycle": r["cycle"] - len(gone), "skipped_cycles": r["skipped_cycles"] + len(gone),
                 "seq": r["seq"] - len(gone) if r["seq"] >= 0 else r["seq"]}
        out.append(json.dumps(r))
    dst.write_text("\n".join(out) + "\n")
    return float(t[best]), float(after)


def test_a_stalled_loop_is_replayed_with_the_firmware_stop_not_its_last_command_held(lost_log, tmp_path):
    """A mission log of a loop that stalled 1.5 s: no command went out, and the Mbed firmware stops both motors 0.5 s
    after the last valid one (docs/mbed-protocol.md). The replay held the last command through the stall (a second of
    thrust the motors never made, in a turn); now it holds it 0.5 s and then replays the stop, and nothing is cut
    (no line was lost, every command sent was acknowledged)."""
    from autopilot.drivers.mbed_protocol import FIRMWARE_STOP_TIMEOUT_S
    from autopilot.sysid.prediction import prepare

    (flown,) = (lost_log[0].parent / "flown").glob("flight-*/mission-*.jsonl")
    stalled = tmp_path / "stalled.jsonl"
    last, first = _stall_in_a_turn(flown, stalled)
    trial = read_trial(stalled)
    assert trial.lost_s == () and trial.undelivered_s == () and trial.stalled_after.sum() == 1
    prep = prepare([trial], dt_s=0.1)
    t = prep.t_grid + trial.t0_s
    k_last = int(np.argmin(np.abs(trial.t_s + trial.t0_s - last)))
    held = (t >= last + 0.05) & (t < last + FIRMWARE_STOP_TIMEOUT_S - 0.1)
    stopped = (t >= last + FIRMWARE_STOP_TIMEOUT_S + 0.05) & (t < first - 0.1)
    assert held.sum() >= 3 and stopped.sum() >= 8
    for side, logged in (("thrust_port_n", trial.thrust_port_n), ("thrust_stbd_n", trial.thrust_stbd_n)):
        grid = getattr(prep, side)[0]
        assert abs(logged[k_last]) > 1.0  # a thrust the motors had in the turn
        np.testing.assert_allclose(grid[held], logged[k_last])
        np.testing.assert_array_equal(grid[stopped], 0.0)


def _at_half_rate(lines):
    """A 10 Hz mission log as the daemon at 5 Hz writes it: every other cycle line, the cycle and command counters
    going on by one, the rate its mission_start gives (the commands are the 10 Hz helm's: this is about their times)."""
    out = []
    for line in lines:
        r = json.loads(line)
        if r.get("event") == "mission_start":
            r["rate_hz"] = 5.0
        elif r.get("event") == "cycle":
            if r["cycle"] % 2:
                continue
            r = {**r, "cycle": r["cycle"] // 2, "seq": r["seq"] // 2 if r["seq"] >= 0 else r["seq"]}
        out.append(json.dumps(r))
    return out


def test_two_lines_lost_at_a_slow_rate_are_not_read_as_a_stall(lost_log, tmp_path):
    """Found by a review: the firmware's stop went in after any row followed by more than 0.5 s. At 5 Hz, two cycle
    lines lost to a failed write are 0.6 s, too few to cut at (lost_stretches: 3), and the daemon went on sending
    then: the replay stopped motors that never stopped. A stop goes in only after skipped deadlines."""
    from autopilot.sysid.prediction import prepare

    (flown,) = (lost_log[0].parent / "flown").glob("flight-*/mission-*.jsonl")
    lines = _at_half_rate(flown.read_text().splitlines())
    recs, cyc, t, turn, inside = _auto_cycles(lines, 1.0)
    k = max(np.flatnonzero(inside), key=lambda k: turn[k])
    gone = {cyc[k + 1][0], cyc[k + 2][0]}  # the two lines after the hardest turn
    damaged = tmp_path / "two-lost.jsonl"
    damaged.write_text("\n".join(s for i, s in enumerate(lines) if i not in gone) + "\n")
    trial = read_trial(damaged)
    assert trial.lost_s == ()
    prep = prepare([trial], dt_s=0.05)
    tt = prep.t_grid + trial.t0_s
    across = (tt >= t[k]) & (tt + 0.05 <= t[k + 3])  # grid intervals wholly between the rows either side of the loss
    assert (tt[across] > t[k] + 0.5).sum() >= 1 and t[k + 3] - t[k] > 0.5
    for side, logged in (("thrust_port_n", trial.thrust_port_n), ("thrust_stbd_n", trial.thrust_stbd_n)):
        held = logged[int(np.argmin(np.abs(trial.t_s + trial.t0_s - t[k])))]
        assert abs(held) > 1.0
        np.testing.assert_allclose(getattr(prep, side)[0][across], held)  # the command sent before, held
    assert not trial.stalled_after.any()


def test_the_autopilot_command_runs_numpy_on_one_blas_thread_unless_told_otherwise():
    """Two identifications at once ran 3x slower with OpenBLAS's threads on this 2-core machine (100 s each, 31 s on
    one thread; the boat's PC runs the daemon beside them): the command sets one thread before numpy is imported,
    and keeps a user's own setting."""
    import subprocess

    probe = ("import os, sys; import autopilot.cli; print('numpy' in sys.modules, os.environ['OPENBLAS_NUM_THREADS'],"
             " os.environ['OMP_NUM_THREADS'])")
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "1", "1"], out
    env["OPENBLAS_NUM_THREADS"] = "2"
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "2", "1"], out
