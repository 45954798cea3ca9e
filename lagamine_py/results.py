"""Read a run's output directory back: tables as column arrays, VTU fields as NumPy arrays.

Used by ``compare``, ``plot``, the sweep and the tests; it reads only what the output contract
(DECKS.md) promises, so it works on archived references as well as on fresh runs.
"""
from __future__ import annotations

import csv
import io
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .core.outdir import run_name

TEXT_COLUMNS = {"status", "nset", "contact", "step_name", "failed", "reason", "load", "foundation",
                "ref_node"}

#: contact.csv columns that came with the COPEN sign of ``gap`` (positive when open): a table
#: without them was written with ``gap`` positive for penetration
COPEN_COLUMNS = ("signed_slip", "slip_increment", "dissipation")


def copen_gap(table: dict[str, np.ndarray]) -> np.ndarray:
    """The ``gap`` column of a contact.csv table in the COPEN convention (positive when open,
    minus the penetration in contact), whichever convention it was written in: a table without
    the :data:`COPEN_COLUMNS` was written before the COPEN sign (the archived references of
    ``decks/reference`` among them), with ``gap`` positive for penetration, and is negated."""
    gap = np.asarray(table["gap"], float)
    return gap if COPEN_COLUMNS[0] in table else -gap


def read_table(path: Path, problems: list[str] | None = None) -> dict[str, np.ndarray]:
    """A CSV with a header row -> {column: array}; numeric columns as float (int for ids).

    ``problems``: a list to collect what is wrong with the file, line by line (NUL bytes, a
    last line cut short, rows whose cell count differs from the header's, text or an empty
    cell in a numeric column, which then reads as NaN) -- a reader that must not trust the
    file (``compare``).  Without it, the file is read as best it can: NUL bytes dropped, short
    rows padded, a column holding text kept as text."""
    raw = Path(path).read_bytes()
    text = raw.decode("utf-8", errors="replace")
    note = problems.append if problems is not None else (lambda _msg: None)
    if "\0" in text:
        note(f"NUL bytes at line {text.count(chr(10), 0, text.index(chr(0))) + 1}")
        text = text.replace("\0", "")
    if text and not text.endswith("\n"):
        note(f"the file ends in the middle of line {text.count(chr(10)) + 1} (cut short)")
    rows = list(csv.reader(io.StringIO(text, newline="")))
    if not rows:
        return {}
    header, body = rows[0], rows[1:]
    for i, r in enumerate(body):
        if len(r) != len(header):
            note(f"line {i + 2} has {len(r)} cells where the header has {len(header)} "
                 f"(a torn or cut row)")
    cols = {}
    for k, name in enumerate(header):
        values = [r[k] if k < len(r) else "" for r in body]
        if name in TEXT_COLUMNS:
            cols[name] = np.array(values, dtype=object)
            continue
        try:
            cols[name] = np.array([float(v) for v in values])
        except ValueError:
            if problems is None:
                cols[name] = np.array(values, dtype=object)
                continue
            numbers = np.full(len(values), np.nan)
            for i, v in enumerate(values):
                try:
                    numbers[i] = float(v)
                except ValueError:
                    note(f"line {i + 2}, column {name}: {v!r} is not a number")
            cols[name] = numbers
    return cols


def read_vtu(path: Path) -> dict[str, np.ndarray]:
    """Points, cells and every point/cell array of a VTU file."""
    # the vtkmodules sub-packages load in a fraction of the time of the whole vtk package
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    out = {"points": vtk_to_numpy(grid.GetPoints().GetData()).copy() if grid.GetPoints() else np.zeros((0, 3))}
    for kind, data in (("point", grid.GetPointData()), ("cell", grid.GetCellData())):
        for k in range(data.GetNumberOfArrays()):
            arr = data.GetArray(k)
            if arr is not None:
                out[f"{kind}:{arr.GetName()}"] = vtk_to_numpy(arr).copy()
    return out


@dataclass
class RunResults:
    """The files of the run in ``outdir``.  The deck-named ones (``<deck>.sta``, ``<deck>.pvd``)
    are those of the deck the directory's record names (:func:`lagamine_py.core.outdir.run_name`),
    never "the first that sorts": a directory holding the files of several decks and no record
    raises :class:`~lagamine_py.core.outdir.ResultsOfAnotherDeck`."""
    outdir: Path

    def __post_init__(self):
        self.outdir = Path(self.outdir)

    @property
    def name(self) -> str | None:
        """The deck name of the run (None when the directory holds no run)."""
        return run_name(self.outdir)

    def own(self, suffix: str) -> Path | None:
        """``OUT/<deck><suffix>`` of the run (``.sta``, ``.pvd``, ``.log``), None if absent."""
        name = self.name
        path = self.outdir / f"{name}{suffix}" if name else None
        return path if path is not None and path.exists() else None

    def table(self, name: str) -> dict[str, np.ndarray]:
        path = self.outdir / name
        return read_table(path) if path.exists() else {}

    def sta(self) -> dict[str, np.ndarray]:
        """The run's status table ``<deck>.sta`` ({} when there is none)."""
        path = self.own(".sta")
        return read_table(path) if path is not None else {}

    def _datasets(self):
        path = self.own(".pvd")
        return [] if path is None else list(ET.parse(path).getroot().iter("DataSet"))

    def pvd(self) -> list[tuple[float, int, Path]]:
        """(time, part, file) of every dataset listed in the PVD index."""
        return [(float(d.get("timestep")), int(d.get("part", 0)), self.outdir / d.get("file"))
                for d in self._datasets()]

    def blocks(self) -> list[tuple[float, str, Path]]:
        """(time, block name, file) of every dataset of the PVD index: ``body``, ``contact
        <pair>``, ``foundation <name>`` (an index written before blocks had names: part 0
        ``body``, 1 ``contact``, 2 ``foundation``)."""
        old = {0: "body", 1: "contact", 2: "foundation"}
        return [(float(d.get("timestep")), d.get("name") or old.get(int(d.get("part", 0)), ""),
                 self.outdir / d.get("file"))
                for d in self._datasets()]

    def body_files(self) -> list[tuple[float, Path]]:
        return [(t, f) for t, name, f in self.blocks() if name == "body"]

    def body(self, index: int = -1) -> dict[str, np.ndarray]:
        return read_vtu(self.body_files()[index][1])
