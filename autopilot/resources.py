"""The files shipped inside the package: vessel parameter sets, the measured table, missions, the default configuration.

They live in ``autopilot/data/`` (the checkout's ``config/`` is a link to it),
are installed with the wheel as package data and are found through
:mod:`importlib.resources`, so an installed copy (``pip install .``, not only
an editable checkout) simulates, evaluates and identifies with its defaults.
``autopilot files`` lists them, so a user can copy one and edit it.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

__all__ = [
    "data_dir",
    "default_config_path",
    "default_params_path",
    "thesis_params_path",
    "measured_table_path",
    "missions_dir",
    "shipped_mission",
    "shipped_missions",
    "find_mission",
    "campaigns_dir",
    "shipped_campaigns",
    "shipped_files",
    "package_version",
]


def data_dir() -> Path:
    """``autopilot/data`` of the installed (or checked-out) package."""
    return Path(str(files("autopilot").joinpath("data")))


def default_config_path() -> Path:
    """``autopilot.yaml``: every daemon setting at its default, with unit and range in comments."""
    return data_dir() / "autopilot.yaml"


def default_params_path() -> Path:
    """``vessel.yaml``: the set calibrated against the measured table (SPEC 6)."""
    return data_dir() / "vessel.yaml"


def thesis_params_path() -> Path:
    """``vessel-thesis.yaml``: Table 5.1 as printed."""
    return data_dir() / "vessel-thesis.yaml"


def measured_table_path() -> Path:
    """``measured-table.csv``: the free-running table of thesis Fig 8.2 (SPEC 6)."""
    return data_dir() / "measured-table.csv"


def missions_dir() -> Path:
    """``missions/``: the thesis and pond missions (and format examples in ``missions/examples``)."""
    return data_dir() / "missions"


def shipped_missions() -> list[Path]:
    """The YAML missions of ``missions/`` (not the format examples), sorted by name."""
    return sorted(missions_dir().glob("*.yaml"))


def shipped_mission(name: str) -> Path | None:
    """The shipped mission a bare name means (``pond-9.4`` or ``pond-9.4.yaml``, format examples too), or None."""
    if not name or "/" in name or name.startswith("."):
        return None
    for p in [*shipped_missions(), *sorted((missions_dir() / "examples").glob("*"))]:
        if name in (p.name, p.stem) and p.is_file():
            return p
    return None


def find_mission(given: str, base_dir: Path | None = None) -> tuple[Path, bool]:
    """(the file a mission argument means, whether it is a shipped one): a file (relative to ``base_dir`` when
    given), else a shipped mission by its name (:func:`shipped_mission`); ConfigError listing the shipped ones.
    One rule for ``run``, ``evaluate`` and campaign specs (evaluate took only files)."""
    from autopilot.schema import ConfigError

    path = Path(given) if base_dir is None else base_dir / given
    if path.is_file() or path.is_dir():  # a directory: the mission reader says so (it was "no such file")
        return path, False
    shipped = shipped_mission(given)
    if shipped is not None:
        return shipped, True
    names = ", ".join(p.stem for p in shipped_missions())
    raise ConfigError(f"{given}: no such file, nor a shipped mission ({names}; `autopilot files` lists them with "
                      "their paths)")


def campaigns_dir() -> Path:
    """``campaigns/``: robustness campaign specs (``autopilot campaign``)."""
    return data_dir() / "campaigns"


def shipped_campaigns() -> list[Path]:
    """The shipped campaign specs, sorted by name."""
    return sorted(campaigns_dir().glob("*.yaml"))


def shipped_files() -> list[tuple[str, Path]]:
    """(what, path) of every shipped file a user may want to copy."""
    out = [
        ("daemon configuration (defaults)", default_config_path()),
        ("vessel parameters, calibrated (default)", default_params_path()),
        ("vessel parameters, thesis Table 5.1", thesis_params_path()),
        ("measured steady-state table (thesis Fig 8.2)", measured_table_path()),
    ]
    out += [("mission", p) for p in shipped_missions()]
    out += [("mission format example", p) for p in sorted((missions_dir() / "examples").iterdir()) if p.is_file()]
    out += [("robustness campaign spec", p) for p in shipped_campaigns()]
    out += [("traffic scenario (autopilot evaluate --traffic)", p) for p in sorted((data_dir() / "traffic").glob("*.yaml"))]
    out += [("boat PC service (INSTALL.md says how)", p) for p in sorted((data_dir() / "systemd").iterdir()) if p.is_file()]
    return out


def package_version() -> str:
    """The installed distribution's version ("unknown" from a checkout that was never installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("wamv-autopilot")
    except PackageNotFoundError:  # pragma: no cover - a bare checkout
        return "unknown"
