"""The boat's environment: water current, steady wind, sinusoidal disturbance force.

- Current: uniform and steady, ``current_speed_m_s`` flowing *towards*
  ``current_towards_deg`` (oceanographic convention). Hydrodynamic forces act
  on the velocity relative to the water (SPEC 3).
- Wind: steady, ``wind_speed_m_s`` blowing *from* ``wind_from_deg``
  (meteorological convention). Simple area-and-coefficient model on the air
  velocity relative to the boat in body axes, (a_x, a_y)::

      X_w = 1/2 rho_a C_X A_F a_x |a_x|
      Y_w = 1/2 rho_a C_Y A_L a_y |a_y|
      N_w = -rho_a C_N A_L L a_x a_y      (= -1/2 rho_a C_N A_L L |a|^2 sin 2 gamma)

  so the drag pushes the boat along the relative air flow in each axis and,
  with C_N > 0, a wind on the bow turns the bow downwind.
- Sinusoidal disturbance (file 003 Eq 7): F_d = A sin(w_d t) + B acting at the
  centre of mass at a fixed angle k from north (earth frame), no moment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.schema import param


@dataclass(frozen=True)
class SinusoidalDisturbance:
    """F_d = A sin(w_d t) + B at earth angle k (file 003 Eq 7; defaults as printed there)."""

    amplitude_n: float = param(10.0, unit="N", lo=0.0, hi=1000.0, source="file 003 Eq 7, A")
    bias_n: float = param(10.0, unit="N", lo=-1000.0, hi=1000.0, source="file 003 Eq 7, B")
    omega_rad_s: float = param(0.628, unit="rad/s", lo=0.0, hi=100.0, source="file 003 Eq 7, w_d")
    angle_rad: float = param(math.pi / 4, unit="rad", lo=-math.pi, hi=math.pi, source="file 003, k (from north)")


@dataclass(frozen=True)
class Environment:
    """Steady current, steady wind and an optional sinusoidal disturbance."""

    current_speed_m_s: float = param(0.0, unit="m/s", lo=0.0, hi=5.0, doc="current speed")
    current_towards_deg: float = param(0.0, unit="deg", lo=-360.0, hi=360.0, doc="direction the current flows towards")
    wind_speed_m_s: float = param(0.0, unit="m/s", lo=0.0, hi=40.0, doc="true wind speed")
    wind_from_deg: float = param(0.0, unit="deg", lo=-360.0, hi=360.0, doc="direction the wind blows from")
    sinusoidal: SinusoidalDisturbance | None = param(None, doc="file 003 Eq 7 force, or none")

    @property
    def current_ne_m_s(self) -> tuple[float, float]:
        """Current velocity (north, east) in m/s."""
        b = math.radians(self.current_towards_deg)
        return self.current_speed_m_s * math.cos(b), self.current_speed_m_s * math.sin(b)

    @property
    def wind_ne_m_s(self) -> tuple[float, float]:
        """Air velocity (north, east) in m/s: it flows away from ``wind_from_deg``."""
        b = math.radians(self.wind_from_deg)
        return -self.wind_speed_m_s * math.cos(b), -self.wind_speed_m_s * math.sin(b)

    @property
    def calm(self) -> bool:
        return self.current_speed_m_s == 0 and self.wind_speed_m_s == 0 and self.sinusoidal is None


CALM = Environment()
