"""SuperLU without importing ``scipy.sparse.linalg``: scipy's own extension, loaded by file.

``scipy.sparse.linalg.splu`` is a thin Python wrapper around the compiled
``scipy.sparse.linalg._dsolve._superlu.gstrf``; importing it imports the whole of
``scipy.sparse.linalg`` (iterative solvers, ARPACK, ``scipy.linalg`` with its documentation
decorators): 0.1 s and ~10 MB, a sixth of the main job's whole run, for one function.
:func:`splu` loads the same compiled module straight from scipy's install directory and calls
it with exactly the arguments ``scipy.sparse.linalg.splu`` passes, so the factor is the same
object, bit for bit (``tests/test_superlu.py``).  Where the file is not found or does not load
(another scipy layout), it falls back to the public function.

:class:`KeptOrdering` spares the column ordering of the factorisations after the first of one
structure: scipy's ``gstrf`` takes no permutation and orders the columns again at every call
(MMD on ``A^T + A``: 12-13 % of a factorisation of the main job's, 8-15 % at 5k DOFs;
``tools/splu_ordering.py``).
"""
from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import os
import sys
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

__all__ = ["CscParts", "KeptOrdering", "splu", "superlu_module", "u_diagonal"]

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
    # scipy.sparse.linalg.splu asks SymmetricMode with a NATURAL ordering
    return _gstrf(n, np.asarray(A.data, np.float64), A.indices.astype(np.intc, copy=False),
                  A.indptr.astype(np.intc, copy=False), permc_spec,
                  symmetric_mode=permc_spec == "NATURAL")


class CscParts(NamedTuple):
    """``L`` or ``U`` of a factor of :meth:`KeptOrdering.factor`: the CSC arrays SuperLU hands
    out, ``(data, indices, indptr)`` (the arrays may run past ``indptr[-1]``), and the shape,
    without scipy matrices built of them (their checks and copies were half of the 0.19 ms the
    first access to ``L`` or ``U`` costs at 866 DOFs, for the diagonal of ``U`` only)."""
    arrays: tuple
    shape: tuple


def u_diagonal(lu) -> np.ndarray:
    """The diagonal (n,) of ``lu.U``, a scipy matrix (:func:`splu`) or :class:`CscParts`,
    as ``U.diagonal()`` gives it (0 where a column has no diagonal entry).  scipy's SuperLU
    puts each column's diagonal entry of ``U`` last: read there when it is, searched for
    otherwise."""
    U = lu.U
    if not isinstance(U, CscParts):
        return U.diagonal()
    (data, indices, indptr), (n, _) = U
    last = indptr[1:] - 1
    rows = np.arange(n)
    if n and indptr[0] == 0 and (np.diff(indptr) > 0).all() and np.array_equal(indices[last], rows):
        return data[last]
    end = int(indptr[-1])
    cols = np.repeat(rows, np.diff(indptr))
    on = np.flatnonzero(indices[:end] == cols)
    diagonal = np.zeros(n)
    diagonal[cols[on]] = data[on]
    return diagonal


def _gstrf(n: int, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, permc_spec: str,
           construct=sp.csc_matrix, symmetric_mode: bool = False):
    """scipy's ``gstrf`` on CSC arrays (indices of C int), with the options
    ``scipy.sparse.linalg.splu`` passes for ``permc_spec`` (and ``SymmetricMode`` if asked);
    ``construct(arrays, shape=)`` makes ``L`` and ``U`` at the first access to either."""
    module = superlu_module()
    options = dict(DiagPivotThresh=None, ColPerm=permc_spec, PanelSize=None, Relax=None)
    if symmetric_mode:
        options["SymmetricMode"] = True
    return module.gstrf(n, data.size, data, indices, indptr, csc_construct_func=construct,
                        ilu=False, options=options)


class KeptOrdering:
    """The column ordering SuperLU chose for one square CSC structure, kept to factorise the
    later matrices of that structure without ordering them again.

    ``perm_c`` of a factor is SuperLU's final ordering (the MMD ordering composed with the
    postorder of the column elimination tree).  The matrix with its columns moved there,
    ``B[:, perm_c[j]] = A[:, j]``, is factorised with ``ColPerm=NATURAL`` and without
    ``SymmetricMode`` (which would skip the postorder): its elimination tree is already in
    postorder, SuperLU's postorder of it is the identity, and the factor is the one
    ``MMD_AT_PLUS_A`` gives for ``A``, bit for bit: the same supernodes, the same operations,
    the same row pivots, as the rows keep their numbers (``tests/test_superlu.py`` compares the
    ``L``, ``U``, ``perm_r`` and solutions of both on the main job's tangents).  The one
    exception, not met on our decks: a column whose largest entry in magnitude is tied, to the
    last bit, with another entry of it, the diagonal or the entry of row ``perm_c[j]``;
    SuperLU's preference for the diagonal (``DiagPivotThresh`` 1) then reads ``A``'s diagonal
    in one factorisation and row ``perm_c[j]`` in the other, and the pivots may differ (both
    are the column's largest: the factor is as stable; the round-off differs).

    Parameters
    ----------
    A : the CSC matrix factorised by ``lu`` (canonical: sorted indices, no duplicates).
    lu : ``splu(A)``'s factor, with any ordering but NATURAL.
    """

    def __init__(self, A: sp.csc_matrix, lu):
        n = A.shape[0]
        self.n = n
        self.indptr, self.indices = A.indptr, A.indices       # the structure, recognised by
        self.position = np.asarray(lu.perm_c, np.intp)        # column j -> position perm_c[j]
        self.columns = np.empty(n, np.intp)                   # position k -> column
        self.columns[self.position] = np.arange(n)
        counts = np.diff(A.indptr)[self.columns]
        indptr = np.zeros(n + 1, np.int64)
        np.cumsum(counts, out=indptr[1:])
        # B.data = A.data[gather]: each column's entries in A's order (rows stay sorted)
        start = np.repeat(np.asarray(A.indptr, np.int64)[self.columns] - indptr[:-1], counts)
        gather = start + np.arange(A.nnz)
        self.gather = gather.astype(np.intp)        # intp: 3x faster a gather than int32
        self.b_indices = np.asarray(A.indices)[gather].astype(np.intc)
        self.b_indptr = indptr.astype(np.intc)
        # where the structure's diagonal entries are in its data (missing ones count 0)
        cols = np.repeat(np.arange(n), np.diff(A.indptr))
        self.diagonal = np.flatnonzero(np.asarray(A.indices) == cols)

    def diagonal_scale(self, data: np.ndarray) -> float:
        """``max |A_ii|`` of the matrix of this structure with values ``data``, as
        ``np.abs(A.diagonal()).max()`` gives it (NaN propagates; 0 without diagonal entries)."""
        return np.abs(data[self.diagonal]).max() if self.diagonal.size else 0.0

    def matches(self, A: sp.csc_matrix | sp.csr_matrix) -> bool:
        """``A`` has the structure this ordering was made for (a CSR ``A`` is read as the CSC
        arrays of its transpose: the matrix ``SpluSolver`` factorises)."""
        if A.shape != (self.n, self.n):
            return False
        if A.indptr is self.indptr and A.indices is self.indices:
            return True
        return np.array_equal(A.indptr, self.indptr) and np.array_equal(A.indices, self.indices)

    def factor(self, data: np.ndarray):
        """The factor of the matrix of this structure with values ``data`` (its CSC order),
        columns in the kept order: its solution of ``B^T y = c`` is the solution of
        ``A^T x = b`` for ``c = b[self.columns]``, and the original column ``j``'s pivot is
        ``U[position[j], position[j]]`` (:func:`u_diagonal`: its ``L`` and ``U`` are
        :class:`CscParts`).  RuntimeError when the matrix is exactly singular."""
        values = np.asarray(data, np.float64)[self.gather]
        return _gstrf(self.n, values, self.b_indices, self.b_indptr, "NATURAL", CscParts)
