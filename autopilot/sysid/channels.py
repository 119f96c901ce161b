"""The measured channels the identification compares with the replay: what each is and how it is shown.

    channel    predicted series (prediction.predict)   measured                                      shown in
    position   north_m, east_m                     the GPS antenna's fixes (1 Hz)                 m
    heading    psi_rad                             the compass (10 Hz), residuals wrapped         deg
    velocity   vn_m_s, ve_m_s                      the receiver's speed and course over ground    m/s
                                                   (SOG/COG of RMC or VTG), one with each fix

The velocity is the receiver's own speed and course over ground, not a difference of fixes: a
satellite compass sends it in RMC/VTG beside the position, and its error does not carry the
position's slow wander. It is what tells a current from that wander (set and drift are the velocity
over ground less the velocity through the water): over five 30-s pond logs with 1.5-2 m of GPS wander,
the positions alone named a hidden 0.2 m/s current in only half the draws. A trial without SOG/COG
simply has no velocity channel.

Position and velocity are horizontal (their RMS is over both axes together, one noise model shared by
the axes); the heading is one component. Every channel's noise is wander plus white (noise.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Channel:
    """One measured channel (module docstring)."""

    name: str
    components: tuple[str, ...]  # the replay's predicted series it is compared with
    unit: str  # shown unit (the heading in degrees, the rest SI)
    key_unit: str  # suffix of its figures in summary.json: position_m, heading_deg, velocity_m_s
    angle: bool = False  # residuals wrapped to (-pi, pi], shown in degrees

    @property
    def horizontal(self) -> bool:
        """Two horizontal axes: an RMS is the horizontal distance (both axes summed)."""
        return len(self.components) == 2

    def shown(self, si: float) -> float:
        """A value (or an RMS) of this channel in its shown unit."""
        return math.degrees(si) if self.angle else si


POSITION = Channel("position", ("north_m", "east_m"), "m", "m")
HEADING = Channel("heading", ("psi_rad",), "deg", "deg", angle=True)
VELOCITY = Channel("velocity", ("vn_m_s", "ve_m_s"), "m/s", "m_s")
CHANNELS: tuple[Channel, ...] = (POSITION, HEADING, VELOCITY)
BY_NAME: dict[str, Channel] = {c.name: c for c in CHANNELS}
