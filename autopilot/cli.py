"""The ``autopilot`` command: one entry point, one subcommand per area.

Each area module defines ``register(subparsers)``, which adds its parser and
sets ``func(args) -> int``. Modules are imported here only to build the
parser; heavy imports (scipy, matplotlib) stay inside the command functions.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from autopilot.schema import ConfigError

# subcommand area modules, in the order they appear in --help
AREAS = (
    "autopilot.sim.cli",
    "autopilot.gnc.cli",
    "autopilot.evaluate",
    "autopilot.drivers.cli",
    "autopilot.daemon.cli",
    "autopilot.sysid.cli",
    "autopilot.review.cli",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="autopilot",
        description="WAM-V autopilot: daemon, simulator, guidance evaluation, identification and review.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in AREAS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and name.startswith(exc.name):  # area (or its package) not built yet
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"autopilot {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
