"""The worked example of docs/meshes.md: meshes made with gmsh (docs/examples/meshes/gmsh_meshes.py),
committed as the .msh and .inp gmsh wrote, run end to end.

* Hertz line contact on the graded quarter cylinder, read from the .msh and from gmsh's .inp
  export (plane-stress CPS8 and T3D3 lines, *IMPORT, ANALYSIS=PLANE STRAIN): a and p0 within
  1 % of the closed form (Johnson, Contact Mechanics 4.2), and the same numbers from both files.
* The punch: its profile, a 1D physical group apart from the block, becomes the foundation
  (*FOUNDATION, CURVE=PUNCH); its points lie on the geometry the script drew (a vertical side
  x = 4, a fillet of radius 1 about (3, 1), the flat face y = 0), in the order that keeps the
  block on the left; the deck (J2_TABLE block) runs.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.checks.base import evaluate_checks
from lagamine_py.deck import load_deck
from lagamine_py.solver import run

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples" / "meshes"


@pytest.fixture(scope="module")
def hertz_runs(tmp_path_factory):
    out = {}
    for name in ("hertz_msh", "hertz_inp"):
        deck = EXAMPLES / f"{name}.dat"
        model = load_deck(deck)
        outdir = tmp_path_factory.mktemp(name)
        outcome = run(model, outdir, deck_path=deck, progress=False)
        assert outcome.status == 0, outcome.message
        (check,) = evaluate_checks(model.checks, outdir)
        out[name] = (model, check)
    return out


@pytest.mark.parametrize("name", ["hertz_msh", "hertz_inp"])
def test_hertz_on_the_gmsh_mesh_within_one_percent(hertz_runs, name):
    model, check = hertz_runs[name]
    assert check["message"] == ""
    assert abs(check["errors"]["a"]) < 0.01 and abs(check["errors"]["p0"]) < 0.01, check
    # the mesh the script asked for: Q8 only, graded from 0.04 mm at the contact point
    (blk,) = model.blocks
    assert blk.type == "Q8PE" and len(blk.ids) > 300
    # the contact side's nodes, mid-side nodes too, on the circle R = 10 (gmsh puts them on it)
    assert np.allclose(np.linalg.norm(model.coords[model.nsets["ARC"]], axis=1), 10.0, rtol=1e-12)
    assert len(model.surfaces["ARC"].elements) > 30


def test_msh_and_inp_give_the_same_answer(hertz_runs):
    (ma, a), (mb, b) = hertz_runs["hertz_msh"], hertz_runs["hertz_inp"]
    assert np.allclose(ma.coords, mb.coords, rtol=0, atol=1e-12 * 10)   # .inp prints 14 digits
    for q in ("a", "p0", "P"):
        assert a["measured"][q] == pytest.approx(b["measured"][q], rel=1e-9)


def exact_profile_distance(pts):
    """Distance of points to the punch profile the script drew."""
    x, y = pts.T
    side = np.where(y >= 1, np.abs(x - 4.0), np.inf)
    fillet = np.where((x >= 3) & (y <= 1), np.abs(np.hypot(x - 3.0, y - 1.0) - 1.0), np.inf)
    flat = np.where(x <= 3, np.abs(y), np.inf)
    return np.minimum(np.minimum(side, fillet), flat)


@pytest.mark.parametrize("mesh", ["punch.msh", "punch.inp"])
def test_the_punch_profile_is_the_drawn_curve(tmp_path, mesh):
    deck = tmp_path / "p.dat"
    deck.write_text((EXAMPLES / "punch.dat").read_text().replace("INPUT=punch.msh", f"INPUT={EXAMPLES / mesh}"))
    m = load_deck(deck)
    pts = m.foundations["PUNCH"].points
    assert len(pts) % 2 == 1 and len(pts) > 20
    assert exact_profile_distance(pts).max() < 1e-9                   # nodes and mid-nodes
    assert np.allclose(pts[0], [4.0, 3.0]) and np.allclose(pts[-1], [-0.5, 0.0])
    # the block on the left of the direction of travel: on the flat face (running towards -x)
    # the left normal points down, into the block
    d = pts[-1] - pts[-3]
    assert d[0] < 0 and abs(d[1]) < 1e-12
    # the curve's nodes are not nodes of the block
    assert m.coords[:, 1].max() <= 0.0 + 1e-12


def test_the_punch_deck_runs(tmp_path):
    deck = EXAMPLES / "punch.dat"
    model = load_deck(deck, parameters={"DEPTH": "0.04", "PHI": "0"})   # frictionless: 10 increments
    outcome = run(model, tmp_path, deck_path=deck, progress=False)
    assert outcome.status == 0, outcome.message
    rows = list(csv.DictReader(open(tmp_path / "contact.csv")))
    last = max(int(r["increment"]) for r in rows)
    p = np.array([float(r["p"]) for r in rows if int(r["increment"]) == last])
    x = np.array([float(r["x"]) for r in rows if int(r["increment"]) == last])
    assert (p[x < 2.5] > 100.0).all()                     # under the flat face: pressed past yield


def test_the_excerpts_in_the_docs_stand_in_the_files():
    """docs/meshes.md quotes the script and the decks in ``text`` blocks (``...`` for what it
    leaves out): every other line stands in the file it quotes."""
    import re
    page = (EXAMPLES.parents[1] / "meshes.md").read_text()
    quoted = re.findall(r"^```text\n(.*?)^```", page, re.S | re.M)
    sources = {"addPhysicalGroup": "gmsh_meshes.py", "hertz_quarter.msh": "hertz_msh.dat",
               "punch.msh": "punch.dat", "J2_TABLE": "punch.dat"}
    checked = 0
    for block in quoted:
        source = next((f for key, f in sources.items() if key in block), None)
        if source is None or "INPUT=path[" in block or "python docs/" in block:
            continue                          # the syntax summary; the command to remake meshes
        text = {line.strip() for line in (EXAMPLES / source).read_text().splitlines()}
        for line in block.splitlines():
            line = line.split("  #")[0].strip()          # the page's own comments
            if line not in ("", "..."):
                assert line in text, f"{source}: no line {line!r}"
                checked += 1
    assert checked >= 20
