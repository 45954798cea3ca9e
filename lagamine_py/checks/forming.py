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
    ``|r - r_cf| / r_cf``.``ROLLING`` (``SIGMAY, PHI, R, H0, H1``, optional ``FOUNDATION``)
    Flat rolling in plane strain, symmetric mill (the lower half of the strip modelled, or one
    roll over a strip on a frictionless flat): over the last step, a steady state.  Measured: the
    roll force ``|RF2|`` and torque ``|RM6|`` (per unit width, one roll) as their means over the
    step's increments weighted by the increment sizes (they ripple as the faces pass the gap),
    and the forward slip ``v1 / (omega R) - 1`` with ``v1`` the advance of the strip's front end
    (the nodes of the largest reference x in displacements.csv, rigid beyond the gap) over the
    step and ``omega R`` the roll surface's (``R |dUR6|``).  Closed form
    (:func:`rolling_slab`): the slab equation of von Karman, which is Orowan's under homogeneous
    compression, with Coulomb friction, a rigid roll and no strip tension.  ``error`` = the
    largest of the three relative errors.

The tool is ``FOUNDATION`` of tool_forces.csv (default: its first).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.params import Param
from ..results import RunResults
from .base import Check, CheckError, rel, result, rows, table

__all__ = ["Upsetting", "RingHomogeneous", "Rolling", "upsetting_pressure", "rolling_slab"]

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


def rolling_slab(sigmay: float, phi: float, radius: float, h0: float, h1: float,
                 n: int = 4001, profile: bool = False) -> dict[str, Any]:
    """Flat rolling by the slab method of von Karman (Orowan's equation under homogeneous
    compression), Coulomb friction, rigid rolls of radius ``radius``, no strip tension,
    thickness ``h0`` to ``h1``, integrated numerically on the exact circular gap.

    With ``x`` from the exit (0) to the entry (``L``), the gap ``h(x) = h1 + 2 (R - sqrt(R^2 -
    x^2))``, the horizontal compressive stress ``s`` and the roll pressure ``p = s + k``
    (``k = 2 sigmay / sqrt 3``, plane-strain yield): ``d(s h)/dx = p dh/dx + 2 phi p`` between
    the exit and the neutral point (the strip outruns the rolls), ``- 2 phi p`` between the
    neutral point and the entry; ``s = 0`` at both ends; the neutral point is where the two
    pressure branches meet.  Returns ``force = int p dx`` and ``torque = R phi (int_entry p ds -
    int_exit p ds)`` per roll and unit width, ``forward_slip = h_n cos(a_n) / h1 - 1`` (the
    flux through the neutral section, which moves with the roll surface), ``neutral`` (x_n),
    ``length`` (L); with ``profile``, also the arrays ``x`` (n,) and ``p`` (n,)."""
    from scipy.integrate import solve_ivp           # scipy only when a check is evaluated
    k = 2.0 * sigmay / math.sqrt(3.0)
    length = math.sqrt(radius**2 - (radius - 0.5 * (h0 - h1)) ** 2)
    x = np.linspace(0.0, length, n)
    gap = h1 + 2.0 * (radius - np.sqrt(radius**2 - x * x))

    def slope(sign: float):
        def f(xx, sh):
            h = h1 + 2.0 * (radius - math.sqrt(radius**2 - xx * xx))
            p = sh[0] / h + k
            return [p * 2.0 * xx / math.sqrt(radius**2 - xx * xx) + sign * 2.0 * phi * p]
        return f

    tol = dict(rtol=1e-10, atol=1e-10 * k * h0)
    exit_side = solve_ivp(slope(+1.0), (0.0, length), [0.0], t_eval=x, **tol).y[0] / gap + k
    entry_side = solve_ivp(slope(-1.0), (length, 0.0), [0.0], t_eval=x[::-1], **tol).y[0][::-1] / gap + k
    p = np.minimum(exit_side, entry_side)
    xn = float(x[int(np.argmin(np.abs(exit_side - entry_side)))])
    ds = np.sqrt(1.0 + (x / np.sqrt(radius**2 - x * x)) ** 2)
    entry = x >= xn
    torque = radius * phi * (np.trapezoid(np.where(entry, p, 0.0) * ds, x)
                             - np.trapezoid(np.where(entry, 0.0, p) * ds, x))
    hn = h1 + 2.0 * (radius - math.sqrt(radius**2 - xn * xn))
    out = {"force": float(np.trapezoid(p, x)), "torque": float(torque),
           "forward_slip": hn * math.sqrt(radius**2 - xn * xn) / radius / h1 - 1.0,
           "neutral": xn, "length": length}
    if profile:
        out.update(x=x, p=p)
    return out


class Rolling(Check):
    """Flat rolling at steady state: roll force, torque and forward slip against the slab
    equation of von Karman (Orowan's under homogeneous compression)."""

    params = (Param("SIGMAY", float, gt=0.0, unit="stress", doc="yield stress"),
              Param("PHI", float, gt=0.0, doc="friction coefficient"),
              Param("R", float, gt=0.0, unit="length", doc="roll radius"),
              Param("H0", float, gt=0.0, unit="length", doc="entry thickness of the whole strip"),
              Param("H1", float, gt=0.0, unit="length", doc="exit thickness (the roll gap)"),
              _TOOL)

    @classmethod
    def example_values(cls) -> dict[str, Any]:
        return {"SIGMAY": 250.0, "PHI": 0.1, "R": 100.0, "H0": 2.0, "H1": 1.6}

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        if not self.h1 < self.h0:
            raise CheckError(f"H1 = {self.h1:g} must be below H0 = {self.h0:g}")
        tab = table(run, "tool_forces.csv", ("foundation", "time", "UR6", "RF2", "RM6"))
        names = np.array([str(n).upper() for n in tab["foundation"]])
        tab = rows(tab, names == (self.foundation or names[0]))
        step = np.asarray(tab["step"], int)
        if len(step) == 0 or len(np.unique(step)) < 2:
            raise CheckError("tool_forces.csv needs the tool over two steps at least "
                             "(the last one steady)")
        last = step == step[-1]
        before = np.flatnonzero(~last)[-1]
        t = np.asarray(tab["time"], float)
        w = np.diff(np.r_[t[before], t[last]])
        force = abs(float(np.sum(w * np.asarray(tab["RF2"], float)[last]) / w.sum()))
        torque = abs(float(np.sum(w * np.asarray(tab["RM6"], float)[last]) / w.sum()))
        turn = abs(float(tab["UR6"][-1]) - float(tab["UR6"][before]))
        disp = table(run, "displacements.csv", ("node", "x", "u1"))
        dstep = np.asarray(disp["step"], int)
        front = np.isclose(np.asarray(disp["x"], float), np.max(disp["x"]))
        ends = [np.asarray(disp["u1"], float)[front & (dstep == k)] for k in (step[before], step[-1])]
        if not (turn > 0 and all(len(e) for e in ends)):
            raise CheckError("the roll did not turn over the last step, or displacements.csv "
                             "lacks its ends")
        slip = float(np.mean(ends[1] - ends[0])) / (self.r * turn) - 1.0
        cf = rolling_slab(self.sigmay, self.phi, self.r, self.h0, self.h1)
        measured = {"force": force, "torque": torque, "forward_slip": slip}
        closed = {k: cf[k] for k in measured}
        errors = {k: rel(measured[k], closed[k]) for k in measured}
        measured["neutral_cf"] = cf["neutral"]
        return result(measured, closed, errors)
