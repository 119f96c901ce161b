"""A weak motor: one thruster short of the thrust table, the other on it (one owner of the two gains).

The simulated Mbed's ``sim.thrust_gain_port`` / ``sim.thrust_gain_stbd``, the identification's ``weak_motor``
effect, its synthetic truth and the campaigns' ``weak_motor_loss_nd`` spread all describe it by one signed
loss ``w`` (dimensionless): w > 0 the port motor makes (1 - w) of the table's thrust, w < 0 the starboard motor
makes (1 + w), w = 0 both make the table's. A fouled propeller, a tired motor or ESC: the helm and the
allocation do not know of it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["weak_motor_gains"]


def weak_motor_gains(loss_nd):
    """(port gain, starboard gain) of the loss ``loss_nd`` (a float, or an array of them: arrays back)."""
    if isinstance(loss_nd, float | int):
        w = float(loss_nd)
        return 1.0 - max(w, 0.0), 1.0 + min(w, 0.0)
    w = np.asarray(loss_nd, dtype=float)
    return 1.0 - np.maximum(w, 0.0), 1.0 + np.minimum(w, 0.0)
