"""Numba kernels of the solid groups: element computation and scatter fused, element by element.

The optional fast path of :class:`~lagamine_py.elements.solid.SolidGroup` (``pip install
lagamine_py[fast]``).  For one group it computes, element by element and Gauss point by Gauss
point, exactly what ``SolidGroup._small_strain`` / ``_large_strain`` compute with the laws
ELASTIC, J2_LINEAR and RAMBERG_OSGOOD (same formulas, same return maps, same tolerances and
failure signalling), and adds the element tangent straight into the CSR ``data`` array at the
cached pattern positions and the element force into the global vector: no (e, nd, nd) array
is ever formed.  The NumPy path stays the reference; results agree to round-off.

Array axes as in :mod:`lagamine_py.elements.solid`: ``e`` element, ``q`` Gauss point, ``a``/``b``
node, ``i``/``j``/``k``/``n`` spatial component, ``s``/``t`` 4-vector component
[11, 22, 33, 12], ``d`` element DOF ``2 a + i``.

One compiled specialisation serves every element type, law and kinematics (they are run-time
arguments), so the first call compiles once; ``cache=True`` keeps the machine code on disk.
``parallel=False``: the factorisation uses the cores.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import calls
from .layout import (BAD_DET_F, ELASTIC, J2_LINEAR, OK, RETURN_MAP_FAILED, YIELD_RTOL,
                     SOLID_A as _A, SOLID_G as _G, SOLID_H as _H, SOLID_K as _K,
                     SOLID_MAXIT as _MAXIT, SOLID_N as _N, SOLID_SIGMAY as _SIGMAY,
                     SOLID_TOL as _TOL)
from .scalars import nmax as _nmax, nmin as _nmin

__all__ = ["scratch_arrays", "solid_group", "start_group"]

# _nrt=False: no reference counting.  The kernels allocate nothing (the caller passes the work
# arrays), and without it every array handed to an inlined helper costs atomic increments and
# decrements per Gauss point: measured 2.35 -> 0.34 us per Q8 element (small strain, no tangent).
_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True, _nrt=False)


def scratch_arrays(nen: int, nq: int) -> tuple:
    """Work arrays of the kernels (they allocate nothing themselves, see ``_JIT``): nodal
    displacements new/old (a, 2), F (q, 2, 2), F33 (q,), radius (q,), gradients (a, 2), hoop
    row (a,), element force (d,), element tangent (d, d), trial strain, stress, D (4, 4),
    elastic strain, M (4, d)."""
    nd = 2 * nen
    return (np.empty((nen, 2)), np.empty((nen, 2)), np.empty((nq, 2, 2)), np.empty(nq),
            np.empty(nq), np.empty((nen, 2)), np.empty(nen), np.empty(nd), np.zeros((nd, nd)),
            np.empty(4), np.empty(4), np.empty((4, 4)), np.empty(4), np.empty((4, nd)))


# --------------------------------------------------------------------------------------------
# scalar helpers (min and max with NumPy's NaN semantics: lagamine_py.kernels.scalars)

@njit(**_JIT)
def _sym_eig2(a, b, c):
    """Eigenvalues (l0 >= l1) of [[a, c], [c, b]] and ``cos 2t``, ``sin 2t`` of the angle t of
    its first eigenvector (``sym_eig2``: t = atan2(c, (a - b)/2) / 2, t = 0 for a multiple
    eigenvalue), without trigonometric functions.  The eigenprojections are
    ``P0 = [[1 + cos, sin], [sin, 1 - cos]] / 2``, ``P1 = I - P0`` and
    ``S = v0 v1^T + v1 v0^T = [[-sin, cos], [cos, sin]]``."""
    m, h = 0.5 * (a + b), 0.5 * (a - b)
    rho = math.sqrt(h * h + c * c)
    if rho > 0.0:
        return m + rho, m - rho, h / rho, c / rho
    return m, m, 1.0, 0.0


# --------------------------------------------------------------------------------------------
# Ramberg-Osgood return map (lagamine_py.laws.ramberg_osgood, point by point)

@njit(**_JIT)
def _ro_residual(by_q, x, qt, pn, G3, a, n):
    """``_g_q`` (by_q, x = ln q) or ``_g_p`` (x = ln P): residual and derivative."""
    if by_q:
        q = math.exp(x)
        P = pn + (qt - q) / G3
        if P > 0.0:
            return a + n * x - math.log(P), n + q / (G3 * P)
        return math.inf, math.inf
    P = math.exp(x)
    q = qt - G3 * (P - pn)
    if q > 0.0:
        return x - a - n * math.log(q), 1.0 + n * G3 * P / q
    return math.inf, math.inf


@njit(**_JIT)
def _safeguarded_newton(by_q, lo, hi, tol, max_iter, qt, pn, G3, a, n):
    """``safeguarded_newton`` for one point: Newton from ``hi``, bisection fallback."""
    x = hi
    for _ in range(max_iter):
        g, dg = _ro_residual(by_q, x, qt, pn, G3, a, n)
        if g > 0.0:
            hi = x
        if g <= 0.0:
            lo = x
        x_newton = x - g / dg
        newton = (x_newton >= lo) and (x_newton <= hi)
        x_new = x_newton if newton else 0.5 * (lo + hi)
        done = (newton and abs(x_new - x) <= tol) or (hi - lo <= tol) or (g == 0.0)
        x = x_new
        if done:
            return x, True
    return x, False


@njit(**_JIT)
def _ro_log_yield(peeq, a, n):
    return (math.log(peeq) - a) / n


@njit(**_JIT)
def _ro_return_map(qt, pn, ln_pn, G3, a, n, tol, max_iter):
    """``RambergOsgood._return_map`` for one plastic point: (q, peeq, dq/dq_tr, ok);
    ``ln_pn = ln peeq_n`` (computed once for the yield test and the bracket)."""
    x_star = math.log(n * (qt + G3 * pn) / (n + 1.0))
    lo = _nmax((ln_pn - a) / n,
               _nmin(math.log(0.5 * qt), _ro_log_yield(pn + qt / (2.0 * G3), a, n)))
    hi = _nmin(math.log(qt), _ro_log_yield(pn + qt / G3, a, n))
    by_q = (x_star >= hi) or (_ro_residual(True, _nmin(x_star, hi), qt, pn, G3, a, n)[0] >= 0.0)
    if by_q:
        x, ok = _safeguarded_newton(True, lo, _nmin(hi, x_star), tol, max_iter, qt, pn, G3, a, n)
        q = math.exp(x)
        peeq = pn + (qt - q) / G3
    else:
        y_lo = _nmax(ln_pn, a + n * x_star)
        y_hi = _nmin(math.log(pn + (qt - math.exp(x_star)) / G3), a + n * hi)
        y, ok = _safeguarded_newton(False, y_lo, y_hi, tol, max_iter, qt, pn, G3, a, n)
        peeq = math.exp(y)
        q = qt - G3 * (peeq - pn)
    return q, peeq, q / (q + G3 * n * peeq), ok


# --------------------------------------------------------------------------------------------
# the laws' update for one point

@njit(inline="always", **_JIT)
def _law_update(kind, lp, Del, eps, peeq_n, stress, D, eps_e):
    """Return mapping of one point: fills ``stress`` (4,), ``D`` (4, 4), ``eps_e`` (4,);
    returns ``(peeq, ok)`` (``MaterialLaw.update`` of ELASTIC, J2_LINEAR, RAMBERG_OSGOOD)."""
    if kind == ELASTIC:
        for s in range(4):
            acc = 0.0
            for t in range(4):
                acc += eps[t] * Del[s, t]
            stress[s] = acc
            eps_e[s] = eps[s]
            for t in range(4):
                D[s, t] = Del[s, t]
        return peeq_n, True

    K, G = lp[_K], lp[_G]
    G2 = 2.0 * G
    tr = eps[0] + eps[1] + eps[2]
    third = tr / 3.0
    s0, s1, s2 = G2 * (eps[0] - third), G2 * (eps[1] - third), G2 * (eps[2] - third)
    s3 = G2 * 0.5 * eps[3]
    norm_tr = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2 + 2.0 * s3 * s3)
    q_tr = math.sqrt(1.5) * norm_tr
    ln_pn = 0.0
    if kind == J2_LINEAR:
        sy_n = lp[_SIGMAY] + lp[_H] * peeq_n
    else:
        ln_pn = math.log(peeq_n)
        sy_n = math.exp((ln_pn - lp[_A]) / lp[_N])
    plastic = q_tr > sy_n * (1.0 + YIELD_RTOL)

    q, peeq, dq, ok = q_tr, peeq_n, 1.0, True
    if plastic:
        G3 = 3.0 * G
        if kind == J2_LINEAR:
            H = lp[_H]
            dp = (q_tr - sy_n) / (G3 + H)
            q, peeq, dq = q_tr - G3 * dp, peeq_n + dp, H / (G3 + H)
        else:
            q, peeq, dq, ok = _ro_return_map(q_tr, peeq_n, ln_pn, G3, lp[_A], lp[_N],
                                             lp[_TOL], int(lp[_MAXIT]))
    theta = q / q_tr if plastic else 1.0
    sv0, sv1, sv2, sv3 = theta * s0, theta * s1, theta * s2, theta * s3
    Ktr = K * tr
    stress[0], stress[1], stress[2], stress[3] = sv0 + Ktr, sv1 + Ktr, sv2 + Ktr, sv3
    if plastic:
        # elastic strain of the returned stress: same volume, deviator s / 2G (shear s12 / G)
        eps_e[0], eps_e[1], eps_e[2] = third + sv0 / G2, third + sv1 / G2, third + sv2 / G2
        eps_e[3] = 2.0 * (sv3 / G2)
        # D = K 1x1 + 2G theta P_dev + 2G (dq/dq_tr - theta) n x n
        nv0, nv1 = s0 / norm_tr, s1 / norm_tr
        nv2, nv3 = s2 / norm_tr, s3 / norm_tr
        a_dev, b_nn = G2 * theta, G2 * (dq - theta)
        for s in range(4):
            ns = nv0 if s == 0 else nv1 if s == 1 else nv2 if s == 2 else nv3
            for t in range(4):
                nt = nv0 if t == 0 else nv1 if t == 1 else nv2 if t == 2 else nv3
                if s < 3 and t < 3:
                    dev = (1.0 if s == t else 0.0) - 1.0 / 3.0
                    D[s, t] = K + a_dev * dev + b_nn * ns * nt
                elif s == 3 and t == 3:
                    D[s, t] = a_dev * 0.5 + b_nn * ns * nt
                else:
                    D[s, t] = b_nn * ns * nt
    else:
        for s in range(4):
            eps_e[s] = eps[s]
            for t in range(4):
                D[s, t] = Del[s, t]
    for s in range(4):
        if not math.isfinite(stress[s]):
            ok = False
        for t in range(4):
            if not math.isfinite(D[s, t]):
                ok = False
    return peeq, ok


# --------------------------------------------------------------------------------------------
# the element loop

@njit(**_JIT)
def _solid_kernel(nlgeom, tangent, axisym, kind, lp, Del, conn, u_new, u_old, Nq, dNdX, R0, w0,
                 eps_e_n, peeq_n, old, bad_old, eps_e_out, peeq_out, stress_out, fe, flags,
                 data, f_out, pos, dofs, scratch):
    """Compute every element of a group and scatter it.

    Inputs: ``conn`` (e, a); ``u_new``/``u_old`` (n, 2); ``Nq`` (q, a); ``dNdX`` (e, q, a, 2);
    ``R0``/``w0`` (e, q); the committed ``eps_e_n`` (e, q, 4), ``peeq_n`` (e, q); NLGEOM:
    ``old`` (e, q, 9) and ``bad_old`` (e,) from :func:`start_kernel`; ``pos`` (e, d, d)
    positions of the element blocks in ``data`` and ``dofs`` (e, d).
    Outputs: the trial state ``eps_e_out``, ``peeq_out``, ``stress_out`` (Cauchy), the element
    forces ``fe`` (e, d), added into ``f_out`` (ndof,); the tangent added into ``data`` (nnz,)
    when ``tangent``; ``flags`` (e,) OK / BAD_DET_F (element skipped) / RETURN_MAP_FAILED.
    ``scratch``: the work arrays of :func:`scratch_arrays`.
    """
    ne, nen = conn.shape
    nq = Nq.shape[0]
    nd = 2 * nen
    ue, uo, F, F33, rq, dx, hh, f, Ke, eps, stress, D, eps_e, M = scratch
    for e in range(ne):
        flags[e] = OK
        for a in range(nen):
            na = conn[e, a]
            ue[a, 0], ue[a, 1] = u_new[na, 0], u_new[na, 1]
            uo[a, 0], uo[a, 1] = u_old[na, 0], u_old[na, 1]
        if nlgeom:
            bad = bad_old[e] != 0
            for q in range(nq):
                _deformation(ue, dNdX, Nq, R0, e, q, axisym, F, F33, rq)
                det = F[q, 0, 0] * F[q, 1, 1] - F[q, 0, 1] * F[q, 1, 0]
                bad |= (det <= 0.0) or (F33[q] <= 0.0)
            if bad:
                flags[e] = BAD_DET_F
                continue
        for d in range(nd):
            f[d] = 0.0
        if tangent:
            for d in range(nd):
                for d2 in range(nd):
                    Ke[d, d2] = 0.0
        for q in range(nq):
            w = w0[e, q]
            if nlgeom:
                ok = _large_strain_point(e, q, F, F33, old, rq, dNdX, Nq, axisym, kind,
                                         lp, Del, eps_e_n, peeq_n, eps_e_out, peeq_out,
                                         stress_out, w, tangent, f, Ke, dx, hh, eps, stress,
                                         D, eps_e, M)
            else:
                ok = _small_strain_point(e, q, ue, uo, dNdX, Nq, R0, axisym, kind, lp, Del,
                                         eps_e_n, peeq_n, eps_e_out, peeq_out, stress_out, w,
                                         tangent, f, Ke, dx, hh, eps, stress, D, eps_e, M)
            if not ok:
                flags[e] = RETURN_MAP_FAILED
        for d in range(nd):
            fe[e, d] = f[d]
            f_out[dofs[e, d]] += f[d]
        if tangent:
            for d in range(nd):
                for d2 in range(nd):
                    data[pos[e, d, d2]] += Ke[d, d2]


@njit(**_JIT)
def _start_kernel(axisym, conn, u_old, Nq, dNdX, R0, eps_e_n, old, bad_old, scratch):
    """What NLGEOM needs of the start of the increment (``SolidGroup._start_of_increment``),
    per point into ``old`` (e, q, 9): F_old^-1 (4, row-major), F33_old, b_e_n = exp(2 eps_e_n)
    in-plane (00, 01, 11) and 33; ``bad_old`` (e,) 1 where det F_old <= 0 or F33_old <= 0."""
    ne, nen = conn.shape
    nq = Nq.shape[0]
    uo, F, F33, r = scratch[1], scratch[2], scratch[3], scratch[4]
    for e in range(ne):
        for a in range(nen):
            uo[a, 0], uo[a, 1] = u_old[conn[e, a], 0], u_old[conn[e, a], 1]
        bad = False
        for q in range(nq):
            _deformation(uo, dNdX, Nq, R0, e, q, axisym, F, F33, r)
            det = F[q, 0, 0] * F[q, 1, 1] - F[q, 0, 1] * F[q, 1, 0]
            bad |= (det <= 0.0) or (F33[q] <= 0.0)
            s = 1.0 / (1.0 if det == 0.0 else det)              # _inv2
            old[e, q, 0], old[e, q, 1] = F[q, 1, 1] * s, -F[q, 0, 1] * s
            old[e, q, 2], old[e, q, 3] = -F[q, 1, 0] * s, F[q, 0, 0] * s
            old[e, q, 4] = F33[q]
            # b_e_n: spectral form of the in-plane Hencky tensor (hencky_to_b)
            l0, l1, cs, sn = _sym_eig2(eps_e_n[e, q, 0], eps_e_n[e, q, 1],
                                       0.5 * eps_e_n[e, q, 3])
            x0, x1 = math.exp(2.0 * l0), math.exp(2.0 * l1)
            old[e, q, 5] = 0.5 * (x0 * (1.0 + cs) + x1 * (1.0 - cs))
            old[e, q, 6] = 0.5 * (x0 - x1) * sn
            old[e, q, 7] = 0.5 * (x0 * (1.0 - cs) + x1 * (1.0 + cs))
            old[e, q, 8] = math.exp(2.0 * eps_e_n[e, q, 2])
        bad_old[e] = 1 if bad else 0


@njit(inline="always", **_JIT)
def _deformation(ue, dNdX, Nq, R0, e, q, axisym, F, F33, r):
    """In-plane F (into F[q]), F33 and the current radius of point q (``_deformation``)."""
    nen = ue.shape[0]
    for i in range(2):
        for j in range(2):
            acc = 0.0
            for a in range(nen):
                acc += ue[a, i] * dNdX[e, q, a, j]
            F[q, i, j] = acc + (1.0 if i == j else 0.0)
    if axisym:
        acc = 0.0
        for a in range(nen):
            acc += Nq[q, a] * ue[a, 0]
        r[q] = R0[e, q] + acc
        F33[q] = r[q] / R0[e, q]
    else:
        r[q] = R0[e, q]
        F33[q] = 1.0


@njit(inline="always", **_JIT)
def _point_law(e, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, stress, D, eps_e):
    """The law at one point; the new eps_e and peeq go to the output state."""
    peeq, ok = _law_update(kind, lp, Del, eps, peeq_n[e, q], stress, D, eps_e)
    for s in range(4):
        eps_e_out[e, q, s] = eps_e[s]
    peeq_out[e, q] = peeq
    return ok


@njit(inline="always", **_JIT)
def _force_and_tangent(nen, dx, hh, tau, D, M, w, tangent, f, Ke, geometric, axisym, Nq, q, r):
    """f += w G^T tau and Ke += w G^T D M (+ the geometric part when ``geometric``), with G the
    strain operator of gradients ``dx`` (a, 2) and hoop row ``hh`` (a,):
    G_a = [[dx_a0, 0], [0, dx_a1], [hh_a, 0], [dx_a1, dx_a0]].

    Geometric part (NLGEOM): ``Kg[a i, b k] = -w dN_a/dx_k (dN_b/dx_j tau_ji)``, and in
    axisymmetry ``Kg[a 0, b 0] -= w tau_33 / r^2 N_a N_b`` (``Nq[q]`` the N_a of the point).
    Node pair by node pair, the w D M columns of node b in scalars: no (4, d) temporaries."""
    t0, t1, t2, t3 = w * tau[0], w * tau[1], w * tau[2], w * tau[3]
    for a in range(nen):
        f[2 * a] += dx[a, 0] * t0 + hh[a] * t2 + dx[a, 1] * t3
        f[2 * a + 1] += dx[a, 1] * t1 + dx[a, 0] * t3
    if not tangent:
        return
    wt00, wt11, wt01 = (t0, t1, t3) if geometric else (0.0, 0.0, 0.0)
    cax = t2 / (r * r) if geometric and axisym else 0.0
    # Exact zeros are left out of the sums: M[2, 2b+1] (a radial stretch only from u_r), in
    # plane strain M[2, :] (no hoop row) and p2, q2 (unread), in small strain the geometric
    # terms.  Each dropped term is a +-0.0 added in place, so a sum it left out differs at most
    # by the sign of a zero, which Ke does not keep (its sums start from +0.0: +0.0 + -0.0 is
    # +0.0); a non-finite D is a failure (the law's ok) before Ke is read.
    for b in range(nen):
        c0, c1 = 2 * b, 2 * b + 1
        m00, m10, m30 = M[0, c0], M[1, c0], M[3, c0]
        m01, m11, m31 = M[0, c1], M[1, c1], M[3, c1]
        # columns of w D M for the two DOFs of node b
        if axisym:
            m20 = M[2, c0]
            p0 = w * (D[0, 0] * m00 + D[0, 1] * m10 + D[0, 2] * m20 + D[0, 3] * m30)
            p1 = w * (D[1, 0] * m00 + D[1, 1] * m10 + D[1, 2] * m20 + D[1, 3] * m30)
            p2 = w * (D[2, 0] * m00 + D[2, 1] * m10 + D[2, 2] * m20 + D[2, 3] * m30)
            p3 = w * (D[3, 0] * m00 + D[3, 1] * m10 + D[3, 2] * m20 + D[3, 3] * m30)
            q2 = w * (D[2, 0] * m01 + D[2, 1] * m11 + D[2, 3] * m31)
        else:
            p0 = w * (D[0, 0] * m00 + D[0, 1] * m10 + D[0, 3] * m30)
            p1 = w * (D[1, 0] * m00 + D[1, 1] * m10 + D[1, 3] * m30)
            p3 = w * (D[3, 0] * m00 + D[3, 1] * m10 + D[3, 3] * m30)
            p2 = q2 = 0.0
        q0 = w * (D[0, 0] * m01 + D[0, 1] * m11 + D[0, 3] * m31)
        q1 = w * (D[1, 0] * m01 + D[1, 1] * m11 + D[1, 3] * m31)
        q3 = w * (D[3, 0] * m01 + D[3, 1] * m11 + D[3, 3] * m31)
        # material and geometric parts share their factors dN_a/dx_k; geometric: w dN_b/dx_j
        # tau_ji (i = 0, 1) and the hoop term's w tau33 / r^2 N_b
        if geometric:
            T0 = dx[b, 0] * wt00 + dx[b, 1] * wt01
            T1 = dx[b, 0] * wt01 + dx[b, 1] * wt11
            a00, a11, b11, b00 = p0 - T0, q3 - T0, p3 - T1, q1 - T1
        else:
            a00, a11, b11, b00 = p0, q3, p3, q1
        if axisym:
            hb = cax * Nq[q, b]
            for a in range(nen):
                x0, x1, h = dx[a, 0], dx[a, 1], hh[a]
                Ke[2 * a, c0] += x0 * a00 + x1 * p3 + h * p2 - hb * Nq[q, a]
                Ke[2 * a, c1] += x0 * q0 + x1 * a11 + h * q2
                Ke[2 * a + 1, c0] += x0 * b11 + x1 * p1
                Ke[2 * a + 1, c1] += x0 * q3 + x1 * b00
        else:
            for a in range(nen):
                x0, x1 = dx[a, 0], dx[a, 1]
                Ke[2 * a, c0] += x0 * a00 + x1 * p3
                Ke[2 * a, c1] += x0 * q0 + x1 * a11
                Ke[2 * a + 1, c0] += x0 * b11 + x1 * p1
                Ke[2 * a + 1, c1] += x0 * q3 + x1 * b00


@njit(inline="always", **_JIT)
def _small_strain_point(e, q, ue, uo, dNdX, Nq, R0, axisym, kind, lp, Del, eps_e_n, peeq_n,
                        eps_e_out, peeq_out, stress_out, w, tangent, f, Ke, dx, hh, eps, stress,
                        D, eps_e, M):
    """One Gauss point of ``_small_strain``: trial ``B u_new - B u_old + eps_e_n``, the law,
    f += w B^T sig and Ke += w B^T D B."""
    nen = ue.shape[0]
    for a in range(nen):
        dx[a, 0], dx[a, 1] = dNdX[e, q, a, 0], dNdX[e, q, a, 1]
        hh[a] = Nq[q, a] / R0[e, q] if axisym else 0.0
    n0 = n1 = n2 = n3 = 0.0
    o0 = o1 = o2 = o3 = 0.0
    for a in range(nen):
        n0 += dx[a, 0] * ue[a, 0]
        n1 += dx[a, 1] * ue[a, 1]
        n2 += hh[a] * ue[a, 0]
        n3 += dx[a, 1] * ue[a, 0] + dx[a, 0] * ue[a, 1]
        o0 += dx[a, 0] * uo[a, 0]
        o1 += dx[a, 1] * uo[a, 1]
        o2 += hh[a] * uo[a, 0]
        o3 += dx[a, 1] * uo[a, 0] + dx[a, 0] * uo[a, 1]
    eps[0] = (n0 - o0) + eps_e_n[e, q, 0]
    eps[1] = (n1 - o1) + eps_e_n[e, q, 1]
    eps[2] = (n2 - o2) + eps_e_n[e, q, 2]
    eps[3] = (n3 - o3) + eps_e_n[e, q, 3]
    ok = _point_law(e, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, stress, D,
                    eps_e)
    for s in range(4):
        stress_out[e, q, s] = stress[s]
    if tangent:                         # M = B (s, d)
        for a in range(nen):
            M[0, 2 * a], M[0, 2 * a + 1] = dx[a, 0], 0.0
            M[1, 2 * a], M[1, 2 * a + 1] = 0.0, dx[a, 1]
            M[2, 2 * a], M[2, 2 * a + 1] = hh[a], 0.0
            M[3, 2 * a], M[3, 2 * a + 1] = dx[a, 1], dx[a, 0]
    _force_and_tangent(nen, dx, hh, stress, D, M, w, tangent, f, Ke, False, axisym, Nq, q, 1.0)
    return ok


@njit(inline="always", **_JIT)
def _large_strain_point(e, q, F, F33, old, rq, dNdX, Nq, axisym, kind, lp, Del, eps_e_n,
                        peeq_n, eps_e_out, peeq_out, stress_out, w, tangent, f, Ke, dx, hh, eps,
                        tau, D, eps_e, M):
    """One Gauss point of ``_large_strain`` (det F already checked): trial b_e, its Hencky
    strain and Daleckii-Krein derivative, the law (Kirchhoff tau), f += w G^T tau and
    Ke += w G^T D M + the geometric part."""
    nen = dNdX.shape[2]
    # start of the increment (start_kernel): F_old^-1, F33_old, b_e_n = exp(2 eps_e_n)
    i00, i01, i10, i11 = old[e, q, 0], old[e, q, 1], old[e, q, 2], old[e, q, 3]
    bn00, bn01, bn11, bn33 = old[e, q, 5], old[e, q, 6], old[e, q, 7], old[e, q, 8]
    # relative deformation f = F F_old^-1 and the trial b = f b_n f^T
    F00, F01, F10, F11 = F[q, 0, 0], F[q, 0, 1], F[q, 1, 0], F[q, 1, 1]
    f00 = F00 * i00 + F01 * i10
    f01 = F00 * i01 + F01 * i11
    f10 = F10 * i00 + F11 * i10
    f11 = F10 * i01 + F11 * i11
    g00, g01 = f00 * bn00 + f01 * bn01, f00 * bn01 + f01 * bn11          # f b_n
    g10, g11 = f10 * bn00 + f11 * bn01, f10 * bn01 + f11 * bn11
    b00 = g00 * f00 + g01 * f01
    b01 = g00 * f10 + g01 * f11
    b10 = g10 * f00 + g11 * f01
    b11 = g10 * f10 + g11 * f11
    f33 = F33[q] / old[e, q, 4]
    b33 = f33 ** 2 * bn33
    # 1/2 ln b and the eigenprojections
    lam0, lam1, cs, sn = _sym_eig2(b00, b11, 0.5 * (b01 + b10))
    P0_00, P0_01, P0_11 = 0.5 * (1.0 + cs), 0.5 * sn, 0.5 * (1.0 - cs)
    P1_00, P1_01, P1_11 = P0_11, -P0_01, P0_00
    hl0, hl1 = 0.5 * math.log(lam0), 0.5 * math.log(lam1)
    E00 = hl0 * P0_00 + hl1 * P1_00
    E11 = hl0 * P0_11 + hl1 * P1_11
    E01 = hl0 * P0_01 + hl1 * P1_01
    eps[0], eps[1], eps[2], eps[3] = E00, E11, 0.5 * math.log(b33), 2.0 * E01
    ok = _point_law(e, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, tau, D, eps_e)
    det2 = F00 * F11 - F01 * F10
    J = det2 * F33[q]
    for s in range(4):
        stress_out[e, q, s] = tau[s] / J
    # spatial gradients dN/dx = dN/dX F^-1 and the hoop row with the current radius
    r = rq[q]
    s_inv = 1.0 / (1.0 if det2 == 0.0 else det2)
    i00, i01, i10, i11 = F11 * s_inv, -F01 * s_inv, -F10 * s_inv, F00 * s_inv
    for a in range(nen):
        X0, X1 = dNdX[e, q, a, 0], dNdX[e, q, a, 1]
        dx[a, 0] = X0 * i00 + X1 * i10
        dx[a, 1] = X0 * i01 + X1 * i11
        hh[a] = Nq[q, a] / r if axisym else 0.0
    if tangent:
        # material part: d eps_trial = C : (l b + b l^T), l = grad_x du; C from Daleckii-Krein
        # C = c0 P0 x P0 + c1 P1 x P1 + c2 S x S, S = v0 v1^T + v1 v0^T
        m = 0.5 * (lam0 + lam1)
        xr = 0.5 * (lam0 - lam1) / m
        if xr < 1e-6:
            ratio = 1.0 + xr * xr / 3.0
        else:
            ratio = math.atanh(_nmin(xr, 1 - 1e-16)) / xr
        c0, c1, c2 = 0.5 / lam0, 0.5 / lam1, 0.25 * ratio / m
        S_00, S_01, S_11 = -sn, cs, sn
        for b in range(nen):
            h0 = dx[b, 0] * b00 + dx[b, 1] * b10                         # h_bn = dN_b/dx_m b_mn
            h1 = dx[b, 0] * b01 + dx[b, 1] * b11
            for k in range(2):
                # (P h_b)_k = sum_n P_kn h_bn, then dE_ijbk = 2 (c0 P0_ij (P0 h)_k + ...)
                if k == 0:
                    p0 = P0_00 * h0 + P0_01 * h1
                    p1 = P1_00 * h0 + P1_01 * h1
                    p2 = S_00 * h0 + S_01 * h1
                else:
                    p0 = P0_01 * h0 + P0_11 * h1
                    p1 = P1_01 * h0 + P1_11 * h1
                    p2 = S_01 * h0 + S_11 * h1
                u0, u1, u2 = 2.0 * c0 * p0, 2.0 * c1 * p1, 2.0 * c2 * p2
                d = 2 * b + k
                M[0, d] = u0 * P0_00 + u1 * P1_00 + u2 * S_00
                M[1, d] = u0 * P0_11 + u1 * P1_11 + u2 * S_11
                M[3, d] = 2.0 * (u0 * P0_01 + u1 * P1_01 + u2 * S_01)
                M[2, d] = hh[b] if k == 0 else 0.0                     # d eps33 = du_r / r
    _force_and_tangent(nen, dx, hh, tau, D, M, w, tangent, f, Ke, True, axisym, Nq, q, r)
    return ok


# --------------------------------------------------------------------------------------------
# entry points (counted: a test of a fast path proves the fast path ran)

def solid_group(*args) -> None:
    """:func:`_solid_kernel` (the arguments are its own)."""
    calls["solid"] += 1
    _solid_kernel(*args)


def start_group(*args) -> None:
    """:func:`_start_kernel` (the arguments are its own)."""
    calls["solid_start"] += 1
    _start_kernel(*args)
