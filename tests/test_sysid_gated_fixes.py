"""noise.gated_fixes on bursts a real receiver gives. Found by a review: the single part with the most fixes was
taken as the track, so a burst longer than the clean stretch on either side was kept and the clean fixes left out;
and after a dropout the way back from a burst passed the daemon's gate grown with the gap, joining the clean fixes
after it to the burst (25-70 % of random burst directions with a 2-5 s dropout)."""

from __future__ import annotations

import numpy as np

from autopilot.sysid.noise import gated_fixes


def _track(n: int, speed: float = 2.0):
    t = np.arange(n, dtype=float) + 0.37
    north = speed * (t - t[0])
    east = 0.3 * np.sin(t / 3.0)  # a little GPS wander
    return t, north, east


def test_a_burst_longer_than_the_clean_stretch_on_either_side_keeps_the_burst():
    """33 fixes at 1 Hz, a boat at 2 m/s; fixes 10-21 (12) held 40 m east (the project's own burst model:
    GpsErrorModel outlier_fixes up to 60). 21 clean fixes, 12 burst ones: the burst should go."""
    t, north, east = _track(33)
    burst = np.zeros(t.size, dtype=bool)
    burst[10:22] = True
    east = east + np.where(burst, 40.0, 0.0)
    gated = gated_fixes(t, north, east, np.full(t.size, 2.0))
    assert not gated[~burst].any(), f"{int(gated[~burst].sum())} clean fixes left out, {int((~gated[burst]).sum())} burst fixes kept"
    assert gated[burst].all()


def test_robust_cases_pass():
    """Sanity: tight turns, dropouts, mixed steps, a stationary boat, few fixes: nothing gated, no crash."""
    t = np.arange(0.0, 60.0, 1.0)
    psi = 0.5 * t  # 0.5 rad/s at 3 m/s: a 6-m radius
    n, e = 6.0 * np.sin(psi), 6.0 * (1 - np.cos(psi))
    assert not gated_fixes(t, n, e, np.full(t.size, 3.0)).any()
    keep = np.ones(t.size, dtype=bool)
    keep[20:25] = False  # a 5-s dropout in the turn
    assert not gated_fixes(t[keep], n[keep], e[keep]).any()
    tm = np.sort(np.r_[np.arange(0, 20, 0.2), np.arange(20, 60, 1.0)])
    assert not gated_fixes(tm, 3 * tm, 0 * tm).any()
    rng = np.random.default_rng(1)
    assert not gated_fixes(t, 2 * rng.standard_normal(t.size), 2 * rng.standard_normal(t.size)).any()
    for k in (0, 1, 2, 3):
        gated_fixes(t[:k], n[:k], e[:k])
    gated_fixes(np.zeros(5), np.arange(5.0) * 20, np.zeros(5))
    gated_fixes(t, n, e, np.full(t.size, np.nan))


def test_a_burst_followed_by_a_short_dropout_is_left_out_and_nothing_else():
    """60 s at 1 Hz, 2 m/s north; fixes 20-27 (8) 40 m east (as GpsErrorModel bursts), then a 3-s dropout
    (fixes 28-30 lost, common as multipath ends). The return from the burst is 41 m in 4 s: within the daemon's
    gate grown with the gap (25 m + 4 m/s x 4 s), and no step cut (the gap is over 1.5 epochs), so the fixes
    after the dropout are glued to the burst."""
    t = np.arange(0.0, 60.0, 1.0)
    keep = ~((t >= 28) & (t <= 30))
    north, east = 2.0 * t, np.zeros(t.size)
    burst = (t >= 20) & (t <= 27)
    east = east + np.where(burst, 40.0, 0.0)
    t, north, east, burst = t[keep], north[keep], east[keep], burst[keep]
    gated = gated_fixes(t, north, east, np.full(t.size, 2.0))
    assert not gated[~burst].any(), f"{int(gated[~burst].sum())} clean fixes left out, {int((~gated[burst]).sum())} burst fixes kept"
    assert gated[burst].all()
