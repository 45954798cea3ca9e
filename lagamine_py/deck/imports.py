"""``*IMPORT``: a user's mesh file read as it is, for the deck builder.

* A gmsh ``.msh`` (:mod:`.gmsh`, through meshio): its 2D elements become elements of the types
  ``ANALYSIS=`` and ``INTEGRATION=`` say (:func:`.abaqus.import_type`), numbered on from the
  largest element id defined so far, in the order of the file; the nodes they use (and the
  points of 0D groups) become nodes, numbered likewise.  Each physical group gives sets of its
  name (``PHYSICAL_<tag>`` without one): 2D -> ELSET; 0D -> NSET; 1D -> a SURFACE (the faces
  of the 2D elements its lines lie on; faces run with the body on their left) and an NSET of
  its nodes -- or, when no line of it touches the 2D mesh, a *curve*: a tool profile that
  ``*FOUNDATION, CURVE=`` makes into a chain of parabolic arcs (3-node lines; a 2-node line is a
  straight arc).
* An Abaqus/CalculiX ``.inp``: read by this program's own reader (ids, sets and surfaces keep
  their names; ``*PART``/``*INSTANCE`` flattened), its ``*NODE``, ``*ELEMENT``, ``*NSET``,
  ``*ELSET`` and ``*SURFACE`` only.  Any 2D continuum type becomes the ``ANALYSIS=`` type of
  its shape (plane-stress ``CPS8`` as gmsh writes it, too); line elements (``T3D3``...) make
  the element sets holding only them into a SURFACE and NSET -- or a curve -- as above.

A mesh error names the mesh file and, in an ASCII file, its line; in a binary one, the deck's
``*IMPORT`` line, the mesh file and the element's place.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.params import did_you_mean
from ..model import Surface, Where
from . import abaqus
from .grammar import Block
from .mesh import ElementGroup, LineCells, chain_lines, face_table

__all__ = ["ImportMixin"]

_MESH_KEYWORDS = ("NODE", "ELEMENT", "NSET", "ELSET", "SURFACE")
_KIND_OF_NEN = {8: "quad8", 4: "quad4", 6: "tri6"}


@dataclass
class _Importing:
    """The *IMPORT being read: its element types and where it stands."""
    analysis: str
    integration: str
    block: Block
    label: str


@dataclass
class _Curve:
    """A 1D group apart from the body: its lines' ends (k, 2) and middles (k,) (-1: 2-node) as
    rows of ``xy`` (n, 2), and where it was read."""
    ends: np.ndarray
    mids: np.ndarray | None
    xy: np.ndarray
    where: Where


def _first_seen(rows: np.ndarray) -> np.ndarray:
    """``rows`` without repeats, in the order each first appears."""
    _, first = np.unique(rows, return_index=True)
    return rows[np.sort(first)]


class ImportMixin:
    """The ``*IMPORT`` keyword and ``*FOUNDATION, CURVE=`` of the deck builder
    (:class:`lagamine_py.deck.builder._Builder` mixes it in)."""

    # ------------------------------------------------------------ the keyword
    def _kw_import(self, blk, params, data):
        before = len(self.pb.items)
        self._import(blk, params)
        # the sets of a mesh that could not be read are missing: said once, at the *IMPORT
        self.import_failed |= len(self.pb.items) > before

    def _import(self, blk, params):
        if self.importing is not None:
            self.pb.at(blk, "*IMPORT inside an imported file: import each mesh from the deck")
            return
        path = Path(blk.file).parent / params["INPUT"]
        label = str(path)
        if not path.is_file():
            self.pb.at(blk, f"mesh file {label} does not exist")
            return
        with open(path, "rb") as fh:
            head = fh.read(4096).lstrip()
        if path.suffix.lower() == ".msh" or head.startswith((b"$MeshFormat", b"$Comments")):
            self._import_msh(blk, params, path, label)
        elif path.suffix.lower() == ".inp" or head.startswith(b"*"):
            self._import_inp(blk, params, path, label)
        else:
            self.pb.at(blk, f"INPUT={params['INPUT']}: neither a gmsh .msh (starting with $MeshFormat) nor "
                            f"an Abaqus/CalculiX .inp (keyword lines starting with *)")

    def _import_summary(self, blk, label, nodes: int, groups, read_as: dict, names_before: dict):
        """One notice of what an *IMPORT made: nodes, elements by type (and the file's type they
        were read from), and the names it defined."""
        counts = ", ".join(f"{len(g)} {g.type}" + (f" (from {read_as[g.type]})" if g.type in read_as else "")
                           for g in groups if len(g))
        made = []
        for kind, table in (("ELSET", self.m.elsets), ("SURFACE", self.m.surfaces), ("NSET", self.m.nsets),
                            ("curve", self.curves)):
            new = [n for n in table if n not in names_before[kind]]
            if new:
                made.append(f"{kind} {', '.join(new)}")
        self._notice(blk.file, blk.line, blk.keyword, f"{label}: {nodes} nodes, {counts or 'no elements'}"
                                                     + (f"; {'; '.join(made)}" if made else ""))

    def _names(self) -> dict:
        return {"ELSET": set(self.m.elsets), "SURFACE": set(self.m.surfaces), "NSET": set(self.m.nsets),
                "curve": set(self.curves)}

    # ------------------------------------------------------------ gmsh
    def _import_msh(self, blk, params, path, label):
        from .gmsh import MeshError, read_msh
        try:
            mesh = read_msh(path, label)
        except MeshError as exc:
            if exc.line:
                self.pb.add(label, exc.line, blk.keyword, exc.message)
            else:
                self.pb.at(blk, f"{label}: {exc.message}")
            return
        except OSError as exc:
            self.pb.at(blk, f"{label}: cannot read the mesh: {exc.strerror or exc}")
            return
        for text in mesh.warnings:
            self._notice(blk.file, blk.line, blk.keyword, f"{label}: meshio says: {text}")

        def where(kind, k):
            """(file, line) of cell k of a kind, for messages."""
            lines = mesh.lines.get(kind)
            return (label, int(lines[k])) if lines is not None else (blk.file, blk.line)

        def at(kind, k, text):
            f, ln = where(kind, k)
            self.pb.add(f, ln, blk.keyword, text if lines_known else f"{label}: {text}")
        lines_known = not mesh.binary

        solid = [k for k in mesh.conn if k in ("quad8", "quad4", "tri6") and len(mesh.conn[k])]
        ok = True
        for kind, conn in mesh.conn.items():
            if not len(conn):
                continue
            message = _refused(kind, len(conn))
            if message:
                at(kind, 0, message)
                ok = False
            elif (conn < 0).any():                   # meshio's mark of a node tag not in the file
                k = int(np.flatnonzero((conn < 0).any(axis=1))[0])
                at(kind, k, "this element names a node that the file does not define")
                ok = False
        if not ok:
            return
        groups = {g.name: g for g in mesh.groups}
        if not solid and not any(g.dim == 1 for g in mesh.groups):
            self.pb.at(blk, f"{label} holds no 2D elements (8-node or 4-node quadrilaterals, 6-node "
                            f"triangles) and no 1D physical group")
            return
        xy = mesh.coords[:, :2]
        keep = np.zeros(len(xy), bool)                  # the nodes of 2D elements and 0D groups
        for k in solid:
            keep[mesh.conn[k].ravel()] = True
        for g in mesh.groups:
            if g.dim == 0 and "vertex" in g.cells:
                keep[mesh.conn["vertex"][g.cells["vertex"], 0]] = True
        made = np.flatnonzero(keep)
        if mesh.coords.shape[1] > 2 and len(made):
            z = mesh.coords[made, 2]
            size = max(np.ptp(xy[made], axis=0).max(), 1e-300)
            if np.abs(z).max() > 1e-9 * size:
                r = made[int(np.argmax(np.abs(z)))]
                self.pb.at(blk, f"{label}: the mesh is not in the plane z = 0 (a node at ({mesh.coords[r, 0]:g}, "
                                f"{mesh.coords[r, 1]:g}, {mesh.coords[r, 2]:g})): this program is 2D")
                return
        names_before = self._names()
        # nodes
        first_id = self.nodes.max_id() + 1
        node_id = np.full(len(xy), -1, np.int64)
        node_id[made] = first_id + np.arange(len(made))
        rows = self.nodes.add(node_id[made], xy[made], blk.file, blk.line)
        node_row = np.full(len(xy), -1, np.int64)
        node_row[made] = rows
        # elements, a group per shape
        elem_id: dict[str, np.ndarray] = {}
        new_groups = []
        for kind in solid:
            grp = self._new_group(blk, abaqus.import_type(kind, params["ANALYSIS"], params["INTEGRATION"]))
            if grp is None:
                return
            conn = mesh.conn[kind]
            k = len(conn)
            eids = self.elements.max_id() + 1 + np.arange(k)
            lines = mesh.lines[kind]
            files = np.full(k, label if lines is not None else blk.file, object)
            self._add_elements(grp, np.column_stack([eids, node_id[conn]]).astype(float),
                               np.full(k, grp.nen + 1), files, lines if lines is not None else np.full(k, blk.line))
            elem_id[kind] = eids
            new_groups.append(grp)
        if params.get("ELSET"):
            self._add_elset(params["ELSET"], np.concatenate(list(elem_id.values()) or [np.zeros(0, np.int64)]))
        # physical groups
        for name, g in groups.items():
            if g.dim == 2:
                self._add_elset(name.upper(), np.concatenate([elem_id[k][idx] for k, idx in g.cells.items()
                                                              if k in elem_id] or [np.zeros(0, np.int64)]))
            elif g.dim == 0 and "vertex" in g.cells:
                self._add_nset(name.upper(), node_row[mesh.conn["vertex"][g.cells["vertex"], 0]])
            elif g.dim == 1:
                parts = []
                for kind, idx in g.cells.items():
                    if kind not in ("line3", "line2"):
                        at(kind, int(idx[0]), f"physical group {name}: its {kind} lines are not 2- or 3-node lines")
                        return
                    c = mesh.conn[kind][idx]
                    mids = c[:, 2] if kind == "line3" else np.full(len(c), -1)
                    ln = mesh.lines[kind]
                    parts.append((c[:, :2], mids, ln[idx] if ln is not None else np.full(len(idx), blk.line)))
                ends, mids, lines = (np.concatenate(p) for p in zip(*parts))
                order = np.argsort(lines, kind="stable")          # in the order of the file
                ends, mids, lines = ends[order], mids[order], lines[order]
                self._line_set(blk, name.upper(), ends, mids, lines, label if lines_known else blk.file,
                               node_row, xy, new_groups)
        self._import_summary(blk, label, len(made), new_groups, {}, names_before)

    # ------------------------------------------------------------ Abaqus / CalculiX
    def _import_inp(self, blk, params, path, label):
        from .grammar import parse_deck_blocks
        blocks, _, _ = parse_deck_blocks(path, self.pb)
        blocks = abaqus.flatten(blocks, self.pb)
        self.importing = _Importing(params["ANALYSIS"], params["INTEGRATION"], blk, label)
        start, nodes_before, names_before = len(self.groups), len(self.nodes), self._names()
        not_read = []
        try:
            for b in blocks:
                if b.keyword in _MESH_KEYWORDS:
                    self._block(b)
                elif b.keyword == "IMPORT":
                    self.pb.at(b, "*IMPORT inside an imported file: import each mesh from the deck")
                elif b.keyword != "HEADING" and not abaqus.skipped(b):
                    not_read.append(b)
        finally:
            self.importing = None
        if not_read:
            kws = []
            for b in not_read:
                if f"*{b.keyword}" not in kws:
                    kws.append(f"*{b.keyword}")
            self._notice(blk.file, blk.line, blk.keyword,
                         f"{label}: *IMPORT reads the mesh (nodes, elements, sets, surfaces); not read: "
                         f"{', '.join(kws)} (from line {not_read[0].line}; *INCLUDE reads everything)")
        new = self.groups[start:]
        solid = [g for g in new if not g.line]
        if params.get("ELSET"):
            self._add_elset(params["ELSET"], np.concatenate([g.ids() for g in solid] or [np.zeros(0, np.int64)]))
        lines = [g for g in new if g.line]
        try:
            if lines:
                self._inp_line_sets(blk, solid, lines)
        finally:
            self._import_summary(blk, label, len(self.nodes) - nodes_before, solid,
                                 {g.type: g.block.params.get("TYPE", "").upper() for g in solid}, names_before)

    def _inp_line_sets(self, blk, solid, lines):
        """The element sets of an imported .inp that hold only line elements: surfaces (and node
        sets) or curves; the line elements are taken out of the other sets."""
        ids = np.concatenate([g.ids() for g in lines])
        conn = [g.conn() for g in lines]
        ends = np.concatenate([c[:, [0, -1]] for c in conn])            # Abaqus: end, mid, end
        mids = np.concatenate([c[:, 1] if c.shape[1] == 3 else np.full(len(c), -1) for c in conn])
        files, where = (np.concatenate(a) for a in zip(*(g.positions(self.files) for g in lines)))
        order = np.argsort(ids)
        node_row = np.arange(len(self.nodes))
        xy = self.nodes.coords()
        for name in list(self.m.elsets):
            members = np.asarray(self.m.elsets[name], np.int64)
            at = np.searchsorted(ids[order], members)
            at = np.minimum(at, len(ids) - 1)
            is_line = ids[order][at] == members
            if not is_line.any():
                continue
            if not is_line.all():
                self.m.elsets[name] = members[~is_line]
                continue
            del self.m.elsets[name]
            k = order[at]
            self._line_set(blk, name, ends[k], mids[k], where[k], files[k[0]], node_row, xy, solid,
                           model_nodes=True)

    def _import_group(self, blk, type_name) -> ElementGroup | None:
        """The group of an *ELEMENT block of an imported .inp: the ANALYSIS= type of its shape, or
        line elements."""
        imp = self.importing
        name = type_name.upper()
        kind = abaqus.element_kind(name)
        if kind is None:
            try:
                from .. import registry
                kind = _KIND_OF_NEN.get(registry.get("elements", name).nen)
            except KeyError:
                kind = None
        if kind in ("quad8", "quad4", "tri6"):
            return self._new_group(blk, abaqus.import_type(kind, imp.analysis, imp.integration))
        if kind in abaqus.LINE_KINDS:
            grp = ElementGroup(name, LineCells, 2 if kind == "line2" else 3, blk, line=True)
            self.groups.append(grp)
            return grp
        if kind == "tri3":
            self.pb.at(blk, f"TYPE={name}: {abaqus.TRIANGLE3}")
        else:
            why = abaqus.advice(name)
            self.pb.at(blk, f"TYPE={name}: " + (why if why and "plane-stress" not in why else
                                                "not a 2D continuum or line element type"))
        return None

    # ------------------------------------------------------------ 1D sets: surfaces and curves
    def _line_set(self, blk, name, ends, mids, lines, file, node_row, xy, groups, model_nodes=False):
        """A set of lines (``ends`` (k, 2), ``mids`` (k,) as rows of ``xy`` of the mesh file,
        ``node_row`` mapping them to model node rows, -1 when not made): a SURFACE and NSET when
        they lie on the 2D elements ``groups``, a curve when apart from them (``model_nodes``:
        its nodes are nodes of the model, as in an .inp: they are the tool's, not the body's)."""
        rows = node_row[np.concatenate([ends.ravel(), mids[mids >= 0]])]
        made = np.zeros(len(self.nodes), bool)
        for g in groups:
            made[g.conn().ravel()] = True
        on = (rows >= 0) & made[np.maximum(rows, 0)]
        first = Where(file, int(lines[0]), blk.keyword)
        if not on.any():
            if name in self.curves:
                self.pb.add(file, int(lines[0]), blk.keyword, f"curve {name} is already defined")
                return
            self.curves[name] = _Curve(ends, mids, xy, first)
            if model_nodes:
                self.curve_rows.append(rows[rows >= 0])
            return
        if not on.all():
            k = int(np.flatnonzero(~(on[:2 * len(ends)].reshape(-1, 2).all(axis=1)))[0]) if \
                not on[:2 * len(ends)].all() else 0
            self.pb.add(file, int(lines[k]), blk.keyword,
                        f"{name}: some of its lines touch the 2D mesh and some do not: a 1D group is either "
                        f"on the boundary of the body (a surface) or apart from it (a tool profile)")
            return
        table = face_table([(g.cls, g.ids(), g.conn()) for g in groups])
        a, b = node_row[ends[:, 0]], node_row[ends[:, 1]]
        count, idx = table.find(a, b)
        for bad, why in ((count == 0, "is not a side of any 2D element (both its ends are nodes of the mesh)"),
                         (count >= 2, "lies inside the mesh, between elements {0} and {1}: a surface must "
                                      "lie on its boundary")):
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                others = [int(table.element[i]) for i in idx[k] if i >= 0]
                self.pb.add(file, int(lines[k]), blk.keyword,
                            f"{name}: its line {why.format(*(others + ['?', '?']))}"
                            + (f" ({int(bad.sum())} such lines)" if bad.sum() > 1 else ""))
                return
        face = idx[:, 0]
        mid = np.where(mids >= 0, node_row[np.maximum(mids, 0)], -1)
        wrong = (mid >= 0) & (table.mid[face] >= 0) & (mid != table.mid[face])
        if wrong.any():
            k = int(np.flatnonzero(wrong)[0])
            self.pb.add(file, int(lines[k]), blk.keyword,
                        f"{name}: the middle node of its line is not the mid-side node of the face of element "
                        f"{int(table.element[face[k]])} it lies on (the 1D and 2D meshes do not share nodes)")
            return
        _, keep = np.unique(face, return_index=True)
        face = face[np.sort(keep)]
        if name in self.m.surfaces:
            self.pb.add(file, int(lines[0]), blk.keyword, f"surface {name} is already defined")
            return
        self.m.surfaces[name] = Surface(name, table.element[face], table.face[face], first)
        self._add_nset(name, _first_seen(rows))

    def _curve_points(self, blk, name: str, reverse: bool) -> np.ndarray | None:
        """The points of a foundation from an imported curve: its lines chained, end, mid, end,
        mid ... (a 2-node line's middle is its midpoint); None after reporting."""
        curve = self.curves.get(name)
        if curve is None and self.import_failed:
            return None                               # its *IMPORT failed and was reported
        if curve is None:
            hint = (f" ({name} is a surface: its lines lie on the body)" if name in self.m.surfaces else
                    did_you_mean(name, self.curves))
            self.pb.at(blk, f"CURVE={name}: no curve of that name; a curve is a 1D group of an *IMPORT whose "
                            f"lines lie apart from the body{hint}")
            return None
        order, why = chain_lines(curve.ends, curve.mids)
        if why:
            self.pb.at(blk, f"CURVE={name} (from {curve.where.file}:{curve.where.line}): {why}")
            return None
        pts = curve.xy[np.maximum(order, 0)].astype(float)
        straight = np.flatnonzero(order < 0)                 # middles of 2-node lines
        pts[straight] = 0.5 * (pts[straight - 1] + pts[straight + 1])
        if reverse:
            pts = pts[::-1].copy()
        same = np.flatnonzero(np.all(pts[1:] == pts[:-1], axis=1))
        if len(same):
            self.pb.at(blk, f"CURVE={name}: point {same[0] + 2} repeats point {same[0] + 1} (a line of zero "
                            f"length): the arc is degenerate")
            return None
        return pts


def _refused(kind: str, count: int) -> str:
    """Why cells of a kind cannot be imported ("" when they can)."""
    if kind in ("quad8", "quad4", "tri6", "line3", "line2", "vertex"):
        return ""
    if kind == "tri3":
        return f"{count} 3-node triangles: {abaqus.TRIANGLE3}"
    if kind == "quad9":
        return (f"{count} 9-node quadrilaterals: make 8-node ones (gmsh: Mesh.SecondOrderIncomplete = 1) "
                f"or 6-node triangles")
    if kind.startswith(("triangle", "quad")):
        return f"{count} {kind} elements: elements of order above 2 are not supported (gmsh: Mesh.ElementOrder = 2)"
    if kind.startswith(("tetra", "hexahedron", "wedge", "pyramid")):
        return f"{count} {kind} elements: a 3D mesh; this program is 2D (plane strain or axisymmetric)"
    return ""                                    # lines of higher order, polygons...: unused unless named
