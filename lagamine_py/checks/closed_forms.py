"""The built-in ``*CHECK`` types: error measures of a run against closed forms.

Each type is a :class:`~lagamine_py.checks.base.Check` plugin (entry points in ``setup.cfg``)
whose ``evaluate`` returns ``measured`` and ``closed_form`` values, the relative ``errors`` per
quantity and the headline ``error``.  Types:

``HERTZ`` (``R, E, NU``, ``SYMMETRY=1|2``, optional ``P``, ``X0``)
    Last increment of ``contact.csv``.  The least-squares fit of ``p^2 = p0^2 (1 - x^2/a^2)``
    over the points with ``p > 0``, ``x`` measured from the initial contact point (``X0`` if
    given; else 0 with ``SYMMETRY=2``, where the symmetry axis holds the contact point; else the
    centroid ``sum x p / sum p`` of the pressure) gives ``a`` and ``p0``.  Closed form (Johnson
    §4.2) ``a = sqrt(4 P R (1 - nu^2) / (pi E))``, ``p0 = 2 P / (pi a)``, at ``P`` if given, else
    at the measured force (a deck driven by displacement).  ``error`` = max of the two
    relative errors.  Reported as well: ``a_moment`` (from the second moment of ``p``,
    ``a^2 = 4 int x^2 p / int p``, trapezoid over the points: a cross-check, not in ``error``)
    and the total normal force ``P`` (``SYMMETRY`` times the model's, from contact_totals.csv).
``CATTANEO`` (``P, R, E, NU, PHI, QRATIO``, optional ``SYMMETRY``)
    Over the increments of the last step: ``Q = |T|``, ``Pn = P`` (contact_totals.csv) and the
    stick half-width ``c`` from contact.csv (see :func:`stick_half_width`), interpolated at
    ``Q / (PHI Pn) = QRATIO``.  Closed form (Johnson §7.1) ``c = a sqrt(1 - QRATIO)`` with ``a``
    from Hertz at the measured ``Pn``; ``error = |c - c_cf| / a``.
``COULOMB`` (``PHI, B, A``)
    Last increment: ``|T|`` against ``PHI |P| + B A``; relative error.
``PENETRATION`` (``P, KP``)
    Last increment, points in contact (``stick`` or ``slip``): the penetration ``d = -gap``
    (gap in the COPEN convention, :func:`lagamine_py.results.copen_gap`) against ``P/KP``,
    ``max |d - P/KP| / (P/KP)``.
``UNIAXIAL_RO`` (``E, SIGMA0, ALPHA, N, R0, H0``, optional ``NSET``)
    Homogeneous axisymmetric compression or tension of a cylinder, at the end of every step
    (where displacements.csv has rows): Kirchhoff stress ``s = J |RF2| / (r^2 / 2)``, with
    ``J = (r/R0)^2 h/H0`` the volume ratio (RF2 per radian of
    ``NSET``, default the node set with the largest ``|RF2|``), ``r = R0 + u1`` of the outermost
    node, log strain ``ln(h / H0)`` with ``h`` the current height; closed form
    ``eps = s/E + ALPHA (SIGMA0/E) (s/SIGMA0)^N``; ``error`` = max over steps of the relative
    error of ``|eps|`` at the measured stress.  Also reported: the relative error of the stress
    against the curve's stress at the measured strain (``errors["stress"]``, about ``N`` times
    smaller on the plastic part of the curve).
``LAME`` (``P, A, B, E, NU``)
    Elastic thick cylinder under internal pressure, axisymmetric with plane-strain ends: the
    radial displacement of the inner and outer surfaces (mean ``u1`` of the nodes at the smallest
    and largest ``x``, last step) against
    ``u(r) = (1 + nu) P A^2 / (E (B^2 - A^2)) ((1 - 2 nu) r + B^2 / r)``; max relative error.
``LIMIT_PRESSURE`` (``P, SIGMAY, A, B``, optional ``PERIOD`` default 1)
    One-step run whose pressure ramps linearly to ``P`` over ``PERIOD``: the pressure reached is
    ``P t / PERIOD`` at the last converged increment of the run's ``<deck>.sta``; closed form (Hill,
    thick cylinder in plane strain) ``p_lim = (2 / sqrt 3) SIGMAY ln(B / A)``.  When ``P`` is
    below ``p_lim`` the run must finish: error 0 if it did, else the shortfall; when ``P`` is
    above, ``error = |p_reached - p_lim| / p_lim``.

A check that cannot be evaluated (a file or a column missing, no contact) gets ``error`` NaN and
a ``message`` saying why (:func:`~lagamine_py.checks.base.evaluate_checks`).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.params import Param, ParamError
from ..results import RunResults, copen_gap
from .base import (Check, CheckError, contact_points, last_increment, one_contact, rel, result,
                   rows, table)

__all__ = ["Hertz", "Cattaneo", "CoulombSliding", "Penetration", "UniaxialRambergOsgood", "Lame",
           "LimitPressure", "hertz_closed_form", "fit_hertz", "stick_edges", "stick_half_width",
           "lame_radial_displacement"]

_CONTACT = Param("CONTACT", str, None, upper=True,
                 doc="the contact pair, by its surface (default: the first pair)")
_SYMMETRY = Param("SYMMETRY", float, 1.0, choices=(), bounds=(1.0, 2.0),
                  doc="2 when the model is the half of a symmetric scene (forces doubled, "
                      "the centre on the axis x = 0)")


# ---------------------------------------------------------------- Hertz


def hertz_closed_form(P: float, R: float, E: float, nu: float) -> tuple[float, float]:
    """Half-width ``a`` and peak pressure ``p0`` of a cylinder (force P per unit length) on a
    rigid flat (Johnson, Contact Mechanics §4.2)."""
    a = math.sqrt(4.0 * P * R * (1.0 - nu**2) / (math.pi * E))
    return a, 2.0 * P / (math.pi * a)


def fit_hertz(x: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of ``p^2 = p0^2 (1 - x^2/a^2)`` (linear in 1 and x^2) over the points
    with ``p > 0``; ``x`` measured from the contact centre.  Returns ``(a, p0)``."""
    on = p > 0
    if on.sum() < 2:
        raise CheckError("fewer than two contact points with p > 0")
    x2, p2 = x[on] ** 2, p[on] ** 2
    (c0, c1), *_ = np.linalg.lstsq(np.column_stack([np.ones_like(x2), x2]), p2, rcond=None)
    if c0 <= 0 or c1 >= 0:
        raise CheckError("the pressure does not decrease away from the centre: no Hertz fit")
    return math.sqrt(-c0 / c1), math.sqrt(c0)


def _moment_half_width(x: np.ndarray, p: np.ndarray) -> float:
    """``a`` from ``int x^2 p dx / int p dx = a^2 / 4`` (Hertz), trapezoid over the points sorted
    by ``x`` (one side or both: the ratio is the same)."""
    order = np.argsort(x)
    xs, ps = x[order], np.clip(p[order], 0.0, None)
    from scipy.integrate import trapezoid      # scipy only when a check is evaluated
    m0 = trapezoid(ps, xs)
    return math.sqrt(4.0 * trapezoid(xs**2 * ps, xs) / m0) if m0 > 0 else math.nan


def _centre(x0: float | None, symmetry: float, x: np.ndarray, p: np.ndarray) -> float:
    """``x0``; 0 with ``symmetry`` 2; else the centroid of the pressure ``sum x p / sum p`` (the
    Hertz and Cattaneo pressures are even about the centre; the largest ``p`` is not a safe
    centre, a penalty contact may peak anywhere near the top of the profile)."""
    if x0 is not None:
        return x0
    if symmetry == 2.0:
        return 0.0
    w = np.clip(p, 0.0, None)
    return float(np.sum(x * w) / np.sum(w)) if np.sum(w) > 0 else float(x[np.argmax(p)])


class Hertz(Check):
    """Hertz line contact of a cylinder on a rigid flat: half-width a and peak pressure p0."""

    params = (Param("R", float, gt=0.0, unit="length", doc="cylinder radius"),
              Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
              Param("NU", float, bounds=(-1.0, 0.5), doc="Poisson's ratio"),
              Param("P", float, None, gt=0.0, unit="force/length",
                    doc="force per unit length (default: the force the run reached)"),
              Param("X0", float, None, unit="length", doc="the contact centre"),
              _SYMMETRY, _CONTACT)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        pts = last_increment(contact_points(run, ("x", "p"), self.contact))
        x, p = pts["x"].astype(float), pts["p"].astype(float)
        xc = x - _centre(self.x0, self.symmetry, x, p)
        a, p0 = fit_hertz(xc, p)
        measured = {"a": a, "p0": p0, "a_moment": _moment_half_width(xc, p)}
        totals = run.table("contact_totals.csv")
        if totals and len(totals.get("P", ())):
            measured["P"] = self.symmetry * abs(float(
                last_increment(one_contact(totals, self.contact))["P"][-1]))
        if self.values["P"] is not None:
            P = self.values["P"]
        elif "P" in measured:
            P = measured["P"]       # displacement-driven: the closed form at the force reached
        else:
            raise CheckError("no P given and contact_totals.csv has no P column")
        a_cf, p0_cf = hertz_closed_form(P, self.r, self.e, self.nu)
        return result(measured, {"a": a_cf, "p0": p0_cf, "a_moment": a_cf, "P": P},
                      {"a": rel(a, a_cf), "p0": rel(p0, p0_cf)})


# ---------------------------------------------------------------- Cattaneo-Mindlin


def _sqrt_edge(x_in: np.ndarray, r_in: np.ndarray, x_out: float) -> float:
    """Edge of the stick zone between its last stick point ``x_in[-1]`` and the first slip point
    ``x_out``: near the edge the traction ratio ``r = |tau| / (phi p)`` rises to 1 like
    ``1 - k sqrt(c - x)`` (Cattaneo), so ``(1 - r)^2`` is linear in ``x``; extrapolate it from the
    two stick points nearest the edge to 0 and keep the result between the two points (midpoint
    when there are too few points or the ratio does not rise)."""
    mid = 0.5 * (x_in[-1] + x_out)
    if len(x_in) < 2:
        return mid
    s1, s2 = (1.0 - np.clip(r_in[-2:], 0.0, 1.0)) ** 2
    x1, x2 = x_in[-2:]
    if not s1 > s2 or x2 == x1:
        return mid
    c = x2 + s2 * (x2 - x1) / (s1 - s2)
    lo, hi = sorted((x_in[-1], x_out))
    return float(np.clip(c, lo, hi))


def stick_edges(x: np.ndarray, status: np.ndarray, ratio: np.ndarray,
                centre: float) -> tuple[float, float]:
    """Left and right edges of the contiguous stick zone around ``centre`` at one increment
    (``(centre, centre)`` when the point nearest it does not stick).

    Parameters
    ----------
    x : (g,) positions of the contact points.
    status : (g,) "open" | "stick" | "slip".
    ratio : (g,) ``|tau| / (phi p)`` (used to place each edge between the last stick and the first
        slip point, see :func:`_sqrt_edge`).
    centre : the contact centre; the stick zone is the run of stick points, in ``x`` order,
        through the point nearest to it.
    """
    order = np.argsort(x)
    xs, st, rs = x[order], np.asarray(status)[order], ratio[order]
    stick = np.array([str(s) == "stick" for s in st])
    k = int(np.argmin(np.abs(xs - centre)))
    if not stick[k]:
        return float(centre), float(centre)
    lo, hi = k, k
    while lo > 0 and stick[lo - 1]:
        lo -= 1
    while hi < len(xs) - 1 and stick[hi + 1]:
        hi += 1
    # edges: extrapolated toward a following slip point, else the last stick point itself
    right = _sqrt_edge(xs[lo:hi + 1], rs[lo:hi + 1], xs[hi + 1]) if hi < len(xs) - 1 else xs[hi]
    left = (-_sqrt_edge(-xs[lo:hi + 1][::-1], rs[lo:hi + 1][::-1], -xs[lo - 1])
            if lo > 0 else xs[lo])
    return float(left), float(right)


def stick_half_width(x: np.ndarray, status: np.ndarray, ratio: np.ndarray, centre: float) -> float:
    """Half-width of the contiguous stick zone around ``centre`` at one increment (0 when the
    point nearest it does not stick): :func:`stick_edges`."""
    left, right = stick_edges(x, status, ratio, centre)
    return 0.5 * (right - left)


class Cattaneo(Check):
    """Cattaneo-Mindlin partial slip: the stick half-width c at a tangential load ratio."""

    params = (Param("P", float, gt=0.0, unit="force/length", doc="normal force per unit length"),
              Param("R", float, gt=0.0, unit="length", doc="cylinder radius"),
              Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
              Param("NU", float, bounds=(-1.0, 0.5), doc="Poisson's ratio"),
              Param("PHI", float, gt=0.0, doc="friction coefficient"),
              Param("QRATIO", float, bounds=(0.0, 1.0), doc="Q / (PHI P) where c is measured"),
              Param("X0", float, None, unit="length", doc="the contact centre"),
              _SYMMETRY, _CONTACT)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        return check_cattaneo(self, run)


def check_cattaneo(chk: Cattaneo, run: RunResults) -> dict[str, Any]:
    P, R, E, nu, phi, qratio = chk.values["P"], chk.r, chk.e, chk.nu, chk.phi, chk.qratio
    sym = chk.symmetry
    totals = one_contact(table(run, "contact_totals.csv", ("P", "T", "contact")), chk.contact)
    pts = contact_points(run, ("x", "p", "tau", "status"), chk.contact)
    last = totals["step"][-1]
    totals = rows(totals, totals["step"] == last)
    pts = rows(pts, pts["step"] == last)
    ratios, widths, forces = [], [], []
    for inc, Q, Pn in zip(totals["increment"], np.abs(totals["T"]), np.abs(totals["P"])):
        at = rows(pts, pts["increment"] == inc)
        if len(at["x"]) == 0 or Pn == 0:
            continue                      # no field output at this increment
        x, p, tau = (at[k].astype(float) for k in ("x", "p", "tau"))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(p > 0, np.abs(tau) / (phi * p), 1.0)
        centre = _centre(chk.x0, sym, x, p)
        ratios.append(Q / (phi * Pn))
        widths.append(stick_half_width(x, at["status"], r, centre))
        forces.append(sym * Pn)
    if len(ratios) < 2:
        raise CheckError(f"fewer than two increments with contact output in step {int(last)}")
    ratios, widths, forces = map(np.asarray, (ratios, widths, forces))
    order = np.argsort(ratios)
    if not ratios[order[0]] <= qratio <= ratios[order[-1]]:
        raise CheckError(f"Q/(PHI P) spans {ratios.min():.4g}..{ratios.max():.4g} in step {int(last)}, "
                         f"QRATIO={qratio:g} is outside")
    c = float(np.interp(qratio, ratios[order], widths[order]))
    Pn = float(np.interp(qratio, ratios[order], forces[order]))
    a = hertz_closed_form(Pn, R, E, nu)[0]
    c_cf = a * math.sqrt(1.0 - qratio)
    err = abs(c - c_cf) / a
    return result({"c": c, "P": Pn, "c_over_a": c / a},
                   {"c": c_cf, "P": P, "c_over_a": c_cf / a, "a": a}, {"c": err}, err)


# ---------------------------------------------------------------- Coulomb, penetration


class CoulombSliding(Check):
    """A block sliding whole: the tangential force T = PHI P + B A."""

    params = (Param("PHI", float, bounds=(0.0, None), doc="friction coefficient"),
              Param("B", float, 0.0, bounds=(0.0, None), unit="stress", doc="adhesion"),
              Param("A", float, 0.0, bounds=(0.0, None), unit="area",
                    doc="contact area (per radian in axisymmetry; needed with B)"),
              _CONTACT)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        totals = last_increment(one_contact(table(run, "contact_totals.csv", ("P", "T", "contact")),
                                            self.contact))
        P, T = abs(float(totals["P"][-1])), abs(float(totals["T"][-1]))
        T_cf = self.phi * P + self.b * self.a
        return result({"T": T, "P": P}, {"T": T_cf}, {"T": rel(T, T_cf)})


class Penetration(Check):
    """A flat punch on the penalty foundation: the penetration d = P / KP."""

    params = (Param("P", float, unit="stress", doc="contact pressure"),
              Param("KP", float, gt=0.0, unit="stress/length", doc="normal penalty"),
              _CONTACT)

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        d_cf = self.values["P"] / self.kp
        pts = last_increment(contact_points(run, ("gap", "status"), self.contact))
        closed = np.array([str(s) in ("stick", "slip") for s in pts["status"]])
        if not closed.any():
            raise CheckError("no contact point is closed at the last increment")
        d = -copen_gap(pts)[closed]
        errs = np.abs(d - d_cf) / abs(d_cf)
        k = int(np.argmax(errs))
        return result({"penetration": float(d[k]), "penetration_mean": float(d.mean())},
                      {"penetration": d_cf, "penetration_mean": d_cf},
                      {"penetration": float(errs[k])})


# ---------------------------------------------------------------- bodies


def _step_ends(run: RunResults) -> dict[str, np.ndarray]:
    return table(run, "displacements.csv", ("x", "y", "u1", "u2"))


class UniaxialRambergOsgood(Check):
    """Homogeneous axisymmetric compression or tension against the Ramberg-Osgood curve."""

    params = (Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
              Param("SIGMA0", float, gt=0.0, unit="stress", doc="reference stress"),
              Param("ALPHA", float, gt=0.0, doc="yield offset coefficient"),
              Param("N", float, bounds=(1.0, None), doc="hardening exponent"),
              Param("R0", float, gt=0.0, unit="length", doc="initial radius"),
              Param("H0", float, gt=0.0, unit="length", doc="initial height"),
              Param("NSET", str, None, upper=True,
                    doc="node set whose RF2 is the force (default: the largest |RF2|)"))

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        return check_uniaxial_ro(self, run)


def check_uniaxial_ro(chk: UniaxialRambergOsgood, run: RunResults) -> dict[str, Any]:
    E, s0, alpha, n, r0, h0 = chk.e, chk.sigma0, chk.alpha, chk.n, chk.r0, chk.h0
    from scipy.optimize import brentq           # scipy only when a check is evaluated
    disp = _step_ends(run)
    reac = table(run, "reactions.csv", ("nset", "RF2"))
    nsets = np.array([str(s).upper() for s in reac["nset"]], dtype=object)
    if chk.nset is not None:
        want = chk.nset
    else:
        last = last_increment(reac)
        want = str(last["nset"][int(np.argmax(np.abs(last["RF2"])))]).upper()
    reac = rows(reac, nsets == want)
    if len(reac["step"]) == 0:
        raise CheckError(f"reactions.csv has no node set {want}")
    found = []
    for step in np.unique(disp["step"]):
        d = rows(disp, disp["step"] == step)
        r_ = rows(reac, reac["step"] == step)
        if len(r_["step"]) == 0:
            continue
        F = abs(float(r_["RF2"][-1]))
        outer = np.argmax(d["x"])
        r = r0 + float(d["u1"][outer])
        y = d["y"] + d["u2"]
        h = float(y.max() - y.min())
        # Kirchhoff stress = J x Cauchy: with Hencky strains and multiplicative plasticity the
        # uniaxial curve holds exactly between the log strain and the Kirchhoff stress
        J = (r / r0) ** 2 * (h / h0)
        s = J * F / (0.5 * r**2)
        eps = abs(math.log(h / h0))
        eps_cf = _ro_strain(s, E, s0, alpha, n)
        # the stress on the curve at the measured strain: monotone in s, below E eps
        s_cf = brentq(lambda t: _ro_strain(t, E, s0, alpha, n) - eps, 0.0, E * eps) if eps > 0 else 0.0
        found.append((int(step), s, eps, eps_cf, s_cf, r))
    if not found:
        raise CheckError(f"no step has both displacements.csv rows and reactions of {want}")
    errs = [rel(e, ecf) for _, _, e, ecf, _, _ in found]
    k = int(np.argmax(errs))
    step, s, eps, eps_cf, s_cf, r = found[k]
    return result({"stress": s, "strain": eps, "radius": r, "step": step},
                  {"strain": eps_cf, "stress": s_cf},
                  {"strain": errs[k], "stress": rel(s, s_cf)}, errs[k])


def _ro_strain(s: float, E: float, s0: float, alpha: float, n: float) -> float:
    """Ramberg-Osgood uniaxial strain ``s/E + alpha (s0/E) (s/s0)^n`` (s >= 0)."""
    return s / E + alpha * (s0 / E) * (s / s0) ** n


def lame_radial_displacement(r, P: float, A: float, B: float, E: float, nu: float):
    """Radial displacement of a thick cylinder (radii A < B) under internal pressure P, plane
    strain (axial strain 0): ``u = (1+nu) P A^2 / (E (B^2-A^2)) ((1-2 nu) r + B^2/r)``."""
    r = np.asarray(r, float)
    return (1.0 + nu) * P * A**2 / (E * (B**2 - A**2)) * ((1.0 - 2.0 * nu) * r + B**2 / r)


def _inner_below_outer(a: float, b: float) -> None:
    """A tube's radii: the closed forms divide by ``B^2 - A^2`` or take ``ln(B / A)``."""
    if not a < b:
        raise ParamError(f"the inner radius A = {a:g} must be below the outer radius B = {b:g}")


class Lame(Check):
    """Elastic thick cylinder under internal pressure: radial displacement of both surfaces."""

    params = (Param("P", float, unit="stress", doc="internal pressure"),
              Param("A", float, gt=0.0, unit="length", doc="inner radius"),
              Param("B", float, gt=0.0, unit="length", doc="outer radius"),
              Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
              Param("NU", float, bounds=(-1.0, 0.5), doc="Poisson's ratio"))

    def __init__(self, **values):
        super().__init__(**values)
        _inner_below_outer(self.a, self.b)

    @classmethod
    def example_values(cls):
        return {"P": 100.0, "A": 10.0, "B": 20.0, "E": 210e3, "NU": 0.3}

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        return check_lame(self, run)


def check_lame(chk: Lame, run: RunResults) -> dict[str, Any]:
    P, A, B, E, nu = chk.values["P"], chk.a, chk.b, chk.e, chk.nu
    disp = _step_ends(run)
    d = rows(disp, disp["step"] == disp["step"][-1])
    x = d["x"].astype(float)
    tol = 1e-9 * max(abs(B), 1.0)
    u_in = float(d["u1"][np.abs(x - x.min()) <= tol].mean())
    u_out = float(d["u1"][np.abs(x - x.max()) <= tol].mean())
    ui_cf, uo_cf = (float(u) for u in lame_radial_displacement([A, B], P, A, B, E, nu))
    return result({"u_inner": u_in, "u_outer": u_out}, {"u_inner": ui_cf, "u_outer": uo_cf},
                  {"u_inner": rel(u_in, ui_cf), "u_outer": rel(u_out, uo_cf)})


class LimitPressure(Check):
    """A perfectly plastic thick cylinder: the pressure reached against Hill's limit pressure."""

    params = (Param("P", float, gt=0.0, unit="stress", doc="pressure at the end of the ramp"),
              Param("SIGMAY", float, gt=0.0, unit="stress", doc="yield stress"),
              Param("A", float, gt=0.0, unit="length", doc="inner radius"),
              Param("B", float, gt=0.0, unit="length", doc="outer radius"),
              Param("PERIOD", float, 1.0, gt=0.0, doc="time over which the pressure ramps to P"))

    def __init__(self, **values):
        super().__init__(**values)
        _inner_below_outer(self.a, self.b)

    @classmethod
    def example_values(cls):
        return {"P": 200.0, "SIGMAY": 300.0, "A": 10.0, "B": 20.0}

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        return check_limit_pressure(self, run)


def check_limit_pressure(chk: LimitPressure, run: RunResults) -> dict[str, Any]:
    P, sy, A, B, period = chk.values["P"], chk.sigmay, chk.a, chk.b, chk.period
    sta = run.sta()
    if not sta:
        raise CheckError(f"no .sta file of the run in {run.outdir}")
    ok = np.array([str(f) != "yes" for f in sta.get("failed", ["no"] * len(sta.get("time", ())))])
    if not ok.any():
        raise CheckError("no converged increment in the .sta file")
    p_reached = P * float(sta["time"][ok][-1]) / period
    p_lim = 2.0 / math.sqrt(3.0) * sy * math.log(B / A)
    finished = math.isclose(p_reached, P, rel_tol=1e-9)
    if P <= p_lim:
        err = 0.0 if finished else (p_lim - p_reached) / p_lim
    else:
        err = rel(p_reached, p_lim)
    return result({"p": p_reached}, {"p": p_lim}, {"p": err}, err)
