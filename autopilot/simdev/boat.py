"""The simulated boat behind the simulated devices: model state advanced on a Clock."""

from __future__ import annotations

import math

import numpy as np

from autopilot.geo import local_to_latlon
from autopilot.gnc.thrust_curve import ThrustCurve
from autopilot.sim import Environment, step

__all__ = ["SimBoat"]


class SimBoat:
    """Holds ``(north_m, east_m, psi_rad, u_m_s, v_m_s, r_rad_s)`` and the thrusts acting on it.

    :meth:`advance_to` integrates :func:`autopilot.sim.step` (RK4) at a fixed
    ``dt_s`` with the thrust held since the last change (zero-order hold, as
    the H-bridge holds its PWM), so devices that call it at different rates
    see one consistent trajectory.
    """

    def __init__(
        self,
        params,
        *,
        env: Environment | None = None,
        x0=None,
        thrust_curve: ThrustCurve | None = None,
        origin_lat_deg: float,
        origin_lon_deg: float,
        dt_s: float = 0.05,
        t0_s: float = 0.0,
        thrust_gain_port: float = 1.0,
        thrust_gain_stbd: float = 1.0,
    ) -> None:
        self.params = params
        self.env = env if env is not None else Environment()
        self.thrust_curve = thrust_curve if thrust_curve is not None else ThrustCurve()
        self.origin_lat_deg = float(origin_lat_deg)
        self.origin_lon_deg = float(origin_lon_deg)
        self.dt_s = float(dt_s)
        self.state = np.zeros(6) if x0 is None else np.array(x0, dtype=float).reshape(6)
        self.t_s = float(t0_s)
        # a motor that makes a fraction of the table's thrust (a fouled propeller, a tired ESC): the bench's weak motor
        self.thrust_gain_port = float(thrust_gain_port)
        self.thrust_gain_stbd = float(thrust_gain_stbd)
        self.thrust_port_n = 0.0
        self.thrust_stbd_n = 0.0

    def set_thrust(self, thrust_port_n: float, thrust_stbd_n: float) -> None:
        self.thrust_port_n = float(thrust_port_n)
        self.thrust_stbd_n = float(thrust_stbd_n)

    def set_duty(self, duty_port_pct: float, reverse_port: bool, duty_stbd_pct: float, reverse_stbd: bool) -> None:
        """Thrusts from duties through the thrust curve (SPEC section 4, Table 4.2), times each motor's gain."""
        self.set_thrust(
            self.thrust_gain_port * self.thrust_curve.thrust_n(duty_port_pct, reverse_port),
            self.thrust_gain_stbd * self.thrust_curve.thrust_n(duty_stbd_pct, reverse_stbd),
        )

    def advance_to(self, t_s: float) -> None:
        """Integrate up to ``t_s`` (no-op if already there)."""
        while self.t_s < t_s - 1e-9:
            dt = min(self.dt_s, t_s - self.t_s)
            self.state = step(
                self.params, self.state, self.thrust_port_n, self.thrust_stbd_n, dt, t_s=self.t_s, env=self.env
            )
            self.t_s += dt

    # ------------------------------------------------------------------ what sensors see (SI)
    @property
    def psi_rad(self) -> float:
        """Heading [0, 2 pi)."""
        return float(self.state[2]) % (2.0 * math.pi)

    @property
    def r_rad_s(self) -> float:
        return float(self.state[5])

    @property
    def sog_m_s(self) -> float:
        return float(math.hypot(self.state[3], self.state[4]))

    @property
    def cog_rad(self) -> float:
        """Course over ground [0, 2 pi)."""
        return float(self.state[2] + math.atan2(self.state[4], self.state[3])) % (2.0 * math.pi)

    @property
    def heading_deg(self) -> float:
        return math.degrees(self.psi_rad)

    def latlon_deg(self, north_noise_m: float = 0.0, east_noise_m: float = 0.0) -> tuple[float, float]:
        lat, lon = local_to_latlon(
            self.state[0] + north_noise_m, self.state[1] + east_noise_m, self.origin_lat_deg, self.origin_lon_deg
        )
        return float(lat), float(lon)
