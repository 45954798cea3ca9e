"""Newton on one increment, with fake spring groups whose tangent is exact."""
from dataclasses import replace

import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.core.errors import DivergingResidual, GroupFailure, IterationLimit, NotANumber
from lagamine_py.solver.linear import FreeDofs, SingularMatrixError, SpluSolver
from lagamine_py.solver.newton import IterationObserver, Settings, solve_increment

from test_solver_fakes import GROUND, Atan, Failing, PlasticSprings, Springs, make_model, make_problem


def setup(groups, nnodes, constrained, **kw):
    model = make_model(nnodes, [])
    problem = make_problem(model, groups)
    free = FreeDofs(problem.pattern, np.asarray(constrained, np.int64))
    return problem, free


def cubic_chain():
    """x DOFs 0, 2, 4 of nodes 0..2 on a chain of cubic springs from the ground;
    y DOFs carry linear springs to the ground (kept out of the way)."""
    return [Springs([[GROUND, 0], [0, 2], [2, 4]], [1.0, 2.0, 1.5], a=2.0),
            Springs([[GROUND, 1], [GROUND, 3], [GROUND, 5]], 1.0)]


def test_quadratic_convergence_and_exact_solution():
    problem, free = setup(cubic_chain(), 3, [])
    F = 3.0
    f_ext = np.zeros(6)
    f_ext[4] = F
    conv = solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                           StepContext(), np.zeros(0), f_ext, Settings(rtol=1e-13))
    # every spring of the chain carries F: k (d + a d^3) = F, solved independently
    for k in (1.0, 2.0, 1.5):
        roots = np.roots([2.0 * k, 0.0, k, -F])
        d = roots[np.abs(roots.imag) < 1e-12].real[0]
        assert k * (d + 2 * d**3) == pytest.approx(F)
    u = conv.u
    d = np.array([u[0], u[2] - u[0], u[4] - u[2]])
    assert np.allclose(np.array([1.0, 2.0, 1.5]) * (d + 2 * d**3), F, rtol=1e-12)
    r = np.array(conv.history)
    # the last steps, once in the basin: log r_{k+1} / log r_k -> 2
    tail = r[r < 1e-2]
    assert len(tail) >= 3
    ratios = np.log(tail[1:]) / np.log(tail[:-1])
    assert ratios[-2] == pytest.approx(2.0, abs=0.35)


def test_linear_problem_converges_in_one_iteration_with_imposed_displacement():
    groups = [Springs([[0, 2], [2, 4]], [1.0, 3.0]), Springs([[GROUND, 1], [GROUND, 3], [GROUND, 5]], 1.0)]
    problem, free = setup(groups, 3, [0, 4])
    u_c = np.array([0.0, 1.0])
    conv = solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                           StepContext(), u_c, np.zeros(6), Settings())
    # springs in series 1 and 3: u2 = k2 / (k1 + k2) * 1
    assert conv.u[2] == pytest.approx(0.75, rel=1e-14)
    assert conv.iterations == 1
    # reaction at DOF 4: series stiffness 0.75
    assert (conv.f_int)[4] == pytest.approx(0.75, rel=1e-13)


def test_iteration_limit():
    problem, free = setup(cubic_chain(), 3, [])
    f_ext = np.zeros(6)
    f_ext[4] = 50.0
    with pytest.raises(IterationLimit) as err:
        solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                        StepContext(), np.zeros(0), f_ext, Settings(maxit=3))
    assert len(err.value.history) == 4


def test_group_failure_and_nan_are_typed():
    base = cubic_chain()
    failing = Failing(base[0], lambda ctx, u: "negative Jacobian in element 7")
    problem, free = setup([failing, base[1]], 3, [])
    f_ext = np.zeros(6)
    f_ext[4] = 1.0
    with pytest.raises(GroupFailure, match="negative Jacobian in element 7"):
        solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                        StepContext(), np.zeros(0), f_ext, Settings())
    f_ext[4] = np.nan
    problem, free = setup(cubic_chain(), 3, [])
    with pytest.raises(NotANumber):
        solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                        StepContext(), np.zeros(0), f_ext, Settings())


def test_singular_tangent_names_global_dofs():
    """y DOFs of node 1 and 2 have no spring: the message names them (global numbering)."""
    groups = [Springs([[GROUND, 0], [0, 2], [2, 4]], 1.0), Springs([[GROUND, 1]], 1.0)]
    problem, free = setup(groups, 3, [])
    f_ext = np.zeros(6)
    f_ext[4] = 1.0
    with pytest.raises(SingularMatrixError) as err:
        solve_increment(problem, SpluSolver(), free, np.zeros(6), problem.init_states(),
                        StepContext(), np.zeros(0), f_ext, Settings())
    assert set(err.value.dofs) == {3, 5}
    assert "node 20 y" in err.value.describe(np.array([10, 20, 30]))


def atan_problem():
    groups = [Atan([[GROUND, 0]], 1.0), Springs([[GROUND, 1]], 1.0)]
    return setup(groups, 1, [])


def test_line_search_rescues_a_diverging_newton():
    """atan(u) = 0.5 from u = 3: plain Newton overshoots further and further (a typed failure);
    with the backtracking line search it converges to u = tan(0.5)."""
    problem, free = atan_problem()
    u0 = np.array([3.0, 0.0])
    f_ext = np.array([0.5, 0.0])
    with pytest.raises((DivergingResidual, IterationLimit, NotANumber, SingularMatrixError)):
        solve_increment(problem, SpluSolver(), free, u0, problem.init_states(), StepContext(),
                        np.zeros(0), f_ext, Settings(maxit=10))
    conv = solve_increment(problem, SpluSolver(), free, u0, problem.init_states(), StepContext(),
                           np.zeros(0), f_ext, Settings(maxit=30, linesearch=True))
    assert conv.u[0] == pytest.approx(np.tan(0.5), rel=1e-10)


def test_trial_state_not_committed_and_returned():
    """The committed state passed in is never modified; the converged trial state is returned."""
    groups = [PlasticSprings([[GROUND, 0]], 10.0, fy=1.0, H=5.0), Springs([[GROUND, 1]], 1.0)]
    problem, free = setup(groups, 1, [0])
    states = problem.init_states()
    conv = solve_increment(problem, SpluSolver(), free, np.zeros(2), states, StepContext(),
                           np.array([0.4]), np.zeros(2), Settings())
    assert np.all(states[0]["dp"] == 0.0)
    # plastic elongation: d - f/k with f = fy + H k/(k+H) (d - fy/k)
    f = 1.0 + 10 * 5 / 15 * (0.4 - 0.1)
    assert conv.states[0]["dp"][0] == pytest.approx(0.4 - f / 10.0, rel=1e-12)


def test_flip_flopping_contact_points_are_frozen():
    """A point whose status switched FLIPFLOP times is held (ctx.freeze_contact[name]); the
    others stay free (-1); solid groups are not watched."""
    from lagamine_py.solver.stabilisation import FlipFlop
    ff = FlipFlop({1: "BOTTOM->FLAT"}, limit=3)
    ctx = StepContext()
    seen = []
    for it in range(5):
        st = np.array([it % 2, 1], np.int8)           # point 0 chatters, point 1 sticks
        contact = {"status": st, "p": np.ones(2), "tau": np.zeros(2)}
        out = ff.context(ctx, [{"status": np.array([it % 2])}, contact])
        seen.append(out.freeze_contact)
    assert seen[:3] == [None, None, None]             # 0, 1, 2 switches
    assert set(seen[3]) == {"BOTTOM->FLAT"}
    assert seen[3]["BOTTOM->FLAT"].tolist() == [1, -1]
    assert seen[4]["BOTTOM->FLAT"].tolist() == [1, -1]   # frozen at the status it had
    assert ctx.freeze_contact is None                 # the caller's context is not modified


class WrongTangent(Springs):
    def compute(self, u_new, u_old, state, ctx, tangent=True):
        res = super().compute(u_new, u_old, state, ctx, tangent)
        if res.K is not None:
            res.K = res.K * 1.01
        return res


def test_check_tangent_tool():
    rng = np.random.default_rng(5)
    u = rng.normal(size=6) * 0.3
    problem, _ = setup(cubic_chain(), 3, [])
    assert problem.check_tangent(u, u, problem.init_states(), StepContext()) < 1e-7
    problem, _ = setup([WrongTangent([[GROUND, 0], [0, 2]], 1.0, a=1.0)] + cubic_chain()[1:], 3, [])
    assert problem.check_tangent(u, u, problem.init_states(), StepContext()) > 1e-3


class HeldSprings(Springs):
    """Springs ten times stiffer while a context holds values (``ctx.freeze_contact`` set)."""

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        res = super().compute(u_new, u_old, state, ctx, tangent)
        if ctx.freeze_contact is not None:
            res.f = res.f * 10.0
            res.K = None if res.K is None else res.K * 10.0
        return res


class HoldUntilReviewed(IterationObserver):
    """Holds from the first solve on; the review with the free law then fails (the held
    springs are stiffer), and :meth:`settle` releases."""

    def __init__(self):
        self.holding = True
        self.settled = 0

    @property
    def active(self):
        return self.holding

    def context(self, ctx, states):
        return replace(ctx, freeze_contact={"held": np.zeros(1, np.int8)}) if self.holding else ctx

    def settle(self, ctx, states):
        self.holding = False
        self.settled += 1
        return ctx


def test_a_failed_review_is_not_an_iteration():
    """The iterations of an increment are its linear solves: the pass that re-evaluates the
    iterate with the settled context after a failed review solves nothing.  Linear springs,
    so each context converges in one solve: free (start), held (u = F/10k, reviewed and
    rejected), free again (u = F/k): three solves, three factorisations, four passes."""
    problem, free = setup([HeldSprings([[GROUND, 0], [GROUND, 1]], 2.0)], 1, [])
    f_ext = np.array([3.0, 1.0])
    watch = HoldUntilReviewed()
    conv = solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                           StepContext(), np.zeros(0), f_ext, Settings(), observers=(watch,))
    assert watch.settled == 1
    assert conv.u == pytest.approx(f_ext / 2.0, rel=1e-14)
    assert conv.factorisations == 3
    assert conv.iterations == 3


def test_a_failed_attempt_reports_its_solves():
    """An attempt stopped by MAXIT after a failed review: two solves (free, held), a review
    pass, and the pass that stops it; the failure carries the solves, not the passes."""
    problem, free = setup([HeldSprings([[GROUND, 0], [GROUND, 1]], 2.0)], 1, [])
    with pytest.raises(IterationLimit) as err:
        solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                        StepContext(), np.zeros(0), np.array([3.0, 1.0]), Settings(maxit=3),
                        observers=(HoldUntilReviewed(),))
    assert err.value.solves == 2
    assert len(err.value.history) == 4


def test_singular_tangent_with_imposed_dofs_keeps_the_whole_tangent_for_the_diagnosis():
    """Newton releases the full tangent before the factorisation and rebuilds it for the
    singular diagnosis from K_ff and the entries of constrained rows/columns: the error's
    ``matrix`` is bit for bit the evaluation's data (computed here independently), and the DOFs
    named are the unrestrained ones (node 1 y, node 2 y), in global numbering."""
    groups = [Springs([[GROUND, 0], [0, 2], [2, 4]], [1.0, 2.0, 3.0], a=0.5),
              Springs([[GROUND, 1]], 1.0)]
    problem, free = setup(groups, 3, [0])
    assert free.not_ff.size > 0                          # the rest is not empty
    u0 = np.zeros(6)
    u_c = np.array([0.1])
    with pytest.raises(SingularMatrixError) as err:
        solve_increment(problem, SpluSolver(), free, u0, problem.init_states(),
                        StepContext(), u_c, np.zeros(6), Settings())
    assert set(err.value.dofs) == {3, 5}
    expected = problem.evaluate(u0, u0, problem.init_states(), StepContext(), True).data
    assert err.value.matrix.dtype == expected.dtype
    assert np.array_equal(err.value.matrix, expected)
    assert err.value.matrix.tobytes() == expected.tobytes()


def test_free_dofs_rest_and_join_give_back_the_data_bit_for_bit():
    groups = [Springs([[GROUND, 0], [0, 2], [2, 4], [1, 3]], 1.0), Springs([[GROUND, 1]], 1.0)]
    problem, free = setup(groups, 3, [0, 3])
    rng = np.random.default_rng(3)
    data = rng.standard_normal(problem.pattern.nnz) * 10.0 ** rng.integers(-300, 300, problem.pattern.nnz)
    A = free.kff(data)
    rest = free.rest(data)
    assert A.data.size + rest.size == data.size
    assert free.join(A.data, rest).tobytes() == data.tobytes()


class _LifetimeSolver(SpluSolver):
    """SPLU that records, at each factorisation, whether an evaluation's full tangent is
    still alive (weak references to every ``data`` the problem handed out)."""

    def __init__(self, refs):
        super().__init__()
        self.refs = refs
        self.alive_at_factor = []

    def factor(self, A):
        # the evaluation whose array K_ff's values were moved into (kff(in_place=True)) is
        # K_ff itself: not counted
        self.alive_at_factor.append(sum(r() is not None and not np.shares_memory(r(), A.data)
                                        for r in self.refs))
        super().factor(A)


def test_the_full_tangent_is_not_alive_through_the_factorisation():
    import weakref
    problem, free = setup(cubic_chain(), 3, [0])
    refs = []
    evaluate = problem.evaluate

    def spy(*args, **kw):
        ev = evaluate(*args, **kw)
        if ev.data is not None:
            refs.append(weakref.ref(ev.data))
        return ev

    problem.evaluate = spy
    f_ext = np.zeros(6)
    f_ext[4] = 3.0
    solver = _LifetimeSolver(refs)
    conv = solve_increment(problem, solver, free, np.zeros(6), problem.init_states(),
                           StepContext(), np.array([0.2]), f_ext, Settings(rtol=1e-12))
    assert conv.iterations >= 3 and len(solver.alive_at_factor) == conv.iterations
    assert solver.alive_at_factor == [0] * conv.iterations


def test_all_finite_is_the_entrywise_test():
    """Newton's non-finite tests (the tangent's data, the correction) read a dot product first:
    the same verdict as ``np.all(np.isfinite(a))`` for every case, an overflowing dot of finite
    entries (settled entry-wise) and an infinity whose partner is zero included."""
    from lagamine_py.solver.newton import _all_finite
    rng = np.random.default_rng(3)
    base = rng.standard_normal(1000)
    cases = {"finite": base, "empty": np.zeros(0), "zeros": np.zeros(7)}
    for name, bad in (("nan", np.nan), ("inf", np.inf), ("-inf", -np.inf),
                      ("huge", 1e200), ("max", np.finfo(float).max)):
        a = base.copy()
        a[17] = bad
        cases[name] = a
    cases["inf and -inf"] = np.array([np.inf, -np.inf, 1.0])
    for name, a in cases.items():
        assert _all_finite(a) is bool(np.all(np.isfinite(a))), name
    # with a given product: an infinity against a zero still makes it non-finite (NaN)
    other = np.ones(1000)
    other[17] = 0.0
    for name in ("finite", "nan", "inf", "-inf", "huge", "max"):
        a = cases[name]
        with np.errstate(all="ignore"):
            dot = abs(float(a @ other))
        assert _all_finite(a, dot) is bool(np.all(np.isfinite(a))), name
