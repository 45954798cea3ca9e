"""Sparsity pattern scatter vs a dense assembly, the free-DOF reduction, and the linear solvers."""
import numpy as np
import pytest
import scipy.sparse as sp

from lagamine_py.registry import get
from lagamine_py.solver.linear import FreeDofs, SingularMatrixError, SpluSolver, make_solver
from lagamine_py.solver.pattern import Pattern


def dense_assembly(ndof, dofs_list, blocks, forces):
    """Reference: element loops into a dense matrix (the textbook way)."""
    K = np.zeros((ndof, ndof))
    F = np.zeros(ndof)
    for dofs, Ke, fe in zip(dofs_list, blocks, forces):
        for d, k, f in zip(dofs, Ke, fe):
            for a in range(len(d)):           # explicit loops: repeated DOFs accumulate
                F[d[a]] += f[a]
                for b in range(len(d)):
                    K[d[a], d[b]] += k[a, b]
    return K, F


def random_groups(rng, ndof):
    """Three groups of different block sizes, overlapping DOFs, repeated DOFs in an element."""
    dofs_list = [rng.integers(0, ndof, size=(7, 4)), rng.integers(0, ndof, size=(5, 6)),
                 np.array([[3, 3], [1, 1]])]
    blocks = [rng.normal(size=(len(d), d.shape[1], d.shape[1])) for d in dofs_list]
    forces = [rng.normal(size=d.shape) for d in dofs_list]
    return dofs_list, blocks, forces


def test_scatter_equals_dense_assembly():
    rng = np.random.default_rng(1)
    ndof = 20
    dofs_list, blocks, forces = random_groups(rng, ndof)
    pat = Pattern(ndof, dofs_list)
    K_ref, F_ref = dense_assembly(ndof, dofs_list, blocks, forces)
    A = pat.matrix(pat.assemble_data(blocks))
    assert np.allclose(A.toarray(), K_ref, rtol=0, atol=1e-13)
    assert np.allclose(pat.assemble_vector(forces), F_ref, rtol=0, atol=1e-13)
    # canonical CSR: sorted, no duplicates, exactly the coupled entries
    B = A.copy()
    B.sum_duplicates()
    assert B.nnz == A.nnz and A.has_canonical_format
    coupled = np.zeros((ndof, ndof), bool)
    for d in dofs_list:
        for row in d:
            coupled[np.ix_(row, row)] = True
    assert A.nnz == coupled.sum()
    # a second assembly with other values reuses the same pattern
    blocks2 = [2 * b + 1 for b in blocks]
    K2, _ = dense_assembly(ndof, dofs_list, blocks2, forces)
    assert np.allclose(pat.matrix(pat.assemble_data(blocks2)).toarray(), K2, atol=1e-13)


def test_free_dof_reduction_equals_dense_slicing():
    rng = np.random.default_rng(2)
    ndof = 20
    dofs_list, blocks, _ = random_groups(rng, ndof)
    pat = Pattern(ndof, dofs_list)
    data = pat.assemble_data(blocks)
    K = pat.matrix(data).toarray()
    constrained = np.array([0, 5, 7, 19])
    fd = FreeDofs(pat, constrained)
    free = np.setdiff1d(np.arange(ndof), constrained)
    assert np.array_equal(fd.free, free)
    assert np.allclose(fd.kff(data).toarray(), K[np.ix_(free, free)], atol=0)
    du = np.zeros(ndof)
    du[constrained] = rng.normal(size=len(constrained))
    assert np.allclose(fd.kfc_dot(data, du), K[np.ix_(free, constrained)] @ du[constrained],
                       atol=1e-13)


@pytest.mark.parametrize("name", ["SPLU", "AUTO"])
def test_solver_matches_dense_solve_nonsymmetric(name):
    rng = np.random.default_rng(3)
    n = 60
    A = sp.random(n, n, density=0.1, random_state=4, format="csr") + sp.eye(n, format="csr") * 5
    A = A.tocsr()
    A.sort_indices()
    b = rng.normal(size=n)
    solver = make_solver(name)
    solver.factor(A)
    x = solver.solve(b)
    assert np.allclose(x, np.linalg.solve(A.toarray(), b), rtol=1e-12, atol=1e-12)
    assert not np.allclose(A.toarray(), A.toarray().T)      # really non-symmetric


def test_solvers_registered():
    assert get("solvers", "SPLU") is SpluSolver
    assert get("solvers", "AUTO") is not None


def chain_matrix(n_springs, grounded=True):
    """Stiffness of a chain of unit springs on DOFs 0..n (ground at the left if grounded)."""
    n = n_springs + 1
    K = np.zeros((n, n))
    for i in range(n_springs):
        K[np.ix_([i, i + 1], [i, i + 1])] += [[1, -1], [-1, 1]]
    if grounded:
        K[0, 0] += 1.0
    return K


def test_singular_zero_diagonal_names_the_dof():
    K = chain_matrix(3)
    K = np.pad(K, ((0, 2), (0, 2)))          # DOFs 4 and 5 (node row 2, x and y): nothing
    with pytest.raises(SingularMatrixError) as err:
        SpluSolver().factor(sp.csr_matrix(K))
    assert set(err.value.dofs) >= {4, 5}
    msg = err.value.describe(node_ids=np.array([10, 20, 30]))
    assert "node 30 x" in msg and "node 30 y" in msg


def test_singular_rigid_mode_names_a_dof_of_the_floating_chain():
    """A chain with no support: every diagonal is non-zero, the last pivot vanishes."""
    K = np.zeros((6, 6))
    K[:3, :3] = chain_matrix(2, grounded=True)
    K[3:, 3:] = chain_matrix(2, grounded=False)        # DOFs 3, 4, 5 float
    with pytest.raises(SingularMatrixError) as err:
        SpluSolver().factor(sp.csr_matrix(K))
    assert len(err.value.dofs) >= 1 and set(err.value.dofs) <= {3, 4, 5}
    assert "unrestrained" in str(err.value)
