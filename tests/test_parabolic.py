"""The parabolic first iterate (``*CONTROLS EXTRAPOLATION=PARABOLIC``).

Closed forms: a path u(t) quadratic in t is reproduced by the quadratic through the last three
converged points, whatever the increments' lengths; the linear extrapolation misses it by
exactly ``c dt (dt + dt1)`` (c the path's t^2 coefficient).  On linear springs loaded along a
tabular amplitude through t^2 the converged displacements are F(t_i) / k exactly, so from the
step's third increment on the parabolic first iterate *is* the answer: the increment converges
without a linear solve.
"""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.model import Amplitude
from lagamine_py.solver.predictor import extrapolated, first_iterate
from test_solver_steps import cload, grounded, make_model, solve, solve_recording_starts, step

DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"

A, B, C = np.array([0.3, -1.0, 2.0]), np.array([1.5, 0.25, -4.0]), np.array([-2.0, 7.0, 0.5])


def _path(t):
    return A + B * t + C * t * t


def _history(t, dt1, dt2):
    """u at t and the last two increments (du, dt) of the path ending at t."""
    u0, u1, u2 = _path(t - dt1 - dt2), _path(t - dt1), _path(t)
    return u2, (u2 - u1, dt1), (u1 - u0, dt2)


@pytest.mark.parametrize("dt1, dt2, dt", [(0.2, 0.3, 0.45), (0.1, 0.1, 0.1), (0.05, 0.4, 0.0125),
                                          (0.3, 0.075, 0.6)])
def test_parabolic_reproduces_a_quadratic_path_with_unequal_increments(dt1, dt2, dt):
    t = 0.9
    u, last, earlier = _history(t, dt1, dt2)
    exact = _path(t + dt)
    par = extrapolated(u, last, dt, "PARABOLIC", earlier)
    assert np.abs(par - exact).max() <= 1e-13 * np.abs(exact).max()
    # the linear prediction misses by the curvature term, in closed form
    lin = extrapolated(u, last, dt, "LINEAR", earlier)
    assert lin - exact == pytest.approx(-C * dt * (dt + dt1), rel=1e-9, abs=1e-14)
    assert np.abs(lin - exact).max() > 1e-4


def test_parabolic_is_exact_on_a_straight_path_and_falls_back_to_linear():
    u, du = np.array([1.0, 2.0]), np.array([0.5, -1.0])
    lin = extrapolated(u, (du, 0.2), 0.1, "LINEAR")
    # a straight path: the second divided difference vanishes
    assert np.array_equal(extrapolated(u, (du, 0.2), 0.1, "PARABOLIC", (2.0 * du, 0.4)), lin)
    # the step's first converged increment only: the linear rule, bit for bit
    assert np.array_equal(extrapolated(u, (du, 0.2), 0.1, "PARABOLIC", None), lin)
    assert np.array_equal(extrapolated(u, (du, 0.2), 0.1, "LINEAR", (du, 0.3)), lin)
    # nothing to extrapolate at a step start, nor with NONE
    assert extrapolated(u, None, 0.1, "PARABOLIC", (du, 0.3)) is None
    assert extrapolated(u, (du, 0.2), 0.1, "NONE", (du, 0.3)) is None


def test_first_iterate_passes_the_earlier_increment_and_its_predicted_part():
    u, last, earlier = _history(1.0, 0.25, 0.25)

    class Ctx:                       # no foundation motion: nothing but the extrapolation
        foundation_old = foundation_new = {}

    start, predicted = first_iterate(u, last, 0.25, "PARABOLIC", Ctx(), earlier=earlier)
    assert np.abs(start - _path(1.25)).max() <= 1e-13 * np.abs(_path(1.25)).max()
    assert np.array_equal(predicted, start - u)
    start, predicted = first_iterate(u, None, 0.25, "PARABOLIC", Ctx(), earlier=earlier)
    assert np.array_equal(start, u) and predicted is None


def _quadratic_ramp(tmp_path, mode, times):
    """A grounded spring k = 2 under F = 4 a(t), a(t) = t^2 tabulated at the increment ends
    ``times`` (and 0): u = 2 a(t) at each of them; the Newton solves per increment."""
    amp = Amplitude("Q", np.concatenate([[0.0], times]), np.concatenate([[0.0], times ** 2]))
    model = make_model(1, [step(dt0=times[0], dt_max=1.0, cloads=[cload(0, 1, 4.0, amplitude="Q")],
                                controls={"EXTRAPOLATION": mode, "GROWTH": 1.5})])
    model.amplitudes = {"Q": amp}
    out, rec = solve(tmp_path / mode, model, grounded([2.0]))
    assert out.status == 0
    assert np.allclose([r.step_time for r in rec.results], times, rtol=1e-14)
    for r in rec.results:
        assert r.u[0, 0] == pytest.approx(2.0 * r.step_time ** 2, rel=1e-12)
    return [r.iterations for r in rec.results]


def test_a_quadratic_load_path_converges_at_the_parabolic_first_iterate(tmp_path):
    """Increments 0.1, 0.1, then growing by 1.5 (0.15, 0.225, 0.3375) and the rest (0.0875):
    PARABOLIC is linear at the second increment (one converged increment of the step), then
    exact; LINEAR misses the curvature at every increment."""
    dts = [0.1, 0.1, 0.15, 0.225, 0.3375]
    times = np.cumsum(dts + [1.0 - sum(dts)])
    times[-1] = 1.0
    assert _quadratic_ramp(tmp_path, "PARABOLIC", times) == [1, 1, 0, 0, 0, 0]
    assert _quadratic_ramp(tmp_path, "LINEAR", times) == [1, 1, 1, 1, 1, 1]


def test_parabolic_does_not_cross_steps(tmp_path, monkeypatch):
    """A step's first increment starts from the converged state; its second uses its first only
    (linear): the path of step 2 is a straight ramp, so the second increment is exact."""
    controls = {"EXTRAPOLATION": "PARABOLIC", "GROWTH": 1.0}
    model = make_model(1, [step("A", dt0=0.25, dt_max=0.25, cloads=[cload(0, 1, 4.0)],
                                controls=controls),
                           step("B", dt0=0.25, dt_max=0.25, cloads=[cload(0, 1, -4.0)],
                                controls=controls)])
    out, rec, starts = solve_recording_starts(tmp_path, model, grounded([2.0]), monkeypatch)
    assert out.status == 0
    assert [s is None for s in starts] == [True, False, False, False] * 2
    assert [r.iterations for r in rec.results] == [1, 0, 0, 0] * 2
    assert rec.results[-1].u[0, 0] == pytest.approx(-2.0, rel=1e-12)


def _parabolic_deck(tmp_path) -> Path:
    text = DECK.read_text().replace("*DLOAD", "*CONTROLS\nEXTRAPOLATION=PARABOLIC\n*DLOAD").replace(
        "*BOUNDARY", "*CONTROLS\nEXTRAPOLATION=PARABOLIC\n*BOUNDARY")
    deck = tmp_path / "ps_parabolic.dat"
    deck.write_text(text)
    return deck


def test_press_then_slide_with_the_keyword_reaches_the_closed_form_and_resumes_alike(tmp_path):
    """The main job with ``*CONTROLS EXTRAPOLATION=PARABOLIC``: the end state slides as a whole,
    T = phi P, P the pressure's resultant; interrupted at the sixth slide increment and resumed,
    the increments after it start from the uninterrupted run's first iterates, bit for bit, and
    take its solves and displacements (the increment before the last is part of the restart
    data)."""
    from lagamine_py.deck import load_deck
    from lagamine_py.solver import run
    from runner import Capture

    deck = _parabolic_deck(tmp_path)
    assert load_deck(deck).steps[1].controls["EXTRAPOLATION"] == "PARABOLIC"

    class Stop(Capture):
        def increment(self, result):
            super().increment(result)
            if (result.step, result.increment) == (2, 6):
                raise KeyboardInterrupt

    import lagamine_py.solver.steps as steps_mod
    orig, starts = steps_mod.solve_increment, []

    def spy(*a, **k):                    # every attempt's first iterate
        starts.append(k["u_start"].copy())
        return orig(*a, **k)

    def go(out, writer, restart=False):
        starts.clear()
        steps_mod.solve_increment = spy
        try:
            return run(load_deck(deck), out, writers=[writer], restart=restart, deck_path=deck)
        finally:
            steps_mod.solve_increment = orig

    full, first, second = Capture(), Stop(), Capture()
    assert go(tmp_path / "full", full).status == 0
    full_starts = list(starts)
    end = full.results[-1].contacts[0]
    assert end.P == pytest.approx(6000.0, rel=1e-3)    # 200 MPa x 30 mm (current length)
    assert abs(end.T) == pytest.approx(0.2 * end.P, rel=1e-6)
    assert go(tmp_path / "cut", first).status == 130
    assert go(tmp_path / "cut", second, restart=True).status == 0
    k = len(first.results) - 1                       # the interrupted increment runs again
    assert [r.iterations for r in second.results] == [r.iterations for r in full.results[k:]]
    # the resumed increment starts where the uninterrupted one did, bit for bit (no cut-back
    # in either run: one attempt per increment)
    assert len(full_starts) == len(full.results) and not full.failures
    assert all(np.array_equal(a, b) for a, b in zip(starts, full_starts[k:]))
    for a, b in zip(second.results, full.results[k:]):
        assert np.abs(a.u - b.u).max() <= 1e-12 * np.abs(b.u).max()
