"""``*IMPORT`` of gmsh meshes (format 2.2 and 4.1, ASCII and binary) and Abaqus/CalculiX ``.inp``.

The meshes are written out here by hand -- two 8-node quadrilaterals side by side on [0, 2] x
[0, 1], physical groups BODY (2D), BOTTOM (1D, y = 0), an unnamed 1D group on y = 1 (tag 3) and
CORNER (0D, the point (0, 0)) -- so that every expectation (ids, sets, faces, lines of the
file) is read off the text, not off the reader.  The binary files (``tests/data/two_quads_*``)
are the ASCII 4.1 text of :func:`msh41` opened in gmsh 4.15 and saved as binary 4.1 and 2.2
(meshio's own 4.1 writer does not write files its reader takes back).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.deck import DeckError, load_deck

NODES = [(0, 0), (1, 0), (2, 0), (2, 1), (1, 1), (0, 1), (0.5, 0), (1.5, 0), (2, 0.5), (1.5, 1),
         (0.5, 1), (0, 0.5), (1, 0.5)]                          # gmsh tags 1..13
QUADS = [(1, 2, 5, 6, 7, 13, 11, 12), (2, 3, 4, 5, 8, 9, 10, 13)]
BOTTOM = [(1, 2, 7), (2, 3, 8)]                                  # gmsh line3: end, end, mid
TOP = [(4, 5, 10), (5, 6, 11)]

STEPS = """*MATERIAL, NAME=M, LAW=ELASTIC
E=1000, NU=0.3
*SOLID, ELSET=BODY, MATERIAL=M
*STEP
*STATIC
1, 1
*BOUNDARY
BOTTOM, 1, 2
PHYSICAL_3, 2, 2, -0.01
*END STEP
"""


def msh22(quads=QUADS, extra="", nodes=NODES) -> str:
    els = ["1 15 2 4 1 1"]
    els += [f"{2 + k} 8 2 1 1 {a} {b} {m}" for k, (a, b, m) in enumerate(BOTTOM)]
    els += [f"{4 + k} 8 2 3 2 {a} {b} {m}" for k, (a, b, m) in enumerate(TOP)]
    els += [f"{6 + k} 16 2 2 1 " + " ".join(map(str, q)) for k, q in enumerate(quads)]
    els += extra.splitlines()
    return "\n".join(["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", "3",
                      '0 4 "CORNER"', '1 1 "BOTTOM"', '2 2 "BODY"', "$EndPhysicalNames",
                      "$Nodes", str(len(nodes))]
                     + [f"{k + 1} {x} {y} 0" for k, (x, y) in enumerate(nodes)]
                     + ["$EndNodes", "$Elements", str(len(els))] + els + ["$EndElements", ""])


def msh41(quads=QUADS) -> str:
    return "\n".join(
        ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames", "3",
         '0 4 "CORNER"', '1 1 "BOTTOM"', '2 2 "BODY"', "$EndPhysicalNames",
         "$Entities", "1 2 1 0", "1 0 0 0 1 4",
         "1 0 0 0 2 0 0 1 1 0", "2 0 1 0 2 1 0 1 3 0",
         "1 0 0 0 2 1 0 1 2 0", "$EndEntities",
         "$Nodes", f"1 {len(NODES)} 1 {len(NODES)}", f"2 1 0 {len(NODES)}"]
        + [str(k + 1) for k in range(len(NODES))] + [f"{x} {y} 0" for x, y in NODES]
        + ["$EndNodes", "$Elements", "4 7 1 7", "0 1 15 1", "1 1",
           "1 1 8 2"] + [f"{2 + k} {a} {b} {m}" for k, (a, b, m) in enumerate(BOTTOM)]
        + ["1 2 8 2"] + [f"{4 + k} {a} {b} {m}" for k, (a, b, m) in enumerate(TOP)]
        + ["2 1 16 2"] + [f"{6 + k} " + " ".join(map(str, q)) for k, q in enumerate(quads)]
        + ["$EndElements", ""])


DATA = Path(__file__).resolve().parent / "data"


def deck_for(tmp_path, mesh_name, text=None, params="", steps=STEPS) -> Path:
    deck = tmp_path / "d.dat"
    deck.write_text(f"*IMPORT, INPUT={mesh_name}{params}\n" + steps)
    return deck


def line_of(text: str, startswith: str) -> int:
    return next(k + 1 for k, t in enumerate(text.splitlines()) if t.startswith(startswith))


@pytest.fixture(params=["2.2", "4.1", "2.2 binary", "4.1 binary"])
def mesh_file(request, tmp_path):
    version = request.param.split()[0]
    path = tmp_path / "two.msh"
    if "binary" in request.param:
        path.write_bytes((DATA / f"two_quads_{version.replace('.', '')}_binary.msh").read_bytes())
    else:
        path.write_text(msh22() if version == "2.2" else msh41())
    return path


def test_every_format_gives_the_mesh_written(tmp_path, mesh_file):
    m = load_deck(deck_for(tmp_path, mesh_file.name))
    assert m.node_ids.tolist() == list(range(1, 14))            # numbered from 1, in file order
    assert np.allclose(m.coords, NODES)
    (blk,) = m.blocks
    assert blk.type == "Q8PE" and blk.ids.tolist() == [1, 2]
    assert (m.node_ids[blk.conn] == np.array(QUADS)).all()
    assert m.elsets["BODY"].tolist() == [1, 2]
    # 1D groups: a surface of the faces on their lines, the body on the left, and a node set
    for name, y, normal in (("BOTTOM", 0.0, -1.0), ("PHYSICAL_3", 1.0, 1.0)):
        surf = m.surfaces[name]
        assert sorted(zip(surf.elements.tolist(), surf.faces.tolist())) == \
            ([(1, 1), (2, 1)] if y == 0 else [(1, 3), (2, 3)])
        for e, f in zip(surf.elements, surf.faces):
            a, b = (m.coords[blk.conn[e - 1][[0, 1, 2, 3, 0][f - 1]]],
                    m.coords[blk.conn[e - 1][[0, 1, 2, 3, 0][f]]])
            assert a[1] == b[1] == y
            t = b - a
            assert np.sign(t[1] * 1 - t[0] * 0) == 0 and np.sign(t[0]) == -normal  # outward normal
        assert sorted(m.node_ids[m.nsets[name]].tolist()) == sorted({n for ln in (BOTTOM if y == 0 else TOP)
                                                                     for n in ln})
    assert m.node_ids[m.nsets["CORNER"]].tolist() == [1]


def test_an_imported_mesh_runs(tmp_path, mesh_file):
    deck = deck_for(tmp_path, mesh_file.name)
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0


def test_axisymmetric_reduced_and_a_set_of_everything(tmp_path):
    (tmp_path / "two.msh").write_text(msh22(nodes=[(x + 1.0, y) for x, y in NODES]))
    m = load_deck(deck_for(tmp_path, "two.msh", params=", ANALYSIS=AXISYMMETRIC, INTEGRATION=REDUCED, "
                                                      "ELSET=ALL", steps=STEPS.replace("BODY", "ALL")))
    assert m.axisymmetric and m.blocks[0].type == "Q8AXR" and m.elsets["ALL"].tolist() == [1, 2]


def test_ids_follow_what_the_deck_defined_before(tmp_path):
    (tmp_path / "two.msh").write_text(msh22())
    deck = tmp_path / "d.dat"
    deck.write_text("*NODE\n100, 9, 9\n*IMPORT, INPUT=two.msh\n" + STEPS)
    m = load_deck(deck)
    assert m.node_ids.tolist() == list(range(101, 114))          # node 100 (unused) left out
    assert m.blocks[0].ids.tolist() == [1, 2]
    assert any("1 node used by no element is left out of the model" in n and n.endswith(": 100")
               for n in m.notices)


def test_clockwise_gmsh_elements_are_renumbered_and_surfaces_follow(tmp_path):
    """A gmsh surface whose normal is -z has clockwise elements: renumbered with a notice; the
    surfaces on them stay on their lines, the body on their left."""
    turned = [(q[0], q[3], q[2], q[1], q[7], q[6], q[5], q[4]) for q in QUADS]
    (tmp_path / "two.msh").write_text(msh22(quads=turned))
    m = load_deck(deck_for(tmp_path, "two.msh"))
    (notice,) = [n for n in m.notices if "renumbered" in n]
    text = msh22(quads=turned)
    assert notice.startswith(f"{tmp_path / 'two.msh'}:{line_of(text, '6 16 ')}: *IMPORT: 2 elements given "
                             f"clockwise renumbered")
    blk = m.blocks[0]
    for name, y in (("BOTTOM", 0.0), ("PHYSICAL_3", 1.0)):
        surf = m.surfaces[name]
        for e, f in zip(surf.elements, surf.faces):
            conn = blk.conn[e - 1]
            a, b = m.coords[conn[f - 1]], m.coords[conn[f % 4]]
            assert a[1] == b[1] == y and (b[0] - a[0]) * (1 if y == 0 else -1) > 0
    assert main(["run", str(deck_for(tmp_path, "two.msh")), "-o", str(tmp_path / "out"), "-q"]) == 0


# ------------------------------------------------------------------------------------------
# errors: the mesh file and, in an ASCII file, its line

def problems_of(deck):
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    assert main(["check", str(deck)]) == 2                        # check refuses what run would
    return info.value.problems


@pytest.mark.parametrize("version", ["2.2", "4.1"])
def test_inverted_element_named_at_its_line_of_the_mesh_file(tmp_path, version):
    crossed = [QUADS[0], (2, 3, 5, 4, 8, 9, 10, 13)]             # element 2 crossed: a bow tie
    text = msh22(quads=crossed) if version == "2.2" else msh41(quads=crossed)
    (tmp_path / "two.msh").write_text(text)
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    line = line_of(text, "7 16 " if version == "2.2" else "7 2 3 5 4")
    assert (p.file, p.line, p.keyword) == (str(tmp_path / "two.msh"), line, "IMPORT")
    assert "element 2 is inverted or degenerate" in p.message


def test_binary_mesh_errors_name_the_file_at_the_import_line(tmp_path):
    (tmp_path / "two.msh").write_bytes((DATA / "two_quads_crossed_41_binary.msh").read_bytes())
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    assert (p.file, p.line, p.keyword) == (str(tmp_path / "d.dat"), 1, "IMPORT")
    assert "element 2 is inverted or degenerate" in p.message


def test_missing_node_and_unreadable_files(tmp_path):
    text = msh22(nodes=NODES[:12], quads=[QUADS[0][:5] + (14,) + QUADS[0][6:], QUADS[1]])
    (tmp_path / "two.msh").write_text(text.replace("\n13 1 0.5 0", ""))
    problems = problems_of(deck_for(tmp_path, "two.msh"))
    assert any("does not define" in p.message or "is not in the file" in p.message for p in problems)
    assert all(p.file.endswith("two.msh") for p in problems)
    # a node tag missing in the middle (node 7 written as 20): the first element using it
    text = msh22().replace("\n7 0.5 0 0\n", "\n20 0.5 0 0\n")
    (tmp_path / "two.msh").write_text(text)
    p = problems_of(deck_for(tmp_path, "two.msh"))[0]
    assert p.line == line_of(text, "2 8 2 1 1 1 2 7") and "names a node that the file does not define" in p.message
    # a file cut short
    text = msh22()
    (tmp_path / "two.msh").write_text(text[:text.index("6 16 2") + 9])
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    assert p.file.endswith("two.msh") and p.line > 0 and "cannot read the gmsh mesh" in p.message
    # not a mesh at all
    (tmp_path / "two.msh").write_text("hello\n")
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    assert p.file.endswith("two.msh") and p.line == 1 and "does not start with $MeshFormat" in p.message
    # no such file
    (p,) = problems_of(deck_for(tmp_path, "none.msh"))
    assert p.line == 1 and "none.msh does not exist" in p.message


def test_three_node_triangles_are_refused_and_told_what_to_do(tmp_path):
    text = msh22(extra="8 2 2 2 1 1 2 13")
    (tmp_path / "two.msh").write_text(text)
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    assert p.line == line_of(text, "8 2 2 2 1") and "3-node triangles lock" in p.message
    assert "Mesh.ElementOrder = 2" in p.message


def test_a_1d_group_inside_the_mesh_is_not_a_surface(tmp_path):
    text = msh22(extra="8 8 2 5 3 2 5 13")                       # the line between the two quads
    text = text.replace('$PhysicalNames\n3\n', '$PhysicalNames\n4\n1 5 "MIDDLE"\n')
    (tmp_path / "two.msh").write_text(text)
    (p,) = problems_of(deck_for(tmp_path, "two.msh"))
    assert p.line == line_of(text, "8 8 2 5 3") and "MIDDLE: its line lies inside the mesh, between " \
                                                    "elements 1 and 2" in p.message


def test_a_deck_surface_inside_the_mesh_is_refused(tmp_path):
    (tmp_path / "two.msh").write_text(msh22())
    deck = tmp_path / "d.dat"
    deck.write_text("*IMPORT, INPUT=two.msh\n*SURFACE, NAME=INNER\n1, S2\n" + STEPS)
    (p,) = problems_of(deck)
    assert (p.line, p.keyword) == (2, "SURFACE") and "face S2 of element 1 is shared with element 2" in p.message


def test_an_msh_given_to_include_is_one_error(tmp_path):
    (tmp_path / "two.msh").write_text(msh22())
    deck = tmp_path / "d.dat"
    deck.write_text("*HEADING\na deck\n*INCLUDE, INPUT=two.msh\n" + STEPS)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    (p,) = [p for p in info.value.problems if p.keyword == "INCLUDE"]
    assert p.line == 3 and "is a gmsh mesh, not deck text: read it with *IMPORT, INPUT=two.msh" in p.message
    assert len(info.value.problems) < 10                         # not thousands: the mesh is not read


# ------------------------------------------------------------------------------------------
# tool profiles: a 1D group apart from the body

def test_foundation_from_a_curve_of_3_node_lines(tmp_path):
    """A 1D group of lines that touch no 2D element is a curve: chained, each 3-node line a
    parabolic arc; the foundation's points are its nodes in chain order, as the first line
    runs (REVERSE the other way)."""
    pts = [(3, 2), (2.5, 2.1), (2, 2), (1.5, 2.1), (1, 2), (0.5, 2.1), (0, 2)]   # gmsh tags 14..20
    nodes = NODES + pts
    lines = [(18, 20, 19), (14, 16, 15), (16, 18, 17)]          # shuffled, each run right to left
    extra = "\n".join(f"{8 + k} 8 2 6 4 {a} {b} {m}" for k, (a, b, m) in enumerate(lines))
    text = msh22(nodes=nodes, extra=extra).replace('$PhysicalNames\n3\n', '$PhysicalNames\n4\n1 6 "DIE"\n')
    (tmp_path / "two.msh").write_text(text)
    steps = "*FOUNDATION, NAME=F, CURVE=DIE\n*FOUNDATION, NAME=G, CURVE=DIE, REVERSE\n" + STEPS
    m = load_deck(deck_for(tmp_path, "two.msh", steps=steps))
    # the first line of the group in the file runs from x = 1 to x = 0: the chain runs that way,
    # the body below on its left
    assert np.allclose(m.foundations["F"].points, pts)
    assert np.allclose(m.foundations["G"].points, m.foundations["F"].points[::-1])
    assert len(m.node_ids) == 13                                # the curve's nodes are not the body's
    assert "DIE" not in m.surfaces and "DIE" not in m.nsets


def test_curve_errors(tmp_path):
    (tmp_path / "two.msh").write_text(msh22())
    steps = "*FOUNDATION, NAME=F, CURVE=BOTTOM\n" + STEPS
    (p,) = problems_of(deck_for(tmp_path, "two.msh", steps=steps))
    assert "CURVE=BOTTOM: no curve of that name" in p.message and "BOTTOM is a surface" in p.message
    pts = [(3, 2), (2.5, 2.1), (2, 2), (5, 5), (6, 5), (5.5, 5.1)]
    extra = "8 8 2 6 4 14 16 15\n9 8 2 6 4 17 18 19"            # two pieces
    text = msh22(nodes=NODES + pts, extra=extra).replace('$PhysicalNames\n3\n', '$PhysicalNames\n4\n1 6 "DIE"\n')
    (tmp_path / "two.msh").write_text(text)
    (p,) = problems_of(deck_for(tmp_path, "two.msh", steps="*FOUNDATION, NAME=F, CURVE=DIE\n" + STEPS))
    assert "CURVE=DIE" in p.message and "it is not one chain: it has 2 pieces" in p.message
