"""The early cut-back (``*CONTROLS IR=, IC=``, :func:`lagamine_py.solver.newton._early_cut`): from
IR iterations into an attempt (or into the round after a failed review), an equilibrium
iteration whose logarithmic rate of convergence needs more than IC further iterations to reach
RTOL cuts the increment back at once, instead of at MAXIT.

A linear spring ``k d = F`` solved with a tangent ``k / (1 - rho)`` converges linearly with the
exact ratio ``rho``: ``|R|/F = rho^n`` after n solves (the error is multiplied by ``1 - 1/c`` at
each solve, c the tangent's factor), so the iteration the rule must stop at, and the count it
predicts, are known in closed form: ``log(RTOL / rho^n) / log(rho)`` iterations to go."""

import numpy as np
import pytest

from lagamine_py.core.errors import IterationLimit, SlowConvergence
from lagamine_py.elements.base import GroupResult, StepContext
from lagamine_py.model import CONTROL_PARAMS
from lagamine_py.solver import newton
from lagamine_py.solver.linear import SpluSolver
from lagamine_py.solver.newton import Settings, solve_increment

from test_rate_rule import HoldThenRestart, Switching
from test_solver_fakes import GROUND, Springs
from test_solver_newton import setup


class RatioSpring(Springs):
    """``k d``, its tangent reported as ``k / (1 - rho)``: Newton's error times ``rho`` per solve
    (``rho = -1``: d = 0, 2F, 0 ...: |R|/F = 1, 0.5, 1 ..., the scale being the larger of F and
    the spring's force).  While a context holds values (``freeze_contact``) the spring is
    ``2 k d`` with its exact tangent: one solve converges it, where the free law disagrees."""

    def __init__(self, pairs, k, rho, held_rho=0.0):
        super().__init__(pairs, k)
        self.rho, self.held_rho = rho, held_rho

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        d = self.elongation(u_new)
        if ctx.freeze_contact is not None:
            f, K = self.blocks(2.0 * self.k * d, 2.0 * self.k / (1.0 - self.held_rho) + 0.0 * d)
        else:
            f, K = self.blocks(self.k * d, self.k / (1.0 - self.rho) + 0.0 * d)
        return GroupResult(f, K if tangent else None, {})


def _solve(rho, observers=(), **settings):
    """The spring loaded by F = 2 from d = 0; the energy test off (ETOL = 0: at the energy's
    rate rho^2 it would stop these sequences before the force test does)."""
    settings.setdefault("etol", 0.0)
    problem, free = setup([RatioSpring([[GROUND, 0]], 1.0, rho), Springs([[GROUND, 1]], 1.0)],
                          1, [])
    return solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                           StepContext(), np.zeros(0), np.array([2.0, 0.0]),
                           Settings(**settings), observers=observers)


def test_the_rate_counts_the_iterations_to_go():
    """``log(RTOL / r_k) / log(r_k / r_k-1)``, from the last two residuals only."""
    assert newton._iterations_to_go([1.0, 1e-1, 1e-2], 1e-8) == pytest.approx(6.0)
    assert newton._iterations_to_go([1e-2, 1e-1, 1e-2], 1e-8) == pytest.approx(6.0)
    assert newton._iterations_to_go([1.0, 0.5], 1e-8) == pytest.approx(np.log2(5e7))
    assert newton._iterations_to_go([1e-1, 1e-1], 1e-8) == np.inf          # stalled
    assert newton._iterations_to_go([1e-2, 1e-1], 1e-8) == np.inf          # growing
    assert newton._iterations_to_go([1e-2, 1e-9], 1e-8) == 0.0             # there
    assert newton._iterations_to_go([0.0, 1e-1], 1e-8) == 0.0              # no rate yet


def test_the_defaults_are_abaqus_and_the_keyword_reads_them():
    params = {p.name: p for p in CONTROL_PARAMS}
    assert (params["IR"].default, params["IC"].default) == (8, 10)
    assert (Settings().ir, Settings().ic) == (8, 10)
    controls = {p.name: p.default for p in CONTROL_PARAMS}
    controls.update(IR=0, IC=4)
    s = Settings.from_controls(controls)
    assert (s.ir, s.ic) == (0, 4)


def test_a_stalled_residual_is_cut_back_at_ir_not_at_maxit():
    """rho = -1: |R|/F = 1, 0.5, 1, 0.5 ... (d = 0, 2F, 0 ...), growing over one iteration at a
    time, so the divergence test never speaks: MAXIT (25 solves) was the only stop; the rule
    stops it at iteration IR = 8 and says why."""
    with pytest.raises(SlowConvergence) as err:
        _solve(-1.0)
    assert err.value.solves == 8 and len(err.value.history) == 9
    assert err.value.history == [1.0, 0.5] * 4 + [1.0]
    assert str(err.value) == ("cut back at iteration 8: |R|/F = 1.000e+00 did not fall over the "
                              "last iteration (more than IC = 10; no contact state switched)")
    assert "IC = 10" in str(err.value) and err.value.reason == "slow convergence"
    with pytest.raises(IterationLimit) as err:             # IR=0: off, MAXIT as before
        _solve(-1.0, ir=0)
    assert err.value.solves == 25


def test_a_slow_rate_is_cut_back_with_its_count():
    """rho = 0.5: |R|/F = 2^-8 = 3.9e-3 at iteration 8, log(1e-8 / 2^-8) / log(0.5) = 18.6 more
    iterations (RTOL at iteration 27, past MAXIT): cut back at 8 with "~19 more".  IR = 5 cuts
    at 5 (22 more); IC = 19 lets iteration 8 pass (18.6 <= 19) and every later one: at MAXIT
    (2^-25) the rate rule's quadratic model grants the rest, converged at 27."""
    with pytest.raises(SlowConvergence) as err:
        _solve(0.5)
    assert err.value.solves == 8
    assert err.value.history[-1] == pytest.approx(2.0 ** -8, rel=1e-9)
    assert "would reach RTOL in ~19 more iterations at its rate" in str(err.value)
    with pytest.raises(SlowConvergence) as err:
        _solve(0.5, ir=5)
    assert err.value.solves == 5 and "~22 more" in str(err.value)
    assert _solve(0.5, ic=19).iterations == 27


def test_an_attempt_converging_late_at_a_steady_rate_is_not_cut_back():
    """rho = 0.3: 6.6e-5 at iteration 8, 7.3 more to go (<= IC): it converges at 16, the
    count of plain Newton with the rule off, bit for bit."""
    conv = _solve(0.3)
    assert conv.iterations == 16 and conv.residual <= 1e-8
    assert 0.3 ** 15 > 1e-8 >= 0.3 ** 16
    assert conv.u.tolist() == _solve(0.3, ir=0).u.tolist()
    assert conv.u[0] == pytest.approx(2.0, rel=1e-8)


def test_no_cut_while_states_switch():
    """An iteration across which contact states switched is a search for states, not Newton's
    rate: the stalled attempt runs to MAXIT as before."""
    with pytest.raises(IterationLimit) as err:
        _solve(-1.0, observers=(Switching(),))
    assert err.value.solves == 25


def test_a_failed_review_starts_the_count_again():
    """The held law converges at solve 1 (d = F / 2k = 1, exact); the review at pass 1 finds
    the free law at |R|/F = 0.5 and drops the hold; the free law with rho = -1 stalls (d = 1,
    3, 1 ...: 0.5, 1/3, 0.5 ...).  IR counts from the review's pass: cut back at pass
    1 + 8 = 9, after 8 solves (1 + 7); counted from the attempt's start it would be pass 8."""
    problem, free = setup([RatioSpring([[GROUND, 0]], 1.0, -1.0), Springs([[GROUND, 1]], 1.0)],
                          1, [])
    with pytest.raises(SlowConvergence) as err:
        solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                        StepContext(), np.zeros(0), np.array([2.0, 0.0]), Settings(etol=0.0),
                        observers=(HoldThenRestart(0),))
    assert err.value.solves == 8 and len(err.value.history) == 10
    assert err.value.history[:3] == [1.0, 0.0, 0.5]
    assert err.value.history[2:] == pytest.approx([0.5, 1 / 3] * 4)
    assert str(err.value).startswith("cut back at iteration 9: |R|/F = 3.333e-01 would reach "
                                     "RTOL in ~43 more iterations")


def test_a_review_after_an_energy_convergence_counts_its_extra_residual():
    """The held law at the ratio 1e-6 (|R|/F 1, 1e-6, 1e-12) under RTOL = 1e-15: the energy
    test converges it at the third solve (pass 2), with one more residual (0, history index 3);
    its review fails and the stalled free law follows (0.5, 1/3 ..., pass 3 = index 4).  The
    rule counts the round from that extra residual by the history, as the replay of
    tools/newton_attempts.py does: cut at index 3 + 8 = 11 (pass 10, after 3 + 7 solves), not
    one pass later as a count of passes would."""
    problem, free = setup([RatioSpring([[GROUND, 0]], 1.0, -1.0, held_rho=1e-6),
                           Springs([[GROUND, 1]], 1.0)], 1, [])
    with pytest.raises(SlowConvergence) as err:
        solve_increment(problem, SpluSolver(), free, np.zeros(2), problem.init_states(),
                        StepContext(), np.zeros(0), np.array([2.0, 0.0]), Settings(rtol=1e-15),
                        observers=(HoldThenRestart(0),))
    h = err.value.history
    assert h[:3] == pytest.approx([1.0, 1e-6, 1e-12], rel=1e-3) and h[3] < 1e-15
    assert h[4:] == pytest.approx([0.5, 1 / 3] * 4)
    assert len(h) == 12 and err.value.solves == 10
    assert str(err.value).startswith("cut back at iteration 10: ")


# ------------------------------------------------------------ through the step controller


class LongStepSpring(RatioSpring):
    """rho = -1 (stalled) over an increment longer than 0.3, an exact tangent over a shorter
    one: the increment of dt 1 cannot converge, its retry at dt 0.25 converges in one solve."""

    def compute(self, u_new, u_old, state, ctx, tangent=True):
        self.rho = -1.0 if ctx.t_new - ctx.t_old > 0.3 else 0.0
        return super().compute(u_new, u_old, state, ctx, tangent)


def _run(tmp_path, controls):
    from lagamine_py.model import CLoad, Step
    from lagamine_py.solver import run
    from test_solver_fakes import Recorder, make_model, make_problem
    load = CLoad("N0", np.array([0]), 1, 2.0)
    model = make_model(1, [Step(name="S", dt0=1.0, dt_max=1.0, cloads=[load],
                                controls=dict(controls, GROWTH=1.0))])
    groups = [LongStepSpring([[GROUND, 0]], 1.0, 0.0), Springs([[GROUND, 1]], 1.0)]
    rec = Recorder()
    out = run(model, tmp_path, writers=[rec],
              problem=make_problem(model, groups))
    return out, rec


def test_the_controller_cuts_back_at_ir_and_says_why(tmp_path):
    """The step's first attempt (dt 1) stalls at |R|/F = 1, 0.5 ...: the failed attempt the
    writers see (the .sta's row) took 8 solves, its reason "slow convergence" and the message
    the rule's; the retry at dt 0.25 and the rest converge: the same increments as with the
    rule off, whose failed attempt ran to MAXIT (25 solves)."""
    out, rec = _run(tmp_path / "on", {})
    assert out.status == 0
    (failed,) = rec.failed
    assert (failed.reason, failed.iterations, failed.dt) == ("slow convergence", 8, 1.0)
    assert "cut back at iteration 8: |R|/F = 1.000e+00 did not fall" in failed.message
    off, rec_off = _run(tmp_path / "off", {"IR": 0})
    assert [(f.reason, f.iterations) for f in rec_off.failed] == [("iteration limit", 25)]
    assert [r.step_time for r in rec.results] == [r.step_time for r in rec_off.results] \
        == pytest.approx([0.25, 0.5, 0.75, 1.0])
    assert rec.results[-1].u[0, 0] == rec_off.results[-1].u[0, 0] == pytest.approx(2.0)


def test_the_recorded_replay_stops_where_the_rule_stops(tmp_path):
    """tools/newton_attempts.py: the step of the controller test recorded with the rule off
    (its first attempt: 25 solves to MAXIT, 1, 0.5 ... with no state switching), then the rule
    replayed on the record stops it at pass 8, the pass the live rule cut it at; the converged
    attempts it leaves alone; IR = 0 stops nothing."""
    import sys
    from pathlib import Path
    from lagamine_py.model import CLoad, Step
    from test_solver_fakes import make_model, make_problem
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from newton_attempts import record, rule_stop, verdicts
    load = CLoad("N0", np.array([0]), 1, 2.0)
    model = make_model(1, [Step(name="S", dt0=1.0, dt_max=1.0, cloads=[load],
                                controls={"GROWTH": 1.0, "IR": 0})])
    groups = [LongStepSpring([[GROUND, 0]], 1.0, 0.0), Springs([[GROUND, 1]], 1.0)]
    attempts = record(model, tmp_path, make_problem(model, groups))
    assert [a["outcome"] for a in attempts] == ["iteration limit"] + ["converged"] * 4
    first = attempts[0]
    assert first["solves"] == 25 and first["switched"] == [] and first["reviews"] == []
    assert first["history"][:4] == [1.0, 0.5, 1.0, 0.5]
    assert rule_stop(first, 8, 10) == 8 and rule_stop(first, 5, 10) == 5
    assert verdicts(attempts, 8, 10) == ([], [(0, 8)])
    assert verdicts(attempts, 0, 10) == ([], [(0, None)])
