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


@dataclass(frozen=True)
class ManoeuvreResult:
    """Time histories and the figures of a manoeuvre."""

    name: str
    t_s: np.ndarray
    states: dict
    thrust_port_n: np.ndarray
    thrust_stbd_n: np.ndarray
    figures: dict


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


def run(params: VesselParams, name: str, *, duration_s: float | None = None, dt_s: float = 0.05, zigzag_angle_deg: float = 20.0, zigzag_differential_n: float = 20.0) -> ManoeuvreResult:
    """Simulate a named manoeuvre from rest (speed, spin, two-letter turn) or from steady speed (zig-zag)."""
    if name == "speed":
        duration = duration_s or 120.0
        t = np.arange(0.0, duration + dt_s / 2, dt_s)
        tp = np.full(t.size, params.max_thrust_n)
        out = simulate(params, t, tp, tp, dt_s=dt_s)
        u = out["u_m_s"]
        u_end = float(u[-1])
        rise = t[np.argmax(u >= 0.632 * u_end)] if u_end > 0 else math.nan
        figures = {"final_speed_m_s": round(u_end, 5), "time_constant_s": round(float(rise), 3)}
        return ManoeuvreResult(name, t, out, tp, tp, figures)
    if name == "spin":
        name = "Ff"
    if _is_letter_pair(name):
        duration = duration_s or 200.0
        t = np.arange(0.0, duration + dt_s / 2, dt_s)
        tp = np.full(t.size, level_thrust_n(name[0]))
        ts = np.full(t.size, level_thrust_n(name[1]))
        out = simulate(params, t, tp, ts, dt_s=dt_s)
        return ManoeuvreResult(name, t, out, tp, ts, _turning_figures(out, t))
    if name == "zigzag":
        return _zigzag(params, duration_s or 120.0, dt_s, zigzag_angle_deg, zigzag_differential_n)
    raise ValueError(f"manoeuvre {name!r}: expected one of speed, zigzag, spin or two command letters A-F/a-f such as AF, BD, Fb")


def _zigzag(params: VesselParams, duration_s: float, dt_s: float, angle_deg: float, differential_n: float) -> ManoeuvreResult:
    common_n = 0.5 * params.max_thrust_n
    speed0 = (1 - params.thrust_deduction) * 2 * common_n / params.resistance_linear_n_s_m
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
    overshoots = zigzag_overshoots_deg(hist[:, 2], switches, angle_deg)
    tp_hist[-1], ts_hist[-1] = tp_hist[-2], ts_hist[-2]
    out = {"t_s": t, **{n: hist[:, i] for i, n in enumerate(STATE_NAMES)}}
    figures = {
        "angle_deg": angle_deg,
        "differential_thrust_n": differential_n,
        "overshoot_deg": [round(o, 3) for o in overshoots[:4]],
    }
    return ManoeuvreResult("zigzag", t, out, tp_hist, ts_hist, figures)


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
