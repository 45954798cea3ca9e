"""The Ramberg-Osgood return map's local Newton, point by point: the NumPy law
(``RambergOsgood._return_map``) and its numba twin (``kernels.solid._ro_return_map``).

Independent sources of the asserted numbers: for N = 2 the consistency equation
``peeq(q) = c q^2 = peeq_n + (q_tr - q)/3G`` is a quadratic in q, solved in closed form (and
``dq/dq_tr = 1/(1 + 6G c q)`` by implicit differentiation); for other N, scipy's ``brentq``
on the same equation in ``ln q`` to 1e-15.  The stopping rule's claim (``kernels.layout.QUAD_Y``:
after a Newton step d with ``quad d^2 <= tol`` the next iterate is within ``tol`` of the root)
is held by the answers being within ``tol`` of those roots with ``max_iter = 2`` at points where
the step rule alone needs a third evaluation.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py.kernels import solid                             # noqa: E402
from lagamine_py.kernels.layout import QUAD_Y                     # noqa: E402
from lagamine_py.laws.ramberg_osgood import RambergOsgood, safeguarded_newton   # noqa: E402

E, NU, S0, ALPHA = 200e3, 0.3, 300.0, 3.0 / 7.0


def law(n, **kw):
    ro = RambergOsgood(E=E, NU=NU, SIGMA0=S0, ALPHA=ALPHA, N=n)
    for k, v in kw.items():
        setattr(ro, k, v)
    return ro


def plastic_points():
    """(q_tr, peeq_n) (m,): virgin and hardened points, trial stresses from 1e-8 to 100 times
    above the current yield stress (both unknowns of the return, see ``rho``)."""
    pn = np.array([0.0, 1e-7, 1e-5, 1e-3, 3e-2])
    over = np.array([1e-8, 1e-5, 1e-3, 3e-2, 0.3, 1.0, 10.0, 100.0])
    P, F = np.meshgrid(pn, over, indexing="ij")
    sy = np.where(P > 0.0, law(2.0).yield_stress(np.maximum(P, 1e-300)), 1.0)
    return (sy * (1.0 + F)).ravel(), P.ravel()


def exact_n2(ro, q_tr, peeq_n):
    """The closed form at N = 2: q, peeq and dq/dq_tr."""
    c, G3 = np.exp(ro._a), 3.0 * ro.G
    b = G3 * peeq_n + q_tr
    q = 2.0 * b / (1.0 + np.sqrt(1.0 + 4.0 * c * G3 * b))        # the stable root
    return q, c * q * q, 1.0 / (1.0 + 2.0 * c * G3 * q)


def kernel_map(ro, q_tr, peeq_n, max_iter=None):
    """The numba return map point by point: q, peeq, dq/dq_tr, ok (m,)."""
    n, G3 = ro.values["N"], 3.0 * ro.G
    out = [solid._ro_return_map(qt, pn, np.log(pn) if pn > 0 else -np.inf, G3, ro._a, n,
                                ro.tol, ro.max_iter if max_iter is None else max_iter)
           for qt, pn in zip(q_tr, peeq_n)]
    return tuple(np.array(v) for v in zip(*out))


def both(ro, q_tr, peeq_n, max_iter=None):
    """The law's and the kernel's answers, by name."""
    if max_iter is not None:
        ro = law(ro.values["N"], max_iter=max_iter)
    with np.errstate(divide="ignore"):
        return {"law": ro._return_map(q_tr, peeq_n), "kernel": kernel_map(ro, q_tr, peeq_n)}


def ln_error(a, b):
    return np.max(np.abs(np.log(a) - np.log(b)))


def test_closed_form_at_n2_both_unknowns():
    ro = law(2.0)
    q_tr, peeq_n = plastic_points()
    q_ex, p_ex, dq_ex = exact_n2(ro, q_tr, peeq_n)
    rho = q_ex / (3.0 * ro.G * 2.0 * p_ex)
    assert (rho <= 1.0).sum() >= 5 and (rho > 1.0).sum() >= 5      # both unknowns exercised
    for name, (q, peeq, dq, ok) in both(ro, q_tr, peeq_n).items():
        assert ok.all(), name
        assert ln_error(q, q_ex) <= 2e-13, name                     # tol = 1e-13 in ln q or ln P
        assert ln_error(peeq, p_ex) <= 1e-12, name                  # (1 + N) tol in the x branch
        assert np.max(np.abs(dq / dq_ex - 1.0)) <= 1e-12, name


@pytest.mark.parametrize("n", [1.5, 10.0, 50.0])
def test_root_against_brentq(n):
    ro = law(n)
    q_tr, peeq_n = plastic_points()
    q_tr = q_tr * np.where(peeq_n > 0.0, ro.yield_stress(np.maximum(peeq_n, 1e-300))
                           / law(2.0).yield_stress(np.maximum(peeq_n, 1e-300)), 1.0)
    G3 = 3.0 * ro.G
    ref = []
    for qt, pn in zip(q_tr, peeq_n):
        def g(x):
            P = pn + (qt - np.exp(x)) / G3
            return ro._a + n * x - np.log(P) if P > 0.0 else 1e300   # past the return line
        lo = ro._log_yield(pn) if pn > 0 else np.log(qt) - 60.0
        ref.append(brentq(g, lo, np.log(qt), xtol=1e-15, rtol=1e-15))
    for name, (q, peeq, dq, ok) in both(ro, q_tr, peeq_n).items():
        assert ok.all(), name
        assert np.max(np.abs(np.log(q) - ref)) <= 2e-13, name


def two_evaluation_points():
    """Small increments on a hardened point (1e-4 to 1e-3 above yield, the return in ln P):
    the second Newton step is below the quadratic rule's sqrt(tol / 2) but not below tol."""
    pn = np.array([1e-6, 1e-5, 1e-4])
    over = np.array([1e-4, 3e-4, 1e-3])
    P, F = np.meshgrid(pn, over, indexing="ij")
    return (law(2.0).yield_stress(P) * (1.0 + F)).ravel(), P.ravel()


def test_quadratic_stop_saves_the_confirming_evaluation():
    ro = law(2.0)
    q_tr, peeq_n = two_evaluation_points()
    q_ex, p_ex, _ = exact_n2(ro, q_tr, peeq_n)
    for name, (q, peeq, dq, ok) in both(ro, q_tr, peeq_n, max_iter=2).items():
        assert ok.all(), name
        assert ln_error(q, q_ex) <= 2e-13 and ln_error(peeq, p_ex) <= 2e-13, name
    # the step rule alone (quad = inf) needs a third evaluation at these points: the test has teeth
    n = 2.0
    y_hi = ro._a + n * np.log(q_tr)
    y_lo = np.log(peeq_n)
    for quad, converged in ((np.inf, False), (QUAD_Y, True)):
        y, ok = safeguarded_newton(lambda y, k: ro._g_p(y, q_tr[k], peeq_n[k]), y_lo, y_hi,
                                   ro.tol, 2, quad=quad)
        assert ok.all() == converged and (ok.any() == converged), quad


def test_safeguard_brings_an_outside_start_back():
    """A start past the end of the return line (P < 0: g = inf, no Newton step) bisects back
    into the bracket, in the kernel and in the law's solver."""
    ro = law(2.0)
    qt, pn = 2000.0, 1e-3
    G3, n = 3.0 * ro.G, 2.0
    q_ex = exact_n2(ro, np.array([qt]), np.array([pn]))[0][0]
    lo, hi = np.log(q_ex) - 0.5, np.log(qt + G3 * pn) + 0.2         # P(e^hi) < 0
    x, ex, ok = solid._safeguarded_newton(True, lo, hi, ro.tol, 1.0 + n, 100, qt, pn, G3, ro._a,
                                          n)
    assert ok and abs(x - np.log(q_ex)) <= 2e-13 and abs(ex / q_ex - 1.0) <= 2e-13
    with np.errstate(invalid="ignore", divide="ignore"):
        x, ok = safeguarded_newton(lambda x, k: ro._g_q(x, qt, pn), np.array([lo]),
                                   np.array([hi]), ro.tol, 100, quad=1.0 + n)
    assert ok.all() and abs(x[0] - np.log(q_ex)) <= 2e-13


def test_safeguard_of_a_newton_step_leaving_the_bracket():
    """arctan from far right: Newton's step jumps past the left end; bisection takes over."""
    x, ok = safeguarded_newton(lambda x, k: (np.arctan(x - 1.0), 1.0 / (1.0 + (x - 1.0) ** 2)),
                               np.array([-10.0]), np.array([10.0]), 1e-13, 100, quad=1.0)
    assert ok.all() and abs(x[0] - 1.0) <= 1e-12
