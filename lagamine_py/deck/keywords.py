"""The keyword table: what each keyword accepts, as data.

One declaration per keyword gives its scope (model data, or inside a ``*STEP``), its parameters
(type, required or default) and the shape of its data lines (columns and their types, how many
lines).  :func:`check_block` validates a block against it and converts the values, and
:func:`reference_markdown` writes the language reference from the same table.  Plugin
parameters (``KEY=VALUE`` data of ``*MATERIAL``, ``*CONTACT LAW``) are declared by the plugins
themselves and checked by the builder with :func:`lagamine_py.registry.validate_params`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..registry import did_you_mean
from .errors import Problems
from .grammar import Block, DataRow, Num, Pair


@dataclass(frozen=True)
class P:
    """A keyword parameter.  ``type``: name (upper-cased), text (as written), int, float,
    yesno, choice (one of ``choices``), flag (no value)."""
    name: str
    type: str = "name"
    required: bool = False
    default: Any = None
    choices: tuple = ()
    low: float | None = None          # inclusive lower bound of a number
    positive: bool = False            # number > 0
    doc: str = ""


@dataclass(frozen=True)
class Col:
    """A data column.  ``type``: int, float, name, ref (an id or a set name), face (S1..S4)."""
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
    params: tuple[P, ...] = ()
    data: Data = Data()
    flag_data: tuple[tuple[str, Data], ...] = ()    # data shape when a flag parameter is given
    doc: str = ""


_AMP = P("AMPLITUDE", doc="amplitude name (default: linear ramp over the step)")
_OP = P("OP", "choice", default="MOD", choices=("MOD", "NEW"), doc="NEW removes the loads of this kind first")
_PAIRS = Data("pairs", doc="`KEY=VALUE` pairs")

KEYWORDS: dict[str, Keyword] = {k.name: k for k in (
    # ---------------------------------------------------------------- model data
    Keyword("HEADING", "model", data=Data("text", doc="free text"), doc="title of the model"),
    Keyword("INCLUDE", "any", (P("INPUT", "text", True, doc="path, relative to the including file"),),
            doc="read another file here"),
    Keyword("PARAMETER", "model", data=Data("pairs", min_lines=1, doc="`name = value` lines"),
            doc="parameters: `<name>` in later lines is replaced by the value"),
    Keyword("NODE", "model", (P("NSET", doc="node set receiving these nodes"),),
            Data("rows", (Col("id", "int"), Col("x"), Col("y"), Col("z", optional=True)), min_lines=1,
                 doc="`id, x, y` (a z column must be 0)"), doc="nodes"),
    Keyword("ELEMENT", "model", (P("TYPE", required=True, doc="element type (registry name or alias)"),
                                 P("ELSET", doc="element set receiving these elements")),
            Data("rows", (Col("id", "int"), Col("node", "int")), repeat=1, min_lines=1,
                 doc="`id, n1, n2, ...`: corners counter-clockwise, then mid-sides"), doc="elements"),
    Keyword("NSET", "model", (P("NSET", required=True), P("GENERATE", "flag")),
            Data("rows", (Col("node or nset", "ref"),), repeat=1, min_lines=1, doc="node ids or node set names"),
            (("GENERATE", Data("rows", (Col("first", "int"), Col("last", "int"), Col("step", "int", True)),
                               min_lines=1, doc="`first, last, step`")),), doc="node set"),
    Keyword("ELSET", "model", (P("ELSET", required=True), P("GENERATE", "flag")),
            Data("rows", (Col("element or elset", "ref"),), repeat=1, min_lines=1,
                 doc="element ids or element set names"),
            (("GENERATE", Data("rows", (Col("first", "int"), Col("last", "int"), Col("step", "int", True)),
                               min_lines=1, doc="`first, last, step`")),), doc="element set"),
    Keyword("MESH", "model", (P("NAME", required=True), P("TYPE", required=True, doc="element type"),
                              P("X0", "float", default=0.0), P("Y0", "float", default=0.0),
                              P("LX", "float", True, positive=True), P("LY", "float", True, positive=True),
                              P("NX", "int", True, low=1), P("NY", "int", True, low=1)),
            doc="structured rectangle: nodes, elements (elset NAME), nsets and surfaces NAME_BOTTOM, "
                "NAME_TOP, NAME_LEFT, NAME_RIGHT"),
    Keyword("SURFACE", "model", (P("NAME", required=True), P("TYPE", "choice", default="ELEMENT",
                                                              choices=("ELEMENT",))),
            Data("rows", (Col("element or elset", "ref"), Col("face", "face")), min_lines=1,
                 doc="`element-or-elset, S1..S4`"), doc="element faces"),
    Keyword("MATERIAL", "model", (P("NAME", required=True), P("LAW", required=True, doc="material law plugin")),
            _PAIRS, doc="material: the law's parameters"),
    Keyword("SOLID", "model", (P("ELSET", required=True), P("MATERIAL", required=True),
                               P("THICKNESS", "float", default=1.0, positive=True)),
            doc="assigns a material to elements"),
    Keyword("FOUNDATION", "model", (P("NAME", required=True),),
            Data("rows", (Col("x"), Col("y")), min_lines=3, doc="`x, y` points, an odd count >= 3"),
            doc="rigid foundation: parabolic arcs through points (1,2,3), (3,4,5), ..."),
    Keyword("CONTACT LAW", "model", (P("NAME", required=True), P("TYPE", required=True, doc="contact law plugin")),
            _PAIRS, doc="contact law: the plugin's parameters"),
    Keyword("CONTACT", "model", (P("SURFACE", required=True), P("FOUNDATION", required=True),
                                 P("LAW", required=True), P("GAUSS", "int", default=3, choices=(2, 3))),
            doc="contact elements on a surface against a foundation"),
    Keyword("AMPLITUDE", "model", (P("NAME", required=True),),
            Data("rows", (Col("time"), Col("value")), repeat=2, min_lines=1, doc="`time, value` pairs"),
            doc="piecewise linear load curve"),
    Keyword("CHECK", "model", (P("NAME", required=True), P("TYPE", required=True)),
            Data("pairs", doc="`KEY=VALUE` numbers"), doc="closed form the results are checked against"),
    # ---------------------------------------------------------------- steps
    Keyword("STEP", "model", (P("NAME", "text"), P("NLGEOM", "yesno", default=False),
                              P("INC", "int", default=1000, low=1)), doc="starts a step"),
    Keyword("STATIC", "step", data=Data("rows", (Col("initial dt"), Col("step time"), Col("min dt", optional=True),
                                                 Col("max dt", optional=True)), min_lines=1, max_lines=1,
                                        doc="`initial dt, step time, min dt, max dt`"),
            doc="incremental static analysis (required in every step)"),
    Keyword("BOUNDARY", "step", (_AMP, _OP),
            Data("rows", (Col("node or nset", "ref"), Col("first dof", "int"), Col("last dof", "int", True),
                          Col("value", optional=True)), min_lines=1,
                 doc="`node-or-nset, first dof, last dof, value`"), doc="imposed displacements"),
    Keyword("CLOAD", "step", (_AMP, _OP),
            Data("rows", (Col("node or nset", "ref"), Col("dof", "int"), Col("value")), min_lines=1,
                 doc="`node-or-nset, dof, value`"), doc="nodal forces (per node)"),
    Keyword("DLOAD", "step", (_AMP, _OP),
            Data("rows", (Col("surface", "name"), Col("load type", "name"), Col("value")), min_lines=1,
                 doc="`surface, P, value`"), doc="pressure (positive into the body)"),
    Keyword("FOUNDATION MOTION", "step", (P("NAME", required=True), _AMP),
            Data("rows", (Col("dx"), Col("dy")), min_lines=1, max_lines=1, doc="`dx, dy`"),
            doc="rigid translation of a foundation reached at the step end"),
    Keyword("OUTPUT", "step", (P("FREQUENCY", "int", default=1, low=1), P("FIELDS", "text",
                               doc="fields of the VTK body files: U, S, PEEQ, RF, separated by / or "
                                   "spaces (default all)"),
                               P("CONTACT", "yesno", default=True)), doc="output requests"),
    Keyword("CONTROLS", "step", data=_PAIRS, doc="Newton and step-controller settings"),
    Keyword("END STEP", "step", doc="ends a step"),
)}


# ---------------------------------------------------------------- checking a block

_INT_MAX = 2**31 - 1       # ids and counts must fit the int arrays of the Model


def _number(text: str) -> float:
    value = float(text.replace("d", "e").replace("D", "E"))
    if not math.isfinite(value):
        raise ValueError(text)
    return value


def _convert_param(p: P, raw: str | None) -> Any:
    """Converted value of a parameter, or raise ValueError with the expectation."""
    if p.type == "flag":
        if raw is not None:
            raise ValueError(f"{p.name} takes no value")
        return True
    if raw is None or raw == "":
        raise ValueError(f"{p.name} needs a value ({p.name}=...)")
    if p.type == "text":
        return raw
    if p.type == "name":
        return raw.upper()
    if p.type == "yesno":
        up = raw.upper()
        if up in ("YES", "TRUE", "ON"):
            return True
        if up in ("NO", "FALSE", "OFF"):
            return False
        raise ValueError(f"{p.name} must be YES or NO, got {raw!r}")
    if p.type == "choice":
        if raw.upper() not in p.choices:
            raise ValueError(f"{p.name} must be one of {', '.join(p.choices)}, got {raw!r}"
                             f"{did_you_mean(raw, p.choices)}")
        return raw.upper()
    try:
        value = _number(raw)
    except ValueError:
        raise ValueError(f"{p.name} must be a number, got {raw!r}") from None
    if p.type == "int":
        if value != int(value) or abs(value) > _INT_MAX:
            raise ValueError(f"{p.name} must be an integer below 2^31, got {raw!r}")
        value = int(value)
    if p.choices and value not in p.choices:
        raise ValueError(f"{p.name} must be one of {', '.join(map(str, p.choices))}, got {raw!r}")
    if p.positive and value <= 0:
        raise ValueError(f"{p.name} must be > 0, got {raw!r}")
    if p.low is not None and value < p.low:
        raise ValueError(f"{p.name} must be >= {p.low:g}, got {raw!r}")
    return value


def check_params(spec: Keyword, block: Block, problems: Problems) -> dict[str, Any] | None:
    """Converted parameters (defaults filled), or None after reporting what is wrong."""
    declared = {p.name: p for p in spec.params}
    out, ok = {}, True
    for name, raw in block.params.items():
        p = declared.get(name)
        if p is None:
            problems.at(block, f"unknown parameter {name}{did_you_mean(name, declared)}; "
                               f"expected {', '.join(declared) or 'no parameters'}")
            ok = False
            continue
        try:
            out[name] = _convert_param(p, raw)
        except ValueError as exc:
            problems.at(block, str(exc))
            ok = False
    for p in spec.params:
        if p.name not in block.params:
            if p.required:
                problems.at(block, f"missing required parameter {p.name}=")
                ok = False
            elif p.type != "flag":
                out[p.name] = p.default
    return out if ok else None


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
            if tok != int(tok) or abs(tok) > _INT_MAX:
                raise ValueError(f"{col.label} must be an integer below 2^31, got {tok.text!r}")
            return int(tok)
        return float(tok)
    if col.type == "ref":
        if isinstance(tok, Num):
            if not math.isfinite(tok) or tok != int(tok) or abs(tok) > _INT_MAX:
                raise ValueError(f"{col.label} must be an integer id below 2^31 or a set name, got {tok.text!r}")
            return int(tok)
        return str(tok).upper()
    if col.type == "face":
        up = str(tok).upper()
        if isinstance(tok, Num) or up not in ("S1", "S2", "S3", "S4"):
            raise ValueError(f"{col.label} must be S1, S2, S3 or S4, got {str(getattr(tok, 'text', tok))!r}")
        return int(up[1])
    if isinstance(tok, Num):                       # name
        raise ValueError(f"{col.label} must be a name, got the number {tok.text!r}")
    return str(tok).upper()


def _shape(data: Data) -> str:
    labels = [c.label + ("?" if c.optional else "") for c in data.cols]
    if data.repeat:
        labels.append("...")
    return ", ".join(labels)


def check_rows(data: Data, block: Block, problems: Problems) -> tuple[list[tuple[DataRow, list]], bool]:
    """Rows of converted values (the readable ones) and whether all were (problems reported)."""
    cols, nrep = data.cols, data.repeat
    nreq = sum(not c.optional for c in cols)
    out, ok = [], True
    for row in block.data:
        n = len(row.items)
        if n < nreq or (not nrep and n > len(cols)) or (nrep > 1 and (n - len(cols)) % nrep):
            want = (f"{nreq}" if nreq == len(cols) else f"{nreq} to {len(cols)}") if not nrep else \
                   f"at least {nreq}" + (f" (then groups of {nrep})" if nrep > 1 else "")
            problems.add(row.file, row.line, block.keyword,
                         f"wrong number of values: expected {want} ({_shape(data)}), got {n}")
            ok = False
            continue
        values, row_ok = [], True
        for k, tok in enumerate(row.items):
            col = cols[k] if k < len(cols) else cols[len(cols) - nrep + (k - len(cols)) % nrep]
            try:
                values.append(_convert_cell(col, tok))
            except ValueError as exc:
                problems.add(row.file, row.line, block.keyword, f"value {k + 1}: {exc}")
                row_ok = False
        if row_ok:
            out.append((row, values))
        ok &= row_ok
    return out, ok


def check_pairs(block: Block, problems: Problems) -> list[tuple[DataRow, Pair]] | None:
    """``KEY=VALUE`` items (each with its row); None after reporting non-pairs or repeats."""
    out, seen, ok = [], {}, True
    for row in block.data:
        for tok in row.items:
            if not isinstance(tok, Pair):
                problems.add(row.file, row.line, block.keyword,
                             f"expected KEY=VALUE pairs, got {getattr(tok, 'text', str(tok))!r}")
                ok = False
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
    """Returns (ok, converted): rows (list of (row, values): the readable rows even when not
    ok), pairs (list of (row, Pair), None when not ok) or the *HEADING text."""
    n = len(block.data)
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
        row = block.data[data.max_lines]
        problems.add(row.file, row.line, block.keyword,
                     f"expected {data.max_lines} data line{'s' * (data.max_lines > 1)} ({data.doc}), got {n}")
        return False, None
    if data.form == "pairs":
        conv = check_pairs(block, problems)
        return conv is not None, conv
    return check_rows(data, block, problems)[::-1]


# ---------------------------------------------------------------- reference

def _param_doc(p: P) -> str:
    if p.type == "flag":
        return f"`{p.name}`"
    if p.choices:
        kind = "/".join(map(str, p.choices))
    else:
        kind = {"name": "name", "text": "text", "int": "integer", "float": "number", "yesno": "YES/NO"}[p.type]
    default = {True: "YES", False: "NO"}.get(p.default, p.default) if p.type == "yesno" else p.default
    extra = "required" if p.required else (f"default {default}" if default is not None else "optional")
    extra += ", > 0" if p.positive else (f", >= {p.low:g}" if p.low is not None else "")
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
    return "\n".join(out)
