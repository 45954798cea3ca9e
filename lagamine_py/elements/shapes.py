"""Line (edge) shape functions and the 1D Gauss rule, shared by faces, pressure loads and the
contact element.

A line has 2 or 3 nodes on xi in [-1, 1]: nodes (-1, +1) or (-1, +1, 0) -- the mid node last, as
on an element face (corner, corner, mid-side).  The element shapes (quadrilaterals, triangles)
live with their element types: :mod:`.quad`, :mod:`.t6`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["gauss_1d", "lobatto_1d", "line_shape"]


def gauss_1d(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [-1, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return x, w


def lobatto_1d(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Lobatto points and weights on [-1, 1] with the ends: n = 2 the trapezoid rule
    (points at the nodes of a 2-node line), n = 3 Simpson's (at the nodes of a 3-node line,
    weights 1/3, 4/3, 1/3: the consistent nodal forces of a uniform pressure on a quadratic face,
    1/6, 2/3, 1/6 of its length)."""
    if n == 2:
        return np.array([-1.0, 1.0]), np.array([1.0, 1.0])
    if n == 3:
        return np.array([-1.0, 0.0, 1.0]), np.array([1.0, 4.0, 1.0]) / 3.0
    raise ValueError(f"Lobatto rules of 2 or 3 points, not {n}")


def line_shape(nen: int, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """N (q, a) and dN/dxi (q, a) of a 2- or 3-node line at points xi (q,)."""
    xi = np.asarray(xi, float)
    if nen == 2:
        N = np.stack([(1 - xi) / 2, (1 + xi) / 2], axis=-1)
        dN = np.stack([-0.5 * np.ones_like(xi), 0.5 * np.ones_like(xi)], axis=-1)
    elif nen == 3:
        N = np.stack([xi * (xi - 1) / 2, xi * (xi + 1) / 2, 1 - xi**2], axis=-1)
        dN = np.stack([xi - 0.5, xi + 0.5, -2 * xi], axis=-1)
    else:
        raise ValueError(f"line elements have 2 or 3 nodes, not {nen}")
    return N, dN
