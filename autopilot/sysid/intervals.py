"""Whether a fit's curvature interval can be believed, and the windows' interval when it cannot.

The curvature interval (fit.py) is the quadratic approximation of the cost around the optimum,
read from the Jacobian. It holds while the replay is nearly linear in the parameters over the
interval. A replay of a closed-loop mission log in wind is not: the helm held the heading
against the wind's yaw moment, the replay holds only the logged thrusts, and a heading error
grows without bound over a 60-s trial. The whole trials' cost is then a ridge of needles: five
pond logs in 5.6 m/s of wind (benchmark seed 844889997) fitted within 0.04 m/s of the truth
with a 95 % interval of +-0.00005 m/s (z 1602); 1e-4 m/s away from the optimum the cost rose
by 7000, 70 times what the Jacobian predicts. The delete-a-trial jackknife did not see it
either: each fold started at that needle and stayed there. Long open-loop trials in strong wind
do it too: twelve 180-s realistic trials in 8.6 m/s, fitted from the truth, ended 0.0005 m/s off it
with an interval of +-0.00002 (z 48 and 44).

:func:`curvature_holds` tests the quadratic model where the interval is read: the cost at two
sigmas either side of each parameter (the states held) against the Jacobian's prediction. When
it fails, :func:`with_windows` takes the larger of the interval and that of the trials cut into
``WINDOW_S`` windows, each replayed from its own fitted state (multiple shooting without the
continuity): short enough that the replay stays near-linear, and its jackknife over the trials'
cross-validation folds (all of a trial's windows held out together) sees the spread between trials. The same seed:
95 % intervals of +-0.023 and +-0.030 m/s, z 1.8 and 2.6; the twelve long trials z 0.05 and 0.06.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from autopilot.sysid.fit import Fit, Problem, fit_model
from autopilot.sysid.holdout import MIN_JACKKNIFE_FOLDS, held_out_folds, with_jackknife

__all__ = ["curvature_holds", "with_windows", "speed_bound", "WINDOW_S", "QUADRATIC_TOLERANCE"]

WINDOW_S = 20.0  # the windows' length (s); 15 s gave z 2.7 and 3.2 on the seed above, 20 s 1.8 and 2.6
QUADRATIC_TOLERANCE = 2.0  # actual / predicted cost rise allowed either way (well-posed fits: 0.9-1.1)
PROBE_SIGMAS = 2.0  # where the quadratic model is tested: the 95 % interval's edge
WINDOW_FOLD_NFEV = 40
MAX_WINDOWS = 48  # evenly spread over the trials beyond this: all 108 windows of twelve 180-s trials took 75 s, 48 took 14 s (sigma within 20 %)


def curvature_holds(prep, vessel, fit: Fit) -> bool:
    """True when the cost rises as the Jacobian predicts at +-PROBE_SIGMAS sigmas of every parameter
    (within a factor QUADRATIC_TOLERANCE), the states held; True for a fit without parameters or intervals."""
    sigma = np.asarray(fit.sigma, dtype=float)
    if not fit.keys or not np.all(np.isfinite(sigma)) or np.any(sigma <= 0.0):
        return True
    prob = Problem(prep, vessel, fit.keys, fit.trials, fit.x0, fixed=fit.fixed)
    z0 = prob.pack(fit.theta, fit.x0)
    r0 = prob.fun(z0)
    jac = prob.jac(z0)
    c0 = float(r0 @ r0)
    for k in range(prob.p):
        for sign in (-1.0, 1.0):
            theta = np.array(fit.theta, dtype=float)
            theta[k] += sign * PROBE_SIGMAS * sigma[k]
            z = prob.pack(theta, fit.x0)
            r = prob.fun(z)
            rise = float(r @ r) - c0
            predicted = float(np.sum((r0 + jac @ (z - z0)) ** 2)) - c0
            if predicted <= 0.0 or not QUADRATIC_TOLERANCE ** -1 <= rise / predicted <= QUADRATIC_TOLERANCE:
                return False
    return True


def with_windows(prep, vessel, fit: Fit, min_folds: int = MIN_JACKKNIFE_FOLDS) -> Fit | None:
    """``fit`` with each sigma the larger of its own and the windows' (module docstring: curvature over
    WINDOW_S windows, widened by their jackknife over the trials' cross-validation folds, holdout.held_out_folds,
    when there are at least ``min_folds``); None when the trials hold no window with enough measurements."""
    from autopilot.sysid.prediction import initial_states
    from autopilot.sysid.search import HORIZONS_S, screening_windows

    own = prep.subset(fit.trials)
    # each trial named by its place (users' trials may share a name): a window's name is its trial's, then "@"
    own = dataclasses.replace(own, trials=tuple(dataclasses.replace(t, name=str(k)) for k, t in enumerate(own.trials)))
    windows = screening_windows(own, window_s=WINDOW_S, max_windows=MAX_WINDOWS)
    if windows is None:
        return None
    n = windows.n_trials
    everyone = tuple(range(n))
    on_windows = fit_model(windows, vessel, fit.effects, everyone, initial_states(windows), theta0=list(fit.theta),
                           fixed=fit.fixed, horizons_s=HORIZONS_S)
    owner = [int(w.name.split("@", 1)[0]) for w in windows.trials]
    folds = held_out_folds(len(fit.trials))  # the trials' folds (at most MAX_FOLDS): many logs cost six refits
    if len(folds) >= min_folds:
        fold_theta = []
        for held in folds:
            keep = tuple(i for i in everyone if owner[i] not in held)
            if not keep:
                continue
            fold_theta.append(fit_model(windows, vessel, fit.effects, keep, on_windows.x0[list(keep)],
                                        theta0=list(on_windows.theta), fixed=fit.fixed, max_nfev=WINDOW_FOLD_NFEV).theta)
        if len(fold_theta) >= min_folds:
            on_windows = with_jackknife(on_windows, fold_theta)
    return dataclasses.replace(fit, sigma=np.fmax(fit.sigma, on_windows.sigma))


# the speeds (m/s) and directions probed for an upper bound (speed_bound), and the Gauss-Newton steps of the trials'
# initial states at each probe (the Jacobian of the fit's held, as screen.py steps candidates)
PROBE_SPEEDS_M_S = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 13.0, 16.0, 20.0, 25.0)
PROBE_DIRECTIONS = 8
PROBE_STATE_STEPS = 3


def speed_bound(prep, vessel, fit: Fit, effect: str) -> float:
    """The 95 % upper bound of the speed of ``effect``'s velocity (its ``north_m_s``, ``east_m_s`` in ``fit``), from
    the cost itself: each of PROBE_SPEEDS_M_S in PROBE_DIRECTIONS directions, the trials' initial states refitted
    (PROBE_STATE_STEPS Gauss-Newton steps from the fit's), is ruled out when its cost exceeds the lowest met (the
    fit's or a probe's) by more than Z_95^2; the bound is the next probed speed above the fastest not ruled out
    (between them the cost was not looked at), the largest probed when none above it is ruled out; the slowest
    probed when every probe is ruled out.

    Near no wind the curvature interval is read across the windage's switch (no wind, no force: the boat's own
    air drag comes on with any wind, as in the simulator) and the force goes with the wind's square: three calm
    realistic trials reported wind.north_m_s -0.029 .. 0.029 m/s (the fit at exactly no wind, its sigma a finite
    difference across the switch). Probed, 0.25 m/s raised the cost by 330-1500 in every direction (the own drag
    a moving boat then carries), 2 m/s by 16000-84000: "at most 0.25 m/s"."""
    from autopilot.sysid.effects import Z_95
    from autopilot.sysid.fit import FREE_STATES, X0_LIMIT, X0_SCALE

    keys = (f"{effect}.north_m_s", f"{effect}.east_m_s")
    k_n, k_e = fit.keys.index(keys[0]), fit.keys.index(keys[1])
    prob = Problem(prep, vessel, fit.keys, fit.trials, fit.x0, fixed=fit.fixed)
    z = prob.pack(fit.theta, fit.x0)
    r_fit = prob.fun(z)
    j_x0 = prob.jac(z, with_theta=False)
    n, free = len(fit.trials), list(FREE_STATES)
    angles = np.arange(PROBE_DIRECTIONS) * 2.0 * np.pi / PROBE_DIRECTIONS
    speeds = np.repeat(PROBE_SPEEDS_M_S, PROBE_DIRECTIONS)
    thetas = np.tile(np.asarray(fit.theta, dtype=float), (speeds.size, 1))
    thetas[:, k_n] = speeds * np.cos(np.tile(angles, len(PROBE_SPEEDS_M_S)))
    thetas[:, k_e] = speeds * np.sin(np.tile(angles, len(PROBE_SPEEDS_M_S)))
    x0s = np.tile(np.asarray(fit.x0, dtype=float), (speeds.size, 1, 1))
    best = np.full(speeds.size, np.inf)
    for step in range(PROBE_STATE_STEPS + 1):
        pred = prob._runs(np.repeat(thetas, n, axis=0), x0s.reshape(-1, 6), np.tile(np.array(fit.trials), speeds.size))
        for q in range(speeds.size):
            r = prob.residual_vector(pred, range(q * n, (q + 1) * n))
            best[q] = min(best[q], float(r @ r))
            if step < PROBE_STATE_STEPS:
                d, *_ = np.linalg.lstsq(j_x0, -r, rcond=None)
                x0 = x0s[q].copy()
                x0[:, free] += d.reshape(n, len(free)) * X0_SCALE[free]
                x0s[q] = np.clip(x0, -X0_LIMIT, X0_LIMIT)
    allowed = best <= min(float(r_fit @ r_fit), float(best.min())) + Z_95**2
    if not allowed.any():
        return float(PROBE_SPEEDS_M_S[0])
    fastest = float(speeds[allowed].max())
    above = [s for s in PROBE_SPEEDS_M_S if s > fastest]
    return float(above[0]) if above else fastest
