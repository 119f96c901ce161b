"""Many runs in lockstep: one batched plant, one daemon cycle per run and period.

Every run of a chunk shares the simulated clock. Each control period, each run still
flying goes through its own :class:`~autopilot.closed_loop.Flight` (the SC-30 model, the
daemon's steps with its failsafe, the helm, evaluate's scorecard: the very objects
``autopilot evaluate`` flies one at a time); then the boats of the whole chunk move together:
one RK4 step over arrays of every run's state, with every run's own vessel parameters,
current, wind and sinusoidal force bound as arrays
(:func:`autopilot.sim.model.make_batch_rhs`), ``substeps`` times per period. Thrust
asymmetry, a weak motor, motor lag and the faults' thrust gates act on the commands between the two.
A run leaves the batch when it ends (the batch is compacted once a quarter of it has
ended); the last few runs (fewer than ``MIN_BATCH``) move on the model's scalar path,
where numpy's per-call cost no longer pays.

What this buys (``benchmarks/campaign_speed.py``): the plant costs ~2.5 us per run and
period in a batch of a few hundred, against 12-15 us for evaluate's ``integrate.step`` and
6-9 us on the scalar path; the rest, ~55 us per run and period, is the daemon's own per-run
Python (the SC-30 model, navigation assembly, failsafe, helm), which a campaign must run as
the daemon does: lockstep is ~1.1x one at a time for the same work, not 10x.

Everything is a pure function of ``(campaign, seed, indices)``: a chunk gives the same bits
on any worker (``fly_chunk``), and ``--replay`` re-flies a run inside its chunk.
"""

from __future__ import annotations

import math

import numpy as np

from autopilot.campaign.draw import RunSetup, draw_run
from autopilot.campaign.faults import FaultModel
from autopilot.campaign.results import run_row
from autopilot.campaign.spec import Campaign
from autopilot.sim.motors import weak_motor_gains

__all__ = ["fly", "fly_chunk", "chunk_indices", "SIM_DT_S", "GNC_RATE_HZ"]

SIM_DT_S = 0.05  # as autopilot evaluate
GNC_RATE_HZ = 10.0


def chunk_indices(campaign: Campaign, runs: int, chunk: int) -> range:
    """The run indices of chunk ``chunk`` (fixed by the spec's chunk_runs, whatever the backend)."""
    size = campaign.spec.chunk_runs
    return range(chunk * size, min((chunk + 1) * size, runs))


def run_gnc(campaign: Campaign, setup: RunSetup):
    """The GNC configuration a run flies: the spec's, with the run's guidance law."""
    from dataclasses import replace

    gnc = campaign.spec.gnc
    return replace(gnc, guidance=replace(gnc.guidance, law=setup.law))


def _flight(campaign: Campaign, setup: RunSetup):
    """The run's Flight: the daemon's cycle with its failsafe, the SC-30 model seeded from the run."""

    from autopilot.closed_loop import Flight
    from autopilot.daemon.config import DaemonConfig
    from autopilot.daemon.cycle import nav_rules
    from autopilot.daemon.failsafe import Failsafe
    from autopilot.evaluate import EVAL_ORIGIN_DEG
    from autopilot.gnc import Autopilot
    from autopilot.sim.sensors import SensorModel

    spec = campaign.spec
    gnc = run_gnc(campaign, setup)
    m = setup.mission
    ap = Autopilot(gnc, m.waypoints_ne_m, speeds_m_s=m.speeds_m_s, holds_s=m.holds_s, rtl=m.rtl,
                   boat_length_m=setup.params.length_m)
    sensors = SensorModel(*EVAL_ORIGIN_DEG, position_noise_m=setup.position_noise_m,
                          heading_noise_deg=setup.heading_noise_deg,
                          rng=np.random.default_rng(np.random.SeedSequence(list(setup.sensor_seed))))
    fs = spec.failsafe
    rules = nav_rules(DaemonConfig(rate_hz=GNC_RATE_HZ, failsafe=fs, gnc=gnc))  # the daemon's own thresholds
    faults = FaultModel(setup, battery_sag_v=fs.battery_sag_v)
    flight = Flight(ap, sensors, dt_s=SIM_DT_S, rate_hz=GNC_RATE_HZ, t_max_s=setup.t_max_s,
                    final_pass_s=gnc.guidance.final_pass_s, origin_lat_deg=EVAL_ORIGIN_DEG[0],
                    origin_lon_deg=EVAL_ORIGIN_DEG[1], rules=rules, failsafe=Failsafe(fs),
                    link=faults.link if faults.affects_link else None,
                    sample_filter=faults.sample_filter if faults.affects_sensors else None, end_on_latched=True)
    faults.bind(flight.cycle)
    return flight, faults


MIN_BATCH = 24  # fewer runs than this still flying: each moves on its own (numpy's per-call cost would dominate)


def _lag_coefficients(tau_s):
    """(a, g) of the interval mean of a first-order lag under a held command (sysid.prediction.lag_filter):
    y_{k+1} = a y_k + (1 - a) u, mean = u + (y_k - u) g; no lag: a = g = 0."""
    tau = np.asarray(tau_s, dtype=float)
    lagged = tau > 1e-6
    a = np.where(lagged, np.exp(-SIM_DT_S / np.where(lagged, tau, 1.0)), 0.0)
    return a, np.where(lagged, tau / SIM_DT_S * (1.0 - a), 0.0)


class _Batch:
    """The plant of many runs as arrays: state columns, per-run constants, the motors' lag state."""

    def __init__(self, setups: list[RunSetup], members: list[int]) -> None:
        from autopilot.sim.model import make_batch_rhs

        self.members = members  # positions (in the chunk) of the runs in the batch, in order
        sel = [setups[j] for j in members]
        self.rhs = make_batch_rhs([s.params for s in sel], [s.env for s in sel])
        self.asym = np.array([s.thrust_asymmetry_nd for s in sel])
        self.gain_port, self.gain_stbd = weak_motor_gains(np.array([s.weak_motor_loss_nd for s in sel]))
        self.lag_a, self.lag_g = _lag_coefficients([s.thrust_lag_s for s in sel])
        self.lag = bool(np.any(self.lag_g > 0.0))
        self.cols = tuple(np.zeros(len(sel)) for _ in range(6))
        self.cols[0][:] = [s.mission.home_ne_m[0] for s in sel]  # at rest at the mission's home, heading north
        self.cols[1][:] = [s.mission.home_ne_m[1] for s in sel]
        self.y_port = np.zeros(len(sel))  # the lagged thrusts (N)
        self.y_stbd = np.zeros(len(sel))
        self.alive = [True] * len(sel)

    def states(self) -> list[list[float]]:
        return np.stack(self.cols, axis=1).tolist()

    def keep(self, setups: list[RunSetup], min_batch: int):
        """The runs still alive, their states carried over: a smaller batch, or single runs when few are left."""
        idx = [k for k, a in enumerate(self.alive) if a]
        if len(idx) < min_batch:
            return _Singles(setups, [self.members[k] for k in idx], [[float(c[k]) for c in self.cols] for k in idx],
                            [(float(self.y_port[k]), float(self.y_stbd[k])) for k in idx])
        new = _Batch(setups, [self.members[k] for k in idx])
        new.cols = tuple(c[idx] for c in self.cols)
        new.y_port, new.y_stbd = self.y_port[idx], self.y_stbd[idx]
        return new

    def move(self, t_s: float, thrust_port_n, thrust_stbd_n, substeps: int) -> float:
        """``substeps`` RK4 steps with the commands held (asymmetry and a weak motor, then the motors' lag); returns the
        new time."""
        from autopilot.sim.integrate import rk4_step

        tp = np.asarray(thrust_port_n) * (1.0 + self.asym) * self.gain_port
        ts = np.asarray(thrust_stbd_n) * (1.0 - self.asym) * self.gain_stbd
        for _ in range(substeps):
            if self.lag:
                mp, ms = tp + (self.y_port - tp) * self.lag_g, ts + (self.y_stbd - ts) * self.lag_g
                self.y_port = self.lag_a * self.y_port + (1.0 - self.lag_a) * tp
                self.y_stbd = self.lag_a * self.y_stbd + (1.0 - self.lag_a) * ts
            else:
                mp, ms = tp, ts
            self.cols = rk4_step(self.rhs, self.cols, mp, ms, SIM_DT_S, t_s=t_s)
            t_s += SIM_DT_S
        return t_s


class _Singles:
    """The last few runs of a chunk, each on the model's scalar path (the same equations, plain floats)."""

    def __init__(self, setups: list[RunSetup], members: list[int], states, lag_states) -> None:
        from autopilot.sim.model import make_rhs

        self.members = members
        sel = [setups[j] for j in members]
        self.rhs = [make_rhs.__wrapped__(s.params, s.env, None, False) for s in sel]  # not into make_rhs's cache
        self.asym = [s.thrust_asymmetry_nd for s in sel]
        self.gains = [weak_motor_gains(float(s.weak_motor_loss_nd)) for s in sel]
        a, g = _lag_coefficients([s.thrust_lag_s for s in sel])
        self.lag_a, self.lag_g = a.tolist(), g.tolist()
        self.x = [tuple(st) for st in states]
        self.y = [list(y) for y in lag_states]
        self.alive = [True] * len(sel)

    def states(self):
        return self.x

    def keep(self, setups: list[RunSetup], min_batch: int):
        new = _Singles.__new__(_Singles)
        idx = [k for k, a in enumerate(self.alive) if a]
        new.members = [self.members[k] for k in idx]
        for name in ("rhs", "asym", "gains", "lag_a", "lag_g", "x", "y"):
            setattr(new, name, [getattr(self, name)[k] for k in idx])
        new.alive = [True] * len(idx)
        return new

    def move(self, t_s: float, thrust_port_n, thrust_stbd_n, substeps: int) -> float:
        from autopilot.sim.integrate import rk4_step

        for k in range(len(self.members)):
            if not self.alive[k]:
                continue
            a, g, y = self.lag_a[k], self.lag_g[k], self.y[k]
            tp = thrust_port_n[k] * (1.0 + self.asym[k]) * self.gains[k][0]
            ts = thrust_stbd_n[k] * (1.0 - self.asym[k]) * self.gains[k][1]
            x, t = self.x[k], t_s
            for _ in range(substeps):
                if g > 0.0:
                    mp, ms = tp + (y[0] - tp) * g, ts + (y[1] - ts) * g
                    y[0], y[1] = a * y[0] + (1.0 - a) * tp, a * y[1] + (1.0 - a) * ts
                else:
                    mp, ms = tp, ts
                x = rk4_step(self.rhs[k], x, mp, ms, SIM_DT_S, t_s=t)
                t += SIM_DT_S
            self.x[k] = x
        for _ in range(substeps):  # the clock, accumulated as the batch's and evaluate's
            t_s += SIM_DT_S
        return t_s


def fly(campaign: Campaign, seed: int, indices, *, watch: dict | None = None, min_batch: int = MIN_BATCH) -> list[dict]:
    """Fly runs ``indices`` in lockstep; one table row per run, in the order given.

    ``min_batch``: below this many runs still flying, each moves on the model's scalar path (a larger
    value than the chunk flies every run on its own, one at a time: the benchmark's comparison).
    ``watch``: index -> ``callback(t_s, flight, cycle)`` called after each of that run's control
    cycles, and ``callback(t_s, flight, None)`` when it ends (``--replay`` writes its log so).
    """
    setups = [draw_run(campaign, seed, i) for i in indices]
    flights = [_flight(campaign, s) for s in setups]
    n = len(setups)
    rows: list[dict | None] = [None] * n
    if n == 0:
        return []
    watch = watch or {}
    members = list(range(n))
    batch = (_Batch(setups, members) if n >= min_batch else
             _Singles(setups, members, [[*s.mission.home_ne_m, 0.0, 0.0, 0.0, 0.0] for s in setups], [(0.0, 0.0)] * n))
    substeps = flights[0][0].substeps
    # per run: the failsafes it had taken by the end of the cycle its mission completed in (the rest came after)
    by_completion: list[int | None] = [None] * n
    t_s = 0.0
    ended_in_batch = 0
    with np.errstate(all="ignore"):
        while True:
            states = batch.states()
            tp = [0.0] * len(batch.members)
            ts = [0.0] * len(batch.members)
            for k, j in enumerate(batch.members):
                if not batch.alive[k]:
                    continue
                flight, faults = flights[j]
                try:
                    thrust = flight.control(t_s, states[k])
                except (ValueError, ArithmeticError) as exc:  # a run that blew up ends alone, marked
                    flight.end_reason = f"error: {type(exc).__name__}: {exc}"[:200]
                    thrust = None
                if by_completion[j] is None and flight.score.completed_at is not None:
                    by_completion[j] = len(flight.cycle.failsafe_causes)
                cb = watch.get(setups[j].index)
                if thrust is None:
                    result = flight.result(t_s, mission=setups[j].mission.name, condition=setups[j].condition)
                    rows[j] = run_row(campaign, setups[j], flight, result, failsafes_by_completion=by_completion[j])
                    batch.alive[k] = False
                    ended_in_batch += 1
                    if cb is not None:
                        cb(t_s, flight, None)
                    continue
                if cb is not None:
                    cb(t_s, flight, flight.last)
                gp, gs = faults.gate(t_s) if faults.affects_thrust else (1.0, 1.0)
                tp[k], ts[k] = thrust[0] * gp, thrust[1] * gs
            alive = sum(batch.alive)
            if not alive:
                break
            if ended_in_batch and (isinstance(batch, _Singles) or ended_in_batch >= len(batch.members) // 4
                                   or alive < min_batch):
                keep = [k for k, a in enumerate(batch.alive) if a]
                batch = batch.keep(setups, min_batch)
                tp, ts = [tp[k] for k in keep], [ts[k] for k in keep]
                ended_in_batch = 0
            t_s = batch.move(t_s, tp, ts, substeps)
    return rows


def fly_chunk(campaign: Campaign, seed: int, runs: int, chunk: int) -> list[dict]:
    """Chunk ``chunk`` of a campaign of ``runs`` runs: the task a worker runs (pure)."""
    return fly(campaign, seed, chunk_indices(campaign, runs, chunk))


def chunks(campaign: Campaign, runs: int) -> int:
    """How many chunks ``runs`` runs make."""
    return max(1, math.ceil(runs / campaign.spec.chunk_runs))
