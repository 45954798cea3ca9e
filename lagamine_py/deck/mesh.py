"""The nodes and elements a deck defines, kept as arrays while the deck is read.

The builder adds nodes and elements in chunks (a ``*NODE`` block, a ``*MESH``, an imported mesh)
and asks vectorised questions of them: which of these ids exist, where was this one defined,
which rows do these ids have.  Ids are looked up in a sorted copy (refreshed after additions),
so a million nodes cost a few arrays, not a million dictionary entries.  Every node and element
remembers the file and line that defined it, for messages.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Files", "NodeTable", "ElementGroup", "ElementIndex", "LineCells", "FaceTable",
           "face_table", "chain_lines"]


class Files:
    """File names by index (the file column of the tables is an int)."""

    def __init__(self):
        self.names: list[str] = []
        self._index: dict[str, int] = {}

    def index(self, name: str) -> int:
        if name not in self._index:
            self._index[name] = len(self.names)
            self.names.append(name)
        return self._index[name]


class _Sorted:
    """Lookup of ids in chunks of (ids, payload) arrays through a sorted copy."""

    def __init__(self):
        self._ids: list[np.ndarray] = []
        self._pos: list[np.ndarray] = []
        self._sorted = None                 # (sorted ids, positions)
        self.count = 0

    def add(self, ids: np.ndarray) -> np.ndarray:
        """Append ``ids`` (k,); their positions (k,) in insertion order."""
        pos = self.count + np.arange(len(ids))
        self._ids.append(np.asarray(ids, np.int64))
        self._pos.append(pos)
        self.count += len(ids)
        self._sorted = None
        return pos

    def all_ids(self) -> np.ndarray:
        return np.concatenate(self._ids) if self._ids else np.zeros(0, np.int64)

    def find(self, ids) -> np.ndarray:
        """Positions of ``ids`` (any shape), -1 where absent."""
        ids = np.asarray(ids, np.int64)
        if self._sorted is None:
            all_ids = self.all_ids()
            order = np.argsort(all_ids, kind="stable")
            all_pos = np.concatenate(self._pos) if self._pos else np.zeros(0, np.int64)
            self._sorted = (all_ids[order], all_pos[order])
        keys, pos = self._sorted
        at = np.searchsorted(keys, ids)
        at_c = np.minimum(at, max(len(keys) - 1, 0))
        hit = (at < len(keys)) & (keys[at_c] == ids) if len(keys) else np.zeros(ids.shape, bool)
        return np.where(hit, pos[at_c] if len(keys) else -1, -1)

    def max_id(self) -> int:
        return max((int(c.max()) for c in self._ids if len(c)), default=0)


class NodeTable:
    """Nodes in deck order: ids, coordinates and where each was defined (file index, line)."""

    def __init__(self, files: Files):
        self.files = files
        self.index = _Sorted()
        self._xy: list[np.ndarray] = []
        self._file: list[np.ndarray] = []
        self._line: list[np.ndarray] = []

    def __len__(self) -> int:
        return self.index.count

    def add(self, ids, xy, file: str | np.ndarray, lines) -> np.ndarray:
        """Append nodes (ids not checked here); their rows (k,)."""
        ids = np.asarray(ids, np.int64)
        f = np.full(len(ids), self.files.index(file)) if isinstance(file, str) else np.asarray(file)
        self._xy.append(np.asarray(xy, float).reshape(-1, 2))
        self._file.append(f)
        self._line.append(np.broadcast_to(np.asarray(lines, np.int64), ids.shape).copy())
        return self.index.add(ids)

    def rows(self, ids) -> np.ndarray:
        """Rows of node ids (any shape), -1 for ids not defined."""
        return self.index.find(ids)

    def where(self, row: int) -> tuple[str, int]:
        f = np.concatenate(self._file)[row]
        return self.files.names[int(f)], int(np.concatenate(self._line)[row])

    def ids(self) -> np.ndarray:
        return self.index.all_ids()

    def coords(self) -> np.ndarray:
        return np.concatenate(self._xy) if self._xy else np.zeros((0, 2))

    def max_id(self) -> int:
        return self.index.max_id()


class LineCells:
    """Line elements of an imported Abaqus mesh (T3D3, B22 ...: ``nen`` 2 or 3, nodes ``end, mid,
    end`` for 3): they carry no stiffness, they say which faces make a surface (or which arcs
    a tool profile)."""
    nen = 0
    faces = ()
    axisymmetric = False


@dataclass(eq=False)                   # groups are told apart by identity (their blocks hold arrays)
class ElementGroup:
    """Elements of one *ELEMENT or *MESH block (one type): ids, connectivity in node rows, the
    file index and line of each, and (at the end of the model data) its *SOLID index.  ``line``:
    line elements of an *IMPORT (:class:`LineCells`), not part of the model."""
    type: str
    cls: type
    nen: int
    block: object
    _ids: list[np.ndarray] = field(default_factory=list)
    _conn: list[np.ndarray] = field(default_factory=list)
    _file: list[np.ndarray] = field(default_factory=list)
    _line: list[np.ndarray] = field(default_factory=list)
    line: bool = False

    def add(self, ids, conn, file_index, lines) -> None:
        ids = np.asarray(ids, np.int64)
        self._ids.append(ids)
        self._conn.append(np.asarray(conn, np.int64).reshape(len(ids), self.nen))
        self._file.append(np.broadcast_to(np.asarray(file_index, np.int64), ids.shape).copy())
        self._line.append(np.broadcast_to(np.asarray(lines, np.int64), ids.shape).copy())

    def __len__(self) -> int:
        return sum(len(c) for c in self._ids)

    def ids(self) -> np.ndarray:
        return np.concatenate(self._ids) if self._ids else np.zeros(0, np.int64)

    def conn(self) -> np.ndarray:
        return np.concatenate(self._conn) if self._conn else np.zeros((0, self.nen), np.int64)

    def where(self, files: Files, k: int) -> tuple[str, int]:
        return files.names[int(np.concatenate(self._file)[k])], int(np.concatenate(self._line)[k])

    def positions(self, files: Files) -> tuple[np.ndarray, np.ndarray]:
        """(file name (e,) object, line (e,)) of every element."""
        if not self._ids:
            return np.zeros(0, object), np.zeros(0, np.int64)
        names = np.array(files.names, object)
        return names[np.concatenate(self._file)], np.concatenate(self._line)

    def set_conn(self, conn: np.ndarray) -> None:
        """Replace the connectivity of all elements (e, nen), in order (renumbered elements)."""
        self._conn = [np.asarray(conn, np.int64).reshape(len(self), self.nen)]


class ElementIndex:
    """Every element id of the deck -> (group, position in the group)."""

    def __init__(self):
        self.index = _Sorted()
        self._group: list[np.ndarray] = []
        self._k: list[np.ndarray] = []
        self._cat = None

    def add(self, group: int, ids, first_k: int) -> None:
        ids = np.asarray(ids, np.int64)
        self.index.add(ids)
        self._group.append(np.full(len(ids), group))
        self._k.append(first_k + np.arange(len(ids)))
        self._cat = None

    def find(self, ids) -> tuple[np.ndarray, np.ndarray]:
        """(group, k) of element ids (any shape); group -1 where not defined."""
        pos = self.index.find(ids)
        if self._cat is None:
            self._cat = (np.concatenate(self._group + [np.zeros(1, np.int64)]),
                         np.concatenate(self._k + [np.zeros(1, np.int64)]))
        g, k = self._cat
        ok = pos >= 0
        return np.where(ok, g[pos], -1), np.where(ok, k[pos], -1)

    def __contains__(self, eid) -> bool:
        return bool(self.index.find(np.array([eid]))[0] >= 0)

    def max_id(self) -> int:
        return self.index.max_id()


@dataclass
class FaceTable:
    """Element faces keyed by their corner nodes: ``a < b`` (F,) node rows of the corners,
    ``mid`` (F,) the mid-side node row (-1 without), ``element`` (F,) deck ids, ``face`` (F,)
    face numbers 1.."""
    a: np.ndarray
    b: np.ndarray
    mid: np.ndarray
    element: np.ndarray
    face: np.ndarray

    def find(self, a, b) -> tuple[np.ndarray, np.ndarray]:
        """For edges with corners ``a``, ``b`` (k,) (either order): ``(count (k,), index (k, 2))``
        the number of faces on each edge and the first two of them (-1 where fewer)."""
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        n = int(max(self.b.max(initial=0), hi.max(initial=0))) + 1
        keys = self.a * n + self.b
        order = np.argsort(keys, kind="stable")
        sk = keys[order]
        want = lo * n + hi
        first = np.searchsorted(sk, want, side="left")
        last = np.searchsorted(sk, want, side="right")
        count = last - first
        idx = np.full((len(want), 2), -1)
        for j in range(2):
            has = count > j
            idx[has, j] = order[first[has] + j]
        return count, idx

    def counts(self) -> np.ndarray:
        """(F,) how many faces share each face's corners (1 on the boundary)."""
        n = int(self.b.max(initial=0)) + 1
        _, inverse, cnt = np.unique(self.a * n + self.b, return_inverse=True, return_counts=True)
        return cnt[inverse.ravel()]


def face_table(groups) -> FaceTable:
    """The faces of ``groups``: (element class, ids (e,), conn (e, nen) node rows) triples."""
    parts = []
    for cls, ids, conn in groups:
        for k, f in enumerate(cls.faces):
            ca, cb = conn[:, f[0]], conn[:, f[1]]
            mid = conn[:, f[2]] if len(f) > 2 else np.full(len(conn), -1)
            parts.append((np.minimum(ca, cb), np.maximum(ca, cb), mid, np.asarray(ids), np.full(len(conn), k + 1)))
    if not parts:
        z = np.zeros(0, np.int64)
        return FaceTable(z, z, z, z, z)
    return FaceTable(*(np.concatenate(c).astype(np.int64) for c in zip(*parts)))


def chain_lines(ends: np.ndarray, mids: np.ndarray | None) -> tuple[np.ndarray, str]:
    """The points of lines that chain into one open path, in order: ``ends`` (k, 2) node
    numbers of each line's ends, ``mids`` (k,) its middle node (None: straight 2-node lines).
    Returns ``(points (2k + 1,), "")`` -- end, mid, end, mid, ..., end (a 2-node line's middle is
    -1) -- running the way the first line runs, or ``(empty, why)`` when the lines branch, leave
    a gap or close on themselves."""
    k = len(ends)
    if k == 0:
        return np.zeros(0, np.int64), "it has no lines"
    mids = np.full(k, -1) if mids is None else np.asarray(mids)
    nodes, count = np.unique(ends, return_counts=True)
    if (count > 2).any():
        return np.zeros(0, np.int64), f"it branches at a node shared by {int(count.max())} lines"
    tips = nodes[count == 1]
    if len(tips) == 0:
        return np.zeros(0, np.int64), "it closes on itself (a tool profile is an open chain)"
    if len(tips) > 2:
        return np.zeros(0, np.int64), f"it is not one chain: it has {len(tips) // 2} pieces"
    at: dict[int, list[int]] = {}
    for j, (a, b) in enumerate(ends.tolist()):
        at.setdefault(a, []).append(j)
        at.setdefault(b, []).append(j)
    # walk from the tip the first line's direction leads away from
    start = int(tips[0])
    out, used, node = [start], np.zeros(k, bool), start
    while True:
        nxt = [j for j in at[node] if not used[j]]
        if not nxt:
            break
        j = nxt[0]
        used[j] = True
        a, b = int(ends[j, 0]), int(ends[j, 1])
        node = b if a == node else a
        out += [int(mids[j]), node]
    pts = np.array(out, np.int64)
    first = int(np.flatnonzero(np.isin(pts[::2], ends[0]))[0])    # where line 0 sits in the walk
    if pts[2 * first] != ends[0, 0]:
        pts = pts[::-1]
    return pts, ""
