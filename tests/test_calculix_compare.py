"""tools/calculix_compare.py: the CalculiX deck of every scene holds our deck's nodes, elements,
material, penalties and loads (read back by a parser of its own, not the writer's code), the
committed decks of tools/calculix_decks are the ones the command writes, CalculiX's result
files are read at their fixed columns, and (when ``ccx`` is installed) CalculiX and lagamine_py
give the same answer on the smallest scene."""
from __future__ import annotations

import shutil
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.deck import load_deck

TOOLS = Path(__file__).resolve().parents[1] / "tools"
sys.path.insert(0, str(TOOLS))
import calculix_compare as cc  # noqa: E402

SCENES = {s.name: s for group in cc.scenes(("16x8",)).values() for s in group}


# ------------------------------------------------------------------ reading an .inp back


def parse_inp(text: str) -> list[tuple[str, dict, list[list[str]]]]:
    """``[(KEYWORD, {PARAM: value}, data lines split at commas)]`` of a CalculiX input."""
    out = []
    for line in text.splitlines():
        if line.startswith("**") or not line.strip():
            continue
        if line.startswith("*"):
            head, *params = [p.strip() for p in line[1:].split(",")]
            opts = {}
            for p in params:
                key, _, value = p.partition("=")
                opts[key.strip().upper()] = value.strip()
            out.append((head.upper(), opts, []))
        else:
            out[-1][2].append([v.strip() for v in line.split(",") if v.strip()])
    return out


def read_inp(text: str) -> dict:
    """What the comparison needs from a CalculiX input: nodes by set, elements by set and type,
    surfaces, materials, contact, and per step its loads and boundary values."""
    kw = parse_inp(text)
    got = {"nodes": {}, "nset_nodes": defaultdict(list), "elements": {}, "etype": {},
           "surfaces": {}, "nsets": {}, "materials": defaultdict(dict), "steps": [],
           "boundary0": []}
    material = None
    for i, (key, opts, data) in enumerate(kw):
        if key == "NODE":
            for row in data:
                got["nodes"][int(row[0])] = (float(row[1]), float(row[2]))
                got["nset_nodes"][opts["NSET"]].append(int(row[0]))
        elif key == "ELEMENT":
            got["etype"][opts["ELSET"]] = opts["TYPE"]
            got["elements"][opts["ELSET"]] = {int(r[0]): tuple(map(int, r[1:])) for r in data}
        elif key == "SURFACE":
            got["surfaces"][opts["NAME"]] = sorted((int(r[0]), r[1]) for r in data)
        elif key == "NSET":
            got["nsets"][opts["NSET"]] = sorted(int(r[0]) for r in data)
        elif key == "MATERIAL":
            material = opts["NAME"]
        elif key in ("ELASTIC", "DEFORMATION PLASTICITY"):
            got["materials"][material][key] = [float(v) for v in data[0]]
        elif key == "SOLID SECTION":
            got["materials"][opts["MATERIAL"]]["ELSET"] = opts["ELSET"]
            got["materials"][opts["MATERIAL"]]["THICKNESS"] = float(data[0][0])
        elif key == "SURFACE BEHAVIOR":
            got["KP"] = float(data[0][0])
        elif key == "FRICTION":
            got["PHI"], got["KT"] = map(float, data[0])
        elif key == "CONTACT PAIR":
            got["pair"] = tuple(data[0])
        elif key == "STEP":
            got["steps"].append({"nlgeom": "NLGEOM" in opts, "inc": int(opts["INC"]),
                                 "dload": [], "boundary": []})
        elif key == "STATIC":
            got["steps"][-1]["static"] = [float(v) for v in data[0]]
        elif key == "DLOAD":
            got["steps"][-1]["dload"] += [(int(r[0]), r[1], float(r[2])) for r in data]
        elif key == "BOUNDARY":
            rows = [(r[0], int(r[1]), int(r[2]), float(r[3])) for r in data]
            (got["steps"][-1]["boundary"] if got["steps"] else got["boundary0"]).extend(rows)
    return got


def _node_ids(model, rows) -> list[int]:
    return sorted(int(model.node_ids[r]) for r in rows)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_ccx_deck_is_our_deck(name, tmp_path):
    """Every node, element, pressure face, imposed value, step time, material constant and
    penalty of our deck is in CalculiX's deck, and the rigid flat is a slab whose every node is
    prescribed (no unknowns), its top on the foundation's line, moved as the foundation."""
    ours, model = cc.write_decks(SCENES[name], tmp_path)
    got = read_inp((tmp_path / f"{name}.inp").read_text())
    ids = [int(i) for i in model.node_ids]
    # nodes: ours with their exact coordinates, then the slab's
    assert sorted(got["nset_nodes"]["NBLOCK"]) == sorted(ids)
    for i, (x, y) in zip(ids, model.coords):
        assert got["nodes"][i] == (float(x), float(y))
    # elements: ours, same ids and node order, of the matching CalculiX type
    block = model.blocks[0]
    assert got["etype"]["BLOCK"] == {"Q8PE": "CPE8", "Q8PER": "CPE8R"}[block.type]
    assert got["elements"]["BLOCK"] == {int(e): tuple(int(model.node_ids[r]) for r in c)
                                        for e, c in zip(block.ids, block.conn)}
    # material and thickness
    mat = model.materials[block.material]
    body = got["materials"]["BODY"]
    assert body["ELASTIC"] == [mat.params["E"], mat.params["NU"]]
    assert body["ELSET"] == "BLOCK" and body["THICKNESS"] == block.thickness
    if mat.law == "RAMBERG_OSGOOD":
        assert body["DEFORMATION PLASTICITY"] == [mat.params[k] for k in
                                                  ("E", "NU", "SIGMA0", "N", "ALPHA")]
    # contact: our surface is the slave, penalties and friction
    contact = model.contacts[0]
    law = model.contact_laws[contact.law].params
    surf = model.surfaces[contact.surface]
    assert got["pair"] == ("SBOT", "SFLAT")
    assert got["surfaces"]["SBOT"] == sorted((int(e), f"S{int(f)}")
                                             for e, f in zip(surf.elements, surf.faces))
    assert got["KP"] == pytest.approx(law["KP"], rel=1e-6)
    if law["PHI"] > 0:
        assert (got["PHI"], got["KT"]) == (law["PHI"], pytest.approx(law["KT"], rel=1e-6))
    else:
        assert "PHI" not in got
    # the slab: all its nodes prescribed in both directions from the start, top on the flat
    slab = got["nset_nodes"]["NSLAB"]
    assert not set(slab) & set(ids)
    assert ("NSLAB", 1, 2, 0.0) in got["boundary0"]
    y_flat = float(model.foundations[contact.foundation].points[0, 1])
    top = {n for e, f in got["surfaces"]["SFLAT"] for n in got["elements"]["SLAB"][e][2:4]}
    assert top and all(got["nodes"][n][1] == y_flat for n in top)
    assert {n for c in got["elements"]["SLAB"].values() for n in c} == set(slab)
    # steps: times, pressures per face, imposed values per node and DOF, foundation motions
    assert len(got["steps"]) == len(model.steps)
    for step, gs in zip(model.steps, got["steps"]):
        assert gs["nlgeom"] == step.nlgeom and gs["inc"] == step.max_increments
        assert gs["static"] == [step.dt0, step.period, step.dt_min, step.dt_max]
        want = sorted((int(e), f"P{int(f)}", d.value) for d in step.dloads
                      for e, f in zip(model.surfaces[d.surface].elements,
                                      model.surfaces[d.surface].faces))
        assert sorted(gs["dload"]) == want
        imposed = {(n, dof, v) for s, a, b, v in gs["boundary"] if s != "NSLAB"
                   for n in got["nsets"][s] for dof in range(a, b + 1)}
        assert imposed == {(n, dof, bc.value) for bc in step.boundaries
                           for n in _node_ids(model, bc.nodes)
                           for dof in range(bc.first, bc.last + 1)}
        moved = {(a, v) for s, a, b, v in gs["boundary"] if s == "NSLAB"}
        assert moved == ({(1, m.dx) for m in step.motions} | {(2, m.dy) for m in step.motions})


def test_committed_decks_are_current(tmp_path):
    """tools/calculix_decks holds what ``--write-decks`` writes today for the default scenes."""
    committed = sorted(p.name for p in cc.OUT_DECKS.iterdir())
    groups = cc.scenes()
    names = [s.name for g in (*cc.DEFAULT_SCENES, "block-8x4") for s in groups[g]]
    assert committed == sorted(f"{n}.{ext}" for n in names for ext in ("dat", "inp"))
    for scene in (s for g in (*cc.DEFAULT_SCENES, "block-8x4") for s in groups[g]):
        assert scene.ours(cc.OUT_DECKS) == (cc.OUT_DECKS / f"{scene.name}.dat").read_text()
        model = load_deck(cc.OUT_DECKS / f"{scene.name}.dat")
        assert cc.ccx_from_model(model) == (cc.OUT_DECKS / f"{scene.name}.inp").read_text(), \
            f"{scene.name}: run python tools/calculix_compare.py --decks-only"


def test_read_frd_fixed_columns(tmp_path):
    """A node's values run into its id and each other (``1-7.4E-05 4.8E-03``): read by column."""
    frd = tmp_path / "r.frd"
    frd.write_text(
        "  100CL  103 1.100000000         224                     0    3           1\n"
        " -4  CONTACT     6    1\n"
        " -5  COPEN       1    4    1    1\n"
        " -1         1-7.41529E-05 4.80358E-03 0.00000E+00 1.48306E+02-4.44917E+01 0.00000E+00\n"
        " -1        17-1.23488E-04 2.35812E-03 0.00000E+00 2.46976E+02 7.40929E+01 0.00000E+00\n"
        " -3\n")
    (blk,) = cc.read_frd(frd)
    assert blk["name"] == "CONTACT" and blk["time"] == 1.1
    np.testing.assert_array_equal(blk["values"][1], [-7.41529e-05, 4.80358e-03, 0.0,
                                                     148.306, -44.4917, 0.0])
    assert blk["values"][17][3] == 246.976


def test_read_totals(tmp_path):
    dat = tmp_path / "r.dat"
    dat.write_text("\n total force (fx,fy,fz) for set NSLAB and time  0.1100000E+01\n\n"
                   "       -6.000000E+02  2.000000E+03  0.000000E+00\n")
    assert cc.read_totals(dat) == [(1.1, -600.0, 2000.0)]


@pytest.mark.skipif(shutil.which("ccx") is None,
                    reason="CalculiX is not installed (ccx not on PATH: apt-get install calculix-ccx)")
def test_ccx_and_ours_agree_on_the_block(tmp_path):
    """The 8x4 Coulomb block without adhesion: at the end of the press both contact forces are
    the applied P = 100 MPa x 20 mm = 2000 N/mm (equilibrium), and once the whole interface
    slides T = PHI P exactly at every point, whatever the mesh and the penalties: T/P = 0.3 for
    both codes up to the 7 digits CalculiX prints (tolerance 1e-5).  A partial slip (too short
    a push), a wrong friction coefficient or penalty in either deck moves T/P off 0.3."""
    row = cc.run_scene(SCENES["block-8x4"], 1, tmp_path, shutil.which("ccx"))
    assert row["dofs"] == 242
    assert row["ours"]["T/P"] == pytest.approx(0.3, abs=1e-5)
    assert row["ccx"]["T/P"] == pytest.approx(0.3, abs=1e-5)
    model = load_deck(tmp_path / "block-8x4.dat")
    end_press = cc.model_step_start(model, 1)
    for incs in (cc.ours_increments(tmp_path / "out"),
                 cc.ccx_increments(tmp_path, model, cc.surface_nodes(model, "BLOCK_BOTTOM"))):
        (press,) = [i for i in incs if abs(i["time"] - end_press) < 1e-9]
        assert press["P"] == pytest.approx(2000.0, rel=1e-6)
        assert press["Q"] < 1e-6 * press["P"]
