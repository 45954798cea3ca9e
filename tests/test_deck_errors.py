"""Malformed decks: each error names the file, the line, the keyword and what was expected.

Each case edits one line of a valid deck (``BASE``, which loads: see the first test) and
asserts that one reported problem sits at the edited line, under the right keyword, with the
key words of the expectation in its message.
"""
import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.cli import main
from lagamine_py.deck import DeckError, load_deck

BASE = """** a unit square, one Q4 element
*NODE
1, 0, 0
2, 1, 0
3, 1, 1
4, 0, 1
*ELEMENT, TYPE=Q4PE, ELSET=E
1, 1, 2, 3, 4
*MATERIAL, NAME=M, LAW=ELASTIC
E=100, NU=0.3
*SOLID, ELSET=E, MATERIAL=M
*STEP
*STATIC
1, 1, 0.1, 1
*BOUNDARY
1, 1, 2
*END STEP
"""


def _out_of_bounds_pair():
    """A KEY=VALUE of the ELASTIC law beyond one of its declared bounds (read from the plugin)."""
    for p in registry.get("laws", "ELASTIC").params:
        low, high = p.bounds
        if high is not None:
            return p.name, high + 1.0
        if low is not None:
            return p.name, low - 1.0
    raise AssertionError("ELASTIC declares no bounded parameter")


def edit(old, new, base=BASE):
    assert base.count(old) == 1, old
    return base.replace(old, new)


BOUND_KEY, BOUND_VALUE = _out_of_bounds_pair()
BOUND_LINE = ", ".join(f"{k}={v}" for k, v in {"E": 100, "NU": 0.3, BOUND_KEY: BOUND_VALUE}.items())

# (id, deck text, the line (its text) the problem must point at, keyword, key words of the message)
CASES = [
    ("unknown keyword", edit("*SOLID,", "*NODES\n5, 2, 2\n*SOLID,"), "*NODES", "NODES",
     ["unknown keyword", "did you mean *NODE?"]),
    ("unknown output field", edit("*END STEP", "*OUTPUT, FIELDS=U/PEQ\n*END STEP"),
     "*OUTPUT, FIELDS=U/PEQ", "OUTPUT", ["unknown field 'PEQ'", "did you mean PEEQ?", "U, S, LE, PE, PEEQ, RF"]),
    ("unknown parameter", edit("MATERIAL=M\n", "MATERIAL=M, THICKNES=2\n"),
     "*SOLID, ELSET=E, MATERIAL=M, THICKNES=2", "SOLID", ["unknown parameter THICKNES", "did you mean THICKNESS?"]),
    ("missing required parameter", edit("TYPE=Q4PE, ELSET=E", "ELSET=E"), "*ELEMENT, ELSET=E", "ELEMENT",
     ["missing required parameter TYPE"]),
    ("wrong count of data values", edit("2, 1, 0", "2, 1"), "2, 1", "NODE",
     ["wrong number of values", "expected 3 to 4", "got 2"]),
    ("node used but not defined", edit("1, 1, 2\n*END", "9, 1, 2\n*END"), "9, 1, 2", "BOUNDARY",
     ["node 9", "not defined"]),
    ("duplicate node id", edit("4, 0, 1\n", "4, 0, 1\n4, 0, 2\n"), "4, 0, 2", "NODE",
     ["duplicate node id 4", "already defined at", ":6"]),
    ("duplicate element id", edit("1, 1, 2, 3, 4\n", "1, 1, 2, 3, 4\n1, 2, 3, 4, 1\n"), "1, 2, 3, 4, 1", "ELEMENT",
     ["duplicate element id 1"]),
    ("element with a repeated node", edit("1, 1, 2, 3, 4", "1, 1, 2, 3, 3"), "1, 1, 2, 3, 3", "ELEMENT",
     ["element 1", "node 3 more than once"]),
    ("element with an unknown node", edit("1, 1, 2, 3, 4", "1, 1, 2, 3, 44"), "1, 1, 2, 3, 44", "ELEMENT",
     ["element 1", "node 44", "not defined"]),
    ("wrong node count for the type", edit("1, 1, 2, 3, 4", "1, 1, 2, 3"), "1, 1, 2, 3", "ELEMENT",
     ["element 1", "Q4PE element has 4 nodes, got 3"]),
    ("set used before it is defined", edit("*SOLID, ELSET=E, MATERIAL=M\n",
                                           "*SOLID, ELSET=LATE, MATERIAL=M\n*ELSET, ELSET=LATE\n1\n"),
     "*SOLID, ELSET=LATE, MATERIAL=M", "SOLID", ["element set LATE", "used before it is defined", "define it first"]),
    ("surface not defined", edit("1, 1, 2\n*END", "1, 1, 2\n*DLOAD\nTOPP, P, 1\n*END"), "TOPP, P, 1", "DLOAD",
     ["surface TOPP is not defined"]),
    ("material never assigned", edit("*SOLID", "*MATERIAL, NAME=M2, LAW=ELASTIC\nE=1, NU=0.2\n*SOLID"),
     "*MATERIAL, NAME=M2, LAW=ELASTIC", "MATERIAL", ["material M2 is never assigned", "no *SOLID"]),
    ("element with no *SOLID", edit("*MATERIAL", "*ELEMENT, TYPE=Q4PE\n2, 2, 3, 4, 1\n*MATERIAL"),
     "*ELEMENT, TYPE=Q4PE", "ELEMENT", ["element 2 has no *SOLID"]),
    ("step without *STATIC", edit("*STATIC\n1, 1, 0.1, 1\n", ""), "*STEP", "STEP", ["has no *STATIC"]),
    ("*END STEP missing", edit("*END STEP\n", ""), "*STEP", "STEP", ["*END STEP missing", "end of the deck"]),
    ("*END STEP missing before the next step", BASE.replace("*END STEP\n", "") + "*STEP\n*STATIC\n1, 1\n*END STEP\n",
     "*STEP", "STEP", ["*END STEP missing", "before the *STEP at line 17"]),
    ("*INCLUDE missing file", edit("*MATERIAL", "*INCLUDE, INPUT=nowhere/mesh.inp\n*MATERIAL"),
     "*INCLUDE, INPUT=nowhere/mesh.inp", "INCLUDE", ["nowhere/mesh.inp does not exist"]),
    ("*INCLUDE of itself", edit("*MATERIAL", "*INCLUDE, INPUT=bad.dat\n*MATERIAL"),
     "*INCLUDE, INPUT=bad.dat", "INCLUDE", ["includes itself"]),
    ("non-numeric data", edit("2, 1, 0", "2, one, 0"), "2, one, 0", "NODE",
     ["value 2", "x must be a number", "non-numeric 'one'"]),
    ("plugin parameter out of bounds", edit("E=100, NU=0.3", BOUND_LINE), BOUND_LINE, "MATERIAL",
     [BOUND_KEY, "bound"]),
    ("unknown element type", edit("TYPE=Q4PE", "TYPE=Q4PF"), "*ELEMENT, TYPE=Q4PF, ELSET=E", "ELEMENT",
     ["unknown element Q4PF", "did you mean Q4PE?"]),
    ("unknown law", edit("LAW=ELASTIC", "LAW=ELASTC"), "*MATERIAL, NAME=M, LAW=ELASTC", "MATERIAL",
     ["unknown material law ELASTC", "did you mean ELASTIC?"]),
    ("unknown law parameter", edit("E=100, NU=0.3", "E=100, NUU=0.3"), "E=100, NUU=0.3", "MATERIAL",
     ["unknown parameter NUU", "did you mean NU?"]),
    ("inverted element", edit("1, 1, 2, 3, 4", "1, 1, 2, 4, 3"), "1, 1, 2, 4, 3", "ELEMENT",
     ["element 1 is inverted or degenerate", "counter-clockwise"]),
    ("degenerate element", edit("3, 1, 1", "3, 1, 0"), "1, 1, 2, 3, 4", "ELEMENT",
     ["element 1 is inverted or degenerate"]),
    ("data outside a keyword", "1, 2, 3\n" + BASE, "1, 2, 3", "", ["data line outside any keyword"]),
    ("model data inside a step", edit("*BOUNDARY", "*NODE, NSET=LATE\n9, 5, 5\n*BOUNDARY"), "*NODE, NSET=LATE", "NODE",
     ["model data", "inside a step"]),
    ("*END STEP without *STEP", BASE + "*END STEP\n", None, "END STEP", ["*END STEP without a *STEP"]),
    ("step data outside a step", edit("*STEP\n", "*CLOAD\n1, 1, 5\n*STEP\n"), "*CLOAD", "CLOAD",
     ["must be inside a step"]),
    ("unreadable keyword line", edit("*SOLID, ELSET=E, MATERIAL=M", "*SOLID ELSET=E, MATERIAL=M"),
     "*SOLID ELSET=E, MATERIAL=M", "SOLID", ["cannot read this keyword line", "column"]),
    ("unreadable data line", edit("2, 1, 0", "2, 1 0"), "2, 1 0", "NODE", ["cannot read this data line", "column 6"]),
    ("undefined parameter", edit("E=100", "E=<YOUNG>"), "E=<YOUNG>, NU=0.3", "MATERIAL",
     ["parameter <YOUNG> is not defined"]),
    ("bad time increments", edit("1, 1, 0.1, 1", "1, 1, 2, 1"), "1, 1, 2, 1", "STATIC",
     ["min dt <= initial dt <= max dt"]),
    ("non-positive time", edit("1, 1, 0.1, 1", "1, -1, 0.1, 1"), "1, -1, 0.1, 1", "STATIC", ["must be > 0"]),
    ("dof out of range", edit("1, 1, 2\n*END", "1, 3, 3\n*END"), "1, 3, 3", "BOUNDARY", ["1 <= first <= last <= 6"]),
    ("foundation with an even count", edit("*STEP\n", "*FOUNDATION, NAME=F\n0, 0\n1, 0\n2, 0\n3, 0\n*STEP\n"),
     "*FOUNDATION, NAME=F", "FOUNDATION", ["odd number >= 3", "got 4"]),
    ("unknown contact law type", edit("*STEP\n", "*CONTACT LAW, NAME=C, TYPE=COULOMBE\nKP=1, KT=1, PHI=0\n*STEP\n"),
     "*CONTACT LAW, NAME=C, TYPE=COULOMBE", "CONTACT LAW", ["COULOMBE", "did you mean COULOMB?"]),
    ("bad GAUSS", edit("*STEP\n", "*CONTACT, SURFACE=S, FOUNDATION=F, LAW=C, GAUSS=4\n*STEP\n"),
     "*CONTACT, SURFACE=S, FOUNDATION=F, LAW=C, GAUSS=4", "CONTACT", ["GAUSS must be one of 2, 3"]),
    ("bad face", edit("*MATERIAL", "*SURFACE, NAME=S\n1, S5\n*MATERIAL"), "1, S5", "SURFACE",
     ["face must be S1, S2, S3 or S4"]),
    ("undefined amplitude", edit("*BOUNDARY", "*BOUNDARY, AMPLITUDE=RAMP"), "*BOUNDARY, AMPLITUDE=RAMP", "BOUNDARY",
     ["amplitude RAMP is not defined"]),
    ("unknown control", edit("*BOUNDARY", "*CONTROLS\nRTOLL=1e-6\n*BOUNDARY"), "RTOLL=1e-6", "CONTROLS",
     ["unknown parameter RTOLL", "did you mean RTOL?"]),
    ("non-numeric check value", edit("*STEP\n", "*CHECK, NAME=C, TYPE=HERTZ\nP=big\n*STEP\n"), "P=big", "CHECK",
     ["P must be a number", "'big'"]),
    ("parameter given twice", edit("*SOLID, ELSET=E, MATERIAL=M", "*SOLID, ELSET=E, MATERIAL=M, elset=E"),
     "*SOLID, ELSET=E, MATERIAL=M, elset=E", "SOLID", ["parameter ELSET is given twice"]),
    ("mixed plane and axisymmetric", edit("*MATERIAL", "*ELEMENT, TYPE=CAX4, ELSET=E\n2, 2, 3, 4, 1\n*MATERIAL"),
     "*ELEMENT, TYPE=CAX4, ELSET=E", "ELEMENT", ["axisymmetric elements (Q4AX) mixed with plane ones (Q4PE"]),
    ("element of two *SOLIDs", edit("*STEP", "*SOLID, ELSET=E, MATERIAL=M\n*STEP"), None, "SOLID",
     ["element 1 already has a *SOLID (line 11)"]),
]


@pytest.mark.parametrize("text, at, keyword, words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_deck_is_reported_where_it_is(tmp_path, text, at, keyword, words):
    deck = tmp_path / "bad.dat"
    deck.write_text(text)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    lines = text.splitlines()
    if at is not None:
        line = lines.index(at) + 1
    else:   # the last line that starts with the keyword
        line = max(i + 1 for i, t in enumerate(lines) if t.upper().startswith("*" + keyword))
    found = [p for p in info.value.problems if p.line == line and p.keyword == keyword
             and all(w in p.message for w in words)]
    assert found, f"expected at line {line} *{keyword}: {words}; got:\n{info.value}"
    head = f"bad.dat:{line}: *{keyword}:" if keyword else f"bad.dat:{line}:"
    assert any(ln.endswith(head + " " + found[0].message) and "bad.dat" in ln for ln in str(info.value).splitlines())


def test_base_deck_is_valid(tmp_path):
    deck = tmp_path / "base.dat"
    deck.write_text(BASE)
    m = load_deck(deck)
    assert list(m.blocks[0].ids) == [1] and len(m.steps) == 1


def test_distinct_error_cases():
    assert len(CASES) >= 20 and len({c[0] for c in CASES}) == len(CASES)


def test_all_problems_are_collected_in_one_error(tmp_path):
    text = edit("2, 1, 0", "2, one, 0").replace("TYPE=Q4PE", "TYPE=Q4PF").replace("*END STEP\n", "")
    deck = tmp_path / "three.dat"
    deck.write_text(text)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    msgs = str(info.value).splitlines()
    assert len(msgs) == len(info.value.problems) >= 3
    assert all(m.startswith(str(deck) + ":") for m in msgs)
    assert {4, 7, 12} <= {p.line for p in info.value.problems}     # 2, one, 0 / *ELEMENT / *STEP


def test_error_in_included_file_names_that_file(tmp_path):
    (tmp_path / "mesh").mkdir()
    (tmp_path / "mesh" / "part.inp").write_text("*NODE\n1, 0, 0\n2, x, 0\n")
    deck = tmp_path / "main.dat"
    rest = BASE.split("*ELEMENT")[0].replace("*NODE\n1, 0, 0\n2, 1, 0\n", "")
    deck.write_text("*INCLUDE, INPUT=mesh/part.inp\n" + rest)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    (p,) = [p for p in info.value.problems if "non-numeric" in p.message]
    assert p.file.endswith("part.inp") and p.line == 3 and p.keyword == "NODE"


def test_recursive_include_through_another_file(tmp_path):
    (tmp_path / "a.inp").write_text("** a\n*INCLUDE, INPUT=b.inp\n")
    (tmp_path / "b.inp").write_text("*INCLUDE, INPUT=a.inp\n")
    deck = tmp_path / "main.dat"
    deck.write_text("*INCLUDE, INPUT=a.inp\n" + BASE)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    (p,) = [p for p in info.value.problems if p.keyword == "INCLUDE"]
    assert p.file.endswith("b.inp") and p.line == 1 and "a.inp includes itself" in p.message


def test_clockwise_elements_are_renumbered_with_a_notice_and_inverted_ones_named(tmp_path):
    # a 4 x 1 row of squares; elements 11 and 13 are given clockwise, 14 crossed (a bow tie)
    nodes = "".join(f"{i + 1}, {i % 5}, {i // 5}\n" for i in range(10))
    elems = "11, 1, 6, 7, 2\n12, 2, 3, 8, 7\n13, 3, 8, 9, 4\n14, 4, 5, 9, 10\n"
    text = f"*NODE\n{nodes}*ELEMENT, TYPE=Q4PE, ELSET=E\n{elems}*MATERIAL" + BASE.split("\n*MATERIAL", 1)[1]
    deck = tmp_path / "inv.dat"
    deck.write_text(text)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    bad = {p.message.split()[1] for p in info.value.problems if "inverted" in p.message}
    assert bad == {"14"}
    # the independent check: the shoelace area of the corners is negative exactly for 11 and 13
    xy = {i + 1: (i % 5, i // 5) for i in range(10)}
    areas = {}
    for eid, conn in ((11, (1, 6, 7, 2)), (12, (2, 3, 8, 7)), (13, (3, 8, 9, 4))):
        x, y = np.array([xy[n] for n in conn], float).T
        areas[eid] = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert areas[11] < 0 and areas[13] < 0 and areas[12] > 0
    # without the bow tie the deck loads: 11 and 13 renumbered counter-clockwise, said in a notice
    deck.write_text(text.replace("14, 4, 5, 9, 10\n", "14, 4, 5, 10, 9\n"))
    m = load_deck(deck)
    (notice,) = [n for n in m.notices if "renumbered" in n]
    assert notice.startswith(f"{deck}:{text.splitlines().index('11, 1, 6, 7, 2') + 1}: *ELEMENT: 2 elements")
    assert notice.endswith(": 11, 13")
    ids = list(m.blocks[0].ids)
    for k, eid in enumerate(ids):
        x, y = m.coords[m.blocks[0].conn[k]].T
        assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(1.0)


def test_cli_check_exits_2_on_a_bad_deck(tmp_path, capsys):
    deck = tmp_path / "bad.dat"
    deck.write_text(edit("TYPE=Q4PE", "TYPE=Q4PF"))
    assert main(["check", str(deck)]) == 2
    err = capsys.readouterr().err
    assert "bad.dat:7: *ELEMENT: TYPE=Q4PF: unknown element Q4PF (did you mean Q4PE?)" in err


def test_unreadable_step_line_still_opens_its_step(tmp_path):
    deck = tmp_path / "step.dat"
    deck.write_text(edit("*STEP\n", "*STEP NAME=ONE\n"))
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    (p,) = info.value.problems              # no "*STATIC must be inside a step" after it
    assert (p.line, p.keyword) == (12, "STEP") and "cannot read this keyword line" in p.message


def test_empty_deck_is_an_error(tmp_path):
    deck = tmp_path / "empty.dat"
    deck.write_text("** nothing here\n\n")
    with pytest.raises(DeckError, match="empty.dat:1: the deck has no keyword lines"):
        load_deck(deck)


def test_deck_error_survives_pickling(tmp_path):
    import pickle
    deck = tmp_path / "bad.dat"
    deck.write_text(edit("TYPE=Q4PE", "TYPE=Q4PF"))
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    again = pickle.loads(pickle.dumps(info.value))
    assert again.problems == info.value.problems and str(again) == str(info.value)


def test_nodes_used_by_no_element_are_left_out_and_the_deck_runs(tmp_path):
    """Before, a node of no element made the stiffness singular at run time (exit 3) though
    check passed; now it is left out of the model with a notice, and the deck runs."""
    text = "*NODE\n99, 5, 5\n" + BASE.replace("*BOUNDARY\n1, 1, 2\n", "*BOUNDARY\n1, 1, 2\n2, 2, 2\n")
    deck = tmp_path / "d.dat"
    deck.write_text(text)
    m = load_deck(deck)
    assert 99 not in m.node_ids and len(m.node_ids) == 4
    assert m.notices == [f"{deck}:2: *NODE: 1 node used by no element is left out of the model (no "
                         f"stiffness): 99"]
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0
    # naming it in a step is an error where it is named
    deck.write_text(text.replace("2, 2, 2\n", "2, 2, 2\n99, 1, 2\n"))
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    (p,) = info.value.problems
    assert (p.line, p.keyword) == (text.splitlines().index("2, 2, 2") + 2, "BOUNDARY")
    assert "node 99 is used by no element" in p.message


def test_nodes_at_the_same_place_are_pointed_out(tmp_path):
    """Two blocks meshed side by side by *MESH share the places of their common side but not
    its nodes: a notice names them (the mesh is not joined there)."""
    deck = tmp_path / "d.dat"
    deck.write_text("*MESH, NAME=A, TYPE=Q4PE, LX=1, LY=1, NX=1, NY=2\n"
                    "*MESH, NAME=B, TYPE=Q4PE, X0=1, LX=1, LY=1, NX=1, NY=2\n"
                    "*ELSET, ELSET=ALL\nA, B\n*MATERIAL, NAME=M, LAW=ELASTIC\nE=1, NU=0.3\n"
                    "*SOLID, ELSET=ALL, MATERIAL=M\n*STEP\n*STATIC\n1, 1\n*END STEP\n")
    m = load_deck(deck)
    (notice,) = m.notices
    # at the line that made the first of them, under its keyword (*MESH, not *NODE)
    assert notice.startswith(f"{deck}:1: *MESH: 3 places of the mesh hold more than one node")
    # the independent count: the right side of A (x = 1) has 3 nodes, as has the left side of B
    at_one = np.flatnonzero(np.isclose(m.coords[:, 0], 1.0))
    assert len(at_one) == 6
    assert "2 and 7 at (1, 0)" in notice
