"""``*CHECK, TYPE=FRETTING``: a cylinder pressed and then rocked sideways (decks/fretting.dat).

``FRETTING`` (``R, E, NU, PHI``, optional ``LOAD`` (step number, default 2), ``QRATIO`` (default
0.5), ``CONTACT``)
    The deck presses (steps before ``LOAD``), loads tangentially from 0 to ``Q*`` in step
    ``LOAD``, and then runs full cycles ``Q* -> -Q* -> Q*``, one step each (at least one).
    Closed forms, line contact of two half-planes without normal-tangential coupling (identical
    materials, or incompressible ones), ``E`` and ``NU`` the pair's (``E*`` and 0 for dissimilar
    bodies), ``a`` from Hertz at the measured normal force (Johnson, Contact Mechanics §4.2,
    §7.1, §7.3):

    * ``c``: the stick half-width in step ``LOAD`` at ``Q / (PHI P) = QRATIO`` (interpolated
      between increments, as ``CATTANEO``): Cattaneo-Mindlin ``c / a = sqrt(1 - QRATIO)``.
    * ``c_rev``: the stick half-width in the first half of the first cycle where ``Q`` passes
      through 0 (the tangential load has fallen by ``Q*``): Mindlin-Deresiewicz ``c' / a =
      sqrt(1 - Q* / (2 PHI P))`` (the reverse slip zone ``c' < |x| < a``).
    * ``q``: the shear traction at the end of step ``LOAD`` against ``q(x) = PHI p0 [sqrt(1 -
      x^2/a^2) - (c/a) sqrt(1 - x^2/c^2)]`` (second term for ``|x| < c``), ``c = a sqrt(1 -
      Q*/(PHI P))``, ``x`` from the pressure's centroid: root mean square of the difference over
      the points with ``p > 0``, divided by ``PHI p0``; reported, ``q_max`` against the peak
      ``PHI p0 sqrt(1 - c^2/a^2)`` at the stick zone's edge, the offset of the run's stick zone
      from the pressure's centroid (``stick_shift_over_a``) and the RMS error with the stick
      term centred there (``q_error_shifted``).
    * ``cycle<k>``: energy over cycle ``k`` (energy.csv, the run keeps it with ``*CHECK,
      TYPE=ENERGY``): the work of the loads ``W`` against the frictional dissipation ``D`` of the
      cycle, ``|W - D| / W``; exact in the limit of small increments once the loop is closed
      (the state, hence the stored energy, returns).  Reported: ``W``, ``D``, the change of the
      stored (elastic and penalty) energy and the dissipation the contact tables write
      (``dissipated_energy`` of contact_totals.csv, the law's path integral).
    * ``steady``: the last cycle's dissipation against the previous one's, relative (the loop
      repeats; needs two cycles).

    ``error`` = the largest of these; ``c`` and ``c_rev`` are divided by ``a``.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.params import Param
from ..results import RunResults
from .base import Check, CheckError, contact_points, one_contact, result, rows, table
from .closed_forms import hertz_closed_form, stick_edges, stick_half_width

__all__ = ["Fretting", "mindlin_traction", "step_widths"]


def mindlin_traction(x: np.ndarray, a: float, c: float, phi_p0: float) -> np.ndarray:
    """Cattaneo-Mindlin shear traction ``q(x)`` (same sign as ``Q``) of a line contact of
    half-width ``a`` with stick half-width ``c``: ``phi p0 [sqrt(1 - x^2/a^2) - (c/a) sqrt(1 -
    x^2/c^2)]``, each root 0 outside its zone."""
    full = np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))
    core = np.sqrt(np.clip(1.0 - (x / c) ** 2, 0.0, None)) if c > 0 else 0.0 * x
    return phi_p0 * (full - (c / a) * core)


def _centroid(x: np.ndarray, p: np.ndarray) -> float:
    w = np.clip(p, 0.0, None)
    return float(np.sum(x * w) / np.sum(w))


def step_widths(totals: dict, pts: dict, step: int, phi: float) -> dict[str, np.ndarray]:
    """Per increment of ``step`` with contact output: signed ``T``, ``P``, the stick half-width
    ``c`` about the pressure's centroid (:func:`stick_half_width`) and the centroid ``x0``."""
    tt = rows(totals, totals["step"] == step)
    pp = rows(pts, pts["step"] == step)
    out: dict[str, list] = {"T": [], "P": [], "c": [], "x0": [], "increment": []}
    for inc, T, P in zip(tt["increment"], tt["T"], tt["P"]):
        at = rows(pp, pp["increment"] == inc)
        x, p, tau = (np.asarray(at[k], float) for k in ("x", "p", "tau"))
        if len(x) == 0 or not (p > 0).any():
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(p > 0, np.abs(tau) / (phi * p), 1.0)
        x0 = _centroid(x, p)
        for k, v in (("T", T), ("P", abs(P)), ("x0", x0), ("increment", inc),
                     ("c", stick_half_width(x, at["status"], ratio, x0))):
            out[k].append(float(v))
    return {k: np.asarray(v) for k, v in out.items()}


class Fretting(Check):
    """Fretting of a cylinder under constant P and cyclic Q: Cattaneo-Mindlin stick zone and
    traction, Mindlin-Deresiewicz reverse slip, the energy of every cycle and the steady loop."""

    params = (Param("R", float, gt=0.0, unit="length", doc="the pair's radius (1/R = 1/R1 + 1/R2)"),
              Param("E", float, gt=0.0, unit="stress", doc="Young's modulus (the pair's E* with NU=0)"),
              Param("NU", float, bounds=(-1.0, 0.5), doc="Poisson's ratio"),
              Param("PHI", float, gt=0.0, doc="friction coefficient"),
              Param("LOAD", int, 2, bounds=(1, 10**6), doc="the step that loads Q from 0 to Q*"),
              Param("QRATIO", float, 0.5, bounds=(0.0, 1.0), doc="Q / (PHI P) where c is measured"),
              Param("CONTACT", str, None, upper=True,
                    doc="the contact pair, by its surface (default: the first pair)"))

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        return check_fretting(self, run)


def _loading(chk: Fretting, w: dict) -> tuple[dict, dict, dict]:
    ratio = np.abs(w["T"]) / (chk.phi * w["P"])
    if len(ratio) < 2 or not ratio.min() <= chk.qratio <= ratio.max():
        raise CheckError(f"step {chk.load}: Q/(PHI P) does not reach QRATIO={chk.qratio:g}")
    order = np.argsort(ratio)
    c = float(np.interp(chk.qratio, ratio[order], w["c"][order]))
    a = hertz_closed_form(float(np.interp(chk.qratio, ratio[order], w["P"][order])),
                          chk.r, chk.e, chk.nu)[0]
    c_cf = a * math.sqrt(1.0 - chk.qratio)
    return {"c_over_a": c / a}, {"c_over_a": c_cf / a}, {"c": abs(c - c_cf) / a}


def _unloading(chk: Fretting, w: dict, q_star: float, sign: float, P: float) -> tuple[dict, dict, dict]:
    """c' where the first cycle's Q (signed like Q*) falls through 0."""
    s = sign * w["T"]
    turn = int(np.argmin(s))                          # -Q*: the end of the first half-cycle
    s, c = s[:turn + 1], w["c"][:turn + 1]
    if len(s) < 2 or not s.min() <= 0.0 <= s.max():
        raise CheckError(f"step {chk.load + 1}: Q does not pass through 0 in its first half")
    c_rev = float(np.interp(0.0, s[::-1], c[::-1]))
    Pn = float(np.interp(0.0, s[::-1], w["P"][:turn + 1][::-1]))
    a = hertz_closed_form(Pn, chk.r, chk.e, chk.nu)[0]
    cf = a * math.sqrt(1.0 - q_star / (2.0 * chk.phi * P))
    return {"c_rev_over_a": c_rev / a}, {"c_rev_over_a": cf / a}, {"c_rev": abs(c_rev - cf) / a}


def _traction(chk: Fretting, pts: dict, step: int, inc: float, q_star: float, P: float):
    at = rows(pts, (pts["step"] == step) & (pts["increment"] == inc))
    x, p, tau = (np.asarray(at[k], float) for k in ("x", "p", "tau"))
    a, p0 = hertz_closed_form(P, chk.r, chk.e, chk.nu)
    c = a * math.sqrt(max(1.0 - q_star / (chk.phi * P), 0.0))
    on = p > 0
    sign = 1.0 if np.sum(tau[on]) >= 0 else -1.0
    x0 = _centroid(x, p)
    q_cf = mindlin_traction(x[on] - x0, a, c, chk.phi * p0)
    err = float(np.sqrt(np.mean((sign * tau[on] - q_cf) ** 2))) / (chk.phi * p0)
    # the same with the stick zone's term centred where the run's stick zone is (finite bodies
    # shift it; reported, not checked)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(on, np.abs(tau) / (chk.phi * p), 1.0)
    left, right = stick_edges(x, at["status"], ratio, x0)
    e = 0.5 * (left + right)
    q_sh = q_cf + (c / a) * chk.phi * p0 * (
        np.sqrt(np.clip(1.0 - ((x[on] - x0) / c) ** 2, 0.0, None))
        - np.sqrt(np.clip(1.0 - ((x[on] - e) / c) ** 2, 0.0, None)))
    shifted = float(np.sqrt(np.mean((sign * tau[on] - q_sh) ** 2))) / (chk.phi * p0)
    # the peak of q, at the stick zone's edge: phi p(c) = phi p0 sqrt(1 - c^2/a^2)
    q_max = chk.phi * p0 * math.sqrt(1.0 - (c / a) ** 2)
    measured = {"q_max": float(np.max(sign * tau[on])), "stick_shift_over_a": (e - x0) / a,
                "q_error_shifted": shifted}
    return measured, {"q_max": q_max}, {"q": err}


def _cycles(run: RunResults, chk: Fretting, steps: np.ndarray, totals: dict):
    """Energy of every cycle (steps after LOAD) from energy.csv and contact_totals.csv."""
    tab = table(run, "energy.csv", ("step", "work", "elastic", "friction", "penalty"))
    st = np.asarray(tab["step"], int)
    ends = {int(k): np.flatnonzero(st == k)[-1] for k in np.unique(st)}
    tst = np.asarray(totals["step"], int)
    tend = {int(k): np.flatnonzero(tst == k)[-1] for k in np.unique(tst)}
    measured, closed, errors, D = {}, {}, {}, []
    for k in steps:
        i0, i1 = ends[int(k) - 1], ends[int(k)]
        W = float(tab["work"][i1] - tab["work"][i0])
        Dk = float(tab["friction"][i1] - tab["friction"][i0])
        stored = float(tab["elastic"][i1] + tab["penalty"][i1] - tab["elastic"][i0] - tab["penalty"][i0])
        n = int(k) - chk.load
        measured.update({f"D_{n}": Dk, f"stored_{n}": stored, f"W_{n}": W})
        if "dissipated_energy" in totals:
            e = totals["dissipated_energy"]
            measured[f"D_tables_{n}"] = float(e[tend[int(k)]] - e[tend[int(k) - 1]])
        closed[f"D_{n}"] = W
        errors[f"cycle{n}"] = abs(W - Dk) / abs(W)
        D.append(Dk)
    if len(D) >= 2:
        errors["steady"] = abs(D[-1] - D[-2]) / abs(D[-2])
    return measured, closed, errors


def check_fretting(chk: Fretting, run: RunResults) -> dict[str, Any]:
    totals = one_contact(table(run, "contact_totals.csv", ("P", "T", "contact")), chk.contact)
    pts = contact_points(run, ("x", "p", "tau", "status"), chk.contact)
    steps = np.unique(np.asarray(totals["step"], int))
    cycles = steps[steps > chk.load]
    if chk.load not in steps or not len(cycles):
        raise CheckError(f"no step {chk.load} (the loading) followed by cycles in contact_totals.csv")
    load = step_widths(totals, pts, chk.load, chk.phi)
    first = step_widths(totals, pts, chk.load + 1, chk.phi)
    if not len(load["T"]) or not len(first["T"]):
        raise CheckError(f"no contact output in step {chk.load} or {chk.load + 1}")
    q_star, sign, P = abs(load["T"][-1]), float(np.sign(load["T"][-1])), load["P"][-1]
    measured = {"Q_star_over_phiP": q_star / (chk.phi * P), "P": P}
    closed: dict[str, float] = {}
    errors: dict[str, float] = {}
    parts = (_loading(chk, load), _unloading(chk, first, q_star, sign, P),
             _traction(chk, pts, chk.load, load["increment"][-1], q_star, P),
             _cycles(run, chk, cycles, totals))
    for m, c, e in parts:
        measured.update(m)
        closed.update(c)
        errors.update(e)
    return result(measured, closed, errors)
