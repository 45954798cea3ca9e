"""The VTU writer of lagamine_py.output.vtk against VTK's and meshio's readers.

The writer lays the file out itself (no vtk import); the oracles are the readers: every array
written must come back from VTK's ``vtkXMLUnstructuredGridReader`` with the same values, type,
number of components and component names, the cells with their connectivity, offsets and types,
the field data with its single tuple, ParaView's active vectors and tensors by name, and meshio
must read the same points, cells and arrays.
"""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from lagamine_py.output import vtk as vtk_out

vtk_io = pytest.importorskip("vtkmodules.vtkIOXML")
from vtkmodules.util.numpy_support import vtk_to_numpy  # noqa: E402


def _grid():
    """Two Q8 cells (VTK type 23) and a vertex (type 1) over 14 points, with arrays of every
    dtype the writer keeps and one it widens (bool -> Int64)."""
    rng = np.random.default_rng(3)
    points = np.column_stack([rng.random((14, 2)), np.zeros(14)])
    quads = np.array([[0, 1, 2, 3, 4, 5, 6, 7], [1, 8, 9, 2, 10, 11, 12, 5]])
    vertex = np.array([[13]])
    grid = vtk_out._grid(points, [quads, vertex], [np.full(2, 23), np.full(1, 1)])
    pd, cd = grid.point_data, grid.cell_data
    pd.add("displacement", rng.standard_normal((14, 3)))
    pd.vectors = "displacement"
    pd.add("stress", rng.standard_normal((14, 6)) * 1e3)
    pd.tensors = "stress"
    pd.add("scalar", rng.standard_normal(14))
    pd.add("node_id", np.arange(1, 15, dtype=np.int64) * 10**12)     # beyond 32 bits
    pd.add("status", rng.integers(0, 3, 14).astype(np.int32))
    cd.add("element_id", np.array([7, 9, 11], np.int64))
    cd.add("flag", np.array([True, False, True]))
    vtk_out._field(grid, "TIME", 0.125, "float")
    vtk_out._field(grid, "STEP", 2)
    vtk_out._field(grid, "units: length mm, force N", None)
    return grid


def test_vtk_reads_back_what_was_written(tmp_path):
    grid = _grid()
    path = tmp_path / "g.vtu"
    vtk_out._write_vtu(grid, path)
    r = vtk_io.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    assert not r.GetErrorCode()
    g = r.GetOutput()
    np.testing.assert_array_equal(vtk_to_numpy(g.GetPoints().GetData()), grid.points)
    cells = g.GetCells()
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetConnectivityArray()),
                                  [0, 1, 2, 3, 4, 5, 6, 7, 1, 8, 9, 2, 10, 11, 12, 5, 13])
    np.testing.assert_array_equal(vtk_to_numpy(cells.GetOffsetsArray()), [0, 8, 16, 17])
    assert [g.GetCellType(i) for i in range(3)] == [23, 23, 1]
    types = {"Float64": "double", "Int64": "long long", "Int32": "int"}
    for data, written in ((g.GetPointData(), grid.point_data), (g.GetCellData(), grid.cell_data)):
        assert data.GetNumberOfArrays() == len(written.arrays)
        for name, values in written.arrays:
            a = data.GetAbstractArray(name)
            expect = np.asarray(values)
            if expect.dtype == bool:
                expect = expect.astype(np.int64)
            assert a.GetDataTypeAsString() == types[vtk_out._VTK_TYPES[
                expect.dtype.kind + str(expect.dtype.itemsize)]], name
            np.testing.assert_array_equal(vtk_to_numpy(a), expect, err_msg=name)
            ncomp = expect.shape[1] if expect.ndim == 2 else 1
            assert a.GetNumberOfComponents() == ncomp, name
            if ncomp == 6:
                assert [a.GetComponentName(k) for k in range(6)] == list(vtk_out.TENSOR_NAMES)
    assert g.GetPointData().GetVectors().GetName() == "displacement"
    assert g.GetPointData().GetTensors().GetName() == "stress"
    fd = g.GetFieldData()
    assert vtk_to_numpy(fd.GetArray("TIME")).tolist() == [0.125]
    assert vtk_to_numpy(fd.GetArray("STEP")).tolist() == [2]
    assert fd.GetArray("units: length mm, force N").GetNumberOfTuples() == 1


def test_meshio_reads_back_what_was_written(tmp_path):
    grid = _grid()
    path = tmp_path / "g.vtu"
    vtk_out._write_vtu(grid, path)
    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, grid.points)
    assert [c.type for c in m.cells] == ["quad8", "vertex"]
    np.testing.assert_array_equal(m.cells[0].data, [[0, 1, 2, 3, 4, 5, 6, 7],
                                                    [1, 8, 9, 2, 10, 11, 12, 5]])
    for name, values in grid.point_data.arrays:
        np.testing.assert_array_equal(m.point_data[name], values, err_msg=name)
    np.testing.assert_array_equal(np.concatenate(m.cell_data["element_id"]), [7, 9, 11])


def test_a_small_file_in_one_write_is_the_streamed_file(tmp_path, monkeypatch):
    """A file under one piece is joined and written at once; the same grid streamed piece by
    piece (pieces of 48 bytes: many per array) gives the same bytes."""
    grid = _grid()
    vtk_out._write_vtu(grid, tmp_path / "once.vtu")
    writes = []

    class Spy(vtk_out._Pieces):
        def write(self, b):
            writes.append(len(b))
            return super().write(b)
    monkeypatch.setattr(vtk_out, "_Pieces", Spy)
    vtk_out._write_vtu(grid, tmp_path / "once_again.vtu")
    assert writes                                       # the small file's way
    monkeypatch.setattr(vtk_out, "_PIECE", 48)
    writes.clear()
    vtk_out._write_vtu(grid, tmp_path / "streamed.vtu")
    assert not writes                                   # streamed
    once = (tmp_path / "once.vtu").read_bytes()
    assert once == (tmp_path / "streamed.vtu").read_bytes() == (tmp_path / "once_again.vtu").read_bytes()


def test_an_empty_grid_is_a_valid_file(tmp_path):
    """No cells, no points (a contact pair without points): VTK opens it (meshio 5 fails on
    any VTU without cells, VTK's own writer's included)."""
    grid = vtk_out._grid(np.zeros((0, 3)), [np.zeros((0, 1), np.int64)], [np.zeros(0)])
    grid.point_data.add("p", np.zeros(0))
    path = tmp_path / "e.vtu"
    vtk_out._write_vtu(grid, path)
    r = vtk_io.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(path))
    r.Update()
    assert not r.GetErrorCode() and r.GetOutput().GetNumberOfPoints() == 0


@pytest.mark.parametrize("value", ["U", "a&b<c>", "say \"hi\"", "it's", "both ' and \"", "tab\tnew\nline\r"])
def test_quoteattr_writes_what_saxutils_writes(value):
    from xml.sax.saxutils import quoteattr as reference

    from lagamine_py.output.vtk import quoteattr
    assert quoteattr(value) == reference(value)
