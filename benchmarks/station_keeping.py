"""Station keeping compared: the precise hold, ArduPilot's drift-and-return (radius 2 m), and zero thrust.

The shipped mission config/missions/station-keep.yaml (drive 28 m out, hold 300 s) on the
calibrated model, through `autopilot evaluate`'s closed loop (the SC-30's rates, the daemon's
navigation): the hold scored from the true position and heading over the 300 s. Zero thrust
is the boat left at rest on the point for 300 s with both thrusters off (the drift). With
--noise the SC-30's position (0.5 m) and heading (0.5 deg) are noisy, several seeds.

--after-rtl scores instead the hold a return to launch ends in: config/missions/pond-9.1.yaml
(one waypoint 27 m out) flown with rtl, the boat coming back at the mission's speed, handing over
to station keeping 8 m out and holding at the launch point; scored from its arrival (the mode
hold) until the run's limit (the route's time limit plus 300 s), so the overshoot and settling
count. --position-noise-m sets the SC-30's position noise alone (white, per 1 Hz fix).

--offset: a hold that starts from rest a few metres from its point, the point off the bow by
0 to 180 deg (a return to launch begun nearby, a "go here" a few metres abeam): a mission of
one hold item there, flown with the lining up (gnc.hold.reposition_m, shipped) and without it
(reposition_m 0), calm and current_wind, 0.3 m position noise, --seeds seeds; the time until
the boat is within 1 m of the point (true position), the largest error over the 30 s after,
and over the hold's last 60 s.

--currents: the station-keep mission's hold in currents of 0.2 to 0.5 m/s towards each quarter
(the conditions above stop at 0.2 m/s), shipped against the learning gate shipped before 2026-12-04
(the disturbance estimate learned only below 0.2 m/s over ground, from at most 1.5 m of error: a
current that carries the boat faster than that was never learned), --position-noise-m noise, --seeds.

    python benchmarks/station_keeping.py [--markdown] [--noise --seeds 5] [--after-rtl] [--position-noise-m M]
    python benchmarks/station_keeping.py --offset [--seeds 3] [--markdown]
--chatter: how the thrust moves while holding with a noisy position (0.3 m white noise per 1 Hz
fix, --seeds seeds), calm and in 0.3 m/s of current, with the position the hold steers by smoothed
(gnc.hold.position_smoothing_s, shipped) and without (0: each fix as it comes): the standard deviation
of each thruster's thrust, the largest change from one 10 Hz command to the next, sign reversals a
minute, the hold's energy and position RMS.

--pause: `ctl pause` at cruise speed (~0.95 m/s, 25 s out on a straight leg) in calm water and in
current_wind, 0.3 m position noise, --seeds seeds, with the learning deadband shipped
(gnc.hold.learn_deadband_m) and without it (0: every error learned, as before 2026-12-06): over the 90 s
after, the heading's swing (largest minus smallest), the time either thruster is saturated, and the
position RMS from the pause point.

    python benchmarks/station_keeping.py --currents [--position-noise-m 0.3] [--seeds 3] [--markdown]
    python benchmarks/station_keeping.py --chatter [--seeds 3] [--markdown]
    python benchmarks/station_keeping.py --pause [--seeds 6] [--markdown]
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from autopilot.evaluate import CONDITION_NAMES, conditions, hold_score, run_closed_loop, time_limit_s
from autopilot.gnc import GncConfig
from autopilot.mission import load_mission
from autopilot.resources import shipped_missions
from autopilot.sim import default_params_path, load_params, step

HOLD_S = 300.0
CONDS = ("calm", "current_n", "current_e", "current_s", "current_w", "wind", "current_wind")


def drift(params, env, hold_s: float = HOLD_S, dt_s: float = 0.05):
    """Zero thrust from rest on the point: the hold's score of doing nothing."""
    x = np.zeros(6)
    d, h, t = [], [], 0.0
    k = 0
    while t < hold_s:
        x = step(params, x, 0.0, 0.0, dt_s, t_s=t, env=env)
        t += dt_s
        k += 1
        if k % 2 == 0:  # the 10 Hz control cycles
            d.append(math.hypot(x[0], x[1]))
            h.append(0.0)  # no heading to hold: scored on position only
    return hold_score(d, h, [0.0] * len(d), 0.1)


OFFSET_HOLD_S = 150.0  # --offset: the hold item's time


def offset_row(params, env, rel_deg: float, dist_m: float, cfg, seeds: int, noise_m: float):
    """(time to within 1 m, max over the 30 s after, max over the last 60 s) per seed: a hold item at ``dist_m``,
    ``rel_deg`` off the bow of a boat at rest at the origin heading north."""
    tgt = (dist_m * math.cos(math.radians(rel_deg)), dist_m * math.sin(math.radians(rel_deg)))
    out = []
    for seed in range(seeds):
        r = run_closed_loop(params, [tgt], holds_s=[OFFSET_HOLD_S], config=cfg, env=env, record=True, seed=seed,
                            position_noise_m=noise_m, t_max_s=OFFSET_HOLD_S + 60.0)
        t = np.asarray(r.trace["t_s"])
        d = np.hypot(np.asarray(r.trace["north_m"]) - tgt[0], np.asarray(r.trace["east_m"]) - tgt[1])
        near = np.flatnonzero(d < 1.0)
        t1 = float(t[near[0]]) if near.size else math.inf
        after = d[(t >= t1) & (t <= t1 + 30.0)] if near.size else d
        out.append((t1, float(after.max()), float(d[t >= t[-1] - 60.0].max())))
    return out


def offset_main(args) -> int:
    params = load_params(default_params_path())
    envs = conditions()
    base = GncConfig()
    ways = {"lining up (shipped)": base,
            "without (reposition_m 0)": dataclasses.replace(base, hold=dataclasses.replace(base.hold, reposition_m=0.0))}
    header = ("condition", "point", "hold", "within 1 m after (s)", "max over the next 30 s (m)", "max, last 60 s (m)")
    out = []
    for cond in ("calm", "current_wind"):
        for dist in (4.0, 7.0):
            for rel in (0.0, 60.0, 90.0, 135.0, 180.0):
                for name, cfg in ways.items():
                    rows = offset_row(params, envs[cond], rel, dist, cfg, args.seeds, 0.3)
                    cols = list(zip(*rows))
                    out.append((cond, f"{dist:.0f} m, {rel:.0f} deg off the bow", name,
                                f"{min(cols[0]):.0f}-{max(cols[0]):.0f}", f"{max(cols[1]):.2f}", f"{max(cols[2]):.2f}"))
    _print(header, out, args.markdown)
    return 0


OLD_GATE = {"learn_below_m_s": 0.2, "learn_error_m": 1.5}  # the learning gate before 2026-12-04


def currents_main(args) -> int:
    from concurrent.futures import ProcessPoolExecutor

    params = load_params(default_params_path())
    mission = load_mission(next(p for p in shipped_missions() if p.stem == "station-keep"))
    base = GncConfig()
    ways = {"shipped": base, "gate before 2026-12-04": dataclasses.replace(base, hold=dataclasses.replace(base.hold,
                                                                                                          **OLD_GATE))}
    envs = [(spd, tow) for spd in (0.2, 0.25, 0.3, 0.4, 0.5) for tow in (0.0, 90.0, 180.0, 270.0)]
    jobs = [(mission, params, cfg, spd, tow, seed, args.position_noise_m or 0.0)
            for spd, tow in envs for cfg in ways.values() for seed in range(args.seeds)]
    with ProcessPoolExecutor() as ex:
        scores = list(ex.map(_current_hold, jobs))
    header = ("current (m/s)", "towards (deg)", *(f"{w}: RMS / max (m), heading RMS (deg)" for w in ways))
    out, k = [], 0
    for spd, tow in envs:
        row = [f"{spd:.2f}", f"{tow:.0f}"]
        for _ in ways:
            got = scores[k:k + args.seeds]
            k += args.seeds
            rms, mx, hd = zip(*got)
            row.append(f"{min(rms):.2f}-{max(rms):.2f} / {max(mx):.1f}, {max(hd):.0f}" if args.seeds > 1 else
                       f"{rms[0]:.2f} / {mx[0]:.1f}, {hd[0]:.0f}")
        out.append(tuple(row))
    _print(header, out, args.markdown)
    return 0


def _current_hold(job):
    from autopilot.sim import Environment

    mission, params, cfg, spd, tow, seed, noise = job
    h = run_closed_loop(params, mission.waypoints_ne_m, holds_s=mission.holds_s, config=cfg, seed=seed,
                        env=Environment(current_speed_m_s=spd, current_towards_deg=tow), position_noise_m=noise).hold
    return h.position_error_rms_m, h.position_error_max_m, h.heading_error_rms_deg


def chatter_main(args) -> int:
    from autopilot.sim import Environment

    params = load_params(default_params_path())
    mission = load_mission(next(p for p in shipped_missions() if p.stem == "station-keep"))
    base = GncConfig()
    ways = {f"smoothed ({base.hold.position_smoothing_s:g} s, shipped)": base,
            "each fix as it comes (0)": dataclasses.replace(base, hold=dataclasses.replace(base.hold,
                                                                                           position_smoothing_s=0.0))}
    header = ("condition", "position", "thrust std (N)", "largest step (N)", "reversals / min", "energy (N s)",
              "position RMS (m)")
    out = []
    for cond, env in (("calm", Environment()), ("0.3 m/s towards 90", Environment(current_speed_m_s=0.3,
                                                                                  current_towards_deg=90.0))):
        for name, cfg in ways.items():
            got = []
            for seed in range(args.seeds):
                r = run_closed_loop(params, mission.waypoints_ne_m, holds_s=mission.holds_s, env=env, config=cfg,
                                    seed=seed, position_noise_m=0.3, record=True)
                held = np.array([h == h and h is not None for h in r.trace["hold_error_m"]])  # not NaN: holding
                tp, ts = (np.asarray(r.trace[k])[held] for k in ("thrust_port_n", "thrust_stbd_n"))
                minutes = held.sum() * 0.1 / 60.0
                flips = (np.count_nonzero(np.diff(np.sign(tp))) + np.count_nonzero(np.diff(np.sign(ts)))) / 2
                got.append((max(tp.std(), ts.std()), max(np.abs(np.diff(tp)).max(), np.abs(np.diff(ts)).max()),
                            flips / minutes, r.hold.energy_n_s, r.hold.position_error_rms_m))
            cols = list(zip(*got))
            out.append((cond, name, *(f"{min(c):{f}}-{max(c):{f}}" if args.seeds > 1 else f"{c[0]:{f}}"
                                      for c, f in zip(cols, (".1f", ".0f", ".0f", ".0f", ".2f")))))
    _print(header, out, args.markdown)
    return 0


def _print(header, out, markdown: bool) -> None:
    if markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for r in out:
            print("| " + " | ".join(r) + " |")
    else:
        print("  ".join(f"{h:>18}" for h in header))
        for r in out:
            print("  ".join(f"{c:>18}" for c in r))


def _pause_run(job):
    params, cfg, cond, seed = job
    r = run_closed_loop(params, [(200.0, 0.0)], env=conditions()[cond], config=cfg, position_noise_m=0.3,
                        heading_noise_deg=0.1, seed=seed, t_max_s=115.0, commands=[(25.0, "pause")], record=True)
    paused = np.asarray(r.trace["mode"]) == "paused"
    psi = np.unwrap(np.asarray(r.trace["psi_rad"]))[paused]
    thrust = np.abs(np.c_[r.trace["thrust_port_n"], r.trace["thrust_stbd_n"]])[paused]
    saturated_s = float(np.count_nonzero(thrust.max(axis=1) >= 32.4)) * 0.1
    return math.degrees(psi.max() - psi.min()), saturated_s, r.hold.position_error_rms_m


def pause_main(args) -> int:
    params = load_params(default_params_path())
    base = GncConfig()
    ways = {"shipped": base,
            "no deadband (before 2026-12-06)": dataclasses.replace(base, hold=dataclasses.replace(base.hold,
                                                                                                 learn_deadband_m=0.0))}
    rows = []
    for cond in ("calm", "current_wind"):
        for name, cfg in ways.items():
            runs = [_pause_run((params, cfg, cond, s)) for s in range(args.seeds)]
            swing, sat, rms = (np.array(v) for v in zip(*runs))
            rows.append((cond, name, f"{swing.min():.0f}-{swing.max():.0f}", f"{sat.min():.1f}-{sat.max():.1f}",
                         f"{rms.min():.2f}-{rms.max():.2f}", f"{np.count_nonzero(swing > 30.0)} of {len(swing)}"))
    _print(("condition", "learning", "heading swing (deg)", "saturated (s)", "position RMS (m)", "swing > 30 deg"),
           rows, args.markdown)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--markdown", action="store_true")
    ap.add_argument("--noise", action="store_true", help="noisy SC-30 (0.5 m, 0.5 deg)")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--after-rtl", action="store_true", help="the hold at the launch point after pond-9.1 with rtl")
    ap.add_argument("--position-noise-m", type=float, default=None, help="position noise alone (m, per fix)")
    ap.add_argument("--offset", action="store_true", help="holds started from rest with the point off the bow")
    ap.add_argument("--currents", action="store_true", help="the hold in currents of 0.2-0.5 m/s")
    ap.add_argument("--chatter", action="store_true", help="the thrust while holding with a noisy position")
    ap.add_argument("--pause", action="store_true", help="a pause at cruise speed, calm and current_wind")
    args = ap.parse_args()
    if args.pause:
        return pause_main(args)
    if args.chatter:
        return chatter_main(args)
    if args.offset:
        return offset_main(args)
    if args.currents:
        return currents_main(args)
    params = load_params(default_params_path())
    mission = load_mission(next(p for p in shipped_missions() if p.stem == ("pond-9.1" if args.after_rtl
                                                                              else "station-keep")))
    envs = conditions()
    base = GncConfig()
    ways = {"hold (radius 0)": base,
            "drift-and-return (radius 2 m)": dataclasses.replace(base, hold=dataclasses.replace(base.hold, radius_m=2.0))}
    noise = dict(position_noise_m=0.5, heading_noise_deg=0.5) if args.noise else {}
    if args.position_noise_m is not None:
        noise = dict(position_noise_m=args.position_noise_m)
    extra = {}
    if args.after_rtl:
        back = [*mission.waypoints_ne_m, (0.0, 0.0)]  # the route and the way back
        extra = dict(rtl=True, t_max_s=time_limit_s(back, base.guidance.default_speed_m_s) + HOLD_S)
    rows = []
    for cond in CONDS:
        assert cond in CONDITION_NAMES
        for name, cfg in ways.items():
            scores = [run_closed_loop(params, mission.waypoints_ne_m, holds_s=mission.holds_s, env=envs[cond],
                                      config=cfg, seed=s, **noise, **extra).hold for s in range(args.seeds)]
            rows.append((cond, name, scores))
        rows.append((cond, "zero thrust (drift)", [drift(params, envs[cond])]))
    header = ("condition", "hold", "position RMS (m)", "p95 (m)", "max (m)", "heading RMS (deg)", "energy (N s)", "VRX")

    def rng(vals, fmt):
        lo, hi = min(vals), max(vals)
        return f"{lo:{fmt}}" if abs(hi - lo) < 0.5 * 10 ** -int(fmt[-2]) else f"{lo:{fmt}}-{hi:{fmt}}"

    out = []
    for cond, name, scores in rows:
        heading = "-" if name.startswith("zero") else rng([s.heading_error_rms_deg for s in scores], ".1f")
        out.append((cond, name, rng([s.position_error_rms_m for s in scores], ".2f"),
                    rng([s.position_error_p95_m for s in scores], ".2f"), rng([s.position_error_max_m for s in scores], ".2f"),
                    heading, rng([s.energy_n_s for s in scores], ".0f"), rng([s.vrx_score for s in scores], ".2f")))
    _print(header, out, args.markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
