"""``*CHECK`` types of the forming scenes: slab-method and kinematic closed forms.

``UPSETTING`` (``SIGMAY, PHI, R0, H0``, optional ``SYMMETRY`` default 1, ``FOUNDATION``)
    Axisymmetric upsetting of a perfectly plastic cylinder between flat platens with Coulomb
    friction, at the end of every step.  The height is ``H = H0 + SYMMETRY U2`` (``U2`` the
    platen's travel in tool_forces.csv, negative down; ``SYMMETRY=2`` when the upper half is
    modelled), the radius from constant volume ``R = R0 sqrt(H0 / H)``, the mean pressure
    ``p = |RF2| / (R^2 / 2)`` (RF2 per radian).  Closed form (slab method, uniform axial strain,
    sliding everywhere, the friction not in the yield condition): ``p / SIGMAY = 2 (e^a - a - 1)
    / a^2`` with ``a = 2 PHI R / H`` (``1 + a / 3 + ...``).  ``error`` = the largest relative
    error of ``p`` over the steps.
``RING`` (``R, H0``, optional ``SYMMETRY`` default 1, ``FOUNDATION``)
    Frictionless axial compression, homogeneous: every node of reference radius ``R`` (the bore
    of a ring) moves to ``r = R sqrt(H0 / H)`` (constant volume; the elastic volume change
    aside), ``H`` as for ``UPSETTING``.  ``error`` = max over the steps and those nodes of
    ``|r - r_cf| / r_cf``.
The tool is ``FOUNDATION`` of tool_forces.csv (default: its first).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.params import Param
from ..results import RunResults
from .base import Check, CheckError, rel, result, rows, table

__all__ = ["Upsetting", "RingHomogeneous", "upsetting_pressure"]

_SYM = Param("SYMMETRY", float, 1.0, choices=(), bounds=(1.0, 2.0),
             doc="2 when one half of the height is modelled (mid-plane symmetric), else 1")
_TOOL = Param("FOUNDATION", str, None, upper=True,
              doc="the moving platen (default: the first foundation of tool_forces.csv)")


def upsetting_pressure(phi: float, radius: float, height: float) -> float:
    """Slab-method mean pressure over the yield stress, ``2 (e^a - a - 1) / a^2``, ``a = 2 phi
    R / H`` (series below 1e-4: the formula cancels there)."""
    a = 2.0 * phi * radius / height
    if a < 1e-4:
        return 1.0 + a / 3.0 + a * a / 12.0
    return 2.0 * (math.expm1(a) - a) / (a * a)


def tool_step_ends(run: RunResults, foundation: str | None) -> dict[str, np.ndarray]:
    """Rows of tool_forces.csv of one tool at the last increment of every step."""
    tab = table(run, "tool_forces.csv", ("foundation", "U2", "RF2"))
    names = np.array([str(n).upper() for n in tab["foundation"]])
    want = foundation or names[0]
    tab = rows(tab, names == want)
    if len(tab["step"]) == 0:
        raise CheckError(f"tool_forces.csv has no foundation {want}")
    step = np.asarray(tab["step"], int)
    last = np.r_[step[1:] != step[:-1], True]
    return rows(tab, last)


def _heights(chk, tools: dict[str, np.ndarray]) -> np.ndarray:
    h = chk.h0 + chk.symmetry * np.asarray(tools["U2"], float)
    if not (h > 0).all():
        raise CheckError(f"the platen's travel leaves no height (H = {h.min():g})")
    return h


class Upsetting(Check):
    """Mean platen pressure of a cylinder's upsetting against the slab method."""

    params = (Param("SIGMAY", float, gt=0.0, unit="stress", doc="yield stress"),
              Param("PHI", float, bounds=(0.0, None), doc="friction coefficient"),
              Param("R0", float, gt=0.0, unit="length", doc="initial radius"),
              Param("H0", float, gt=0.0, unit="length", doc="initial height of the whole cylinder"),
              _SYM, _TOOL)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        tools = tool_step_ends(run, self.foundation)
        heights = _heights(self, tools)
        found = []
        for step, h, f in zip(tools["step"], heights, tools["RF2"]):
            r = self.r0 * math.sqrt(self.h0 / h)
            p = abs(float(f)) / (0.5 * r * r)
            p_cf = self.sigmay * upsetting_pressure(self.phi, r, h)
            found.append((int(step), float(h), r, p, p_cf, abs(float(f))))
        errs = [rel(p, p_cf) for _, _, _, p, p_cf, _ in found]
        k = int(np.argmax(errs))
        step, h, r, p, p_cf, force = found[k]
        measured = {"pressure": p, "height": h, "radius": r, "step": step, "force": force}
        return result(measured, {"pressure": p_cf}, {"pressure": errs[k]}, errs[k])


class RingHomogeneous(Check):
    """Frictionless compression: the bore radius against constant volume."""

    params = (Param("R", float, gt=0.0, unit="length", doc="reference radius of the nodes checked"),
              Param("H0", float, gt=0.0, unit="length", doc="initial height of the whole body"),
              _SYM, _TOOL)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        tools = tool_step_ends(run, self.foundation)
        heights = dict(zip(np.asarray(tools["step"], int), _heights(self, tools)))
        disp = table(run, "displacements.csv", ("x", "u1"))
        on = np.isclose(np.asarray(disp["x"], float), self.r, rtol=1e-9, atol=1e-9 * self.r)
        if not on.any():
            raise CheckError(f"displacements.csv has no node at radius R = {self.r:g}")
        worst = (-1.0, 0, 0.0, 0.0)
        for step, h in heights.items():
            d = rows(disp, on & (np.asarray(disp["step"], int) == step))
            if len(d["step"]) == 0:
                continue
            r = self.r + np.asarray(d["u1"], float)
            r_cf = self.r * math.sqrt(self.h0 / h)
            k = int(np.argmax(np.abs(r - r_cf)))
            e = abs(r[k] - r_cf) / r_cf
            if e > worst[0]:
                worst = (e, step, float(r[k]), r_cf, float(h))
        if worst[0] < 0:
            raise CheckError("no step has both displacements.csv rows and the tool's travel")
        e, step, r, r_cf, h = worst
        return result({"radius": r, "height": h, "step": step}, {"radius": r_cf}, {"radius": e}, e)
