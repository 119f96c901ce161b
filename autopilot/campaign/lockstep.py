"""Many runs in lockstep: one batched plant, one daemon cycle per run and period.

Every run of a chunk shares the simulated clock. Each control period, each run still
flying goes through its own :class:`~autopilot.closed_loop.Flight` (the SC-30 model, the
daemon's steps with its failsafe, the helm, evaluate's scorecard: the very objects
``autopilot evaluate`` flies one at a time); then the boats of the whole chunk move together:
one RK4 step over arrays of every run's state, with every run's own vessel parameters,
current, wind and sinusoidal force bound as arrays
(:func:`autopilot.sim.model.make_batch_rhs`), ``substeps`` times per period. Thrust
asymmetry, motor lag and the faults' thrust gates act on the commands between the two.

A run leaves the batch when it ends (the batch is compacted once a quarter of it has
ended). Everything is a pure function of ``(campaign, seed, indices)``: a chunk gives the
same bits on any worker (``fly_chunk``), and ``--replay`` re-flies a run inside its chunk.
"""

from __future__ import annotations

import math

import numpy as np

from autopilot.campaign.draw import RunSetup, draw_run
from autopilot.campaign.faults import FaultModel
from autopilot.campaign.results import run_row
from autopilot.campaign.spec import Campaign

__all__ = ["fly", "fly_chunk", "chunk_indices", "SIM_DT_S", "GNC_RATE_HZ"]

SIM_DT_S = 0.05  # as autopilot evaluate
GNC_RATE_HZ = 10.0


def chunk_indices(campaign: Campaign, runs: int, chunk: int) -> range:
    """The run indices of chunk ``chunk`` (fixed by the spec's chunk_runs, whatever the backend)."""
    size = campaign.spec.chunk_runs
    return range(chunk * size, min((chunk + 1) * size, runs))


def _flight(campaign: Campaign, setup: RunSetup):
    """The run's Flight: the daemon's cycle with its failsafe, the SC-30 model seeded from the run."""
    from dataclasses import replace

    from autopilot.closed_loop import Flight
    from autopilot.daemon.config import DaemonConfig
    from autopilot.daemon.cycle import nav_rules
    from autopilot.daemon.failsafe import Failsafe
    from autopilot.evaluate import EVAL_ORIGIN_DEG
    from autopilot.gnc import Autopilot
    from autopilot.sim.sensors import SensorModel

    spec = campaign.spec
    gnc = replace(spec.gnc, guidance=replace(spec.gnc.guidance, law=setup.law))
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


class _Batch:
    """The plant of the runs still flying: state columns, per-run constants, thrust lag state."""

    def __init__(self, setups: list[RunSetup], members: list[int]) -> None:
        from autopilot.sim.model import make_batch_rhs

        self.members = members  # positions (in the chunk) of the runs in the batch, in order
        sel = [setups[j] for j in members]
        self.rhs = make_batch_rhs([s.params for s in sel], [s.env for s in sel])
        self.asym = np.array([s.thrust_asymmetry_nd for s in sel])
        tau = np.array([s.thrust_lag_s for s in sel])
        lagged = tau > 1e-6
        self.lag = bool(lagged.any())
        a = np.where(lagged, np.exp(-SIM_DT_S / np.where(lagged, tau, 1.0)), 0.0)
        self.lag_a, self.lag_g = a, np.where(lagged, tau / SIM_DT_S * (1.0 - a), 0.0)  # sysid.replay.lag_filter
        self.cols = tuple(np.zeros(len(sel)) for _ in range(6))
        self.y_port = np.zeros(len(sel))  # the lagged thrusts (N)
        self.y_stbd = np.zeros(len(sel))
        self.alive = np.ones(len(sel), dtype=bool)

    def keep(self, setups: list[RunSetup]) -> _Batch:
        """A compacted batch of the runs still alive, carrying their states over."""
        idx = np.nonzero(self.alive)[0]
        new = _Batch(setups, [self.members[k] for k in idx])
        new.cols = tuple(c[idx] for c in self.cols)
        new.y_port, new.y_stbd = self.y_port[idx], self.y_stbd[idx]
        return new

    def move(self, t_s: float, thrust_port_n: np.ndarray, thrust_stbd_n: np.ndarray, substeps: int) -> float:
        """``substeps`` RK4 steps with the commands held (asymmetry, then the motors' lag); returns the new time."""
        from autopilot.sim.integrate import rk4_step

        tp = thrust_port_n * (1.0 + self.asym)
        ts = thrust_stbd_n * (1.0 - self.asym)
        for _ in range(substeps):
            if self.lag:  # the interval mean of a first-order lag under a held command (exact for ZOH)
                mp, ms = tp + (self.y_port - tp) * self.lag_g, ts + (self.y_stbd - ts) * self.lag_g
                self.y_port = self.lag_a * self.y_port + (1.0 - self.lag_a) * tp
                self.y_stbd = self.lag_a * self.y_stbd + (1.0 - self.lag_a) * ts
            else:
                mp, ms = tp, ts
            self.cols = rk4_step(self.rhs, self.cols, mp, ms, SIM_DT_S, t_s=t_s)
            t_s += SIM_DT_S
        return t_s


def fly(campaign: Campaign, seed: int, indices, *, watch: dict | None = None) -> list[dict]:
    """Fly runs ``indices`` in lockstep; one table row per run, in the order given.

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
    batch = _Batch(setups, list(range(n)))
    substeps = flights[0][0].substeps
    t_s = 0.0
    ended_in_batch = 0
    with np.errstate(all="ignore"):
        while True:
            states = np.stack(batch.cols, axis=1).tolist()
            tp = np.zeros(len(batch.members))
            ts = np.zeros(len(batch.members))
            for k, j in enumerate(batch.members):
                if not batch.alive[k]:
                    continue
                flight, faults = flights[j]
                try:
                    thrust = flight.control(t_s, states[k])
                except (ValueError, ArithmeticError) as exc:  # a run that blew up ends alone, marked
                    flight.end_reason = f"error: {type(exc).__name__}: {exc}"[:200]
                    thrust = None
                cb = watch.get(setups[j].index)
                if thrust is None:
                    rows[j] = run_row(campaign, setups[j], flight, flight.result(t_s, mission=setups[j].mission.name,
                                                                                 condition=setups[j].condition))
                    batch.alive[k] = False
                    ended_in_batch += 1
                    if cb is not None:
                        cb(t_s, flight, None)
                    continue
                if cb is not None:
                    cb(t_s, flight, flight.last)
                gp, gs = faults.gate(t_s) if faults.affects_thrust else (1.0, 1.0)
                tp[k], ts[k] = thrust[0] * gp, thrust[1] * gs
            if not batch.alive.any():
                break
            if ended_in_batch and ended_in_batch >= max(1, len(batch.members) // 4):
                keep = batch.alive.copy()
                batch = batch.keep(setups)
                tp, ts = tp[keep], ts[keep]
                ended_in_batch = 0
            t_s = batch.move(t_s, tp, ts, substeps)
    return rows


def fly_chunk(campaign: Campaign, seed: int, runs: int, chunk: int) -> list[dict]:
    """Chunk ``chunk`` of a campaign of ``runs`` runs: the task a worker runs (pure)."""
    return fly(campaign, seed, chunk_indices(campaign, runs, chunk))


def chunks(campaign: Campaign, runs: int) -> int:
    """How many chunks ``runs`` runs make."""
    return max(1, math.ceil(runs / campaign.spec.chunk_runs))
