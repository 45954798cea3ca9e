"""Numba kernels of the contact computation: the foundation projection, and the whole contact
group with the COULOMB law fused.

The optional fast path (``pip install lagamine_py[fast]``) of
:meth:`lagamine_py.foundation.Foundation.project`
and :meth:`lagamine_py.elements.contact.ContactGroup.compute` (with the COULOMB law against a
Foundation): one loop over the contact points doing, point by point, exactly what the NumPy
code does array by array (same formulas in the same order, same branches, derivatives known to
be zero skipped the same way), without the ~100 small array operations whose fixed cost
dominates a contact group of a few hundred points.  The NumPy code stays the reference; results
agree bit for bit except the Gauss-Legendre sum of the dissipation (summed in another order,
~1e-16 relative) and, in the fused group kernel, the end half-line candidates of the projection
(NumPy takes ``perp(e_u) . t`` from BLAS, which may fuse the multiply-add).

Axes: ``g`` contact point (``f*nq + q``), ``f`` face, ``q`` Gauss point, ``a`` face node, ``i``
component, ``J`` face DOF ``2a + i``; ``k`` candidate intersection of the projection (two roots
per arc, then the two end half-lines).

Importing this module imports numba: callers import it lazily
(through :func:`lagamine_py.kernels.module`) and fall back to NumPy without numba.
``cache=True`` keeps the machine code on disk; the first call compiles.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.status import OPEN, SLIP, STICK
from . import calls
from .layout import (COULOMB_B as _B, COULOMB_CLASSICAL as _CLASSICAL, COULOMB_HB as _HB,
                     COULOMB_HPHI as _HPHI, COULOMB_K1 as _K1, COULOMB_K2 as _K2,
                     COULOMB_KP as _KP, COULOMB_KT as _KT, COULOMB_NK as _NK,
                     COULOMB_PHI as _PHI, COULOMB_PREDICTOR as _PREDICTOR, COULOMB_SNAP as _SNAP,
                     ON_SURFACE_RTOL as _ON_SURFACE_RTOL)
from .scalars import nmax as _nmax, nmin as _nmin

__all__ = ["project_points", "face_positions", "contact_group"]

_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


# --------------------------------------------------------------------------------------------
# scalar helpers with NumPy's NaN semantics

@njit(**_JIT)
def _clip01(x):
    return _nmin(_nmax(x, 0.0), 1.0)


@njit(**_JIT)
def _sign(x):
    """np.sign (NaN for NaN)."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return x          # 0.0 or NaN


@njit(**_JIT)
def _clipped(v0, slope, lam):
    """``Coulomb._hardening`` for one function: ``max(v0 + slope lam, 0)`` and its
    right-derivative; ``(v0, 0)`` when the slope is 0."""
    if slope == 0.0:
        return v0, 0.0
    kink = -v0 / slope if slope < 0.0 else math.inf
    return _nmax(v0 + slope * lam, 0.0), (slope if lam < kink else 0.0)


# --------------------------------------------------------------------------------------------
# COULOMB

@njit(**_JIT)
def _dissipation(lv, tau0, p0, dp, dv_c, lam0, dlam, sig):
    """``Coulomb._dissipation`` for one plastic point with dlam != 0."""
    kt = lv[_KT]
    lam1 = lam0 + dlam
    lo, hi = _nmin(lam0, lam1), _nmax(lam0, lam1)
    nk = int(lv[_NK])
    # the pieces between lo, the kinks inside [lo, hi] (sorted) and hi; no array allocated
    e1 = e2 = hi
    if nk >= 1:
        e1 = _nmin(_nmax(lv[_K1], lo), hi)
    if nk == 2:
        e2 = _nmin(_nmax(lv[_K2], lo), hi)
        if e2 < e1:
            e1, e2 = e2, e1
    total = 0.0
    for piece in range(1 + nk):
        a = lo if piece == 0 else (e1 if piece == 1 else e2)
        c = e1 if piece == 0 else (e2 if piece == 1 else hi)
        acc = 0.0
        for k in range(8):
            lam = 0.5 * (a + c) + 0.5 * (c - a) * _GL_X[k]
            b, _ = _clipped(lv[_B], lv[_HB], lam)
            phi, _ = _clipped(lv[_PHI], lv[_HPHI], lam)
            num = kt * (lam - lam0) + b + phi * p0 - sig * tau0
            den = sig * kt * dv_c - phi * dp
            s = num / den if abs(den) > 1e-300 else 1.0
            s = _clip01(s)
            acc += (b + phi * (p0 + dp * s)) * _GL_W[k]
        total += acc * 0.5 * (c - a)
    return _sign(dlam) * total


@njit(**_JIT)
def _coulomb_point(lv, po, tau_old, lam_old, slip_old, vp_old, dissip_old, status_old, dg, dug,
                   dvg, h_g, tan):
    """``Coulomb._update`` at one point (``h_g`` its hold, -1 free): returns ``p, tau, lam,
    slip, vp, dissip, status, snap_back`` and fills ``tan`` (14,) in the order of TAN_KEYS;
    ``snap_back``: the return met ``KT + H <= 0`` (the NumPy path raises ReturnMappingError)."""
    kp, kt = lv[_KP], lv[_KT]
    classical, predictor = lv[_CLASSICAL] != 0.0, lv[_PREDICTOR] != 0.0
    nk = int(lv[_NK])
    snap = lv[_SNAP] != 0.0
    bad = False
    closable = h_g != OPEN
    contact = (dg >= 0.0) and closable
    p1 = kp * _nmax(dg, 0.0) if contact else 0.0
    d_old = dg - dug
    recon = contact and status_old == OPEN
    partial = recon and (dg <= dug) and (dug > 0.0)
    sep = (not contact) and (po > 0.0) and (d_old > 0.0) and (dg <= 0.0) and closable
    frac = 1.0
    if partial:
        frac = dg / dug
    elif sep:
        frac = d_old / (d_old - dg)
    active = contact or sep
    dv_c = dvg * frac
    tau0 = 0.0 if recon else tau_old
    p0 = 0.0 if recon else po
    lam0 = lam_old
    tau_tr = tau0 + kt * dv_c
    # loading (Coulomb._loading)
    b0, hb0 = _clipped(lv[_B], lv[_HB], lam0)
    phi0, hphi0 = _clipped(lv[_PHI], lv[_HPHI], lam0)
    radius0 = b0 + phi0 * p0
    abs_tau0 = abs(tau0)
    f0 = abs_tau0 - radius0
    f_tr = abs(tau_tr) - b0 - phi0 * p1
    sig = 1.0 if tau_tr >= 0.0 else -1.0
    if tau0 != 0.0:
        sig0 = _sign(tau0)
    else:
        sig0 = 1.0 if dv_c >= 0.0 else -1.0
    on = active and (f0 >= -_ON_SURFACE_RTOL * (radius0 + abs_tau0))
    indicator = sig0 * kt * dv_c - phi0 * (p1 - p0)
    pos_tr = f_tr > 0.0
    if classical:
        h0 = hb0 + hphi0 * p0
        indicator = h0 * indicator / (h0 + kt)
        loading_on = on and (indicator >= 0.0)
    else:
        loading_on = on and ((indicator > 0.0) or ((indicator == 0.0) and pos_tr))
    plastic = loading_on or (pos_tr and active and ((not on) or (sig != sig0)))
    if h_g == STICK:
        plastic = False
    elif h_g == SLIP:
        plastic = contact
    # return (Coulomb._return), walking over the kinks
    lam = lam0
    resid = f_tr
    done = not plastic
    dmat = kt
    h = hb0 + hphi0 * p1
    for it in range(nk + 1):
        if done:
            break
        if it:
            _, hb = _clipped(lv[_B], lv[_HB], lam)
            _, hphi = _clipped(lv[_PHI], lv[_HPHI], lam)
            h = hb + hphi * p1
        step = resid / (kt + h)
        cross = False
        ahead = math.inf
        if nk:
            for i in range(nk):
                k = lv[_K1 + i]
                if lam < k < ahead:
                    ahead = k
            cross = (step > 0.0) and (lam + step > ahead)
        if not cross:
            if snap and kt + h <= 0.0:
                bad = True
            dmat = kt + h
            lam = lam + step
            done = True
        else:
            resid = resid - (kt + h) * (ahead - lam)
            lam = ahead
    phi1, _ = _clipped(lv[_PHI], lv[_HPHI], lam)
    dlam = lam - lam0 if plastic else 0.0
    if predictor and h_g != SLIP:
        dlam = _nmax(dlam, 0.0)
    skt = sig * kt
    ddis = 0.0
    if plastic and dlam != 0.0:
        ddis = _dissipation(lv, tau0, p0, p1 - p0, dv_c, lam0, dlam, sig)
    # tangent (Coulomb._tangent)
    c = 1.0 if contact else 0.0
    act = 1.0 if active else 0.0
    frac_d = 0.0
    frac_du = 0.0
    if partial:
        frac_d = 1.0 / dug
        frac_du = -frac / dug
    elif sep:
        frac_d = -1.0 / dug
        frac_du = (1.0 - frac) / dug
    ktdv = kt * dvg
    dtr_d, dtr_du, dtr_v = ktdv * frac_d, ktdv * frac_du, kt * frac
    dtr_tau = 0.0 if recon else 1.0
    kpc = kp * c
    if plastic:
        lam_tr, lam_p1, lam_lam = sig / dmat, -phi1 / dmat, kt / dmat
    else:
        lam_tr, lam_p1, lam_lam = 0.0, 0.0, 1.0
    lam_d = act * (lam_tr * dtr_d + lam_p1 * kpc)
    lam_du = act * (lam_tr * dtr_du)
    lam_v = act * (lam_tr * dtr_v)
    lam_t = act * (lam_tr * dtr_tau)
    tan[0] = lam_d
    tan[1] = c * (dtr_d - skt * lam_d)
    tan[2] = lam_du
    tan[3] = c * (dtr_du - skt * lam_du)
    tan[4] = lam_v
    tan[5] = c * (dtr_v - skt * lam_v)
    tan[6] = lam_t
    tan[7] = c * (dtr_tau - skt * lam_t)
    tan[8] = lam_lam
    tan[9] = c * (-skt * (lam_lam - 1.0) if plastic else 0.0)
    tan[10] = kpc
    tan[11] = kpc
    tan[12] = tan[1] + tan[3]
    tan[13] = lam_d + lam_du
    status = (SLIP if plastic else STICK) if contact else OPEN
    return (p1, tau_tr - skt * dlam if contact else 0.0, lam0 + dlam, slip_old + abs(dlam),
            vp_old + sig * dlam, dissip_old + ddis, status, bad)


_NO_HOLD = np.full(0, -1, np.int64)


def _arr(x, dtype=float):
    """``x`` as a C-contiguous, writable array of ``dtype``: the one array type the kernels
    are compiled for (a read-only or broadcast input would compile another specialisation)."""
    a = np.ascontiguousarray(x, dtype)
    return a if a.flags.writeable else a.copy()


# --------------------------------------------------------------------------------------------
# foundation projection

@njit(**_JIT)
def _project_one(A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, c, px, py, ex, ey,
                 wt_s, wt_e):
    """``Foundation.project`` of one line (P, e_u): candidates in the same order (roots r1 of
    every arc, roots r2, start half-line, end half-line), the first of the smallest valid |d|
    wins.  ``wt_s``, ``wt_e``: ``perp(e_u) . t`` of the end half-lines.  Returns ``found, d,
    arc, s, X (2), dF/ds (2)`` (``d = inf`` where not found)."""
    nj = A.shape[0]
    lo, hi = -1.0 - s_tol, 1.0 + s_tol
    w0, w1 = -ey, ex
    best = math.inf
    bX0 = bX1 = bT0 = bT1 = bd = bs = 0.0
    barc = -1
    for k in range(2 * nj + 2):
        # the candidate's arc parameter s (NaN: none)
        if k < 2 * nj:
            j = k % nj
            a = w0 * C[j, 0] + w1 * C[j, 1]
            b = w0 * B[j, 0] + w1 * B[j, 1]
            c0 = w0 * ((A[j, 0] + c[0]) - px) + w1 * ((A[j, 1] + c[1]) - py)
            disc = b * b - 4 * a * c0
            if not disc >= 0:
                continue                              # NaN roots
            sq = math.sqrt(disc)
            q = -0.5 * (b + (sq if b >= 0 else -sq))
            # a division by zero gives inf or NaN, which the range test rejects
            if k < nj:
                if a == 0.0:
                    continue
                s = q / a
            elif q == 0.0 and a != 0.0:        # ray through the vertex, tangent
                s = -b / (2 * a)
            else:
                if q == 0.0:
                    continue
                s = c0 / q
            if not (s >= lo and s <= hi):
                continue
            arc = j
        else:
            end = k - 2 * nj
            o = start_o if end == 0 else end_o
            sign = -1.0 if end == 0 else 1.0
            wt = wt_s if end == 0 else wt_e
            ds = -(w0 * ((o[0] + c[0]) - px) + w1 * ((o[1] + c[1]) - py)) / wt
            if not ds * sign > 0:
                continue
            s = sign + ds
            arc = 0 if end == 0 else nj - 1
        # evaluate (Foundation.evaluate)
        if arc == 0 and s < -1:
            X0 = start_o[0] + (s + 1) * start_t[0]
            X1 = start_o[1] + (s + 1) * start_t[1]
            T0, T1 = start_t[0], start_t[1]
        elif arc == nj - 1 and s > 1:
            X0 = end_o[0] + (s - 1) * end_t[0]
            X1 = end_o[1] + (s - 1) * end_t[1]
            T0, T1 = end_t[0], end_t[1]
        else:
            X0 = A[arc, 0] + B[arc, 0] * s + C[arc, 0] * (s * s)
            X1 = A[arc, 1] + B[arc, 1] * s + C[arc, 1] * (s * s)
            T0 = B[arc, 0] + 2 * C[arc, 0] * s
            T1 = B[arc, 1] + 2 * C[arc, 1] * s
        X0 = X0 + c[0]
        X1 = X1 + c[1]
        m0, m1 = -T1, T0
        m_norm = math.sqrt(m0 * m0 + m1 * m1)
        cosn = (m0 * ex + m1 * ey) / (m_norm if m_norm > 0 else 1.0)
        dist = ((px - X0) * ex + (py - X1) * ey) / (ex * ex + ey * ey)
        if not (m_norm > 0 and cosn < -cos_min):
            continue
        score = abs(dist)
        if score < best:                   # the first of equal scores wins (np.argmin)
            best = score
            bX0, bX1, bT0, bT1, bd, bs, barc = X0, X1, T0, T1, dist, s, arc
    return best < math.inf, bd, barc, bs, bX0, bX1, bT0, bT1


@njit(**_JIT)
def _project(A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, c, P, e_u, wt_start,
             wt_end, d, found, arc_out, s_out, Q, tangent, dd_dP, dd_de):
    """:func:`_project_one` for every point, with the derivatives of d.  ``wt_start``,
    ``wt_end`` (g,): BLAS products in the NumPy path, passed in so that they are the same."""
    for g in range(P.shape[0]):
        ex, ey = e_u[g, 0], e_u[g, 1]
        ok, bd, barc, bs, bX0, bX1, bT0, bT1 = _project_one(
            A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, c, P[g, 0], P[g, 1], ex,
            ey, wt_start[g], wt_end[g])
        if ok:
            found[g] = True
            d[g] = bd
            arc_out[g] = barc
            s_out[g] = bs
            Q[g, 0], Q[g, 1] = bX0, bX1
            tn = math.sqrt(bT1 * bT1 + bT0 * bT0)
            tn = tn if tn > 0 else 1.0
            tangent[g, 0], tangent[g, 1] = bT0 / tn, bT1 / tn
            mb0, mb1 = -bT1, bT0
            me = mb0 * ex + mb1 * ey
            dd_dP[g, 0], dd_dP[g, 1] = mb0 / me, mb1 / me
            dd_de[g, 0], dd_de[g, 1] = -bd * dd_dP[g, 0], -bd * dd_dP[g, 1]
        else:
            found[g] = False
            d[g] = -math.inf
            arc_out[g] = -1
            s_out[g] = math.nan
            Q[g, 0] = Q[g, 1] = tangent[g, 0] = tangent[g, 1] = math.nan
            dd_dP[g, 0] = dd_dP[g, 1] = 0.0
            dd_de[g, 0] = dd_de[g, 1] = -0.0


def project_points(chain, P, e_u, c):
    """``Foundation.project`` through the kernel: the fields of a
    :class:`~lagamine_py.foundation.Projection` as a dict.

    ``chain``: the foundation's arrays, ``Foundation.kernel_arrays()``: ``A, B, C`` (j, 2) the
    arc coefficients, the start and end half-lines' origins and directions (2,) and the
    tolerances ``s_tol``, ``cos_min``."""
    calls["projection"] += 1
    A, B, C, so, st, eo, et, s_tol, cos_min = chain
    g = P.shape[0]
    P = _arr(P, float)
    e_u = _arr(e_u, float)
    w = np.stack([-e_u[:, 1], e_u[:, 0]], axis=-1)
    wt_start, wt_end = w @ st, w @ et
    d = np.empty(g)
    found = np.empty(g, bool)
    arc = np.empty(g, np.int64)
    s = np.empty(g)
    Q, tangent, dd_dP, dd_de = (np.empty((g, 2)) for _ in range(4))
    _project(A, B, C, so, st, eo, et, s_tol, cos_min, _arr(c, float), P, e_u, wt_start, wt_end,
             d, found, arc, s, Q, tangent, dd_dP, dd_de)
    normal = np.empty((g, 2))
    normal[:, 0] = -tangent[:, 1]
    normal[:, 1] = tangent[:, 0]
    return dict(Q=Q, d=d, arc=arc, s=s, tangent=tangent, normal=normal, found=found,
                dd_dP=dd_dP, dd_de=dd_de)


# --------------------------------------------------------------------------------------------
# the whole contact group: ContactGroup.compute with COULOMB and a Foundation, fused

@njit(**_JIT)
def _interp(Nq, x, e, i):
    """``sum_a N_qa x_eai`` summed over a in order (``ContactGroup._interp``)."""
    out = Nq[0] * x[e, 0, i]
    for a in range(1, Nq.shape[0]):
        out = out + Nq[a] * x[e, a, i]
    return out


@njit(**_JIT)
def _turned(th, X, c, px, py, ex, ey):
    """The line (P, e_u) in the frame of a chain turned by ``th`` about ``X + c`` (``th`` != 0:
    ``ContactGroup._project``): ``X + R^T (P - X - c)`` and ``R^T e_u``."""
    cs, sn = math.cos(th), math.sin(th)
    rx, ry = px - (X[0] + c[0]), py - (X[1] + c[1])
    return (X[0] + (cs * rx + sn * ry), X[1] + (-sn * rx + cs * ry), cs * ex + sn * ey,
            -sn * ex + cs * ey)


@njit(**_JIT)
def _penetration(geo, touch_tol, far, x, e, Nq, dNq, t0_0, t0_1, c, th, X, czero, A, B, C,
                 start_o, start_t, end_o, end_t, s_tol, cos_min):
    """``ContactGroup._penetration`` of one point without derivatives: d at face positions
    ``x`` (f, a, 2) of face ``e`` and placement ``c``, ``th`` (reference point ``X``); ``t0_*``
    the reference tangent (axes without NLGEOM).  Returns ``d`` (-far where the line misses, 0
    within ``touch_tol``)."""
    P_0, P_1 = _interp(Nq, x, e, 0), _interp(Nq, x, e, 1)
    if geo:
        t_0, t_1 = _interp(dNq, x, e, 0), _interp(dNq, x, e, 1)
    else:
        t_0, t_1 = t0_0, t0_1
    n = math.sqrt(t_0 * t_0 + t_1 * t_1)
    sn = n if n > 0 else 1.0
    eu0, eu1 = t_1 / sn, -(t_0 / sn)
    cp = c
    if th != 0.0:
        P_0, P_1, eu0, eu1 = _turned(th, X, c, P_0, P_1, eu0, eu1)
        cp = czero
    w0, w1 = -eu1, eu0
    ok, bd, _, _, _, _, _, _ = _project_one(
        A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, cp, P_0, P_1, eu0, eu1,
        w0 * start_t[0] + w1 * start_t[1], w0 * end_t[0] + w1 * end_t[1])
    d = bd if ok else -far
    return 0.0 if abs(d) <= touch_tol else d


@njit(**_JIT)
def _contact(geo, tangent, ax, nsub, theta, thickness, touch_tol, far, jac_tol, xo, xn, N, dN, W,
             t0, P0, At, RAt, AP0, AP1, start_needed, d_start, co, cn, tho, thn, X, nt, stab, A, B,
             C, start_o, start_t, end_o, end_t, s_tol, cos_min, lv, p_old, tau_old, lam_old,
             slip_old, vp_old, dissip_old, status_old, hold, has_hold, p_new, tau_new, lam_new,
             slip_new, vp_new, dissip_new, status_new, ps_new, ts_new, d_out, dv_out, outside, f,
             K):
    """``ContactGroup.compute`` (``_integrate`` and the forces/tangent) point by point for the
    COULOMB law against a :class:`~lagamine_py.foundation.Foundation`: the same formulas in
    the same order; derivatives known to be zero are skipped as there.  Arrays: ``xo``, ``xn``
    (f, a, 2) face nodes at the start and end; ``N``, ``dN`` (q, a); ``W`` (q,); ``t0``, ``P0``
    (g, 2) reference face; ``At``, ``RAt`` (q, 2, nd) and ``AP0``, ``AP1`` (q, nd) the element's
    constant derivative blocks; ``d_start`` (g,) the start penetration, computed here (and
    written) when ``start_needed``.  The foundation's placement: translations ``co``, ``cn``
    (2,) and rotations ``tho``, ``thn`` of its reference point ``X`` (2,); ``nt`` the tool's
    DOFs (0, 2 or 3: columns and rows ``nd..`` of ``f`` and ``K``); ``stab`` (3,) the
    stabilisation ``(kn, kt, range)`` (``kn < 0``: none).  Writes the new state, the
    stabilisation's ``ps_new``, ``ts_new``, ``d_end`` and the sum of the sub-intervals' ``dv``
    (``d_out``, ``dv_out``: for the energy), ``outside`` (g,)
    (``Coulomb.outside_cone``), ``f`` (f, nw) and ``K`` (f, nw, nw) when ``tangent``; returns
    ``(snap-backs, degenerate faces (|t| <= jac_tol), non-finite f, p or tau)`` as counts."""
    nf, na = xo.shape[0], xo.shape[1]
    nq = N.shape[0]
    nd = 2 * na
    nw = nd + nt
    kt = lv[_KT]
    has_stab = stab[0] >= 0.0
    Dd_end = np.zeros(nw)
    Dd_k = np.zeros(nw)
    Dd_prev = np.zeros(nw)
    Ddu = np.zeros(nw)
    Ddv = np.zeros(nw)
    Ddv_sum = np.zeros(nw)
    Dp, Dtau, Dlam = np.zeros(nw), np.zeros(nw), np.zeros(nw)
    nDp, nDtau, nDlam = np.zeros(nw), np.zeros(nw), np.zeros(nw)
    Dvec = np.zeros((2, nw))
    czero = np.zeros(2)
    tl = np.empty(14)
    dx = xn - xo
    dc0, dc1 = (cn[0] - co[0]) / nsub, (cn[1] - co[1]) / nsub
    turning = nt == 3 or thn != tho
    csd, snd = math.cos(thn - tho), math.sin(thn - tho)
    xr0, xr1 = X[0] + cn[0], X[1] + cn[1]                  # the tool's point now
    bad = degenerate = nonfinite = 0
    for e in range(nf):
        for q in range(nq):
            g = e * nq + q
            Nq, dNq = N[q], dN[q]
            if start_needed:
                d_start[g] = _penetration(geo, touch_tol, far, xo, e, Nq, dNq, t0[g, 0],
                                          t0[g, 1], co, tho, X, czero, A, B, C, start_o, start_t,
                                          end_o, end_t, s_tol, cos_min)
            # end configuration: P, the axes' tangent, the penetration and its derivative
            P_0, P_1 = _interp(Nq, xn, e, 0), _interp(Nq, xn, e, 1)
            if geo:
                t_0, t_1 = _interp(dNq, xn, e, 0), _interp(dNq, xn, e, 1)
            else:
                t_0, t_1 = t0[g, 0], t0[g, 1]
            n = math.sqrt(t_0 * t_0 + t_1 * t_1)
            sn = n if n > 0 else 1.0
            th0, th1 = t_0 / sn, t_1 / sn
            eu0, eu1 = th1, -th0                                   # R t / |t|
            # d e_u / d t = (R - e_u th^T) / |t|, R = [[0, 1], [-1, 0]]
            de00, de01 = (0.0 - eu0 * th0) / n, (1.0 - eu0 * th1) / n
            de10, de11 = (-1.0 - eu1 * th0) / n, (0.0 - eu1 * th1) / n
            pp0, pp1, ep0, ep1, cp = P_0, P_1, eu0, eu1, cn
            if thn != 0.0:                         # the turned chain: project in its frame
                pp0, pp1, ep0, ep1 = _turned(thn, X, cn, P_0, P_1, eu0, eu1)
                cp = czero
            w0, w1 = -ep1, ep0
            ok, bd, _, _, _, _, T0, T1 = _project_one(
                A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, cp, pp0, pp1, ep0, ep1,
                w0 * start_t[0] + w1 * start_t[1], w0 * end_t[0] + w1 * end_t[1])
            d_end = bd if ok else -far
            if abs(d_end) <= touch_tol:
                d_end = 0.0
            if tangent:
                if ok:
                    mb0, mb1 = -T1, T0
                    me = mb0 * ep0 + mb1 * ep1
                    dP0, dP1 = mb0 / me, mb1 / me
                    dE0, dE1 = -bd * dP0, -bd * dP1
                    if thn != 0.0:                 # back to the current frame: R v
                        cs, sn_ = math.cos(thn), math.sin(thn)
                        dP0, dP1 = cs * dP0 - sn_ * dP1, sn_ * dP0 + cs * dP1
                        dE0, dE1 = cs * dE0 - sn_ * dE1, sn_ * dE0 + cs * dE1
                    dt0 = dE0 * de00 + dE1 * de10
                    dt1 = dE0 * de01 + dE1 * de11
                    for a in range(na):
                        Dd_end[2 * a] = Nq[a] * dP0
                        Dd_end[2 * a + 1] = Nq[a] * dP1
                        if geo:
                            Dd_end[2 * a] += dNq[a] * dt0
                            Dd_end[2 * a + 1] += dNq[a] * dt1
                    if nt:                         # the tool's placement
                        Dd_end[nd], Dd_end[nd + 1] = -dP0, -dP1
                        if nt == 3:
                            qx = P_0 - d_end * eu0 - (X[0] + cn[0])
                            qy = P_1 - d_end * eu1 - (X[1] + cn[1])
                            Dd_end[nd + 2] = dP0 * qy - dP1 * qx
                else:
                    Dd_end[:] = 0.0
            # relative displacement per sub-interval (minus the tool's material point's motion)
            rel0 = _interp(Nq, dx, e, 0) / nsub - dc0
            rel1 = _interp(Nq, dx, e, 1) / nsub - dc1
            qa0 = qa1 = 0.0
            if turning:
                arm0 = _interp(Nq, xo, e, 0) - (X[0] + co[0])
                arm1 = _interp(Nq, xo, e, 1) - (X[1] + co[1])
                qa0, qa1 = csd * arm0 - snd * arm1, snd * arm0 + csd * arm1
                if thn != tho:
                    rel0 = rel0 - (qa0 - arm0) / nsub
                    rel1 = rel1 - (qa1 - arm1) / nsub
            # the sub-intervals (ContactGroup._integrate)
            h_g = hold[g] if has_hold else -1
            sp, stau, slam = p_old[g], tau_old[g], lam_old[g]
            sslip, svp, sdis, sstat = slip_old[g], vp_old[g], dissip_old[g], status_old[g]
            d_prev = d_start[g]
            have_prev = False
            zp = ztau = zlam = True
            dv_sum = 0.0
            for k in range(1, nsub + 1):
                a_k = k / nsub
                if nsub == 1:
                    d_k = d_end
                    Dd_k[:] = Dd_end
                else:
                    d_k = d_start[g] + a_k * (d_end - d_start[g])
                    for J in range(nw):
                        Dd_k[J] = a_k * Dd_end[J]
                a_th = (k - 1 + theta) / nsub
                if geo:
                    tt0 = dNq[0] * (xo[e, 0, 0] + a_th * dx[e, 0, 0])
                    tt1 = dNq[0] * (xo[e, 0, 1] + a_th * dx[e, 0, 1])
                    for a in range(1, na):
                        tt0 = tt0 + dNq[a] * (xo[e, a, 0] + a_th * dx[e, a, 0])
                        tt1 = tt1 + dNq[a] * (xo[e, a, 1] + a_th * dx[e, a, 1])
                else:
                    tt0, tt1 = t0[g, 0], t0[g, 1]
                nv = math.sqrt(tt0 * tt0 + tt1 * tt1)
                snv = nv if nv > 0 else 1.0
                h0, h1 = tt0 / snv, tt1 / snv
                ev0, ev1 = -h0, -h1
                # d e_v / d t = -(I - th th^T) / |t|
                dv00, dv01 = -(1.0 - h0 * h0) / nv, -(0.0 - h0 * h1) / nv
                dv10, dv11 = -(0.0 - h1 * h0) / nv, -(1.0 - h1 * h1) / nv
                dv = ev0 * rel0 + ev1 * rel1
                du = d_k - d_prev
                np_, ntau, nlam, nslip, nvp, ndis, nstat, snap = _coulomb_point(
                    lv, sp, stau, slam, sslip, svp, sdis, sstat, d_k, du, dv, h_g, tl)
                bad += snap
                dv_sum = dv_sum + dv
                if tangent:
                    for a in range(na):
                        Ddv[2 * a] = Nq[a] * ev0
                        Ddv[2 * a + 1] = Nq[a] * ev1
                    if nsub != 1:
                        for J in range(nd):
                            Ddv[J] /= nsub
                    if geo:
                        for a in range(na):
                            for i in range(2):
                                dev0i = dv00 if i == 0 else dv01
                                dev1i = dv10 if i == 0 else dv11
                                turn = dNq[a] * (rel0 * dev0i) + dNq[a] * (rel1 * dev1i)
                                Ddv[2 * a + i] += turn if a_th == 1.0 else a_th * turn
                    if nt:
                        Ddv[nd], Ddv[nd + 1] = -ev0 / nsub, -ev1 / nsub
                        if nt == 3:
                            Ddv[nd + 2] = -(ev1 * qa0 - ev0 * qa1) / nsub
                    if has_stab:
                        for J in range(nw):
                            Ddv_sum[J] = Ddv[J] if k == 1 else Ddv_sum[J] + Ddv[J]
                    for J in range(nw):
                        Ddu[J] = Dd_k[J] - Dd_prev[J] if have_prev else Dd_k[J]
                    lam_needed = k < nsub
                    # chain (ContactGroup._chain): inputs u, v, d, p, tau, lam in this order
                    for J in range(nw):
                        acc = tl[11] * Ddu[J]                              # p_u
                        if have_prev:
                            acc += tl[10] * Dd_prev[J]                     # p_d
                        nDp[J] = acc
                        acc = tl[12] * Ddu[J]                              # tau_u
                        acc += tl[5] * Ddv[J]                              # tau_v
                        if have_prev:
                            acc += tl[1] * Dd_prev[J]                      # tau_d
                        if not ztau:
                            acc += tl[7] * Dtau[J]                         # tau_tau
                        if not zlam:
                            acc += tl[9] * Dlam[J]                         # tau_lam
                        nDtau[J] = acc
                        if lam_needed:
                            acc = tl[13] * Ddu[J]                          # lam_u
                            acc += tl[4] * Ddv[J]                          # lam_v
                            if have_prev:
                                acc += tl[0] * Dd_prev[J]                  # lam_d
                            if not ztau:
                                acc += tl[6] * Dtau[J]                     # lam_tau
                            if not zlam:
                                acc += tl[8] * Dlam[J]                     # lam_lam
                            nDlam[J] = acc
                    Dp[:] = nDp
                    Dtau[:] = nDtau
                    if lam_needed:
                        Dlam[:] = nDlam
                    zp = ztau = False
                    zlam = not lam_needed
                if h_g == OPEN:                    # held open by the solver
                    np_, ntau, nlam, nslip, nvp, ndis, nstat = (0.0, 0.0, slam, sslip, svp,
                                                                sdis, OPEN)
                    if tangent:
                        Dp[:] = 0.0
                        Dtau[:] = 0.0
                        Dlam[:] = 0.0
                sp, stau, slam, sslip, svp, sdis, sstat = np_, ntau, nlam, nslip, nvp, ndis, nstat
                d_prev = d_k
                Dd_prev[:] = Dd_k
                have_prev = True
            if tangent and zp:
                Dp[:] = 0.0
            if tangent and ztau:
                Dtau[:] = 0.0
            p_new[g], tau_new[g], lam_new[g] = sp, stau, slam
            slip_new[g], vp_new[g], dissip_new[g], status_new[g] = sslip, svp, sdis, sstat
            # Coulomb.outside_cone
            b1, _ = _clipped(lv[_B], lv[_HB], slam)
            phi1, _ = _clipped(lv[_PHI], lv[_HPHI], slam)
            radius = b1 + phi1 * sp
            abs_tau = abs(stau)
            outside[g] = abs_tau - radius > 1e-7 * (radius + abs_tau + sp) + 1e-12 * kt
            if not ax:
                wt = W[q] * thickness
            elif geo:
                wt = W[q] * P_0
            else:
                wt = W[q] * P0[g, 0]
            # the stabilisation (ContactGroup._stabilise)
            ps = ts = 0.0
            if has_stab:
                rng = stab[2]
                ok = d_end > -rng and d_start[g] > -0.5 * far
                wn = dwn = wts = dwt = 0.0           # ContactGroup._stab_weights
                if ok and d_end >= 0.0:
                    wn = 1.0
                elif ok:
                    x = -d_end / rng
                    wn, dwn = 1.0 - x, 1.0 / rng
                    wts, dwt = 4.0 * x * (1.0 - x), -4.0 * (1.0 - 2.0 * x) / rng
                dd = d_end - d_start[g] if wn > 0.0 else 0.0
                dvs = dv_sum if wts > 0.0 else 0.0
                ps, ts = stab[0] * wn * dd, stab[1] * wts * dvs
                if tangent and ok:
                    sa = stab[0] * (wn + dd * dwn)
                    sb = stab[1] * dvs * dwt
                    sc = stab[1] * wts
                    for J in range(nw):
                        Dp[J] = Dp[J] + sa * Dd_end[J]
                        Dtau[J] = Dtau[J] + (sc * Ddv_sum[J] + sb * Dd_end[J])
            ps_new[g], ts_new[g] = ps, ts
            d_out[g], dv_out[g] = d_end, dv_sum
            sp = sp + ps
            stau = stau + ts
            # forces and tangent (ContactGroup.compute)
            degenerate += n <= jac_tol
            nonfinite += not (math.isfinite(sp) and math.isfinite(stau))
            Rt0, Rt1 = t_1, -t_0
            vec0 = sp * Rt0 - stau * t_0
            vec1 = sp * Rt1 - stau * t_1
            for a in range(na):
                fa0 = Nq[a] * vec0 * wt
                fa1 = Nq[a] * vec1 * wt
                if q == 0:
                    f[e, 2 * a], f[e, 2 * a + 1] = fa0, fa1
                else:
                    f[e, 2 * a] += fa0
                    f[e, 2 * a + 1] += fa1
            F0, F1 = vec0 * wt, vec1 * wt
            arm0, arm1 = P_0 - xr0, P_1 - xr1
            if nt:                                 # the tool's rows, negated after the face
                mq = arm0 * F1 - arm1 * F0
                if q == 0:
                    f[e, nd], f[e, nd + 1] = F0, F1
                    if nt == 3:
                        f[e, nd + 2] = mq
                else:
                    f[e, nd] += F0
                    f[e, nd + 1] += F1
                    if nt == 3:
                        f[e, nd + 2] += mq
            if tangent:
                for J in range(nw):
                    Dvec[0, J] = Rt0 * Dp[J] - t_0 * Dtau[J]
                    Dvec[1, J] = Rt1 * Dp[J] - t_1 * Dtau[J]
                    if geo and J < nd:
                        Dvec[0, J] += sp * RAt[q, 0, J] - stau * At[q, 0, J]
                        Dvec[1, J] += sp * RAt[q, 1, J] - stau * At[q, 1, J]
                for a in range(na):
                    for i in range(2):
                        veci = vec0 if i == 0 else vec1
                        for J in range(nw):
                            kg = Nq[a] * Dvec[i, J] * wt
                            if ax and geo and J < nd:
                                kg = kg + Nq[a] * veci * (W[q] * AP0[q, J])
                            if q == 0:
                                K[e, 2 * a + i, J] = kg
                            else:
                                K[e, 2 * a + i, J] += kg
                if nt:
                    for J in range(nw):
                        df0 = Dvec[0, J] * wt
                        df1 = Dvec[1, J] * wt
                        if ax and geo and J < nd:
                            df0 = df0 + vec0 * (W[q] * AP0[q, J])
                            df1 = df1 + vec1 * (W[q] * AP0[q, J])
                        if q == 0:
                            K[e, nd, J], K[e, nd + 1, J] = df0, df1
                        else:
                            K[e, nd, J] += df0
                            K[e, nd + 1, J] += df1
                        if nt == 3:
                            dm = arm0 * df1 - arm1 * df0
                            if J < nd:
                                dm += AP0[q, J] * F1 - AP1[q, J] * F0
                            elif J == nd:
                                dm -= F1
                            elif J == nd + 1:
                                dm += F0
                            if q == 0:
                                K[e, nd + 2, J] = dm
                            else:
                                K[e, nd + 2, J] += dm
        for J in range(nd):
            nonfinite += not math.isfinite(f[e, J])
        for r in range(nd, nw):                    # the tool's rows: minus the sums
            f[e, r] = -f[e, r]
            if tangent:
                for J in range(nw):
                    K[e, r, J] = -K[e, r, J]
    return bad, degenerate, nonfinite


@njit(**_JIT)
def _faces(u_old, u_new, face_nodes, x0, xo, xn, cached, cxo, cco, co):
    """Face node positions ``xo``, ``xn`` (f, a, 2) = ``x0 + u[face_nodes]`` (as
    ``ContactGroup._face_x``); returns whether the cached start configuration ``cxo``, ``cco``
    is the same (``cached`` False: there is none), compared with ``==`` as np.array_equal."""
    same = cached and cco.shape[0] == co.shape[0]
    for i in range(co.shape[0]):
        if same and not cco[i] == co[i]:
            same = False
    for e in range(face_nodes.shape[0]):
        for a in range(face_nodes.shape[1]):
            node = face_nodes[e, a]
            for i in range(2):
                xo[e, a, i] = x0[e, a, i] + u_old[node, i]
                xn[e, a, i] = x0[e, a, i] + u_new[node, i]
                if same and not xo[e, a, i] == cxo[e, a, i]:
                    same = False
    return same


def face_positions(u_old, u_new, face_nodes, x0, cache, co):
    """Face node positions ``xo``, ``xn`` (f, a, 2) at the start and end of the increment
    (``face_nodes`` (f, a) int64, ``x0`` (f, a, 2) reference positions) and whether the start
    is the cached one: ``cache`` None or ``(xo, co, d_start)`` of an earlier call."""
    nf, na = face_nodes.shape
    xo, xn = np.empty((2, nf, na, 2))
    co = _arr(co, float)
    cached = cache is not None
    cxo, cco = (cache[0], cache[1]) if cached else (xo, co)
    same = _faces(_arr(u_old, float), _arr(u_new, float), face_nodes, x0, xo, xn, cached, cxo,
                  cco, co)
    return xo, xn, same


def contact_group(element, chain, law_vector, xo, xn, reuse, d_start, place_o, place_n,
                  centre, nt, stab, nsub, theta, geo, tangent, state, frozen):
    """:func:`_contact` for one contact group: ``(new_state, f, K, outside, d_start, flags)``.

    ``element``: the group's constant arrays ``(N, dN, W, t0, P0, At, RAt, AP0, AP1,
    axisymmetric, thickness, touch_tol, far, jac_tol)`` (see ``ContactGroup``); ``chain``: the
    foundation's ``kernel_arrays()``; ``law_vector``: ``Coulomb.kernel_vector()``; ``xo``,
    ``xn``, ``reuse`` from :func:`face_positions`; ``d_start`` (g,) the start penetration when
    ``reuse`` (else computed here and returned); ``place_o``, ``place_n`` the foundation's
    placements (dx, dy, theta) at the start and end, ``centre`` its reference point; ``nt`` the
    tool's DOFs (0, 2, 3); ``stab`` ``(kn, kt, range)`` or None; ``nsub`` the sub-intervals.
    The new state holds ``ps``, ``ts`` (the stabilisation), ``d_end`` and ``dv`` (the
    increment's penetration at its end and tangential relative displacement); ``flags``: counts of
    (snap-backs, degenerate faces, non-finite values)."""
    calls["contact"] += 1
    N, dN, W, t0, P0, At, RAt, AP0, AP1, axisym, thickness, touch_tol, far, jac_tol = element
    A, B, C, so, st, eo, et, s_tol, cos_min = chain
    c = _arr
    nf, na = xo.shape[0], xo.shape[1]
    nd, ng = 2 * na, nf * N.shape[0]
    nw = nd + int(nt)
    if not reuse:
        d_start = np.empty(ng)
    out = np.empty((10, ng))
    status = np.empty(ng, np.int8)
    outside = np.empty(ng, np.bool_)
    f = np.empty((nf, nw))
    K = np.empty((nf, nw, nw)) if tangent else np.empty((0, nw, nw))
    hold = _NO_HOLD if frozen is None else c(np.broadcast_to(frozen, (ng,)), np.int64)
    po, pn = c(place_o, float), c(place_n, float)
    sv = np.array([-1.0, 0.0, 0.0]) if stab is None else c(stab, float)
    flags = _contact(bool(geo), bool(tangent), bool(axisym), int(nsub), float(theta),
                     float(thickness), touch_tol, far, jac_tol, xo, xn, N, dN, W, t0, P0, At,
                     RAt, AP0, AP1, not reuse, d_start, po[:2].copy(), pn[:2].copy(),
                     float(po[2]), float(pn[2]), c(centre, float), int(nt), sv, A, B, C, so, st,
                     eo, et, s_tol, cos_min, law_vector, c(state["p"], float),
                     c(state["tau"], float), c(state["lam"], float), c(state["slip"], float),
                     c(state["vp"], float), c(state["dissip"], float), c(state["status"], np.int8),
                     hold, frozen is not None, out[0], out[1], out[2], out[3], out[4], out[5],
                     status, out[6], out[7], out[8], out[9], outside, f, K)
    new_state = dict(p=out[0], tau=out[1], lam=out[2], slip=out[3], vp=out[4], dissip=out[5],
                     status=status, ps=out[6], ts=out[7], d_end=out[8], dv=out[9])
    for k, v in state.items():                # entries the law does not own: copied through
        if k not in new_state:
            new_state[k] = np.array(v, copy=True)
    return new_state, f, (K if tangent else None), outside, d_start, flags
