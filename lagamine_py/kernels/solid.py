"""Numba kernels of the solid groups: element computation and scatter fused, in blocks of elements.

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

SIMD across elements: the element loop takes ``LANES`` (16) elements at a time, every per-point
quantity held as a row of 16 values (flat work arrays, the lane axis last), and its arithmetic
loops run over the lanes, which LLVM turns into packed instructions (ymm ``vmulpd``/``vaddpd``;
no ``vfmadd``: without fastmath LLVM contracts nothing).  Each lane does the scalar arithmetic
of one element in the order the element-by-element kernel did, so every output is that
kernel's bit for bit (``tools/kernel_calls.py --check``).  Scalar, lane by lane: the law (its
branches, logarithms and Newton iterations), the logarithms of the Hencky strain and the
Daleckii-Krein atanh, the gathers and the scatter.  Sixteen lanes, not 8: LLVM's loop vectoriser
refuses a loop of fewer than 16 iterations that needs run-time alias checks (the work arrays
may alias as far as it knows).  The last block's spare lanes repeat its last element and are
never read.  The start of the increment (:func:`_start_kernel`, once per increment) stays
element by element.

One compiled specialisation serves every element type, law and kinematics (they are run-time
arguments), so the first call compiles once; ``cache=True`` keeps the machine code on disk.
``parallel=False``: the factorisation uses the cores.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import calls
from .layout import (BAD_DET_F, ELASTIC, J2_LINEAR, OK, QUAD_Y, RETURN_MAP_FAILED, YIELD_RTOL,
                     SOLID_A as _A, SOLID_G as _G, SOLID_H as _H, SOLID_K as _K,
                     SOLID_MAXIT as _MAXIT, SOLID_N as _N, SOLID_SIGMAY as _SIGMAY,
                     SOLID_TOL as _TOL)
from .scalars import nmax as _nmax, nmin as _nmin

__all__ = ["NO_DEFER", "Split", "scratch_arrays", "solid_group", "start_group"]

# _nrt=False: no reference counting.  The kernels allocate nothing (the caller passes the work
# arrays), and without it every array handed to an inlined helper costs atomic increments and
# decrements per Gauss point: measured 2.35 -> 0.34 us per Q8 element (small strain, no tangent).
_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True, _nrt=False)


# --------------------------------------------------------------------------------------------
# scalar helpers (min and max with NumPy's NaN semantics: lagamine_py.kernels.scalars)

@njit(inline="always", **_JIT)
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

_LN2 = math.log(2.0)


@njit(inline="always", **_JIT)
def _quad_x(n):
    """``layout.quad_x``: the x = ln q branch's error factor."""
    return 1.0 + n


@njit(**_JIT)
def _ro_residual(by_q, x, qt, pn, G3, a, n):
    """``_g_q`` (by_q, x = ln q) or ``_g_p`` (x = ln P): the residual, the Newton step
    g / g' and e^x (the step's exp, which the answer reuses)."""
    if by_q:
        q = math.exp(x)
        P = pn + (qt - q) / G3
        if P > 0.0:
            g = a + n * x - math.log(P)
            return g, g * (G3 * P) / (n * (G3 * P) + q), q     # g / (n + q / (3G P))
        return math.inf, math.nan, q
    P = math.exp(x)
    q = qt - G3 * (P - pn)
    if q > 0.0:
        g = x - a - n * math.log(q)
        return g, g * q / (q + n * G3 * P), P          # g / (1 + n 3G P / q)
    return math.inf, math.nan, P


@njit(**_JIT)
def _safeguarded_newton(by_q, lo, hi, tol, quad, max_iter, qt, pn, G3, a, n):
    """``safeguarded_newton`` for one point: Newton from ``hi``, bisection fallback; done
    when a Newton step d has ``|d| <= tol`` or ``quad d^2 <= tol`` (a bound on the next
    iterate's error: ``layout.QUAD_Y``).  Returns
    ``(x, e^x, converged)``: after a Newton step d from x_k, e^x = e^x_k (1 - d + d^2/2)
    (relative error d^3/6 < 1e-20 there), no exp of its own."""
    x = hi
    for _ in range(max_iter):
        g, step, ex = _ro_residual(by_q, x, qt, pn, G3, a, n)
        if g > 0.0:
            hi = x
        if g <= 0.0:
            lo = x
        x_newton = x - step
        newton = (x_newton >= lo) and (x_newton <= hi)
        if newton and (abs(step) <= tol or quad * step * step <= tol or g == 0.0):
            return x_newton, ex * (1.0 - step + 0.5 * step * step), True
        x_new = x_newton if newton else 0.5 * (lo + hi)
        if (hi - lo <= tol) or (g == 0.0):
            return x_new, math.exp(x_new), True
        x = x_new
    return x, math.exp(x), False


@njit(**_JIT)
def _ro_log_yield(peeq, a, n):
    return (math.log(peeq) - a) / n


@njit(**_JIT)
def _ro_return_map(qt, pn, ln_pn, G3, a, n, tol, max_iter):
    """``RambergOsgood._return_map`` for one plastic point: (q, peeq, dq/dq_tr, ok);
    ``ln_pn = ln peeq_n`` (computed once for the yield test and the bracket).  The unknown
    is chosen at q* = e^(x*) (rho = 1) with no exp: ln P where q* < q_tr, P(q*) > 0 and the
    residual in ln q is negative there; ln P(q*) then bounds ln P from above (rho >= 1 on
    all the bracket), as does ln peeq(q_tr) (the start of Newton: the lower of the two).
    ``ln (peeq_n + q_tr/3G)``, the old third bound, is above ln P(q*): not computed."""
    q_star = n * (qt + G3 * pn) / (n + 1.0)
    p_star = pn + (qt - q_star) / G3
    by_q = True
    if q_star < qt and p_star > 0.0:
        x_star, y_hi = math.log(q_star), math.log(p_star)
        by_q = a + n * x_star - y_hi >= 0.0
    if by_q:
        x_star, ln_qt = math.log(q_star), math.log(qt)
        hi = _nmin(ln_qt, _ro_log_yield(pn + qt / G3, a, n))
        lo = _nmax((ln_pn - a) / n,
                   _nmin(ln_qt - _LN2, _ro_log_yield(pn + qt / (2.0 * G3), a, n)))
        x, q, ok = _safeguarded_newton(True, lo, _nmin(hi, x_star), tol, _quad_x(n), max_iter,
                                       qt, pn, G3, a, n)
        peeq = pn + (qt - q) / G3
    else:
        y_lo = _nmax(ln_pn, a + n * x_star)
        y_hi = _nmin(y_hi, a + n * math.log(qt))        # P <= peeq(q_tr) too
        y, peeq, ok = _safeguarded_newton(False, y_lo, y_hi, tol, QUAD_Y, max_iter, qt, pn, G3,
                                          a, n)
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
# the element loop: LANES elements side by side

#: elements computed side by side.  Every per-point quantity of a block is a row of LANES
#: values (the element of the block is the last, contiguous axis), and the arithmetic loops
#: run over the lanes, which LLVM turns into packed instructions; each lane does the scalar
#: arithmetic of one element in the same order, so every answer is the element-by-element one
#: bit for bit (``fastmath=False``: no reassociation, no contraction into FMA).  The law (its
#: branches and logarithms) and the scatter stay scalar, lane by lane.
LANES = 16


def _rows(*counts: int) -> list[int]:
    """Offsets in the lane array of consecutive groups of ``counts`` rows, and its length."""
    out, at = [], 0
    for c in counts:
        out.append(at * LANES)
        at += c
    return out + [at * LANES]


# the lane array ``v``: rows at constant offsets, so LLVM sees that the rows a loop reads and
# writes never overlap and vectorises it without run-time alias checks.  _W weight; _OLD the
# start of the increment (9, as start_kernel's ``old``); _B trial b_e 00, 01, 10, 11, 33;
# _EIG its lam0, lam1, cos 2t, sin 2t; _FI F^-1 00, 01, 10, 11; _TAU the law's stress (tau
# under NLGEOM); _T w tau; _D the law's D (4 s + t); _C the Daleckii-Krein c0, c1, c2; _R0 the
# reference radius; _SUM small strain's B u_new (4) and B u_old (4); _COL the w D M columns of
# one node (and the geometric parts) that the node-pair loop reads
(_W, _OLD, _B, _EIG, _FI, _TAU, _T, _D, _C, _R0, _SUM, _COL, _NV) = _rows(
    1, 9, 5, 4, 4, 4, 4, 16, 3, 1, 8, 11)
_L = LANES


def scratch_arrays(nen: int, nq: int) -> tuple:
    """Work arrays of the kernels (they allocate nothing themselves, see ``_JIT``).

    Of :func:`_start_kernel`: nodal displacements (a, 2), F (q, 2, 2), F33 (q,), radius (q,).
    Of :func:`_solid_kernel`, flat, lane axis last (``LANES``): the block's elements (l,); the
    lane array (rows ``_W`` ...); U: u_new then u_old (2 a + i); X: dN/dX (q, a, j); Fq: F00,
    F01, F10, F11, F33, r (q, 6); G: dN/dx and the hoop row (a, 3); Ml: M (d, s); fl: element
    force (d,); Ke: element tangent by node pair (b, a, 4: [2a, 2b], [2a, 2b+1], [2a+1, 2b],
    [2a+1, 2b+1]).  Of the law, one point: trial strain, stress, D (4, 4), elastic strain."""
    nd = 2 * nen
    return (np.empty((nen, 2)), np.empty((nq, 2, 2)), np.empty(nq), np.empty(nq),
            np.zeros(_L, np.int64), np.zeros(_NV), np.zeros(2 * nd * _L),
            np.zeros(nq * nd * _L), np.zeros(nq * 6 * _L), np.zeros(3 * nen * _L),
            np.zeros(4 * nd * _L), np.zeros(nd * _L), np.zeros(nd * nd * _L),
            np.empty(4), np.empty(4), np.empty((4, 4)), np.empty(4))


@njit(**_JIT)
def _solid_kernel(nlgeom, tangent, axisym, kind, lp, Del, conn, u_new, u_old, Nq, dNdX, R0, w0,
                 eps_e_n, peeq_n, old, bad_old, eps_e_out, peeq_out, stress_out, fe, flags,
                 data, f_out, pos, dofs, scratch, defer):
    """Compute every element of a group and scatter it.

    Inputs: ``conn`` (e, a); ``u_new``/``u_old`` (n, 2); ``Nq`` (q, a); ``dNdX`` (e, q, a, 2);
    ``R0``/``w0`` (e, q); the committed ``eps_e_n`` (e, q, 4), ``peeq_n`` (e, q); NLGEOM:
    ``old`` (e, q, 9) and ``bad_old`` (e,) from :func:`start_kernel`; ``pos`` (e, d, d)
    positions of the element blocks in ``data`` and ``dofs`` (e, d).
    Outputs: the trial state ``eps_e_out``, ``peeq_out``, ``stress_out`` (Cauchy), the element
    forces ``fe`` (e, d), added into ``f_out`` (ndof,); the tangent added into ``data`` (nnz,)
    when ``tangent``; ``flags`` (e,) OK / BAD_DET_F (element skipped) / RETURN_MAP_FAILED.
    ``scratch``: the work arrays of :func:`scratch_arrays`.  ``defer``: :data:`NO_DEFER` (every
    contribution into ``data`` and ``f_out``) or, for an element range on a thread of its own,
    the range's :class:`Split` tables (its contributions to entries an earlier range also
    touches go, in order, to buffers that :meth:`Split.run` adds afterwards).

    Blocks of ``LANES`` elements; the last block's spare lanes repeat its last element, and
    are computed (the vector loops) but never read, nor is any lane of a BAD_DET_F element.
    """
    ne, nen = conn.shape
    nq = Nq.shape[0]
    nd = 2 * nen
    _, _, _, _, el, v, U, X, Fq, G, Ml, fl, Ke, eps, stress, D, eps_e = scratch
    brow, bdof, bpos, fbuf, kbuf = defer
    deferring = brow.shape[0] > 0
    for e0 in range(0, ne, _L):
        n = min(_L, ne - e0)
        for l in range(_L):
            el[l] = e0 + min(l, n - 1)
        for l in range(n):
            flags[e0 + l] = OK
        _gather(el, conn, u_new, u_old, dNdX, nen, nq, U, X)
        if nlgeom:
            for q in range(nq):
                _block_deformation(U, X, Nq, R0, el, q, nen, axisym, Fq)
            for l in range(n):
                e = e0 + l
                bad = bad_old[e] != 0
                for q in range(nq):
                    o = q * 6 * _L + l
                    det = Fq[o] * Fq[o + 3 * _L] - Fq[o + _L] * Fq[o + 2 * _L]
                    bad |= (det <= 0.0) or (Fq[o + 4 * _L] <= 0.0)
                if bad:
                    flags[e] = BAD_DET_F
        for i in range(nd * _L):
            fl[i] = 0.0
        if tangent:
            for i in range(nd * nd * _L):
                Ke[i] = 0.0
        for q in range(nq):
            for l in range(_L):
                v[_W + l] = w0[el[l], q]
            if nlgeom:
                _large_strain_block(n, el, q, nen, Fq, X, old, Nq, axisym, kind, lp, Del,
                                    eps_e_n, peeq_n, eps_e_out, peeq_out, stress_out, tangent,
                                    flags, v, G, Ml, fl, Ke, eps, stress, D, eps_e)
            else:
                _small_strain_block(n, el, q, nen, U, X, Fq, R0, Nq, axisym, kind, lp, Del,
                                    eps_e_n, peeq_n, eps_e_out, peeq_out, stress_out, tangent,
                                    flags, v, G, Ml, fl, Ke, eps, stress, D, eps_e)
        if deferring:           # a range after the first, on its own thread
            _scatter_deferred(n, el, nen, tangent, flags, fl, Ke, fe, f_out, data, pos, dofs,
                              brow, bdof, bpos, fbuf, kbuf)
        else:
            _scatter(n, el, nen, tangent, flags, fl, Ke, fe, f_out, data, pos, dofs)


@njit(inline="always", **_JIT)
def _view(a, row, rows):
    """Rows ``row`` to ``row + rows`` of a flat lane array: inside a loop over the lanes the
    index is then a constant plus the lane, which LLVM knows is not negative (no wrap-around
    select), so the access is a unit-stride one it vectorises."""
    return a[row * _L:(row + rows) * _L]


@njit(inline="always", **_JIT)
def _gather(el, conn, u_new, u_old, dNdX, nen, nq, U, X):
    """The block's nodal displacements (U: u_new then u_old) and dN/dX, lane axis last."""
    nd = 2 * nen
    for l in range(_L):
        e = el[l]
        for a in range(nen):
            na = conn[e, a]
            U[2 * a * _L + l], U[(2 * a + 1) * _L + l] = u_new[na, 0], u_new[na, 1]
            U[(nd + 2 * a) * _L + l], U[(nd + 2 * a + 1) * _L + l] = u_old[na, 0], u_old[na, 1]
        for q in range(nq):
            for a in range(nen):
                for j in range(2):
                    X[((q * nen + a) * 2 + j) * _L + l] = dNdX[e, q, a, j]


@njit(inline="always", **_JIT)
def _block_deformation(U, X, Nq, R0, el, q, nen, axisym, Fq):
    """In-plane F, F33 and the current radius of point q of every lane (``_deformation``)."""
    Fp = _view(Fq, q * 6, 6)
    for i in range(4 * _L):
        Fp[i] = 0.0
    for a in range(nen):                # the four sums over a, each in the order of a
        u, x = _view(U, 2 * a, 2), _view(X, (q * nen + a) * 2, 2)
        for l in range(_L):
            Fp[l] += u[l] * x[l]
            Fp[_L + l] += u[l] * x[_L + l]
            Fp[2 * _L + l] += u[_L + l] * x[l]
            Fp[3 * _L + l] += u[_L + l] * x[_L + l]
    for l in range(_L):     # "+ 0.0" as _deformation's acc + 0.0: a -0.0 sum becomes +0.0
        Fp[l] = Fp[l] + 1.0
        Fp[_L + l] = Fp[_L + l] + 0.0
        Fp[2 * _L + l] = Fp[2 * _L + l] + 0.0
        Fp[3 * _L + l] = Fp[3 * _L + l] + 1.0
    if axisym:
        for l in range(_L):
            Fp[5 * _L + l] = 0.0
        for a in range(nen):
            u, na = _view(U, 2 * a, 1), Nq[q, a]
            for l in range(_L):
                Fp[5 * _L + l] += na * u[l]
        for l in range(_L):
            Fp[5 * _L + l] = R0[el[l], q] + Fp[5 * _L + l]
            Fp[4 * _L + l] = Fp[5 * _L + l] / R0[el[l], q]
    else:
        for l in range(_L):
            Fp[5 * _L + l] = R0[el[l], q]
            Fp[4 * _L + l] = 1.0


@njit(inline="always", **_JIT)
def _lane_law(el, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, flags,
              stress, D, eps_e, v, l, tangent):
    """The law at one lane's point (the trial strain in ``eps``): the new eps_e and peeq to the
    output state, a failure to ``flags``, stress (and D for a ``tangent``) to the lane rows."""
    e = el[l]
    ok = _point_law(e, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, stress, D,
                    eps_e)
    if not ok:
        flags[e] = RETURN_MAP_FAILED
    for s in range(4):
        v[_TAU + s * _L + l] = stress[s]
    if tangent:
        for s in range(4):
            for t in range(4):
                v[_D + (4 * s + t) * _L + l] = D[s, t]


# The three per-point block functions are called, not inlined: inlined (twice for
# _force_and_tangent), the kernel took 22 s of CPU and 610 MB to compile instead of 11 s and
# 250 MB, for no speed (one call per point and block of LANES elements).

@njit(**_JIT)
def _small_strain_block(n, el, q, nen, U, X, Fq, R0, Nq, axisym, kind, lp, Del, eps_e_n, peeq_n,
                        eps_e_out, peeq_out, stress_out, tangent, flags, v, G, Ml, fl, Ke, eps,
                        stress, D, eps_e):
    """Point q of ``_small_strain`` in every lane: trial ``B u_new - B u_old + eps_e_n``, the
    law, f += w B^T sig and Ke += w B^T D B."""
    nd = 2 * nen
    for l in range(_L):
        v[_R0 + l] = R0[el[l], q]
    for a in range(nen):
        x, g, na = _view(X, (q * nen + a) * 2, 2), _view(G, 3 * a, 3), Nq[q, a]
        for l in range(_L):
            g[l], g[_L + l] = x[l], x[_L + l]
            g[2 * _L + l] = na / v[_R0 + l] if axisym else 0.0
    for i in range(8 * _L):
        v[_SUM + i] = 0.0
    for a in range(nen):
        g, un, uo = _view(G, 3 * a, 3), _view(U, 2 * a, 2), _view(U, nd + 2 * a, 2)
        for l in range(_L):
            x0, x1, h = g[l], g[_L + l], g[2 * _L + l]
            n0, n1 = un[l], un[_L + l]
            p0, p1 = uo[l], uo[_L + l]
            v[_SUM + l] += x0 * n0
            v[_SUM + _L + l] += x1 * n1
            v[_SUM + 2 * _L + l] += h * n0
            v[_SUM + 3 * _L + l] += x1 * n0 + x0 * n1
            v[_SUM + 4 * _L + l] += x0 * p0
            v[_SUM + 5 * _L + l] += x1 * p1
            v[_SUM + 6 * _L + l] += h * p0
            v[_SUM + 7 * _L + l] += x1 * p0 + x0 * p1
    for l in range(n):
        e = el[l]
        for s in range(4):
            eps[s] = (v[_SUM + s * _L + l] - v[_SUM + (4 + s) * _L + l]) + eps_e_n[e, q, s]
        _lane_law(el, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, flags,
                  stress, D, eps_e, v, l, tangent)
        for s in range(4):
            stress_out[e, q, s] = stress[s]
    if tangent:                         # M = B (d, s)
        for a in range(nen):
            g, m = _view(G, 3 * a, 3), _view(Ml, 8 * a, 8)
            for l in range(_L):
                x0, x1 = g[l], g[_L + l]
                m[l], m[_L + l], m[2 * _L + l], m[3 * _L + l] = x0, 0.0, g[2 * _L + l], x1
                m[4 * _L + l], m[5 * _L + l], m[6 * _L + l], m[7 * _L + l] = 0.0, x1, 0.0, x0
    _force_and_tangent(nen, q, Nq, G, Ml, v, _view(Fq, 0, 1), tangent, False, axisym, fl, Ke)


@njit(**_JIT)
def _large_strain_block(n, el, q, nen, Fq, X, old, Nq, axisym, kind, lp, Del, eps_e_n, peeq_n,
                        eps_e_out, peeq_out, stress_out, tangent, flags, v, G, Ml, fl, Ke, eps,
                        tau, D, eps_e):
    """Point q of ``_large_strain`` in every lane (det F already checked): trial b_e, its
    Hencky strain and Daleckii-Krein derivative, the law (Kirchhoff tau), f += w G^T tau and
    Ke += w G^T D M + the geometric part."""
    Fp = _view(Fq, q * 6, 6)
    for l in range(_L):
        e = el[l]
        for k in range(9):
            v[_OLD + k * _L + l] = old[e, q, k]
    for l in range(_L):
        # start of the increment (start_kernel): F_old^-1, F33_old, b_e_n = exp(2 eps_e_n)
        i00, i01 = v[_OLD + l], v[_OLD + _L + l]
        i10, i11 = v[_OLD + 2 * _L + l], v[_OLD + 3 * _L + l]
        bn00, bn01 = v[_OLD + 5 * _L + l], v[_OLD + 6 * _L + l]
        bn11, bn33 = v[_OLD + 7 * _L + l], v[_OLD + 8 * _L + l]
        # relative deformation f = F F_old^-1 and the trial b = f b_n f^T
        F00, F01, F10, F11 = Fp[l], Fp[_L + l], Fp[2 * _L + l], Fp[3 * _L + l]
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
        f33 = Fp[4 * _L + l] / v[_OLD + 4 * _L + l]
        v[_B + l], v[_B + _L + l], v[_B + 2 * _L + l], v[_B + 3 * _L + l] = b00, b01, b10, b11
        v[_B + 4 * _L + l] = f33 ** 2 * bn33
        lam0, lam1, cs, sn = _sym_eig2(b00, b11, 0.5 * (b01 + b10))
        v[_EIG + l], v[_EIG + _L + l], v[_EIG + 2 * _L + l], v[_EIG + 3 * _L + l] = \
            lam0, lam1, cs, sn
    for l in range(n):
        e = el[l]
        if flags[e] == BAD_DET_F:
            continue
        # 1/2 ln b and the eigenprojections
        lam0, lam1 = v[_EIG + l], v[_EIG + _L + l]
        cs, sn = v[_EIG + 2 * _L + l], v[_EIG + 3 * _L + l]
        P0_00, P0_01, P0_11 = 0.5 * (1.0 + cs), 0.5 * sn, 0.5 * (1.0 - cs)
        P1_00, P1_01, P1_11 = P0_11, -P0_01, P0_00
        hl0, hl1 = 0.5 * math.log(lam0), 0.5 * math.log(lam1)
        E00 = hl0 * P0_00 + hl1 * P1_00
        E11 = hl0 * P0_11 + hl1 * P1_11
        E01 = hl0 * P0_01 + hl1 * P1_01
        eps[0], eps[1], eps[2], eps[3] = E00, E11, 0.5 * math.log(v[_B + 4 * _L + l]), 2.0 * E01
        _lane_law(el, q, kind, lp, Del, eps, eps_e_n, peeq_n, eps_e_out, peeq_out, flags,
                  tau, D, eps_e, v, l, tangent)
        F00, F01, F10, F11 = Fp[l], Fp[_L + l], Fp[2 * _L + l], Fp[3 * _L + l]
        det2 = F00 * F11 - F01 * F10
        J = det2 * Fp[4 * _L + l]
        for s in range(4):
            stress_out[e, q, s] = tau[s] / J
        if tangent:
            # material part: d eps_trial = C : (l b + b l^T), l = grad_x du; C from
            # Daleckii-Krein C = c0 P0 x P0 + c1 P1 x P1 + c2 S x S, S = v0 v1^T + v1 v0^T
            m = 0.5 * (lam0 + lam1)
            xr = 0.5 * (lam0 - lam1) / m
            if xr < 1e-6:
                ratio = 1.0 + xr * xr / 3.0
            else:
                ratio = math.atanh(_nmin(xr, 1 - 1e-16)) / xr
            v[_C + l], v[_C + _L + l], v[_C + 2 * _L + l] = 0.5 / lam0, 0.5 / lam1, 0.25 * ratio / m
    # spatial gradients dN/dx = dN/dX F^-1 and the hoop row with the current radius
    for l in range(_L):
        F00, F01, F10, F11 = Fp[l], Fp[_L + l], Fp[2 * _L + l], Fp[3 * _L + l]
        det2 = F00 * F11 - F01 * F10
        s_inv = 1.0 / (1.0 if det2 == 0.0 else det2)
        v[_FI + l], v[_FI + _L + l] = F11 * s_inv, -F01 * s_inv
        v[_FI + 2 * _L + l], v[_FI + 3 * _L + l] = -F10 * s_inv, F00 * s_inv
    for a in range(nen):
        x, g, na = _view(X, (q * nen + a) * 2, 2), _view(G, 3 * a, 3), Nq[q, a]
        for l in range(_L):
            X0, X1 = x[l], x[_L + l]
            g[l] = X0 * v[_FI + l] + X1 * v[_FI + 2 * _L + l]
            g[_L + l] = X0 * v[_FI + _L + l] + X1 * v[_FI + 3 * _L + l]
            g[2 * _L + l] = na / Fp[5 * _L + l] if axisym else 0.0
    if tangent:
        for b in range(nen):
            g, m = _view(G, 3 * b, 3), _view(Ml, 8 * b, 8)
            for l in range(_L):
                cs, sn = v[_EIG + 2 * _L + l], v[_EIG + 3 * _L + l]
                P0_00, P0_01, P0_11 = 0.5 * (1.0 + cs), 0.5 * sn, 0.5 * (1.0 - cs)
                P1_00, P1_01, P1_11 = P0_11, -P0_01, P0_00
                S_00, S_01, S_11 = -sn, cs, sn
                x0, x1 = g[l], g[_L + l]
                h0 = x0 * v[_B + l] + x1 * v[_B + 2 * _L + l]          # h_bn = dN_b/dx_m b_mn
                h1 = x0 * v[_B + _L + l] + x1 * v[_B + 3 * _L + l]
                c0, c1, c2 = 2.0 * v[_C + l], 2.0 * v[_C + _L + l], 2.0 * v[_C + 2 * _L + l]
                # (P h_b)_k = sum_n P_kn h_bn, then dE_ijbk = 2 (c0 P0_ij (P0 h)_k + ...);
                # the DOFs k = 0 and 1 of node b written out (one lane loop per node)
                u0 = c0 * (P0_00 * h0 + P0_01 * h1)
                u1 = c1 * (P1_00 * h0 + P1_01 * h1)
                u2 = c2 * (S_00 * h0 + S_01 * h1)
                m[l] = u0 * P0_00 + u1 * P1_00 + u2 * S_00
                m[_L + l] = u0 * P0_11 + u1 * P1_11 + u2 * S_11
                m[3 * _L + l] = 2.0 * (u0 * P0_01 + u1 * P1_01 + u2 * S_01)
                m[2 * _L + l] = g[2 * _L + l]                       # d eps33 = du_r / r
                u0 = c0 * (P0_01 * h0 + P0_11 * h1)
                u1 = c1 * (P1_01 * h0 + P1_11 * h1)
                u2 = c2 * (S_01 * h0 + S_11 * h1)
                m[4 * _L + l] = u0 * P0_00 + u1 * P1_00 + u2 * S_00
                m[5 * _L + l] = u0 * P0_11 + u1 * P1_11 + u2 * S_11
                m[7 * _L + l] = 2.0 * (u0 * P0_01 + u1 * P1_01 + u2 * S_01)
                m[6 * _L + l] = 0.0
    _force_and_tangent(nen, q, Nq, G, Ml, v, _view(Fp, 5, 1), tangent, True, axisym, fl, Ke)


@njit(**_JIT)
def _force_and_tangent(nen, q, Nq, G, Ml, v, r_, tangent, geometric, axisym, fl, Ke):
    """f += w G^T tau and Ke += w G^T D M (+ the geometric part when ``geometric``) in every
    lane, with G the strain operator of gradients dx and hoop row hh (``G``, (a, 3)):
    G_a = [[dx_a0, 0], [0, dx_a1], [hh_a, 0], [dx_a1, dx_a0]]; tau, D, w in the lane rows.

    Geometric part (NLGEOM): ``Kg[a i, b k] = -w dN_a/dx_k (dN_b/dx_j tau_ji)``, and in
    axisymmetry ``Kg[a 0, b 0] -= w tau_33 / r^2 N_a N_b`` (``Nq[q]`` the N_a of the point, r
    the lanes' current radius ``r_``).  Node b's w D M columns go to the rows ``_COL``, then
    :func:`_node_pairs` adds them up."""
    for l in range(_L):
        w = v[_W + l]
        v[_T + l], v[_T + _L + l] = w * v[_TAU + l], w * v[_TAU + _L + l]
        v[_T + 2 * _L + l], v[_T + 3 * _L + l] = w * v[_TAU + 2 * _L + l], w * v[_TAU + 3 * _L + l]
    for a in range(nen):
        g, fa = _view(G, 3 * a, 3), _view(fl, 2 * a, 2)
        for l in range(_L):
            x0, x1, h = g[l], g[_L + l], g[2 * _L + l]
            t0, t1, t2, t3 = v[_T + l], v[_T + _L + l], v[_T + 2 * _L + l], v[_T + 3 * _L + l]
            fa[l] += x0 * t0 + h * t2 + x1 * t3
            fa[_L + l] += x1 * t1 + x0 * t3
    if not tangent:
        return
    # Exact zeros are left out of the sums: M[2, 2b+1] (a radial stretch only from u_r), in
    # plane strain M[2, :] (no hoop row) and p2, q2 (unread), in small strain the geometric
    # terms.  Each dropped term is a +-0.0 added in place, so a sum it left out differs at most
    # by the sign of a zero, which Ke does not keep (its sums start from +0.0: +0.0 + -0.0 is
    # +0.0); a non-finite D is a failure (the law's ok) before Ke is read.
    for b in range(nen):
        g, m = _view(G, 3 * b, 3), _view(Ml, 8 * b, 8)
        for l in range(_L):
            w = v[_W + l]
            t0, t1, t2, t3 = v[_T + l], v[_T + _L + l], v[_T + 2 * _L + l], v[_T + 3 * _L + l]
            m00, m10, m30 = m[l], m[_L + l], m[3 * _L + l]
            m01, m11, m31 = m[4 * _L + l], m[5 * _L + l], m[7 * _L + l]
            D00, D01, D02, D03 = v[_D + l], v[_D + _L + l], v[_D + 2 * _L + l], v[_D + 3 * _L + l]
            D10, D11, D12, D13 = (v[_D + 4 * _L + l], v[_D + 5 * _L + l], v[_D + 6 * _L + l],
                                  v[_D + 7 * _L + l])
            D20, D21, D22, D23 = (v[_D + 8 * _L + l], v[_D + 9 * _L + l], v[_D + 10 * _L + l],
                                  v[_D + 11 * _L + l])
            D30, D31, D32, D33 = (v[_D + 12 * _L + l], v[_D + 13 * _L + l], v[_D + 14 * _L + l],
                                  v[_D + 15 * _L + l])
            # columns of w D M for the two DOFs of node b
            if axisym:
                m20 = m[2 * _L + l]
                p0 = w * (D00 * m00 + D01 * m10 + D02 * m20 + D03 * m30)
                p1 = w * (D10 * m00 + D11 * m10 + D12 * m20 + D13 * m30)
                p2 = w * (D20 * m00 + D21 * m10 + D22 * m20 + D23 * m30)
                p3 = w * (D30 * m00 + D31 * m10 + D32 * m20 + D33 * m30)
                q2 = w * (D20 * m01 + D21 * m11 + D23 * m31)
            else:
                p0 = w * (D00 * m00 + D01 * m10 + D03 * m30)
                p1 = w * (D10 * m00 + D11 * m10 + D13 * m30)
                p3 = w * (D30 * m00 + D31 * m10 + D33 * m30)
                p2 = q2 = 0.0
            q0 = w * (D00 * m01 + D01 * m11 + D03 * m31)
            q1 = w * (D10 * m01 + D11 * m11 + D13 * m31)
            q3 = w * (D30 * m01 + D31 * m11 + D33 * m31)
            # material and geometric parts share their factors dN_a/dx_k; geometric: w dN_b/dx_j
            # tau_ji (i = 0, 1) and the hoop term's w tau33 / r^2 N_b
            if geometric:
                wt00, wt11, wt01 = t0, t1, t3
                x0, x1 = g[l], g[_L + l]
                T0 = x0 * wt00 + x1 * wt01
                T1 = x0 * wt01 + x1 * wt11
                a00, a11, b11, b00 = p0 - T0, q3 - T0, p3 - T1, q1 - T1
            else:
                a00, a11, b11, b00 = p0, q3, p3, q1
            if geometric and axisym:
                r = r_[l]
                cax = t2 / (r * r)
            else:
                cax = 0.0
            v[_COL + l], v[_COL + _L + l], v[_COL + 2 * _L + l] = a00, p3, p2
            v[_COL + 3 * _L + l], v[_COL + 4 * _L + l], v[_COL + 5 * _L + l] = \
                cax * Nq[q, b], q0, a11
            v[_COL + 6 * _L + l], v[_COL + 7 * _L + l], v[_COL + 8 * _L + l] = q2, b11, p1
            v[_COL + 9 * _L + l], v[_COL + 10 * _L + l] = q3, b00
        _node_pairs(nen, b, q, Nq, G, v, Ke, axisym)


@njit(inline="always", **_JIT)
def _node_pairs(nen, b, q, Nq, G, v, Ke, axisym):
    """Ke[a, b] += G_a^T (the w D M columns of node b, rows ``_COL``), one lane loop per node
    pair.  (The loop over a inside the lane loop, unrolled for Q8, was not vectorised by LLVM:
    twice the scalar instructions, no gain.)"""
    for a in range(nen):
        g, k = _view(G, 3 * a, 3), _view(Ke, (b * nen + a) * 4, 4)
        if axisym:
            na = Nq[q, a]
            for l in range(_L):
                x0, x1, h = g[l], g[_L + l], g[2 * _L + l]
                hb = v[_COL + 3 * _L + l]
                k[l] += (x0 * v[_COL + l] + x1 * v[_COL + _L + l]
                         + h * v[_COL + 2 * _L + l] - hb * na)
                k[_L + l] += (x0 * v[_COL + 4 * _L + l] + x1 * v[_COL + 5 * _L + l]
                              + h * v[_COL + 6 * _L + l])
                k[2 * _L + l] += x0 * v[_COL + 7 * _L + l] + x1 * v[_COL + 8 * _L + l]
                k[3 * _L + l] += x0 * v[_COL + 9 * _L + l] + x1 * v[_COL + 10 * _L + l]
        else:
            for l in range(_L):
                x0, x1 = g[l], g[_L + l]
                k[l] += x0 * v[_COL + l] + x1 * v[_COL + _L + l]
                k[_L + l] += x0 * v[_COL + 4 * _L + l] + x1 * v[_COL + 5 * _L + l]
                k[2 * _L + l] += x0 * v[_COL + 7 * _L + l] + x1 * v[_COL + 8 * _L + l]
                k[3 * _L + l] += x0 * v[_COL + 9 * _L + l] + x1 * v[_COL + 10 * _L + l]


@njit(inline="always", **_JIT)
def _scatter(n, el, nen, tangent, flags, fl, Ke, fe, f_out, data, pos, dofs):
    """The block's element forces to ``fe`` and ``f_out`` and tangents to ``data``, element by
    element in order (each entry's sum in the element-by-element order); a BAD_DET_F element
    and the spare lanes add nothing."""
    for l in range(n):
        if flags[el[l]] != BAD_DET_F:
            _scatter_element(l, el[l], nen, tangent, fl, Ke, fe, f_out, data, pos, dofs)


@njit(inline="always", **_JIT)
def _scatter_element(l, e, nen, tangent, fl, Ke, fe, f_out, data, pos, dofs):
    """Lane ``l``'s element ``e`` to ``fe``, ``f_out`` and ``data``."""
    nd = 2 * nen
    for d in range(nd):
        fe[e, d] = fl[d * _L + l]
        f_out[dofs[e, d]] += fl[d * _L + l]
    if tangent:
        for d in range(nd):
            for d2 in range(nd):
                data[pos[e, d, d2]] += Ke[_ke_at(d, d2, nen, l)]


@njit(inline="always", **_JIT)
def _ke_at(d, d2, nen, l):
    """Where lane ``l``'s element tangent entry [d, d2] is in ``Ke`` (node pair (d2 // 2,
    d // 2), component 2 (d % 2) + d2 % 2: see :func:`scratch_arrays`); both scatters read
    through it."""
    return ((d2 // 2 * nen + d // 2) * 4 + 2 * (d % 2) + d2 % 2) * _L + l


@njit(inline="always", **_JIT)
def _scatter_deferred(n, el, nen, tangent, flags, fl, Ke, fe, f_out, data, pos, dofs,
                      brow, bdof, bpos, fbuf, kbuf):
    """:func:`_scatter` of a range on a thread of its own: an element of the range's boundary
    (``brow[e] >= 0``) sends each contribution to an entry that an earlier range also touches
    to its slot ``-t - 1`` of ``fbuf`` / ``kbuf`` (``t`` the entry's code in ``bdof`` /
    ``bpos``), every other contribution straight into ``f_out`` / ``data`` (an entry no other
    thread writes)."""
    nd = 2 * nen
    for l in range(n):
        e = el[l]
        if flags[e] == BAD_DET_F:
            continue
        r = brow[e]
        if r < 0:                                   # inside the range: as _scatter
            _scatter_element(l, e, nen, tangent, fl, Ke, fe, f_out, data, pos, dofs)
            continue
        for d in range(nd):
            x = fl[d * _L + l]
            fe[e, d] = x
            t = bdof[r, d]
            if t >= 0:
                f_out[t] += x
            else:
                fbuf[-t - 1] = x
        if tangent:
            for d in range(nd):
                for d2 in range(nd):
                    t = bpos[r, d, d2]
                    if t >= 0:
                        data[t] += Ke[_ke_at(d, d2, nen, l)]
                    else:
                        kbuf[-t - 1] = Ke[_ke_at(d, d2, nen, l)]


@njit(**_JIT)
def _start_kernel(axisym, conn, u_old, Nq, dNdX, R0, eps_e_n, old, bad_old, scratch):
    """What NLGEOM needs of the start of the increment (``SolidGroup._start_of_increment``),
    per point into ``old`` (e, q, 9): F_old^-1 (4, row-major), F33_old, b_e_n = exp(2 eps_e_n)
    in-plane (00, 01, 11) and 33; ``bad_old`` (e,) 1 where det F_old <= 0 or F33_old <= 0."""
    ne, nen = conn.shape
    nq = Nq.shape[0]
    uo, F, F33, r = scratch[0], scratch[1], scratch[2], scratch[3]
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


# --------------------------------------------------------------------------------------------
# entry points (counted: a test of a fast path proves the fast path ran)

def solid_group(*args, split: "Split | None" = None) -> None:
    """:func:`_solid_kernel` (the arguments are its own but the trailing ``defer``): on one
    thread, or on the ranges of ``split``, one thread each (the same bytes)."""
    calls["solid"] += 1
    if split is None:
        _solid_kernel(*args, NO_DEFER)
    else:
        calls["solid_split"] += 1
        split.run(args)


def start_group(*args) -> None:
    """:func:`_start_kernel` (the arguments are its own)."""
    calls["solid_start"] += 1
    _start_kernel(*args)


# --------------------------------------------------------------------------------------------
# element ranges on threads, bit for bit with one thread

#: ``defer`` of the one-thread kernel: no boundary rows, every contribution straight in
NO_DEFER = (np.empty(0, np.int64), np.empty((0, 0), np.int64), np.empty((0, 0, 0), np.int64),
            np.empty(0), np.empty(0))

#: :func:`_solid_kernel`'s arguments (but ``defer``), and those with a leading element axis:
#: a range runs on their slices (C-contiguous views, the one compiled signature)
_ARGS = ("nlgeom", "tangent", "axisym", "kind", "lp", "Del", "conn", "u_new", "u_old", "Nq",
         "dNdX", "R0", "w0", "eps_e_n", "peeq_n", "old", "bad_old", "eps_e_out", "peeq_out",
         "stress_out", "fe", "flags", "data", "f_out", "pos", "dofs", "scratch")
_PER_ELEMENT = tuple(i for i, name in enumerate(_ARGS) if name in (
    "conn", "dNdX", "R0", "w0", "eps_e_n", "peeq_n", "old", "bad_old", "eps_e_out", "peeq_out",
    "stress_out", "fe", "flags", "pos", "dofs"))
_FLAGS, _DATA, _F_OUT, _SCRATCH = (_ARGS.index(n) for n in ("flags", "data", "f_out", "scratch"))


class _Deferred:
    """What one range after the first defers, for :func:`_scatter_deferred`: ``defer`` (its
    trailing kernel argument: ``brow`` (e,) the element's row in ``bdof`` (k, d) / ``bpos``
    (k, d, d) or -1 inside the range, there an entry's index or ``-1 - slot``, and the buffers
    ``fbuf`` / ``kbuf``), and for each buffer the waves that add it: (slots, their element,
    their entry), each entry at most once per wave, the waves in the slots' order."""

    def __init__(self, dofs, pos, seen_f, seen_k):
        shared = seen_f[dofs]                                   # (e, d)
        rows = np.flatnonzero(shared.any(axis=1))
        brow = np.full(len(dofs), -1, np.int64)
        brow[rows] = np.arange(len(rows))
        # an entry an earlier range touches is a DOF it touches too (the entry's row DOF):
        # the rows of shared DOFs hold every shared entry
        bdof, self.f_waves = self._codes(dofs[rows], shared[rows], rows)
        if pos.size:
            p = pos[rows]
            bpos, self.k_waves = self._codes(p, seen_k[p], rows)
        else:
            bpos, self.k_waves = NO_DEFER[2], []
        self.defer = (brow, bdof, bpos, np.zeros(-int(bdof.min(initial=0))),
                      np.zeros(-int(bpos.min(initial=0))))

    @staticmethod
    def _codes(to, shared, rows):
        """``to`` (int64) with its shared entries replaced by ``-1 - slot`` (slots in C order,
        the scatter's), and the waves adding the slots back."""
        codes = to.astype(np.int64)
        n = int(shared.sum())
        target = codes[shared]
        element = np.repeat(rows, shared.sum(axis=tuple(range(1, shared.ndim))))
        codes[shared] = -1 - np.arange(n)
        # the rank of each slot among those of its entry: wave w holds the w-th of each entry
        order = np.argsort(target, kind="stable")
        first = np.r_[True, target[order][1:] != target[order][:-1]]
        start = np.maximum.accumulate(np.where(first, np.arange(n), 0))
        rank = np.empty(n, np.int64)
        rank[order] = np.arange(n) - start
        waves = []
        for w in range(int(rank.max(initial=-1)) + 1):
            slots = np.flatnonzero(rank == w)
            waves.append((slots, element[slots], target[slots]))
        return codes, waves

    def add(self, tangent, flags, f_out, data) -> None:
        """The deferred contributions into ``f_out`` (and ``data``), wave by wave; a BAD_DET_F
        element's slots (not written by this call: they hold an earlier call's) left out."""
        parts = [(self.f_waves, self.defer[3], f_out)]
        if tangent:
            parts.append((self.k_waves, self.defer[4], data))
        for waves, buf, out in parts:
            for slots, element, target in waves:
                ok = flags[element] != BAD_DET_F
                out[target[ok]] += buf[slots[ok]]


class Split:
    """One group's elements in contiguous ranges, one thread each, summing every entry of
    ``data`` and ``f_out`` as the one-thread kernel does, in its order.

    The range bounds are multiples of ``LANES``.  An entry only one range touches is that
    thread's alone.  An entry several touch ("shared") is summed directly by the first of them,
    complete once its thread is joined; each later range writes its contributions to that
    entry, in order, to a buffer (:func:`_scatter_deferred`) added after the join, range after
    range.  Built from the group's ``dofs`` (e, d) and pattern positions ``pos`` (e, d, d), once
    per pattern; ``workers`` runs the ranges after the first (the caller's thread runs the
    first)."""

    def __init__(self, dofs, pos, parts: int, workers):
        ne = len(dofs)
        cuts = np.round(np.arange(1, parts) * ne / parts / LANES).astype(np.int64) * LANES
        self.bounds = np.unique(np.r_[0, np.clip(cuts, 0, ne), ne])
        self.workers = workers
        seen_f = np.zeros(int(dofs.max(initial=0)) + 1, bool)
        seen_k = np.zeros(int(pos.max(initial=0)) + 1 if pos.size else 0, bool)
        self.deferred = []
        for j, (lo, hi) in enumerate(zip(self.bounds[:-1], self.bounds[1:])):
            d, p = dofs[lo:hi], pos[lo:hi]
            if j:
                self.deferred.append(_Deferred(d, p, seen_f, seen_k))
            seen_f[d] = True
            seen_k[p] = True

    @property
    def ranges(self) -> list[tuple[int, int]]:
        return [(int(lo), int(hi)) for lo, hi in zip(self.bounds[:-1], self.bounds[1:])]

    def run(self, args) -> None:
        """:func:`_solid_kernel` on every range (``args`` its own but ``defer``), the deferred
        contributions added after."""
        nen, nq = args[_ARGS.index("conn")].shape[1], args[_ARGS.index("Nq")].shape[0]
        ranges = self.ranges
        futures = []
        try:
            for (lo, hi), deferred in zip(ranges[1:], self.deferred):
                futures.append(self.workers.submit(
                    _solid_kernel, *self._slice(args, lo, hi, scratch_arrays(nen, nq)),
                    deferred.defer))
            _solid_kernel(*self._slice(args, *ranges[0], args[_SCRATCH]), NO_DEFER)
        finally:
            for f in futures:             # no thread left writing when this returns
                f.result()
        tangent, flags = args[1], args[_FLAGS]
        for (lo, hi), deferred in zip(ranges[1:], self.deferred):
            deferred.add(tangent, flags[lo:hi], args[_F_OUT], args[_DATA])

    @staticmethod
    def _slice(args, lo, hi, scratch):
        out = list(args)
        for i in _PER_ELEMENT:
            out[i] = args[i][lo:hi]
        out[_SCRATCH] = scratch
        return out
