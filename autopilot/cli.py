"""The ``autopilot`` command: one entry point, one subcommand per area.

Each area module defines ``register(subparsers)``, which adds its parser and
sets ``func(args) -> int``. Modules are imported here only to build the
parser; heavy imports (scipy, matplotlib) stay inside the command functions.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

# One BLAS thread, set before anything imports numpy: the identification's many small least-squares problems ran 3x
# slower with OpenBLAS's threads on a 2-core machine as soon as anything else ran (two identifications at once: 100 s
# each, 31 s single-threaded; alone 35 and 33 s), and the boat's PC runs the daemon beside them. A user's own
# setting is kept.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# subcommand area modules, in the order they appear in --help
AREAS = (
    "autopilot.sim.cli",
    "autopilot.gnc.cli",
    "autopilot.evaluate",
    "autopilot.campaign.cli",
    "autopilot.drivers.cli",
    "autopilot.daemon.cli",
    "autopilot.sysid.cli",
    "autopilot.review.cli",
)


def _files(args: argparse.Namespace) -> int:
    from autopilot.resources import shipped_files

    for what, path in shipped_files():
        print(f"{path}  ({what})")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from autopilot.resources import package_version

    parser = argparse.ArgumentParser(
        prog="autopilot",
        description="WAM-V autopilot: daemon, simulator, guidance evaluation, identification and review.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    f = sub.add_parser("files", help="list the files shipped with the package (configuration, vessel sets, missions)",
                       description="Print the path of every file shipped inside the package: the default daemon "
                       "configuration, the two vessel parameter sets, the measured table and the missions. "
                       "Copy one to edit it.")
    f.set_defaults(func=_files)
    for name in AREAS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and name.startswith(exc.name):  # area (or its package) not built yet
                continue
            raise
        module.register(sub)
    return parser


def _command_parser(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.ArgumentParser:
    """The parser of the command ``argv`` names (``nmea``'s, not ``autopilot``'s)."""
    for action in parser._actions:  # noqa: SLF001 - argparse keeps its subcommands there, and nowhere public
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for k, word in enumerate(argv):
                if word in action.choices:
                    return _command_parser(action.choices[word], argv[k + 1:])
    return parser


def main(argv: list[str] | None = None) -> int:
    # The console script imports this module before main() runs: it imports nothing of ours at the top,
    # so a Ctrl-C while the areas (numpy and all) load lands here, not in a traceback.
    try:
        from autopilot.schema import ConfigError

        parser = build_parser()
        args, extra = parser.parse_known_args(argv)
        if extra:  # said by the command's own parser: the top level's usage never said what `nmea` takes
            _command_parser(parser, sys.argv[1:] if argv is None else argv).error(
                f"unrecognized arguments: {' '.join(extra)}")
    except KeyboardInterrupt:
        print("autopilot: interrupted", file=sys.stderr)
        return 130
    try:
        return int(args.func(args) or 0)
    except ConfigError as exc:
        print(f"autopilot {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        return 0
    except KeyboardInterrupt:
        print(f"autopilot {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - no traceback reaches a user; AUTOPILOT_DEBUG=1 shows it
        if os.environ.get("AUTOPILOT_DEBUG"):
            raise
        from autopilot.userfile import NO_ROOM_ERRNOS

        if isinstance(exc, IsADirectoryError):  # a directory where an output file goes: the user's to move
            print(f"autopilot {args.command}: error: cannot write {exc.filename}: it is a directory", file=sys.stderr)
            return 1
        if isinstance(exc, OSError) and exc.errno in NO_ROOM_ERRNOS:  # the machine's state, not a bug
            where = f" {exc.filename}" if exc.filename else ""
            print(f"autopilot {args.command}: error: cannot write{where}: {exc.strerror} (the disk is full, "
                  "read-only, or a quota or file size limit was reached; free space and run again)", file=sys.stderr)
            return 1
        print(f"autopilot {args.command}: internal error: {type(exc).__name__}: {exc} "
              "(a bug: please report it with the command line; AUTOPILOT_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
