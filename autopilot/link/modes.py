"""How the autopilot presents its modes over MAVLink: ArduPilot Rover's numbering, one table.

The HEARTBEAT says ``MAV_AUTOPILOT_ARDUPILOTMEGA`` and ``MAV_TYPE_SURFACE_BOAT`` with Rover's
``custom_mode`` numbers, so that QGroundControl and Mission Planner (whose ArduPilot plug-ins
know those numbers) name the mode on screen and offer their mode buttons, and a mode set from
them arrives as a number this table maps back. A generic autopilot would show only
``base_mode`` flags and could not be switched from either planner's mode menu. The meaning
follows Rover's: Rover's HOLD stops the motors (our ``stop``), Rover's LOITER holds position
(our ``hold``).

    ours       Rover          set from the planner as
    waiting    INITIALISING   - (before control starts; a mode chosen meanwhile is reported as itself)
    auto       AUTO (10)      AUTO: the mission (not back to what a pause interrupted: DO_PAUSE_CONTINUE)
    hold       LOITER (5)     LOITER: hold here
    paused     LOITER (5)     (MAV_CMD_DO_PAUSE_CONTINUE 0)
    rtl        RTL (11)       RTL (and the hold at the launch point it ends in, as Rover's)
    stop       HOLD (4)       HOLD: zero thrust
    failsafe   HOLD (4)       -
    complete   HOLD (4)       -
    manual     MANUAL (0)     MANUAL: needs MANUAL_CONTROL (else the manual timeout holds)
    -          GUIDED (15)    GUIDED: hold here until a reposition ("go here")
"""

from __future__ import annotations

from autopilot.logschema import RTL_ARRIVED_CAUSE, Mode

__all__ = ["ROVER_MODES", "GUIDED_CAUSE", "rover_mode", "rover_mode_name", "command_for_rover_mode"]

ROVER_MODES = {0: "MANUAL", 1: "ACRO", 3: "STEERING", 4: "HOLD", 5: "LOITER", 6: "FOLLOW", 7: "SIMPLE",
               8: "DOCK", 9: "CIRCLE", 10: "AUTO", 11: "RTL", 12: "SMART_RTL", 15: "GUIDED", 16: "INITIALISING"}

_OURS_TO_ROVER = {
    Mode.WAITING: 16, Mode.AUTO: 10, Mode.HOLD: 5, Mode.PAUSED: 5, Mode.RTL: 11, Mode.STOP: 4,
    Mode.FAILSAFE: 4, Mode.COMPLETE: 4, Mode.MANUAL: 0,
}
# AUTO is the mission, never "back to what a pause interrupted" (ctl resume, DO_PAUSE_CONTINUE): as resume, AUTO
# chosen while paused on an rtl was acknowledged and took the boat home (a new-user audit)
_ROVER_TO_COMMAND = {10: "auto", 5: "hold", 11: "rtl", 4: "stop", 0: "manual", 15: "hold"}


GUIDED_CAUSE = "mavlink guided"  # the helm's mode cause of a hold the planner asked for as GUIDED


def rover_mode(mode: Mode | str, cause: str | None = None) -> int:
    """The Rover mode number of ours; a hold asked for as GUIDED is GUIDED (15): reported as LOITER, QGC's Start
    Mission (GUIDED, arm, MISSION_START) saw the mode change fail three times and gave up (found by a GCS audit)."""
    if Mode(mode) is Mode.HOLD and cause == GUIDED_CAUSE:
        return 15
    if Mode(mode) is Mode.HOLD and cause == RTL_ARRIVED_CAUSE:
        return 11  # Rover stays in RTL at home (a boat loiters there): LOITER came unasked (a GCS audit)
    return _OURS_TO_ROVER[Mode(mode)]


def rover_mode_name(mode: Mode | str, cause: str | None = None) -> str:
    """The name a planner shows for the mode: ``LOITER`` for our ``hold``, ``HOLD`` for our ``stop``."""
    return ROVER_MODES[rover_mode(mode, cause)]


def command_for_rover_mode(custom_mode: int) -> str | None:
    """The command a planner's mode change means, or None (unsupported)."""
    return _ROVER_TO_COMMAND.get(int(custom_mode))
