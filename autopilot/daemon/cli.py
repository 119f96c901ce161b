"""``autopilot run``: the onboard daemon (issue 4), or a bench run against simulated devices."""

from __future__ import annotations

import argparse
import math

__all__ = ["register"]


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run",
        help="run the autopilot daemon on a mission (real devices, or --sim)",
        description=(
            "Run the fixed-rate autopilot loop on a mission. Configuration and mission are checked "
            "before any port is opened; thrust starts at zero and control begins once heading and "
            "position are valid. SIGTERM/SIGINT stop the boat (zero thrust, acknowledged) and exit 0."
        ),
    )
    p.add_argument("--config", required=True, metavar="FILE", help="daemon configuration (config/autopilot.yaml)")
    p.add_argument("--mission", required=True, metavar="FILE", help="mission file (waypoints)")
    p.add_argument("--sim", action="store_true", help="start simulated SC-30 and Mbed on pseudo-terminals in this process")
    p.add_argument("--speedup", type=_speedup, default=1.0, metavar="N|max",
                   help="--sim: run the clock N times faster than real time (default 1), or max: the daemon and the "
                   "simulated devices in lockstep on a simulated clock, as fast as the machine allows and the same "
                   "run on a busy machine as on an idle one")
    p.add_argument("--log-dir", metavar="DIR", help="override log_dir (systemd: $LOGS_DIRECTORY)")
    p.add_argument("--state-dir", metavar="DIR", help="override state_dir (systemd: $STATE_DIRECTORY)")
    p.add_argument("--fresh", action="store_true", help="ignore mission progress saved by an interrupted run")
    p.set_defaults(func=_run)


def _speedup(text: str) -> float:
    if text.strip().lower() == "max":
        return math.inf
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r} (or max)") from None


def _run(args: argparse.Namespace) -> int:
    from autopilot.daemon.app import RunOptions, run_daemon
    from autopilot.daemon.config import load_config

    cfg = load_config(args.config)
    opts = RunOptions(
        mission_path=args.mission,
        sim=args.sim,
        speedup=args.speedup,
        log_dir=args.log_dir,
        state_dir=args.state_dir,
        fresh=args.fresh,
    )
    try:
        return run_daemon(cfg, opts)
    except KeyboardInterrupt:  # a Ctrl-C before the signal handlers are installed
        return 130
