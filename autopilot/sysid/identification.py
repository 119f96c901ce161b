"""The identification workflow on trials: its stages, in order, and the rules of the verdict.

1. Measurements (``prediction.prepare``): each position fix and heading at the time it was measured,
   single-fix outliers rejected.
2. Baseline (:func:`baseline`): the trials replayed with no effect, their initial states fitted,
   weighted by the search's noise (wandering + white per channel, ``noise.py``: the white parts
   measured without a model, the wander a typical sensor's; ``prediction.first_guess_noise``).
3. Search (``search.py``): every candidate screened, the best fitted fully; every fitted model
   scored under its own noise (``judge.Scores``) and the fits weighted from then on by the noise
   of the best (:func:`renoise`); stuck fits retried.
4. Choice (:func:`choose`): a single effect must beat the baseline by ``bic_margin`` in BIC
   (both models' restricted deviances under the candidate's own noise + k ln m: judge.Scores), its parameters
   must be clearly away from their
   no-effect values and it must explain at least MIN_EFFECT_SIZE noise RMS on some channel. Only
   when the single is not adequate (judge.py: its residual is more than the sensor's noise) is a
   second effect sought, and it must pass the same three tests against the single (and beat the
   best single in BIC when it was grown from the runner-up).
5. Confirmation (:func:`confirm`): the noise re-estimated from the chosen model, which is refitted
   under it; cross-validation over trials (``holdout.py``): the chosen model must lower the held-out
   cost of a channel by ``min_holdout_gain`` against the baseline (and not raise the total), a pair
   also against its single; the
   intervals are the larger of curvature and the delete-a-fold jackknife (and, where the cost is not
   quadratic over them, of short windows': ``intervals.py``), and every named effect must still be
   clearly away from no effect with them.
6. Verdict (:func:`verdict`): the final model's channels are adequate -> its effects, or ``none``;
   otherwise ``unexplained``, with the nearest candidates and how far they fall short: never a
   confident name for a model that does not fit. A ``none`` whose noise estimate sits at a sensor's
   bound is ``inconclusive`` (the residual may hold a model error the size of the noise); beside any
   verdict but ``unexplained``, the fitted candidates not named with their 95 % intervals (what the
   trials cannot rule out). A single effect with a rival single that passes the same tests and falls
   short of it by less than ``bic_margin`` is ``inconclusive`` too: the trials cannot tell them apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.sim import VesselParams
from autopilot.sysid import judge, search
from autopilot.sysid.effects import BY_NAME, EFFECT_NAMES, PARAM_BY_KEY
from autopilot.sysid.fit import Fit, fit_model
from autopilot.sysid.holdout import (
    MIN_JACKKNIFE_FOLDS,
    baseline_held_out,
    cross_validate,
    held_out_folds,
    held_out_gain,
    with_jackknife,
)
from autopilot.sysid.intervals import WINDOW_S, curvature_holds, with_windows
from autopilot.sysid.noise import NoiseBounds
from autopilot.sysid.prediction import Prepared, initial_states, predict, prepare, trial_cost
from autopilot.sysid.trials import cut_long

BIC_MARGIN = 2.0  # "positive" evidence on the Kass-Raftery scale; held-out, size and z gates follow
MIN_HOLDOUT_GAIN = 0.05


@dataclass(frozen=True)
class Settings:
    """The workflow's knobs (defaults as documented in the module docstring and the README)."""

    top_k: int = 3
    pair_k: int = 2
    bic_margin: float = BIC_MARGIN
    min_holdout_gain: float = MIN_HOLDOUT_GAIN
    max_retries: int = search.MAX_RETRIES
    min_effect_size: float = judge.MIN_EFFECT_SIZE
    adequate_chi2: float = judge.ADEQUATE_CHI2
    bounds: NoiseBounds = NoiseBounds()


@dataclass
class Identification:
    """Everything the report needs."""

    prep: Prepared
    vessel: VesselParams
    base: Fit
    chosen: Fit
    verdict: tuple[str, ...]  # the named effects; () for none, inconclusive and unexplained
    status: str  # "effects", "none", "inconclusive" or "unexplained"
    candidates: list[dict]
    held_out: tuple[tuple[int, ...], ...]  # cross-validation folds
    rmse_before: dict
    rmse_after: dict
    adequacy: dict  # per channel of the final model (judge.channels)
    nearest: list[dict] = field(default_factory=list)  # unexplained: the candidates that came closest
    notes: list[str] = field(default_factory=list)
    # fitted candidates not named: their 95 % intervals (beside an effects verdict: the second effects not kept)
    not_excluded: list[dict] = field(default_factory=list)

    def values(self) -> dict[str, float]:
        return self.chosen.values() if self.verdict else {}


def identify(trials, vessel: VesselParams, *, candidates=EFFECT_NAMES, top_k: int = 3, pair_k: int = 2,
             bic_margin: float = BIC_MARGIN, min_holdout_gain: float = MIN_HOLDOUT_GAIN,
             max_retries: int = search.MAX_RETRIES, bounds: NoiseBounds | None = None, dt_s: float | None = None,
             log=None) -> Identification:
    """Run the whole workflow on measured trials against the ``vessel`` parameter set (module docstring).

    The work is bounded whatever the data (search.py's budget): at most 2 + 2 top_k + 2 pair_k + 6
    fits (each screening of second effects gives up to pair_k pairs, the runner-up's one each), 7 more (the leader
    from its mirror; per screening of second effects, the single refitted on the windows and the pairs with a wind or
    a weak motor second from its mirror), ``max_retries`` retries and two cross-validations of MAX_FOLDS folds.
    """
    s = Settings(top_k=top_k, pair_k=pair_k, bic_margin=bic_margin, min_holdout_gain=min_holdout_gain,
                 max_retries=max_retries, bounds=bounds or NoiseBounds())
    say = log or (lambda msg: None)
    trials, cut = cut_long(trials)
    for note in cut:
        say(note)
    prep = prepare(trials, dt_s=dt_s)
    cut = cut + outlier_notes(prep)
    x0_init = initial_states(prep)
    prep, base = baseline(prep, vessel, x0_init, s, say)
    scores = judge.Scores(prep, vessel, s.bounds)
    starts, screen_cost = search.screen_candidates(prep, vessel, base, candidates, s.top_k, say)
    fits = {(): base, **search.fit_singles(prep, vessel, starts, say, base)}
    prep, fits = renoise(prep, vessel, fits, scores, say)
    retries = search.Retries(s.max_retries)
    search.polish_and_retry(prep, vessel, fits, x0_init, retries, say, fits[()])
    chosen, single = choose(prep, vessel, fits, scores, candidates, x0_init, retries, s, say)
    prep, fits, chosen, notes, cv = confirm(prep, vessel, fits, chosen, single, x0_init, scores, s, say)
    return verdict(prep, vessel, fits, chosen, screen_cost, cv, scores, cut + notes, s)


def baseline(prep: Prepared, vessel, x0_init, s: Settings, say) -> tuple[Prepared, Fit]:
    """The no-effect fit under the search's noise (prediction.first_guess_noise)."""
    base = fit_model(prep, vessel, (), tuple(range(prep.n_trials)), x0_init, horizons_s=search.HORIZONS_S)
    say(f"baseline: chi2 {search.chi2(base):.3f} over {base.n_obs} measurements; search noise " + _noise_text(prep))
    return prep, base


def _noise_text(prep: Prepared) -> str:
    parts = []
    for c in prep.channels:
        n = prep.noise.of(c.name)
        parts.append(f"{c.name} {c.shown(n.white):.3g} {c.unit} white + {c.shown(n.wander):.3g} {c.unit} wander "
                     f"({n.time_s:.0f} s)")
    return ", ".join(parts)


def renoise(prep: Prepared, vessel, fits: dict, scores, say, key=None) -> tuple[Prepared, dict]:
    """The fits' weighting changed to the noise of the best-scoring model (or ``key``'s), every fit
    rescored under it (their chi-square: what the retries and the held-out costs use)."""
    key = min(fits, key=lambda k: scores.delta_bic(fits[k], fits[()])) if key is None else key
    noise = scores(fits[key])["noise"]
    if noise == prep.noise:  # already weighted so (the confirmation's call after the choice's)
        return prep, fits
    prep = prep.with_noise(noise)
    fits = {k: judge.rescore(prep, vessel, f) for k, f in fits.items()}
    say(f"noise from {'+'.join(key) or 'the baseline'}: {_noise_text(prep)}")
    return prep, fits


def _delta_bic(scores, fits, key, ref) -> float:
    return scores.delta_bic(fits[key], fits[ref])


def _passes(prep, vessel, fits, scores, key, ref, s: Settings) -> bool:
    """BIC against ``ref``, the new effect away from no effect, and large enough to matter."""
    if _delta_bic(scores, fits, key, ref) >= -s.bic_margin:
        return False
    if not judge.is_away(fits[key], key[-1]):
        return False
    return max(judge.explained(prep, vessel, fits[ref], fits[key]).values()) >= s.min_effect_size


def _adequacy(prep, vessel, fit, scores, s: Settings) -> dict:
    """judge.channels under the fit's own noise."""
    own = prep.with_noise(scores(fit)["noise"])
    return judge.channels(own, vessel, fit, s.bounds, adequate_chi2=s.adequate_chi2)


def _adequate(prep, vessel, fit, scores, s: Settings) -> bool:
    """Adequate under its own noise (judge.channels)."""
    return all(c["adequate"] for c in _adequacy(prep, vessel, fit, scores, s).values())


def choose(prep, vessel, fits: dict, scores, candidates, x0_init, retries, s: Settings, say) -> tuple:
    """(chosen key, its single's key): the best single passing the tests; a pair when the single is not
    adequate, or when the screening says a second effect pays for itself, and the pair passes the tests
    against its single. Pairs are grown from the two best singles: a wind force's constant moment can
    beat a thrust asymmetry alone, and the deadband hidden with the asymmetry is then found only as
    wind_force + thrust_deadband. The best pair holding a thrust asymmetry or a weak motor is fitted with the
    other in its place too (search.sibling_pair): the two nearly alias."""
    passing = [k for k in sorted((k for k in fits if len(k) == 1), key=lambda k: _delta_bic(scores, fits, k, ()))
               if _passes(prep, vessel, fits, scores, k, (), s)]
    if not passing:
        return (), ()
    single = passing[0]
    adequacy = _adequacy(prep, vessel, fits[single], scores, s)
    adequate = all(c["adequate"] for c in adequacy.values())
    # a single adequate only under noise its residual pushed to a sensor's bound may hide a second effect there (a
    # wind beside a weak motor: the heading wander at its 1-deg bound): the second effects are screened over 15-s
    # windows too (search.second_effects); not for a single adequate well within the bounds, where the windows'
    # screening found drops for whatever it screened (a weak motor alone, realistic trials: a wind force, a deadband
    # and a yaw damping each "paid" and were fitted for nothing, doubling the identification's time)
    look_closer = (not adequate or bool(judge.binding(adequacy))
                   or bool(judge.at_bounds(scores(fits[single])["noise"], s.bounds)))
    pairs = []
    # the runner-up grows pairs too when it came close (at least half the leader's BIC gain)
    close = [k for k in passing[1:2] if _delta_bic(scores, fits, k, ()) <= 0.5 * _delta_bic(scores, fits, single, ())]
    for rank, leader in enumerate([single] + close):
        seconds = search.second_effects(prep, vessel, fits, leader, candidates, s.pair_k if rank == 0 else 1, s.bic_margin,
                                        windows=look_closer)
        if adequate:  # not adequate: the best second effects are fitted anyway
            seconds = [sc for sc in seconds if sc[2]]
        seconds = [sc for sc in seconds if not any(set(p) == set(leader + (sc[0],)) for p in pairs)]
        pairs += search.fit_pairs(prep, vessel, fits, leader, seconds, x0_init, retries, say, fits[()])
        if not pairs:  # the leader needs no second effect: neither does the runner-up
            break
    if not adequate:
        search.refit_best_pair(prep, vessel, fits, pairs, x0_init, say, fits[()])
    # the best pair with a thrust asymmetry has a weak motor in its place too (and back): the two nearly alias
    swapped = search.sibling_pair(prep, vessel, fits, pairs, say, fits[()])
    if swapped is not None and swapped not in pairs:
        pairs.append(swapped)
    # a pair grown from the runner-up must also beat the leader: else a wind force at the noise lost
    # to thrust_asymmetry + yaw_damping_quadratic, which beat only the asymmetry (seed 1360939945)
    good = [p for p in sorted(pairs, key=lambda p: _delta_bic(scores, fits, p, ()))
            if _passes(prep, vessel, fits, scores, p, p[:1], s)
            and (p[:1] == single or _delta_bic(scores, fits, p, single) < -s.bic_margin)]
    if not good:
        return single, single
    alone = search.backward_step(prep, vessel, fits, good[0], x0_init, say, fits[()])
    if _delta_bic(scores, fits, good[0], alone) >= -s.bic_margin:
        return alone, alone
    return good[0], good[0][:1]


def confirm(prep, vessel, fits: dict, chosen, single, x0_init, scores, s: Settings, say):
    """Final noise, refit, cross-validation gates and honest intervals (module docstring, stage 5)."""
    notes: list[str] = []
    folds = held_out_folds(prep.n_trials)
    prep, fits = renoise(prep, vessel, fits, scores, say, key=chosen)
    everyone = tuple(range(prep.n_trials))
    for key in {chosen, single, ()}:
        f = fits[key]
        fits[key] = fit_model(prep, vessel, f.effects, everyone, f.x0, theta0=list(f.theta) if f.keys else None,
                              max_nfev=search.BACKWARD_NFEV)
    cv = {(): baseline_held_out(fits[()])}
    if not folds:
        notes.append("one trial only: no held-out trial, held-out figures repeat the fitted ones")
        _few_trials(prep.n_trials, fits[chosen], notes)
        return prep, fits, chosen, notes, cv
    if chosen and not _adequate(prep, vessel, fits[chosen], scores, s):
        # the verdict will be unexplained whatever the held-out trials say; their fits are the dearest
        # of all for a model that does not fit (every held-out state tries all its starts)
        notes.append(f"{'+'.join(chosen)} is not adequate: not cross-validated")
        return prep, fits, chosen, notes, cv
    while chosen:
        cv[chosen] = cv.get(chosen) or cross_validate(prep, vessel, fits[chosen], fits[()], x0_init, folds)
        ref = () if chosen == single else single
        if ref and ref not in cv:
            cv[ref] = cross_validate(prep, vessel, fits[ref], fits[()], x0_init, folds)
        fits[chosen] = unstick_states(prep, vessel, fits[chosen], cv[chosen], notes)
        gain, per = held_out_gain(prep, vessel, cv[chosen], cv[ref])
        say(f"cross-validated {'+'.join(chosen)} over {len(folds)} folds: held-out cost "
            + ", ".join(f"{ch} {100 * g:.0f} %" for ch, g in per.items()) + f" below {'+'.join(ref) or 'the baseline'}")
        fits[chosen] = with_jackknife(fits[chosen], cv[chosen].fold_theta)
        fits[chosen] = _honest_curvature(prep, vessel, fits[chosen], notes)
        weak = [e for e in chosen if not judge.is_away(fits[chosen], e)]
        if gain >= s.min_holdout_gain and not weak:
            break
        why = (f"lowered the held-out cost by only {100 * gain:.1f} % (< {100 * s.min_holdout_gain:.0f} %)"
               if gain < s.min_holdout_gain else f"{', '.join(weak)} not clearly away from no effect")
        notes.append(f"{'+'.join(chosen)} against {'+'.join(ref) or 'no effect'}: {why}: dropped")
        chosen = ref if ref != chosen else ()
    if len(folds) < MIN_JACKKNIFE_FOLDS:
        _few_trials(prep.n_trials, fits[chosen], notes)
    return prep, fits, chosen, notes, cv


STUCK_MARGIN = 1.0  # chi-square units a trial's held-out cost must beat its fitted cost by to count as stuck


def unstick_states(prep, vessel, fit: Fit, held, notes: list) -> Fit:
    """``fit`` refitted from its held-out states where a trial's held-out cost is below its fitted one.

    In-sample a trial's states and the parameters are fitted together: it can never fit worse than with the
    parameters of the other trials and only its states fitted (the cross-validation's held-out fit), unless the
    joint fit stopped in another basin of that trial's states. It did on pieces of a long log (a sysid audit,
    2026-12-05): two pieces' fitted starts sat 2-3 m off their fixes, the verdict printed a position residual of
    2.07 m "adequate" beside a held-out error of 0.74 m. The joint fit is redone from the held-out states of
    those trials (the others' kept) and taken when its cost is lower."""
    pred_fit = judge.predict_fit(prep, vessel, fit)
    pred_held = predict(prep, vessel, np.arange(prep.n_trials), held.x0, held.values)
    where = {t: j for j, t in enumerate(fit.trials)}
    stuck = []
    for t in fit.trials:
        fitted, out = trial_cost(prep, t, pred_fit, where[t]), trial_cost(prep, t, pred_held, t)
        if out < fitted - STUCK_MARGIN * max(1.0, 0.01 * fitted):
            stuck.append(t)
    if not stuck:
        return fit
    x0 = np.array(fit.x0, dtype=float)
    for t in stuck:
        x0[where[t]] = held.x0[t]
    again = fit_model(prep, vessel, fit.effects, fit.trials, x0, theta0=list(fit.theta) if fit.keys else None,
                      max_nfev=search.BACKWARD_NFEV)
    if not again.cost < fit.cost:
        return fit
    notes.append(f"{'+'.join(fit.effects) or 'no effect'}: the fitted starting states of {len(stuck)} trial(s) "
                 f"({', '.join(str(t) for t in stuck)}) fitted worse than their held-out ones (another basin of the "
                 f"joint fit): refitted from those, cost {fit.cost:.0f} -> {again.cost:.0f}")
    return again


def _honest_curvature(prep, vessel, fit: Fit, notes: list) -> Fit:
    """``fit`` with the windows' intervals when its cost is not quadratic over its own (intervals.py)."""
    if curvature_holds(prep, vessel, fit):
        return fit
    widened = with_windows(prep, vessel, fit)
    note = (f"{'+'.join(fit.effects)}: the whole trials' cost is not quadratic over the curvature interval (the "
            "replay is far from linear in the parameters there: a threshold, or wind over long trials or closed-loop "
            "logs, whose replay leaves the track within seconds)")
    if widened is None:
        notes.append(note + ": no window long enough to widen it; the intervals may be too narrow")
        return fit
    notes.append(note + f": the intervals are the larger of the whole trials' and {WINDOW_S:.0f}-s windows'")
    return widened


MAX_RUNS_SHOWN = 6  # outlier runs named per trial in a note (the rest counted)


def outlier_runs(prep: Prepared, channel: str = "position") -> list[dict]:
    """Per trial, the rejected samples of ``channel`` as runs of consecutive ones: ``{"trial", "t_s": [first,
    last] on the file's clock, "count", "gated"}`` (``gated``: how many the daemon's fix gate refused)."""
    out = []
    for tr, m in zip(prep.trials, prep.measured):
        s = m.get(channel)
        if s is None or not s.rejected:
            continue
        step = float(np.median(np.diff(s.t_s))) if s.t_s.size > 1 else 1.0
        t, gated = s.rejected_t_s, s.gated
        cuts = np.flatnonzero(np.diff(t) > 1.5 * step) + 1  # a kept sample between: another run
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
            out.append({"trial": tr.name, "t_s": [float(t[a] + tr.t0_s), float(t[b - 1] + tr.t0_s)],
                        "count": int(b - a), "gated": int(gated[a:b].sum())})
    return out


def outlier_notes(prep: Prepared) -> list[str]:
    """A note per trial naming the position fixes left out as outliers: how many, when (t_s of the file), how
    many the daemon's fix gate refused. They were only counted in summary.json: a log with multipath bursts came
    out ``unexplained`` and nothing pointed at the fixes."""
    from autopilot.gnc.navigation import NavRules

    rules = NavRules()
    by_trial: dict = {}
    for run in outlier_runs(prep):
        by_trial.setdefault(run["trial"], []).append(run)
    notes = []
    for name, runs in by_trial.items():
        total, gated = sum(r["count"] for r in runs), sum(r["gated"] for r in runs)
        shown = [f"{r['t_s'][0]:.1f} s" if r["count"] == 1 else
                 f"{r['t_s'][0]:.1f}-{r['t_s'][1]:.1f} s ({r['count']} in a row)" for r in runs[:MAX_RUNS_SHOWN]]
        more = f" and {len(runs) - MAX_RUNS_SHOWN} more" if len(runs) > MAX_RUNS_SHOWN else ""
        gate = (f"; {gated} of them beyond the daemon's fix gate ({rules.position_jump_m:g} m plus the speed over "
                f"ground and {rules.jump_speed_margin_m_s:g} m/s times the time since the fix before: a jump no boat "
                "makes, multipath?)" if gated else "")
        what = f"{total} position fixes left out as GPS outliers" if total > 1 else "1 position fix left out as a GPS outlier"
        notes.append(f"{name}: {what}, at t_s "
                     f"{', '.join(shown)}{more}{gate}")
    return notes


MISFIT_SIGMAS = 5.0  # a fix this many robust sigmas off the run of the fit's residuals around it stands out
MISFIT_SHARE = 0.2  # ... and those fixes holding this share of the squared position residual drive the misfit
MISFIT_NEIGHBOURS = 15  # fixes a side whose median residual is the run a fix is judged against


def misfit_outliers(prep: Prepared, vessel, fit: Fit) -> list[str]:
    """A note when the position misfit of ``fit`` sits much in a few fixes that stand off the run of its
    residuals around them (by MISFIT_SIGMAS robust sigmas of those steps and OUTLIER_POSITION_M) and hold
    MISFIT_SHARE or more of the squared residual: GPS outliers the screens did not catch (a burst under the fix
    gate's radius, longer than the model-free test sees) look like that; a missing effect moves the residuals
    smoothly. A log with bursts of 10 fixes 20 m off came out ``unexplained``, and the notes said only that no
    listed effect fitted."""
    from autopilot.sysid.channels import POSITION
    from autopilot.sysid.judge import predict_fit
    from autopilot.sysid.prediction import OUTLIER_POSITION_M, channel_residuals

    pred = predict_fit(prep, vessel, fit)
    series = []
    for run, i in enumerate(fit.trials):
        parts = channel_residuals(prep, i, pred, [run], POSITION)
        if not parts or parts[0].shape[1] < 2 * MISFIT_NEIGHBOURS:
            continue
        r = np.vstack([parts[0][0], parts[1][0]])
        if not np.isfinite(r).all():
            continue
        k = MISFIT_NEIGHBOURS
        level = np.array([np.median(r[:, max(j - k, 0):j + k + 1], axis=1) for j in range(r.shape[1])]).T
        series.append((i, r, np.hypot(*(r - level))))
    if not series:
        return []
    dev = np.concatenate([d for _, _, d in series])
    limit = max(MISFIT_SIGMAS * 1.4826 * float(np.median(dev)), OUTLIER_POSITION_M)
    runs, far_sq, all_sq = [], 0.0, 0.0
    for i, r, d in series:
        far = d > limit
        far_sq += float(np.sum(d[far] ** 2))
        all_sq += float(np.sum(r ** 2))
        tr, t = prep.trials[i], prep.measured[i].get("position").t_s
        edges = np.flatnonzero(np.diff(np.r_[0, far.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            runs.append((tr.name, t[a] + tr.t0_s, t[b - 1] + tr.t0_s, b - a, float(d[a:b].min()), float(d[a:b].max())))
    share = far_sq / max(all_sq, 1e-12)
    if not runs or share < MISFIT_SHARE:
        return []
    shown = [f"{name} at t_s {a:.1f} s" if n == 1 else f"{name} at t_s {a:.1f}-{b:.1f} s ({n} in a row)"
             for name, a, b, n, _, _ in runs[:MAX_RUNS_SHOWN]]
    more = f" and {len(runs) - MAX_RUNS_SHOWN} more" if len(runs) > MAX_RUNS_SHOWN else ""
    count = sum(run[3] for run in runs)
    off = f"{min(run[4] for run in runs):.0f}-{max(run[5] for run in runs):.0f} m"
    return [f"{share:.0%} of the position misfit of {'+'.join(fit.effects) or 'no effect'} sits in {count} fixes "
            f"standing {off} off the residuals around them (the others within {limit:.1f} m): {', '.join(shown)}"
            f"{more}. GPS outliers the screens did not catch (a multipath burst under the fix gate's radius) look "
            "like this, a missing effect does not: check those fixes; if they are glitches, delete their rows and "
            "run again"]


def _few_trials(n_trials: int, fit, notes: list[str]) -> None:
    """Too few trials for the jackknife that widens the intervals (holdout.with_jackknife): say so."""
    if fit.keys:
        notes.append(f"{n_trials} trial(s): the intervals rest on the noise model alone (the jackknife over trials "
                     f"that widens them needs {MIN_JACKKNIFE_FOLDS} or more) and may be too narrow: on two 60-s "
                     f"trials under 1.5 m of GPS wander the 95 % intervals of a hidden current held it 89 % of the "
                     f"time, on three 97 % (benchmarks/sysid_coverage.py); fly {MIN_JACKKNIFE_FOLDS} or more trials")


def verdict(prep, vessel, fits, chosen, screen_cost, cv, scores, notes, s: Settings) -> Identification:
    """The final model's adequacy decides: its effects (or none) when adequate, else ``unexplained``."""
    base = fits[()]
    adequacy = judge.channels(prep, vessel, fits[chosen], s.bounds, adequate_chi2=s.adequate_chi2)
    adequate = all(c["adequate"] for c in adequacy.values())
    status = ("effects" if chosen else "none") if adequate else "unexplained"
    bound = judge.at_bounds(prep.noise, s.bounds, adequacy) if adequate else []
    if bound:
        why = "; ".join(bound)
        if status == "none":
            status = "inconclusive"
            notes.append(f"{why}: the trials cannot tell a missing effect of the noise's size from the sensor's own "
                         "noise, so no effect is not the same as none: verdict inconclusive (fly longer or more "
                         "trials, or bound the sensor: --gps-wander-max, --heading-wander-max)")
        else:
            notes.append(f"{why}: the intervals may be too narrow")
    elif status == "effects" and (binding := judge.binding(adequacy)):
        # bound by a part under AT_BOUND of its limit (or the correlation time): at_bounds names none, and a wind
        # named alone beside a weak motor it had absorbed (1.97 deg of heading residual under a 0.95-deg wander)
        # gave intervals missing the truth with nothing said (a sysid audit, 2026-12-06)
        notes.append("; ".join(f"the {ch} residual asks for more noise than the sensor's bounds allow (freeing "
                               f"them gains {d:.1f} of deviance)" for ch, d in binding.items())
                     + ": a model error of the noise's size may be in it, and the intervals may be too narrow")
    elif status == "none":
        absorbed = absorbed_by_noise(prep, fits, s)
        if absorbed:
            status = "inconclusive"
            notes.append(f"{'; '.join(judge.at_bounds(prep.noise, s.bounds))}, and there it absorbs what "
                         f"{', '.join(absorbed)} would explain, clearly away from no effect (their intervals are among those not ruled out): "
                         "verdict inconclusive, not none (bound the sensor tighter if it is better than that: "
                         "--gps-wander-max, --heading-wander-max; or fly more trials)")
    if status == "effects" and len(chosen) == 1:
        rivals = tied_singles(prep, vessel, fits, chosen, scores, s)
        if rivals:
            status = "inconclusive"
            notes.append(f"{chosen[0]} and {', '.join(r[0] for r in rivals)} explain the trials about equally well "
                         f"(BIC within {s.bic_margin:g}, each passing every test): the trials cannot tell them apart, "
                         "so neither is named (their intervals are what cannot be ruled out; for a lag and a "
                         "delay, sharp thrust steps tell them apart: a lag rounds the response, a delay shifts it)")
    if status == "effects" and (alias := alias_note(prep, fits[chosen], chosen)) is not None:
        notes.append(alias)
    cands = candidate_table(prep, vessel, fits, screen_cost, scores, s)
    nearest = [] if adequate else [c for c in cands if c.get("adequacy")][:3]
    for c in nearest:  # judged as the verdict is (with the sensor-bound test): the table's cheap one said adequate
        c["adequacy"] = judge.channels(prep, vessel, fits[tuple(c["effect"].split("+"))], s.bounds,
                                       adequate_chi2=s.adequate_chi2)
    if not adequate:
        worst = [ch for ch, c in adequacy.items() if not c["adequate"]]
        tried = sorted("+".join(k) for k in fits if len(k) == 2)
        notes.append(f"no model fitted brings the {' and '.join(worst)} residual down to the noise: verdict unexplained"
                     + (f" (nearest: {', '.join(c['effect'] for c in nearest)})" if nearest else "")
                     + f"; pairs fitted: {', '.join(tried) if tried else 'none'}, the others untried (name the "
                     "effects to fit with --effects)")
        if "position" in worst:
            notes += misfit_outliers(prep, vessel, fits[chosen])
    held_before = cv[()].rmse(prep, vessel)
    held_after = cv[chosen].rmse(prep, vessel) if chosen in cv else held_before
    from autopilot.sysid.judge import predict_fit
    from autopilot.sysid.prediction import rmse

    def fitted(f):
        return rmse(prep, f.trials, predict_fit(prep, vessel, f), range(len(f.trials)))

    named = chosen if status == "effects" else ()
    return Identification(
        prep=prep, vessel=vessel, base=base, chosen=fits[named], verdict=tuple(named), status=status,
        candidates=cands, held_out=held_out_folds(prep.n_trials),
        rmse_before={"fitted": fitted(base), "held_out": held_before},
        rmse_after={"fitted": fitted(fits[named]), "held_out": held_after if named else held_before},
        adequacy=adequacy, nearest=nearest, notes=notes,
        not_excluded=(not_excluded(fits, named, vessel, prep) if status in ("none", "inconclusive")
                      else beside(prep, vessel, fits, named, scores, s) if status == "effects" else []),
    )


ALIAS_MIN_SPEED_M_S = 0.2  # slower than this, an effect's alias at speed is not said


def typical_speed_m_s(prep: Prepared) -> float:
    """The median speed over ground (m/s) between the trials' fixes at least a second apart; NaN without any."""
    speeds = []
    for m in prep.measured:
        t, n, e = m.t_pos_s, m.north_m, m.east_m
        dt = np.diff(t)
        ok = dt >= 1.0 - 1e-6
        speeds.append(np.hypot(np.diff(n), np.diff(e))[ok] / dt[ok])
    allv = np.concatenate(speeds) if speeds else np.zeros(0)
    return float(np.median(allv)) if allv.size else math.nan


def alias_note(prep: Prepared, fit, chosen: tuple) -> str | None:
    """What the single effect named looks like on straight runs at the trials' typical speed (its
    ``alias_at_speed``: fixes late and an antenna aft), or None; at rest neither shows."""
    if len(chosen) != 1:
        return None
    speed = typical_speed_m_s(prep)
    if not speed > ALIAS_MIN_SPEED_M_S:
        return None
    eff = BY_NAME[chosen[0]]
    return eff.alias_at_speed({k.split(".", 1)[1]: float(v) for k, v in zip(fit.keys, fit.theta)}, speed)


def absorbed_by_noise(prep, fits: dict, s: Settings) -> list[str]:
    """The fitted single candidates clearly away from no effect when the noise estimate sits at a sensor's bound
    without binding (judge.at_bounds): a closed-loop log exported without its time columns carries a real
    0.2-s delay of every measurement (sensor_delay 0.161-0.231 s), and a heading wander held at its 1-deg bound
    with a 4-s correlation time swallowed it whole: ``none``, though the delay was 11 sigma from zero."""
    if not judge.at_bounds(prep.noise, s.bounds):
        return []
    return sorted(k[0] for k, f in fits.items() if len(k) == 1 and f.keys and judge.is_away(f, k[0]))


def tied_singles(prep, vessel, fits: dict, chosen: tuple, scores, s: Settings) -> list[tuple]:
    """Other single effects that pass the same tests against no effect and fall short of ``chosen`` by less than
    the BIC margin: a thrust lag and a sensor delay under 0.1 s change the trials almost alike, and the
    better by 0.8-1.9 in BIC was named with a tight interval, the wrong one in 3 of 30 such draws
    (benchmarks/sysid_reliability.py --groups small)."""
    return [k for k in fits if len(k) == 1 and k != chosen and _passes(prep, vessel, fits, scores, k, (), s)
            and _delta_bic(scores, fits, k, chosen) < s.bic_margin]


def not_excluded(fits: dict, named: tuple, vessel, prep: Prepared | None = None) -> list[dict]:
    """Each fitted single candidate not named, with the 95 % interval of each parameter (SI, as the effect
    declares it, and as a named effect reports it: hydro_refit's as the coefficients' new values, ``null`` the
    vessel's own): what the trials cannot rule out (a "none" from one short log may still allow a 0.3 m/s
    current). Given as the change, hydro_refit's resistance read '0.0135..0.52 N s/m' beside a vessel of 14.07
    (a sysid audit).

    An effect whose speed is bounded (``Effect.speed_bounded``: the wind), near no effect (its components' 95 %
    ellipse holds zero, or they have no interval), with ``prep`` given: one row, ``<effect>.speed_m_s`` from 0 to
    its probed upper bound (intervals.speed_bound; ``upper_bound``: true), in place of its components' intervals
    (a symmetric "-0.029 .. 0.029 m/s" of each component, read across the windage's switch at no wind)."""
    out = []
    for key, f in fits.items():
        if len(key) != 1 or key[0] in named:
            continue
        out += _interval_rows(f, key[0], vessel, prep)
    return out


def _interval_rows(f: Fit, effect: str, vessel, prep: Prepared | None) -> list[dict]:
    """The rows of :func:`not_excluded` for ``effect`` in the fit ``f``: each parameter's 95 % interval as reported,
    or for a speed-bounded effect near none (with ``prep``) one row of its speed from 0 to its probed bound."""
    from autopilot.sysid.effects import speed_interval
    from autopilot.sysid.intervals import speed_bound

    eff = BY_NAME[effect]
    if eff.speed_bounded and prep is not None:
        v = f.values()
        k_n, k_e = f.keys.index(f"{eff.name}.north_m_s"), f.keys.index(f"{eff.name}.east_m_s")
        lo, _, _ = speed_interval(v[f.keys[k_n]], v[f.keys[k_e]], float(f.sigma[k_n]), float(f.sigma[k_e]))
        if not lo > 0.0:  # zero inside, or NaN
            return [{"effect": eff.name, "param": f"{eff.name}.speed_m_s", "unit": "m/s", "null": 0.0,
                     "ci95": [0.0, speed_bound(prep, vessel, f, eff.name)], "upper_bound": True}]
    out = []
    for k, (lo, hi) in f.ci95().items():
        p = PARAM_BY_KEY[k]
        if k.startswith(f"{eff.name}.") and math.isfinite(lo) and math.isfinite(hi):
            shift = eff.reported(p.name, p.null, vessel) - p.null  # reported() is the change plus a constant
            out.append({"effect": eff.name, "param": k, "unit": p.unit, "null": p.null + shift,
                        "ci95": [lo + shift, hi + shift]})
    return out


FAILED_PAIR_COST = 2.0  # a pair whose cost is above its named single's by more than this failed to fit


def beside(prep, vessel, fits: dict, named: tuple, scores, s: Settings) -> list[dict]:
    """Each second effect fitted beside the named model and not kept (named + it, search.fit_pairs), with the 95 %
    interval of each of its parameters given the named ones (rows as :func:`not_excluded`'s) and what it would
    take to be named: ``beside`` (the named model), ``delta_bic`` (against it; naming takes below -``bic_margin``),
    ``z`` and ``z_limit`` (clearly away from no effect at z >= z_limit), ``explained_nd`` (the most residual RMS it
    removes on a channel, in the noise's RMS; naming takes ``min_effect_size_nd``); a pair that passed all three
    was dropped by the held-out trials (the notes say why). A pair that fitted worse than the named model it holds
    (FAILED_PAIR_COST) is left out. A 3-deg compass offset beside a 0.2 m/s current moves the
    track by a third of the GPS noise: the pair's fit found it, 3 sigma from none and its interval round the
    truth, but too small to name, and the report named the current with nothing said of it (a sysid audit)."""
    out = []
    if not named:
        return out
    for key, f in fits.items():
        if len(key) != len(named) + 1 or not set(named) < set(key):  # (named, second) or (second, named): either order
            continue
        (extra,) = [e for e in key if e not in named]
        delta_bic = float(_delta_bic(scores, fits, key, named))
        if delta_bic - len(BY_NAME[extra].keys) * math.log(max(f.n_obs, 2)) > FAILED_PAIR_COST:
            # it holds the named model: a fit worse than it stopped off its optimum, and its interval says nothing
            # (a wind's pair with a deadband, chi-square 6.08 against the wind's 0.87, was listed: a review)
            continue
        z, limit = judge.away_from_null(f, extra)
        why = {"beside": "+".join(named), "delta_bic": delta_bic,
               "z": float(z), "z_limit": float(limit),
               "explained_nd": float(max(judge.explained(prep, vessel, fits[named], f).values())),
               "min_effect_size_nd": float(s.min_effect_size), "bic_margin": float(s.bic_margin)}
        out += [{**row, **why} for row in _interval_rows(f, extra, vessel, prep)]
    return out


def candidate_table(prep, vessel, fits: dict, screen_cost: dict, scores, s: Settings) -> list[dict]:
    """Every screened candidate, the fitted ones with their scores, adequacy and size, best BIC first."""
    from autopilot.sysid.summary import effect_report

    base = fits[()]
    rows = {c: {"effect": c, "params": [], "screen_cost": v} for c, v in screen_cost.items()}
    for key, f in fits.items():
        if not key:
            continue
        ref = () if len(key) == 1 else key[:-1]
        entry = rows.setdefault("+".join(key), {"effect": "+".join(key), "screen_cost": None})
        z, limit = judge.away_from_null(f, key[-1])
        entry.update({
            "params": list(f.keys), "cost": f.cost, "delta_bic": scores.delta_bic(f, base),
            "chi2_per_measurement": search.chi2(f), "z_from_null": z, "z_limit": limit,
            "explained_noise_rms": judge.explained(prep, vessel, fits.get(ref, base), f),
            "adequacy": judge.channels(prep, vessel, f, s.bounds, adequate_chi2=s.adequate_chi2, full=False),
            "fitted": effect_report(f, vessel),
        })
    return sorted(rows.values(), key=lambda d: (d.get("delta_bic", math.inf), d["screen_cost"] or 0.0))
