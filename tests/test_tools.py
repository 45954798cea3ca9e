"""Rigid tools (issue 15): a foundation with a reference node (u, v, rotation), its exact tangent
(NumPy and numba), tool forces against equilibrium and closed forms, several tools, the circle
generator, the contact stabilisation and the explanation of a singular tangent.

Decks: ``tests/data/tools/*.dat`` (each says what it models and what it checks).
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from lagamine_py import kernels
from lagamine_py.deck import DeckError, load_deck
from lagamine_py.elements.base import StepContext
from lagamine_py.foundation import Foundation, circle_error, circle_points, placed
from lagamine_py.solver.problem import build_problem

from runner import is_quadratic, run_deck

DATA = Path(__file__).resolve().parent / "data" / "tools"


def rows(path: Path, **match) -> list[dict]:
    with open(path, newline="") as fh:
        return [r for r in csv.DictReader(fh) if all(r[k] == v for k, v in match.items())]


def last(path: Path, **match) -> dict:
    return rows(path, **match)[-1]


# ------------------------------------------------------------------------------------------
# the tangent with respect to the tool's DOFs

ROLL_DECK = """*MESH, NAME=BLOCK, TYPE=Q8PE, X0=-2, Y0=-1, LX=4, LY=1, NX=2, NY=1
*NODE
1000, 0, 10
*MATERIAL, NAME=STEEL, LAW=ELASTIC
E=2000, NU=0.3
*SOLID, ELSET=BLOCK, MATERIAL=STEEL
*FOUNDATION, NAME=ROLL, REF NODE=1000, CIRCLE=OUTSIDE
0, 10, 10, 240, 300, 4
*CONTACT LAW, NAME=LAW, TYPE=COULOMB
KP=1e4, KT=1e4, PHI=<PHI>
*CONTACT, SURFACE=BLOCK_TOP, FOUNDATION=ROLL, LAW=LAW
*STEP, NLGEOM=<NLGEOM>
*STATIC
1, 1
*BOUNDARY
BLOCK_BOTTOM, 1, 2, 0
*END STEP
"""

#: (PHI, the roll's motion over the increment (dx, dy, dtheta), expected statuses)
REGIMES = {"stick": (5.0, (0.05, -0.25, 0.004), {1}), "slip": (0.1, (0.05, -0.25, 0.004), {2}),
           "frictionless": (0.0, (0.05, -0.25, 0.004), {2}),
           "open, stabilised": (0.3, (0.0, 0.01, 0.004), {0})}


def roll_problem(tmp_path, phi, nlgeom):
    deck = tmp_path / "roll.dat"
    deck.write_text(ROLL_DECK.replace("<PHI>", str(phi)).replace("<NLGEOM>", nlgeom))
    model = load_deck(deck)
    return model, build_problem(model)


def roll_state(problem, motion, seed=0):
    """u_old, u_new: the roll placed at (0.001, -0.002, 0.01), then moved by ``motion``; the
    block's top nodes moved a little at random."""
    rng = np.random.default_rng(seed)
    ndof = problem.ndof
    rot = problem.tools["ROLL"]
    u_old = np.zeros(ndof)
    u_old[rot] = [0.001, -0.002, 0.01]
    u_new = u_old.copy()
    u_new[:ndof - 1] += 2e-4 * rng.standard_normal(ndof - 1)
    u_new[rot] += motion
    return u_old, u_new


@pytest.mark.parametrize("nlgeom", ["NO", "YES"])
@pytest.mark.parametrize("regime", list(REGIMES))
@pytest.mark.parametrize("kernel", ["NUMPY", "NUMBA"])
def test_tangent_exact_in_the_tool_dofs(tmp_path, regime, nlgeom, kernel):
    """The whole assembled tangent -- the block's DOFs, the roll's translation AND rotation --
    against central differences of the assembled forces (Problem.check_tangent, every column),
    in stick, slip, frictionless slip and open (with the stabilisation's damping), on the NumPy
    path and the numba kernel's; kernels.calls proves which one ran."""
    if kernel == "NUMBA":
        pytest.importorskip("numba")
    phi, motion, statuses = REGIMES[regime]
    model, problem = roll_problem(tmp_path, phi, nlgeom)
    problem.set_kernel(kernel)
    u_old, u_new = roll_state(problem, motion)
    stab = {"BLOCK_TOP->ROLL": (200.0, 80.0, 0.5)} if regime.startswith("open") else None
    ctx = StepContext(nlgeom=nlgeom == "YES", stabilisation=stab)
    states = problem.init_states()
    before = kernels.calls["contact"]
    ev = problem.evaluate(u_new, u_old, states, ctx, True)
    assert (kernels.calls["contact"] > before) == (kernel == "NUMBA")
    k = problem.indices("contact")[0]
    assert set(np.unique(ev.states[k]["status"]).tolist()) == statuses
    rot = problem.tools["ROLL"]
    K = problem.pattern.matrix(ev.data).toarray()
    assert np.abs(K[rot][:, rot]).max() > 0 and np.abs(K[:, rot[2]]).max() > 0
    err = problem.check_tangent(u_new, u_old, states, ctx, h=1e-7)
    assert err < 1e-6, err


@pytest.mark.parametrize("nlgeom", ["NO", "YES"])
def test_numba_twin_of_the_tool_rows(tmp_path, nlgeom):
    """The numba kernel and the NumPy reference give the same forces, tangent and state on the
    roll (rotation, tool rows, stabilisation) to round-off."""
    pytest.importorskip("numba")
    out = {}
    for kernel in ("NUMPY", "NUMBA"):
        model, problem = roll_problem(tmp_path, 0.1, nlgeom)
        problem.set_kernel(kernel)
        u_old, u_new = roll_state(problem, (0.05, -0.2, 0.004), seed=3)
        ctx = StepContext(nlgeom=nlgeom == "YES", stabilisation={"BLOCK_TOP->ROLL": (50.0, 20.0, 0.3)})
        out[kernel] = problem.evaluate(u_new, u_old, problem.init_states(), ctx, True)
    a, b = out["NUMPY"], out["NUMBA"]
    np.testing.assert_allclose(b.f_int, a.f_int, rtol=0, atol=1e-12 * np.abs(a.f_int).max())
    np.testing.assert_allclose(b.data, a.data, rtol=0, atol=1e-12 * np.abs(a.data).max())
    k = 1
    for key in ("p", "tau", "lam", "status", "ps", "ts", "fdis", "stab"):
        np.testing.assert_allclose(b.states[k][key], a.states[k][key], rtol=1e-12, atol=1e-14,
                                   err_msg=key)


def test_contact_forces_are_self_equilibrated(tmp_path):
    """The contact group's forces on the faces and on the tool sum to zero, and so do their
    moments: a rigid motion of everything does no work."""
    model, problem = roll_problem(tmp_path, 0.1, "YES")
    u_old, u_new = roll_state(problem, (0.05, -0.25, 0.004))
    ev = problem.evaluate(u_new, u_old, problem.init_states(), StepContext(nlgeom=True), False)
    f = ev.results[1].f
    grp = problem.groups[1]
    n2 = 2 * len(model.node_ids)
    x = (model.coords + u_new[:n2].reshape(-1, 2))
    fx = f[:, :grp.nd:2].ravel()
    fy = f[:, 1:grp.nd:2].ravel()
    nodes = grp.face_nodes.ravel()
    tool = f[:, grp.nd:].sum(axis=0)
    xr = np.array([0.0, 10.0]) + u_new[problem.tools["ROLL"][:2]]
    assert abs(fx.sum() + tool[0]) < 1e-12 * np.abs(f).max()
    assert abs(fy.sum() + tool[1]) < 1e-12 * np.abs(f).max()
    moment = np.sum((x[nodes, 0] - xr[0]) * fy - (x[nodes, 1] - xr[1]) * fx)
    assert abs(moment + tool[2]) < 1e-11 * np.abs(f).max()


# ------------------------------------------------------------------------------------------
# runs: tool forces, closed forms, several tools

def test_punch_force_against_equilibrium_and_closed_form(tmp_path):
    out, cap, res = run_deck(DATA / "punch_force.dat", tmp_path)
    assert out.status == 0
    E, nu, KP, F, L, H = 210000.0, 0.3, 1e6, 600.0, 10.0, 5.0
    p = F / L
    tool = last(tmp_path / "tool_forces.csv", foundation="PUNCH")
    flat = last(tmp_path / "tool_forces.csv", foundation="FLAT")
    assert float(tool["RF2"]) == pytest.approx(-F, rel=1e-10)
    assert float(flat["RF2"]) == pytest.approx(F, rel=1e-10)       # the block's support
    # the closed form of the punch's travel: the block's shortening and two penalty layers
    assert -float(tool["U2"]) == pytest.approx(p * (1 - nu**2) * H / E + 2 * p / KP, rel=1e-9)
    assert float(tool["ref_node"]) == 1000 and float(tool["y"]) == pytest.approx(H + float(tool["U2"]))
    # the moment: the block spreads, u1 = nu (1 + nu) p x / E: the resultant acts off the node
    M = -F * nu * (1 + nu) * p * L / (2 * E)
    assert float(tool["RM6"]) == pytest.approx(M, rel=1e-6)
    # in step 1 the node's DOFs 2 and 6 are prescribed: its reactions are the tool's
    press = [r for r in rows(tmp_path / "reactions.csv", nset="1000") if r["step"] == "1"]
    tools = [r for r in rows(tmp_path / "tool_forces.csv", foundation="PUNCH") if r["step"] == "1"]
    assert press and len(press) == len(tools)
    for r, t in zip(press, tools):
        assert float(r["RF2"]) == pytest.approx(float(t["RF2"]), rel=1e-9)
        assert float(r["RM6"]) == pytest.approx(float(t["RM6"]), rel=1e-9)
    assert float(last(tmp_path / "energy.csv")["relative"]) < 1e-9     # small strain, flat


def test_two_tools_each_its_motion_one_surface(tmp_path):
    """A blank between a punch (force on its reference node) and a die (*FOUNDATION MOTION):
    one surface, two pairs kept apart in contact.csv, contact_totals.csv and the VTK series;
    the die's friction T = phi P drags the blank against its held edge."""
    out, cap, res = run_deck(DATA / "two_tools.dat", tmp_path)
    assert out.status == 0
    P, phi = 1000.0, 0.2
    die = last(tmp_path / "tool_forces.csv", foundation="DIE")
    punch = last(tmp_path / "tool_forces.csv", foundation="PUNCH")
    assert (float(die["RF1"]), float(die["RF2"])) == pytest.approx((phi * P, P), rel=1e-9)
    assert float(punch["RF2"]) == pytest.approx(-P, rel=1e-9)
    assert float(die["U1"]) == pytest.approx(0.01)
    assert float(last(tmp_path / "reactions.csv", nset="BLANK_LEFT")["RF1"]) == pytest.approx(-phi * P)
    pts = rows(tmp_path / "contact.csv", step="2", increment=die["increment"])
    for pair in ("BLANK->PUNCH", "BLANK->DIE"):
        mine = [r for r in pts if r["contact"] == pair]
        facing = [r for r in mine if r["status"] != "none"]
        assert len(mine) == 30 and len(facing) == 15      # each face meets the tool it faces
        y = [float(r["y"]) for r in facing]
        assert (min(y) > 1.9) == (pair == "BLANK->PUNCH") and (max(y) < 0.1) == (pair == "BLANK->DIE")
    totals = {r["contact"]: r for r in rows(tmp_path / "contact_totals.csv", step="2",
                                            increment=die["increment"])}
    assert float(totals["BLANK->DIE"]["T"]) == pytest.approx(phi * P)
    assert float(totals["BLANK->PUNCH"]["P"]) == pytest.approx(P)
    blocks = {name for _, name, _ in res.blocks()}
    assert {"contact BLANK->PUNCH", "contact BLANK->DIE", "foundation PUNCH"} <= blocks
    assert abs(float(last(tmp_path / "energy.csv")["relative"])) < 1e-9


def test_roll_torque_and_quadratic_newton(tmp_path):
    """A roll pressed by a force, then turned about its fixed centre (DOF 6): every point slips,
    T = phi P, the moment about the centre is the friction's, M = T R within the contact's
    extent; Newton converges quadratically while the roll turns."""
    out, cap, res = run_deck(DATA / "roll_turn.dat", tmp_path)
    assert out.status == 0
    roll = last(tmp_path / "tool_forces.csv", foundation="ROLL")
    tot = last(tmp_path / "contact_totals.csv")
    P, T = float(tot["P"]), float(tot["T"])
    assert -float(roll["RF2"]) == pytest.approx(20000.0, rel=1e-9)
    assert abs(T) == pytest.approx(0.2 * P, rel=1e-9)
    assert float(roll["UR6"]) == pytest.approx(0.02)
    assert abs(float(roll["RM6"])) == pytest.approx(abs(T) * 20.0, rel=5e-3)
    assert float(last(tmp_path / "reactions.csv", nset="1000")["RM6"]) == pytest.approx(
        float(roll["RM6"]), rel=1e-9)
    # the outputs of a model with a rotation DOF: the body's VTU (the reference node a point of
    # it, with no cell), the tool's VTU displaced by its rigid motion, compare against itself
    import meshio
    from lagamine_py.compare import compare_dirs
    body = res.body_files()[-1][1]
    model = load_deck(DATA / "roll_turn.dat")
    assert len(meshio.read(body).points) == len(model.node_ids)
    tool = [p for _, name, p in res.blocks() if name == "foundation ROLL"][-1]
    grid = meshio.read(tool)
    X = grid.points[:, :2]
    place = [float(roll[k]) for k in ("U1", "U2", "UR6")]
    np.testing.assert_allclose(grid.point_data["displacement"][:, :2],
                               placed(X, (0.0, 20.0), place) - X, atol=1e-12)
    assert compare_dirs(tmp_path, tmp_path).ok
    turning = [r for r in cap.results if r.step == 2 and len(r.residual_history) >= 4]
    assert turning, [r.residual_history for r in cap.results]
    for r in turning:
        order = is_quadratic(r.residual_history)
        assert order is not None and order > 1.8, r.residual_history


# ------------------------------------------------------------------------------------------
# the stabilisation, and a singular tangent explained

def hertz_force(tmp_path, stabilise=True, **params):
    deck = tmp_path / "hertz_force.dat"
    text = (DATA / "hertz_force.dat").read_text().replace(
        "../../../decks/meshes", str(Path(__file__).resolve().parents[1] / "decks" / "meshes"))
    if not stabilise:
        text = "\n".join(l for l in text.splitlines() if "CONTACT STABILIZATION" not in l)
    deck.write_text(text)
    return run_deck(deck, tmp_path / "out", parameters=params or None)


def test_point_contact_under_a_force_needs_the_stabilisation(tmp_path):
    """A cylinder touching a flat at a point, pressed by a platen under a force: without the
    stabilisation the first iteration is singular and the message says that the contact is not
    closed yet, naming the platen and the body moving together and the open pair."""
    out, cap, _ = hertz_force(tmp_path, stabilise=False)
    assert out.status == 3 and not cap.results
    assert "contact is not closed yet" in out.message
    assert "tool PLATEN (reference node 1000) (y) with the body of elements" in out.message
    assert "ARC->FLAT: 0 of 36 points closed" in out.message
    assert "*CONTACT STABILIZATION" in out.message


def test_singular_tangent_of_an_all_slipping_contact_is_explained_as_such(tmp_path):
    """The Coulomb block of the stability study at KT = 2e9 (24 000 E/h): the press's first
    attempts meet a tangent singular in x because every contact point slips at the iterate (the
    trial states of a very stiff KT), not because the contact is open (it was, at the start of
    the increment) nor for want of a *BOUNDARY (every point is closed).  The log says so; the
    cut-backs then find the stick points and the run completes."""
    deck = Path(__file__).resolve().parents[1] / "tools" / "study_decks" / "block_study.dat"
    out, cap, _ = run_deck(deck, tmp_path / "out", parameters={"KT": 2e9})
    assert out.status == 0
    failed = [l for l in (tmp_path / "out" / "block_study.log").read_text().splitlines()
              if "attempt failed" in l and "singular" in l and "INFO" in l]
    assert len(failed) == 2, failed
    for line in failed:
        assert "the body of elements 1..32 (x) can move freely: held only by friction" in line
        assert "BLOCK_BOTTOM->FLAT: 24 of 24 points closed, none sticking" in line
        assert "not closed yet" not in line and "add the *BOUNDARY" not in line


def test_stabilised_point_contact_matches_hertz(tmp_path):
    """With *CONTACT STABILIZATION it runs: the platen carries F, the flat F, Hertz's a and p0
    at P = 2 F (the coarse mesh's accuracy, as decks/hertz.dat driven by a displacement), and
    the damping took a small part of the work, which the energy balance accounts for."""
    from lagamine_py.checks.base import evaluate_checks
    out, cap, res = hertz_force(tmp_path)
    assert out.status == 0
    F = 8000.0
    platen = last(tmp_path / "out" / "tool_forces.csv", foundation="PLATEN")
    flat = last(tmp_path / "out" / "tool_forces.csv", foundation="FLAT")
    assert float(platen["RF2"]) == pytest.approx(-F, rel=1e-9)
    assert float(flat["RF2"]) == pytest.approx(F, rel=1e-9)
    model = load_deck(tmp_path / "hertz_force.dat")
    checks = {r["name"]: r for r in evaluate_checks(model.checks, tmp_path / "out")}
    assert checks["HERTZ"]["errors"]["a"] < 0.01 and checks["HERTZ"]["errors"]["p0"] < 0.02
    assert checks["HERTZ"]["measured"]["P"] == pytest.approx(2 * F, rel=2e-3)
    energy = last(tmp_path / "out" / "energy.csv")
    assert 0 < float(energy["stabilisation"]) < 0.005 * float(energy["work"])
    assert checks["ENERGY"]["error"] < 0.005


# ------------------------------------------------------------------------------------------
# the circle generator

@pytest.mark.parametrize("start, end, arcs", [(200, 340, 4), (0, 90, 1), (-170, 170, 12)])
@pytest.mark.parametrize("body", ["INSIDE", "OUTSIDE"])
def test_circle_points_on_the_circle_and_the_closed_form_error(start, end, arcs, body):
    xc, yc, R = 3.0, -2.0, 7.5
    pts = circle_points(xc, yc, R, start, end, arcs, body)
    assert len(pts) == 2 * arcs + 1
    np.testing.assert_allclose(np.hypot(pts[:, 0] - xc, pts[:, 1] - yc), R, rtol=1e-14)
    f = Foundation(pts)
    assert not f.shape_problems()
    s = np.linspace(-1, 1, 401)
    arc = np.repeat(np.arange(arcs), len(s))
    X, _ = f.evaluate(arc, np.tile(s, arcs))
    r = np.hypot(X[:, 0] - xc, X[:, 1] - yc)
    err = circle_error(R, start, end, arcs)
    assert np.all(r <= R * (1 + 1e-14))                      # the parabolas lie inside
    assert err * (1 - 1e-3) <= (R - r).max() <= err * (1 + 1e-9)   # sampled: at most the bound
    Xm, _ = f.evaluate(np.arange(arcs), np.full(arcs, 1 / math.sqrt(2)))
    np.testing.assert_allclose(R - np.hypot(Xm[:, 0] - xc, Xm[:, 1] - yc), err, rtol=1e-9)
    phi = math.radians((end - start) / (2 * arcs))
    assert err == pytest.approx(R * phi**4 / 32, rel=phi**2)   # the small-angle form
    # the body's side: the left of the direction of travel
    inside = f.side(np.array([[xc, yc]]) + 0.5 * (pts[arcs] - [xc, yc]),
                    np.array([pts[arcs] - [xc, yc]]))
    assert inside[0] == (1 if body == "INSIDE" else -1)


def test_circle_keyword_and_its_errors(tmp_path):
    deck = tmp_path / "c.dat"
    base = ROLL_DECK.replace("<PHI>", "0.1").replace("<NLGEOM>", "NO")
    deck.write_text(base)
    model = load_deck(deck)
    spec = model.foundations["ROLL"]
    np.testing.assert_allclose(spec.points, circle_points(0, 10, 10, 240, 300, 4, "OUTSIDE"))
    assert spec.centre == (0.0, 10.0) and model.node_ids[spec.ref_node] == 1000
    for bad, words in (("0, 10, 10, 300, 240, 4", ["start < end < start + 360"]),
                       ("0, 10, -1, 240, 300, 4", ["radius must be > 0"]),
                       ("0, 10, 10, 0, 360, 4", ["a whole circle is closed"]),
                       ("0, 10, 10, 240, 300, 0", ["arcs must be >= 1"])):
        deck.write_text(base.replace("0, 10, 10, 240, 300, 4", bad))
        with pytest.raises(DeckError) as info:
            load_deck(deck)
        text = str(info.value)
        assert "c.dat:8: *FOUNDATION" in text and all(w in text for w in words), text
    # INSIDE: the block below lies outside the circle: the side check refuses it
    deck.write_text(base.replace("CIRCLE=OUTSIDE", "CIRCLE=INSIDE"))
    with pytest.raises(DeckError, match="lie on the right of foundation ROLL"):
        load_deck(deck)


# ------------------------------------------------------------------------------------------
# placements, motion with an angle

def test_foundation_motion_with_an_angle_turns_about_the_centre(tmp_path):
    """*FOUNDATION MOTION dx, dy, angle on a tool without a reference node turns it about XC,
    YC; on one with a reference node it prescribes the node's DOFs 1, 2, 6."""
    deck = tmp_path / "m.dat"
    deck.write_text(TWO_FLATS)
    out, cap, _ = run_deck(deck, tmp_path / "out")
    assert out.status == 0
    r = cap.results[-1]
    pts = np.array([[10.0, 1.0], [0.0, 1.0], [-10.0, 1.0]])
    np.testing.assert_allclose(r.foundations["TOP"], placed(pts, (0.0, 1.0), (0.001, -0.0002, 0.001)),
                               atol=1e-15)
    ts = r.tools["TOP"]
    assert ts.ref_node is None and np.allclose(ts.placement, [0.001, -0.0002, 0.001])
    ref = r.tools["BOTTOM"]
    assert ref.ref_node == 500 and np.allclose(ref.placement, [0.0, 0.0002, -0.0005])
    assert {"UR6 500", "U1 500", "U2 500"} & set(r.loads)


TWO_FLATS = """*MESH, NAME=B, TYPE=Q8PE, X0=-1, Y0=0, LX=2, LY=1, NX=2, NY=1
*NODE
500, 0, -1
*MATERIAL, NAME=M, LAW=ELASTIC
E=1000, NU=0.3
*SOLID, ELSET=B, MATERIAL=M
*FOUNDATION, NAME=TOP, XC=0, YC=1
10, 1
0, 1
-10, 1
*FOUNDATION, NAME=BOTTOM, REF NODE=500
-10, 0
0, 0
10, 0
*CONTACT LAW, NAME=C, TYPE=COULOMB
KP=1e5, KT=1e5, PHI=0
*CONTACT, SURFACE=B_TOP, FOUNDATION=TOP, LAW=C
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=BOTTOM, LAW=C
*STEP, NLGEOM=YES
*STATIC
0.5, 1, 1e-3, 0.5
*BOUNDARY
B_LEFT, 1, 1, 0
*FOUNDATION MOTION, NAME=TOP
0.001, -0.0002, 0.001
*FOUNDATION MOTION, NAME=BOTTOM
0, 0.0002, -0.0005
*END STEP
"""


def test_every_kernel_mutation_still_finds_its_text(monkeypatch):
    """``tools/kernel_mutations.py`` replaces a text that must occur exactly once in its file: a
    rewrite that moves the text leaves the mutation (and the branch it proves) untested, which
    the tool only says when it is run (the NumPy RO branch swap was stale that way).  Here, not in
    tests/test_kernel_twins.py, which the tool runs on each mutant: there it would catch them all."""
    import importlib.util
    import sys
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "tools" / "kernel_mutations.py"
    spec = importlib.util.spec_from_file_location("kernel_mutations", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)     # its dataclass looks itself up
    spec.loader.exec_module(module)
    module.check(module.MUTATIONS)                 # SystemExit names the stale mutation


# ------------------------------------------------------------------------------------------
# tools/other_cpus.py: decks run with another processor's round-off

def test_other_cpus_runs_a_deck_and_judges_it_against_its_reference(tmp_path, capsys):
    """The tool runs the deck in a process with the configuration's environment and prints
    compare's verdict with the run's path (increments and solves, as its .sta file has them)."""
    import importlib.util
    import re
    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("other_cpus", root / "tools" / "other_cpus.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    assert tool.main(["coulomb_block", "--cpus", "prescott", "--keep", str(tmp_path)]) == 0
    line = capsys.readouterr().out.strip()
    found = re.fullmatch(r"prescott +coulomb_block +PASS \((\d+) increments, (\d+) solves\)", line)
    assert found, line
    sta = tmp_path / "prescott" / "coulomb_block" / "coulomb_block.sta"
    rows = [r for r in csv.DictReader(sta.open()) if r["failed"] == "no"]
    assert (int(found[1]), int(found[2])) == (len(rows), sum(int(r["iterations"]) for r in rows))
    assert tool.cpu_env({"OPENBLAS_CORETYPE": "Zen"})["OPENBLAS_CORETYPE"] == "Zen"
