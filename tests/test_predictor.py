"""The first iterate of an increment: linear extrapolation against none, on press-then-slide.

Without a predictor Newton starts every increment from the converged state, where every contact
point is in the stick state of a zero increment; the slip zone of the last increment is then
found again one front point per iteration.  Extrapolation starts the slipping points slipping.
Both must reach the same end state: P = the applied pressure resultant and T = phi P, the whole
interface sliding (closed form), within the Newton tolerance.
"""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.results import read_table
from lagamine_py.solver.predictor import FrontPredictor, front_holds
from runner import run_deck

DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"


def _run(tmp_path, mode):
    text = DECK.read_text().replace("*DLOAD", f"*CONTROLS\nEXTRAPOLATION={mode}\n*DLOAD").replace(
        "*BOUNDARY", f"*CONTROLS\nEXTRAPOLATION={mode}\n*BOUNDARY")
    deck = tmp_path / f"ps_{mode}.dat"
    deck.write_text(text)
    out = tmp_path / mode
    outcome, cap, _ = run_deck(deck, out)
    assert outcome.status == 0, outcome.message
    totals = read_table(out / "contact_totals.csv")
    solves = sum(r.iterations for r in cap.results) + sum(f.iterations for f in cap.failures)
    return solves, float(totals["P"][-1]), float(totals["T"][-1])


def test_extrapolation_needs_far_fewer_newton_iterations_for_the_same_end_state(tmp_path):
    it_lin, P_lin, T_lin = _run(tmp_path, "LINEAR")
    it_none, P_none, T_none = _run(tmp_path, "NONE")
    assert it_lin < 0.6 * it_none, (it_lin, it_none)      # measured: 55 against 137 solves
    for P, T in ((P_lin, T_lin), (P_none, T_none)):
        assert P == pytest.approx(6000.0, rel=1e-3)       # 200 MPa x 30 mm (current length)
        assert abs(T) == pytest.approx(0.2 * P, rel=1e-6)
    assert P_lin == pytest.approx(P_none, rel=1e-6)


def test_energy_test_does_not_tighten_with_the_predictor(tmp_path):
    """The energy test is relative to the first iteration's energy.  With the extrapolated first
    iterate that energy is only the predictor's error, so without the predicted part's own
    energy |d.K d| in the reference a stiff-KT block (24 000 E/h: its residual stalls at its
    round-off floor, ~4e-8 of F) stopped with exit 3 in the press step.  It must run, and slide
    at the Coulomb closed form T = phi P + B A."""
    from lagamine_py.checks import evaluate_checks
    from lagamine_py.deck import load_deck
    deck = Path(__file__).resolve().parents[1] / "tools" / "study_decks" / "block_study.dat"
    params = {"KP": "2e6", "KT": "2e9"}
    outcome, _, _ = run_deck(deck, tmp_path, parameters=params)
    assert outcome.status == 0, outcome.message
    (check,) = evaluate_checks(load_deck(deck, parameters=params).checks, tmp_path)
    assert check["error"] < 1e-6, check


# -- the slip front extrapolated (predictor.front_holds, FrontPredictor) ----------------------

def _line(n=30):
    """n contact points 1 apart on a line, listed out of order (the predictor must not rely
    on the order of the points)."""
    order = np.random.default_rng(3).permutation(n)
    x = np.zeros((n, 2))
    x[order, 0] = np.arange(n, dtype=float)
    return x, order


def _codes(order, spec):
    """State codes along the line from a string: '.' stick, '+' slip+, '-' slip-, 'o' open."""
    c = np.empty(len(spec), np.int8)
    c[order] = ["o.+-".index(ch) for ch in spec]
    return c


def _held(h, order):
    return "" if h is None else "".join("H" if h[order][i] >= 0 else "_" for i in range(len(order)))


def test_front_holds_follows_each_front_at_its_last_speed():
    """The slip+ zone grew from 5 to 8 points (3 ahead), the slip- zone from the right by 2:
    with the same increment the next 3 and 2 stick points are held SLIP, twice as many with an
    increment twice as long; the stick points of the other tau sign are not."""
    x, order = _line()
    before = _codes(order, "+++++" + "." * 21 + "----")
    after = _codes(order, "++++++++" + "." * 16 + "------")
    tau = np.where(np.isin(np.arange(30), order[:15]), 1.0, -1.0)     # tau > 0 on the left half
    assert _held(front_holds(x, before, after, tau, 1.0), order) == \
        "________HHH" + "_" * 11 + "HH" + "_" * 6
    assert _held(front_holds(x, before, after, tau, 2.0), order) == \
        "________HHHHHH" + "_" * 6 + "HHHH" + "_" * 6
    tau_all_neg = -np.ones(30)              # no stick point leans towards the slip+ front
    assert _held(front_holds(x, before, after, tau_all_neg, 1.0), order) == \
        "_" * 22 + "HH" + "_" * 6


def test_front_holds_ignores_a_front_that_moved_one_point_and_a_new_zone():
    """One point more (Newton finds it at its first iteration) and a point slipping away from
    every slip zone (born there, no front to extrapolate) predict nothing."""
    x, order = _line()
    tau = np.ones(30)
    before = _codes(order, "+++++" + "." * 25)
    assert front_holds(x, before, _codes(order, "++++++" + "." * 24), tau, 1.0) is None
    assert front_holds(x, before, _codes(order, "+++++" + "." * 10 + "+++" + "." * 12), tau,
                       1.0) is None
    assert front_holds(x, before, before, tau, 1.0) is None          # nothing moved


def test_front_predictor_holds_the_first_evaluation_only():
    holds = np.array([-1, 2, 2], np.int8)
    fp = FrontPredictor({"C": holds, "D": None})
    ctx = StepContext()
    first = fp.start(ctx)
    assert fp.active and list(first.freeze_contact) == ["C"]
    assert first.freeze_contact["C"].tolist() == [-1, 2, 2]
    assert ctx.freeze_contact is None                 # the caller's context is not modified
    assert fp.context(ctx, []) is ctx and not fp.active
    assert fp.start(ctx).freeze_contact is None       # released for good
    assert FrontPredictor({"C": None}).start(ctx) is ctx


def _slide_solves(tmp_path, monkeypatch, predict: bool, name: str):
    from lagamine_py.solver import steps
    if not predict:
        monkeypatch.setattr(steps, "front_holds", lambda *a: None)
    out = tmp_path / name
    outcome, cap, _ = run_deck(DECK, out)
    monkeypatch.undo()
    assert outcome.status == 0, outcome.message
    totals = read_table(out / "contact_totals.csv")
    solves = [r.iterations for r in cap.results if r.step == 2]
    return solves, float(totals["P"][-1]), float(totals["T"][-1])


def test_front_prediction_saves_iterations_on_press_then_slide(tmp_path, monkeypatch):
    """The main job's slide step, where the stick zone shrinks from both ends: with the fronts
    extrapolated fewer Newton solves, the same increments and the same end state (T = phi P,
    the whole interface sliding)."""
    with_, P1, T1 = _slide_solves(tmp_path, monkeypatch, True, "front")
    without, P0, T0 = _slide_solves(tmp_path, monkeypatch, False, "nofront")
    assert len(with_) == len(without)
    assert sum(with_) < sum(without), (with_, without)
    assert P1 == pytest.approx(P0, rel=1e-9) and T1 == pytest.approx(T0, rel=1e-9)
    assert abs(T1) == pytest.approx(0.2 * P1, rel=1e-6)


def test_a_resumed_run_predicts_the_same_fronts(tmp_path):
    """The fronts of the last increment are part of the restart data: the main job interrupted
    while the sixth slide increment is handed out resumes from the fifth (the stick zone then
    shrinks from both ends) and computes the sixth with the fronts of the fifth: the
    uninterrupted run's iterations (3, against 4 without the prediction) and answers."""
    from lagamine_py.deck import load_deck
    from lagamine_py.solver import run
    from runner import Capture

    class Stop(Capture):
        def increment(self, result):
            super().increment(result)
            if (result.step, result.increment) == (2, 6):
                raise KeyboardInterrupt

    def go(out, writer, restart=False):
        return run(load_deck(DECK), out, writers=[writer], restart=restart, deck_path=DECK)

    full, first, second = Capture(), Stop(), Capture()
    assert go(tmp_path / "full", full).status == 0
    assert go(tmp_path / "cut", first).status == 130
    assert go(tmp_path / "cut", second, restart=True).status == 0
    k = len(first.results) - 1                       # the interrupted increment runs again
    assert [r.iterations for r in second.results] == [r.iterations for r in full.results[k:]]
    for a, b in zip(second.results, full.results[k:]):
        assert np.abs(a.u - b.u).max() <= 1e-12 * np.abs(b.u).max()


def test_a_cut_back_attempt_predicts_no_front(tmp_path, monkeypatch):
    """The prediction may be what failed: the first predicted attempt of the main job is made to
    fail once; its retry (smaller) holds nothing, and the run goes on to the same end state."""
    from lagamine_py.core.errors import IterationLimit
    from lagamine_py.solver import steps

    real = steps.solve_increment
    calls = []

    def fail_first_predicted(*a, observers=(), **k):
        predicted = bool(observers[0].holds)
        calls.append(predicted)
        if predicted and calls.count(True) == 1:
            raise IterationLimit("made to fail", [1.0], factor=0.9)   # a retry almost as long
        return real(*a, observers=observers, **k)

    monkeypatch.setattr(steps, "solve_increment", fail_first_predicted)
    outcome, cap, _ = run_deck(DECK, tmp_path / "out")
    assert outcome.status == 0, outcome.message
    first = calls.index(True)
    assert calls[first + 1] is False                  # the retry of that increment
    assert len(cap.failures) == 1 and cap.failures[0].dt > cap.results[first].dt
    assert True in calls[first + 2:]                  # later increments predict again
    totals = read_table(tmp_path / "out" / "contact_totals.csv")
    assert abs(float(totals["T"][-1])) == pytest.approx(0.2 * float(totals["P"][-1]), rel=1e-6)


def test_augmentations_start_without_the_prediction(tmp_path, monkeypatch):
    """METHOD=AUGMENTED solves an increment again from its converged solve: the fronts are held
    at the first evaluation of the increment's first solve only."""
    from lagamine_py.solver import steps

    text = DECK.read_text().replace("B=0, THETA=1, SUBSTEPS=1",
                                    "B=0, THETA=1, SUBSTEPS=1, METHOD=AUGMENTED, PTOL=3e-6")
    deck = tmp_path / "ps_augmented.dat"
    deck.write_text(text)
    real = steps.solve_increment
    calls = []                                        # (increment end time, holds at the call)

    def recording(problem, solver, free, u_old, states, ctx, *a, observers=(), **k):
        calls.append((ctx.t_new, observers[0].active))
        return real(problem, solver, free, u_old, states, ctx, *a, observers=observers, **k)

    monkeypatch.setattr(steps, "solve_increment", recording)
    outcome, cap, _ = run_deck(deck, tmp_path / "out")
    assert outcome.status == 0, outcome.message
    times = [t for t, _ in calls]
    again = [t for t in set(times) if times.count(t) > 1]
    assert again                                      # increments that were augmented
    assert any(held for _, held in calls)             # and fronts predicted
    for t in set(times):
        held = [h for tt, h in calls if tt == t]
        assert not any(held[1:]), (t, held)
