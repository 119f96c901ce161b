"""Candidate effects: physically named extensions of the model, few parameters each.

Every effect is applied outside the simulator's equations, on its inputs
(thrust series), through its ``external_force`` hook, or on its outputs
(what the sensors report), so the simulator itself stays as the lead wrote it:

    identifier              parameters                        where it acts
    current                 north_m_s, east_m_s               uniform steady current (exact: the
                                                              model is written in water-relative
                                                              velocity, so the ground track is the
                                                              calm-water track plus current * t)
    wind_force              north_n, east_n, moment_nm        steady earth-frame force + yaw moment
    thrust_asymmetry        asymmetry_nd (a)                  T_P (1 + a), T_S (1 - a)
    thrust_lag              time_constant_s                   first-order lag of both thrusts
    thrust_deadband         threshold_pct                     no thrust below |duty| = threshold
                                                              (edge softened over +-1 % duty)
    heading_bias            bias_deg                          compass reads psi + bias
    antenna_offset          forward_m, starboard_m            GPS antenna at this body lever arm
    sensor_delay            delay_s                           position and heading reported late
    yaw_damping_quadratic   n_rr_nm_s2                        extra yaw moment -N_rr |r| r
    hydro_refit             resistance_linear_n_s_m, n_r_nd   re-fit of VesselParams fields
                                                              (deltas applied as body forces)

``current`` is reported also as speed and direction (towards), with
intervals by the delta method.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect: name, unit, the no-effect value, bounds, typical size."""

    name: str
    unit: str
    null: float
    lo: float
    hi: float
    scale: float
    fd_step: float = 1e-3  # finite-difference step in units of ``scale``
    init: float | None = None  # starting value when the null value has no gradient
    grid: tuple[float, ...] | None = None  # screening starts when the cost is far from quadratic
    # the cost is flat between steps (a threshold between the duties a trial holds): a fit stuck
    # above the noise is profiled over ``grid`` (identify._profile)
    stepwise: bool = False

    def __post_init__(self):
        if self.stepwise and not self.grid:
            raise ValueError(f"{self.name}: a stepwise parameter needs a grid to profile over")

    @property
    def start(self) -> float:
        return self.null if self.init is None else self.init


@dataclass(frozen=True)
class Effect:
    """A candidate effect and its parameters (SI; degrees only where the name says so)."""

    name: str
    params: tuple[EffectParam, ...]
    doc: str
    kind: str  # "input", "force", "environment", "sensor", "hydro"
    steady: bool = False  # observable in a steady-state table

    def key(self, param: EffectParam) -> str:
        return f"{self.name}.{param.name}"

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(self.key(p) for p in self.params)


INF = float("inf")

EFFECTS: tuple[Effect, ...] = (
    Effect(
        "current",
        (
            EffectParam("north_m_s", "m/s", 0.0, -2.0, 2.0, 0.1),
            EffectParam("east_m_s", "m/s", 0.0, -2.0, 2.0, 0.1),
        ),
        "uniform steady water current (velocity towards north/east)",
        "environment",
    ),
    Effect(
        "wind_force",
        (
            EffectParam("north_n", "N", 0.0, -200.0, 200.0, 5.0),
            EffectParam("east_n", "N", 0.0, -200.0, 200.0, 5.0),
            EffectParam("moment_nm", "N m", 0.0, -200.0, 200.0, 2.0),
        ),
        "steady force in the earth frame and a steady yaw moment (wind on the superstructure)",
        "force",
    ),
    Effect(
        "thrust_asymmetry",
        (EffectParam("asymmetry_nd", "-", 0.0, -0.6, 0.6, 0.05, grid=(-0.08, -0.04, 0.0, 0.04, 0.08)),),
        "one side pushes more: port thrust x (1 + a), starboard x (1 - a)",
        "input",
        steady=True,
    ),
    Effect(
        "thrust_lag",
        (EffectParam("time_constant_s", "s", 0.0, 0.0, 10.0, 0.5, grid=(0.0, 0.5, 1.0, 2.0)),),
        "motor spin-up: thrust follows the command with a first-order lag",
        "input",
    ),
    Effect(
        "thrust_deadband",
        (EffectParam("threshold_pct", "%", 0.0, 0.0, 60.0, 10.0, fd_step=0.03, init=5.0,
                     grid=(5.0, 12.0, 19.0, 26.0, 33.0, 40.0), stepwise=True),),
        "no thrust below a duty threshold (the motor does not start)",
        "input",
        steady=True,
    ),
    Effect(
        "heading_bias",
        (EffectParam("bias_deg", "deg", 0.0, -30.0, 30.0, 1.0),),
        "compass mounted off the centre line: it reads psi + bias",
        "sensor",
    ),
    Effect(
        "antenna_offset",
        (
            EffectParam("forward_m", "m", 0.0, -5.0, 5.0, 0.5),
            EffectParam("starboard_m", "m", 0.0, -5.0, 5.0, 0.5),
        ),
        "GPS antenna away from the centre of gravity (body lever arm)",
        "sensor",
    ),
    Effect(
        "sensor_delay",
        (EffectParam("delay_s", "s", 0.0, 0.0, 5.0, 0.3, grid=(0.0, 0.5, 1.0, 1.5)),),
        "position and heading reported late by a fixed delay",
        "sensor",
    ),
    Effect(
        "yaw_damping_quadratic",
        (EffectParam("n_rr_nm_s2", "N m s^2", 0.0, -1e5, 1e5, 20.0, grid=(0.0, 15.0, 40.0)),),
        "unmodelled quadratic yaw damping: extra moment -N_rr |r| r",
        "force",
        steady=True,
    ),
    Effect(
        "hydro_refit",
        (
            EffectParam("resistance_linear_n_s_m", "N s/m", 0.0, -1e3, 1e3, 1.0),
            EffectParam("n_r_nd", "-", 0.0, -50.0, 50.0, 0.02),
        ),
        "re-fit of existing hydrodynamic coefficients (linear resistance r1, MMG N'_r); "
        "parameters are the new values, fitted as changes from the base set",
        "hydro",
        steady=True,
    ),
)

BY_NAME: dict[str, Effect] = {e.name: e for e in EFFECTS}
EFFECT_NAMES: tuple[str, ...] = tuple(BY_NAME)
ALL_KEYS: tuple[str, ...] = tuple(k for e in EFFECTS for k in e.keys)
PARAM_BY_KEY: dict[str, EffectParam] = {e.key(p): p for e in EFFECTS for p in e.params}


def null_values() -> dict[str, float]:
    """Every effect parameter at its no-effect value."""
    return {k: p.null for k, p in PARAM_BY_KEY.items()}
