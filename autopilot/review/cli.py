"""``autopilot review``: one command from mission logs to a report, a scorecard and exports."""

from __future__ import annotations

import argparse
import math
from pathlib import Path


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "review",
        help="post-mission review: plots, scorecard, report.html, GPX/KML/GeoJSON/CSV exports",
        description="Review one or several mission logs (JSON lines, docs/log-schema.md). "
        "Writes DIR/report.html with its PNGs and summary.json; with several logs, an "
        "overlay of the tracks and a side-by-side scorecard, each log in DIR/<k>-<stem>/.",
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help="mission log file(s) (.jsonl)")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output directory (default: review-<stem of the first log> here)")
    p.add_argument("--export", metavar="FMTS", default="",
                   help="comma-separated exports: gpx,kml,geojson,csv (csv = the sysid trial file)")
    p.add_argument("--no-plots", action="store_true", help="skip the figures (scorecard and exports only)")
    p.set_defaults(func=run)


def is_review_summary(summary) -> bool:
    """A summary.json this command wrote: one log's scorecard, or a list of them."""
    cards = summary if isinstance(summary, list) else [summary]
    return bool(cards) and all(isinstance(c, dict) and "cycles" in c for c in cards)


def run(args: argparse.Namespace) -> int:
    from autopilot.review.export import parse_formats
    from autopilot.review.reader import check_mission_log
    from autopilot.review.report import review

    formats = parse_formats(args.export)
    for path in args.logs:
        check_mission_log(path)
    from autopilot.userfile import output_dir

    out = output_dir(args.out if args.out else f"review-{Path(args.logs[0]).stem}",
                     files=("report.html", "summary.json", "tracks.png"), summary_is_ours=is_review_summary,
                     command="autopilot review")
    result = review(args.logs, out, formats=formats, with_plots=not args.no_plots)
    failed = False
    for one in result.logs:
        card = one.card
        if card.cycles == 0:
            print(f"{card.path}: no cycle lines: nothing to review (report written with what was read)")
            failed = True
        else:
            travelled = f"{card.distance_m:.1f} m" if math.isfinite(card.distance_m) else "no position"
            print(f"{card.path}: {card.cycles} cycles, {card.mission_time_s:.1f} s, "
                  f"{travelled}, {len(card.failsafes)} failsafe(s)")
        for note in card.read_notes[1:]:
            print(f"  {note}")
        for fmt, path in one.exports.items():
            print(f"  {fmt}: {path}")
        for fmt, msg in one.export_errors.items():
            print(f"  {fmt} export failed: {msg}")
            failed = True
    print(f"report: {result.report}")
    return 1 if failed else 0
