"""The check contract, and the evaluation of a deck's ``*CHECK`` requests on a run.

A deck declares ``*CHECK, NAME=..., TYPE=...`` with ``KEY=VALUE`` data; the deck builder looks
``TYPE`` up in the registry (kind ``checks``), validates the data against the plugin's declared
``params`` and builds it once (so ``check`` refuses what ``run`` would), and keeps the request in
``Model.checks`` as a dict (``name``, ``type``, ``params``, ``where``).  A check computes its
error measures from the run's output files only (the output contract of DECKS.md, read back with
:mod:`lagamine_py.results`), so it works on a finished run, an archived reference or a sweep
point alike.

The helpers below read the tables as checks need them; plugin authors may use them.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import registry
from ..core.outdir import OutputDirError
from ..core.plugin import Parametrized
from ..results import RunResults

__all__ = ["Check", "CheckError", "evaluate_checks", "evaluate_check", "check_columns", "table",
           "rows", "last_increment", "one_contact", "contact_points", "rel", "result"]


class CheckError(Exception):
    """A check cannot be evaluated from the files at hand (the message says why)."""


class Check(Parametrized):
    """Base of check plugins: one ``*CHECK, TYPE=<name>`` of a deck.

    Built as ``Check(**values)`` from the ``*CHECK`` data (validated against ``params``).
    :meth:`evaluate` reads a run's output directory and returns a dict with ``measured`` and
    ``closed_form`` values (same keys where they compare), the relative ``errors`` per quantity
    and the headline ``error`` (:func:`result` builds it); it raises :class:`CheckError` when
    the files at hand cannot answer (the report then says why, with error NaN).
    ``example_values()`` (:class:`~lagamine_py.core.plugin.Parametrized`) gives the values the
    contract checks build it from.
    """

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def contract_problem(cls) -> str:
        return "" if cls.evaluate is not Check.evaluate else "it does not implement evaluate()"


def evaluate_checks(model_checks: list[dict[str, Any]], outdir: Path) -> list[dict[str, Any]]:
    """Evaluate every ``*CHECK`` of a model on the output directory ``outdir``.

    Returns one dict per check: ``name``, ``type``, ``error`` (headline relative error, NaN when
    it cannot be evaluated), ``measured``, ``closed_form``, ``errors`` (per quantity) and
    ``message`` ("" when all went well).  Never raises for a check that cannot be evaluated.
    """
    run = RunResults(Path(outdir))
    out = []
    for chk in model_checks:
        name, kind = str(chk.get("name", "")), str(chk.get("type", "")).upper()
        try:
            check = registry.get("checks", kind)(**dict(chk.get("params", {})))
        except (KeyError, registry.ParamError) as exc:
            entry = _entry(name, kind)
            entry["message"] = str(exc.args[0]) if exc.args else type(exc).__name__
            out.append(entry)
            continue
        out.append(evaluate_check(check, run, name, kind))
    return out


def evaluate_check(check: Check, run: RunResults, name: str = "", kind: str = "") -> dict[str, Any]:
    """One built check's entry of :func:`evaluate_checks` (same keys); a check that cannot be
    evaluated gets ``error`` NaN and the ``message``, it does not raise."""
    entry = _entry(name, kind)
    try:
        entry.update(check.evaluate(run))
    except (CheckError, KeyError, registry.ParamError, OutputDirError) as exc:
        entry["message"] = str(exc.args[0]) if exc.args else type(exc).__name__
    except (OSError, IndexError, ValueError, ZeroDivisionError) as exc:
        entry["message"] = f"{type(exc).__name__}: {exc}"
    return entry


def _entry(name: str, kind: str) -> dict[str, Any]:
    return {"name": name or kind, "type": kind, "error": math.nan, "measured": {},
            "closed_form": {}, "errors": {}, "message": ""}


def check_columns(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Flat columns for a table row (the sweep): ``<name>_error``, ``<name>_<qty>`` (measured),
    ``<name>_<qty>_cf`` (closed form) and ``<name>_message`` when there is one."""
    row: dict[str, Any] = {}
    for r in results:
        n = r["name"]
        row[f"{n}_error"] = r["error"]
        for k, v in r.get("measured", {}).items():
            row[f"{n}_{k}"] = v
        for k, v in r.get("closed_form", {}).items():
            row[f"{n}_{k}_cf"] = v
        if r.get("message"):
            row[f"{n}_message"] = r["message"]
    return row


# ---------------------------------------------------------------- reading the tables

def table(run: RunResults, name: str, columns: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The table ``name`` of the run, which must exist, have rows and ``columns``."""
    tab = run.table(name)
    if not tab or len(tab.get("step", ())) == 0:
        raise CheckError(f"{name} is missing or empty in {run.outdir}")
    missing = [c for c in columns if c not in tab]
    if missing:
        raise CheckError(f"{name} has no column {', '.join(missing)}")
    return tab


def rows(tab: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    """The rows of ``tab`` where ``mask``."""
    return {k: v[mask] for k, v in tab.items()}


def last_increment(tab: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Rows of the last (step, increment) written (tables are written in time order)."""
    mask = (tab["step"] == tab["step"][-1]) & (tab["increment"] == tab["increment"][-1])
    return rows(tab, mask)


def one_contact(tab: dict[str, np.ndarray], contact: str | None,
                name: str = "contact_totals.csv") -> dict[str, np.ndarray]:
    """Rows of contact pair ``contact`` if given, else of the first pair in the table.  The pair
    is named ``SURFACE->FOUNDATION`` in the tables; ``CONTACT=`` may give the surface alone (a
    deck's data line cannot hold ``->``), which must then name one pair."""
    names = np.array([str(n).upper() for n in tab["contact"]])
    want = str(contact if contact is not None else names[0]).upper()
    mask = names == want
    if not mask.any():
        mask = np.array([n.split("->")[0] == want for n in names])
        pairs = sorted(set(names[mask]))
        if len(pairs) > 1:
            raise CheckError(f"CONTACT={want} names {len(pairs)} contact pairs in {name}: "
                             f"{', '.join(pairs)}")
    if not mask.any():
        raise CheckError(f"{name} has no contact {want!r}")
    return rows(tab, mask)


def contact_points(run: RunResults, columns: tuple[str, ...], contact: str | None) -> dict[str, np.ndarray]:
    """contact.csv rows of one contact pair (``contact``, else the first), when the table names
    its pairs; every row of a table written before it had the ``contact`` column."""
    tab = table(run, "contact.csv", columns)
    return one_contact(tab, contact, "contact.csv") if "contact" in tab else tab


def rel(measured: float, exact: float) -> float:
    """``|measured - exact| / |exact|`` (inf when exact is 0)."""
    return abs(measured - exact) / abs(exact) if exact != 0 else math.inf


def result(measured: dict, closed: dict, errors: dict, error: float | None = None) -> dict:
    """What :meth:`Check.evaluate` returns; the headline error defaults to the largest."""
    head = max(errors.values()) if error is None else error
    return {"measured": measured, "closed_form": closed, "errors": errors, "error": float(head)}
