"""Writers: VTU/PVD series, contact and reaction tables, status and log files.

Hand-built increments on a 2-element Q8 mesh (parallelograms, 3x3 Gauss) and a 2-element Q4
mesh (2x2 Gauss).  The Gauss values are closed-form fields evaluated at the Gauss points, so the
extrapolation to a node gives the same field at the node (it is exact for fields the rule
represents: quadratic for 3x3, linear for 2x2); the nodal value written is that value, or the
nearest bound of the Gauss values of the elements around the node when it lies outside them
(computed here node by node); the expected cell means are exact integrals (scipy ``dblquad``).
"""
from __future__ import annotations

import csv
import logging
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.integrate import dblquad

from lagamine_py.elements.quad import gauss_quad, quad_shape
from lagamine_py.model import Model, OutputRequest, Step
from lagamine_py.output import ContactPoints, FailedAttempt, IncrementResult, default_writers
from lagamine_py.elements.base import CellBlock
from lagamine_py.elements.quad import Q4PlaneStrain, Q8PlaneStrain
from lagamine_py.foundation import Foundation
from lagamine_py.results import read_vtu

import vtk  # noqa: E402  (a hard dependency)

SIGMA, TAU = 120.0, 35.0                       # uniform Q4 stress [SIGMA, 0, 0, TAU]


def shear_map(s, t):
    """Affine map of the Q8 strip: parent grid (s, t) -> parallelograms."""
    return np.stack([s + 0.3 * t, 1.2 * t], axis=-1)


def stress_field(xy):
    """Quadratic 4-vector field on the Q8 mesh (exactly extrapolated from 3x3 Gauss points)."""
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([1 + 2 * x - 3 * y + 0.5 * x * x, -2 + x * y, 0.25 * y * y - x, 3 + 0.1 * x - 0.7 * y * y],
                    axis=-1)


def peeq_field(xy):
    return 0.01 + 0.002 * xy[..., 0] + 0.003 * xy[..., 1]


def build_mesh():
    """Q8 strip (nodes 1..15 on a 5x3 grid, centres unused) and Q4 strip (nodes 16..21)."""
    s, t = np.meshgrid(np.arange(5) * 0.5, np.arange(3) * 0.5, indexing="xy")
    q8_xy = shear_map(s.ravel(), t.ravel())                       # row = 5*j + i
    row = lambda i, j: 5 * j + i                                  # noqa: E731
    q8 = np.array([[row(2 * e, 0), row(2 * e + 2, 0), row(2 * e + 2, 2), row(2 * e, 2),
                    row(2 * e + 1, 0), row(2 * e + 2, 1), row(2 * e + 1, 2), row(2 * e, 1)] for e in range(2)])
    q4_xy = np.array([[10, 0], [11, 0], [12, 0], [10, 1], [11, 1], [12, 1]], float)
    q4 = np.array([[0, 1, 4, 3], [1, 2, 5, 4]]) + len(q8_xy)
    coords = np.vstack([q8_xy, q4_xy])
    model = Model(name="deck", node_ids=np.arange(1, len(coords) + 1), coords=coords)
    return model, q8, q4


def gauss_points(coords, conn, n):
    N, _ = quad_shape(conn.shape[1], gauss_quad(n)[0])
    return np.einsum("qa,eai->eqi", N, coords[conn])


def make_result(model, q8, q4, step=1, inc=1, time=0.5, write_fields=True, contacts=True, seed=0):
    rng = np.random.default_rng(seed)
    n = len(model.coords)
    xg8, xg4 = gauss_points(model.coords, q8, 3), gauss_points(model.coords, q4, 2)
    cells = [CellBlock(Q8PlaneStrain, np.array([1, 2]), q8, stress_field(xg8), peeq_field(xg8)),
             CellBlock(Q4PlaneStrain, np.array([11, 12]), q4,
                       np.broadcast_to([SIGMA, 0.0, 0.0, TAU], xg4.shape[:2] + (4,)).copy(),
                       peeq_field(xg4))]
    cps, fnd = [], {}
    if contacts:
        x0 = rng.normal(size=(3, 2))
        cps = [ContactPoints(name="BOT->TOOL", element=np.array([1, 1, 2]), face=np.array([1, 1, 1]),
                             gauss=np.array([1, 2, 3]), x=x0 + rng.normal(size=(3, 2)) / 5,
                             p=rng.normal(size=3) / 3, tau=rng.normal(size=3) / 7,
                             gap=rng.normal(size=3) * 1e-7, slip=rng.random(3) / 9,
                             lam=rng.random(3) * np.pi, status=np.array([0, 1, 3], np.int8),
                             P=float(rng.normal()) / 3, T=float(rng.normal()) / 11, x0=x0,
                             vp=rng.normal(size=3) / 13, dvp=rng.normal(size=3) / 17,
                             dissip=rng.random(3) / 19, E=float(rng.random()) / 23)]
        xs = np.linspace(-2, 2, 5)
        fnd = {"TOOL": np.column_stack([xs + time, 0.1 * xs**2 - 1])}
    return IncrementResult(step=step, step_name="LOAD", increment=inc, time=time, step_time=time, dt=0.25,
                           iterations=3, residual=1.234e-9, cutbacks=0, coords0=model.coords,
                           u=rng.normal(size=(n, 2)) / 3, reaction=rng.normal(size=(n, 2)) * 7,
                           reactions_by_set={"LEFT": rng.normal(size=2) / 3, "BOT": rng.normal(size=2) / 7},
                           cells=cells, contacts=cps, foundations=fnd, write_fields=write_fields,
                           residual_history=[1.0, 2.5e-3, 1.234e-9])


@pytest.fixture
def run(tmp_path):
    """A run of three increments (the second without field output), writers not yet closed."""
    model, q8, q4 = build_mesh()
    writers = default_writers(tmp_path / "out", model)
    for w in writers:
        w.start_run()
    for w in writers:
        w.start_step(1, Step(name="LOAD"))
    results = [make_result(model, q8, q4, inc=k + 1, time=t, write_fields=wf, seed=k)
               for k, (t, wf) in enumerate([(0.25, True), (0.5, False), (1.0, True)])]
    for r in results:
        for w in writers:
            w.increment(r)
    yield tmp_path / "out", model, results, writers
    for w in writers:
        w.close(0, "done")


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_vtu_round_trip_gives_fields_exactly(run):
    out, model, results, _ = run
    body = read_vtu(out / "deck_0001.vtu")                       # written before close()
    r = results[2]
    assert np.array_equal(body["points"][:, :2], model.coords) and not body["points"][:, 2].any()
    assert np.array_equal(body["point:displacement"][:, :2], r.u)
    assert not body["point:displacement"][:, 2].any()
    assert np.array_equal(body["point:reaction"][:, :2], r.reaction)
    assert np.array_equal(body["point:node_id"], model.node_ids)
    assert np.array_equal(body["cell:element_id"], [1, 2, 11, 12])

    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(out / "deck_0001.vtu"))
    reader.Update()
    grid = reader.GetOutput()
    assert [grid.GetCellType(k) for k in range(grid.GetNumberOfCells())] == [23, 23, 9, 9]
    _, q8, q4 = build_mesh()
    conn = [[grid.GetCell(k).GetPointId(a) for a in range(grid.GetCell(k).GetNumberOfPoints())] for k in range(4)]
    assert conn == q8.tolist() + q4.tolist()


def patch_range(coords, blocks, field):
    """Per node, [min, max] of ``field`` over the Gauss points of the elements around it, node
    by node (the bound the nodal values must respect)."""
    lo = np.full(len(coords), np.inf)
    hi = -lo
    for conn, ngauss in blocks:
        values = field(gauss_points(coords, conn, ngauss))            # (e, q)
        for e, nodes in enumerate(conn):
            lo[nodes] = np.minimum(lo[nodes], values[e].min())
            hi[nodes] = np.maximum(hi[nodes], values[e].max())
    return lo, hi


def test_nodal_values_are_the_field_within_the_patch_range(run):
    out, model, _, _ = run
    body = read_vtu(out / "deck_0000.vtu")
    _, q8, q4 = build_mesh()
    n8, n4 = np.unique(q8), np.unique(q4)
    X = model.coords
    S, peeq = body["point:stress"], body["point:PEEQ"]
    assert S.shape == (len(X), 6) and not S[:, 4:].any()            # XX YY ZZ XY, YZ = XZ = 0
    for k in range(4):
        lo, hi = patch_range(X, [(q8, 3)], lambda x: stress_field(x)[..., k])
        want = np.clip(stress_field(X[n8])[:, k], lo[n8], hi[n8])
        assert np.allclose(S[n8, k], want, rtol=1e-12, atol=1e-12), k
        if k == 0:                            # the clip acts on some nodes, not on the others
            exact = stress_field(X[n8])[:, k]
            assert (want != exact).any() and (want == exact).any()
    assert np.allclose(S[n4, :4], [SIGMA, 0, 0, TAU], rtol=1e-12)
    lo, hi = patch_range(X, [(q8, 3), (q4, 2)], peeq_field)
    nodes = np.r_[n8, n4]
    assert np.allclose(peeq[nodes], np.clip(peeq_field(X[nodes]), lo[nodes], hi[nodes]), rtol=1e-12)
    assert np.allclose(body["point:von_mises"][n4], np.hypot(SIGMA, np.sqrt(3) * TAU), rtol=1e-12)
    assert np.allclose(body["point:pressure"][n4], -SIGMA / 3, rtol=1e-12)
    unused = np.setdiff1d(np.arange(len(X)), nodes)                   # Q8 grid centres
    assert len(unused) == 2 and not S[unused].any()


def test_recovery_bounds_what_extrapolation_overshoots():
    """A PEEQ rising steeply across one Q8 element: extrapolated to the nodes it goes negative
    and above the largest Gauss value; recovered, it stays within them."""
    from lagamine_py.output.recovery import nodal_values
    model, q8, _ = build_mesh()
    xg = gauss_points(model.coords, q8[:1], 3)
    gauss = (np.maximum(xg[..., 0] - 0.5, 0.0) ** 2)[..., None]        # 0 on the left third
    plain = nodal_values(len(model.coords), [(Q8PlaneStrain, q8[:1], gauss)], bounded=False)
    bounded = nodal_values(len(model.coords), [(Q8PlaneStrain, q8[:1], gauss)])
    nodes = q8[0]
    assert plain[nodes].min() < 0 or plain[nodes].max() > gauss.max()
    assert bounded[nodes].min() >= gauss.min() and bounded[nodes].max() <= gauss.max()


def test_cell_data_are_exact_means(run):
    out, model, _, _ = run
    body = read_vtu(out / "deck_0000.vtu")
    S = body["cell:element_stress"]
    for e in range(2):   # exact integral means over the parallelograms (the affine map has constant J)
        for k in range(4):
            exact, _ = dblquad(lambda t, s: stress_field(shear_map(np.array(s), np.array(t)))[k],
                               e, e + 1, 0, 1, epsabs=1e-13, epsrel=1e-13)
            assert S[e, k] == pytest.approx(exact, rel=1e-11, abs=1e-12)
        centroid = shear_map(np.array(e + 0.5), np.array(0.5))
        assert body["cell:element_PEEQ"][e] == pytest.approx(peeq_field(centroid), rel=1e-12)
    assert np.allclose(S[2:, 0], SIGMA) and np.allclose(S[2:, 3], TAU) and not S[:, 4:].any()
    assert np.allclose(body["cell:element_von_mises"][2:], np.sqrt(SIGMA**2 + 3 * TAU**2), rtol=1e-12)
    assert np.allclose(body["cell:element_PEEQ"][2:], peeq_field(np.array([[11, 0.5], [12, 0.5]]) - [0.5, 0]),
                       rtol=1e-12)


def test_contact_and_foundation_parts(run):
    out, model, results, _ = run
    r = results[2]
    cp = r.contacts[0]
    c = read_vtu(out / "deck_contact_BOT-TOOL_0001.vtu")
    # at the reference positions, with the displacement to the current ones (warp keeps them on the body)
    assert np.array_equal(c["points"][:, :2], cp.x0)
    assert np.allclose(c["points"][:, :2] + c["point:displacement"][:, :2], cp.x, rtol=0, atol=1e-15)
    for name, attr in (("p", "p"), ("tau", "tau"), ("gap", "gap"), ("slip", "slip"), ("lambda", "lam"),
                       ("signed_slip", "vp"), ("slip_increment", "dvp"), ("dissipation", "dissip"),
                       ("status", "status"), ("element", "element"), ("gauss", "gauss")):
        assert np.array_equal(c[f"point:{name}"], getattr(cp, attr)), name
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(out / "deck_contact_BOT-TOOL_0001.vtu"))
    reader.Update()
    fd = reader.GetOutput().GetFieldData()
    codes = {fd.GetArray(k).GetName(): fd.GetArray(k).GetValue(0) for k in range(fd.GetNumberOfArrays())}
    assert {k: v for k, v in codes.items() if k.startswith("status_")} == {
        "status_open": 0, "status_stick": 1, "status_slip": 2, "status_none": 3}
    assert codes["TIME"] == r.time and codes["STEP"] == 1 and codes["INCREMENT"] == 3
    f = read_vtu(out / "deck_foundation_TOOL_0001.vtu")
    fx = f["points"][:, :2] + f["point:displacement"][:, :2]          # the current position
    assert len(fx) == 2 * 16 + 1
    # the arcs interpolate a parabola exactly; ends are the given points
    x = fx[:, 0] - r.time
    assert np.allclose(fx[:, 1], 0.1 * x**2 - 1, rtol=0, atol=1e-13)
    assert np.allclose(fx[[0, -1]], r.foundations["TOOL"][[0, -1]], rtol=0, atol=1e-15)
    assert np.allclose(np.diff(x), 4 / 32)


def test_sample_arcs_follows_each_arc():
    # two arcs, 4 intervals each: the given points are hit at parameters -1, 0, +1 of each arc,
    # and a quarter-parameter sample is the quadratic's value there: (3 P0 + 6 P1 - P2) / 8
    pts = np.array([[0, 0], [1, 1], [2, 0], [3, -2], [4, 0]], float)
    s = Foundation(pts).sample(4)
    assert len(s) == 9
    assert np.array_equal(s[[0, 2, 4, 6, 8]], pts)
    assert np.allclose(s[5], (3 * pts[2] + 6 * pts[3] - pts[4]) / 8)


def test_pvd_lists_every_file_with_increasing_time(run):
    out, _, _, _ = run
    root = ET.parse(out / "deck.pvd").getroot()
    sets = [(float(d.get("timestep")), int(d.get("part")), d.get("name"), d.get("file"))
            for d in root.iter("DataSet")]
    assert sets == [(0.25, 0, "body", "deck_0000.vtu"),
                    (0.25, 1, "contact BOT->TOOL", "deck_contact_BOT-TOOL_0000.vtu"),
                    (0.25, 2, "foundation TOOL", "deck_foundation_TOOL_0000.vtu"),
                    (1.0, 0, "body", "deck_0001.vtu"),
                    (1.0, 1, "contact BOT->TOOL", "deck_contact_BOT-TOOL_0001.vtu"),
                    (1.0, 2, "foundation TOOL", "deck_foundation_TOOL_0001.vtu")]
    assert all((out / f).exists() for _, _, _, f in sets)
    assert not (out / "deck_0002.vtu").exists() and not list(out.glob("*.tmp"))


def test_contact_tables(run):
    out, _, results, _ = run
    header, rows = read_csv(out / "contact.csv")
    # DECKS.md's columns, then the pair (an extension: decks with several contact pairs), then
    # the signed slip, its increment and the dissipation, appended (older readers keep working)
    assert header == ("step,increment,time,element,gauss,x,y,p,tau,gap,slip,lambda,status,contact,"
                      "signed_slip,slip_increment,dissipation").split(",")
    assert [(int(r[0]), int(r[1])) for r in rows] == [(1, 1)] * 3 + [(1, 3)] * 3   # output increments only
    for r, rows3 in ((results[0], rows[:3]), (results[2], rows[3:])):
        cp = r.contacts[0]
        got = np.array([[float(v) for v in row[5:12]] for row in rows3])
        want = np.column_stack([cp.x, cp.p, cp.tau, cp.gap, cp.slip, cp.lam])
        assert np.array_equal(got, want)                       # full precision
        got = np.array([[float(v) for v in row[14:17]] for row in rows3])
        assert np.array_equal(got, np.column_stack([cp.vp, cp.dvp, cp.dissip]))
        assert [float(row[2]) for row in rows3] == [r.time] * 3
        assert [(int(row[3]), int(row[4])) for row in rows3] == [(1, 1), (1, 2), (2, 3)]
        assert [row[12] for row in rows3] == ["open", "stick", "none"]
        assert [row[13] for row in rows3] == ["BOT->TOOL"] * 3
    header, rows = read_csv(out / "contact_totals.csv")
    assert header == ["step", "increment", "time", "contact", "P", "T", "dissipated_energy"]
    assert [(int(r[1]), r[3]) for r in rows] == [(1, "BOT->TOOL"), (2, "BOT->TOOL"), (3, "BOT->TOOL")]
    assert [tuple(map(float, r[4:7])) for r in rows] == [(x.contacts[0].P, x.contacts[0].T, x.contacts[0].E)
                                                         for x in results]


def test_reactions_table(run):
    out, _, results, _ = run
    header, rows = read_csv(out / "reactions.csv")
    assert header == ["step", "increment", "time", "nset", "RF1", "RF2", "RM6"]
    assert len(rows) == 6
    for k, row in enumerate(rows):
        r = results[k // 2]
        name = ("LEFT", "BOT")[k % 2]
        assert (int(row[0]), int(row[1]), float(row[2]), row[3]) == (1, r.increment, r.time, name)
        assert [float(row[4]), float(row[5])] == list(r.reactions_by_set[name])
        assert float(row[6]) == 0.0            # no reference node among its nodes


def test_status_and_log(run):
    out, _, results, writers = run
    logging.getLogger("lagamine_py.solver").info("newton says hello")
    status = next(w for w in writers if type(w).__name__ == "StatusWriter")
    status.failed_attempt(FailedAttempt(step=1, step_name="LOAD", increment=4, time=1.0, step_time=1.0, dt=0.5,
                               iterations=2, residual_history=[1.0, 2.0, 3.0], cutbacks=1,
                               reason="too many iterations, residual 3", message="diverging: residual grew"))
    header, rows = read_csv(out / "deck.sta")
    assert header[:8] == ["step", "step_name", "increment", "time", "dt", "iterations", "residual", "cutbacks"]
    assert [(int(r[2]), float(r[3]), r[8]) for r in rows] == [(1, 0.25, "no"), (2, 0.5, "no"), (3, 1.0, "no"),
                                                              (4, 1.5, "yes")]
    assert rows[0][1] == "LOAD" and int(rows[0][5]) == 3 and float(rows[0][6]) == 1.234e-9
    assert rows[3][9] == "too many iterations, residual 3"   # a comma in the reason survives
    log = (out / "deck.log").read_text()
    assert "run of deck deck started" in log
    assert log.count("residuals 1.000e+00 2.500e-03 1.234e-09") == 3
    assert "newton says hello" in log and "diverging: residual grew; residuals 1.000e+00 2.000e+00" in log
    assert float(rows[3][6]) == 3.0 and int(rows[3][7]) == 1
    status.close(3, "step LOAD did not converge")
    log = (out / "deck.log").read_text()
    assert "exit status 3: step LOAD did not converge" in log.splitlines()[-1]
    logging.getLogger("lagamine_py.solver").warning("after close")
    assert "after close" not in (out / "deck.log").read_text()


def test_no_contact_and_contact_no(tmp_path):
    model, q8, q4 = build_mesh()
    model.axisymmetric = True
    writers = default_writers(tmp_path, model)
    for w in writers:
        w.start_run()
    for w in writers:
        w.start_step(1, Step(name="A"))
    for w in writers:
        w.increment(make_result(model, q8, q4, contacts=False))
    for w in writers:   # a step with contact results but *OUTPUT, CONTACT=NO
        w.start_step(2, Step(name="B", output=OutputRequest(contact=False)))
    for w in writers:
        w.increment(make_result(model, q8, q4, step=2, time=1.0))
    for w in writers:
        w.close(0, "done")
    root = ET.parse(tmp_path / "deck.pvd").getroot()
    assert [int(d.get("part")) for d in root.iter("DataSet")] == [0, 0, 1, 2]
    assert read_csv(tmp_path / "contact.csv")[1] == [] and read_csv(tmp_path / "contact_totals.csv")[1] == []
    assert len(read_csv(tmp_path / "reactions.csv")[1]) == 4


def test_writer_modules_do_not_import_vtk():
    code = ("import sys; from lagamine_py.output import default_writers; from lagamine_py.model import Model; "
            "import lagamine_py.output.vtk, lagamine_py.output.tables, lagamine_py.output.status; "
            "default_writers('unused', Model(name='x')); print('vtk' in sys.modules)")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "False"


def test_resume_appends_and_drops_what_came_after_the_restart_point(tmp_path):
    model, q8, q4 = build_mesh()

    def drive(writers, incs, seed0):
        for w in writers:
            w.start_run()
        for w in writers:
            w.start_step(1, Step(name="LOAD"))
        results = [make_result(model, q8, q4, inc=k, time=0.25 * k, write_fields=k % 2 == 1, seed=seed0 + k)
                   for k in incs]
        for r in results:
            for w in writers:
                w.increment(r)
        for w in writers:
            w.close(0, "done")
        return results

    first = drive(default_writers(tmp_path, model), [1, 2, 3], 0)
    # the restart data held increment 2: increment 3 is computed again, with other numbers,
    # by writers built with append=True as the step controller builds them on a restart
    resumed = default_writers(tmp_path, model, append=True)
    again = drive(resumed, [3, 4, 5], 100)
    _, rows = read_csv(tmp_path / "reactions.csv")
    assert [int(r[1]) for r in rows] == [1, 1, 2, 2, 3, 3, 4, 4, 5, 5]
    want = [first[0], first[1], *again]
    assert [float(r[4]) for r in rows[::2]] == [x.reactions_by_set["LEFT"][0] for x in want]
    header, rows = read_csv(tmp_path / "contact.csv")
    assert header[0] == "step" and [int(r[1]) for r in rows[::3]] == [1, 3, 5]
    assert float(rows[3][7]) == again[0].contacts[0].p[0]
    _, rows = read_csv(tmp_path / "deck.sta")
    assert [int(r[2]) for r in rows] == [1, 2, 3, 4, 5]
    sets = [(float(d.get("timestep")), d.get("file"))
            for d in ET.parse(tmp_path / "deck.pvd").getroot().iter("DataSet") if d.get("part") == "0"]
    assert sets == [(0.25, "deck_0000.vtu"), (0.75, "deck_0001.vtu"), (1.25, "deck_0002.vtu")]
    assert np.array_equal(read_vtu(tmp_path / "deck_0001.vtu")["point:displacement"][:, :2], again[0].u)
    log = (tmp_path / "deck.log").read_text()
    assert "run of deck deck started" in log and "run of deck deck resumed" in log


@pytest.mark.parametrize("fields, present, absent", [
    (("S",), {"point:stress", "point:von_mises", "point:pressure", "cell:element_stress",
              "cell:element_von_mises"},
     {"point:displacement", "point:reaction", "point:PEEQ", "cell:element_PEEQ"}),
    (("U", "PEEQ"), {"point:displacement", "point:PEEQ", "cell:element_PEEQ"},
     {"point:stress", "point:reaction", "cell:element_stress", "cell:element_von_mises"}),
    ((), {"point:displacement", "point:reaction", "point:stress", "point:PEEQ", "cell:element_stress"},
     set()),
])
def test_output_fields_select_the_vtk_arrays(tmp_path, fields, present, absent):
    """*OUTPUT, FIELDS= limits the body files' arrays (the mesh and the ids are always there);
    the arrays written are the same values as with every field."""
    model, q8, q4 = build_mesh()
    w = default_writers(tmp_path, model, names=("VTK",))[0]
    w.start_run()
    w.start_step(1, Step(name="LOAD", output=OutputRequest(1, fields, True)))
    r = make_result(model, q8, q4)
    w.increment(r)
    body = read_vtu(tmp_path / "deck_0000.vtu")
    assert present <= set(body) and not (absent & set(body)), sorted(body)
    assert {"point:node_id", "cell:element_id"} <= set(body)
    if "point:displacement" in present:
        assert np.array_equal(body["point:displacement"][:, :2], r.u)
