"""The factor in hand reused as the preconditioner of GMRES (solver/reuse.py).

Every answer is checked against an independent one: the direct solve of the same matrix
(scipy's SuperLU on the new matrix), Krylov theory (a change of rank r is absorbed in at most
r + 1 steps), and on a whole deck the Coulomb closed form of press-then-slide's end state,
T = phi P with P the pressure resultant.
"""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lagamine_py.elements.base import StepContext
from lagamine_py.solver import steps as steps_mod
from lagamine_py.solver.linear import FreeDofs, LinearSolver, SpluSolver
from lagamine_py.solver.newton import Settings, solve_increment
from lagamine_py.solver.reuse import FactorReuse, forcing, gmres_right

from runner import run_deck
from test_solver_fakes import GROUND, Springs, make_model, make_problem

DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"


def _matrix(n=300, seed=0):
    """A sparse non-symmetric, diagonally dominant matrix (a tangent's character)."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.02, random_state=rng, format="csr")
    return (A + sp.diags(4.0 + rng.random(n))).tocsr()


def _low_rank_change(A, rank, seed=1):
    """A + U V^T with U, V (n, rank) nonzero on a few rows: contact faces changing status."""
    rng = np.random.default_rng(seed)
    n = A.shape[0]
    rows = rng.choice(n, size=3 * rank, replace=False)
    U = np.zeros((n, rank))
    V = np.zeros((n, rank))
    for j in range(rank):
        U[rows[3 * j:3 * j + 3], j] = rng.standard_normal(3)
        V[rows[3 * j:3 * j + 3], j] = rng.standard_normal(3)
    return (A + sp.csr_matrix(U @ V.T)).tocsr()


class Counting(LinearSolver):
    """A SuperLU solver whose factorisations and back-substitutions are counted."""

    def __init__(self):
        self.inner = SpluSolver()
        self.factors = self.solves = 0

    def factor(self, A):
        self.factors += 1
        self.inner.factor(A)

    def solve(self, b):
        self.solves += 1
        return self.inner.solve(b)


@pytest.mark.parametrize("rank", [1, 3, 6])
def test_gmres_on_the_old_factor_absorbs_a_rank_r_change_in_r_plus_one_steps(rank):
    A_old = _matrix()
    A_new = _low_rank_change(A_old, rank)
    lu = spla.splu(A_old.tocsc())
    b = np.random.default_rng(2).standard_normal(A_old.shape[0])
    x, steps = gmres_right(A_new, lu.solve, b, 1e-10, 20)
    assert x is not None
    assert steps <= rank + 1                    # Krylov: M A_new = I + rank-r
    x_direct = spla.splu(A_new.tocsc()).solve(b)
    assert np.linalg.norm(x - x_direct) <= 1e-8 * np.linalg.norm(x_direct)
    assert np.linalg.norm(A_new @ x - b) <= 1e-10 * np.linalg.norm(b)


def test_gmres_gives_up_when_the_steps_run_out():
    A_old = _matrix()
    A_new = _low_rank_change(A_old, 8)
    lu = spla.splu(A_old.tocsc())
    b = np.ones(A_old.shape[0])
    x, steps = gmres_right(A_new, lu.solve, b, 1e-12, 3)
    assert x is None and steps == 3


def test_gmres_with_the_exact_factor_takes_one_step_and_zero_rhs_none():
    A = _matrix()
    lu = spla.splu(A.tocsc())
    b = np.arange(A.shape[0], dtype=float)
    x, steps = gmres_right(A, lu.solve, b, 1e-12, 5)
    assert steps == 1 and np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b)
    x, steps = gmres_right(A, lu.solve, np.zeros_like(b), 1e-12, 5)
    assert steps == 0 and not x.any()


def test_factor_reuse_reuses_falls_back_and_keys_on_the_free_set():
    A_old = _matrix()
    n = A_old.shape[0]
    b = np.ones(n)
    free_a, free_b = _Free(n), _Free(n)
    inner = Counting()
    reuse = FactorReuse(inner, krylov=8)
    x = reuse.solve(free_a, A_old, b)                      # nothing in hand: factorise
    assert inner.factors == 1 and reuse.factorisations == 1
    A_near = _low_rank_change(A_old, 2)
    x = reuse.solve(free_a, A_near, b)                     # rank 2: reused
    assert inner.factors == 1 and reuse.reused == 1
    assert np.linalg.norm(A_near @ x - b) <= 1e-7 * np.linalg.norm(b)
    assert reuse.back_substitutions == inner.solves > 2
    A_far = _low_rank_change(A_old, 12, seed=5)            # rank 12 > 8 steps: factorise
    x = reuse.solve(free_a, A_far, b)
    assert inner.factors == 2
    assert np.linalg.norm(A_far @ x - b) <= 1e-12 * np.linalg.norm(b)
    reuse.solve(free_b, A_far, b)                          # another free-DOF set: factorise
    assert inner.factors == 3
    reuse.min_dofs = n + 1                                 # below KRYLOVDOFS: factorise
    reuse.solve(free_b, A_far, b)
    assert inner.factors == 4
    off = FactorReuse(Counting(), krylov=0)                # KRYLOV=0: every solve factorises
    off.solve(free_a, A_old, b)
    off.solve(free_a, A_old, b)
    assert off.factorisations == 2 and off.reused == 0


class _Free:
    """The part of FreeDofs that FactorReuse reads."""

    def __init__(self, n):
        self.nfree = n


def test_forcing_term_follows_the_residual_reduction_and_is_clamped():
    assert forcing([1.0]) == 1e-2                             # ETA_FIRST
    assert forcing([1e-2, 1e-3]) == pytest.approx(0.9e-2)
    assert forcing([1e-2, 1e-6]) == 1e-7                      # 0.9e-8 clamped to RTOL
    assert forcing([1e-2, 1e-1]) == 0.1                       # residual grew: ETA_MAX


def test_newton_with_the_factor_reused_reaches_plain_newtons_answer_with_fewer_factors():
    """A chain of cubic springs (exact tangent): the same converged u as plain Newton (to the
    tolerance), fewer factorisations, the same number of Newton iterations or one more."""
    def solve(reuse):
        model = make_model(3, [])
        problem = make_problem(model, [Springs([[GROUND, 0], [0, 2], [2, 4]], [1.0, 2.0, 1.5],
                                               a=2.0),
                                       Springs([[GROUND, 1], [GROUND, 3], [GROUND, 5]], 1.0)])
        free = FreeDofs(problem.pattern, np.zeros(0, np.int64))
        f_ext = np.zeros(6)
        f_ext[4] = 3.0
        conv = solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                               StepContext(), np.zeros(0), f_ext, Settings(rtol=1e-12),
                               solves=reuse)
        return conv
    plain = solve(None)
    reused = solve(FactorReuse(SpluSolver(), krylov=5))
    assert plain.factorisations == plain.iterations
    assert reused.factorisations < plain.factorisations
    assert reused.iterations <= plain.iterations + 1
    assert np.allclose(reused.u, plain.u, rtol=1e-10, atol=0)
    d = np.array([reused.u[0], reused.u[2] - reused.u[0], reused.u[4] - reused.u[2]])
    assert np.allclose(np.array([1.0, 2.0, 1.5]) * (d + 2 * d**3), 3.0, rtol=1e-11)


def _press_slide(tmp_path, name, controls, monkeypatch):
    """press_slide.dat with ``controls`` in both steps; (factorisations, Newton solves, P, T)."""
    text = DECK.read_text()
    for kw in ("*DLOAD", "*BOUNDARY"):
        text = text.replace(kw, f"*CONTROLS\n{controls}\n{kw}")
    deck = tmp_path / f"{name}.dat"
    deck.write_text(text)
    factors = []
    make = steps_mod.make_solver

    def counting(solver_name):
        s = make(solver_name)
        inner = s.factor

        def factor(A):
            factors.append(A.shape[0])
            inner(A)
        s.factor = factor
        return s
    monkeypatch.setattr(steps_mod, "make_solver", counting)
    outcome, cap, res = run_deck(deck, tmp_path / name)
    assert outcome.status == 0, outcome.message
    solves = sum(r.iterations for r in cap.results) + sum(f.iterations for f in cap.failures)
    totals = res.table("contact_totals.csv")
    return len(factors), solves, float(totals["P"][-1]), float(totals["T"][-1])


def test_press_slide_with_the_factor_reused_slides_at_the_closed_form(tmp_path, monkeypatch):
    """The main job with the reuse forced on (KRYLOVDOFS=0; its 866 DOFs are below the
    default's 5 000) and off (KRYLOV=0): both end with the whole interface sliding,
    T = phi P, P = 200 MPa x 30 mm; the reuse factorises at most a third as often."""
    f_on, s_on, P_on, T_on = _press_slide(tmp_path, "on", "KRYLOVDOFS=0", monkeypatch)
    f_off, s_off, P_off, T_off = _press_slide(tmp_path, "off", "KRYLOV=0", monkeypatch)
    assert f_off >= 0.9 * s_off               # off: about one factorisation per Newton solve
    assert f_on <= f_off / 3, (f_on, f_off)
    for P, T in ((P_on, T_on), (P_off, T_off)):
        assert P == pytest.approx(6000.0, rel=1e-3)
        assert abs(T) == pytest.approx(0.2 * P, rel=1e-6)


def test_gmres_gives_up_early_when_its_rate_cannot_reach_the_tolerance():
    """A preconditioner that does nothing on a matrix whose eigenvalues spread over eight
    decades: the residual falls by a few per cent per step, so GMRES stops at its third step
    instead of spending the fifty it was allowed (each one a back-substitution)."""
    A = sp.diags(np.logspace(0.0, 8.0, 400)).tocsr()
    calls = []

    def M(v):
        calls.append(1)
        return v
    x, k = gmres_right(A, M, np.ones(400), 1e-8, 50)
    assert x is None and k == 3 and len(calls) == 3
