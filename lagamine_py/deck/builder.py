"""Keyword blocks -> :class:`lagamine_py.model.Model`, with every problem of the deck collected.

Blocks are read in deck order: a name (set, surface, material, foundation, contact law,
amplitude) or a node/element id must be defined before it is used.  Model data comes before
the first ``*STEP``; step data lies between ``*STEP`` and ``*END STEP``.  When the model data is
complete (at the first ``*STEP``), the element blocks are assembled and checked: every element
has a ``*SOLID``, every material is used, plane strain and axisymmetric types are not mixed,
no element is inverted or degenerate (det J > 0 at its Gauss points and nodes).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from .. import registry
from ..core.params import ParamError, did_you_mean, validate_params
from ..elements.structured import SIDES, rectangle
from ..model import (CONTROL_PARAMS, OUTPUT_FIELDS, Amplitude, Boundary, CLoad, ContactLawSpec,
                     ContactSpec, DLoad, ElementBlock, FoundationMotion, FoundationSpec,
                     MaterialSpec, Model, OutputRequest, Step, Surface, Where)
from .errors import Problems
from .grammar import Block, Num
from .keywords import KEYWORDS, check_data, check_params, data_spec


# Keywords whose readable data lines are used even when other lines of the block failed
# (fewer follow-on messages: the nodes of the good lines exist).
_PARTIAL_OK = {"NODE", "ELEMENT", "NSET", "ELSET", "SURFACE", "BOUNDARY", "CLOAD", "DLOAD"}


class _Controls:
    """Stand-in plugin class so that *CONTROLS is validated like a plugin."""
    params = CONTROL_PARAMS


def _few(ids, n=8) -> str:
    ids = [str(int(i)) for i in ids]
    return ", ".join(ids[:n]) + (f" and {len(ids) - n} more" if len(ids) > n else "")


@dataclass
class _ElementGroup:
    """Elements of one *ELEMENT or *MESH block (one type)."""
    type: str
    cls: type
    nen: int
    block: Block
    ids: list[int] = field(default_factory=list)
    conn: list[list[int]] = field(default_factory=list)      # node rows
    lines: list[tuple[str, int]] = field(default_factory=list)


class _Builder:
    def __init__(self, name: str, blocks: list[Block], problems: Problems):
        self.pb = problems
        self.blocks = blocks
        self.m = Model(name)
        self.node_ids: list[int] = []
        self.coords: list[tuple[float, float]] = []
        self.row_of: dict[int, int] = {}
        self.node_at: dict[int, tuple[str, int]] = {}
        self.groups: list[_ElementGroup] = []
        self.elem_at: dict[int, tuple[int, int]] = {}            # id -> (group, k)
        self.nsets: dict[str, list[int]] = {}
        self.elsets: dict[str, list[int]] = {}
        self.solid_of: dict[int, int] = {}                          # element id -> solid index
        self.solids: list[tuple[Block, dict]] = []
        self.used_materials: set[str] = set()
        self.step: Step | None = None
        self.step_static = False
        self.model_done = False
        self.later = self._definitions()
        self.index = 0                       # of the block being read
        self.solid_failed = False

    # ------------------------------------------------------------ helpers
    def _definitions(self) -> dict[tuple[str, str], tuple[str, int, int]]:
        """Where each name is first defined (file, line, block index): a use before it gets
        "defined later, at ..."; a use after a definition that failed gets no second message."""
        out: dict[tuple[str, str], tuple[str, int, int]] = {}

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
                    if row.items and isinstance(row.items[0], Num) and np.isfinite(row.items[0]):
                        put(b.keyword, str(int(row.items[0])) if row.items[0] == int(row.items[0])
                            else row.items[0].text, b)
        return out

    def _missing(self, file, line, keyword, kind: str, name, known, prefix: str = "") -> None:
        """Report a name used before (or without) its definition -- unless its definition
        came earlier and already failed (reported there)."""
        seen = self.later.get((kind, str(name).upper()))
        if seen is not None and seen[2] < self.index:
            return
        self.pb.add(file, line, keyword, prefix + self._undefined(kind, name, known))

    def _undefined(self, kind: str, name, known) -> str:
        """Message for a name used before (or without) its definition."""
        key = str(name).upper()
        label = {"NSET": "node set", "ELSET": "element set", "SURFACE": "surface", "MATERIAL": "material",
                 "FOUNDATION": "foundation", "CONTACT LAW": "contact law", "AMPLITUDE": "amplitude",
                 "NODE": "node", "ELEMENT": "element"}[kind]
        later = self.later.get((kind, key))
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
            self.pb.at(blk, f"TYPE={name}: {exc.args[0]}")
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
            if target not in self.row_of:
                self._missing(row.file, row.line, blk.keyword, "NODE", target, ())
                return None
            return np.array([self.row_of[target]])
        if target not in self.m.nsets:
            self._missing(row.file, row.line, blk.keyword, "NSET", target, self.m.nsets)
            return None
        return np.asarray(self.m.nsets[target])

    # ------------------------------------------------------------ driver
    def build(self) -> Model:
        for self.index, blk in enumerate(self.blocks):
            self._block(blk)
        self.index = len(self.blocks)
        if self.step is not None:
            self.pb.at(self.step.where, f"*END STEP missing: step {self.step.name} is not closed "
                                        f"before the end of the deck")
            self._close_step()
        if not self.model_done:
            self._finish_model()
        if not self.m.steps and self.blocks:
            last = self.blocks[-1]
            self.pb.add(last.file, last.line, last.keyword, "the deck has no step: add *STEP, *STATIC "
                                                            "and *END STEP after the model data")
        return self.m

    def _block(self, blk: Block) -> None:
        kw = blk.keyword
        spec = KEYWORDS.get(kw)
        if spec is None:
            if not blk.broken:
                self.pb.at(blk, f"unknown keyword *{kw}" + did_you_mean(kw, KEYWORDS).replace("mean ", "mean *"))
            return
        if not self._scope(blk, spec):
            return
        if kw == "STEP" and not self.model_done:
            self._finish_model()
        if blk.broken:
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

    def _kw_include(self, blk, params, data):
        pass

    def _kw_parameter(self, blk, params, pairs):
        for _row, pair in pairs:
            v = pair.value
            self.m.parameters[pair.key] = float(v) if isinstance(v, Num) else str(v)

    def _kw_node(self, blk, params, rows):
        new = []
        for row, vals in rows:
            nid, x, y = vals[0], vals[1], vals[2]
            if nid < 1:
                self.pb.add(row.file, row.line, "NODE", f"node id must be a positive integer, got {nid}")
                continue
            if len(vals) > 3 and vals[3] != 0.0:
                self.pb.add(row.file, row.line, "NODE", f"node {nid}: z = {vals[3]:g}, but the model is 2D "
                                                        f"(z must be 0 or absent)")
                continue
            if nid in self.node_at:
                f, ln = self.node_at[nid]
                self.pb.add(row.file, row.line, "NODE", f"duplicate node id {nid} (already defined at {f}:{ln})")
                continue
            self.node_at[nid] = (row.file, row.line)
            self.row_of[nid] = len(self.node_ids)
            self.node_ids.append(nid)
            self.coords.append((x, y))
            new.append(self.row_of[nid])
        if params.get("NSET"):
            self._add_nset(params["NSET"], new)

    def _add_nset(self, name: str, rows) -> None:
        cur = self.nsets.setdefault(name, [])
        seen = set(cur)
        cur.extend(r for r in rows if not (r in seen or seen.add(r)))
        self.m.nsets[name] = np.asarray(cur, dtype=int)

    def _add_elset(self, name: str, ids) -> None:
        cur = self.elsets.setdefault(name, [])
        seen = set(cur)
        cur.extend(i for i in ids if not (i in seen or seen.add(i)))
        self.m.elsets[name] = np.asarray(cur, dtype=int)

    def _new_group(self, blk, type_name) -> _ElementGroup | None:
        canonical, cls, nen = self._element_class(blk, type_name)
        if cls is None:
            return None
        grp = _ElementGroup(canonical, cls, nen, blk)
        self.groups.append(grp)
        return grp

    def _add_element(self, grp: _ElementGroup, file: str, line: int, eid: int, nodes) -> bool:
        kw = grp.block.keyword
        if eid < 1:
            self.pb.add(file, line, kw, f"element id must be a positive integer, got {eid}")
            return False
        if eid in self.elem_at:
            g, k = self.elem_at[eid]
            f, ln = self.groups[g].lines[k]
            self.pb.add(file, line, kw, f"duplicate element id {eid} (already defined at {f}:{ln})")
            return False
        if len(nodes) != grp.nen:
            self.pb.add(file, line, kw, f"element {eid}: a {grp.type} element has {grp.nen} nodes, got {len(nodes)}")
            return False
        missing = [n for n in nodes if n not in self.row_of]
        if missing:
            seen = [self.later.get(("NODE", str(n))) for n in missing]
            if all(w is not None and w[2] < self.index for w in seen):
                return False                   # their *NODE lines failed and were reported
            later = any(w is not None and w[2] >= self.index for w in seen)
            self.pb.add(file, line, kw, f"element {eid} uses node{'s' * (len(missing) > 1)} {_few(missing)} "
                                        f"that {'are' if len(missing) > 1 else 'is'} not defined"
                                        + (" before this line" if later else ""))
            return False
        if len(set(nodes)) != len(nodes):
            twice = sorted({n for n in nodes if nodes.count(n) > 1})
            self.pb.add(file, line, kw, f"element {eid} uses node {_few(twice)} more than once")
            return False
        self.elem_at[eid] = (len(self.groups) - 1, len(grp.ids))
        grp.ids.append(eid)
        grp.conn.append([self.row_of[n] for n in nodes])
        grp.lines.append((file, line))
        return True

    def _kw_element(self, blk, params, rows):
        grp = self._new_group(blk, params["TYPE"])
        if grp is None:
            return
        added = [vals[0] for row, vals in rows if self._add_element(grp, row.file, row.line, vals[0], vals[1:])]
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
        nx, ny = params["NX"], params["NY"]
        if (grp.cls.grid_order * nx + 1) * (grp.cls.grid_order * ny + 1) > 5_000_000:
            self.pb.at(blk, f"NX={nx}, NY={ny} makes too many nodes")
            return
        mesh = rectangle(grp.cls, params["X0"], params["Y0"], params["LX"], params["LY"], nx, ny)
        first = max(self.node_ids, default=0) + 1
        nids = first + np.arange(len(mesh.coords))
        for nid, (xn, yn) in zip(nids, mesh.coords):
            self.node_at[int(nid)] = (blk.file, blk.line)
            self.row_of[int(nid)] = len(self.node_ids)
            self.node_ids.append(int(nid))
            self.coords.append((float(xn), float(yn)))
        eid0 = max(self.elem_at, default=0) + 1
        eids = eid0 + np.arange(len(mesh.conn))
        for eid, nodes in zip(eids, nids[mesh.conn]):
            self._add_element(grp, blk.file, blk.line, int(eid), [int(n) for n in nodes])
        self._add_elset(name, [int(e) for e in eids])
        for side in SIDES:
            key = f"{name}_{side}"
            self._add_nset(key, [self.row_of[int(n)] for n in nids[mesh.side_nodes[side]]])
            if key in self.m.surfaces:
                self.pb.at(blk, f"surface {key} is already defined")
                continue
            elems, faces = mesh.side_faces[side]
            self.m.surfaces[key] = Surface(key, eids[elems], faces, blk.where)

    def _set_members(self, blk, rows, kind: str, generate: bool) -> list[int] | None:
        """Ids (node rows for NSET, element ids for ELSET) listed by a *NSET / *ELSET block."""
        out, ok = [], True
        known_ids = self.row_of if kind == "NSET" else self.elem_at
        sets = self.m.nsets if kind == "NSET" else self.m.elsets
        what = "NODE" if kind == "NSET" else "ELEMENT"
        for row, vals in rows:
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
                    if it not in known_ids:
                        self._missing(row.file, row.line, blk.keyword, what, it, ())
                        ok = False
                        break
                    out.append(self.row_of[it] if kind == "NSET" else it)
                elif it in sets:
                    out.extend(int(v) for v in sets[it])
                else:
                    self._missing(row.file, row.line, blk.keyword, kind, it, sets)
                    ok = False
        return out if ok else None

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
            if target not in self.elem_at:
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
            short = [e for e in ids if face > len(self.groups[self.elem_at[e][0]].cls.faces)]
            if short:
                cls = self.groups[self.elem_at[short[0]][0]].cls
                self.pb.add(row.file, row.line, blk.keyword,
                            f"element {short[0]} ({cls.__name__}) has faces S1..S{len(cls.faces)}, "
                            f"not S{face}")
                ok = False
                continue
            elems += ids
            faces += [face] * len(ids)
        if ok:
            self.m.surfaces[name] = Surface(name, np.asarray(elems, int), np.asarray(faces, int), blk.where)

    def _plugin(self, blk, kind: str, type_name: str, pairs):
        """Plugin class and validated parameters, or (None, None) after reporting.  The plugin is
        built once, so that the constraints its constructor checks between parameters (KT + HB
        > 0, say) are reported here: ``check`` refuses what ``run`` would."""
        try:
            cls = registry.get(kind, type_name)
        except KeyError as exc:
            self.pb.at(blk, exc.args[0])
            return None, None
        given = {pair.key: pair.text for _row, pair in pairs}
        try:
            values = validate_params(cls, given)
            cls(**given)
        except ParamError as exc:
            self._param_error(blk, exc, pairs)
            return None, None
        return cls, values

    def _param_error(self, blk, exc: ParamError, pairs) -> None:
        """Report each part of a ParamError at the data line of the parameter it names."""
        line_of = {pair.key: row.line for row, pair in pairs or ()}
        for part in _split_param_error(str(exc)):
            words = set(re.findall(r"[A-Za-z_]\w*", part.upper()))
            key = next((k for k in line_of if k in words), None)
            self.pb.at(blk, part, line=line_of.get(key))

    def _kw_material(self, blk, params, pairs):
        name = params["NAME"]
        if self._defined_twice(blk, "material", name, self.m.materials):
            return
        cls, values = self._plugin(blk, "laws", params["LAW"], pairs)
        if cls is not None:
            self.m.materials[name] = MaterialSpec(name, params["LAW"], values, blk.where)

    def _kw_solid(self, blk, params, data):
        elset, mat = params["ELSET"], params["MATERIAL"]
        ok = True
        self.used_materials.add(mat)
        if mat not in self.m.materials:
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
        twice = [int(e) for e in self.m.elsets[elset] if int(e) in self.solid_of]
        if twice:
            other = self.solids[self.solid_of[twice[0]]][0]
            self.pb.at(blk, f"element{'s' * (len(twice) > 1)} {_few(twice)} already "
                            f"{'have' if len(twice) > 1 else 'has'} a *SOLID (line {other.line})")
        for e in self.m.elsets[elset]:
            self.solid_of.setdefault(int(e), index)

    def _kw_foundation(self, blk, params, rows):
        name = params["NAME"]
        if self._defined_twice(blk, "foundation", name, self.m.foundations):
            return
        pts = np.array([vals for _row, vals in rows], float)
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
        self.m.foundations[name] = FoundationSpec(name, pts, blk.where)

    def _kw_contact_law(self, blk, params, pairs):
        name = params["NAME"]
        if self._defined_twice(blk, "contact law", name, self.m.contact_laws):
            return
        cls, values = self._plugin(blk, "contact_laws", params["TYPE"], pairs)
        if cls is not None:
            self.m.contact_laws[name] = ContactLawSpec(name, params["TYPE"], values, blk.where)

    def _kw_contact(self, blk, params, data):
        ok = True
        for key, kind, table in (("SURFACE", "SURFACE", self.m.surfaces),
                                 ("FOUNDATION", "FOUNDATION", self.m.foundations),
                                 ("LAW", "CONTACT LAW", self.m.contact_laws)):
            if params[key] not in table:
                self._missing(blk.file, blk.line, blk.keyword, kind, params[key], table, f"{key}={params[key]}: ")
                ok = False
        if ok:
            self.m.contacts.append(ContactSpec(params["SURFACE"], params["FOUNDATION"], params["LAW"],
                                               params["GAUSS"], blk.where))

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
        m.node_ids = np.asarray(self.node_ids, dtype=int)
        m.coords = np.asarray(self.coords, dtype=float).reshape(-1, 2)
        for name, mat in m.materials.items():
            if name not in self.used_materials:
                self.pb.at(mat.where, f"material {name} is never assigned: no *SOLID uses it")
        for grp in self.groups:
            bare = [e for e in grp.ids if e not in self.solid_of]
            if bare and not self.solid_failed:
                self.pb.at(grp.block, f"element{'s' * (len(bare) > 1)} {_few(bare)} "
                                      f"{'have' if len(bare) > 1 else 'has'} no *SOLID (no material)")
        self._axisymmetry()
        self._assemble_blocks()

    def _axisymmetry(self) -> None:
        kinds = {}
        for grp in self.groups:
            kinds.setdefault(bool(grp.cls.axisymmetric), grp)
        if len(kinds) > 1:
            self.pb.at(kinds[True].block, f"axisymmetric elements ({kinds[True].type}) mixed with plane ones "
                                          f"({kinds[False].type}, line {kinds[False].block.line})")
        self.m.axisymmetric = bool(kinds) and list(kinds)[0]
        if self.m.axisymmetric and len(self.coords):
            r = self.m.coords[:, 0]
            tol = 1e-9 * max(np.ptp(self.m.coords), 1.0)
            used = np.unique(np.concatenate([np.ravel(g.conn) for g in self.groups if g.conn] or [[]]).astype(int))
            neg = used[r[used] < -tol]
            for row in neg[:5]:
                nid = int(self.m.node_ids[row])
                f, ln = self.node_at[nid]
                self.pb.add(f, ln, "NODE", f"node {nid} has r = x = {r[row]:g} < 0 in an axisymmetric model")

    def _assemble_blocks(self) -> None:
        """One ElementBlock per (element type, *SOLID), and the Jacobian check."""
        m = self.m
        for s, (sblk, sparams) in enumerate(self.solids):
            for grp in self.groups:
                keep = [k for k, e in enumerate(grp.ids) if self.solid_of.get(e) == s]
                if not keep:
                    continue
                ids = np.asarray([grp.ids[k] for k in keep], int)
                conn = np.asarray([grp.conn[k] for k in keep], int).reshape(len(keep), grp.nen)
                self._jacobian(grp, keep, ids, conn)
                m.blocks.append(ElementBlock(grp.type, ids, conn, sparams["MATERIAL"], sparams["THICKNESS"],
                                             sparams["ELSET"], sblk.where))

    def _jacobian(self, grp, keep, ids, conn) -> None:
        """Refuse inverted or degenerate elements (the element class's own check)."""
        bad, detj = grp.cls.invalid(self.m.coords[conn])
        bad = np.flatnonzero(bad)
        for k in bad[:10]:
            f, ln = grp.lines[keep[k]]
            self.pb.add(f, ln, grp.block.keyword,
                        f"element {ids[k]} is inverted or degenerate (min det J = {detj[k]:.3g} <= 0): "
                        f"give its corners counter-clockwise, then the mid-side nodes")
        if len(bad) > 10:
            self.pb.at(grp.block, f"{len(bad) - 10} more inverted or degenerate elements: {_few(ids[bad[10:]])}")

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
            if not 1 <= first <= last <= 2:
                self.pb.add(row.file, row.line, blk.keyword,
                            f"DOFs must satisfy 1 <= first <= last <= 2 (1 = x or r, 2 = y or z), got {first}, {last}")
                continue
            nodes = self._nodes_of(blk, row, vals[0])
            if nodes is not None:
                self.step.boundaries.append(Boundary(str(vals[0]), nodes, first, last, value,
                                                     params["AMPLITUDE"], Where(row.file, row.line, blk.keyword)))

    def _kw_cload(self, blk, params, rows):
        if not self._amplitude(blk, params["AMPLITUDE"]):
            return
        self._op(blk, params)
        for row, (target, dof, value) in rows:
            if dof not in (1, 2):
                self.pb.add(row.file, row.line, blk.keyword, f"dof must be 1 (x or r) or 2 (y or z), got {dof}")
                continue
            nodes = self._nodes_of(blk, row, target)
            if nodes is not None:
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
        if ok:
            dx, dy = rows[0][1]
            self.step.motions.append(FoundationMotion(name, dx, dy, params["AMPLITUDE"], blk.where))

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
                              if isinstance(exc, KeyError) else exc, pairs)
            return
        self.step.controls.update({k: v for k, v in values.items() if k.upper() in given})


def _split_param_error(message: str) -> list[str]:
    """The parts of a ParamError message ('; '-joined), keeping each 'expected one of' with its part."""
    parts: list[str] = []
    for piece in message.split("; "):
        if piece.startswith("expected ") and parts:
            parts[-1] += "; " + piece
        else:
            parts.append(piece)
    return parts


def build_model(name: str, blocks: list[Block], problems: Problems) -> Model:
    """The Model of ``blocks``; problems go to ``problems`` (the caller raises)."""
    return _Builder(name, blocks, problems).build()
