"""Navigation assembly: the compass's latest sample -> what the guidance steers by, every cycle.

Pure: a :class:`~autopilot.devices.NavSample` (SI, stamped on the caller's clock), the
time now and the small :class:`NavMemory` of the previous cycle in; a :class:`Navigation`
out. The daemon, ``autopilot evaluate`` and the campaigns call the same function, so a
simulated run sees the sensor's 1 Hz fixes and fallbacks exactly as the boat does:

- heading: the compass's while fresh (``heading_stale_s``) and valid; else, when
  ``cog_fallback`` allows and the boat moves at least ``cog_fallback_min_sog_m_s``, the
  course over ground (source ``COG``); else the stale or invalid heading, for the
  failsafe to judge;
- yaw rate: ROT while fresh, valid and plausible, else the heading differenced over the cycle;
- a frozen compass: while the compass heading stays within ``HEADING_STILL_RAD`` of where it
  was, the turn the ROT reports (rates below ``ROT_NOISE_RAD_S`` left out) is summed
  (``Navigation.still_turn_rad``); the failsafe calls a sum of ``heading_frozen_deg`` a frozen
  heading. A stuck SC-30 (checksum-valid sentences repeating one heading) once spun the boat
  at 50 deg/s for 30 s with nothing in the log: the PID chased a heading that never moved.
  The sum restarts only when the heading moves, so a frozen compass keeps its fault. Since when the
  heading has stood still is kept too (``Navigation.heading_still_since_s``): a compass whose rate of
  turn froze as well reports no turn, and the failsafe judges instead how long the helm steered meanwhile;
- speed and course over ground: while valid, fresh (``position_stale_s``) and plausible;
- position: the last fix in the local frame of the mission's origin (a jump refused, below), and that fix
  carried forward by the velocity over ground over its age (at most
  ``dead_reckon_max_s``: the SC-30 gives position at 1 Hz on a 4800-baud line, SPEC 10;
  held, it lags the boat by up to a second, 1.5 m at cruise); a fix that first appears
  this cycle is flagged ``new_fix`` (a held fix is not a new measurement).

"Plausible": a checksum-valid sentence can still carry a value no WAM-V reaches (a glitch,
another talker on the line). One RMC at 999 kn carried the steered position 570 m away and
one ROT at 9999 deg/min saturated the heading PID; such values are not used (``max_sog_m_s``,
``max_yaw_rate_rad_s``): the fix is not carried forward, the differenced heading gives the rate.

A position jump (multipath, a receiver glitch) is refused as ArduPilot's EKF refuses a GPS
glitch (``EK3_GLITCH_RAD``): a new fix farther from the last one used than ``position_jump_m``
plus a speed bound times the time between them is not used (the bound: the receiver's speed over ground
plus ``jump_speed_margin_m_s``, :func:`jump_speed_bound_m_s`), and the last fix goes on ageing
(``position_stale`` fires if no good fix follows). One far fix once latched the geofence or the
distance limit and ended the mission. A second new fix that agrees with the refused one (within
the same gate of it) is believed: the boat or the receiver really moved, and the position is
re-anchored there, about a second later. Each refusal and each re-anchoring is reported in
``Navigation.jump`` for the log. A chain of fixes (from the first, or from one re-anchored to: a
glitch can last several epochs) is steered by but not ``fix_confirmed`` until its fixes have passed
the gate from one another for ``fix_confirm_s``: the failsafe latches no geofence or distance limit
on it, and control does not start on it (the launch point is set there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.devices import NavSample, Stamped, age_s
from autopilot.geo import latlon_to_local, wrap_pi
from autopilot.logschema import COG_HEADING_SOURCE

__all__ = ["NavRules", "NavMemory", "Navigation", "PositionJump", "Gated", "assemble", "gate_fix", "dead_reckon_ne",
           "velocity_over_ground", "still_turn",
           "MIN_SOG_FOR_COG_M_S", "HEADING_STILL_RAD", "ROT_NOISE_RAD_S"]

MIN_SOG_FOR_COG_M_S = 0.3  # below this the GNSS course is noise: carry along the heading instead
HEADING_STILL_RAD = math.radians(0.5)  # 5 x the 0.1 deg an HDT carries: a heading that moves less is still
ROT_NOISE_RAD_S = math.radians(2.0)  # a rate of turn below this is not counted as turning (bias, noise at rest)


@dataclass(frozen=True)
class NavRules:
    """The assembly's thresholds (the daemon builds them from its configuration: failsafe.* and dead_reckon_max_s)."""

    heading_stale_s: float = 1.0
    position_stale_s: float = 3.0
    cog_fallback: bool = False
    cog_fallback_min_sog_m_s: float = 0.5
    dead_reckon_max_s: float = 1.5
    max_sog_m_s: float = 10.0  # a WAM-V does ~2.5 m/s: above this, no speed over ground is believed
    # full opposite thrust spins it at ~1.6 rad/s (the model's extrapolation); above 2 rad/s the differenced
    # heading stands in, which serves as well if a real spin is faster
    max_yaw_rate_rad_s: float = 2.0
    position_jump_m: float = 25.0  # ArduPilot's EK3_GLITCH_RAD default; plus a speed bound per second between fixes
    # the speed bound of the gate: the receiver's own speed over ground plus this (its noise, a second's
    # acceleration, the epoch between them); max_sog_m_s when it reports none
    jump_speed_margin_m_s: float = 2.0
    # a chain of fixes (the first, or one re-anchored to) is confirmed once its fixes have passed the gate from
    # one another for this long: the two-fix rule alone believed a glitch lasting three epochs (ArduPilot's EKF
    # wants 10 s of passing GPS checks before it aligns)
    fix_confirm_s: float = 5.0


@dataclass(frozen=True)
class NavMemory:
    """What the assembly keeps from one cycle to the next."""

    heading_t_s: float | None = None  # when the heading last used was taken
    heading_rad: float | None = None
    fix_t_s: float | None = None  # receive time of the last fix seen
    fix: Stamped | None = None  # the last valid fix used (a refused jump leaves it in place)
    jump: Stamped | None = None  # a refused fix waiting to be confirmed by the next one
    judged_t_s: float | None = None  # receive time of the last valid fix the gate judged
    confirmed: bool = False  # ``fix`` agrees with a fix before it (see Navigation.fix_confirmed)
    anchored_t_s: float | None = None  # receive time of the first fix of ``fix``'s chain (NavRules.fix_confirm_s)
    still_heading_rad: float | None = None  # the compass heading the still_turn_rad sum started at
    still_turn_rad: float = 0.0  # the turn ROT reported since (Navigation.still_turn_rad)
    still_t_s: float | None = None  # the time of the compass heading sample last judged
    still_since_s: float | None = None  # the time of the compass heading sample the sum is anchored at


@dataclass(frozen=True)
class PositionJump:
    """A new fix too far from the last one used: refused, or (confirmed by the next fix) re-anchored to."""

    lat_deg: float
    lon_deg: float
    distance_m: float  # from the last fix used
    gate_m: float  # what it may be: position_jump_m + jump_speed_bound_m_s x the time between the two
    accepted: bool  # False: refused, the last fix is kept; True: the position re-anchored here
    repeated: bool = False  # refused while another refused fix was waiting (far fixes that do not agree)

    def log_fields(self) -> dict:
        """The ``position_jump`` line's fields (autopilot.logschema)."""
        return {"lat_deg": self.lat_deg, "lon_deg": self.lon_deg, "distance_m": self.distance_m,
                "gate_m": self.gate_m, "accepted": self.accepted, "repeated": self.repeated}


@dataclass(frozen=True)
class Navigation:
    """One cycle's navigation: SI, local frame, ages in seconds at ``t_s``."""

    t_s: float
    heading_rad: float | None
    heading_source: str | None
    heading_age_s: float
    heading_valid: bool
    yaw_rate_rad_s: float | None
    lat_deg: float | None
    lon_deg: float | None
    north_m: float | None  # the last fix
    east_m: float | None
    est_north_m: float | None  # the fix carried forward (what the guidance steers by)
    est_east_m: float | None
    position_age_s: float
    fix_quality: int  # 0 when the fix is invalid or absent
    fix_t_s: float | None  # receive time of that fix
    new_fix: bool  # the fix first appears this cycle
    sog_m_s: float | None
    cog_rad: float | None
    jump: PositionJump | None = None  # a fix refused or re-anchored to this cycle
    # the fix used passed the gate from the fix before it: not the first fix, nor one just re-anchored to
    # (two fixes agreeing may still be a glitch that lasted two epochs); what may latch a position limit
    fix_confirmed: bool = True
    # the turn (rad, signed) the rate of turn reported while the compass heading stayed still (a frozen compass)
    still_turn_rad: float = 0.0
    # since when (the sample's time, s) the compass heading has stayed within HEADING_STILL_RAD; None: no compass
    # heading yet. The failsafe counts how long the helm steered while it did (a compass whose ROT froze too)
    heading_still_since_s: float | None = None

    @property
    def steerable(self) -> bool:
        """A heading and a position to steer by (the failsafe decides whether they are good enough)."""
        return self.heading_rad is not None and self.est_north_m is not None


def _value(s):
    return None if s is None else s.value


def velocity_over_ground(sample: NavSample, now_s: float, rules: NavRules) -> tuple[float | None, float | None]:
    """(sog_m_s, cog_rad) to use: each valid and at most ``position_stale_s`` old, the speed plausible; the
    course only with the speed."""
    sog, cog = sample.sog_m_s, sample.cog_rad
    if (sog is None or sog.value is None or not sog.valid or age_s(sog, now_s) > rules.position_stale_s
            or not 0.0 <= float(sog.value) <= rules.max_sog_m_s):
        return None, None
    if cog is None or cog.value is None or not cog.valid or age_s(cog, now_s) > rules.position_stale_s:
        return float(sog.value), None
    return float(sog.value), float(cog.value)


def choose_heading(sample: NavSample, now_s: float, rules: NavRules):
    """(heading_rad, source, age_s, valid); see the module docstring."""
    h = sample.heading_rad
    age = age_s(h, now_s)
    if h is not None and age <= rules.heading_stale_s and h.valid:
        return float(h.value), h.source, age, True
    if rules.cog_fallback:
        sog, cog = velocity_over_ground(sample, now_s, rules)
        if cog is not None and sog >= rules.cog_fallback_min_sog_m_s:
            return cog, COG_HEADING_SOURCE, age_s(sample.cog_rad, now_s), True
    if h is None or h.value is None:
        return None, None if h is None else h.source, age, False
    return float(h.value), h.source, age, bool(h.valid)


def _rot(sample: NavSample, now_s: float, rules: NavRules) -> float | None:
    """The compass's rate of turn (rad/s) while fresh, valid and plausible, else None."""
    rot = sample.yaw_rate_rad_s
    if (rot is not None and rot.valid and rot.value is not None and age_s(rot, now_s) <= rules.heading_stale_s
            and abs(float(rot.value)) <= rules.max_yaw_rate_rad_s):
        return float(rot.value)
    return None


def still_turn(heading_rad: float | None, heading_t_s: float | None, rot_rad_s: float | None,
               memory: NavMemory) -> tuple[float | None, float | None, float]:
    """(the heading the sum is anchored at, the time of the heading sample last judged, the turn ROT reported
    since the heading was last seen to move); see the module docstring. Only a new compass heading sample is
    judged (one held while the sentences stop is no evidence: heading_stale judges that), over the time since
    the sample before it, at the rate of turn beside it; without a ROT nothing is added."""
    anchor, judged_t_s, turned = memory.still_heading_rad, memory.still_t_s, memory.still_turn_rad
    if heading_rad is None or heading_t_s is None or heading_t_s == judged_t_s:
        return anchor, judged_t_s, turned
    dt_s = 0.0 if judged_t_s is None else min(max(heading_t_s - judged_t_s, 0.0), 1.0)
    if anchor is None or abs(wrap_pi(heading_rad - anchor)) > HEADING_STILL_RAD:
        return heading_rad, heading_t_s, 0.0  # it moved: start again from here
    if rot_rad_s is not None and abs(rot_rad_s) >= ROT_NOISE_RAD_S:
        turned += rot_rad_s * dt_s
    return anchor, heading_t_s, turned


def _yaw_rate(sample: NavSample, now_s: float, heading_rad, memory: NavMemory, rules: NavRules) -> float | None:
    rot = _rot(sample, now_s, rules)
    if rot is not None:
        return rot
    if heading_rad is not None and memory.heading_rad is not None and now_s > memory.heading_t_s:
        return wrap_pi(heading_rad - memory.heading_rad) / (now_s - memory.heading_t_s)
    return None


def dead_reckon_ne(
    north_m: float,
    east_m: float,
    age_s: float,
    sog_m_s: float | None,
    cog_rad: float | None,
    heading_rad: float | None,
    *,
    max_age_s: float,
) -> tuple[float, float]:
    """The fix (north_m, east_m) carried forward ``min(age_s, max_age_s)`` seconds at the velocity over ground.

    The direction is the course over ground when the speed is at least
    MIN_SOG_FOR_COG_M_S (a crabbing boat moves along its course, not its bow),
    else the heading. Without a speed, or with ``max_age_s`` = 0, the fix is returned.
    """
    if sog_m_s is None or not math.isfinite(sog_m_s) or max_age_s <= 0 or not (age_s > 0):
        return north_m, east_m
    direction = cog_rad if (cog_rad is not None and sog_m_s >= MIN_SOG_FOR_COG_M_S) else heading_rad
    if direction is None or not math.isfinite(direction):
        return north_m, east_m
    travel_m = sog_m_s * min(age_s, max_age_s)
    return north_m + travel_m * math.cos(direction), east_m + travel_m * math.sin(direction)


def _apart_m(a: Stamped, b: Stamped) -> float:
    """Distance (m) between two fixes."""
    north, east = latlon_to_local(*a.value, *b.value)
    return math.hypot(north, east)


@dataclass(frozen=True)
class Gated:
    """What :func:`gate_fix` decides: the fix to use this cycle, and the memory it leaves."""

    used: Stamped | None  # the fix to use (the sample's, or the last one kept)
    fix: Stamped | None  # NavMemory.fix
    pending: Stamped | None  # NavMemory.jump
    judged_t_s: float | None  # NavMemory.judged_t_s
    confirmed: bool  # NavMemory.confirmed
    anchored_t_s: float | None  # NavMemory.anchored_t_s
    jump: PositionJump | None = None  # to report this cycle

    @property
    def used_confirmed(self) -> bool:
        return self.confirmed and self.used == self.fix  # equal, not the same object: a sample is rebuilt


def jump_speed_bound_m_s(sog_m_s: float | None, rules: NavRules) -> float:
    """How fast (m/s) the gate lets a fix have moved from the last: the speed over ground the receiver reports
    (Doppler, independent of the position solution) plus ``jump_speed_margin_m_s``, never above
    ``max_sog_m_s``; ``max_sog_m_s`` without one. With 10 m/s whatever the speed, a 30-m glitch at rest passed
    as a move (25 m + 10 m/s x 1 s): the first fix of a run, it became the launch point, 30 m from the boat."""
    if sog_m_s is None:
        return rules.max_sog_m_s
    return min(rules.max_sog_m_s, sog_m_s + rules.jump_speed_margin_m_s)


def gate_fix(pos: Stamped | None, memory: NavMemory, rules: NavRules, sog_m_s: float | None = None) -> Gated:
    """Judge the sample's fix once (see the module docstring). An invalid fix is used as it is (the failsafe
    judges it: no_fix) and leaves the gate's memory as it was. ``sog_m_s``: the receiver's speed over ground
    now (:func:`velocity_over_ground`; None: none to trust), which bounds how far the boat can have gone."""
    last, pending, judged, confirmed = memory.fix, memory.jump, memory.judged_t_s, memory.confirmed
    anchored = memory.anchored_t_s
    if pos is None or pos.value is None or not pos.valid:
        return Gated(pos, last, pending, judged, confirmed, anchored)
    if pos.t_s == judged:  # the fix already judged: the judgement stands
        refused = pending is not None and pending.t_s == pos.t_s
        return Gated(last if refused else pos, last, pending, judged, confirmed, anchored)
    if last is None or anchored is None:  # the first fix: nothing to judge it by yet
        return Gated(pos, pos, None, pos.t_s, False, pos.t_s)
    speed_m_s = jump_speed_bound_m_s(sog_m_s, rules)
    gate_m = rules.position_jump_m + speed_m_s * max(pos.t_s - last.t_s, 0.0)
    distance_m = _apart_m(pos, last)
    lat, lon = pos.value
    if pending is not None:
        agree_m = rules.position_jump_m + speed_m_s * max(pos.t_s - pending.t_s, 0.0)
        # two fixes agree: the position really moved (or a long glitch). Judged before the gate: the gate grows
        # with the time since the last fix used, and a glitch's second fix 2.5 s on passed it as a confirmed
        # move (a bench receiver at 1.27 s a fix): the launch point 30 m off
        if _apart_m(pos, pending) <= agree_m and _apart_m(pending, last) > agree_m:
            return Gated(pos, pos, None, pos.t_s, False, pos.t_s,
                         PositionJump(float(lat), float(lon), distance_m, gate_m, accepted=True))
    if distance_m <= gate_m:
        # a chain is fixes that agree one after another: after a gap longer than position_stale_s it starts
        # anew (a glitch before four lost epochs and again after them was confirmed at once, the gate grown)
        anchored = pos.t_s if pos.t_s - last.t_s > rules.position_stale_s else anchored
        return Gated(pos, pos, None, pos.t_s, pos.t_s - anchored >= rules.fix_confirm_s, anchored)
    return Gated(last, last, pos, pos.t_s, confirmed, anchored,
                 PositionJump(float(lat), float(lon), distance_m, gate_m, accepted=False, repeated=pending is not None))


def assemble(sample: NavSample, now_s: float, memory: NavMemory, rules: NavRules, *,
             origin_lat_deg: float, origin_lon_deg: float) -> tuple[Navigation, NavMemory]:
    """This cycle's :class:`Navigation` and the memory for the next one."""
    heading_rad, source, heading_age, heading_valid = choose_heading(sample, now_s, rules)
    yaw_rate = _yaw_rate(sample, now_s, heading_rad, memory, rules)
    h = sample.heading_rad
    compass = h is not None and h.valid and h.value is not None and age_s(h, now_s) <= rules.heading_stale_s
    still_anchor, still_t, still_turned = still_turn(float(h.value) if compass else None, h.t_s if compass else None,
                                                     _rot(sample, now_s, rules), memory)
    still_since = still_t if still_anchor != memory.still_heading_rad else memory.still_since_s
    seen = sample.position
    sog, cog = velocity_over_ground(sample, now_s, rules)
    gated = gate_fix(seen, memory, rules, sog)
    pos = gated.used
    latlon = _value(pos)
    lat = lon = north = east = est_n = est_e = None
    position_age = age_s(pos, now_s)
    if latlon is not None:
        lat, lon = latlon
        north, east = latlon_to_local(lat, lon, origin_lat_deg, origin_lon_deg)
        est_n, est_e = dead_reckon_ne(north, east, position_age, sog, cog, heading_rad, max_age_s=rules.dead_reckon_max_s)
    fq = _value(sample.fix_quality)
    fix_quality = int(fq) if fq is not None else 0
    if pos is not None and not pos.valid:
        fix_quality = 0
    seen_t = None if seen is None else seen.t_s
    nav = Navigation(
        t_s=now_s, heading_rad=heading_rad, heading_source=source, heading_age_s=heading_age,
        heading_valid=heading_valid, yaw_rate_rad_s=yaw_rate, lat_deg=lat, lon_deg=lon, north_m=north, east_m=east,
        est_north_m=est_n, est_east_m=est_e, position_age_s=position_age, fix_quality=fix_quality,
        fix_t_s=None if pos is None else pos.t_s,
        new_fix=latlon is not None and pos is seen and seen_t != memory.fix_t_s, sog_m_s=sog, cog_rad=cog,
        jump=gated.jump, fix_confirmed=bool(pos is not None and pos.valid and gated.used_confirmed),
        still_turn_rad=still_turned, heading_still_since_s=still_since,
    )
    if heading_rad is not None:
        heading_t, heading = now_s, heading_rad
    else:
        heading_t, heading = memory.heading_t_s, memory.heading_rad
    return nav, NavMemory(heading_t_s=heading_t, heading_rad=heading, fix_t_s=seen_t, fix=gated.fix,
                          jump=gated.pending, judged_t_s=gated.judged_t_s, confirmed=gated.confirmed,
                          anchored_t_s=gated.anchored_t_s,
                          still_heading_rad=still_anchor, still_turn_rad=still_turned, still_t_s=still_t,
                          still_since_s=still_since)
