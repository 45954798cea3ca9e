"""Shape functions and Gauss rules, shared by solid elements, edge loads and contact elements.

Line (edge) elements have 2 or 3 nodes on xi in [-1, 1]: nodes (-1, +1) or (-1, +1, 0) -- the
mid node last, as on a Q8 face (corner, corner, mid-side).  Quadrilaterals: Q4 corners
(-1,-1), (1,-1), (1,1), (-1,1); Q8 adds mid-sides 5..8 between 1-2, 2-3, 3-4, 4-1.
"""
from __future__ import annotations

import numpy as np

# Face node order on an element (0-based local nodes), faces S1..S4.
Q4_FACES = ((0, 1), (1, 2), (2, 3), (3, 0))
Q8_FACES = ((0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7))


def gauss_1d(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [-1, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return x, w


def gauss_quad(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n x n tensor Gauss rule on the square: points (q, 2), weights (q,)."""
    x, w = gauss_1d(n)
    xi, eta = np.meshgrid(x, x, indexing="ij")
    W = np.outer(w, w)
    return np.stack([xi.ravel(), eta.ravel()], axis=1), W.ravel()


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


def quad_shape(nen: int, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """N (q, a) and dN/d(xi, eta) (q, a, 2) of Q4 or Q8 at points (q, 2)."""
    xi, eta = np.asarray(pts, float).T
    cx = np.array([-1, 1, 1, -1], float)
    cy = np.array([-1, -1, 1, 1], float)
    if nen == 4:
        N = 0.25 * (1 + xi[:, None] * cx) * (1 + eta[:, None] * cy)
        dxi = 0.25 * cx * (1 + eta[:, None] * cy)
        deta = 0.25 * cy * (1 + xi[:, None] * cx)
        return N, np.stack([dxi, deta], axis=-1)
    if nen != 8:
        raise ValueError(f"quadrilaterals have 4 or 8 nodes, not {nen}")
    X, Y = xi[:, None], eta[:, None]
    # corners
    Nc = 0.25 * (1 + X * cx) * (1 + Y * cy) * (X * cx + Y * cy - 1)
    dNc_x = 0.25 * cx * (1 + Y * cy) * (2 * X * cx + Y * cy)
    dNc_y = 0.25 * cy * (1 + X * cx) * (X * cx + 2 * Y * cy)
    # mid-sides 5 (eta=-1), 6 (xi=+1), 7 (eta=+1), 8 (xi=-1)
    N5 = 0.5 * (1 - X**2) * (1 - Y)
    N6 = 0.5 * (1 + X) * (1 - Y**2)
    N7 = 0.5 * (1 - X**2) * (1 + Y)
    N8 = 0.5 * (1 - X) * (1 - Y**2)
    Nm = np.concatenate([N5, N6, N7, N8], axis=1)
    dNm_x = np.concatenate([-X * (1 - Y), 0.5 * (1 - Y**2), -X * (1 + Y), -0.5 * (1 - Y**2)], axis=1)
    dNm_y = np.concatenate([-0.5 * (1 - X**2), -Y * (1 + X), 0.5 * (1 - X**2), -Y * (1 - X)], axis=1)
    N = np.concatenate([Nc, Nm], axis=1)
    dN = np.stack([np.concatenate([dNc_x, dNm_x], axis=1),
                   np.concatenate([dNc_y, dNm_y], axis=1)], axis=-1)
    return N, dN
