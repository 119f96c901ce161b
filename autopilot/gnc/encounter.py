"""Encounter assessment (issue 18): where each target is relative to own ship, and which COLREGs rule applies.

Pure: states in (local north-east frame, SI, as :mod:`autopilot.geo`), numbers
out; the only state is one small record per target in :class:`EncounterTracker`.

Geometry (per target, own ship O, target T; p = T - O, v = v_T - v_O, velocities
over ground from course and speed):

    range     = |p|,  bearing theta = atan2(p_E, p_N) (true, from own ship)
    relative bearing beta = wrap(theta - psi_O)          (+ = on our starboard side)
    aspect    alpha_T = wrap(theta + pi - psi_T)        (where we are, seen from the target's bow)
    bearing rate      = (p_N v_E - p_E v_N) / |p|^2     (0 = constant bearing: rule 7(d)(i))
    TCPA      = -(p . v) / |v|^2,  DCPA = |p + v TCPA|  (TCPA = 0, DCPA = range without relative motion)
    DCPA'     = DCPA / L                                 (thesis Eq 6.7)
    TCPA'     = TCPA / (L / U)                           (thesis Eq 6.8; U = own speed, floored)

The thesis defines DCPA' and TCPA' for a waypoint (Eq 6.5-6.8), a point at
rest: there the relative speed is the own speed U. For a moving target the
CPA comes from the relative motion, and TCPA' keeps the thesis's scale: the
time to CPA in units of the time own ship takes to run one boat length, i.e.
how many of its own lengths it can still run before the CPA (Hasegawa's
SAFES reasons about nearness relative to the own ship's size and speed). U
is floored at ``tcpa_speed_floor_m_s`` so that a boat at rest does not see
every target at TCPA' = 0.

Situations (COLREGs Part B section II, the own ship a power-driven vessel):

=====================  ======  ======================================================================
situation              rule    geometry (first match, in this order)
=====================  ======  ======================================================================
overtaking             13      we come up on the target from more than 22.5 deg abaft its beam:
                               ``|alpha_T| > 112.5 deg`` (its sternlight sector, rules 13(b), 21(c)),
                               target forward of our beams; also a target (nearly) stopped
                               (``< stationary_speed_m_s``: keep clear either side, rules 13, 2)
overtaken              13, 17  the target comes up from more than 22.5 deg abaft our beam:
                               ``|beta| > 112.5 deg``; it keeps out of the way, we stand on
head-on                14      target ahead ``|beta| <= head_on_bearing_deg`` on a reciprocal course,
                               ``|wrap(chi_T - chi_O - pi)| <= head_on_course_deg`` (masthead lights
                               in line, rule 14(b)); both alter to starboard
crossing, give way     15, 16  any other target on our starboard side, ``0 <= beta <= 112.5 deg``:
                               keep out of the way, avoid crossing ahead (15), early and
                               substantial action (16)
crossing, stand on     17      any other target on our port side, ``-112.5 <= beta < 0 deg``: keep
                               course and speed; act when the give-way vessel does not (17(a)(ii),
                               17(b)), never to port for a vessel on our port side (17(c))
safe                   --      no risk of collision: DCPA >= ``risk_dcpa_m`` or TCPA outside
                               (0, ``risk_tcpa_s``], or past (TCPA <= 0) and opening beyond
                               ``clear_range_m``
=====================  ======  ======================================================================

Thresholds and their sources: 112.5 deg = 22.5 deg abaft the beam, the
sidelight / sternlight boundary (rules 13(b), 21(b), 21(c)); head-on within
6 deg of reciprocal courses and of dead ahead (rule 14(b): "masthead lights
in a line or nearly in a line"; 6 deg is the usual reading of "nearly", and
MOOS-IvP's BHV_AvdColregs uses a few degrees likewise); on a dead-ahead
crossing (beta = 0) we give way (rule 14(c): in doubt, assume the duty).

Hysteresis, so a situation does not flicker with AIS noise (MOOS-IvP's
BHV_AvdColregs names its mode and keeps it):

- an encounter begins when risk exists (DCPA < ``risk_dcpa_m`` and
  0 < TCPA <= ``risk_tcpa_s``; or the target is inside ``clear_range_m`` with
  its CPA past or no relative motion: close quarters, where rule 7(a) deems
  risk to exist, as ArduPilot's AP_Avoidance counts the present distance as
  a closest approach) and ends only when the range is at least
  ``clear_range_m`` and the risk has clearly gone: TCPA <= 0 (past and
  clear), DCPA >= ``exit_factor`` x ``risk_dcpa_m`` or TCPA > ``exit_factor``
  x ``risk_tcpa_s``, judged both on own ship's actual motion and on the
  mission's intended course and speed (so avoiding does not itself end the
  encounter: it ends when the mission can be resumed);
- overtaking and being overtaken are kept until past and clear whatever the
  bearing does (rule 13(d): a later change of bearing does not make the
  overtaking vessel a crossing one);
- any other situation is judged afresh only when the target has altered its
  course by more than ``reclassify_course_deg`` since it was judged (our own
  avoiding turn and the closing geometry move the bearing, not the duty; a
  target that turns into us does change it), and then with the current
  situation's region widened by ``sector_margin_deg`` on every boundary and
  the others narrowed by as much.

Every :class:`Encounter` carries ``reason``, a sentence with the numbers that
decided it, for the log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING

from autopilot.geo import latlon_to_local, wrap_pi
from autopilot.measured import HULL_LENGTH_M
from autopilot.schema import param

if TYPE_CHECKING:  # the record it is read from; gnc/ imports no driver at run time
    from autopilot.drivers.ais import AisTarget

__all__ = [
    "OwnShip",
    "TargetState",
    "Geometry",
    "Situation",
    "Encounter",
    "EncounterConfig",
    "EncounterTracker",
    "geometry",
    "cpa",
    "classify",
    "STERN_SECTOR_DEG",
]

STERN_SECTOR_DEG = 112.5  # 22.5 deg abaft the beam: sidelight / sternlight boundary (rules 13(b), 21)


@dataclass(frozen=True)
class OwnShip:
    """Own ship in the local frame: position (m), course and speed over ground, heading (rad, from north)."""

    north_m: float
    east_m: float
    course_rad: float
    speed_m_s: float
    heading_rad: float


@dataclass(frozen=True)
class TargetState:
    """A target in the local frame, SI. ``heading_rad`` None: use the course. ``extent_m``: the farthest
    hull point from the reported position (AIS dimensions), which a safe distance between reference
    points must add. ``age_s``: how old the report behind it is (after any extrapolation)."""

    target_id: int
    north_m: float
    east_m: float
    course_rad: float
    speed_m_s: float
    heading_rad: float | None = None
    extent_m: float = 0.0
    length_m: float | None = None
    name: str | None = None
    age_s: float = 0.0
    motion_known: bool = True

    @classmethod
    def from_ais(cls, target: AisTarget, *, origin_lat_deg: float, origin_lon_deg: float, now_s: float,
                 max_extrapolation_s: float = 180.0) -> TargetState:
        """From an :class:`autopilot.drivers.ais.AisTarget` (with a position): to the local frame, dead
        reckoned along its course for its age (at most ``max_extrapolation_s``, default the longest
        nominal report interval, 3 min: ITU-R M.1371-5 Annex 1 Tables 1-2). A course "not available"
        with a speed: its heading is its course; a speed or course not available otherwise: its track
        between its last two reports (``track_ne_m_s``); only without either, treated as stopped where it
        was reported (``motion_known`` False). A vessel at 3.9 kn reporting course 360 (many class B
        transponders do) was taken as stopped: judged overtaking, avoided to port, passed at 0.6 m."""
        north_m, east_m = latlon_to_local(target.lat_deg, target.lon_deg, origin_lat_deg, origin_lon_deg)
        sog, cog, heading = target.sog_m_s, target.cog_rad, target.heading_rad
        track = target.track_ne_m_s
        known = True
        if sog is not None and cog is not None:
            speed, course = sog, cog
        elif sog is not None and heading is not None:
            speed, course = sog, heading
        elif track is not None:
            speed, course = math.hypot(*track), math.atan2(track[1], track[0])
        elif sog == 0.0:
            speed, course = 0.0, heading or 0.0
        else:
            known, speed, course = False, 0.0, cog if cog is not None else (heading or 0.0)
        age = target.age_s(now_s)
        dt = min(max(age, 0.0), max_extrapolation_s)
        north_m += speed * math.cos(course) * dt
        east_m += speed * math.sin(course) * dt
        return cls(target_id=target.mmsi, north_m=north_m, east_m=east_m, course_rad=course, speed_m_s=speed,
                   heading_rad=target.heading_rad, extent_m=target.extent_m, length_m=target.length_m,
                   name=target.shipname, age_s=age, motion_known=known)


@dataclass(frozen=True)
class Geometry:
    """One target relative to own ship, now (SI; angles in rad, bearings true unless 'relative')."""

    range_m: float
    bearing_rad: float  # true bearing of the target from own ship, (-pi, pi]
    relative_bearing_rad: float  # from own heading, + = starboard
    aspect_rad: float  # bearing of own ship from the target's bow, + = its starboard
    course_difference_rad: float  # wrap(target course - own course)
    bearing_rate_rad_s: float  # + = bearing drawing right (clockwise)
    range_rate_m_s: float  # - = closing
    dcpa_m: float
    tcpa_s: float  # < 0: the CPA is past
    dcpa_nd: float  # DCPA' (Eq 6.7)
    tcpa_nd: float  # TCPA' (Eq 6.8)
    relative_speed_m_s: float
    target_speed_m_s: float
    own_speed_m_s: float


def _velocity(course_rad: float, speed_m_s: float) -> tuple[float, float]:
    return speed_m_s * math.cos(course_rad), speed_m_s * math.sin(course_rad)


def cpa(dn_m: float, de_m: float, vn_m_s: float, ve_m_s: float) -> tuple[float, float]:
    """(DCPA m, TCPA s) of a relative position (target - own) and relative velocity (target - own).

    Without relative motion the distance never changes: TCPA 0, DCPA the range."""
    v2 = vn_m_s * vn_m_s + ve_m_s * ve_m_s
    if v2 < 1e-12:
        return math.hypot(dn_m, de_m), 0.0
    tcpa_s = -(dn_m * vn_m_s + de_m * ve_m_s) / v2
    return math.hypot(dn_m + vn_m_s * tcpa_s, de_m + ve_m_s * tcpa_s), tcpa_s


def geometry(own: OwnShip, target: TargetState, *, length_m: float = HULL_LENGTH_M,
             tcpa_speed_floor_m_s: float = 0.5) -> Geometry:
    """The relative geometry of one target (see the module docstring for the equations)."""
    dn, de = target.north_m - own.north_m, target.east_m - own.east_m
    von, voe = _velocity(own.course_rad, own.speed_m_s)
    vtn, vte = _velocity(target.course_rad, target.speed_m_s)
    vn, ve = vtn - von, vte - voe
    r = math.hypot(dn, de)
    theta = math.atan2(de, dn) if r > 0.0 else own.heading_rad
    psi_t = target.heading_rad if target.heading_rad is not None else target.course_rad
    dcpa_m, tcpa_s = cpa(dn, de, vn, ve)
    u = max(own.speed_m_s, tcpa_speed_floor_m_s)
    return Geometry(
        range_m=r,
        bearing_rad=wrap_pi(theta),
        relative_bearing_rad=wrap_pi(theta - own.heading_rad),
        aspect_rad=wrap_pi(theta + math.pi - psi_t),
        course_difference_rad=wrap_pi(target.course_rad - own.course_rad),
        bearing_rate_rad_s=(dn * ve - de * vn) / (r * r) if r > 0.0 else 0.0,
        range_rate_m_s=(dn * vn + de * ve) / r if r > 0.0 else 0.0,
        dcpa_m=dcpa_m,
        tcpa_s=tcpa_s,
        dcpa_nd=dcpa_m / length_m,  # Eq 6.7
        tcpa_nd=tcpa_s / (length_m / u),  # Eq 6.8
        relative_speed_m_s=math.hypot(vn, ve),
        target_speed_m_s=target.speed_m_s,
        own_speed_m_s=own.speed_m_s,
    )


class Situation(str, Enum):
    """The COLREGs situation of one target (the value is what the log writes)."""

    SAFE = "safe"
    HEAD_ON = "head-on"
    CROSSING_GIVE_WAY = "crossing-give-way"
    CROSSING_STAND_ON = "crossing-stand-on"
    OVERTAKING = "overtaking"
    OVERTAKEN = "overtaken"

    @property
    def rule(self) -> str:
        return _RULES[self]

    @property
    def give_way(self) -> bool:
        """Own ship must keep out of the way (rules 13, 14, 15, 16)."""
        return self in (Situation.HEAD_ON, Situation.CROSSING_GIVE_WAY, Situation.OVERTAKING)

    @property
    def stand_on(self) -> bool:
        """Own ship keeps course and speed, and acts only when the other does not (rule 17)."""
        return self in (Situation.CROSSING_STAND_ON, Situation.OVERTAKEN)

    @property
    def code(self) -> int:
        """A small integer for numeric logs (0 = safe)."""
        return list(Situation).index(self)


_RULES = {
    Situation.SAFE: "",
    Situation.HEAD_ON: "14",
    Situation.CROSSING_GIVE_WAY: "15/16",
    Situation.CROSSING_STAND_ON: "17",
    Situation.OVERTAKING: "13",
    Situation.OVERTAKEN: "13/17",
}


@dataclass(frozen=True)
class EncounterConfig:
    """Thresholds of the encounter assessment (YAML keys are the field names)."""

    length_m: float = param(HULL_LENGTH_M, unit="m", lo=0.5, hi=500.0, source="thesis ch. 2 (SPEC 1)",
                            doc="own hull length L of DCPA' = DCPA / L and TCPA' = TCPA / (L / U) (Eq 6.7, 6.8)")
    tcpa_speed_floor_m_s: float = param(
        0.5, unit="m/s", lo=0.05, hi=5.0, source="guard: Eq 6.8's U -> 0 would put every target at TCPA' = 0",
        doc="U of TCPA' = TCPA U / L is at least this",
    )
    risk_dcpa_m: float = param(
        8 * HULL_LENGTH_M, unit="m", lo=1.0, hi=10000.0, source="twice the avoidance's default safe distance (4 L)",
        doc="an encounter begins when the DCPA is below this (and the TCPA within the horizon)",
    )
    risk_tcpa_s: float = param(
        180.0, unit="s", lo=5.0, hi=3600.0, source="chosen: 3 min, the longest AIS report interval of a moving ship",
        doc="... and 0 < TCPA <= this",
    )
    exit_factor: float = param(
        1.25, unit="-", lo=1.0, hi=5.0, source="hysteresis, chosen",
        doc="an encounter ends when DCPA >= this x risk_dcpa_m or TCPA > this x risk_tcpa_s (or past and clear)",
    )
    clear_range_m: float = param(
        4 * HULL_LENGTH_M, unit="m", lo=0.0, hi=10000.0, source="the avoidance's default safe distance (4 L)",
        doc="'past and clear': TCPA <= 0 (opening) and the range at least this",
    )
    head_on_bearing_deg: float = param(
        6.0, unit="deg", lo=0.0, hi=45.0, source="rule 14(b): ahead or nearly ahead, lights nearly in line",
        doc="head-on only when the target bears within this of dead ahead",
    )
    head_on_course_deg: float = param(
        6.0, unit="deg", lo=0.0, hi=45.0, source="rule 14(a)(b): reciprocal or nearly reciprocal courses",
        doc="... and its course is within this of the reciprocal of ours",
    )
    stern_sector_deg: float = param(
        STERN_SECTOR_DEG, unit="deg", lo=90.0, hi=180.0, source="rules 13(b), 21(b)(c): 22.5 deg abaft the beam",
        doc="relative bearing beyond which a vessel is 'abaft the beam' (overtaking geometry)",
    )
    sector_margin_deg: float = param(
        5.0, unit="deg", lo=0.0, hi=30.0, source="hysteresis, chosen (AIS course noise of a few degrees)",
        doc="the current situation's region is widened by this on every boundary",
    )
    reclassify_course_deg: float = param(
        15.0, unit="deg", lo=0.0, hi=180.0,
        source="chosen: well above AIS course noise; our own manoeuvres and the closing geometry move the "
        "bearing but do not change the duty",
        doc="a situation is judged afresh only after the target's course has changed by more than this "
        "since it was judged",
    )
    stationary_speed_m_s: float = param(
        0.25, unit="m/s", lo=0.0, hi=2.0, source="chosen: below AIS's 0.1 kn resolution x 5",
        doc="a target slower than this has no meaningful course: it is passed as an overtaking vessel would",
    )
    forget_after_s: float = param(
        60.0, unit="s", lo=0.0, hi=3600.0, source="bookkeeping",
        doc="a target absent from the input this long loses its situation record",
    )


def _region(sit: Situation, g: Geometry, cfg: EncounterConfig, widen_rad: float) -> bool:
    """Is the geometry in the situation's region (every boundary moved outwards by ``widen_rad``)?"""
    stern = math.radians(cfg.stern_sector_deg)
    beta, aspect = g.relative_bearing_rad, g.aspect_rad
    if sit is Situation.OVERTAKING:
        if g.target_speed_m_s < cfg.stationary_speed_m_s:
            return True  # closing on a stopped vessel, from any side
        return abs(aspect) > stern - widen_rad and abs(beta) < stern + widen_rad
    if sit is Situation.OVERTAKEN:
        return abs(beta) > stern - widen_rad and g.target_speed_m_s >= cfg.stationary_speed_m_s
    if sit is Situation.HEAD_ON:
        reciprocal = abs(wrap_pi(g.course_difference_rad - math.pi))
        return (abs(beta) <= math.radians(cfg.head_on_bearing_deg) + widen_rad
                and reciprocal <= math.radians(cfg.head_on_course_deg) + widen_rad)
    if sit is Situation.CROSSING_GIVE_WAY:
        return -widen_rad <= beta <= stern + widen_rad
    if sit is Situation.CROSSING_STAND_ON:
        return -stern - widen_rad <= beta < widen_rad
    return False


_ORDER = (Situation.OVERTAKING, Situation.OVERTAKEN, Situation.HEAD_ON, Situation.CROSSING_GIVE_WAY,
          Situation.CROSSING_STAND_ON)


def _deg(x_rad: float) -> float:
    return math.degrees(x_rad)


def _why(sit: Situation, g: Geometry, cfg: EncounterConfig) -> str:
    b = _deg(g.relative_bearing_rad)
    side = "starboard" if b >= 0 else "port"
    if sit is Situation.OVERTAKING:
        if g.target_speed_m_s < cfg.stationary_speed_m_s:
            return f"target (nearly) stopped ({g.target_speed_m_s:.2f} m/s) {abs(b):.0f} deg to {side}: keep clear (rules 13, 2)"
        return f"we come up {abs(_deg(g.aspect_rad)):.0f} deg from its bow, abaft its beam: we overtake, keep clear (rule 13)"
    if sit is Situation.OVERTAKEN:
        return f"target {abs(b):.0f} deg on our {side} quarter, coming up: it overtakes, we stand on (rules 13, 17)"
    if sit is Situation.HEAD_ON:
        return (f"target {b:+.1f} deg ahead on a reciprocal course "
                f"({_deg(abs(wrap_pi(g.course_difference_rad - math.pi))):.1f} deg off): head-on, alter to starboard (rule 14)")
    if sit is Situation.CROSSING_GIVE_WAY:
        return f"target {b:.0f} deg on our starboard side, crossing: we give way, pass astern (rules 15, 16)"
    return f"target {-b:.0f} deg on our port side, crossing: we stand on (rule 17)"


def classify(g: Geometry, config: EncounterConfig = EncounterConfig(), *,
             current: Situation | None = None) -> tuple[Situation, str]:
    """The situation the geometry puts the target in (regardless of risk) and why: the first match
    in the table's order.

    With ``current`` (not SAFE) the current situation's region is widened by
    ``sector_margin_deg`` on every boundary and every other region narrowed by as much, so a
    change needs the geometry to be clearly in the new region (the bias falls away where it
    would leave a gap between regions)."""
    if current is not None and current is not Situation.SAFE:
        m = math.radians(config.sector_margin_deg)
        for sit in _ORDER:
            if _region(sit, g, config, m if sit is current else -m):
                return sit, _why(sit, g, config)
    for sit in _ORDER:
        if _region(sit, g, config, 0.0):
            return sit, _why(sit, g, config)
    raise AssertionError("the regions cover every geometry")  # pragma: no cover


@dataclass(frozen=True)
class Encounter:
    """One target's assessment at one time: geometry, situation (with hysteresis) and why."""

    target: TargetState
    geometry: Geometry
    situation: Situation
    reason: str
    since_s: float  # when this situation began
    changed: bool  # the situation changed at this step
    risk_exists: bool  # the crisp rule-7 test of this step (before hysteresis)

    @property
    def target_id(self) -> int:
        return self.target.target_id


@dataclass
class _Record:
    situation: Situation = Situation.SAFE
    since_s: float = 0.0
    seen_s: float = 0.0
    reason: str = ""
    judged_course_rad: float = 0.0  # the target's course when the situation was last judged


@dataclass
class EncounterTracker:
    """The situation of every target, with hysteresis (the module docstring); pure apart from its records."""

    config: EncounterConfig = field(default_factory=EncounterConfig)
    _records: dict[int, _Record] = field(default_factory=dict)

    def reset(self) -> None:
        self._records.clear()

    def situation_of(self, target_id: int) -> Situation:
        rec = self._records.get(target_id)
        return Situation.SAFE if rec is None else rec.situation

    def assess(self, own: OwnShip, targets: list[TargetState], t_s: float, *,
               intended: OwnShip | None = None) -> list[Encounter]:
        """Every target's encounter now. ``intended``: own ship as the mission would have it (same
        position, the mission's course and speed); with it, risk is judged on both the actual and the
        intended motion, so an encounter does not end merely because we are avoiding: it ends when
        neither motion is at risk (and the range is at least ``clear_range_m``)."""
        cfg = self.config
        out = []
        for tgt in targets:
            g = geometry(own, tgt, length_m=cfg.length_m, tcpa_speed_floor_m_s=cfg.tcpa_speed_floor_m_s)
            gi = g if intended is None else geometry(intended, tgt, length_m=cfg.length_m,
                                                     tcpa_speed_floor_m_s=cfg.tcpa_speed_floor_m_s)
            rec = self._records.setdefault(tgt.target_id, _Record(since_s=t_s))
            rec.seen_s = t_s
            risk = self._risk(g) or self._risk(gi)
            old = rec.situation
            if old is Situation.SAFE:
                if risk:
                    new, why = classify(g, cfg)
                else:
                    new, why = Situation.SAFE, self._safe_reason(gi)
            else:
                ended = g.range_m >= cfg.clear_range_m and self._no_risk(g) and self._no_risk(gi)
                if ended and g.tcpa_s <= 0.0 and gi.tcpa_s <= 0.0:
                    new, why = Situation.SAFE, f"past and clear: opening, range {g.range_m:.0f} m"
                elif ended:
                    new, why = Situation.SAFE, f"risk gone: DCPA {gi.dcpa_m:.0f} m on the intended course"
                elif old in (Situation.OVERTAKING, Situation.OVERTAKEN):
                    new, why = old, _why(old, g, cfg) + "; kept until past and clear (rule 13(d))"
                elif abs(turned := wrap_pi(tgt.course_rad - rec.judged_course_rad)) > math.radians(
                        cfg.reclassify_course_deg):
                    new, why = classify(g, cfg, current=old)  # the target has turned: judge afresh
                    rec.judged_course_rad = tgt.course_rad
                    if new is not old:
                        why += f" (it altered course {math.degrees(turned):+.0f} deg)"
                else:
                    new, why = old, rec.reason
            changed = new is not old
            if changed:
                rec.situation, rec.since_s = new, t_s
                rec.judged_course_rad = tgt.course_rad
            rec.reason = why
            out.append(Encounter(target=tgt, geometry=g, situation=new, reason=why, since_s=rec.since_s,
                                 changed=changed, risk_exists=risk))
        for tid in [k for k, r in self._records.items() if t_s - r.seen_s > cfg.forget_after_s]:
            del self._records[tid]
        return out

    def _risk(self, g: Geometry) -> bool:
        """Rule 7's test, crisp: the CPA is ahead, within the horizon, and close; or the target is already
        inside the safe distance (a boat alongside at 2 m, on our course and speed, was 'CPA past')."""
        c = self.config
        return (g.dcpa_m < c.risk_dcpa_m and 0.0 < g.tcpa_s <= c.risk_tcpa_s) or \
            (g.tcpa_s <= 0.0 and g.range_m < c.clear_range_m)

    def _no_risk(self, g: Geometry) -> bool:
        """... and clearly not (the exit side of the hysteresis)."""
        c = self.config
        return g.tcpa_s <= 0.0 or g.dcpa_m >= c.exit_factor * c.risk_dcpa_m or g.tcpa_s > c.exit_factor * c.risk_tcpa_s

    def _safe_reason(self, g: Geometry) -> str:
        if g.tcpa_s <= 0.0:
            return f"no risk: CPA past, range {g.range_m:.0f} m opening"
        if g.tcpa_s > self.config.risk_tcpa_s:
            return f"no risk yet: TCPA {g.tcpa_s:.0f} s beyond {self.config.risk_tcpa_s:.0f} s"
        return f"no risk: DCPA {g.dcpa_m:.0f} m >= {self.config.risk_dcpa_m:.0f} m"
