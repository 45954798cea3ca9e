"""Keyword blocks -> :class:`lagamine_py.model.Model`, with every problem of the deck collected.

Blocks are read in deck order: a name (set, surface, material, foundation, contact law,
amplitude) or a node/element id must be defined before it is used -- except a material, which
may follow the sections that use it (Abaqus writes the materials after the parts).  Model data comes before
the first ``*STEP``; step data lies between ``*STEP`` and ``*END STEP``.  When the model data is
complete (at the first ``*STEP``), the element blocks are assembled and checked: every element
has a ``*SOLID``, every material is used, plane strain and axisymmetric types are not mixed, no
element is inverted or degenerate anywhere inside (det J > 0 proved over the whole element, see
:meth:`lagamine_py.elements.base.Element.jacobian_check`), every surface lies on the boundary.
Clockwise elements (det J < 0 everywhere: the mirror image of a valid element) are renumbered
counter-clockwise, and the surfaces on them keep their edges; nodes that no element uses are
left out.  Each of these, and the Abaqus keywords that carry nothing here (:mod:`.abaqus`), is
said once in :attr:`Model.notices <lagamine_py.model.Model.notices>`.

Abaqus structure (``*PART``, ``*INSTANCE`` ...) is flattened first (:func:`.abaqus.flatten`);
``*IMPORT`` reads a mesh file (:mod:`.imports`).
"""
from __future__ import annotations

import re
import numpy as np

from .. import registry
from ..core.params import ParamError, did_you_mean, validate_params
from ..core.tensors import right_normal
from ..elements.edges import surface_faces
from ..elements.structured import SIDES, rectangle
from ..foundation import Foundation, circle_points
from ..model import (CONTROL_PARAMS, OUTPUT_FIELDS, Amplitude, Boundary, CLoad, ContactLawSpec,
                     ContactSpec, DLoad, ElementBlock, FoundationMotion, FoundationSpec, LawChange,
                     MaterialSpec, Model, OutputRequest, Stabilisation, Step, Surface, Where)
from . import abaqus
from .errors import Problems
from .grammar import Block, DataRow, Num, NumberRows, Pair
from .imports import ImportMixin
from .keywords import KEYWORDS, check_data, check_params, data_spec
from .mesh import ElementGroup, ElementIndex, Files, NodeTable, face_table


# Keywords whose readable data lines are used even when other lines of the block failed
# (fewer follow-on messages: the nodes of the good lines exist).
_PARTIAL_OK = {"NODE", "ELEMENT", "NSET", "ELSET", "SURFACE", "BOUNDARY", "CLOAD", "DLOAD"}


class _Controls:
    """Stand-in plugin class so that *CONTROLS is validated like a plugin."""
    params = CONTROL_PARAMS


def _few(ids, n=8) -> str:
    ids = [str(int(i)) for i in ids]
    return ", ".join(ids[:n]) + (f" and {len(ids) - n} more" if len(ids) > n else "")


class _PendingMaterial:
    """A *MATERIAL whose cards (*ELASTIC, *PLASTIC) may still follow."""

    def __init__(self, name: str, law: str | None, pairs, block: Block):
        self.name, self.law, self.pairs, self.block = name, law, pairs, block
        self.elastic = None          # (row, E, nu)
        self.plastic = None          # (block, rows (k, 2))


class _PendingContactLaw:
    """A *CONTACT LAW whose *CONTACT LAW TABLE may still follow."""

    def __init__(self, name: str, type_name: str, pairs, block: Block):
        self.name, self.type, self.pairs, self.block = name, type_name, pairs, block
        self.table = None            # (block, rows)


class _Builder(ImportMixin):
    def __init__(self, name: str, blocks: list[Block], problems: Problems):
        self.pb = problems
        self.blocks = abaqus.flatten(blocks, problems)
        self.m = Model(name)
        self.files = Files()
        self.nodes = NodeTable(self.files)
        self.groups: list[ElementGroup] = []
        self.elements = ElementIndex()                              # id -> (group, k)
        self.solid_of: list[np.ndarray] = []                        # per group: *SOLID index, -1
        self.solids: list[tuple[Block, dict]] = []
        self.used_materials: set[str] = set()
        self.step: Step | None = None
        self.step_static = False
        self.model_done = False
        self.later = self._definitions()
        self.index = 0                       # of the block being read
        self.solid_failed = False
        self.material: _PendingMaterial | None = None
        self.contact_law: _PendingContactLaw | None = None
        self.skipped: list[Block] = []       # keywords that carry nothing here
        self.curves: dict = {}               # name -> an imported tool profile (imports._Curve)
        self.curve_rows: list[np.ndarray] = []   # node rows of those profiles (not the body's)
        self.importing = None                # the *IMPORT being read (its element types)
        self.import_failed = False           # an *IMPORT could not be read: its names are missing
        self.row_map: np.ndarray | None = None   # old node row -> row after unused nodes left out
        self.ref_rows: set[int] = set()      # node-table rows of the tools' reference nodes
        self.centred: set[str] = set()       # foundations given a centre (XC=, YC=, a CIRCLE)

    # ------------------------------------------------------------ helpers
    def _definitions(self) -> dict[tuple[str, str], tuple[str, int, int]]:
        """Where each name is first defined (file, line, block index): a use before it gets
        "defined later, at ..."; a use after a definition that failed gets no second message.
        Node and element ids go to :attr:`id_blocks` (arrays, see :meth:`_defined`)."""
        out: dict[tuple[str, str], tuple[str, int, int]] = {}
        self.id_blocks: dict[str, list[tuple[np.ndarray, np.ndarray, str, int]]] = {"NODE": [], "ELEMENT": []}

        def put(kind, name, blk):
            if name:
                out.setdefault((kind, str(name).upper()), (blk.file, blk.line, index))
        for index, b in enumerate(self.blocks):
            p = b.params
            if b.keyword in ("NODE", "NSET"):
                put("NSET", p.get("NSET"), b)
            if b.keyword in ("ELEMENT", "ELSET"):
                put("ELSET", p.get("ELSET"), b)
            if b.keyword == "MESH":
                put("ELSET", p.get("NAME"), b)
                for side in ("BOTTOM", "TOP", "LEFT", "RIGHT"):
                    put("NSET", f"{p.get('NAME')}_{side}", b)
                    put("SURFACE", f"{p.get('NAME')}_{side}", b)
            for kw, kind in (("SURFACE", "SURFACE"), ("MATERIAL", "MATERIAL"), ("FOUNDATION", "FOUNDATION"),
                             ("CONTACT LAW", "CONTACT LAW"), ("AMPLITUDE", "AMPLITUDE")):
                if b.keyword == kw:
                    put(kind, p.get("NAME"), b)
            if b.keyword in ("NODE", "ELEMENT"):
                for row in b.data:
                    if isinstance(row, NumberRows):
                        first = row.values[np.cumsum(row.counts) - row.counts]
                        self.id_blocks[b.keyword].append((first, row.line_numbers(), row.file, index))
                    elif row.items and isinstance(row.items[0], Num) and np.isfinite(row.items[0]):
                        self.id_blocks[b.keyword].append((np.array([float(row.items[0])]),
                                                          np.array([row.line]), row.file, index))
        return out

    def _defined(self, kind: str, name) -> tuple[str, int, int] | None:
        """Where ``name`` of ``kind`` is first defined: (file, line, block index), or None."""
        if kind not in ("NODE", "ELEMENT"):
            return self.later.get((kind, str(name).upper()))
        try:
            value = float(name)
        except (TypeError, ValueError):
            return None
        for ids, lines, file, index in self.id_blocks[kind]:
            hit = np.flatnonzero(ids == value)
            if len(hit):
                return file, int(lines[hit[0]]), index
        return None

    def _missing(self, file, line, keyword, kind: str, name, known, prefix: str = "") -> None:
        """Report a name used before (or without) its definition -- unless its definition
        came earlier and already failed (reported there)."""
        seen = self._defined(kind, name)
        if seen is not None and seen[2] < self.index:
            return
        if self.import_failed and kind in ("NSET", "ELSET", "SURFACE"):
            return                           # maybe a name of the mesh that could not be read
        self.pb.add(file, line, keyword, prefix + self._undefined(kind, name, known))

    def _undefined(self, kind: str, name, known) -> str:
        """Message for a name used before (or without) its definition."""
        key = str(name).upper()
        label = {"NSET": "node set", "ELSET": "element set", "SURFACE": "surface", "MATERIAL": "material",
                 "FOUNDATION": "foundation", "CONTACT LAW": "contact law", "AMPLITUDE": "amplitude",
                 "NODE": "node", "ELEMENT": "element"}[kind]
        later = self._defined(kind, name)
        if later is not None and later[2] > self.index:
            return (f"{label} {key} is used before it is defined (defined later, at {later[0]}:{later[1]}); "
                    f"define it first")
        hint = did_you_mean(key, [str(k) for k in known]) if kind not in ("NODE", "ELEMENT") else ""
        return f"{label} {key} is not defined{hint}"

    def _defined_twice(self, blk: Block, kind: str, name: str, table: dict) -> bool:
        old = table.get(name)
        if old is None:
            return False
        at = old.where
        self.pb.at(blk, f"{kind} {name} is already defined" + (f" at {at.file}:{at.line}" if at else ""))
        return True

    def _element_class(self, blk: Block, name: str):
        try:
            canonical = registry.canonical("elements", name)
        except KeyError as exc:
            why = abaqus.advice(name)
            self.pb.at(blk, f"TYPE={name}: {why or exc.args[0]}")
            return None, None, 0
        cls = registry.get("elements", canonical)
        return canonical, cls, cls.nen

    def _amplitude(self, blk: Block, name) -> bool:
        if name is None or name in self.m.amplitudes:
            return True
        self._missing(blk.file, blk.line, blk.keyword, "AMPLITUDE", name, self.m.amplitudes)
        return False

    def _nodes_of(self, blk: Block, row, target) -> np.ndarray | None:
        """Node rows of a node id or node set name."""
        if isinstance(target, int):
            rows = self.nodes.rows([target])
            if rows[0] < 0:
                self._missing(row.file, row.line, blk.keyword, "NODE", target, ())
                return None
            if self.row_map is not None:
                rows = self.row_map[rows]
                if rows[0] < 0:
                    self.pb.add(row.file, row.line, blk.keyword, f"node {target} is used by no element: it "
                                                                 f"was left out of the model (it has no stiffness)")
                    return None
            return rows
        if target not in self.m.nsets:
            self._missing(row.file, row.line, blk.keyword, "NSET", target, self.m.nsets)
            return None
        return np.asarray(self.m.nsets[target])

    # ------------------------------------------------------------ driver
    def build(self) -> Model:
        for self.index, blk in enumerate(self.blocks):
            self._block(blk)
        self.index = len(self.blocks)
        if self.material is not None:
            self._finish_material()
        if self.contact_law is not None:
            self._finish_contact_law()
        if self.step is not None:
            self.pb.at(self.step.where, f"*END STEP missing: step {self.step.name} is not closed "
                                        f"before the end of the deck")
            self._close_step()
        if not self.model_done:
            self._finish_model()
        self._skipped_notice()
        if not self.m.steps and self.blocks:
            last = self.blocks[-1]
            self.pb.add(last.file, last.line, last.keyword, "the deck has no step: add *STEP, *STATIC "
                                                            "and *END STEP after the model data")
        return self.m

    def _block(self, blk: Block) -> None:
        kw = blk.keyword
        if abaqus.skipped(blk):
            self.skipped.append(blk)
            return
        if self.material is not None and kw not in ("ELASTIC", "PLASTIC"):
            self._finish_material()
        if self.contact_law is not None and kw != "CONTACT LAW TABLE":
            self._finish_contact_law()
        spec = KEYWORDS.get(kw)
        if spec is None:
            if not blk.broken:
                self.pb.at(blk, f"unknown keyword *{kw}" + did_you_mean(kw, KEYWORDS).replace("mean ", "mean *"))
            return
        if not self._scope(blk, spec):
            return
        if kw == "STEP" and not self.model_done:
            self._finish_model()
        if blk.broken or (blk.continued and self._continued(blk, spec)):
            params = None
        else:
            params = check_params(spec, blk, self.pb)
        if params is None:
            self.solid_failed |= kw == "SOLID"
            if kw == "STEP":                          # keep the step structure for later messages
                self._open_step(blk, {"NAME": None, "NLGEOM": False, "INC": 1000})
            elif kw == "END STEP":
                self._end_step(blk, {}, None)
            return
        ok, data = check_data(spec, data_spec(spec, params), blk, self.pb)
        if not ok:
            if kw == "SOLID":
                self.solid_failed = True
            if kw not in ("STEP", "END STEP") and (kw not in _PARTIAL_OK or data is None):
                return
        getattr(self, "_kw_" + kw.lower().replace(" ", "_"))(blk, params, data)

    def _continued(self, blk: Block, spec) -> bool:
        """True (after saying so) when the keyword line ends with ',' and the next line gives
        parameters of the keyword: Abaqus reads such a line on, this language does not (the next
        line would be data, and a data line of ``KEY=VALUE`` pairs is a plugin's parameters)."""
        row = blk.data[0] if blk.data else None
        if not isinstance(row, DataRow) or not row.items or not all(
                isinstance(it, Pair) for it in row.items):
            return False
        names = {p.name for p in spec.params}
        keys = [it.key for it in row.items if it.key in names]
        if not keys:
            return False
        self.pb.add(row.file, row.line, blk.keyword,
                    f"{', '.join(keys)} {'is a parameter' if len(keys) == 1 else 'are parameters'} of "
                    f"*{blk.keyword}: write {'it' if len(keys) == 1 else 'them'} on the keyword line "
                    f"(line {blk.line}); a keyword line ending with ',' does not go on to the next line")
        return True

    def _scope(self, blk: Block, spec) -> bool:
        kw = blk.keyword
        if kw == "STEP" and self.step is not None:
            self.pb.at(self.step.where, f"*END STEP missing: step {self.step.name} is not closed before "
                                        f"the *STEP at line {blk.line}")
            self._close_step()
            return True
        if spec.scope == "model" and kw != "STEP" and (self.step is not None or self.m.steps):
            where = "inside a step" if self.step is not None else "after the first *STEP"
            self.pb.at(blk, f"*{kw} is model data and cannot come {where}; put it before the first *STEP"
                       + (" (or is an *END STEP missing?)" if self.step is not None else ""))
            return False
        if spec.scope == "step" and self.step is None:
            if kw == "END STEP":
                self.pb.at(blk, "*END STEP without a *STEP")
            else:
                self.pb.at(blk, f"*{kw} must be inside a step (between *STEP and *END STEP)")
            return False
        return True

    # ------------------------------------------------------------ model keywords
    def _kw_heading(self, blk, params, text):
        self.m.heading = "\n".join(text)

    def _kw_units(self, blk, params, rows):
        if self.m.units:
            self.pb.at(blk, "*UNITS is given twice")
            return
        self.m.units = tuple(str(v) for v in rows[0][1])

    def _kw_include(self, blk, params, data):
        pass

    def _kw_parameter(self, blk, params, pairs):
        for _row, pair in pairs:
            v = pair.value
            self.m.parameters[pair.key] = float(v) if isinstance(v, Num) else str(v)

    @staticmethod
    def _table(rows, width: int):
        """The rows of a bulk keyword as one table: ``(values (k, width) float, NaN where a line
        has fewer values; counts (k,); files (k,) object; lines (k,))``."""
        parts = []
        for item in rows:
            if isinstance(item, NumberRows):
                counts = item.counts
                vals = np.full((len(counts), width), np.nan)
                fit = np.minimum(counts, width)
                cols = np.arange(width)
                mask = cols[None, :] < fit[:, None]
                starts = np.cumsum(counts) - counts
                vals[mask] = item.values[(starts[:, None] + cols[None, :])[mask]]
                parts.append((vals, counts, np.full(len(counts), item.file, object),
                              item.line_numbers()))
            else:
                row, v = item
                vals = np.full((1, width), np.nan)
                vals[0, :min(len(v), width)] = v[:width]
                parts.append((vals, np.array([len(v)]), np.array([row.file], object),
                              np.array([row.line])))
        if not parts:
            return np.zeros((0, width)), np.zeros(0, int), np.zeros(0, object), np.zeros(0, int)
        return tuple(np.concatenate(p) for p in zip(*parts))

    def _kw_node(self, blk, params, rows):
        vals, counts, files, lines = self._table(rows, 4)
        ids = vals[:, 0].astype(np.int64)
        bad = ids < 1
        for k in np.flatnonzero(bad):
            self.pb.add(files[k], lines[k], "NODE", f"node id must be a positive integer, got {ids[k]}")
        z = np.where(counts > 3, vals[:, 3], 0.0)
        flat = (z != 0.0) & ~bad
        for k in np.flatnonzero(flat):
            self.pb.add(files[k], lines[k], "NODE", f"node {ids[k]}: z = {z[k]:g}, but the model is 2D "
                                                    f"(z must be 0 or absent)")
        ok = ~(bad | flat)
        ok &= ~self._duplicates(ids, ok, files, lines, "NODE", "node",
                                lambda i: self.nodes.rows(i) >= 0, self._node_at)
        file_index = np.array([self.files.index(f) for f in files[ok]], np.int64) if ok.any() \
            else np.zeros(0, np.int64)
        new = self.nodes.add(ids[ok], vals[ok, 1:3], file_index, lines[ok])
        if params.get("NSET"):
            self._add_nset(params["NSET"], new)

    def _node_at(self, nid: int) -> tuple[str, int]:
        return self.nodes.where(int(self.nodes.rows([nid])[0]))

    def _element_at(self, eid: int) -> tuple[str, int]:
        g, k = self.elements.find([eid])
        return self.groups[int(g[0])].where(self.files, int(k[0]))

    def _duplicates(self, ids, ok, files, lines, keyword, label, exists, first_at) -> np.ndarray:
        """(k,) mask of ``ids`` already defined (``exists``) or repeated within ``ids`` (after
        its first), reported with where the first one was defined (``first_at(id)``)."""
        dup = ok & exists(ids)
        for k in np.flatnonzero(dup):
            f, ln = first_at(int(ids[k]))
            self.pb.add(files[k], lines[k], keyword, f"duplicate {label} id {ids[k]} "
                                                     f"(already defined at {f}:{ln})")
        cand = np.flatnonzero(ok & ~dup)
        _, first = np.unique(ids[cand], return_index=True)
        again = np.ones(len(cand), bool)
        again[first] = False
        if again.any():
            first_of = {int(ids[cand[i]]): cand[i] for i in first}
            for i in cand[again]:
                j = first_of[int(ids[i])]
                self.pb.add(files[i], lines[i], keyword, f"duplicate {label} id {ids[i]} "
                                                         f"(already defined at {files[j]}:{lines[j]})")
            dup[cand[again]] = True
        return dup

    def _add_nset(self, name: str, rows) -> None:
        self.m.nsets[name] = _union(self.m.nsets.get(name), rows)

    def _add_elset(self, name: str, ids) -> None:
        self.m.elsets[name] = _union(self.m.elsets.get(name), ids)

    def _new_group(self, blk, type_name) -> ElementGroup | None:
        canonical, cls, nen = self._element_class(blk, type_name)
        if cls is None:
            return None
        grp = ElementGroup(canonical, cls, nen, blk)
        self.groups.append(grp)
        return grp

    def _add_elements(self, grp: ElementGroup, vals, counts, files, lines) -> np.ndarray:
        """Check and add elements (rows of ``vals``: id, then node ids); their ids."""
        kw = grp.block.keyword
        ids = vals[:, 0].astype(np.int64)
        ok = ids >= 1
        for k in np.flatnonzero(~ok):
            self.pb.add(files[k], lines[k], kw, f"element id must be a positive integer, got {ids[k]}")
        ok &= ~self._duplicates(ids, ok, files, lines, kw, "element",
                                lambda e: self.elements.find(e)[0] >= 0, self._element_at)
        wrong = ok & (counts - 1 != grp.nen)
        for k in np.flatnonzero(wrong):
            self.pb.add(files[k], lines[k], kw, f"element {ids[k]}: a {grp.type} element has "
                                                f"{grp.nen} nodes, got {counts[k] - 1}")
        ok &= ~wrong
        node_ids = np.where(ok[:, None], np.nan_to_num(vals[:, 1:grp.nen + 1]), 0).astype(np.int64)
        rows = self.nodes.rows(node_ids)
        missing = ok & (rows < 0).any(axis=1)
        for k in np.flatnonzero(missing):
            absent = node_ids[k][rows[k] < 0].tolist()
            seen = [self._defined("NODE", n) for n in absent]
            if all(w is not None and w[2] < self.index for w in seen):
                continue                       # their *NODE lines failed and were reported
            later = any(w is not None and w[2] >= self.index for w in seen)
            self.pb.add(files[k], lines[k], kw, f"element {ids[k]} uses node{'s' * (len(absent) > 1)} "
                                                f"{_few(absent)} that {'are' if len(absent) > 1 else 'is'} "
                                                f"not defined" + (" before this line" if later else ""))
        ok &= ~missing
        srt = np.sort(node_ids, axis=1)
        twice = ok & (srt[:, 1:] == srt[:, :-1]).any(axis=1)
        for k in np.flatnonzero(twice):
            nodes = node_ids[k].tolist()
            rep = sorted({n for n in nodes if nodes.count(n) > 1})
            self.pb.add(files[k], lines[k], kw, f"element {ids[k]} uses node {_few(rep)} more than once")
        ok &= ~twice
        g = self.groups.index(grp)
        self.elements.add(g, ids[ok], len(grp))
        grp.add(ids[ok], rows[ok], np.array([self.files.index(f) for f in files[ok]], np.int64)
                if ok.any() else np.zeros(0, np.int64), lines[ok])
        return ids[ok]

    def _kw_element(self, blk, params, rows):
        if self.importing is not None:
            grp = self._import_group(blk, params["TYPE"])
        else:
            grp = self._new_group(blk, params["TYPE"])
        if grp is None:
            return
        added = self._add_elements(grp, *self._table(rows, grp.nen + 1))
        if params.get("ELSET"):
            self._add_elset(params["ELSET"], added)

    def _kw_mesh(self, blk, params, data):
        """Structured rectangle (:func:`lagamine_py.elements.structured.rectangle`).  Nodes are
        numbered on from the largest id, row by row from the bottom-left corner, left to right;
        elements likewise, from the largest element id.  Sides: nsets and surfaces NAME_BOTTOM,
        NAME_RIGHT, NAME_TOP, NAME_LEFT."""
        name = params["NAME"]
        grp = self._new_group(blk, params["TYPE"])
        if grp is None:
            return
        if not grp.cls.cell_elements:
            self.pb.at(blk, f"*MESH cannot fill a rectangle with {grp.type} elements (the element "
                            f"type declares no cell_elements)")
            return
        taken = [f"{name}_{side}" for side in SIDES if f"{name}_{side}" in self.m.surfaces]
        if taken:           # one message, not one per side (a *MESH line given twice, say)
            at = self.m.surfaces[taken[0]].where
            where = "" if at is None else (f" (line {at.line})" if at.file == blk.file
                                           else f" ({at.file}:{at.line})")
            self.pb.at(blk, f"NAME={name}: surface{'s' * (len(taken) > 1)} {', '.join(taken)} "
                            f"already defined{where}: give this *MESH another NAME")
            return
        nx, ny = params["NX"], params["NY"]
        if (grp.cls.grid_order * nx + 1) * (grp.cls.grid_order * ny + 1) > 5_000_000:
            self.pb.at(blk, f"NX={nx}, NY={ny} makes too many nodes")
            return
        mesh = rectangle(grp.cls, params["X0"], params["Y0"], params["LX"], params["LY"], nx, ny)
        nids = self.nodes.max_id() + 1 + np.arange(len(mesh.coords))
        node_rows = self.nodes.add(nids, mesh.coords, blk.file, blk.line)
        eids = self.elements.max_id() + 1 + np.arange(len(mesh.conn))
        k = len(eids)
        added = self._add_elements(grp, np.column_stack([eids, nids[mesh.conn]]).astype(float),
                                   np.full(k, grp.nen + 1), np.full(k, blk.file, object),
                                   np.full(k, blk.line))
        self._add_elset(name, added)
        for side in SIDES:
            key = f"{name}_{side}"
            self._add_nset(key, node_rows[mesh.side_nodes[side]])
            elems, faces = mesh.side_faces[side]
            self.m.surfaces[key] = Surface(key, eids[elems], faces, blk.where)

    def _set_members(self, blk, rows, kind: str, generate: bool) -> np.ndarray | None:
        """Node rows (NSET) or element ids (ELSET) listed by a *NSET / *ELSET block, in order;
        None after reporting an unknown id or set."""
        out, ok = [], True
        sets = self.m.nsets if kind == "NSET" else self.m.elsets
        what = "NODE" if kind == "NSET" else "ELEMENT"
        for item in rows:
            if isinstance(item, NumberRows) and not generate:
                ids = item.values.astype(np.int64)
                found = self._members(kind, ids)
                if (found < 0).any():
                    k = int(np.flatnonzero(found < 0)[0])
                    line = int(np.repeat(item.line_numbers(), item.counts)[k])
                    self._missing(item.file, line, blk.keyword, what, int(ids[k]), ())
                    ok = False
                out.append(found[found >= 0])
                continue
            for row, vals in (item.rows() if isinstance(item, NumberRows) else [item]) \
                    if not isinstance(item, tuple) else [item]:
                if isinstance(row, NumberRows):
                    continue
                if generate:
                    first, last = vals[0], vals[1]
                    step = vals[2] if len(vals) > 2 else 1
                    if step < 1 or last < first:
                        self.pb.add(row.file, row.line, blk.keyword,
                                    f"GENERATE needs first <= last and step >= 1, got {first}, {last}, {step}")
                        ok = False
                        continue
                    if (last - first) // step > 10_000_000:
                        self.pb.add(row.file, row.line, blk.keyword, "GENERATE range is too large")
                        ok = False
                        continue
                    items = list(range(first, last + 1, step))
                else:
                    items = vals
                for it in items:
                    if isinstance(it, int):
                        found = self._members(kind, np.array([it]))
                        if found[0] < 0:
                            self._missing(row.file, row.line, blk.keyword, what, it, ())
                            ok = False
                            break
                        out.append(found)
                    elif it in sets:
                        out.append(np.asarray(sets[it], np.int64))
                    else:
                        self._missing(row.file, row.line, blk.keyword, kind, it, sets)
                        ok = False
        return np.concatenate(out) if ok and out else (np.zeros(0, np.int64) if ok else None)

    def _members(self, kind: str, ids: np.ndarray) -> np.ndarray:
        """Node rows (NSET) or the ids themselves (ELSET) of ``ids``, -1 where undefined."""
        if kind == "NSET":
            return self.nodes.rows(ids)
        return np.where(self.elements.find(ids)[0] >= 0, ids, -1)

    def _kw_nset(self, blk, params, rows):
        members = self._set_members(blk, rows, "NSET", bool(params.get("GENERATE")))
        if members is not None:
            self._add_nset(params["NSET"], members)

    def _kw_elset(self, blk, params, rows):
        members = self._set_members(blk, rows, "ELSET", bool(params.get("GENERATE")))
        if members is not None:
            self._add_elset(params["ELSET"], members)

    def _elements_of(self, blk, row, target) -> list[int] | None:
        if isinstance(target, int):
            if target not in self.elements:
                self._missing(row.file, row.line, blk.keyword, "ELEMENT", target, ())
                return None
            return [target]
        if target not in self.m.elsets:
            self._missing(row.file, row.line, blk.keyword, "ELSET", target, self.m.elsets)
            return None
        return [int(e) for e in self.m.elsets[target]]

    def _kw_surface(self, blk, params, rows):
        name = params["NAME"]
        if self._defined_twice(blk, "surface", name, self.m.surfaces):
            return
        elems, faces, ok = [], [], True
        for row, (target, face) in rows:
            ids = self._elements_of(blk, row, target)
            if ids is None:
                ok = False
                continue
            groups = self.elements.find(ids)[0]
            short = [e for e, g in zip(ids, groups) if face > len(self.groups[g].cls.faces)]
            if short:
                cls = self.groups[int(self.elements.find([short[0]])[0][0])].cls
                self.pb.add(row.file, row.line, blk.keyword,
                            f"element {short[0]} ({cls.__name__}) has faces S1..S{len(cls.faces)}, "
                            f"not S{face}")
                ok = False
                continue
            elems += ids
            faces += [face] * len(ids)
        if ok:
            self.m.surfaces[name] = Surface(name, np.asarray(elems, int), np.asarray(faces, int), blk.where)

    def _plugin(self, blk, kind: str, type_name: str, pairs, lines: dict | None = None):
        """Plugin class and validated parameters, or (None, None) after reporting.  ``pairs``:
        the (row, Pair) items of the block, or a dict of given values with ``lines`` the line
        of each (for messages).  The plugin is built once, so that the constraints its
        constructor checks between parameters (KT + HB > 0, say) are reported here: ``check``
        refuses what ``run`` would."""
        try:
            cls = registry.get(kind, type_name)
        except KeyError as exc:
            self.pb.at(blk, exc.args[0])
            return None, None
        if isinstance(pairs, dict):
            given = pairs
        else:
            given = {pair.key: pair.text for _row, pair in pairs}
            lines = {pair.key: row.line for row, pair in pairs or ()}
        try:
            values = validate_params(cls, given)
            cls(**given)
        except ParamError as exc:
            self._param_error(blk, exc, lines or {})
            return None, None
        return cls, values

    def _param_error(self, blk, exc: ParamError, line_of: dict) -> None:
        """Report each part of a ParamError at the data line of the parameter it names."""
        for part in _split_param_error(str(exc)):
            words = set(re.findall(r"[A-Za-z_]\w*", part.upper()))
            key = next((k for k in line_of if k in words), None)
            self.pb.at(blk, part, line=line_of.get(key))

    def _kw_material(self, blk, params, pairs):
        """A material: with LAW=, the law's KEY=VALUE parameters (and a *PLASTIC table for a law
        that takes one); without (Abaqus), the *ELASTIC and *PLASTIC cards that follow give it:
        ELASTIC, or J2_TABLE with a *PLASTIC.  Built when its cards are over."""
        name = params["NAME"]
        if self._defined_twice(blk, "material", name, self.m.materials):
            return
        if params["LAW"] is None and pairs:
            row = pairs[0][0]
            self.pb.add(row.file, row.line, blk.keyword, "KEY=VALUE data needs LAW= on the *MATERIAL line "
                                                         "(without LAW=, *ELASTIC and *PLASTIC cards follow)")
            return
        self.material = _PendingMaterial(name, params["LAW"], pairs, blk)

    def _material_card(self, blk) -> _PendingMaterial | None:
        if self.material is None:
            self.pb.at(blk, f"*{blk.keyword} must follow a *MATERIAL (or its other cards)")
        return self.material

    def _kw_elastic(self, blk, params, rows):
        pm = self._material_card(blk)
        if pm is None:
            return
        if pm.law is not None:
            self.pb.at(blk, f"material {pm.name} has LAW={pm.law}: give E= and NU= on its data lines "
                            f"(*ELASTIC is for a *MATERIAL without LAW=)")
            pm.law = "?"                              # reported: do not build it
            return
        if pm.elastic is not None:
            self.pb.at(blk, f"material {pm.name} has two *ELASTIC")
            return
        row, vals = rows[0]
        if len(vals) < 2:
            self.pb.add(row.file, row.line, blk.keyword, "expected E, nu")
            return
        pm.elastic = (row, vals[0], vals[1])

    def _kw_plastic(self, blk, params, rows):
        pm = self._material_card(blk)
        if pm is None:
            return
        if pm.plastic is not None:
            self.pb.at(blk, f"material {pm.name} has two *PLASTIC")
            return
        table = np.array([vals + [np.nan] * (3 - len(vals)) for _row, vals in rows], float)
        temps = table[:, 2]
        if np.isfinite(temps).any() and not (np.isfinite(temps).all() and np.ptp(temps) == 0.0):
            self.pb.at(blk, "a hardening table that depends on temperature is not supported")
            return
        pm.plastic = (blk, table[:, :2])

    def _finish_material(self) -> None:
        pm, self.material = self.material, None
        if pm.law == "?":
            return
        lines = {pair.key: row.line for row, pair in pm.pairs or ()}
        if pm.law is None:
            if pm.elastic is None:
                self.pb.at(pm.block, f"material {pm.name} has no law: give LAW= (and its parameters), "
                                     f"or an *ELASTIC card (E, nu) and optionally *PLASTIC")
                return
            row, E, nu = pm.elastic
            law, given = ("J2_TABLE" if pm.plastic is not None else "ELASTIC"), {"E": E, "NU": nu}
            lines.update({"E": row.line, "NU": row.line})
        else:
            law = pm.law
            given = {pair.key: pair.text for _row, pair in pm.pairs}
        if pm.plastic is not None:
            if "PLASTIC" in given:
                self.pb.at(pm.block, "PLASTIC is given by the *PLASTIC block: leave PLASTIC= out",
                           line=lines["PLASTIC"])
                return
            given["PLASTIC"] = pm.plastic[1].tolist()
            lines["PLASTIC"] = pm.plastic[0].line
        cls, values = self._plugin(pm.block, "laws", law, given, lines)
        if cls is not None:
            self.m.materials[pm.name] = MaterialSpec(pm.name, law, values, pm.block.where)

    def _kw_solid(self, blk, params, data):
        elset, mat = params["ELSET"], params["MATERIAL"]
        ok = True
        self.used_materials.add(mat)
        # a material may come after the sections that use it (Abaqus writes it after the parts)
        if mat not in self.m.materials and self._defined("MATERIAL", mat) is None:
            self._missing(blk.file, blk.line, blk.keyword, "MATERIAL", mat, self.m.materials)
            ok = False
        if elset not in self.m.elsets:
            self._missing(blk.file, blk.line, blk.keyword, "ELSET", elset, self.m.elsets)
            ok = False
        if not ok:
            self.solid_failed = True
            return
        index = len(self.solids)
        self.solids.append((blk, params))
        ids = np.asarray(self.m.elsets[elset], np.int64)
        groups, ks = self.elements.find(ids)
        solid = self._solid_of(groups, ks)
        twice = ids[solid >= 0]
        if len(twice):
            other = self.solids[int(solid[solid >= 0][0])][0]
            self.pb.at(blk, f"element{'s' * (len(twice) > 1)} {_few(twice)} already "
                            f"{'have' if len(twice) > 1 else 'has'} a *SOLID (line {other.line})")
        for g in np.unique(groups):
            sel = (groups == g) & (solid < 0)
            self.solid_of[g][ks[sel]] = index

    def _kw_solid_section(self, blk, params, rows):
        """Abaqus's *SOLID SECTION: *SOLID with the thickness on its data line."""
        thickness = rows[0][1][0] if rows and rows[0][1] else 1.0
        if not thickness > 0.0:
            row = rows[0][0]
            self.pb.add(row.file, row.line, blk.keyword, f"thickness must be > 0, got {thickness:g}")
            self.solid_failed = True
            return
        self._kw_solid(blk, {**params, "THICKNESS": thickness}, None)

    def _solid_of(self, groups, ks) -> np.ndarray:
        """The *SOLID index of elements (group, k) so far, -1 where none (arrays grown to the
        groups' current sizes)."""
        while len(self.solid_of) < len(self.groups):
            self.solid_of.append(np.zeros(0, np.int64))
        for g, grp in enumerate(self.groups):
            if len(self.solid_of[g]) < len(grp):
                self.solid_of[g] = np.concatenate([self.solid_of[g],
                                                   np.full(len(grp) - len(self.solid_of[g]), -1)])
        out = np.full(len(groups), -1)
        for g in np.unique(groups):
            out[groups == g] = self.solid_of[g][ks[groups == g]]
        return out

    def _kw_foundation(self, blk, params, rows):
        name = params["NAME"]
        if self._defined_twice(blk, "foundation", name, self.m.foundations):
            return
        placement = self._foundation_placement(blk, params)
        if placement is None:
            return
        if params["CURVE"] is not None:
            if rows or params["CIRCLE"]:
                where = (rows[0][0].file, rows[0][0].line) if rows else (blk.file, blk.line)
                self.pb.add(*where, blk.keyword, "give the points, CURVE= or CIRCLE=, one of them")
                return
            pts = self._curve_points(blk, params["CURVE"], bool(params["REVERSE"]))
            if pts is not None:
                self.m.foundations[name] = FoundationSpec(name, pts, blk.where, *placement)
            return
        if params["REVERSE"]:
            self.pb.at(blk, "REVERSE goes with CURVE= (give the points in the order you want)")
            return
        if params["CIRCLE"]:
            pts = self._circle(blk, params, rows)
            if pts is None:
                return
            ref, centre = placement
            if ref is None and name not in self.centred:       # turns about the circle's centre
                centre = tuple(float(v) for v in rows[0][1][:2])
                self.centred.add(name)
            problems = Foundation(pts, name).shape_problems()
            for message in problems:
                self.pb.at(blk, f"foundation {name}: {message}")
            if not problems:
                self.m.foundations[name] = FoundationSpec(name, pts, blk.where, ref, centre)
            return
        pts = np.array([vals for _row, vals in rows], float)
        if not _sane_coordinates(pts):
            self.pb.at(blk, f"foundation {name}: a coordinate of magnitude {np.abs(pts).max():.3g} "
                            f"exceeds {COORD_MAX:g}: {_COORD_WHY}")
            return
        if len(pts) < 3 or len(pts) % 2 == 0:
            self.pb.at(blk, f"a foundation needs an odd number >= 3 of points (arcs through points 1-2-3, "
                            f"3-4-5, ...), got {len(pts)}")
            return
        same = np.flatnonzero(np.all(pts[1:] == pts[:-1], axis=1))
        if len(same):
            row = rows[same[0] + 1][0]
            self.pb.add(row.file, row.line, blk.keyword, f"point {same[0] + 2} repeats point {same[0] + 1}: "
                                                         f"the arc is degenerate")
            return
        problems = Foundation(pts, name).shape_problems()
        for message in problems:
            self.pb.at(blk, f"foundation {name}: {message}")
        if not problems:
            self.m.foundations[name] = FoundationSpec(name, pts, blk.where, *placement)

    def _foundation_placement(self, blk, params):
        """``(ref_node row or None, centre)`` of a *FOUNDATION, or None after reporting: REF
        NODE must be a node defined before (its row in the node table; remapped when unused
        nodes are left out), and goes without XC=, YC=."""
        ref, xc, yc = params["REF NODE"], params["XC"], params["YC"]
        if ref is None:
            if xc is not None or yc is not None:
                self.centred.add(params["NAME"])
            return None, (float(xc or 0.0), float(yc or 0.0))
        row = int(self.nodes.rows([ref])[0])
        if row < 0:
            self._missing(blk.file, blk.line, blk.keyword, "NODE", ref, (), "REF NODE: ")
            return None
        self.ref_rows.add(row)        # kept even if the foundation fails: no follow-on message
        if xc is not None or yc is not None:
            self.pb.at(blk, "give REF NODE= or XC=, YC=, not both: a tool with a reference node "
                            "turns about it")
            return None
        return row, tuple(float(v) for v in self.nodes.coords()[row])

    def _circle(self, blk, params, rows) -> np.ndarray | None:
        """The points of a CIRCLE= foundation (:func:`lagamine_py.foundation.circle_points`)."""
        row, (xc, yc, radius, start, end, arcs) = rows[0]
        bad = []
        if not radius > 0:
            bad.append(f"the radius must be > 0, got {radius:g}")
        if not start < end < start + 360.0:
            bad.append(f"the angles must satisfy start < end < start + 360 (degrees, counter-clockwise; "
                       f"a whole circle is closed, and a tool profile must be open), got {start:g}, {end:g}")
        if arcs < 1:
            bad.append(f"arcs must be >= 1, got {arcs}")
        for message in bad:
            self.pb.add(row.file, row.line, blk.keyword, message)
        return None if bad else circle_points(xc, yc, radius, start, end, arcs, params["CIRCLE"])

    def _kw_contact_law(self, blk, params, pairs):
        """A contact law: the plugin's KEY=VALUE parameters, and a *CONTACT LAW TABLE if one
        follows (its rows are the parameter CONTACT LAW TABLE).  Built when its cards are over."""
        name = params["NAME"]
        if self._defined_twice(blk, "contact law", name, self.m.contact_laws):
            return
        self.contact_law = _PendingContactLaw(name, params["TYPE"], pairs, blk)

    def _kw_contact_law_table(self, blk, params, rows):
        law = self.contact_law
        if law is None:
            self.pb.at(blk, "*CONTACT LAW TABLE must follow the *CONTACT LAW it belongs to")
            return
        if law.table is not None:
            self.pb.at(blk, f"contact law {law.name} has two *CONTACT LAW TABLE")
            return
        law.table = (blk, [vals for _row, vals in rows])

    def _finish_contact_law(self) -> None:
        law, self.contact_law = self.contact_law, None
        given = {pair.key: pair.text for _row, pair in law.pairs}
        lines = {pair.key: row.line for row, pair in law.pairs or ()}
        if law.table is not None:
            if any(k.upper() == "CONTACT LAW TABLE" for k in given):
                self.pb.at(law.block, "the table is given by the *CONTACT LAW TABLE block: leave "
                                      "CONTACT LAW TABLE= out")
                return
            given["CONTACT LAW TABLE"] = law.table[1]
            lines["TABLE"] = law.table[0].line       # messages about the table point at it
        cls, values = self._plugin(law.block, "contact_laws", law.type, given, lines)
        if cls is not None:
            self.m.contact_laws[law.name] = ContactLawSpec(law.name, law.type, values,
                                                           law.block.where)

    def _kw_contact(self, blk, params, data):
        ok = True
        target = "MASTER" if params["MASTER"] is not None else "FOUNDATION"
        if (params["MASTER"] is None) == (params["FOUNDATION"] is None):
            self.pb.at(blk, "give one of FOUNDATION= (a rigid foundation) and MASTER= (a surface of "
                            "a deformable body)" + (", not both" if params["MASTER"] else ""))
            return
        if target == "MASTER" and str(params["GAUSS"]).upper() == "LINEAR":
            # the two-body element integrates at its points; the corner interpolation of
            # GAUSS=LINEAR (elements.contact) is written for a rigid foundation only
            self.pb.at(blk, "GAUSS=LINEAR is not available with MASTER= (use 2, 3, LOBATTO2 or "
                            "LOBATTO3)")
            ok = False
        if params["SEARCH"] is not None and target != "MASTER":
            self.pb.at(blk, "SEARCH= goes with MASTER= (the pairing of two deformable bodies)")
            ok = False
        if params["PASSES"] != 1 and target != "MASTER":
            self.pb.at(blk, "PASSES= goes with MASTER= (a rigid foundation has no points of its own)")
            ok = False
        for key, kind, table in (("SURFACE", "SURFACE", self.m.surfaces),
                                 (target, "SURFACE" if target == "MASTER" else "FOUNDATION",
                                  self.m.surfaces if target == "MASTER" else self.m.foundations),
                                 ("LAW", "CONTACT LAW", self.m.contact_laws)):
            if params[key] not in table:
                self._missing(blk.file, blk.line, blk.keyword, kind, params[key], table, f"{key}={params[key]}: ")
                ok = False
        if ok and params["MASTER"] == params["SURFACE"]:
            self.pb.at(blk, f"MASTER={params['MASTER']} is the SURFACE itself: a surface cannot be "
                            "its own master")
            ok = False
        if ok:
            for c in self.m.contacts:
                if (c.surface, c.target) == (params["SURFACE"], params[target]):
                    self.pb.at(blk, f"contact pair {c.surface}->{c.target} is already defined (line "
                                    f"{c.where.line}); change its law in a step with *CHANGE CONTACT LAW")
                    return
            self.m.contacts.append(ContactSpec(params["SURFACE"], params["FOUNDATION"] or "",
                                               params["LAW"], params["GAUSS"], blk.where,
                                               master=params["MASTER"], search=params["SEARCH"],
                                               passes=params["PASSES"]))

    def _kw_amplitude(self, blk, params, rows):
        name = params["NAME"]
        if self._defined_twice(blk, "amplitude", name, self.m.amplitudes):
            return
        flat = np.array([v for _row, vals in rows for v in vals], float).reshape(-1, 2)
        if np.any(np.diff(flat[:, 0]) <= 0):
            self.pb.at(blk, "amplitude times must be strictly increasing")
            return
        self.m.amplitudes[name] = Amplitude(name, flat[:, 0], flat[:, 1], blk.where)

    def _kw_check(self, blk, params, pairs):
        cls, values = self._plugin(blk, "checks", params["TYPE"], pairs)
        if cls is not None:
            given = {k.upper() for _row, pair in pairs for k in (pair.key,)}
            self.m.checks.append({"name": params["NAME"],
                                  "type": registry.canonical("checks", params["TYPE"]),
                                  "params": {k: v for k, v in values.items() if k.upper() in given},
                                  "where": blk.where})

    # ------------------------------------------------------------ the model is complete
    def _finish_model(self) -> None:
        self.model_done = True
        m = self.m
        m.node_ids = self.nodes.ids()
        m.coords = self.nodes.coords()
        for name, mat in m.materials.items():
            if name not in self.used_materials:
                self.pb.at(mat.where, f"material {name} is never assigned: no *SOLID uses it")
        self._solid_of(np.zeros(0, np.int64), np.zeros(0, np.int64))     # sizes up to date
        for g, grp in enumerate(self.groups):
            bare = grp.ids()[self.solid_of[g] < 0]
            if len(bare) and not self.solid_failed and not grp.line:
                self.pb.at(grp.block, f"element{'s' * (len(bare) > 1)} {_few(bare)} "
                                      f"{'have' if len(bare) > 1 else 'has'} no *SOLID (no material)")
        big = np.flatnonzero(~np.all(np.abs(m.coords) <= COORD_MAX, axis=1))
        for row in big[:5]:
            f, ln = self.nodes.where(int(row))
            self.pb.add(f, ln, "NODE", f"node {int(m.node_ids[row])}: a coordinate of magnitude "
                                       f"{np.abs(m.coords[row]).max():.3g} exceeds {COORD_MAX:g}: "
                                       f"{_COORD_WHY}")
        if len(big):
            return
        for grp in self._solid_groups():
            self._orient(grp)
        self._axisymmetry()
        self._surfaces_on_boundary()
        self._reference_nodes_apart()
        self._leave_out_unused_nodes()
        self._coincident_nodes()
        self._assemble_blocks()
        self._energy_laws()
        if not self.pb:
            self._master_surfaces()
        if not self.pb:
            self._foundation_sides()

    def _energy_laws(self) -> None:
        """``*CHECK, TYPE=ENERGY`` needs every material law and contact law to report its energy
        (:meth:`MaterialLaw.energy`, :meth:`ContactLaw.stored_energy`): refused here, as the run
        would refuse it."""
        checks = [c for c in self.m.checks if c["type"] == "ENERGY"]
        if not checks:
            return
        specs = [("laws", m.law, m.params, m.where) for m in self.m.materials.values()]
        specs += [("contact_laws", c.type, c.params, c.where) for c in self.m.contact_laws.values()]
        for kind, name, params, where in specs:
            law = registry.get(kind, name)(**params)
            try:
                if kind == "laws":
                    st = law.init_state((1, 1))
                    law.energy(st, st)
                else:
                    law.stored_energy(law.init_state(1))
            except NotImplementedError as exc:
                self.pb.at(checks[0]["where"], f"TYPE=ENERGY: {exc} (defined at line {where.line})")

    def _master_surfaces(self) -> None:
        """A MASTER= surface must have 3-node faces (Q8, T6: each face is a parabolic arc) and
        share no face with its slave surface."""
        for cs in self.m.contacts:
            if cs.master is None:
                continue
            if cs.master in self.m.foundations:
                # pairs, tool forces and law changes are keyed SURFACE->name: one name, one thing
                self.pb.at(cs.where, f"MASTER={cs.master} is also the name of a *FOUNDATION: rename "
                                     f"one (pairs and tool forces are keyed by that name)")
                continue
            try:
                rows, elements, faces = surface_faces(self.m, cs.master)
                slave_rows, slave_el, slave_faces = surface_faces(self.m, cs.surface)
            except (KeyError, ValueError) as exc:
                self.pb.at(cs.where, str(exc).strip("'\""))
                continue
            if rows.shape[1] != 3:
                self.pb.at(cs.where, f"MASTER={cs.master}: its faces have {rows.shape[1]} nodes; a "
                                     f"master surface needs 3-node faces (Q8, T6 elements), whose "
                                     f"parabolic arcs the slave's points project on")
                continue
            if cs.passes == 2 and slave_rows.shape[1] != 3:
                self.pb.at(cs.where, f"PASSES=2: SURFACE={cs.surface} has {slave_rows.shape[1]}-node "
                                     f"faces; with two passes it is a master too and needs 3-node "
                                     f"faces (Q8, T6 elements)")
                continue
            both = set(zip(elements.tolist(), faces.tolist())) & set(zip(slave_el.tolist(),
                                                                          slave_faces.tolist()))
            if both:
                e, f = sorted(both)[0]
                self.pb.at(cs.where, f"SURFACE={cs.surface} and MASTER={cs.master} share "
                                     f"{len(both)} face(s) (S{f} of element {e}): a face cannot "
                                     f"touch itself")

    def _foundation_sides(self) -> None:
        """Each foundation must have its contact bodies on its left (the direction of travel of
        its points): a body on its right means the points were written in the wrong order.
        Faces touching the chain are judged by their normals, faces apart by the side they
        stand on (which they approach from); when every face lies beyond the chain's ends (a
        body that slides onto the tool later), against the end half-lines that continue it."""
        for cs in self.m.contacts:
            spec = None if cs.master else self.m.foundations.get(cs.foundation)
            if spec is None:
                continue
            rows, _, _ = surface_faces(self.m, cs.surface)
            x = self.m.coords[rows]                                    # (f, a, 2)
            mid = x[:, 2] if rows.shape[1] == 3 else 0.5 * (x[:, 0] + x[:, 1])
            normal = right_normal(x[:, 1] - x[:, 0])                  # outward: body on the left
            chain = Foundation(spec.points, spec.name)
            side = chain.side(mid, normal)
            if not side.any():
                side = chain.side(mid, normal, extend=True)
            if (side < 0).sum() > (side > 0).sum():
                self.pb.at(cs.where, f"the bodies of surface {cs.surface} lie on the right of "
                                     f"foundation {spec.name} (at {int((side < 0).sum())} of "
                                     f"{len(side)} faces): a foundation's points run with the "
                                     f"body on their left; reverse the point order of *FOUNDATION, "
                                     f"NAME={spec.name} (line {spec.where.line})")

    def _solid_groups(self) -> list[ElementGroup]:
        return [grp for grp in self.groups if not grp.line]

    def _notice(self, file: str, line: int, keyword: str, text: str) -> None:
        self.m.notices.append(f"{file}:{line}: *{keyword}: {text}")

    def _orient(self, grp: ElementGroup) -> None:
        """The Jacobian check of a group (the element class's own, over the whole element):
        clockwise elements (det J < 0 everywhere) are renumbered counter-clockwise, with the faces
        of surfaces on them; inverted or degenerate ones are refused."""
        conn = grp.conn()
        if not len(conn):
            return
        X = self.m.coords[conn]
        cls = grp.cls
        check = cls.jacobian_check(X)
        bad = ~check.valid
        if cls.axisymmetric:
            bad |= cls.off_axis(X)
        ids = grp.ids()
        if bad.any():
            mirror = cls.mirror()
            turned = cls.jacobian_check(X[bad][:, mirror]).valid
            clockwise = np.zeros(len(conn), bool)
            clockwise[np.flatnonzero(bad)[turned]] = True
            if clockwise.any():
                conn[clockwise] = conn[clockwise][:, mirror]
                grp.set_conn(conn)
                self._turn_surfaces(ids[clockwise], cls.mirror_faces())
                k = int(np.flatnonzero(clockwise)[0])
                f, ln = grp.where(self.files, k)
                n = int(clockwise.sum())
                self._notice(f, ln, grp.block.keyword,
                             f"{n} element{'s' * (n > 1)} given clockwise renumbered counter-clockwise "
                             f"(surfaces on {'them' if n > 1 else 'it'} keep their edges): {_few(ids[clockwise])}")
                X = self.m.coords[conn]
                if cls.axisymmetric:
                    bad = bad & ~clockwise | (clockwise & cls.off_axis(X))
                else:
                    bad &= ~clockwise
        bad = np.flatnonzero(bad)
        for k in bad[:10]:
            f, ln = grp.where(self.files, int(k))
            self.pb.add(f, ln, grp.block.keyword, self._invalid_message(cls, ids[k], X[k], check, k))
        if len(bad) > 10:
            self.pb.at(grp.block, f"{len(bad) - 10} more inverted or degenerate elements: {_few(ids[bad[10:]])}")

    def _invalid_message(self, cls, eid, X, check, k) -> str:
        """Why element ``eid`` (coordinates X (nen, 2)) is refused, and where."""
        if cls.axisymmetric and cls.off_axis(X[None])[0] and check.valid[k]:
            return (f"element {eid} reaches r < 0 (or has a Gauss point at r = 0): in an axisymmetric "
                    f"model the mesh lies at r = x >= 0")
        xi = check.at[k]
        x = cls.shape_functions(xi[None])[0][0] @ X
        size = np.ptp(X, axis=0).max()
        what = ("its area is zero or nearly" if abs(check.min_found[k]) <= 1e-8 * size ** 2
                else "det J must stay > 0 over the whole element")
        return (f"element {eid} is inverted or degenerate: det J = {check.min_found[k]:.3g} at "
                f"({x[0]:.6g}, {x[1]:.6g}) (natural coordinates {xi[0]:.3g}, {xi[1]:.3g}); {what}: "
                f"give its corners counter-clockwise, then the mid-side nodes, each near the middle "
                f"of its side")

    def _turn_surfaces(self, ids: np.ndarray, face_map: np.ndarray) -> None:
        """Faces of renumbered elements ``ids`` in every surface: the same edges, new numbers."""
        for surf in self.m.surfaces.values():
            on = np.isin(surf.elements, ids)
            if on.any():
                faces = np.asarray(surf.faces).copy()
                faces[on] = face_map[faces[on] - 1]
                surf.faces = faces

    def _surfaces_on_boundary(self) -> None:
        """Refuse surface faces that another element shares (inside the mesh)."""
        groups = self._solid_groups()
        if not self.m.surfaces or not groups:
            return
        table = face_table([(g.cls, g.ids(), g.conn()) for g in groups])
        shared = table.counts() > 1
        if not shared.any():
            return
        width = int(table.face.max()) + 1
        inside = np.sort(table.element[shared] * width + table.face[shared])
        for name, surf in self.m.surfaces.items():
            keys = np.asarray(surf.elements, np.int64) * width + np.asarray(surf.faces, np.int64)
            at = np.minimum(np.searchsorted(inside, keys), len(inside) - 1)
            hits = np.flatnonzero(inside[at] == keys)
            if not len(hits):
                continue
            e, f = int(surf.elements[hits[0]]), int(surf.faces[hits[0]])
            row = np.flatnonzero((table.element == e) & (table.face == f))[0]
            _, idx = table.find(table.a[row:row + 1], table.b[row:row + 1])
            other = [int(table.element[i]) for i in idx[0] if i >= 0 and int(table.element[i]) != e]
            where = surf.where or Where("", 0, "SURFACE")
            self.pb.add(where.file, where.line, where.keyword,
                        f"surface {name}: face S{f} of element {e} is shared with element "
                        f"{other[0] if other else '?'}: it lies inside the mesh, and a surface must lie on "
                        f"its boundary" + (f" ({len(hits)} such faces)" if len(hits) > 1 else ""))

    def _leave_out_unused_nodes(self) -> None:
        """Nodes that no element uses carry no stiffness (their DOFs would make the system
        singular): they are left out of the model, with a notice."""
        m = self.m
        used = np.zeros(len(m.node_ids), bool)
        for grp in self._solid_groups():
            used[grp.conn().ravel()] = True
        used[sorted(self.ref_rows)] = True                 # a tool's reference node: kept
        if used.all() or not len(used):
            return
        tool = np.zeros(len(used), bool)               # nodes of imported tool profiles: expected
        for rows in self.curve_rows:
            tool[rows] = True
        unused = np.flatnonzero(~used & ~tool)
        if len(unused):
            f, ln = self.nodes.where(int(unused[0]))
            self._notice(f, ln, "NODE", f"{len(unused)} node{'s' * (len(unused) > 1)} used by no element "
                                        f"{'are' if len(unused) > 1 else 'is'} left out of the model (no "
                                        f"stiffness): {_few(m.node_ids[unused])}")
        row_map = np.cumsum(used) - 1
        row_map[~used] = -1
        self.row_map = row_map
        m.node_ids, m.coords = m.node_ids[used], m.coords[used]
        for grp in self.groups:
            if not grp.line:
                grp.set_conn(row_map[grp.conn()])
        for name, rows in m.nsets.items():
            new = row_map[np.asarray(rows, np.int64)]
            m.nsets[name] = new[new >= 0]
        for spec in m.foundations.values():
            if spec.ref_node is not None:
                spec.ref_node = int(row_map[spec.ref_node])

    def _reference_nodes_apart(self) -> None:
        """A tool's reference node carries a rigid body's motion: no element may use it."""
        if not self.ref_rows:
            return
        for grp in self._solid_groups():
            conn = grp.conn()
            for spec in self.m.foundations.values():
                if spec.ref_node is None:
                    continue
                hit = np.flatnonzero((conn == spec.ref_node).any(axis=1))
                if len(hit):
                    nid = int(self.m.node_ids[spec.ref_node])
                    self.pb.at(spec.where, f"REF NODE={nid} of foundation {spec.name} is a node of "
                                           f"element {int(grp.ids()[hit[0]])}: a reference node carries "
                                           f"the rigid tool's motion and must be used by no element "
                                           f"(define a node of its own, at the tool's centre say)")

    def _coincident_nodes(self) -> None:
        """A notice for nodes at the same place (within 1e-9 of the model's size): the mesh is
        not joined there (two bodies touching, or a mesh that should have been merged)."""
        xy = self.m.coords
        if len(xy) < 2:
            return
        tol = 1e-9 * max(np.ptp(xy, axis=0).max(), 1e-300)
        q = np.round((xy - xy.min(axis=0)) / tol).astype(np.int64)
        key = q[:, 0] * (int(q[:, 1].max()) + 1) + q[:, 1]
        # a tool's reference node often sits on the body (a punch's centre on its face): not a mesh
        for spec in self.m.foundations.values():
            if spec.ref_node is not None:
                key[spec.ref_node] = -1 - spec.ref_node
        _, inverse, count = np.unique(key, return_inverse=True, return_counts=True)
        inverse = inverse.ravel()
        twice = count[inverse] > 1
        if not twice.any():
            return
        rows = np.flatnonzero(twice)
        order = rows[np.argsort(inverse[rows], kind="stable")]
        pairs = []
        for g in np.unique(inverse[order])[:5]:
            members = order[inverse[order] == g]
            pairs.append(" and ".join(str(int(self.m.node_ids[r])) for r in members)
                         + f" at ({xy[members[0], 0]:.6g}, {xy[members[0], 1]:.6g})")
        n = int((count > 1).sum())
        f, ln = self.nodes.where(int(self._old_row(order[0])))
        # the line that made the node: a *NODE data line, or a *MESH or *IMPORT keyword line
        kw = next((b.keyword for b in self.blocks if (b.file, b.line) == (f, ln)), "NODE")
        self._notice(f, ln, kw, f"{n} place{'s' * (n > 1)} of the mesh hold{'s' * (n == 1)} more than "
                                    f"one node, which are not joined (merge them if they should be): "
                                    + "; ".join(pairs) + (" ..." if n > 5 else ""))

    def _old_row(self, row: int) -> int:
        """The row of the node table (before unused nodes were left out) of model row ``row``."""
        return int(np.flatnonzero(self.row_map == row)[0]) if self.row_map is not None else row

    def _skipped_notice(self) -> None:
        if not self.skipped:
            return
        by_kw: dict[str, list[Block]] = {}
        for b in self.skipped:
            by_kw.setdefault(b.keyword, []).append(b)
        parts = []
        for kw, blocks in by_kw.items():
            what = "Abaqus output request" if kw == "OUTPUT" else abaqus.SKIPPED[kw]
            at = ", ".join(f"{b.file}:{b.line}" for b in blocks[:3]) + (" ..." if len(blocks) > 3 else "")
            parts.append(f"*{kw} ({what}; {at})")
        first = self.skipped[0]
        self._notice(first.file, first.line, first.keyword,
                     "skipped, as they carry nothing for this program: " + "; ".join(parts))

    def _axisymmetry(self) -> None:
        kinds = {}
        for grp in self._solid_groups():
            kinds.setdefault(bool(grp.cls.axisymmetric), grp)
        if len(kinds) > 1:
            self.pb.at(kinds[True].block, f"axisymmetric elements ({kinds[True].type}) mixed with plane ones "
                                          f"({kinds[False].type}, line {kinds[False].block.line})")
        self.m.axisymmetric = bool(kinds) and list(kinds)[0]
        if self.m.axisymmetric and len(self.m.coords):
            r = self.m.coords[:, 0]
            tol = 1e-9 * float(np.abs(self.m.coords).max())       # relative: any length unit
            used = np.unique(np.concatenate([g.conn().ravel() for g in self._solid_groups()] or [[]]).astype(int))
            neg = used[r[used] < -tol]
            for row in neg[:5]:
                nid = int(self.m.node_ids[row])
                f, ln = self.nodes.where(int(row))
                self.pb.add(f, ln, "NODE", f"node {nid} has r = x = {r[row]:g} < 0 in an axisymmetric model")

    def _assemble_blocks(self) -> None:
        """One ElementBlock per (element type, *SOLID)."""
        m = self.m
        for s, (sblk, sparams) in enumerate(self.solids):
            for g, grp in enumerate(self.groups):
                keep = np.flatnonzero(self.solid_of[g] == s)
                if not len(keep) or grp.line:
                    continue
                m.blocks.append(ElementBlock(grp.type, grp.ids()[keep], grp.conn()[keep], sparams["MATERIAL"],
                                             sparams["THICKNESS"], sparams["ELSET"], sblk.where))

    # ------------------------------------------------------------ steps
    def _open_step(self, blk, params):
        n = len(self.m.steps) + 1
        self.step = Step(name=params.get("NAME") or f"Step-{n}", nlgeom=bool(params.get("NLGEOM")),
                         max_increments=int(params.get("INC") or 1000), where=blk.where)
        self.step_static = False

    def _close_step(self):
        if not self.step_static:
            self.pb.at(self.step.where, f"step {self.step.name} has no *STATIC (initial dt, step time, "
                                        f"min dt, max dt)")
        self.m.steps.append(self.step)
        self.step = None

    def _kw_step(self, blk, params, data):
        self._open_step(blk, params)

    def _end_step(self, blk, params, data):
        if self.step is not None:
            self._close_step()

    _kw_end_step = _end_step

    def _kw_static(self, blk, params, rows):
        if self.step_static:
            self.pb.at(blk, f"step {self.step.name} has two *STATIC")
            return
        self.step_static = True
        row, vals = rows[0]
        dt0, period = vals[0], vals[1]
        dtmin = vals[2] if len(vals) > 2 else min(dt0, 1e-5 * period)
        dtmax = vals[3] if len(vals) > 3 else max(dt0, period)
        if min(dt0, period, dtmin, dtmax) <= 0:
            self.pb.add(row.file, row.line, blk.keyword, "time values must be > 0 (initial dt, step time, "
                                                         "min dt, max dt)")
            return
        if not dtmin <= dt0 <= dtmax:
            self.pb.add(row.file, row.line, blk.keyword, f"need min dt <= initial dt <= max dt, got "
                                                         f"{dtmin:g}, {dt0:g}, {dtmax:g}")
            return
        st = self.step
        st.dt0, st.period, st.dt_min, st.dt_max = dt0, period, dtmin, dtmax

    def _op(self, blk, params):
        if params["OP"] == "NEW":
            self.step.op_new.add(blk.keyword)

    def _kw_boundary(self, blk, params, rows):
        if not self._amplitude(blk, params["AMPLITUDE"]):
            return
        self._op(blk, params)
        for row, vals in rows:
            first = vals[1]
            last = vals[2] if len(vals) > 2 else first
            value = vals[3] if len(vals) > 3 else 0.0
            dofs = tuple(d for d in (1, 2, 6) if first <= d <= last)
            if not (1 <= first <= last <= 6 and dofs):
                self.pb.add(row.file, row.line, blk.keyword,
                            f"DOFs must satisfy 1 <= first <= last <= 6 and include 1 (x or r), 2 (y "
                            f"or z) or 6 (the rotation of a tool's reference node), got {first}, {last}")
                continue
            nodes = self._nodes_of(blk, row, vals[0])
            if nodes is not None and self._rotation_ok(blk, row, nodes, 6 in dofs):
                self.step.boundaries.append(Boundary(str(vals[0]), nodes, first, last, value,
                                                     params["AMPLITUDE"], Where(row.file, row.line, blk.keyword),
                                                     dofs))

    def _rotation_ok(self, blk, row, nodes, rotation: bool) -> bool:
        """DOF 6 exists on the reference nodes of tools only (and not in axisymmetry)."""
        if not rotation:
            return True
        if self.m.axisymmetric:
            self.pb.add(row.file, row.line, blk.keyword,
                        "DOF 6: in an axisymmetric model a tool does not rotate (its reference node has "
                        "DOFs 1 and 2 only)")
            return False
        rot = set(self.m.rotation_nodes)
        # a node named REF NODE by a *FOUNDATION that failed: reported there, not again here
        named = {int(self.row_map[r]) if self.row_map is not None else r for r in self.ref_rows}
        other = [int(r) for r in np.asarray(nodes).ravel() if int(r) not in rot | named]
        if other:
            self.pb.add(row.file, row.line, blk.keyword,
                        f"DOF 6 (a rotation) exists only on the reference node of a tool (*FOUNDATION, "
                        f"REF NODE=); node {int(self.m.node_ids[other[0]])} is not one")
            return False
        return True

    def _kw_cload(self, blk, params, rows):
        if not self._amplitude(blk, params["AMPLITUDE"]):
            return
        self._op(blk, params)
        for row, (target, dof, value) in rows:
            if dof not in (1, 2, 6):
                self.pb.add(row.file, row.line, blk.keyword, f"dof must be 1 (x or r), 2 (y or z) or 6 (a "
                                                             f"moment on a tool's reference node), got {dof}")
                continue
            nodes = self._nodes_of(blk, row, target)
            if nodes is not None and self._rotation_ok(blk, row, nodes, dof == 6):
                self.step.cloads.append(CLoad(str(target), nodes, dof, value, params["AMPLITUDE"],
                                              Where(row.file, row.line, blk.keyword)))

    def _kw_dload(self, blk, params, rows):
        if not self._amplitude(blk, params["AMPLITUDE"]):
            return
        self._op(blk, params)
        for row, (surf, kind, value) in rows:
            if kind != "P":
                self.pb.add(row.file, row.line, blk.keyword, f"load type must be P (pressure), got {kind}")
                continue
            if surf not in self.m.surfaces:
                self._missing(row.file, row.line, blk.keyword, "SURFACE", surf, self.m.surfaces)
                continue
            self.step.dloads.append(DLoad(surf, "P", value, params["AMPLITUDE"],
                                          Where(row.file, row.line, blk.keyword)))

    def _kw_foundation_motion(self, blk, params, rows):
        name = params["NAME"]
        ok = self._amplitude(blk, params["AMPLITUDE"])
        if name not in self.m.foundations:
            self._missing(blk.file, blk.line, blk.keyword, "FOUNDATION", name, self.m.foundations)
            ok = False
        if not ok:
            return
        row, vals = rows[0]
        dx, dy = vals[:2]
        angle = vals[2] if len(vals) > 2 else 0.0
        if not _sane_coordinates([dx, dy]):
            self.pb.add(row.file, row.line, blk.keyword,
                        f"a translation of magnitude {max(abs(dx), abs(dy)):.3g} exceeds "
                        f"{COORD_MAX:g}: {_MOVED_WHY}")
            return
        spec = self.m.foundations[name]
        if angle != 0.0 and self.m.axisymmetric:
            self.pb.add(row.file, row.line, blk.keyword, "an angle: in an axisymmetric model a tool does "
                                                         "not rotate")
            return
        if spec.ref_node is not None:       # the tool's motion is that of its reference node
            nid = str(int(self.m.node_ids[spec.ref_node]))
            for dof, value in ((1, dx), (2, dy), (6, angle)):
                if dof == 6 and self.m.axisymmetric:
                    continue
                self.step.boundaries.append(Boundary(nid, np.array([spec.ref_node]), dof, dof, value,
                                                     params["AMPLITUDE"], blk.where, (dof,)))
            return
        if angle != 0.0 and name not in self.centred:
            self.pb.add(row.file, row.line, blk.keyword,
                        f"foundation {name} has no point to turn about: give it REF NODE= (a node at its "
                        f"centre) or XC=, YC= (line {spec.where.line})")
            return
        self.step.motions.append(FoundationMotion(name, dx, dy, params["AMPLITUDE"], blk.where, angle))

    def _kw_change_contact_law(self, blk, params, data):
        surface, law = params["SURFACE"], params["LAW"]
        if (params["FOUNDATION"] is None) == (params["MASTER"] is None):
            self.pb.at(blk, "give one of FOUNDATION= and MASTER= (the other side of the pair)")
            return
        key = "FOUNDATION" if params["FOUNDATION"] is not None else "MASTER"
        foundation = params[key]
        if law not in self.m.contact_laws:
            self._missing(blk.file, blk.line, blk.keyword, "CONTACT LAW", law, self.m.contact_laws,
                          f"LAW={law}: ")
            return
        pairs = [f"{c.surface}->{c.target}" for c in self.m.contacts]
        pair = f"{surface}->{foundation}"
        if pair not in pairs:
            self.pb.at(blk, f"no contact pair {pair} (SURFACE={surface}, {key}={foundation}): "
                            f"the *CONTACT pairs are {', '.join(pairs) or 'none'}"
                            f"{did_you_mean(pair, pairs)}")
            return
        self.step.law_changes = [c for c in self.step.law_changes if c.pair != pair]
        self.step.law_changes.append(LawChange(pair, law, blk.where))

    def _kw_contact_stabilization(self, blk, params, data):
        if self.step.stabilisation is not None:
            self.pb.at(blk, f"step {self.step.name} has two *CONTACT STABILIZATION")
            return
        surface, foundation = params["SURFACE"], params["FOUNDATION"]
        pairs = tuple(f"{c.surface}->{c.target}" for c in self.m.contacts
                      if surface in (None, c.surface) and foundation in (None, c.target))
        if not pairs:
            self.pb.at(blk, "no contact pair to stabilise" + (
                f" (SURFACE={surface}, FOUNDATION={foundation}; the pairs are "
                f"{', '.join(f'{c.surface}->{c.target}' for c in self.m.contacts) or 'none'})"
                if surface or foundation else ": the model has no *CONTACT"))
            return
        self.step.stabilisation = Stabilisation(params["FACTOR"], params["TANGENTIAL"], params["RANGE"],
                                                pairs, blk.where)

    def _kw_output(self, blk, params, data):
        fields = tuple(f.upper() for f in re.split(r"[\s/;:+]+", params["FIELDS"] or "") if f)
        unknown = [f for f in fields if f not in OUTPUT_FIELDS]
        if unknown:
            self.pb.add(blk.file, blk.line, blk.keyword,
                        f"FIELDS: unknown field {unknown[0]!r}"
                        f"{did_you_mean(unknown[0], OUTPUT_FIELDS)}; expected some of "
                        f"{', '.join(OUTPUT_FIELDS)} (separated by / or spaces)")
            return
        writers = tuple(w.upper() for w in re.split(r"[\s/;:+]+", params["WRITERS"] or "") if w)
        known = registry.names("writers")
        unknown = [w for w in writers if w not in known]
        if unknown:
            self.pb.add(blk.file, blk.line, blk.keyword,
                        f"WRITERS: unknown writer {unknown[0]!r}{did_you_mean(unknown[0], known)}; "
                        f"installed: {', '.join(known)} (separated by /)")
            return
        writers = tuple(registry.canonical("writers", w) for w in writers)
        self.step.output = OutputRequest(params["FREQUENCY"], fields, params["CONTACT"], writers)

    def _kw_controls(self, blk, params, pairs):
        given = {pair.key: pair.text for _row, pair in pairs}
        try:
            values = validate_params(_Controls, given)
            if "SOLVER" in {k.upper() for k in given}:
                values["SOLVER"] = registry.canonical("solvers", values["SOLVER"])
        except (ParamError, KeyError) as exc:
            self._param_error(blk, ParamError(f"SOLVER={values['SOLVER']}: {exc.args[0]}")
                              if isinstance(exc, KeyError) else exc,
                              {pair.key: row.line for row, pair in pairs or ()})
            return
        if not self._controls_can_run(values, given, pairs):
            return
        self.step.controls.update({k: v for k, v in values.items() if k.upper() in given})

    def _controls_can_run(self, values, given, pairs) -> bool:
        """False (after saying why) when the *CONTROLS name a solver or kernel that cannot run
        here (an optional package missing): ``run`` would stop at that step's start, after the
        steps before it ran; ``check`` refuses the deck as ``run`` then does, before anything."""
        line_of = {pair.key: row for row, pair in pairs}
        why = {}
        if "SOLVER" in given:
            why["SOLVER"] = registry.get("solvers", values["SOLVER"]).unavailable()
        if "KERNEL" in given and values["KERNEL"] == "NUMBA":
            from .. import kernels
            why["KERNEL"] = "" if kernels.available() else (
                "the numba kernels need the optional package numba (pip install "
                "'lagamine_py[fast]')")
        for key, reason in why.items():
            if reason:
                row = line_of[key]
                self.pb.add(row.file, row.line, "CONTROLS", f"{key}={values[key]}: {reason}")
        return not any(why.values())


#: largest coordinate magnitude: products of two coordinates (areas, Jacobians) must stay finite
COORD_MAX = 1e150
_COORD_WHY = "products of coordinates (areas, Jacobians) would overflow; choose another length unit"
_MOVED_WHY = ("products of the positions it moves to (distances, areas) would overflow; choose "
              "another length unit")


def _sane_coordinates(x) -> bool:
    return bool(np.all(np.abs(np.asarray(x, float)) <= COORD_MAX))


def _union(old: np.ndarray | None, new) -> np.ndarray:
    """``old`` followed by the members of ``new`` not already in it, in order, without repeats."""
    both = np.concatenate([np.zeros(0, np.int64) if old is None else np.asarray(old, np.int64),
                           np.asarray(new, np.int64).ravel()])
    _, first = np.unique(both, return_index=True)
    return both[np.sort(first)]


def _split_param_error(message: str) -> list[str]:
    """The parts of a ParamError message ('; '-joined), keeping each 'expected one of' with its part."""
    parts: list[str] = []
    for piece in message.split("; "):
        if piece.startswith(("expected ", "installed: ")) and parts:
            parts[-1] += "; " + piece
        else:
            parts.append(piece)
    return parts


def build_model(name: str, blocks: list[Block], problems: Problems) -> Model:
    """The Model of ``blocks``; problems go to ``problems`` (the caller raises)."""
    return _Builder(name, blocks, problems).build()
