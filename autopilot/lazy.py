"""A package's exported names, each loaded from its module on first use (PEP 562).

A package whose ``__init__`` imports its modules loads them into every process that imports any one
of its submodules (``autopilot`` imports each area's ``cli`` to build its parser): the daemon
carried scipy that way. A name exported here must not also be a submodule's name: importing that
submodule would replace the export (tests/test_package_exports.py).
"""

from __future__ import annotations

import importlib


def lazy_exports(package: str, owners: dict[str, str], namespace: dict):
    """(``__getattr__``, ``__dir__``) for ``package``: ``owners`` maps each name to its submodule;
    ``namespace`` is the package's ``globals()`` (what it defines itself)."""

    def __getattr__(name: str):
        if name in owners:
            return getattr(importlib.import_module(f"{package}.{owners[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted({*namespace, *owners})

    return __getattr__, __dir__
