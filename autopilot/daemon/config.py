"""Daemon configuration: every setting of ``config/autopilot.yaml`` as frozen dataclasses.

Loaded with :func:`autopilot.schema.load_yaml`, so an unknown key, a wrong
type or an out-of-range value stops ``autopilot run`` with a message naming
the key and the allowed range *before any serial port is opened*.
The GNC's own settings (guidance law, PID gains, allocation, membership
universes) are the ``gnc`` section, :class:`autopilot.gnc.GncConfig`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

from autopilot.drivers.ais import AisConfig
from autopilot.drivers.mbed_protocol import FIRMWARE_STOP_TIMEOUT_S
from autopilot.drivers.sc30_output import SENTENCES as SC30_SENTENCES
from autopilot.gnc import GncConfig
from autopilot.link.config import MavlinkConfig
from autopilot.logschema import FAILSAFE_ACTIONS
from autopilot.measured import HULL_LENGTH_M
from autopilot.schema import ConfigError, load_yaml, param
from autopilot.userfile import other_file_kind

__all__ = [
    "SerialConfig",
    "FailsafeConfig",
    "FailsafeActions",
    "GeofenceConfig",
    "SimConfig",
    "DaemonConfig",
    "load_config",
]

_SC30_BAUDS = (4800, 9600, 19200, 38400)
_MBED_BAUDS = (9600, 19200, 38400, 57600, 115200)
_SIM_SENTENCES = SC30_SENTENCES


@dataclass(frozen=True)
class SerialConfig:
    """The two serial devices (stable names from systemd/99-wamv.rules)."""

    sc30_port: str = param("/dev/sc30", doc="SC-30 satellite compass NMEA port")
    sc30_baud: int = param(4800, unit="bit/s", lo=4800, hi=38400, source="SPEC 10", doc="SC-30 baud rate: 4800, 9600, 19200 or 38400")
    mbed_port: str = param("/dev/mbed", doc="Mbed LPC1768 thruster controller port (USB CDC)")
    mbed_baud: int = param(115200, unit="bit/s", lo=9600, hi=115200, doc="Mbed baud rate")
    reconnect_min_s: float = param(0.2, unit="s", lo=0.01, hi=10.0, doc="first reconnect back-off after a port vanished")
    reconnect_max_s: float = param(5.0, unit="s", lo=0.05, hi=60.0, doc="largest reconnect back-off")
    ack_timeout_s: float = param(0.3, unit="s", lo=0.01, hi=5.0, doc="an Mbed command not acknowledged within this is missing")

    def __post_init__(self) -> None:
        if self.sc30_baud not in _SC30_BAUDS:
            raise ConfigError(f"serial.sc30_baud: {self.sc30_baud} is not one of {', '.join(map(str, _SC30_BAUDS))}")
        if self.mbed_baud not in _MBED_BAUDS:
            raise ConfigError(f"serial.mbed_baud: {self.mbed_baud} is not one of {', '.join(map(str, _MBED_BAUDS))}")
        if self.reconnect_max_s < self.reconnect_min_s:
            raise ConfigError("serial.reconnect_max_s: must be >= serial.reconnect_min_s")


@dataclass(frozen=True)
class GeofenceConfig:
    """A polygon the boat must stay inside; leaving it is a latched failsafe (zero thrust)."""

    frame: str = param("none", choices=("none", "local", "latlon"), doc="polygon vertices as [north_m, east_m] (local) or [lat_deg, lon_deg] (latlon); none = no fence")
    polygon: tuple[tuple[float, float], ...] = param((), unit="m or deg", lo=-1e6, hi=1e6, doc="vertices in order (>= 3), closed implicitly")

    def __post_init__(self) -> None:
        if self.frame == "none" and self.polygon:  # the fence was off without a word (a new user's test)
            raise ConfigError(f"geofence.polygon: {len(self.polygon)} vertices given with frame 'none', which is no "
                              "fence: set geofence.frame to local ([north_m, east_m]) or latlon ([lat_deg, lon_deg]), "
                              "or leave the polygon out")
        if self.frame != "none" and len(self.polygon) < 3:
            raise ConfigError(f"geofence.polygon: needs at least 3 vertices for frame {self.frame!r}, got {len(self.polygon)}")
        if self.frame == "latlon":
            for i, (lat, lon) in enumerate(self.polygon):
                if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                    raise ConfigError(f"geofence.polygon[{i}]: [{lat}, {lon}] is not a latitude in [-90, 90] deg and longitude in [-180, 180] deg")
        if self.frame != "none":
            from autopilot.mathutil import polygon_problem

            # a fence of no area (or a bow tie) has no inside: the boat was "outside" at its first fix and stopped
            problem = polygon_problem(self.polygon)
            if problem is not None:
                raise ConfigError(f"geofence.polygon: {problem}")


_ACTIONS = FAILSAFE_ACTIONS


@dataclass(frozen=True)
class FailsafeActions:
    """What each fault class does (ArduPilot's FS_ACTION). ``hold`` and ``rtl`` need a position and a
    heading: for a position or heading fault, or when either is missing, they fall back to ``stop``
    (logged). Mbed-link faults and ``battery_critical`` always stop: the firmware stops anyway, and an
    empty battery cannot bring the boat home."""

    position: str = param("stop", choices=_ACTIONS, source="issue 15 (the guard makes hold and rtl stop)",
                          doc="position stale, no fix")
    heading: str = param("stop", choices=_ACTIONS, source="issue 15 (the guard makes hold and rtl stop)",
                         doc="heading stale or invalid, compass port lost, garbage on the compass line")
    geofence: str = param("rtl", choices=_ACTIONS, source="ArduPilot FENCE_ACTION (RTL or hold)",
                          doc="the boat left the geofence")
    max_distance: str = param("rtl", choices=_ACTIONS, source="as the geofence",
                              doc="farther than max_distance_m from the origin")
    max_mission_time: str = param("stop", choices=_ACTIONS,
                                  doc="mission time limit; stop ends the run (exit, stop reason max_mission_time)")
    battery_low: str = param("rtl", choices=_ACTIONS, source="issue 15; ArduPilot BATT_FS_LOW_ACT",
                             doc="battery below battery_low_v for battery_low_s")


@dataclass(frozen=True)
class FailsafeConfig:
    """Detection thresholds, the recovery rule and the action per fault class (issues 7, 15)."""

    heading_stale_s: float = param(1.0, unit="s", lo=0.05, hi=10.0, doc="heading older than this is a fault (SC-30 sends it at 10 Hz)")
    position_stale_s: float = param(3.0, unit="s", lo=0.1, hi=30.0, doc="position older than this is a fault (GGA/RMC at 1 Hz)")
    position_jump_m: float = param(25.0, unit="m", lo=1.0, hi=10000.0, source="ArduPilot EK3_GLITCH_RAD",
                                   doc="a new fix farther than this (plus the receiver's speed over ground + 2 m/s, or 10 m/s "
                                       "without one, x the time since) from the last fix used is refused, until a second fix "
                                       "agrees with it")
    position_confirm_s: float = param(
        5.0, unit="s", lo=0.0, hi=60.0, source="chosen: longer than the 3-4 epoch glitches the two-fix rule believed; "
        "ArduPilot's EKF wants 10 s of passing GPS checks before it aligns",
        doc="the first fix, or one the position re-anchored to after a jump, is steered by but confirmed only once "
            "the fixes after it have agreed for this long: no geofence or distance limit latches on it and control "
            "does not start on it (the launch point)")
    heading_frozen_deg: float = param(
        20.0, unit="deg", lo=5.0, hi=360.0, source="chosen: 4 x the heading PID's typical error; a stuck SC-30 spun the "
        "boat at 50 deg/s unnoticed", doc="the rate of turn (ROT) says the boat turned this much while the compass heading "
        "stayed within 0.5 deg: the heading is frozen (heading_frozen, until it moves)")
    heading_frozen_steer_s: float = param(
        3.0, unit="s", lo=0.0, hi=60.0, source="chosen: 2x the longest such time in 1,200 campaign runs (up to 10 m/s "
        "of wind) and 168 evaluate runs (1.5 s)", doc="the helm steered at least heading_frozen_steer_error_deg off "
        "the compass heading for this long while the heading stayed within 0.5 deg: the heading is frozen "
        "(heading_frozen, until it moves); catches a compass whose rate of turn froze too; 0 = off (a bench with "
        "the boat out of the water)")
    heading_frozen_steer_error_deg: float = param(
        20.0, unit="deg", lo=5.0, hi=180.0, source="chosen: a WAM-V pinned by 10 m/s of wind held 15 deg off for 9 s",
        doc="the heading error that counts towards heading_frozen_steer_s")
    ack_missing_n: int = param(5, unit="commands", lo=1, hi=100, doc="this many consecutive unacknowledged Mbed commands is a fault")
    garbage_hold_s: float = param(1.0, unit="s", lo=0.0, hi=30.0, doc="a garbage burst on either line counts as a fault for this long")
    nmea_garbage_lines: int = param(5, unit="lines", lo=1, hi=1000, doc="more rejected NMEA lines than this within 1 s is a garbage burst on the compass line")
    mbed_garbage_lines: int = param(5, unit="lines", lo=1, hi=1000, doc="more malformed Mbed lines than this within 1 s is a garbage burst")
    garbage_bytes: int = param(32, unit="bytes", lo=1, hi=100000, doc="more bytes that no NMEA or Mbed line can hold (not printable ASCII, CR, LF) than this within 1 s is a garbage burst on that line (random bytes at 4800 baud: ~300 a second)")
    resume_valid_s: float = param(2.0, unit="s", lo=0.0, hi=120.0, doc="data must be valid again for this long before thrust resumes")
    start_valid_s: float = param(1.0, unit="s", lo=0.0, hi=120.0, doc="data must be valid for this long before the mission starts")
    max_mission_time_s: float = param(1800.0, unit="s", lo=1.0, hi=86400.0, doc="mission time limit: zero thrust and stop when reached")
    max_distance_m: float = param(500.0, unit="m", lo=1.0, hi=20000.0, doc="largest distance from the origin before a latched failsafe")
    resume_after_restart: bool = param(False, doc="after a restart, continue from the saved waypoint (else refuse to move)")
    allow_beyond_limits: bool = param(False, doc="a mission (at start or uploaded) or a point commanded beyond the geofence or "
                                      "max_distance_m, or a start outside them, is refused naming it; true allows it, to test "
                                      "those failsafes on the water (the failsafe then takes the boat when it gets there)")
    cog_fallback: bool = param(False, doc="steer on course over ground when the heading is lost (logged as heading_source COG)")
    cog_fallback_min_sog_m_s: float = param(0.5, unit="m/s", lo=0.0, hi=10.0, doc="COG is meaningless below this speed")
    battery_sag_v: float = param(1.2, unit="V", lo=0.0, hi=5.0,
                                 source="~60 A x 20 mOhm; measure it: resting voltage minus voltage at full thrust",
                                 doc="voltage drop at 100 % duty on both thrusters; the failsafe judges the resting voltage "
                                     "estimate V + sag (d_port^3 + d_stbd^3) / 2 (0 = the voltage as measured)")
    battery_low_v: float = param(12.0, unit="V", lo=0.0, hi=30.0,
                                 source="12 V lead-acid resting: ~30 % charge, enough to come home (SPEC 1: 105 Ah)",
                                 doc="resting voltage estimate below this for battery_low_s: battery_low (0 = off)")
    battery_low_s: float = param(10.0, unit="s", lo=0.0, hi=600.0, source="ArduPilot BATT_LOW_TIMER",
                                 doc="how long it must stay low (a short sag is not an empty battery)")
    battery_critical_v: float = param(11.7, unit="V", lo=0.0, hi=30.0, source="12 V lead-acid resting: ~10 % charge",
                                      doc="below this for battery_critical_s: battery_critical, always stop (0 = off)")
    battery_critical_s: float = param(5.0, unit="s", lo=0.0, hi=600.0, doc="how long it must stay that low")
    actions: FailsafeActions = param(default_factory=FailsafeActions, doc="the action per fault class")

    def __post_init__(self) -> None:
        # ordered only when both are on: battery_low_v 0 is "off", as documented (a new-user audit found it refused)
        if self.battery_low_v > 0.0 and self.battery_critical_v > self.battery_low_v:
            raise ConfigError(f"failsafe.battery_critical_v: {self.battery_critical_v:g} V is above "
                              f"failsafe.battery_low_v ({self.battery_low_v:g} V)")


@dataclass(frozen=True)
class AisSourceConfig:
    """Where AIS comes from (issue 18): a receiver on its own port, or interleaved on the compass line."""

    port: str = param("", doc="the AIS receiver's serial port (an udev name such as /dev/ais); empty = none")
    baud: int = param(38400, unit="bit/s", lo=4800, hi=38400, source="IEC 61162-2 (AIS receivers: 38400)",
                      doc="its baud rate: 4800 or 38400")
    on_compass_line: bool = param(False, doc="AIS sentences (!AIVDM) arrive interleaved on the SC-30's line (at 4800 "
                                  "baud the SC-30's sentences leave ~46 characters a second: a few vessels; see the README)")
    receiver: AisConfig = param(default_factory=AisConfig, doc="target table: stale targets, message assembly")

    def __post_init__(self) -> None:
        if self.baud not in (4800, 38400):
            raise ConfigError(f"ais.baud: {self.baud} is not one of 4800, 38400")


@dataclass(frozen=True)
class SimConfig:
    """`--sim`: the simulated SC-30 and Mbed on pseudo-terminals, in the daemon's own event loop."""

    origin_lat_deg: float = param(52.0, unit="deg", lo=-89.0, hi=89.0, doc="where a local-frame mission without origin is placed under --sim (any point; only the local frame matters)")
    origin_lon_deg: float = param(4.4, unit="deg", lo=-180.0, hi=180.0, doc="see origin_lat_deg")
    vessel: str = param("", doc="vessel parameter file; empty = the calibrated default (config/vessel.yaml)")
    sc30_fast_sentences: tuple[str, ...] = param((), choices=_SIM_SENTENCES, doc="sentences the simulated SC-30 sends at 10 Hz; empty = the default for serial.sc30_baud (docs/sc30.md)")
    sc30_slow_sentences: tuple[str, ...] = param((), choices=_SIM_SENTENCES, doc="sentences it sends at 1 Hz; empty = the default for serial.sc30_baud (docs/sc30.md)")
    heading_noise_deg: float = param(0.1, unit="deg", lo=0.0, hi=10.0, doc="SC-30 heading noise (1 sigma)")
    position_noise_m: float = param(0.3, unit="m", lo=0.0, hi=20.0, doc="SC-30 position noise (1 sigma)")
    seed: int = param(0, lo=0, hi=2**31 - 1, doc="noise seed")
    current_speed_m_s: float = param(0.0, unit="m/s", lo=0.0, hi=3.0, doc="uniform current speed")
    current_towards_deg: float = param(0.0, unit="deg", lo=0.0, hi=360.0, doc="current direction (towards)")
    wind_speed_m_s: float = param(0.0, unit="m/s", lo=0.0, hi=30.0, doc="wind speed")
    wind_from_deg: float = param(0.0, unit="deg", lo=0.0, hi=360.0, doc="wind direction (from)")
    battery_capacity_ah: float = param(105.0, unit="Ah", lo=0.001, hi=1000.0, source="SPEC 1",
                                       doc="the simulated battery's capacity (autopilot/sim/battery.py)")
    battery_initial_soc: float = param(1.0, unit="-", lo=0.0, hi=1.0, doc="its state of charge at the start")
    thrust_gain_port: float = param(1.0, unit="-", lo=0.0, hi=1.5, source="not in the sources: a bench fault",
                                    doc="the simulated port motor makes this fraction of the thrust table's thrust "
                                    "(0.9: a fouled propeller's 10 % loss); the helm and the allocation do not know")
    thrust_gain_stbd: float = param(1.0, unit="-", lo=0.0, hi=1.5, source="not in the sources: a bench fault",
                                    doc="the same for the starboard motor")
    mbed_reports_battery: bool = param(True, doc="the simulated Mbed reports the battery voltage (false: old firmware)")
    traffic: str = param("", doc="a traffic scenario (a shipped name such as head-on, or a YAML file): its vessels "
                         "are sent as AIS sentences by a simulated receiver on its own pseudo-terminal; empty = none")
    # realistic SC-30 errors (autopilot.sim.gps_error, the identification's measurement model); 0 = off
    position_wander_m: float = param(0.0, unit="m", lo=0.0, hi=50.0, source="issue 12: 0.5-2 m", doc="wandering (Gauss-Markov) GPS error per axis, 1 sigma; > 0 (or an outlier rate) switches to one fix per second with position_noise_m as its white part")
    position_wander_time_s: float = param(45.0, unit="s", lo=0.1, hi=1e5, source="issue 12: 30-60 s", doc="correlation time of the GPS wander")
    position_outlier_rate: float = param(0.0, unit="-", lo=0.0, hi=1.0, source="issue 12: 1 %", doc="fraction of GPS fixes that start a jump by position_outlier_m")
    position_outlier_m: float = param(10.0, unit="m", lo=0.0, hi=1000.0, source="issue 12: 10 m", doc="size of a GPS jump")
    position_outlier_fixes: int = param(1, unit="fixes", lo=1, hi=60, source="not in the sources: multipath holds a receiver on a wrong solution for seconds", doc="consecutive fixes one GPS jump lasts (1: single-fix outliers)")
    velocity_noise_m_s: float = param(0.05, unit="m/s", lo=0.0, hi=5.0, source="not in the sources: a GNSS receiver's Doppler velocity", doc="error of the reported speed and course over ground, as a velocity error per axis (white, 1 sigma), with the realistic GPS error above")
    heading_wander_deg: float = param(0.0, unit="deg", lo=0.0, hi=30.0, source="issue 12: 0.3 deg", doc="slowly wandering heading error, 1 sigma; > 0 (or a loss rate) adds it to heading_noise_deg")
    heading_wander_time_s: float = param(30.0, unit="s", lo=0.1, hi=1e5, doc="correlation time of the heading wander")
    heading_loss_rate: float = param(0.0, unit="-", lo=0.0, hi=1.0, source="issue 12: 0.5 %", doc="fraction of heading sentences lost")

    @property
    def position_error_model(self):
        """The realistic GPS error of the simulated SC-30, or None (plain position_noise_m per sentence)."""
        from autopilot.sim.gps_error import GpsErrorModel

        if self.position_wander_m == 0.0 and self.position_outlier_rate == 0.0:
            return None
        return GpsErrorModel(wander_m=self.position_wander_m, wander_time_s=self.position_wander_time_s,
                             white_m=self.position_noise_m, outlier_rate=self.position_outlier_rate,
                             outlier_m=self.position_outlier_m, outlier_fixes=self.position_outlier_fixes,
                             velocity_white_m_s=self.velocity_noise_m_s)

    @property
    def heading_error_model(self):
        """The realistic heading error of the simulated SC-30, or None (plain heading_noise_deg)."""
        from autopilot.sim.gps_error import HeadingErrorModel

        if self.heading_wander_deg == 0.0 and self.heading_loss_rate == 0.0:
            return None
        return HeadingErrorModel(wander_deg=self.heading_wander_deg, wander_time_s=self.heading_wander_time_s,
                                 white_deg=self.heading_noise_deg, loss_rate=self.heading_loss_rate)


# two commands inside the Mbed firmware's stop timeout at least: at 1-2 Hz it cut the motors between commands
MIN_RATE_HZ = 2.0 / FIRMWARE_STOP_TIMEOUT_S


@dataclass(frozen=True)
class DaemonConfig:
    """The whole ``autopilot run`` configuration."""

    rate_hz: float = param(10.0, unit="Hz", lo=MIN_RATE_HZ, hi=50.0,
                           doc="control loop rate (absolute deadlines); at least two commands inside the Mbed firmware's "
                               "0.5-s stop timeout (docs/mbed-protocol.md): at 1-2 Hz it cut the motors between commands")
    origin_lat_deg: float | None = param(None, unit="deg", lo=-90.0, hi=90.0, doc="local-frame origin; null = the mission file's origin")
    origin_lon_deg: float | None = param(None, unit="deg", lo=-180.0, hi=180.0, doc="local-frame origin; null = the mission file's origin")
    max_mission_range_m: float = param(2000.0, unit="m", lo=1.0, hi=50000.0, doc="refuse missions with a waypoint farther than this from the origin")
    boat_length_m: float = param(HULL_LENGTH_M, unit="m", lo=1.0, hi=50.0, source="SPEC 1", doc="hull length L for the fuzzy guidance (the simulated vessel's own length under --sim)")
    log_dir: str = param("logs", doc="mission log directory (systemd passes $LOGS_DIRECTORY with --log-dir)")
    state_dir: str = param("state", doc="mission progress directory (systemd passes $STATE_DIRECTORY with --state-dir)")
    runtime_dir: str = param("", doc="directory of the control socket (autopilot ctl); empty = $RUNTIME_DIRECTORY (systemd), else $XDG_RUNTIME_DIR/autopilot, else /tmp/autopilot-<uid>")
    ready_timeout_s: float = param(30.0, unit="s", lo=0.5, hi=600.0, doc="log a warning if both devices have not answered after this")
    stop_ack_timeout_s: float = param(1.0, unit="s", lo=0.05, hi=10.0, doc="on SIGTERM, wait this long for the zero-thrust acknowledgement")
    dead_reckon_max_s: float = param(
        1.5, unit="s", lo=0.0, hi=5.0,
        doc="carry the last position fix forward by SOG/COG for at most this long between fixes (0 = off; autopilot.gnc.navigation)",
    )
    serial: SerialConfig = param(default_factory=SerialConfig)
    failsafe: FailsafeConfig = param(default_factory=FailsafeConfig)
    geofence: GeofenceConfig = param(default_factory=GeofenceConfig)
    sim: SimConfig = param(default_factory=SimConfig)
    gnc: GncConfig = param(default_factory=GncConfig)
    ais: AisSourceConfig = param(default_factory=AisSourceConfig, doc="AIS targets for collision avoidance (issue 18)")
    mavlink: MavlinkConfig = param(default_factory=MavlinkConfig, doc="the live link to QGroundControl and Mission Planner (issue 16)")

    def __post_init__(self) -> None:
        if (self.origin_lat_deg is None) != (self.origin_lon_deg is None):
            raise ConfigError("origin_lat_deg, origin_lon_deg: give both or neither")
        for key, port in self.device_ports():
            if not port.strip():  # the daemon retried "cannot open : no such device" for ever, naming no key
                raise ConfigError(f"{key}: empty; the device's serial port, such as /dev/sc30 or /dev/serial/by-id/...")
        ports = self.device_ports()
        for k, (key, port) in enumerate(ports):
            for other, same in ports[:k]:
                if os.path.realpath(port) == os.path.realpath(same):
                    # two drivers on one line steal each other's bytes: the boat sat waiting with no reason given
                    raise ConfigError(f"{key}: {port} is {other} too: each device needs its own port")
        if self.failsafe.heading_stale_s < 1.0 / self.rate_hz:
            raise ConfigError(
                f"failsafe.heading_stale_s: {self.failsafe.heading_stale_s} s is shorter than one control period ({1.0 / self.rate_hz:g} s)"
            )

    @property
    def period_s(self) -> float:
        return 1.0 / self.rate_hz

    def device_ports(self) -> list[tuple[str, str]]:
        """(key, path) of each serial device the daemon drives or reads (the AIS port when there is one)."""
        ports = [("serial.sc30_port", self.serial.sc30_port), ("serial.mbed_port", self.serial.mbed_port)]
        return ports + ([("ais.port", self.ais.port)] if self.ais.port else [])


def load_config(path: str | Path) -> DaemonConfig:
    """Read and check the whole configuration file (raises ConfigError naming file and key)."""
    # an empty file (a copy cut short, a config management template never filled) flew on every default
    # without a word: the boat's own failsafe limits and origin silently replaced by the shipped ones
    try:
        cfg = load_yaml(DaemonConfig, path, empty="the configuration is empty (no setting at all); to run on every "
                        "default say so with {} in the file, or start from config/autopilot.yaml")
    except ConfigError as exc:
        # a mission or a vessel file given as the configuration was refused as "frame: unknown key": say what it is
        what = other_file_kind(path)
        if what is not None and not what.startswith("a daemon configuration") and ": unknown key (allowed: " in str(exc):
            where = "--config and --mission swapped?" if what.startswith("a mission") else "sim.vessel names it"
            raise ConfigError(f"{exc}; {path} is {what}, not the daemon's configuration ({where})") from None
        raise
    if not math.isfinite(cfg.period_s):  # pragma: no cover - rate_hz is range-checked
        raise ConfigError("rate_hz: not finite")
    return cfg


def render_yaml(cfg: DaemonConfig | None = None) -> str:
    """The whole configuration as commented YAML (how config/autopilot.yaml is generated)::

        python -c "from autopilot.daemon.config import render_yaml; print(render_yaml(), end='')" > config/autopilot.yaml
    """
    import dataclasses

    import yaml

    from autopilot.schema import _range_text, to_dict

    lines = [
        "# autopilot run --config config/autopilot.yaml: every setting, with its default.",
        "# Unit, allowed range and meaning in the comment above each key. An unknown key, a wrong",
        "# type or an out-of-range value stops the start (before any port is opened) naming the key.",
        "",
    ]

    def emit(obj, pad: str) -> None:
        for f in dataclasses.fields(obj):
            value, meta = getattr(obj, f.name), f.metadata
            doc = meta.get("doc", "")
            if dataclasses.is_dataclass(value):
                if doc:
                    lines.append(f"{pad}# {doc}")
                lines.append(f"{pad}{f.name}:")
                emit(value, pad + "  ")
                continue
            if meta.get("choices"):
                rng = "one of " + ", ".join(meta["choices"])
            elif meta.get("lo") is not None or meta.get("hi") is not None:
                rng = _range_text(meta)
            else:
                rng = "" if meta.get("unit", "-") == "-" else meta["unit"]
            src = f"; source: {meta['source']}" if meta.get("source") else ""
            lines.append((f"{pad}# {doc}" + (f" [{rng}]" if rng else "") + src).rstrip())
            text = yaml.safe_dump({f.name: to_dict(value)}, default_flow_style=True, width=1000).strip()
            lines.append(pad + (text[1:-1] if text.startswith("{") else text))

    emit(cfg or DaemonConfig(), "")
    return "\n".join(lines) + "\n"
