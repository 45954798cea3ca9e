"""Sparse linear solvers (plugins ``lagamine_py.solvers``) and the reduction to the free DOFs.

Imposed DOFs are handled by *reduction*: the system solved is ``K_ff du_f = -R_f - K_fc du_c``.
:class:`FreeDofs` precomputes, once per set of constrained DOFs, which entries of the CSR
``data`` of the full pattern belong to ``K_ff`` (their order in ``data`` already is the CSR order
of ``K_ff``) and which to ``K_fc``.  Reduction rather than zeroed rows/columns with a unit
diagonal because (i) the factorised system is smaller, (ii) no artificial unit pivots whose scale
has nothing to do with the stiffness (they blur the pivot-based singularity diagnosis), and
(iii) ``K_fc`` is at hand to turn an imposed displacement increment into the linearised load of
the first iteration, so boundary elements are not distorted alone by a jump of their nodes.

Solvers: ``SPLU`` (SuperLU with the ``MMD_AT_PLUS_A`` ordering), ``PARDISO`` (MKL through
``pypardiso``, usable when it imports), ``AUTO`` (PARDISO above 8k DOFs when available,
SPLU otherwise: with its analysis reused PARDISO is faster from 8-11k DOFs on press-slide
runs, see ``docs/performance.md``; below, SPLU costs no more time, less memory, and names the
unrestrained DOFs of a singular tangent by its pivots).  The default COLAMD ``spsolve`` is never used
(4-17x slower on these matrices).
"""
from __future__ import annotations

import ctypes
import functools
import logging

import numpy as np
import scipy.sparse as sp

from .. import registry
from ..core.errors import SingularMatrixError
from ..core.plugin import Plugin
from ..core.threads import pin_threads
from .pattern import index_dtype
from .superlu import KeptOrdering, splu, superlu_module, u_diagonal

pin_threads()          # OpenBLAS (numpy, scipy) to one thread: see lagamine_py/_threads.py

#: measured crossover (docs/performance.md, "Memory, branch memory"): whole press-slide runs at
#: 5k and 7.3k DOFs cost 0.9x the CPU on SPLU and 26-34 MB less memory (MKL's libraries and a
#: factor twice SuperLU's are not loaded); at 11k PARDISO is 1.2x faster
AUTO_PARDISO_DOFS = 8_000
#: entries of a SuperLU factor (``SuperLU.nnz``) past which AUTO moves a run below
#: AUTO_PARDISO_DOFS to PARDISO: fill, not size, sets SPLU's cost (docs/performance.md)
AUTO_SPLU_FILL = 1_500_000
PIVOT_RTOL = 1e-12          # |pivot| below this times max |K_ii| counts as zero
SOLVE_RTOL = 1e-6           # PARDISO: |A x - b| above this times |b| means a singular A
#: SPLU trims the heap (:func:`return_free_heap`) before a factorisation only when the last
#: factor or the matrix holds this many entries: below, the freed blocks are a few MB, and the
#: trim handed pages back that the next factorisation and evaluation faulted in again (the
#: main job, 849 DOFs and 74k factor entries: 0.3 ms a call in ``malloc_trim``, ~70 ms of
#: its 0.46 s of increments in all; docs/performance.md)
TRIM_FILL = 200_000
#: SPLU keeps a structure's column ordering (:class:`KeptOrdering`) up to this many entries of
#: the matrix: the ordering is 12-13 % of a factorisation of the main job's (24 800 entries)
#: and 8-15 % of 40x20's (152 000), and the kept arrays and the permuted values take ~20 bytes
#: an entry; above, it is ordered afresh at every factorisation as before (kept, 40x20 held
#: +2.0-2.6 MiB at a peak that sits at CalculiX's, for no measurable CPU: most of its solves
#: reuse a factor through GMRES; docs/performance.md, "Start-up, first run, memory")
KEEP_ORDERING_ENTRIES = 100_000
#: a ``lagamine-py run`` of up to this many DOFs keeps the C heap's freed blocks for the rest of
#: the process (:func:`keep_freed_heap`): its arrays are re-made at every evaluation and
#: factorisation, and glibc's default policy (a block above the mmap threshold mapped afresh,
#: the heap's top handed back past the trim threshold) faulted their pages in again each time;
#: above it the memory item's peaks (40x20: 5 042 DOFs, at CalculiX's) keep the default
KEEP_HEAP_DOFS = 4_000
#: glibc ``mallopt`` parameters and the values :func:`keep_freed_heap` sets
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
KEPT_TRIM_THRESHOLD, KEPT_MMAP_THRESHOLD = 64 << 20, 16 << 20


class FreeDofs:
    """Index maps from the full CSR pattern to ``K_ff`` and ``K_fc`` for one constrained set.

    Parameters
    ----------
    pattern : :class:`lagamine_py.solver.pattern.Pattern`
    constrained : (c,) int array of constrained global DOFs.
    """

    def __init__(self, pattern, constrained: np.ndarray):
        n = pattern.ndof
        self.constrained = np.unique(np.asarray(constrained, dtype=np.int64))
        is_free = np.ones(n, bool)
        is_free[self.constrained] = False
        self.free = np.flatnonzero(is_free)
        self.nfree = len(self.free)
        new_index = np.full(n, -1, np.int64)
        new_index[self.free] = np.arange(self.nfree)
        rows, cols = pattern.rows, pattern.indices
        row_free, col_free = is_free[rows], is_free[cols]
        # K_ff: its entries, in CSR order of the full pattern, are in CSR order of K_ff too;
        # index arrays of one integer type (int32 while it holds them): scipy keeps them as they
        # are, so every K_ff shares the same two arrays and a solver recognises its structure
        # by identity (a mixed pair was recast, i.e. copied and compared, every iteration)
        # (``ff`` is a boolean mask of the full ``data``: a gather through it is as fast as
        # through intp indices when most entries are free (22 against 24 ms at 9.6M entries),
        # and it is one byte an entry instead of eight: 77 -> 10 MB at 309k DOFs; int32
        # indices would be converted first, +70 %)
        itype = index_dtype(max(pattern.nnz, n + 1))
        self.ff = row_free & col_free
        self.ff_indices = new_index[cols[self.ff]].astype(itype)
        self.ff_indptr = np.zeros(self.nfree + 1, itype)
        np.cumsum(np.bincount(new_index[rows[self.ff]], minlength=self.nfree), out=self.ff_indptr[1:])
        self.not_ff = np.flatnonzero(~self.ff)       # the other entries: few (constrained DOFs)
        # the in-place gather (kff(in_place=True)) by blocks: where each block's K_ff entries go
        starts = np.arange(0, self.ff.size, self.COMPACT_BLOCK)
        counts = np.add.reduceat(self.ff, starts, dtype=np.int64) if starts.size else np.zeros(0, np.int64)
        self._block_dst = np.concatenate(([0], np.cumsum(counts)[:-1])).astype(np.int64)
        self._block_whole = counts == np.diff(np.append(starts, self.ff.size))
        self.ff_diag = np.flatnonzero(self.ff & (rows == cols))
        self.diag_dof = rows[self.ff_diag]
        # K_fc: entries coupling a free row to a constrained column
        self.fc = np.flatnonzero(row_free & ~col_free)
        self.fc_row = new_index[rows[self.fc]]
        self.fc_col = cols[self.fc]

    #: entries per block of the in-place gather (its temporaries are a block's)
    COMPACT_BLOCK = 1 << 16

    def kff(self, data: np.ndarray, in_place: bool = False) -> sp.csr_matrix:
        """``K_ff`` as CSR from the full CSR ``data``: new values, the structure arrays
        ``ff_indices``/``ff_indptr`` themselves (sorted, no duplicates: flagged so, not
        re-checked).

        ``in_place``: the values are moved to the head of ``data`` itself, which is overwritten
        (take :meth:`rest` first), and ``K_ff``'s data is a view of that head: no second array
        of the tangent's size beside the full one (77 MB at 309k DOFs, while the solver holds
        its factor and the last ``K_ff``).  The same values, bit for bit."""
        values = self._compact(data) if in_place else data[self.ff]
        A = sp.csr_matrix((values, self.ff_indices, self.ff_indptr),
                          shape=(self.nfree, self.nfree), copy=False)
        A.has_sorted_indices = True
        A.has_canonical_format = True
        return A

    def _compact(self, data: np.ndarray) -> np.ndarray:
        """``data[self.ff]`` written over the head of ``data`` block by block, returned as a
        view.  A block's entries land at or before its start (``_block_dst``), so the blocks
        still to be read are never overwritten; a block whose entries all stay in place is
        skipped."""
        step = self.COMPACT_BLOCK
        for i, (dst, whole) in enumerate(zip(self._block_dst.tolist(), self._block_whole.tolist())):
            a = i * step
            b = min(a + step, data.size)
            if whole:
                if dst != a:
                    data[dst:dst + b - a] = data[a:b]
            else:
                v = data[a:b][self.ff[a:b]]
                data[dst:dst + v.size] = v
        return data[:self.ff_indices.size]

    def rest(self, data: np.ndarray) -> np.ndarray:
        """The entries of the full CSR ``data`` that ``K_ff`` leaves out (those of constrained
        rows or columns), in the order of ``data``: with ``K_ff``'s, all of it (:meth:`join`)."""
        return data[self.not_ff]

    def join(self, kff_data: np.ndarray, rest: np.ndarray) -> np.ndarray:
        """The full CSR data from ``K_ff``'s data and :meth:`rest`'s (bit for bit the data they
        were taken from)."""
        data = np.empty(self.ff.size, np.result_type(kff_data, rest))
        data[self.ff] = kff_data
        data[self.not_ff] = rest
        return data

    def kfc_dot(self, data: np.ndarray, du_full: np.ndarray) -> np.ndarray:
        """``K_fc @ du_c`` (nfree,), ``du_full`` a global (ndof,) vector read at constrained DOFs."""
        return np.bincount(self.fc_row, weights=data[self.fc] * du_full[self.fc_col],
                           minlength=self.nfree)


class LinearSolver(Plugin):
    """Base of linear-solver plugins (entry-point group ``lagamine_py.solvers``), chosen by
    ``*CONTROLS SOLVER=<name>`` or ``lagamine-py run --solver <name>``.

    Built without arguments, once per step.  Newton calls ``factor(A)`` once per iteration,
    then ``solve(b)``.  ``A`` is a square CSR matrix (``K_ff``, the free DOFs), generally
    non-symmetric, whose structure is the same from one iteration to the next (a solver may
    keep its symbolic analysis while it is).  ``factor`` (or ``solve``) raises
    :class:`~lagamine_py.core.errors.SingularMatrixError` with the DOFs (indices into ``A``)
    that look unrestrained: the increment is then cut back.
    """

    @classmethod
    def unavailable(cls) -> str:
        """Why the solver cannot run here ("" when it can): a missing optional package, say."""
        return ""

    def factor(self, A: sp.csr_matrix) -> None:
        raise NotImplementedError

    def solve(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def hold_matrix(self, A: sp.csr_matrix | None) -> None:
        """What the solves on the factor in hand read beside it
        (:class:`~lagamine_py.solver.reuse.FactorReuse` calls this).

        ``None``: after a solve, the factorised matrix's values need not be held any more: the
        factor stays, and later solves on it are the preconditioner of GMRES, which checks its
        own residual.  ``A``: before those solves, the matrix GMRES works on (``K_ff`` of a later
        iteration, the factorised structure), to read in place of the one let go.  A solver
        whose solves read only its factor (SuperLU) does nothing: the default."""


class SpluSolver(LinearSolver):
    """SuperLU (scipy splu) with the MMD_AT_PLUS_A ordering, computed at the first
    factorisation of a structure and kept for the next ones (:class:`KeptOrdering`: the same
    factor, bit for bit, without ordering again)."""

    lu = None
    #: the kept ordering of the structure last factorised (None: not kept yet)
    ordering: KeptOrdering | None = None
    #: the factor in hand is of the columns in ``ordering``'s order (its solves permute ``b``)
    ordered = False

    def factor(self, A: sp.csr_matrix) -> None:
        # The CSR arrays of A are the CSC arrays of A^T: factor A^T without any conversion
        # and solve with trans="T".  A kept ordering reads those arrays straight from A (the
        # same structure arrays, square shape); the CSC view of A^T is made only when the
        # structure is new or the factorisation fails (scipy's checks of its arrays were
        # ~0.1 ms a factorisation of the main job's 866 DOFs)
        order = self.ordering
        kept = order is not None and order.matches(A)
        # max |K_ii|: through the kept structure's diagonal positions (scipy's diagonal() of a
        # CSR matrix was ~45 us a factorisation of the main job's)
        scale = (order.diagonal_scale(A.data) if kept else np.abs(A.diagonal()).max()) \
            if A.shape[0] else 0.0
        # the last factor goes before the next is computed, and the heap's free pages with it:
        # SuperLU grows its work arrays by reallocation, which left the heap holding 20-70 MB
        # of freed blocks at 5-7k DOFs (peaks 123-197 MB from one run to the next, 40x20-48x24);
        # a small factor's few MB are not worth the trim (TRIM_FILL)
        fill = max(A.nnz, self.lu.nnz if self.lu is not None else 0)
        self.lu = None
        if fill >= TRIM_FILL:
            return_free_heap()
        try:
            if kept:
                self.lu = order.factor(A.data)
                self.ordered = True
            else:
                At = _transposed_csc(A)
                self.lu = splu(At, permc_spec="MMD_AT_PLUS_A")
                self.ordered = False
                order = self.ordering = _kept_ordering(At, self.lu)
        except RuntimeError:                # "Factor is exactly singular"
            raise SingularMatrixError(_exact_singular_dofs(_transposed_csc(A), scale),
                                      "zero pivot") from None
        # Pr A Pc = L U with Pc[j, perm_c[j]] = 1: original column j has pivot U[perm_c[j]]
        position = order.position if order is not None else self.lu.perm_c
        pivots = np.abs(u_diagonal(self.lu))[position]
        small = ~(pivots > PIVOT_RTOL * scale)          # also catches NaN
        if small.any():
            bad = np.flatnonzero(small)
            raise SingularMatrixError(np.union1d(bad, _suspects(A)), "zero pivot")

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, float)
        if self.ordered:
            b = b[self.ordering.columns]
        return self.lu.solve(b, trans="T")


def _transposed_csc(A: sp.csr_matrix) -> sp.csc_matrix:
    """``A^T`` as CSC: the CSR arrays of ``A`` themselves (no copy)."""
    return sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)


def _kept_ordering(At: sp.csc_matrix, lu) -> KeptOrdering | None:
    """``lu``'s column ordering kept for the structure of ``At``; None when the matrix is above
    ``KEEP_ORDERING_ENTRIES``, scipy's SuperLU is not loaded by file (the public ``splu``
    forces ``SymmetricMode`` with a NATURAL ordering) or ``At`` is not canonical (SuperLU
    factorised a summed copy)."""
    if At.nnz > KEEP_ORDERING_ENTRIES or superlu_module() is None or not At.has_canonical_format:
        return None
    return KeptOrdering(At, lu)


@functools.lru_cache(maxsize=None)
def _malloc_trim():
    """glibc's ``malloc_trim``, or None (another C library: nothing to call)."""
    try:
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):     # TypeError: Windows has no CDLL(None)
        return None


def return_free_heap() -> None:
    """Give the pages of the C heap's free blocks back to the system (glibc's
    ``malloc_trim(0)``, ~1 ms; nothing where the C library has no such call).  Freed blocks
    below glibc's mmap threshold (which rises to the size of the largest block freed, up to
    32 MB) stay in the heap, resident, until a later allocation reuses them."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.lru_cache(maxsize=None)
def _mallopt():
    """glibc's ``mallopt``, or None (another C library)."""
    try:
        return ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):
        return None


def keep_freed_heap() -> bool:
    """Keep freed blocks in the C heap from now on (glibc: blocks up to
    ``KEPT_MMAP_THRESHOLD`` come from the heap, whose top is handed back only past
    ``KEPT_TRIM_THRESHOLD``; :func:`return_free_heap` still trims on demand).  Process-wide and
    for good (glibc's dynamic thresholds do not come back): for a process that runs one small
    model (``lagamine-py run``, :data:`KEEP_HEAP_DOFS`).  False where there is no ``mallopt``
    or it refuses."""
    mallopt = _mallopt()
    if mallopt is None:
        return False
    return bool(mallopt(_M_TRIM_THRESHOLD, KEPT_TRIM_THRESHOLD)) \
        and bool(mallopt(_M_MMAP_THRESHOLD, KEPT_MMAP_THRESHOLD))


def _exact_singular_dofs(At: sp.csc_matrix, scale: float) -> np.ndarray:
    """DOFs of an exactly singular matrix: factor it with a tiny diagonal shift; the pivots
    of the singular directions come out of the order of the shift."""
    shift = 1e-10 * (scale if scale > 0 else 1.0)
    try:
        lu = splu((At + shift * sp.eye(At.shape[0], format="csc")).tocsc(),
                       permc_spec="MMD_AT_PLUS_A")
    except RuntimeError:
        return _suspects(At.T.tocsr())
    pivots = np.abs(lu.U.diagonal())[lu.perm_c]
    return np.union1d(np.flatnonzero(pivots <= 1e3 * shift), _suspects(At.T.tocsr()))


def _singular_dofs(A: sp.csr_matrix) -> np.ndarray:
    """The DOFs a singular ``A`` leaves unrestrained, by SuperLU's pivots (PARDISO perturbs
    zero pivots instead of naming them): what SPLU would report, found once the matrix is known
    to be singular."""
    try:
        SpluSolver().factor(A)
    except SingularMatrixError as exc:
        return exc.dofs
    return _suspects(A)


def _suspects(A: sp.csr_matrix) -> np.ndarray:
    """Rows of ``A`` with a zero or negligible diagonal."""
    d = np.abs(A.diagonal())
    scale = d.max() if d.size else 0.0
    return np.flatnonzero(d <= PIVOT_RTOL * scale)


@functools.lru_cache(maxsize=None)
def _mkl_library():
    """MKL's runtime library (``mkl_rt``) through ctypes, or None when MKL is not installed.

    Looked up once per process, as pypardiso looks it up (``PYPARDISO_MKL_RT``, the library
    search path, then ``lib*/**/*mkl_rt*`` under the interpreter's prefix and the user base) --
    pypardiso itself (the package that installs MKL) is not imported: it searches the file tree
    at import and again in every solver object, 0.1-0.2 s each."""
    import glob
    import os
    import site
    import sys
    from ctypes.util import find_library

    from ..core.threads import prepare_openmp_env
    prepare_openmp_env()                    # before MKL's OpenMP runtime loads
    candidates = [os.environ.get("PYPARDISO_MKL_RT"), find_library("mkl_rt"),
                  find_library("mkl_rt.1")]
    candidates = [c for c in candidates if c]
    if not candidates:                      # where pip puts it first (no tree walk), then the tree
        found = (glob.glob(f"{sys.prefix}/lib/*mkl_rt*")
                 or glob.glob(f"{sys.prefix}/[Ll]ib*/**/*mkl_rt*", recursive=True)
                 or glob.glob(f"{site.USER_BASE}/[Ll]ib*/**/*mkl_rt*", recursive=True))
        candidates = sorted(found, key=len)
    for path in candidates:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        lib.pardiso.restype = None
        lib.pardisoinit.restype = None
        pin_threads()
        return lib
    return None


def _mkl_pardiso():
    """MKL's ``pardiso`` function, or None (see :func:`_mkl_library`)."""
    lib = _mkl_library()
    return None if lib is None else lib.pardiso


def pardiso_available() -> bool:
    """True when MKL PARDISO loads (the optional package pypardiso installs MKL)."""
    return _mkl_pardiso() is not None


class PardisoSolver(LinearSolver):
    """MKL PARDISO (installed by pypardiso): real non-symmetric mode (mtype 11), or symmetric
    indefinite (mtype -2, upper triangle, LDL^T: about half the work) when the matrix is
    symmetric to round-off.

    The symbolic analysis (phase 11: ordering, matching, symbolic factor) is kept while the
    structure of ``A`` and the mode do not change, so a Newton iteration pays only the numerical
    factorisation (phase 22) and the solve (phase 33).  The structure is recognised by identity
    of the ``indices``/``indptr`` arrays (``FreeDofs.kff`` hands out the same ones every
    iteration) or, failing that, by comparing them.  Symmetry is tested on every factorisation
    (``|A - A^T| <= SYM_RTOL max|A|``, one gather through a transpose permutation cached per
    structure), so a contact status change that breaks symmetry switches the mode at once;
    each switch costs one new analysis.  ``symmetric=False`` forces the non-symmetric mode.
    """

    SYM_RTOL = 1e-13
    SYM_CHUNK = 1 << 16          # entries per block of the symmetry test (early exit)
    #: PARDISO's two-level factorisation (``iparm[23] = 10``): see :meth:`_set_iparm`
    TWO_LEVEL = True

    @classmethod
    def unavailable(cls) -> str:
        return "" if pardiso_available() else ("the optional package pypardiso is not "
                                               "installed (pip install 'lagamine_py[pardiso]')")

    def __init__(self, symmetric: bool = True):
        self._call = _mkl_pardiso()
        if self._call is None:
            raise KeyError(self.unavailable())
        self.allow_symmetric = bool(symmetric)
        self.pt = np.zeros(64, np.int64)
        self.iparm = np.zeros(64, np.int32)
        self.mtype = 0                      # 0: no analysis held
        self.n = 0
        self.analyses = 0                   # counters (benchmarks, tests)
        self.factorizations = 0
        self._struct = None                 # (indptr, indices) of the analysed structure
        self._ia = self._ja = None
        self._asym_block = 0                # where the symmetry test last failed

    # -- structure ---------------------------------------------------------------------
    def _same_structure(self, A) -> bool:
        if self._struct is None:
            return False
        indptr, indices = self._struct
        if _same_buffer(A.indptr, indptr) and _same_buffer(A.indices, indices):
            return True
        return (A.shape[0] == self.n and np.array_equal(A.indptr, indptr)
                and np.array_equal(A.indices, indices))

    def _new_structure(self, A) -> None:
        n = A.shape[0]
        self.n = n
        self._struct = (A.indptr, A.indices)
        if not np.diff(A.indptr).all():
            self._empty_rows = _suspects(A)
        else:
            self._empty_rows = None
        self._toffset = _transpose_offsets(A)
        # zero-based indexing (iparm[34] = 1): A's own index arrays, no one-based copies
        self._ia_full = np.ascontiguousarray(A.indptr, dtype=np.int32)
        self._ja_full = np.ascontiguousarray(A.indices, dtype=np.int32)
        self._sym_structure = None          # (upper mask, ia, ja): at the first symmetric A
        self.mtype = 0                                   # force an analysis

    def _symmetric_structure(self):
        """The upper triangle of the analysed structure: ``(mask of A's entries, ia, ja)``,
        built when a matrix of this structure is first found symmetric (a step whose tangents
        are all non-symmetric never holds it: 29 MB at 309k DOFs).  The upper triangle's
        entries as a mask: a byte an entry, not an intp of each (the gather per symmetric
        factorisation is 7 ms slower at 309k DOFs, 29 MB smaller)."""
        if self._sym_structure is None:
            indptr, indices = self._struct
            rows = np.repeat(np.arange(self.n, dtype=np.int32), np.diff(indptr))
            upper = indices >= rows
            ia = np.zeros(self.n + 1, np.int32)
            np.cumsum(np.bincount(rows[upper], minlength=self.n), out=ia[1:])
            self._sym_structure = (upper, ia, self._ja_full[upper])
        return self._sym_structure

    def is_symmetric(self, A) -> bool:
        """A is symmetric to round-off (and its structure is).

        Tested block by block (``SYM_CHUNK`` entries), starting with the block where the last
        matrix was found non-symmetric: a contact tangent is non-symmetric in the rows of the
        contact DOFs only, which stay where they are from one iteration to the next, so the
        usual non-symmetric verdict costs one block instead of three temporaries of ``nnz``
        (the whole test was 11 % of the run at 309k DOFs).  A symmetric matrix is read whole."""
        if self._toffset is None:
            return False
        d = A.data
        if not d.size:
            return True
        tol = self.SYM_RTOL * max(float(d.max()), -float(d.min()))
        if not tol >= 0.0:                  # NaN entries: no verdict of symmetry
            return False
        n, step = d.size, self.SYM_CHUNK
        starts = list(range(0, n, step))
        first = min(self._asym_block, len(starts) - 1)
        where = np.empty(min(step, n), self._struct[0].dtype)     # a block's buffers
        diff = np.empty(min(step, n))
        for a in starts[first:] + starts[:first]:
            b = min(a + step, n)
            t = self._transposed(a, b, where[:b - a])
            v = np.take(d, t, out=diff[:b - a])
            np.subtract(d[a:b], v, out=v)
            if np.abs(v, out=v).max() > tol:
                self._asym_block = a // step
                return False
        return True

    def _transposed(self, a: int, b: int, out: np.ndarray | None = None) -> np.ndarray:
        """Where the transposes of the entries ``a:b`` of the analysed structure are: entry
        ``(i, j)``'s is in row ``j``, at its offset there (:func:`_transpose_offsets`)."""
        indptr, indices = self._struct
        out = np.take(indptr, indices[a:b], out=out)
        return np.add(out, self._toffset[a:b], out=out, casting="unsafe")

    # -- PARDISO calls -----------------------------------------------------------------
    def _pardiso(self, phase: int, data, ia, ja, b=None, x=None) -> None:
        c_int = ctypes.c_int32
        ip = ctypes.POINTER(ctypes.c_int32)
        dp = ctypes.POINTER(ctypes.c_double)
        if b is None:
            b = x = np.zeros(1)
        nrhs = 1
        err = c_int(0)
        self._call(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                   ctypes.byref(c_int(1)), ctypes.byref(c_int(1)), ctypes.byref(c_int(self.mtype)),
                   ctypes.byref(c_int(phase)), ctypes.byref(c_int(self.n)),
                   data.ctypes.data_as(dp), ia.ctypes.data_as(ip), ja.ctypes.data_as(ip),
                   np.zeros(0, np.int32).ctypes.data_as(ip), ctypes.byref(c_int(nrhs)),
                   self.iparm.ctypes.data_as(ip), ctypes.byref(c_int(0)),
                   b.ctypes.data_as(dp), x.ctypes.data_as(dp), ctypes.byref(err))
        if err.value != 0:
            raise _PardisoError(err.value)

    def _release(self) -> None:
        """Free PARDISO's factor and analysis (phase -1), and MKL's pool of freed buffers:
        MKL keeps them for reuse, and a new analysis of another size (the next step's free
        DOFs) would allocate beside them (measured: 40 of 240 MB at 77k DOFs kept)."""
        if self.mtype:
            try:
                self._pardiso(-1, np.zeros(1), self._ia, self._ja)
            except _PardisoError:
                pass
            self.mtype = 0
            _mkl_library().mkl_free_buffers()

    def __del__(self):
        try:
            self._release()
        except Exception:
            pass

    def factor(self, A: sp.csr_matrix) -> None:
        A = A.tocsr()
        if not A.has_sorted_indices:
            A = A.sorted_indices()
        if not self._same_structure(A):
            self._release()
            self._new_structure(A)
        if self._empty_rows is not None:      # MKL would crash on an empty row
            raise SingularMatrixError(self._empty_rows, "empty row")
        sym = self.allow_symmetric and self.is_symmetric(A)
        mtype = -2 if sym else 11
        if sym:
            upper, ia_sym, ja_sym = self._symmetric_structure()
            self._data = np.ascontiguousarray(A.data[upper], dtype=np.float64)
            self._ia, self._ja = ia_sym, ja_sym
        else:
            self._data = np.ascontiguousarray(A.data, dtype=np.float64)
            self._ia, self._ja = self._ia_full, self._ja_full
        self._A = A
        try:
            if mtype != self.mtype:
                self._release()
                self.mtype = mtype
                self._set_iparm()
                self._pardiso(11, self._data, self._ia, self._ja)
                self.analyses += 1
            self._pardiso(22, self._data, self._ia, self._ja)
            self.factorizations += 1
        except _PardisoError as exc:
            self._release()
            raise SingularMatrixError(_singular_dofs(A), f"PARDISO: {exc}") from None

    def _suspect_dofs(self) -> np.ndarray:
        """The DOFs a failed solve names: by SuperLU on the factorised matrix, none when it was
        let go (:meth:`hold_matrix`: GMRES then gives up on the old factor)."""
        return _no_dofs() if self._A is None else _singular_dofs(self._A)

    def _set_iparm(self) -> None:
        """PARDISO's defaults for the matrix type (``pardisoinit``, then ``iparm[0] = 1``: the
        values are ours), with two changes:

        * no iterative refinement (``iparm[7] = 0``).  MKL's non-symmetric default is 2 steps
          on *every* solve, i.e. three substitutions and two products: 2.4x the solve time
          (43.5 against 17.8 ms at 77k DOFs) for a residual of 7e-14 instead of 1.2e-13, which
          Newton does not need.  With 0, PARDISO still refines by itself when it had to perturb
          pivots, and :meth:`solve`'s residual test stays the guard against a singular matrix;
        * the two-level factorisation (``iparm[23] = 10``, which PARDISO reads only with
          ``iparm[0] = 1``) when :attr:`TWO_LEVEL`: measured on the press-slide tangents
          (``tools/bench.py pardiso``, docs/performance.md) with one and two threads.

        And zero-based indices (``iparm[34] = 1``): PARDISO reads ``K_ff``'s own index arrays
        (one-based copies were 40 MB at 309k DOFs)."""
        self.iparm[:] = 0
        _mkl_library().pardisoinit(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                                   ctypes.byref(ctypes.c_int32(self.mtype)),
                                   self.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)))
        self.iparm[0] = 1
        self.iparm[7] = 0
        self.iparm[34] = 1                  # zero-based ia, ja (CSR arrays as scipy has them)
        if self.TWO_LEVEL:
            self.iparm[23] = 10

    def hold_matrix(self, A: sp.csr_matrix | None) -> None:
        """See :meth:`LinearSolver.hold_matrix`.  ``None``: the factorised ``K_ff`` (77 MB at
        309k DOFs, alive through the next evaluation beside the factor otherwise) is let go when
        the factorisation perturbed no pivot (``iparm[13] == 0``): PARDISO then refines no
        solve (``iparm[7] = 0``) and reads only its factor; in the symmetric mode the upper
        triangle handed to it stays (a copy).  ``A``: a non-symmetric solve hands PARDISO
        ``A``'s values as its matrix argument (a valid array of the factorised structure; not
        read without refinement).  The residual guard of :meth:`solve` checks a solve against
        the factorised matrix only: GMRES checks its own."""
        if A is None:
            if self.mtype and self.iparm[13] == 0:
                self._A = None
                if self.mtype == 11:
                    self._data = None
        elif self._data is None and self.mtype == 11:
            self._data = np.ascontiguousarray(A.data, dtype=np.float64)

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.array(b, dtype=np.float64, order="F")
        x = np.zeros_like(b)
        if self._data is None:
            raise RuntimeError("PARDISO: a solve on a factor whose matrix was let go, with no "
                               "matrix handed (hold_matrix)")
        try:
            self._pardiso(33, self._data, self._ia, self._ja, b, x)
        except _PardisoError as exc:
            raise SingularMatrixError(self._suspect_dofs(), f"PARDISO: {exc}") from None
        if not np.all(np.isfinite(x)):
            raise SingularMatrixError(self._suspect_dofs(), "PARDISO returned a non-finite solution")
        if self._A is None:                 # a preconditioner's solve: GMRES checks it
            return x
        # PARDISO perturbs zero pivots instead of failing: a singular matrix comes back
        # "solved" with a large residual.  One product with A (cheap next to the factor) tells.
        # (Not only when iparm[13] reports perturbed pivots: a singular symmetric tangent's
        # round-off pivot passes unperturbed, tests/test_linear_solvers.py.)
        bnorm = np.linalg.norm(b)
        if np.linalg.norm(self._A @ x - b) > SOLVE_RTOL * bnorm:
            raise SingularMatrixError(_singular_dofs(self._A), "PARDISO: residual of the solve too "
                                      "large (perturbed zero pivots)")
        return x


def _transpose_offsets(A) -> np.ndarray | None:
    """For each entry ``(i, j)`` of the CSR structure of ``A`` (sorted), the offset of entry
    ``(j, i)`` in row ``j``; None when the structure is not symmetric.

    ``indptr[indices] + offsets`` is the transpose permutation (``data[...]`` is ``A^T``'s data
    in ``A``'s CSR order).  Offsets are below the longest row: one byte an entry where rows are
    shorter than 256 entries (a 2D element mesh's are ~50), where the permutation itself took
    four (38 MB against 10 MB at 309k DOFs).  The permutation is made once, carried as the data
    of the transposed matrix in the index type (float64 doubled this transient)."""
    itype = index_dtype(A.nnz)
    T = sp.csr_matrix((np.arange(A.nnz, dtype=itype), A.indices, A.indptr),
                      shape=A.shape).T.tocsr()
    T.sort_indices()
    if not (np.array_equal(T.indptr, A.indptr) and np.array_equal(T.indices, A.indices)):
        return None
    longest = int(np.diff(A.indptr).max()) if A.shape[0] else 0
    otype = np.uint8 if longest <= 256 else np.uint16 if longest <= 65536 else itype
    offsets = T.data
    del T
    offsets -= A.indptr[A.indices]
    return offsets.astype(otype)


def _no_dofs() -> np.ndarray:
    return np.zeros(0, np.int64)


def _same_buffer(a: np.ndarray, b: np.ndarray) -> bool:
    """``a`` reads the very memory of ``b`` (held alive by the caller, so no other array can
    have its address): the same object, or a whole view of it, as scipy hands out for the index
    arrays it was given (``FreeDofs.kff``)."""
    return a is b or (a.shape == b.shape and a.dtype == b.dtype and a.strides == b.strides
                      and a.ctypes.data == b.ctypes.data)


class _PardisoError(RuntimeError):
    def __init__(self, code: int):
        super().__init__(f"error {code}")
        self.code = code


#: what a run on SPLU above AUTO_PARDISO_DOFS says, once per process
SLOW_SOLVER_NOTICE = ("{n} free DOFs factorised by SPLU: PARDISO is 3-4x faster on such tangents "
                      "(docs/performance.md); install it with: pip install 'lagamine_py[pardiso]'")
_told_slow = False


class AutoSolver(LinearSolver):
    """PARDISO above ``AUTO_PARDISO_DOFS`` (8k) DOFs when pypardiso is installed, SPLU otherwise;
    below that size too, from the factorisation after one whose SPLU factor outgrew
    ``AUTO_SPLU_FILL`` entries (a poorly ordered mesh: SPLU's cost follows its fill). The
    choice is made on counts, not times, so a run takes the same path on any machine.

    SPLU above that size says so once per process, with the command that installs PARDISO."""

    def __init__(self):
        self.impl: LinearSolver | None = None
        self.outgrown = False        # an SPLU factor of this run outgrew AUTO_SPLU_FILL

    def factor(self, A: sp.csr_matrix) -> None:
        global _told_slow
        large = A.shape[0] > AUTO_PARDISO_DOFS
        want_pardiso = (large or self.outgrown) and pardiso_available()
        if large and not want_pardiso and not _told_slow:
            _told_slow = True
            logging.getLogger("lagamine_py.solver").warning(SLOW_SOLVER_NOTICE.format(n=A.shape[0]))
        cls = PardisoSolver if want_pardiso else SpluSolver
        if not isinstance(self.impl, cls):
            self.impl = cls()
        self.impl.factor(A)
        if cls is SpluSolver and self.impl.lu.nnz > AUTO_SPLU_FILL:
            self.outgrown = True

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self.impl.solve(b)

    def hold_matrix(self, A: sp.csr_matrix | None) -> None:
        if self.impl is not None:
            self.impl.hold_matrix(A)


def make_solver(name: str) -> LinearSolver:
    """Instantiate the solver plugin ``name`` (AUTO, SPLU, PARDISO or a plugin's name); KeyError
    with the reason when it is unknown or cannot run here."""
    cls = registry.get("solvers", name)
    why = cls.unavailable()
    if why:
        raise KeyError(f"SOLVER={str(name).upper()}: {why}")
    return cls()
