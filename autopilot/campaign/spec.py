"""The campaign spec (YAML) and the resolved :class:`Campaign` that every run is drawn from.

A spec names missions, guidance laws, a vessel-parameter spread and named *conditions*,
each a spread of disturbances, sensor imperfections and faults::

    name: pond-robustness
    missions: [pond-9.1, pond-9.4]          # shipped names, or files relative to the spec
    laws: [fuzzy, los]
    runs: 1200                               # default of --runs
    seed: 1                                  # default of --seed
    chunk_runs: 120                          # runs flown in lockstep per task (the unit of retry)
    success_radius_m: 2.5                    # success: completed, no circling, every waypoint within this
    vessel:
      file: ""                               # VesselParams YAML; empty = config/vessel.yaml
      sysid: ""                              # a sysid summary.json: its 95 % intervals as uniform spreads
      fields: {mass_kg: {scale: [0.9, 1.1]}, n_r_nd: {uniform: [-0.25, -0.12]}}
    conditions:
      calm: {}
      current: {current_speed_m_s: {uniform: [0.0, 0.3]}, current_towards_deg: {uniform: [0, 360]}}
      faults: {faults: {probability: 1.0, kinds: [gnss_lost, mbed_lost], at_s: {uniform: [5, 40]}}}
    gnc: {...}                               # GncConfig keys (autopilot.gnc.config)
    failsafe: {...}                          # the daemon's FailsafeConfig keys

A spread (:class:`Spread`) is a bare number (fixed), ``{value: x}``, ``{uniform: [lo, hi]}``,
``{normal: [mean, sd]}`` (cut at mean +- 3 sd) or ``{scale: [lo, hi]}`` (the nominal value
times a factor uniform in [lo, hi]). Every quantity's unit and allowed range are its owner's
(``VesselParams``, ``Environment``, ``SinusoidalDisturbance``, the sysid effects, the daemon's
``SimConfig``): a spread that can reach outside that range is refused naming the key and the
range, as an unknown key is (:mod:`autopilot.schema`).

:func:`resolve` turns a checked spec into a :class:`Campaign`: data only (missions as
waypoints, the base vessel as numbers), so a Dask worker on another machine needs neither
the spec nor the mission files; ``Campaign.to_data`` / ``Campaign.from_data`` round-trip it
through JSON exactly (``DIR/campaign.json``, what ``--replay`` re-flies).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from autopilot.daemon.config import FailsafeConfig, SimConfig
from autopilot.gnc import GncConfig
from autopilot.gnc.config import LAWS
from autopilot.schema import ConfigError, _range_text, load, param, to_dict
from autopilot.sim import Environment, SinusoidalDisturbance, VesselParams
from autopilot.sysid.effects import BY_NAME as EFFECTS

__all__ = ["Spread", "FaultSpread", "Condition", "VesselSpread", "CampaignSpec", "MissionData", "Campaign",
           "FAULT_KINDS", "VESSEL_FIELDS", "load_spec", "resolve", "spread_support"]

FAULT_KINDS = ("gnss_lost", "compass_lost", "mbed_lost", "nmea_garbage", "thruster_failure", "battery_low")
# VesselParams' numeric fields: the ones a spread may move
VESSEL_FIELDS = tuple(f.name for f in dataclasses.fields(VesselParams) if f.type in ("float", float))


@dataclass(frozen=True)
class Spread:
    """How one quantity varies from run to run: exactly one of these."""

    value: float | None = param(None, doc="fixed value")
    uniform: tuple[float, float] | None = param(None, doc="[lo, hi]: uniform between")
    normal: tuple[float, float] | None = param(None, doc="[mean, sd]: normal, cut at mean +- 3 sd")
    scale: tuple[float, float] | None = param(None, doc="[lo, hi]: the nominal value times a factor uniform between")

    def draw(self, rng, nominal: float = 0.0) -> float:
        """One value (uses the generator only when there is something to draw)."""
        if self.value is not None:
            return float(self.value)
        if self.uniform is not None:
            lo, hi = self.uniform
            return lo + (hi - lo) * float(rng.random())
        if self.normal is not None:
            mean, sd = self.normal
            return min(max(float(rng.normal(mean, sd)), mean - 3.0 * sd), mean + 3.0 * sd)
        lo, hi = self.scale
        return nominal * (lo + (hi - lo) * float(rng.random()))



def spread_support(spread: Spread, nominal: float = 0.0) -> tuple[float, float]:
    """The smallest interval every draw lies in."""
    if spread.value is not None:
        return spread.value, spread.value
    if spread.uniform is not None:
        return spread.uniform
    if spread.normal is not None:
        mean, sd = spread.normal
        return mean - 3.0 * sd, mean + 3.0 * sd
    a, b = nominal * spread.scale[0], nominal * spread.scale[1]
    return min(a, b), max(a, b)


def _check_spread(key: str, spread: Spread) -> None:
    given = [k for k in ("value", "uniform", "normal", "scale") if getattr(spread, k) is not None]
    if len(given) != 1:
        raise ConfigError(f"{key}: give exactly one of value, uniform, normal, scale (got {', '.join(given) or 'none'})")
    for k in ("uniform", "scale"):
        pair = getattr(spread, k)
        if pair is not None and pair[1] < pair[0]:
            raise ConfigError(f"{key}.{k}: [{pair[0]:g}, {pair[1]:g}] has hi < lo")
    if spread.normal is not None and spread.normal[1] < 0.0:
        raise ConfigError(f"{key}.normal: sd {spread.normal[1]:g} is negative")


def _check_support(key: str, spread: Spread, meta, nominal: float = 0.0) -> None:
    """The spread is well formed and every draw lies inside its quantity's allowed range."""
    _check_spread(key, spread)
    lo, hi = spread_support(spread, nominal)
    allowed_lo, allowed_hi = meta.get("lo"), meta.get("hi")
    # a rounding's worth of slack: normal [0.15, 0.05] reaches 0.15 - 3 x 0.05 = -2.8e-17, and a spread a user wrote
    # to end at the bound was refused as "outside [0, 5]" (a new-user audit)
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    if (allowed_lo is not None and lo < allowed_lo - tol) or (allowed_hi is not None and hi > allowed_hi + tol):
        raise ConfigError(f"{key}: the spread reaches [{lo:g}, {hi:g}], outside the allowed range {_range_text(meta)}")


def _meta(owner: type, name: str) -> dict:
    return dict(next(f for f in dataclasses.fields(owner) if f.name == name).metadata)


def _spread_of(owner: type, name: str, *, doc: str = "") -> Any:
    """A condition field whose unit and range are the owner's (one owner per fact)."""
    m = _meta(owner, name)
    return param(None, unit=m["unit"], lo=m["lo"], hi=m["hi"], source=f"{owner.__name__}.{name}",
                 doc=doc or m.get("doc") or m.get("source", ""))


def _spread_of_effect(effect: str, name: str, *, doc: str) -> Any:
    p = next(q for q in EFFECTS[effect].params if q.name == name)
    return param(None, unit=p.unit, lo=p.lo, hi=p.hi, source=f"autopilot.sysid.effects {effect}.{name}", doc=doc)


def _own(*, unit: str, lo: float, hi: float, doc: str) -> Any:
    return param(None, unit=unit, lo=lo, hi=hi, source="autopilot.campaign", doc=doc)


@dataclass(frozen=True)
class FaultSpread:
    """At most one fault per run, at a random time."""

    probability: float = param(1.0, unit="-", lo=0.0, hi=1.0, doc="chance that a run has a fault")
    kinds: tuple[str, ...] = param(FAULT_KINDS, choices=FAULT_KINDS,
                                   doc="the fault is one of these, each as likely: gnss_lost (no fixes), compass_lost "
                                       "(the SC-30 port closes), mbed_lost (the Mbed port closes: its firmware stops "
                                       "the thrusters), nmea_garbage (garbage on the compass line), thruster_failure "
                                       "(one side delivers no thrust; the failsafe cannot see it), battery_low (the "
                                       "resting voltage falls to battery_rest_v and stays there)")
    at_s: Spread = param(default_factory=lambda: Spread(uniform=(5.0, 40.0)), unit="s", lo=0.0, hi=86400.0,
                         doc="mission time the fault starts")
    duration_s: Spread = param(default_factory=lambda: Spread(uniform=(1.0, 10.0)), unit="s", lo=0.0, hi=86400.0,
                               doc="how long it lasts (battery_low: for good)")
    battery_rest_v: Spread = param(default_factory=lambda: Spread(value=11.9), unit="V", lo=0.0, hi=30.0,
                                   doc="battery_low: the resting voltage it falls to (nominal 12.7 V)")

    def __post_init__(self) -> None:
        if not self.kinds:
            raise ConfigError("kinds: give at least one fault kind")


@dataclass(frozen=True)
class Condition:
    """One named condition spread: disturbances, thrusters, sensors and faults (absent = nominal)."""

    current_speed_m_s: Spread | None = _spread_of(Environment, "current_speed_m_s")
    current_towards_deg: Spread | None = _spread_of(Environment, "current_towards_deg")
    wind_speed_m_s: Spread | None = _spread_of(Environment, "wind_speed_m_s")
    wind_from_deg: Spread | None = _spread_of(Environment, "wind_from_deg")
    sinusoidal_amplitude_n: Spread | None = _spread_of(SinusoidalDisturbance, "amplitude_n",
                                                       doc="file 003 Eq 7 A (any sinusoidal_* key turns the force on)")
    sinusoidal_bias_n: Spread | None = _spread_of(SinusoidalDisturbance, "bias_n", doc="file 003 Eq 7 B")
    sinusoidal_omega_rad_s: Spread | None = _spread_of(SinusoidalDisturbance, "omega_rad_s", doc="file 003 Eq 7 w_d")
    sinusoidal_angle_rad: Spread | None = _spread_of(SinusoidalDisturbance, "angle_rad", doc="file 003 k, from north")
    thrust_asymmetry_nd: Spread | None = _spread_of_effect("thrust_asymmetry", "asymmetry_nd",
                                                           doc="port thrust x (1 + a), starboard x (1 - a)")
    thrust_lag_s: Spread | None = _spread_of_effect("thrust_lag", "time_constant_s",
                                                    doc="first-order lag of both thrusts (motor spin-up)")
    weak_motor_loss_nd: Spread | None = _spread_of_effect("weak_motor", "loss_nd",
                                                          doc="one motor short of the thrust table: port x (1 - w) "
                                                          "for w > 0, starboard x (1 + w) for w < 0")
    position_noise_m: Spread | None = _spread_of(SimConfig, "position_noise_m")
    heading_noise_deg: Spread | None = _spread_of(SimConfig, "heading_noise_deg")
    position_dropouts_per_min: Spread | None = _own(unit="1/min", lo=0.0, hi=60.0,
                                                    doc="GNSS dropouts (no fixes) per minute, at random times")
    position_dropout_s: Spread | None = _own(unit="s", lo=0.0, hi=3600.0, doc="length of each GNSS dropout (default 3 s)")
    heading_dropouts_per_min: Spread | None = _own(unit="1/min", lo=0.0, hi=60.0,
                                                   doc="heading dropouts (no HDT/ROT) per minute, at random times")
    heading_dropout_s: Spread | None = _own(unit="s", lo=0.0, hi=3600.0, doc="length of each heading dropout (default 1.5 s)")
    faults: FaultSpread | None = param(None, doc="a fault at a random time")


SPREAD_KEYS = tuple(f.name for f in dataclasses.fields(Condition) if f.name != "faults")
# The spread quantities that are directions, with their unit's full turn: 359 deg and 1 deg are neighbours, so
# what they do to the outcome is measured on the circle, not on the line (results.sensitivity).
DIRECTION_TURN = {"current_towards_deg": 360.0, "wind_from_deg": 360.0, "sinusoidal_angle_rad": 2.0 * math.pi}


@dataclass(frozen=True)
class VesselSpread:
    """The vessel's parameters: a base set, spreads from an identification, spreads per field."""

    file: str = param("", doc="VesselParams YAML (relative to the spec); empty = the calibrated default")
    sysid: str = param("", doc="a sysid summary.json (relative to the spec): each identified parameter uniform over "
                               "its 95 % interval (hydro_refit fields, yaw_damping_quadratic; thrust_asymmetry, "
                               "weak_motor and thrust_lag for the conditions that set none)")
    fields: Any = param(default_factory=dict, doc="VesselParams field -> spread (wins over sysid)")


@dataclass(frozen=True)
class CampaignSpec:
    """A campaign: see the module docstring."""

    name: str = param("campaign", doc="the campaign's name (reports)")
    description: str = param("", doc="what it is for")
    missions: tuple[str, ...] = param((), doc="mission files (relative to the spec) or shipped mission names")
    laws: tuple[str, ...] = param(LAWS, choices=LAWS, doc="guidance laws flown")
    runs: int = param(1000, unit="runs", lo=1, hi=10_000_000, doc="runs (--runs overrides)")
    seed: int = param(0, lo=0, hi=2**63 - 1, doc="campaign seed (--seed overrides); run i draws from (seed, i)")
    chunk_runs: int = param(100, unit="runs", lo=1, hi=100_000,
                            doc="runs flown in lockstep per task; the unit of distribution and retry")
    success_radius_m: float = param(2.5, unit="m", lo=0.0, hi=1000.0,
                                    doc="a run succeeds when it completes, does not circle and passes every "
                                        "waypoint within this")
    vessel: VesselSpread = param(default_factory=VesselSpread, doc="vessel parameters")
    conditions: Any = param(default_factory=lambda: {"nominal": {}}, doc="condition name -> Condition")
    gnc: GncConfig = param(default_factory=GncConfig, doc="the GNC configuration (the law is each run's)")
    failsafe: FailsafeConfig = param(default_factory=FailsafeConfig, doc="the daemon's failsafe configuration")

    def __post_init__(self) -> None:
        if not self.name.strip():  # a blank name made a report titled "Robustness campaign " and nothing else
            raise ConfigError("name: give the campaign a name (it titles the report), or leave the key out")


@dataclass(frozen=True)
class MissionData:
    """A mission as numbers (what a run needs of it)."""

    name: str
    waypoints_ne_m: tuple[tuple[float, float], ...]
    speeds_m_s: tuple
    holds_s: tuple
    rtl: bool = False
    home_ne_m: tuple[float, float] = (0.0, 0.0)  # where the boat starts, at rest heading north (as --sim)


@dataclass(frozen=True)
class Campaign:
    """A checked spec resolved to data: everything a run needs, nothing read from files."""

    spec: CampaignSpec
    missions: tuple[MissionData, ...]
    vessel: VesselParams
    vessel_spreads: tuple[tuple[str, Spread], ...]  # VesselParams field -> spread, sorted by field
    conditions: tuple[tuple[str, Condition], ...]
    sysid_thrust: tuple[tuple[str, Spread], ...] = ()  # thrust_asymmetry_nd / weak_motor_loss_nd / thrust_lag_s from a sysid summary
    sources: tuple[str, ...] = ()  # where the vessel and its spreads came from (for the report)

    @property
    def laws(self) -> tuple[str, ...]:
        return self.spec.laws

    @property
    def cells(self) -> int:
        return len(self.missions) * len(self.laws) * len(self.conditions)

    def to_data(self) -> dict:
        """Plain JSON-able data (floats round-trip exactly)."""
        spec = to_dict(self.spec)
        spec["conditions"] = {name: _condition_data(c) for name, c in self.conditions}
        spec["vessel"] = {"file": self.spec.vessel.file, "sysid": self.spec.vessel.sysid, "fields": {}}
        return {
            "format": "autopilot-campaign-1",
            "spec": spec,
            "missions": [dataclasses.asdict(m) for m in self.missions],
            "vessel": to_dict(self.vessel),
            "vessel_spreads": {k: _spread_data(s) for k, s in self.vessel_spreads},
            "sysid_thrust": {k: _spread_data(s) for k, s in self.sysid_thrust},
            "sources": list(self.sources),
        }

    @classmethod
    def from_data(cls, data: dict) -> Campaign:
        """The campaign of :meth:`to_data` (checked again with the same schema)."""
        if not isinstance(data, dict) or data.get("format") != "autopilot-campaign-1":
            raise ConfigError("campaign.json: not a campaign written by autopilot campaign (format autopilot-campaign-1)")
        spec = _load_spec(data["spec"])
        missions = tuple(MissionData(m["name"], tuple((float(n), float(e)) for n, e in m["waypoints_ne_m"]),
                                     tuple(m["speeds_m_s"]), tuple(m["holds_s"]), bool(m["rtl"]),
                                     tuple(float(x) for x in m.get("home_ne_m", (0.0, 0.0))))
                         for m in data["missions"])
        vessel = load(VesselParams, data["vessel"], where="vessel.")
        spreads = tuple(sorted((k, _vessel_spread(k, v, vessel)) for k, v in data["vessel_spreads"].items()))
        thrust = tuple((k, load(Spread, v)) for k, v in data.get("sysid_thrust", {}).items())
        return cls(spec, missions, vessel, spreads, _conditions(spec.conditions), thrust, tuple(data.get("sources", ())))

    def digest(self) -> str:
        """A short hash of the campaign's data (the same campaign gives the same digest)."""
        text = json.dumps(self.to_data(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _spread_data(s: Spread) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in to_dict(s).items() if v is not None}


def _condition_data(c: Condition) -> dict:
    out = {}
    for f in dataclasses.fields(Condition):
        v = getattr(c, f.name)
        if v is None:
            continue
        if isinstance(v, Spread):
            out[f.name] = _spread_data(v)
        else:  # FaultSpread
            out[f.name] = {"probability": v.probability, "kinds": list(v.kinds), "at_s": _spread_data(v.at_s),
                           "duration_s": _spread_data(v.duration_s), "battery_rest_v": _spread_data(v.battery_rest_v)}
    return out


def _as_spread_mapping(value: Any) -> Any:
    """A bare number is a fixed value."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return {"value": value}
    return value


_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def _condition(name: str, data: Any) -> Condition:
    where = f"conditions.{name}."
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"conditions.{name}: expected a mapping of spreads, got {data!r}")
    data = {k: _as_spread_mapping(v) for k, v in data.items()}
    if isinstance(data.get("faults"), dict):
        data["faults"] = {k: _as_spread_mapping(v) if k in ("at_s", "duration_s", "battery_rest_v") else v
                          for k, v in data["faults"].items()}
    cond = load(Condition, data, where=where)

    def check(key: str, spread: Spread, meta) -> None:
        if spread.scale is not None:  # {scale} multiplied a nominal of 0: 0.3 m of noise became 0 m, unsaid
            raise ConfigError(f"{key}.scale: a condition's quantity has no nominal value to scale; give a value, "
                              "{uniform: [lo, hi]} or {normal: [mean, sd]} (scale is for vessel.fields)")
        _check_support(key, spread, meta)

    for f in dataclasses.fields(Condition):
        v = getattr(cond, f.name)
        if isinstance(v, Spread):
            check(where + f.name, v, f.metadata)
        elif isinstance(v, FaultSpread):
            for g in ("at_s", "duration_s", "battery_rest_v"):
                meta = next(x for x in dataclasses.fields(FaultSpread) if x.name == g).metadata
                check(f"{where}faults.{g}", getattr(v, g), meta)
    return cond


def _conditions(data: Any) -> tuple[tuple[str, Condition], ...]:
    if not isinstance(data, dict) or not data:
        raise ConfigError("conditions: expected a mapping of condition name -> spreads (at least one)")
    out = []
    for name, value in data.items():
        if not isinstance(name, str):  # YAML read `1:` or `on:` as a number or a boolean: "is letters, digits" misled
            raise ConfigError(f"conditions.{name}: YAML reads this name as " + (
                f"{name} (yes, no, on, off, true, false); quote it" if isinstance(name, bool) else
                f"the number {name!r}; quote it (\"{name}\":)") + ", or choose one that starts with a letter")
        if not _NAME.match(name):
            raise ConfigError(f"conditions.{name}: a condition name is letters, digits, '_', '-', '.' (up to 64)")
        if name == "all":
            raise ConfigError("conditions.all: 'all' names the results' column over every condition; choose another name")
        out.append((name, _condition(name, value)))
    return tuple(out)


def _vessel_spread(field: str, value: Any, vessel: VesselParams, *, where: str = "vessel.fields.") -> Spread:
    if field not in VESSEL_FIELDS:
        raise ConfigError(f"{where}{field}: unknown VesselParams field (allowed: {', '.join(VESSEL_FIELDS)})")
    spread = load(Spread, _as_spread_mapping(value), where=f"{where}{field}.")
    _check_support(f"{where}{field}", spread, _meta(VesselParams, field), getattr(vessel, field))
    return spread


def _load_spec(data: Any) -> CampaignSpec:
    if isinstance(data, dict) and isinstance(data.get("vessel"), dict):
        fields = data["vessel"].get("fields")
        if fields is not None and not isinstance(fields, dict):
            raise ConfigError(f"vessel.fields: expected a mapping of VesselParams field -> spread, got {fields!r}")
    spec = load(CampaignSpec, data)
    if not spec.missions:
        raise ConfigError("missions: name at least one mission (a file, or a shipped name such as pond-9.1)")
    if not spec.laws:
        raise ConfigError(f"laws: name at least one guidance law ({', '.join(LAWS)})")
    for i, law in enumerate(spec.laws):  # a law twice printed two rows of half the runs each
        if law in spec.laws[:i]:
            raise ConfigError(f"laws[{i}]: {law} is given twice")
    _conditions(spec.conditions)  # checked here, so a bad condition fails at load
    return spec


def load_spec(path: str | Path) -> CampaignSpec:
    """Read and check a spec file (ConfigError naming the file and the key otherwise)."""
    import yaml

    from autopilot.userfile import parse_yaml, read_text, yaml_problem

    path = Path(path)
    text = read_text(path, what="campaign spec")
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({yaml_problem(exc)})") from exc
    if data is None:  # it said "missions: name at least one mission", as if a key were missing
        raise ConfigError(f"{path}: the file is empty (or comments only): a campaign spec names its missions, "
                          "laws and conditions (see the shipped one: autopilot files)")
    try:
        return _load_spec(data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from exc


def _mission(entry: str, base_dir: Path, i: int) -> MissionData:
    from autopilot.mission import load_mission
    from autopilot.resources import find_mission

    try:
        path, _ = find_mission(entry, base_dir)
    except ConfigError as exc:
        # where it was looked for: a path given relative to the working directory was refused without it (an audit)
        raise ConfigError(f"missions[{i}]: {exc} (a file relative to the spec's directory, "
                          f"{base_dir.resolve()}, or a shipped name)") from None
    m = load_mission(path)
    return MissionData(m.name, tuple((float(n), float(e)) for n, e in m.waypoints_ne_m),
                       tuple(None if s is None else float(s) for s in m.speeds_m_s),
                       tuple(None if h is None else float(h) for h in m.holds_s), bool(m.rtl), m.home_ne_m)


def _sysid_base(summary: dict, path: Path, base_dir: Path) -> tuple[VesselParams | None, str]:
    """The vessel the identification started from (summary.json's ``params_file``: as given, or relative to the
    summary or to the campaign spec) and its name; None when the summary names none or it is not here."""
    from autopilot.sim import load_params

    name = summary.get("params_file")
    if not isinstance(name, str) or not name:
        return None, ""
    given = Path(name)
    for p in ([given] if given.is_absolute() else [given, path.parent / given, base_dir / given]):
        if p.is_file():
            try:
                return load_params(p), name
            except ConfigError as exc:
                raise ConfigError(f"vessel.sysid ({path}): params_file: {exc}") from None
    return None, name


def _sysid_spreads(path: Path, vessel: VesselParams, base_dir: Path = Path(".")) -> tuple[dict, dict, list[str]]:
    """(VesselParams field -> Spread, thrust key -> Spread, notes) from a sysid summary.json's 95 % intervals.

    hydro_refit reports the fields' new values; yaw_damping_quadratic a change from the vessel the identification
    started from (``params_file``), so it is added to that vessel's: added to the campaign's, a campaign of
    sysid's own vessel-updated.yaml (where it is written in already) flew it twice (40 N m s^2 identified, 70 drawn;
    a new-user audit). A campaign vessel that differs from that one in a field the summary does not spread is
    another boat, refused."""
    from autopilot.userfile import read_text

    where = f"vessel.sysid ({path})"
    try:
        summary = json.loads(read_text(path, what="sysid summary.json"))
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{where}: not JSON ({exc})") from None
    except ConfigError as exc:  # it named the file alone, not the key that gave it
        raise ConfigError(f"vessel.sysid: {exc}") from None
    effects = summary.get("effects") if isinstance(summary, dict) else None
    if not isinstance(effects, dict):
        raise ConfigError(f"{where}: no 'effects' mapping (a summary.json written by autopilot sysid)")
    base, base_name = _sysid_base(summary, path, base_dir)
    fields, thrust, notes = {}, {}, []

    def interval(effect: str, p: dict) -> tuple[float, float]:
        ci = p.get("ci95")
        if not (isinstance(ci, list) and len(ci) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                               and math.isfinite(x) for x in ci)):
            raise ConfigError(f"{where}: {effect}.{p.get('name')}: ci95 is not a finite [lo, hi]")
        return float(min(ci)), float(max(ci))

    for effect, body in effects.items():
        params = body.get("params") if isinstance(body, dict) else None
        if not isinstance(params, list):  # null or 5 was an internal error; a renamed key spread nothing, unsaid
            raise ConfigError(f"{where}: effects.{effect}.params is not a list of parameters (a summary.json "
                              "written by autopilot sysid)")
        for p in params:
            name = p.get("name") if isinstance(p, dict) else None
            if effect == "hydro_refit" and name in VESSEL_FIELDS:
                lo, hi = interval(effect, p)
                fields[name] = (Spread(uniform=(lo, hi)), f"{where}: hydro_refit.{name}")
            elif effect == "yaw_damping_quadratic" and name == "n_rr_nm_s2":
                lo, hi = interval(effect, p)
                if base is None and base_name:  # a change from a vessel not here: added to the campaign's, it was
                    # counted twice for sysid's own vessel-updated.yaml (a review of 2026-12-06)
                    raise ConfigError(f"{where}: params_file {base_name}, the vessel the yaw damping's change was "
                                      "identified from, is not found (as given, beside the summary or the spec): "
                                      "copy it beside the summary")
                n_rr = (base or vessel).yaw_damping_quadratic_nm_s2
                fields["yaw_damping_quadratic_nm_s2"] = (Spread(uniform=(n_rr + lo, n_rr + hi)),
                                                         f"{where}: yaw_damping_quadratic.n_rr_nm_s2 (added to "
                                                         f"{base_name if base else 'the campaign vessel'}'s)")
            elif effect == "thrust_asymmetry" and name == "asymmetry_nd":
                thrust["thrust_asymmetry_nd"] = Spread(uniform=interval(effect, p))
            elif effect == "thrust_lag" and name == "time_constant_s":
                lo, hi = interval(effect, p)
                thrust["thrust_lag_s"] = Spread(uniform=(max(lo, 0.0), max(hi, 0.0)))
            elif effect == "weak_motor":
                if name == "loss_nd":  # its other row, the weak side's gain, is this one's (sysid's derived row)
                    thrust["weak_motor_loss_nd"] = Spread(uniform=interval(effect, p))
            else:
                notes.append(f"{effect}.{name}: not spread (the campaign's plant has no such term)")
    if not fields and not thrust:
        # {"effects": {}} (a verdict of none) flew the nominal vessel with only a line in summary.json's sources
        raise ConfigError(f"{where}: no identified parameter to spread (verdict none, or no effect the campaign's "
                          "plant has: " + (", ".join(n.split(":")[0] for n in notes) or "no effects") + "); leave "
                          "vessel.sysid empty to fly the vessel as it is")
    other = [f for f in VESSEL_FIELDS if base is not None and f not in fields and getattr(base, f) != getattr(vessel, f)]
    if other:
        raise ConfigError(f"{where}: identified on another vessel, {base_name} (params_file): it differs from the "
                          f"campaign's in {', '.join(other[:4])}{', ...' if len(other) > 4 else ''}; set vessel.file "
                          "to it (or to the vessel-updated.yaml sysid wrote beside the summary), or identify this one")
    out = {}
    for name, (spread, key) in fields.items():
        _check_support(key, spread, _meta(VesselParams, name))
        out[name] = spread
    for key, spread in thrust.items():
        _check_support(f"{where}: {key}", spread, next(f for f in dataclasses.fields(Condition) if f.name == key).metadata)
    return out, thrust, notes


def _within_limits(spec: CampaignSpec, missions: tuple[MissionData, ...]) -> None:
    """Every mission inside the spec's failsafe limits, as the daemon checks it at start: a mission it would refuse
    was flown, and every run counted as the max_distance failsafe's (a new-user audit). A campaign has no geofence;
    failsafe.allow_beyond_limits flies such missions on purpose (a campaign of that failsafe)."""
    from autopilot.daemon.failsafe import mission_beyond_limits

    if spec.failsafe.allow_beyond_limits:
        return
    for i, m in enumerate(missions):
        why = mission_beyond_limits(m.home_ne_m, m.waypoints_ne_m, m.rtl, spec.failsafe, None, "the start")
        if why is not None:
            raise ConfigError(f"missions[{i}]: {spec.missions[i]}: {why} (the daemon refuses such a mission at start; "
                              "failsafe.allow_beyond_limits: true flies it, a campaign of that failsafe)")


def resolve(spec: CampaignSpec, *, base_dir: str | Path = ".") -> Campaign:
    """A checked spec -> the campaign's data (missions read, vessel and sysid spreads resolved)."""
    from autopilot.sim import default_params_path, load_params

    base_dir = Path(base_dir)
    missions = tuple(_mission(m, base_dir, i) for i, m in enumerate(spec.missions))
    for i, m in enumerate(missions):  # two files of one mission name were merged into one row of results
        first = next(j for j, o in enumerate(missions) if o.name == m.name)
        if first != i:
            raise ConfigError(f"missions[{i}]: {spec.missions[i]} is named {m.name}, as missions[{first}] "
                              f"({spec.missions[first]}): the results are kept by mission name")
    _within_limits(spec, missions)
    vessel_path = (base_dir / spec.vessel.file) if spec.vessel.file else default_params_path()
    try:
        vessel = load_params(vessel_path)
    except ConfigError as exc:  # it named the file alone, not the key that gave it
        raise ConfigError(f"vessel.file: {exc}" if spec.vessel.file else str(exc)) from None
    sources = [f"vessel: {vessel_path}"]
    spreads: dict[str, Spread] = {}
    thrust: dict[str, Spread] = {}
    if spec.vessel.sysid:
        sysid_path = base_dir / spec.vessel.sysid
        spreads, thrust, notes = _sysid_spreads(sysid_path, vessel, base_dir)
        sources.append(f"sysid intervals: {sysid_path} ({', '.join(sorted(spreads) + sorted(thrust)) or 'none'})")
        sources += notes
    for name, value in (spec.vessel.fields or {}).items():
        spreads[name] = _vessel_spread(str(name), value, vessel)
    campaign = Campaign(spec, missions, vessel, tuple(sorted(spreads.items())), _conditions(spec.conditions),
                        tuple(sorted(thrust.items())), tuple(sources))
    return Campaign.from_data(campaign.to_data())  # what a worker and --replay get: the JSON round trip
