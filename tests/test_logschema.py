"""The log schema has one owner (autopilot.logschema): the docs, the daemon, the reader and the synthetic log follow it."""

from __future__ import annotations

import json

from autopilot.logschema import (
    CYCLE,
    CYCLE_KEYS,
    EVENT_NAMES,
    FAULT_CAUSES,
    HEADING_SOURCES,
    MODES,
    STOP_REASONS,
    render_markdown,
)
from autopilot.review import reader
from autopilot.review.synthetic import write_synthetic_log


def test_docs_are_generated_from_the_schema(repo):
    assert (repo / "docs" / "log-schema.md").read_text() == render_markdown(), (
        "docs/log-schema.md is out of date: python -m autopilot.logschema > docs/log-schema.md")


def test_reader_knows_every_numeric_cycle_field_and_every_event():
    assert set(reader.CYCLE_FIELDS) == {"t_s"} | {f.name for f in CYCLE if f.numeric}
    assert "tau_com_trim_n" in reader.CYCLE_FIELDS  # was logged but dropped by the reader
    assert reader.EVENTS == set(EVENT_NAMES) and "waypoint_pass" in reader.EVENTS


def test_a_cycle_steered_by_pfec_gpatt_reads_back_as_that_source(tmp_path):
    # the reader used to list "PFEC" while the driver logs "PFEC_GPatt": read back as unknown
    lines = [json.dumps({"event": "cycle", "t_s": 0.1 * k, "mode": "auto", "heading_source": src, "heading_deg": 10.0})
             for k, src in enumerate(HEADING_SOURCES)]
    (tmp_path / "h.jsonl").write_text("\n".join(lines) + "\n")
    log = reader.read_log(tmp_path / "h.jsonl")
    assert [HEADING_SOURCES[c] for c in log.heading_source] == list(HEADING_SOURCES)
    assert "PFEC_GPatt" in HEADING_SOURCES


def test_synthetic_logs_use_only_schema_values(tmp_path):
    for name, kw in (("ok", {}), ("fs", {"failsafe_at_s": 20.0, "dropout_every_s": 12.0}), ("loop", {"loop": True, "duration_s": 60.0})):
        write_synthetic_log(tmp_path / f"{name}.jsonl", **kw)
        for line in (tmp_path / f"{name}.jsonl").read_text().splitlines():
            rec = json.loads(line)
            assert rec["event"] in EVENT_NAMES, rec["event"]
            if rec["event"] == "cycle":
                assert set(rec) == {"event", "t_s", "timestamp", *CYCLE_KEYS}
                assert rec["mode"] in MODES
                assert rec["heading_source"] in (*HEADING_SOURCES, None)
            if rec["event"] == "stop":
                assert rec["reason"] in STOP_REASONS  # the synthetic failsafe log wrote "failsafe"
            if rec["event"] in ("fault", "failsafe"):
                assert rec["cause"] in FAULT_CAUSES
