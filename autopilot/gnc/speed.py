"""Common-mode thrust that keeps the speed (SPEC 8, Eq 8.5-8.6): table feed-forward + a bounded PI trim.

    tau_com = T_table(U_cmd) + trim,   trim = K_p (U_cmd - U_sog) + K_i integral(U_cmd - U_sog) dt

SPEC 8 says "tau_com keeps the speed". The thesis reads tau_com from the
measured free-running table (Fig 8.2) alone, which holds the speed only in
the conditions the table was measured in: still water, no wind. A 5 m/s
headwind puts ~20 N of drag on the WAM-V at 1 m/s (model ``wind_cx`` x frontal
area), more than the table's 2 x 9.4 N for that speed, and the boat stalls
or drifts astern; a following current makes it overshoot the speed and every
turn radius grows. The trim closes the loop on the speed over ground the
GPS gives, made along the heading (:func:`along_heading_m_s`: a boat going
astern is slower than stopped, not faster), so the table stays the feed-forward (it
carries the steady thrust, the trim only the disturbance) and the trim can be
small and slow.

The integral learns from the speed the boat should have by now (the wanted
speed through a first-order lag, ``reference_time_constant_s``): from rest the
boat needs ~10 s to get going, and an integral of the wanted speed's error
wound up over them (16 N against the table's 9.4 N at 1 m/s) and drove the
boat 40 % over its speed for the next 20 s. A headwind's or a current's
steady error still reaches it: the reference arrives at the wanted speed.

Bounded, with anti-windup:
- the trim is clamped to +-``trim_limit_n`` (the feed-forward stays in charge);
- the integral is clamped to +-``integral_limit_n``; it may not grow while the
  allocator cuts the common mode (saturation: more cannot be delivered), nor
  fall while tau_com sits at zero (the trim never asks for astern common
  thrust: braking by reversing both thrusters is not what "keep the speed"
  means, and the table has no reverse straight-line speeds);
- no integration while the wanted speed is zero (stopped, or holding inside
  the radius): the trim is reset there.

Pure: speed, wanted speed, dt in; newtons out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.mathutil import clamp
from autopilot.schema import param

# the speeds the boat can be asked for (a mission's legs, ctl speed, the configuration's default): at most the
# fastest measured row (FF, 3.47 m/s, Fig 8.2); at least enough to move (0.01 m/s was taken, the boat sat still
# while the status said auto: a new user's test)
MIN_SPEED_M_S = 0.05
MAX_SPEED_M_S = 3.5
SPEED_RANGE = f"[{MIN_SPEED_M_S:g}, {MAX_SPEED_M_S:g}] m/s"  # as the refusals say it


def is_speed(value) -> bool:
    """A speed the boat can be asked for: a number (not a bool) in [MIN_SPEED_M_S, MAX_SPEED_M_S] (NaN is not)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and MIN_SPEED_M_S <= value <= MAX_SPEED_M_S


@dataclass(frozen=True)
class SpeedTrimConfig:
    """Gains and bounds of the speed trim on top of the Fig 8.2 feed-forward."""

    enabled: bool = param(True, source="SPEC 8 (tau_com keeps the speed)", doc="add the speed-over-ground PI trim to the table feed-forward (false = thesis: table only)")
    kp_n_s_per_m: float = param(8.0, unit="N s/m", lo=0.0, hi=200.0, source="chosen in simulation (autopilot evaluate, wind)", doc="proportional gain per thruster on the speed error")
    ki_n_per_m: float = param(3.0, unit="N/m", lo=0.0, hi=200.0, source="chosen in simulation (autopilot evaluate, wind)", doc="integral gain per thruster on the speed error")
    integral_limit_n: float = param(15.0, unit="N", lo=0.0, hi=100.0, source="anti-windup", doc="largest |Ki * integral| contribution per thruster")
    trim_limit_n: float = param(20.0, unit="N", lo=0.0, hi=100.0, source="bound (table carries the steady thrust)", doc="largest |trim| per thruster")
    reference_time_constant_s: float = param(
        10.0, unit="s", lo=0.0, hi=60.0, source="benchmarks/speed_trim.py (the calibrated model's surge response)",
        doc="the integral learns from the speed the boat should have by now, the wanted speed through a first-order "
            "lag of this time constant, not from the wanted speed itself (from rest it wound up over the ~10 s the "
            "boat takes to get going, and the boat then ran 40 % over its speed); 0 = from the wanted speed")
    short_warn_s: float = param(
        30.0, unit="s", lo=1.0, hi=3600.0, source="chosen: longer than the boat takes to get going from rest (~10 s)",
        doc="short of the wanted speed by short_margin_m_s this long with the trim, its integral or the thrusters at "
            "their bound is said (speed_short: found by a modes audit, a boat losing ground at 29.4 N unsaid)")
    short_margin_m_s: float = param(0.2, unit="m/s", lo=0.01, hi=5.0, source="chosen: a fifth of the cruise speed",
                                    doc="see short_warn_s (said again made within half of it)")


@dataclass(frozen=True)
class SpeedTrimTerms:
    """One cycle's trim (N per thruster): p + i, clamped to the trim limit."""

    p_n: float
    i_n: float
    trim_n: float


def along_heading_m_s(nav) -> float:
    """The speed over ground made along the heading (m/s; negative: the boat goes astern), what the common thrust
    drives: the size of the speed over ground took a boat blown backwards at 2.3 m/s for one too fast, and the
    trim floored its forward thrust at zero (found by a modes audit: an rtl in a gale drifted 3.8 km)."""
    return nav.speed_m_s * math.cos(nav.course_rad - nav.psi_rad)


class SpeedTrim:
    """Bounded PI on (U_cmd - U_sog) with conditional integration."""

    def __init__(self, config: SpeedTrimConfig = SpeedTrimConfig()) -> None:
        self.config = config
        self.integral_n = 0.0
        self.reference_m_s: float | None = None  # the speed the boat should have by now (None: from the next speed)

    def reset(self) -> None:
        self.integral_n = 0.0
        self.reference_m_s = None

    def terms(self, speed_cmd_m_s: float, speed_m_s: float) -> SpeedTrimTerms:
        cfg = self.config
        if not cfg.enabled or speed_cmd_m_s <= 0.0:
            return SpeedTrimTerms(0.0, 0.0, 0.0)
        p = cfg.kp_n_s_per_m * (speed_cmd_m_s - speed_m_s)
        lim = cfg.trim_limit_n
        t = p + self.integral_n
        t = clamp(t, -lim, lim)
        return SpeedTrimTerms(p, self.integral_n, t)

    def integrate(self, speed_cmd_m_s: float, speed_m_s: float, dt_s: float, *, block_up: bool = False, block_down: bool = False) -> None:
        """Advance the integral by one cycle.

        ``block_up``: the common mode could not be delivered in full (the
        allocator cut it): the integral may not grow. ``block_down``: tau_com
        sits at its floor of zero: the integral may not fall.
        """
        cfg = self.config
        if not cfg.enabled or speed_cmd_m_s <= 0.0:
            self.reset()
            return
        tau = cfg.reference_time_constant_s
        if tau > 0.0:
            ref = speed_m_s if self.reference_m_s is None else self.reference_m_s
            self.reference_m_s = ref = ref + (speed_cmd_m_s - ref) * min(1.0, dt_s / tau)
        else:
            ref = speed_cmd_m_s
        inc = cfg.ki_n_per_m * (ref - speed_m_s) * dt_s
        if (inc > 0.0 and block_up) or (inc < 0.0 and block_down):
            return
        new = self.integral_n + inc
        lim = cfg.integral_limit_n
        self.integral_n = clamp(new, -lim, lim)


class SpeedShort:
    """Says when the boat has been short of its wanted speed by more than ``short_margin_m_s`` for ``short_warn_s``
    with nothing more to give: the trim or its integral at its bound, or the thrusters at full (a headwind or a
    current more than the trim may stem, or than the boat can), and when it makes its speed again (within half
    the margin) or the course ends. The bounds stay (the feed-forward carries the steady thrust); the operator
    learns that they bind, and whether the thrusters had more to give."""

    def __init__(self, config: SpeedTrimConfig = SpeedTrimConfig()) -> None:
        self.config = config
        self.for_s = 0.0
        self.said = False

    def restart(self) -> None:
        """The helm drives again after cycles it did not: the time short counts afresh (what was said stays said)."""
        self.for_s = 0.0

    def update(self, speed_cmd_m_s: float | None, speed_m_s: float, dt_s: float, *, trim_n: float = 0.0,
               integral_n: float = 0.0, thrusters_full: bool = False) -> dict | None:
        """One cycle (``speed_cmd_m_s`` None: not on a course); the fields of a ``speed_short`` event when one is
        due. A boat going astern makes a negative ``speed_m_s`` (along_heading_m_s)."""
        cfg = self.config
        on = speed_cmd_m_s is not None and cfg.enabled and speed_cmd_m_s > 0.0
        pinned = ((cfg.trim_limit_n > 0.0 and trim_n >= cfg.trim_limit_n - 1e-9) or thrusters_full
                  or (cfg.integral_limit_n > 0.0 and integral_n >= cfg.integral_limit_n - 1e-9))  # 0: no such bound
        short = on and pinned and speed_m_s < speed_cmd_m_s - cfg.short_margin_m_s
        self.for_s = self.for_s + dt_s if short else 0.0
        if short and not self.said and self.for_s >= cfg.short_warn_s:
            self.said = True
            return {"short": True, "speed_m_s": round(speed_m_s, 2), "wanted_m_s": round(speed_cmd_m_s, 2),
                    "for_s": round(self.for_s, 1), "limit_n": cfg.trim_limit_n, "thrusters_full": bool(thrusters_full)}
        if self.said and (not on or speed_m_s >= speed_cmd_m_s - 0.5 * cfg.short_margin_m_s):
            self.said = False
            return {"short": False, "limit_n": cfg.trim_limit_n}
        return None
