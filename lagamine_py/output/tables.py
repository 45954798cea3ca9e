"""CSV tables of the output contract: contact points, contact totals, reactions.

Numbers are written with ``%.17g`` (they read back to the same double), one block of rows per
increment, flushed before returning.

* ``contact.csv``: one row per contact Gauss point, on output increments (``write_fields``),
  unless the step's ``*OUTPUT, CONTACT=NO``.
* ``contact_totals.csv``: one row per contact pair on every converged increment (cheap, and it
  makes the P(t), T(t) curves independent of the field-output frequency), same CONTACT=NO rule.
* ``reactions.csv``: one row per imposed-displacement target on every converged increment.
"""
from __future__ import annotations

import csv

import numpy as np

from ..laws.base import STATUS_NAMES
from ..registry import register
from .base import IncrementResult, Writer

CONTACT_HEADER = ("step", "increment", "time", "element", "gauss", "x", "y",
                  "p", "tau", "gap", "slip", "lambda", "status")
TOTALS_HEADER = ("step", "increment", "time", "contact", "P", "T")
REACTIONS_HEADER = ("step", "increment", "time", "nset", "RF1", "RF2")


def fmt(values) -> np.ndarray:
    """Floats -> strings that read back exactly (``%.17g``), element-wise."""
    return np.char.mod("%.17g", np.asarray(values, float))


class _CsvWriter(Writer):
    """Opens ``files`` = {attribute: (file name, header)} at start_run, closes them at close."""

    files: dict[str, tuple[str, tuple[str, ...]]] = {}

    def start_run(self) -> None:
        self.outdir.mkdir(parents=True, exist_ok=True)
        self._handles = []
        for attr, (name, header) in self.files.items():
            fh = open(self.outdir / name, "w", newline="")
            out = csv.writer(fh, lineterminator="\n")
            out.writerow(header)
            fh.flush()
            self._handles.append(fh)
            setattr(self, attr, out)
        self._flush()

    def _flush(self) -> None:
        for fh in self._handles:
            fh.flush()

    def close(self, status: int, message: str) -> None:
        for fh in getattr(self, "_handles", ()):
            fh.close()
        self._handles = []


@register("writers", "CONTACT")
class ContactWriter(_CsvWriter):
    """contact.csv (per contact Gauss point) and contact_totals.csv (per contact pair)."""

    params = ()
    files = {"_points": ("contact.csv", CONTACT_HEADER), "_totals": ("contact_totals.csv", TOTALS_HEADER)}

    def start_run(self) -> None:
        super().start_run()
        self.enabled = True

    def start_step(self, step_number: int, step) -> None:
        output = getattr(step, "output", None)
        self.enabled = bool(getattr(output, "contact", True))

    def increment(self, result: IncrementResult) -> None:
        if not self.enabled or not result.contacts:
            return
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        if result.write_fields:
            self._points.writerows(row for cp in result.contacts for row in point_rows(head, cp))
        self._totals.writerows(head + [cp.name, *fmt([cp.P, cp.T])] for cp in result.contacts)
        self._flush()


def point_rows(head: list[str], cp) -> list[list[str]]:
    """Rows of contact.csv for one contact pair: ``head`` (step, increment, time) + point values."""
    x = np.asarray(cp.x, float).reshape(-1, 2)
    numbers = fmt(np.column_stack([x, cp.p, cp.tau, cp.gap, cp.slip, cp.lam]))
    status = np.asarray(STATUS_NAMES, dtype=object)[np.asarray(cp.status, int)]
    ids = np.column_stack([np.asarray(cp.element, int), np.asarray(cp.gauss, int)]).astype(str)
    return [head + [*i, *v, s] for i, v, s in zip(ids.tolist(), numbers.tolist(), status)]


@register("writers", "REACTIONS")
class ReactionsWriter(_CsvWriter):
    """reactions.csv: summed reaction force per imposed-displacement target, every increment."""

    params = ()
    files = {"_rows": ("reactions.csv", REACTIONS_HEADER)}

    def increment(self, result: IncrementResult) -> None:
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        self._rows.writerows(head + [name, *fmt(np.asarray(rf, float).ravel()[:2])]
                             for name, rf in result.reactions_by_set.items())
        self._flush()
