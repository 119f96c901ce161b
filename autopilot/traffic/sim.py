"""A small closed-loop encounter simulation: a kinematic own ship, simulated traffic, the avoidance in between.

Own ship (deliberately simple; the real model and GNC are ``autopilot evaluate --traffic``'s):

    dpsi/dt = clip(wrap(psi_c - psi) / T_psi, -r_max, r_max)    (first-order heading response)
    dU/dt   = (U_c - U) / T_U                                    (first-order speed response)
    dN/dt   = U cos psi,  dE/dt = U sin psi                      (no current: course = heading)

steered each ``dt_s`` by pure pursuit to the scenario's goal (psi_d = bearing
of the goal, speed = the scenario's speed) composed with
:meth:`autopilot.gnc.avoidance.Avoidance.step` (psi_c, U_c = its output). The
targets move by :class:`autopilot.simdev.traffic.TrafficSim` (``gives_way``
ones react to own ship). With ``via_ais`` the avoidance sees the targets only
through their AIS sentences (encoded by pyais at the scenario's report rates,
decoded by :mod:`autopilot.drivers.ais`, dead reckoned for their age), as on
the boat; otherwise it sees the truth.

:func:`simulate` returns the sampled run (:class:`EncounterRun`);
:func:`score_run` scores it with :func:`autopilot.traffic.score.score_encounter`
against the same mission without traffic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.drivers.ais import AisReceiver
from autopilot.geo import wrap_pi
from autopilot.gnc.avoidance import Avoidance, AvoidanceConfig
from autopilot.gnc.encounter import OwnShip, TargetState
from autopilot.schema import param
from autopilot.simdev.traffic import TrafficScenario, TrafficSim, sentences_between
from autopilot.traffic.score import EncounterScore, mission_cost, score_encounter

__all__ = ["KinematicBoatConfig", "EncounterRun", "simulate", "score_run"]


@dataclass(frozen=True)
class KinematicBoatConfig:
    heading_time_constant_s: float = param(2.0, unit="s", lo=0.1, hi=60.0, source="chosen, of the order of the "
                                           "calibrated model's yaw response", doc="T_psi")
    max_turn_rate_rad_s: float = param(0.5, unit="rad/s", lo=0.01, hi=3.0,
                                       source="Fig 8.2: the measured turns reach 0.34-0.63 rad/s", doc="r_max")
    speed_time_constant_s: float = param(3.0, unit="s", lo=0.1, hi=60.0, source="chosen", doc="T_U")
    capture_radius_m: float = param(3.0, unit="m", lo=0.1, hi=100.0, source="chosen", doc="goal reached within this")
    dt_s: float = param(0.25, unit="s", lo=0.01, hi=2.0, source="the control cycle order", doc="step")
    t_max_s: float = param(900.0, unit="s", lo=1.0, hi=1e5, source="chosen", doc="the run stops here at the latest")


@dataclass
class EncounterRun:
    """A sampled run. Per-target series are keyed by MMSI; ``events`` are (t_s, text) whenever the
    avoidance's reason changed (what a log would show)."""

    t_s: np.ndarray
    north_m: np.ndarray
    east_m: np.ndarray
    psi_rad: np.ndarray
    speed_m_s: np.ndarray
    psi_share_rad: np.ndarray
    active: np.ndarray
    targets: dict[int, tuple[np.ndarray, np.ndarray]]
    situation: dict[int, list[str]]
    acting: dict[int, list[bool]]
    risk: dict[int, list[float]]
    required_m: dict[int, float]
    reached: bool
    arrival_t_s: float | None
    events: list[tuple[float, str]] = field(default_factory=list)


def simulate(scenario: TrafficScenario, *, avoidance: Avoidance | None = None,
             boat: KinematicBoatConfig = KinematicBoatConfig(), via_ais: bool = False,
             with_traffic: bool = True, allowed=None) -> EncounterRun:
    """Run own ship to the scenario's goal among its targets (module docstring). ``avoidance`` None:
    a default :class:`Avoidance`; ``with_traffic`` False: the same mission with no targets at all;
    ``allowed(north_m, east_m) -> bool``: the position limits the avoidance keeps inside (a geofence)."""
    av = avoidance if avoidance is not None else Avoidance()
    av.reset()
    specs = {s.mmsi: s for s in scenario.targets} if with_traffic else {}
    traffic = TrafficSim(scenario)
    rx = AisReceiver() if via_ais else None
    own_spec = scenario.own
    n, e = own_spec.north_m, own_spec.east_m
    psi = math.radians(own_spec.course_deg)
    u = own_spec.speed_m_s
    gn, ge = own_spec.goal_north_m, own_spec.goal_east_m
    dt = boat.dt_s
    steps = int(math.ceil(boat.t_max_s / dt))
    rows = []
    tracks: dict[int, list[tuple[float, float]]] = {m: [] for m in specs}
    sit: dict[int, list[str]] = {m: [] for m in specs}
    act: dict[int, list[bool]] = {m: [] for m in specs}
    risk: dict[int, list[float]] = {m: [] for m in specs}
    events: list[tuple[float, str]] = []
    last_reason = None
    arrival = None
    t_prev = -1e-9
    for k in range(steps + 1):
        t = k * dt
        own = OwnShip(north_m=n, east_m=e, course_rad=psi, speed_m_s=u, heading_rad=psi)
        kin = {m: x for m, x in zip((s.mmsi for s in scenario.targets), traffic.step(t, own)) if m in specs}
        if via_ais and specs:
            truth = traffic.kinematics(t)
            for ts, s in sentences_between(scenario, t_prev, t, states=lambda mmsi, tt: truth[mmsi]):
                rx.feed_line(s, ts)
            seen = [TargetState.from_ais(tg, origin_lat_deg=scenario.origin_lat_deg,
                                         origin_lon_deg=scenario.origin_lon_deg, now_s=t)
                    for tg in rx.targets(t) if tg.mmsi in specs]
            # the AIS picture has no size but the static report's; the truth's extent is what it says
            seen = [_with_extent(s, kin[s.target_id].as_target_state(specs[s.target_id]).extent_m) for s in seen]
        else:
            seen = [kin[m].as_target_state(specs[m]) for m in kin]
        t_prev = t
        dist_goal = math.hypot(gn - n, ge - e)
        psi_d = math.atan2(ge - e, gn - n)  # pure pursuit
        out = av.step(own, seen, psi_d, own_spec.speed_m_s, t, allowed)
        by_id = {a.target_id: a for a in out.targets}
        for m in specs:
            a = by_id.get(m)
            tracks[m].append((kin[m].north_m, kin[m].east_m))
            sit[m].append(a.situation.value if a else "safe")
            act[m].append(bool(a.acting) if a else False)
            risk[m].append(a.risk if a else 0.0)
        rows.append((t, n, e, psi, u, out.psi_d_share_rad, out.active))
        if out.reason != last_reason:
            events.append((t, out.reason))
            last_reason = out.reason
        if dist_goal <= boat.capture_radius_m:
            arrival = t
            break
        # own ship: first-order heading and speed, exact position update for the step
        err = wrap_pi(out.psi_d_rad - psi)
        r = max(-boat.max_turn_rate_rad_s, min(boat.max_turn_rate_rad_s, err / boat.heading_time_constant_s))
        u += (out.speed_cmd_m_s - u) * (1.0 - math.exp(-dt / boat.speed_time_constant_s))
        psi_new = psi + r * dt
        if abs(r) > 1e-9:
            n += u / r * (math.sin(psi_new) - math.sin(psi))
            e += u / r * (math.cos(psi) - math.cos(psi_new))
        else:
            n += u * math.cos(psi) * dt
            e += u * math.sin(psi) * dt
        psi = psi_new % (2 * math.pi)
    arr = np.array(rows, dtype=float)
    return EncounterRun(
        t_s=arr[:, 0], north_m=arr[:, 1], east_m=arr[:, 2], psi_rad=arr[:, 3], speed_m_s=arr[:, 4],
        psi_share_rad=arr[:, 5], active=arr[:, 6].astype(bool),
        targets={m: (np.array([p[0] for p in tr]), np.array([p[1] for p in tr])) for m, tr in tracks.items()},
        situation=sit, acting=act, risk=risk,
        required_m={m: av.config.safe_distance_m + kin[m].as_target_state(specs[m]).extent_m for m in specs},
        reached=arrival is not None, arrival_t_s=arrival, events=events,
    )


def _with_extent(s: TargetState, extent_m: float) -> TargetState:
    from dataclasses import replace

    return replace(s, extent_m=max(s.extent_m, extent_m))


def score_run(run: EncounterRun, scenario: TrafficScenario, *, boat: KinematicBoatConfig = KinematicBoatConfig(),
              config: AvoidanceConfig | None = None) -> EncounterScore:
    """Score a run against the same mission without traffic (delay, extra distance)."""
    ref = simulate(scenario, avoidance=Avoidance(config or AvoidanceConfig()), boat=boat, with_traffic=False)
    goal = dict(goal_north_m=scenario.own.goal_north_m, goal_east_m=scenario.own.goal_east_m,
                capture_radius_m=boat.capture_radius_m)
    return score_encounter(
        run.t_s, run.north_m, run.east_m, run.targets, situation=run.situation, acting=run.acting,
        psi_share_rad=run.psi_share_rad, required_m=run.required_m,
        cost=mission_cost(run.t_s, run.north_m, run.east_m, **goal),
        reference=mission_cost(ref.t_s, ref.north_m, ref.east_m, **goal),
    )
