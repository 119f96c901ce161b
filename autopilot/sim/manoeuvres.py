"""Standard manoeuvres of the WAM-V (thesis ch. 4): speed test, turning test, zig-zag, spin.

Turning tests are named by two command letters, port then starboard
(Table 4.2): capital = forward, small = reverse, "A" = 0 V ... "F" = 12 V; e.g.
"AF" (port off, starboard full ahead), "BD", "Fb". "Ff" spins in place.
The zig-zag switches the differential thrust each time the heading passes
+-``zigzag_angle_deg`` (the usual 20/20 manoeuvre, with thrust instead of
rudder).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from autopilot.measured import LEVELS, level_thrust_n
from autopilot.sim.environment import CALM
from autopilot.sim.integrate import STATE_NAMES, simulate, step
from autopilot.sim.params import VesselParams
from autopilot.userfile import writing

NAMES = ("speed", "zigzag", "spin", "<two letters, e.g. AF, BD, Fb>")
DEFAULT_DT_S = 0.05
MAX_DURATION_S = 3600.0
TURN_TAIL_S = 30.0  # a turning test's steady figures are the mean over its last 30 s
ZIGZAG_REVERSALS = 4  # overshoots a zig-zag reports


@dataclass(frozen=True)
class ManoeuvreResult:
    """Time histories and the figures of a manoeuvre; ``warnings``: why a figure is not what its name says
    (a run too short to settle, a zig-zag with fewer reversals than asked)."""

    name: str
    t_s: np.ndarray
    states: dict
    thrust_port_n: np.ndarray
    thrust_stbd_n: np.ndarray
    figures: dict
    warnings: tuple[str, ...] = ()


def still_changing(params: VesselParams, t_s: np.ndarray, series) -> bool:
    """True when a run ends before its steady state: a value's mean over the last AVERAGE_OVER_S differs from
    the one before by more than SETTLED_REL, scaled by the surge time constant as ``model check`` does
    (``series``: (values, the smallest magnitude that counts) pairs). A run shorter than two windows is."""
    from autopilot.sim.steady import AVERAGE_OVER_S, SETTLED_REL

    if t_s[-1] - t_s[0] < 2 * AVERAGE_OVER_S:
        return True
    last = t_s >= t_s[-1] - AVERAGE_OVER_S
    before = (t_s >= t_s[-1] - 2 * AVERAGE_OVER_S) & ~last
    r1 = params.resistance_linear_n_s_m
    ahead = max(1.0, (params.mass_x_kg / r1 if r1 > 0 else MAX_DURATION_S) / AVERAGE_OVER_S)
    for values, floor in series:
        now, then = float(np.mean(values[last])), float(np.mean(values[before]))
        if ahead * abs(now - then) > SETTLED_REL * max(abs(now), floor):
            return True
    return False


def _not_steady(name: str, duration_s: float) -> str:
    return (f"{name}: still changing at the end of the {duration_s:g} s run: its figures are not a steady state "
            f"(give a longer --duration-s)")


def _is_letter_pair(name: str) -> bool:
    return len(name) == 2 and all(c.upper() in LEVELS for c in name)


def _turning_figures(out: dict, t: np.ndarray) -> dict:
    tail = t >= t[-1] - 30.0
    speed = np.hypot(out["u_m_s"], out["v_m_s"])
    r_ss = float(out["r_rad_s"][tail].mean())
    u_ss = float(speed[tail].mean())
    north, east = out["north_m"][tail], out["east_m"][tail]
    return {
        "steady_yaw_rate_rad_s": round(r_ss, 5),
        "steady_speed_m_s": round(u_ss, 5),
        "turning_diameter_m": round(2 * u_ss / abs(r_ss), 3) if abs(r_ss) > 1e-6 else None,
        "track_extent_m": round(float(max(np.ptp(north), np.ptp(east))), 3),
    }


def run(params: VesselParams, name: str, *, duration_s: float | None = None, dt_s: float = DEFAULT_DT_S, zigzag_angle_deg: float = 20.0, zigzag_differential_n: float = 20.0) -> ManoeuvreResult:
    """Simulate a named manoeuvre from rest (speed, spin, two-letter turn) or from steady speed (zig-zag).
    ``duration_s`` within [dt_s, MAX_DURATION_S] (a zig-zag of 0.01 s stopped on an IndexError)."""
    if duration_s is not None and not (dt_s <= duration_s <= MAX_DURATION_S):
        raise ValueError(f"duration_s: {duration_s:g} is outside the allowed range [{dt_s:g}, {MAX_DURATION_S:g}] s "
                         f"(at least one {dt_s:g} s step)")
    if name == "speed":
        duration = duration_s or 120.0
        t = np.arange(0.0, duration + dt_s / 2, dt_s)
        tp = np.full(t.size, params.max_thrust_n)
        out = simulate(params, t, tp, tp, dt_s=dt_s)
        u = out["u_m_s"]
        u_end = float(u[-1])
        # None, not NaN, when the boat never moved: --json printed "time_constant_s": NaN, which is not JSON
        rise = round(float(t[np.argmax(u >= 0.632 * u_end)]), 3) if u_end > 0 else None
        figures = {"final_speed_m_s": round(u_end, 5), "time_constant_s": rise}
        # a 5 s run printed "final speed 0.80 m/s, time constant 3.05 s" (3.47 and 19 s settled) without a word
        warnings = (_not_steady(name, duration),) if still_changing(params, t, ((u, 0.05),)) else ()
        return ManoeuvreResult(name, t, out, tp, tp, figures, warnings)
    if name == "spin":
        name = "Ff"
    if _is_letter_pair(name):
        duration = duration_s or 200.0
        t = np.arange(0.0, duration + dt_s / 2, dt_s)
        tp = np.full(t.size, level_thrust_n(name[0]))
        ts = np.full(t.size, level_thrust_n(name[1]))
        out = simulate(params, t, tp, ts, dt_s=dt_s)
        speed = np.hypot(out["u_m_s"], out["v_m_s"])
        # AF for 1 s printed "steady" 0.045 m/s and a 2.78 m turning circle (1.50 m/s, 4.25 m settled)
        warnings = (_not_steady(name, duration),) if (duration < 2 * TURN_TAIL_S or still_changing(
            params, t, ((speed, 0.05), (out["r_rad_s"], 0.01)))) else ()
        return ManoeuvreResult(name, t, out, tp, ts, _turning_figures(out, t), warnings)
    if name == "zigzag":
        return _zigzag(params, duration_s or 120.0, dt_s, zigzag_angle_deg, zigzag_differential_n)
    raise ValueError(f"manoeuvre {name!r}: expected one of speed, zigzag, spin or two command letters A-F/a-f such as AF, BD, Fb")


def steady_speed_m_s(params: VesselParams, thrust_each_n: float) -> float:
    """Steady straight-line speed with ``thrust_each_n`` on both thrusters: (1 - t_P) 2 T = r1 U + r2 U^2
    (SPEC 5). With the linear term alone it read r1 U and divided by zero on a set fitted quadratic."""
    force = (1 - params.thrust_deduction) * 2 * thrust_each_n
    r1, r2 = params.resistance_linear_n_s_m, params.resistance_quadratic_n_s2_m2
    if r2 == 0:
        return force / r1
    return (-r1 + math.sqrt(r1 * r1 + 4 * r2 * force)) / (2 * r2)


def _zigzag(params: VesselParams, duration_s: float, dt_s: float, angle_deg: float, differential_n: float) -> ManoeuvreResult:
    common_n = 0.5 * params.max_thrust_n
    speed0 = steady_speed_m_s(params, common_n)
    x = np.array([0.0, 0.0, 0.0, speed0, 0.0, 0.0])
    n_steps = int(round(duration_s / dt_s))
    t = np.arange(n_steps + 1) * dt_s
    hist = np.empty((n_steps + 1, 6))
    hist[0] = x
    tp_hist = np.empty(n_steps + 1)
    ts_hist = np.empty(n_steps + 1)
    turn_sign = 1.0  # start turning to starboard
    switches: list[tuple[int, float]] = []  # (step index, sign of the turn that was reversed)
    limit = math.radians(angle_deg)
    for k in range(n_steps):
        psi = x[2]
        if turn_sign > 0 and psi >= limit or turn_sign < 0 and psi <= -limit:
            switches.append((k, turn_sign))
            turn_sign = -turn_sign
        tp = common_n + turn_sign * differential_n / 2
        ts = common_n - turn_sign * differential_n / 2
        tp_hist[k], ts_hist[k] = tp, ts
        x = step(params, x, tp, ts, dt_s, t_s=t[k], env=CALM)
        hist[k + 1] = x
    if not np.all(np.isfinite(hist)):  # simulate() says so; stepping by hand, a stiff set printed "overshoot_deg = []"
        raise FloatingPointError("the simulation diverged (NaN or infinite state); check the parameters and dt_s")
    overshoots = zigzag_overshoots_deg(hist[:, 2], switches, angle_deg)
    tp_hist[-1], ts_hist[-1] = tp_hist[-2], ts_hist[-2]
    out = {"t_s": t, **{n: hist[:, i] for i, n in enumerate(STATE_NAMES)}}
    figures = {
        "angle_deg": angle_deg,
        "differential_thrust_n": differential_n,
        "overshoot_deg": [round(o, 3) for o in overshoots[:ZIGZAG_REVERSALS]],
    }
    warnings = ()
    if len(overshoots) < ZIGZAG_REVERSALS:  # "overshoot_deg = []" alone did not say why
        warnings = (f"zigzag: {len(overshoots)} of {ZIGZAG_REVERSALS} reversals completed in the {duration_s:g} s "
                    f"run, so {len(overshoots)} overshoots; give a longer --duration-s"
                    + (f" (or a larger --differential-n: the heading never reached {angle_deg:g} deg)" if not switches
                       else ""),)
    return ManoeuvreResult("zigzag", t, out, tp_hist, ts_hist, figures, warnings)


def zigzag_overshoots_deg(psi_rad: np.ndarray, switches, angle_deg: float) -> list[float]:
    """One overshoot per completed reversal: how far the heading went past +-``angle_deg``.

    ``switches``: (sample index, sign of the turn being reversed) in order. After each switch
    the heading keeps swinging the old way for a while; its largest excursion in that direction
    before the next switch, minus the angle, is the overshoot. A swing cut off by the end of the
    run (no later switch) is not counted.
    """
    out = []
    for (i, sign), (j, _) in zip(switches, switches[1:]):
        out.append(math.degrees(float(np.max(sign * psi_rad[i:j + 1]))) - angle_deg)
    return out


def plot(result: ManoeuvreResult, path: str) -> None:
    """Track, heading, speed, yaw rate and thrust of a manoeuvre, to a PNG."""
    from autopilot.plotting import pyplot, track_frame

    plt = pyplot()
    s = result.states
    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    ax[0, 0].plot(s["east_m"], s["north_m"], label="track")
    ax[0, 0].plot(s["east_m"][0], s["north_m"][0], "go", label="start")
    track_frame(ax[0, 0], s["north_m"], s["east_m"], title=f"{result.name}: track")
    ax[0, 1].plot(result.t_s, np.degrees(s["psi_rad"]))
    ax[0, 1].set(xlabel="time (s)", ylabel="heading (deg)", title="heading")
    if "overshoot_deg" in result.figures:  # the switching angles and each overshoot beyond them
        angle = result.figures["angle_deg"]
        for y in (angle, -angle):
            ax[0, 1].axhline(y, color="grey", ls=":", lw=1)
        ax[0, 1].set_title("heading; overshoots " + ", ".join(f"{o:.1f}" for o in result.figures["overshoot_deg"]) + " deg")
    ax[1, 0].plot(result.t_s, np.hypot(s["u_m_s"], s["v_m_s"]), label="speed (m/s)")
    ax[1, 0].plot(result.t_s, s["r_rad_s"], label="yaw rate (rad/s)")
    ax[1, 0].set(xlabel="time (s)", title="speed and yaw rate")
    ax[1, 0].legend()
    ax[1, 1].plot(result.t_s, result.thrust_port_n, label="port")
    ax[1, 1].plot(result.t_s, result.thrust_stbd_n, label="starboard")
    ax[1, 1].set(xlabel="time (s)", ylabel="thrust (N)", title="thrust")
    ax[1, 1].legend()
    for a in ax.flat:
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    with writing(path):  # a full disk names the file
        fig.savefig(path, dpi=90)
    plt.close(fig)
