"""``autopilot run``: the onboard daemon (issue 4), or a bench run against simulated devices."""

from __future__ import annotations

import argparse
import math

__all__ = ["register"]


def register(subparsers) -> None:
    from autopilot.logschema import COMMANDS

    p = subparsers.add_parser(
        "run",
        help="run the autopilot daemon on a mission (real devices, or --sim)",
        description=(
            "Run the fixed-rate autopilot loop on a mission. Configuration and mission are checked "
            "before any port is opened; thrust starts at zero and control begins once heading and "
            "position are valid. SIGTERM/SIGINT/SIGHUP stop the boat (zero thrust, acknowledged) and exit 0."
        ),
    )
    p.add_argument("--config", metavar="FILE", help="daemon configuration (config/autopilot.yaml); required on the "
                   "boat, with --sim the shipped one by default (autopilot files lists it)")
    p.add_argument("--mission", required=True, metavar="FILE", help="mission file (waypoints), or the name of a "
                   "shipped one (pond-9.4; autopilot files lists them)")
    p.add_argument("--sim", action="store_true", help="start simulated SC-30 and Mbed on pseudo-terminals in this process")
    p.add_argument("--speedup", type=_speedup, default=1.0, metavar="N|max",
                   help="--sim: run the clock N times faster than real time (default 1), or max: the daemon and the "
                   "simulated devices in lockstep on a simulated clock, as fast as the machine allows and the same "
                   "run on a busy machine as on an idle one")
    p.add_argument("--log-dir", metavar="DIR", help="override log_dir (systemd: $LOGS_DIRECTORY)")
    p.add_argument("--state-dir", metavar="DIR", help="override state_dir (systemd: $STATE_DIRECTORY)")
    p.add_argument("--runtime-dir", metavar="DIR", help="override runtime_dir: where the control socket goes "
                   "(systemd: $RUNTIME_DIRECTORY)")
    p.add_argument("--fresh", action="store_true", help="ignore mission progress saved by an interrupted run")
    p.add_argument("--mavlink", action="append", default=[], metavar="URL",
                   help="a MAVLink endpoint, repeatable: udpout:HOST:PORT (a ground station listening, QGC: "
                   "udpout:127.0.0.1:14550), udpin:ADDR:PORT (listen there), /dev/ttyUSB0:57600 (a radio)")
    p.set_defaults(func=_run)

    c = subparsers.add_parser(
        "ctl",
        help="command the running daemon: status, hold, pause, resume, rtl, stop, speed",
        description=(
            "Talk to the running daemon over its control socket (/run/wamv-autopilot/control.sock for the "
            "service; members of its group may use it). Each command answers with the new mode or a refusal "
            "that says why (rtl refused: position stale). status: mode, waypoint, position, battery, faults. "
            "hold: keep station here (least-effort heading, or --heading); pause: hold here, resume continues "
            "the mission from the same waypoint; resume: back to the mission (ends a hold item early); rtl: "
            "return to the launch point and hold there; stop: zero thrust until the next command; disarm: zero thrust "
            "whatever the mode until arm; speed M_S: the speed over ground on every leg of the mission and of a return "
            "in place of the planned ones (turns and arrivals still slow it), until `speed mission` gives them back or a "
            "new mission comes. "
            "Exit 0 accepted, 1 refused, 3 no daemon."
        ),
    )
    c.add_argument("command", choices=COMMANDS)
    c.add_argument("value", nargs="?", metavar="M_S", help="speed: the legs' speed in m/s, or `mission` for the "
                   "mission's planned speeds")
    c.add_argument("--heading", type=float, metavar="DEG", help="hold: the heading to keep (deg from north)")
    c.add_argument("--runtime-dir", metavar="DIR", help="the daemon's runtime directory (default: the service's, "
                   "then $XDG_RUNTIME_DIR/autopilot)")
    c.add_argument("--json", action="store_true", help="print the daemon's answer as JSON")
    c.set_defaults(func=_ctl)


def _speedup(text: str) -> float:
    if text.strip().lower() == "max":
        return math.inf
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r} (or max)") from None


def _run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from autopilot.daemon.app import RunOptions, run_daemon
    from autopilot.daemon.config import load_config
    from autopilot.resources import default_config_path, find_mission
    from autopilot.schema import ConfigError

    config = args.config
    if config is None:
        if not args.sim:  # the boat's own ports and launch point: never a default that only fits the bench
            print("autopilot run: error: --config is required without --sim (the boat's serial ports and origin; "
                  "`autopilot files` lists the shipped configuration to copy and edit)", file=sys.stderr)
            return 2
        config = default_config_path()
        print(f"note: --sim without --config: the shipped configuration ({config})", file=sys.stderr)
    cfg = load_config(config)  # the configuration's errors first, as before a mission was found by its name
    mission = args.mission
    if not Path(mission).exists():
        try:
            shipped, _ = find_mission(mission)
        except ConfigError as exc:
            print(f"autopilot run: error: --mission {exc}", file=sys.stderr)
            return 2
        print(f"note: --mission {mission}: the shipped mission {shipped}", file=sys.stderr)
        mission = str(shipped)
    opts = RunOptions(
        mission_path=mission,
        sim=args.sim,
        speedup=args.speedup,
        log_dir=args.log_dir,
        state_dir=args.state_dir,
        runtime_dir=args.runtime_dir,
        fresh=args.fresh,
        mavlink=tuple(args.mavlink),
    )
    try:
        return run_daemon(cfg, opts)
    except KeyboardInterrupt:  # a Ctrl-C before the signal handlers are installed
        return 130


def _ctl(args: argparse.Namespace) -> int:
    import errno
    import json
    import math
    import sys

    from autopilot.daemon.control import request, socket_candidates
    from autopilot.gnc.speed import SPEED_RANGE

    req: dict = {"command": args.command}
    if (args.value is None) != (args.command != "speed"):
        print("autopilot ctl: error: " + ("speed needs a speed in m/s, or `mission`" if args.value is None
                                          else f"a value ({args.value}) is for speed only"), file=sys.stderr)
        return 2
    if args.command == "speed":
        speed = None if args.value.strip().lower() == "mission" else _ctl_speed(args.value)
        if speed is False:
            print(f"autopilot ctl: error: speed: {args.value!r} is not a speed in {SPEED_RANGE} or "
                  "`mission`", file=sys.stderr)
            return 2
        req["speed_m_s"] = speed
    if args.heading is not None:
        if args.command != "hold":
            print("autopilot ctl: error: --heading is for hold only", file=sys.stderr)
            return 2
        if not (math.isfinite(args.heading) and 0.0 <= args.heading < 360.0):  # 400 used to hold 40
            print(f"autopilot ctl: error: --heading: {args.heading:g} is outside the allowed range [0, 360) deg",
                  file=sys.stderr)
            return 2
        req["heading_deg"] = args.heading
    tried = socket_candidates(args.runtime_dir)
    reply, problems = None, []
    for path in tried:
        try:
            reply = request(path, req)
            break
        except FileNotFoundError:
            problems.append(f"no socket at {path}")
        except PermissionError:
            problems.append(f"{path}: permission denied (the socket is for the service's user and group: "
                            "add yourself to the group wamv-autopilot)")
        except OSError as exc:
            reason = "no daemon answers" if exc.errno in (errno.ECONNREFUSED, errno.ENOENT) else exc.strerror
            problems.append(f"{path}: {reason or exc}")
        except ValueError:
            problems.append(f"{path}: the answer was not JSON")
    if reply is None:
        print("autopilot ctl: no running daemon answered (" + "; ".join(problems) + ")", file=sys.stderr)
        return 3
    if not isinstance(reply, dict) or (args.command == "status" and reply.get("ok")
                                       and not isinstance(reply.get("status"), dict)):
        # something answers on the socket that is not this daemon (an internal error: AttributeError before)
        print(f"autopilot ctl: the answer on {path} is not a daemon's: {str(reply)[:200]}", file=sys.stderr)
        return 3
    if args.json:
        print(json.dumps(reply, indent=2 if args.command == "status" else None))
    elif args.command == "status" and reply.get("ok"):
        for line in _status_lines(reply["status"]):
            print(line)
    else:
        text = reply.get("answer", "")
        print(text + (f" ({reply['note']})" if reply.get("note") else ""))
    return 0 if reply.get("ok") else 1


def _ctl_speed(text: str):
    """A speed (m/s) the boat can be asked for (autopilot.gnc.speed.is_speed), or False."""
    from autopilot.gnc.speed import is_speed

    try:
        v = float(text.replace(",", "."))  # 1,5 as a European keyboard gives it
    except ValueError:
        return False
    return v if is_speed(v) else False


def _status_lines(st: dict) -> list[str]:
    def num(key, fmt, unit=""):
        v = st.get(key)
        return "n/a" if v is None else f"{v:{fmt}}{unit}"

    cause = st.get("mode_cause")
    lines = [f"mode: {st.get('mode')}" + (f" (helm: {st['helm_mode']})" if st.get("helm_mode") not in (None, st.get("mode"))
                                         else "")
             + _planner_name(st.get("mode"), cause)
             # why (a held start said only "mode: stop"; --json had it: a new-user audit)
             + (f" - {cause}" if cause and cause != "start" else "")
             + (" - DISARMED: zero thrust whatever the mode (autopilot ctl arm)" if st.get("armed") is False else "")
             # a mode chosen before control starts is shown as itself: said that it waits (zero thrust until then)
             + (" - control has not started (waiting for valid data)"
                if st.get("control_started") is False and st.get("mode") != "waiting" else ""),
             f"mission time: {num('t_s', '.1f', ' s')}, cycle {st.get('cycle')}"]
    if "wp_index" in st:
        done = ", complete" if st.get("mission_complete") else ""
        lines.append(f"waypoint: {st['wp_index']} of {st.get('wp_count')}{done}")
    if st.get("speed_set_m_s") is not None:
        lines.append(f"speed: {st['speed_set_m_s']:g} m/s on every leg, the operator's (`autopilot ctl speed mission`: "
                     "the planned speeds)")
    lines.append(f"position: north {num('north_m', '.1f', ' m')}, east {num('east_m', '.1f', ' m')}; heading "
                 f"{num('heading_deg', '.1f', ' deg')}; speed {num('sog_m_s', '.2f', ' m/s')}")
    if st.get("hold_north_m") is not None:
        lines.append(f"holding: north {st['hold_north_m']:.1f} m, east {st['hold_east_m']:.1f} m, "
                     f"error {num('hold_error_m', '.2f', ' m')}")
        if st.get("hold_across_feasible_deg") is not None:  # said in the log and to the planner only (an audit)
            lines.append(f"hold heading {num('hold_heading_deg', '.0f', ' deg')} cannot keep the point: the current "
                         f"or wind is across it, from about {st['hold_across_feasible_deg']:.0f} deg; hold without "
                         "--heading to face it")
    lines.append(f"battery: {num('battery_v', '.2f', ' V')}")
    # a latched fault's action stays in force whether or not its cause is still there: listed apart, and one
    # carried over from the run before a restart said so (it read as a fault of now: an operator audit)
    latched = st.get("latched_faults") or []
    before = set(st.get("latched_before_restart") or ())
    faults = [f for f in st.get("active_faults") or [] if f not in latched]
    lines.append("faults: " + (", ".join(faults) if faults else "none")
                 + ("; latched: " + ", ".join(f + (" (before the restart)" if f in before else "") for f in latched)
                    if latched else ""))
    return lines


def _planner_name(mode, cause) -> str:
    """The name QGroundControl and Mission Planner show for our mode, where it is not ours: their HOLD is our
    stop, their LOITER our hold (an operator audit: the planner and ctl named one mode two ways)."""
    from autopilot.link.modes import rover_mode_name

    try:
        name = rover_mode_name(mode, cause)
    except (ValueError, KeyError):
        return ""
    return "" if name.lower() == str(mode) else f" (planner: {name})"
