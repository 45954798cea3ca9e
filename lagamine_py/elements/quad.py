"""Quadrilaterals: the reference shapes Q4 and Q8 and the element types built on them.

Natural coordinates (xi, eta) in [-1, 1]^2.  Q4 corners (-1,-1), (1,-1), (1,1), (-1,1); Q8 adds
the mid-sides 5..8 between 1-2, 2-3, 3-4, 4-1 (Abaqus CPE8/CAX8 order, which is also VTK's
order for VTK_QUAD and VTK_QUADRATIC_QUAD).  Faces S1..S4 are (1,2[,5]), (2,3[,6]), (3,4[,7]),
(4,1[,8]).  Gauss rules are n x n tensor Gauss-Legendre rules (:func:`gauss_quad`).
"""
from __future__ import annotations

import numpy as np

from .shapes import gauss_1d
from .solid import SolidElement

__all__ = ["gauss_quad", "quad_shape", "Quad4", "Quad8", "Q8PlaneStrain", "Q8Axisymmetric",
           "Q8PlaneStrainReduced", "Q8AxisymmetricReduced", "Q4PlaneStrain", "Q4Axisymmetric"]

VTK_QUAD, VTK_QUADRATIC_QUAD = 9, 23


def gauss_quad(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n x n tensor Gauss rule on the square: points (q, 2) (xi major), weights (q,)."""
    x, w = gauss_1d(n)
    xi, eta = np.meshgrid(x, x, indexing="ij")
    return np.stack([xi.ravel(), eta.ravel()], axis=1), np.outer(w, w).ravel()


_CX = np.array([-1, 1, 1, -1], float)
_CY = np.array([-1, -1, 1, 1], float)


def quad_shape(nen: int, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """N (q, a) and dN/d(xi, eta) (q, a, 2) of Q4 or Q8 at points (q, 2)."""
    xi, eta = np.asarray(pts, float).T
    cx, cy = _CX, _CY
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


class _Quad:
    """What Q4 and Q8 share: the square, tensor Gauss rules of ``ngauss`` points a side."""

    ngauss = 2
    reference_domain = "square"

    @classmethod
    def shape_functions(cls, pts):
        return quad_shape(cls.nen, pts)

    @classmethod
    def gauss_rule(cls):
        return gauss_quad(cls.ngauss)

    @classmethod
    def recovery_basis(cls, pts, nq):
        """Tensor monomials xi^i eta^j, i, j < n, for an n x n rule (Lagrange through the
        Gauss points: bilinear for 2 x 2, biquadratic for 3 x 3)."""
        n = int(round(np.sqrt(nq)))
        if n * n != nq:
            raise ValueError(f"{cls.__name__}: {nq} Gauss points are not an n x n rule")
        xi, eta = np.asarray(pts, float).T
        return np.stack([xi**i * eta**j for i in range(n) for j in range(n)], axis=1)


class Quad4(_Quad):
    """The 4-node quadrilateral (bilinear)."""

    nen = 4
    node_xi = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    faces = ((0, 1), (1, 2), (2, 3), (3, 0))
    outline = (0, 1, 2, 3)
    vtk_cell = VTK_QUAD
    # x_xi is linear in eta, x_eta in xi: det J has degree 1 in each (its xi eta terms cancel)
    jacobian_degree = (1, 1)
    grid_order = 1
    cell_elements = (((0, 0), (1, 0), (1, 1), (0, 1)),)


class Quad8(_Quad):
    """The 8-node serendipity quadrilateral (quadratic edges)."""

    nen = 8
    node_xi = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1],
                        [0, -1], [1, 0], [0, 1], [-1, 0]], float)
    faces = ((0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7))
    outline = (0, 4, 1, 5, 2, 6, 3, 7)
    vtk_cell = VTK_QUADRATIC_QUAD
    # x_xi spans 1, xi, eta, xi eta, eta^2 (degree (1, 2)) and x_eta degree (2, 1): det J (3, 3)
    jacobian_degree = (3, 3)
    grid_order = 2
    cell_elements = (((0, 0), (2, 0), (2, 2), (0, 2), (1, 0), (2, 1), (1, 2), (0, 1)),)


class Q8PlaneStrain(Quad8, SolidElement):
    """8-node plane-strain quadrilateral, 3x3 Gauss."""
    aliases = ("CPE8",)
    ngauss = 3


class Q8Axisymmetric(Quad8, SolidElement):
    """8-node axisymmetric quadrilateral, 3x3 Gauss."""
    aliases = ("CAX8",)
    ngauss = 3
    axisymmetric = True


class Q8PlaneStrainReduced(Quad8, SolidElement):
    """8-node plane-strain quadrilateral, 2x2 reduced Gauss (CPE8R)."""
    aliases = ("CPE8R",)
    ngauss = 2


class Q8AxisymmetricReduced(Quad8, SolidElement):
    """8-node axisymmetric quadrilateral, 2x2 reduced Gauss (CAX8R)."""
    aliases = ("CAX8R",)
    ngauss = 2
    axisymmetric = True


class Q4PlaneStrain(Quad4, SolidElement):
    """4-node plane-strain quadrilateral, 2x2 Gauss."""
    aliases = ("CPE4",)
    ngauss = 2


class Q4Axisymmetric(Quad4, SolidElement):
    """4-node axisymmetric quadrilateral, 2x2 Gauss."""
    aliases = ("CAX4",)
    ngauss = 2
    axisymmetric = True
