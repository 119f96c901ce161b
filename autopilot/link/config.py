"""The ``mavlink:`` block of the daemon's configuration (issue 16)."""

from __future__ import annotations

from dataclasses import dataclass

from autopilot.schema import ConfigError, param

__all__ = ["MavlinkRates", "MavlinkConfig", "GCS_LOST_ACTIONS", "MANUAL_TIMEOUT_ACTIONS"]

GCS_LOST_ACTIONS = ("continue", "hold", "rtl")
MANUAL_TIMEOUT_ACTIONS = ("hold", "stop")


@dataclass(frozen=True)
class MavlinkRates:
    """How often each telemetry message goes out (Hz of wall time; 0 = not sent). A ground station may
    change them with MAV_CMD_SET_MESSAGE_INTERVAL."""

    heartbeat_hz: float = param(1.0, unit="Hz", lo=0.2, hi=10.0, source="MAVLink: 1 Hz", doc="HEARTBEAT")
    sys_status_hz: float = param(1.0, unit="Hz", lo=0.0, hi=10.0, doc="SYS_STATUS (battery, sensor health)")
    gps_raw_int_hz: float = param(1.0, unit="Hz", lo=0.0, hi=10.0, source="the SC-30's fix rate",
                                  doc="GPS_RAW_INT")
    global_position_int_hz: float = param(5.0, unit="Hz", lo=0.0, hi=50.0, doc="GLOBAL_POSITION_INT")
    attitude_hz: float = param(10.0, unit="Hz", lo=0.0, hi=50.0, source="the SC-30's heading rate", doc="ATTITUDE")
    vfr_hud_hz: float = param(4.0, unit="Hz", lo=0.0, hi=50.0, doc="VFR_HUD")
    nav_controller_output_hz: float = param(4.0, unit="Hz", lo=0.0, hi=50.0, doc="NAV_CONTROLLER_OUTPUT")
    mission_current_hz: float = param(1.0, unit="Hz", lo=0.0, hi=10.0, doc="MISSION_CURRENT")


@dataclass(frozen=True)
class MavlinkConfig:
    """The live link to QGroundControl and Mission Planner. Nothing listens unless an endpoint is given."""

    endpoints: tuple[str, ...] = param((), doc="udpout:HOST:PORT (a ground station listening; QGC's default "
                                       "14550), udpin:ADDR:PORT (the daemon listens on that address only), or a "
                                       "serial radio /dev/...:BAUD; autopilot run --mavlink adds more")
    system_id: int = param(1, lo=1, hi=255, source="MAVLink: 1 for the first vehicle", doc="this vehicle's system id")
    component_id: int = param(1, lo=1, hi=255, source="MAV_COMP_ID_AUTOPILOT1", doc="this autopilot's component id")
    gcs_system_id: int = param(255, lo=1, hi=255, source="QGC and Mission Planner use 255",
                               doc="the ground station whose heartbeat counts for link loss")
    gcs_timeout_s: float = param(5.0, unit="s", lo=1.0, hi=300.0, source="ArduPilot FS_GCS_TIMEOUT",
                                 doc="a ground station seen once whose heartbeat stops this long: link lost")
    gcs_lost_action: str = param("continue", choices=GCS_LOST_ACTIONS,
                                 doc="on link loss: the mission goes on, or hold, or return to launch")
    manual_timeout_s: float = param(0.5, unit="s", lo=0.1, hi=10.0, source="issue 16",
                                    doc="manual control silent this long ends manual (never the last stick position)")
    manual_timeout_action: str = param("hold", choices=MANUAL_TIMEOUT_ACTIONS, doc="what follows a silent manual source")
    signing_key_file: str = param("", doc="MAVLink 2 signing key (64 hex digits, or 32 raw bytes), a file readable by "
                                  "the service's user alone; credential:NAME = $CREDENTIALS_DIRECTORY/NAME (systemd "
                                  "LoadCredential=); empty = no signing")
    signing_required: bool = param(True, doc="with a key: unsigned or wrongly signed commands, missions and parameter "
                                   "writes are refused and logged (telemetry and read requests still answered)")
    rx_queue_bytes: int = param(262144, unit="bytes", lo=4096, hi=16777216,
                                doc="received bytes waiting to be parsed; beyond, datagrams are dropped and counted "
                                    "(a flood never delays the control loop)")
    rates: MavlinkRates = param(default_factory=MavlinkRates, doc="telemetry rates")

    def __post_init__(self) -> None:
        from autopilot.link.endpoint import parse_endpoint

        for url in self.endpoints:
            try:
                parse_endpoint(url)
            except ValueError as exc:
                raise ConfigError(f"mavlink.endpoints: {exc}") from None
