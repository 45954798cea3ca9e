"""The linear-solver contract (:class:`lagamine_py.solver.linear.LinearSolver`) as checks.

Small sparse matrices with the structure of an element pattern (structurally symmetric), built
with a known solution: solved to round-off, refactored with new values on the same structure,
and made singular at known DOFs.
"""
from __future__ import annotations

import numpy as np

from .findings import ContractFailure, Finding, Suite, all_within, require


SOLVER_ITEMS = ("non-symmetric", "symmetric", "refactor", "singular")


def _grid_matrix(n_side: int, symmetric: bool, seed: int):
    """A structurally symmetric 5-point-stencil matrix on an n x n grid (like an element
    pattern), diagonally dominant: random non-symmetric values, or symmetric positive."""
    import scipy.sparse as sp
    rng = np.random.default_rng(seed)
    n = n_side * n_side
    idx = np.arange(n).reshape(n_side, n_side)
    rows = np.concatenate([idx[:, :-1].ravel(), idx[:-1, :].ravel()])
    cols = np.concatenate([idx[:, 1:].ravel(), idx[1:, :].ravel()])
    upper = -rng.uniform(0.5, 1.5, len(rows))
    lower = upper if symmetric else -rng.uniform(0.5, 1.5, len(rows))
    A = sp.coo_matrix((np.concatenate([upper, lower]),
                       (np.concatenate([rows, cols]), np.concatenate([cols, rows]))), (n, n))
    A = A.tocsr()
    diag = np.abs(A).sum(axis=1).A1 + rng.uniform(0.5, 1.0, n)
    A = (A + sp.diags(diag)).tocsr()
    A.sort_indices()
    return A


def _solve_error(solver, A, x_exact) -> tuple[float, float]:
    b = A @ x_exact
    x = np.asarray(solver.solve(b), float).reshape(-1)
    return (float(np.linalg.norm(x - x_exact) / np.linalg.norm(x_exact)),
            float(np.linalg.norm(A @ x - b) / np.linalg.norm(b)))


def _solver_system(cls, symmetric: bool) -> str:
    A = _grid_matrix(7, symmetric, 1 if symmetric else 2)
    x = np.random.default_rng(5).normal(size=A.shape[0])
    s = cls()
    s.factor(A)
    err, res = _solve_error(s, A, x)
    what = "symmetric positive definite" if symmetric else "non-symmetric"
    return f"{A.shape[0]} x {A.shape[0]} {what}: " + all_within(
        [("|x - x_exact| / |x_exact|", err, 1e-10), ("|A x - b| / |b|", res, 1e-12)])


def _same_structure(A, seed: int):
    """``A`` with new values on the same structure, still diagonally dominant."""
    B = A.copy()
    B.data = B.data * np.random.default_rng(seed).uniform(0.5, 2.0, B.nnz)
    rows = np.repeat(np.arange(B.shape[0]), np.diff(B.indptr))
    diag = rows == B.indices
    B.data[diag] = 0.0
    B.data[diag] = np.bincount(rows, np.abs(B.data), B.shape[0])[rows[diag]] + 1.0
    return B


def _solver_refactor(cls) -> str:
    A1 = _grid_matrix(7, False, 3)
    A2 = _same_structure(A1, 4)
    rng = np.random.default_rng(6)
    s = cls()
    measures = []
    for k, A in enumerate((A1, A2, A1), 1):
        s.factor(A)
        for j in (1, 2):
            err, _ = _solve_error(s, A, rng.normal(size=A.shape[0]))
            measures.append((f"factorisation {k}, right-hand side {j}: |x - x_exact| / |x_exact|",
                             err, 1e-10))
    return "one solver, three factorisations (the structure kept, the values changed), two " \
           "solves each: " + all_within(measures)


def _without(A, dofs):
    """``A`` with the rows and columns ``dofs`` zeroed, their entries kept as stored zeros (the
    structure of a tangent does not change with its values)."""
    B = A.copy()
    rows = np.repeat(np.arange(B.shape[0]), np.diff(B.indptr))
    B.data[np.isin(rows, dofs) | np.isin(B.indices, dofs)] = 0.0
    return B


def _solver_singular(cls) -> str:
    from ..core.errors import SingularMatrixError
    A = _grid_matrix(7, False, 7)
    n = A.shape[0]
    zero = [9, 30]                  # two DOFs without any stiffness
    B = _without(A, zero)
    pair = [15, 16]                 # grid neighbours held by a spring between them only
    C = _without(A, pair)
    rows = np.repeat(np.arange(n), np.diff(C.indptr))
    for i in pair:
        for j in pair:
            C.data[(rows == i) & (C.indices == j)] = 2.0 if i == j else -2.0
    results = []
    for label, M, right, exact in (("zero rows and columns", B, zero, True),
                                   ("a floating spring", C, pair, False)):
        s = cls()
        try:
            s.factor(M)
            x = s.solve(np.ones(n))
        except SingularMatrixError as exc:
            named = sorted(int(d) for d in exc.dofs)
            if exact:
                require(named == right, f"{label} at DOFs {right}: SingularMatrixError names "
                        f"{named}")
            else:
                require(bool(named) and set(named) <= set(right),
                        f"{label} between DOFs {right}: SingularMatrixError names {named} "
                        f"(want one or both of them)")
            results.append(f"{label} at DOFs {right}: SingularMatrixError names {named}")
            continue
        raise ContractFailure(f"{label} at DOFs {right}: no SingularMatrixError (solve gave "
                              f"max |x| = {np.abs(np.asarray(x)).max():.3g})")
    return "; ".join(results)


def check_solver(cls) -> list[Finding]:
    """The linear-solver contract (:class:`~lagamine_py.solver.linear.LinearSolver`)."""
    s = Suite(SOLVER_ITEMS)
    why = cls.unavailable()
    if why:
        return s.skip_rest(f"not available here: {why}")
    s.run("non-symmetric", _solver_system, cls, False)
    s.run("symmetric", _solver_system, cls, True)
    s.run("refactor", _solver_refactor, cls)
    s.run("singular", _solver_singular, cls)
    return s.findings
