"""A directory given as the mission: said so, as `autopilot run` says it. Found by a model audit: `autopilot
evaluate --mission DIR` said "no such file, nor a shipped mission"."""

from __future__ import annotations

from autopilot.cli import main


def test_evaluate_names_a_directory_given_as_the_mission(tmp_path, capsys):
    assert main(["evaluate", "--mission", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path}: is a directory, not a mission file" in err and "Traceback" not in err
