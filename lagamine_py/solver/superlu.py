"""SuperLU without importing ``scipy.sparse.linalg``: scipy's own extension, loaded by file.

``scipy.sparse.linalg.splu`` is a thin Python wrapper around the compiled
``scipy.sparse.linalg._dsolve._superlu.gstrf``; importing it imports the whole of
``scipy.sparse.linalg`` (iterative solvers, ARPACK, ``scipy.linalg`` with its documentation
decorators): 0.1 s and ~10 MB, a sixth of the main job's whole run, for one function.
:func:`splu` loads the same compiled module straight from scipy's install directory and calls
it with exactly the arguments ``scipy.sparse.linalg.splu`` passes, so the factor is the same
object, bit for bit (``tests/test_superlu.py``).  Where the file is not found or does not load
(another scipy layout), it falls back to the public function.
"""
from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import os
import sys

import numpy as np
import scipy.sparse as sp

__all__ = ["splu", "superlu_module"]

_NAME = "scipy.sparse.linalg._dsolve._superlu"


@functools.lru_cache(maxsize=None)
def superlu_module():
    """scipy's compiled SuperLU module, loaded once without its parent packages; None when
    this scipy does not have it where expected (the caller then uses the public ``splu``)."""
    if _NAME in sys.modules:                     # scipy.sparse.linalg already imported
        return sys.modules[_NAME]
    spec = importlib.util.find_spec("scipy")
    if spec is None or not spec.submodule_search_locations:
        return None
    folder = os.path.join(spec.submodule_search_locations[0], "sparse", "linalg", "_dsolve")
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    try:
        files = [f for f in os.listdir(folder) if f.startswith("_superlu.") and f.endswith(suffixes)]
    except OSError:
        return None
    if len(files) != 1:
        return None
    loader = importlib.machinery.ExtensionFileLoader(_NAME, os.path.join(folder, files[0]))
    ext = importlib.util.spec_from_file_location(_NAME, loader.path, loader=loader)
    try:
        module = importlib.util.module_from_spec(ext)
        loader.exec_module(module)
    except ImportError:
        return None
    # registered as scipy would, so a later `import scipy.sparse.linalg` reuses this module
    sys.modules[_NAME] = module
    return module


def splu(A: sp.csc_matrix, permc_spec: str = "MMD_AT_PLUS_A"):
    """LU factor of the square float CSC matrix ``A`` (canonical: sorted indices, no
    duplicates, as our patterns are), as ``scipy.sparse.linalg.splu(A, permc_spec=...)``
    returns it (a ``SuperLU`` object: ``solve``, ``L``, ``U``, ``perm_c``, ``perm_r``).

    Raises RuntimeError when the matrix is exactly singular, as scipy's does."""
    module = superlu_module()
    if module is None:
        import scipy.sparse.linalg as spla
        return spla.splu(A, permc_spec=permc_spec)
    A = A if A.has_canonical_format else A.copy()
    A.sum_duplicates()
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"splu needs a square matrix, got {A.shape}")
    # the arguments scipy.sparse.linalg.splu passes for splu(A, permc_spec=...)
    options = dict(DiagPivotThresh=None, ColPerm=permc_spec, PanelSize=None, Relax=None)
    if permc_spec == "NATURAL":
        options["SymmetricMode"] = True
    return module.gstrf(n, A.nnz, np.asarray(A.data, np.float64), A.indices.astype(np.intc, copy=False),
                        A.indptr.astype(np.intc, copy=False), csc_construct_func=sp.csc_matrix,
                        ilu=False, options=options)
