"""The public API: ``lagamine_py.__all__`` resolves, names no two different things, and costs
nothing to import."""
import importlib
import pkgutil
import subprocess
import sys
from collections import defaultdict

import lagamine_py


def test_every_public_name_resolves():
    for name in lagamine_py.__all__:
        assert getattr(lagamine_py, name) is not None, name
    assert lagamine_py.Element.__module__ == "lagamine_py.elements.base"
    assert lagamine_py.get_plugin("elements", "cpe8") is lagamine_py.get_plugin("elements", "Q8PE")


def test_no_two_public_names_clash():
    """A name in the ``__all__`` of two modules is one object (a re-export), never two things."""
    where = defaultdict(dict)
    for info in pkgutil.walk_packages(lagamine_py.__path__, "lagamine_py."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name in getattr(module, "__all__", ()):
            where[name][id(getattr(module, name))] = info.name
    clashes = {name: sorted(mods.values()) for name, mods in where.items() if len(mods) > 1}
    assert not clashes, clashes


def test_import_is_light():
    code = "import sys, lagamine_py; print(' '.join(sys.modules))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True).stdout.split()
    assert "lagamine_py" in loaded
    assert not [m for m in loaded if m.startswith(("numpy", "scipy", "lagamine_py."))]
