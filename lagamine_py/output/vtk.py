"""VTK output: one ``.vtu`` per output increment and part, indexed by a ``.pvd`` collection.

Parts (the ``part`` attribute of the PVD ``DataSet`` entries):

* ``0`` bodies, ``OUT/<deck>_NNNN.vtu``: the mesh in *reference* coordinates with the
  displacement as a 3-component vector (ParaView "Warp By Vector" shows the deformed shape).
  Point data: ``displacement``, ``reaction``, ``stress`` (S11, S22, S33, S12), ``von_mises``,
  ``PEEQ``, ``node_id``.  Cell data: ``element_id``, ``S11``, ``S22``, ``S33``, ``S12``,
  ``von_mises``, ``PEEQ``.
* ``1`` contact Gauss points, ``OUT/<deck>_contact_NNNN.vtu``: VTK_VERTEX cells at the current
  positions, point data ``p``, ``tau``, ``gap``, ``slip``, ``lambda``, ``status``
  (0 open, 1 stick, 2 slip), ``element``, ``face``, ``gauss``, ``contact`` (pair index).
* ``2`` foundations, ``OUT/<deck>_foundation_NNNN.vtu``: one poly-line per foundation through
  its current points, each 3-point arc sampled with quadratic Lagrange interpolation.

Nodal stress and PEEQ are *extrapolated* from the Gauss points to the element nodes with the
tensor Lagrange polynomials through the Gauss abscissae (bilinear for 2x2, biquadratic for 3x3:
exact for fields the Gauss rule can represent), then averaged over the elements sharing the
node.  Cell values are Gauss-weight means over the element's parent square (the exact integral
mean for affine elements); the cell von Mises is the mean of the Gauss-point von Mises values.

Option ``append`` (resuming a run): the existing PVD entries are kept up to, not including, the
time of the first resumed increment, and the file counter continues after the last kept file.

The ``vtk`` package is imported inside the methods, so ``lagamine-py --help`` does not load it.
"""
from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..elements.shapes import gauss_quad, line_shape
from ..laws.j2 import von_mises
from ..registry import register
from .base import IncrementResult, Writer

# VTK cell types by number of element nodes (CPE8 node order = VTK_QUADRATIC_QUAD order).
VTK_VERTEX, VTK_POLY_LINE, VTK_POLYGON = 1, 4, 7
CELL_TYPES = {3: 5, 4: 9, 6: 22, 8: 23, 9: 28}     # other node counts: VTK_POLYGON

# Parent coordinates of quadrilateral nodes: corners, mid-sides 5..8, centre (Q9).
QUAD_NODES = np.array([(-1, -1), (1, -1), (1, 1), (-1, 1),
                       (0, -1), (1, 0), (0, 1), (-1, 0), (0, 0)], float)

SAMPLES_PER_ARC = 16
STRESS_NAMES = ("S11", "S22", "S33", "S12")


def _lagrange_1d(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Lagrange basis through ``nodes`` (k,) evaluated at ``x`` (m,): (m, k)."""
    diff = x[:, None, None] - nodes[None, None, :]              # (m, 1, k)
    den = nodes[:, None] - nodes[None, :]                        # (k, k)
    eye = np.eye(len(nodes), dtype=bool)
    ratio = np.where(eye, 1.0, diff / np.where(eye, 1.0, den))   # (m, k, k): (x - x_j)/(x_i - x_j)
    return ratio.prod(axis=-1)


def extrapolation_matrix(nen: int, nq: int) -> np.ndarray | None:
    """E (a, q) taking Gauss values of an ``n x n`` rule (``gauss_quad`` order) to the nodes.

    None when the element is not a 4/8/9-node quadrilateral or ``nq`` is not a square: the
    caller then uses the plain element average.
    """
    n = int(round(np.sqrt(nq)))
    if nen not in (4, 8, 9) or n * n != nq:
        return None
    pts, _ = gauss_quad(n)
    abscissae = np.polynomial.legendre.leggauss(n)[0]
    # index of each Gauss point's xi and eta among the abscissae (robust to the rule's ordering)
    ix = np.abs(pts[:, 0][:, None] - abscissae[None, :]).argmin(axis=1)
    iy = np.abs(pts[:, 1][:, None] - abscissae[None, :]).argmin(axis=1)
    nodes = QUAD_NODES[:nen]
    Lx = _lagrange_1d(abscissae, nodes[:, 0])                   # (a, n)
    Ly = _lagrange_1d(abscissae, nodes[:, 1])
    return Lx[:, ix] * Ly[:, iy]


def cell_weights(nq: int) -> np.ndarray:
    """Gauss weights (q,) normalised to 1 (plain mean when ``nq`` is not a square)."""
    n = int(round(np.sqrt(nq)))
    if n * n != nq:
        return np.full(nq, 1.0 / nq)
    w = gauss_quad(n)[1]
    return w / w.sum()


def nodal_fields(n_nodes: int, cells: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Nodal stress (n, 4) and PEEQ (n,) from Gauss values, extrapolated then averaged.

    Nodes outside every element get zeros.
    """
    total = np.zeros((n_nodes, 5))
    count = np.zeros(n_nodes)
    for c in cells:
        conn = np.asarray(c["conn"])
        e, nen = conn.shape
        gauss = _gauss_values(c)                                  # (e, q, 5)
        E = extrapolation_matrix(nen, gauss.shape[1])
        if E is None:
            at_nodes = np.repeat(gauss.mean(axis=1, keepdims=True), nen, axis=1)
        else:
            at_nodes = np.einsum("aq,eqs->eas", E, gauss)
        idx = conn.ravel()
        for k in range(5):  # one bincount per component, over all elements at once
            total[:, k] += np.bincount(idx, weights=at_nodes[..., k].ravel(), minlength=n_nodes)
        count += np.bincount(idx, minlength=n_nodes)
    mean = total / np.maximum(count, 1)[:, None]
    return mean[:, :4], mean[:, 4]


def _gauss_values(c: dict) -> np.ndarray:
    """Stack stress (e, q, 4) and peeq (e, q) into (e, q, 5)."""
    stress = np.asarray(c["stress"], float)
    peeq = c.get("peeq")
    peeq = np.zeros(stress.shape[:2]) if peeq is None else np.asarray(peeq, float)
    return np.concatenate([stress, peeq[..., None]], axis=-1)


def sample_arcs(points: np.ndarray, per_arc: int = SAMPLES_PER_ARC) -> np.ndarray:
    """Points (m, 2), m odd: arcs through (0,1,2), (2,3,4), ... sampled ``per_arc`` intervals each.

    Each arc is the quadratic through its three points with the middle one at parameter 0
    (the foundation's own interpolation).  Returns (per_arc * (m-1)/2 + 1, 2).
    """
    points = np.asarray(points, float)
    if len(points) < 3:
        return points.copy()
    n_arc = (len(points) - 1) // 2
    k = 2 * np.arange(n_arc)
    arcs = np.stack([points[k], points[k + 2], points[k + 1]], axis=1)   # line_shape node order
    N, _ = line_shape(3, np.linspace(-1.0, 1.0, per_arc + 1))
    samples = np.einsum("sa,kai->ksi", N, arcs)                          # (arc, s, 2)
    return np.concatenate([samples[:, :-1].reshape(-1, 2), samples[-1, -1:]], axis=0)


def _vec3(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, float)
    return np.column_stack([a, np.zeros(len(a))]) if a.shape[1] == 2 else a


_VTK = None


def _vtk():
    """The VTK classes this writer uses, imported on first use from the ``vtkmodules``
    sub-packages: 0.2 s, against 0.7 s for the whole ``vtk`` package, which was most of the
    output cost of a short run."""
    global _VTK
    if _VTK is None:
        from types import SimpleNamespace

        from vtkmodules.util.numpy_support import numpy_to_vtk, numpy_to_vtkIdTypeArray
        from vtkmodules.vtkCommonCore import (VTK_UNSIGNED_CHAR, vtkDoubleArray, vtkIntArray,
                                              vtkPoints, vtkStringArray)
        from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkUnstructuredGrid
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter
        _VTK = SimpleNamespace(
            numpy_to_vtk=numpy_to_vtk, numpy_to_vtkIdTypeArray=numpy_to_vtkIdTypeArray,
            VTK_UNSIGNED_CHAR=VTK_UNSIGNED_CHAR, vtkDoubleArray=vtkDoubleArray,
            vtkIntArray=vtkIntArray, vtkPoints=vtkPoints, vtkStringArray=vtkStringArray,
            vtkCellArray=vtkCellArray, vtkUnstructuredGrid=vtkUnstructuredGrid,
            vtkXMLUnstructuredGridWriter=vtkXMLUnstructuredGridWriter)
    return _VTK


def _array(values: np.ndarray, name: str, components: tuple[str, ...] = ()):
    arr = _vtk().numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    arr.SetName(name)
    for k, comp in enumerate(components):
        arr.SetComponentName(k, comp)
    return arr


def _grid(points: np.ndarray, conn: list[np.ndarray], types: list[np.ndarray]):
    """vtkUnstructuredGrid from points (n, 3), connectivity chunks (c, k) and their types (c,)."""
    vtk = _vtk()
    numpy_to_vtk, numpy_to_vtkIdTypeArray = vtk.numpy_to_vtk, vtk.numpy_to_vtkIdTypeArray
    grid = vtk.vtkUnstructuredGrid()
    pts = vtk.vtkPoints()
    pts.SetData(numpy_to_vtk(np.ascontiguousarray(points, float), deep=True))
    grid.SetPoints(pts)
    flat = np.concatenate([c.ravel() for c in conn] + [np.zeros(0)]).astype(np.int64)
    sizes = np.concatenate([np.full(len(c), c.shape[1]) for c in conn] + [np.zeros(0)])
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    cells = vtk.vtkCellArray()
    cells.SetData(numpy_to_vtkIdTypeArray(offsets, deep=True), numpy_to_vtkIdTypeArray(flat, deep=True))
    ctypes = np.concatenate(list(types) + [np.zeros(0)]).astype(np.uint8)
    grid.SetCells(numpy_to_vtk(ctypes, deep=True, array_type=vtk.VTK_UNSIGNED_CHAR), cells)
    return grid


def _write_vtu(grid, path: Path) -> None:
    writer = _vtk().vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(grid)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    # LZ4 rather than the default zlib: 17x faster to write, files 1.24x larger (160x80 body:
    # 5.2 against 88.9 ms, 4.0 against 3.2 MB; uncompressed 6.5 MB)
    writer.SetCompressorTypeToLZ4()
    if not writer.Write():
        raise OSError(f"could not write {path}")


def read_pvd(path: Path) -> list[tuple[float, int, str]]:
    """(timestep, part, file) of each DataSet of a PVD file."""
    root = ET.parse(path).getroot()
    return [(float(d.get("timestep", 0)), int(d.get("part", 0)), d.get("file", ""))
            for d in root.iter("DataSet")]


@register("writers", "VTK")
class VtkWriter(Writer):
    """VTU files per output increment (bodies, contact points, foundations) and a PVD index."""

    params = ()

    def __init__(self, outdir, model, **options):
        super().__init__(outdir, model, **options)
        self.append = bool(options.get("append", False))
        self.fields: set[str] | None = None       # *OUTPUT, FIELDS= of the step; None: all

    def start_run(self) -> None:
        self.outdir.mkdir(parents=True, exist_ok=True)
        self.deck = getattr(self.model, "name", None) or "run"
        self.pvd_path = self.outdir / f"{self.deck}.pvd"
        self.counter = 0
        self.entries: list[tuple[float, int, str]] = []    # (time, part, file name)
        resuming = self.append or bool(getattr(self, "restarting", False))   # set by the controller
        self._pending_trim = resuming and self.pvd_path.exists()
        if self._pending_trim:
            self.entries = read_pvd(self.pvd_path)
        else:
            self._write_pvd()

    def _resume_at(self, time: float) -> None:
        """Drop the entries an interrupted run wrote at or after ``time``; continue the counter."""
        self._pending_trim = False
        self.entries = [e for e in self.entries if e[0] < time]
        numbers = [int(m.group(1)) for _, _, name in self.entries
                   if (m := re.search(r"_(\d+)\.vtu$", name))]
        self.counter = max(numbers, default=-1) + 1
        self._write_pvd()

    def increment(self, result: IncrementResult) -> None:
        if self._pending_trim:
            self._resume_at(float(result.time))
        if not result.write_fields:
            return
        stem = f"{self.deck}_{{}}{self.counter:04d}.vtu"
        parts = [(0, stem.format(""), self._body_grid(result))]
        if result.contacts:
            parts.append((1, stem.format("contact_"), self._contact_grid(result)))
        if result.foundations:
            parts.append((2, stem.format("foundation_"), self._foundation_grid(result)))
        for part, name, grid in parts:
            _write_vtu(grid, self.outdir / name)
            self.entries.append((float(result.time), part, name))
        self.counter += 1
        self._write_pvd()

    def start_step(self, step_number: int, step) -> None:
        fields = getattr(getattr(step, "output", None), "fields", ())
        self.fields = set(fields) if fields else None          # None: every field

    def _wants(self, name: str) -> bool:
        """``*OUTPUT, FIELDS=`` of the step asks for ``name`` (U, S, PEEQ, RF), or nothing
        was asked (all)."""
        return self.fields is None or name in self.fields

    def close(self, status: int, message: str) -> None:
        pass

    # -- parts ---------------------------------------------------------------------------
    def _body_grid(self, r: IncrementResult):
        vtk = _vtk()

        n = len(r.coords0)
        conn = [np.asarray(c["conn"]) for c in r.cells]
        types = [np.full(len(cn), CELL_TYPES.get(cn.shape[1], VTK_POLYGON)) for cn in conn]
        grid = _grid(_vec3(r.coords0), conn, types)

        want_s, want_peeq = self._wants("S"), self._wants("PEEQ")
        pd = grid.GetPointData()
        if self._wants("U"):
            pd.AddArray(_array(_vec3(r.u), "displacement"))
            pd.SetActiveVectors("displacement")
        if self._wants("RF"):
            pd.AddArray(_array(_vec3(r.reaction), "reaction"))
        if want_s or want_peeq:
            s_nod, peeq_nod = nodal_fields(n, r.cells)
            if want_s:
                pd.AddArray(_array(s_nod, "stress", STRESS_NAMES))
                pd.AddArray(_array(von_mises(s_nod), "von_mises"))
            if want_peeq:
                pd.AddArray(_array(peeq_nod, "PEEQ"))
        node_ids = getattr(self.model, "node_ids", None)
        if node_ids is not None and len(node_ids) == n:
            pd.AddArray(_array(np.asarray(node_ids, np.int64), "node_id"))

        cd = grid.GetCellData()
        if r.cells:
            gauss = [_gauss_values(c) for c in r.cells]
            w = [cell_weights(g.shape[1]) for g in gauss]
            mean = np.concatenate([np.einsum("q,eqs->es", wk, g) for wk, g in zip(w, gauss)])
            vm = np.concatenate([np.einsum("q,eq->e", wk, von_mises(g[..., :4])) for wk, g in zip(w, gauss)])
            ids = np.concatenate([np.asarray(c["ids"], np.int64) for c in r.cells])
        else:
            mean, vm, ids = np.zeros((0, 5)), np.zeros(0), np.zeros(0, np.int64)
        cd.AddArray(_array(ids, "element_id"))
        if want_s:
            for k, name in enumerate(STRESS_NAMES):
                cd.AddArray(_array(mean[:, k], name))
            cd.AddArray(_array(vm, "von_mises"))
        if want_peeq:
            cd.AddArray(_array(mean[:, 4], "PEEQ"))
        self._add_time(grid, r, vtk)
        return grid

    def _contact_grid(self, r: IncrementResult):
        vtk = _vtk()

        cps = r.contacts
        x = np.concatenate([np.asarray(cp.x, float).reshape(-1, 2) for cp in cps])
        g = len(x)
        grid = _grid(_vec3(x), [np.arange(g)[:, None]], [np.full(g, VTK_VERTEX)])
        pd = grid.GetPointData()

        def cat(attr, dtype=float):
            return np.concatenate([np.asarray(getattr(cp, attr)).ravel() for cp in cps]).astype(dtype)

        for attr, name in (("p", "p"), ("tau", "tau"), ("gap", "gap"), ("slip", "slip"), ("lam", "lambda")):
            pd.AddArray(_array(cat(attr), name))
        for attr in ("status", "element", "face", "gauss"):
            pd.AddArray(_array(cat(attr, np.int32), attr))
        pair = np.concatenate([np.full(len(np.asarray(cp.p).ravel()), k, np.int32) for k, cp in enumerate(cps)])
        pd.AddArray(_array(pair, "contact"))
        names = vtk.vtkStringArray()
        names.SetName("contact_names")
        for cp in cps:
            names.InsertNextValue(cp.name)
        grid.GetFieldData().AddArray(names)
        self._add_time(grid, r, vtk)
        return grid

    def _foundation_grid(self, r: IncrementResult):
        vtk = _vtk()

        lines = [sample_arcs(p) for p in r.foundations.values()]
        start = np.cumsum([0] + [len(s) for s in lines[:-1]])
        conn = [np.arange(s0, s0 + len(s))[None, :] for s0, s in zip(start, lines)]
        grid = _grid(_vec3(np.concatenate(lines)), conn, [np.full(1, VTK_POLY_LINE)] * len(lines))
        grid.GetCellData().AddArray(_array(np.arange(len(lines), dtype=np.int32), "foundation"))
        names = vtk.vtkStringArray()
        names.SetName("foundation_names")
        for name in r.foundations:
            names.InsertNextValue(name)
        grid.GetFieldData().AddArray(names)
        self._add_time(grid, r, vtk)
        return grid

    @staticmethod
    def _add_time(grid, r: IncrementResult, vtk) -> None:
        """TIME, STEP, INCREMENT as field data (ParaView shows them with "Python Annotation")."""
        fd = grid.GetFieldData()
        for name, value, cls in (("TIME", r.time, vtk.vtkDoubleArray), ("STEP", r.step, vtk.vtkIntArray),
                                 ("INCREMENT", r.increment, vtk.vtkIntArray)):
            arr = cls()
            arr.SetName(name)
            arr.InsertNextValue(value)
            fd.AddArray(arr)

    # -- index ---------------------------------------------------------------------------
    def _write_pvd(self) -> None:
        """Rewrite the PVD index atomically (tmp file + rename), so a reader never sees half."""
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                 "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" group="" part="{part}" file={quoteattr(name)}/>'
                  for t, part, name in self.entries]
        lines += ["  </Collection>", "</VTKFile>", ""]
        tmp = self.pvd_path.with_name(self.pvd_path.name + ".tmp")
        with open(tmp, "w") as fh:
            fh.write("\n".join(lines))
        os.replace(tmp, self.pvd_path)
