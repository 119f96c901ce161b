"""One run of a campaign, drawn from ``(seed, index)`` alone: :func:`draw_run`.

Run ``index`` flies cell ``index mod cells`` of missions x laws x conditions (the mission
changes fastest), so every block of ``cells`` consecutive runs covers each cell once and a
law's success rate is not skewed by which missions it happened to draw. Its random numbers
come from ``numpy.random.SeedSequence([seed, index])``: two child streams, one for the
spreads and the faults (drawn in a fixed order: vessel fields by name, the condition's
quantities in declaration order, dropouts, the fault) and one for the sensor noise, so a
run is the same whatever else the campaign holds, whichever worker flies it and whenever.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from autopilot.campaign.spec import SPREAD_KEYS, Campaign, Condition, MissionData, Spread
from autopilot.sim import Environment, SinusoidalDisturbance, VesselParams

__all__ = ["Fault", "RunSetup", "draw_run", "cell_of", "run_time_limit_s", "DEFAULT_DROPOUT_S"]

DEFAULT_DROPOUT_S = {"position_dropout_s": 3.0, "heading_dropout_s": 1.5}


@dataclass(frozen=True)
class Fault:
    """A fault of one run: ``kind`` (spec.FAULT_KINDS) from ``at_s`` for ``duration_s`` (mission time)."""

    kind: str
    at_s: float
    duration_s: float
    side: str = ""  # thruster_failure: "port" or "stbd"
    battery_rest_v: float = math.nan  # battery_low: the resting voltage it falls to

    @property
    def end_s(self) -> float:
        return math.inf if self.kind == "battery_low" else self.at_s + self.duration_s

    def describe(self) -> str:
        side = f" {self.side}" if self.side else ""
        if self.kind == "battery_low":
            return f"battery_low@{self.at_s:.1f}s to {self.battery_rest_v:.2f} V"
        return f"{self.kind}{side}@{self.at_s:.1f}s+{self.duration_s:.1f}s"


@dataclass(frozen=True)
class RunSetup:
    """Everything one run flies with."""

    index: int
    mission: MissionData
    law: str
    condition: str
    params: VesselParams
    env: Environment
    thrust_asymmetry_nd: float
    thrust_lag_s: float
    weak_motor_loss_nd: float
    position_noise_m: float
    heading_noise_deg: float
    position_dropouts: tuple[tuple[float, float], ...]  # (start_s, end_s): no fixes
    heading_dropouts: tuple[tuple[float, float], ...]  # no heading, no rate of turn
    faults: tuple[Fault, ...]
    t_max_s: float
    sensor_seed: tuple[int, ...]  # entropy of the sensor noise's generator
    drawn: tuple[tuple[str, float], ...]  # (column, value): every quantity a spread drew (the table's inputs)


def cell_of(campaign: Campaign, index: int) -> tuple[int, int, int]:
    """(mission, law, condition) indices of run ``index``."""
    m, n_laws = len(campaign.missions), len(campaign.laws)
    return index % m, (index // m) % n_laws, (index // (m * n_laws)) % len(campaign.conditions)


def run_time_limit_s(campaign: Campaign, mission: MissionData) -> float:
    """evaluate's generous limit (three times the route at the wanted speed, plus two minutes, plus the holds)."""
    from autopilot.evaluate import time_limit_s

    return time_limit_s(mission.waypoints_ne_m, campaign.spec.gnc.guidance.default_speed_m_s, mission.holds_s,
                        start_ne_m=mission.home_ne_m)


def _dropouts(rng, rate_per_min: float, length_s: float, t_max_s: float) -> tuple[tuple[float, float], ...]:
    """Poisson-many dropouts over the run, at uniform times."""
    if rate_per_min <= 0.0 or length_s <= 0.0:
        return ()
    n = int(rng.poisson(rate_per_min * t_max_s / 60.0))
    starts = sorted(float(s) for s in rng.random(n) * t_max_s)
    return tuple((s, s + length_s) for s in starts)


def draw_run(campaign: Campaign, seed: int, index: int) -> RunSetup:
    """Run ``index`` of the campaign with seed ``seed`` (pure: the same arguments give the same run)."""
    mi, li, ci = cell_of(campaign, index)
    mission, law = campaign.missions[mi], campaign.laws[li]
    cond_name, cond = campaign.conditions[ci]
    spreads_ss, sensor_ss = np.random.SeedSequence([int(seed), int(index)]).spawn(2)
    rng = np.random.default_rng(spreads_ss)
    drawn: list[tuple[str, float]] = []

    changes = {}
    for name, spread in campaign.vessel_spreads:  # sorted by field name
        changes[name] = spread.draw(rng, getattr(campaign.vessel, name))
        drawn.append((f"vessel.{name}", changes[name]))
    params = dataclasses.replace(campaign.vessel, **changes) if changes else campaign.vessel

    values: dict[str, float] = {}
    own_thrust = dict(campaign.sysid_thrust)
    for key in SPREAD_KEYS:
        spread: Spread | None = getattr(cond, key)
        if spread is None and key in own_thrust:
            spread = own_thrust[key]  # the identification's interval where the condition sets none
        if spread is None:
            continue
        nominal = _nominal(key)
        values[key] = spread.draw(rng, nominal)
        drawn.append((key, values[key]))
    env = _environment(values)
    t_max_s = run_time_limit_s(campaign, mission)
    position_dropouts = _dropouts(rng, values.get("position_dropouts_per_min", 0.0),
                                  values.get("position_dropout_s", DEFAULT_DROPOUT_S["position_dropout_s"]), t_max_s)
    heading_dropouts = _dropouts(rng, values.get("heading_dropouts_per_min", 0.0),
                                 values.get("heading_dropout_s", DEFAULT_DROPOUT_S["heading_dropout_s"]), t_max_s)
    faults = _faults(rng, cond)
    return RunSetup(
        index=int(index), mission=mission, law=law, condition=cond_name, params=params, env=env,
        thrust_asymmetry_nd=values.get("thrust_asymmetry_nd", 0.0), thrust_lag_s=values.get("thrust_lag_s", 0.0),
        weak_motor_loss_nd=values.get("weak_motor_loss_nd", 0.0),
        position_noise_m=values.get("position_noise_m", 0.0), heading_noise_deg=values.get("heading_noise_deg", 0.0),
        position_dropouts=position_dropouts, heading_dropouts=heading_dropouts, faults=faults, t_max_s=t_max_s,
        sensor_seed=tuple(int(x) for x in sensor_ss.generate_state(4)), drawn=tuple(drawn),
    )


def _nominal(key: str) -> float:
    """The value a ``scale`` spread multiplies: the owner's default (0 for what is off by default)."""
    defaults = {f"sinusoidal_{f.name}": f.default for f in dataclasses.fields(SinusoidalDisturbance)}
    defaults.update({f.name: f.default for f in dataclasses.fields(Environment) if isinstance(f.default, float)})
    defaults.update(DEFAULT_DROPOUT_S)
    return float(defaults.get(key, 0.0))


def _environment(values: dict[str, float]) -> Environment:
    sinus = None
    if any(k.startswith("sinusoidal_") for k in values):
        base = SinusoidalDisturbance()
        sinus = SinusoidalDisturbance(**{f.name: values.get(f"sinusoidal_{f.name}", getattr(base, f.name))
                                         for f in dataclasses.fields(SinusoidalDisturbance)})
    return Environment(
        current_speed_m_s=values.get("current_speed_m_s", 0.0),
        current_towards_deg=values.get("current_towards_deg", 0.0),
        wind_speed_m_s=values.get("wind_speed_m_s", 0.0),
        wind_from_deg=values.get("wind_from_deg", 0.0),
        sinusoidal=sinus,
    )


def _faults(rng, cond: Condition) -> tuple[Fault, ...]:
    fs = cond.faults
    if fs is None:
        return ()
    if fs.probability < 1.0 and float(rng.random()) >= fs.probability:
        return ()
    kind = fs.kinds[int(rng.integers(len(fs.kinds)))] if len(fs.kinds) > 1 else fs.kinds[0]
    at_s = fs.at_s.draw(rng)
    duration_s = fs.duration_s.draw(rng)
    side = ("port", "stbd")[int(rng.integers(2))] if kind == "thruster_failure" else ""
    rest_v = fs.battery_rest_v.draw(rng) if kind == "battery_low" else math.nan
    return (Fault(kind, at_s, duration_s, side, rest_v),)
