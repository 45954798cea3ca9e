"""The energy test's floor (``solver.newton.ENERGY_FLOOR_FRACTION`` times the largest energy
reference of earlier increments, as the force scale's floor): a stress-free body in an increment
where nothing moves converges; a loaded body's path is not touched by it.  Found by helper
``fuzz9``: a coulomb_block lifted off its foundation by imposed motions, then held, stopped with
exit 3 (every force and every energy round-off, compared with round-off)."""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.results import read_table
from lagamine_py.solver import newton, steps

DECKS = Path(__file__).resolve().parents[1] / "decks"

#: decks/coulomb_block.dat with its pressure replaced by imposed motions: the block lifted 10 mm
#: off the flat (its left edge held in x), then a step in which nothing moves.  The block is
#: stress-free throughout: every force is round-off, so |R|/F is ~1 at every iterate.
LIFTED = (DECKS / "coulomb_block.dat").read_text().replace(
    "*DLOAD\nBLOCK_TOP, P, 100\n", "*BOUNDARY\nBLOCK_TOP, 2, 2, 10\nBLOCK_LEFT, 1, 1, 0\n").replace(
    "BLOCK_LEFT, 1, 1, 0.05", "BLOCK_LEFT, 1, 1, 0")


def _run(directory, text, name="d"):
    directory.mkdir(parents=True, exist_ok=True)
    deck = directory / f"{name}.dat"
    deck.write_text(text)
    out = directory / name
    return main(["run", str(deck), "-o", str(out), "-q"]), out


def test_a_stress_free_body_converges_where_nothing_moves(tmp_path, capsys):
    """Both steps complete: step 2 (nothing moves) in its 10 increments of 2 solves each, by the
    energy test against the floor from step 1's increments; the block has risen by 10 and
    carries no stress (every reaction below 1e-6 N, round-off of E x extent = 4e6 N)."""
    assert "BLOCK_TOP, 2, 2, 10" in LIFTED and "0.05" not in LIFTED.split("*STEP, NAME=PUSH")[1]
    status, out = _run(tmp_path, LIFTED, "lifted")
    assert status == 0, capsys.readouterr().err
    sta = read_table(out / "lifted.sta")
    push = sta["step"] == 2
    assert push.sum() == 10 and (sta["failed"][push] == "no").all()
    assert (sta["iterations"][push] == 2).all()
    u = read_table(out / "displacements.csv")
    assert np.allclose(u["u2"][u["increment"] == u["increment"].max()], 10.0, atol=1e-9)
    rf = read_table(out / "reactions.csv")
    assert max(np.abs(rf["RF1"]).max(), np.abs(rf["RF2"]).max()) < 1e-6
    with np.load(out / "restart.npz") as data:    # the floor's reference resumes with the run
        assert float(data["energy_ref"]) > 1.0


def test_without_the_floor_the_same_deck_stops(tmp_path, monkeypatch, capsys):
    """The floor is what makes it converge: without it step 2 is cut back to its minimum
    increment and the run stops (exit 3), as it did before."""
    monkeypatch.setattr(steps, "ENERGY_FLOOR_FRACTION", 0.0)
    status, _ = _run(tmp_path, LIFTED, "lifted")
    assert status == 3
    assert "could not converge" in capsys.readouterr().err


def test_the_floor_is_the_force_floor_squared():
    """energy ~ force^2: the floors apply in the same regime (a force under 1e-6 of the largest
    earlier, an energy under 1e-12)."""
    assert newton.ENERGY_FLOOR_FRACTION == newton.FLOOR_FRACTION ** 2 == pytest.approx(1e-12)


@pytest.mark.parametrize("deck", ["coulomb_block.dat", "press_slide.dat", "compression_ro.dat",
                                  "stick_slip.dat"])
def test_a_loaded_body_is_not_touched_by_it(tmp_path, monkeypatch, deck):
    """A loaded body's first-iteration energies stay far above 1e-12 of the largest: the run's
    status file is the same with the floor off, row for row."""
    text = (DECKS / deck).read_text()
    assert _run(tmp_path / "on", text)[0] == 0
    monkeypatch.setattr(steps, "ENERGY_FLOOR_FRACTION", 0.0)
    assert _run(tmp_path / "off", text)[0] == 0
    assert (tmp_path / "on" / "d" / "d.sta").read_text() == (tmp_path / "off" / "d" / "d.sta").read_text()
