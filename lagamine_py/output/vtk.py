"""VTK output: one ``.vtu`` per block and output state, indexed by a ``.pvd`` collection.

Every file opens in ParaView, VTK, pyvista and meshio (``tests/test_vtk_clients.py`` reads every
file of a run with meshio and VTK).

Blocks (``DataSet`` entries of the PVD, each with its ``part`` number and its ``name``):

* ``body``, ``OUT/<deck>_NNNN.vtu``: the mesh in *reference* coordinates with the displacement
  as a 3-component vector (ParaView "Warp By Vector" shows the deformed shape).
  Point data (nodal values, see :mod:`lagamine_py.output.recovery`): ``displacement`` (U),
  ``reaction`` (RF), ``stress`` (S: Cauchy, a symmetric tensor in ParaView's order XX, YY, ZZ,
  XY, YZ, XZ; in axisymmetry X = r, Y = z, Z = hoop), ``von_mises`` and ``pressure``
  (``-trace/3``, positive in compression) recovered from their Gauss values, ``log_strain``
  (LE, under NLGEOM: ``ln V``) or ``strain`` (E, small strain) and ``plastic_strain`` (PE, total
  minus elastic strain), tensors like the stress, ``PEEQ``, ``node_id``.  Cell data (element
  values: Gauss-weight means over the reference element, exact integral means for affine
  elements): ``element_id`` and ``element_<name>`` of every point field but the displacement
  and the reaction.
* ``contact <pair>`` (one per contact pair), ``OUT/<deck>_contact_<pair>_NNNN.vtu``: the
  contact Gauss points as VTK_VERTEX cells at their *reference* positions with a
  ``displacement`` (so that a warp of any scale keeps them on the body).  Point data ``p``,
  ``tau``, ``gap`` (COPEN: positive when open), ``slip``, ``signed_slip``, ``slip_increment``,
  ``dissipation`` (per unit area), ``lambda``, ``status`` (codes, named in the field data:
  arrays ``status_open`` = 0, ``status_stick`` = 1, ``status_slip`` = 2, ``status_none`` =
  3), ``element``, ``face``, ``gauss``.  Signs: :class:`~lagamine_py.elements.base.ContactPoints`.
* ``foundation <name>`` (one per foundation), ``OUT/<deck>_foundation_<name>_NNNN.vtu``: line
  segments through the foundation's reference position, each 3-point arc sampled with its own
  interpolation (VTK_LINE cells: meshio drops poly-lines), with its rigid ``displacement``.

Every file carries field data ``TIME``, ``STEP``, ``INCREMENT`` and, with ``*UNITS``, an array
named ``units: length <L>, force <F>, stress <S>`` (text lives in array names: meshio cannot
read VTK string arrays).  The series starts with the state at t = 0 (:meth:`VtkWriter.initial`),
and times are the rounded times the step controller hands out.

Encoding: appended data, base64-encoded, uncompressed.  Measured (``python tools/bench.py vtu
FILE``, median of 12 writes) on a body file of press-slide at 160x80 Q8 (38881 nodes, 12800
elements, every field): raw appended data 11.6 ms and 12.8 MB, base64 70 ms and 17.1 MB, base64
with zlib level 1 157 ms and 9.0 MB, raw with LZ4 15 ms and 8.3 MB; at 40x20 (5042 DOFs) base64
5.0 ms, base64 + zlib 10.3 ms.  LZ4 meshio cannot read at all (``KeyError:
'vtkLZ4DataCompressor'``); raw appended data meshio reads by looking each array up by its offset
after renumbering the offsets, which mixes arrays up when a new offset equals an old one (the
tube's body file with the earlier fields failed so), so raw data is not safe either.  Of the
encodings every client reads, uncompressed base64 is the fastest; zlib would halve the files and
double the writing time, which at 40x20 would take the VTK output above 10 % of the run
(``docs/performance.md``).

Option ``append`` (resuming a run): the existing PVD entries are kept up to, not including, the
time of the first resumed increment, and the file counter continues after the last kept file.

The files are written here (:func:`_write_vtu`, VTK's own layout), without the ``vtk`` package:
its import and objects were 0.1-0.2 s of a short run.
"""
from __future__ import annotations

import base64
import re
import struct
from pathlib import Path

import numpy as np

from ..core.outdir import write_atomic
from ..core.status import STATUS_NAMES
from ..core.tensors import von_mises
from ..foundation import Foundation
from .base import CellBlock, IncrementResult, Writer
from .recovery import RecoveryPlan, nodal_values


_ATTR_ESCAPES = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;", "\n": "&#10;", "\r": "&#13;",
                                "\t": "&#9;"})


def quoteattr(value: str) -> str:
    """``value`` as a quoted XML attribute value, exactly as ``xml.sax.saxutils.quoteattr``
    writes it (whose import pulls in urllib, http and ssl: 0.02 s of a short run)."""
    value = value.translate(_ATTR_ESCAPES)       # one C pass (the .pvd rewrites every name)
    if '"' not in value:
        return f'"{value}"'
    if "'" not in value:
        return f"'{value}'"
    return '"' + value.replace('"', "&quot;") + '"'


VTK_VERTEX, VTK_LINE = 1, 3
SAMPLES_PER_ARC = 16
#: ParaView's order of a symmetric tensor's 6 components
TENSOR_NAMES = ("XX", "YY", "ZZ", "XY", "YZ", "XZ")


def tensor6(v4: np.ndarray) -> np.ndarray:
    """4-vectors [11, 22, 33, 12] (tensor components) (..., 4) -> ParaView's 6 (..., 6)."""
    v4 = np.asarray(v4, float)
    out = np.zeros(v4.shape[:-1] + (6,))
    out[..., :4] = v4
    return out


def pressure(stress: np.ndarray) -> np.ndarray:
    """``-(s11 + s22 + s33) / 3`` (positive in compression) of stress 4-vectors (..., 4)."""
    s = np.asarray(stress, float)
    return -(s[..., 0] + s[..., 1] + s[..., 2]) / 3.0


# -- Gauss fields of the body, as (e, q, k) blocks of scalars --------------------------------
def body_fields(cells: list[CellBlock], wants) -> list[tuple[str, int, list[np.ndarray]]]:
    """The body's fields to write: ``(name, components, [Gauss values (e, q, components) per
    cell block])``; ``wants(code)`` says whether ``*OUTPUT, FIELDS=`` asks for a field
    (U, S, LE, PE, PEEQ, RF).  A field some block lacks (an element that gives no strains) is
    left out."""
    fields = []
    if wants("S"):
        fields += [("stress", 4, [c.stress for c in cells]),
                   ("von_mises", 1, [von_mises(np.asarray(c.stress, float))[..., None] for c in cells]),
                   ("pressure", 1, [pressure(c.stress)[..., None] for c in cells])]
    if wants("LE") and cells and all(c.strain is not None for c in cells):
        kinds = {c.strain_kind for c in cells}
        name = "log_strain" if kinds == {"log"} else "strain"
        fields.append((name, 4, [c.strain for c in cells]))
    if wants("PE") and cells and all(c.plastic_strain is not None for c in cells):
        fields.append(("plastic_strain", 4, [c.plastic_strain for c in cells]))
    if wants("PEEQ"):
        fields.append(("PEEQ", 1, [np.asarray(c.peeq, float)[..., None] for c in cells]))
    return fields


def recovered(n_nodes: int, cells: list[CellBlock], fields, bounded: bool = True,
              plan: RecoveryPlan | None = None):
    """``(nodal, element)``: dicts ``{name: values}`` of the ``fields`` (:func:`body_fields`),
    nodal values (n, ...) by :func:`~lagamine_py.output.recovery.nodal_values` (``plan``: a
    :class:`~lagamine_py.output.recovery.RecoveryPlan` of the cells' connectivities, kept by
    the writer across increments) and element values (e, ...) the Gauss-weight means; tensors
    as ParaView's 6 components.

    Large meshes field by field (:func:`_batches`): the recovery's temporaries (the Gauss
    values, their extrapolations to every element's nodes and the patch bounds, each (e, a,
    components)) are then those of one field rather than of all 15 components at once (~14 MB
    at 80x40, ~0.2 GB at 320x160, while the factor is held); every value is computed by the
    same operations as all at once."""
    nodal, element = {}, {}
    n_values = sum(np.size(g) for f in fields for g in f[2])
    weights = [plan.gauss_weights(c.element) if plan is not None else c.element.gauss_weights()
               for c in cells]
    for batch in _batches(fields, n_values):
        gauss = [_joined([np.asarray(f[2][b], float).reshape(len(c.conn), -1, f[1])
                          for f in batch])
                 for b, c in enumerate(cells)]                       # (e, q, k) per block
        values = nodal_values(n_nodes, [(c.element, c.conn, g) for c, g in zip(cells, gauss)],
                              bounded, plan)
        means = np.concatenate([np.einsum("q,eqk->ek", w, g) for w, g in zip(weights, gauss)])
        nodal.update(_split(values, batch))
        element.update(_split(means, batch))
    order = [f[0] for f in fields]                  # the files list them in the fields' order
    return {k: nodal[k] for k in order}, {k: element[k] for k in order}


#: Gauss values (bytes) of all the fields below which they are recovered in one batch: one
#: call's fixed cost instead of four (the main job's VTK state 3.8 -> 3.0 ms); above, by batches
#: (80x40: 8 MB less peak for 1.7 ms more a state)
RECOVERY_BATCH_BYTES = 1 << 20


def _batches(fields, n_values: int = 0):
    """The fields recovered together: all at once when their ``n_values`` Gauss values (over
    every component) fit in :data:`RECOVERY_BATCH_BYTES`, else each tensor alone and the scalars
    in one batch (NumPy's products of a single column take another path whose round-off
    differs: batched, the values are those of one product over every field, bit for bit)."""
    if 8 * n_values <= RECOVERY_BATCH_BYTES:
        return [list(fields)]
    scalars = [f for f in fields if f[1] == 1]
    return [[f] for f in fields if f[1] != 1] + ([scalars] if scalars else [])


def _joined(parts: list[np.ndarray]) -> np.ndarray:
    """The parts joined along their last axis; a single part as it is (read only: a tensor
    field's batch at 320x160 is 15 MB that a copy would pass over twice)."""
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=-1)


def _split(values: np.ndarray, fields):
    """(m, k) stacked components -> {name: (m, components)} (tensors as ParaView's 6)."""
    out, k = {}, 0
    for name, ncomp, _ in fields:
        part = values[:, k:k + ncomp]
        out[name] = tensor6(part) if ncomp == 4 else part[:, 0]
        k += ncomp
    return out


def _vec3(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, float).reshape(len(a), -1)
    return np.column_stack([a, np.zeros(len(a))]) if a.shape[1] == 2 else a


def file_tag(name: str) -> str:
    """A block name as a file-name part: ``BLOCK_BOTTOM->FLAT`` -> ``BLOCK_BOTTOM-FLAT``."""
    return re.sub(r"-+", "-", re.sub(r"[^A-Za-z0-9_.]+", "-", name)).strip("-") or "x"


_VTK_TYPES = {"f8": "Float64", "i8": "Int64", "i4": "Int32", "u1": "UInt8"}


class _Data:
    """The point, cell or field data of a :class:`_Grid`: named arrays in order, and the
    names ParaView shows first (``vectors``, ``tensors``)."""

    def __init__(self):
        self.arrays: list[tuple[str, np.ndarray]] = []
        self.vectors: str | None = None
        self.tensors: str | None = None

    def add(self, name: str, values) -> None:
        values = np.asarray(values)
        code = values.dtype.kind + str(values.dtype.itemsize)
        if code not in _VTK_TYPES:                 # bool, int16, float32 ...: widened
            values = values.astype(np.float64 if values.dtype.kind == "f" else np.int64)
        self.arrays.append((name, values))


class _Grid:
    """An unstructured grid as a VTU file holds it: points (n, 3), cells (VTK connectivity,
    end offsets, types) and point, cell and field data."""

    def __init__(self, points: np.ndarray, conn: list[np.ndarray], types: list[np.ndarray]):
        self.points = np.ascontiguousarray(points, float)
        self.connectivity = np.concatenate([c.ravel() for c in conn] + [np.zeros(0)]).astype(np.int64)
        sizes = np.concatenate([np.full(len(c), c.shape[1]) for c in conn] + [np.zeros(0)])
        self.offsets = np.cumsum(sizes).astype(np.int64)
        self.types = np.concatenate(list(types) + [np.zeros(0)]).astype(np.uint8)
        self.point_data, self.cell_data, self.field_data = _Data(), _Data(), _Data()


def _grid(points: np.ndarray, conn: list[np.ndarray], types: list[np.ndarray]) -> _Grid:
    """A grid from points (n, 3), connectivity chunks (c, k) and their types (c,)."""
    return _Grid(points, conn, types)


def _field(grid: _Grid, name: str, value, kind: str = "int") -> None:
    """One field-data value (TIME, STEP ...; a name-only marker when ``value`` is None)."""
    grid.field_data.add(name, np.array([0 if value is None else value],
                                       np.float64 if kind == "float" else np.int32))


#: bytes of an array base64-encoded per call: a multiple of 3, so that the pieces' encodings
#: concatenate to the encoding of the whole (no padding inside), and above the 4-byte count;
#: 1 MiB of text per piece
_PIECE = 3 << 18


def _appended_size(nbytes: int) -> int:
    """Length of an array's appended base64 text: its UInt32 byte count and its bytes."""
    return 4 * ((4 + nbytes + 2) // 3)


def _write_appended(fh, values: np.ndarray) -> None:
    """The appended data of one array (its UInt32 byte count, then its bytes, base64) written
    piece by piece: what ``base64.b64encode(count + values.tobytes())`` gives, without a copy
    of the array or its whole text in memory.  ``fh``: anything with ``write``."""
    raw = values.reshape(-1).view(np.uint8)
    head = struct.pack("<I", raw.size)
    first = _PIECE - len(head)
    fh.write(base64.b64encode(head + raw[:first].tobytes()))
    for a in range(first, raw.size, _PIECE):
        fh.write(base64.b64encode(raw[a:a + _PIECE]))


class _Pieces(list):
    """The pieces of a small file, written at once (``write`` is ``append``)."""
    write = list.append


def _write_vtu(grid: _Grid, path: Path) -> None:
    """The VTU file of ``grid`` as VTK's own XML writer writes it with appended, base64-encoded,
    uncompressed data (``header_type="UInt32"``: each array is the base64 text of its byte
    count and its bytes, little-endian), which ParaView, VTK and meshio read (see the module
    doc for the encoding).  Written here rather than through the vtk library: its import and
    objects were 0.1-0.2 s of a short run.

    The XML comes first, each array's offset from the lengths of the texts before it; then
    every array is encoded and written piece by piece (:func:`_write_appended`): the file is
    never whole in memory (at 320x160 the body file's text was ~0.1 GB, built beside the arrays
    it encodes while the factor was held)."""
    xml, arrays, offset = [], [], 0

    def array(name, values, indent, extra="", tuples=False):
        nonlocal offset
        values = np.ascontiguousarray(values)
        values = values.astype(values.dtype.newbyteorder("<"), copy=False)
        ncomp = values.shape[1] if values.ndim == 2 else 1
        attrs = f'type="{_VTK_TYPES[values.dtype.kind + str(values.dtype.itemsize)]}"{extra} ' \
                f'Name={quoteattr(name)}'
        if tuples:
            attrs += f' NumberOfTuples="{len(values)}"'
        elif ncomp > 1:
            attrs += f' NumberOfComponents="{ncomp}"'
            if ncomp == 6:
                attrs += "".join(f' ComponentName{k}="{c}"' for k, c in enumerate(TENSOR_NAMES))
        xml.append(f'{indent}<DataArray {attrs} format="appended" offset="{offset}"/>')
        arrays.append(values)
        offset += _appended_size(values.nbytes)

    def data(tag, d: _Data):
        active = "".join(f' {key}={quoteattr(v)}' for key, v in (("Vectors", d.vectors),
                                                                  ("Tensors", d.tensors)) if v)
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
    if offset <= _PIECE:
        # a small file (every state of the main job): its pieces joined and written in one
        # call without a buffer (a 768 KB buffer per file was allocated, and mapped, to be
        # filled a few KB deep)
        fh = _Pieces()
        _write_vtu_text(fh, xml, arrays)
        with open(path, "wb", buffering=0) as raw:
            raw.write(b"".join(fh))
        return
    with open(path, "wb", buffering=_PIECE) as fh:     # small arrays: one write per piece
        _write_vtu_text(fh, xml, arrays)


def _write_vtu_text(fh, xml: list[str], arrays: list[np.ndarray]) -> None:
    """The XML, then every array's appended data, then the end of the file, into ``fh``."""
    fh.write("\n".join(xml).encode())
    for values in arrays:
        _write_appended(fh, values)
    fh.write(b"\n  </AppendedData>\n</VTKFile>\n")


def read_pvd(path: Path) -> list[tuple[float, int, str, str]]:
    """(timestep, part, file, name) of each DataSet of a PVD file, one per line as
    :class:`VtkWriter` writes them; a line that is not a whole DataSet element (torn by a run
    killed while appending, always at or after the time a resumed run starts from) is skipped."""
    import xml.etree.ElementTree as ET      # only to resume a series
    out = []
    for line in Path(path).read_text(errors="replace").splitlines():
        line = line.strip()
        if not line.startswith("<DataSet"):
            continue
        try:
            d = ET.fromstring(line)
        except ET.ParseError:
            continue
        out.append((float(d.get("timestep", 0)), int(d.get("part", 0)), d.get("file", ""),
                    d.get("name", "")))
    return out


_PVD_HEAD = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" '
             'byte_order="LittleEndian">\n  <Collection>\n')
_PVD_FOOT = "  </Collection>\n</VTKFile>\n"


def _pvd_line(t: float, part: int, fname: str, name: str) -> str:
    return (f'    <DataSet timestep="{t!r}" group="" part="{part}" name={quoteattr(name)} '
            f'file={quoteattr(fname)}/>\n')


class VtkWriter(Writer):
    """VTU files of the body, each contact pair and each foundation per output state; a PVD.

    See the module docstring."""

    def __init__(self, outdir, model, append: bool = False):
        super().__init__(outdir, model, append)
        self.fields: set[str] | None = None       # *OUTPUT, FIELDS= of the step; None: all
        self.parts: dict[str, int] = {"body": 0}  # block name -> part number
        self._plan: RecoveryPlan | None = None    # the body's recovery plan (fixed mesh)
        self._references: dict[str, np.ndarray] = {}  # foundation -> its reference samples

    def start_run(self) -> None:
        self.outdir.mkdir(parents=True, exist_ok=True)
        self.deck = self.model.name or "run"
        self.pvd_path = self.outdir / f"{self.deck}.pvd"
        self.counter = 0
        self.entries: list[tuple[float, int, str, str]] = []    # (time, part, file, name)
        self._pending_trim = self.append and self.pvd_path.exists()
        if self._pending_trim:
            self.entries = read_pvd(self.pvd_path)
            for _, part, _, name in self.entries:
                if name:
                    self.parts.setdefault(name, part)
        else:
            self._write_pvd()

    def _resume_at(self, time: float) -> None:
        """Drop the entries an interrupted run wrote at or after ``time``; continue the counter."""
        self._pending_trim = False
        self.entries = [e for e in self.entries if e[0] < time]
        numbers = [int(m.group(1)) for _, _, name, _ in self.entries
                   if (m := re.search(r"_(\d+)\.vtu$", name))]
        self.counter = max(numbers, default=-1) + 1
        self._write_pvd()

    def initial(self, result: IncrementResult) -> None:
        """The state at t = 0: the first entries of the series."""
        self._write_state(result)

    def increment(self, result: IncrementResult) -> None:
        if self._pending_trim:
            self._resume_at(float(result.time))
        if result.write_fields:
            self._write_state(result)

    def _write_state(self, result: IncrementResult) -> None:
        stem = f"{self.deck}_{{}}{self.counter:04d}.vtu"
        # each grid built when its file is written: one grid's arrays alive at a time
        blocks = [("body", stem.format(""), lambda: self._body_grid(result))]
        blocks += [(f"contact {cp.name}", stem.format(f"contact_{file_tag(cp.name)}_"),
                    lambda cp=cp: self._contact_grid(result, cp)) for cp in result.contacts]
        blocks += [(f"foundation {name}", stem.format(f"foundation_{file_tag(name)}_"),
                    lambda name=name, pts=pts: self._foundation_grid(result, name, pts))
                   for name, pts in result.foundations.items()]
        first = len(self.entries)
        for name, fname, grid in blocks:
            _write_vtu(grid(), self.outdir / fname)
            part = self.parts.setdefault(name, len(self.parts))
            self.entries.append((float(result.time), part, fname, name))
        self.counter += 1
        self._append_pvd(first)

    def start_step(self, step_number: int, step) -> None:
        fields = step.output.fields
        self.fields = set(fields) if fields else None          # None: every field

    def _wants(self, name: str) -> bool:
        """``*OUTPUT, FIELDS=`` of the step asks for ``name`` (U, S, LE, PE, PEEQ, RF), or
        nothing was asked (all)."""
        return self.fields is None or name in self.fields

    def close(self, status: int, message: str) -> None:
        pass

    # -- blocks --------------------------------------------------------------------------
    def _body_grid(self, r: IncrementResult):
        n = len(r.coords0)
        conn = [np.asarray(c.conn) for c in r.cells]
        types = [np.full(len(c.conn), c.element.vtk_cell) for c in r.cells]
        grid = _grid(_vec3(r.coords0), conn, types)

        pd = grid.point_data
        if self._wants("U"):
            pd.add("displacement", _vec3(r.u))
            pd.vectors = "displacement"
        if self._wants("RF"):
            pd.add("reaction", _vec3(r.reaction))
        fields = body_fields(r.cells, self._wants)
        cd = grid.cell_data
        ids = (np.concatenate([np.asarray(c.ids, np.int64) for c in r.cells]) if r.cells
               else np.zeros(0, np.int64))
        cd.add("element_id", ids)
        if fields and r.cells:
            conns = [np.asarray(c.conn) for c in r.cells]
            if self._plan is None or not self._plan.fits(n, conns):
                self._plan = RecoveryPlan(n, conns)
            nodal, element = recovered(n, r.cells, fields, plan=self._plan)
            for name, values in nodal.items():
                pd.add(name, values)
            for name, values in element.items():
                cd.add(f"element_{name}", values)
            if any(f[0] == "stress" for f in fields):
                pd.tensors = "stress"
        pd.add("node_id", np.asarray(self.model.node_ids, np.int64))
        self._add_metadata(grid, r)
        return grid

    def _contact_grid(self, r: IncrementResult, cp):
        x = np.asarray(cp.x, float).reshape(-1, 2)
        x0 = np.asarray(cp.x0, float).reshape(-1, 2)
        g = len(x)
        grid = _grid(_vec3(x0), [np.arange(g)[:, None]], [np.full(g, VTK_VERTEX)])
        pd = grid.point_data
        pd.add("displacement", _vec3(x - x0))
        pd.vectors = "displacement"
        for name, values in (("p", cp.p), ("tau", cp.tau), ("gap", cp.gap), ("slip", cp.slip),
                             ("signed_slip", cp.vp), ("slip_increment", cp.dvp),
                             ("dissipation", cp.dissip), ("lambda", cp.lam)):
            pd.add(name, np.asarray(values, float).ravel())
        for name, values in (("status", cp.status), ("element", cp.element), ("face", cp.face),
                             ("gauss", cp.gauss)):
            pd.add(name, np.asarray(values).ravel().astype(np.int32))
        for code, status in enumerate(STATUS_NAMES):
            _field(grid, f"status_{status}", code)
        self._add_metadata(grid, r)
        return grid

    def _foundation_grid(self, r: IncrementResult, name: str, points):
        current = Foundation(points).sample(SAMPLES_PER_ARC)
        spec = self.model.foundations.get(name)
        if spec is not None and np.shape(spec.points) == np.shape(points):
            if name not in self._references:        # the deck's position: sampled once
                self._references[name] = Foundation(spec.points).sample(SAMPLES_PER_ARC)
            reference = self._references[name]
        else:
            reference = current
        m = len(reference) - 1
        grid = _grid(_vec3(reference), [np.column_stack([np.arange(m), np.arange(1, m + 1)])],
                     [np.full(m, VTK_LINE)])
        grid.point_data.add("displacement", _vec3(current - reference))
        grid.point_data.vectors = "displacement"
        self._add_metadata(grid, r)
        return grid

    def _add_metadata(self, grid, r: IncrementResult) -> None:
        """TIME, STEP, INCREMENT (ParaView shows them with "Python Annotation") and the units."""
        _field(grid, "TIME", r.time, "float")
        _field(grid, "STEP", r.step)
        _field(grid, "INCREMENT", r.increment)
        units = tuple(self.model.units)
        if units:
            _field(grid, "units: " + ", ".join(f"{what} {u}" for what, u in
                                               zip(("length", "force", "stress"), units)), None)

    # -- index ---------------------------------------------------------------------------
    def _write_pvd(self) -> None:
        """Rewrite the PVD index atomically (tmp file + rename): at the start and on resuming."""
        body = (_PVD_HEAD + "".join(_pvd_line(*e) for e in self.entries)).encode()
        write_atomic(self.pvd_path, body + _PVD_FOOT.encode())
        self._pvd_end = len(body)           # where the footer starts

    def _append_pvd(self, first: int) -> None:
        """Add the entries from ``first`` on: written over the footer, with the footer, in one
        write.  Not a rewrite and rename: the index grows by a line per block and state, and a
        rename over the old file costs 0.1-3 ms of wall time on ext4 (it starts the new file's
        write-back) and the whole index's formatting, quadratic in the run's length (1.6 ms at
        650 entries).  A reader sees the new index or, during that one write, its old entries
        with part of the new; a run killed then leaves a torn last line, which a resumed run
        (:func:`read_pvd`) skips and rewrites."""
        data = "".join(_pvd_line(*e) for e in self.entries[first:]).encode()
        with open(self.pvd_path, "r+b") as fh:
            fh.seek(self._pvd_end)
            fh.write(data + _PVD_FOOT.encode())
        self._pvd_end += len(data)
