"""A run's dropouts and faults, between the simulated devices and the daemon's steps.

The daemon sees a fault only through what its drivers report, so that is where one is
injected (as pymodbus's test transport corrupts bytes on purpose):

- a GNSS dropout or ``gnss_lost``: no new fix; the last one stays in the sample, ageing
  (dead reckoning for ``dead_reckon_max_s``, then ``position_stale``);
- a heading dropout: no new heading or rate of turn (``heading_stale`` after ``heading_stale_s``);
- ``compass_lost``: the SC-30 port closes (``compass_port_lost``) and nothing new arrives;
- ``nmea_garbage``: garbage bursts on the compass line while it lasts (``nmea_garbage``);
- ``mbed_lost``: the Mbed port closes (``mbed_port_lost``) and its firmware stops both thrusters;
- ``thruster_failure``: one side delivers no thrust; the daemon cannot see it;
- ``battery_low``: the resting voltage falls to the drawn value and stays (the Mbed reports the
  voltage under load: the daemon's ``resting_voltage_v`` estimate recovers the resting value).

Pure given the run's :class:`~autopilot.campaign.draw.RunSetup`; queried with mission time.
"""

from __future__ import annotations

from dataclasses import replace

from autopilot.closed_loop import LINK_OK, LinkState
from autopilot.devices import NavSample

__all__ = ["FaultModel", "NOMINAL_REST_V"]

NOMINAL_REST_V = 12.7  # a charged 12 V lead-acid battery at rest


def _inside(intervals, t_s: float) -> bool:
    for a, b in intervals:
        if a <= t_s < b:
            return True
    return False


class FaultModel:
    """The link state, the sample filter and the thrust gate of one run (see the module docstring)."""

    def __init__(self, setup, *, battery_sag_v: float) -> None:
        by = {k: [(f.at_s, f.end_s) for f in setup.faults if f.kind == k]
              for k in ("gnss_lost", "compass_lost", "mbed_lost", "nmea_garbage")}
        self.position_off = tuple(setup.position_dropouts) + tuple(by["gnss_lost"]) + tuple(by["compass_lost"])
        self.heading_off = tuple(setup.heading_dropouts) + tuple(by["compass_lost"])
        self.compass_down = tuple(by["compass_lost"])
        self.mbed_down = tuple(by["mbed_lost"])
        self.garbage = tuple(by["nmea_garbage"])
        self.thruster = tuple((f.side, f.at_s, f.end_s) for f in setup.faults if f.kind == "thruster_failure")
        self.battery = tuple((f.at_s, f.battery_rest_v) for f in setup.faults if f.kind == "battery_low")
        self.battery_sag_v = float(battery_sag_v)
        self.affects_sensors = bool(self.position_off or self.heading_off)
        self.affects_link = bool(self.compass_down or self.mbed_down or self.garbage or self.battery)
        self.affects_thrust = bool(self.mbed_down or self.thruster)
        self.cycle = None  # the run's ControlCycle (its last command loads the battery): set by bind()
        self._pos = (None, None, None, None)  # the last position group let through
        self._hdg = (None, None)

    def bind(self, cycle) -> None:
        self.cycle = cycle

    def sample_filter(self, t_s: float, s: NavSample) -> NavSample:
        """The sample the compass driver would hold: during a dropout, the last values received before it."""
        pos_off = _inside(self.position_off, t_s)
        hdg_off = _inside(self.heading_off, t_s)
        if not pos_off:
            self._pos = (s.position, s.fix_quality, s.sog_m_s, s.cog_rad)
        if not hdg_off:
            self._hdg = (s.heading_rad, s.yaw_rate_rad_s)
        if not (pos_off or hdg_off):
            return s
        pos, fq, sog, cog = self._pos
        hdg, rot = self._hdg
        return replace(s, position=pos, fix_quality=fq, sog_m_s=sog, cog_rad=cog, heading_rad=hdg, yaw_rate_rad_s=rot)

    def link(self, t_s: float) -> LinkState:
        """What the drivers report at ``t_s`` besides navigation."""
        if not self.affects_link:
            return LINK_OK
        garbage = None
        for a, b in self.garbage:
            if t_s >= a:
                garbage = min(t_s, b)  # bursts keep coming while it lasts
        battery_v = None
        if self.battery:
            rest_v = NOMINAL_REST_V
            for a, v in self.battery:
                if t_s >= a:
                    rest_v = v
            cmd = self.cycle.last_cmd if self.cycle is not None else None
            dp = 0.0 if cmd is None else abs(cmd.duty_port_pct) / 100.0
            ds = 0.0 if cmd is None else abs(cmd.duty_stbd_pct) / 100.0
            battery_v = rest_v - self.battery_sag_v * 0.5 * (dp ** 3 + ds ** 3)  # under the last command's load
        return LinkState(compass_connected=not _inside(self.compass_down, t_s),
                         thrusters_connected=not _inside(self.mbed_down, t_s),
                         compass_garbage_s=garbage, battery_v=battery_v)

    def gate(self, t_s: float) -> tuple[float, float]:
        """Factors on the commanded thrusts (port, starboard) that reach the water at ``t_s``."""
        if _inside(self.mbed_down, t_s):
            return 0.0, 0.0
        gp = gs = 1.0
        for side, a, b in self.thruster:
            if a <= t_s < b:
                if side == "port":
                    gp = 0.0
                else:
                    gs = 0.0
        return gp, gs
