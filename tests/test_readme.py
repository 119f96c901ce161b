"""The README's promises: two quick-start commands naming real files; the bad-input table is current."""

import re
import shlex

from tests.conftest import REPO


def _readme() -> str:
    return (REPO / "README.md").read_text(encoding="utf-8")


def test_quick_start_has_exactly_two_commands_and_ci_runs_the_second():
    text = _readme()
    block = re.search(r"## Quick start\s+```sh\n(.*?)```", text, re.S)
    assert block, "README has no Quick start code block"
    commands = [line for line in block.group(1).splitlines() if line.strip()]
    assert len(commands) == 2
    run_cmd, test_cmd = commands
    words = shlex.split(run_cmd)
    for flag in ("--config", "--mission"):
        assert (REPO / words[words.index(flag) + 1]).is_file()
    assert "--sim" in words
    assert test_cmd in (REPO / ".ci" / "run").read_text()


def test_bad_input_table_in_readme_matches_the_generated_document():
    doc = (REPO / "docs" / "bad-inputs.md").read_text(encoding="utf-8")
    readme = _readme()
    rows = [line for line in doc.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) > 20
    missing = [row for row in rows if row not in readme]
    assert not missing, f"README's bad-input table is stale; regenerate from docs/bad-inputs.md: {missing[:2]}"
