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

__all__ = ["Files", "NodeTable", "ElementGroup", "ElementIndex"]


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


@dataclass
class ElementGroup:
    """Elements of one *ELEMENT or *MESH block (one type): ids, connectivity in node rows, the
    file index and line of each, and (at the end of the model data) its *SOLID index."""
    type: str
    cls: type
    nen: int
    block: object
    _ids: list[np.ndarray] = field(default_factory=list)
    _conn: list[np.ndarray] = field(default_factory=list)
    _file: list[np.ndarray] = field(default_factory=list)
    _line: list[np.ndarray] = field(default_factory=list)

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
