"""Severe discontinuity iterations (``*CONTROLS SDI``): a residual that grows while an observer
sees its states switching is not called diverging; the blow-up test and MAXIT still stop
Newton.  Plain Newton on cbrt(u) = 0 from u = 1 jumps to u = -2 u at every iteration: its
residual grows by 2^(1/3) each time (the textbook divergence), its tangent never vanishes."""
import csv
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.core.errors import DivergingResidual, IterationLimit
from lagamine_py.elements.base import GroupResult, StepContext
from lagamine_py.solver import newton
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


def test_growth_while_states_switch_is_excused_up_to_the_limit():
    """Growing over 3..SDI_GROWTH_LIMIT-1 iterations running is excused while states switch;
    over SDI_GROWTH_LIMIT it is a divergence, excused or not (asked no more then)."""
    watch = Switching(True)
    with pytest.raises(DivergingResidual) as err:
        _solve(True, (watch,))
    limit = newton.SDI_GROWTH_LIMIT
    h = np.array(err.value.history)
    assert len(h) == limit + 1 and np.allclose(h[1:] / h[:-1], 2.0 ** (1.0 / 3.0))
    assert f"grew over {limit} iterations" in str(err.value)
    assert watch.asked == limit - 4             # iterations 4 .. limit - 1


def test_growth_while_states_switch_without_a_limit_runs_to_maxit(monkeypatch):
    monkeypatch.setattr(newton, "SDI_GROWTH_LIMIT", 100)
    watch = Switching(True)
    with pytest.raises(IterationLimit) as err:
        _solve(True, (watch,))
    h = np.array(err.value.history)
    assert len(h) == 13 and np.allclose(h[1:] / h[:-1], 2.0 ** (1.0 / 3.0))
    # asked at each growth verdict (iterations 4-11) and by the early cut-back (IR = 8: 8-11),
    # which the switching states hold off too
    assert watch.asked == 8 + 4


def _stiff_kt_block(tmp_path, name):
    """The Coulomb block of the stability study with KT = 2e9 (24 000 E/h): its press step
    cuts back four times (docs/stability.md); the .sta rows and the last contact totals."""
    from lagamine_py.deck import load_deck
    from lagamine_py.solver import run
    deck = Path(__file__).resolve().parents[1] / "tools" / "study_decks" / "block_study.dat"
    out = tmp_path / name
    run(load_deck(deck, parameters={"KT": "2e9"}), out)
    with open(out / "block_study.sta", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return rows, (out / "contact_totals.csv").read_text().splitlines()[-1]


def test_an_attempt_losing_its_states_stops_at_the_growth_limit(tmp_path, monkeypatch):
    """The stiff-KT block: two attempts' residuals grow from 1e-2 to 1.0 (every point open)
    while points switch; they now stop after SDI_GROWTH_LIMIT iterations, not MAXIT (25), and
    the run takes the same converged increments to the same end state, bit for bit."""
    rows, end = _stiff_kt_block(tmp_path, "limit")
    grown = [r for r in rows if r["failed"] == "yes" and r["reason"] == "diverging residual"]
    assert len(grown) == 2
    assert all(int(r["iterations"]) == newton.SDI_GROWTH_LIMIT for r in grown)
    monkeypatch.setattr(newton, "SDI_GROWTH_LIMIT", 100)
    # the behaviour before the limit, when a release had no iterations of its own either
    monkeypatch.setattr(FlipFlop, "release_iterations", 0)
    rows_old, end_old = _stiff_kt_block(tmp_path, "nolimit")
    failed_old = [r for r in rows_old if r["failed"] == "yes"]
    assert [r["reason"] for r in failed_old if r["reason"] != "singular matrix"] == \
        ["iteration limit"] * 2
    assert all(int(r["iterations"]) == 25 for r in failed_old if r["reason"] == "iteration limit")
    keep = ("step", "increment", "time", "dt", "residual")
    assert [[r[k] for k in keep] for r in rows if r["failed"] == "no"] == \
        [[r[k] for k in keep] for r in rows_old if r["failed"] == "no"]
    assert end == end_old


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
