"""The VTU writer streams its appended data (issue 17 item 5: the body file of a 320x160 run
was ~0.1 GB of text built in memory while the factor was held): the file must be, byte for
byte, the one the former writer built whole in memory (kept below as the oracle: one
``base64.b64encode`` of each array's UInt32 byte count and bytes, all texts joined), whatever
the piece size, for arrays of every length modulo 3, empty ones and ones spanning many pieces.
(That VTK and meshio read the files is tests/test_vtu_writer.py's.)"""
from __future__ import annotations

import base64

import numpy as np
import pytest

from lagamine_py.output import vtk as vtk_out

from conftest import DECKS


def _in_memory_vtu(grid, path) -> None:
    """The writer of lagamine_py before streaming (b91459b's ``_write_vtu``), verbatim but for
    the names it reads from the module."""
    xml, blobs, offset = [], [], 0

    def array(name, values, indent, extra="", tuples=False):
        nonlocal offset
        values = np.ascontiguousarray(values)
        values = values.astype(values.dtype.newbyteorder("<"), copy=False)
        raw = values.tobytes()
        blob = base64.b64encode(np.uint32(len(raw)).astype("<u4").tobytes() + raw)
        ncomp = values.shape[1] if values.ndim == 2 else 1
        attrs = f'type="{vtk_out._VTK_TYPES[values.dtype.kind + str(values.dtype.itemsize)]}"' \
                f'{extra} Name={vtk_out.quoteattr(name)}'
        if tuples:
            attrs += f' NumberOfTuples="{len(values)}"'
        elif ncomp > 1:
            attrs += f' NumberOfComponents="{ncomp}"'
            if ncomp == 6:
                attrs += "".join(f' ComponentName{k}="{c}"'
                                 for k, c in enumerate(vtk_out.TENSOR_NAMES))
        xml.append(f'{indent}<DataArray {attrs} format="appended" offset="{offset}"/>')
        blobs.append(blob)
        offset += len(blob)

    def data(tag, d):
        active = "".join(f' {key}={vtk_out.quoteattr(v)}'
                         for key, v in (("Vectors", d.vectors), ("Tensors", d.tensors)) if v)
        xml.append(f"      <{tag}{active}>")
        for name, values in d.arrays:
            array(name, values, "        ")
        xml.append(f"      </{tag}>")

    xml += ['<?xml version="1.0"?>',
            '<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian" '
            'header_type="UInt32">', "  <UnstructuredGrid>", "    <FieldData>"]
    for name, values in grid.field_data.arrays:
        array(name, values, "      ", tuples=True)
    xml += ["    </FieldData>",
            f'    <Piece NumberOfPoints="{len(grid.points)}" NumberOfCells="{len(grid.types)}">']
    data("PointData", grid.point_data)
    data("CellData", grid.cell_data)
    xml.append("      <Points>")
    array("Points", grid.points, "        ")
    xml += ["      </Points>", "      <Cells>"]
    array("connectivity", grid.connectivity, "        ", extra=' IdType="1"')
    array("offsets", grid.offsets, "        ")
    array("types", grid.types, "        ")
    xml += ["      </Cells>", "    </Piece>", "  </UnstructuredGrid>",
            '  <AppendedData encoding="base64">', "   _"]
    with open(path, "wb") as fh:
        fh.write("\n".join(xml).encode())
        for blob in blobs:
            fh.write(blob)
        fh.write(b"\n  </AppendedData>\n</VTKFile>\n")


def _grid(n_points: int, seed: int = 5):
    """A grid of ``n_points`` points in Q4 cells and vertices with arrays of every dtype the
    writer keeps (UInt8 types: lengths of every residue modulo 3), one widened (bool), an
    empty cell array when there are no cells, and field data."""
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.random((n_points, 2)), np.zeros(n_points)])
    nq = n_points // 4
    quads = np.arange(4 * nq).reshape(nq, 4)
    verts = np.arange(4 * nq, n_points)[:, None]
    grid = vtk_out._grid(points, [quads, verts], [np.full(nq, 9), np.full(len(verts), 1)])
    grid.point_data.add("displacement", rng.standard_normal((n_points, 3)))
    grid.point_data.vectors = "displacement"
    grid.point_data.add("stress", rng.standard_normal((n_points, 6)))
    grid.point_data.tensors = "stress"
    grid.point_data.add("status", rng.integers(0, 3, n_points).astype(np.int32))
    grid.point_data.add("id", np.arange(n_points, dtype=np.int64) * 10**11)
    grid.cell_data.add("flag", rng.random(len(grid.types)) > 0.5)
    vtk_out._field(grid, "TIME", 0.5, "float")
    vtk_out._field(grid, "units: length mm", None)
    return grid


@pytest.mark.parametrize("n_points", [0, 1, 2, 3, 5, 14, 4096 + 7])
@pytest.mark.parametrize("piece", [6, 9, 48, vtk_out._PIECE])
def test_streamed_file_is_the_in_memory_writers_byte_for_byte(tmp_path, monkeypatch, n_points,
                                                              piece):
    grid = _grid(n_points)
    _in_memory_vtu(grid, tmp_path / "whole.vtu")
    monkeypatch.setattr(vtk_out, "_PIECE", piece)
    vtk_out._write_vtu(grid, tmp_path / "streamed.vtu")
    assert (tmp_path / "streamed.vtu").read_bytes() == (tmp_path / "whole.vtu").read_bytes()


def test_an_array_of_many_pieces(tmp_path):
    """The default piece size, an array of ~2.5 pieces (the 4-byte count shifts every piece)."""
    grid = vtk_out._grid(np.zeros((0, 3)), [np.zeros((0, 1), np.int64)], [np.zeros(0)])
    grid.field_data.add("big", np.arange(int(2.5 * vtk_out._PIECE) // 8 + 1, dtype=np.float64))
    _in_memory_vtu(grid, tmp_path / "whole.vtu")
    vtk_out._write_vtu(grid, tmp_path / "streamed.vtu")
    assert (tmp_path / "streamed.vtu").read_bytes() == (tmp_path / "whole.vtu").read_bytes()


def test_the_appended_size_is_the_length_of_the_text():
    for nbytes in range(0, 40):
        text = base64.b64encode(bytes(4 + nbytes))
        assert vtk_out._appended_size(nbytes) == len(text)


@pytest.mark.parametrize("deck", DECKS, ids=[d.stem for d in DECKS])
def test_recovery_by_batches_is_the_recovery_of_all_fields_at_once(deck, deck_run, monkeypatch):
    """The body's nodal and element values, recovered a tensor at a time and the scalars
    together (``recovered`` above ``RECOVERY_BATCH_BYTES``, forced here: their temporaries a
    field's, not all 15 components'), are bit for bit what the recovery of every field in one
    (e, q, 15) block gave (the former code, here), in the same order, on every example deck's
    written increments."""
    from lagamine_py.output.recovery import nodal_values

    monkeypatch.setattr(vtk_out, "RECOVERY_BATCH_BYTES", 0)
    got = deck_run(deck)
    assert got.outcome.status == 0, got.outcome.message
    checked = 0
    for r in got.results[-2:]:
        fields = vtk_out.body_fields(r.cells, lambda code: True)
        if not (r.write_fields and fields and r.cells):
            continue
        n = len(r.coords0)
        gauss = [np.concatenate([np.asarray(f[2][b], float).reshape(len(c.conn), -1, f[1])
                                 for f in fields], axis=-1) for b, c in enumerate(r.cells)]
        whole = nodal_values(n, [(c.element, c.conn, g) for c, g in zip(r.cells, gauss)])
        means = np.concatenate([np.einsum("q,eqk->ek", c.element.gauss_weights(), g)
                                for c, g in zip(r.cells, gauss)])
        nodal, element = vtk_out.recovered(n, r.cells, fields)
        assert list(nodal) == list(element) == [f[0] for f in fields]
        for name, values in vtk_out._split(whole, fields).items():
            np.testing.assert_array_equal(nodal[name], values, err_msg=name)
        for name, values in vtk_out._split(means, fields).items():
            np.testing.assert_array_equal(element[name], values, err_msg=name)
        checked += 1
    assert checked


def test_batches_by_size():
    """All the fields in one batch up to RECOVERY_BATCH_BYTES of Gauss values, else each tensor
    alone and the scalars together, in the fields' order."""
    fields = [("stress", 4, []), ("von_mises", 1, []), ("pressure", 1, []),
              ("log_strain", 4, []), ("PEEQ", 1, [])]
    small = vtk_out.RECOVERY_BATCH_BYTES // 8
    assert vtk_out._batches(fields, small) == [fields]
    names = [[f[0] for f in b] for b in vtk_out._batches(fields, small + 1)]
    assert names == [["stress"], ["log_strain"], ["von_mises", "pressure", "PEEQ"]]
