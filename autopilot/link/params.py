"""MAVLink parameters: a chosen set of configuration keys, read and set with the YAML's own ranges.

Names follow ArduPilot's where the meaning is the same (WP_SPEED, WP_RADIUS, LOIT_RADIUS,
FS_GCS_TIMEOUT); the rest are this autopilot's own. Every value is a float on the wire
(PARAM_FLOAT); a choice (an action) is its index in the key's choices, a flag 0 or 1. A set is
checked with the key's range exactly as the configuration file is (:func:`autopilot.schema`'s
checks), applied between two cycles, logged (``param`` event), and not written back to the file:
the configuration file stays the boat's source of truth after a restart.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass

from autopilot.schema import ConfigError, _convert

__all__ = ["PARAMS", "Param", "by_name", "value_of", "check_set"]


@dataclass(frozen=True)
class Param:
    name: str  # at most 16 characters (MAVLink param_id)
    key: str  # dotted configuration key


PARAMS: tuple[Param, ...] = (
    Param("HDG_KP", "gnc.pid.kp_n_per_deg"),
    Param("HDG_KI", "gnc.pid.ki_n_per_deg_s"),
    Param("HDG_KD", "gnc.pid.kd_n_s_per_deg"),
    Param("HDG_IMAX", "gnc.pid.integral_limit_n"),
    Param("WP_SPEED", "gnc.guidance.default_speed_m_s"),
    Param("WP_SPEED_MIN", "gnc.guidance.min_speed_m_s"),
    Param("WP_RADIUS", "gnc.guidance.capture_radius_m"),
    Param("WP_SLOWDOWN", "gnc.guidance.arrival_slowdown_m"),
    Param("SPD_KP", "gnc.speed.kp_n_s_per_m"),
    Param("SPD_KI", "gnc.speed.ki_n_per_m"),
    Param("LOIT_RADIUS", "gnc.hold.radius_m"),
    Param("HOLD_KV", "gnc.hold.kv_n_s_per_m"),
    Param("HOLD_KI", "gnc.hold.ki_n_per_m_s"),
    Param("HOLD_SPD_GAIN", "gnc.hold.speed_gain_per_s"),
    Param("HOLD_BRAKE", "gnc.hold.brake_m_s2"),
    Param("HOLD_HDG_RATE", "gnc.hold.heading_rate_deg_s"),
    Param("FS_HDG_STALE", "failsafe.heading_stale_s"),
    Param("FS_POS_STALE", "failsafe.position_stale_s"),
    Param("FS_RESUME", "failsafe.resume_valid_s"),
    Param("FS_MAX_TIME", "failsafe.max_mission_time_s"),
    Param("FS_MAX_DIST", "failsafe.max_distance_m"),
    Param("FS_ACK_MISS", "failsafe.ack_missing_n"),
    Param("FS_GF_ACT", "failsafe.actions.geofence"),
    Param("FS_DIST_ACT", "failsafe.actions.max_distance"),
    Param("FS_TIME_ACT", "failsafe.actions.max_mission_time"),
    Param("FS_BATT_ACT", "failsafe.actions.battery_low"),
    Param("BATT_LOW_V", "failsafe.battery_low_v"),
    Param("BATT_CRT_V", "failsafe.battery_critical_v"),
    Param("BATT_SAG_V", "failsafe.battery_sag_v"),
    Param("FS_GCS_TIMEOUT", "mavlink.gcs_timeout_s"),
    Param("FS_GCS_ACT", "mavlink.gcs_lost_action"),
    Param("MAN_TIMEOUT", "mavlink.manual_timeout_s"),
    Param("MAN_TIMEOUT_ACT", "mavlink.manual_timeout_action"),
)
_BY_NAME = {p.name: p for p in PARAMS}
assert all(len(p.name) <= 16 for p in PARAMS)


def by_name(name: str) -> Param | None:
    return _BY_NAME.get(name)


def _field(cfg, key: str):
    """(the dataclass field of a dotted key, its type) in a configuration tree."""
    obj, parts = cfg, key.split(".")
    for part in parts[:-1]:
        obj = getattr(obj, part)
    hints = typing.get_type_hints(type(obj))
    field = next(f for f in dataclasses.fields(obj) if f.name == parts[-1])
    return field, hints[parts[-1]], getattr(obj, parts[-1])


def value_of(cfg, p: Param) -> float:
    """The parameter's value as MAVLink carries it (a float)."""
    field, tp, value = _field(cfg, p.key)
    choices = field.metadata.get("choices")
    if choices:
        return float(choices.index(value))
    return float(value)


WIRE_TYPE = 9  # MAV_PARAM_TYPE_REAL32: what every PARAM_VALUE says (MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT)


def _type_name(param_type: int) -> str:
    from pymavlink.dialects.v20 import common

    entry = common.enums["MAV_PARAM_TYPE"].get(param_type)
    return f"{param_type} ({entry.name})" if entry is not None else str(param_type)


def as_typed(wire_value: float) -> float:
    """A float32 field as the operator typed it. PARAM_SET and COMMAND_LONG carry float32: 0.06 arrives as
    0.05999999865889549, 1.6 m/s as 1.600000023841858. The shortest decimal that is the same float32 (7
    significant digits) is what the operator typed, and what the log and the answers show."""
    return float(f"{wire_value:.7g}")


def check_set(cfg, p: Param, wire_value: float, param_type: int = WIRE_TYPE):
    """The configuration value a PARAM_SET means, checked with the key's range; ConfigError names both.

    ``param_type`` other than REAL32 (or 0, unsaid) is refused: the float field then holds another type's
    bytes (an INT32 1 sent bytewise reads 1.4e-45, inside HDG_KP's range, found by a new-user audit)."""
    if param_type not in (0, WIRE_TYPE):
        raise ConfigError(f"{p.name} ({p.key}): param_type {_type_name(param_type)} refused: every parameter here "
                          f"is a float, param_type {_type_name(WIRE_TYPE)}, as its PARAM_VALUE says")
    field, tp, _ = _field(cfg, p.key)
    meta = field.metadata
    choices = meta.get("choices")
    if not math.isfinite(wire_value):
        raise ConfigError(f"{p.name} ({p.key}): {wire_value!r} is not a finite number")
    if choices:
        k = int(wire_value)
        if k != wire_value or not 0 <= k < len(choices):
            raise ConfigError(f"{p.name} ({p.key}): {wire_value:g} is not one of "
                              + ", ".join(f"{i} = {c}" for i, c in enumerate(choices)))
        return choices[k]
    if tp is bool:
        if wire_value not in (0.0, 1.0):
            raise ConfigError(f"{p.name} ({p.key}): {wire_value:g} is not 0 or 1")
        return bool(wire_value)
    wire_value = as_typed(wire_value)
    value = int(wire_value) if tp is int and float(wire_value).is_integer() else wire_value
    try:
        return _convert(p.key, value, tp, meta)
    except ConfigError as exc:
        raise ConfigError(f"{p.name} ({exc})") from None
