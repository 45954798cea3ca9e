"""Answers that do not depend on the length unit, and failures named for what they are.

* ``coulomb_block.dat`` rescaled to lengths of 1e-9 .. 1e6 (every length times s, the penalties
  KP, KT -- stress per length -- divided by s, stresses unchanged) gives the same Coulomb
  answer, T/P = (phi P + B A)/P = 0.35 (DESIGN.md section 4).  A model smaller than ~1e-6 used
  to stop with a "singular" matrix: the absolute touching tolerance of the contact element
  (1e-12) swallowed its whole penetration p/KP ~ 5e-14.
* A penalty of 1e10 E/h makes the tangent ill-conditioned; the run stops saying so, with the
  penalty advice, instead of blaming "unrestrained DOFs".  A body that floats still gets
  "unrestrained DOFs" (tests/test_solver_steps.py, tests/test_verify_contact.py).
* A foundation whose every contact face lies beyond its ends (the body slides onto it later)
  is judged against the end half-lines that continue it: written in the wrong direction it is
  refused at check.
"""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.core.errors import SingularMatrixError
from lagamine_py.deck import DeckError, load_deck
from lagamine_py.results import read_table

DECKS = Path(__file__).resolve().parents[1] / "decks"
BLOCK = (DECKS / "coulomb_block.dat").read_text()


def rescaled(s: float) -> str:
    """coulomb_block.dat with every length times ``s`` (KP, KT divided by s; stresses kept)."""
    edits = [("LX=20, LY=10", f"LX={20 * s!r}, LY={10 * s!r}"),
             ("-20, 0\n10, 0\n40, 0", f"{-20 * s!r}, 0\n{10 * s!r}, 0\n{40 * s!r}, 0"),
             ("KP=2e6, KT=2e6", f"KP={2e6 / s!r}, KT={2e6 / s!r}"),
             ("A=20", f"A={20 * s!r}"),
             ("BLOCK_LEFT, 1, 1, 0.05", f"BLOCK_LEFT, 1, 1, {0.05 * s!r}")]
    text = BLOCK
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    return text


@pytest.mark.parametrize("s", [1e-9, 1e-6, 1e6])
def test_the_answer_does_not_depend_on_the_length_unit(tmp_path, s):
    deck = tmp_path / "block.dat"
    deck.write_text(rescaled(s))
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0
    tot = read_table(tmp_path / "out" / "contact_totals.csv")
    P, T = float(tot["P"][-1]), float(tot["T"][-1])
    assert P == pytest.approx(100.0 * 20 * s, rel=1e-9)      # the pressure times the top length
    assert abs(T) / P == pytest.approx((0.3 * P + 5.0 * 20 * s) / P, rel=1e-6)
    gap = read_table(tmp_path / "out" / "contact.csv")["gap"]
    assert np.all(np.isfinite(gap))


def test_a_huge_penalty_is_reported_as_ill_conditioning(tmp_path, capsys):
    deck = tmp_path / "stiff.dat"
    deck.write_text(_press_slide_with_kp(1e15))
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 3
    err = capsys.readouterr().err
    last = [ln for ln in err.splitlines() if "could not converge" in ln][0]
    assert "ill-conditioned" in last and "unrestrained DOFs" not in last
    assert "KP = 1e+15 is 1.19e+10 E/h" in last          # the penalty advice says which


def _press_slide_with_kp(kp: float) -> str:
    text = (DECKS / "press_slide.dat").read_text()
    lines = [ln for ln in text.splitlines() if ln.startswith("KP=")]
    assert len(lines) == 1
    old = lines[0].split(",")[0]
    return text.replace(old, f"KP={kp:g}")


def test_the_singular_verdict_reads_the_diagonal_span():
    """A span of the diagonal beyond 1e8 is ill-conditioning; below, unrestrained DOFs."""
    floating = SingularMatrixError([3], "zero pivot", node_ids=np.array([10, 11]),
                                   span=(2.0e5, 8.0e5))
    assert "unrestrained DOFs (node, direction): node 11 y" in str(floating)
    stiff = SingularMatrixError([3], "zero pivot", node_ids=np.array([10, 11]),
                                span=(2.1e5, 1.33e15))
    assert stiff.ill_conditioned and "spans 6.3e+09" in str(stiff)
    assert "smallest pivots at (node, direction): node 11 y" in str(stiff)


def test_a_reversed_foundation_beyond_the_body_is_refused(tmp_path):
    """The block stands beyond the end of the flat (x from 50 to 70, the flat from -20 to
    40): every face is beyond the chain; the end half-line decides."""
    text = BLOCK.replace("X0=0, Y0=0", "X0=50, Y0=0")
    deck = tmp_path / "beyond.dat"
    deck.write_text(text)
    load_deck(deck)                                            # body on the left: fine
    deck.write_text(text.replace("-20, 0\n10, 0\n40, 0\n", "40, 0\n10, 0\n-20, 0\n"))
    with pytest.raises(DeckError, match="reverse the point order"):
        load_deck(deck)
    # apart (above the flat, not touching) and reversed: judged by the side it approaches from
    apart = BLOCK.replace("X0=0, Y0=0", "X0=0, Y0=0.5")
    deck.write_text(apart.replace("-20, 0\n10, 0\n40, 0\n", "40, 0\n10, 0\n-20, 0\n"))
    with pytest.raises(DeckError, match="reverse the point order"):
        load_deck(deck)


def test_values_near_the_float_range_stop_the_run_with_a_reason(tmp_path, capsys):
    """E = 1e308 passes check (no bound to give it) but its stiffness overflows: the run stops
    with exit 3 saying the tangent is not finite, without NumPy warnings, instead of calling
    every DOF "unrestrained"."""
    import warnings
    deck = tmp_path / "huge_e.dat"
    deck.write_text(BLOCK.replace("E=210000", "E=1e308"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 3
    err = capsys.readouterr().err
    assert "non-finite tangent stiffness" in err and "unrestrained" not in err
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


def test_a_residual_that_blew_up_is_not_written_as_nan(tmp_path):
    """An imposed displacement of -1e300 (found by tools/fuzz_run.py): every attempt ends in a
    NaN residual; the run stops with exit 3 and the .sta rows of its failed attempts say "NaN"
    as the reason, with an empty residual -- no NaN in any output table."""
    deck = tmp_path / "punch.dat"
    text = (DECKS / "flat_punch.dat").read_text()
    assert text.count("BLOCK_LEFT, 1, 1, 0") == 1
    deck.write_text(text.replace("BLOCK_LEFT, 1, 1, 0", "BLOCK_LEFT, 1, 1, -1e300"))
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 3
    sta = read_table(tmp_path / "out" / "punch.sta")
    assert list(sta["failed"]) == ["yes"] * len(sta["failed"]) and set(sta["reason"]) == {"NaN"}
    assert set(sta["residual"]) == {""}
    for path in (tmp_path / "out").glob("*.csv"):
        assert "nan" not in path.read_text().lower(), path.name
