"""What Abaqus and CalculiX input files hold beyond the deck language proper.

* :func:`flatten`: ``*PART`` / ``*ASSEMBLY`` / ``*INSTANCE`` structure turned into the flat
  blocks the builder reads.  Each ``*INSTANCE`` places a copy of its part's blocks: nodes moved
  by the instance's translation (then rotation about an axis parallel to z), node and element
  ids offset past those already defined when they would clash, and set, surface and section
  names qualified as Abaqus does (``INSTANCE.NAME``).  Assembly-level sets given with
  ``INSTANCE=`` name that instance's ids and sets.
* :data:`SKIPPED`: keywords that carry nothing for this program (output requests, printing
  controls, density in a static analysis...): the builder skips them and lists them in one
  notice.  Anything else it does not know is an error.
* Element types: :func:`element_kind` (the shape of an Abaqus type: ``quad8``, ``tri6``,
  ``line3``...), :func:`import_type` (what ``*IMPORT`` makes of a shape), :func:`advice` (why a
  type is refused and what to use).
"""
from __future__ import annotations

import math
import re

import numpy as np

from .errors import Problems
from .grammar import Block, DataRow, Name, Num, NumberRows
from .keywords import KEYWORDS, SKIPPED, check_data, check_params

__all__ = ["SKIPPED", "skipped", "flatten", "element_kind", "import_type", "advice",
           "LINE_KINDS", "SOLID_KINDS"]

def skipped(block: Block) -> bool:
    """Whether the block is one of :data:`SKIPPED`, or an Abaqus ``*OUTPUT, FIELD`` /
    ``*OUTPUT, HISTORY`` request (this program's own ``*OUTPUT`` takes neither)."""
    if block.keyword in SKIPPED:
        return True
    return block.keyword == "OUTPUT" and any(p in block.params for p in ("FIELD", "HISTORY"))


# ---------------------------------------------------------------- element types

SOLID_KINDS = ("quad8", "quad4", "tri6", "tri3")
LINE_KINDS = ("line2", "line3")
_SOLID = re.compile(r"^(CPE|CPS|CAX|CPEG)([3468])([A-Z]*)$")
_TRUSS = re.compile(r"^T[23]D([23])[A-Z]*$")             # T2D2, T3D3H ...: the last digit, nodes
_BEAM = re.compile(r"^B[23]([123])[A-Z]*$")               # B21, B31: 2 nodes; B22, B32, B33: 3
_KIND_OF_NODES = {"3": "tri3", "4": "quad4", "6": "tri6", "8": "quad8"}


def element_kind(name: str) -> str | None:
    """The shape of an Abaqus/CalculiX element type (``quad8``, ``quad4``, ``tri6``, ``tri3``,
    ``line2``, ``line3``), or None when it is not a 2D continuum or line element."""
    name = name.upper()
    m = _SOLID.match(name)
    if m:
        return _KIND_OF_NODES[m.group(2)]
    m = _TRUSS.match(name)
    if m:
        return f"line{m.group(1)}"
    m = _BEAM.match(name)
    if m:
        return "line2" if m.group(1) == "1" else "line3"
    return None


def import_type(kind: str, analysis: str, integration: str) -> str:
    """The element type ``*IMPORT`` makes of a 2D shape (``quad8``, ``quad4``, ``tri6``):
    plane strain or axisymmetric, and for 8-node quads full (3x3) or reduced (2x2) Gauss points.
    4-node quads keep 2x2 and 6-node triangles 3 points (no reduced variant)."""
    ax = analysis == "AXISYMMETRIC"
    if kind == "quad8":
        return ("Q8AX" if ax else "Q8PE") + ("R" if integration == "REDUCED" else "")
    return {"quad4": "Q4", "tri6": "T6"}[kind] + ("AX" if ax else "PE")


TRIANGLE3 = ("3-node triangles lock (their strain is constant: in bending, plastic flow or a "
             "nearly incompressible material they are far too stiff); make second-order elements "
             "(gmsh: Mesh.ElementOrder = 2, or gmsh.model.mesh.setOrder(2); 6-node triangles "
             "CPE6/CAX6) or 8-node quadrilaterals")


def advice(name: str) -> str:
    """Why the element type ``name`` is not one of this program's, and what to use ("" when
    there is nothing to say beyond 'unknown')."""
    name = name.upper()
    m = _SOLID.match(name)
    if m:
        family, nodes, suffix = m.groups()
        plain = {"CPS": "CPE", "CPEG": "CPE"}.get(family, family) + nodes
        reduced = "R" if "R" in suffix and nodes == "8" else ""
        if nodes == "3":
            return f"{name} is a 3-node triangle: {TRIANGLE3}"
        if family == "CPS":
            return (f"{name} is a plane-stress element, which this program does not model: use "
                    f"CPE{nodes}{reduced} (plane strain) or CAX{nodes}{reduced} (axisymmetric), "
                    f"or read the mesh with *IMPORT, INPUT=<file>, ANALYSIS=PLANE STRAIN or "
                    f"AXISYMMETRIC")
        if family == "CPEG":
            return f"{name} is generalized plane strain, which this program does not model: use {plain}"
        if "H" in suffix:
            return (f"{name} is a hybrid (mixed pressure) element, which this program does not have: "
                    f"use {plain}{reduced}")
        if nodes == "4" and "R" in suffix:
            return (f"{name} needs hourglass control, which this program does not have: use "
                    f"{plain} (2x2 Gauss points) or {family}8R")
        if "I" in suffix or "M" in suffix:
            return f"{name} is not one of this program's elements: use {plain}"
        return ""
    if _TRUSS.match(name) or _BEAM.match(name):
        return (f"{name} is a line element, which carries nothing here: read the mesh with "
                f"*IMPORT, which makes surfaces (and tool curves) of the lines")
    if re.match(r"^(C3D|S\d|SC\d|M3D|R3D|DC)", name):
        return f"{name} is not a 2D continuum element: this program is 2D (plane strain or axisymmetric)"
    return ""


# ---------------------------------------------------------------- parts and instances

_PART_KEYWORDS = ("NODE", "ELEMENT", "NSET", "ELSET", "SURFACE", "SOLID SECTION", "SOLID")
_STRUCTURE = ("PART", "END PART", "ASSEMBLY", "END ASSEMBLY", "INSTANCE", "END INSTANCE")


class _Placement:
    """An instance: its name, id offsets and the map of coordinates."""

    def __init__(self, name: str, node_offset: int, element_offset: int, matrix, shift):
        self.name = name
        self.node_offset = node_offset
        self.element_offset = element_offset
        self.matrix = np.asarray(matrix, float)
        self.shift = np.asarray(shift, float)

    def qualify(self, name: str) -> str:
        return f"{self.name}.{name}"


def _max_ids(blocks: list[Block], keyword: str) -> tuple[float, float]:
    """(smallest, largest) first value of the data lines of ``keyword`` blocks (ids)."""
    lo, hi = math.inf, 0.0
    for b in blocks:
        if b.keyword != keyword:
            continue
        for row in b.data:
            if isinstance(row, NumberRows):
                first = row.values[row.starts()]
                if len(first):
                    lo, hi = min(lo, float(first.min())), max(hi, float(first.max()))
            elif row.items and isinstance(row.items[0], Num) and math.isfinite(row.items[0]):
                lo, hi = min(lo, float(row.items[0])), max(hi, float(row.items[0]))
    return lo, hi


def _num(value: float) -> Num:
    return Num(f"{value:.17g}")


def _shift_row(row, first_offset: float, rest_offset: float, qualify=None, columns=None):
    """A data row (DataRow or NumberRows) with its numbers offset: the first value of each line
    by ``first_offset``, the others by ``rest_offset`` (``columns``: only values at those places
    on a line are offset, the others kept); names qualified by ``qualify``."""
    if isinstance(row, NumberRows):
        place = np.arange(row.values.size) - np.repeat(row.starts(), row.counts)
        off = np.where(place == 0, first_offset, rest_offset)
        if columns is not None:
            off = np.where(np.isin(place, columns), off, 0.0)
        return row.with_values(row.values + off)
    items = []
    for k, tok in enumerate(row.items):
        mine = columns is None or k in columns            # an id or set name (not a face, a step)
        if isinstance(tok, Num) and mine:
            items.append(_num(tok + (first_offset if k == 0 else rest_offset)))
        elif isinstance(tok, Name) and qualify is not None and mine:
            items.append(Name(qualify(str(tok))))
        else:
            items.append(tok)
    return DataRow(row.file, row.line, items)


def _move_nodes(row, placement: _Placement):
    """A *NODE data row of a part placed by an instance: ids offset, (x, y) moved."""
    def move(xy):
        return xy @ placement.matrix.T + placement.shift
    if isinstance(row, NumberRows):
        values = row.values.copy()
        s = row.starts()
        ok = row.counts >= 3
        values[s] += placement.node_offset
        xy = np.stack([values[s[ok] + 1], values[s[ok] + 2]], axis=1)
        moved = move(xy)
        values[s[ok] + 1], values[s[ok] + 2] = moved[:, 0], moved[:, 1]
        return row.with_values(values)
    items = list(row.items)
    if items and isinstance(items[0], Num):
        items[0] = _num(items[0] + placement.node_offset)
    if len(items) >= 3 and all(isinstance(t, Num) for t in items[1:3]):
        x, y = move(np.array([[float(items[1]), float(items[2])]]))[0]
        items[1], items[2] = _num(x), _num(y)
    return DataRow(row.file, row.line, items)


def _placed(block: Block, pl: _Placement) -> Block:
    """The copy of a part's block that an instance places."""
    params = dict(block.params)
    for key in ("NSET", "ELSET", "NAME"):
        if params.get(key):
            params[key] = pl.qualify(params[key])
    kw, q = block.keyword, pl.qualify
    if kw == "NODE":
        data = [_move_nodes(r, pl) for r in block.data]
    elif kw == "ELEMENT":
        data = [_shift_row(r, pl.element_offset, pl.node_offset) for r in block.data]
    elif kw in ("NSET", "ELSET"):
        off = pl.node_offset if kw == "NSET" else pl.element_offset
        generate = "GENERATE" in params
        data = [_shift_row(r, off, off, q, columns=(0, 1) if generate else None) for r in block.data]
    elif kw == "SURFACE":
        data = [_shift_row(r, pl.element_offset, 0.0, q, columns=(0,)) for r in block.data]
    else:                                            # SOLID SECTION, SOLID: names only
        data = list(block.data)
    return Block(kw, params, block.file, block.line, data, list(block.text), block.broken)


def _instance_set(block: Block, pl: _Placement) -> Block:
    """An assembly-level *NSET / *ELSET with ``INSTANCE=``: its lines name that instance's ids and
    sets."""
    params = {k: v for k, v in block.params.items() if k != "INSTANCE"}
    off = pl.node_offset if block.keyword == "NSET" else pl.element_offset
    generate = "GENERATE" in params
    data = [_shift_row(r, off, off, pl.qualify, columns=(0, 1) if generate else None) for r in block.data]
    return Block(block.keyword, params, block.file, block.line, data, list(block.text), block.broken)


def _placement_map(block: Block, problems: Problems):
    """(matrix (2, 2), shift (2,)) of an *INSTANCE's data lines, or None after reporting."""
    ok, rows = check_data(KEYWORDS["INSTANCE"], KEYWORDS["INSTANCE"].data, block, problems)
    if not ok:
        return None
    matrix, shift = np.eye(2), np.zeros(2)
    for k, (row, vals) in enumerate(rows):
        if k == 0:
            if len(vals) < 2 or len(vals) > 3:
                problems.add(row.file, row.line, block.keyword, f"expected a translation `x, y, z`, got "
                                                                f"{len(vals)} values")
                return None
            if len(vals) == 3 and vals[2] != 0.0:
                problems.add(row.file, row.line, block.keyword,
                             f"a translation along z ({vals[2]:g}) takes the part out of the plane")
                return None
            shift = np.array(vals[:2], float)
        else:
            if len(vals) != 7:
                problems.add(row.file, row.line, block.keyword, f"expected a rotation `a_x, a_y, a_z, "
                                                                f"b_x, b_y, b_z, angle`, got {len(vals)} values")
                return None
            a, b, angle = np.array(vals[:3]), np.array(vals[3:6]), vals[6]
            axis = b - a
            if np.hypot(axis[0], axis[1]) > 1e-9 * np.linalg.norm(axis) or axis[2] == 0.0:
                problems.add(row.file, row.line, block.keyword, "a rotation about an axis not parallel "
                                                                "to z takes the part out of the plane")
                return None
            t = math.radians(angle) * np.sign(axis[2])
            R = np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
            # translated first, then turned about the axis through (a_x, a_y)
            matrix, shift = R @ matrix, R @ (shift - a[:2]) + a[:2]
    return matrix, shift


def flatten(blocks: list[Block], problems: Problems) -> list[Block]:
    """The blocks with the ``*PART`` / ``*ASSEMBLY`` / ``*INSTANCE`` structure resolved (see the
    module docstring); decks without it come back as they are."""
    if not any(b.keyword in _STRUCTURE or "INSTANCE" in b.params for b in blocks):
        return blocks
    out: list[Block] = []
    parts: dict[str, list[Block]] = {}
    part: tuple[str, Block] | None = None           # the part being read, and its *PART block
    assembly: Block | None = None
    instance: Block | None = None
    placements: dict[str, _Placement] = {}
    for b in blocks:
        kw = b.keyword
        if kw in _STRUCTURE:
            params = None if b.broken else check_params(KEYWORDS[kw], b, problems)
            if params is None:
                continue                              # reported (the line, or its parameters)
        if kw == "PART":
            if part is not None or assembly is not None:
                where = f"inside *PART {part[0]}" if part else "inside the *ASSEMBLY"
                problems.at(b, f"*PART cannot come {where}")
                continue
            part = (params["NAME"], b)
            parts[params["NAME"]] = []
        elif kw == "END PART":
            if part is None:
                problems.at(b, "*END PART without a *PART")
            part = None
        elif part is not None:
            if kw not in _PART_KEYWORDS:
                problems.at(b, f"*{kw} cannot be inside *PART {part[0]} (a part holds "
                               f"{', '.join('*' + k for k in _PART_KEYWORDS)})")
                continue
            parts[part[0]].append(b)
        elif kw == "ASSEMBLY":
            if assembly is not None:
                problems.at(b, "*ASSEMBLY inside the *ASSEMBLY")
            assembly = b
        elif kw == "END ASSEMBLY":
            if assembly is None:
                problems.at(b, "*END ASSEMBLY without an *ASSEMBLY")
            if instance is not None:
                problems.at(instance, "*END INSTANCE missing before *END ASSEMBLY")
                instance = None
            assembly = None
        elif kw == "INSTANCE":
            if instance is not None:
                problems.at(instance, f"*END INSTANCE missing before the *INSTANCE at line {b.line}")
            instance = b
            name, part_name = params["NAME"], params["PART"]
            if part_name not in parts:
                problems.at(b, f"PART={part_name}: no *PART of that name comes before"
                               + (f" (parts: {', '.join(parts)})" if parts else ""))
                continue
            if name in placements:
                problems.at(b, f"instance {name} is already defined")
                continue
            placement = _placement_map(b, problems)
            if placement is None:
                continue
            body = parts[part_name]
            offsets = []
            for keyword in ("NODE", "ELEMENT"):
                lo, _ = _max_ids(body, keyword)
                _, hi = _max_ids(out, keyword)
                offsets.append(int(hi) if lo <= hi else 0)
            pl = _Placement(name, offsets[0], offsets[1], *placement)
            placements[name] = pl
            out += [_placed(pb, pl) for pb in body]
        elif kw == "END INSTANCE":
            if instance is None:
                problems.at(b, "*END INSTANCE without an *INSTANCE")
            instance = None
        elif instance is not None:
            problems.at(b, f"*{kw} inside *INSTANCE: only *END INSTANCE may follow (an instance places "
                           f"its part as it is)")
        elif kw in ("NSET", "ELSET") and b.params.get("INSTANCE"):
            inst = b.params["INSTANCE"].strip().upper()
            if inst not in placements:
                problems.at(b, f"INSTANCE={inst}: no *INSTANCE of that name comes before"
                               + (f" (instances: {', '.join(placements)})" if placements else ""))
                continue
            out.append(_instance_set(b, placements[inst]))
        else:
            out.append(b)
    for open_block, what in ((part[1] if part else None, "*END PART"), (assembly, "*END ASSEMBLY"),
                             (instance, "*END INSTANCE")):
        if open_block is not None:
            problems.at(open_block, f"{what} missing: *{open_block.keyword} is not closed")
    return out
