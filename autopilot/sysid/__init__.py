"""System identification: find where simulation and measurements disagree and name the missing effect.

- :func:`read_trial` (CSV or mission log) -> :class:`Trial`; :func:`read_table_csv`
- :func:`identify` (trials, vessel) -> :class:`Identification`; :func:`identify_table`
- :func:`run` (trials, vessel, out_dir) writes summary.json, report.html, vessel-updated.yaml, effects.yaml
- :data:`EFFECTS` the candidate effects; :func:`load_effects` reads effects.yaml back
- :func:`replay` simulate a trial with effects (what the sensors would have reported)
"""

from __future__ import annotations

import numpy as np

from autopilot.sysid.effects import EFFECT_NAMES, EFFECTS, Effect, EffectParam
from autopilot.sysid.identify import Identification, identify
from autopilot.sysid.mission_log import read_mission_log
from autopilot.sysid.output import load_effects, updated_vessel
from autopilot.sysid.replay import initial_state, predict, prepare
from autopilot.sysid.table import identify_table, read_table_csv, write_table_csv
from autopilot.sysid.trials import (
    Trial,
    make_trial,
    read_trial,
    read_trial_csv,
    write_trial_csv,
)
from autopilot.sysid.workflow import run


def replay(trial: Trial, vessel, effects: dict | None = None, *, x0=None) -> dict:
    """Simulate one trial from its recorded commands with effects ({"identifier.param": value}).

    x0 defaults to the state estimated from the trial's first seconds. Returns the
    grid ``t_s`` and what the sensors would report (north_m, east_m, psi_rad) plus u, v, r.
    """
    prep = prepare([trial], reject=False)
    start = initial_state(trial) if x0 is None else np.asarray(x0, dtype=float)
    out = predict(prep, vessel, [0], start[None, :], dict(effects or {}), sway_over_ground=True)
    result = {k: v[0] for k, v in out.items()}
    result["t_s"] = prep.t_grid
    return result


__all__ = [
    "EFFECTS", "EFFECT_NAMES", "Effect", "EffectParam", "Identification", "Trial", "identify", "identify_table",
    "load_effects", "make_trial", "read_mission_log", "read_table_csv", "read_trial", "read_trial_csv", "replay",
    "run", "updated_vessel", "write_table_csv", "write_trial_csv",
]
