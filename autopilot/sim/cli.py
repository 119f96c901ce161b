"""``autopilot model``: check, calibrate, manoeuvre, nomoto."""

from __future__ import annotations

import argparse
import json
import sys

from autopilot.schema import ConfigError


def register(sub) -> None:
    p = sub.add_parser("model", help="vessel model: check against the measured table, calibrate, manoeuvres, Nomoto")
    msub = p.add_subparsers(dest="model_command", metavar="ACTION")
    msub.required = True

    c = msub.add_parser("check", help="simulate the 20 measured rows to steady state and compare")
    c.add_argument("--params", help="vessel parameter YAML (default: the shipped vessel.yaml)")
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.set_defaults(func=cmd_check)

    k = msub.add_parser("calibrate", help="fit a vessel set to the measured table and write it",
                        description="Fit resistance, yaw and sway damping of a starting set to the measured "
                        "free-running table (SPEC 6) and write the result. The shipped default (vessel.yaml, "
                        "`autopilot files`) is this command's output from the thesis set; re-running it reproduces "
                        "the file. Nothing is overwritten unless --out names it.")
    k.add_argument("--base", help="starting set (default: the shipped vessel-thesis.yaml)")
    k.add_argument("--out", default="vessel-calibrated.yaml",
                   help="output YAML (default: ./vessel-calibrated.yaml; an existing file is refused without --force)")
    k.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    k.set_defaults(func=cmd_calibrate)

    m = msub.add_parser(
        "manoeuvre", help="simulate a standard manoeuvre: speed, zigzag, spin, or letters such as AF, BD, Fb",
        description="Simulate a standard manoeuvre of the WAM-V from rest (zigzag: from steady speed) and print its "
        "figures. speed: both thrusters full ahead, final speed and time constant. zigzag: half thrust common, "
        "a differential thrust switched each time the heading passes +-angle (the 20/20 manoeuvre with thrust "
        "for rudder): one overshoot per reversal. spin: Ff, opposite full thrust. Two command letters (Table 4.2, "
        "port then starboard, capital = ahead): a turning test, steady yaw rate, speed and turning diameter.")
    m.add_argument("name", help="speed, zigzag, spin, or two letters A-F / a-f (AF, BD, Fb, ...)")
    m.add_argument("--params", help="vessel parameter YAML (default: the shipped vessel.yaml)")
    m.add_argument("--duration-s", type=float, default=None,
                   help="simulated time, 0.05-3600 s (default: speed 120 s, zigzag 120 s, turning tests and spin "
                   "200 s; a run too short to settle is said on stderr)")
    m.add_argument("--angle-deg", type=float, default=20.0, help="zigzag: heading at which the turn reverses (default 20)")
    m.add_argument("--differential-n", type=float, default=20.0,
                   help="zigzag: differential thrust T_port - T_stbd (default 20 N, within the 32.5 N per thruster)")
    m.add_argument("--plot", metavar="PNG", help="write track, heading, speed, yaw rate and thrust to this PNG")
    m.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    m.set_defaults(func=cmd_manoeuvre)

    n = msub.add_parser("nomoto", help="second-order Nomoto model at a speed (SPEC 3)")
    n.add_argument("--speed", type=float, required=True, help="forward speed (m/s)")
    n.add_argument("--params", help="vessel parameter YAML (default: the shipped vessel.yaml)")
    n.add_argument("--json", action="store_true")
    n.set_defaults(func=cmd_nomoto)


def _params(path):
    from autopilot.sim.params import default_params_path, load_params

    return load_params(path or default_params_path())


def _source(path) -> str:
    """The vessel file a message names (the shipped default when --params is not given)."""
    from autopilot.sim.params import default_params_path

    return str(path or default_params_path())


def _warn(warnings) -> None:
    for text in warnings:
        print(f"warning: {text}", file=sys.stderr)


# What the README requires of a fitted set (`model check`, SPEC 6): calibrate says when its fit misses it.
ACCEPT_STRAIGHT_SPEED = 0.03  # worst straight/reverse speed error
ACCEPT_TURN_SPEED_RMS = 0.10
ACCEPT_TURN_YAW_RATE_RMS = 0.20


def cmd_check(args: argparse.Namespace) -> int:
    from autopilot.sim.steady import CHECK_DT_S, check_table

    params = _params(args.params)
    try:
        result = check_table(params)
    except FloatingPointError:
        from autopilot.sim.params import diverged_error

        raise diverged_error(_source(args.params), CHECK_DT_S) from None
    if args.json:
        print(json.dumps({"params": params.name, "rows": [r.as_dict() for r in result.rows], **result.summary()}))
        return 0
    print(f"parameter set: {params.name}")
    print(f"{'row':4} {'T_P':>7} {'T_S':>7} {'U meas':>8} {'U sim':>8} {'err':>7}   {'r meas':>8} {'r sim':>8} {'err':>7}")
    for r in result.rows:
        d = r.as_dict()
        u_err = f"{100 * r.speed_rel_error:6.1f}%" if r.row.speed_m_s else "      -"
        r_err = f"{100 * r.yaw_rate_rel_error:6.1f}%" if r.row.yaw_rate_rad_s else "      -"
        print(
            f"{d['name']:4} {d['thrust_port_n']:7.2f} {d['thrust_stbd_n']:7.2f} {d['u_meas']:8.4f} {d['u_sim']:8.4f} {u_err}"
            f"   {d['r_meas']:8.4f} {d['r_sim']:8.4f} {r_err}"
        )
    s = result.summary()
    print(f"straight/reverse rows, worst speed error: {100 * s['straight_speed_max_rel_error']:.2f} %")
    print(f"turning rows, RMS relative error: speed {100 * s['turn_speed_rms_rel_error']:.1f} %, yaw rate {100 * s['turn_yaw_rate_rms_rel_error']:.1f} %")
    print(f"turning rows, yaw-rate sign right every time: {'yes' if s['turn_yaw_rate_sign_correct'] else 'NO'}")
    if result.not_settled:
        print(f"warning: rows {', '.join(result.not_settled)} still changing at the end of the simulation: their figures "
              "are not a steady state", file=sys.stderr)
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from autopilot.sim.calibrate import calibrate, write_params
    from autopilot.sim.params import (
        default_params_path,
        load_params,
        thesis_params_path,
    )
    from autopilot.sim.steady import CHECK_DT_S, check_table
    from autopilot.userfile import output_file

    out = output_file(args.out, what="--out", suffixes=(".yaml", ".yml"))
    if out.exists() and not args.force:
        raise ConfigError(f"--out {out}: exists; give --force to overwrite it, or another --out")
    if out.resolve() == default_params_path().resolve():
        print(f"overwriting the shipped default set {out}", file=sys.stderr)
    base = load_params(args.base or thesis_params_path())
    fitted = calibrate(base)
    try:
        check = check_table(fitted)
    except FloatingPointError:
        from autopilot.sim.params import diverged_error

        raise diverged_error(args.base or thesis_params_path(), CHECK_DT_S) from None
    write_params(fitted, out)
    s = check.summary()
    print(f"wrote {out}")
    print(json.dumps(s))
    if check.not_settled:  # it wrote a set checked on transients, with no word (a 10000-kg base)
        print(f"warning: rows {', '.join(check.not_settled)} of the fitted set still change at the end of the "
              "simulation: the figures above are not steady states", file=sys.stderr)
    # a 1000-kg base was fitted to 88 % turning-speed RMS and written with exit 0 and no word: the numbers were
    # there in the JSON, but nothing said the set fails what the default set must meet (README, SPEC 6)
    missed = [f"{what} {100 * got:.1f} % > {100 * limit:g} %" for what, got, limit in (
        ("straight/reverse worst speed error", s["straight_speed_max_rel_error"], ACCEPT_STRAIGHT_SPEED),
        ("turning speed RMS", s["turn_speed_rms_rel_error"], ACCEPT_TURN_SPEED_RMS),
        ("turning yaw-rate RMS", s["turn_yaw_rate_rms_rel_error"], ACCEPT_TURN_YAW_RATE_RMS)) if got > limit]
    if not s["turn_yaw_rate_sign_correct"]:
        missed.append("a turning row's yaw rate has the wrong sign")
    if missed:
        print(f"warning: the fitted set does not reproduce the measured table as the default set must: "
              f"{'; '.join(missed)} (`autopilot model check --params {out}` shows each row); check the base "
              f"set's fixed values (mass_kg, yaw_inertia_kg_m2, y_p_m, ...)", file=sys.stderr)
    return 0


def cmd_manoeuvre(args: argparse.Namespace) -> int:
    from autopilot.sim import manoeuvres

    params = _params(args.params)
    if args.plot is not None:  # --plot "" (an unset shell variable) drew nothing and said nothing
        from autopilot.userfile import PLOT_SUFFIXES, output_file

        if not args.plot.strip():
            raise ConfigError(f"--plot: empty; give a file name ending in {', '.join(PLOT_SUFFIXES)}")
        output_file(args.plot, what="--plot", suffixes=PLOT_SUFFIXES)
    try:
        if not (0.0 < args.angle_deg < 90.0):
            raise ValueError(f"--angle-deg: {args.angle_deg} is outside the allowed range (0, 90) deg")
        if not (0.0 < args.differential_n <= params.max_thrust_n):
            # half thrust common: a difference above max_thrust_n asked a thruster for more than it has (48.75 N of 32.5)
            raise ValueError(f"--differential-n: {args.differential_n} is outside the allowed range (0, "
                             f"{params.max_thrust_n:g}] N (with half thrust common, each thruster within its "
                             f"{params.max_thrust_n:g} N)")
        shortest_s, longest_s = manoeuvres.DEFAULT_DT_S, manoeuvres.MAX_DURATION_S
        if args.duration_s is not None and not (shortest_s <= args.duration_s <= longest_s):
            # 0.01 s was let through: the zig-zag stopped on "internal error: IndexError", the speed test printed NaN
            raise ValueError(f"--duration-s: {args.duration_s:g} is outside the allowed range [{shortest_s:g}, "
                             f"{longest_s:g}] s (at least one {shortest_s:g} s step of the simulation)")
        result = manoeuvres.run(params, args.name, duration_s=args.duration_s, zigzag_angle_deg=args.angle_deg,
                                zigzag_differential_n=args.differential_n)
    except FloatingPointError:
        from autopilot.sim.params import diverged_error

        raise diverged_error(_source(args.params), manoeuvres.DEFAULT_DT_S) from None
    except ValueError as exc:
        raise ConfigError(str(exc)) from exc
    if args.plot:
        manoeuvres.plot(result, args.plot)
    if args.json:
        print(json.dumps({"name": result.name, **result.figures}))
    else:
        print(f"{result.name}: " + ", ".join(f"{k} = {v}" for k, v in result.figures.items()))
        if args.plot:
            print(f"plot: {args.plot}")
    _warn(result.warnings)
    return 0


def cmd_nomoto(args: argparse.Namespace) -> int:
    from autopilot.gnc.speed import SPEED_RANGE, is_speed
    from autopilot.sim.nomoto import nomoto

    params = _params(args.params)
    if not is_speed(args.speed):  # inf printed K = 0 and bad JSON
        raise ConfigError(f"--speed: {args.speed:g} is outside the allowed range {SPEED_RANGE} (the "
                          "boat's top speed: 3.468 m/s measured at full thrust, row FF of SPEC 6)")
    try:
        model = nomoto(params, args.speed)
    except ValueError as exc:  # the parameter set's (no sway damping, q3 = 0), not the speed's: name the file
        raise ConfigError(f"{_source(args.params)}: {exc}") from exc
    fields = {
        "speed_m_s": model.speed_m_s,
        "K_rad_s_per_n": model.gain_rad_s_per_n,
        "K_nd": model.gain_nd,
        "T1_s": model.t1_s,
        "T2_s": model.t2_s,
        "T3_s": model.t3_s,
        "course_stable": model.course_stable,
    }
    if args.json:
        print(json.dumps(fields))
    else:
        print(f"Nomoto model of {params.name} at {args.speed} m/s (P = T_P - T_S in N):")
        print(f"  K  = {model.gain_rad_s_per_n:.5g} (rad/s)/N   (K' = {model.gain_nd:.5g})")
        print(f"  T1 = {model.t1_s:.4g} s\n  T2 = {model.t2_s:.4g} s\n  T3 = {model.t3_s:.4g} s")
        if not model.course_stable:
            print("  course-unstable: T1 < 0")
    return 0
