"""System identification: find where simulation and measurements disagree and name the missing effect.

- :func:`read_trial` (CSV or mission log) -> :class:`Trial`; :func:`read_table_csv`
- :func:`identify` (trials, vessel) -> :class:`Identification`; :func:`identify_table`
- :func:`run` (trials, vessel, out_dir) writes summary.json, report.html, vessel-updated.yaml, effects.yaml
- :data:`EFFECTS` the candidate effects; :func:`load_effects` reads effects.yaml back
- :func:`replay` simulate a trial with effects (what the sensors would have reported)
"""

from __future__ import annotations

from autopilot.lazy import lazy_exports

# Exported names -> the module that owns each. Loaded on first use (PEP 562): importing one light
# submodule (the campaign spec imports effects; `autopilot` imports sysid.cli to build its parser)
# runs this file, which must not load scipy and the whole workflow (the daemon's memory on the boat).
_OWNERS = {
    "EFFECTS": "effects", "EFFECT_NAMES": "effects", "Effect": "effects", "EffectParam": "effects",
    "Identification": "identification", "identify": "identification",
    "read_mission_log": "mission_log",
    "load_effects": "output", "updated_vessel": "output",
    "initial_state": "prediction", "predict": "prediction", "prepare": "prediction",
    "identify_table": "table", "read_table_csv": "table", "write_table_csv": "table",
    "Trial": "trials", "make_trial": "trials", "read_trial": "trials", "read_trial_csv": "trials",
    "write_trial_csv": "trials",
    "run": "workflow",
}


__getattr__, __dir__ = lazy_exports(__name__, _OWNERS, globals())


def replay(trial, vessel, effects: dict | None = None, *, x0=None) -> dict:
    """Simulate one trial from its recorded commands with effects ({"identifier.param": value}).

    x0 defaults to the state estimated from the trial's first seconds. Returns the
    grid ``t_s`` and what the sensors would report (north_m, east_m, psi_rad) plus u, v, r.
    """
    import numpy as np

    from autopilot.sysid.prediction import initial_state, predict, prepare

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
