"""The deck language: lexical forms, includes, parameters, and a complete deck built into a Model.

Every expected value below is read off the deck text of the test (a coordinate, a set member, a
parameter written there) or follows from the geometry of a structured rectangle (node positions
x0 + i*LX/(2*NX), mid-side nodes at the middle of their edge, counter-clockwise corners).
"""
import numpy as np
import pytest

from lagamine_py.deck import DeckError, KEYWORDS, load_deck, parse_deck, reference_markdown
from lagamine_py.deck.grammar import GRAMMAR
from lagamine_py.elements.quad import Quad8


def write(tmp_path, text, name="deck.dat"):
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


# ---------------------------------------------------------------- lexical forms

def test_numbers_names_pairs_and_line_numbers(tmp_path):
    text = ("** comment\n"
            "\n"
            "*foundation ,  name=flat\n"            # case, spaces around the comma
            "1.5e3, 1.5E+3\n"
            "1.5D3, .5,\n"                          # Fortran exponent, leading dot, trailing comma
            "  -2 ,  +3.\n"
            "*Contact   Law, NAME=dry, TYPE=coulomb\n"
            "KP=1e6, phi = 0.3\n"
            "*END STEP")                             # no newline at the end
    blocks = parse_deck(write(tmp_path, text))
    assert [b.keyword for b in blocks] == ["FOUNDATION", "CONTACT LAW", "END STEP"]
    assert [b.line for b in blocks] == [3, 7, 9]
    assert blocks[0].params == {"NAME": "flat"}
    rows = blocks[0].data
    assert [r.line for r in rows] == [4, 5, 6]
    assert [list(map(float, r.items)) for r in rows] == [[1500.0, 1500.0], [1500.0, 0.5], [-2.0, 3.0]]
    pairs = blocks[1].data[0].items
    assert [(p.key, p.text) for p in pairs] == [("KP", "1e6"), ("PHI", "0.3")]


def test_heading_text_is_free_and_crlf_is_accepted(tmp_path):
    text = "*HEADING\r\nA block, pressed (§7) <not a parameter>\r\n\r\n*NODE\r\n1, 0, 0\r\n"
    blocks = parse_deck(write(tmp_path, text))
    assert blocks[0].text == ["A block, pressed (§7) <not a parameter>"]
    assert blocks[1].keyword == "NODE" and blocks[1].data[0].line == 5
    # the grammar itself, on text that did not go through universal-newline reading
    lines = GRAMMAR.parse_text(text)
    assert [type(x).__name__ for x in lines] == ["KeywordLine", "TextLine", "KeywordLine", "DataLine"]
    assert lines[1].text == "A block, pressed (§7) <not a parameter>" and lines[3].line == 5


def test_include_keeps_file_and_line_and_data_continues(tmp_path):
    write(tmp_path, "** nodes only\n3, 1, 1\n4, 0, 1\n*NSET, NSET=TOP\n3, 4\n", "mesh/nodes.inp")
    deck = write(tmp_path, "*NODE\n1, 0, 0\n2, 1, 0\n*INCLUDE, INPUT=mesh/nodes.inp\n*NSET, NSET=BOT\n1, 2\n")
    blocks = parse_deck(deck)
    node = blocks[0]
    assert [(r.file.endswith("nodes.inp"), r.line) for r in node.data] == \
        [(False, 2), (False, 3), (True, 2), (True, 3)]
    top, bot = blocks[1], blocks[2]
    assert top.file.endswith("nodes.inp") and top.line == 4
    assert bot.file == str(deck) and bot.line == 5


def test_parameters_substitute_in_later_lines_and_can_be_overridden(tmp_path):
    write(tmp_path, "*NODE\n1, 0, 0\n", "mesh_a.inp")
    write(tmp_path, "*NODE\n1, 5, 0\n", "mesh_b.inp")
    deck = write(tmp_path, "*PARAMETER\nMESH = a\nX = 2.5\n*INCLUDE, INPUT=mesh_<MESH>.inp\n"
                           "*FOUNDATION, NAME=F<MESH>\n<X>, 0\n1, 0\n2, <x>\n")
    blocks = parse_deck(deck)
    assert float(blocks[1].data[0].items[1]) == 0.0           # from mesh_a.inp
    assert blocks[2].params["NAME"] == "Fa"
    assert float(blocks[2].data[0].items[0]) == 2.5 and float(blocks[2].data[2].items[1]) == 2.5
    blocks = parse_deck(deck, parameters={"mesh": "b"})
    assert float(blocks[1].data[0].items[1]) == 5.0           # from mesh_b.inp
    with pytest.raises(DeckError, match="XX given to override is not defined.*did you mean X"):
        parse_deck(deck, parameters={"XX": "1"})


def test_reference_lists_every_keyword():
    ref = reference_markdown()
    for name in KEYWORDS:
        assert f"`*{name}`" in ref
    assert "`NLGEOM=` (YES/NO, default NO)" in ref and "`GAUSS=` (2/3/LOBATTO2/LOBATTO3/LINEAR, default 3)" in ref


# ---------------------------------------------------------------- a complete deck

MIDS = "** mid-side nodes of the square\n5, 1, 0\n6, 2, 1\n7, 1, 2\n8, 0, 1\n"

FULL = """** every keyword once
*HEADING
Every keyword, once (test)
*PARAMETER
E = 2.1D5
NAME = steel
*NODE, NSET=ALLN
1, 0., 0.
2, 2.0, 0
3, 2, 2
4, 0, 2
*INCLUDE, INPUT=sub/mids.inp
*ELEMENT, TYPE=CPE8, ELSET=SQ
1, 1, 2, 3, 4, 5, 6, 7, 8
*MESH, NAME=B, TYPE=Q8PE, X0=5, Y0=-1, LX=4, LY=2, NX=2, NY=1
*NSET, NSET=BASE
1, 2
5
*NSET, NSET=GEN, GENERATE
1, 7, 3
*NSET, NSET=BOTH
base, B_LEFT
*ELSET, ELSET=ALLE, GENERATE
1, 3
*ELSET, ELSET=MIX
sq, 3
*SURFACE, NAME=TOPS
SQ, s3
3, S3
*MATERIAL, NAME=<NAME>, LAW=elastic
E=<E>, NU=.3
*MATERIAL, NAME=SOFT, LAW=RAMBERG_OSGOOD
E=1.5E+3, NU=0.25, SIGMA0=10, ALPHA=0.5, N=5
*SOLID, ELSET=SQ, MATERIAL=STEEL, THICKNESS=2.5
*SOLID, ELSET=B, MATERIAL=SOFT
*FOUNDATION, NAME=FLAT
-1, -1
5, -1
11, -1
*CONTACT LAW, NAME=DRY, TYPE=COULOMB
KP=1e6, KT=2e6, PHI=0.3
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=flat, LAW=DRY, GAUSS=2
*AMPLITUDE, NAME=RAMP
0, 0, 0.5, 1
1, 1
*CHECK, NAME=C1, TYPE=COULOMB
PHI=0.3, A=4
*STEP, NAME=PRESS, NLGEOM=YES, INC=50
*STATIC
0.1, 1, 1e-4, 0.25
*BOUNDARY
BASE, 1, 2
4, 1, 1, 0.5
*CLOAD, AMPLITUDE=RAMP
3, 2, -10
*DLOAD
TOPS, P, 7.5
*FOUNDATION MOTION, NAME=FLAT
0.1, -0.2
*OUTPUT, FREQUENCY=2, FIELDS=U S, CONTACT=NO
*CONTROLS
RTOL=1e-6, MAXIT=12
*END STEP
*STEP
*STATIC
0.5, 2
*BOUNDARY, OP=NEW
GEN, 2, 2, -0.01
*end step
"""


@pytest.fixture
def full(tmp_path):
    write(tmp_path, MIDS, "sub/mids.inp")
    path = write(tmp_path, FULL, "every_keyword.dat")
    return load_deck(path), FULL.splitlines()


def line_of(lines, text):
    return lines.index(text) + 1


def test_full_deck_model_data(full):
    m, lines = full
    assert m.name == "every_keyword" and m.heading == "Every keyword, once (test)"
    assert m.parameters == {"E": 210000.0, "NAME": "steel"}
    assert not m.axisymmetric
    # nodes: the square as written, then the *MESH nodes numbered on from 9
    assert list(m.node_ids[:8]) == list(range(1, 9))
    np.testing.assert_array_equal(m.coords[:8], [[0, 0], [2, 0], [2, 2], [0, 2], [1, 0], [2, 1], [1, 2], [0, 1]])
    # Q8 grid of 5 x 3 points without the 2 element centres
    assert len(m.node_ids) == 8 + 5 * 3 - 2 and list(m.node_ids[8:]) == list(range(9, 22))
    # blocks: one per *SOLID, in *SOLID order; CPE8 is Q8PE
    (sq, b) = m.blocks
    assert (sq.type, list(sq.ids), sq.material, sq.thickness, sq.elset) == ("Q8PE", [1], "STEEL", 2.5, "SQ")
    assert sq.conn.tolist() == [list(range(8))]
    assert sq.where.line == line_of(lines, "*SOLID, ELSET=SQ, MATERIAL=STEEL, THICKNESS=2.5")
    assert (b.type, list(b.ids), b.material, b.thickness) == ("Q8PE", [2, 3], "SOFT", 1.0)
    # sets: *NODE NSET takes the included data lines too; sets store rows / element ids
    assert sorted(m.nsets["ALLN"]) == list(range(8))
    assert list(m.nsets["BASE"]) == [0, 1, 4]
    assert list(m.nsets["GEN"]) == [0, 3, 6]
    assert set(m.nsets["BOTH"]) == {0, 1, 4} | set(m.nsets["B_LEFT"])
    assert list(m.elsets["ALLE"]) == [1, 2, 3] and list(m.elsets["MIX"]) == [1, 3]
    assert list(m.elsets["B"]) == [2, 3]
    surf = m.surfaces["TOPS"]
    assert list(surf.elements) == [1, 3] and list(surf.faces) == [3, 3]
    # plugins, validated (defaults filled by the plugin's declaration)
    assert m.materials["STEEL"].law.upper() == "ELASTIC"
    assert m.materials["STEEL"].params["E"] == 2.1e5 and m.materials["STEEL"].params["NU"] == 0.3
    assert m.materials["SOFT"].params["N"] == 5 and m.materials["SOFT"].params["E"] == 1500.0
    law = m.contact_laws["DRY"]
    assert (law.params["KP"], law.params["KT"], law.params["PHI"], law.params["B"]) == (1e6, 2e6, 0.3, 0.0)
    np.testing.assert_array_equal(m.foundations["FLAT"].points, [[-1, -1], [5, -1], [11, -1]])
    (c,) = m.contacts
    assert (c.surface, c.foundation, c.law, c.gauss) == ("B_BOTTOM", "FLAT", "DRY", 2)
    amp = m.amplitudes["RAMP"]
    assert list(amp.time) == [0, 0.5, 1] and list(amp.value) == [0, 1, 1] and amp(0.25) == 0.5
    (chk,) = m.checks
    assert chk["name"] == "C1" and chk["type"] == "COULOMB" and chk["params"] == {"PHI": 0.3, "A": 4.0}
    assert chk["where"].line == line_of(lines, "*CHECK, NAME=C1, TYPE=COULOMB")


def test_full_deck_steps(full):
    m, lines = full
    s1, s2 = m.steps
    assert (s1.name, s1.nlgeom, s1.max_increments) == ("PRESS", True, 50)
    assert (s1.dt0, s1.period, s1.dt_min, s1.dt_max) == (0.1, 1.0, 1e-4, 0.25)
    b1, b2 = s1.boundaries
    assert (b1.target, list(b1.nodes), b1.first, b1.last, b1.value) == ("BASE", [0, 1, 4], 1, 2, 0.0)
    assert (list(b2.nodes), b2.first, b2.last, b2.value) == ([3], 1, 1, 0.5)
    assert b2.where.line == line_of(lines, "4, 1, 1, 0.5")
    (cl,) = s1.cloads
    assert (list(cl.nodes), cl.dof, cl.value, cl.amplitude) == ([2], 2, -10.0, "RAMP")
    (dl,) = s1.dloads
    assert (dl.surface, dl.kind, dl.value, dl.amplitude) == ("TOPS", "P", 7.5, None)
    (mo,) = s1.motions
    assert (mo.foundation, mo.dx, mo.dy) == ("FLAT", 0.1, -0.2)
    assert (s1.output.frequency, s1.output.fields, s1.output.contact) == (2, ("U", "S"), False)
    assert s1.controls == {"RTOL": 1e-6, "MAXIT": 12}
    assert s1.op_new == set()
    # second step: defaults, OP=NEW recorded, dt_min/dt_max defaults bracket dt0
    assert (s2.name, s2.nlgeom, s2.max_increments) == ("Step-2", False, 1000)
    assert (s2.dt0, s2.period) == (0.5, 2.0) and s2.dt_min <= s2.dt0 <= s2.dt_max
    assert s2.op_new == {"BOUNDARY"}
    (b,) = s2.boundaries
    assert (list(b.nodes), b.first, b.last, b.value) == ([0, 3, 6], 2, 2, -0.01)


def test_mesh_geometry_sets_and_surfaces(full):
    m, _ = full
    x0, y0, lx, ly, nx, ny = 5.0, -1.0, 4.0, 2.0, 2, 1
    mesh_rows = np.arange(8, len(m.node_ids))
    xy = m.coords[mesh_rows]
    # every grid point x0 + i*LX/(2NX), y0 + j*LY/(2NY) except the element centres
    grid = {(x0 + i * lx / (2 * nx), y0 + j * ly / (2 * ny)) for i in range(2 * nx + 1) for j in range(2 * ny + 1)
            if not (i % 2 and j % 2)}
    assert {tuple(p) for p in xy} == grid
    conn = m.blocks[1].conn
    c = m.coords[conn]                                            # (e, 8, 2)
    # corners counter-clockwise: positive shoelace area = LX*LY / (NX*NY)
    x, y = c[:, :4, 0], c[:, :4, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    np.testing.assert_allclose(area, lx * ly / (nx * ny))
    # mid-side node k+4 in the middle of corners k, k+1
    np.testing.assert_allclose(c[:, 4:], 0.5 * (c[:, :4] + np.roll(c[:, :4], -1, axis=1)))
    # node sets on the four sides, and faces S1..S4 of the surfaces lying on them
    side = {"BOTTOM": (1, y0), "TOP": (1, y0 + ly), "LEFT": (0, x0), "RIGHT": (0, x0 + lx)}
    for name, (axis, value) in side.items():
        on_side = mesh_rows[np.isclose(xy[:, axis], value)]
        assert sorted(m.nsets[f"B_{name}"]) == sorted(on_side)
        surf = m.surfaces[f"B_{name}"]
        lookup = m.element_lookup()
        for eid, face in zip(surf.elements, surf.faces):
            blk, k = lookup[int(eid)]
            face_nodes = m.blocks[blk].conn[k][list(Quad8.faces[face - 1])]
            np.testing.assert_allclose(m.coords[face_nodes, axis], value)
        # every element touching the side has its face there once
        touching = {int(e) for e, nodes in zip(m.blocks[1].ids, conn) if np.sum(np.isin(nodes, on_side)) == 3}
        assert sorted(surf.elements) == sorted(touching)


def test_axisymmetric_aliases_and_second_mesh_numbering(tmp_path):
    text = ("*NODE\n1, 0, 0\n2, 1, 0\n3, 1, 1\n4, 0, 1\n*ELEMENT, TYPE=CAX4, ELSET=A\n7, 1, 2, 3, 4\n"
            "*MESH, NAME=M, TYPE=Q4AX, X0=2, Y0=0, LX=1, LY=1, NX=1, NY=1\n"
            "*MATERIAL, NAME=S, LAW=ELASTIC\nE=1, NU=0.3\n*ELSET, ELSET=ALL\nA, M\n"
            "*SOLID, ELSET=ALL, MATERIAL=S\n*STEP\n*STATIC\n1, 1, 1, 1\n*END STEP\n")
    m = load_deck(write(tmp_path, text))
    assert m.axisymmetric
    assert m.blocks[0].type == "Q4AX" and list(m.blocks[0].ids) == [7]
    # a second mesh numbers on after the largest ids: nodes 5..8, element 8
    assert list(m.node_ids) == [1, 2, 3, 4, 5, 6, 7, 8] and list(m.elsets["M"]) == [8]
    np.testing.assert_array_equal(m.coords[m.blocks[1].conn[0]], [[2, 0], [3, 0], [3, 1], [2, 1]])


def test_line_numbers_after_tab_indented_lines_are_the_files(tmp_path):
    """pyparsing parses a text with its tabs expanded (columns of 8): the line numbers are
    counted in that text, else every line after a tab-indented one is numbered later (a bad
    line's message pointed at another line).  Found by helper small6's differential test."""
    text = "x\n\t\t\t<P>\nA\n\t1,\t2\nB"
    assert [o.line for o in GRAMMAR.parse_text(text, 10)] == [11, 12, 13, 14, 15]
    deck = write(tmp_path, "*NODE\n\t\t1,\t0.,\t0.\n\t\t2,\t1.,\t0.\n3, 1 2\n")
    with pytest.raises(DeckError) as err:
        parse_deck(deck)
    assert [p.line for p in err.value.problems] == [4]
