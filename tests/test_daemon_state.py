"""Mission progress file: atomic replacement, resume only for the same, unfinished mission."""

import json

from autopilot.daemon.state import Progress, StateStore


def test_save_load_roundtrip_and_resume_rules(tmp_path):
    st = StateStore(tmp_path / "state")
    assert st.load() is None and st.interrupted("abc", 4) == (None, None)
    st.save(Progress("m", "abc", 2, "running"))
    assert st.load() == Progress("m", "abc", 2, "running")
    assert st.interrupted("abc", 4) == (2, None)
    assert st.interrupted("other-content", 4)[0] is None  # mission file changed: not resumed (held, see below)
    st.save(Progress("m", "abc", 3, "complete"))
    assert st.interrupted("abc", 4) == (None, None)
    assert sorted(p.name for p in (tmp_path / "state").iterdir()) == ["mission-progress.json"]  # no tmp left


def test_half_written_or_foreign_file_is_not_trusted(tmp_path):
    st = StateStore(tmp_path)
    st.path.write_text('{"mission": "m", "wp_index": ')
    assert st.load() is None
    st.path.write_text(json.dumps({"mission": "m", "mission_sha256": "x", "wp_index": "two", "status": "running"}))
    assert st.load() is None


def test_replace_keeps_the_old_version_when_the_new_one_is_not_complete(tmp_path):
    st = StateStore(tmp_path)
    st.save(Progress("m", "abc", 1, "running"))
    # a crash between write and rename leaves only a stray tmp file, never a torn state file
    (tmp_path / ".mission-progress.json.999.tmp").write_text('{"mission": "m", "wp')
    assert StateStore(tmp_path).load() == Progress("m", "abc", 1, "running")


def test_an_interrupted_run_that_cannot_be_continued_holds_zero_not_starts_afresh(tmp_path):
    """Found by fault injection (real daemon, restarts): progress saying 'running' for an uploaded mission
    since deleted or edited, or for the mission file since edited, started the configured mission at
    waypoint 0 unasked; a saved waypoint out of range (999, -1) or Infinity crashed the start (exit 1: a
    systemd restart loop)."""
    st = StateStore(tmp_path)
    assert st.interrupted("abc", 4) == (None, None)  # no file: nothing was interrupted
    st.save(Progress("m", "abc", 2, "running"))
    assert st.interrupted("abc", 4) == (2, None)
    index, why = st.interrupted("edited", 4)
    assert index is None and "interrupted run of another mission (m" in why
    for bad_index in (999, -1):
        st.path.write_text(json.dumps({"mission": "m", "mission_sha256": "abc", "wp_index": bad_index,
                                       "status": "running"}))
        index, why = st.interrupted("abc", 4)
        assert index is None and f"waypoint {bad_index} is not in this mission (0..3)" in why
    for text in ('{"mission": "m", "mission_sha256": "abc", "wp_index": Infinity, "status": "running"}',
                 '{"mission": "m", "mission_sha256": "abc", "wp_index": "3", "status": "running"}',
                 '{"mission": "m", "wp_index": ', "[]"):
        st.path.write_text(text)
        index, why = st.interrupted("abc", 4)
        assert index is None and why.startswith(f"the saved progress {st.path} cannot be read"), (text, why)
    st.save(Progress("m", "abc", 3, "complete"))
    assert st.interrupted("other", 4) == (None, None)  # a finished run: start as configured


def test_an_uploaded_mission_that_is_a_directory_is_not_continued(tmp_path):
    st = StateStore(tmp_path)
    (tmp_path / "uploaded-mission.waypoints").mkdir()
    st.save(Progress(str(tmp_path / "uploaded-mission.waypoints"), "abc", 1, "running"))
    assert st.uploaded_to_continue() is None  # was IsADirectoryError: internal error, exit 1
    assert st.interrupted("configured-sha", 4)[1].startswith("an interrupted run of another mission")



def test_a_restart_remembers_latched_faults_the_launch_point_and_an_aborted_run(tmp_path):
    """Found by fault injection: the progress held only the waypoint and 'running'. A kill -9 after a geofence's
    rtl, and the next start's `ctl resume` drove back to the fence, rtl's home wherever the boat then was; a run
    aborted (max_mission_time, a crash the loop caught) flew again from W0 at the next start, unasked."""
    st = StateStore(tmp_path)
    st.save(Progress("m", "abc", 1, "running", latched=("geofence",), launch_ne_m=(1.5, -2.0)))
    assert StateStore(tmp_path).load() == Progress("m", "abc", 1, "running", latched=("geofence",),
                                                   launch_ne_m=(1.5, -2.0))
    index, why = st.interrupted("abc", 4)
    assert index is None and why.startswith("an interrupted run of this mission had geofence latched")
    st.save(Progress("m", "abc", 1, "stopped", latched=("battery_low",)))  # a clean stop: the operator's
    assert st.interrupted("abc", 4) == (None, None)
    st.save(Progress("m", "abc", 1, "aborted", reason="max_mission_time", latched=("max_mission_time",)))
    assert "ended with max_mission_time latched" in st.interrupted("abc", 4)[1]
    st.save(Progress("m", "abc", 0, "aborted", reason="error"))
    assert st.interrupted("abc", 4) == (None, "the last run of this mission was aborted (error)")
    assert st.interrupted("another", 4) == (None, None)  # another mission after it: a new run
    st.save(Progress("m", "abc", 0, "stopped"))  # stopped cleanly, nothing latched: the next run is a new one
    assert st.interrupted("abc", 4) == (None, None)
    st.path.write_text(json.dumps({"mission": "m", "mission_sha256": "abc", "wp_index": 0, "status": "running",
                                   "launch_ne_m": [1.0, "x"]}))
    assert st.interrupted("abc", 4)[1].startswith(f"the saved progress {st.path} cannot be read")
    old = {"mission": "m", "mission_sha256": "abc", "wp_index": 2, "status": "running"}  # an older daemon's file
    st.path.write_text(json.dumps(old))
    assert st.interrupted("abc", 4) == (2, None) and st.load().armed  # armed unless it says it was not
    st.save(Progress("m", "abc", 1, "running", armed=False))  # the operator's disarm
    assert StateStore(tmp_path).load().armed is False
    st.path.write_text(json.dumps({**old, "armed": "no"}))  # not a file a daemon wrote: not trusted
    assert st.interrupted("abc", 4)[1].startswith(f"the saved progress {st.path} cannot be read")


def test_a_disarm_is_kept_for_the_next_start_however_the_last_run_ended(tmp_path):
    """A disarm is the operator's "no thrust" for the boat: after a crash (status running), a clean stop (systemctl
    restart: status stopped) or a completed run, the next start is disarmed until armed; --fresh starts armed."""
    from autopilot.daemon.app import RunOptions, _armed_at_start

    st = StateStore(tmp_path)
    opts, fresh = RunOptions(mission_path="m.yaml"), RunOptions(mission_path="m.yaml", fresh=True)
    assert _armed_at_start(opts, st)  # no progress: armed
    for status in ("running", "stopped", "complete", "aborted"):
        st.save(Progress("m", "abc", 1, status, armed=False))
        assert not _armed_at_start(opts, st), status
        assert _armed_at_start(fresh, st)
    st.save(Progress("other", "def", 0, "stopped"))
    assert _armed_at_start(opts, st)


def test_a_progress_file_that_cannot_be_read_starts_disarmed(tmp_path):
    """Found by a review: a start held over an unreadable progress file could not save a disarm given in it (the
    file is kept as it is), and the next start came up armed: a `resume` then drove a boat the operator had
    disarmed. An unreadable file may have said disarmed: the start is disarmed too; --fresh starts armed."""
    from autopilot.daemon.app import RunOptions, _armed_at_start

    st = StateStore(tmp_path)
    st.path.write_text('{"mission": "m", "mission_sha256": "abc", "wp_index": "3", "status": "running"}\n')
    assert not _armed_at_start(RunOptions(mission_path="m.yaml"), st)
    assert _armed_at_start(RunOptions(mission_path="m.yaml", fresh=True), st)
    from autopilot.daemon.app import _disarmed_at_start  # what the start says, from the same read

    assert _disarmed_at_start(RunOptions(mission_path="m.yaml"), st) == (
        "the saved progress cannot be read (it may have said disarmed)")
