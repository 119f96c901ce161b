"""``autopilot campaign --replay DIR INDEX``: re-fly one run and write its mission log.

The run is flown again inside its own chunk (the same batch it was flown in, so the
same bits), from ``DIR/campaign.json``; while it flies, every control cycle becomes a
``cycle`` line (:func:`autopilot.daemon.cycle.cycle_record`, every key of
:data:`autopilot.logschema.CYCLE`) and every event the daemon would have logged (faults,
failsafes, modes, waypoints reached, each pass's closest approach, completion) a line
of its own, in the order the daemon writes them, between ``mission_start`` and ``stop``.
``autopilot review DIR/replay-INDEX.jsonl`` reads it like a log from the boat. Timestamps
are a fixed date plus mission time, so the same run gives the same file.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
from pathlib import Path

from autopilot.campaign.draw import draw_run
from autopilot.campaign.lockstep import GNC_RATE_HZ, chunk_indices, fly, run_gnc
from autopilot.campaign.results import RUN_COLUMNS, read_runs_csv
from autopilot.daemon.cycle import cycle_record
from autopilot.daemon.missionlog import to_json
from autopilot.schema import ConfigError, to_dict
from autopilot.userfile import writing

__all__ = ["replay", "same_row", "EPOCH"]

EPOCH = _dt.datetime(2026, 1, 1, tzinfo=_dt.timezone.utc)  # replayed logs' timestamps: this plus mission time


def same_row(a: dict, b: dict, keys=None) -> bool:
    """Two rows hold the same values (NaN equals NaN)."""
    for k in keys or a.keys():
        x, y = a.get(k, math.nan), b.get(k, math.nan)
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            continue
        if x != y:
            return False
    return True


class _LogWriter:
    """The mission-log lines of one run, written as it flies."""

    def __init__(self, path: Path, campaign, setup, seed: int) -> None:
        # written aside and put in place at the run's end: a Ctrl-C left a replay-N.jsonl without its stop line,
        # which `autopilot review` read as a run cut short (a campaign audit)
        self.path, self.part = path, path.with_name(f".{path.name}.part")
        try:
            self.f = open(self.part, "w", encoding="utf-8")  # noqa: SIM115 - closed at the run's end
        except OSError as exc:  # before anything is flown
            raise ConfigError(f"cannot write the run's log {path} ({exc.strerror or exc}): give --log FILE in a "
                              "directory you can write") from None
        self.setup, self.n_passes, self.cycle_no = setup, 0, 0
        m = setup.mission
        spec = campaign.spec
        self.line("mission_start", 0.0, mission=f"campaign:{spec.name}#{setup.index}", mission_name=m.name,
                  guidance=setup.law, rate_hz=GNC_RATE_HZ, sim=True, speedup="max", origin_lat_deg=52.0,
                  origin_lon_deg=4.4, waypoints=[[n, e] for n, e in m.waypoints_ne_m],
                  waypoint_speeds_m_s=list(m.speeds_m_s), boat_length_m=setup.params.length_m,
                  config={"gnc": to_dict(run_gnc(campaign, setup)), "failsafe": to_dict(spec.failsafe),
                          "campaign": {"name": spec.name, "seed": seed, "index": setup.index,
                                       "condition": setup.condition, "drawn": dict(setup.drawn),
                                       "faults": [f.describe() for f in setup.faults],
                                       "position_dropouts": [list(d) for d in setup.position_dropouts],
                                       "heading_dropouts": [list(d) for d in setup.heading_dropouts]}},
                  version=_version(), start_index=0, sc30_port="simulated", mbed_port="simulated", pid=None)

    def line(self, event: str, t_s: float, **fields) -> None:
        stamp = (EPOCH + _dt.timedelta(seconds=t_s)).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        with writing(str(self.path)):  # a full disk names the file
            self.f.write(to_json({"event": event, "t_s": t_s, **fields, "timestamp": stamp}) + "\n")

    def __call__(self, t_s: float, flight, c) -> None:
        """After each control cycle of the run (``c`` None: the run ended at ``t_s``)."""
        if c is None:
            if flight.cycles > self.cycle_no:  # the cycle that ended the run
                self._cycle(t_s, flight, flight.last)
            else:
                self._passes(t_s, flight)
            self._stop(t_s, flight)
        else:
            self._cycle(t_s, flight, c)

    def _passes(self, t_s: float, flight) -> None:
        passes = flight.score.ended_passes
        for p in passes[self.n_passes:]:  # the passes the scorecard closed this cycle
            self.line("waypoint_pass", t_s, wp_index=p.wp_index, closest_approach_m=p.closest_approach_m,
                      closest_t_s=p.t_s, closest_north_m=p.north_m, closest_east_m=p.east_m, fixes=p.fixes)
        self.n_passes = len(passes)

    def _cycle(self, t_s: float, flight, c) -> None:
        for name, fields in c.events:
            self.line(name, t_s, **fields)
        self._passes(t_s, flight)
        self.line("cycle", t_s, **cycle_record(
            cycle=self.cycle_no, t_s=t_s, mode=c.mode, nav=c.nav, out=c.out, cmd=c.cmd, wp_index=flight.ap.wp_index,
            steering=c.out is not None, lateness_s=0.0, skipped=0, heading_latency_s=None, seq=self.cycle_no,
            ack_missing=0, nmea_dropped=0, active_faults=c.active_faults, battery_v=c.battery_v,
            battery_rest_v=c.battery_rest_v))
        self.cycle_no += 1

    def _stop(self, t_s: float, flight) -> None:
        end = flight.end_reason or ""
        reason = ({"finished": "complete", "time": "max_mission_time"}.get(end) or
                  ("failsafe" if end.startswith("failsafe") else "error" if end.startswith("error") else "signal"))
        if reason not in ("complete", "max_mission_time"):
            self.line("info", t_s, message=f"campaign run ended: {end}")
        closest = [None if not math.isfinite(v) else v for v in
                   (flight.score.closest_by_wp.get(i, math.inf) for i in range(len(flight.score.wps)))]
        self.line("stop", t_s, reason=reason, signal=None, ack_received=True, cycles=self.cycle_no, skipped_cycles=0,
                  late_cycles=0, speedup_held=None, nmea_dropped=0, ack_missing=0, closest_approach_m=closest)
        self.f.close()
        os.replace(self.part, self.path)

    def discard(self) -> None:
        """The run did not end (interrupted, an error): no log is left of it."""
        if not self.f.closed:
            self.f.close()
        with contextlib.suppress(OSError):
            self.part.unlink()


def _version() -> str:
    from autopilot.resources import package_version

    return package_version()


def replay(out_dir, index: int, *, log_path=None) -> tuple[dict, Path, dict | None]:
    """Re-fly run ``index`` of the campaign in ``out_dir``: (its row now, the log written, its row in runs.csv
    or None when the directory has no table)."""
    from autopilot.campaign.run import load_run_dir

    out = Path(out_dir)
    campaign, seed, runs = load_run_dir(out)
    if not 0 <= index < runs:
        raise ConfigError(f"--replay {out} {index}: the campaign has runs 0..{runs - 1}")
    chunk = index // campaign.spec.chunk_runs
    path = Path(log_path) if log_path else out / f"replay-{index}.jsonl"
    writer = _LogWriter(path, campaign, draw_run(campaign, seed, index), seed)
    indices = chunk_indices(campaign, runs, chunk)
    try:
        rows = fly(campaign, seed, indices, watch={index: writer})
    finally:
        writer.discard()  # a log put in place is kept; a part one is not
    row = rows[list(indices).index(index)]
    table = None
    if (out / "runs.csv").is_file():
        table = next((r for r in read_runs_csv(out / "runs.csv") if r["index"] == index), None)
    return row, path, table


def scorecard_text(row: dict) -> str:
    """The replayed run's scorecard, one key a line."""
    keys = [k for k, _ in RUN_COLUMNS]
    return "\n".join(f"{k:>26}: {row[k]!r}" for k in keys) + "\n" + json.dumps(
        {k: v for k, v in row.items() if k not in dict(RUN_COLUMNS)}, indent=None)
