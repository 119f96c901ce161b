"""Files the workflow writes: vessel-updated.yaml, effects.yaml, summary.json (and loading them back).

``vessel-updated.yaml`` is a VesselParams file (autopilot.sim.load_params reads
it): the base set with the effects that are VesselParams fields written in
(``Effect.vessel_fields``, through each effect's ``fields`` hook: ``hydro_refit`` ->
the re-fitted fields; ``yaw_damping_quadratic`` -> yaw_damping_quadratic_nm_s2 + N_rr).
Every other effect has no field in VesselParams and goes to ``effects.yaml``::

    effects:
      <identifier>:            # see autopilot/sysid/effects.py
        <param>: value         # SI / as named (deg, %, s)
    intervals95:
      <identifier>: {<param>: [lo, hi]}

``load_effects`` reads it back as the flat mapping ``prediction.predict`` takes,
refusing unknown identifiers and parameters (ConfigError).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

import yaml

from autopilot.schema import ConfigError, to_dict
from autopilot.sim import VesselParams
from autopilot.sim.params import undamped_axis
from autopilot.sysid.effects import BY_NAME, EFFECTS, by_effect

FIELD_EFFECTS = tuple(e.name for e in EFFECTS if e.vessel_fields)


def updated_vessel(vessel: VesselParams, values: dict, *, digits: int | None = None) -> VesselParams:
    """The base parameters with the field-type effects written in (their ``fields`` hooks; rounded
    to ``digits`` if given)."""
    changes = {}
    for eff, v in by_effect(values).items():
        if eff.vessel_fields:
            changes.update(eff.written_fields(v, vessel))
    if digits is not None:
        changes = {k: float(f"{v:.{digits}g}") for k, v in changes.items()}
    return dataclasses.replace(vessel, **changes)


def write_vessel_updated(vessel: VesselParams, values: dict, verdict, path, *, source: str = "") -> VesselParams:
    """Write DIR/vessel-updated.yaml; returns the parameters written."""
    new = updated_vessel(vessel, values, digits=6)
    written = [e for e in verdict if e in FIELD_EFFECTS]
    others = [e for e in verdict if e not in FIELD_EFFECTS]
    desc = (f"{vessel.description} | autopilot sysid{(' on ' + source) if source else ''}: "
            f"verdict {', '.join(verdict) or 'none'}; written into fields: {', '.join(written) or 'nothing'}"
            + (f"; in effects.yaml (no VesselParams field): {', '.join(others)}" if others else ""))
    new = dataclasses.replace(new, name=f"{vessel.name}-sysid", description=desc)
    problem = undamped_axis(new)
    if problem is not None:  # a fit on a bound (hydro_refit's linear resistance at 0): said, not written as loadable
        print(f"autopilot sysid: warning: {path}: {problem}; the fit sits on a bound: the model lacks what damps "
              "it, or the trials do not show it (load_params refuses this file)", file=sys.stderr)
    header = ("# Vessel parameters updated by `autopilot sysid` (autopilot/sysid/output.py).\n"
              + ("# Loadable by autopilot.sim.load_params; effects without a VesselParams field: effects.yaml.\n"
                 if problem is None else f"# NOT LOADABLE as it stands (autopilot.sim.load_params refuses it): {problem}\n"))
    Path(path).write_text(header + yaml.safe_dump(to_dict(new), sort_keys=False, width=100), encoding="utf-8")
    return new


def write_effects_yaml(effects: dict, path) -> None:
    """effects: the summary's ``effects`` mapping (identifier -> params with values and intervals)."""
    data = {"effects": {}, "intervals95": {}}
    for name, eff in effects.items():
        if name in FIELD_EFFECTS:
            continue
        own = {p.name for p in BY_NAME[name].params}
        data["effects"][name] = {p["name"]: float(p["value"]) for p in eff["params"] if p["name"] in own}
        data["intervals95"][name] = {p["name"]: [float(x) for x in p["ci95"]] for p in eff["params"] if p["name"] in own}
    header = ("# Effects found by `autopilot sysid` that VesselParams has no field for.\n"
              "# Meaning and units of every parameter: autopilot/sysid/effects.py; load with\n"
              "# autopilot.sysid.load_effects(path) and replay with autopilot.sysid.prediction.predict.\n")
    Path(path).write_text(header + yaml.safe_dump(data, sort_keys=False), encoding="utf-8")


def load_effects(path) -> dict[str, float]:
    """effects.yaml -> {"identifier.param": value}."""
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: cannot read effects ({exc})") from exc
    out = {}
    for name, params in (data.get("effects") or {}).items():
        if name not in BY_NAME:
            raise ConfigError(f"{path}: effects.{name}: unknown effect (allowed: {', '.join(BY_NAME)})")
        own = {p.name: p for p in BY_NAME[name].params}
        for pname, value in (params or {}).items():
            if pname not in own:
                raise ConfigError(f"{path}: effects.{name}.{pname}: unknown parameter (allowed: {', '.join(own)})")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"{path}: effects.{name}.{pname}: expected a finite number, got {value!r}")
            p = own[pname]
            if not p.lo <= value <= p.hi:
                raise ConfigError(f"{path}: effects.{name}.{pname}: {value} outside [{p.lo}, {p.hi}] {p.unit}")
            out[f"{name}.{pname}"] = float(value)
    return out


def _clean(obj):
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, str):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(data: dict, path) -> None:
    Path(path).write_text(json.dumps(_clean(data), indent=2) + "\n", encoding="utf-8")
