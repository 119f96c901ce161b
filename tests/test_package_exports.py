"""The packages whose names load on first use (PEP 562): what they export is what it says."""

import importlib
import pkgutil
import types

import pytest


@pytest.mark.parametrize("package", ["autopilot.sysid", "autopilot.campaign"])
def test_each_exported_name_stays_the_function_or_class_after_every_submodule_is_imported(package):
    """A submodule's import sets the package's attribute of its name: a submodule named like an
    export (sysid's replay.py and identify.py, campaign's replay.py before their renaming) would
    then replace the function, depending on what was imported before."""
    pkg = importlib.import_module(package)
    for sub in pkgutil.iter_modules(pkg.__path__):
        importlib.import_module(f"{package}.{sub.name}")
    for name in pkg.__all__:
        obj = getattr(pkg, name)
        assert not isinstance(obj, types.ModuleType), f"{package}.{name} is a module"
        assert name in dir(pkg)
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        pkg.nonexistent  # noqa: B018
