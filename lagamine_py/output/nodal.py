"""``displacements.csv``: nodal positions and displacements at the last converged increment of each step.

The VTK series holds every output increment for ParaView; this table holds, as text, the state that
references archive and ``lagamine-py compare`` checks.  The last increment of a step
(``result.step_end``) is written at once, before the controller saves its restart point: a kill
at the step end cannot lose it (``tests/test_kill_windows.py``).  The latest increment of a step
in progress is kept in memory and written when the run closes, so an interrupted step still
leaves its last converged increment on disk; a resumed run drops those rows of the step it
resumes.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .base import IncrementResult, Writer
from .tables import trim_rows


class _Row(NamedTuple):
    """What :meth:`DisplacementsWriter._write` reads of an increment: kept in place of the
    whole :class:`IncrementResult`, whose cells (strains, the committed law state) and contact
    points would stay alive through the next increment's evaluations and factorisations."""
    step: int
    increment: int
    time: float
    coords0: np.ndarray
    u: np.ndarray


def _row(r: IncrementResult) -> _Row:
    return _Row(r.step, r.increment, r.time, r.coords0, r.u)


class DisplacementsWriter(Writer):
    """Nodal displacements at the end of each step (displacements.csv)."""

    def start_run(self) -> None:
        self.outdir.mkdir(parents=True, exist_ok=True)
        path = self.outdir / "displacements.csv"
        self._resume = self.append and path.exists()
        self._fh = open(path, "a" if self._resume else "w")
        if not self._resume:
            self._fh.write("step,increment,time,node,x,y,u1,u2\n")
        self._fh.flush()
        self._pending: _Row | None = None

    def _trim_once(self, r: IncrementResult) -> None:
        """On resume, rows of the step being resumed (written by a clean stop) go."""
        if self._resume:
            self._fh.close()
            trim_rows(self.outdir / "displacements.csv", (r.step, 0))
            self._fh = open(self.outdir / "displacements.csv", "a")
            self._resume = False

    def increment(self, result: IncrementResult) -> None:
        self._trim_once(result)
        if self._pending is not None and self._pending.step != result.step:
            self._write(self._pending)
        self._pending = _row(result)
        if result.step_end:
            self._write(self._pending)
            self._pending = None

    def start_step(self, step_number, step) -> None:
        if self._pending is not None and self._pending.step < step_number:
            self._write(self._pending)
            self._pending = None

    def close(self, status: int, message: str) -> None:
        try:
            if self._pending is not None:
                self._write(self._pending)
                self._pending = None
        finally:
            self._fh.close()

    def _write(self, r: _Row) -> None:
        # Python floats and ints (tolist): formatting NumPy scalars one by one is 3x slower
        ids = np.asarray(self.model.node_ids).astype(np.int64).tolist()
        lead = f"{r.step},{r.increment},{r.time:.17g}"
        lines = [f"{lead},{n},{x:.17g},{y:.17g},{u:.17g},{v:.17g}\n"
                 for n, (x, y), (u, v) in zip(ids, np.asarray(r.coords0, float).tolist(),
                                              np.asarray(r.u, float).reshape(-1, 2).tolist())]
        self._fh.write("".join(lines))
        self._fh.flush()
