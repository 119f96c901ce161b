"""A small Mamdani fuzzy inference engine (thesis 6.2, SPEC section 7).

Two crisp inputs, triangular membership functions, a rule table mapping
(input-1 set, input-2 set) -> output set, min-max inference and
centre-of-gravity defuzzification over a sampled output universe (Eq 6.9):

    CDH = sum_k y_k mu(y_k) / sum_k mu(y_k)

with mu(y) = max over rules of min(firing strength, mu_out(y)) and the firing
strength of a rule = min(mu_1(x_1), mu_2(x_2)).

Two evaluation paths give the same numbers: :meth:`Mamdani.evaluate` is
vectorised (numpy, whole control surfaces at once) and
:meth:`Mamdani.evaluate_scalar` is plain Python floats, which is several
times faster than numpy for one point per control cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from autopilot.mathutil import clamp

Triangle = tuple[float, float, float]  # (left foot, peak, right foot)


def tri(x, a: float, b: float, c: float):
    """Triangular membership of x (scalar or array) in the triangle (a, b, c).

    a == b (or b == c) gives a vertical side: a shoulder whose peak is an edge.
    """
    x = np.asarray(x, dtype=float)
    up = (x - a) / (b - a) if b > a else np.where(x >= b, 1.0, 0.0)
    down = (c - x) / (c - b) if c > b else np.where(x <= b, 1.0, 0.0)
    out = np.clip(np.minimum(up, down), 0.0, 1.0)
    return float(out) if out.ndim == 0 else out


def _tri_scalar(x: float, a: float, b: float, c: float) -> float:
    up = (x - a) / (b - a) if b > a else (1.0 if x >= b else 0.0)
    down = (c - x) / (c - b) if c > b else (1.0 if x <= b else 0.0)
    m = up if up < down else down
    return clamp(m, 0.0, 1.0)


def uniform_partition(lo: float, hi: float, n: int, *, extend: bool = False) -> tuple[Triangle, ...]:
    """``n`` triangles evenly spaced over [lo, hi], neighbours crossing at 0.5.

    With ``extend`` the end triangles are symmetric and reach half a step
    beyond the universe (so that a fully fired end set defuzzifies exactly
    to ``lo`` or ``hi``); without it the end triangles are shoulders whose
    peak sits on the universe edge.
    """
    if n < 2 or not hi > lo:
        raise ValueError("uniform_partition needs n >= 2 and hi > lo")
    step = (hi - lo) / (n - 1)
    out = []
    for k in range(n):
        peak = lo + k * step
        left = peak - step if (k > 0 or extend) else peak
        right = peak + step if (k < n - 1 or extend) else peak
        out.append((left, peak, right))
    return tuple(out)


@dataclass(frozen=True)
class Mamdani:
    """Two-input, one-output Mamdani system.

    ``rules[i][j]`` is the index of the output set fired by input-1 set i and
    input-2 set j. Inputs outside their universes are clamped to the edge
    (the end sets are shoulders: "larger than large" is still large).
    """

    in1_sets: tuple[Triangle, ...]
    in2_sets: tuple[Triangle, ...]
    out_sets: tuple[Triangle, ...]
    rules: tuple[tuple[int, ...], ...]
    in1_range: tuple[float, float]
    in2_range: tuple[float, float]
    out_range: tuple[float, float]
    n_points: int = 201

    def __post_init__(self) -> None:
        if len(self.rules) != len(self.in1_sets) or any(len(r) != len(self.in2_sets) for r in self.rules):
            raise ValueError("rule table shape must be (len(in1_sets), len(in2_sets))")
        if any(not 0 <= k < len(self.out_sets) for r in self.rules for k in r):
            raise ValueError("rule table refers to an output set that does not exist")
        if self.n_points < 3:
            raise ValueError("n_points must be >= 3")
        # sampled output universe and each set's membership there, both as arrays
        # (vector path) and as, per sample, the few non-zero (set, mu) pairs (scalar path)
        y = np.linspace(self.out_range[0], self.out_range[1], self.n_points)
        mu = np.array([tri(y, *s) for s in self.out_sets])  # (n_sets, n_points)
        object.__setattr__(self, "_y", y)
        object.__setattr__(self, "_mu_out", mu)
        nz = tuple(
            (float(y[p]), tuple((k, float(mu[k, p])) for k in range(len(self.out_sets)) if mu[k, p] > 0.0))
            for p in range(self.n_points)
        )
        object.__setattr__(self, "_nonzero", nz)
        object.__setattr__(self, "_rules_flat", tuple((i, j, k) for i, r in enumerate(self.rules) for j, k in enumerate(r)))

    # ------------------------------------------------------------------ vectorised
    def evaluate(self, x1, x2) -> np.ndarray:
        """Crisp output for arrays x1, x2 (broadcast together); Eq 6.9."""
        x1 = np.clip(np.asarray(x1, dtype=float), *self.in1_range)
        x2 = np.clip(np.asarray(x2, dtype=float), *self.in2_range)
        x1, x2 = np.broadcast_arrays(x1, x2)
        shape = x1.shape
        a = np.stack([tri(x1.ravel(), *s) for s in self.in1_sets], axis=-1)  # (n, n1)
        b = np.stack([tri(x2.ravel(), *s) for s in self.in2_sets], axis=-1)  # (n, n2)
        fire = np.minimum(a[:, :, None], b[:, None, :])  # (n, n1, n2) min (AND)
        rules = np.asarray(self.rules)
        strength = np.zeros((fire.shape[0], len(self.out_sets)))
        for k in range(len(self.out_sets)):  # max over rules with the same consequent
            mask = rules == k
            if mask.any():
                strength[:, k] = fire[:, mask].max(axis=1)
        clipped = np.minimum(strength[:, :, None], self._mu_out[None, :, :])  # implication: min
        agg = clipped.max(axis=1)  # aggregation: max
        den = agg.sum(axis=1)
        num = (agg * self._y[None, :]).sum(axis=1)
        mid = 0.5 * (self.out_range[0] + self.out_range[1])
        out = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), mid)
        return out.reshape(shape)

    # ------------------------------------------------------------------ scalar
    def evaluate_scalar(self, x1: float, x2: float) -> float:
        """Crisp output for one point, plain Python (same numbers as :meth:`evaluate`)."""
        lo1, hi1 = self.in1_range
        lo2, hi2 = self.in2_range
        x1 = clamp(x1, lo1, hi1)
        x2 = clamp(x2, lo2, hi2)
        a = [_tri_scalar(x1, *s) for s in self.in1_sets]
        b = [_tri_scalar(x2, *s) for s in self.in2_sets]
        strength = [0.0] * len(self.out_sets)
        for i, j, k in self._rules_flat:
            ai = a[i]
            if ai <= 0.0:
                continue
            w = ai if ai < b[j] else b[j]
            if w > strength[k]:
                strength[k] = w
        num = den = 0.0
        for y, pairs in self._nonzero:
            m = 0.0
            for k, mu in pairs:
                s = strength[k]
                v = s if s < mu else mu
                if v > m:
                    m = v
            num += y * m
            den += m
        if den <= 0.0:
            return 0.5 * (self.out_range[0] + self.out_range[1])
        return num / den


def rule_indices(table: Sequence[Sequence[str]], names: Sequence[str]) -> tuple[tuple[int, ...], ...]:
    """A rule table written with set names -> the same table of set indices."""
    index = {n: i for i, n in enumerate(names)}
    return tuple(tuple(index[c] for c in row) for row in table)
