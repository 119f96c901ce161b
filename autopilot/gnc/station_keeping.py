"""Station keeping (HOLD) for a catamaran with two fixed thrusters and no rudder.

The boat can push along its hull, ahead or astern (the reverse curve of SPEC 4), and
turn; it cannot push sideways. So it holds a point the way a weathervaning vessel
does (Fossen's weather-optimal positioning): it lies with its bow into the resultant
of current and wind, holds the distance along the hull with the common thrust, and
steers a lateral error away with a small heading correction.

    e          = target - position (north, east)                the error, earth frame
    D         += ki e dt, near the point, |D| <= integral_limit   the thrust per thruster the current and
                                                                  wind take, earth frame, estimated on line
    psi_ref    = the given hold heading, else the direction of D  least effort: bow into the resultant, where
                 (rate-limited; held while |D| < disturbance_min)  the hull's drag is lowest
    e_a, v_a   = e and the ground speed along the hull (actual heading)
    v_ref      = sqrt_controller(e_a, speed_gain, brake)          the speed to close with: linear near the
                                                                  point, braking-limited farther out
    tau_com    = kv (v_ref - v_a) + D . u_hull                    per thruster (N), ahead or astern
    e_l        = e to starboard of psi_ref
    psi_d      = psi_ref + atan(+-e_l / lookahead), within +-max_correction (the sign of tau_com: astern,
                 the stern leads)

tau_com and psi_d go to the same heading PID and allocation as every mode
(:class:`autopilot.gnc.autopilot.Autopilot`). Farther than ``approach_m`` from the
point the boat first steers to it at ``approach_speed_m_s`` (the course path), as a
waypoint; inside it the speed to close with never asks for more braking than
``brake_m_s2`` (the position -> velocity square-root law of ArduPilot's position
controllers), so the boat arrives without overshooting on what two thrusters astern
can stop. A hold that starts farther than ``reposition_m`` from its point with the point
well off both the bow and the stern (a return to launch begun a few metres away, a hold
asked of a boat lying across the line to its point) first lines the hull up with the
point, bow or stern (ArduPilot Rover's loiter: forward or reverse to the point), closes
along that line and holds with the hull as it then lies: the heading correction above
(at most ``max_correction_deg``, through a thrust that is small near the point) would
take tens of seconds to slide the boat sideways there. With ``radius_m`` > 0 it drifts
at zero thrust inside the radius and drives back when it reaches it (ArduPilot's loiter
for boats: ``LOIT_RADIUS``), until it is within half the radius and slow again (else it
coasts through and out the other side); 0 = hold precisely. Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.geo import wrap_pi
from autopilot.gnc.speed import MAX_SPEED_M_S
from autopilot.mathutil import clamp
from autopilot.schema import param

__all__ = ["HoldConfig", "HoldOutput", "StationKeeper"]

CROSS_MIN_X = 3.0  # a given heading is called infeasible once this x disturbance_min_n pushes across it
_ASTERN_DEG = 110.0  # lining up: the stern leads when the point is farther than this off the bow ...
_ASTERN_BAND_DEG = 20.0  # ... give or take this much (hysteresis)


@dataclass(frozen=True)
class HoldConfig:
    """The ``gnc.hold`` block: station keeping's gains and limits (tuned in simulation: README, Modes)."""

    radius_m: float = param(0.0, unit="m", lo=0.0, hi=100.0, source="ArduPilot LOIT_RADIUS (drift, then return)",
                            doc="drift at zero thrust inside this radius, drive back at it; 0 = hold precisely")
    position_smoothing_s: float = param(3.0, unit="s", lo=0.0, hi=30.0, source="benchmarks/station_keeping.py --chatter",
                                        doc="the position the hold steers by follows each fix with this time constant, "
                                            "moved on by the speed and course over ground between (no lag for the "
                                            "boat's own motion; each fix's noise jump spread out); 0 = the fixes as "
                                            "they come")
    radius_slow_m_s: float = param(0.2, unit="m/s", lo=0.01, hi=3.0, source="chosen",
                                   doc="with radius_m: back within half the radius, drift again only below this ground "
                                       "speed (else it coasts through and out the other side)")
    speed_gain_per_s: float = param(0.55, unit="1/s", lo=0.01, hi=10.0, source="tuned in simulation (autopilot evaluate)",
                                    doc="near the point, the speed to close with per metre of error along the hull")
    brake_m_s2: float = param(0.25, unit="m/s^2", lo=0.01, hi=2.0,
                              source="two thrusters astern (~2 x 25 N) on ~300 kg with added mass, with margin",
                              doc="farther out, the speed to close with is what this deceleration can stop")
    kv_n_s_per_m: float = param(90.0, unit="N s/m", lo=0.0, hi=500.0, source="tuned in simulation",
                                doc="common thrust per thruster per m/s the speed along the hull misses that speed")
    ki_n_per_m_s: float = param(0.4, unit="N/(m s)", lo=0.0, hi=50.0, source="tuned in simulation",
                                doc="growth of the disturbance estimate per metre of error along the hull")
    learn_within_m: float = param(5.0, unit="m", lo=0.1, hi=50.0, source="chosen",
                                  doc="the disturbance estimate learns only this close to the point (not from an approach)")
    learn_below_m_s: float = param(3.0, unit="m/s", lo=0.01, hi=3.0,
                                   source="benchmarks/station_keeping.py --currents: at 0.2 m/s a current of 0.25 m/s "
                                          "or more, carrying the boat faster than that, was never learned (RMS 9-11 m)",
                                   doc="... and only below this ground speed (3 = at any speed; with radius_m, below "
                                       "radius_slow_m_s too)")
    learn_deadband_m: float = param(0.5, unit="m", lo=0.0, hi=5.0,
                                    source="benchmarks/station_keeping.py --pause (a pause at cruise in calm water)",
                                    doc="error within this does not drive the estimate (a fix's noise, an offset the "
                                        "boat cannot push sideways out of: 0.17 m abeam, learned for 20 s, turned a "
                                        "hold in calm water 100 deg at full thrust)")
    learn_error_m: float = param(3.0, unit="m", lo=0.05, hi=50.0, source="benchmarks/station_keeping.py --currents",
                                 doc="at most this much error drives the estimate (a large error is a transient)")
    integral_limit_n: float = param(28.0, unit="N", lo=0.0, hi=100.0, source="below the 32.5 N of a thruster",
                                    doc="largest disturbance estimate (per thruster)")
    off_warn_m: float = param(5.0, unit="m", lo=0.5, hi=1000.0, source="chosen: 5x the hold's error in 0.2 m/s of "
                              "current (README, Modes); a modes audit's hold swept 18 m off and back every 80 s unsaid",
                              doc="a hold this far off its point for off_warn_s is said (hold_off: it is not keeping it)")
    off_warn_s: float = param(30.0, unit="s", lo=1.0, hi=3600.0, source="chosen: longer than an approach or a "
                              "failsafe's resume takes", doc="see off_warn_m")
    disturbance_min_n: float = param(1.0, unit="N", lo=0.0, hi=30.0, source="chosen",
                                     doc="below this estimate the heading held so far is kept (no resultant to face)")
    heading_rate_deg_s: float = param(9.0, unit="deg/s", lo=0.1, hi=90.0, source="chosen",
                                      doc="how fast the least-effort heading may swing")
    lookahead_m: float = param(5.0, unit="m", lo=0.5, hi=100.0, source="chosen, ~1 boat length",
                               doc="heading correction atan(lateral error / lookahead)")
    max_correction_deg: float = param(40.0, unit="deg", lo=0.0, hi=90.0, source="chosen",
                                      doc="largest heading correction for a lateral error")
    approach_m: float = param(8.0, unit="m", lo=1.0, hi=500.0, source="chosen, two boat lengths",
                              doc="farther than this the boat first steers to the point as to a waypoint")
    approach_speed_m_s: float = param(1.0, unit="m/s", lo=0.1, hi=MAX_SPEED_M_S, source="Fig 8.2 (CC)",
                                      doc="speed of that approach")
    reposition_m: float = param(3.0, unit="m", lo=0.0, hi=100.0,
                                source="chosen: benchmarks/station_keeping.py --offset (within 1 m in 6-17 s, was 6-50 s)",
                                doc="a least-effort hold starting farther than this from its point, the point well off the "
                                    "bow and the stern, first lines up with it (bow or stern) and closes along that line; "
                                    "0 = never")
    reposition_off_deg: float = param(30.0, unit="deg", lo=0.0, hi=90.0, source="chosen",
                                      doc="... well off: more than this from both the bow and the stern")


@dataclass(frozen=True)
class HoldOutput:
    """One station-keeping step: a course demand (``approach``), a force demand, or drift (zero thrust)."""

    psi_d_rad: float
    tau_com_n: float  # per thruster, negative = astern (force demand only)
    speed_cmd_m_s: float  # the approach's speed (course demand only)
    approach: bool  # steer to the point as to a waypoint (the course path)
    drifting: bool  # inside the radius: zero thrust
    error_m: float
    psi_ref_rad: float  # the heading it holds (given, or least effort)
    disturbance_n: float  # the steady thrust the disturbance takes, along psi_ref, per thruster
    # a given hold heading the disturbance lies across, beyond max_correction_deg of it (either end): the boat
    # cannot push sideways, so it cannot hold the point at that heading; the heading it could hold (rad)
    feasible_heading_rad: float | None = None


LEAD_BY_MOTION_M_S = 0.2  # with this much way on along the hull, the motion's sign steers the correction


def sqrt_controller(error: float, gain: float, accel: float) -> float:
    """Rate for an error: ``gain * error`` near zero, ``sqrt(2 accel |error|)`` farther out (continuous at the
    knee ``accel / gain^2``), so closing at that rate can always be stopped at ``accel``."""
    knee = accel / (gain * gain)
    if abs(error) <= knee:
        return gain * error
    return math.copysign(math.sqrt(2.0 * accel * (abs(error) - 0.5 * knee)), error)


class StationKeeper:
    """Holds one point (and a heading, or the least-effort one). :meth:`step` once per control cycle."""

    def __init__(self, config: HoldConfig, target_ne_m: tuple[float, float], *, heading_rad: float | None = None,
                 initial_heading_rad: float = 0.0) -> None:
        self.config = config
        self.target = (float(target_ne_m[0]), float(target_ne_m[1]))
        self.heading_rad = heading_rad
        self._psi_ref = heading_rad if heading_rad is not None else float(initial_heading_rad)
        self._d_n = (0.0, 0.0)  # the disturbance estimate D (north, east), N per thruster
        self._drifting = False
        self._started = False
        self._lining_up = False  # closing along the line to the point (bow or stern on it)
        self._astern = False  # ... stern first
        self._position: tuple[float, float] | None = None  # the smoothed position (north, east), m

    @property
    def disturbance_ne_n(self) -> tuple[float, float]:
        return self._d_n

    def least_effort(self, psi_rad: float, *, target_ne_m: tuple[float, float] | None = None) -> StationKeeper:
        """The same point (or ``target_ne_m``) and what was learned of the disturbance (north/east, whatever the
        heading), the heading no longer given: the least-effort one from ``psi_rad`` (the boat's now)."""
        keeper = StationKeeper(self.config, self.target if target_ne_m is None else target_ne_m, heading_rad=None,
                               initial_heading_rad=psi_rad)
        keeper._d_n = self._d_n
        return keeper

    def step(self, north_m: float, east_m: float, psi_rad: float, sog_m_s: float, cog_rad: float,
             dt_s: float, *, max_speed_m_s: float | None = None) -> HoldOutput:
        """``max_speed_m_s``: the operator's speed (ctl speed, DO_CHANGE_SPEED) when the mission or a return closes on a
        point it stops at: the approach goes no faster (None: approach_speed_m_s)."""
        cfg = self.config
        approach_m_s = cfg.approach_speed_m_s if max_speed_m_s is None else min(cfg.approach_speed_m_s, max_speed_m_s)
        north_m, east_m = self._smoothed(north_m, east_m, sog_m_s, cog_rad, dt_s)
        en, ee = self.target[0] - north_m, self.target[1] - east_m
        d = math.hypot(en, ee)
        if cfg.radius_m > 0.0:  # drift inside the radius; come back from its edge to half of it, and stop there
            slow = not math.isfinite(sog_m_s) or sog_m_s < cfg.radius_slow_m_s
            if self._drifting and d >= cfg.radius_m:
                self._drifting = False
            elif not self._drifting and d <= 0.5 * cfg.radius_m and slow:
                self._drifting = True
        if self._drifting:
            return self._out(psi_rad, 0.0, 0.0, False, True, d)
        if d > cfg.approach_m:
            return self._out(math.atan2(ee, en), 0.0, approach_m_s, True, False, d)
        # drifting and driving back (radius_m), the drive back is no holding to learn from: only when slow there
        below = cfg.learn_below_m_s if cfg.radius_m <= 0.0 else min(cfg.learn_below_m_s, cfg.radius_slow_m_s)
        slow = not math.isfinite(sog_m_s) or sog_m_s < below
        if d < cfg.learn_within_m and slow and d > cfg.learn_deadband_m:  # learn from holding, not an approach
            # the error beyond the deadband, at most learn_error_m of it, drives the estimate
            w = min(d - cfg.learn_deadband_m, cfg.learn_error_m) / d
            dn = self._d_n[0] + cfg.ki_n_per_m_s * en * w * dt_s
            de = self._d_n[1] + cfg.ki_n_per_m_s * ee * w * dt_s
            size = math.hypot(dn, de)
            if size > cfg.integral_limit_n:
                dn, de = dn * cfg.integral_limit_n / size, de * cfg.integral_limit_n / size
            self._d_n = (dn, de)
        self._update_reference(dt_s)
        self._update_line_up(en, ee, d, psi_rad)
        c, s = math.cos(psi_rad), math.sin(psi_rad)
        e_a = en * c + ee * s  # the thrust acts along the hull as it lies now
        v_a = sog_m_s * math.cos(cog_rad - psi_rad) if math.isfinite(sog_m_s) else 0.0
        v_ref = clamp(sqrt_controller(e_a, cfg.speed_gain_per_s, cfg.brake_m_s2), -approach_m_s, approach_m_s)
        tau_com = cfg.kv_n_s_per_m * (v_ref - v_a) + self._d_n[0] * c + self._d_n[1] * s
        if self._lining_up:  # psi_ref is the line; the thrust along the hull closes as the hull comes round
            return self._out(self._psi_ref, tau_com, 0.0, False, False, d)
        e_l = -en * math.sin(self._psi_ref) + ee * math.cos(self._psi_ref)
        limit = math.radians(cfg.max_correction_deg)
        # astern, turning the other way moves the boat the same way; the way the boat moves, not the thrust, while
        # it has way on: braking astern at 2 m/s ahead, the thrust's sign turned it away from the point, and the
        # overshoot that followed wound the disturbance estimate up to its limit in calm water (a modes audit)
        moving = v_a if abs(v_a) >= LEAD_BY_MOTION_M_S else tau_com
        lead = 1.0 if moving >= 0.0 else -1.0
        psi_d = self._psi_ref + clamp(math.atan2(lead * e_l, cfg.lookahead_m), -limit, limit)
        return self._out(wrap_pi(psi_d), tau_com, 0.0, False, False, d)

    def _smoothed(self, north_m: float, east_m: float, sog_m_s: float, cog_rad: float, dt_s: float):
        """A complementary filter: the position moves with the velocity over ground and closes on the measured one
        with ``position_smoothing_s``; a fix's noise reached the thrust at once through the speed law (~50 N per
        metre: with 0.3 m of noise a fix, 60 N steps, ahead to astern, dozens of times a minute)."""
        tau = self.config.position_smoothing_s
        if tau <= 0.0 or self._position is None or not (math.isfinite(north_m) and math.isfinite(east_m)):
            self._position = (north_m, east_m)
            return north_m, east_m
        pn, pe = self._position
        if math.isfinite(sog_m_s) and math.isfinite(cog_rad):
            pn, pe = pn + sog_m_s * math.cos(cog_rad) * dt_s, pe + sog_m_s * math.sin(cog_rad) * dt_s
        k = min(1.0, dt_s / tau)
        self._position = (pn + k * (north_m - pn), pe + k * (east_m - pe))
        return self._position

    def _update_line_up(self, en: float, ee: float, d: float, psi_rad: float) -> None:
        """Lining up with the point: decided at the hold's first step, ends at half ``reposition_m``; the bow or
        the stern (astern when the point is more than 110 deg off the bow, with 20 deg of hysteresis: two
        thrusters astern push less), and the held heading is that line."""
        cfg = self.config
        line = math.atan2(ee, en)
        if not self._started:
            self._started = True
            off = abs(wrap_pi(line - psi_rad))
            self._lining_up = (self.heading_rad is None and cfg.reposition_m > 0.0 and d > cfg.reposition_m
                               and min(off, math.pi - off) > math.radians(cfg.reposition_off_deg))
        elif self._lining_up and d < 0.5 * cfg.reposition_m:
            self._lining_up = False
        if not self._lining_up:
            return
        off = abs(wrap_pi(line - psi_rad))
        self._astern = off > math.radians(_ASTERN_DEG - _ASTERN_BAND_DEG if self._astern else _ASTERN_DEG + _ASTERN_BAND_DEG)
        self._psi_ref = wrap_pi(line + math.pi) if self._astern else line

    def _update_reference(self, dt_s: float) -> None:
        """Least effort: the bow swings (rate-limited) towards the direction of the disturbance estimate,
        once there is one to face."""
        cfg = self.config
        if self.heading_rad is not None:
            self._psi_ref = self.heading_rad
            return
        dn, de = self._d_n
        if math.hypot(dn, de) < cfg.disturbance_min_n:
            return
        turn = wrap_pi(math.atan2(de, dn) - self._psi_ref)
        step = math.radians(cfg.heading_rate_deg_s) * dt_s
        self._psi_ref = wrap_pi(self._psi_ref + clamp(turn, -step, step))

    def _out(self, psi_d, tau_com, speed, approach, drifting, d) -> HoldOutput:
        dn, de = self._d_n
        along = dn * math.cos(self._psi_ref) + de * math.sin(self._psi_ref)
        return HoldOutput(psi_d_rad=psi_d, tau_com_n=tau_com, speed_cmd_m_s=speed, approach=approach,
                          drifting=drifting, error_m=d, psi_ref_rad=self._psi_ref, disturbance_n=along,
                          feasible_heading_rad=self._infeasible())

    def _infeasible(self) -> float | None:
        """With a given heading: the disturbance's own direction when it lies across that heading (the hull line,
        bow or stern) by more than ``max_correction_deg`` and pushes sideways with ``CROSS_MIN_X`` x
        ``disturbance_min_n`` or more; None otherwise (least effort always faces it)."""
        cfg = self.config
        if self.heading_rad is None:
            return None
        dn, de = self._d_n
        off = abs(wrap_pi(math.atan2(de, dn) - self.heading_rad))
        off = min(off, math.pi - off)
        cross = math.hypot(dn, de) * math.sin(off)
        if off <= math.radians(cfg.max_correction_deg) or cross < CROSS_MIN_X * cfg.disturbance_min_n:
            return None
        return math.atan2(de, dn)
