"""Declarative parameters: frozen dataclasses whose fields carry unit, range and source.

Every parameter of the project (vessel model, GNC gains, daemon settings) is
declared once with :func:`param`; :func:`load` builds the dataclass from a
mapping (parsed YAML) and refuses unknown keys, missing keys, wrong types,
NaN and out-of-range values with a message that names the key and the
allowed range, before anything is used.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

__all__ = ["ConfigError", "param", "load", "load_yaml", "to_dict", "describe", "unknown_key"]


class ConfigError(ValueError):
    """A configuration or parameter value that cannot be accepted."""


def param(
    default: Any = dataclasses.MISSING,
    *,
    unit: str = "-",
    lo: float | None = None,
    hi: float | None = None,
    source: str = "",
    doc: str = "",
    choices: tuple[str, ...] | None = None,
    default_factory: Any = dataclasses.MISSING,
) -> Any:
    """A dataclass field with its unit, inclusive range [lo, hi], source and meaning."""
    meta = {"unit": unit, "lo": lo, "hi": hi, "source": source, "doc": doc, "choices": choices}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _bound_text(x: float | int) -> str:
    # an integer bound exactly (a seed's 2**63 - 1 read 9.22337e+18); a float one short
    return str(x) if isinstance(x, int) else f"{x:g}"


def _range_text(meta: Mapping[str, Any]) -> str:
    lo, hi = meta.get("lo"), meta.get("hi")
    unit = meta.get("unit", "-")
    lo_s = "-inf" if lo is None else _bound_text(lo)
    hi_s = "inf" if hi is None else _bound_text(hi)
    return f"[{lo_s}, {hi_s}] {'' if unit == '-' else unit}".rstrip()


def _check_number(key: str, value: Any, want: type, meta: Mapping[str, Any]) -> float | int:
    bounded = meta.get("lo") is not None or meta.get("hi") is not None
    within = f" in {_range_text(meta)}" if bounded else ""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{key}: expected a{'n integer' if want is int else ' number'}{within}, got {value!r}")
    if want is int and not float(value).is_integer():
        raise ConfigError(f"{key}: expected an integer{within}, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{key}: {value!r} is not a finite number" + (f"; allowed range {_range_text(meta)}"
                                                                          if bounded else ""))
    lo, hi = meta.get("lo"), meta.get("hi")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        hint = ""
        if meta.get("unit") == "deg" and lo is not None and hi is not None and -lo == hi and hi in (90.0, 180.0):
            from autopilot.userfile import degrees_minutes

            deg = degrees_minutes(float(value), float(hi))  # origin_lat_deg: 4807.038, a GGA's ddmm.mmm as it is
            if deg is not None:
                hint = f" ({value!r} is degrees and minutes as NMEA writes them? that is {deg:.6f} deg)"
        raise ConfigError(f"{key}: {value!r} is outside the allowed range {_range_text(meta)}{hint}")
    return int(value) if want is int else float(value)


def _convert(key: str, value: Any, tp: Any, meta: Mapping[str, Any]) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(key, value, inner[0], meta)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, Mapping):
            got = "nothing (an empty section)" if value is None else f"{type(value).__name__} {value!r}"
            raise ConfigError(f"{key}: expected its settings as 'key: value' lines below it, got {got}")
        return load(tp, value, where=f"{key}.")
    if tp is float or tp is int:
        return _check_number(key, value, tp, meta)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if tp is str:
        choices = meta.get("choices")
        if not isinstance(value, str):
            # `position: no` is YAML's false and `sc30_port:` with nothing is null: "expected a string, got False"
            # named neither what to write nor that YAML had read a word as something else (a new-user audit)
            want = f"one of {', '.join(choices)}" if choices else "a string"
            got = ("nothing (write '' for empty)" if value is None and not choices else "nothing" if value is None
                   else f"{value!r} (YAML reads yes/no/on/off as true/false: quote the word)" if isinstance(value, bool)
                   else repr(value))
            raise ConfigError(f"{key}: expected {want}, got {got}")
        if choices and value not in choices:
            raise ConfigError(f"{key}: {value!r} is not one of {', '.join(choices)}")
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{key}: expected a list, got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(f"{key}[{i}]", v, args[0], meta) for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{key}: expected a list of {len(args)} values, got {len(value)}")
        return tuple(_convert(f"{key}[{i}]", v, a, meta) for i, (v, a) in enumerate(zip(value, args)))
    if tp is Any:
        return value
    raise ConfigError(f"{key}: unsupported parameter type {tp!r}")  # pragma: no cover - programming error



def unknown_key(key, allowed) -> str:
    """"unknown key (allowed: ...)" for ``key``, with the allowed key it most likely misspells: among 34 vessel keys
    a `mass_kgs` or a `sc30_prot` left the user to spot the right one in the list."""
    import difflib

    text = f"unknown key (allowed: {', '.join(sorted(allowed))})"
    close = difflib.get_close_matches(str(key), [str(k) for k in allowed], n=1, cutoff=0.75)
    return text + (f"; did you mean {close[0]}?" if close else "")

def load(cls: type, data: Mapping[str, Any] | None, *, where: str = "", require_all: bool = False) -> Any:
    """Build the frozen dataclass ``cls`` from ``data``, checking every key.

    Missing keys take the field's default when it has one; a key without
    a default must be present, and with ``require_all`` every key must (a
    vessel file: a default there would be a thesis value passed off as the
    user's boat). ``where`` prefixes key names in messages.
    """
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        what = where.rstrip(".") if where else "the file"
        raise ConfigError(f"{what}: expected settings as 'key: value' lines, got a {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(f"{where}{unknown[0]}: {unknown_key(unknown[0], fields)}")
    kwargs: dict[str, Any] = {}
    for name, f in fields.items():
        key = f"{where}{name}"
        if name not in data:
            if ((require_all and hints[name] is not str)  # a label (name, description) may be left out
                    or (f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)):
                where_ok = _range_text(f.metadata) if f.metadata.get("lo") is not None or f.metadata.get("hi") is not None else ""
                raise ConfigError(f"{key}: missing required key ({f.metadata.get('doc', '')} {where_ok})"
                                  .replace("( ", "(").replace(" )", ")"))
            continue
        kwargs[name] = _convert(key, data[name], hints[name], f.metadata)
    try:
        obj = cls(**kwargs)
    except ConfigError as exc:
        # a check across fields names its field as the class knows it ("kinds: ..."); nested, the reader needs
        # the whole path ("conditions.gusty.faults.kinds: ...")
        if where and str(exc).split(":", 1)[0] in fields:
            raise ConfigError(f"{where}{exc}") from None
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where or cls.__name__}: {exc}") from exc
    return obj


def load_yaml(cls: type, path: str | Path, *, require_all: bool = False, empty: str | None = None) -> Any:
    """Load ``cls`` from a YAML file; syntax errors become :class:`ConfigError` naming the file. ``empty``:
    an empty file (or comments only) is refused with this text, rather than read as every default."""
    from autopilot.userfile import parse_yaml, read_text, yaml_problem

    path = Path(path)
    text = read_text(path, what="YAML file")
    try:
        data = parse_yaml(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({yaml_problem(exc)})") from exc
    if data is None and empty is not None:
        raise ConfigError(f"{path}: {empty}")
    try:
        return load(cls, data, require_all=require_all)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from exc


def to_dict(obj: Any) -> Any:
    """Plain YAML-able data of a parameter dataclass (tuples become lists)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj) if f.init}
    if isinstance(obj, (tuple, list)):
        return [to_dict(v) for v in obj]
    return obj


def describe(cls: type) -> list[dict[str, Any]]:
    """One row per field: name, unit, range, default, source, meaning (for docs and --help)."""
    rows = []
    for f in dataclasses.fields(cls):
        default = None if f.default is dataclasses.MISSING else f.default
        rows.append(
            {
                "name": f.name,
                "unit": f.metadata.get("unit", "-"),
                "range": _range_text(f.metadata),
                "default": default,
                "source": f.metadata.get("source", ""),
                "doc": f.metadata.get("doc", ""),
            }
        )
    return rows
