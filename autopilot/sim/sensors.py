"""What the SC-30 reports of the simulated boat, as the daemon's :class:`~autopilot.devices.NavSample`.

For closed-loop runs on simulated time without serial lines (``autopilot evaluate``, the
campaigns): each quantity is measured at its own rate (docs/sc30.md: at 4800 baud the
heading at 10 Hz, rate of turn, position, speed and course at 1 Hz), held between
measurements and stamped with the time it was taken, so the navigation assembly
(:func:`autopilot.gnc.navigation.assemble`) sees what it sees on the boat: a fix up to a
second old, dead reckoning between fixes, the heading differenced between ROT sentences.
Noise-free unless asked (heading noise quantised to the SC-30's 0.1 deg). Pure: the
truth and the time in, a sample out; the random generator is the caller's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autopilot.devices import NavSample, Stamped
from autopilot.geo import local_to_latlon

__all__ = ["SensorRates", "SensorModel"]


@dataclass(frozen=True)
class SensorRates:
    """Measurement periods (s), as the simulated SC-30 sends them at 4800 baud (docs/sc30.md)."""

    heading_period_s: float = 0.1
    rot_period_s: float = 1.0
    fix_period_s: float = 1.0


class SensorModel:
    """The measurements of one run; call :meth:`observe` with the true state at each control cycle."""

    def __init__(self, origin_lat_deg: float, origin_lon_deg: float, *, rates: SensorRates = SensorRates(),
                 position_noise_m: float = 0.0, heading_noise_deg: float = 0.0,
                 rng: np.random.Generator | None = None) -> None:
        self.origin = (float(origin_lat_deg), float(origin_lon_deg))
        self.rates = rates
        self.position_noise_m = float(position_noise_m)
        self.heading_noise_deg = float(heading_noise_deg)
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self._due = {"heading": 0.0, "rot": 0.0, "fix": 0.0}
        self._latest: dict[str, Stamped] = {}

    def _is_due(self, what: str, t_s: float, period_s: float) -> bool:
        if t_s + 1e-9 < self._due[what]:
            return False
        due = self._due[what] + period_s
        while due <= t_s + 1e-9:  # a caller that skipped samples: the next one falls after now
            due += period_s
        self._due[what] = due
        return True

    def observe(self, t_s: float, state) -> NavSample:
        """The sample at ``t_s`` of a boat in ``state`` = (north_m, east_m, psi_rad, u_m_s, v_m_s, r_rad_s)."""
        n, e, psi, u, v, r = (float(x) for x in state)
        lt = self._latest
        if self._is_due("heading", t_s, self.rates.heading_period_s):
            h = psi
            if self.heading_noise_deg:
                h += math.radians(self.rng.normal(0.0, self.heading_noise_deg))
            h = math.radians(round(math.degrees(h) % 360.0, 1) % 360.0)  # the 0.1 deg a sentence carries
            lt["heading_rad"] = Stamped(h, t_s, "HDT", True)
        if self._is_due("rot", t_s, self.rates.rot_period_s):
            lt["yaw_rate_rad_s"] = Stamped(r, t_s, "ROT", True)
        if self._is_due("fix", t_s, self.rates.fix_period_s):
            dn, de = (self.rng.normal(0.0, self.position_noise_m, 2) if self.position_noise_m else (0.0, 0.0))
            lat, lon = local_to_latlon(n + dn, e + de, *self.origin)
            lt["position"] = Stamped((lat, lon), t_s, "GGA", True)
            lt["fix_quality"] = Stamped(1, t_s, "GGA", True)
            lt["sog_m_s"] = Stamped(math.hypot(u, v), t_s, "RMC", True)
            lt["cog_rad"] = Stamped((psi + math.atan2(v, u)) % (2.0 * math.pi), t_s, "RMC", True)
        return NavSample(**lt)
