"""The measured data of the real boat (SPEC sections 4 and 6).

These are the only measurements in the sources: the thrust of each command
level (thesis Table 4.2, Fig 4.11) and the free-running lookup table of
steady speed and yaw rate for port/starboard thrust (thesis Fig 8.2). The
model calibration, the thrust allocation and the identification all read
them from here.
"""

from __future__ import annotations

from dataclasses import dataclass

HULL_LENGTH_M = 3.96  # L, thesis ch. 2 (the papers give 3.91 m); SPEC 1

# Table 4.2 / SPEC section 4: command level -> (voltage V, PWM duty %, thrust N).
LEVELS: dict[str, tuple[float, float, float]] = {
    "A": (0.0, 0.0, 0.0),
    "B": (2.4, 20.0, 2.3),
    "C": (4.8, 40.0, 10.25),
    "D": (7.2, 60.0, 18.56),
    "E": (9.6, 80.0, 21.15),
    "F": (12.0, 100.0, 32.5),
}


MAX_THRUST_N = LEVELS["F"][2]  # level F, 12 V: the largest thrust per thruster (Table 4.2)


def level_thrust_n(letter: str) -> float:
    """Thrust (N) of a level letter: capital = forward, small = reverse (negative)."""
    thrust = LEVELS[letter.upper()][2]
    return thrust if letter.isupper() else -thrust


@dataclass(frozen=True)
class SteadyRow:
    """One row of the free-running table: input pair and the steady response.

    ``speed_m_s`` is the speed magnitude (reverse rows go astern);
    ``yaw_rate_rad_s`` is negative for a turn to port (SPEC section 2).
    """

    name: str
    thrust_port_n: float
    thrust_stbd_n: float
    yaw_rate_rad_s: float
    speed_m_s: float

    @property
    def kind(self) -> str:
        """'straight', 'reverse' or 'turn'."""
        if self.thrust_port_n == self.thrust_stbd_n:
            return "reverse" if self.thrust_port_n < 0 else "straight"
        return "turn"


# Thesis Fig 8.2 as tabulated in SPEC section 6.
MEASURED_TABLE: tuple[SteadyRow, ...] = (
    SteadyRow("AA", 0.0, 0.0, 0.0, 0.0),
    SteadyRow("BB", 2.3, 2.3, 0.0, 0.2456),
    SteadyRow("CC", 10.25, 10.25, 0.0, 1.09430605),
    SteadyRow("DD", 18.56, 18.56, 0.0, 1.98),
    SteadyRow("EE", 21.15, 21.15, 0.0, 2.25),
    SteadyRow("FF", 32.5, 32.5, 0.0, 3.468),
    SteadyRow("bb", -2.3, -2.3, 0.0, 0.24),
    SteadyRow("cc", -10.25, -10.25, 0.0, 1.09430605),
    SteadyRow("dd", -18.56, -18.56, 0.0, 1.98),
    SteadyRow("ee", -21.15, -21.15, 0.0, 2.25),
    SteadyRow("ff", -32.5, -32.5, 0.0, 3.468),
    SteadyRow("AB", 0.0, 2.3, -0.113, 0.124),
    SteadyRow("AC", 0.0, 10.25, -0.342, 0.53),
    SteadyRow("AD", 0.0, 18.56, -0.489, 0.904),
    SteadyRow("AE", 0.0, 21.15, -0.52, 1.01),
    SteadyRow("AF", 0.0, 32.5, -0.615, 1.44),
    SteadyRow("BC", 2.3, 10.25, -0.382, 0.64),
    SteadyRow("BD", 2.3, 18.56, -0.514, 1.0),
    SteadyRow("BE", 2.3, 21.15, -0.5423, 1.1),
    SteadyRow("BF", 2.3, 32.5, -0.63, 1.53),
)


def row(name: str) -> SteadyRow:
    """The measured row with this two-letter name."""
    for r in MEASURED_TABLE:
        if r.name == name:
            return r
    raise KeyError(f"no measured row named {name!r}")
