"""The identification workflow on trials: replay, fit candidates, choose, confirm on held-out trials.

1. Baseline: each trial replayed from its initial state (first-seconds estimate,
   refined by least squares with no effect).
2. Screening: a few batched Gauss-Newton steps of every candidate from the
   baseline, twice (over whole trials, at most SCREEN_MAX_TRIALS of them, and over
   15-s windows, at most SCREEN_MAX_WINDOWS), rank them by cost; the ``top_k`` best
   of each are fitted fully (scipy.optimize.least_squares over all trials), with
   bounded retries from fresh states for fits that stop above the noise.
3. Choice by BIC (chi-square + k ln m; the residuals are divided by the noise
   estimated from the data), so extra parameters must pay for themselves:
   a candidate must beat the baseline by ``bic_margin``. Then forward
   selection of a second effect from the best single's fit, kept only if it
   beats the single by ``bic_margin`` too.
4. Confirmation on held-out trials, by cross-validation over trials: each fold
   (one trial, up to MAX_FOLDS folds) is held out in turn, the chosen effects are
   fitted on the other trials and only the held-out trial's initial state is fitted
   with them fixed. Summed over the folds, the held-out cost must fall by
   ``min_holdout_gain`` (relative); otherwise the verdict is ``none``. Every trial is
   held out once because one held-out trial may not excite the effect at all (a
   26 % deadband on a trial with no low duties: seed 639445189 of the tests).
   The folds' training fits also give the intervals: each parameter's sigma is the larger of the
   curvature estimate and the delete-a-fold jackknife (_with_jackknife).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.sim import VesselParams
from autopilot.sysid.effects import BY_NAME, EFFECT_NAMES, PARAM_BY_KEY
from autopilot.sysid.fit import Fit, fit_model, screen
from autopilot.sysid.replay import Prepared, initial_state, predict, prepare, rmse

BIC_MARGIN = 10.0  # "very strong" evidence on the Kass-Raftery scale
MIN_HOLDOUT_GAIN = 0.05
# growing fit horizons from the first-seconds states: a 10 s first step from a rough start (0.8 m
# noise, a hard turn at 6 s) fell into a wrong basin, 5 s did not (seed 1711974792 of the tests)
HORIZONS_S = (5.0, 10.0, 30.0)
# chi-square per residual below which the model explains the data to the noise: no second effect sought
ADEQUATE_CHI2 = 1.15
# refits from a start next to the optimum (the leader's polish, a single from a pair's values):
# if that start is not in the optimum's basin, a longer fit only confirms it (a current refit took
# 10 s of a 65 s benchmark)
BACKWARD_NFEV = 20
STUCK_CHI2 = ADEQUATE_CHI2  # above this after a fit from the screening start, retry through growing horizons
# Hard work budget (no wall clock: the same inputs always do the same work). Every fit is bounded by
# scipy's max_nfev (fit_model's default 40, RETRY_NFEV for retries; the Jacobian calls add at most as
# many again, and each horizon stage of fit_model is bounded at 15); the number of fits is bounded
# by top_k, pair_k and MAX_RETRIES: at most 2 (baselines) + 2 top_k (two screenings) + 1 (polish) +
# pair_k + 3 (backward, BACKWARD_NFEV) + 4 x folds (cross-validation, MAX_FOLDS: a training fit and
# up to three starts of the held-out states) fits plus MAX_RETRIES retries, each of at most 2 fits
# and, for a stepwise one-parameter effect (the deadband), one per grid value and a free fit
# (_profile: 7). Found stalling otherwise: a large thrust asymmetry (13 %) retried every single
# and pair with 100 evaluations each for > 3 minutes.
RETRY_NFEV = 60
MAX_RETRIES = 3


class _Retries:
    """Counts the retries left; a retry asked for beyond the budget returns the fit unchanged."""

    def __init__(self, n: int):
        self.left = int(n)

    def __call__(self, prep, vessel, f: Fit, x0_fresh) -> Fit:
        if self.left <= 0 or f.cost / max(f.n_obs, 1) <= STUCK_CHI2:
            return f
        self.left -= 1
        return _retry(prep, vessel, f, x0_fresh)


def _retry(prep, vessel, f: Fit, x0_fresh) -> Fit:
    """If a fit did not reach the noise level: run it longer, then retry it through growing horizons
    from the first-seconds states (the baseline's states were bent to hide the effect), then for a
    stepwise parameter (a threshold) profile it over its grid; keep the best."""
    if f.cost / max(f.n_obs, 1) > STUCK_CHI2:  # first: let it run longer from where it stopped
        g = fit_model(prep, vessel, f.effects, f.trials, f.x0, theta0=list(f.theta), max_nfev=RETRY_NFEV)
        f = g if g.cost < f.cost else f
    if f.cost / max(f.n_obs, 1) > STUCK_CHI2:
        f = _from_fresh_states(prep, vessel, f, x0_fresh, RETRY_NFEV)
    if f.cost / max(f.n_obs, 1) > STUCK_CHI2 and len(f.keys) == 1 and PARAM_BY_KEY[f.keys[0]].stepwise:
        f = _profile(prep, vessel, f, x0_fresh)
    return f


def _profile(prep, vessel, f: Fit, x0_fresh) -> Fit:
    """A stepwise one-parameter fit still above the noise: profile its cost over the parameter's grid
    (the states refitted from the first-seconds states with the value held), free fit from the best.
    Only for stepwise parameters: for the others a fit stuck above the noise is far more often a
    missing second effect, and the profile cost 12 s per single for nothing (benchmarks/sysid_speed.py).

    For a cost that is flat between steps, a gradient fit stops on whichever stretch it starts
    on: a 24.2 % deadband fitted 39 % at chi-square 5 from the screening's and from fresh states
    (seed 1462085713 of the tests; the held duties are 0, 20, 30 %, so nothing moves a threshold
    between 30 and 60 %)."""
    key = f.keys[0]
    profile = [(v, fit_model(prep, vessel, (), f.trials, x0_fresh[list(f.trials)], fixed={key: v},
                             horizons_s=HORIZONS_S, max_nfev=BACKWARD_NFEV)) for v in PARAM_BY_KEY[key].grid]
    v, g = min(profile, key=lambda vg: vg[1].cost)
    if g.cost >= f.cost:
        return f
    h = fit_model(prep, vessel, f.effects, f.trials, g.x0, theta0=[v], max_nfev=RETRY_NFEV)
    return h if h.cost < f.cost else f


def _from_fresh_states(prep, vessel, f: Fit, x0_fresh, max_nfev: int) -> Fit:
    """``f`` refitted with its own values from the first-seconds states through growing horizons
    (a fit can stop in the basin of the states it started from); the better of the two.
    ``x0_fresh``: the first-seconds states of every trial of ``prep`` (here and in _retry, _profile)."""
    g = fit_model(prep, vessel, f.effects, f.trials, x0_fresh[list(f.trials)], theta0=list(f.theta),
                  horizons_s=HORIZONS_S, max_nfev=max_nfev)
    return g if g.cost < f.cost else f


@dataclass
class Identification:
    """Everything the report needs."""

    prep: Prepared
    vessel: VesselParams
    base: Fit
    chosen: Fit
    verdict: tuple[str, ...]
    candidates: list[dict]
    held_out: tuple[tuple[int, ...], ...]  # cross-validation folds (trial indices held out together)
    rmse_before: dict
    rmse_after: dict
    notes: list[str] = field(default_factory=list)

    def values(self) -> dict[str, float]:
        return self.chosen.values() if self.verdict else {}


MAX_FOLDS = 6  # beyond six trials, fold j holds out trials j, j + 6, j + 12, ...


SCREEN_WINDOW_S = 15.0  # screening runs on windows of the trials this long (see screening_windows)
# Screening only ranks and gives starts (the full fits use every trial), so it runs on a spread
# subset: its cost grows with the data times ~50 candidate runs times 4 steps (ten 120 s trials
# took 86 s of a 167 s identification screening everything)
SCREEN_MAX_TRIALS = 4
SCREEN_MAX_WINDOWS = 16


def spread_subset(n: int, k: int) -> tuple[int, ...]:
    """At most ``k`` of ``range(n)``, evenly spread, first and last included."""
    return tuple(int(i) for i in np.unique(np.linspace(0, n - 1, min(n, k)).round().astype(int))) if n else ()


def _screen_subset(prep, vessel, fit: Fit, candidates) -> dict:
    """:func:`screen` on at most SCREEN_MAX_TRIALS of the fit's trials; states returned for all of them."""
    pick = spread_subset(len(fit.trials), SCREEN_MAX_TRIALS)
    sub = dataclasses.replace(fit, trials=tuple(fit.trials[i] for i in pick), x0=fit.x0[list(pick)])
    out = screen(prep, vessel, sub, candidates)
    for c in out:
        x0 = fit.x0.copy()
        x0[list(pick)] = out[c]["x0"]
        out[c]["x0"] = x0
    return out


def screening_windows(prep: Prepared, window_s: float = SCREEN_WINDOW_S, max_windows: int | None = None) -> Prepared | None:
    """The trials cut into windows of ``window_s``, each replayed from its own initial state.

    Screening takes a few Gauss-Newton steps from the no-effect model; over a whole trial a
    large effect puts the replay tens of degrees and metres off, where one linear step ranks
    the candidates wrongly (a 1.2 s sensor delay ranked below a current and a deadband, seed
    1268740813; a 3 % thrust asymmetry below a wind moment). Over short windows the errors stay
    small and nearly linear in the effect. Each window keeps its trial's noise estimate.
    ``max_windows``: keep at most this many, evenly spread over the trials. None when no window
    has enough positions and headings (at least 3 of each in its first 3 s, 10 positions in all).
    """
    windows, parent = [], []
    for i, tr in enumerate(prep.trials):
        start = float(tr.t_s[0])
        while start + 0.5 * window_s < tr.t_s[-1] or start == tr.t_s[0]:
            sel = (tr.t_s >= start) & (tr.t_s < start + window_s)
            first = sel & (tr.t_s < start + 3.0)  # initial_state fits the first 3 s of each window
            if (sel.sum() >= 20 and np.isfinite(tr.north_m[sel]).sum() >= 10
                    and np.isfinite(tr.north_m[first]).sum() >= 3 and np.isfinite(tr.heading_rad[first]).sum() >= 3):
                fields = {}
                for f in dataclasses.fields(tr):
                    v = getattr(tr, f.name)
                    if isinstance(v, np.ndarray) and v.shape == tr.t_s.shape:
                        v = v[sel]
                    fields[f.name] = v
                fields["name"] = f"{tr.name}@{start - tr.t_s[0]:.0f}s"
                fields["t_s"] = tr.t_s[sel] - start
                windows.append(dataclasses.replace(tr, **fields))
                parent.append(i)
            start += window_s
    if not windows:
        return None
    if max_windows is not None:
        keep = spread_subset(len(windows), max_windows)
        windows, parent = [windows[i] for i in keep], [parent[i] for i in keep]
    w = prepare(windows, dt_s=prep.dt_s)
    return dataclasses.replace(w, sigma_pos_m=prep.sigma_pos_m[parent], sigma_psi_rad=prep.sigma_psi_rad[parent])


def held_out_folds(n: int) -> tuple[tuple[int, ...], ...]:
    """Cross-validation folds over ``n`` trials: leave one out up to MAX_FOLDS, none for one trial."""
    if n < 2:
        return ()
    k = min(n, MAX_FOLDS)
    return tuple(tuple(range(j, n, k)) for j in range(k))


def _predict_fit(prep, vessel, fit: Fit):
    n = len(fit.trials)
    values = {k: np.full(n, v) for k, v in fit.values().items()}
    return predict(prep, vessel, np.array(fit.trials), fit.x0, values)


def fit_rmse(prep: Prepared, vessel: VesselParams, fit: Fit) -> dict:
    """Unweighted position/heading RMS of a fit over its trials."""
    pred = _predict_fit(prep, vessel, fit)
    return rmse(prep, fit.trials, pred, range(len(fit.trials)))


def _subset_x0(fit: Fit, trials) -> np.ndarray:
    where = {t: k for k, t in enumerate(fit.trials)}
    return np.array([fit.x0[where[t]] for t in trials])


def _with_jackknife(fit: Fit, fold_theta) -> Fit:
    """``fit`` with each sigma the larger of its curvature estimate and the delete-a-fold jackknife
    over the cross-validation's training fits (three folds at least; applied to the chosen model
    only, the other candidates keep their curvature sigmas). With more than MAX_FOLDS trials the
    folds differ in size by one trial and the (g - 1) / g formula, exact for equal folds, is off
    by ~2 %.

    The curvature sigma assumes white noise and a model linear in its parameters near the optimum.
    A threshold is neither: the deadband's information sits in the few samples where a ramp crosses
    it: fitted from its true value, its error was 1.6 curvature sigmas RMS over 19 seeds (a 27.13 %
    deadband fitted 26.56 +- 0.17, seed 1610372544 of the tests). Measured GPS noise is not white either (it wanders over
    seconds), which the curvature estimate cannot see but the spread between trials does.
    """
    g = len(fold_theta)
    if g < 3 or not fit.keys:
        return fit
    th = np.asarray(fold_theta, dtype=float)
    sigma_jk = np.sqrt((g - 1) / g * np.sum((th - th.mean(axis=0)) ** 2, axis=0))
    return dataclasses.replace(fit, sigma=np.maximum(fit.sigma, sigma_jk))  # NaN (not identifiable) stays NaN


def effect_report(fit: Fit, vessel: VesselParams) -> dict:
    """Per effect: parameters with names, units, values and 95 % intervals."""
    out = {}
    ci = fit.ci95()
    for name in fit.effects:
        eff = BY_NAME[name]
        params = []
        for p in eff.params:
            key = eff.key(p)
            k = fit.keys.index(key)
            value, lo, hi = float(fit.theta[k]), ci[key][0], ci[key][1]
            offset = 0.0
            if name == "hydro_refit":  # fitted as a change; reported as the new field value
                offset = getattr(vessel, p.name)
            params.append({
                "name": p.name, "unit": p.unit, "value": value + offset,
                "ci95": [lo + offset, hi + offset], "sigma": float(fit.sigma[k]),
            })
        if name == "current":  # speed and direction, delta method
            cn, ce = fit.theta[fit.keys.index("current.north_m_s")], fit.theta[fit.keys.index("current.east_m_s")]
            sn, se = fit.sigma[fit.keys.index("current.north_m_s")], fit.sigma[fit.keys.index("current.east_m_s")]
            speed = math.hypot(cn, ce)
            s_speed = math.sqrt((cn * sn) ** 2 + (ce * se) ** 2) / max(speed, 1e-9)
            s_dir = math.degrees(math.sqrt((ce * sn) ** 2 + (cn * se) ** 2)) / max(speed**2, 1e-12)
            towards = math.degrees(math.atan2(ce, cn)) % 360.0
            params.append({"name": "speed_m_s", "unit": "m/s", "value": speed,
                           "ci95": [speed - 1.96 * s_speed, speed + 1.96 * s_speed], "sigma": s_speed})
            params.append({"name": "towards_deg", "unit": "deg", "value": towards,
                           "ci95": [towards - 1.96 * s_dir, towards + 1.96 * s_dir], "sigma": s_dir})
        out[name] = {"doc": eff.doc, "params": params}
    return out


def identify(
    trials,
    vessel: VesselParams,
    *,
    candidates=EFFECT_NAMES,
    top_k: int = 3,
    pair_k: int = 1,
    bic_margin: float = BIC_MARGIN,
    min_holdout_gain: float = MIN_HOLDOUT_GAIN,
    max_retries: int = MAX_RETRIES,
    dt_s: float | None = None,
    log=None,
) -> Identification:
    """Run the whole workflow on measured trials against the ``vessel`` parameter set.

    The work is bounded whatever the data (see RETRY_NFEV, MAX_RETRIES and the budget beside them):
    at most 6 + 2 top_k + pair_k + 4 MAX_FOLDS fits and ``max_retries`` retries of at most 2 fits each
    (9 for the deadband, whose retry may profile its threshold over 6 values).
    """
    say = log or (lambda msg: None)
    retry = _Retries(max_retries)
    prep = prepare(trials, dt_s=dt_s)
    n = prep.n_trials
    everyone = tuple(range(n))
    x0_init = np.array([initial_state(t) for t in prep.trials])
    base = fit_model(prep, vessel, (), everyone, x0_init, horizons_s=HORIZONS_S)
    say(f"baseline: cost {base.cost:.0f} over {base.n_obs} residuals")

    # stage 1: screen every candidate, fit the best few on the whole trials.
    # Two screenings (whole trials and 15-s windows), because each misranks some effects: over whole trials a large effect is far
    # from linear; over windows an effect that a shifted initial state mimics (a sensor delay)
    # hardly shows. The top_k of each are fitted.
    scr = _screen_subset(prep, vessel, base, candidates)
    ranked = sorted(scr, key=lambda c: scr[c]["predicted_cost"])
    prep_w = screening_windows(prep, max_windows=SCREEN_MAX_WINDOWS)
    if prep_w is not None:
        every_w = tuple(range(prep_w.n_trials))
        base_w = fit_model(prep_w, vessel, (), every_w, np.array([initial_state(t) for t in prep_w.trials]))
        scr_w = screen(prep_w, vessel, base_w, candidates)
    else:  # no window with enough data: the whole-trial screening alone
        scr_w = {}
    ranked_w = sorted(scr_w, key=lambda c: scr_w[c]["predicted_cost"])
    say("screened: whole trials " + ", ".join(ranked[:top_k])
        + f"; {prep_w.n_trials if prep_w else 0} windows " + ", ".join(ranked_w[:top_k]))
    table = {c: {"effect": c, "params": list(BY_NAME[c].keys), "screen_cost": scr[c]["predicted_cost"]} for c in candidates}
    fits: dict[tuple[str, ...], Fit] = {(): base}
    starts = [(c, scr[c]["x0"], scr[c]["theta"], ()) for c in ranked[:top_k]]
    # from the windows' values, the whole-trial states go through growing horizons (the
    # baseline's states were bent to hide the effect)
    starts += [(c, x0_init, scr_w[c]["theta"], HORIZONS_S) for c in ranked_w[:top_k] if c not in ranked[:top_k]]
    for c, x0_start, theta_start, horizons in starts:
        f = fit_model(prep, vessel, (c,), everyone, x0_start, theta0=theta_start, horizons_s=horizons)
        fits[(c,)] = f
        say(f"fitted {c}: cost {f.cost:.0f}, BIC {f.bic - base.bic:+.0f}")
    singles = [k for k in fits if len(k) == 1]
    best = min(singles, key=lambda k: fits[k].bic) if singles else ()
    if best:
        # The leader is refitted once from the first-seconds states with its own values: from the
        # screening's states a fit can stop near the noise level but well off the optimum (a 25 %
        # deadband fitted 20.9 % at chi-square 7432; from fresh states 25.1 % at 6946, seed 333892304).
        # Above STUCK_CHI2 the retry below does this and more.
        if fits[best].cost / max(fits[best].n_obs, 1) <= STUCK_CHI2:
            polish = _from_fresh_states(prep, vessel, fits[best], x0_init, BACKWARD_NFEV)
            if polish is not fits[best]:
                fits[best] = polish
                say(f"refitted {best[0]} from fresh states: cost {polish.cost:.0f}, BIC {polish.bic - base.bic:+.0f}")
        # it gets a second, slower try when it did not reach the noise level; if it still does
        # not, every fitted single gets one (large effects make the problem very nonlinear)
        fits[best] = retry(prep, vessel, fits[best], x0_init)
        if fits[best].cost / max(fits[best].n_obs, 1) > ADEQUATE_CHI2:
            for k in singles:  # the leader has had its retry; the budget stops the rest
                if k != best:
                    fits[k] = retry(prep, vessel, fits[k], x0_init)
        best = min(singles, key=lambda k: fits[k].bic)
    chosen = ()
    if best and fits[best].bic < base.bic - bic_margin:
        chosen = best
    if chosen and fits[best].cost / fits[best].n_obs > ADEQUATE_CHI2:
        # stage 2: a second effect from the best single's fit
        scr2 = _screen_subset(prep, vessel, fits[best], [c for c in candidates if c not in best])
        for c in sorted(scr2, key=lambda c: scr2[c]["predicted_cost"])[:pair_k]:
            pair = tuple(best) + (c,)
            f = retry(prep, vessel, fit_model(prep, vessel, pair, everyone, scr2[c]["x0"],
                                                theta0=list(fits[best].theta) + scr2[c]["theta"]), x0_init)
            fits[pair] = f
            say(f"fitted {'+'.join(pair)}: cost {f.cost:.0f}, BIC {f.bic - base.bic:+.0f}")
        pairs = [k for k in fits if len(k) == 2]
        if pairs:
            best_pair = min(pairs, key=lambda k: fits[k].bic)
            if fits[best_pair].bic < fits[best].bic - bic_margin:
                chosen = best_pair
                # backward step: a single may now fit from the pair's values (its own first fit
                # may have stopped in a local minimum); the simpler model wins unless the pair
                # beats it by the margin
                pf = fits[best_pair]
                for e in best_pair:
                    keys = BY_NAME[e].keys
                    start = [pf.theta[pf.keys.index(k)] for k in keys]
                    f = fit_model(prep, vessel, (e,), everyone, pf.x0, theta0=start, max_nfev=BACKWARD_NFEV)
                    if (e,) not in fits or f.bic < fits[(e,)].bic:
                        fits[(e,)] = f
                        say(f"refitted {e} from the pair: cost {f.cost:.0f}, BIC {f.bic - base.bic:+.0f}")
                alone = min(((e,) for e in best_pair), key=lambda k: fits[k].bic)
                if fits[alone].bic > pf.bic + bic_margin:
                    # the pair's states may be a basin the single cannot leave (a hidden hydro refit
                    # found as yaw_damping_quadratic + hydro_refit: the single stopped 35 above the
                    # pair from the pair's states, 55 below it from fresh ones, seed 1283586661)
                    f = _from_fresh_states(prep, vessel, fits[alone], x0_init, BACKWARD_NFEV)
                    if f is not fits[alone]:
                        fits[alone] = f
                        say(f"refitted {alone[0]} from fresh states: cost {f.cost:.0f}, BIC {f.bic - base.bic:+.0f}")
                if fits[alone].bic <= pf.bic + bic_margin:
                    chosen = alone

    # held-out confirmation: cross-validation over trials
    folds = held_out_folds(n)
    notes = []
    before_fit = fit_rmse(prep, vessel, base)
    after_fit = fit_rmse(prep, vessel, fits[chosen])
    # with no effect there is nothing to fit on the other trials: the held-out states are fitted
    # states, exactly as in the baseline
    before_held, cost_before_held = before_fit, base.cost
    after_held = before_held
    if not folds:
        notes.append("one trial only: no held-out trial, held-out figures repeat the fitted ones")
    if chosen and folds:
        cost_after_held = 0.0
        fold_theta = []
        x0_held = np.zeros((n, 6))
        values_held = {k: np.zeros(n) for k in fits[chosen].keys}
        for held in folds:
            train = tuple(i for i in everyone if i not in held)
            on_train = fit_model(prep, vessel, chosen, train, _subset_x0(fits[chosen], train),
                                 theta0=fits[chosen].theta)
            fixed = on_train.values()
            fold_theta.append(on_train.theta)
            # The held-out score is the held trial's cost minimised over its initial state only, with
            # the effect fixed from training; the starts only help the optimiser find that minimum:
            # the chosen fit's states (the no-effect states are bent to hide the effect: a 4 deg
            # heading bias scored 2 % instead of 96 % from them, seed 712309766), the first-seconds
            # estimate, the no-effect fit's; the lowest wins, stop once at the noise level.
            h = None
            for start in (_subset_x0(fits[chosen], held), x0_init[list(held)], _subset_x0(base, held)):
                g = fit_model(prep, vessel, (), held, start, fixed=fixed, horizons_s=HORIZONS_S)
                h = g if h is None or g.cost < h.cost else h
                if h.cost / max(h.n_obs, 1) <= ADEQUATE_CHI2:
                    break
            cost_after_held += h.cost
            for j, t in enumerate(held):
                x0_held[t] = h.x0[j]
                for k in values_held:
                    values_held[k][t] = fixed[k]
        fits[chosen] = _with_jackknife(fits[chosen], fold_theta)
        pred = predict(prep, vessel, np.array(everyone), x0_held, values_held)
        after_held = rmse(prep, everyone, pred, range(n))
        gain = 1.0 - cost_after_held / max(cost_before_held, 1e-12)
        say(f"cross-validated over {len(folds)} folds: cost {cost_before_held:.0f} -> {cost_after_held:.0f} "
            f"({100 * gain:.0f} %)")
        if gain < min_holdout_gain:
            notes.append(f"{'+'.join(chosen)} won on BIC but lowered the held-out cost by only {100 * gain:.1f} % "
                         f"(< {100 * min_holdout_gain:.0f} %): verdict none")
            chosen = ()
            after_fit, after_held = before_fit, before_held
    elif chosen:
        after_held = after_fit
    for key, f in fits.items():
        if len(key) == 1:
            table[key[0]].update(_fit_entry(f, base, vessel))
    cands = sorted(table.values(), key=lambda d: (d.get("delta_bic", math.inf), d["screen_cost"]))
    for key, f in fits.items():
        if len(key) == 2:
            cands.append({"effect": "+".join(key), "params": list(f.keys), "screen_cost": None, **_fit_entry(f, base, vessel)})
    return Identification(
        prep=prep, vessel=vessel, base=base, chosen=fits[chosen], verdict=tuple(chosen), candidates=cands,
        held_out=folds,
        rmse_before={"fitted": before_fit, "held_out": before_held},
        rmse_after={"fitted": after_fit, "held_out": after_held},
        notes=notes,
    )


def _fit_entry(f: Fit, base: Fit, vessel: VesselParams) -> dict:
    return {
        "cost": f.cost,
        "bic": f.bic,
        "delta_bic": f.bic - base.bic,
        "aic": f.aic,
        "fitted": effect_report(f, vessel),
    }
