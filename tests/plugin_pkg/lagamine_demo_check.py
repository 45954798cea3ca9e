"""A third-party lagamine_py ``*CHECK``: a plane-strain bar pulled by a uniform traction.

The entry point in setup.cfg (group ``lagamine_py.checks``) makes it available as
``*CHECK, NAME=..., TYPE=BAR_END`` with data ``SIGMA=, E=, NU=, LENGTH=``.  It reads
``displacements.csv`` (the last step) and compares the mean ``u1`` of the nodes at the bar's
end (the largest x) with the closed form of plane strain with ``sigma_yy = 0``,
``u = SIGMA (1 - NU^2) LENGTH / E`` (the other end held in x).
"""
import numpy as np

from lagamine_py.checks.base import Check, rel, result, rows, table
from lagamine_py.registry import Param


class BarEnd(Check):
    """Plane-strain bar under a uniform end traction: the end displacement."""

    params = (
        Param("SIGMA", float, unit="stress", doc="traction on the pulled end"),
        Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
        Param("NU", float, bounds=(-1.0, 0.5), doc="Poisson's ratio"),
        Param("LENGTH", float, gt=0.0, unit="length", doc="length of the bar"),
    )

    @classmethod
    def example_values(cls):
        return {"SIGMA": 100.0, "E": 200e3, "NU": 0.3, "LENGTH": 4.0}

    def evaluate(self, run):
        tab = table(run, "displacements.csv", ("step", "x", "u1"))
        last = rows(tab, tab["step"] == tab["step"][-1])
        x = last["x"].astype(float)
        end = x >= x.max() - 1e-9 * max(1.0, np.abs(x).max())
        u = float(last["u1"][end].astype(float).mean())
        closed = self.sigma * (1.0 - self.nu**2) * self.length / self.e
        return result({"u_end": u}, {"u_end": closed}, {"u_end": rel(u, closed)})
