"""Batched replay of trials through the simulator with candidate effects, and its residuals.

All trials are put on one uniform time grid (the median row interval), thrust
held from each command to the next (the motors hold their last command). A
*run* is one trial with one initial state and one set of effect values; many
runs are integrated in a single batched ``simulate`` call, so a
finite-difference Jacobian over all trials costs one call. The effects act
through their own hooks (:mod:`autopilot.sysid.effects`); this module names none.

Measurements are compared at the times they were measured (``Trial.position_time_s``,
``heading_time_s``; the prediction interpolated on the grid), weighted by the
noise model of :mod:`autopilot.sysid.noise` (wandering + white, one per channel).
Outliers are rejected here, before any fit: the fixes beyond the daemon's fix gate (noise.gated_fixes), then
single samples and short bursts without a model (noise.outliers); counted, and their times kept for the notes.

Initial state of a run: (north_m, east_m, psi_rad, u_m_s, v_m_s, r_rad_s) at
the trial's first row, u and v over ground (the shared state contract).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.geo import wrap_pi
from autopilot.sim import STATE_NAMES, VesselParams, simulate
from autopilot.sysid.channels import CHANNELS, HEADING, POSITION, VELOCITY, Channel
from autopilot.sysid.effects import (
    BY_NAME,
    SENSED_EFFECTS,
    THRUST_EFFECTS,
)
from autopilot.sysid.noise import ChannelNoise, Whitener, gated_fixes, outliers, white_scale
from autopilot.sysid.trials import Trial

SCALAR_MAX_RUNS = 24  # below this many runs the scalar loop beats numpy batching
# model-free outlier rejection (noise.outliers): a fix against its 4 nearest neighbours (a 1 Hz GPS:
# +-2 s, where a turning boat's track is still a quadratic to ~0.7 m), a heading against 6 (+-0.3 s; a heading
# held on a row without its time, 0.1 s old at 0.3 rad/s, is 1.7 deg off), a velocity against 4 (a thrust
# step changes the acceleration at once: a quadratic over +-2 s misses it by ~0.1 m/s)
# the replay's step: the rows' interval, at most this (the daemon's period). Rows of a 1 Hz logger taken as the
# step integrated the model a second at a time: NaN residuals and a "nearest: wind"; at 2-3 Hz spurious effects
STEP_MAX_S = 0.1
OUTLIER_POSITION_M = 3.0
OUTLIER_HEADING_RAD = math.radians(1.0)
OUTLIER_VELOCITY_M_S = 0.5
# (neighbours, window_s, floor) of the outlier test and the model-free white-noise estimate, per channel
LOCAL_FIT = {"position": (4, 4.0, OUTLIER_POSITION_M), "heading": (6, 1.0, OUTLIER_HEADING_RAD),
             "velocity": (4, 4.0, OUTLIER_VELOCITY_M_S)}
# fixes skipped on each side by the outlier test's second fit (noise.outliers): a GPS multipath burst holds a
# few consecutive fixes on one wrong solution, which the plain fit follows (a 3-fix burst of 10 m went
# unflagged, the clean fixes beside it flagged instead, and the residual it left was judged a missing effect)
OUTLIER_SKIP = {"position": 1, "heading": 0, "velocity": 0}
CHANNEL_NAMES = tuple(c.name for c in CHANNELS)


@dataclass(frozen=True)
class Noise:
    """The noise model of each channel (shared by all trials: one receiver, one compass); velocity None
    when the trials carry no speed and course over ground."""

    position: ChannelNoise
    heading: ChannelNoise
    velocity: ChannelNoise | None = None

    def of(self, channel: str) -> ChannelNoise | None:
        return getattr(self, channel)


@dataclass(frozen=True)
class Samples:
    """One channel's measurements of one trial at their times, with their interpolation on the grid."""

    t_s: np.ndarray  # (n,)
    values: np.ndarray  # (components, n), SI (the heading unwrapped as measured, wrapped in residuals)
    at: tuple[np.ndarray, np.ndarray]  # (grid index k, weight of k + 1)
    rejected: int  # outliers rejected (single samples and bursts; the gated fixes among them)
    white: float | None  # model-free estimate of the white noise (noise.white_scale), None when too short
    rejected_t_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # when the rejected ones were measured
    gated: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # which of them the fix gate refused

    @property
    def size(self) -> int:
        return self.t_s.size


@dataclass(frozen=True)
class Measured:
    """One trial's measurements, per channel (``series``: only the channels the trial has)."""

    series: dict  # channel name -> Samples

    def get(self, channel: str) -> Samples | None:
        return self.series.get(channel)

    # the two channels every trial has, by name, for the readers of tracks and headings
    @property
    def t_pos_s(self) -> np.ndarray:
        return self.series["position"].t_s

    @property
    def north_m(self) -> np.ndarray:
        return self.series["position"].values[0]

    @property
    def east_m(self) -> np.ndarray:
        return self.series["position"].values[1]

    @property
    def t_psi_s(self) -> np.ndarray:
        return self.series["heading"].t_s

    @property
    def psi_rad(self) -> np.ndarray:
        return self.series["heading"].values[0]


@dataclass(frozen=True)
class Prepared:
    """Trials on a common grid with their measurements, noise model and weights."""

    trials: tuple[Trial, ...]
    dt_s: float
    t_grid: np.ndarray  # (G,)
    thrust_port_n: np.ndarray  # (N, G) zero-order hold of the commands
    thrust_stbd_n: np.ndarray
    duty_port_pct: np.ndarray
    duty_stbd_pct: np.ndarray
    measured: tuple[Measured, ...]
    noise: Noise
    weights: dict  # channel name -> (Whitener per trial) for the channels of ``channels``

    @property
    def n_trials(self) -> int:
        return len(self.trials)

    @functools.cached_property
    def channels(self) -> tuple[Channel, ...]:
        """The channels some trial measured (position and heading always), in CHANNELS order."""
        return tuple(c for c in CHANNELS if any(c.name in m.series for m in self.measured))

    @property
    def has_velocity(self) -> bool:
        return VELOCITY in self.channels

    @property
    def pos_weights(self) -> tuple[Whitener, ...]:
        return self.weights["position"]

    def n_measurements(self, i: int) -> int:
        return sum(len(c.components) * self._size(i, c.name) for c in self.channels)

    def _size(self, i: int, channel: str) -> int:
        s = self.measured[i].get(channel)
        return 0 if s is None else s.size

    def n_rows(self, i: int) -> int:
        """Weighted residual rows of trial i (each channel's components in order)."""
        return sum(len(c.components) * self.weights[c.name][i].rows for c in self.channels)

    def row_blocks(self, i: int) -> list[tuple[Channel, int, int]]:
        """(channel, first row, rows per component) of trial i's weighted residuals, in order."""
        out, row = [], 0
        for c in self.channels:
            rows = self.weights[c.name][i].rows
            out.append((c, row, rows))
            row += len(c.components) * rows
        return out

    def with_noise(self, noise: Noise) -> Prepared:
        """The same trials weighted by another noise model."""
        weights = {}
        for c in CHANNELS:
            ch_noise = noise.of(c.name)
            if ch_noise is None or not any(c.name in m.series for m in self.measured):
                continue
            weights[c.name] = tuple(Whitener(_times(m, c.name), ch_noise) for m in self.measured)
        return dataclasses.replace(self, noise=noise, weights=weights)

    def subset(self, trials, end_s: float | None = None) -> Prepared:
        """Trials ``trials`` only (renumbered 0, 1, ...), cut at ``end_s`` when given (a fit's horizon)."""
        idx = list(trials)
        size = self.t_grid.size if end_s is None else int(min(self.t_grid.size, math.floor(end_s / self.dt_s + 1e-9) + 2))
        measured = []
        for i in idx:
            m = self.measured[i]
            if end_s is not None:
                m = Measured({name: _cut(s, s.t_s <= end_s) for name, s in m.series.items()})
            measured.append(m)
        cut = dataclasses.replace(
            self, trials=tuple(self.trials[i] for i in idx), t_grid=self.t_grid[:size],
            thrust_port_n=self.thrust_port_n[idx, :size], thrust_stbd_n=self.thrust_stbd_n[idx, :size],
            duty_port_pct=self.duty_port_pct[idx, :size], duty_stbd_pct=self.duty_stbd_pct[idx, :size],
            measured=tuple(measured))
        return cut.with_noise(self.noise)


def _times(m: Measured, channel: str) -> np.ndarray:
    s = m.get(channel)
    return np.zeros(0) if s is None else s.t_s


def _cut(s: Samples, keep: np.ndarray) -> Samples:
    return dataclasses.replace(s, t_s=s.t_s[keep], values=s.values[:, keep], at=tuple(a[keep] for a in s.at))


def _grid_weights(t_s: np.ndarray, dt_s: float, size: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.clip(np.floor(t_s / dt_s + 1e-9).astype(int), 0, size - 2)
    return k, np.clip(t_s / dt_s - k, 0.0, 1.0)


def _raw_samples(tr: Trial) -> dict:
    """channel -> (rows' measurement times, values (components, n)) of the trial's new measurements."""
    out = {}
    p = tr.fix_rows
    out["position"] = (tr.position_time_s[p], np.vstack([tr.north_m[p], tr.east_m[p]]))
    h = tr.heading_rows
    out["heading"] = (tr.heading_time_s[h], tr.heading_rad[h][None, :])
    v = tr.velocity_rows
    if v.size:
        sog, cog = tr.sog_m_s[v], tr.cog_rad[v]
        out["velocity"] = (tr.velocity_time_s[v], np.vstack([sog * np.cos(cog), sog * np.sin(cog)]))
    return out


def _samples(channel: str, t: np.ndarray, values: np.ndarray, end_s: float, dt_s: float, size: int,
             reject: bool, sog_m_s: np.ndarray | None = None) -> Samples:
    """One channel's measurements inside the trial, in time order, outliers rejected (any component): for
    positions first the fixes the daemon's fix gate refuses (noise.gated_fixes; ``sog_m_s`` per fix bounds the
    speed), then the model-free test on the rest."""
    inside = (t >= 0.0) & (t <= end_s)
    t, values = t[inside], values[:, inside]
    order = np.argsort(t, kind="stable")
    t, values = t[order], values[:, order]
    if channel == "heading":
        values = np.unwrap(values, axis=1)
    neighbours, window_s, floor = LOCAL_FIT[channel]
    bad = np.zeros(t.size, dtype=bool)
    gated = np.zeros(t.size, dtype=bool)
    if reject:
        if channel == "position":
            gated = gated_fixes(t, values[0], values[1], None if sog_m_s is None else sog_m_s[inside][order])
        bad |= gated
        for y in values:
            bad |= outliers(t, y, neighbours=neighbours, window_s=window_s, floor=floor, skip=OUTLIER_SKIP[channel],
                            bad=gated)
    rejected_t, gated = t[bad], gated[bad]
    t, values = t[~bad], values[:, ~bad]
    scales = [white_scale(t, y, neighbours=neighbours, window_s=window_s) for y in values]
    white = None if any(w is None for w in scales) else math.sqrt(sum(w * w for w in scales) / len(scales))
    return Samples(t, values, _grid_weights(t, dt_s, size), int(rejected_t.size), white, rejected_t, gated)


def _measured(tr: Trial, dt_s: float, size: int, reject: bool) -> Measured:
    end = tr.t_s[-1]
    sog = None if tr.sog_m_s is None else tr.sog_m_s[tr.fix_rows]  # the speed the receiver gave with each fix
    return Measured({name: _samples(name, t, values, end, dt_s, size, reject, sog if name == "position" else None)
                     for name, (t, values) in _raw_samples(tr).items()})


def _interval_means(t_rows: np.ndarray, u: np.ndarray, g: np.ndarray, dt_s: float) -> np.ndarray:
    """Mean over each grid interval [g, g + dt) of ``u`` held from each row's time to the next (before the
    first row: its value). The simulator holds a grid interval's value for the whole interval: a log's
    rows come a few milliseconds after the grid's times (the loop starts each cycle a little late), and
    the value *at* each grid time would be the previous row's: every command one step (0.1 s) late,
    which fits as a thrust lag of a tenth of a second (five calm closed-loop logs did)."""
    integral = np.concatenate([[0.0], np.cumsum(u[:-1] * np.diff(t_rows))])  # from t_rows[0] to each row

    def at(t):
        k = np.clip(np.searchsorted(t_rows, t, side="right") - 1, 0, t_rows.size - 1)
        return integral[k] + u[k] * (t - t_rows[k])

    return (at(g + dt_s) - at(g)) / dt_s


def firmware_stops(t_rows: np.ndarray, srcs, stalled_after: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Held commands' rows with the Mbed firmware's stop added: after each row the loop stalled after
    (``stalled_after``) whose next row came more than FIRMWARE_STOP_TIMEOUT_S later, a zero command that long after
    it (docs/mbed-protocol.md: both motors stop 0.5 s after the last valid command). A loop that stalls sends nothing,
    and the replay held its last command through a 1.5-s stall. Only a stall: across a line or two the log lost, the
    daemon went on sending (a review: at 5 Hz two lost lines are 0.6 s, and a stop there was never made)."""
    from autopilot.drivers.mbed_protocol import FIRMWARE_STOP_TIMEOUT_S

    late = np.flatnonzero(stalled_after[:-1] & (np.diff(t_rows) > FIRMWARE_STOP_TIMEOUT_S))
    if late.size == 0:
        return t_rows, list(srcs)
    at = late + 1
    t_out = np.insert(t_rows, at, t_rows[late] + FIRMWARE_STOP_TIMEOUT_S)
    return t_out, [np.insert(np.asarray(src, dtype=float), at, 0.0) for src in srcs]


def _commands(tr: Trial, g: np.ndarray, dt_s: float):
    """The trial's commands on the grid: each interval's mean of the commands held from each row.
    Across a missing row of a CSV (a dropped row: the command then is unknown) they are interpolated,
    which is exact on ramps and half wrong at a step (holding is wrong on every ramp sample); a
    mission log holds (the motors did), until the firmware's stop (:func:`firmware_stops`)."""
    srcs = (tr.thrust_port_n, tr.thrust_stbd_n, tr.duty_port_pct, tr.duty_stbd_pct)
    t_rows, held = (tr.t_s, list(srcs)) if tr.stalled_after is None else firmware_stops(tr.t_s, srcs, tr.stalled_after)
    out = [_interval_means(t_rows, src, g, dt_s) for src in held]
    k = np.clip(np.searchsorted(tr.t_s, g + 1e-9, side="right") - 1, 0, tr.t_s.size - 1)
    gap = (np.abs(tr.t_s[k] - g) > 0.5 * dt_s) & (g <= tr.t_s[-1])
    if gap.any() and not tr.commands_held:
        for arr, src in zip(out, srcs):
            arr[gap] = np.interp(g[gap], tr.t_s, src)
    return out


# the wander and correlation time the search weights by before any model's noise is known: a
# typical sensor's (issue 12: 0.5-2 m, 30-60 s; 0.3 deg). Not the baseline's: its residual holds the
# missing effect, and a noise that wanders by the effect's size hides it (a 0.2 m/s current in five
# pond logs, fitted at 0.11 m/s under a baseline noise at the sensor's bounds).
SEARCH_POSITION_WANDER_M = 1.0
SEARCH_HEADING_WANDER_RAD = math.radians(0.3)
SEARCH_WANDER_TIME_S = 30.0
# a receiver's velocity error is nearly white (Doppler); a little short wander for a smoothing receiver
SEARCH_VELOCITY_WANDER_M_S = 0.02
SEARCH_VELOCITY_TIME_S = 5.0
WHITE_FLOOR = {"position": 0.05, "heading": math.radians(0.05), "velocity": 0.005}  # SI; 0.005 m/s: 0.01 kn printed
SEARCH_WANDER = {"position": (SEARCH_POSITION_WANDER_M, SEARCH_WANDER_TIME_S),
                 "heading": (SEARCH_HEADING_WANDER_RAD, SEARCH_WANDER_TIME_S),
                 "velocity": (SEARCH_VELOCITY_WANDER_M_S, SEARCH_VELOCITY_TIME_S)}


def first_guess_noise(measured) -> Noise:
    """The search's noise: the white parts measured without a model (noise.white_scale, the median over
    the trials), the wander a typical sensor's (above). Replaced by the best model's own noise once
    the candidates are fitted (identification.renoise)."""
    out = {}
    for name in CHANNEL_NAMES:
        samples = [m.get(name) for m in measured if m.get(name) is not None]
        if not samples:
            continue
        v = [s.white for s in samples if s.white is not None and math.isfinite(s.white)]
        white = max(float(np.median(v)) if v else WHITE_FLOOR[name], WHITE_FLOOR[name])
        out[name] = ChannelNoise(white, *SEARCH_WANDER[name])
    return Noise(**out)


def prepare(trials, *, dt_s: float | None = None, noise: Noise | None = None, reject: bool = True) -> Prepared:
    """Put trials on one grid, take their measurements (outliers rejected) and weight them by ``noise``."""
    trials = tuple(trials)
    if not trials:
        raise ValueError("no trials")
    if dt_s is None:
        dt_s = float(np.median(np.concatenate([np.diff(t.t_s) for t in trials])))
        dt_s = min(max(round(dt_s, 3), 0.01), STEP_MAX_S)
    length = max(t.t_s[-1] for t in trials)
    g = np.arange(0.0, length + dt_s * 0.999, dt_s)
    cmds = np.array([_commands(tr, g, dt_s) for tr in trials])  # (N, 4, G)
    measured = tuple(_measured(tr, dt_s, g.size, reject) for tr in trials)
    noise = noise or first_guess_noise(measured)
    prep = Prepared(trials, dt_s, g, cmds[:, 0], cmds[:, 1], cmds[:, 2], cmds[:, 3], measured, noise, {})
    return prep.with_noise(noise)


def truncate(trial: Trial, end_s: float) -> Trial:
    """The trial's rows up to ``end_s``."""
    keep = trial.t_s <= end_s
    changes = {f.name: getattr(trial, f.name)[keep] for f in dataclasses.fields(trial)
               if isinstance(getattr(trial, f.name), np.ndarray)}
    return dataclasses.replace(trial, **changes)


def initial_state(trial: Trial, *, window_s: float = 3.0) -> np.ndarray:
    """State at the first row from quadratic fits to the first seconds of position and heading
    (the trial's outliers rejected first: a 10 m jump in the first fix bent a whole trial's start)."""
    return measured_initial_state(_measured(trial, 0.1, 2, True), window_s=window_s)


def initial_states(prep: Prepared, *, window_s: float = 3.0) -> np.ndarray:
    """:func:`initial_state` of every trial of ``prep`` from its measurements (outliers rejected)."""
    return np.array([measured_initial_state(m, window_s=window_s) for m in prep.measured])


def measured_initial_state(m: Measured, *, window_s: float = 3.0) -> np.ndarray:
    """State at t = 0 from quadratic fits to the first seconds of the measurements.

    Only a start: noise makes the velocities rough (``fit.fit_model`` refines them). With 1 Hz
    fixes the window grows until it holds six of them; so does the headings' when the compass starts late.
    """
    tp, th = m.t_pos_s, m.t_psi_s
    # a compass that starts late (no heading in the first seconds) crashed np.polyfit on an empty window
    wp = max(window_s, float(tp[min(5, tp.size - 1)]) + 1e-6) if tp.size else window_s
    wh = max(window_s, float(th[min(5, th.size - 1)]) + 1e-6) if th.size else window_s
    ok, okh = tp <= wp, th <= wh
    deg = 2 if ok.sum() > 10 else 1
    pn = np.polyfit(tp[ok], m.north_m[ok], deg)
    pe = np.polyfit(tp[ok], m.east_m[ok], deg)
    psi_u = np.unwrap(m.psi_rad[okh])
    ph = np.polyfit(th[okh], psi_u, 2 if okh.sum() > 10 else 1)
    psi0 = float(ph[-1])
    vn, ve = float(pn[-2]), float(pe[-2])
    vel = m.get("velocity")
    if vel is not None and vel.size >= 3:  # the receiver's own velocity: far better than differenced fixes
        okv = vel.t_s <= max(window_s, float(vel.t_s[2]) + 1e-6)
        vn, ve = (float(np.polyfit(vel.t_s[okv], y[okv], 1)[-1]) for y in vel.values)
    c, s = math.cos(psi0), math.sin(psi0)
    # sway from a few seconds of noisy positions is mostly noise; it decays within a second anyway
    return np.array([pn[-1], pe[-1], wrap_pi(psi0), vn * c + ve * s, 0.0, ph[-2]])


class _Active:
    """The effects active in a batch of runs and their per-run parameter arrays (None: at null everywhere)."""

    def __init__(self, values: dict, n_runs: int):
        per: dict = {}
        for key, val in values.items():
            name, _, pname = key.partition(".")
            arr = np.broadcast_to(np.asarray(val, dtype=float), (n_runs,))
            per.setdefault(name, {})[pname] = arr
        self.v = {}
        for name, given in per.items():
            eff = BY_NAME[name]
            if all(np.all(given.get(p.name, p.null) == p.null) for p in eff.params):
                continue
            self.v[eff] = {p.name: given.get(p.name, np.full(n_runs, p.null)) for p in eff.params}

    def having(self, hook: str):
        return [(e, v) for e, v in self.v.items() if getattr(e, hook) is not None]


def _external(terms):
    """One body-frame external force from the force hooks (state water-relative: see _predict), taking the
    state's columns (sim.integrate.simulate's ``takes_columns``)."""
    def external(t_s, n, e, psi, u, vv, r):
        x = y = m = 0.0
        for f in terms:
            fx, fy, fn = f(psi, u, vv, r)
            x, y, m = x + fx, y + fy, m + fn
        return x, y, m

    external.takes_columns = True
    return external


def _simulate_scalar(vessel, g, tp, ts, x0, dt, fields, forces, c_n, c_e) -> dict:
    """Runs one by one on the simulator's scalar path (faster than a small batch): the field-type
    effects written into VesselParams, the other force hooks bound to the run's own values (exactly what
    the batched path adds); ``c_n``, ``c_e``: each run's current (m/s), for a force over ground (the wind)."""
    n_runs = tp.shape[0]
    out = {name: np.empty((n_runs, g.size)) for name in STATE_NAMES}
    for j in range(n_runs):
        changes = {}
        for eff, v in fields:
            changes.update(eff.fields({k: a[j] for k, a in v.items()}, vessel))
        params = dataclasses.replace(vessel, **changes) if changes else vessel
        terms = [eff.force({k: float(a[j]) for k, a in v.items()}, vessel, (float(c_n[j]), float(c_e[j])))
                 for eff, v in forces if eff.fields is None]
        # a parameter trial far out may blow up: NaN, the fit sees huge residuals
        run = simulate(params, g, tp[j], ts[j], x0=x0[j], dt_s=dt, diverged_as_nan=True,
                       external_force=_external(terms) if terms else None)
        for name in STATE_NAMES:
            out[name][j] = run[name]
    return out


def predict(prep: Prepared, vessel: VesselParams, trial_idx, x0, values: dict, *, sway_over_ground: bool = False) -> dict:
    """Simulate runs and return what the sensors would report on the grid (see :func:`_predict`)."""
    with np.errstate(all="ignore"):  # a far-out parameter trial may overflow; the caller sees NaN
        return _predict(prep, vessel, trial_idx, x0, values, sway_over_ground)


def _predict(prep: Prepared, vessel: VesselParams, trial_idx, x0, values: dict, sway_over_ground: bool) -> dict:
    """trial_idx: (R,) trial of each run; x0: (R, 6) initial states; values: effect key -> scalar
    or (R,) array. Returns ``north_m``, ``east_m``, ``psi_rad`` (R, G) as sensed (the sensed hooks
    applied) and the true ``u_m_s``, ``v_m_s``, ``r_rad_s`` over ground.

    x0's u and r are over ground (the state contract); its sway v is relative to the water unless
    ``sway_over_ground``: the fits hold the sway at its start value (fit.FREE_STATES), and a boat
    that starts without sideways motion through the water moves sideways over ground with the
    current. Held over ground instead, a current model starts the boat slipping through the water
    at the current's cross component: a sway transient that turns the boat (N_v v) and made a
    hidden current lose to other effects in closed-loop logs."""
    idx = np.asarray(trial_idx, dtype=int)
    n_runs = idx.size
    x0 = np.array(np.broadcast_to(np.asarray(x0, dtype=float), (n_runs, 6)))
    g, dt = prep.t_grid, prep.dt_s
    act = _Active(values, n_runs)
    tp, ts = prep.thrust_port_n[idx].copy(), prep.thrust_stbd_n[idx].copy()
    ctx = {"duty_port_pct": prep.duty_port_pct[idx], "duty_stbd_pct": prep.duty_stbd_pct[idx], "dt_s": dt}
    for eff in THRUST_EFFECTS:
        if eff in act.v:
            tp, ts = eff.thrust(act.v[eff], tp, ts, ctx)
    # A uniform steady current only shifts the water-relative motion (model.py works in relative
    # velocity; the added forces depend on psi, the relative velocity and r only): simulate calm
    # water from the relative initial velocity and add current * t to the track.
    c_n, c_e = np.zeros(n_runs), np.zeros(n_runs)
    for eff, v in act.having("water"):
        dn, de = eff.water(v)
        c_n, c_e = c_n + dn, c_e + de
    cp, sp = np.cos(x0[:, 2]), np.sin(x0[:, 2])
    x0[:, 3] -= c_n * cp + c_e * sp
    if sway_over_ground:
        x0[:, 4] -= -c_n * sp + c_e * cp
    forces = act.having("force")
    fields = act.having("fields")
    if n_runs <= SCALAR_MAX_RUNS:
        out = _simulate_scalar(vessel, g, tp, ts, x0, dt, fields, forces, c_n, c_e)
    else:  # batched; a run that blows up comes back NaN, the others stand
        external = _external([e.force(v, vessel, (c_n, c_e)) for e, v in forces]) if forces else None
        out = simulate(vessel, g, tp, ts, x0=x0, external_force=external, dt_s=dt, diverged_as_nan=True)
    psi = out["psi_rad"]
    c, s = np.cos(psi), np.sin(psi)
    sensed = {"north_m": out["north_m"] + c_n[:, None] * g, "east_m": out["east_m"] + c_e[:, None] * g, "psi_rad": psi}
    for eff in SENSED_EFFECTS:
        if eff in act.v:
            sensed = eff.sensed(act.v[eff], sensed, g)
    if prep.has_velocity:  # the antenna's velocity over ground: what the receiver reports as SOG/COG
        for comp, pos in (("vn_m_s", "north_m"), ("ve_m_s", "east_m")):
            sensed[comp] = np.gradient(sensed[pos], dt, axis=1, edge_order=2) if g.size > 2 else np.zeros_like(sensed[pos])
    return {**sensed, "u_m_s": out["u_m_s"] + c_n[:, None] * c + c_e[:, None] * s,
            "v_m_s": out["v_m_s"] - c_n[:, None] * s + c_e[:, None] * c, "r_rad_s": out["r_rad_s"]}


def _at(series: np.ndarray, where: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    k, w = where
    return series[:, k] * (1.0 - w) + series[:, k + 1] * w


def channel_residuals(prep: Prepared, i: int, pred: dict, runs, channel: Channel) -> list[np.ndarray]:
    """Per component of ``channel``, measured - predicted (len(runs), samples) of runs ``runs`` of ``pred``
    against trial ``i`` (the heading wrapped); [] when the trial has no such measurement."""
    s = prep.measured[i].get(channel.name)
    if s is None:
        return []
    runs = np.atleast_1d(np.asarray(runs, dtype=int))
    out = [s.values[q][None, :] - _at(pred[comp][runs], s.at) for q, comp in enumerate(channel.components)]
    return [wrap_pi(r) for r in out] if channel.angle else out


def raw_residuals(prep: Prepared, i: int, pred: dict, runs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(north_m, east_m, heading_rad) residuals, measured - predicted, of runs ``runs`` of ``pred``
    against trial ``i``: each (len(runs), samples)."""
    rn, re = channel_residuals(prep, i, pred, runs, POSITION)
    (rh,) = channel_residuals(prep, i, pred, runs, HEADING)
    return rn, re, rh


def residuals(prep: Prepared, i: int, pred: dict, runs) -> np.ndarray:
    """Weighted residuals (len(runs), prep.n_rows(i)): each channel's components in turn (position north
    and east, heading, velocity north and east), each through its channel's noise model."""
    parts = []
    for c in prep.channels:
        w = prep.weights[c.name][i]
        parts += [w.apply(r.T).T for r in channel_residuals(prep, i, pred, runs, c)]
    return np.hstack(parts)


def trial_cost(prep: Prepared, i: int, pred: dict, run: int) -> float:
    """Weighted sum of squares of trial ``i`` predicted by run ``run`` of ``pred`` (a NaN, a replay gone far off,
    counts 1e3 a residual)."""
    return float(np.sum(np.nan_to_num(residuals(prep, i, pred, [run])[0], nan=1e3) ** 2))


def channel_costs(prep: Prepared, pred: dict, trials_idx, runs) -> dict:
    """Weighted cost and number of measurements per channel: {"position": (cost, n), "heading": (cost, n), ...}."""
    cost = {c.name: 0.0 for c in prep.channels}
    count = {c.name: 0 for c in prep.channels}
    for i, j in zip(trials_idx, runs):
        r = np.nan_to_num(residuals(prep, i, pred, [j])[0], nan=1e3)
        for c, row, rows in prep.row_blocks(i):
            cost[c.name] += float(np.sum(r[row : row + len(c.components) * rows] ** 2))
            count[c.name] += len(c.components) * prep._size(i, c.name)
    return {name: (cost[name], count[name]) for name in cost}


def noise_floor(t_s: np.ndarray, noise: ChannelNoise) -> float:
    """Expected sum of squares of pure noise at times ``t_s`` once its mean is removed (what a fitted
    initial offset absorbs): trace(S) - 1' S 1 / n, S the noise covariance (O(n): the sum of
    exp(-|t_i - t_j| / tau) over pairs by the recursion a_i = exp(-(t_i - t_{i-1}) / tau) (a_{i-1} + 1))."""
    n = t_s.size
    if n < 2:
        return 0.0
    pairs = 0.0
    if noise.has_wander:
        decay = np.exp(-np.diff(t_s) / noise.time_s).tolist()
        a = 0.0
        for d in decay:
            a = d * (a + 1.0)
            pairs += a
    total = n * (noise.white**2 + (noise.wander**2 if noise.has_wander else 0.0))
    one_s_one = n * noise.white**2 + (noise.wander**2 * (n + 2.0 * pairs) if noise.has_wander else 0.0)
    return float(total - one_s_one / n)


def rmse(prep: Prepared, trials_idx, pred: dict, runs) -> dict:
    """Per channel, the RMS error over the given trials in its shown unit (position and velocity horizontal:
    ``position_m``, ``heading_deg``, ``velocity_m_s``), the noise's share of it (``*_noise_*``: what the
    noise model expects) and the rest (``*_model_*``)."""
    out = {}
    for c in prep.channels:
        se = floor = 0.0
        count = 0
        noise = prep.noise.of(c.name)
        for i, j in zip(trials_idx, runs):
            parts = channel_residuals(prep, i, pred, [j], c)
            if not parts:
                continue
            t = prep.measured[i].get(c.name).t_s
            se += float(sum(np.sum(r**2) for r in parts))
            floor += len(parts) * noise_floor(t, noise)
            count += t.size
        n = max(count, 1)
        k = c.key_unit
        out[f"{c.name}_{k}"] = c.shown(math.sqrt(se / n))
        out[f"{c.name}_noise_{k}"] = c.shown(math.sqrt(floor / n))
        # the part of the gap the measurement noise (its model estimated from the data) does not explain
        out[f"{c.name}_model_{k}"] = c.shown(math.sqrt(max(se - floor, 0.0) / n))
    return out
