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
