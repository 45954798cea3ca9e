"""CSV tables of the output contract: contact points, contact totals, reactions.

Numbers are written with ``repr`` (the shortest text that reads back to the same double), one
block of rows per increment, flushed before returning.

* ``contact.csv``: one row per contact Gauss point, on output increments (``write_fields``),
  unless the step's ``*OUTPUT, CONTACT=NO``; ``status`` as text (``open``, ``stick``,
  ``slip``, ``none``).
* ``contact_totals.csv``: one row per contact pair on every converged increment (cheap, and it
  makes the P(t), T(t) curves independent of the field-output frequency), same CONTACT=NO rule.
* ``reactions.csv``: one row per imposed-displacement target on every converged increment:
  RF1, RF2 and RM6 (the moment of a tool's reference node, 0 for other nodes).

Resuming a run (``append=True``, for ``lagamine-py run --restart``): the files are opened for
appending, and when the first increment arrives the rows at or after its (step, increment) --
written after the restart point by the interrupted run -- are dropped (:func:`trim_rows`).
"""
from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np

from ..core.status import STATUS_NAMES
from .base import IncrementResult, Writer

# DECKS.md's columns, then, appended so that older tables and their readers keep working:
# ``contact`` (the pair, as in contact_totals.csv: a deck with several contact pairs is read
# pair by pair), the signed slip, its increment over the increment and the dissipation D per
# unit area (ContactPoints.vp, dvp, dissip; their signs in ContactPoints).  ``gap`` follows
# COPEN (positive when open); results.COPEN_COLUMNS tells these tables from the older ones.
CONTACT_HEADER = ("step", "increment", "time", "element", "gauss", "x", "y",
                  "p", "tau", "gap", "slip", "lambda", "status", "contact",
                  "signed_slip", "slip_increment", "dissipation")
# the energy the pair has dissipated by friction since the start of the run (ContactPoints.E)
TOTALS_HEADER = ("step", "increment", "time", "contact", "P", "T", "dissipated_energy")
# RM6: the reaction moment of the rotation DOFs of the tools' reference nodes among the target's
# nodes (0 for other nodes), appended so that older readers keep working
REACTIONS_HEADER = ("step", "increment", "time", "nset", "RF1", "RF2", "RM6")


def fmt(values) -> np.ndarray:
    """Floats -> the shortest strings that read back to the same double (``repr``), element-wise."""
    a = np.asarray(values, float)
    return np.array(list(map(repr, a.ravel().tolist())), dtype=object).reshape(a.shape)


def trim_rows(path: Path, before: tuple[int, int]) -> None:
    """Keep the header and the rows of a CSV whose (step, increment) is below ``before``.

    A row with no readable increment (a failed attempt logged without one) counts as the last
    of its step.  A last line without its end (a row torn by a kill) is dropped whatever it
    holds, so that the resumed run does not glue its first row to it.  Rewritten atomically
    (tmp file + rename), and only when something is dropped.
    """
    with open(path, newline="") as fh:
        text = fh.read()
    torn = bool(text) and not text.endswith("\n")
    if torn:
        text = text[:text.rfind("\n") + 1]
    rows = list(csv.reader(io.StringIO(text.replace("\0", ""), newline="")))
    if not rows:
        if torn:
            _rewrite(path, [])
        return
    i_step, i_inc = rows[0].index("step"), rows[0].index("increment")

    def number(row, i):
        try:
            return float(row[i])
        except (ValueError, IndexError):
            return math.inf

    kept = rows[:1] + [r for r in rows[1:] if (number(r, i_step), number(r, i_inc)) < tuple(before)]
    if len(kept) == len(rows) and not torn:
        return
    _rewrite(path, kept)


def _rewrite(path: Path, rows: list) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as fh:
        csv.writer(fh, lineterminator="\n").writerows(rows)
    os.replace(tmp, path)


class CsvFiles:
    """CSV files opened together, written with ``csv.writer``, flushed together.

    ``append``: keep existing content (write the header only into new or empty files); call
    :meth:`resume_at` with the first (step, increment) of the resumed run to drop what the
    interrupted run wrote at or after it.
    """

    def __init__(self, outdir: Path, files: dict[str, tuple[str, tuple[str, ...]]], append: bool = False):
        outdir.mkdir(parents=True, exist_ok=True)
        self.paths = {attr: outdir / name for attr, (name, _) in files.items()}
        self.handles, self.writers = {}, {}
        self.pending_trim = append
        for attr, (name, header) in files.items():
            self._open(attr, "a" if append else "w", header)
        self.flush()

    def _open(self, attr: str, mode: str, header=()) -> None:
        path = self.paths[attr]
        fresh = mode == "w" or not path.exists() or path.stat().st_size == 0
        fh = open(path, mode, newline="")
        self.handles[attr] = fh
        self.writers[attr] = csv.writer(fh, lineterminator="\n")
        if fresh and header:
            self.writers[attr].writerow(header)

    def resume_at(self, step: int, increment: int) -> None:
        """Once, in append mode: drop rows at or after (step, increment) in every file."""
        if not self.pending_trim:
            return
        self.pending_trim = False
        for attr, fh in self.handles.items():
            fh.close()
            trim_rows(self.paths[attr], (int(step), int(increment)))
            self._open(attr, "a")

    def flush(self) -> None:
        for fh in self.handles.values():
            fh.flush()

    def close(self) -> None:
        for fh in self.handles.values():
            fh.close()
        self.handles = {}


class _CsvWriter(Writer):
    """Opens ``files`` = {attribute: (file name, header)} at start_run, closes them at close;
    ``append``: resume into existing files (see the module doc)."""

    files: dict[str, tuple[str, tuple[str, ...]]] = {}
    _csv: CsvFiles | None = None

    def start_run(self) -> None:
        self._csv = CsvFiles(self.outdir, self.files, self.append)
        for attr, out in self._csv.writers.items():
            setattr(self, attr, out)

    def _begin(self, result: IncrementResult) -> None:
        """Before writing an increment: settle a resumed run's files."""
        if self._csv.pending_trim:
            self._csv.resume_at(result.step, result.increment)
            for attr, out in self._csv.writers.items():
                setattr(self, attr, out)

    def _flush(self) -> None:
        self._csv.flush()

    def close(self, status: int, message: str) -> None:
        if self._csv is not None:
            self._csv.close()


class ContactWriter(_CsvWriter):
    """contact.csv (per contact Gauss point) and contact_totals.csv (per contact pair)."""

    files = {"_points": ("contact.csv", CONTACT_HEADER), "_totals": ("contact_totals.csv", TOTALS_HEADER)}

    def start_run(self) -> None:
        super().start_run()
        self.enabled = True

    def start_step(self, step_number: int, step) -> None:
        self.enabled = bool(step.output.contact)

    def increment(self, result: IncrementResult) -> None:
        self._begin(result)
        if not self.enabled or not result.contacts:
            return
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        plain = all(_plain(cp.name) for cp in result.contacts)
        if result.write_fields:
            if plain:
                lead = ",".join(head) + ","
                self._csv.handles["_points"].write("".join(
                    point_lines(lead, cp) for cp in result.contacts))
            else:
                self._points.writerows(row for cp in result.contacts for row in point_rows(head, cp))
        self._totals.writerows(head + [cp.name, *fmt([cp.P, cp.T, cp.E])] for cp in result.contacts)
        self._flush()


def _plain(text: str) -> bool:
    """``text`` is a field ``csv.writer`` writes as it is (QUOTE_MINIMAL: no delimiter, quote
    or line break in it, and not empty)."""
    return bool(text) and not any(c in text for c in ',"\r\n')


def _point_columns(cp):
    """The columns of contact.csv for one pair, as lists of texts per point: ids (element,
    gauss), numbers (x, y, p, tau, gap, slip, lambda), status, and the appended ones."""
    x = np.asarray(cp.x, float).reshape(-1, 2)
    numbers = fmt(np.column_stack([x, cp.p, cp.tau, cp.gap, cp.slip, cp.lam]))
    more = fmt(np.column_stack([cp.vp, cp.dvp, cp.dissip]))
    status = np.asarray(STATUS_NAMES, dtype=object)[np.asarray(cp.status, int)]
    ids = np.column_stack([np.asarray(cp.element, int), np.asarray(cp.gauss, int)]).astype(str)
    return ids.tolist(), numbers.tolist(), status.tolist(), more.tolist()


def point_rows(head: list[str], cp) -> list[list[str]]:
    """Rows of contact.csv for one contact pair: ``head`` (step, increment, time) + point values."""
    ids, numbers, status, more = _point_columns(cp)
    return [head + [*i, *v, s, cp.name, *m] for i, v, s, m in zip(ids, numbers, status, more)]


def point_lines(lead: str, cp) -> str:
    """The text of :func:`point_rows` as ``csv.writer`` writes it when no field needs quotes
    (numbers by ``repr``, status names, and a pair name that :func:`_plain` accepts): each
    row joined by commas, without the writer's per-field quoting checks (a third of the
    main job's contact tables)."""
    ids, numbers, status, more = _point_columns(cp)
    tail = f",{cp.name},"
    return "".join(f"{lead}{','.join(i)},{','.join(v)},{s}{tail}{','.join(m)}\n"
                   for i, v, s, m in zip(ids, numbers, status, more))


class ReactionsWriter(_CsvWriter):
    """reactions.csv: summed reaction force per imposed-displacement target, every increment."""

    files = {"_rows": ("reactions.csv", REACTIONS_HEADER)}

    def increment(self, result: IncrementResult) -> None:
        self._begin(result)
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        self._rows.writerows(head + [name, *fmt(_rf3(rf))]
                             for name, rf in result.reactions_by_set.items())
        self._flush()


def _rf3(rf) -> np.ndarray:
    """(RF1, RF2, RM6) of a target's summed reactions (RM6 0 when not given)."""
    a = np.asarray(rf, float).ravel()[:3]
    return np.concatenate([a, np.zeros(3 - a.size)])
