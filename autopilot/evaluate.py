"""``autopilot evaluate``: closed-loop simulation of missions x guidance laws x conditions.

Model (``autopilot.sim.step``, RK4 at ``dt_s`` = 0.05 s) + the full GNC stack
(``autopilot.gnc.Autopilot`` at 10 Hz, thrust held between cycles), no
serial, simulated time. The GNC sees what it sees on the boat: the SC-30's
measurements at their rates (``autopilot.sim.sensors``: a 1 Hz fix, the 10 Hz
heading, ROT at 1 Hz), put together by the daemon's own navigation assembly
(``autopilot.gnc.navigation.assemble``: dead reckoning, differenced yaw rate). The boat starts at the mission's home (the local
origin), heading north, at rest. Each run gives a scorecard:

- completed: the autopilot reached the last waypoint, and held its hold item if it has one, within the time
  limit (the time is then when the route was complete);
- closest_approach_m: per waypoint, the closest approach over its pass, from
  the simulated 1 Hz position fixes (:mod:`autopilot.gnc.passes`, the same
  definition the daemon logs and ``autopilot review`` recomputes);
- xte_rms_m / xte_max_m: cross-track error from the leg being followed;
- time_s: time to complete (or the time limit);
- energy_ns: integral of |T_port| + |T_stbd| dt;
- saturation_pct: share of control cycles in which the allocator saturated;
- circled: the heading turned through more than 360 deg while steering to
  one waypoint (a boat circling a waypoint it cannot hit).

Missions with a hold item (``hold_s``) are also scored on holding, over every
control cycle station keeping ran, from the true (simulated) position and heading:

- hold_position_error_rms_m / _p95_m: distance from the point held;
- hold_heading_error_rms_deg: from the heading held (the given one, or the
  least-effort one station keeping chose);
- hold_energy_n_s: integral of |T_port| + |T_stbd| dt while holding;
- vrx_score: the Virtual RobotX station-keeping score, the mean over the hold
  of d + 0.75^d |heading error (rad)| (lower is better; osrf/vrx
  ``stationkeeping_scoring_plugin``).

Conditions: ``calm``; ``current_n/e/s/w``: 0.2 m/s flowing FROM that side;
``sinusoidal``: file 003 Eq 7 force (A = B = 10 N, 0.628 rad/s, at 45 deg);
``wind``: 5 m/s from the north-east; ``current_wind``: 0.2 m/s from the north and
5 m/s of wind from the east.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path

from autopilot.daemon.missionlog import json_ready
from autopilot.geo import wrap_pi
from autopilot.schema import ConfigError
from autopilot.sim.sensors import SensorModel, SensorRates

GNC_RATE_HZ = 10.0
SIM_DT_S = 0.05
EVAL_ORIGIN_DEG = (52.0, 4.4)  # where the local frame lies (any point: only the local frame matters)


def conditions() -> dict:
    """Condition name -> autopilot.sim.Environment."""
    from autopilot.sim import Environment, SinusoidalDisturbance

    def current_from(from_deg: float) -> Environment:
        return Environment(current_speed_m_s=0.2, current_towards_deg=(from_deg + 180.0) % 360.0)

    return {
        "calm": Environment(),
        "current_n": current_from(0.0),
        "current_e": current_from(90.0),
        "current_s": current_from(180.0),
        "current_w": current_from(270.0),
        "sinusoidal": Environment(sinusoidal=SinusoidalDisturbance()),
        "wind": Environment(wind_speed_m_s=5.0, wind_from_deg=45.0),
        "current_wind": Environment(current_speed_m_s=0.2, current_towards_deg=180.0, wind_speed_m_s=5.0,
                                    wind_from_deg=90.0),
    }


CONDITION_NAMES = ("calm", "current_n", "current_e", "current_s", "current_w", "sinusoidal", "wind", "current_wind")
VRX_HEADING_BASE = 0.75  # pose error = d + 0.75^d |heading error|


@dataclass(frozen=True)
class HoldScore:
    """How well station keeping held (true position and heading, over the cycles it ran)."""

    time_s: float
    position_error_rms_m: float
    position_error_p95_m: float
    position_error_max_m: float
    heading_error_rms_deg: float
    energy_n_s: float
    vrx_score: float

    def as_json(self) -> dict:
        return {
            "hold_time_s": round(self.time_s, 1),
            "hold_position_error_rms_m": round(self.position_error_rms_m, 3),
            "hold_position_error_p95_m": round(self.position_error_p95_m, 3),
            "hold_position_error_max_m": round(self.position_error_max_m, 3),
            "hold_heading_error_rms_deg": round(self.heading_error_rms_deg, 2),
            "hold_energy_n_s": round(self.energy_n_s, 1),
            "vrx_score": round(self.vrx_score, 3),
        }


def hold_score(distance_m, heading_error_rad, thrust_abs_sum_n, dt_s: float) -> HoldScore | None:
    """The hold's score from per-cycle samples (equal steps of ``dt_s``); None without samples."""
    import numpy as np

    d = np.asarray(distance_m, float)
    if d.size == 0:
        return None
    h = np.abs(np.asarray(heading_error_rad, float))
    return HoldScore(
        time_s=d.size * dt_s,
        position_error_rms_m=float(np.sqrt(np.mean(d * d))),
        position_error_p95_m=float(np.percentile(d, 95)),
        position_error_max_m=float(d.max()),
        heading_error_rms_deg=float(np.degrees(np.sqrt(np.mean(h * h)))),
        energy_n_s=float(np.sum(thrust_abs_sum_n) * dt_s),
        vrx_score=float(np.mean(d + VRX_HEADING_BASE ** d * h)),
    )


@dataclass
class RunResult:
    mission: str
    guidance: str
    condition: str
    completed: bool
    closest_approach_m: list[float]
    xte_rms_m: float
    xte_max_m: float
    time_s: float
    energy_ns: float
    saturation_pct: float
    circled: bool
    hold: HoldScore | None = None
    trace: dict = field(default_factory=dict, repr=False)

    def as_json(self) -> dict:
        return {**self._as_json(), **({} if self.hold is None else self.hold.as_json())}

    def _as_json(self) -> dict:
        return {
            "mission": self.mission,
            "guidance": self.guidance,
            "condition": self.condition,
            "completed": self.completed,
            "closest_approach_m": [round(c, 3) for c in self.closest_approach_m],
            "xte_rms_m": round(self.xte_rms_m, 3),
            "xte_max_m": round(self.xte_max_m, 3),
            "time_s": round(self.time_s, 2),
            "energy_ns": round(self.energy_ns, 1),
            "saturation_pct": round(self.saturation_pct, 2),
            "circled": self.circled,
        }


class CirclingMonitor:
    """Flags a boat circling a waypoint: its heading turned through more than
    ``limit_rad`` (one full turn) while it steered to one and the same waypoint.

    Fed the heading once per control cycle; the turn between two samples is
    the wrapped difference (the boat cannot turn half a revolution in one
    10 Hz cycle), so the sum is the net heading change since the target last
    changed. Oscillation about a course sums to ~0; a full loop sums to 2 pi.
    """

    def __init__(self, limit_rad: float = 2.0 * math.pi) -> None:
        self.limit_rad = limit_rad
        self.circled = False
        self._target: int | None = None
        self._prev_psi = 0.0
        self._turned_rad = 0.0

    def update(self, wp_index: int, psi_rad: float) -> bool:
        """One heading sample while steering to ``wp_index``; returns the flag so far."""
        if wp_index != self._target:
            self._target, self._turned_rad = wp_index, 0.0
        else:
            self._turned_rad += wrap_pi(psi_rad - self._prev_psi)
            if abs(self._turned_rad) > self.limit_rad:
                self.circled = True
        self._prev_psi = psi_rad
        return self.circled


def circled(wp_index, psi_rad, *, limit_rad: float = 2.0 * math.pi) -> bool:
    """The scorecard's circling flag for a heading history (one sample per control cycle)."""
    mon = CirclingMonitor(limit_rad)
    for i, psi in zip(wp_index, psi_rad):
        mon.update(int(i), float(psi))
    return mon.circled


def time_limit_s(waypoints_ne_m, speed_m_s: float, holds_s=(), start_ne_m=(0.0, 0.0)) -> float:
    """Generous limit: three times the polyline from ``start_ne_m`` at the wanted speed, plus two minutes, plus the holds."""
    length = 0.0
    prev = (float(start_ne_m[0]), float(start_ne_m[1]))
    for n, e in waypoints_ne_m:
        length += math.hypot(n - prev[0], e - prev[1])
        prev = (n, e)
    held = sum(h for h in (holds_s or ()) if h is not None and math.isfinite(h))
    return 120.0 + 3.0 * length / max(speed_m_s, 0.1) + held


def run_closed_loop(
    params,
    waypoints_ne_m,
    *,
    config=None,
    speeds_m_s=None,
    holds_s=None,
    env=None,
    external_force=None,
    t_max_s: float | None = None,
    dt_s: float = SIM_DT_S,
    rate_hz: float = GNC_RATE_HZ,
    record: bool = False,
    mission: str = "",
    condition: str = "",
    sensor_rates: SensorRates = SensorRates(),
    position_noise_m: float = 0.0,
    heading_noise_deg: float = 0.0,
    seed: int = 0,
    traffic=None,
    x0=None,
    rtl: bool = False,
    within_limits=None,
    commands=(),
):
    """Simulate one mission with the autopilot in the loop; returns a :class:`RunResult`. ``traffic``: a
    :class:`autopilot.traffic.feed.TrafficFeed` whose targets the boat sees (through AIS) and avoids;
    ``x0``: the start state (north, east, psi, u, v, r), at rest at the origin heading north if None;
    ``rtl``: the mission ends returning to the launch point and holds there until ``t_max_s``;
    ``within_limits(north_m, east_m) -> bool``: the position limits the helm keeps its own holds and avoidance's
    alterations inside, as the daemon's failsafe hands it (None: none); ``commands``: ``(t_s, command)`` the
    operator gives (``pause``, ``hold``, ``rtl``, ...), each at the first cycle from ``t_s`` with a position.

    One run at a time through :class:`autopilot.closed_loop.Flight` (the daemon's control cycle without
    its failsafe, evaluate's scorecard); the campaigns fly the same flights in lockstep."""
    import numpy as np

    from autopilot.closed_loop import Flight
    from autopilot.daemon.cycle import nav_input
    from autopilot.gnc import Autopilot, GncConfig
    from autopilot.sim import step

    config = config or GncConfig()
    wps = [(float(n), float(e)) for n, e in waypoints_ne_m]
    ap = Autopilot(config, wps, speeds_m_s=speeds_m_s, holds_s=holds_s, rtl=rtl, boat_length_m=params.length_m,
                   within_limits=within_limits)
    # the daemon's navigation: the SC-30's rates (a 1 Hz fix, dead-reckoned), the same assembly
    origin = EVAL_ORIGIN_DEG if traffic is None else traffic.origin  # AIS positions are decoded around it
    sensors = SensorModel(*origin, rates=sensor_rates, position_noise_m=position_noise_m,
                          heading_noise_deg=heading_noise_deg, rng=np.random.default_rng(seed))
    if t_max_s is None:
        start = (0.0, 0.0) if x0 is None else (float(x0[0]), float(x0[1]))
        t_max_s = time_limit_s(wps + [start] if rtl else wps, config.guidance.default_speed_m_s, holds_s,
                               start_ne_m=start)  # the return to launch is a leg too
    flight = Flight(ap, sensors, dt_s=dt_s, rate_hz=rate_hz, t_max_s=t_max_s,
                    final_pass_s=config.guidance.final_pass_s, origin_lat_deg=origin[0],
                    origin_lon_deg=origin[1], record=record, traffic=traffic)
    x = np.zeros(6) if x0 is None else np.array(x0, dtype=float)
    t = 0.0
    pending = sorted(commands)
    while (thrust := flight.control(t, x)) is not None:
        while pending and t >= pending[0][0] and flight.last.nav.steerable:
            ap.request(pending.pop(0)[1], nav_input(flight.last.nav), cause="evaluate")  # from the next cycle
        for _ in range(flight.substeps):
            x = step(params, x, thrust[0], thrust[1], dt_s, t_s=t, env=env, external_force=external_force)
            t += dt_s
        if not math.isfinite(x.sum()):  # a set too stiff for the step: it was "internal error: ValueError: NavInput"
            raise FloatingPointError("the simulation diverged (NaN or infinite state); check the parameters and dt_s")
    return flight.result(t, mission=mission, condition=condition)


@dataclass
class EncounterResult:
    scenario: str
    condition: str
    completed: bool
    score: object  # autopilot.traffic.score.EncounterScore
    energy_ns: float
    reference_energy_ns: float
    trace: dict = field(default_factory=dict, repr=False)

    def as_json(self) -> dict:
        return {"scenario": self.scenario, "condition": self.condition, "completed": self.completed,
                **self.score.summary(), "energy_ns": round(self.energy_ns, 1),
                "extra_energy_ns": round(self.energy_ns - self.reference_energy_ns, 1)}


def run_encounter(params, scenario, *, config=None, env=None, condition: str = "", via_ais: bool = True,
                  record: bool = False, within_limits=None, reference: bool = True) -> EncounterResult:
    """One traffic scenario on the calibrated model with the whole GNC stack: own ship from the scenario's start
    (under way at its speed) to its goal, the targets seen through AIS; scored against the same run without
    traffic (the delay and the extra energy the encounter cost). ``within_limits``: as run_closed_loop's;
    ``reference`` False: no run without traffic (half the cost; the delay and extra energy then read 0)."""
    import numpy as np

    from autopilot.gnc import GncConfig
    from autopilot.traffic.feed import TrafficFeed
    from autopilot.traffic.score import mission_cost, score_encounter

    config = config or GncConfig()
    own = scenario.own
    wps = [(own.goal_north_m, own.goal_east_m)]
    x0 = (own.north_m, own.east_m, math.radians(own.course_deg), own.speed_m_s, 0.0, 0.0)
    speeds = [own.speed_m_s]
    feed = TrafficFeed(scenario, via_ais=via_ais)
    run = run_closed_loop(params, wps, config=config, speeds_m_s=speeds, env=env, record=True, x0=x0,
                          traffic=feed, mission=scenario.name, condition=condition, within_limits=within_limits)
    ref = run if not reference else run_closed_loop(
        params, wps, config=config, speeds_m_s=speeds, env=env, record=True, x0=x0,
        traffic=TrafficFeed(_no_targets(scenario)), mission=scenario.name, condition=condition)
    tr = run.trace
    ids = list(feed.specs)
    goal = dict(goal_north_m=own.goal_north_m, goal_east_m=own.goal_east_m,
                capture_radius_m=config.guidance.capture_radius_m + 0.5)

    def cost(t):
        return mission_cost(t["t_s"], t["north_m"], t["east_m"], thrust_port_n=t["thrust_port_n"],
                            thrust_stbd_n=t["thrust_stbd_n"], **goal)

    score = score_encounter(
        tr["t_s"], tr["north_m"], tr["east_m"],
        {m: (np.array([p[0] for p in feed.truth[m]]), np.array([p[1] for p in feed.truth[m]])) for m in ids},
        situation={m: [d.get(m, "safe") for d in tr["situations"]] for m in ids},
        acting={m: [d.get(m, False) for d in tr["acting"]] for m in ids},
        psi_share_rad=tr["avoid_share_rad"], required_m=feed.required_m(config.avoidance.safe_distance_m),
        cost=cost(tr), reference=cost(ref.trace))
    trace = {**tr, "targets": feed.truth, "waypoints": wps} if record else {}
    return EncounterResult(scenario.name, condition, run.completed, score, run.energy_ns, ref.energy_ns, trace)


def _no_targets(scenario):
    import dataclasses

    return dataclasses.replace(scenario, targets=())


def shipped_scenarios() -> list[Path]:
    from autopilot.resources import data_dir

    return sorted((data_dir() / "traffic").glob("*.yaml"))


def shipped_missions() -> list[Path]:
    """The shipped missions (``autopilot files``; not the format examples)."""
    from autopilot.resources import shipped_missions as missions

    return missions()


def evaluate(mission_paths, laws, condition_names, *, params=None, base_config=None, record: bool = False):
    """Every mission x law x condition: an iterator of RunResult. Every mission file is read and checked
    here, before the first run (a bad file used to be refused after the table's header was out)."""
    from autopilot.gnc import GncConfig
    from autopilot.mission import load_mission
    from autopilot.sim import default_params_path, load_params

    missions = [load_mission(path) for path in mission_paths]
    params = params or load_params(default_params_path())
    base_config = base_config or GncConfig()
    return _runs(missions, laws, condition_names, params, base_config, record)


def _runs(missions, laws, condition_names, params, base_config, record: bool):
    envs = conditions()
    for m in missions:
        for law in laws:
            cfg = replace(base_config, guidance=replace(base_config.guidance, law=law))
            for cond in condition_names:
                yield run_closed_loop(
                    params, m.waypoints_ne_m, config=cfg, speeds_m_s=m.speeds_m_s, holds_s=m.holds_s, env=envs[cond],
                    record=record, mission=m.name, condition=cond, x0=(*m.home_ne_m, 0.0, 0.0, 0.0, 0.0), rtl=m.rtl,
                )


def format_row(r: RunResult) -> str:
    ca = " ".join(f"{c:4.2f}" if math.isfinite(c) else " n/a" for c in r.closest_approach_m)  # as the run summary
    return (
        f"{r.mission:<14} {r.guidance:<12} {r.condition:<12} {'yes' if r.completed else 'NO ':<4} "
        f"{r.xte_rms_m:6.2f} {r.xte_max_m:6.2f} {r.time_s:7.1f} {r.energy_ns:8.0f} {r.saturation_pct:5.1f} "
        f"{'CIRCLED' if r.circled else '-':<7} {ca}"
        + ("" if r.hold is None else
           f"  hold: rms {r.hold.position_error_rms_m:.2f} m, p95 {r.hold.position_error_p95_m:.2f} m, heading rms "
           f"{r.hold.heading_error_rms_deg:.1f} deg, {r.hold.energy_n_s:.0f} N s, VRX {r.hold.vrx_score:.2f}")
    )


HEADER = (
    f"{'mission':<14} {'guidance':<12} {'condition':<12} {'done':<4} {'xteRMS':>6} {'xteMAX':>6} "
    f"{'time_s':>7} {'energyNs':>8} {'sat%':>5} {'circle':<7} closest approach per waypoint (m)"
)


def _gnc_config(path):
    """The GNC settings of ``path`` (:func:`autopilot.gnc.cli.load_gnc_config`: GncConfig keys, or the daemon's
    configuration with its ``gnc:`` section)."""
    from autopilot.gnc.cli import load_gnc_config

    return load_gnc_config(path)


def _mission_arg(given: str) -> Path:
    """A --mission: a file, or a shipped mission by its name, as ``autopilot run`` takes it."""
    from autopilot.resources import find_mission

    try:
        return find_mission(given)[0]
    except ConfigError as exc:
        raise ConfigError(f"--mission {exc}") from None


def _cmd(args: argparse.Namespace) -> int:
    from autopilot.gnc import GUIDANCE_LAWS, GncConfig
    from autopilot.sim import default_params_path, load_params

    # each given once: a repeated --guidance flew every run twice and counted both in the summary
    missions = (list(dict.fromkeys(_mission_arg(p) for p in args.mission)) if args.mission
                else shipped_missions())
    laws = list(dict.fromkeys(args.guidance or GUIDANCE_LAWS))
    conds = list(dict.fromkeys(args.condition or CONDITION_NAMES))
    for law in laws:
        if law not in GUIDANCE_LAWS:
            raise ConfigError(f"--guidance: unknown law {law!r} (known: {', '.join(GUIDANCE_LAWS)})")
    for c in conds:
        if c not in CONDITION_NAMES:
            raise ConfigError(f"--condition: unknown condition {c!r} (known: {', '.join(CONDITION_NAMES)})")
    params = load_params(args.vessel or default_params_path())
    base = _gnc_config(args.config) if args.config else GncConfig()
    if args.traffic:
        for given, opt in ((args.plot, "--plot"), (args.mission, "--mission")):
            if given:  # both were ignored without a word: the encounter suite flies each scenario's own route
                raise ConfigError(f"{opt} is not for --traffic: the encounter suite flies each scenario's own route "
                                  "and draws no figures")
        if args.guidance:  # ignored without a word too: the suite flies the configuration's law
            raise ConfigError(f"--guidance is not for --traffic: the encounter suite flies the configuration's law "
                              f"({base.guidance.law}); give another with --config (guidance: law:)")
        try:
            return _traffic(args, params, base, list(dict.fromkeys(args.condition or TRAFFIC_CONDITIONS)))
        except FloatingPointError:
            from autopilot.sim.params import diverged_error

            raise diverged_error(args.vessel or default_params_path(), SIM_DT_S) from None
    if args.plot is not None:  # --plot "" (an unset shell variable) drew nothing and said nothing
        from autopilot.userfile import output_dir

        output_dir(args.plot, what="--plot")
    runs = evaluate(missions, laws, conds, params=params, base_config=base, record=bool(args.plot))
    if not args.json:
        print(HEADER)
    try:
        for r in runs:
            if args.json:
                print(json.dumps(json_ready(r.as_json()), allow_nan=False))
            else:
                print(format_row(r))
            sys.stdout.flush()
            if args.plot:
                from autopilot.gnc.plots import plot_run

                plot_run(r, Path(args.plot) / f"{r.mission}-{r.guidance}-{r.condition}.png")
    except FloatingPointError:  # the vessel set's, not a bug of ours: name the file and what to look at
        from autopilot.sim.params import diverged_error

        raise diverged_error(args.vessel or default_params_path(), SIM_DT_S) from None
    return 0


TRAFFIC_CONDITIONS = ("calm", "current_n", "current_e", "current_s", "current_w", "current_wind")
TRAFFIC_HEADER = (f"{'scenario':<24} {'condition':<12} {'done':<4} {'min m':>6} {'kept':<4} {'rules':<5} {'delay s':>7} "
                  f"{'extra Ns':>8}  per target: situation, side, closest / required (m)")


def _scenario_paths(names) -> list[Path]:
    shipped = {p.stem: p for p in shipped_scenarios()}
    out = []
    for name in names:
        if name == "all":
            out += list(shipped.values())
        elif name in shipped:
            out.append(shipped[name])
        elif Path(name).exists():
            out.append(Path(name))
        else:
            raise ConfigError(f"--traffic: {name!r} is neither a file nor a shipped scenario "
                              f"({', '.join(shipped)}, or all)")
    return list(dict.fromkeys(out))  # each once: "--traffic all --traffic head-on" flew head-on twice


def _traffic(args, params, base, conds) -> int:
    """The encounter suite: each traffic scenario x condition on the calibrated model, targets seen through AIS."""
    from autopilot.simdev.traffic import load_scenario

    envs = conditions()
    scenarios = [load_scenario(p) for p in _scenario_paths(args.traffic)]
    if not args.json:
        print(TRAFFIC_HEADER)
    for sc in scenarios:
        for cond in conds:
            r = run_encounter(params, sc, config=base, env=envs[cond], condition=cond)
            j = r.as_json()
            if args.json:
                print(json.dumps(json_ready(j), allow_nan=False))
            else:
                per = "; ".join(f"{t['situation']}, {t['side'] or '-'}, {t['min_distance_m']:.1f} / {t['required_m']:.1f}"
                                for t in j["targets"])
                delay = "-" if j["delay_s"] is None else f"{j['delay_s']:.1f}"
                print(f"{sc.name:<24} {cond:<12} {'yes' if j['completed'] else 'NO':<4} {j['min_distance_m']:6.1f} "
                      f"{'yes' if j['distance_kept'] else 'NO':<4} {'yes' if j['rules_followed'] else 'NO':<5} "
                      f"{delay:>7} {j['extra_energy_ns']:8.0f}  {per}")
            sys.stdout.flush()
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help="closed-loop simulation scorecard: missions x guidance laws x conditions",
        description=(
            "Fly every mission x guidance law x condition on simulated time: the calibrated model (RK4, "
            "20 Hz) with the whole GNC stack at 10 Hz, no serial. One scorecard per run: completed, closest "
            "approach per waypoint (over its pass, from 1 Hz fixes), cross-track RMS and maximum, time, "
            "thrust energy, saturation time, circling. Conditions: calm; current_n/e/s/w (0.2 m/s from that "
            "side); sinusoidal (file 003 Eq 7 force); wind (5 m/s from the north-east); current_wind (0.2 m/s from "
            "the north, 5 m/s of wind from the east). Missions with a hold item are also scored on holding "
            "(position and heading error, energy, the VRX station-keeping score)."
        ),
    )
    p.add_argument("--json", action="store_true", help="one JSON object per run")
    p.add_argument("--mission", action="append", metavar="FILE",
                   help="mission file (any supported format) or a shipped mission's name (pond-9.4); default: every "
                        "shipped mission (`autopilot files`)")
    p.add_argument("--guidance", action="append", metavar="NAME", help="fuzzy, los, proportional (default: all)")
    p.add_argument("--condition", action="append", metavar="NAME", help=f"{', '.join(CONDITION_NAMES)} (default: all)")
    p.add_argument("--plot", metavar="DIR", help="draw the thesis figures of each run into DIR")
    p.add_argument("--traffic", action="append", metavar="SCENARIO",
                   help="the encounter suite instead: a traffic scenario (a shipped name, a YAML file, or all), "
                   "own ship to its goal among AIS targets; per run the closest distance to each target, the rule "
                   f"followed, the delay and extra energy; conditions default to {', '.join(TRAFFIC_CONDITIONS)}")
    p.add_argument("--config", metavar="FILE", help="GNC configuration YAML (GncConfig keys)")
    p.add_argument("--vessel", metavar="FILE",
                   help="vessel parameters (default: the shipped vessel.yaml, which `autopilot files` shows)")
    p.set_defaults(func=_cmd)
