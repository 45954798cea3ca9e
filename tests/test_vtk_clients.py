"""The VTK series of a whole run opens in every client: every VTU of press_slide is read by
meshio and by VTK with the same points and arrays; the PVD names its blocks, starts at t = 0 and
writes times as the steps define them; the fields are those a ParaView user expects; the run
ends by saying where the results are and what happened."""
from __future__ import annotations

import contextlib
import io
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.results import read_table, read_vtu

meshio = pytest.importorskip("meshio")          # the test extra installs it

DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"


@pytest.fixture(scope="module")
def press_slide(tmp_path_factory):
    out = tmp_path_factory.mktemp("vtk") / "press_slide"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["run", str(DECK), "-o", str(out), "-q"]) == 0
    return out, text.getvalue()


def pvd_sets(out):
    root = ET.parse(out / "press_slide.pvd").getroot()
    return [(d.get("timestep"), int(d.get("part")), d.get("name"), d.get("file"))
            for d in root.iter("DataSet")]


def test_every_vtu_opens_in_meshio_and_vtk(press_slide):
    out, _ = press_slide
    files = sorted(out.glob("*.vtu"))
    assert {f.name for f in files} == {s[3] for s in pvd_sets(out)}
    assert len(files) == 3 * len({s[0] for s in pvd_sets(out)})
    for f in files:
        mesh = meshio.read(f)
        ref = read_vtu(f)                                     # VTK's own reader
        np.testing.assert_array_equal(mesh.points, ref["points"], err_msg=f.name)
        assert sum(len(c.data) for c in mesh.cells) > 0, f.name   # no cell type dropped
        for name, values in mesh.point_data.items():
            np.testing.assert_array_equal(values, ref[f"point:{name}"], err_msg=f"{f.name}:{name}")
        for name, blocks in mesh.cell_data.items():
            np.testing.assert_array_equal(np.concatenate(blocks), ref[f"cell:{name}"],
                                          err_msg=f"{f.name}:{name}")
        units = "units: length mm, force N, stress MPa"
        assert {"TIME", "STEP", "INCREMENT", units} <= set(mesh.field_data)


def test_pvd_names_blocks_starts_at_zero_and_rounds_times(press_slide):
    out, _ = press_slide
    sets = pvd_sets(out)
    assert {(part, name) for _, part, name, _ in sets} == {
        (0, "body"), (1, "contact BLOCK_BOTTOM->FLAT"), (2, "foundation FLAT")}
    times = [float(t) for t, *_ in sets]
    assert times[:3] == [0.0] * 3 and times == sorted(times)
    # the steps' times: dt0 0.25 then 0.05 growing by 1.5 (the .sta), all written to 12 digits
    sta = read_table(out / "press_slide.sta")
    assert sorted({t for t in times if t > 0}) == sorted(set(sta["time"][sta["failed"] == "no"]))
    assert all(len(t) <= 14 for t, *_ in sets), [t for t, *_ in sets if len(t) > 14]


def test_body_fields_for_paraview(press_slide):
    out, _ = press_slide
    first = read_vtu(out / "press_slide_0000.vtu")
    last = read_vtu(sorted(out.glob("press_slide_0*.vtu"))[-1])
    n, e = len(last["points"]), len(last["cell:element_id"])
    for name in ("stress", "log_strain", "plastic_strain"):           # NLGEOM: logarithmic strain
        assert last[f"point:{name}"].shape == (n, 6)
        assert last[f"cell:element_{name}"].shape == (e, 6)
        assert not last[f"point:{name}"][:, 4:].any()                  # plane: YZ = XZ = 0
    for name in ("von_mises", "pressure", "PEEQ"):
        assert last[f"point:{name}"].shape == (n,) and last[f"cell:element_{name}"].shape == (e,)
    S = last["cell:element_stress"]
    np.testing.assert_allclose(last["cell:element_pressure"], -S[:, :3].sum(axis=1) / 3, rtol=1e-12)
    assert (last["point:PEEQ"] >= 0).all() and last["point:PEEQ"].max() > 0
    assert not first["point:displacement"].any() and not first["point:stress"].any()   # t = 0


def test_contact_points_move_with_the_body(press_slide):
    """Reference positions plus the displacement are the current positions of contact.csv (so
    a warp of any scale keeps them on the warped body, whose nodes move the same way)."""
    out, _ = press_slide
    c = read_table(out / "contact.csv")
    last_step, last_inc = c["step"][-1], c["increment"][-1]
    rows = (c["step"] == last_step) & (c["increment"] == last_inc)
    v = read_vtu(sorted(out.glob("press_slide_contact_*.vtu"))[-1])
    np.testing.assert_allclose(v["points"][:, :2] + v["point:displacement"][:, :2],
                               np.column_stack([c["x"][rows], c["y"][rows]]), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(v["points"][:, 1], 0.0)              # on the block's bottom
    for name in ("gap", "signed_slip", "slip_increment", "dissipation"):
        np.testing.assert_array_equal(v[f"point:{name}"], c[name][rows])
    assert set(c["status"]) <= {"open", "stick", "slip", "none"}


def test_the_run_says_where_and_what(press_slide):
    out, text = press_slide
    lines = text.strip().splitlines()
    assert lines[0].startswith("lagamine-py: completed 2 step(s) (PRESS, SLIDE)")
    totals = read_table(out / "contact_totals.csv")
    P, T = totals["P"][-1], totals["T"][-1]
    assert (f"contact BLOCK_BOTTOM->FLAT: P = {P:.6g} N, T = {T:.6g} N, T/P = 0.2000; "
            "48 points: 0 open, 0 stick, 48 slip") in text
    assert f"results in {out} (ParaView: {out / 'press_slide.pvd'})" in text
    assert lines[-1].startswith("wall time ") or lines[-1].strip().startswith("wall time ")
