"""The boat's 12 V 105 Ah lead-acid battery (SPEC 1), as the simulated Mbed reports it.

    V = OCV(soc) - I R,   OCV(soc): the resting voltage, piecewise linear through OCV_TABLE
    I = idle + I_full (|d_port|^3 + |d_stbd|^3),  d = duty / 100            battery current (A)
    d soc / dt = -I / (3600 capacity_ah)

The cube: a PWM-driven motor draws I_motor at duty d, and the battery supplies it only
the fraction d of the time; a propeller's torque (so I_motor) grows with the square of
its speed, which follows the voltage d x 12 V: d x d^2. Sag under load is the I R drop
(battery and wiring); Peukert's capacity loss at high current is left out. The numbers
are a typical 105 Ah deep-cycle battery and a 30 A trolling motor, not measurements of
the WAM-V's own. Pure: duties and a time step in, a state of charge and volts out.
"""

from __future__ import annotations

from dataclasses import dataclass

from autopilot.mathutil import clamp
from autopilot.schema import param

__all__ = ["BatteryConfig", "Battery", "OCV_TABLE"]

# (state of charge, resting voltage V) of a 12 V flooded lead-acid battery: ~linear from full to ~10 %,
# then the knee of a flat battery
OCV_TABLE = ((0.0, 10.5), (0.1, 11.7), (0.5, 12.2), (1.0, 12.7))


@dataclass(frozen=True)
class BatteryConfig:
    capacity_ah: float = param(105.0, unit="Ah", lo=0.001, hi=1000.0, source="SPEC 1", doc="usable capacity")
    initial_soc: float = param(1.0, unit="-", lo=0.0, hi=1.0, doc="state of charge at the start (1 = full)")
    resistance_ohm: float = param(0.02, unit="ohm", lo=0.0, hi=1.0, source="battery ~6 mOhm + wiring and H-bridge",
                                  doc="internal and wiring resistance: the sag under load")
    motor_full_a: float = param(30.0, unit="A", lo=0.0, hi=200.0, source="a 30 lb, 12 V trolling motor at full speed",
                                doc="one motor's battery current at 100 % duty")
    idle_a: float = param(0.5, unit="A", lo=0.0, hi=20.0, source="Mbed and H-bridge", doc="current with the motors off")


class Battery:
    """State of charge and terminal voltage; :meth:`drain` over each stretch of constant duty."""

    def __init__(self, config: BatteryConfig = BatteryConfig()) -> None:
        self.config = config
        self.soc = float(config.initial_soc)

    def current_a(self, duty_port_pct: float, duty_stbd_pct: float) -> float:
        c = self.config
        dp, ds = abs(duty_port_pct) / 100.0, abs(duty_stbd_pct) / 100.0
        return c.idle_a + c.motor_full_a * (dp ** 3 + ds ** 3)

    def drain(self, duty_port_pct: float, duty_stbd_pct: float, dt_s: float) -> None:
        """These duties held for ``dt_s``."""
        used_ah = self.current_a(duty_port_pct, duty_stbd_pct) * max(dt_s, 0.0) / 3600.0
        self.soc = clamp(self.soc - used_ah / self.config.capacity_ah, 0.0, 1.0)

    def voltage_v(self, duty_port_pct: float, duty_stbd_pct: float) -> float:
        """Terminal voltage now, under these duties."""
        return max(0.0, self.resting_v() - self.current_a(duty_port_pct, duty_stbd_pct) * self.config.resistance_ohm)

    def resting_v(self) -> float:
        """Open-circuit voltage at this state of charge (OCV_TABLE)."""
        for (s0, v0), (s1, v1) in zip(OCV_TABLE, OCV_TABLE[1:]):
            if self.soc <= s1:
                return v0 + (v1 - v0) * (self.soc - s0) / (s1 - s0)
        return OCV_TABLE[-1][1]
