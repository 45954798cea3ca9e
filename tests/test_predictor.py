"""The first iterate of an increment: linear extrapolation against none, on press-then-slide.

Without a predictor Newton starts every increment from the converged state, where every contact
point is in the stick state of a zero increment; the slip zone of the last increment is then
found again one front point per iteration.  Extrapolation starts the slipping points slipping.
Both must reach the same end state: P = the applied pressure resultant and T = phi P, the whole
interface sliding (closed form), within the Newton tolerance.
"""
from pathlib import Path

import pytest

from lagamine_py.results import read_table
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
