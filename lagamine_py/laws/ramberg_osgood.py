"""J2 plasticity with Ramberg-Osgood hardening (incremental theory).

The uniaxial curve ``eps = s/E + ALPHA (SIGMA0/E) (s/SIGMA0)^N`` is split into its elastic
part and a plastic part that defines the hardening curve of isotropic J2 plasticity::

    peeq(q)     = ALPHA (SIGMA0/E) (q/SIGMA0)^N           (plastic strain at von Mises stress q)
    sigma_y(p)  = SIGMA0 (p E / (ALPHA SIGMA0))^(1/N)     (its inverse)

so yielding starts at zero stress and ``d sigma_y / d peeq`` is infinite at ``peeq = 0``.

Radial return: with ``x = ln q`` the consistency equation
``peeq(q) = peeq_n + (q_tr - q) / (3G)`` becomes

    g(x) = ln peeq(e^x) - ln(peeq_n + (q_tr - e^x) / (3G)) = 0,

where ``ln peeq`` is *linear* in ``x`` (no overflow for any N, no infinite slope) and the
second term is convex: ``g`` is increasing and convex.  The root is bracketed a priori within
a factor 2 in ``q`` (see :meth:`RambergOsgood._bracket`); Newton on ``x`` starts from the upper
bound (monotone for a convex increasing ``g``) and falls back to bisection whenever a step
leaves the bracket, so it converges for any N and any increment size.
"""
from __future__ import annotations

import numpy as np

from ..core.params import Param
from ..kernels.layout import (QUAD_Y, RAMBERG_OSGOOD, SOLID_A, SOLID_G, SOLID_K, SOLID_MAXIT,
                              SOLID_N, SOLID_TOL, SOLID_VECTOR, quad_x)
from .j2 import J2Plasticity

__all__ = ["RambergOsgood", "safeguarded_newton"]


class RambergOsgood(J2Plasticity):
    """Von Mises plasticity whose uniaxial curve is Ramberg-Osgood's."""

    params = (
        Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
        Param("NU", float, bounds=(-0.999, 0.4999), doc="Poisson's ratio"),
        Param("SIGMA0", float, gt=0.0, unit="stress", doc="reference stress"),
        Param("ALPHA", float, gt=0.0, doc="yield offset coefficient"),
        Param("N", float, bounds=(1.0, None), doc="hardening exponent (>= 1)"),
    )

    @classmethod
    def example_values(cls):
        return {"E": 200e3, "NU": 0.3, "SIGMA0": 300.0, "ALPHA": 0.5, "N": 5.0}

    #: Newton tolerance on ln q (relative change of the equivalent stress) and iteration cap
    tol = 1e-13
    max_iter = 100

    def __init__(self, **values):
        super().__init__(**values)
        E, s0, a, n = (self.values[k] for k in ("E", "SIGMA0", "ALPHA", "N"))
        self._a = np.log(a * s0 / E) - n * np.log(s0)      # ln peeq(q) = _a + N ln q

    def plastic_strain(self, q):
        """Equivalent plastic strain on the hardening curve at von Mises stress ``q`` (>= 0)."""
        with np.errstate(divide="ignore"):
            return np.exp(self._a + self.values["N"] * np.log(np.asarray(q, dtype=float)))

    def yield_stress(self, peeq):
        return np.exp(self._log_yield(np.asarray(peeq, dtype=float)))

    def _log_yield(self, peeq):
        """``ln sigma_y(peeq)`` (``-inf`` at ``peeq = 0``)."""
        with np.errstate(divide="ignore"):
            return (np.log(peeq) - self._a) / self.values["N"]

    def _return_map(self, q_tr, peeq_n):
        """Solve the consistency equation on the plastic points (m,), all at once.

        Along the return line ``P = peeq_n + (q_tr - q)/3G`` the ratio
        ``rho = q / (3G N P)`` (with ``dq/dq_tr = rho/(1 + rho)``) decreases as ``q`` does; it
        is 1 at ``q* = N (q_tr + 3G peeq_n)/(N + 1)``.  Where the root has ``rho <= 1``
        (plastic flow dominates) the unknown is ``x = ln q``; where ``rho > 1`` (a small
        plastic correction, e.g. the first tiny increment from ``peeq = 0``) it is
        ``y = ln P``.  Each residual is convex, increasing, and its slope varies by at most a
        factor 2 on its interval, so both are well conditioned.
        """
        G3, n = 3.0 * self.G, self.values["N"]
        q_star = n * (q_tr + G3 * peeq_n) / (n + 1.0)
        x_star = np.log(q_star)
        with np.errstate(divide="ignore"):
            ln_pn = np.log(peeq_n)
        lo, hi = self._bracket(q_tr, peeq_n)
        # the unknown is chosen at q*: ln P where q* < q_tr, P(q*) > 0 and g_q(x*) < 0 there
        p_star = peeq_n + (q_tr - q_star) / G3
        with np.errstate(invalid="ignore", divide="ignore"):
            ln_p_star = np.log(p_star)
        by_q = ~((q_star < q_tr) & (p_star > 0.0) & (self._a + n * x_star - ln_p_star < 0.0))

        q, peeq, ok = np.empty_like(q_tr), np.empty_like(q_tr), np.empty(q_tr.shape, dtype=bool)
        for in_q, mask in ((True, by_q), (False, ~by_q)):
            if not mask.any():
                continue
            i = slice(None) if mask.all() else mask         # every point: views, no gathers
            qt, pn, xs = q_tr[i], peeq_n[i], x_star[i]
            if in_q:
                x, ok[i] = safeguarded_newton(lambda x, k: self._g_q(x, qt[k], pn[k]),
                                              lo[i], np.minimum(hi[i], xs), self.tol,
                                              self.max_iter, quad=quad_x(n))
                q[i] = np.exp(x)
                peeq[i] = pn + (qt - q[i]) / G3
            else:
                # ln P(q*) bounds ln P from above (rho >= 1, r <= 1, on all the bracket), as
                # does ln peeq(q_tr); ln(peeq_n + q_tr/3G) (a + n hi's other term) exceeds both
                y_lo = np.maximum(ln_pn[i], self._a + n * xs)
                y_hi = np.minimum(ln_p_star[i], self._a + n * np.log(qt))
                y, ok[i] = safeguarded_newton(lambda y, k: self._g_p(y, qt[k], pn[k]),
                                              y_lo, y_hi, self.tol, self.max_iter, quad=QUAD_Y)
                peeq[i] = np.exp(y)
                q[i] = qt - G3 * (peeq[i] - pn)
        # dq/dq_tr = 1 / (1 + 3G peeq'(q)) with peeq'(q) = N peeq(q) / q
        return q, peeq, q / (q + G3 * n * peeq), ok

    def _bracket(self, q_tr, peeq_n):
        """Bounds on ``x = ln q`` at the root, with ``hi - lo <= ln 2``.

        At the root ``dp = (q_tr - q)/3G`` lies in ``[0, q_tr/3G]``, so
        ``sigma_y(peeq_n) <= q <= min(q_tr, sigma_y(peeq_n + q_tr/3G))``; and either
        ``q >= q_tr/2`` or ``dp > q_tr/6G``, hence ``q >= min(q_tr/2, sigma_y(peeq_n + q_tr/6G))``.
        """
        G3, ln_qt = 3.0 * self.G, np.log(q_tr)
        lo = np.maximum(self._log_yield(peeq_n),
                        np.minimum(ln_qt - np.log(2.0), self._log_yield(peeq_n + q_tr / (2.0 * G3))))
        hi = np.minimum(ln_qt, self._log_yield(peeq_n + q_tr / G3))
        return lo, hi

    def _g_q(self, x, q_tr, peeq_n):
        """Residual in ``x = ln q``: ``ln peeq(q) - ln P(q)`` and its derivative
        (``+inf`` past the end of the return line, ``P <= 0``)."""
        G3, n = 3.0 * self.G, self.values["N"]
        q = np.exp(x)
        P = peeq_n + (q_tr - q) / G3
        pos = P > 0.0
        if pos.all():                   # the usual case: the same values, no selections
            return self._a + n * x - np.log(P), n + q / (G3 * P)
        Ps = np.where(pos, P, 1.0)
        return (np.where(pos, self._a + n * x - np.log(Ps), np.inf),
                np.where(pos, n + q / (G3 * Ps), np.inf))

    def _g_p(self, y, q_tr, peeq_n):
        """Residual in ``y = ln P``: ``y - ln peeq(q(P))`` and its derivative
        (``+inf`` past ``q = 0``)."""
        G3, n = 3.0 * self.G, self.values["N"]
        P = np.exp(y)
        q = q_tr - G3 * (P - peeq_n)
        pos = q > 0.0
        if pos.all():                   # the usual case: the same values, no selections
            return y - self._a - n * np.log(q), 1.0 + n * G3 * P / q
        qs = np.where(pos, q, 1.0)
        return (np.where(pos, y - self._a - n * np.log(qs), np.inf),
                np.where(pos, 1.0 + n * G3 * P / qs, np.inf))

    def kernel_parameters(self):
        if type(self) is not RambergOsgood:      # a subclass may change anything: NumPy
            return None
        p = np.zeros(SOLID_VECTOR)
        p[SOLID_K], p[SOLID_G] = self.K, self.G
        p[SOLID_A], p[SOLID_N] = self._a, self.values["N"]
        p[SOLID_TOL], p[SOLID_MAXIT] = self.tol, self.max_iter
        return RAMBERG_OSGOOD, p, np.ascontiguousarray(self.D_elastic, dtype=float)


def safeguarded_newton(fun, lo, hi, tol, max_iter, quad=np.inf):
    """Roots of increasing scalar functions, batched: Newton from ``hi``, bisection fallback.

    ``fun(x, k) -> (g, dg)`` evaluates the residuals of the points ``k`` (``slice(None)``, every
    point, at the first iteration; then an index array into the batch) at ``x``; ``lo``/``hi``
    (m,) bracket the roots (``g(lo) <= 0 <= g(hi)``).
    A Newton step that leaves the current bracket is replaced by bisection, so the iteration
    cannot diverge.  Returns ``(x, converged)``: converged after a Newton step d with
    ``|d| <= tol`` or ``quad d^2 <= tol`` (``quad``: a bound on the next iterate's error over
    d^2, ``kernels.layout.QUAD_Y``; inf: the step alone), or where the bracket is narrower.
    """
    lo, hi = lo.astype(float), hi.astype(float)
    x = hi.copy()
    active = slice(None)                  # every point at first: views, then the indices left
    with np.errstate(invalid="ignore"):       # once, not per iteration (~2 us each time)
        for _ in range(max_iter):
            xa, la, ha = x[active], lo[active], hi[active]
            g, dg = fun(xa, active)
            ha = np.where(g > 0.0, xa, ha)
            la = np.where(g <= 0.0, xa, la)
            x_newton = xa - g / dg
            newton = (x_newton >= la) & (x_newton <= ha)
            x_new = np.where(newton, x_newton, 0.5 * (la + ha))
            step = x_new - xa
            done = ((newton & ((np.abs(step) <= tol) | (quad * step * step <= tol)))
                    | (ha - la <= tol) | (g == 0.0))
            x[active], lo[active], hi[active] = x_new, la, ha
            active = np.flatnonzero(~done) if isinstance(active, slice) else active[~done]
            if active.size == 0:
                break
    converged = np.ones(x.shape, dtype=bool)
    converged[active] = False
    return x, converged
