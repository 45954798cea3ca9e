"""solver.superlu: scipy's SuperLU loaded by file gives scipy's factor, bit for bit, and spares
the import of scipy.sparse.linalg."""
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lagamine_py.solver import superlu


def _matrix(n=60, seed=0):
    """A non-symmetric, diagonally weighted sparse matrix in canonical CSC."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.1, random_state=rng, format="csc") + 4 * sp.eye(n, format="csc")
    A = A.tocsc()
    A.sum_duplicates()
    return A


def test_the_compiled_module_is_loaded_by_file():
    assert superlu.superlu_module() is not None


@pytest.mark.parametrize("permc", ["MMD_AT_PLUS_A", "COLAMD", "NATURAL"])
def test_factor_and_solutions_are_scipys_bit_for_bit(permc):
    A = _matrix()
    b = np.random.default_rng(1).standard_normal(A.shape[0])
    ours, theirs = superlu.splu(A, permc_spec=permc), spla.splu(A, permc_spec=permc)
    np.testing.assert_array_equal(ours.perm_c, theirs.perm_c)
    np.testing.assert_array_equal(ours.perm_r, theirs.perm_r)
    np.testing.assert_array_equal(ours.U.diagonal(), theirs.U.diagonal())
    for trans in ("N", "T"):
        np.testing.assert_array_equal(ours.solve(b, trans=trans), theirs.solve(b, trans=trans))
    # and the solution solves the system (an independent check of the factor)
    np.testing.assert_allclose(A @ ours.solve(b), b, rtol=0, atol=1e-12 * np.abs(b).max())


def test_a_non_canonical_matrix_is_not_changed_and_is_summed():
    A = _matrix(20)
    rows, cols = A.nonzero()
    data = np.asarray(A[rows, cols]).ravel()
    # every entry split in two halves: duplicates, in reversed order (unsorted indices)
    dup = sp.csc_matrix((np.r_[data / 2, data / 2][::-1], (np.r_[rows, rows][::-1],
                                                             np.r_[cols, cols][::-1])),
                        shape=A.shape)
    dup = sp.csc_matrix((dup.data, dup.indices, dup.indptr), shape=A.shape)
    before = dup.data.copy()
    b = np.arange(1.0, 21.0)
    np.testing.assert_allclose(superlu.splu(dup).solve(b), spla.splu(A).solve(b), rtol=1e-12)
    np.testing.assert_array_equal(dup.data, before)


def test_an_exactly_singular_matrix_raises_runtime_error_as_scipy():
    A = _matrix(10).tolil()
    A[:, 3] = 0.0
    with pytest.raises(RuntimeError):
        spla.splu(A.tocsc())
    with pytest.raises(RuntimeError):
        superlu.splu(A.tocsc())


def test_a_factorisation_does_not_import_scipy_sparse_linalg():
    code = ("import sys, numpy as np, scipy.sparse as sp\n"
            "from lagamine_py.solver.linear import SpluSolver\n"
            "s = SpluSolver(); s.factor(sp.csr_matrix(np.diag([2.0, 4.0])))\n"
            "assert np.allclose(s.solve(np.ones(2)), [0.5, 0.25])\n"
            "print('scipy.sparse.linalg' in sys.modules)\n"
            "from lagamine_py.solver.superlu import splu\n"
            "A = (sp.random(40, 40, density=0.1, random_state=3) + 4 * sp.eye(40)).tocsc()\n"
            "ours = splu(A).solve(np.arange(40.0))\n"
            "import scipy.sparse.linalg as spla\n"
            "assert (ours == spla.splu(A, permc_spec='MMD_AT_PLUS_A').solve(np.arange(40.0))).all()\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"     # and the file-loaded factor is scipy's


# -- the kept column ordering (superlu.KeptOrdering, used by linear.SpluSolver) -------------

def _same_values(A, seed):
    """A matrix of A's structure with other values (a later Newton iteration's tangent)."""
    B = A.copy()
    B.data = B.data * (1.0 + 0.3 * np.random.default_rng(seed).standard_normal(B.nnz))
    return B


def _press_slide_tangent():
    """K_ff of press_slide.dat pressed and sliding (non-symmetric: friction, follower
    pressure), as CSC of its transpose: the matrix SpluSolver hands SuperLU."""
    from pathlib import Path

    from lagamine_py.deck import load_deck
    from lagamine_py.elements.base import StepContext
    from lagamine_py.solver.linear import FreeDofs
    from lagamine_py.solver.problem import build_problem
    model = load_deck(Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat")
    problem = build_problem(model)
    xy = model.coords
    u = np.zeros(2 * len(xy))
    u[0::2] = 1e-3 * xy[:, 0] / 40.0
    u[1::2] = -2e-3 * xy[:, 1] / 20.0 - 1e-4
    problem.set_pressures({name: 200.0 for name in problem.pressure_groups})
    ctx = StepContext(nlgeom=True, t_old=0.0, t_new=1.0,
                      foundation_old={"FLAT": np.zeros(2)}, foundation_new={"FLAT": np.zeros(2)})
    ev = problem.evaluate(u, np.zeros_like(u), problem.init_states(), ctx, True)
    A = FreeDofs(problem.pattern, 2 * np.flatnonzero(xy[:, 0] > 40 - 1e-9)).kff(ev.data)
    return sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)


@pytest.fixture(scope="module")
def fe_tangent():
    return _press_slide_tangent()


def _assert_same_factor(lu, ref, order, b):
    """``lu`` (columns in ``order``'s order, NATURAL) is ``ref`` (MMD_AT_PLUS_A) bit for bit."""
    np.testing.assert_array_equal(lu.perm_c, np.arange(len(lu.perm_c)))   # no reordering
    np.testing.assert_array_equal(lu.perm_r, ref.perm_r)
    for a, r in ((lu.L, ref.L), (lu.U, ref.U)):
        assert isinstance(a, superlu.CscParts) and a.shape == r.shape
        data, indices, indptr = a.arrays
        end = indptr[-1]
        np.testing.assert_array_equal(indptr, r.indptr)
        np.testing.assert_array_equal(indices[:end], r.indices)
        np.testing.assert_array_equal(data[:end], r.data)
    np.testing.assert_array_equal(superlu.u_diagonal(lu), ref.U.diagonal())
    np.testing.assert_array_equal(superlu.u_diagonal(ref), ref.U.diagonal())
    np.testing.assert_array_equal(lu.solve(b[order.columns], trans="T"), ref.solve(b, trans="T"))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kept_ordering_gives_the_mmd_factor_bit_for_bit(seed):
    A = _matrix(80, seed)
    order = superlu.KeptOrdering(A, superlu.splu(A))
    b = np.random.default_rng(5).standard_normal(A.shape[0])
    for k in range(3):                            # later matrices of the structure
        B = _same_values(A, 10 * seed + k)
        _assert_same_factor(order.factor(B.data), superlu.splu(B), order, b)


def test_kept_ordering_on_a_tangent_of_the_main_job(fe_tangent):
    A = fe_tangent
    order = superlu.KeptOrdering(A, superlu.splu(A))
    assert not np.array_equal(order.position, np.arange(A.shape[0]))     # it does reorder
    b = np.random.default_rng(6).standard_normal(A.shape[0])
    for k in range(2):
        B = _same_values(A, k)
        _assert_same_factor(order.factor(B.data), superlu.splu(B), order, b)
        # and it solves B^T x = b (a check that does not rest on the reference factor)
        x = order.factor(B.data).solve(b[order.columns], trans="T")
        np.testing.assert_allclose(B.T @ x, b, rtol=0, atol=1e-8 * np.abs(b).max())


def test_kept_ordering_recognises_its_structure(fe_tangent):
    A = fe_tangent
    order = superlu.KeptOrdering(A, superlu.splu(A))
    assert order.matches(A) and order.matches(_same_values(A, 3))       # same arrays, equal arrays
    other = A.tolil()
    other[0, A.shape[0] - 1] = 1.0                                      # one more entry
    assert not order.matches(other.tocsc())
    assert not order.matches(A[:-1, :-1].tocsc())


def _parts(M):
    """A CSC matrix as CscParts, with spare room past its last entry as SuperLU leaves it."""
    M = sp.csc_matrix(M)
    pad = lambda a: np.concatenate([a, np.full(5, a[-1] if a.size else 0, a.dtype)])  # noqa: E731
    return superlu.CscParts((pad(M.data), pad(M.indices), M.indptr), M.shape)


class _Factor:
    def __init__(self, U):
        self.U = U


@pytest.mark.parametrize("case", ["last", "unsorted", "missing", "empty column"])
def test_u_diagonal_of_the_raw_arrays_is_scipys(case):
    """The diagonal read from CscParts equals scipy's U.diagonal(): where each column's
    diagonal entry comes last (SuperLU's U) and, searched, where it does not."""
    rng = np.random.default_rng(3)
    U = sp.triu(sp.random(12, 12, density=0.3, random_state=rng)) + sp.diags(rng.random(12) + 1)
    U = sp.csc_matrix(U)
    if case == "unsorted":              # a column's diagonal entry first
        U = U.copy()
        for j in range(12):
            a, b = U.indptr[j], U.indptr[j + 1]
            U.indices[a:b], U.data[a:b] = U.indices[a:b][::-1].copy(), U.data[a:b][::-1].copy()
        U.has_sorted_indices = False
    elif case == "missing":
        U = U.tolil()
        U[4, 4] = 0.0
        U = sp.csc_matrix(U)
        U.eliminate_zeros()
    elif case == "empty column":
        U = U.tolil()
        U[:, 7] = 0.0
        U = sp.csc_matrix(U)
        U.eliminate_zeros()
    np.testing.assert_array_equal(superlu.u_diagonal(_Factor(_parts(U))), U.diagonal())


@pytest.mark.parametrize("case", ["full", "missing", "nan", "none"])
def test_kept_ordering_diagonal_scale_is_the_diagonals_largest_magnitude(case):
    """``diagonal_scale`` (the pivot test's scale, read at the structure's diagonal positions)
    is ``np.abs(A.diagonal()).max()`` for any values of the structure: with diagonal entries
    missing from it (they count 0), a NaN among them, or none at all."""
    rng = np.random.default_rng(7)
    A = sp.random(30, 30, density=0.2, random_state=rng, format="csc") + sp.diags(rng.random(30) + 1)
    A = sp.csc_matrix(A)
    if case in ("missing", "none"):
        A = A.tolil()
        for i in (range(30) if case == "none" else (3, 11, 29)):
            A[i, i] = 0.0
        A = sp.csc_matrix(A)
        A.eliminate_zeros()
        A = A + sp.csc_matrix((np.full(30, 5.0), (np.arange(30), (np.arange(30) + 1) % 30)),
                              shape=A.shape)                        # nonsingular for splu
        A = sp.csc_matrix(A)
    A.sort_indices()
    order = superlu.KeptOrdering(A, superlu.splu(A))
    for _ in range(3):
        data = rng.standard_normal(A.nnz) * 10.0
        if case == "nan":
            data[A.indptr[5] + np.flatnonzero(A.indices[A.indptr[5]:A.indptr[6]] == 5)[0]] = np.nan
        B = sp.csc_matrix((data, A.indices, A.indptr), shape=A.shape)
        want = np.abs(B.diagonal()).max()
        got = order.diagonal_scale(data)
        assert (np.isnan(got) and np.isnan(want)) if case == "nan" else got == want
