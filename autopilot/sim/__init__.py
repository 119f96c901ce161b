"""The WAM-V simulator: MMG model, environment, RK4 integration (public API).

- :func:`load_params` (path) -> :class:`VesselParams`
- :func:`simulate` (params, t_s, thrust_port_n, thrust_stbd_n, *, x0, current, wind,
  external_force, dt_s) -> mapping of arrays
- :func:`step` one RK4 step, for closed-loop simulation
- :class:`Environment`, :class:`SinusoidalDisturbance`
"""

from autopilot.sim.environment import CALM, Environment, SinusoidalDisturbance
from autopilot.sim.integrate import STATE_NAMES, simulate, step
from autopilot.sim.params import (
    VesselParams,
    default_params_path,
    load_params,
    thesis_params_path,
)

__all__ = [
    "CALM",
    "Environment",
    "STATE_NAMES",
    "SinusoidalDisturbance",
    "VesselParams",
    "default_params_path",
    "load_params",
    "simulate",
    "step",
    "thesis_params_path",
]
