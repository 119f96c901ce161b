"""Mission progress file: atomic replacement, resume only for the same, unfinished mission."""

import json

from autopilot.daemon.state import Progress, StateStore


def test_save_load_roundtrip_and_resume_rules(tmp_path):
    st = StateStore(tmp_path / "state")
    assert st.load() is None and st.resume_index("m", "abc") is None
    st.save(Progress("m", "abc", 2, "running"))
    assert st.load() == Progress("m", "abc", 2, "running")
    assert st.resume_index("m", "abc") == 2
    assert st.resume_index("m", "other-content") is None  # mission file changed
    st.save(Progress("m", "abc", 3, "complete"))
    assert st.resume_index("m", "abc") is None
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
