"""Mission progress in the state directory, written atomically (issue 7, restart safety).

One small JSON file per daemon: which mission (path and SHA-256 of its
content), the waypoint being steered to, and whether the mission is still
running. Written as tmp file + fsync + rename + fsync of the directory, so
after a crash or power cut the file is either the old or the new version,
never half of one.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

from autopilot.gnc.speed import SPEED_RANGE, is_speed

__all__ = ["Progress", "StateStore", "file_sha256", "save_uploaded_mission", "UPLOADED_MISSION"]

STATE_FILE = "mission-progress.json"
OPERATOR_MODES = ("", "stop", "hold", "paused", "rtl", "manual")  # Progress.operator
RESUME_REFUSED = "a failsafe took the boat; resume is refused"  # said of a held start that resume cannot end
UPLOADED_MISSION = "uploaded-mission.waypoints"  # a mission uploaded over MAVLink (Mission Planner's format)


def file_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class Progress:
    mission: str
    mission_sha256: str
    wp_index: int
    status: str  # "running", "complete", "stopped", "aborted"
    # what a restart must not forget (found by fault injection: a kill -9 after a geofence's rtl, and the next
    # start's `ctl resume` drove back to the fence, its rtl "home" wherever the boat was at the restart)
    latched: tuple[str, ...] = ()  # the latched failsafe causes
    launch_ne_m: tuple[float, float] | None = None  # rtl's home
    reason: str = ""  # why an aborted run stopped (the stop line's reason: max_mission_time, error)
    # the operator's disarm: zero thrust whatever the mode, until armed (found by a link audit: a kill -9 of a
    # disarmed boat and a restart with resume_after_restart flew the mission under thrust)
    armed: bool = True
    # the route done and the mission's own rtl under way: a restart resumes the way home, not the last waypoint
    # (left in stop 42's note: `resume` after a crash on the way home flew out to the last waypoint first)
    homeward: bool = False
    # the mode the operator (ctl, the ground station, its loss) took the boat off the mission with, in force: stop,
    # hold, paused, rtl, manual; "" while the mission (or nothing the operator chose) runs. A restart with
    # resume_after_restart flew the mission again after a crash in the operator's stop, hold or rtl (an operator
    # audit); it holds zero thrust now
    operator: str = ""
    # the operator's speed (m/s) for the legs, in place of the planned ones (Autopilot.speed_m_s); None: planned.
    # A restart carrying the run on keeps it (the boat slowed near swimmers went on at its planned speed)
    speed_m_s: float | None = None


class StateStore:
    """Reads and atomically replaces ``<state_dir>/mission-progress.json``."""

    def __init__(self, state_dir: str | Path) -> None:
        self.dir = Path(state_dir)
        self.path = self.dir / STATE_FILE
        self._last: Progress | None = None

    def load(self) -> Progress | None:
        """The saved progress, or None when absent or unreadable (never trusted half-way)."""
        return self.read()[0]

    def read(self) -> tuple[Progress | None, str | None]:
        """(the saved progress or None, why a file that is there cannot be read, or None). A progress file
        that cannot be read may be that of an interrupted run: the caller must not take it as none."""
        if not self.path.exists():
            return None, None
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            index = data["wp_index"]
            if type(index) is not int:  # not "3", 3.0, true, Infinity: a file no daemon wrote
                raise ValueError(f"wp_index {index!r} is not a whole number")
            latched = tuple(data.get("latched") or ())
            if not all(isinstance(c, str) for c in latched):
                raise ValueError(f"latched {data.get('latched')!r} is not a list of causes")
            armed = data.get("armed", True)
            if type(armed) is not bool:
                raise ValueError(f"armed {armed!r} is not true or false")
            homeward = data.get("homeward", False)
            if type(homeward) is not bool:
                raise ValueError(f"homeward {homeward!r} is not true or false")
            operator = data.get("operator", "")
            if operator not in OPERATOR_MODES:
                raise ValueError(f"operator {operator!r} is not one of {', '.join(repr(m) for m in OPERATOR_MODES)}")
            speed = data.get("speed_m_s")
            if speed is not None and not is_speed(speed):
                raise ValueError(f"speed_m_s {speed!r} is not a speed in {SPEED_RANGE}")
            launch = data.get("launch_ne_m")
            if launch is not None:
                launch = tuple(float(v) for v in launch)
                if len(launch) != 2 or not all(math.isfinite(v) for v in launch):
                    raise ValueError(f"launch_ne_m {data.get('launch_ne_m')!r} is not a point")
            return Progress(mission=str(data["mission"]), mission_sha256=str(data["mission_sha256"]),
                            wp_index=index, status=str(data["status"]), latched=latched, launch_ne_m=launch,
                            reason=str(data.get("reason") or ""), armed=armed, homeward=homeward,
                            operator=operator, speed_m_s=None if speed is None else float(speed)), None
        except (OSError, ValueError, KeyError, TypeError, AttributeError, OverflowError) as exc:
            return None, f"{type(exc).__name__}: {exc}"

    def save(self, progress: Progress) -> None:
        """Replace the file atomically; skip when nothing changed."""
        if progress == self._last:
            return
        data = json.dumps(asdict(progress), sort_keys=True).encode("utf-8")
        write_atomically(self.path, data + b"\n")
        self._last = progress

    def uploaded_to_continue(self) -> Path | None:
        """The mission uploaded over MAVLink, if it is the saved one and was neither completed nor cleared: it
        replaced the configured mission, and a restart (a crash, or systemctl restart) keeps it."""
        saved = self.load()
        path = self.dir / UPLOADED_MISSION
        if saved is None or saved.status in ("complete", "cleared") or Path(saved.mission) != path or not path.is_file():
            return None
        try:
            return path if file_sha256(path) == saved.mission_sha256 else None
        except OSError:  # unreadable: the caller holds zero (an interrupted run of a mission it cannot load)
            return None

    def interrupted(self, mission_sha256: str, n_waypoints: int) -> tuple[int | None, str | None]:
        """After a start without --fresh: (the waypoint an interrupted run of this mission was at, None), or
        (None, why the boat must hold zero thrust: a run was, or may have been, interrupted and cannot be
        continued as it was; or the last run of this mission was aborted, or ended with a failsafe latched),
        or (that waypoint, why) when the operator's mode was in force (held there, resume continues),
        or (None, None) when no run was interrupted. A run of another mission (an
        uploaded one since deleted or edited, or the mission file edited since) is not the one to continue,
        nor a reason to start this one from its first waypoint unasked."""
        saved, problem = self.read()
        if problem is not None:
            return None, f"the saved progress {self.path} cannot be read ({problem}): a run may have been interrupted"
        if saved is not None and saved.mission_sha256 == mission_sha256 and saved.status == "aborted":
            # a crash caught by the loop, or max_mission_time: it flew again from W0 (a clean stop, a signal, is
            # the operator's: the next start is a new run, its latched faults not carried over)
            if saved.latched:
                return None, (f"the last run of this mission ended with {', '.join(saved.latched)} latched "
                              f"({RESUME_REFUSED})")
            return None, f"the last run of this mission was aborted ({saved.reason or 'no reason saved'})"
        if saved is not None and saved.status == "cleared":
            # the ground station cleared the mission and the daemon never stopped cleanly after (a crash, a kill,
            # a power cut): the operator's "no mission" stands. It flew the configured mission from its first
            # waypoint under thrust, unasked (a new-user audit)
            return None, ("the last run's mission was cleared from the ground station (MISSION_CLEAR_ALL) and that "
                          "run did not end cleanly")
        if saved is None or saved.status != "running":
            return None, None
        if saved.latched and saved.mission_sha256 == mission_sha256:
            return None, f"an interrupted run of this mission had {', '.join(saved.latched)} latched ({RESUME_REFUSED})"
        if saved.mission_sha256 != mission_sha256:
            return None, (f"an interrupted run of another mission ({saved.mission}, or this file since edited) "
                          "is in the state directory")
        if not 0 <= saved.wp_index < n_waypoints:
            return None, f"the saved progress's waypoint {saved.wp_index} is not in this mission (0..{n_waypoints - 1})"
        if saved.operator:  # held at the waypoint it was at: ctl resume continues from there
            return saved.wp_index, (f"the operator's {saved.operator} was in force when a run of this mission was "
                                    "interrupted (the boat had been taken off the mission): not flown again unasked")
        return saved.wp_index, None


def write_atomically(path: Path, data: bytes) -> None:
    """tmp file + fsync + rename + fsync of the directory: after a power cut, the old file or the new one."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o640)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    dfd = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)


def save_uploaded_mission(state_dir: str | Path, mission) -> tuple[Path, str]:
    """Write a mission uploaded over the link to the state directory; (its path, its SHA-256)."""
    from autopilot.mission import to_waypoints_text

    path = Path(state_dir) / UPLOADED_MISSION
    data = to_waypoints_text(mission).encode("utf-8")
    write_atomically(path, data)
    return path, hashlib.sha256(data).hexdigest()
