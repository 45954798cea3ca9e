"""Linear solver plugins: PARDISO (symmetric / non-symmetric modes, analysis reuse) against SPLU.

Every check is an exact invariant (the residual ``|A x - b|`` of the computed solution) or the
agreement of two independent factorisations (SuperLU and MKL PARDISO), on tangents assembled
from a real deck (press-then-slide: NLGEOM Ramberg-Osgood block, frictional contact, follower
pressure), so that the matrices have the structure and the conditioning of a run.  PARDISO
tests are skipped only when MKL PARDISO cannot be loaded (optional extra ``pardiso``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from lagamine_py.deck import load_deck
from lagamine_py.elements.base import StepContext
from lagamine_py.solver import linear
from lagamine_py.solver.linear import (FreeDofs, SingularMatrixError, SpluSolver,
                                       make_solver, pardiso_available)
from lagamine_py.solver.problem import build_problem

DECKS = Path(__file__).resolve().parents[1] / "decks"
needs_pardiso = pytest.mark.skipif(not pardiso_available(),
                                   reason="MKL PARDISO cannot be loaded (optional extra 'pardiso')")


@pytest.fixture(scope="module")
def tangents():
    """Reduced tangents of press_slide.dat (16 x 8 Q8): ``nonsym`` with the contact pressed and
    sliding plus the follower pressure, ``sym`` of the solid group alone (no contact, no
    pressure: symmetric in theory), and a right-hand side."""
    model = load_deck(DECKS / "press_slide.dat")
    problem = build_problem(model)
    n = len(model.coords)
    xy = model.coords
    u = np.zeros(2 * n)
    u[0::2] = 1e-3 * xy[:, 0] / 40.0
    u[1::2] = -2e-3 * xy[:, 1] / 20.0 - 1e-4
    problem.set_pressures({name: 200.0 for name in problem.pressure_groups})
    ctx = StepContext(nlgeom=True, t_old=0.0, t_new=1.0,
                      foundation_old={"FLAT": np.zeros(2)}, foundation_new={"FLAT": np.zeros(2)})
    states = problem.init_states()
    ev = problem.evaluate(u, np.zeros(2 * n), states, ctx, True)
    right = np.flatnonzero(xy[:, 0] > 40 - 1e-9)
    free = FreeDofs(problem.pattern, 2 * right)
    nonsym = free.kff(ev.data)
    k = problem.kinds.index("solid")
    res = problem.groups[k].compute(u.reshape(-1, 2), np.zeros((n, 2)), states[k], ctx, True)
    data = problem.pattern.assemble_data([res.K if j == k else None
                                          for j in range(len(problem.groups))])
    bottom = np.flatnonzero(xy[:, 1] < 1e-9)
    free_sym = FreeDofs(problem.pattern, np.concatenate([2 * bottom, 2 * bottom + 1]))
    sym = free_sym.kff(data)
    # unloaded, held at one node only: free to rotate (an exact zero-energy mode)
    res0 = problem.groups[k].compute(np.zeros((n, 2)), np.zeros((n, 2)), states[k],
                                     StepContext(nlgeom=False), True)
    data0 = problem.pattern.assemble_data([res0.K if j == k else None
                                           for j in range(len(problem.groups))])
    floating = FreeDofs(problem.pattern, np.array([0, 1])).kff(data0)
    b = np.random.default_rng(0).standard_normal(nonsym.shape[0])
    return {"nonsym": nonsym, "sym": sym, "floating": floating, "b": b}


def _rel_residual(A, x, b):
    return np.linalg.norm(A @ x - b) / np.linalg.norm(b)


def test_fixture_matrices_are_what_they_claim(tangents):
    A, S = tangents["nonsym"], tangents["sym"]
    asym = abs(A - A.T).max() / abs(A).max()
    assert asym > 1e-6                           # friction + follower pressure: non-symmetric
    assert abs(S - S.T).max() <= 1e-13 * abs(S).max()


def test_splu_solves_to_round_off(tangents):
    A, b = tangents["nonsym"], tangents["b"]
    s = SpluSolver()
    s.factor(A)
    assert _rel_residual(A, s.solve(b), b) < 1e-10



def _with_values(A, seed, scale=0.1):
    """A CSR matrix on A's very index arrays (as FreeDofs.kff hands them out), other values."""
    rng = np.random.default_rng(seed)
    return sp.csr_matrix((A.data * (1 + scale * rng.random(A.nnz)), A.indices, A.indptr),
                         shape=A.shape)


def test_splu_orders_a_structure_once(tangents, monkeypatch):
    """SuperLU's column ordering is computed at the first factorisation of a structure and
    kept (superlu.KeptOrdering): the later factors and solutions are those of an ordering
    computed afresh, bit for bit."""
    A, b = tangents["nonsym"], tangents["b"]
    orderings = []
    real = linear.splu
    monkeypatch.setattr(linear, "splu", lambda *a, **k: orderings.append(1) or real(*a, **k))
    s = SpluSolver()
    for k, Ak in enumerate([A, _with_values(A, 1), _with_values(A, 2)]):
        s.factor(Ak)
        x = s.solve(b)
        fresh = SpluSolver()
        fresh.factor(Ak)                                  # its own first: ordered afresh
        np.testing.assert_array_equal(x, fresh.solve(b))
        assert _rel_residual(Ak, x, b) < 1e-10
        assert s.ordered == (k > 0)
    assert len(orderings) == 1 + 3                        # s ordered once, each fresh once
    # equal structure in new arrays: still kept; another structure: ordered again
    A3 = sp.csr_matrix((A.data.copy(), A.indices.copy(), A.indptr.copy()), shape=A.shape)
    s.factor(A3)
    assert s.ordered and len(orderings) == 4
    S = tangents["sym"]
    s.factor(S)
    assert not s.ordered and len(orderings) == 5
    assert _rel_residual(S, s.solve(b[:S.shape[0]]), b[:S.shape[0]]) < 1e-10


def test_splu_orders_every_factorisation_above_the_kept_size(tangents, monkeypatch):
    A, b = tangents["nonsym"], tangents["b"]
    monkeypatch.setattr(linear, "KEEP_ORDERING_ENTRIES", A.nnz - 1)
    s = SpluSolver()
    for k in range(2):
        s.factor(_with_values(A, k))
        assert s.ordering is None and not s.ordered
        assert _rel_residual(_with_values(A, k), s.solve(b), b) < 1e-10
    monkeypatch.setattr(linear, "KEEP_ORDERING_ENTRIES", A.nnz)
    s.factor(A)
    s.factor(A)
    assert s.ordered


def _nearly_dependent(A):
    """A matrix of A's structure whose row 2i+1 is row 2i plus 1e-14 of itself (the two DOFs of
    a node: the same pattern), for the first node where this makes a pivot negligible without
    a negligible diagonal; and the DOFs the public ``splu`` names by their pivots."""
    import scipy.sparse.linalg as spla
    for i in range(10, A.shape[0] // 2):
        j, k = 2 * i + 1, 2 * i
        rows_j, rows_k = (slice(A.indptr[r], A.indptr[r + 1]) for r in (j, k))
        if not np.array_equal(A.indices[rows_j], A.indices[rows_k]):
            continue
        W = A.copy()
        W.data[rows_j] = W.data[rows_k] + 1e-14 * W.data[rows_j]
        lu = spla.splu(sp.csc_matrix((W.data, W.indices, W.indptr), shape=W.shape),
                       permc_spec="MMD_AT_PLUS_A")
        pivots = np.abs(lu.U.diagonal())[lu.perm_c]
        bad = np.flatnonzero(~(pivots > linear.PIVOT_RTOL * np.abs(W.diagonal()).max()))
        if bad.size and not np.isin(bad, linear._suspects(W)).any():
            return W, bad
    raise AssertionError("no node pair makes a negligible pivot")


def test_splu_names_a_small_pivot_by_its_column_with_the_kept_ordering(tangents):
    """The pivot check maps the kept order's pivots back to the matrix's own columns: the DOFs
    named are those scipy's own splu names by its pivots (not by a small diagonal)."""
    A = tangents["nonsym"]
    weak, bad = _nearly_dependent(A)
    s = SpluSolver()
    s.factor(A)
    with pytest.raises(SingularMatrixError) as kept:
        s.factor(sp.csr_matrix((weak.data, A.indices, A.indptr), shape=A.shape))
    assert s.ordering.matches(sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape))
    np.testing.assert_array_equal(kept.value.dofs, bad)
    with pytest.raises(SingularMatrixError) as fresh:
        SpluSolver().factor(weak)
    np.testing.assert_array_equal(fresh.value.dofs, bad)


@needs_pardiso
@pytest.mark.parametrize("which, mtype", [("nonsym", 11), ("sym", -2)])
def test_pardiso_agrees_with_splu(tangents, which, mtype):
    A = tangents[which]
    b = tangents["b"][: A.shape[0]]
    ref = SpluSolver()
    ref.factor(A)
    x_ref = ref.solve(b)
    p = linear.PardisoSolver()
    p.factor(A)
    x = p.solve(b)
    assert p.mtype == mtype                       # symmetric mode only for a symmetric tangent
    assert _rel_residual(A, x, b) < 1e-10
    assert np.abs(x - x_ref).max() <= 1e-10 * np.abs(x_ref).max()
    # no iterative refinement on a factor without perturbed pivots (it tripled the solve)
    assert p.iparm[13] == 0 and p.iparm[6] == 0, (p.iparm[13], p.iparm[6])


@needs_pardiso
def test_pardiso_reuses_the_analysis_while_the_structure_holds(tangents):
    A = tangents["nonsym"]
    b = tangents["b"]
    p = linear.PardisoSolver()
    p.factor(A)
    # new values on the same structure (same index arrays, as FreeDofs.kff hands out)
    rng = np.random.default_rng(1)
    A2 = sp.csr_matrix((A.data * (1 + 0.1 * rng.random(A.nnz)), A.indices, A.indptr),
                       shape=A.shape)
    p.factor(A2)
    assert (p.analyses, p.factorizations) == (1, 2)
    x2 = p.solve(b)
    assert _rel_residual(A2, x2, b) < 1e-10       # the new values were factorised
    # equal structure in new arrays: still recognised
    A3 = sp.csr_matrix((A.data.copy(), A.indices.copy(), A.indptr.copy()), shape=A.shape)
    p.factor(A3)
    assert p.analyses == 1
    assert _rel_residual(A3, p.solve(b), b) < 1e-10
    # another structure (a DOF dropped): new analysis
    A4 = A[1:, 1:].tocsr()
    p.factor(A4)
    assert p.analyses == 2
    assert _rel_residual(A4, p.solve(b[1:]), b[1:]) < 1e-10


@needs_pardiso
def test_pardiso_switches_mode_with_symmetry(tangents):
    S = tangents["sym"]
    b = tangents["b"][: S.shape[0]]
    p = linear.PardisoSolver()
    p.factor(S)
    assert p.mtype == -2
    # break the symmetry of one off-diagonal pair: back to the non-symmetric mode at once
    T = S.copy()
    row = 3
    cols = slice(T.indptr[row], T.indptr[row + 1])
    off = np.where(T.indices[cols] != row, np.abs(T.data[cols]), 0.0)
    j = T.indptr[row] + int(np.argmax(off))               # largest off-diagonal entry of the row
    T.data[j] *= 1.5
    T = sp.csr_matrix((T.data, S.indices, S.indptr), shape=S.shape)
    p.factor(T)
    assert p.mtype == 11 and p.analyses == 2
    assert _rel_residual(T, p.solve(b), b) < 1e-10
    p_forced = linear.PardisoSolver(symmetric=False)
    p_forced.factor(S)
    assert p_forced.mtype == 11


@needs_pardiso
@pytest.mark.parametrize("where", [0.0, 0.37, 0.999])
def test_symmetry_test_by_blocks_finds_one_broken_pair_anywhere(tangents, where):
    """The block-wise symmetry test (early exit, starting where the last matrix failed) gives the
    verdict of the whole-matrix test ``max |A - A^T| <= tol max |A|``: one broken pair at the
    start, middle or end of ``data`` is found, whichever block the search starts from."""
    S = tangents["sym"]
    p = linear.PardisoSolver()
    p.SYM_CHUNK = 97                       # many blocks on this small matrix
    p.factor(S)
    assert p.mtype == -2
    j = min(int(where * S.nnz), S.nnz - 1)
    j = j if S.indices[j] != np.searchsorted(S.indptr, j, side="right") - 1 else j + 1
    T = sp.csr_matrix((S.data.copy(), S.indices, S.indptr), shape=S.shape)
    T.data[j] += 1e-9 * np.abs(S.data).max()          # 1e4 x the tolerance, one entry
    whole = np.abs(T.data - T.T.tocsr().sorted_indices().data).max() > p.SYM_RTOL * np.abs(T.data).max()
    assert whole
    for _ in range(2):                     # second time: the search starts at the failing block
        assert not p.is_symmetric(T)
    assert p.is_symmetric(S)               # and a symmetric matrix is read whole again
    U = sp.csr_matrix((S.data.copy(), S.indices, S.indptr), shape=S.shape)
    U.data[1] += 1e-9 * np.abs(S.data).max()   # the first row's first off-diagonal entry
    assert U.indices[1] != 0 and not p.is_symmetric(U)     # found after wrapping around
    T.data[j] = np.nan
    assert not p.is_symmetric(T)


@needs_pardiso
@pytest.mark.parametrize("two_level", [True, False])
def test_two_level_factorisation_agrees_with_splu(tangents, two_level, monkeypatch):
    """PARDISO with and without its two-level factorisation (iparm[23] = 10, read because
    iparm[0] = 1) solves the press-slide tangent to round-off, as SuperLU does."""
    monkeypatch.setattr(linear.PardisoSolver, "TWO_LEVEL", two_level)
    A, b = tangents["nonsym"], tangents["b"]
    p = linear.PardisoSolver()
    p.factor(A)
    assert p.iparm[0] == 1 and p.iparm[23] == (10 if two_level else 0)
    ref = SpluSolver()
    ref.factor(A)
    x, x_ref = p.solve(b), ref.solve(b)
    assert _rel_residual(A, x, b) < 1e-10
    assert np.abs(x - x_ref).max() <= 1e-10 * np.abs(x_ref).max()


@pytest.mark.parametrize("solver", ["SPLU", pytest.param("PARDISO", marks=needs_pardiso)])
def test_singular_tangent_is_reported(tangents, solver):
    """A body held at one node only can rotate: its tangent is singular.  SPLU sees a zero
    pivot; PARDISO perturbs the pivot and is caught by the residual of its solve."""
    A = tangents["floating"]
    s = make_solver(solver)
    with pytest.raises(SingularMatrixError):
        s.factor(A)
        s.solve(np.ones(A.shape[0]))


@needs_pardiso
def test_pardiso_empty_row_is_singular():
    A = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 1.0, 3.0]]))
    with pytest.raises(SingularMatrixError):
        linear.PardisoSolver().factor(A)


def test_auto_picks_by_size(tangents, monkeypatch):
    A, b = tangents["nonsym"], tangents["b"]
    auto = make_solver("AUTO")
    monkeypatch.setattr(linear, "AUTO_PARDISO_DOFS", A.shape[0] + 1)
    auto.factor(A)
    assert isinstance(auto.impl, SpluSolver)
    if pardiso_available():
        monkeypatch.setattr(linear, "AUTO_PARDISO_DOFS", A.shape[0] - 1)
        auto.factor(A)
        assert isinstance(auto.impl, linear.PardisoSolver)
        assert _rel_residual(A, auto.solve(b), b) < 1e-10


def test_auto_moves_to_pardiso_after_a_factor_that_outgrew_its_fill(tangents, monkeypatch):
    """Below AUTO_PARDISO_DOFS, AUTO keeps SPLU while its factor stays under AUTO_SPLU_FILL
    entries; once one factor outgrew it, the next factorisations are PARDISO's (when
    installed), with the same solution."""
    A, b = tangents["nonsym"], tangents["b"]
    monkeypatch.setattr(linear, "AUTO_PARDISO_DOFS", A.shape[0] + 1)
    fill = linear.SpluSolver()
    fill.factor(A)
    monkeypatch.setattr(linear, "AUTO_SPLU_FILL", fill.lu.nnz)        # not above: SPLU stays
    auto = make_solver("AUTO")
    for _ in range(2):
        auto.factor(A)
        assert isinstance(auto.impl, SpluSolver) and not auto.outgrown
    monkeypatch.setattr(linear, "AUTO_SPLU_FILL", fill.lu.nnz - 1)
    auto = make_solver("AUTO")
    auto.factor(A)                                   # this factor is SPLU's, and outgrows
    assert isinstance(auto.impl, SpluSolver) and auto.outgrown
    x_splu = auto.solve(b)
    auto.factor(A)
    if pardiso_available():
        assert isinstance(auto.impl, linear.PardisoSolver)
        assert np.abs(auto.solve(b) - x_splu).max() < 1e-10 * np.abs(x_splu).max()
    else:
        assert isinstance(auto.impl, SpluSolver)


def test_large_run_without_pardiso_says_so_once(tangents, monkeypatch, caplog):
    """AUTO above its PARDISO size without PARDISO installed: SPLU, and one warning per process
    with the install command; none below the size."""
    A = tangents["nonsym"]
    monkeypatch.setattr(linear, "pardiso_available", lambda: False)     # as without MKL
    monkeypatch.setattr(linear, "_told_slow", False)
    monkeypatch.setattr(linear, "AUTO_PARDISO_DOFS", A.shape[0])
    with caplog.at_level("WARNING", logger="lagamine_py.solver"):
        make_solver("AUTO").factor(A)                    # not above the size: nothing said
        assert not caplog.records
        monkeypatch.setattr(linear, "AUTO_PARDISO_DOFS", A.shape[0] - 1)
        for _ in range(3):
            auto = make_solver("AUTO")
            auto.factor(A)
            assert isinstance(auto.impl, SpluSolver)
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and "pip install 'lagamine_py[pardiso]'" in said[0], said
    assert f"{A.shape[0]} free DOFs" in said[0]


@needs_pardiso
def test_whole_run_agrees_between_solvers(tmp_path):
    """Press-then-slide-like contact run (coulomb_block.dat) with SPLU and with PARDISO: the
    same increments, and displacements that agree to 1e-10 of their largest value."""
    from lagamine_py.solver import run

    from runner import Capture

    out = {}
    for name in ("SPLU", "PARDISO"):
        model = load_deck(DECKS / "coulomb_block.dat")
        for step in model.steps:
            step.controls["SOLVER"] = name
        cap = Capture()
        outcome = run(model, tmp_path / name, writers=[cap])
        assert outcome.status == 0, outcome.message
        out[name] = cap.results
    a, b = out["SPLU"], out["PARDISO"]
    assert [(r.step, r.increment) for r in a] == [(r.step, r.increment) for r in b]
    scale = max(np.abs(r.u).max() for r in a)
    diff = max(np.abs(ra.u - rb.u).max() for ra, rb in zip(a, b))
    assert diff <= 1e-10 * scale


@needs_pardiso
def test_pardiso_analysis_kept_across_steps_with_the_same_free_dofs(tmp_path, monkeypatch):
    """One solver for the run: a third step with the constraints of the second (a copy of it,
    holding the push) factorises on the analysis of the second.  The run with the third step
    makes one solver object and as many analyses as the run without it."""
    import copy

    from lagamine_py.solver import run, steps

    made = []

    def recording(name):
        made.append(make_solver(name))
        return made[-1]
    monkeypatch.setattr(steps, "make_solver", recording)
    counts = []
    for hold_step in (False, True):
        model = load_deck(DECKS / "coulomb_block.dat")
        if hold_step:
            hold = copy.deepcopy(model.steps[1])
            hold.name = "HOLD"
            model.steps.append(hold)
        for step in model.steps:
            step.controls["SOLVER"] = "PARDISO"
        made.clear()
        outcome = run(model, tmp_path / f"out{hold_step}", writers=[])
        assert outcome.status == 0, outcome.message
        assert len(made) == 1
        counts.append((made[0].analyses, made[0].factorizations))
    assert counts[1][0] == counts[0][0] and counts[1][1] > counts[0][1], counts


@needs_pardiso
def test_pardiso_analysis_kept_across_a_rebuilt_pattern(tangents):
    """A pattern rebuilt from the same element DOFs (what a two-body re-pairing that lands on the
    same windows does, ``Problem.refresh``) gives new index arrays with the same structure: the
    analysis is kept.  Different couplings (a group's DOFs changed): a new analysis.  Within
    one ``FreeDofs`` every ``K_ff`` reads the very same index buffers (no comparison needed)."""
    from lagamine_py.solver.pattern import Pattern

    model = load_deck(DECKS / "press_slide.dat")
    problem = build_problem(model)
    pattern = problem.pattern
    right = 2 * np.flatnonzero(model.coords[:, 0] > 40 - 1e-9)
    free = FreeDofs(pattern, right)
    rng = np.random.default_rng(2)
    data = rng.random(pattern.nnz) + pattern.ndof * (pattern.rows == pattern.indices)
    A = free.kff(data)
    again = free.kff(2.0 * data)
    assert linear._same_buffer(again.indices, A.indices)
    assert linear._same_buffer(again.indptr, A.indptr)
    p = linear.PardisoSolver(symmetric=False)
    p.factor(A)
    rebuilt = Pattern(pattern.ndof, pattern.dofs)
    assert rebuilt.positions[0] is not pattern.positions[0]
    B = FreeDofs(rebuilt, right).kff(data)
    assert B.indices.ctypes.data != A.indices.ctypes.data
    p.factor(B)
    b = np.ones(B.shape[0])
    assert (p.analyses, p.factorizations) == (1, 2)
    assert _rel_residual(B, p.solve(b), b) < 1e-10
    # one element coupled to a node it did not touch: another structure, a new analysis
    dofs = [d.copy() for d in pattern.dofs]
    far = int(np.setdiff1d(np.arange(pattern.ndof // 2), dofs[0][0] // 2)[-1])
    dofs[0][0, :2] = 2 * far, 2 * far + 1
    changed = Pattern(pattern.ndof, dofs)
    C = FreeDofs(changed, right).kff(rng.random(changed.nnz)
                                      + changed.ndof * (changed.rows == changed.indices))
    p.factor(C)
    assert p.analyses == 2


@needs_pardiso
def test_pardiso_analyses_of_a_run_are_its_structure_and_mode_changes(tmp_path, monkeypatch):
    """A whole run (press_slide.dat, two steps with different constraints, contact switching
    the tangent between symmetric and not) analyses exactly when the structure of ``K_ff``
    or the mode changes from one factorisation to the next -- the changes counted here from
    the matrices themselves (their index arrays, and ``|A - A^T|`` over the whole matrix) --
    and never otherwise: every other Newton iteration pays the numerical factorisation only."""
    from lagamine_py.solver import run, steps

    seen = []

    class Recording(linear.PardisoSolver):
        def factor(self, A):
            sym = abs(A - A.T).max() <= self.SYM_RTOL * abs(A).max()
            seen.append((A.indptr.tobytes() + A.indices.tobytes(), bool(sym)))
            super().factor(A)

    made = []

    def recording(name):
        made.append(Recording())
        return made[-1]
    monkeypatch.setattr(steps, "make_solver", recording)
    model = load_deck(DECKS / "press_slide.dat")
    outcome = run(model, tmp_path / "out", writers=[])
    assert outcome.status == 0, outcome.message
    assert len(made) == 1
    changes = sum(1 for k, key in enumerate(seen) if k == 0 or key != seen[k - 1])
    assert made[0].factorizations == len(seen) > 20
    assert made[0].analyses == changes
    assert changes < len(seen) // 4


@needs_pardiso
def test_mkl_is_looked_up_once_per_process(tangents, monkeypatch):
    """MKL's runtime is found and loaded once, however many PARDISO solvers a process makes (a
    run makes one per solver name, a sweep many), and pypardiso -- which searches the file tree
    at import and in every solver object -- is never imported."""
    import ctypes
    import sys

    loads = []
    real = ctypes.CDLL

    def counting(path, *a, **k):
        if "mkl_rt" in str(path):
            loads.append(path)
        return real(path, *a, **k)
    linear._mkl_library.cache_clear()
    monkeypatch.setattr(ctypes, "CDLL", counting)
    A, b = tangents["nonsym"], tangents["b"]
    for _ in range(3):
        p = linear.PardisoSolver()
        p.factor(A)
        assert _rel_residual(A, p.solve(b), b) < 1e-10
    assert len(loads) == 1, loads
    assert "pypardiso" not in sys.modules


def test_openblas_pinned_to_one_thread():
    """Importing the solver limits every loaded OpenBLAS to one thread (the policy of
    lagamine_py/_threads.py), and leaves MKL alone."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    import os
    if "OPENBLAS_NUM_THREADS" in os.environ or "OMP_NUM_THREADS" in os.environ:
        pytest.skip("the user chose the OpenBLAS threads")
    from lagamine_py.core.threads import pin_threads
    pin_threads()
    info = threadpoolctl.threadpool_info()
    openblas = [i for i in info if i["internal_api"] == "openblas"]
    assert openblas and all(i["num_threads"] == 1 for i in openblas)


@needs_pardiso
def test_pardiso_builds_the_upper_triangle_only_for_a_symmetric_matrix(tangents):
    """A non-symmetric factorisation holds no symmetric structure; the first symmetric matrix
    of the same structure builds it: PARDISO then gets exactly the upper triangle (scipy's
    ``triu``, CSR) and solves the matrix."""
    S = tangents["sym"]
    b = tangents["b"][: S.shape[0]]
    off = np.where(S.indices != np.repeat(np.arange(S.shape[0]), np.diff(S.indptr)),
                   np.abs(S.data), 0.0)
    data = S.data.copy()
    data[int(np.argmax(off))] *= 1.5                     # the largest off-diagonal entry
    T = sp.csr_matrix((data, S.indices, S.indptr), shape=S.shape)
    p = linear.PardisoSolver()
    p.factor(T)
    assert p.mtype == 11 and p._sym_structure is None
    p.factor(sp.csr_matrix((S.data, S.indices, S.indptr), shape=S.shape))
    assert p.mtype == -2 and p._sym_structure is not None
    U = sp.triu(S, format="csr")
    U.sort_indices()
    assert np.array_equal(p._ia, U.indptr) and np.array_equal(p._ja, U.indices)
    assert np.array_equal(p._data, U.data)
    assert _rel_residual(S, p.solve(b), b) < 1e-10


def test_splu_reports_an_exactly_singular_matrix_alike_with_the_kept_ordering(tangents):
    """A zero row (its entries kept as explicit zeros): SuperLU stops on an exactly zero pivot
    (RuntimeError), on the kept order as on a fresh one, and the same DOFs are named."""
    A = tangents["nonsym"]
    j = 101
    zero = A.copy()
    zero.data[zero.indptr[j]:zero.indptr[j + 1]] = 0.0
    s = SpluSolver()
    s.factor(A)
    with pytest.raises(SingularMatrixError) as kept:
        s.factor(sp.csr_matrix((zero.data, A.indices, A.indptr), shape=A.shape))
    with pytest.raises(SingularMatrixError) as fresh:
        SpluSolver().factor(zero)
    assert j in kept.value.dofs
    np.testing.assert_array_equal(kept.value.dofs, fresh.value.dofs)
    s.factor(A)                                     # and the kept ordering serves again
    assert s.ordered
    assert _rel_residual(A, s.solve(tangents["b"]), tangents["b"]) < 1e-10


def test_splu_orders_every_factorisation_without_the_file_loaded_superlu(tangents, monkeypatch):
    """Without scipy's SuperLU loaded by file, factors come from the public ``splu``, which
    forces SymmetricMode with a NATURAL ordering: no ordering is kept."""
    A, b = tangents["nonsym"], tangents["b"]
    monkeypatch.setattr(linear, "superlu_module", lambda: None)
    s = SpluSolver()
    for k in range(2):
        s.factor(_with_values(A, k))
        assert s.ordering is None and not s.ordered
        assert _rel_residual(_with_values(A, k), s.solve(b), b) < 1e-10
