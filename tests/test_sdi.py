"""Severe discontinuity iterations (``*CONTROLS SDI``): a residual that grows while an observer
sees its states switching is not called diverging; the blow-up test and MAXIT still stop
Newton.  Plain Newton on cbrt(u) = 0 from u = 1 jumps to u = -2 u at every iteration: its
residual grows by 2^(1/3) each time (the textbook divergence), its tangent never vanishes."""
import numpy as np
import pytest

from lagamine_py.core.errors import DivergingResidual, IterationLimit
from lagamine_py.elements.base import GroupResult, StepContext
from lagamine_py.solver.linear import SpluSolver
from lagamine_py.solver.newton import IterationObserver, Settings, solve_increment
from lagamine_py.solver.stabilisation import FlipFlop

from test_solver_fakes import GROUND, Atan, Springs
from test_solver_newton import setup


class CubeRoot(Atan):
    """f = k cbrt(d): Newton's step from d is -3 d."""

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = self.elongation(u_new)
        c = np.cbrt(d)
        f, K = self.blocks(self.k * c, self.k / (3.0 * c**2))
        return GroupResult(f, K if tangent else None, {})


class Switching(IterationObserver):
    """An observer whose states always switch (or never)."""

    def __init__(self, always: bool):
        self.always = always
        self.asked = 0

    def switching(self, states) -> bool:
        self.asked += 1
        return self.always


def _solve(sdi, observers):
    """DOF 0 on the cube-root spring from u = 1; DOF 1 a linear spring in equilibrium under
    1000 (the force scale, so the relative residual is |cbrt(u)| / 1000 and grows)."""
    problem, free = setup([CubeRoot([[GROUND, 0]], 1.0), Springs([[GROUND, 1]], 1.0)], 1, [])
    return solve_increment(problem, SpluSolver(), free, np.array([1.0, 1000.0]),
                           problem.init_states(), StepContext(), np.zeros(0),
                           np.array([0.0, 1000.0]), Settings(maxit=12, sdi=sdi),
                           observers=observers)


def test_growth_while_states_switch_is_not_a_divergence():
    watch = Switching(True)
    with pytest.raises(IterationLimit) as err:
        _solve(True, (watch,))
    h = np.array(err.value.history)
    assert len(h) == 13 and np.allclose(h[1:] / h[:-1], 2.0 ** (1.0 / 3.0))
    assert watch.asked == 8                     # asked at each growth verdict (iterations 4-11)


@pytest.mark.parametrize("sdi, always", [(False, True), (True, False)])
def test_growth_is_a_divergence_without_sdi_or_without_switching(sdi, always):
    with pytest.raises(DivergingResidual):
        _solve(sdi, (Switching(always),))


def test_flipflop_switching_compares_with_the_last_context():
    """FlipFlop says its states switch when a watched point's state (with its slip direction)
    differs from the one its last :meth:`context` saw; never before a first context."""
    ff = FlipFlop({0: "C"}, limit=4)
    st = {"status": np.array([1, 2, 2], np.int8), "tau": np.array([0.0, 1.0, 1.0]),
          "p": np.ones(3)}
    assert not ff.switching([st])
    ff.context(StepContext(), [st])
    assert not ff.switching([st])
    reversed_ = dict(st, tau=np.array([0.0, 1.0, -1.0]))       # slip+ -> slip-
    assert ff.switching([reversed_])
    stuck = dict(st, status=np.array([1, 1, 2], np.int8))     # slip -> stick
    assert ff.switching([stuck])
