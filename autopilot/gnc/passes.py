"""Closest approach to each waypoint over its whole pass, from measured position fixes.

One definition, used by the daemon (the ``waypoint_pass`` log event), ``autopilot
evaluate`` and ``autopilot review``:

    The pass of waypoint W_i begins with the first fix taken while W_i is the target
    and ends when W_{i+1} is reached (the boat has steered to W_i, switched, and left
    it behind), or when the mission ends. Its closest approach is the smallest
    distance from W_i of the position fixes measured during the pass.

Why: the guidance switches to the next waypoint as soon as it counts W_i reached
(within the capture radius, or passed abeam, TCPA' < 0), and the boat goes on
closing on W_i for a while after that; the distance at the switch is not how close
it came. Fixes, not dead-reckoned estimates: what the GPS measured is the evidence
(at 1 Hz and 1 m/s the true closest point may lie up to ~0.5 m nearer than the
nearest fix). Pure: numbers in, numbers out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Pass", "PassTracker", "closest_per_pass"]


@dataclass(frozen=True)
class Pass:
    """The closest fix of one waypoint's pass (NaN fields when the pass had no fix)."""

    wp_index: int
    closest_approach_m: float
    t_s: float
    north_m: float
    east_m: float
    fixes: int


class PassTracker:
    """Incremental closest approach per pass; feed fixes in time order.

    ``on_fix(t_s, north_m, east_m, target)`` for every new fix, with the index of the
    waypoint being steered to when the fix was taken; ``on_target(target)`` when the
    target changes (it closes the passes that ended); ``finish()`` at the end of the
    mission closes the rest. Each method returns the passes it closed, in order.
    """

    def __init__(self, waypoints_ne_m, *, start_index: int = 0) -> None:
        self._wps = [(float(n), float(e)) for n, e in waypoints_ne_m]
        self._open: dict[int, list] = {}  # wp -> [distance, t, north, east, fixes]
        self._next_to_open = int(start_index)
        self._target = int(start_index)

    def _ensure_open(self, upto: int) -> None:
        while self._next_to_open <= min(upto, len(self._wps) - 1):
            self._open[self._next_to_open] = [math.inf, math.nan, math.nan, math.nan, 0]
            self._next_to_open += 1

    def _close(self, i: int) -> Pass:
        d, t, n, e, k = self._open.pop(i)
        return Pass(i, d if k else math.nan, t, n, e, k)

    def on_target(self, target: int) -> list[Pass]:
        """The guidance now steers to ``target``: the passes of waypoints before ``target - 1`` end."""
        self._target = int(target)
        self._ensure_open(self._target)
        return [self._close(i) for i in sorted(self._open) if i <= self._target - 2]

    def on_fix(self, t_s: float, north_m: float, east_m: float, target: int) -> list[Pass]:
        """A new fix taken while steering to ``target``; updates the passes of ``target - 1`` and ``target``."""
        closed = self.on_target(target) if target != self._target else []
        self._ensure_open(self._target)
        if not (math.isfinite(north_m) and math.isfinite(east_m)):
            return closed
        for i in (self._target - 1, self._target):
            rec = self._open.get(i)
            if rec is None:
                continue
            wn, we = self._wps[i]
            d = math.hypot(north_m - wn, east_m - we)
            rec[4] += 1
            if d < rec[0]:
                rec[0], rec[1], rec[2], rec[3] = d, float(t_s), float(north_m), float(east_m)
        return closed

    def finish(self) -> list[Pass]:
        """The mission ended: every open pass ends with it."""
        return [self._close(i) for i in sorted(self._open)]


def closest_per_pass(t_s, north_m, east_m, target, waypoints_ne_m, *, start_index: int = 0) -> list[Pass]:
    """Every waypoint's pass from a table of fixes (one entry per fix, in time order).

    Waypoints whose pass never began (the mission ended before them) get a Pass with NaN.
    """
    n_wps = len(waypoints_ne_m)
    tracker = PassTracker(waypoints_ne_m, start_index=start_index)
    done: dict[int, Pass] = {}
    for t, n, e, k in zip(t_s, north_m, east_m, target):
        for p in tracker.on_fix(float(t), float(n), float(e), int(k)):
            done[p.wp_index] = p
    for p in tracker.finish():
        done[p.wp_index] = p
    return [done.get(i, Pass(i, math.nan, math.nan, math.nan, math.nan, 0)) for i in range(n_wps)]
