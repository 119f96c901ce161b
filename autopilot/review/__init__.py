"""Post-mission review: mission log -> scorecard, figures, report.html and map/trial exports.

``autopilot review LOG [LOG ...] [--out DIR] [--export gpx,kml,geojson,csv]``.
The reader streams the log once and is tolerant of cut, corrupt and
unknown lines (it counts them and never invents data); see
docs/log-schema.md for the format.
"""

from autopilot.review.reader import CYCLE_FIELDS, MissionLog, ReadStats, read_log

__all__ = ["CYCLE_FIELDS", "MissionLog", "ReadStats", "read_log"]
