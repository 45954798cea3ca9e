"""The iteration limit's rate rule (:data:`lagamine_py.solver.newton.RATE_GRACE`): at MAXIT an
attempt goes on only while its residual, falling without contact states switching, reaches
RTOL within the iterations left past MAXIT by Newton's quadratic model.

Newton on ``k atan(d) = F`` (k = 1, F = 1.45, from d = 0) needs 8 solves, its residual
1, 0.33, 0.14, 5.4e-2, 1.5e-2, 2.0e-3, 4.7e-5, 2.6e-8, 8e-15 (measured, converging as the
model says once in the basin): the sequence the tests cut with MAXIT."""
import numpy as np
import pytest

from lagamine_py.core.errors import IterationLimit
from lagamine_py.elements.base import StepContext
from lagamine_py.solver import newton
from lagamine_py.solver.linear import SpluSolver
from lagamine_py.solver.newton import IterationObserver, Settings, solve_increment

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
    assert "no convergence in 5 iterations" in str(err.value)


def test_no_grace_while_states_switch():
    """An iteration across which contact states switched is a search for states, not an
    equilibrium iteration whose rate means anything: MAXIT stops it as before."""
    with pytest.raises(IterationLimit) as err:
        _atan(6, (Switching(),))
    assert len(err.value.history) == 7
