"""Error measures of a run against closed forms: the deck's ``*CHECK`` requests.

A deck declares ``*CHECK, NAME=..., TYPE=...`` with ``KEY=VALUE`` data; the deck builder keeps
them as ``Model.checks`` (dicts with ``name``, ``type``, ``params``, ``where``).
:func:`evaluate_checks` computes each one from the run's output files only (the output contract
of DECKS.md, read back with :mod:`lagamine_py.results`), so it works on a finished run, an
archived reference or a sweep point alike.

Each check type is a function ``f(params, run) -> dict`` registered in :data:`CHECKS` with
:func:`register_check`; it returns ``measured`` and ``closed_form`` values (same keys where they
compare), the relative ``errors`` per quantity and the headline ``error``.  Types:

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
    Last increment, points not ``open``: ``max |gap - P/KP| / (P/KP)``.
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
    ``P t / PERIOD`` at the last converged increment of the ``.sta`` file; closed form (Hill,
    thick cylinder in plane strain) ``p_lim = (2 / sqrt 3) SIGMAY ln(B / A)``.  When ``P`` is
    below ``p_lim`` the run must finish: error 0 if it did, else the shortfall; when ``P`` is
    above, ``error = |p_reached - p_lim| / p_lim``.

A check that cannot be evaluated (a file or a column missing, no contact) gets ``error`` NaN and
a ``message`` saying why; it never raises.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy.integrate import trapezoid
from scipy.optimize import brentq

from .results import RunResults

__all__ = ["CHECKS", "register_check", "evaluate_checks", "check_columns", "CheckError",
           "hertz_closed_form", "fit_hertz", "stick_half_width"]

CheckFunction = Callable[[dict[str, Any], RunResults], dict[str, Any]]
CHECKS: dict[str, CheckFunction] = {}
_REQUIRED = object()


class CheckError(Exception):
    """A check cannot be evaluated from the files at hand (the message says why)."""


def register_check(name: str) -> Callable[[CheckFunction], CheckFunction]:
    """Decorator: register ``f(params, run) -> dict`` as the check type ``name`` (upper-cased)."""
    def deco(func: CheckFunction) -> CheckFunction:
        CHECKS[name.upper()] = func
        return func
    return deco


def evaluate_checks(model_checks: list[dict[str, Any]], outdir: Path) -> list[dict[str, Any]]:
    """Evaluate every ``*CHECK`` of a model on the output directory ``outdir``.

    Returns one dict per check: ``name``, ``type``, ``error`` (headline relative error, NaN when
    it cannot be evaluated), ``measured``, ``closed_form``, ``errors`` (per quantity) and
    ``message`` ("" when all went well).
    """
    run = RunResults(Path(outdir))
    out = []
    for chk in model_checks:
        name, kind = str(chk.get("name", "")), str(chk.get("type", "")).upper()
        entry = {"name": name or kind, "type": kind, "error": math.nan, "measured": {},
                 "closed_form": {}, "errors": {}, "message": ""}
        func = CHECKS.get(kind)
        if func is None:
            entry["message"] = f"unknown check type {kind!r} (known: {', '.join(sorted(CHECKS))})"
        else:
            try:
                entry.update(func(_upper_keys(chk.get("params", {})), run))
            except CheckError as exc:
                entry["message"] = str(exc)
            except (OSError, KeyError, IndexError, ValueError, ZeroDivisionError) as exc:
                entry["message"] = f"{type(exc).__name__}: {exc}"
        out.append(entry)
    return out


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


# ---------------------------------------------------------------- helpers


def _upper_keys(params: dict[str, Any]) -> dict[str, Any]:
    return {str(k).upper(): v for k, v in dict(params or {}).items()}


def _num(params: dict[str, Any], key: str, default: Any = _REQUIRED) -> float:
    if key not in params:
        if default is _REQUIRED:
            raise CheckError(f"parameter {key} is missing")
        return default
    try:
        return float(str(params[key]).replace("D", "E").replace("d", "e"))
    except ValueError:
        raise CheckError(f"parameter {key}={params[key]!r} is not a number") from None


def _table(run: RunResults, name: str, columns: tuple[str, ...]) -> dict[str, np.ndarray]:
    tab = run.table(name)
    if not tab or len(tab.get("step", ())) == 0:
        raise CheckError(f"{name} is missing or empty in {run.outdir}")
    missing = [c for c in columns if c not in tab]
    if missing:
        raise CheckError(f"{name} has no column {', '.join(missing)}")
    return tab


def _rows(tab: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    return {k: v[mask] for k, v in tab.items()}


def _last_increment(tab: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Rows of the last (step, increment) written (tables are written in time order)."""
    mask = (tab["step"] == tab["step"][-1]) & (tab["increment"] == tab["increment"][-1])
    return _rows(tab, mask)


def _one_contact(tab: dict[str, np.ndarray], params: dict[str, Any],
                 name: str = "contact_totals.csv") -> dict[str, np.ndarray]:
    """Rows of contact pair ``CONTACT=`` if given, else of the first pair in the table.  The pair
    is named ``SURFACE->FOUNDATION`` in the tables; ``CONTACT=`` may give the surface alone (a
    deck's data line cannot hold ``->``), which must then name one pair."""
    names = np.array([str(n).upper() for n in tab["contact"]])
    want = str(params.get("CONTACT", names[0])).upper()
    mask = names == want
    if not mask.any():
        mask = np.array([n.split("->")[0] == want for n in names])
        pairs = sorted(set(names[mask]))
        if len(pairs) > 1:
            raise CheckError(f"CONTACT={want} names {len(pairs)} contact pairs in {name}: "
                             f"{', '.join(pairs)}")
    if not mask.any():
        raise CheckError(f"{name} has no contact {want!r}")
    return _rows(tab, mask)


def _points(run: RunResults, columns: tuple[str, ...], params: dict[str, Any]) -> dict[str, np.ndarray]:
    """contact.csv rows of one contact pair (``CONTACT=``, else the first), when the table names
    its pairs; every row of a table written before it had the ``contact`` column."""
    tab = _table(run, "contact.csv", columns)
    return _one_contact(tab, params, "contact.csv") if "contact" in tab else tab


def _rel(measured: float, exact: float) -> float:
    return abs(measured - exact) / abs(exact) if exact != 0 else math.inf


def _result(measured: dict, closed: dict, errors: dict, error: float | None = None) -> dict:
    head = max(errors.values()) if error is None else error
    return {"measured": measured, "closed_form": closed, "errors": errors, "error": float(head)}


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
    m0 = trapezoid(ps, xs)
    return math.sqrt(4.0 * trapezoid(xs**2 * ps, xs) / m0) if m0 > 0 else math.nan


def _centre(params: dict[str, Any], x: np.ndarray, p: np.ndarray) -> float:
    """``X0``; 0 with ``SYMMETRY=2``; else the centroid of the pressure ``sum x p / sum p`` (the
    Hertz and Cattaneo pressures are even about the centre; the largest ``p`` is not a safe
    centre, a penalty contact may peak anywhere near the top of the profile)."""
    if "X0" in params:
        return _num(params, "X0")
    if _num(params, "SYMMETRY", 1.0) == 2.0:
        return 0.0
    w = np.clip(p, 0.0, None)
    return float(np.sum(x * w) / np.sum(w)) if np.sum(w) > 0 else float(x[np.argmax(p)])


@register_check("HERTZ")
def check_hertz(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    R, E, nu = (_num(params, k) for k in ("R", "E", "NU"))
    sym = _num(params, "SYMMETRY", 1.0)
    pts = _last_increment(_points(run, ("x", "p"), params))
    x, p = pts["x"].astype(float), pts["p"].astype(float)
    xc = x - _centre(params, x, p)
    a, p0 = fit_hertz(xc, p)
    measured = {"a": a, "p0": p0, "a_moment": _moment_half_width(xc, p)}
    totals = run.table("contact_totals.csv")
    if totals and len(totals.get("P", ())):
        measured["P"] = sym * abs(float(_last_increment(_one_contact(totals, params))["P"][-1]))
    if "P" in params:
        P = _num(params, "P")
    elif "P" in measured:
        P = measured["P"]       # displacement-driven: the closed form at the force reached
    else:
        raise CheckError("no P given and contact_totals.csv has no P column")
    a_cf, p0_cf = hertz_closed_form(P, R, E, nu)
    return _result(measured, {"a": a_cf, "p0": p0_cf, "a_moment": a_cf, "P": P},
                   {"a": _rel(a, a_cf), "p0": _rel(p0, p0_cf)})


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


def stick_half_width(x: np.ndarray, status: np.ndarray, ratio: np.ndarray, centre: float) -> float:
    """Half-width of the contiguous stick zone around ``centre`` at one increment.

    Parameters
    ----------
    x : (g,) positions of the contact points.
    status : (g,) "open" | "stick" | "slip".
    ratio : (g,) ``|tau| / (phi p)`` (used to place each edge between the last stick and the first
        slip point, see :func:`_sqrt_edge`).
    centre : the contact centre; the stick zone is the run of stick points, in ``x`` order,
        through the point nearest to it (0 if that point is not stick).
    """
    order = np.argsort(x)
    xs, st, rs = x[order], np.asarray(status)[order], ratio[order]
    stick = np.array([str(s) == "stick" for s in st])
    k = int(np.argmin(np.abs(xs - centre)))
    if not stick[k]:
        return 0.0
    lo, hi = k, k
    while lo > 0 and stick[lo - 1]:
        lo -= 1
    while hi < len(xs) - 1 and stick[hi + 1]:
        hi += 1
    # edges: extrapolated toward a following slip point, else the last stick point itself
    right = _sqrt_edge(xs[lo:hi + 1], rs[lo:hi + 1], xs[hi + 1]) if hi < len(xs) - 1 else xs[hi]
    left = (-_sqrt_edge(-xs[lo:hi + 1][::-1], rs[lo:hi + 1][::-1], -xs[lo - 1])
            if lo > 0 else xs[lo])
    return 0.5 * float(right - left)


@register_check("CATTANEO")
def check_cattaneo(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    P, R, E, nu, phi, qratio = (_num(params, k) for k in ("P", "R", "E", "NU", "PHI", "QRATIO"))
    sym = _num(params, "SYMMETRY", 1.0)
    totals = _one_contact(_table(run, "contact_totals.csv", ("P", "T", "contact")), params)
    pts = _points(run, ("x", "p", "tau", "status"), params)
    last = totals["step"][-1]
    totals = _rows(totals, totals["step"] == last)
    pts = _rows(pts, pts["step"] == last)
    ratios, widths, forces = [], [], []
    for inc, Q, Pn in zip(totals["increment"], np.abs(totals["T"]), np.abs(totals["P"])):
        at = _rows(pts, pts["increment"] == inc)
        if len(at["x"]) == 0 or Pn == 0:
            continue                      # no field output at this increment
        x, p, tau = (at[k].astype(float) for k in ("x", "p", "tau"))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(p > 0, np.abs(tau) / (phi * p), 1.0)
        centre = _centre(params, x, p)
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
    return _result({"c": c, "P": Pn, "c_over_a": c / a},
                   {"c": c_cf, "P": P, "c_over_a": c_cf / a, "a": a}, {"c": err}, err)


# ---------------------------------------------------------------- Coulomb, penetration


@register_check("COULOMB")
def check_coulomb(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    phi, b, area = (_num(params, k) for k in ("PHI", "B", "A"))
    totals = _last_increment(_one_contact(_table(run, "contact_totals.csv", ("P", "T", "contact")),
                                          params))
    P, T = abs(float(totals["P"][-1])), abs(float(totals["T"][-1]))
    T_cf = phi * P + b * area
    return _result({"T": T, "P": P}, {"T": T_cf}, {"T": _rel(T, T_cf)})


@register_check("PENETRATION")
def check_penetration(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    d_cf = _num(params, "P") / _num(params, "KP")
    pts = _last_increment(_points(run, ("gap", "status"), params))
    closed = np.array([str(s) != "open" for s in pts["status"]])
    if not closed.any():
        raise CheckError("no contact point is closed at the last increment")
    gap = pts["gap"][closed].astype(float)
    errs = np.abs(gap - d_cf) / abs(d_cf)
    k = int(np.argmax(errs))
    return _result({"gap": float(gap[k]), "gap_mean": float(gap.mean())},
                   {"gap": d_cf, "gap_mean": d_cf}, {"gap": float(errs[k])})


# ---------------------------------------------------------------- bodies


def _step_ends(run: RunResults) -> dict[str, np.ndarray]:
    return _table(run, "displacements.csv", ("x", "y", "u1", "u2"))


@register_check("UNIAXIAL_RO")
def check_uniaxial_ro(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    E, s0, alpha, n, r0, h0 = (_num(params, k) for k in ("E", "SIGMA0", "ALPHA", "N", "R0", "H0"))
    disp = _step_ends(run)
    reac = _table(run, "reactions.csv", ("nset", "RF2"))
    nsets = np.array([str(s).upper() for s in reac["nset"]], dtype=object)
    if "NSET" in params:
        want = str(params["NSET"]).upper()
    else:
        last = _last_increment(reac)
        want = str(last["nset"][int(np.argmax(np.abs(last["RF2"])))]).upper()
    reac = _rows(reac, nsets == want)
    if len(reac["step"]) == 0:
        raise CheckError(f"reactions.csv has no node set {want}")
    rows = []
    for step in np.unique(disp["step"]):
        d = _rows(disp, disp["step"] == step)
        r_ = _rows(reac, reac["step"] == step)
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
        rows.append((int(step), s, eps, eps_cf, s_cf, r))
    if not rows:
        raise CheckError(f"no step has both displacements.csv rows and reactions of {want}")
    errs = [_rel(e, ecf) for _, _, e, ecf, _, _ in rows]
    k = int(np.argmax(errs))
    step, s, eps, eps_cf, s_cf, r = rows[k]
    return _result({"stress": s, "strain": eps, "radius": r, "step": step},
                   {"strain": eps_cf, "stress": s_cf},
                   {"strain": errs[k], "stress": _rel(s, s_cf)}, errs[k])


def _ro_strain(s: float, E: float, s0: float, alpha: float, n: float) -> float:
    """Ramberg-Osgood uniaxial strain ``s/E + alpha (s0/E) (s/s0)^n`` (s >= 0)."""
    return s / E + alpha * (s0 / E) * (s / s0) ** n


def lame_radial_displacement(r, P: float, A: float, B: float, E: float, nu: float):
    """Radial displacement of a thick cylinder (radii A < B) under internal pressure P, plane
    strain (axial strain 0): ``u = (1+nu) P A^2 / (E (B^2-A^2)) ((1-2 nu) r + B^2/r)``."""
    r = np.asarray(r, float)
    return (1.0 + nu) * P * A**2 / (E * (B**2 - A**2)) * ((1.0 - 2.0 * nu) * r + B**2 / r)


@register_check("LAME")
def check_lame(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    P, A, B, E, nu = (_num(params, k) for k in ("P", "A", "B", "E", "NU"))
    disp = _step_ends(run)
    d = _rows(disp, disp["step"] == disp["step"][-1])
    x = d["x"].astype(float)
    tol = 1e-9 * max(abs(B), 1.0)
    u_in = float(d["u1"][np.abs(x - x.min()) <= tol].mean())
    u_out = float(d["u1"][np.abs(x - x.max()) <= tol].mean())
    ui_cf, uo_cf = (float(u) for u in lame_radial_displacement([A, B], P, A, B, E, nu))
    return _result({"u_inner": u_in, "u_outer": u_out}, {"u_inner": ui_cf, "u_outer": uo_cf},
                   {"u_inner": _rel(u_in, ui_cf), "u_outer": _rel(u_out, uo_cf)})


@register_check("LIMIT_PRESSURE")
def check_limit_pressure(params: dict[str, Any], run: RunResults) -> dict[str, Any]:
    P, sy, A, B = (_num(params, k) for k in ("P", "SIGMAY", "A", "B"))
    period = _num(params, "PERIOD", 1.0)
    stas = sorted(run.outdir.glob("*.sta"))
    if not stas:
        raise CheckError(f"no .sta file in {run.outdir}")
    sta = RunResults(run.outdir).table(stas[0].name)
    ok = np.array([str(f) != "yes" for f in sta.get("failed", ["no"] * len(sta.get("time", ())))])
    if not ok.any():
        raise CheckError("no converged increment in the .sta file")
    p_reached = P * float(sta["time"][ok][-1]) / period
    p_lim = 2.0 / math.sqrt(3.0) * sy * math.log(B / A)
    finished = math.isclose(p_reached, P, rel_tol=1e-9)
    if P <= p_lim:
        err = 0.0 if finished else (p_lim - p_reached) / p_lim
    else:
        err = _rel(p_reached, p_lim)
    return _result({"p": p_reached}, {"p": p_lim}, {"p": err}, err)
