"""Bernstein forms on the reference square and triangle: certified bounds of a polynomial.

A polynomial of degree ``(p, q)`` on the square ``[-1, 1]^2`` (tensor degree) or of total degree
``d`` on the triangle ``(0,0), (1,0), (0,1)`` is known exactly by its values at the points of a
lattice (``(p + 1) x (q + 1)`` equispaced points; the ``(d + 1)(d + 2)/2`` points ``(i/d, j/d)``).
Its Bernstein coefficients are a fixed linear map of those values, and the polynomial lies
between the smallest and the largest of them over the whole domain (the Bernstein basis is a
partition of unity of non-negative functions).  The coefficients at the vertices are the values
there, and on a sub-domain the bound closes in on the true extremes quadratically with its size
(Farouki 2012, *The Bernstein polynomial basis: a centennial retrospective*): subdividing the
sub-domains whose bound does not decide settles any polynomial that is not zero at a point.

:func:`domain` gives, for a reference domain and a degree, the lattice, the map from values to
coefficients, and the affine maps of the domain onto its four halves-by-side (the children of a
subdivision).  The element check that uses them is :meth:`lagamine_py.elements.base.Element.jacobian_check`.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import comb, factorial

import numpy as np

__all__ = ["Domain", "domain", "DOMAINS"]

DOMAINS = ("square", "triangle")


@dataclass(frozen=True)
class Domain:
    """A reference domain with a polynomial degree.

    ``points`` (m, 2): the lattice, in the domain's natural coordinates; ``to_bernstein`` (m, m):
    Bernstein coefficients = ``to_bernstein @ values`` at ``points``; ``children``: the four
    affine maps ``x = origin + matrix @ u`` of the domain onto its sub-domains, as ``origins``
    (4, 2) and ``matrices`` (4, 2, 2)."""
    kind: str
    degree: tuple[int, ...]
    points: np.ndarray
    to_bernstein: np.ndarray
    origins: np.ndarray
    matrices: np.ndarray


def _bernstein_1d(n: int, u: np.ndarray) -> np.ndarray:
    """(len(u), n + 1) the Bernstein polynomials of degree n on [0, 1] at ``u``."""
    i = np.arange(n + 1)
    return np.array([comb(n, k) for k in i]) * u[:, None] ** i * (1.0 - u[:, None]) ** (n - i)


def _square(p: int, q: int) -> Domain:
    xi = np.linspace(-1.0, 1.0, p + 1)
    eta = np.linspace(-1.0, 1.0, q + 1)
    X, Y = np.meshgrid(xi, eta, indexing="ij")
    points = np.stack([X.ravel(), Y.ravel()], axis=1)
    Bu = _bernstein_1d(p, (points[:, 0] + 1.0) / 2.0)           # (m, p+1)
    Bv = _bernstein_1d(q, (points[:, 1] + 1.0) / 2.0)           # (m, q+1)
    V = (Bu[:, :, None] * Bv[:, None, :]).reshape(len(points), -1)
    half = np.array([-0.5, 0.5])
    origins = np.array([[a, b] for a in half for b in half])
    matrices = np.broadcast_to(0.5 * np.eye(2), (4, 2, 2)).copy()
    return Domain("square", (p, q), points, np.linalg.inv(V), origins, matrices)


def _triangle(d: int) -> Domain:
    ij = np.array([(i, j) for i in range(d + 1) for j in range(d + 1 - i)])
    points = ij / d
    L = np.stack([1.0 - points.sum(1), points[:, 0], points[:, 1]], axis=1)   # (m, 3)
    abc = np.column_stack([d - ij.sum(1), ij])                                # multi-indices
    coef = np.array([factorial(d) / (factorial(a) * factorial(b) * factorial(c)) for a, b, c in abc])
    V = coef * np.prod(L[:, None, :] ** abc[None, :, :], axis=2)
    origins = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5], [0.5, 0.5]])
    matrices = np.array([0.5 * np.eye(2)] * 3 + [-0.5 * np.eye(2)])          # the middle one turned
    return Domain("triangle", (d,), points, np.linalg.inv(V), origins, matrices)


@lru_cache(maxsize=None)
def domain(kind: str, degree) -> Domain:
    """The :class:`Domain` of ``kind`` (``"square"``: ``degree = (p, q)``; ``"triangle"``:
    ``degree = d``)."""
    if kind == "square":
        p, q = (degree, degree) if np.isscalar(degree) else degree
        return _square(int(p), int(q))
    if kind == "triangle":
        return _triangle(int(degree if np.isscalar(degree) else degree[0]))
    raise ValueError(f"unknown reference domain {kind!r}: expected one of {', '.join(DOMAINS)}")
