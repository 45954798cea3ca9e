"""The keyword table: what each keyword accepts, as data.

One declaration per keyword gives its scope (model data, or inside a ``*STEP``), its parameters
(:class:`~lagamine_py.core.params.Param`, the declaration plugins use too) and the shape of its
data lines (columns and their types, how many lines).  :func:`check_params` and
:func:`check_data` validate a block against it and convert the values, and
:func:`reference_markdown` writes the language reference from the same table.  Plugin
parameters (``KEY=VALUE`` data of ``*MATERIAL``, ``*CONTACT LAW``, ``*CHECK``) are declared by
the plugins themselves and checked by the builder against the same kind of declaration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.params import INT_MAX as _INT_MAX, REQUIRED, Param, validate
from .errors import Problems
from .grammar import Block, DataRow, Num, NumberRows, Pair


@dataclass(frozen=True)
class Col:
    """A data column.  ``type``: int, float, name (upper-cased: names are case-insensitive),
    text (a name kept as written: ``MPa`` is not ``mPa``), ref (an id or a set name), face
    (S1..S4)."""
    label: str
    type: str = "float"
    optional: bool = False


@dataclass(frozen=True)
class Data:
    """Data lines: ``form`` none | text | rows | pairs.  For rows, ``cols`` then, if
    ``repeat`` > 0, the last ``repeat`` columns any number of times."""
    form: str = "none"
    cols: tuple[Col, ...] = ()
    repeat: int = 0
    min_lines: int = 0
    max_lines: int | None = None
    doc: str = ""


@dataclass(frozen=True)
class Keyword:
    name: str
    scope: str                         # model | step | any
    params: tuple[Param, ...] = ()
    data: Data = Data()
    flag_data: tuple[tuple[str, Data], ...] = ()    # data shape when a flag parameter is given
    doc: str = ""
    bulk: bool = False          # its number lines may stay NumberRows (the builder vectorises)


def _name(name: str, required: bool = False, doc: str = "") -> Param:
    """A name parameter (upper-cased: names are case-insensitive)."""
    return Param(name, str, REQUIRED if required else None, upper=True, doc=doc)


_AMP = _name("AMPLITUDE", doc="amplitude name (default: linear ramp over the step)")
_OP = Param("OP", str, "MOD", choices=("MOD", "NEW"), doc="NEW removes the loads of this kind first")
_PAIRS = Data("pairs", doc="`KEY=VALUE` pairs")
# Abaqus: INTERNAL marks a set Abaqus/CAE made itself (read like any other); INSTANCE= (in an
# *ASSEMBLY) says whose ids and sets the data lines name
_SET_EXTRA = (Param("INTERNAL", flag=True, default=None, doc="Abaqus/CAE's own set (read as any)"),
              _name("INSTANCE", doc="in an *ASSEMBLY: the instance whose ids and sets the lines name"))

KEYWORDS: dict[str, Keyword] = {k.name: k for k in (
    # ---------------------------------------------------------------- model data
    Keyword("HEADING", "model", data=Data("text", doc="free text"), doc="title of the model"),
    Keyword("UNITS", "model",
            data=Data("rows", (Col("length", "text"), Col("force", "text"), Col("stress", "text")),
                      min_lines=1, max_lines=1, doc="`length, force, stress` unit names"),
            doc="the names of the deck's units (`mm, N, MPa`), carried into the outputs' "
                "metadata and the plots' axes; nothing is converted"),
    Keyword("INCLUDE", "any", (Param("INPUT", str, doc="path, relative to the including file"),),
            doc="read another file here"),
    Keyword("PARAMETER", "model", data=Data("pairs", min_lines=1, doc="`name = value` lines"),
            doc="parameters: `<name>` in later lines is replaced by the value"),
    Keyword("NODE", "model", (_name("NSET", doc="node set receiving these nodes"),),
            Data("rows", (Col("id", "int"), Col("x"), Col("y"), Col("z", optional=True)), min_lines=1,
                 doc="`id, x, y` (a z column must be 0)"), doc="nodes", bulk=True),
    Keyword("ELEMENT", "model", (_name("TYPE", True, doc="element type (registry name or alias)"),
                                 _name("ELSET", doc="element set receiving these elements")),
            Data("rows", (Col("id", "int"), Col("node", "int")), repeat=1, min_lines=1,
                 doc="`id, n1, n2, ...`: corners counter-clockwise, then mid-sides"), doc="elements", bulk=True),
    Keyword("IMPORT", "model", (Param("INPUT", str, doc="a gmsh .msh (format 2.2 or 4.1, ASCII or binary) or "
                                                          "an Abaqus/CalculiX .inp, relative to this file"),
                                Param("ANALYSIS", str, "PLANE STRAIN", choices=("PLANE STRAIN", "AXISYMMETRIC"),
                                      doc="the element types the 2D elements become"),
                                Param("INTEGRATION", str, "FULL", choices=("FULL", "REDUCED"),
                                      doc="REDUCED: 8-node quads with 2x2 Gauss points (Q8PER, Q8AXR)"),
                                _name("ELSET", doc="element set receiving every 2D element of the file")),
            doc="reads the nodes, 2D elements and named sets of a mesh file: 8-node quads -> Q8, 4-node "
                "-> Q4, 6-node triangles -> T6; gmsh physical groups: 2D -> ELSET, 1D -> SURFACE and "
                "NSET (or a curve for *FOUNDATION, CURVE= when apart from the body), 0D -> NSET"),
    Keyword("PART", "model", (_name("NAME", True),), doc="Abaqus part: its nodes, elements, sets and "
                                                          "sections, placed by *INSTANCE"),
    Keyword("END PART", "model", doc="ends a *PART"),
    Keyword("ASSEMBLY", "model", (_name("NAME"),), doc="Abaqus assembly: instances and assembly-level sets"),
    Keyword("END ASSEMBLY", "model", doc="ends the *ASSEMBLY"),
    Keyword("INSTANCE", "model", (_name("NAME", True), _name("PART", True)),
            Data("rows", tuple(Col(label, optional=k >= 2) for k, label in enumerate(
                ("x", "y", "z", "b_x", "b_y", "b_z", "angle"))), max_lines=2,
                 doc="optional `x, y, z`: translation; then `a_x, a_y, a_z, b_x, b_y, b_z, angle`: "
                     "rotation by angle (degrees) about the axis from a to b (parallel to z)"),
            doc="places a *PART: its nodes and elements (ids offset past those already defined when "
                "they clash) and its sets, named INSTANCE.SET"),
    Keyword("END INSTANCE", "model", doc="ends an *INSTANCE"),
    Keyword("NSET", "model", (_name("NSET", True), Param("GENERATE", flag=True, default=None), *_SET_EXTRA),
            Data("rows", (Col("node or nset", "ref"),), repeat=1, min_lines=1, doc="node ids or node set names"),
            (("GENERATE", Data("rows", (Col("first", "int"), Col("last", "int"), Col("step", "int", True)),
                               min_lines=1, doc="`first, last, step`")),), doc="node set", bulk=True),
    Keyword("ELSET", "model", (_name("ELSET", True), Param("GENERATE", flag=True, default=None), *_SET_EXTRA),
            Data("rows", (Col("element or elset", "ref"),), repeat=1, min_lines=1,
                 doc="element ids or element set names"),
            (("GENERATE", Data("rows", (Col("first", "int"), Col("last", "int"), Col("step", "int", True)),
                               min_lines=1, doc="`first, last, step`")),), doc="element set", bulk=True),
    Keyword("MESH", "model", (_name("NAME", True), _name("TYPE", True, doc="element type"),
                              Param("X0", float, 0.0), Param("Y0", float, 0.0),
                              Param("LX", float, gt=0.0), Param("LY", float, gt=0.0),
                              Param("NX", int, bounds=(1, None)), Param("NY", int, bounds=(1, None))),
            doc="structured rectangle: nodes, elements (elset NAME), nsets and surfaces NAME_BOTTOM, "
                "NAME_TOP, NAME_LEFT, NAME_RIGHT"),
    Keyword("SURFACE", "model", (_name("NAME", True), Param("TYPE", str, "ELEMENT",
                                                            choices=("ELEMENT",))),
            Data("rows", (Col("element or elset", "ref"), Col("face", "face")), min_lines=1,
                 doc="`element-or-elset, face`: S1..S4 on quadrilaterals, S1..S3 on triangles"),
            doc="element faces"),
    Keyword("MATERIAL", "model", (_name("NAME", True), _name("LAW", doc="material law plugin; without it "
                                                                       "the Abaqus cards that follow "
                                                                       "(*ELASTIC, *PLASTIC) give the law")),
            _PAIRS, doc="material: the law's parameters"),
    Keyword("ELASTIC", "model", (Param("TYPE", str, "ISOTROPIC", choices=("ISOTROPIC",)),),
            Data("rows", (Col("E"), Col("nu"), Col("temperature", optional=True)), min_lines=1, max_lines=1,
                 doc="`E, nu`"),
            doc="after a *MATERIAL without LAW= (Abaqus): isotropic elasticity (law ELASTIC, or "
                "J2_TABLE with a *PLASTIC)"),
    Keyword("PLASTIC", "model", (Param("HARDENING", str, "ISOTROPIC", choices=("ISOTROPIC",)),),
            Data("rows", (Col("yield stress"), Col("plastic strain"), Col("temperature", optional=True)),
                 min_lines=1, doc="`yield stress, plastic strain` rows, the first at plastic strain 0"),
            doc="after a *MATERIAL: the hardening table of J2_TABLE (piecewise linear, flat beyond "
                "the last row)"),
    Keyword("SOLID", "model", (_name("ELSET", True), _name("MATERIAL", True),
                               Param("THICKNESS", float, 1.0, gt=0.0)),
            doc="assigns a material to elements"),
    Keyword("SOLID SECTION", "model", (_name("ELSET", True), _name("MATERIAL", True)),
            Data("rows", (Col("thickness", optional=True),), max_lines=1,
                 doc="optional `thickness` (plane strain; default 1)"),
            doc="Abaqus form of *SOLID"),
    Keyword("FOUNDATION", "model", (_name("NAME", True),
                                    _name("CURVE", doc="a curve of an *IMPORT (a 1D group of lines apart "
                                                       "from the body): its lines, chained, are the arcs"),
                                    Param("REVERSE", flag=True, default=None,
                                          doc="run the CURVE the other way (the body on its left)"),
                                    Param("REF NODE", int, None, bounds=(1, None),
                                          doc="a node of *NODE, used by no element, that carries the "
                                              "rigid tool's motion: DOFs 1, 2 and, in plane strain, 6 "
                                              "(the rotation, radians, counter-clockwise), prescribed by "
                                              "*BOUNDARY or loaded by *CLOAD; its reactions are the tool's "
                                              "force and moment"),
                                    Param("XC", float, None, unit="length",
                                          doc="without REF NODE: x of the point *FOUNDATION MOTION turns "
                                              "the tool about (default 0, or the CIRCLE's centre)"),
                                    Param("YC", float, None, unit="length", doc="likewise y"),
                                    Param("CIRCLE", str, None, choices=("INSIDE", "OUTSIDE"), upper=True,
                                          doc="generate the points on a circle: the contact bodies lie "
                                              "INSIDE it (a die) or OUTSIDE (a roll)")),
            Data("rows", (Col("x"), Col("y")), doc="`x, y` points, an odd count >= 3 (none with CURVE=)"),
            (("CIRCLE", Data("rows", (Col("xc"), Col("yc"), Col("radius"), Col("start angle"),
                                      Col("end angle"), Col("arcs", "int")), min_lines=1, max_lines=1,
                             doc="`xc, yc, radius, start angle, end angle, arcs`: the arc from start to "
                                 "end angle (degrees, counter-clockwise from +x) as `arcs` parabolic "
                                 "arcs")),),
            doc="rigid foundation: parabolic arcs through points (1,2,3), (3,4,5), ..."),
    Keyword("CONTACT LAW", "model", (_name("NAME", True), _name("TYPE", True, doc="contact law plugin")),
            _PAIRS, doc="contact law: the plugin's parameters"),
    Keyword("CONTACT LAW TABLE", "model", (),
            Data("rows", (Col("lambda"), Col("phi"), Col("B")), min_lines=1,
                 doc="`lambda, phi, B` rows, the first at lambda = 0, lambda increasing"),
            doc="after a *CONTACT LAW (COULOMB): friction phi and adhesion B piecewise linear in the "
                "slip lambda, flat beyond the last row (instead of PHI, B and their hardening)"),
    Keyword("CONTACT", "model", (_name("SURFACE", True),
                                 _name("FOUNDATION", doc="the rigid foundation (or MASTER=)"),
                                 _name("MASTER", doc="a surface of another deformable body, whose 3-node "
                                                     "faces the SURFACE's Gauss points project on "
                                                     "(instead of FOUNDATION=)"),
                                 _name("LAW", True),
                                 Param("GAUSS", int, 3,
                                       choices=(2, 3, "LOBATTO2", "LOBATTO3", "LINEAR"),
                                       doc="the contact element's points: 2 or 3 Gauss points; "
                                           "LOBATTO3 (LOBATTO2 on 2-node faces): at the face's "
                                           "nodes; LINEAR: the law at the face's corners, its "
                                           "tractions linear along the face (no pressure "
                                           "oscillation under stiff penalties, "
                                           "docs/accuracy_speed.md)"),
                                 Param("SEARCH", float, None, gt=0.0, unit="length",
                                       doc="with MASTER: each slave face couples to the master faces "
                                           "within this distance (default three times the larger "
                                           "median face length); re-paired before every increment"),
                                 Param("PASSES", int, 1, choices=(1, 2),
                                       doc="with MASTER: 1, the SURFACE's points kept out of the "
                                           "master; 2, the MASTER's points kept out of the SURFACE "
                                           "too, each pass carrying half the forces (both surfaces "
                                           "need 3-node faces; docs/two_body.md)")),
            doc="contact elements on a surface against a foundation or a master surface"),
    Keyword("AMPLITUDE", "model", (_name("NAME", True),),
            Data("rows", (Col("time"), Col("value")), repeat=2, min_lines=1, doc="`time, value` pairs"),
            doc="piecewise linear load curve"),
    Keyword("CHECK", "model", (_name("NAME", True), _name("TYPE", True, doc="check plugin")),
            Data("pairs", doc="`KEY=VALUE`: the check's parameters"),
            doc="closed form the results are checked against"),
    # ---------------------------------------------------------------- steps
    Keyword("STEP", "model", (Param("NAME", str, None), Param("NLGEOM", bool, False),
                              Param("INC", int, 1000, bounds=(1, None))), doc="starts a step"),
    Keyword("STATIC", "step", data=Data("rows", (Col("initial dt"), Col("step time"), Col("min dt", optional=True),
                                                 Col("max dt", optional=True)), min_lines=1, max_lines=1,
                                        doc="`initial dt, step time, min dt, max dt`"),
            doc="incremental static analysis (required in every step)"),
    Keyword("BOUNDARY", "step", (_AMP, _OP),
            Data("rows", (Col("node or nset", "ref"), Col("first dof", "int"), Col("last dof", "int", True),
                          Col("value", optional=True)), min_lines=1,
                 doc="`node-or-nset, first dof, last dof, value` (DOFs 1, 2; 6 the rotation of a tool's "
                     "reference node, radians)"), doc="imposed displacements"),
    Keyword("CLOAD", "step", (_AMP, _OP),
            Data("rows", (Col("node or nset", "ref"), Col("dof", "int"), Col("value")), min_lines=1,
                 doc="`node-or-nset, dof, value` (DOF 6 on a tool's reference node: a moment)"),
            doc="nodal forces (per node)"),
    Keyword("DLOAD", "step", (_AMP, _OP),
            Data("rows", (Col("surface", "name"), Col("load type", "name"), Col("value")), min_lines=1,
                 doc="`surface, P, value`"), doc="pressure (positive into the body)"),
    Keyword("FOUNDATION MOTION", "step", (_name("NAME", True), _AMP),
            Data("rows", (Col("dx"), Col("dy"), Col("angle", optional=True)), min_lines=1, max_lines=1,
                 doc="`dx, dy[, angle]`: translation of the reference point and rotation about it "
                     "(radians, counter-clockwise; default 0)"),
            doc="rigid motion of a foundation reached at the step end (totals from where the deck puts "
                "it); on a foundation with a REF NODE, *BOUNDARY on its DOFs 1, 2, 6"),
    Keyword("CHANGE CONTACT LAW", "step", (_name("SURFACE", True),
                                          _name("FOUNDATION", doc="the pair's foundation (or MASTER=)"),
                                          _name("MASTER", doc="the pair's master surface (two "
                                                              "deformable bodies)"),
                                          _name("LAW", True)),
            doc="the contact pair SURFACE->FOUNDATION (or ->MASTER) uses the contact law LAW from this "
                "step on; its state (p, tau, the slip lambda, the dissipation) carries over"),
    Keyword("CONTACT STABILIZATION", "step",
            (Param("FACTOR", float, 1e-4, gt=0.0,
                   doc="damping coefficient as a fraction of KP times the step time"),
             Param("TANGENTIAL", float, 1.0, bounds=(0.0, None),
                   doc="tangential damping relative to the normal one"),
             Param("RANGE", float, None, gt=0.0, unit="length",
                   doc="open points within this distance of the foundation are damped (default one "
                       "face length of the surface)"),
             _name("SURFACE", doc="the pairs of this surface only (default every pair)"),
             _name("FOUNDATION", doc="the pairs of this foundation only")),
            doc="viscous damping of the open contact points near their foundation, fading over the "
                "step: a body or tool held only by contact that is not closed yet (touching at a "
                "point, driven by a force) runs without a singular matrix; its energy is in the log"),
    Keyword("OUTPUT", "step", (Param("FREQUENCY", int, 1, bounds=(1, None)),
                               Param("FIELDS", str, None,
                                     doc="fields of the VTK body files: U, S, LE, PE, PEEQ, RF, "
                                         "separated by / or spaces (default all)"),
                               Param("CONTACT", bool, True),
                               Param("WRITERS", str, None,
                                     doc="registered writers, separated by / (default: the "
                                         "built-ins)")), doc="output requests"),
    Keyword("CONTROLS", "step", data=_PAIRS, doc="Newton and step-controller settings"),
    Keyword("END STEP", "step", doc="ends a step"),
)}


#: keyword -> why it is skipped (it changes nothing this program computes)
SKIPPED = {
    "PREPRINT": "printing controls", "RESTART": "Abaqus restart files", "MONITOR": "progress output",
    "PRINT": "printing controls", "FILE FORMAT": "results file format",
    "NODE OUTPUT": "output request", "ELEMENT OUTPUT": "output request",
    "CONTACT OUTPUT": "output request", "ENERGY OUTPUT": "output request",
    "INTEGRATED OUTPUT": "output request", "SECTION OUTPUT": "output request",
    "NODE PRINT": "output request", "EL PRINT": "output request", "CONTACT PRINT": "output request",
    "ENERGY PRINT": "output request", "SECTION PRINT": "output request",
    "NODE FILE": "output request", "EL FILE": "output request", "CONTACT FILE": "output request",
    "ENERGY FILE": "output request", "SECTION FILE": "output request",
    "DENSITY": "inertia (the analysis is static)", "PHYSICAL CONSTANTS": "physical constants",
}


# ---------------------------------------------------------------- checking a block

def check_params(spec: Keyword, block: Block, problems: Problems) -> dict[str, Any] | None:
    """Converted parameters (defaults filled), or None after reporting what is wrong."""
    out, errors = validate(spec.params, block.params)
    for _, message in errors:
        if message.startswith("unknown parameter") and not spec.params:
            message = message.replace("it takes none", "*" + spec.name + " takes no parameters")
        problems.at(block, message)
    if errors:
        return None
    for p in spec.params:
        out.setdefault(p.name, None if not p.flag else False)
    return out


def _convert_cell(col: Col, tok) -> Any:
    """Converted value of one data field, or raise ValueError."""
    if isinstance(tok, Pair):
        raise ValueError(f"{col.label} expected, got {tok.key}={tok.text}")
    if col.type in ("int", "float"):
        if not isinstance(tok, Num):
            raise ValueError(f"{col.label} must be a number, got non-numeric {str(tok)!r}")
        if not math.isfinite(tok):
            raise ValueError(f"{col.label} must be finite, got {tok.text!r}")
        if col.type == "int":
            if tok != int(tok):
                raise ValueError(f"{col.label} must be an integer, got {tok.text!r}")
            if abs(tok) > _INT_MAX:
                raise ValueError(f"{col.label} must be below 2^31, got {tok.text!r}")
            return int(tok)
        return float(tok)
    if col.type == "ref":
        if isinstance(tok, Num):
            if not math.isfinite(tok) or tok != int(tok) or abs(tok) > _INT_MAX:
                what = "below 2^31" if math.isfinite(tok) and tok == int(tok) else "an integer"
                raise ValueError(f"{col.label} must be an id ({what}) or a set name, got {tok.text!r}")
            return int(tok)
        return str(tok).upper()
    if col.type == "face":
        up = str(tok).upper()
        if isinstance(tok, Num) or up not in ("S1", "S2", "S3", "S4"):
            raise ValueError(f"{col.label} must be S1, S2, S3 or S4, got {str(getattr(tok, 'text', tok))!r}")
        return int(up[1])
    if isinstance(tok, Num):                       # name, text
        raise ValueError(f"{col.label} must be a name, got the number {tok.text!r}")
    return str(tok) if col.type == "text" else str(tok).upper()


def _shape(data: Data) -> str:
    labels = [c.label + ("?" if c.optional else "") for c in data.cols]
    if data.repeat:
        labels.append("...")
    return ", ".join(labels)


def _wrong_count(data: Data, n: int) -> str | None:
    """The message for a line of ``n`` values that the data shape does not allow, else None."""
    cols, nrep = data.cols, data.repeat
    nreq = sum(not c.optional for c in cols)
    if n < nreq or (not nrep and n > len(cols)) or (nrep > 1 and (n - len(cols)) % nrep):
        want = (f"{nreq}" if nreq == len(cols) else f"{nreq} to {len(cols)}") if not nrep else \
               f"at least {nreq}" + (f" (then groups of {nrep})" if nrep > 1 else "")
        return f"wrong number of values: expected {want} ({_shape(data)}), got {n}"
    return None


def _column(data: Data, k: int) -> Col:
    cols, nrep = data.cols, data.repeat
    return cols[k] if k < len(cols) else cols[len(cols) - nrep + (k - len(cols)) % nrep]


def _check_number_rows(data: Data, nr: NumberRows, keyword: str, problems: Problems):
    """The lines of ``nr`` checked in bulk against the data shape: ``(good lines as a
    NumberRows, all good)``, the others reported one by one."""
    counts, values = nr.counts, nr.values
    bad_line = np.zeros(len(counts), bool)
    for n in np.unique(counts):
        message = _wrong_count(data, int(n))
        if message:
            for k in np.flatnonzero(counts == n):
                problems.add(nr.file, int(nr.line_numbers()[k]), keyword, message)
            bad_line |= counts == n
    # the column of every value, from its place on its line
    starts = np.repeat(np.cumsum(counts) - counts, counts)
    place = np.arange(values.size) - starts
    line_of = np.repeat(np.arange(len(counts)), counts)
    kinds = np.array([_column(data, k).type for k in range(int(counts.max(initial=0)))] or ["float"])
    kind = kinds[np.minimum(place, len(kinds) - 1)]
    integral = np.isin(kind, ("int", "ref"))
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(values) | (integral & ((values != np.round(values)) | (np.abs(values) > _INT_MAX)))
    bad &= ~bad_line[line_of]
    for v in np.flatnonzero(bad)[:1000]:
        k, p = int(line_of[v]), int(place[v])
        tok = nr.text(k).rstrip(" \t\r,").split(",")[p].strip()
        try:
            _convert_cell(_column(data, p), Num(tok))
            message = f"value {p + 1}: cannot read {tok!r}"
        except ValueError as exc:
            message = f"value {p + 1}: {exc}"
        problems.add(nr.file, int(nr.line_numbers()[k]), keyword, message)
    bad_line[line_of[bad]] = True
    if not bad_line.any():
        return nr, True
    keep = np.flatnonzero(~bad_line)
    good = NumberRows(nr.file, nr.line, counts[keep], values[~bad_line[line_of]],
                      [nr.text(k) for k in keep] if nr.raw is not None else None,
                      nr.line_numbers()[keep])
    return good, False


def check_rows(data: Data, block: Block, problems: Problems, bulk: bool = False):
    """Rows of converted values (the readable ones) and whether all were (problems reported).

    Rows are ``(DataRow, values)`` pairs; with ``bulk``, number lines read in bulk stay
    :class:`~lagamine_py.deck.grammar.NumberRows` (checked in bulk: ints integral, floats
    finite) for the builder to use as arrays."""
    out, ok = [], True
    for row in block.data:
        if isinstance(row, NumberRows):
            if bulk:
                good, all_good = _check_number_rows(data, row, block.keyword, problems)
                ok &= all_good
                if len(good):
                    out.append(good)
                continue
            sub, sub_ok = _check_data_rows(data, row.rows(), block.keyword, problems)
        else:
            sub, sub_ok = _check_data_rows(data, [row], block.keyword, problems)
        out += sub
        ok &= sub_ok
    return out, ok


def _check_data_rows(data: Data, rows: list[DataRow], keyword: str, problems: Problems):
    out, ok = [], True
    for row in rows:
        n = len(row.items)
        message = _wrong_count(data, n)
        if message:
            problems.add(row.file, row.line, keyword, message)
            ok = False
            continue
        values, row_ok = [], True
        for k, tok in enumerate(row.items):
            try:
                values.append(_convert_cell(_column(data, k), tok))
            except ValueError as exc:
                problems.add(row.file, row.line, keyword, f"value {k + 1}: {exc}")
                row_ok = False
        if row_ok:
            out.append((row, values))
        ok &= row_ok
    return out, ok


def check_pairs(block: Block, problems: Problems) -> list[tuple[DataRow, Pair]] | None:
    """``KEY=VALUE`` items (each with its row); None after reporting non-pairs or repeats."""
    out, seen, ok = [], {}, True
    for row in (r for item in block.data
                for r in (item.rows() if isinstance(item, NumberRows) else [item])):
        others = [getattr(tok, "text", str(tok)) for tok in row.items if not isinstance(tok, Pair)]
        if others:          # one message for the line (a line of numbers is one mistake)
            problems.add(row.file, row.line, block.keyword,
                         f"expected KEY=VALUE pairs, got {', '.join(others)!r}")
            ok = False
        for tok in row.items:
            if not isinstance(tok, Pair):
                continue
            elif tok.key in seen:
                problems.add(row.file, row.line, block.keyword,
                             f"{tok.key} is given twice (first on line {seen[tok.key]})")
                ok = False
            else:
                seen[tok.key] = row.line
                out.append((row, tok))
    return out if ok else None


def data_spec(spec: Keyword, params: dict[str, Any]) -> Data:
    for flag, data in spec.flag_data:
        if params.get(flag):
            return data
    return spec.data


def check_data(spec: Keyword, data: Data, block: Block, problems: Problems):
    """Returns (ok, converted): rows (list of (row, values), or NumberRows for a bulk keyword:
    the readable rows even when not ok), pairs (list of (row, Pair), None when not ok) or the
    *HEADING text."""
    n = sum(len(r) if isinstance(r, NumberRows) else 1 for r in block.data)
    if data.form in ("none", "text"):
        if block.data:
            problems.add(block.data[0].file, block.data[0].line, block.keyword,
                         f"*{block.keyword} takes no data lines")
            return False, None
        return True, block.text
    if n < data.min_lines:
        problems.at(block, f"expected at least {data.min_lines} data line{'s' * (data.min_lines > 1)} "
                           f"({data.doc}), got {n}")
        return False, None
    if data.max_lines is not None and n > data.max_lines:
        lines = [(r.file, r.line + k) for r in block.data
                 for k in range(len(r) if isinstance(r, NumberRows) else 1)]
        problems.add(*lines[data.max_lines], block.keyword,
                     f"expected {data.max_lines} data line{'s' * (data.max_lines > 1)} ({data.doc}), got {n}")
        return False, None
    if data.form == "pairs":
        conv = check_pairs(block, problems)
        return conv is not None, conv
    return check_rows(data, block, problems, spec.bulk)[::-1]


# ---------------------------------------------------------------- reference

def _param_doc(p: Param) -> str:
    if p.flag:
        return f"`{p.name}`"
    choices = p.allowed()
    if choices:
        kind = "/".join(map(str, choices))
    elif p.type is bool:
        kind = "YES/NO"
    elif p.type is tuple:
        kind = f"table: {', '.join(p.columns)} rows of a *{p.name} block"
    else:
        kind = {float: "number", int: "integer", str: "name" if p.upper else "text"}[p.type]
    default = {True: "YES", False: "NO"}.get(p.default, p.default) if p.type is bool else p.default
    extra = "required" if p.required else (f"default {default}" if default is not None else "optional")
    extra += f", > {p.gt:g}" if p.gt is not None else ""
    low = p.bounds[0]
    extra += f", >= {low:g}" if low is not None and not choices else ""
    doc = f": {p.doc}" if p.doc else ""
    return f"`{p.name}=` ({kind}, {extra}){doc}"


def reference_markdown() -> str:
    """The keyword reference (markdown), generated from :data:`KEYWORDS`."""
    out = []
    for scope, title in (("model", "Model keywords"), ("step", "Step keywords (between *STEP and *END STEP)"),
                         ("any", "Anywhere")):
        out += [f"## {title}", "", "| keyword | parameters | data lines | what |", "|---|---|---|---|"]
        for kw in KEYWORDS.values():
            if kw.scope != scope:
                continue
            params = "<br>".join(_param_doc(p) for p in kw.params)
            data = kw.data.doc if kw.data.form != "none" else ""
            for flag, d in kw.flag_data:
                data += f"<br>with `{flag}`: {d.doc}"
            out.append(f"| `*{kw.name}` | {params} | {data} | {kw.doc} |")
        out.append("")
    out += ["## Skipped", "", "Abaqus and CalculiX keywords that carry nothing for this program: read, "
            "listed once in a notice, and skipped (so are Abaqus's `*OUTPUT, FIELD` and `*OUTPUT, HISTORY` "
            "requests). Any other keyword this page does not list is an error.", "",
            "| keyword | what it is |", "|---|---|"]
    out += [f"| `*{kw}` | {why} |" for kw, why in sorted(SKIPPED.items())]
    out.append("")
    return "\n".join(out)
