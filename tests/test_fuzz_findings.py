"""Run-time failures found by ``tools/fuzz_run.py`` (mutated decks), each as the smallest deck
that showed it; the expectation is read off the deck, not off the program."""
from pathlib import Path

import pytest

from lagamine_py.cli import main
from lagamine_py.deck import DeckError, load_deck
from lagamine_py.results import read_table

#: a blank between a die (moved by *FOUNDATION MOTION) and a punch (REF NODE 1000)
TOOLS = (Path(__file__).parent / "data" / "tools" / "two_tools.dat").read_text()

APART = """*MESH, NAME=UP, TYPE=Q8PE, X0=0.5, Y0=1, LX=2, LY=1, NX=2, NY=1
*MESH, NAME=LOW, TYPE=Q8PE, X0=0, Y0=0, LX=3, LY=1, NX=3, NY=1
*MATERIAL, NAME=STEEL, LAW=ELASTIC
E=210000, NU=0.3
*SOLID, ELSET=UP, MATERIAL=STEEL
*SOLID, ELSET=LOW, MATERIAL=STEEL
*CONTACT LAW, NAME=DRY, TYPE=COULOMB
KP=1e7, KT=1e7, PHI=0.2
*CONTACT, SURFACE=UP_BOTTOM, MASTER=LOW_TOP, LAW=DRY
*STEP, NAME=LIFT
*STATIC
0.5, 1, 1e-3, 0.5
*BOUNDARY
LOW_BOTTOM, 1, 2, 0
UP_LEFT, 1, 1, 0
UP_TOP, 2, 2, 10
*END STEP
"""


def test_two_bodies_moved_apart_beyond_the_search_distance(tmp_path, capsys):
    """The upper body lifted by 10 (the search distance is 3 face lengths, 3): after the first
    increment no master face is near any slave face.  Re-pairing raised 'attempt to get argmax
    of an empty sequence' (exit 1, "an unexpected error"); the windows are now empty: every
    point faces no master, no force."""
    deck = tmp_path / "apart.dat"
    deck.write_text(APART)
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0, capsys.readouterr().err
    rows = read_table(tmp_path / "out" / "contact.csv")
    last = rows["increment"] == rows["increment"].max()
    assert set(rows["status"][last]) <= {"open", "none"}
    assert (rows["p"][last] == 0).all() and (rows["tau"][last] == 0).all()


@pytest.mark.parametrize("data, keyword, magnitude", [
    ("*FOUNDATION MOTION, NAME=DIE\n-1e300, 0", "FOUNDATION MOTION", "a translation of magnitude 1e+300"),
    ("*FOUNDATION MOTION, NAME=DIE\n0, 1e160, 0", "FOUNDATION MOTION", "a translation of magnitude 1e+160")])
def test_a_motion_beyond_the_coordinate_bound_is_a_deck_error(tmp_path, capsys, data, keyword, magnitude):
    """A tool moved by -1e300 (tools/fuzz_run.py seed 912 example 281, two_tools.dat): the run
    went on with overflowing squares of distances (RuntimeWarnings, a moment of 5e302).  Nodes
    and foundation points are bounded by COORD_MAX (1e150); a translation past it is refused at
    its line as they are.  (An imposed displacement that large is not: Newton meets a NaN
    residual, cuts back and stops with exit 3, test_scale_and_conditioning.py; a tool's
    reference node moved by *BOUNDARY likewise.)"""
    from lagamine_py.deck.builder import COORD_MAX
    assert 1e160 > COORD_MAX
    text = TOOLS.replace("*FOUNDATION MOTION, NAME=DIE\n0.01, 0", data)
    deck = tmp_path / "d.dat"
    deck.write_text(text)
    with pytest.raises(DeckError) as err:
        load_deck(deck)
    (p,) = err.value.items
    line = text.split("\n").index(data.split("\n")[1]) + 1
    assert (p.line, p.keyword) == (line, keyword)
    assert p.message.startswith(f"{magnitude} exceeds 1e+150: products of the positions")
    assert main(["check", str(deck)]) == 2
    capsys.readouterr()


def test_a_motion_up_to_the_bound_is_read(tmp_path):
    deck = tmp_path / "d.dat"
    deck.write_text(TOOLS.replace("*FOUNDATION MOTION, NAME=DIE\n0.01, 0",
                                  "*FOUNDATION MOTION, NAME=DIE\n1e150, -1e150"))
    motion = load_deck(deck).steps[1].motions[0]
    assert (motion.dx, motion.dy) == (1e150, -1e150)
