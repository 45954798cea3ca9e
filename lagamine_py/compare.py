"""``lagamine-py compare RUN REF``: check a run against an archived reference.

What is compared (the text tables of the output contract, present in both directories):

==========================  ====================================  ==========================
file                        row key                               quantities
==========================  ====================================  ==========================
contact.csv                 step, increment, element, gauss       p, tau, gap, slip, lambda, status
                                                                  (signed_slip, slip_increment,
                                                                  dissipation)
contact_totals.csv          step, increment, contact              P, T (dissipated_energy)
reactions.csv               step, increment, nset                 RF1, RF2
displacements.csv           step, node                            u1, u2
==========================  ====================================  ==========================

Quantities in parentheses are compared when both tables have them (older tables do not).
``gap`` is compared in the COPEN convention (positive when open): a contact.csv written before
it (without the ``signed_slip`` column, :data:`lagamine_py.results.COPEN_COLUMNS`) had
``gap`` positive for penetration and NaN where the normal missed the foundation, with status
``open``; it is read as ``-gap`` and, where the gap is NaN, status ``none``.  The gap of a
``none`` point (a distance to the foundation in newer tables, NaN in older ones) is not
compared; its status is.

A value passes when ``|run - ref| <= max(rel * |ref|, abs)``; ``abs`` defaults to ``rel`` times the
largest magnitude of that quantity in the reference (an absolute floor near zero, as MOOSE's csvdiff
does).  When the two runs did not take the same increments, run values are interpolated linearly in
time within each step onto the reference times, and the report says so.  Exit status 0 when every
quantity is within tolerance, 1 otherwise (also when files, steps or points do not match), 2 for
a malformed ``--tol``.

Neither file is trusted: a table that is cut short, has torn rows (a cell count other than the
header's), text or NUL bytes where numbers belong, NaN in a key column (step, increment,
element ...), or rows that repeat (the same row twice, or an increment with more rows for a
point than the step's other increments) is reported as a mismatch, with its line, and is not
compared.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .core.exits import EXIT_DECK, EXIT_OK, EXIT_OTHER
from .results import COPEN_COLUMNS, copen_gap, read_table

# quantity -> (relative tolerance, absolute floor or None for rel * max|ref|)
DEFAULT_TOL: dict[str, tuple[float, float | None]] = {
    "p": (1e-6, None), "tau": (1e-6, None), "gap": (1e-6, None), "slip": (1e-6, None),
    "lambda": (1e-6, None), "signed_slip": (1e-6, None), "slip_increment": (1e-6, None),
    "dissipation": (1e-6, None), "P": (1e-6, None), "T": (1e-6, None),
    "dissipated_energy": (1e-6, None),
    "RF1": (1e-6, None), "RF2": (1e-6, None), "u1": (1e-6, None), "u2": (1e-6, None),
}

#: (file, row key, quantities, text column, quantities compared when both tables have them)
TABLES = (
    ("contact.csv", ("element", "gauss"), ("p", "tau", "gap", "slip", "lambda"), "status",
     ("signed_slip", "slip_increment", "dissipation")),
    ("contact_totals.csv", ("contact",), ("P", "T"), None, ("dissipated_energy",)),
    ("reactions.csv", ("nset",), ("RF1", "RF2"), None, ()),
    ("displacements.csv", ("node",), ("u1", "u2"), None, ()),
)

#: components of one vector share one scale: the floor of the allowed difference is relative to
#: the vector's size, not to a component that is round-off everywhere (a reaction RF1 ~ 1e-14
#: beside RF2 ~ 1e3 would otherwise allow 1e-20); the slips share the scale of the largest
#: (an increment of slip is judged against the slip the run produces)
FAMILIES = (("p", "tau"), ("P", "T"), ("RF1", "RF2"), ("u1", "u2"),
            ("slip", "lambda", "signed_slip", "slip_increment"))
#: forces of different tables share the run's force scale too (reactions at a symmetry axis are
#: round-off beside the contact force)
FORCES = ("P", "T", "RF1", "RF2")


@dataclass
class Finding:
    quantity: str
    table: str
    worst: float = 0.0            # worst |diff| / allowed (<= 1 passes)
    diff: float = 0.0
    allowed: float = 0.0
    where: str = ""


@dataclass
class Report:
    findings: list[Finding] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems and all(f.worst <= 1.0 for f in self.findings)

    def text(self) -> str:
        lines = []
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"MISMATCH: {p}" for p in self.problems]
        if self.findings:
            lines.append(f"{'quantity':<10} {'table':<20} {'max |diff|':>12} {'allowed':>12} {'ratio':>8}  where")
            for f in sorted(self.findings, key=lambda f: -f.worst):
                flag = "" if f.worst <= 1.0 else "  FAIL"
                lines.append(f"{f.quantity:<10} {f.table:<20} {f.diff:12.4e} {f.allowed:12.4e} "
                             f"{f.worst:8.3g}  {f.where}{flag}")
        lines.append("PASS: within tolerance" if self.ok else "FAIL: outside tolerance")
        return "\n".join(lines)


def parse_tolerances(items: list[str]) -> dict[str, tuple[float, float | None]]:
    """``["p=1e-4,1e-2", "u1=1e-5"]`` -> overrides of DEFAULT_TOL; ``all=`` sets every quantity."""
    tol = dict(DEFAULT_TOL)
    for item in items:
        name, _, value = item.partition("=")
        parts = [v for v in value.split(",") if v.strip()]
        if not name or not parts or len(parts) > 2:
            raise ValueError(f"--tol {item!r}: expected QTY=REL[,ABS]")
        try:
            rel = float(parts[0])
            ab = float(parts[1]) if len(parts) == 2 else None
        except ValueError:
            raise ValueError(f"--tol {item!r}: expected QTY=REL[,ABS] with numbers") from None
        if not all(np.isfinite(v) and v >= 0 for v in (rel, 0.0 if ab is None else ab)):
            raise ValueError(f"--tol {item!r}: tolerances must be finite and >= 0")
        keys = list(tol) if name.strip().lower() == "all" else [name.strip()]
        for k in keys:
            if k not in tol:
                raise ValueError(f"--tol {item!r}: unknown quantity {k}; known: {', '.join(DEFAULT_TOL)}")
            tol[k] = (rel, ab)
    return tol


def compare_dirs(run: Path, ref: Path, tol=None) -> Report:
    tol = tol or DEFAULT_TOL
    rep = Report()
    tables = []
    for fname, key_cols, qtys, text_col, optional in TABLES:
        ref_path, run_path = Path(ref) / fname, Path(run) / fname
        if not ref_path.exists():
            continue
        if not run_path.exists():
            rep.problems.append(f"{fname} is in the reference but not in the run")
            continue
        run_t = _checked(run_path, "run", key_cols, rep)
        ref_t = _checked(ref_path, "reference", key_cols, rep)
        if run_t is None or ref_t is None:
            continue
        if fname == "contact.csv":
            run_t, ref_t = copen_view(run_t), copen_view(ref_t)
        qtys = tuple(qtys) + tuple(q for q in optional if q in run_t and q in ref_t)
        tables.append((fname, run_t, ref_t, key_cols, qtys, text_col))
    force = max((float(np.max(np.abs(t[2][q]))) for t in tables for q in t[4]
                 if q in FORCES and q in t[2] and len(t[2][q])), default=0.0)
    for fname, run_t, ref_t, key_cols, qtys, text_col in tables:
        _compare_table(fname, run_t, ref_t, key_cols, qtys, text_col, tol, rep, force)
    if not any((Path(ref) / t[0]).exists() for t in TABLES):
        rep.problems.append(f"{ref} holds none of the compared tables")
    return rep


MAX_FILE_PROBLEMS = 5      # problems listed per malformed file, then a count

#: key columns of every compared table, besides the table's own row key
_KEYS = ("step", "increment")


def _checked(path: Path, which: str, key_cols, rep: Report) -> dict[str, np.ndarray] | None:
    """The table at ``path``, or None (and its problems in ``rep``) when it cannot be trusted:
    see the module docstring."""
    problems: list[str] = []
    try:
        table = read_table(path, problems)
    except OSError as exc:
        problems.append(f"cannot be read: {exc.strerror or exc}")
        table = {}
    if not problems:
        if not table or "step" not in table:
            problems.append("has no header row with a step column")
        else:
            problems += _key_problems(table, key_cols) + _repeats(table, key_cols)
    if not problems:
        return table
    shown = problems[:MAX_FILE_PROBLEMS]
    more = f" (and {len(problems) - len(shown)} more)" if len(problems) > len(shown) else ""
    rep.problems.append(f"{path.name} of the {which} cannot be compared: {'; '.join(shown)}{more}")
    return None


def _key_problems(table, key_cols) -> list[str]:
    """Key cells that are not finite numbers (NaN, inf; text is caught when reading)."""
    out = []
    for c in _KEYS + tuple(key_cols):
        col = table.get(c)
        if col is None or col.dtype == object:
            continue
        bad = np.flatnonzero(~np.isfinite(col))
        if len(bad):
            out.append(f"line {bad[0] + 2}: key column {c} is {float(col[bad[0]])}"
                       + (f" ({len(bad)} such rows)" if len(bad) > 1 else ""))
    return out


def _repeats(table, key_cols) -> list[str]:
    """Rows that repeat: identical rows, or an increment with more rows for a point (step, key)
    than the other increments of its step have."""
    cols = [c for c in table if len(table[c]) == len(table["step"])]
    n = len(table["step"])
    seen: dict[tuple, int] = {}
    for i in range(n):
        row = tuple(_norm_cell(table[c][i]) for c in cols)
        if row in seen:
            return [f"line {i + 2} repeats line {seen[row] + 2} (an increment written twice?)"]
        seen[row] = i
    keys = [c for c in key_cols if c in table]
    if "increment" not in table:
        return []
    count: dict[tuple, dict] = {}
    for i in range(n):
        point = (table["step"][i],) + tuple(_norm_cell(table[c][i]) for c in keys)
        per = count.setdefault(point, {})
        inc = table["increment"][i]
        per[inc] = per.get(inc, 0) + 1
    for point, per in count.items():
        if len(set(per.values())) > 1:
            usual = min(per.values())
            inc = max(per, key=per.get)
            return [f"step {int(point[0])} increment {int(inc)} has {per[inc]} rows for "
                    f"{dict(zip(keys, point[1:]))}, the step's other increments {usual}: rows "
                    f"repeat"]
    return []


def _norm_cell(v):
    return v.upper() if isinstance(v, str) else (None if v != v else float(v))


def copen_view(table: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A contact.csv table as newer tables write it: ``gap`` in the COPEN convention
    (:func:`~lagamine_py.results.copen_gap`), status ``none`` where an older table has a NaN
    gap (the normal missed the foundation), and NaN as the gap of ``none`` points (not
    compared: see the module docstring)."""
    if "gap" not in table or "status" not in table:
        return table
    out = dict(table)
    gap = copen_gap(table)
    status = np.asarray(table["status"], dtype=object).copy()
    if COPEN_COLUMNS[0] not in table:
        status[np.isnan(gap)] = "none"
    out["gap"] = np.where(status == "none", np.nan, gap)
    out["status"] = status
    return out


def _series(table, key_cols):
    """Group rows by (step, key...) -> list of row indices ordered by time."""
    groups: dict[tuple, list[int]] = {}
    steps = table["step"].astype(int)
    keys = [table[c] for c in key_cols]
    for i in range(len(steps)):
        k = (int(steps[i]),) + tuple(_norm(col[i]) for col in keys)
        groups.setdefault(k, []).append(i)
    return groups


def _norm(v):
    if isinstance(v, str):
        return v.upper()
    return int(v) if float(v) == int(v) else float(v)


def _finite_scale(values: np.ndarray) -> float:
    """Largest |value| of a column over its finite entries (0 when none): a gap is NaN where a
    contact point has no partner, and a NaN scale would allow no difference at all."""
    v = np.abs(np.asarray(values, float))
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else 0.0


def _compare_table(fname, run, ref, key_cols, qtys, text_col, tol, rep, force=0.0):
    for c in ("step",) + tuple(key_cols) + tuple(qtys):
        if c not in ref:
            rep.problems.append(f"{fname}: reference has no column {c}")
            return
        if c not in run:
            rep.problems.append(f"{fname}: run has no column {c}")
            return
    if "contact" in run and "contact" in ref and "contact" not in key_cols:
        key_cols = tuple(key_cols) + ("contact",)      # contact.csv names its pairs (both files)
    g_run, g_ref = _series(run, key_cols), _series(ref, key_cols)
    steps_ref = sorted({k[0] for k in g_ref})
    steps_run = sorted({k[0] for k in g_run})
    if steps_ref != steps_run:
        rep.problems.append(f"{fname}: the run has steps {steps_run}, the reference {steps_ref}")
    missing = [k for k in g_ref if k not in g_run and k[0] in steps_run]
    extra = [k for k in g_run if k not in g_ref and k[0] in steps_ref]
    if missing:
        rep.problems.append(f"{fname}: {len(missing)} reference points absent from the run, e.g. "
                            f"step {missing[0][0]} {dict(zip(key_cols, missing[0][1:]))}")
    if extra:
        rep.problems.append(f"{fname}: {len(extra)} run points absent from the reference, e.g. "
                            f"step {extra[0][0]} {dict(zip(key_cols, extra[0][1:]))}")
    has_time = "time" in ref and "time" in run
    interpolated = False
    findings = {q: Finding(q, fname) for q in qtys}
    scale = {q: _finite_scale(ref[q]) for q in qtys}
    for family in FAMILIES:
        shared = max((scale[q] for q in family if q in scale), default=0.0)
        scale.update({q: shared for q in family if q in scale})
    scale.update({q: max(scale[q], force) for q in qtys if q in FORCES})
    for key, rows_ref in g_ref.items():
        rows_run = g_run.get(key)
        if rows_run is None:
            continue
        same = len(rows_run) == len(rows_ref) and (not has_time or np.allclose(
            run["time"][rows_run], ref["time"][rows_ref], rtol=1e-12, atol=1e-14))
        if not same:
            if not has_time or len(rows_run) < 1:
                rep.problems.append(f"{fname}: step {key[0]} has {len(rows_run)} rows in the run and "
                                    f"{len(rows_ref)} in the reference, and no time to interpolate")
                continue
            interpolated = True
        for q in qtys:
            r_ref = ref[q][rows_ref].astype(float)
            if same:
                r_run = run[q][rows_run].astype(float)
            else:
                r_run = np.interp(ref["time"][rows_ref], run["time"][rows_run],
                                  run[q][rows_run].astype(float))
            rel, ab = tol.get(q, (1e-6, None))
            floor = ab if ab is not None else rel * scale[q]
            allowed = np.maximum(rel * np.abs(r_ref), floor)
            diff = np.abs(r_run - r_ref)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(allowed > 0, diff / allowed, np.where(diff > 0, np.inf, 0.0))
            ratio = np.where(np.isnan(r_run) != np.isnan(r_ref), np.inf, np.nan_to_num(ratio))
            k = int(np.argmax(ratio))
            if ratio[k] > findings[q].worst or not findings[q].where:
                inc = int(ref["increment"][rows_ref][k]) if "increment" in ref else None
                where = f"step {key[0]}" + (f", increment {inc}" if inc is not None else "") + \
                        "".join(f", {c} {v}" for c, v in zip(key_cols, key[1:]))
                findings[q] = Finding(q, fname, float(ratio[k]), float(diff[k]), float(allowed[k]), where)
        if text_col and same and text_col in ref and text_col in run:
            bad = np.nonzero(run[text_col][rows_run] != ref[text_col][rows_ref])[0]
            if len(bad):
                i = rows_ref[bad[0]]
                rep.problems.append(f"{fname}: {text_col} differs at step {key[0]}, increment "
                                    f"{int(ref['increment'][i])}, " + ", ".join(
                                        f"{c} {v}" for c, v in zip(key_cols, key[1:]))
                                    + f": run {run[text_col][rows_run[bad[0]]]}, reference {ref[text_col][i]}")
    if interpolated:
        rep.notes.append(f"{fname}: the run and the reference took different increments; run values "
                         f"were interpolated linearly in time onto the reference increments")
    rep.findings.extend(findings.values())


def compare_main(run: Path, ref: Path, tol_items: list[str]) -> int:
    try:
        tol = parse_tolerances(tol_items)
    except ValueError as exc:
        print(f"lagamine-py compare: {exc}", file=sys.stderr)
        return EXIT_DECK
    for d in (run, ref):
        if not Path(d).is_dir():
            print(f"lagamine-py compare: {d} is not a directory", file=sys.stderr)
            return EXIT_OTHER
    rep = compare_dirs(run, ref, tol)
    print(rep.text())
    return EXIT_OK if rep.ok else EXIT_OTHER
