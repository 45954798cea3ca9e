"""CSV tables of the rigid tools and of the energy balance.

* ``tool_forces.csv`` (writer ``TOOLS``, one of the built-ins): one row per foundation on every
  converged increment, ``step, increment, time, foundation, ref_node`` (its reference node's id,
  empty for a tool moved by ``*FOUNDATION MOTION``), ``x, y`` (the reference point now), ``U1, U2,
  UR6`` (its translation and rotation, radians, counter-clockwise), ``RF1, RF2, RM6``: the force
  and the moment about the reference point that the tool exerts on the bodies -- the sum over
  its contact pairs, stabilisation included; at equilibrium the reactions of its reference node
  (:class:`~lagamine_py.output.base.ToolState`).  In axisymmetry the forces are per radian and
  the moment is that of the per-radian forces in the r-z plane.
* ``energy.csv`` (writer ``ENERGY``, on every run, writing only when the run keeps the energy
  balance: a ``*CHECK, TYPE=ENERGY`` or ``*OUTPUT, WRITERS=`` naming ENERGY): one row per
  converged increment with the terms of :mod:`lagamine_py.solver.energy` (``work, elastic,
  plastic, friction, penalty, stabilisation, balance, relative, friction_path``), cumulative
  from t = 0.

Both are flushed after every increment and resume like the other tables
(:class:`~lagamine_py.output.tables.CsvFiles`).
"""
from __future__ import annotations

import numpy as np

from .base import IncrementResult
from .tables import CsvFiles, _CsvWriter, fmt

__all__ = ["ToolForcesWriter", "EnergyWriter", "TOOL_HEADER", "ENERGY_HEADER"]

TOOL_HEADER = ("step", "increment", "time", "foundation", "ref_node", "x", "y", "U1", "U2", "UR6",
               "RF1", "RF2", "RM6")
ENERGY_TERMS = ("work", "elastic", "plastic", "friction", "penalty", "stabilisation", "balance",
                "relative", "friction_path")
ENERGY_HEADER = ("step", "increment", "time") + ENERGY_TERMS


class ToolForcesWriter(_CsvWriter):
    """tool_forces.csv: every foundation's placement, force and moment, every increment."""

    files = {"_rows": ("tool_forces.csv", TOOL_HEADER)}

    def increment(self, result: IncrementResult) -> None:
        self._begin(result)
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        rows = []
        for name, ts in result.tools.items():
            values = np.concatenate([np.asarray(ts.point, float), np.asarray(ts.placement, float),
                                     np.asarray(ts.force, float), [float(ts.moment)]])
            rows.append(head + [name, "" if ts.ref_node is None else str(int(ts.ref_node)),
                                *fmt(values)])
        self._rows.writerows(rows)
        self._flush()


class EnergyWriter(_CsvWriter):
    """energy.csv: the energy balance, every increment of a run that keeps it (the file is
    opened at the first such increment; a run without it gets no file)."""

    always = True
    files = {"_rows": ("energy.csv", ENERGY_HEADER)}

    def start_run(self) -> None:
        self._csv = None                     # opened with the first energy row

    def increment(self, result: IncrementResult) -> None:
        if not result.energy:
            return
        if self._csv is None:
            self._csv = CsvFiles(self.outdir, self.files, self.append)
            self._rows = self._csv.writers["_rows"]
        self._begin(result)
        head = [str(result.step), str(result.increment), fmt(result.time)[()]]
        self._rows.writerow(head + list(fmt([result.energy[k] for k in ENERGY_TERMS])))
        self._flush()
