"""Measurement noise of a channel (position per axis, heading): wandering plus white, estimated, whitened.

Model of one series (one trial, one channel; measurement times t_k, issue 12 "Build" 2)::

    y_k = h(x(t_k)) + b_k + e_k
    e_k ~ N(0, s_w^2)                                      white
    b_k = phi_k b_{k-1} + w_k,  phi_k = exp(-(t_k - t_{k-1}) / tau),
          w_k ~ N(0, q_k),  q_k = s_g^2 (1 - phi_k^2),  b_0 ~ N(0, s_g^2)   Gauss-Markov wander

so cov(y) = S = s_w^2 I + G, G_kl = s_g^2 exp(-|t_k - t_l| / tau). The fit minimises the
generalised least-squares cost r^T S^-1 r of the residuals r, written as a sum of squares by
profiling the wander out (a Gauss-Markov error state per sample, solved exactly)::

    min_b |r - b|^2 / s_w^2 + |D b|^2 = r^T S^-1 r        D b: (b_0 / s_g, (b_k - phi_k b_{k-1}) / sqrt(q_k))
    b* = M^-1 r / s_w^2,  M = D^T D + I / s_w^2            (tridiagonal: one banded Cholesky per series)
    weighted residuals = [(r - b*) / s_w ; D b*]           (2n rows, linear in r)

The noise (s_w, s_g, tau) of a channel is shared by all trials (one receiver, one compass) and
estimated by restricted maximum likelihood from a fitted model's residuals (:func:`estimate`,
each series' mean removed as the initial state's offset absorbs it), inside the bounds a real
sensor has (:class:`NoiseBounds`): a residual that needs more than that is model error, not noise.
Outliers (single fixes and short bursts) are rejected before any fit, without a model (:func:`outliers`),
and before them the fixes the daemon's fix gate refuses, judged with hindsight (:func:`gated_fixes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded

from autopilot.schema import param

MIN_DT_S = 1e-3  # two measurements closer than this are treated as this far apart
EPS_WANDER = 1e-6  # below this (relative to the white part) the wander is off: white noise only


@dataclass(frozen=True)
class ChannelNoise:
    """Noise of one channel: white part, wander (Gauss-Markov) and its correlation time (SI: m or rad)."""

    white: float
    wander: float
    time_s: float

    @property
    def rms(self) -> float:
        return math.hypot(self.white, self.wander)

    @property
    def has_wander(self) -> bool:
        return self.wander > EPS_WANDER * max(self.white, 1e-12)


@dataclass(frozen=True)
class NoiseBounds:
    """What a sensor's noise may be (estimates are held inside; beyond them a residual is model error)."""

    position_white_min_m: float = param(0.05, unit="m", lo=0.001, hi=10.0, doc="the replay's own position resolution")
    position_white_max_m: float = param(3.0, unit="m", lo=0.01, hi=50.0, doc="largest white GPS noise")
    position_wander_max_m: float = param(3.0, unit="m", lo=0.01, hi=50.0, source="issue 12: 0.5-2 m", doc="largest wandering GPS error (1 sigma per axis)")
    position_time_max_s: float = param(120.0, unit="s", lo=1.0, hi=3600.0, source="issue 12: 30-60 s", doc="longest correlation time of the GPS wander")
    heading_white_min_deg: float = param(0.05, unit="deg", lo=0.001, hi=10.0, source="SPEC 1: 0.1 deg resolution", doc="the replay's own heading resolution")
    heading_white_max_deg: float = param(1.0, unit="deg", lo=0.01, hi=30.0, source="SPEC 1: 0.5 deg rms", doc="largest white heading noise")
    heading_wander_max_deg: float = param(1.0, unit="deg", lo=0.01, hi=30.0, source="SPEC 1: 0.5 deg rms", doc="largest wandering heading error")
    heading_time_max_s: float = param(120.0, unit="s", lo=1.0, hi=3600.0, doc="longest correlation time of the heading wander")
    # A receiver's velocity (Doppler) error is nearly white; a short wander allows for one that smooths
    # its output. Held short and small: a velocity error that wanders for minutes would be a current.
    velocity_white_min_m_s: float = param(0.005, unit="m/s", lo=0.0001, hi=1.0, doc="SOG as printed: 0.01 kn")
    velocity_white_max_m_s: float = param(0.5, unit="m/s", lo=0.001, hi=10.0, doc="largest white velocity noise per axis")
    velocity_wander_max_m_s: float = param(0.1, unit="m/s", lo=0.001, hi=10.0, doc="largest wandering velocity error per axis")
    velocity_time_max_s: float = param(10.0, unit="s", lo=1.0, hi=3600.0, doc="longest correlation time of the velocity wander")
    time_min_s: float = param(2.0, unit="s", lo=0.1, hi=100.0, doc="shortest correlation time of a wander")
    # The search (screening and first fits) weights by the baseline's noise, whose wander holds the
    # missing effect too: capped at a typical sensor's, or a model that misses an effect would weight
    # by a noise that hides it and flatten the cost the fits follow (a hidden 0.2 m/s current in
    # closed-loop logs was fitted at 0.11 m/s under a baseline noise at the sensor bounds).
    position_wander_search_m: float = param(1.0, unit="m", lo=0.01, hi=50.0, doc="largest GPS wander the search weights by")
    heading_wander_search_deg: float = param(0.3, unit="deg", lo=0.01, hi=30.0, doc="largest heading wander the search weights by")

    # The wander's correlation time from trials about as long as it is poorly determined: after each
    # trial's initial state took its share, a 45 s wander fitted as 10 s and half its size, and the
    # intervals with it (z = 3.3 for a current). A log-normal prior holds it near a GPS's.
    time_prior_s: float = param(40.0, unit="s", lo=1.0, hi=3600.0, source="issue 12: 30-60 s", doc="centre of the prior on the wander's correlation time")
    time_prior_factor: float = param(2.0, unit="-", lo=1.01, hi=100.0, doc="one sigma of that prior, as a factor (log-normal)")

    @property
    def time_prior(self) -> tuple[float, float]:
        return self.time_prior_s, self.time_prior_factor

    def prior(self, name: str) -> tuple[float, float] | None:
        """The prior on the correlation time of ``name``'s wander (the GPS's and the compass's; the
        velocity's is short and bounded instead)."""
        return None if name == "velocity" else self.time_prior

    def for_search(self) -> NoiseBounds:
        """These bounds with the wander capped at the search's (above)."""
        import dataclasses

        return dataclasses.replace(self, position_wander_max_m=min(self.position_wander_max_m, self.position_wander_search_m),
                                   heading_wander_max_deg=min(self.heading_wander_max_deg, self.heading_wander_search_deg))

    def channel(self, name: str) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
        """((white lo, hi), (wander lo, hi), (time lo, hi)) of ``position`` (m), ``velocity`` (m/s) or
        ``heading`` (rad)."""
        if name == "position":
            return ((self.position_white_min_m, self.position_white_max_m), (1e-3, self.position_wander_max_m),
                    (self.time_min_s, self.position_time_max_s))
        if name == "velocity":
            return ((self.velocity_white_min_m_s, self.velocity_white_max_m_s), (1e-4, self.velocity_wander_max_m_s),
                    (self.time_min_s, self.velocity_time_max_s))
        rad = math.radians
        return ((rad(self.heading_white_min_deg), rad(self.heading_white_max_deg)), (rad(1e-3), rad(self.heading_wander_max_deg)),
                (self.time_min_s, self.heading_time_max_s))


class Whitener:
    """The linear map r -> weighted residuals of one series (module docstring); 2n rows with wander, else n."""

    def __init__(self, t_s: np.ndarray, noise: ChannelNoise):
        t = np.asarray(t_s, dtype=float)
        self.n = t.size
        self.noise = noise
        self.s_w = float(noise.white)
        self.wander = noise.has_wander and self.n > 1
        if not self.wander:
            self.rows = self.n
            return
        self.rows = 2 * self.n
        dt = np.maximum(np.diff(t), MIN_DT_S)
        phi = np.r_[0.0, np.exp(-dt / noise.time_s)]
        q = noise.wander**2 * np.maximum(1.0 - phi * phi, 1e-12)
        self.phi, self.d = phi, 1.0 / np.sqrt(q)  # D row k: d_k (b_k - phi_k b_{k-1})
        d2 = self.d**2
        diag = d2 + 1.0 / self.s_w**2
        diag[:-1] += (phi[1:] * self.d[1:]) ** 2
        ab = np.zeros((2, self.n))
        ab[0, 1:] = -phi[1:] * d2[1:]  # upper form: ab[0, k] = M[k-1, k]
        ab[1] = diag
        self.chol = cholesky_banded(ab, lower=False)
        self.logdet = float(2 * self.n * math.log(self.s_w) + np.sum(np.log(q)) + 2.0 * np.sum(np.log(self.chol[1])))

    def _d_times(self, b: np.ndarray) -> np.ndarray:
        out = self.d[:, None] * b
        out[1:] -= (self.d[1:] * self.phi[1:])[:, None] * b[:-1]
        return out

    def apply(self, r: np.ndarray) -> np.ndarray:
        """Weighted residuals of ``r`` (n,) or (n, k) -> (rows,) or (rows, k)."""
        r = np.asarray(r, dtype=float)
        one = r.ndim == 1
        r2 = r[:, None] if one else r
        if not self.wander:
            out = r2 / self.s_w
        else:
            b = cho_solve_banded((self.chol, False), r2 / self.s_w**2, check_finite=False)
            out = np.vstack([(r2 - b) / self.s_w, self._d_times(b)])
        return out[:, 0] if one else out

    def solve(self, v: np.ndarray) -> np.ndarray:
        """S^-1 v (Woodbury: (v - M^-1 v / s_w^2) / s_w^2)."""
        if not self.wander:
            return v / self.s_w**2
        b = cho_solve_banded((self.chol, False), v / self.s_w**2, check_finite=False)
        return (v - b) / self.s_w**2

    def log_det(self) -> float:
        return float(self.logdet) if self.wander else 2.0 * self.n * math.log(self.s_w)


def restricted_deviance(series, noise: ChannelNoise) -> float:
    """-2 restricted log-likelihood (constant dropped) of residual series.

    Each item is ``(t_s, r)`` (its mean is what the fit absorbed) or ``(blocks, design)``: blocks
    [(t_s, r), ...] of one trial that share the fitted parameters whose sensitivities are the columns
    of ``design`` (rows: the blocks' samples in order). Restricted likelihood counts what the fit
    absorbed: without it the noise left after fitting initial states looks whiter and smaller than
    the sensor's (a 45 s wander came out at 9 s, and the intervals with it)."""
    total = 0.0
    for item in series:
        blocks, design = _blocks(item)
        n = sum(r.size for _, r in blocks)
        if n <= design.shape[1]:
            continue
        quad, logdet, xtr, xtx, row = 0.0, 0.0, np.zeros(design.shape[1]), np.zeros((design.shape[1],) * 2), 0
        for t, r in blocks:
            x = design[row : row + r.size]
            row += r.size
            w = Whitener(t, noise)
            sol = w.solve(np.column_stack([r, x]))
            quad += float(r @ sol[:, 0])
            xtr += x.T @ sol[:, 0]
            xtx += x.T @ sol[:, 1:]
            logdet += w.log_det()
        sign, logdet_x = np.linalg.slogdet(xtx)
        if sign <= 0:
            continue
        total += logdet + logdet_x + quad - float(xtr @ np.linalg.solve(xtx, xtr))
    return total


def _blocks(item):
    first, second = item
    if isinstance(first, list):
        return first, np.asarray(second, dtype=float)
    t, r = np.asarray(first, float), np.asarray(second, float)
    return [(t, r)], np.ones((r.size, 1))


def estimate(series, bounds: tuple, start: ChannelNoise | None = None, time_prior: tuple | None = None) -> ChannelNoise:
    """Restricted maximum-likelihood noise of a channel from residual series, inside ``bounds``
    ((white lo, hi), (wander lo, hi), (time lo, hi) as NoiseBounds.channel), with the log-normal
    prior ``time_prior`` = (centre s, factor for one sigma) on the correlation time when given
    (NoiseBounds.time_prior: trials about as long as the correlation time cannot pin it down)."""
    from scipy.optimize import minimize

    series = [item for item in series if sum(r.size for _, r in _blocks(item)[0]) >= 2]
    if not series:
        (w_lo, _), _, (t_lo, _) = bounds
        return ChannelNoise(w_lo, 0.0, t_lo)
    lo = np.log([b[0] for b in bounds])
    hi = np.log([b[1] for b in bounds])
    if start is None:
        spread = math.sqrt(float(np.mean(np.concatenate([r - r.mean() for item in series for _, r in _blocks(item)[0]]) ** 2)))
        z0 = np.log([0.3 * spread, 0.8 * spread, 30.0])
    else:
        z0 = np.log([start.white, max(start.wander, 1e-9), start.time_s])
    z0 = np.clip(z0, lo + 1e-6, hi - 1e-6)

    def f(z):
        prior = 0.0 if time_prior is None else ((z[2] - math.log(time_prior[0])) / math.log(time_prior[1])) ** 2
        return restricted_deviance(series, ChannelNoise(*np.exp(z))) + prior

    best = minimize(f, z0, method="L-BFGS-B", bounds=list(zip(lo, hi)), options={"maxiter": 60})
    return ChannelNoise(*(float(x) for x in np.exp(best.x)))


def outliers(t_s: np.ndarray, y: np.ndarray, *, neighbours: int, window_s: float, floor: float,
             k: float = 6.0, skip: int = 0, bad: np.ndarray | None = None) -> np.ndarray:
    """Outliers of a smooth series, without a model: each sample against a quadratic through its
    ``neighbours`` nearest valid neighbours within ``window_s`` (itself left out); flagged above
    max(k robust sigmas, ``floor``), the worst first, the others judged again without it.

    ``skip`` > 0 also judges each sample against a quadratic through neighbours beyond the ``skip``
    nearest valid ones on each side (two-sided only; its window widened in proportion): a burst of
    outliers with one offset (multipath holding a receiver on a wrong solution for a few fixes) pulls
    the plain fit through its own members, hiding the burst and flagging the clean fixes beside it,
    but not this one. A sample's score is the larger of its two errors, each over its own limit;
    flagged one at a time, a burst goes from the middle out, up to about 2 (skip + 1) fixes long.
    ``bad``: samples already left out (no one's neighbour; flagged in the mask returned). Returns a boolean mask."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    bad = np.zeros(t.size, dtype=bool) if bad is None else np.array(bad, dtype=bool)
    if t.size < neighbours + 4:
        return bad
    half = max(neighbours // 2, 1)
    stencils = [(0, window_s)] + ([(skip, window_s * (skip + half) / half)] if skip > 0 else [])
    while True:
        score = np.full(t.size, -np.inf)
        for gap, window in stencils:
            err, gain = _leave_one_out_errors(t, y, bad, neighbours, window, skip=gap, with_gain=True)
            ok = np.isfinite(err)
            if ok.sum() < 5:
                if gap == 0:
                    return bad
                continue
            limit = max(k * 1.4826 * float(np.median(np.abs(err[ok]))), floor)
            if gap == 0:
                err, ok = _with_ends(t, y, bad, neighbours, window, err, gain, ok)
            score = np.where(ok, np.maximum(score, np.abs(np.where(ok, err, 0.0)) / limit), score)
        worst = int(np.argmax(score))
        if not score[worst] > 1.0:
            return bad
        bad[worst] = True


END_WINDOW_FACTOR = 2.0  # the ends' one-sided neighbours are looked for this much farther


def _with_ends(t, y, bad, neighbours: int, window_s: float, err, gain, ok):
    """``err`` with the samples it could not judge (the first and last of a series, one beside a gap: their
    nearest neighbours lie on one side, beyond ``window_s``) judged by the straight line through neighbours
    within ``END_WINDOW_FACTOR`` times it, extrapolated (a quadratic amplified the noise 30-fold two seconds
    out), its error scaled to an interior sample's noise (by sqrt((1 + gain) / (1 + gain_end))). Unjudged, a 40-m
    first fix of a trial bent its neighbours' fits instead: three good fixes were flagged, the glitch
    kept, and a correct model was `unexplained`."""
    far, far_gain = _leave_one_out_errors(t, y, bad, neighbours, window_s * END_WINDOW_FACTOR, with_gain=True,
                                          degree=1)
    ends = ~ok & np.isfinite(far)
    if not ends.any():
        return err, ok
    inner_gain = float(np.median(gain[ok]))
    scaled = far * np.sqrt((1.0 + inner_gain) / (1.0 + np.where(ends, far_gain, 0.0)))
    return np.where(ends, scaled, err), ok | ends


def _leave_one_out_errors(t, y, bad, neighbours: int, window_s: float, *, with_gain: bool = False, skip: int = 0,
                          degree: int = 2):
    """Each sample minus the quadratic through its nearest valid neighbours at its time (NaN where too
    few within ``window_s``); with ``with_gain`` also sum(w^2) of the prediction's weights (the error's
    variance for white noise s^2 is s^2 (1 + sum w^2)). ``skip`` > 0: the neighbours beyond the ``skip``
    nearest valid ones on each side, on both sides (NaN where one side has none). Vectorised over the
    samples."""
    err = np.full(t.size, np.nan)
    gain = np.full(t.size, np.nan)
    good = np.flatnonzero(~bad)
    n = good.size
    if n > neighbours + 2 * skip:
        tg, yg = t[good], y[good]
        offsets = np.r_[np.arange(-neighbours - skip, -skip), np.arange(skip + 1, skip + neighbours + 1)]
        cand = np.arange(n)[:, None] + offsets[None, :]  # positions in the good samples
        inside = (cand >= 0) & (cand < n)
        cand_c = np.clip(cand, 0, n - 1)
        dt = np.where(inside, tg[cand_c] - tg[:, None], np.inf)
        order = np.argsort(np.abs(dt), axis=1, kind="stable")[:, :neighbours]
        pick = np.take_along_axis(cand_c, order, axis=1)
        dtp = np.take_along_axis(dt, order, axis=1)
        ok = np.all(np.abs(dtp) <= window_s, axis=1)
        if skip > 0:  # across the gap, not extrapolated past it
            ok &= np.any(dtp < 0.0, axis=1) & np.any(dtp > 0.0, axis=1)
        if ok.any():
            d = dtp[ok]
            vander = np.stack([d ** p for p in range(degree, -1, -1)], axis=2)  # (m, neighbours, degree + 1)
            w = np.linalg.pinv(vander)[:, degree, :]  # weights of the fitted value at dt = 0
            err[good[ok]] = yg[ok] - np.sum(w * yg[pick[ok]], axis=1)
            gain[good[ok]] = np.sum(w * w, axis=1)
    return (err, gain) if with_gain else err


def white_scale(t_s: np.ndarray, y: np.ndarray, *, neighbours: int, window_s: float, bad=None) -> float | None:
    """A model-free estimate of the white part of a smooth series' noise: the robust spread of the
    leave-one-out errors (:func:`outliers`' local quadratics), each divided by sqrt(1 + sum w^2).
    Slow wander and the motion pass the local quadratic almost untouched; None when too short."""
    t, y = np.asarray(t_s, float), np.asarray(y, float)
    if t.size < neighbours + 4:
        return None
    err, gain = _leave_one_out_errors(t, y, np.zeros(t.size, bool) if bad is None else bad, neighbours, window_s,
                                      with_gain=True)
    ok = np.isfinite(err)
    if ok.sum() < 5:
        return None
    return float(1.4826 * np.median(np.abs(err[ok]) / np.sqrt(1.0 + gain[ok])))


def gated_fixes(t_s: np.ndarray, north_m: np.ndarray, east_m: np.ndarray, sog_m_s: np.ndarray | None = None,
                rules=None) -> np.ndarray:
    """Fixes beyond the daemon's fix gate (:func:`autopilot.gnc.navigation.gate_fix`, its rule and its
    ``NavRules``: a fix farther from the last one used than ``position_jump_m`` plus the receiver's speed over
    ground and a margin times the time between them), judged with hindsight over the whole series. Returns a
    boolean mask.

    The series is cut where a fix fails the gate from the fix before it, or lies, an epoch after it, farther
    from it than CUT_FRACTION of ``position_jump_m`` (a burst 28 m off passes on the speed allowance; a burst
    20 m off inside one 35 m off leaves it by a step the gate passes, and uncut, the clean fixes after it
    were left out with it). Each cut is a jump: the
    step between the fixes beside it less the boat's own motion (the velocity of the fixes before it). The part
    with the most fixes is the track; a part whose jumps from it add up to more than ``position_jump_m`` is left
    out. On line the daemon believes a second fix that agrees with a refused one (the boat may have moved): a
    multipath burst of several fixes 40 m off was refused at its first fix only, and the identification,
    taking the rest, answered ``unexplained``. With hindsight the jump out and the jump back cancel, and the
    fixes after the burst join the track again. ``sog_m_s``: the receiver's speed over ground at each fix;
    where it has none, the median speed between the fixes around it (FIX_SPEED_NEIGHBOURS a side: a burst's two
    jumps do not move the median; the daemon, without one, allows its largest speed, 10 m/s, and a 6-fix burst
    30 m off passed: 25 m + 10 m/s x 1 s)."""
    from autopilot.devices import Stamped
    from autopilot.geo import local_to_latlon
    from autopilot.gnc.navigation import NavMemory, NavRules, gate_fix

    rules = rules or NavRules()
    t = np.asarray(t_s, dtype=float)
    north_m, east_m = np.asarray(north_m, dtype=float), np.asarray(east_m, dtype=float)
    bad = np.zeros(t.size, dtype=bool)
    if t.size < 3:
        return bad
    lat, lon = local_to_latlon(north_m, east_m, 0.0, 0.0)
    sog = np.full(t.size, np.nan) if sog_m_s is None else np.array(sog_m_s, dtype=float)
    if not np.isfinite(sog).all():
        sog = np.where(np.isfinite(sog), sog, _fix_speeds(t, north_m, east_m))

    def passes(i: int, j: int) -> bool:
        """Fix j passes the gate with fix i, before it, the last one used."""
        last = Stamped((float(lat[i]), float(lon[i])), float(t[i]), "GGA", True)
        pos = Stamped((float(lat[j]), float(lon[j])), float(t[j]), "GGA", True)
        memory = NavMemory(fix=last, judged_t_s=last.t_s, anchored_t_s=last.t_s, confirmed=True)
        return gate_fix(pos, memory, rules, float(sog[j])).jump is None

    ne = np.column_stack([north_m, east_m])
    dt = np.diff(t)
    epoch_s = 1.5 * float(np.median(dt))
    step = np.hypot(np.diff(north_m), np.diff(east_m))

    def velocity_before(k: int, start: int) -> np.ndarray:
        """The boat's velocity over ground (m/s) at fix k, from the fixes of its part (from ``start``) up to
        VELOCITY_BASELINE_S back (one pair of fixes 0.2 s apart carries the wander's step tenfold); 0 alone."""
        a = max(start, int(np.searchsorted(t, t[k] - VELOCITY_BASELINE_S)))
        return (ne[k] - ne[a]) / (t[k] - t[a]) if t[k] - t[a] >= MIN_BASELINE_S else np.zeros(2)

    # cut where the gate refuses a fix after the one before it, where a fix lies an epoch after it farther than
    # CUT_FRACTION of position_jump_m, and, across a gap, where a part that began with a jump comes back by more than
    # that to within position_jump_m of the track an earlier part was on (after a 3-s dropout the gate had grown
    # with the gap, 25 m + 4 m/s x 4 s, and the 40-m way back from a burst passed it: the clean fixes after were
    # joined to the burst and left out with it, a review). Not on a gap alone: a 5-s dropout in a 6-m turn at 3 m/s
    # lies ~20 m off the straight motion
    cuts, jumps, start, offsets = [], [], 0, [np.zeros(2)]
    for k in range(t.size - 1):
        off = ne[k + 1] - ne[k] - velocity_before(k, start) * dt[k]
        back = (dt[k] > epoch_s and start > 0 and np.hypot(*off) > CUT_FRACTION * rules.position_jump_m
                and any(np.hypot(*(offsets[-1] + off - o)) <= rules.position_jump_m for o in offsets[:-1]))
        if (step[k] > CUT_FRACTION * rules.position_jump_m and dt[k] <= epoch_s) or not passes(k, k + 1) or back:
            cuts.append(k)
            jumps.append(off)
            offsets.append(offsets[-1] + off)
            start = k + 1
    if not cuts:
        return bad
    starts = [0] + [k + 1 for k in cuts]
    parts = [np.arange(a, b) for a, b in zip(starts, starts[1:] + [t.size])]
    offset = np.array(offsets)  # each part's, from the first
    # the track is the largest group of parts whose offsets agree within position_jump_m (the way out to a burst
    # and back cancel): taken as the single largest part, a burst longer than the clean stretch on either side
    # was kept and the 21 clean fixes around it left out (a review)
    groups: list[list[int]] = []
    for q in range(len(parts)):
        home = next((g for g in groups if np.hypot(*(offset[q] - offset[g[0]])) <= rules.position_jump_m), None)
        if home is None:
            groups.append([q])
        else:
            home.append(q)
    track = max(groups, key=lambda g: (sum(parts[q].size for q in g), -g[0]))
    for q, part in enumerate(parts):
        if q not in track:
            bad[part] = True
    return bad


VELOCITY_BASELINE_S = 3.0  # gated_fixes: the boat's motion at a cut from its fixes up to this far back
MIN_BASELINE_S = 0.5  # ... over at least this long (else none)
CUT_FRACTION = 0.5  # gated_fixes: a step of this share of position_jump_m within an epoch is a jump (a WAM-V: <= 4 m)
FIX_SPEED_NEIGHBOURS = 5  # fix-to-fix speeds a side whose median stands in for a missing speed over ground


def _fix_speeds(t: np.ndarray, north: np.ndarray, east: np.ndarray) -> np.ndarray:
    """Per fix the median of the fix-to-fix speeds (m/s) within FIX_SPEED_NEIGHBOURS intervals a side."""
    step = np.hypot(np.diff(north), np.diff(east)) / np.maximum(np.diff(t), MIN_DT_S)
    k = FIX_SPEED_NEIGHBOURS
    return np.array([float(np.median(step[max(i - k, 0):i + k])) for i in range(t.size)])
