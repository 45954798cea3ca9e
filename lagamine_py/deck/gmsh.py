"""A gmsh ``.msh`` file (format 2.2 or 4.1, ASCII or binary) as arrays, read through meshio.

:func:`read_msh` returns a :class:`GmshMesh`: the node coordinates, the cells of each kind in
the order of the file (``quad8``, ``quad4``, ``tri6``, ``tri3``, ``line3``, ``line2``,
``vertex``, or meshio's name for anything else), the line of each cell in an ASCII file, and the
physical groups (name, dimension, the cells of each kind they hold).  Nothing here knows about
the model: the deck builder decides what the cells become.

meshio does the reading (it is well kept and reads every variant); what this module adds:

* the line of each element in an ASCII file, for messages: one element per line in format 2.2
  (``$Elements``, its count, then the elements in order), and in 4.1 a header line per entity
  block (meshio keeps one cell block per entity block, empty ones included);
* physical groups from both formats: format 4.1 gives named groups as meshio cell sets (every
  group of an entity) and the first group's tag per cell; format 2.2 gives the tag per cell,
  writing an element once per group it belongs to (those copies are merged here);
* node order ``(end, end, mid)`` for 3-node lines, as meshio gives them (Abaqus writes ``(end,
  mid, end)``); 8-node quads and 6-node triangles are in Abaqus order already;
* errors as :class:`MeshError` with the line where reading stopped (ASCII), and meshio's own
  warnings (printed with ``rich``) collected as :attr:`GmshMesh.warnings`.

Measured on this machine, a 1 011 521-node, 336 400-Q8 mesh: meshio reads it in 2.0 s (4.1
ASCII), 0.06 s (4.1 binary), 2.8 s (2.2 ASCII) and 4.0 s (2.2 binary, whose reader loops over
the elements in Python); the arrays here add well under a second.
"""
from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["GmshMesh", "PhysicalGroup", "MeshError", "read_msh"]

#: meshio cell type -> our name of the shape
CELL_KINDS = {"quad8": "quad8", "quad": "quad4", "triangle6": "tri6", "triangle": "tri3",
         "line3": "line3", "line": "line2", "vertex": "vertex"}
DIMENSION = {"quad8": 2, "quad4": 2, "tri6": 2, "tri3": 2, "line3": 1, "line2": 1, "vertex": 0}


class MeshError(Exception):
    """The file cannot be read as a gmsh mesh: ``line`` (0 when unknown) and the message."""

    def __init__(self, line: int, message: str):
        super().__init__(message)
        self.line = int(line)
        self.message = message


@dataclass
class PhysicalGroup:
    """A physical group: ``name`` (``PHYSICAL_<tag>`` when gmsh has none), ``dim``, ``tag``, and
    ``cells``: kind -> (c,) indices into :attr:`GmshMesh.conn` of that kind."""
    name: str
    dim: int
    tag: int
    cells: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class GmshMesh:
    """``coords`` (n, 3); per kind: ``conn[kind]`` (c, nodes) node rows and ``lines[kind]`` (c,)
    the file line of each cell (None in a binary file); ``groups`` the physical groups in tag
    order; ``version`` ("2.2" or "4.1") and ``binary``; ``warnings`` meshio's messages."""
    path: str
    version: str
    binary: bool
    coords: np.ndarray
    conn: dict[str, np.ndarray]
    lines: dict[str, np.ndarray | None]
    groups: list[PhysicalGroup]
    warnings: list[str]


def _header(data: bytes) -> tuple[str, bool]:
    """(version, binary) from ``$MeshFormat``; MeshError when the file does not start with it."""
    head = data.lstrip()
    if not (head.startswith(b"$MeshFormat") or head.startswith(b"$Comments")):
        raise MeshError(1, "not a gmsh mesh: it does not start with $MeshFormat")
    start = data.find(b"$MeshFormat")
    line = data[start:start + 200].split(b"\n")[1].split()
    if len(line) < 3:
        raise MeshError(data.count(b"\n", 0, start) + 2, "cannot read the $MeshFormat line "
                                                         "(expected: version, file type, data size)")
    version = line[0].decode(errors="replace")
    if version not in ("2.2", "2", "4.1", "4"):
        raise MeshError(data.count(b"\n", 0, start) + 2,
                        f"gmsh format {version}: save the mesh in format 4.1 or 2.2 "
                        f"(gmsh: Mesh.MshFileVersion = 4.1)")
    return ("2.2" if version.startswith("2") else "4.1"), line[1] == b"1"


def _line_of(data: bytes, section: bytes) -> int:
    """The line number of the line ``section`` (``$Elements``) in the file."""
    at = data.find(b"\n" + section)
    return data.count(b"\n", 0, at + 1) + 1 if at >= 0 else 0


def _element_lines(data: bytes, version: str, sizes: list[int]) -> np.ndarray:
    """(sum(sizes),) the line of each element of the file in order; ``sizes`` the cells of
    each meshio block."""
    first = _line_of(data, b"$Elements") + 2              # after $Elements and its counts line
    total = int(sum(sizes))
    if version == "2.2":
        return first + np.arange(total)
    # 4.1: before block b come its own header and the earlier blocks with theirs
    headers = np.cumsum([1] * len(sizes))
    return first + np.arange(total) + np.repeat(headers, sizes)


def read_msh(path, label: str | None = None) -> GmshMesh:
    """The gmsh mesh at ``path`` (``label``: how messages name it); MeshError when it cannot
    be read."""
    import meshio
    from meshio.gmsh.main import read_buffer

    path = Path(path)
    label = str(path) if label is None else label
    data = path.read_bytes()
    version, binary = _header(data)
    err = io.StringIO()
    with open(path, "rb") as fh, contextlib.redirect_stderr(err):
        try:
            mesh = read_buffer(fh)
        except Exception as exc:                # meshio raises ReadError, ValueError, KeyError ...
            where = 0 if binary else data.count(b"\n", 0, min(fh.tell(), len(data))) + 1
            reason = str(exc) or type(exc).__name__
            if isinstance(exc, KeyError):
                reason = f"unknown element type {exc.args[0]}"
            elif isinstance(exc, IndexError):
                reason = "an element names a node that is not in the file (or the file is cut short)"
            raise MeshError(where, f"cannot read the gmsh mesh: {reason}") from None
    warnings = [" ".join(w.split()) for w in err.getvalue().replace("Warning:", "\n").splitlines() if w.strip()]
    if not isinstance(mesh, meshio.Mesh) or mesh.points is None or not len(mesh.cells):
        raise MeshError(0, "the file holds no elements")
    sizes = [len(c.data) for c in mesh.cells]
    lines = None if binary else _element_lines(data, version, sizes)
    kinds = [CELL_KINDS.get(c.type, c.type) for c in mesh.cells]
    offsets = np.concatenate([[0], np.cumsum(sizes)])

    # cells of each kind, in file order; where each block's cells land among them
    conn: dict[str, list[np.ndarray]] = {}
    line_of: dict[str, list[np.ndarray]] = {}
    start_in_kind = []
    for b, (kind, block) in enumerate(zip(kinds, mesh.cells)):
        start_in_kind.append(sum(len(c) for c in conn.get(kind, [])))
        c = np.asarray(block.data, np.int64).reshape(len(block.data), -1)
        conn.setdefault(kind, []).append(c)
        line_of.setdefault(kind, []).append(None if lines is None else lines[offsets[b]:offsets[b + 1]])
    conn_k = {k: np.concatenate(v) for k, v in conn.items()}
    lines_k = {k: None if lines is None else np.concatenate(v) for k, v in line_of.items()}

    groups = _groups(mesh, kinds, start_in_kind)
    if version == "2.2":                        # 4.1 gives groups per entity: no copies
        conn_k, lines_k, groups = _merge_copies(conn_k, lines_k, groups)
    return GmshMesh(label, version, binary, np.asarray(mesh.points, float).reshape(len(mesh.points), -1),
                    conn_k, lines_k, groups, warnings)


def _groups(mesh, kinds: list[str], start_in_kind: list[int]) -> list[PhysicalGroup]:
    """The physical groups, with their cells as indices among the cells of each kind."""
    names = {(int(v[1]), int(v[0])): str(k) for k, v in mesh.field_data.items()
             if np.size(v) >= 2}                      # (dim, tag) -> name
    found: dict[tuple[int, int], dict[str, list[np.ndarray]]] = {}

    def add(dim, tag, kind, idx):
        found.setdefault((dim, tag), {}).setdefault(kind, []).append(idx)

    sets = mesh.cell_sets or {}
    physical = mesh.cell_data.get("gmsh:physical")
    for b, kind in enumerate(kinds):
        dim = DIMENSION.get(kind, -1)
        named_here = set()
        for (gdim, tag), name in names.items():       # format 4.1: named groups, every one
            members = sets.get(name)
            if members is not None and b < len(members) and members[b] is not None and len(members[b]) \
                    and gdim == dim:
                add(gdim, tag, kind, start_in_kind[b] + np.asarray(members[b], np.int64))
                named_here.add(tag)
        if physical is None or b >= len(physical):
            continue
        tags = np.asarray(physical[b], np.int64)
        for tag in np.unique(tags):
            if int(tag) in named_here or (sets and (dim, int(tag)) in names):
                continue                               # already taken from the cell sets
            add(dim, int(tag), kind, start_in_kind[b] + np.flatnonzero(tags == tag))
    out = []
    for (dim, tag), cells in sorted(found.items()):
        if dim < 0 or tag <= 0:
            continue
        out.append(PhysicalGroup(names.get((dim, tag), f"PHYSICAL_{tag}"), dim, tag,
                         {k: np.unique(np.concatenate(v)) for k, v in cells.items()}))
    return out


def _merge_copies(conn, lines, groups):
    """Format 2.2 writes an element once per physical group it belongs to: keep the first copy
    of each 2D element (same nodes) and point the groups at it."""
    for kind in [k for k in conn if DIMENSION.get(k) == 2]:
        c = conn[kind]
        _, first, inverse = np.unique(np.sort(c, axis=1), axis=0, return_index=True, return_inverse=True)
        if len(first) == len(c):
            continue
        keep = np.sort(first)
        new_index = np.full(len(c), -1)
        new_index[keep] = np.arange(len(keep))
        where = new_index[first[inverse.ravel()]]     # every copy -> the kept copy's new index
        conn[kind] = c[keep]
        if lines[kind] is not None:
            lines[kind] = lines[kind][keep]
        for g in groups:
            if kind in g.cells:
                g.cells[kind] = np.unique(where[g.cells[kind]])
    return conn, lines, groups
