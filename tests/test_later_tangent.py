"""The tangent of an evaluation taken later (``tangent=LATER``, issue 17 item 8).

Newton asks for the evaluation it expects to converge at with ``tangent=LATER``
(:func:`lagamine_py.solver.newton._tangent_wanted`): the forces and states now, the CSR data only
if read.  What must hold: such an evaluation is bit for bit the evaluation with ``tangent=True``
(forces, scale, states, and the data once read) on every kind of group and kernel -- NumPy solids
deferring their tangent (one block and by chunks, small strain and NLGEOM, plane and
axisymmetric), fused numba solids computed again, contact, two-body and tool groups computing
theirs at once --; a whole run is then the same, to the bit, with the guess on or off; and the
guess does save tangents.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py import kernels
from lagamine_py.deck import load_deck
from lagamine_py.elements.base import LATER, StepContext
from lagamine_py.elements.solid import SolidElement
from lagamine_py.output import default_writers
from lagamine_py.solver import newton, run
from lagamine_py.solver import problem as problem_mod

from runner import DECKS

KERNELS = ["NUMPY"] + (["NUMBA"] if kernels.available() else [])


def _context(problem, nlgeom):
    zero = {name: np.zeros(2) for name in problem.foundations}
    return StepContext(nlgeom=nlgeom, t_old=0.0, t_new=1.0, foundation_old=zero,
                       foundation_new=dict(zero))


def _displacement(model, problem, seed):
    """A small random displacement with the bottom pushed down (contact points closed)."""
    rng = np.random.default_rng(seed)
    size = float(np.ptp(model.coords, axis=0).max())
    u = 1e-4 * size * rng.standard_normal(problem.ndof)
    n2 = 2 * len(model.coords)
    y = model.coords[:, 1]
    u[1:n2:2] -= 1e-4 * size * (y <= y.min() + 1e-9 * size)
    return u


def _same(a, b, what):
    assert type(a) is type(b), what
    if isinstance(a, dict):
        assert a.keys() == b.keys(), what
        for k in a:
            _same(a[k], b[k], f"{what}[{k}]")
    else:
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), what


@pytest.mark.parametrize("kernel", KERNELS)
@pytest.mark.parametrize("deck, nlgeom, chunk", [
    ("press_slide", True, None),         # Q8 NLGEOM Ramberg-Osgood, contact
    ("press_slide", True, 40),           # the same by chunks of 40 elements
    ("press_slide", False, 40),          # small strain by chunks
    ("axisym_press_friction", True, None),   # axisymmetric
    ("hertz_two_body", False, None),     # two deformable bodies
    ("tube_joint", True, None),          # a tool with a reference node
])
def test_later_evaluation_is_the_immediate_one_bit_for_bit(deck, nlgeom, chunk, kernel,
                                                            monkeypatch):
    if chunk:
        monkeypatch.setattr(SolidElement, "chunk", chunk)
    model = load_deck(DECKS / f"{deck}.dat")
    problem = problem_mod.build_problem(model)
    problem.set_kernel(kernel)
    u = _displacement(model, problem, 3)
    states, ctx = problem.init_states(), _context(problem, nlgeom)
    now = problem.evaluate(u, np.zeros(problem.ndof), states, ctx, True)
    later = problem.evaluate(u, np.zeros(problem.ndof), states, ctx, LATER)
    solid = problem.indices("solid")
    for k in solid:                              # deferred, or (fused) not computed at all
        assert later.results[k].K is None
        assert (later.results[k].later is not None) == (not problem.groups[k].fused)
    _same(later.f_int, now.f_int, "f_int")
    assert later.scale == now.scale
    for k, (a, b) in enumerate(zip(later.states, now.states)):
        _same(a, b, f"states[{k}]")
    _same(later.data, now.data, "data")
    assert later.data is later.data              # computed once, then kept
    assert chunk is None or len(problem.groups[solid[0]]._chunk_views()) > 1


def test_the_guess_follows_newtons_quadratic_model():
    rtol = 1e-8
    assert newton._tangent_wanted([1.0], rtol) is True                   # nothing to go by
    assert newton._tangent_wanted([0.0, 1e-3], rtol) is True
    assert newton._tangent_wanted([1e-2, 1e-3], rtol) is True            # next ~ 1e-5
    assert newton._tangent_wanted([1e-2, 1e-4], rtol) is LATER           # next ~ 1e-8 <= 10 rtol
    assert newton._tangent_wanted([1e-2, 2e-4], rtol) is LATER           # next 8e-8
    assert newton._tangent_wanted([1, 1e-2, 2.2e-4], rtol) is True       # next 1.06e-7
    assert newton._tangent_wanted([1e-3, 0.5e-3], rtol) is True          # slow: next ~ 1.2e-4


def _run(deck, out, kernel, monkeypatch, guess: bool):
    """Run ``deck``; returns the bytes of its tables and (LATER evaluations, tangents taken)."""
    counts = {"later": 0, "finished": 0}
    orig_eval = problem_mod.Problem.evaluate
    orig_data = problem_mod.Problem._later_data

    def evaluate(self, *a, **k):
        counts["later"] += a[4] is LATER if len(a) > 4 else k.get("tangent") is LATER
        return orig_eval(self, *a, **k)

    def later_data(self, *a, **k):
        counts["finished"] += 1
        return orig_data(self, *a, **k)
    with monkeypatch.context() as m:
        m.setattr(problem_mod.Problem, "evaluate", evaluate)
        m.setattr(problem_mod.Problem, "_later_data", later_data)
        if not guess:
            m.setattr(newton, "_tangent_wanted", lambda history, rtol: True)
        model = load_deck(DECKS / f"{deck}.dat")
        for step in model.steps:
            step.controls["KERNEL"] = kernel
        writers = default_writers(out, model, names=("CONTACT", "REACTIONS", "DISPLACEMENTS"))
        assert run(model, out, writers=writers).status == 0
    tables = {p.name: p.read_bytes() for p in sorted(out.glob("*.csv"))}
    return tables, counts


@pytest.mark.parametrize("deck, kernel", [("press_slide", "NUMPY"), ("compression_ro", KERNELS[-1])])
def test_a_run_is_the_same_with_the_guess_and_saves_tangents(deck, kernel, tmp_path, monkeypatch):
    off, counts_off = _run(deck, tmp_path / "off", kernel, monkeypatch, guess=False)
    on, counts_on = _run(deck, tmp_path / "on", kernel, monkeypatch, guess=True)
    assert counts_off == {"later": 0, "finished": 0}
    assert off.keys() == on.keys() and "displacements.csv" in on
    for name in off:
        assert on[name] == off[name], name
    # some evaluations guessed, most of them right: their tangent was never computed
    assert counts_on["later"] >= 3 and counts_on["finished"] <= counts_on["later"] // 2
