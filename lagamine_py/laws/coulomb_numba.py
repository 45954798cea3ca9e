"""Numba kernels of the contact computation: the COULOMB update and the foundation projection.

The optional fast path (``pip install lagamine_py[fast]``) of
:meth:`lagamine_py.laws.coulomb.Coulomb.update` and
:meth:`lagamine_py.foundation.Foundation.project`: one loop over the contact points doing, point
by point, exactly what the NumPy code does array by array (same formulas in the same order,
same branches, same NaN handling where it matters), without the ~100 small array operations
whose fixed cost dominates a contact group of a few hundred points.  The NumPy code stays the
reference; results agree to round-off (bit for bit except the Gauss-Legendre sum of the
dissipation, and BLAS's fused products in the end half-line candidates of the projection).

Axes: ``g`` contact point, ``k`` candidate intersection (``2 j + 2`` for ``j`` arcs: two roots per
arc, then the two end half-lines).

Importing this module imports numba: callers import it lazily and fall back to NumPy on
ImportError.  ``cache=True`` keeps the machine code on disk; the first call compiles.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["coulomb_update", "TAN_KEYS", "project_points", "law_vector"]

_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True)

OPEN, STICK, SLIP = 0, 1, 2          # lagamine_py.laws.base
_ON_SURFACE_RTOL = 1e-10             # lagamine_py.laws.coulomb
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)

#: rows of the tangent array returned by :func:`coulomb_update`
TAN_KEYS = ("lam_d", "tau_d", "lam_du", "tau_du", "lam_v", "tau_v", "lam_tau", "tau_tau",
            "lam_lam", "tau_lam", "p_d", "p_u", "tau_u", "lam_u")
# layout of the law vector
_KP, _KT, _PHI, _B, _HPHI, _HB, _CLASSICAL, _PREDICTOR, _K1, _K2, _NK, _SNAP = range(12)


def law_vector(law) -> np.ndarray:
    """The parameters of a :class:`~lagamine_py.laws.coulomb.Coulomb` law as a (12,) vector."""
    v = np.zeros(12)
    v[_KP], v[_KT], v[_PHI], v[_B], v[_HPHI], v[_HB] = (law.kp, law.kt, law.phi, law.b,
                                                         law.hphi, law.hb)
    v[_CLASSICAL] = law.indicator == "CLASSICAL"
    v[_PREDICTOR] = law.indicator == "PREDICTOR"
    kinks = law._kinks
    v[_NK] = len(kinks)
    v[_K1] = kinks[0] if len(kinks) > 0 else np.inf
    v[_K2] = kinks[1] if len(kinks) > 1 else np.inf
    v[_SNAP] = law._may_snap_back
    return v


# --------------------------------------------------------------------------------------------
# scalar helpers with NumPy's NaN semantics

@njit(**_JIT)
def _nmax(a, b):
    """np.maximum of two scalars (NaN propagates)."""
    if a != a or b != b:
        return math.nan
    return a if a > b else b


@njit(**_JIT)
def _nmin(a, b):
    """np.minimum of two scalars (NaN propagates)."""
    if a != a or b != b:
        return math.nan
    return a if a < b else b


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
    edges = np.empty(4)
    edges[0] = lo
    for i in range(nk):
        edges[1 + i] = _nmin(_nmax(lv[_K1 + i], lo), hi)
    edges[1 + nk] = hi
    if nk:
        edges[:2 + nk].sort()
    total = 0.0
    for piece in range(1 + nk):
        a, c = edges[piece], edges[piece + 1]
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
def _coulomb(lv, p_old, tau_old, lam_old, slip_old, dissip_old, status_old, d, du, dv, hold,
             has_hold, p_new, tau_new, lam_new, slip_new, dissip_new, status_new, tan):
    """One sub-interval of ``Coulomb._update`` for every point; returns the number of points
    whose return met ``KT + H <= 0`` (the NumPy path raises ReturnMappingError)."""
    kp, kt = lv[_KP], lv[_KT]
    classical, predictor = lv[_CLASSICAL] != 0.0, lv[_PREDICTOR] != 0.0
    nk = int(lv[_NK])
    snap = lv[_SNAP] != 0.0
    bad = 0
    for g in range(p_old.shape[0]):
        h_g = hold[g] if has_hold else -1
        dg, dug, dvg = d[g], du[g], dv[g]
        po = p_old[g]
        closable = h_g != OPEN
        contact = (dg >= 0.0) and closable
        p1 = kp * _nmax(dg, 0.0) if contact else 0.0
        d_old = dg - dug
        recon = contact and status_old[g] == OPEN
        partial = recon and (dg <= dug) and (dug > 0.0)
        sep = (not contact) and (po > 0.0) and (d_old > 0.0) and (dg <= 0.0) and closable
        frac = 1.0
        if partial:
            frac = dg / dug
        elif sep:
            frac = d_old / (d_old - dg)
        active = contact or sep
        dv_c = dvg * frac
        tau0 = 0.0 if recon else tau_old[g]
        p0 = 0.0 if recon else po
        lam0 = lam_old[g]
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
                    if lam < k and k < ahead:
                        ahead = k
                cross = (step > 0.0) and (lam + step > ahead)
            if not cross:
                if snap and kt + h <= 0.0:
                    bad += 1
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
        tau_new[g] = tau_tr - skt * dlam if contact else 0.0
        p_new[g] = p1
        lam_new[g] = lam0 + dlam
        slip_new[g] = slip_old[g] + abs(dlam)
        ddis = 0.0
        if plastic and dlam != 0.0:
            ddis = _dissipation(lv, tau0, p0, p1 - p0, dv_c, lam0, dlam, sig)
        dissip_new[g] = dissip_old[g] + ddis
        status_new[g] = (SLIP if plastic else STICK) if contact else OPEN
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
        tan[0, g] = lam_d
        tan[1, g] = c * (dtr_d - skt * lam_d)
        tan[2, g] = lam_du
        tan[3, g] = c * (dtr_du - skt * lam_du)
        tan[4, g] = lam_v
        tan[5, g] = c * (dtr_v - skt * lam_v)
        tan[6, g] = lam_t
        tan[7, g] = c * (dtr_tau - skt * lam_t)
        tan[8, g] = lam_lam
        tan[9, g] = c * (-skt * (lam_lam - 1.0) if plastic else 0.0)
        tan[10, g] = kpc
        tan[11, g] = kpc
        tan[12, g] = tan[1, g] + tan[3, g]
        tan[13, g] = lam_d + lam_du
    return bad


_NO_HOLD = np.full(0, -1, np.int64)


def coulomb_update(lv, state, d, du, dv, frozen):
    """``Coulomb._update`` through the kernel: ``(new_state, tan, n_snap_back)``.

    ``lv`` the law vector (:func:`law_vector`); arrays (g,) (``d``, ``du``, ``dv`` broadcast).
    The tangent arrays are rows of one (14, g) array."""
    c = np.ascontiguousarray
    p_old = c(state["p"], float)
    g = p_old.shape[0]
    d, du, dv = (c(np.broadcast_to(np.asarray(x, float), (g,))) for x in (d, du, dv))
    hold = _NO_HOLD if frozen is None else c(np.broadcast_to(frozen, (g,)), np.int64)
    out = np.empty((5, g))
    status = np.empty(g, np.int8)
    tan = np.empty((len(TAN_KEYS), g))
    bad = _coulomb(lv, p_old, c(state["tau"], float), c(state["lam"], float),
                   c(state["slip"], float), c(state["dissip"], float),
                   c(state["status"], np.int8), d, du, dv, hold, frozen is not None,
                   out[0], out[1], out[2], out[3], out[4], status, tan)
    new_state = dict(state)
    new_state.update(p=out[0], tau=out[1], lam=out[2], slip=out[3], dissip=out[4],
                     status=status)
    return new_state, dict(zip(TAN_KEYS, tan)), bad


# --------------------------------------------------------------------------------------------
# foundation projection

@njit(**_JIT)
def _project(A, B, C, start_o, start_t, end_o, end_t, s_tol, cos_min, c, P, e_u, wt_start,
             wt_end, d, found, arc_out, s_out, Q, tangent, dd_dP, dd_de):
    """``Foundation.project`` point by point: candidates in the same order (roots r1 of every
    arc, roots r2, start half-line, end half-line), the first of the smallest valid |d| wins.
    ``wt_start``, ``wt_end`` (g,): ``perp(e_u) . t`` of the end half-lines (BLAS products in
    the NumPy path, passed in so that they are the same numbers)."""
    nj = A.shape[0]
    lo, hi = -1.0 - s_tol, 1.0 + s_tol
    for g in range(P.shape[0]):
        px, py = P[g, 0], P[g, 1]
        ex, ey = e_u[g, 0], e_u[g, 1]
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
                wt = wt_start[g] if end == 0 else wt_end[g]
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
        if best < math.inf:
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


def project_points(found_obj, P, e_u, c):
    """``Foundation.project`` through the kernel: the fields of a
    :class:`~lagamine_py.foundation.Projection` as a dict."""
    g = P.shape[0]
    P = np.ascontiguousarray(P, float)
    e_u = np.ascontiguousarray(e_u, float)
    w = np.stack([-e_u[:, 1], e_u[:, 0]], axis=-1)
    (so, st), (eo, et) = found_obj._start, found_obj._end
    wt_start, wt_end = w @ st, w @ et
    d = np.empty(g)
    found = np.empty(g, bool)
    arc = np.empty(g, np.int64)
    s = np.empty(g)
    Q, tangent, dd_dP, dd_de = (np.empty((g, 2)) for _ in range(4))
    _project(found_obj.A, found_obj.B, found_obj.C, so, st, eo, et, found_obj.s_tol,
             found_obj.cos_min, np.ascontiguousarray(c, float), P, e_u, wt_start, wt_end, d,
             found, arc, s, Q, tangent, dd_dP, dd_de)
    normal = np.empty((g, 2))
    normal[:, 0] = -tangent[:, 1]
    normal[:, 1] = tangent[:, 0]
    return dict(Q=Q, d=d, arc=arc, s=s, tangent=tangent, normal=normal, found=found,
                dd_dP=dd_dP, dd_de=dd_de)
