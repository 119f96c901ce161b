"""Fuzzy collision avoidance under COLREGs (issue 18): a course/speed change that composes with the mission.

Pure: own ship, targets and the mission's desired course and speed in, the
course and speed to steer out, with the reasons; the only state is small (the
situation records of :class:`~autopilot.gnc.encounter.EncounterTracker`, which
targets we are acting for, the alteration held and its side).

**Collision risk** (SAFES, Hasegawa et al. 1986; the same two inputs as the
thesis's waypoint guidance, Eq 6.5-6.8, with the target's CPA): a Mamdani
system (:mod:`autopilot.gnc.fuzzy`: triangular sets, min-max inference,
centre of gravity) of DCPA' = DCPA / L and TCPA' = TCPA / (L / U) gives the
risk CR in [0, 1]. Five evenly spaced sets on each input, {SA, SM, ME, ML,
LA} over [0, ``dcpa_max_nd``] and [0, ``tcpa_max_nd``] (shoulders at the
ends), and on the output over [0, 1]. THE rule table (rows DCPA', columns
TCPA'; entries CR):

=============  ====  ====  ====  ====  ====
DCPA' \\ TCPA'  SA    SM    ME    ML    LA
=============  ====  ====  ====  ====  ====
SA             LA    LA    ML    ME    SM
SM             LA    ML    ME    SM    SA
ME             ML    ME    SM    SA    SA
ML             ME    SM    SA    SA    SA
LA             SA    SA    SA    SA    SA
=============  ====  ====  ====  ====  ====

It reads as Table 6.1 does for CDH (near in both = large, far in either =
small), one step more cautious on the diagonal: a target on a collision
course (DCPA' SA) is already a medium risk at a medium TCPA'. A CPA in the
past (TCPA <= 0) is no risk.

**When to act** (per target, from its COLREGs situation,
:mod:`autopilot.gnc.encounter`):

- give way (head-on 14, crossing 15/16, overtaking 13): act once
  CR >= ``give_way_risk``, early (rule 16: "early and substantial action");
- stand on (crossing 17, being overtaken 13/17): keep course and speed while
  CR < ``stand_on_risk``; above it the give-way vessel has evidently not
  acted in time and we act (17(a)(ii), 17(b));
- close quarters, either way: a target that will pass inside the distance
  it needs (safe distance + extent) and is within ``close_quarters_factor``
  x that distance is acted for whatever its risk (17(b)): a vessel closing
  slowly has a long TCPA, so a low risk, until no alteration can open the
  distance (one overtaking at 1.2 m/s passed our 1 m/s boat 5.8 m off);
- safe: nothing. Once acting for a target we keep acting until its
  situation is safe again (past and clear, or the risk gone).

**What to do**: the smallest alteration a of the mission's course psi_d
(``0``, then ``min_alteration_deg`` .. ``max_alteration_deg`` in
``alteration_step_deg`` steps; rule 8(b): an alteration large enough to be
readily apparent, not a succession of small ones) such that, steering
psi_d + a at the commanded speed, every target passes at DCPA >= safe
distance + its extent (or its CPA is past or beyond the horizon):

- to starboard only, when any target we act for is head-on (14), crossing
  (15, and 17(c): not to port for a vessel on our port side), or overtaking
  us; either side when we are only overtaking (13), the side kept once chosen;
- in a crossing where we give way, only alterations with which we pass astern
  of the target (15: "avoid crossing ahead"), unless we would cross ahead by
  more than twice the required distance;
- hysteresis: an alteration smaller than the one held must clear every target
  by ``resume_margin`` x the safe distance;
- slowing to ``slow_factor`` x the commanded speed (rule 8(e): slacken speed)
  is a candidate too, costing as much as a ``slow_cost_deg`` alteration: the
  cheapest candidate that clears every target is taken (a turn of up to 60 deg
  before slowing, by default);
- none clears every target: the one that opens the smallest DCPA the most,
  slowed;
- inside the position limits: given ``allowed(north_m, east_m)`` (the
  daemon's geofence and distance limit), an alteration whose straight run
  until the targets' CPAs (at most ``limits_lookahead_s``) at its speed, and
  ``limits_margin_m`` beyond, leaves them is not a candidate. Leaving the
  geofence latches its failsafe (rtl by default) in the middle of the
  encounter, and a fence is drawn round water the boat must not enter. The
  mission's own course is the guidance's to keep inside. When no alteration
  to the side the rules allow clears every target inside the limits, the
  other side is searched (rule 2(b)), and a departure once taken is kept to
  until it ends.

**Resume**: when no target calls for action any more, the mission course is
taken back once it clears every target by ``resume_margin`` x the safe
distance (past and clear); until then the alteration is held.

Interface for the helm (:meth:`Avoidance.step`): the mission's psi_d and
speed go in, the output psi_d and speed come out, ``active`` says whether
they differ, and ``psi_d_share_rad`` is the avoidance's share of the course
(output - mission), so the log shows both the mission's wish and the
avoidance's correction. Per target: situation, rule, risk, acting and the
reason in words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

from autopilot.geo import wrap_pi
from autopilot.gnc.encounter import (
    Encounter,
    EncounterConfig,
    EncounterTracker,
    OwnShip,
    Situation,
    TargetState,
    cpa,
)
from autopilot.gnc.fuzzy import Mamdani, rule_indices, uniform_partition
from autopilot.measured import HULL_LENGTH_M
from autopilot.schema import param

__all__ = [
    "SETS",
    "RISK_RULE_TABLE",
    "AvoidanceConfig",
    "TargetAssessment",
    "AvoidanceOutput",
    "Avoidance",
    "collision_risk",
    "risk_engine",
]

SETS = ("SA", "SM", "ME", "ML", "LA")  # small, small-medium, medium, medium-large, large

# Collision risk CR: rows DCPA', columns TCPA'. THE rule table, nowhere else.
RISK_RULE_TABLE: tuple[tuple[str, ...], ...] = (
    # TCPA':  SA    SM    ME    ML    LA
    ("LA", "LA", "ML", "ME", "SM"),  # DCPA' SA
    ("LA", "ML", "ME", "SM", "SA"),  # DCPA' SM
    ("ML", "ME", "SM", "SA", "SA"),  # DCPA' ME
    ("ME", "SM", "SA", "SA", "SA"),  # DCPA' ML
    ("SA", "SA", "SA", "SA", "SA"),  # DCPA' LA
)


@dataclass(frozen=True)
class AvoidanceConfig:
    """Collision avoidance settings (YAML keys are the field names)."""

    safe_distance_m: float = param(
        4 * HULL_LENGTH_M, unit="m", lo=1.0, hi=5000.0, source="issue 18: 4 boat lengths (L = 3.96 m, thesis ch. 2)",
        doc="every target is to pass at least this far (plus its extent from the AIS dimensions)",
    )
    dcpa_max_nd: float = param(
        8.0, unit="-", lo=0.5, hi=500.0, source="chosen: twice the safe distance in boat lengths",
        doc="DCPA' universe [0, this] boat lengths, five evenly spaced sets; LA from here on",
    )
    tcpa_max_nd: float = param(
        40.0, unit="-", lo=1.0, hi=5000.0,
        source="chosen in simulation: 40 L/U = 160 s at 1 m/s, time to turn and open 4 L",
        doc="TCPA' universe [0, this] (own boat lengths run before the CPA); LA from here on",
    )
    give_way_risk: float = param(
        0.45, unit="-", lo=0.0, hi=1.0, source="chosen in simulation (rule 16: early action)",
        doc="a give-way vessel acts once the collision risk reaches this",
    )
    stand_on_risk: float = param(
        0.75, unit="-", lo=0.0, hi=1.0,
        source="chosen in simulation (rule 17(a)(ii), 17(b)): 0.85 let a vessel that does not give way overtake "
               "within 14.5 m of the calibrated model (autopilot evaluate --traffic)",
        doc="a stand-on vessel keeps course and speed below this risk and acts above it",
    )
    close_quarters_factor: float = param(
        2.0, unit="-", lo=1.0, hi=20.0,
        source="rule 17(a)(ii), 17(b); chosen in simulation: a vessel overtaking at 1.2 m/s (ours 1 m/s) passed "
               "5.8 m off, its risk under stand_on_risk until 8 m",
        doc="whatever the risk, we act for a target that will pass closer than the safe distance (plus its extent) "
            "once it is within this x that distance: a vessel closing slowly has a long TCPA, so a low risk, "
            "until it is too close for any alteration to open the safe distance",
    )
    min_alteration_deg: float = param(
        30.0, unit="deg", lo=0.0, hi=90.0, source="rule 8(b): large enough to be readily apparent",
        doc="an alteration of course is at least this",
    )
    max_alteration_deg: float = param(
        120.0, unit="deg", lo=10.0, hi=180.0, source="chosen: enough to pass astern of a crossing target",
        doc="largest alteration searched",
    )
    alteration_step_deg: float = param(5.0, unit="deg", lo=0.5, hi=30.0, source="search resolution",
                                       doc="step of the alterations searched")
    resume_margin: float = param(
        1.25, unit="-", lo=1.0, hi=5.0, source="hysteresis, chosen",
        doc="a smaller alteration, or the mission course, is taken only if it clears every target by this x safe distance",
    )
    slow_factor: float = param(
        0.5, unit="-", lo=0.0, hi=1.0, source="rule 8(e): slacken speed when a turn alone does not do",
        doc="speed factor when no alteration within the range clears every target",
    )
    slow_cost_deg: float = param(
        60.0, unit="deg", lo=0.0, hi=360.0, source="chosen in simulation: turn first (rule 8(b)), slow when a turn alone is large",
        doc="in the search, slowing to slow_factor costs as much as this alteration",
    )
    limits_lookahead_s: float = param(
        90.0, unit="s", lo=0.0, hi=600.0,
        source="chosen in simulation (the shipped scenarios with a fence 12-40 m to starboard): 30 s let the boat turn "
               "toward the fence and swing back as it neared it, a head-on vessel passing 19.5 m off (22.2 m needed)",
        doc="an alteration is a candidate only if a straight run on it until the targets' CPAs, at most this long, "
            "stays inside the position limits",
    )
    limits_margin_m: float = param(
        HULL_LENGTH_M, unit="m", lo=0.0, hi=1000.0, source="chosen: one boat length, room for the turn back",
        doc="and this far beyond that run",
    )
    horizon_s: float = param(
        300.0, unit="s", lo=10.0, hi=3600.0, source="chosen: beyond the encounter's risk_tcpa_s",
        doc="a candidate's CPA later than this is not checked",
    )
    defuzz_points: int = param(61, unit="-", lo=11, hi=2001, source="as FuzzyConfig (Eq 6.9)",
                               doc="samples of the risk universe for the centre of gravity")
    encounter: EncounterConfig = param(default_factory=EncounterConfig, doc="situation thresholds and hysteresis")


@lru_cache(maxsize=32)
def risk_engine(dcpa_max_nd: float, tcpa_max_nd: float, n_points: int = 61) -> Mamdani:
    """The Mamdani system of :data:`RISK_RULE_TABLE` (in1 = DCPA', rows; in2 = TCPA', columns).

    Output sets as the CDH engine's (:func:`autopilot.gnc.fuzzy_guidance.cdh_engine`): five
    triangles over [0, 1] with symmetric end sets, centre of gravity over [-0.25, 1.25], clipped."""
    n_points = 6 * -(-(n_points - 1) // 6) + 1
    return Mamdani(
        in1_sets=uniform_partition(0.0, dcpa_max_nd, len(SETS)),
        in2_sets=uniform_partition(0.0, tcpa_max_nd, len(SETS)),
        out_sets=uniform_partition(0.0, 1.0, len(SETS), extend=True),
        rules=rule_indices(RISK_RULE_TABLE, SETS),
        in1_range=(0.0, dcpa_max_nd),
        in2_range=(0.0, tcpa_max_nd),
        out_range=(-0.25, 1.25),
        n_points=n_points,
    )


def collision_risk(dcpa_nd, tcpa_nd, config: AvoidanceConfig = AvoidanceConfig()):
    """CR in [0, 1] for DCPA', TCPA' (scalars or arrays); 0 where TCPA' <= 0 (the CPA is past)."""
    import numpy as np

    engine = risk_engine(config.dcpa_max_nd, config.tcpa_max_nd, config.defuzz_points)
    tcpa = np.asarray(tcpa_nd, dtype=float)
    cr = np.clip(engine.evaluate(dcpa_nd, tcpa), 0.0, 1.0)
    out = np.where(tcpa > 0.0, cr, 0.0)
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True)
class TargetAssessment:
    """One target's part of an :class:`AvoidanceOutput` (what the log and the review show)."""

    target_id: int
    situation: Situation
    rule: str
    risk: float
    acting: bool
    reason: str
    range_m: float
    bearing_rad: float
    relative_bearing_rad: float
    bearing_rate_rad_s: float
    dcpa_m: float
    tcpa_s: float
    dcpa_nd: float
    tcpa_nd: float
    since_s: float
    name: str | None = None


@dataclass(frozen=True)
class AvoidanceOutput:
    """What to steer (``psi_d_rad``, ``speed_cmd_m_s``) and why.

    ``active``: the output differs from the mission's; ``psi_d_share_rad`` = wrap(output psi_d -
    mission psi_d), + = to starboard; ``speed_factor`` = output / mission speed; ``targets`` per
    target, most at risk first; ``reason`` one sentence for the log.
    """

    psi_d_rad: float
    speed_cmd_m_s: float
    active: bool
    psi_d_share_rad: float
    speed_factor: float
    targets: tuple[TargetAssessment, ...]
    reason: str

    @property
    def worst(self) -> TargetAssessment | None:
        return self.targets[0] if self.targets else None

    def log_fields(self) -> dict:
        """Flat, numeric-first fields for a per-cycle log line (degrees for people, as the log's other angles)."""
        w = self.worst
        return {
            "avoid_active": int(self.active),
            "avoid_psi_share_deg": round(math.degrees(self.psi_d_share_rad), 2),
            "avoid_speed_factor": round(self.speed_factor, 3),
            "avoid_targets": len(self.targets),
            "avoid_target": w.target_id if w else None,
            "avoid_situation": w.situation.value if w else Situation.SAFE.value,
            "avoid_risk": round(w.risk, 3) if w else 0.0,
            "avoid_range_m": round(w.range_m, 1) if w else None,
            "avoid_dcpa_m": round(w.dcpa_m, 1) if w else None,
            "avoid_tcpa_s": round(w.tcpa_s, 1) if w else None,
            "avoid_reason": self.reason,
        }


MAX_ASSESSED = 48  # safe targets assessed a cycle at most (the soonest able to come near): the loop's time


@dataclass(frozen=True)
class Occupied:
    """A waypoint inside a (nearly) stopped vessel's safe distance, with the boat as near as the rules allow."""

    target: TargetState
    need_m: float  # the safe distance plus the vessel's extent
    target_to_point_m: float
    reach_m: float  # the boat within this of the point has come as near as it may
    hold_ne_m: tuple[float, float]  # where a hold at the point is kept: the boat's side of the vessel, or the nearest bearing clear


HOLD_OFF_TURN_DEG = 15.0  # the hold off an occupied point looks round the vessel in these steps
# 0, +15, -15, +30, ... +180: nearest the boat's own bearing first (-180 is +180, so it is left out)
HOLD_OFF_TURNS_DEG = (0.0, *(sign * k * HOLD_OFF_TURN_DEG for k in range(1, 13) for sign in (1.0, -1.0)))[:-1]


DEPARTURE_HOLD_S = 10.0  # a departure's alteration (rule 2(b)) is held this long before a smaller one is taken
LIMITS_STEP_M = 5.0  # an alteration's run is checked against the position limits at points this far apart at most


def _fenced_words(fenced: list[float]) -> str:
    """What the log adds of the alterations left out for the position limits (nothing when none was)."""
    if not fenced:
        return ""
    least = min(fenced, key=abs)
    return (f"; {len({abs(a) for a in fenced})} alteration sizes leave the position limits, the smallest "
            f"{abs(math.degrees(least)):.0f} deg to {'starboard' if least > 0 else 'port'}")


@dataclass
class Avoidance:
    """COLREGs collision avoidance composed with the mission's course and speed (the module docstring)."""

    config: AvoidanceConfig = field(default_factory=AvoidanceConfig)

    def __post_init__(self) -> None:
        self.tracker = EncounterTracker(self.config.encounter)
        self.reset()

    def reset(self) -> None:
        self.tracker.reset()
        self._acting: set[int] = set()
        self._alteration_rad = 0.0  # signed, + = starboard
        self._side = 0  # +1 starboard, -1 port, 0 not chosen (overtaking only)
        self._slow = False
        self._departed = False  # the alteration held is to port because to starboard leaves the limits (rule 2(b))
        self._since_s = -math.inf  # when the alteration held was taken

    @property
    def active(self) -> bool:
        return self._alteration_rad != 0.0 or self._slow

    def relevant(self, own: OwnShip, intended: OwnShip, targets: list[TargetState]) -> list[TargetState]:
        """The targets worth assessing this cycle: every one the tracker holds in an encounter or the boat acts
        for; of the others (safe), those that could come within the safe distance inside the encounter
        horizon (exit_factor x risk_tcpa_s) at both vessels' speeds, whatever course either steers; and of
        those at most MAX_ASSESSED: first the ones whose closest approach, on the actual or the mission's
        motion, is within the horizon and the risk distance, then the soonest able to come near. A busy
        port's AIS (1500 vessels, most of them moored or kilometres away) once cost ~70 ms a cycle to assess
        in full, and the late cycles stopped the boat every few seconds (heading_stale, mbed_ack_missing)."""
        cfg = self.config
        enc = cfg.encounter
        horizon_s = enc.exit_factor * enc.risk_tcpa_s
        near_m = enc.exit_factor * enc.risk_dcpa_m
        own_speed = max(own.speed_m_s, intended.speed_m_s)
        motions = [(own.speed_m_s * math.cos(own.course_rad), own.speed_m_s * math.sin(own.course_rad)),
                   (intended.speed_m_s * math.cos(intended.course_rad), intended.speed_m_s * math.sin(intended.course_rad))]
        keep, candidates = [], []
        for tgt in targets:
            tid = tgt.target_id
            if tid in self._acting or self.tracker.situation_of(tid) is not Situation.SAFE:
                keep.append(tgt)
                continue
            dn, de = tgt.north_m - own.north_m, tgt.east_m - own.east_m
            soonest_s = max(math.hypot(dn, de) - cfg.safe_distance_m, 0.0) / (own_speed + max(tgt.speed_m_s, 0.0) + 1e-3)
            if soonest_s > horizon_s:
                continue
            vtn, vte = tgt.speed_m_s * math.cos(tgt.course_rad), tgt.speed_m_s * math.sin(tgt.course_rad)
            at_risk = math.hypot(dn, de) < enc.clear_range_m  # close quarters whatever the motion (encounter._risk)
            for von, voe in motions:
                dcpa_m, tcpa_s = cpa(dn, de, vtn - von, vte - voe)
                at_risk = at_risk or (0.0 < tcpa_s <= horizon_s and dcpa_m < near_m)
            candidates.append((not at_risk, soonest_s, tid, tgt))
        candidates.sort(key=lambda c: c[:3])
        return keep + [c[3] for c in candidates[: max(0, MAX_ASSESSED - len(keep))]]

    def need_m(self, tgt: TargetState) -> float:
        """The distance the rules keep from ``tgt``'s reported position: the safe distance plus its extent (m)."""
        return self.config.safe_distance_m + tgt.extent_m

    def clear_of(self, tgt: TargetState, point_ne_m) -> bool:
        """``point_ne_m`` lies beyond ``tgt``'s safe distance by ``resume_margin`` x (the hysteresis avoidance lets go
        with): a vessel reported so is off a waypoint it occupied. At the bare safe distance one AIS report 2 m
        off (its receiver's noise, the swing of its mooring) freed a waypoint still occupied (a review)."""
        return math.hypot(point_ne_m[0] - tgt.north_m, point_ne_m[1] - tgt.east_m) > (
            self.config.resume_margin * self.need_m(tgt))

    def occupying(self, own: OwnShip, point_ne_m, targets, allowed=None) -> Occupied | None:
        """The stopped vessel whose safe distance covers ``point_ne_m`` (a waypoint), when own ship is at that
        distance from it (within ``resume_margin`` x): the waypoint cannot be reached by the rules, and the boat
        is as near as it may come. A moored vessel on the mission's waypoint kept the boat circling it at 21-25 m
        for 27 minutes, until max_mission_time stopped it in open water (found by an AIS audit). ``allowed(north_m,
        east_m) -> bool``: where a hold may be kept (the daemon's geofence and distance limit), see ``_hold_off``."""
        cfg = self.config
        for tgt in targets:
            if tgt.speed_m_s >= cfg.encounter.stationary_speed_m_s:
                continue  # a moving vessel leaves the point
            need = self.need_m(tgt)
            to_point = math.hypot(point_ne_m[0] - tgt.north_m, point_ne_m[1] - tgt.east_m)
            from_own = math.hypot(own.north_m - tgt.north_m, own.east_m - tgt.east_m)
            if to_point < need and from_own <= cfg.resume_margin * need:
                return Occupied(tgt, need, to_point, cfg.resume_margin * need + to_point,
                                self._hold_off(own, tgt, need, from_own, point_ne_m, targets, allowed))
        return None

    def _hold_off(self, own: OwnShip, tgt: TargetState, need_m: float, from_own_m: float, point_ne_m, targets,
                  allowed=None):
        """Where a hold at an occupied point is kept: held inside the safe distance, every move toward the point set
        avoidance acting again, so where avoidance lets go (resume_margin x the safe distance from the vessel), on
        the boat's bearing from it, or the bearing nearest to that (``HOLD_OFF_TURN_DEG`` steps either way) whose
        spot is clear of every other vessel's safe distance (a review: next to a second moored vessel) and
        ``allowed`` (a hold off a vessel moored by the geofence's edge sat outside it: the fence's failsafe then
        took the boat). The point itself (avoidance then keeps the boat off, as before) when no bearing will do or
        the boat is on the vessel's own position."""
        at_point = (float(point_ne_m[0]), float(point_ne_m[1]))
        if from_own_m <= 1e-6:
            return at_point
        cfg = self.config
        radius_m = max(cfg.resume_margin * need_m, from_own_m)
        bearing = math.atan2(own.east_m - tgt.east_m, own.north_m - tgt.north_m)
        for turn_deg in HOLD_OFF_TURNS_DEG:
            b = bearing + math.radians(turn_deg)
            hold = (tgt.north_m + radius_m * math.cos(b), tgt.east_m + radius_m * math.sin(b))
            crowded = any(other is not tgt and math.hypot(hold[0] - other.north_m, hold[1] - other.east_m)
                          < cfg.resume_margin * (cfg.safe_distance_m + other.extent_m) for other in targets)
            if not crowded and (allowed is None or allowed(*hold)):
                return hold
        return at_point

    def step(self, own: OwnShip, targets: list[TargetState], psi_d_rad: float, speed_cmd_m_s: float,
             t_s: float, allowed=None) -> AvoidanceOutput:
        """One cycle: the course and speed to steer, given the mission's ``psi_d_rad`` and ``speed_cmd_m_s``.
        ``allowed(north_m, east_m) -> bool``: the position limits an alteration keeps inside (module docstring)."""
        cfg = self.config
        engine = risk_engine(cfg.dcpa_max_nd, cfg.tcpa_max_nd, cfg.defuzz_points)
        speed_m_s = speed_cmd_m_s if speed_cmd_m_s > 0.0 else own.speed_m_s
        if allowed is not None and not allowed(own.north_m, own.east_m):
            # outside already (a failsafe takes it back): a run from here starts outside, and every turn was refused
            # (a head-on vessel passed 1.0 m off on an rtl heading back in; a review)
            allowed = None

        def u_of(slow: bool) -> float:
            return speed_m_s * (cfg.slow_factor if slow else 1.0)

        intended = OwnShip(north_m=own.north_m, east_m=own.east_m, course_rad=psi_d_rad, speed_m_s=speed_m_s,
                           heading_rad=psi_d_rad)
        encounters = self.tracker.assess(own, self.relevant(own, intended, targets), t_s, intended=intended)
        assessed: list[tuple[Encounter, float, bool]] = []
        for e in encounters:
            g = e.geometry
            risk = engine.evaluate_scalar(g.dcpa_nd, g.tcpa_nd) if g.tcpa_s > 0.0 else 0.0
            risk = min(max(risk, 0.0), 1.0)
            tid = e.target_id
            if e.situation is Situation.SAFE:
                self._acting.discard(tid)
            elif tid not in self._acting:
                threshold = cfg.give_way_risk if e.situation.give_way else cfg.stand_on_risk
                if risk >= threshold or self._close_quarters(e):
                    self._acting.add(tid)
            assessed.append((e, risk, tid in self._acting))
        present = {e.target_id for e in encounters}
        self._acting &= present

        acting = [(e, r) for e, r, a in assessed if a]
        reason: str
        if acting:
            starboard_only = any(e.situation is not Situation.OVERTAKING for e, _ in acting)
            alteration, slow, why = self._search(own, encounters, psi_d_rad, u_of, starboard_only, allowed,
                                                 reduce=t_s - self._since_s >= DEPARTURE_HOLD_S or not self._departed)
            if (alteration, slow) != (self._alteration_rad, self._slow):
                self._since_s = t_s
            self._alteration_rad, self._slow = alteration, slow
            worst = max(acting, key=lambda er: er[1])[0]
            reason = f"{worst.situation.value} {worst.target_id} (rule {worst.situation.rule}): {why}"
        elif self.active:
            # nobody calls for action: take the mission back once it is clear of everyone
            clear = self._clears(own, encounters, psi_d_rad, u_of(False), margin=cfg.resume_margin, astern=False)
            # a held alteration's run is checked against the limits as a new one's is: held for a slow vessel the
            # mission course did not clear by the margin, a 30 deg turn ran the boat 20 m out through the fence
            leaving = (allowed is not None and self._alteration_rad != 0.0 and not self._stays_inside(
                own, encounters, psi_d_rad + self._alteration_rad, u_of(self._slow), allowed))
            if clear or leaving:
                self._alteration_rad, self._slow, self._side, self._departed = 0.0, False, 0, False
                reason = ("past and clear: back on the mission's course" if clear else
                          "no target calls for action and the alteration held would leave the position limits: "
                          "back on the mission's course")
            else:
                reason = (f"holding {math.degrees(self._alteration_rad):+.0f} deg until the mission course clears "
                          f"every target by {cfg.resume_margin:g} x {cfg.safe_distance_m:.0f} m")
        else:
            reason = "no action: " + ("no targets" if not encounters else "no target calls for it")
        psi_out = psi_d_rad if self._alteration_rad == 0.0 else wrap_pi(psi_d_rad + self._alteration_rad)
        factor = cfg.slow_factor if self._slow else 1.0
        rows = sorted(
            (self._row(e, r, a) for e, r, a in assessed), key=lambda row: (-row.risk, row.range_m)
        )
        return AvoidanceOutput(
            psi_d_rad=psi_out,
            speed_cmd_m_s=speed_cmd_m_s * factor,
            active=self.active,
            psi_d_share_rad=0.0 if psi_out == psi_d_rad else wrap_pi(psi_out - psi_d_rad),
            speed_factor=factor,
            targets=tuple(rows),
            reason=reason,
        )

    def _close_quarters(self, e: Encounter) -> bool:
        """The target will pass inside the distance it needs and is already within close_quarters_factor x it."""
        g, need = e.geometry, self.config.safe_distance_m + e.target.extent_m
        return g.tcpa_s > 0.0 and g.dcpa_m < need and g.range_m < self.config.close_quarters_factor * need

    # ------------------------------------------------------------------ the search
    def _clearance(self, own: OwnShip, e: Encounter, course_rad: float, speed_m_s: float,
                   astern: bool) -> float:
        """DCPA / required distance with own ship on ``course_rad`` (inf: CPA past or beyond the horizon).
        With ``astern`` (crossing, give way), crossing ahead of the target counts as 0."""
        tgt = e.target
        dn, de = tgt.north_m - own.north_m, tgt.east_m - own.east_m
        vn = tgt.speed_m_s * math.cos(tgt.course_rad) - speed_m_s * math.cos(course_rad)
        ve = tgt.speed_m_s * math.sin(tgt.course_rad) - speed_m_s * math.sin(course_rad)
        dcpa_m, tcpa_s = cpa(dn, de, vn, ve)
        if tcpa_s <= 0.0 or tcpa_s > self.config.horizon_s:
            return math.inf
        need = self.config.safe_distance_m + tgt.extent_m
        if astern and e.situation is Situation.CROSSING_GIVE_WAY and tgt.speed_m_s > 0.0:
            # at the CPA, is own ship behind the target (along its course)? p_c . u_T > 0 means the
            # target is ahead of us along its own track: we pass astern of it
            pcn, pce = dn + vn * tcpa_s, de + ve * tcpa_s
            along = pcn * math.cos(tgt.course_rad) + pce * math.sin(tgt.course_rad)
            if along < 0.0 and dcpa_m < 2.0 * need:
                return 0.0  # crossing ahead of it, and not by a wide margin
        return dcpa_m / need

    def _clears(self, own, encounters, course_rad, speed_m_s, *, margin: float, astern: bool) -> bool:
        return all(self._clearance(own, e, course_rad, speed_m_s, astern) >= margin for e in encounters)

    def _stays_inside(self, own: OwnShip, encounters: list[Encounter], course_rad: float, speed_m_s: float,
                      allowed) -> bool:
        """A straight run on ``course_rad`` until the last of the targets' CPAs on it (the alteration is held that
        long), at most limits_lookahead_s, and limits_margin_m beyond, is inside ``allowed`` (checked every
        LIMITS_STEP_M at most)."""
        run_s = 0.0
        for e in encounters:
            tgt = e.target
            tcpa_s = cpa(tgt.north_m - own.north_m, tgt.east_m - own.east_m,
                         tgt.speed_m_s * math.cos(tgt.course_rad) - speed_m_s * math.cos(course_rad),
                         tgt.speed_m_s * math.sin(tgt.course_rad) - speed_m_s * math.sin(course_rad))[1]
            run_s = max(run_s, min(tcpa_s, self.config.limits_lookahead_s))
        reach_m = speed_m_s * run_s + self.config.limits_margin_m
        n = max(1, math.ceil(reach_m / LIMITS_STEP_M))
        c, s = math.cos(course_rad), math.sin(course_rad)
        return all(allowed(own.north_m + reach_m * k / n * c, own.east_m + reach_m * k / n * s) for k in range(1, n + 1))

    def _search(self, own: OwnShip, encounters: list[Encounter], psi_d_rad: float, u_of,
                starboard_only: bool, allowed=None, reduce: bool = True) -> tuple[float, bool, str]:
        """The cheapest (alteration, slow) that clears every target: cost = |alteration| in degrees, plus
        ``slow_cost_deg`` when slowing to ``slow_factor``; ties to the smaller alteration. ``u_of(slow)``: the
        speed a candidate is judged at.

        With ``allowed``, an alteration that leaves the position limits is no candidate (the mission course, slowed
        or not, always is). When every clearing one to the side the rules allow (or the side kept) leaves them, the
        other side is searched too (rule 2(b): a departure the limits of navigation make necessary; a head-on vessel
        2 m to starboard with the fence 12 m to starboard was otherwise passed 0.8 m off, slowed). A departure once
        taken is searched first until it ends: swinging back to starboard across the target's track when the
        departure's side stopped clearing passed a vessel overtaking us 3.3 m off; and its alteration is not made
        smaller (``reduce`` False) until held DEPARTURE_HOLD_S: a departure's large turns, each cutting the speed the
        guidance gives (its turn slow-down is on the mission's course), changed every candidate's clearance, and the
        alteration flicked between -30 and -70 deg every few seconds (108 changes in a minute; a review). Only a departure is: a port turn
        taken to overtake was kept as one for a head-on vessel met after it, and said to be rule 2(b) (a review)."""
        cfg = self.config
        if starboard_only:
            primary = (1,)
        elif self._side:
            primary = (self._side,)
        else:
            primary = (1, -1)
        if starboard_only and self._departed and self._alteration_rad < 0.0 and allowed is not None:
            primary = (-1,)  # a departure under way is kept to
        fenced: list[float] = []  # the alterations (signed) left out because they leave the limits
        departed = starboard_only and primary == (-1,)
        found, best = self._first_clearing(own, encounters, psi_d_rad, u_of, primary, allowed, fenced, reduce)
        if found is None and fenced and len(primary) == 1:
            found = self._first_clearing(own, encounters, psi_d_rad, u_of, (-primary[0],), allowed, fenced, reduce)[0]
            departed = starboard_only and found is not None and found[0] < 0.0
        departure = " (rule 2(b): to starboard leaves the position limits)"
        if found is not None:
            alt, slow = found
            self._departed = departed and alt < 0.0
            if alt != 0.0 and not starboard_only:
                self._side = 1 if alt > 0 else -1
            if alt == 0.0 and not slow:
                return 0.0, False, "the mission course already clears every target"
            what = []
            if alt != 0.0:
                what.append(f"alter {math.degrees(alt):+.0f} deg to {'starboard' if alt > 0 else 'port'}"
                            + (departure if self._departed else ""))
            if slow:
                what.append(f"slow to {cfg.slow_factor:g} x speed (rule 8(e))")
            return alt, slow, (" and ".join(what) + f": every target passes >= {cfg.safe_distance_m:.0f} m"
                               + _fenced_words(fenced))
        self._departed = departed and best[1] < 0.0
        if not starboard_only and best[1] != 0.0:
            self._side = 1 if best[1] > 0 else -1
        return best[1], True, (f"nothing up to {cfg.max_alteration_deg:.0f} deg clears every target: "
                               f"{math.degrees(best[1]):+.0f} deg{departure if self._departed else ''}"
                               f" (clearance x{best[0]:.2f}) and slow to {cfg.slow_factor:g} x speed (rule 8(e))"
                               + _fenced_words(fenced))

    def _first_clearing(self, own, encounters, psi_d_rad, u_of, sides, allowed, fenced, reduce=True):
        """Over the candidates to ``sides`` (and none), cheapest first: the first (signed alteration, slow) that clears
        every target, or None; and the best clearance seen, (worst clearance, signed alteration, slow). The alterations
        that leave ``allowed`` are appended to ``fenced``."""
        cfg = self.config
        step = math.radians(cfg.alteration_step_deg)
        a_min, a_max = math.radians(cfg.min_alteration_deg), math.radians(cfg.max_alteration_deg)
        sizes = [0.0]
        a = max(a_min, step)
        while a <= a_max + 1e-9:
            sizes.append(a)
            a += step
        slow_cost = math.radians(cfg.slow_cost_deg)
        candidates = sorted(
            ((size + (slow_cost if slow else 0.0), size, side, slow)
             for size in sizes for side in (sides if size > 0.0 else (1,)) for slow in (False, True)
             if not (slow and cfg.slow_factor >= 1.0)),
            key=lambda c: (c[0], c[1]),
        )
        held = abs(self._alteration_rad) + (slow_cost if self._slow else 0.0)
        best: tuple[float, float, bool] | None = None
        for cost, size, side, slow in candidates:
            alt = side * size
            u = u_of(slow)
            if cost < held - 1e-9 and not reduce:
                continue
            margin = cfg.resume_margin if cost < held - 1e-9 else 1.0
            worst = min((self._clearance(own, e, psi_d_rad + alt, u, True) for e in encounters), default=math.inf)
            if worst < margin and best is not None and worst <= best[0] + 1e-9:
                continue  # neither taken nor the best so far: its run need not be checked (a fence's vertices cost)
            if size > 0.0 and allowed is not None and not self._stays_inside(own, encounters, psi_d_rad + alt, u, allowed):
                fenced.append(alt)
                continue
            if worst >= margin:
                return (alt, slow), best
            best = (worst, alt, slow)
        if best is None:
            # not reducing, and every alteration as large as the one held leaves the limits (a narrow channel): the
            # smaller ones after all; the search raised in the control loop here (a departure of 75 deg held; found
            # rereading the change)
            return self._first_clearing(own, encounters, psi_d_rad, u_of, sides, allowed, fenced)
        return None, best

    def _row(self, e: Encounter, risk: float, acting: bool) -> TargetAssessment:
        g = e.geometry
        if acting and e.situation.stand_on:
            reason = e.reason + f"; risk {risk:.2f} >= {self.config.stand_on_risk:g}: the give-way vessel is not acting, we act (17(a)(ii))"
        elif acting:
            reason = e.reason + f"; risk {risk:.2f}: acting"
        elif e.situation.stand_on:
            reason = e.reason + f"; risk {risk:.2f}: keep course and speed"
        else:
            reason = e.reason + (f"; risk {risk:.2f}" if e.situation is not Situation.SAFE else "")
        return TargetAssessment(
            target_id=e.target_id, situation=e.situation, rule=e.situation.rule, risk=risk, acting=acting,
            reason=reason, range_m=g.range_m, bearing_rad=g.bearing_rad, relative_bearing_rad=g.relative_bearing_rad,
            bearing_rate_rad_s=g.bearing_rate_rad_s, dcpa_m=g.dcpa_m, tcpa_s=g.tcpa_s, dcpa_nd=g.dcpa_nd,
            tcpa_nd=g.tcpa_nd, since_s=e.since_s, name=e.target.name,
        )
