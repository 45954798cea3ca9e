"""What a run does not hold while it factorises (issue 17 item 5): arrays that the
factorisation does not need are released before it, checked by weak references on whole runs
of the main job and on the solver objects themselves.  Each test fails when the array it names
is kept (the mutations of docs/performance.md, "Memory, branch `memory3`")."""
from __future__ import annotations

import weakref
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from lagamine_py.deck import load_deck
from lagamine_py.solver import linear, run
from lagamine_py.solver import steps as steps_mod
from lagamine_py.solver.pattern import Pattern

DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"


def _solid_arrays(problem, states):
    """The arrays of the solid groups' states (each evaluation makes new ones)."""
    return [a for kind, st in zip(problem.kinds, states) if kind == "solid"
            for a in st.values() if isinstance(a, np.ndarray)]


@pytest.mark.parametrize("energy", [False, True])
def test_states_two_commits_old_are_not_alive_at_a_factorisation(tmp_path, monkeypatch, energy):
    """The committed states a commit replaces are released by the next increment's
    factorisations: the controller keeps the previous states only from the commit to the
    hand-out that reads them (the energy balance), and not at all without it."""
    text = DECK.read_text()
    if energy:
        text = text.replace("*END STEP", "*OUTPUT, WRITERS=CONTACT/ENERGY\n*END STEP")
    deck = tmp_path / "deck.dat"
    deck.write_text(text)
    model = load_deck(deck)
    assert steps_mod.tracks_energy(model) == energy
    replaced = []            # weak refs to the solid arrays of states replaced by a commit
    alive = []               # at each factorisation: how many of them are alive
    commit = steps_mod.Controller._commit

    def spy_commit(self, conv, loads, free):
        if self.total_increments > 0:          # the initial states: not a commit's
            replaced.extend(weakref.ref(a) for a in _solid_arrays(self.problem, self.states))
        commit(self, conv, loads, free)

    factor = linear.SpluSolver.factor

    def spy_factor(self, A):
        alive.append(sum(r() is not None for r in replaced))
        factor(self, A)

    monkeypatch.setattr(steps_mod.Controller, "_commit", spy_commit)
    monkeypatch.setattr(linear.SpluSolver, "factor", spy_factor)
    outcome = run(model, tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert len(replaced) >= 3 * 10 and len(alive) >= 20     # ten commits and more
    assert alive == [0] * len(alive)


def test_the_last_increments_start_arrays_are_released_before_the_next_are_made(monkeypatch):
    """``SolidElement._kernel_start`` drops its cached start arrays before the kernel makes the
    next increment's: never two sets alive (33 MB each at 51k Q8)."""
    from lagamine_py import kernels
    from lagamine_py.elements.quad import Q8PlaneStrain as Q8PE
    from test_kernel_twins import kernel_laws, solid_setup

    nk = kernels.module("solid")
    if nk is None:
        pytest.skip("numba is not installed: no kernel start arrays")
    group, state, _, u_old = solid_setup(Q8PE, kernel_laws()["ELASTIC"])
    u_old = np.ascontiguousarray(u_old, float)
    eps_e = np.ascontiguousarray(state["eps_e"], float)
    refs, alive = [], []
    start_group = nk.start_group

    def spy(*args):
        alive.append(sum(r() is not None for r in refs))
        return start_group(*args)

    monkeypatch.setattr(nk, "start_group", spy)
    for k in range(3):
        old, bad = group._kernel_start(u_old + 1e-3 * k, eps_e)
        refs += [weakref.ref(old), weakref.ref(bad)]
        del old, bad
    assert alive == [0, 0, 0]


@pytest.mark.parametrize("block", [7, 64, 1 << 16])
@pytest.mark.parametrize("constrained", [[], [0], [59], [0, 1, 7, 30, 59], list(range(20, 40))])
def test_kff_in_place_is_the_gather_bit_for_bit(monkeypatch, block, constrained):
    """``kff(data, in_place=True)``: K_ff's values in the head of ``data`` are ``data[ff]``
    (the gather into a new array) bit for bit, with blocks smaller than, about and larger
    than the pattern, and constrained DOFs first, last, scattered, in a run or none; the
    entries left out are what :meth:`FreeDofs.rest` took before, and ``join`` gives the
    full data back."""
    monkeypatch.setattr(linear.FreeDofs, "COMPACT_BLOCK", block)
    rng = np.random.default_rng(len(constrained) + block)
    pat = Pattern(60, [rng.choice(60, size=(25, 6), replace=True)])
    free = linear.FreeDofs(pat, np.array(constrained, int))
    data = rng.standard_normal(pat.nnz) * 10.0 ** rng.integers(-300, 300, pat.nnz)
    ref = free.kff(data.copy())
    rest = free.rest(data)
    original = data.copy()
    A = free.kff(data, in_place=True)
    if A.data.size > data.size // 2:       # (scipy copies a view of less than half its base)
        assert np.shares_memory(A.data, data) and A.data.ctypes.data == data.ctypes.data
    assert A.data.tobytes() == ref.data.tobytes()
    assert np.shares_memory(A.indices, free.ff_indices)
    assert np.shares_memory(A.indptr, free.ff_indptr)
    assert free.join(A.data, rest).tobytes() == original.tobytes()


def test_kff_in_place_allocates_no_array_of_the_tangents_size(monkeypatch):
    """The in-place gather's temporaries are a block's, not K_ff's (traced allocations)."""
    import tracemalloc
    monkeypatch.setattr(linear.FreeDofs, "COMPACT_BLOCK", 4096)
    rng = np.random.default_rng(5)
    n = 6000
    pat = Pattern(n, [rng.choice(n, size=(4000, 16), replace=True)])
    free = linear.FreeDofs(pat, np.arange(0, n, 97))
    data = rng.standard_normal(pat.nnz)
    size = free.ff_indices.size * 8
    assert size > 20 * free.COMPACT_BLOCK * 8
    for in_place, low, high in ((False, size, 10 * size), (True, 0, size / 10)):
        copy = data.copy()
        tracemalloc.start()
        A = free.kff(copy, in_place=in_place)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert low <= peak <= high, (in_place, peak, size)
        del A


def test_newton_factorises_k_ff_in_the_evaluations_own_array(tmp_path, monkeypatch):
    """In a whole run every K_ff factorised is the head of an evaluation's tangent array (the
    in-place gather), and no other evaluation's tangent is alive then."""
    from lagamine_py.solver import problem as problem_mod
    refs, seen = [], []
    evaluate = problem_mod.Problem.evaluate

    def spy_evaluate(self, *a, **k):
        ev = evaluate(self, *a, **k)
        if ev.data is not None:
            refs.append(weakref.ref(ev.data))
        return ev

    factor = linear.SpluSolver.factor

    def spy_factor(self, A):
        alive = [r() for r in refs if r() is not None]
        seen.append((len(alive), sum(np.shares_memory(a, A.data) for a in alive)))
        factor(self, A)

    monkeypatch.setattr(problem_mod.Problem, "evaluate", spy_evaluate)
    monkeypatch.setattr(linear.SpluSolver, "factor", spy_factor)
    outcome = run(load_deck(DECK), tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert len(seen) >= 20 and seen == [(1, 1)] * len(seen)


def _transpose_permutation(A):
    """Reference: the position of each entry's transpose, from scipy's transpose of the entry
    numbers (what PARDISO's symmetry test held as int32 before)."""
    T = sp.csr_matrix((np.arange(A.nnz, dtype=float), A.indices, A.indptr), shape=A.shape)
    T = T.T.tocsr()
    T.sort_indices()
    return T.data.astype(np.int64)


@pytest.mark.parametrize("element_dofs, offset_type", [(6, np.uint8), (300, np.uint16)])
def test_pardiso_symmetry_test_keeps_one_byte_offsets_not_the_permutation(element_dofs,
                                                                           offset_type):
    """The symmetry test's map to transposed entries is an offset in the partner row, one byte
    an entry while rows are at most 256 long (two beyond), and it gives the transpose
    permutation exactly (scipy's, by the entry numbers)."""
    rng = np.random.default_rng(element_dofs)
    n = 400
    pat = Pattern(n, [np.array([rng.choice(n, element_dofs, replace=False) for _ in range(60)])])
    A = pat.matrix(rng.standard_normal(pat.nnz))
    offsets = linear._transpose_offsets(A)
    assert offsets.dtype == offset_type and offsets.nbytes == A.nnz * np.dtype(offset_type).itemsize
    perm = A.indptr[A.indices].astype(np.int64) + offsets
    np.testing.assert_array_equal(perm, _transpose_permutation(A))
    assert np.diff(A.indptr).max() > 256 or offset_type is np.uint8
    nonsym = sp.csr_matrix((np.ones(3), [1, 2, 0], [0, 2, 2, 3]), shape=(3, 3))
    assert linear._transpose_offsets(nonsym) is None          # (0,1) has no (1,0)


needs_pardiso = pytest.mark.skipif(not linear.pardiso_available(),
                                   reason="MKL PARDISO cannot be loaded (optional extra 'pardiso')")


def _nonsym(n=300, seed=0):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.02, random_state=rng, format="csr")
    A = (A + A.T + sp.diags(4.0 + rng.random(n))).tocsr()       # structurally symmetric
    A.sort_indices()
    A.data += 0.1 * rng.standard_normal(A.nnz)                    # values not
    return A


def _same_structure(A, seed):
    rng = np.random.default_rng(seed)
    return sp.csr_matrix((A.data * (1.0 + 0.05 * rng.standard_normal(A.nnz)), A.indices,
                          A.indptr), shape=A.shape)


@needs_pardiso
@pytest.mark.parametrize("symmetric", [False, True])
def test_pardiso_lets_the_factorised_matrix_go_and_solves_the_same(symmetric):
    """``hold_matrix(None)`` after a solve: the factorised K_ff is no longer held (weak
    reference), and the solves on the factor that follow, with another matrix of the structure
    handed (``hold_matrix(A2)``), give bit for bit the solutions of a solver that kept it --
    PARDISO reads its factor only: even NaN values in place of the matrix change nothing."""
    A1 = _nonsym()
    if symmetric:
        A1 = ((A1 + A1.T) * 0.5).tocsr()
        A1.sort_indices()
    A2 = _same_structure(A1, 1)
    b = np.random.default_rng(2).standard_normal(A1.shape[0])
    kept = linear.PardisoSolver()
    kept.factor(A1.copy())
    p = linear.PardisoSolver()
    p.factor(A1)
    assert p.mtype == (-2 if symmetric else 11) and p.iparm[13] == 0
    first = p.solve(b)
    assert first.tobytes() == kept.solve(b).tobytes()
    ref = weakref.ref(A1.data)
    p.hold_matrix(None)
    del A1
    assert ref() is None                               # nothing holds the factorised K_ff
    p.hold_matrix(A2)
    for seed in (3, 4):
        c = np.random.default_rng(seed).standard_normal(A2.shape[0])
        assert p.solve(c).tobytes() == kept.solve(c).tobytes()
    if not symmetric:
        p._data = np.full_like(p._data, np.nan)          # not read: the same solution
        assert p.solve(b).tobytes() == first.tobytes()
    p.hold_matrix(None)
    with pytest.raises(RuntimeError) if not symmetric else _nothing():
        p.solve(b)                                     # no matrix handed: said, not guessed


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@needs_pardiso
def test_pardiso_keeps_the_matrix_of_a_factor_with_perturbed_pivots():
    """A factorisation that perturbed pivots (a singular matrix: a free-free chain of springs)
    keeps its matrix: its solves refine against it and its residual guard needs it."""
    n = 40
    L = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tolil()
    L[0, 0] = L[n - 1, n - 1] = 1.0
    L = L.tocsr()
    for p in (linear.PardisoSolver(), linear.PardisoSolver(symmetric=False)):
        p.factor(L)
        assert p.iparm[13] > 0
        p.hold_matrix(None)
        assert p._A is L and p._data is not None
        with pytest.raises(linear.SingularMatrixError):
            p.solve(np.ones(n))                        # the guard, against the matrix kept


def _alive_at_evaluations(monkeypatch, refs: list) -> list[int]:
    """``Problem.evaluate`` patched to record, at each call, how many of the weak references
    ``refs`` (filled by the caller's own spies) are alive; returns that record."""
    from lagamine_py.solver import problem as problem_mod
    alive, evaluate = [], problem_mod.Problem.evaluate

    def spy_evaluate(self, *args, **kw):
        alive.append(sum(r() is not None for r in refs))
        return evaluate(self, *args, **kw)

    monkeypatch.setattr(problem_mod.Problem, "evaluate", spy_evaluate)
    return alive


def _pardiso_run(tmp_path, name, monkeypatch, hold=True):
    """The main job on PARDISO with the factor reused (KRYLOVDOFS=0: its 866 DOFs are below
    the default's 5 000); ``hold=False``: the solver keeps its matrix (``hold_matrix`` does
    nothing), as before.  Returns (u at the end, contact totals, factorisations, alive) with
    ``alive`` the factorised K_ff still held at each evaluation that follows a solve."""
    from lagamine_py.results import RunResults
    text = DECK.read_text()
    for kw in ("*DLOAD", "*BOUNDARY"):
        text = text.replace(kw, f"*CONTROLS\nSOLVER=PARDISO, KRYLOVDOFS=0\n{kw}")
    deck = tmp_path / f"{name}.dat"
    deck.write_text(text)
    factored, factor = [], linear.PardisoSolver.factor

    def spy_factor(self, A):
        factored.append(weakref.ref(A.data if A.data.base is None else A.data.base))
        factor(self, A)

    monkeypatch.setattr(linear.PardisoSolver, "factor", spy_factor)
    alive = _alive_at_evaluations(monkeypatch, factored)
    if not hold:
        monkeypatch.setattr(linear.PardisoSolver, "hold_matrix", lambda self, A: None)
    outcome = run(load_deck(deck), tmp_path / name)
    monkeypatch.undo()
    assert outcome.status == 0, outcome.message
    res = RunResults(tmp_path / name)
    u = np.loadtxt(tmp_path / name / "displacements.csv", delimiter=",", skiprows=1)
    return u, res.table("contact_totals.csv"), len(factored), alive


@needs_pardiso
def test_a_run_that_lets_the_matrix_go_is_the_run_that_keeps_it(tmp_path, monkeypatch):
    """The main job on PARDISO with GMRES on the old factor: letting the factorised K_ff go
    after each solve gives the same factorisations and bit for bit the same displacements and
    contact totals as keeping it; no factorised K_ff is alive at any evaluation (one was, the
    solver's, at every evaluation after the first solve)."""
    u1, t1, f1, alive1 = _pardiso_run(tmp_path, "let_go", monkeypatch)
    u0, t0, f0, alive0 = _pardiso_run(tmp_path, "kept", monkeypatch, hold=False)
    assert f1 == f0 and f1 >= 5
    assert u1.tobytes() == u0.tobytes()
    for col in ("P", "T"):
        assert np.asarray(t1[col]).tobytes() == np.asarray(t0[col]).tobytes()
    assert max(alive1) == 0
    assert max(alive0) == 1


@pytest.mark.parametrize("rtol", [1e-8, 1e-300])
def test_newton_holds_no_earlier_evaluation_while_it_evaluates(rtol):
    """At every evaluation Newton asks for -- the iterations, the energy-converged one, and the
    review of held values with the free law (evaluated twice when it fails) -- no evaluation
    it received earlier is alive: their tangents (77 MB) and states (33 MB at 309k DOFs) were
    alive beside the next one in the review (``rtol`` 1e-300: converged in energy)."""
    from lagamine_py.elements.base import StepContext
    from lagamine_py.solver.linear import SpluSolver
    from lagamine_py.solver.newton import Settings, solve_increment
    from test_solver_fakes import GROUND
    from test_solver_newton import HeldSprings, HoldUntilReviewed, setup

    problem, free = setup([HeldSprings([[GROUND, 0], [GROUND, 1]], 2.0)], 1, [])
    refs, alive = [], []
    evaluate = problem.evaluate

    def spy(*args, **kw):
        alive.append(sum(r() is not None for r in refs))
        ev = evaluate(*args, **kw)
        refs.append(weakref.ref(ev))
        return ev

    problem.evaluate = spy
    watch = HoldUntilReviewed()
    f_ext = np.array([3.0, 1.0])
    conv = solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                           StepContext(), np.zeros(0), f_ext, Settings(rtol=rtol),
                           observers=(watch,))
    assert watch.settled == 1 and conv.u == pytest.approx(f_ext / 2.0, rel=1e-14)
    assert len(alive) >= 5 and alive == [0] * len(alive)


def test_no_increment_result_is_alive_at_the_next_increments_evaluations(tmp_path, monkeypatch):
    """The results handed to the writers are let go after the hand-out: the displacements
    table keeps of a step's latest increment only what it writes (step, increment, time,
    coordinates, displacements), not the whole result, whose cells (strains, stresses) and
    contact points were alive through every evaluation and factorisation of the next increment
    (memory4).  The table written is unchanged (tests/test_regression.py compares it)."""
    from lagamine_py.output import nodal
    model = load_deck(DECK)
    refs, increment = [], nodal.DisplacementsWriter.increment

    def spy_increment(self, result):
        refs.append(weakref.ref(result))
        increment(self, result)

    monkeypatch.setattr(nodal.DisplacementsWriter, "increment", spy_increment)
    alive = _alive_at_evaluations(monkeypatch, refs)
    outcome = run(model, tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert len(refs) >= 10 and len(alive) >= 20
    assert alive == [0] * len(alive)
    rows = (tmp_path / "out" / "displacements.csv").read_text().splitlines()
    assert len(rows) == 1 + len(model.steps) * len(model.coords)
