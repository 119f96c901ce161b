"""Simulated traffic as the boat sees it: the scenario's targets moved, reported by AIS, decoded, dead-reckoned.

One step per control cycle: :class:`autopilot.simdev.traffic.TrafficSim` moves the targets (the
``gives_way`` ones react to own ship), the sentences each would have sent since the last step (at
ITU-R M.1371 rates: :func:`autopilot.simdev.traffic.sentences_between`) go through the real decoder
and target table (:class:`autopilot.drivers.ais.AisReceiver`), and the targets it holds come back as
:class:`autopilot.gnc.encounter.TargetState`, dead-reckoned for their age, as on the boat. The truth
is kept for scoring. Used by ``autopilot evaluate --traffic`` (and so by the campaigns).
"""

from __future__ import annotations

from dataclasses import replace

from autopilot.drivers.ais import AisReceiver
from autopilot.gnc.encounter import OwnShip, TargetState
from autopilot.simdev.traffic import TrafficScenario, TrafficSim, sentences_between

__all__ = ["TrafficFeed"]


class TrafficFeed:
    def __init__(self, scenario: TrafficScenario, *, via_ais: bool = True) -> None:
        self.scenario = scenario
        self.via_ais = via_ais
        self.sim = TrafficSim(scenario)
        self.rx = AisReceiver()
        self.specs = {s.mmsi: s for s in scenario.targets}
        self._t_prev = -1e-9
        self.truth: dict[int, list[tuple[float, float]]] = {m: [] for m in self.specs}  # per step, for scoring

    @property
    def origin(self) -> tuple[float, float]:
        return self.scenario.origin_lat_deg, self.scenario.origin_lon_deg

    def required_m(self, safe_distance_m: float) -> dict[int, float]:
        """Each target's required distance: the safe distance plus its extent."""
        out = {}
        for m, spec in self.specs.items():
            kin = self.sim.kinematics(0.0)[m]
            out[m] = safe_distance_m + kin.as_target_state(spec).extent_m
        return out

    def step(self, t_s: float, own: OwnShip) -> list[TargetState]:
        self.sim.step(t_s, own)  # the reactive targets answer own ship
        states = self.sim.kinematics(t_s)
        for m in self.specs:
            self.truth[m].append((states[m].north_m, states[m].east_m))
        if not self.via_ais:
            return [states[m].as_target_state(self.specs[m]) for m in self.specs]
        for ts, line in sentences_between(self.scenario, self._t_prev, t_s, states=lambda mmsi, tt: states[mmsi]):
            self.rx.feed_line(line, ts)
        self._t_prev = t_s
        seen = []
        for tg in self.rx.targets(t_s):
            if tg.mmsi not in self.specs:
                continue
            s = TargetState.from_ais(tg, origin_lat_deg=self.origin[0], origin_lon_deg=self.origin[1], now_s=t_s)
            truth = states[tg.mmsi].as_target_state(self.specs[tg.mmsi])
            seen.append(replace(s, extent_m=max(s.extent_m, truth.extent_m)))  # a size only the static report gives
        return seen
