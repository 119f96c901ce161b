"""``autopilot gnc``: looks at the guidance itself (``gnc surface --plot out.png``)."""

from __future__ import annotations

import argparse


def _surface(args: argparse.Namespace) -> int:
    from autopilot.gnc.config import GncConfig
    from autopilot.gnc.fuzzy_guidance import cdh
    from autopilot.gnc.plots import plot_surface
    from autopilot.schema import load_yaml

    cfg = (load_yaml(GncConfig, args.config) if args.config else GncConfig()).guidance.fuzzy
    if args.plot:
        from autopilot.userfile import PLOT_SUFFIXES, output_file

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
    s.add_argument("--config", metavar="FILE", help="GNC configuration YAML (for the universes)")
    s.set_defaults(func=_surface)
