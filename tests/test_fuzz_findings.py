"""Run-time failures found by ``tools/fuzz_run.py`` (mutated decks), each as the smallest deck
that showed it; the expectation is read off the deck, not off the program."""
from lagamine_py.cli import main
from lagamine_py.results import read_table

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
