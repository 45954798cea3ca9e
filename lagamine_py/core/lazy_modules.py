"""NumPy submodules a run never uses, made lazy before SciPy's import would execute them.

``import scipy.sparse`` imports SciPy's array-API layer, which clones NumPy's namespace: it
asks NumPy for every public name, and NumPy imports its lazily-loaded submodules on that
request -- ``numpy.f2py`` (a Fortran parser compiling ~60 regular expressions) and
``numpy.testing`` (``unittest``, ``difflib`` ...): ~0.03 s of the main job's 0.75 s, for modules
nothing of a run touches.  (``numpy.ma`` and ``numpy.polynomial`` are not worth it: ``np.unique``
asks ``np.ma.is_masked``, and the Coulomb law takes its Gauss-Legendre rule from
``np.polynomial`` at import.)  :func:`defer_numpy_submodules` registers
them beforehand as :class:`importlib.util.LazyLoader` modules: the clone then gets a module
object whose code runs at the first attribute access, so any later use (a user script, the
tests) sees the real module.
"""
from __future__ import annotations

import importlib.util
import sys

#: NumPy's lazily-loaded submodules that SciPy's namespace clone would import (numpy 2.x)
DEFERRED = ("f2py", "testing")


def defer_numpy_submodules(names: tuple[str, ...] = DEFERRED) -> list[str]:
    """Register ``numpy.<name>`` as a lazy module (executed at its first attribute access) for
    each of ``names`` not yet imported, and bind it on ``numpy`` as the import system would
    (numpy's own ``__getattr__`` would otherwise import it).  Imports numpy itself.  Returns
    the names made lazy (none that numpy lacks)."""
    import numpy

    deferred = []
    for name in names:
        full = f"numpy.{name}"
        if full in sys.modules:
            continue
        spec = importlib.util.find_spec(full)
        if spec is None or spec.loader is None:
            continue
        spec.loader = importlib.util.LazyLoader(spec.loader)
        module = importlib.util.module_from_spec(spec)
        sys.modules[full] = module
        spec.loader.exec_module(module)          # lazy: only arms the first-access hook
        setattr(numpy, name, module)
        deferred.append(name)
    return deferred
