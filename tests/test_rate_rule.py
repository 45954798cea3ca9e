"""The iteration limit's rate rule (:data:`lagamine_py.solver.newton.RATE_GRACE`): at MAXIT an
attempt goes on only while its residual, falling without contact states switching, reaches
RTOL within the iterations left past MAXIT by Newton's quadratic model.

Newton on ``k atan(d) = F`` (k = 1, F = 1.45, from d = 0) needs 8 solves, its residual
1, 0.33, 0.14, 5.4e-2, 1.5e-2, 2.0e-3, 4.7e-5, 2.6e-8, 8e-15 (measured, converging as the
model says once in the basin): the sequence the tests cut with MAXIT."""
from dataclasses import replace

import numpy as np
import pytest

from lagamine_py.core.errors import IterationLimit
from lagamine_py.elements.base import GroupResult, StepContext
from lagamine_py.solver import newton
from lagamine_py.solver.linear import SpluSolver
from lagamine_py.solver.newton import IterationObserver, Settings, solve_increment
from lagamine_py.solver.stabilisation import FlipFlop

from test_solver_fakes import GROUND, Atan, Springs
from test_solver_newton import setup


class Switching(IterationObserver):
    """An observer whose states always switch."""

    def switching(self, states) -> bool:
        return True


def _atan(maxit, observers=()):
    problem, free = setup([Atan([[GROUND, 0]], 1.0), Springs([[GROUND, 1]], 1.0)], 1, [])
    return solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                           StepContext(), np.zeros(0), np.array([1.45, 0.0]),
                           Settings(maxit=maxit), observers=observers)


def test_the_model_counts_the_solves_to_go():
    """r_k+1 = r_k^3 / r_k-1^2: from 1e-1, 1e-2 the model gives 1e-4, then 1e-8."""
    assert newton._solves_to_go([1e-1, 1e-2], 1e-7, 3) == 2
    assert newton._solves_to_go([1e-1, 1e-2], 1e-7, 1) is None
    assert newton._solves_to_go([1e-1, 1e-2], 1e-9, 3) == 3
    assert newton._solves_to_go([1e-1, 1e-2], 1e-3, 3) == 1
    assert newton._solves_to_go([1e-2, 1e-1], 1e-8, 3) is None          # growing
    assert newton._solves_to_go([1e-2, 1e-2], 1e-8, 3) is None          # stalled
    assert newton._solves_to_go([1e-2], 1e-8, 3) is None


def test_an_attempt_converging_at_maxit_is_finished():
    """MAXIT = 6 stops the sequence at 4.7e-5, two solves from RTOL by the model: it goes on
    and converges in 8, where without the grace it is cut back."""
    assert newton.RATE_GRACE >= 2
    conv = _atan(6)
    assert conv.iterations == 8 and conv.residual <= 1e-8
    free_run = _atan(40)
    assert conv.u.tolist() == free_run.u.tolist()          # the same iterates, bit for bit
    assert np.tan(1.45) == pytest.approx(conv.u[0], rel=1e-12)


def test_without_the_grace_maxit_stops_it(monkeypatch):
    monkeypatch.setattr(newton, "RATE_GRACE", 0)
    with pytest.raises(IterationLimit) as err:
        _atan(6)
    assert len(err.value.history) == 7 and err.value.solves == 6


def test_a_slow_rate_is_stopped_once_the_model_needs_more_than_the_room():
    """MAXIT = 4 (1.5e-2 after 5.4e-2): three solves to go, granted at 4; at 5 (2.0e-3 after
    1.5e-2) the model needs 3 again with 2 left: stopped there, not at 4 + RATE_GRACE."""
    assert newton.RATE_GRACE == 3
    with pytest.raises(IterationLimit) as err:
        _atan(4)
    assert len(err.value.history) == 6 and err.value.solves == 5
    assert "no convergence in 5 iterations (5 linear solves, |R|/F = " in str(err.value)


def test_no_grace_while_states_switch():
    """An iteration across which contact states switched is a search for states, not an
    equilibrium iteration whose rate means anything: MAXIT stops it as before."""
    with pytest.raises(IterationLimit) as err:
        _atan(6, (Switching(),))
    assert len(err.value.history) == 7


# ------------------------------------------------- a release restarts the count (FlipFlop)


class HeldLinear(Atan):
    """k atan(d), or the linear spring k d while a context holds values: the held law
    converges in one solve, where the free law disagrees."""

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        if ctx.freeze_contact is None:
            return super().compute(u_new, u_old, state, ctx, tangent)
        d = self.elongation(u_new)
        f, K = self.blocks(self.k * d, self.k + 0.0 * d)
        return GroupResult(f, K if tangent else None, {})


class HoldThenRestart(IterationObserver):
    """Holds from the first evaluation; its first settle drops the hold and restarts the free
    law with ``grant`` iterations."""

    def __init__(self, grant):
        self.grant, self.holding, self.restarted = grant, True, False

    @property
    def active(self):
        return self.holding

    def start(self, ctx):
        return replace(ctx, freeze_contact={"held": np.zeros(1, np.int8)})

    def context(self, ctx, states):
        return replace(ctx, freeze_contact={"held": np.zeros(1, np.int8)}) if self.holding else ctx

    def settle(self, ctx, states):
        self.holding, self.restarted = False, True
        return ctx

    def restart_iterations(self):
        return self.grant if self.restarted else 0


def _held_atan(maxit, grant):
    problem, free = setup([HeldLinear([[GROUND, 0]], 1.0), Springs([[GROUND, 1]], 1.0)], 1, [])
    return solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                           StepContext(), np.zeros(0), np.array([1.2, 0.0]),
                           Settings(maxit=maxit), observers=(HoldThenRestart(grant),))


def test_a_restart_is_granted_its_iterations_past_maxit(monkeypatch):
    """The held law converges at once (solve 1), the review (pass 1) rejects it, the free law
    needs 5 more solves (|R|/F 0.27, 7.9e-2, 1.3e-2, 4.6e-4, 6.5e-7, 1.3e-12): MAXIT = 3 stops
    it unless the restart is granted its iterations, counted from the review's pass; past them
    the rate rule may finish it (4.6e-4 after 1.3e-2: two solves to go by the model)."""
    reference = _held_atan(40, 0)
    assert reference.iterations == 6
    with pytest.raises(IterationLimit) as err:
        _held_atan(3, 0)
    assert err.value.solves == 3
    conv = _held_atan(3, 10)
    assert conv.iterations == 6 and conv.u.tolist() == reference.u.tolist()
    assert np.tan(1.2) == pytest.approx(conv.u[0], rel=1e-10)      # |R|/F 1.3e-12
    with pytest.raises(IterationLimit):                   # limit 3: the rate rule cannot reach
        _held_atan(3, 2)
    assert _held_atan(3, 3).iterations == 6               # limit 4, then the rate rule
    monkeypatch.setattr(newton, "RATE_GRACE", 0)
    with pytest.raises(IterationLimit):
        _held_atan(3, 5)
    assert _held_atan(3, 6).iterations == 6               # limit 7: pass 7 converges


def test_flipflop_grants_iterations_to_its_release_only():
    """FlipFlop.settle: the rounds that adjust frozen points grant nothing, the release grants
    release_iterations, the failure after it nothing."""
    ff = FlipFlop({0: "C"}, limit=1)
    st = {"status": np.array([1, 2], np.int8), "tau": np.array([0.0, 1.0]), "p": np.ones(2)}
    ff.context(StepContext(), [st])
    ff.context(StepContext(), [dict(st, status=np.array([2, 2], np.int8))])   # point 0 frozen
    assert ff.active
    grants = []
    for _ in range(FlipFlop.max_rounds + 1):
        assert ff.settle(StepContext(), [st]) is not None
        grants.append(ff.restart_iterations())
    assert grants == [0] * FlipFlop.max_rounds + [FlipFlop.release_iterations]
    assert FlipFlop.release_iterations > 0 and not ff.active
