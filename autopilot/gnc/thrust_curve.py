"""Thrust <-> voltage <-> PWM duty and direction (SPEC section 4, thesis Table 4.2, Fig 4.11).

The Minn Kota motors were commanded at six levels, 0-12 V in 2.4 V steps,
PWM duty 0-100 % (duty = voltage / 12 V). The measured thrust of each level
is interpolated monotonically (piecewise linear) in both directions. The
reverse curve is its own configurable curve because trolling motors push
less astern; by default it mirrors the forward one, as the thesis tabulates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autopilot.measured import LEVELS
from autopilot.schema import param

_FORWARD_DUTY = tuple(v[1] for v in LEVELS.values())
_FORWARD_THRUST = tuple(v[2] for v in LEVELS.values())


@dataclass(frozen=True)
class ThrustCurve:
    """Duty (%) -> thrust (N) per direction, monotonic, through (0, 0)."""

    forward_duty_pct: tuple[float, ...] = param(
        _FORWARD_DUTY, unit="%", lo=0, hi=100, source="Table 4.2", doc="duty of each forward level"
    )
    forward_thrust_n: tuple[float, ...] = param(
        _FORWARD_THRUST, unit="N", lo=0, hi=500, source="Fig 8.2 / SPEC 4", doc="thrust of each forward level"
    )
    reverse_duty_pct: tuple[float, ...] = param(
        _FORWARD_DUTY, unit="%", lo=0, hi=100, source="Table 4.2", doc="duty of each reverse level"
    )
    reverse_thrust_n: tuple[float, ...] = param(
        _FORWARD_THRUST,
        unit="N",
        lo=0,
        hi=500,
        source="SPEC 4 (table mirrors forward)",
        doc="thrust magnitude of each reverse level",
    )

    def __post_init__(self) -> None:
        for name in ("forward", "reverse"):
            duty = np.asarray(getattr(self, f"{name}_duty_pct"))
            thrust = np.asarray(getattr(self, f"{name}_thrust_n"))
            if duty.shape != thrust.shape or duty.size < 2:
                raise ValueError(f"{name}_duty_pct and {name}_thrust_n must be lists of equal length >= 2")
            if duty[0] != 0 or thrust[0] != 0:
                raise ValueError(f"{name} curve must start at 0 % duty and 0 N")
            if np.any(np.diff(duty) <= 0) or np.any(np.diff(thrust) <= 0):
                raise ValueError(f"{name}_duty_pct and {name}_thrust_n must be strictly increasing")

    @property
    def max_forward_n(self) -> float:
        """Largest forward thrust (N)."""
        return float(self.forward_thrust_n[-1])

    @property
    def max_reverse_n(self) -> float:
        """Largest reverse thrust magnitude (N)."""
        return float(self.reverse_thrust_n[-1])

    def thrust_n(self, duty_pct, reverse):
        """Thrust (N, negative astern) of a duty (0-100 %) and direction (True = reverse)."""
        duty = np.clip(np.asarray(duty_pct, dtype=float), 0.0, 100.0)
        fwd = np.interp(duty, self.forward_duty_pct, self.forward_thrust_n)
        rev = -np.interp(duty, self.reverse_duty_pct, self.reverse_thrust_n)
        out = np.where(np.asarray(reverse, dtype=bool), rev, fwd)
        return float(out) if out.ndim == 0 else out

    def thrust_from_signed_duty_n(self, signed_duty_pct):
        """Thrust (N) of a signed duty (%): negative duty = reverse."""
        d = np.asarray(signed_duty_pct, dtype=float)
        return self.thrust_n(np.abs(d), d < 0)

    def duty_pct(self, thrust_n):
        """Duty (0-100 %) and direction (True = reverse) that give a thrust (N); saturates."""
        t = np.asarray(thrust_n, dtype=float)
        fwd = np.interp(t, self.forward_thrust_n, self.forward_duty_pct)
        rev = np.interp(-t, self.reverse_thrust_n, self.reverse_duty_pct)
        reverse = t < 0
        duty = np.where(reverse, rev, fwd)
        if duty.ndim == 0:
            return float(duty), bool(reverse)
        return duty, reverse

    def signed_duty_pct(self, thrust_n):
        """Signed duty (%), negative = reverse, for a thrust (N)."""
        duty, reverse = self.duty_pct(thrust_n)
        out = np.where(reverse, -duty, duty)
        return float(out) if np.ndim(out) == 0 else out
