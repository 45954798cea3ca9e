"""Newton's linear solves with the factor in hand: GMRES preconditioned by the last factorisation.

A Newton iteration's tangent differs from the one factorised at an earlier iteration (of this
increment or of the one before) by the change of the material tangent and by the faces whose
contact points changed status: a small change, of low rank where only contact changed.  So
``K_new du = b`` is solved first by GMRES on ``K_new`` with the factor of ``K_old`` as the
(right) preconditioner: every GMRES step costs one back-substitution and one product with
``K_new``; a change of rank ``r`` is absorbed in about ``r + 1`` steps.  When ``KRYLOV`` steps
(``*CONTROLS``, default 4) have not brought it below the forcing term (:func:`forcing`), the
tangent is factorised as usual and that solve is exact.  A factorisation costs 24, 13 and 9
back-substitutions of PARDISO (one thread, 5k, 20k and 78k DOFs of the press-slide tangent;
a back-substitution is memory-bound, the factorisation is not), and each GMRES step adds a
product with ``K_new``: a reuse pays only when it takes a few steps, hence the small budget and
the early give-up of :func:`gmres_right`.

The linear residual left is the Eisenstat-Walker forcing term times the right-hand side: what
the last Newton iteration's own reduction says the next iterate's error will be anyway, so the
Newton iteration counts stay about those of plain Newton (+0 to 5 % on press-then-slide) and the
converged answers meet the same tolerances; what falls is the number of factorisations.

:class:`FactorReuse` counts factorisations and back-substitutions separately
(``docs/performance.md`` reports both; the issue's "linear solves per increment" goal counts
factorisations).
"""
from __future__ import annotations

import logging

import numpy as np

from ..core.errors import SingularMatrixError

__all__ = ["FactorReuse", "RTOL", "forcing", "gmres_right"]

log = logging.getLogger("lagamine_py.solver")

RTOL = 1e-7          # linear residual |b - A x| / |b| a reused factor must reach (at most)
ETA_FIRST = 1e-2     # forcing term of an increment's first solve
ETA_MAX = 0.1        # and the largest one


def forcing(history: list[float]) -> float:
    """Eisenstat-Walker forcing term (their choice 2, gamma 0.9): how far a linear solve on the
    factor in hand may stop from the exact Newton step, ``|b - A x| <= eta |b|``, given the
    relative residuals of the increment so far.  ``0.9 (r_k / r_k-1)^2`` is the residual
    reduction the last iteration achieved, squared: Newton's own error at the next iterate is
    about that, so solving the linear system further buys nothing.  Clamped to
    ``[RTOL, ETA_MAX]``; ``ETA_FIRST`` at the first iteration."""
    if len(history) < 2 or not history[-2] > 0.0:
        return ETA_FIRST
    eta = 0.9 * (history[-1] / history[-2]) ** 2
    return float(min(max(eta, RTOL), ETA_MAX))


class FactorReuse:
    """A linear solver plugin instance with its factor kept between Newton iterations.

    Parameters
    ----------
    solver : :class:`~lagamine_py.solver.linear.LinearSolver` instance (its ``solve`` uses the
        factor of its last ``factor`` call).
    krylov : GMRES steps allowed with the factor in hand before the matrix is factorised
        (0: every solve factorises).
    min_dofs : the factor is reused only for matrices of at least this many rows (below
        ``*CONTROLS KRYLOVDOFS``' 5 000, SPLU factorises in milliseconds: a GMRES step's Python
        overhead is then not small beside a back-substitution, and nothing is saved).
    """

    def __init__(self, solver, krylov: int = 0, min_dofs: int = 0):
        self.solver = solver
        self.krylov = int(krylov)
        self.min_dofs = int(min_dofs)
        self.factorisations = 0
        self.back_substitutions = 0
        self.solves = 0               # linear solves, by either way
        self.reused = 0               # solves done with an older factor
        self._key = None              # the free-DOF set (object) the factor in hand belongs to

    def forget(self) -> None:
        """No factor in hand any more (a failed factorisation, or the caller's choice)."""
        self._key = None

    def solve(self, free, A, rhs: np.ndarray, atol: float = 0.0) -> np.ndarray:
        """``x`` with ``A x = rhs``, ``A`` = ``K_ff`` (CSR) of the free-DOF set ``free``:
        by GMRES on the factor in hand when it reaches ``|rhs - A x| <= max(RTOL |rhs|, atol)``
        within ``krylov`` steps, else by a new factorisation (SingularMatrixError from the
        solver as usual)."""
        self.solves += 1
        if (self.krylov > 0 and self._key is free and A.shape[0] == free.nfree
                and A.shape[0] >= self.min_dofs):
            self.solver.hold_matrix(A)
            x, steps = gmres_right(A, self._back_substitute, rhs, RTOL, self.krylov, atol)
            if x is not None:
                self.reused += 1
                log.debug("      factor reused: %d GMRES steps", steps)
                self.solver.hold_matrix(None)
                return x
        self._key = None
        self.solver.factor(A)
        self.factorisations += 1
        self._key = free
        x = self._back_substitute(rhs)
        # the factor is kept for the next solves, the matrix need not be (the solver's choice):
        # not alive through the next evaluation beside the factor (77 MB at 309k DOFs)
        self.solver.hold_matrix(None)
        return x

    def _back_substitute(self, b: np.ndarray) -> np.ndarray:
        self.back_substitutions += 1
        return self.solver.solve(b)

    def counts(self) -> tuple[int, int]:
        """(factorisations, back-substitutions) so far."""
        return self.factorisations, self.back_substitutions


def gmres_right(A, M, b: np.ndarray, rtol: float, steps: int, atol: float = 0.0):
    """Right-preconditioned GMRES from ``x = 0``: ``min |b - A M y|`` over the Krylov space of
    ``A M`` (Arnoldi with modified Gram-Schmidt), at most ``steps`` steps.

    Parameters
    ----------
    A : (n, n) sparse matrix; M : callable, ``M(v)`` ~ ``A^-1 v`` (the factor in hand);
    b : (n,) right-hand side.

    Returns ``(x, k)``: the solution after ``k`` steps once ``|b - A x| <= max(rtol |b|, atol)``
    (checked on the true residual), or ``(None, k)`` when it gives up after ``k`` steps: the
    steps ran out, the preconditioned operator broke down without reaching it, or from the
    third step on the mean reduction per step so far, kept up to ``steps``, would end more
    than ten times above it (a factor that far from the matrix is not worth more steps).
    Costs ``k + 1`` calls of ``M`` when it succeeds, ``k`` when it gives up."""
    beta = float(np.linalg.norm(b))
    if beta == 0.0:
        return np.zeros_like(b), 0
    tol = max(rtol * beta, atol)
    n = b.size
    V = np.empty((steps + 1, n))          # rows: orthonormal basis of the Krylov space
    H = np.zeros((steps + 1, steps))      # Hessenberg matrix of A M on that basis
    V[0] = b / beta
    e1 = np.zeros(steps + 1)
    e1[0] = beta
    for j in range(steps):
        try:
            w = A @ M(V[j])
        except SingularMatrixError:       # the old factor's own residual guard: give up
            return None, steps
        if not np.all(np.isfinite(w)):
            return None, steps
        for i in range(j + 1):            # modified Gram-Schmidt
            H[i, j] = float(V[i] @ w)
            w -= H[i, j] * V[i]
        H[j + 1, j] = float(np.linalg.norm(w))
        y, *_ = np.linalg.lstsq(H[:j + 2, :j + 1], e1[:j + 2], rcond=None)
        estimate = float(np.linalg.norm(e1[:j + 2] - H[:j + 2, :j + 1] @ y))
        if estimate <= tol or H[j + 1, j] <= 1e-14 * beta:
            try:
                x = M(y @ V[:j + 1])
            except SingularMatrixError:
                return None, steps
            if float(np.linalg.norm(b - A @ x)) <= tol:
                return x, j + 1
            return None, steps
        if j >= 2 and beta * (estimate / beta) ** (steps / (j + 1)) > 10.0 * tol:
            return None, j + 1            # the rate so far would not reach tol in `steps`
        V[j + 1] = w / H[j + 1, j]
    return None, steps
