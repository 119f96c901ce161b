"""``autopilot gnc``: looks at the guidance itself (``gnc surface --plot out.png``)."""

from __future__ import annotations

import argparse


def load_gnc_config(path):
    """The GNC settings of ``path``: a file of GncConfig keys, or one with a ``gnc:`` section (the daemon's
    configuration, which `autopilot files` ships: it was refused as "ais: unknown key", so a tuned gnc block
    could not be evaluated or drawn without copying it out by hand). ``autopilot evaluate --config`` and
    ``autopilot gnc surface --config`` both read it so."""
    from autopilot.daemon.config import DaemonConfig
    from autopilot.gnc.config import GncConfig
    from autopilot.schema import ConfigError, load, load_yaml
    from autopilot.userfile import other_file_kind, parse_yaml, read_text

    try:
        data = parse_yaml(read_text(path, what="YAML file"))
    except Exception:  # noqa: BLE001 - load_yaml below says what is wrong with it, naming the file
        data = None
    if isinstance(data, dict) and "gnc" in data:
        try:  # the whole daemon configuration checked, its gnc section taken
            return load(DaemonConfig, data).gnc
        except ConfigError as exc:
            raise ConfigError(f"{path}: {exc}") from None
    try:
        return load_yaml(GncConfig, path)
    except ConfigError as exc:
        # the vessel file or a mission given as --config said "added_inertia_ratio: unknown key (allowed: ...)"
        what = other_file_kind(path)
        if what is not None and not what.startswith("a daemon") and ": unknown key (allowed: " in str(exc):
            unknown = str(exc).split(" (allowed: ", 1)[0]
            raise ConfigError(f"{unknown}; {path} is {what}, not a GNC configuration (--config takes the daemon's "
                              "configuration, autopilot.yaml, or a file of its gnc: keys)") from None
        raise


def _surface(args: argparse.Namespace) -> int:
    from autopilot.gnc.config import GncConfig
    from autopilot.gnc.fuzzy_guidance import cdh
    from autopilot.gnc.plots import plot_surface

    # the daemon's configuration (the shipped autopilot.yaml) was refused here as "ais: unknown key", while
    # `evaluate --config` read its gnc: section: the one reader now serves both
    cfg = (load_gnc_config(args.config) if args.config else GncConfig()).guidance.fuzzy
    if args.plot is not None:  # --plot "" (an unset shell variable) printed the table instead, unsaid
        from autopilot.userfile import PLOT_SUFFIXES, output_file

        if not args.plot.strip():
            from autopilot.schema import ConfigError

            raise ConfigError(f"--plot: empty; give a file name ending in {', '.join(PLOT_SUFFIXES)}")
        plot_surface(output_file(args.plot, what="--plot", suffixes=PLOT_SUFFIXES), cfg)
        print(f"wrote {args.plot}")
    else:  # a coarse table of the surface on stdout
        import numpy as np

        tcpa = np.linspace(0, cfg.tcpa_max_nd, 7)
        print("DCPA' \\ TCPA' " + " ".join(f"{t:6.2f}" for t in tcpa))
        for d in np.linspace(0, cfg.dcpa_max_nd, 7):
            print(f"{d:13.2f} " + " ".join(f"{c:6.3f}" for c in cdh(tcpa, d, cfg)))
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("gnc", help="guidance tools (fuzzy control surface)")
    sub = p.add_subparsers(dest="gnc_command", metavar="SUBCOMMAND")
    sub.required = True
    s = sub.add_parser("surface", help="the CDH control surface of Table 6.1 (Fig 6.5)")
    s.add_argument("--plot", metavar="PNG", help="write the surface as an image (else print a table)")
    s.add_argument("--config", metavar="FILE", help="GNC configuration YAML (for the universes): the daemon's "
                   "configuration (autopilot.yaml, its gnc: section) or a file of its gnc keys")
    s.set_defaults(func=_surface)
