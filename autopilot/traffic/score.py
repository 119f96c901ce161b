"""Scoring an encounter, pure on trajectories (issue 18): distances kept, rules followed, what it cost the mission.

Inputs are time series sampled at the same times ``t_s`` (numpy arrays or
sequences): own ship's north/east (m), each target's north/east (m), and what
the avoidance logged each cycle (:meth:`autopilot.gnc.avoidance.AvoidanceOutput`):
per target its situation (``Situation.value``) and whether we acted for it,
and the avoidance's share of the desired course ``psi_d_share_rad``. Nothing
here runs a model or reads a clock, so the daemon's logs, ``autopilot evaluate
--traffic`` and the standalone :mod:`autopilot.traffic.sim` are scored alike.

Per target (:class:`TargetScore`):

- the closest approach (between samples the relative motion is taken as
  linear, so a fast pass between two samples is not missed) against the
  required distance (safe distance + the target's extent);
- the situation it was in (the first that was not "safe") and whether we
  acted, when, to which side, and by how much;
- whether the rule was followed: give way (14, 15/16) = any alteration made
  while acting for it is to starboard; stand on (17, 13 overtaken) = we did
  never altered to port while acting for it (17(c)); an alteration made for
  another target while standing on is noted, not failed;
  overtaking (13) = either side; safe = we never acted for it; and in every
  case the boats never came within a boat length (``CONTACT_M``, rule 8).

For the mission (:class:`MissionCost`, :func:`mission_cost`): arrival time,
distance run and thrust impulse (N s, as ``autopilot.review.metrics``'s
``thrust_energy_n_s``) of a run; :func:`score_encounter` with a ``reference``
(the same mission without traffic) gives the delay, extra distance and extra
impulse the encounter cost.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from autopilot.measured import HULL_LENGTH_M

# closer than the WAM-V's own length is contact or as near as makes no difference: it was scored "as the rules
# want" at 0.9 m (the other vessel overtaking, the boat set back into its track)
CONTACT_M = HULL_LENGTH_M

__all__ = ["CONTACT_M", "TargetScore", "MissionCost", "EncounterScore", "closest_approach", "mission_cost", "score_target",
           "score_encounter", "GIVE_WAY", "STAND_ON"]

GIVE_WAY = ("head-on", "crossing-give-way")
STAND_ON = ("crossing-stand-on", "overtaken")
_SIDE_TOL_RAD = math.radians(1.0)  # an alteration smaller than this is none


def closest_approach(t_s, own_north_m, own_east_m, tgt_north_m, tgt_east_m) -> tuple[float, float]:
    """(smallest distance m, its time s) between two sampled tracks, linear between samples."""
    t = np.asarray(t_s, dtype=float)
    dn = np.asarray(tgt_north_m, dtype=float) - np.asarray(own_north_m, dtype=float)
    de = np.asarray(tgt_east_m, dtype=float) - np.asarray(own_east_m, dtype=float)
    d = np.hypot(dn, de)
    k = int(np.argmin(d))
    best, t_best = float(d[k]), float(t[k])
    if len(t) > 1:
        # the minimum of |p0 + s (p1 - p0)| over s in [0, 1] in each interval
        pn, pe = dn[:-1], de[:-1]
        qn, qe = np.diff(dn), np.diff(de)
        q2 = qn * qn + qe * qe
        s = np.clip(-(pn * qn + pe * qe) / np.where(q2 > 0, q2, 1.0), 0.0, 1.0)
        di = np.hypot(pn + s * qn, pe + s * qe)
        j = int(np.argmin(di))
        if di[j] < best:
            best, t_best = float(di[j]), float(t[j] + s[j] * (t[j + 1] - t[j]))
    return best, t_best


@dataclass(frozen=True)
class TargetScore:
    target_id: int
    situation: str  # the first situation other than "safe" ("safe" if none)
    situations: tuple[str, ...]  # every situation it was in, in order of appearance
    min_distance_m: float
    t_min_s: float
    required_m: float
    distance_kept: bool
    acted: bool
    first_action_t_s: float | None
    side: str | None  # "starboard", "port" or None (no alteration while acting for it)
    max_alteration_deg: float  # largest |psi_d share| while acting for it
    rule_followed: bool
    note: str


def score_target(target_id: int, t_s, own_north_m, own_east_m, tgt_north_m, tgt_east_m, *, situation: Sequence[str],
                 acting: Sequence[bool], psi_share_rad, required_m: float) -> TargetScore:
    """One target's score (module docstring)."""
    d_min, t_min = closest_approach(t_s, own_north_m, own_east_m, tgt_north_m, tgt_east_m)
    t = np.asarray(t_s, dtype=float)
    share = np.asarray(psi_share_rad, dtype=float)
    act = np.asarray(acting, dtype=bool)
    seen: list[str] = []
    for s in situation:
        if s not in seen:
            seen.append(s)
    first = next((s for s in seen if s != "safe"), "safe")
    acted = bool(act.any())
    first_action = float(t[np.argmax(act)]) if acted else None
    during = share[act] if acted else np.zeros(0)
    big = during[np.abs(during) > _SIDE_TOL_RAD]
    side = None
    if big.size:
        side = "starboard" if big[0] > 0 else "port"
    max_alt = float(np.degrees(np.max(np.abs(during)))) if during.size else 0.0
    kept = d_min >= required_m
    sit_arr = np.asarray(list(situation))
    notes = []
    ok = True
    if d_min < CONTACT_M:  # whatever the situation was, or if it was never seen: rule 8 (avoid collision) failed
        ok = False
        notes.append(f"came within {d_min:.1f} m, under a boat length ({CONTACT_M:g} m): collision not avoided "
                     "(rules 8, 17(b))" + ("; never seen at risk" if first == "safe" else ""))
    if first in GIVE_WAY:
        if big.size and np.any(big < 0):
            ok = False
            notes.append(f"altered to port while giving way ({first}: rules 14-16 want starboard)")
        if not acted and not kept:
            ok = False
            notes.append("gave way too little: did not act and the distance was not kept")
    elif first in STAND_ON:
        stand = np.isin(sit_arr, STAND_ON)
        if np.any(stand & ~act & (np.abs(share) > _SIDE_TOL_RAD)):
            notes.append("course altered while standing on (for another target)")
        if big.size and np.any(big < 0):
            ok = False
            notes.append("altered to port for a vessel on our port side / overtaking us (rule 17(c))")
    elif first == "overtaking":
        pass
    else:  # safe throughout
        if acted:
            ok = False
            notes.append("acted for a target that was never at risk")
    if not notes:
        notes.append("as the rules want" if ok else "")
    return TargetScore(
        target_id=int(target_id), situation=first, situations=tuple(seen), min_distance_m=d_min, t_min_s=t_min,
        required_m=float(required_m), distance_kept=kept, acted=acted, first_action_t_s=first_action, side=side,
        max_alteration_deg=max_alt, rule_followed=ok, note="; ".join(notes),
    )


@dataclass(frozen=True)
class MissionCost:
    arrival_t_s: float | None  # first time within the capture radius of the goal (None: never)
    distance_m: float  # run until arrival (or the end)
    thrust_impulse_n_s: float | None  # integral of |T_port| + |T_stbd| until arrival (None: no thrust given)


def mission_cost(t_s, north_m, east_m, *, goal_north_m: float, goal_east_m: float, capture_radius_m: float,
                 thrust_port_n=None, thrust_stbd_n=None) -> MissionCost:
    t = np.asarray(t_s, dtype=float)
    n = np.asarray(north_m, dtype=float)
    e = np.asarray(east_m, dtype=float)
    inside = np.hypot(n - goal_north_m, e - goal_east_m) <= capture_radius_m
    end = int(np.argmax(inside)) if inside.any() else len(t) - 1
    arrival = float(t[end]) if inside.any() else None
    dist = float(np.sum(np.hypot(np.diff(n[: end + 1]), np.diff(e[: end + 1]))))
    impulse = None
    if thrust_port_n is not None and thrust_stbd_n is not None:
        tp = np.abs(np.asarray(thrust_port_n, dtype=float)) + np.abs(np.asarray(thrust_stbd_n, dtype=float))
        impulse = float(np.sum(0.5 * (tp[1 : end + 1] + tp[:end]) * np.diff(t[: end + 1])))
    return MissionCost(arrival_t_s=arrival, distance_m=dist, thrust_impulse_n_s=impulse)


@dataclass(frozen=True)
class EncounterScore:
    targets: tuple[TargetScore, ...]
    min_distance_m: float  # over all targets
    distance_kept: bool  # every target at or beyond its required distance
    rules_followed: bool
    cost: MissionCost | None
    delay_s: float | None  # arrival later than the reference run (None: no reference or no arrival)
    extra_distance_m: float | None
    extra_thrust_impulse_n_s: float | None

    def summary(self) -> dict:
        """A flat dict for a report or a JSON line."""
        return {
            "min_distance_m": round(self.min_distance_m, 2),
            "distance_kept": self.distance_kept,
            "rules_followed": self.rules_followed,
            "delay_s": None if self.delay_s is None else round(self.delay_s, 1),
            "extra_distance_m": None if self.extra_distance_m is None else round(self.extra_distance_m, 1),
            "targets": [
                {"id": s.target_id, "situation": s.situation, "min_distance_m": round(s.min_distance_m, 2),
                 "required_m": round(s.required_m, 2), "acted": s.acted, "side": s.side,
                 "max_alteration_deg": round(s.max_alteration_deg, 1), "rule_followed": s.rule_followed,
                 "note": s.note}
                for s in self.targets
            ],
        }


def score_encounter(t_s, own_north_m, own_east_m, targets: Mapping[int, tuple], *,
                    situation: Mapping[int, Sequence[str]], acting: Mapping[int, Sequence[bool]], psi_share_rad,
                    required_m: Mapping[int, float] | float, cost: MissionCost | None = None,
                    reference: MissionCost | None = None) -> EncounterScore:
    """Score every target (``targets[id] = (north_m array, east_m array)``) and the mission's cost."""
    scores = []
    for tid, (tn, te) in targets.items():
        req = required_m[tid] if isinstance(required_m, Mapping) else float(required_m)
        scores.append(score_target(tid, t_s, own_north_m, own_east_m, tn, te, situation=situation[tid],
                                   acting=acting[tid], psi_share_rad=psi_share_rad, required_m=req))
    delay = extra_d = extra_i = None
    if cost is not None and reference is not None:
        if cost.arrival_t_s is not None and reference.arrival_t_s is not None:
            delay = cost.arrival_t_s - reference.arrival_t_s
        extra_d = cost.distance_m - reference.distance_m
        if cost.thrust_impulse_n_s is not None and reference.thrust_impulse_n_s is not None:
            extra_i = cost.thrust_impulse_n_s - reference.thrust_impulse_n_s
    return EncounterScore(
        targets=tuple(scores),
        min_distance_m=min((s.min_distance_m for s in scores), default=math.inf),
        distance_kept=all(s.distance_kept for s in scores),
        rules_followed=all(s.rule_followed for s in scores),
        cost=cost, delay_s=delay, extra_distance_m=extra_d, extra_thrust_impulse_n_s=extra_i,
    )
