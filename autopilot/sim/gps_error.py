"""Measurement errors of a satellite compass (GPS position and heading): pure, numbers in/out, seeded.

One model, used by the realistic trial generator of the identification
(``autopilot.sysid.realistic``) and by the simulated SC-30 behind
``autopilot run --sim`` (``autopilot.simdev.sc30``), so that both produce the
same kind of error:

- Position (per axis, north and east independently): a first-order
  Gauss-Markov error ``b`` (1-sigma ``wander_m``, correlation time
  ``wander_time_s``) plus white noise (``white_m``); a fraction
  ``outlier_rate`` of the fixes jumps by ``outlier_m`` in a random direction,
  for ``outlier_fixes`` consecutive fixes (1: a single-fix outlier, the next
  fix is clean again; more: a burst, multipath holding the receiver on one
  wrong solution). The GPS computes one fix per second; the error is drawn at
  the fix times.
- Velocity (the speed and course over ground the receiver reports with each fix):
  the true velocity over ground plus white noise per axis (``velocity_white_m_s``),
  a Doppler measurement that does not carry the position's wander.
- Heading: a first-order Gauss-Markov wander (``wander_deg``,
  ``wander_time_s``) plus white noise (``white_deg``), quantised to
  ``resolution_deg`` (the SC-30 prints 0.1 deg, SPEC 1); a fraction
  ``loss_rate`` of the sentences is lost.

Gauss-Markov, exact for any spacing of the samples (dt_k = t_k - t_{k-1})::

    b_k = phi_k b_{k-1} + sigma sqrt(1 - phi_k^2) w_k,   phi_k = exp(-dt_k / tau),  w_k ~ N(0, 1)
    b_0 ~ N(0, sigma^2)                                   (stationary from the start)

Defaults are the ones of project issue 12 (what the SC-30 and the daemon give):
0.5-2 m of wander with 30-60 s correlation time, ~0.15 m white, 1 % of fixes
jumping 10 m; heading 0.3 deg of slow wander, 0.1 deg quantisation, 0.5 % lost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autopilot.schema import param

__all__ = [
    "GpsErrorModel",
    "HeadingErrorModel",
    "HeadingErrorStream",
    "PositionErrorStream",
    "gauss_markov",
    "gauss_markov_step",
    "heading_errors",
    "position_errors",
    "quantise_deg",
    "velocity_errors",
]


@dataclass(frozen=True)
class GpsErrorModel:
    """GPS position error per axis: Gauss-Markov wander + white noise + outliers (single fixes or bursts)."""

    wander_m: float = param(1.0, unit="m", lo=0.0, hi=50.0, source="issue 12: 0.5-2 m", doc="1-sigma of the wandering (Gauss-Markov) error per axis")
    wander_time_s: float = param(45.0, unit="s", lo=0.1, hi=1e5, source="issue 12: 30-60 s", doc="correlation time of the wander")
    white_m: float = param(0.15, unit="m", lo=0.0, hi=50.0, source="issue 12: ~0.15 m", doc="1-sigma of the white part per axis")
    outlier_rate: float = param(0.01, unit="-", lo=0.0, hi=1.0, source="issue 12: 1 %", doc="fraction of fixes that start a jump")
    outlier_m: float = param(10.0, unit="m", lo=0.0, hi=1000.0, source="issue 12: 10 m", doc="size of a jump (random direction)")
    outlier_fixes: int = param(1, unit="fixes", lo=1, hi=60, source="not in the sources: multipath holds a receiver on a wrong solution for seconds", doc="consecutive fixes one jump lasts (the same offset on each)")
    velocity_white_m_s: float = param(0.05, unit="m/s", lo=0.0, hi=5.0, source="not in the sources: a GNSS receiver's Doppler velocity", doc="1-sigma of the velocity error per axis behind the reported speed and course over ground (white)")

    @property
    def rms_m(self) -> float:
        """Total error RMS per axis (outliers aside)."""
        return math.hypot(self.wander_m, self.white_m)


@dataclass(frozen=True)
class HeadingErrorModel:
    """Heading error: Gauss-Markov wander + white noise, quantised, some sentences lost."""

    wander_deg: float = param(0.3, unit="deg", lo=0.0, hi=30.0, source="issue 12: 0.3 deg", doc="1-sigma of the slowly wandering error")
    wander_time_s: float = param(30.0, unit="s", lo=0.1, hi=1e5, doc="correlation time of the wander")
    white_deg: float = param(0.0, unit="deg", lo=0.0, hi=30.0, doc="1-sigma of the white part")
    resolution_deg: float = param(0.1, unit="deg", lo=0.0, hi=10.0, source="SPEC 1 (SC-30 resolution)", doc="quantisation step (0 = none)")
    loss_rate: float = param(0.005, unit="-", lo=0.0, hi=1.0, source="issue 12: 0.5 %", doc="fraction of heading sentences lost")


def gauss_markov_step(b: float, dt_s: float, sigma: float, tau_s: float, w: float) -> float:
    """One exact step of the first-order Gauss-Markov process over ``dt_s`` with the N(0, 1) draw ``w``."""
    phi = math.exp(-max(dt_s, 0.0) / tau_s)
    return phi * b + sigma * math.sqrt(max(1.0 - phi * phi, 0.0)) * w


def gauss_markov(t_s, sigma: float, tau_s: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary Gauss-Markov series at the (increasing) times ``t_s``."""
    t = np.asarray(t_s, dtype=float)
    out = np.zeros(t.size)
    if t.size == 0 or sigma <= 0.0:
        return out
    w = rng.standard_normal(t.size)
    phi = np.exp(-np.diff(t, prepend=t[0]) / tau_s)
    gain = sigma * np.sqrt(np.maximum(1.0 - phi * phi, 0.0))
    gain[0] = sigma
    b = 0.0
    for k in range(t.size):  # a first-order recursion (lfilter needs constant coefficients)
        b = phi[k] * b + gain[k] * w[k]
        out[k] = b
    return out


def position_errors(model: GpsErrorModel, t_fix_s, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(north_m, east_m, is_outlier) errors of fixes taken at ``t_fix_s``."""
    t = np.asarray(t_fix_s, dtype=float)
    north = gauss_markov(t, model.wander_m, model.wander_time_s, rng) + rng.normal(0.0, 1.0, t.size) * model.white_m
    east = gauss_markov(t, model.wander_m, model.wander_time_s, rng) + rng.normal(0.0, 1.0, t.size) * model.white_m
    start = rng.random(t.size) < model.outlier_rate
    angle = rng.uniform(0.0, 2.0 * math.pi, t.size)
    # a burst repeats its first fix's offset (the same draws as single-fix outliers: seeds keep their errors)
    last_start = np.maximum.accumulate(np.where(start, np.arange(t.size), -model.outlier_fixes))
    jump = np.arange(t.size) - last_start < model.outlier_fixes
    angle = angle[np.maximum(last_start, 0)]
    north = north + np.where(jump, model.outlier_m * np.cos(angle), 0.0)
    east = east + np.where(jump, model.outlier_m * np.sin(angle), 0.0)
    return north, east, jump


def velocity_errors(model: GpsErrorModel, t_fix_s, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(north_m_s, east_m_s) errors of the velocity reported with the fixes at ``t_fix_s``."""
    n = np.asarray(t_fix_s, dtype=float).size
    return rng.normal(0.0, 1.0, n) * model.velocity_white_m_s, rng.normal(0.0, 1.0, n) * model.velocity_white_m_s


def quantise_deg(heading_deg, resolution_deg: float):
    """Heading as printed: rounded to ``resolution_deg`` and wrapped to [0, 360)."""
    h = np.asarray(heading_deg, dtype=float) % 360.0
    if resolution_deg > 0.0:
        h = np.round(h / resolution_deg) * resolution_deg
    return h % 360.0


def heading_errors(model: HeadingErrorModel, t_s, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(error_deg before quantisation, lost) of heading samples at ``t_s``."""
    t = np.asarray(t_s, dtype=float)
    err = gauss_markov(t, model.wander_deg, model.wander_time_s, rng) + rng.normal(0.0, 1.0, t.size) * model.white_deg
    return err, rng.random(t.size) < model.loss_rate


class PositionErrorStream:
    """The position error fix by fix, for a device that produces fixes as time goes (the simulated SC-30)."""

    def __init__(self, model: GpsErrorModel, rng: np.random.Generator) -> None:
        self.model, self._rng = model, rng
        self._t_s: float | None = None
        self._b = np.zeros(2)
        self._jump = np.zeros(2)  # the offset of the burst under way
        self._jump_left = 0  # fixes it still lasts

    def next(self, t_s: float) -> tuple[float, float]:
        """(north_m, east_m) error of the fix taken at ``t_s`` (times increasing)."""
        m, rng = self.model, self._rng
        w = rng.standard_normal(2)
        if self._t_s is None:
            self._b = m.wander_m * w
        else:
            self._b = np.array([gauss_markov_step(float(b), t_s - self._t_s, m.wander_m, m.wander_time_s, float(x))
                                for b, x in zip(self._b, w)])
        self._t_s = float(t_s)
        err = self._b + m.white_m * rng.standard_normal(2)
        if rng.random() < m.outlier_rate:
            a = rng.uniform(0.0, 2.0 * math.pi)
            self._jump, self._jump_left = m.outlier_m * np.array([math.cos(a), math.sin(a)]), m.outlier_fixes
        if self._jump_left > 0:
            err = err + self._jump
            self._jump_left -= 1
        return float(err[0]), float(err[1])

    def velocity(self, vn_m_s: float, ve_m_s: float) -> tuple[float, float]:
        """(speed_m_s, course_rad in [0, 2 pi)) reported for a true velocity over ground (north, east) at this
        fix: the receiver's velocity error added."""
        dv = self.model.velocity_white_m_s * self._rng.standard_normal(2)
        vn, ve = vn_m_s + float(dv[0]), ve_m_s + float(dv[1])
        return math.hypot(vn, ve), math.atan2(ve, vn) % (2.0 * math.pi)


class HeadingErrorStream:
    """The heading error sample by sample (the simulated SC-30); ``None`` for a lost sentence."""

    def __init__(self, model: HeadingErrorModel, rng: np.random.Generator) -> None:
        self.model, self._rng = model, rng
        self._t_s: float | None = None
        self._b = 0.0

    def next(self, t_s: float) -> float | None:
        m, rng = self.model, self._rng
        w = float(rng.standard_normal())
        self._b = m.wander_deg * w if self._t_s is None else gauss_markov_step(self._b, t_s - self._t_s, m.wander_deg, m.wander_time_s, w)
        self._t_s = float(t_s)
        err = self._b + m.white_deg * float(rng.standard_normal())
        return None if rng.random() < m.loss_rate else err
