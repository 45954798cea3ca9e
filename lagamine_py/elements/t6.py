"""Six-node triangles: the reference shape T6 and the element types built on it.

Natural coordinates (xi, eta) are area coordinates of the reference triangle (0,0), (1,0),
(0,1), with ``L1 = 1 - xi - eta``, ``L2 = xi``, ``L3 = eta``.  Node order is Abaqus CPE6/CAX6
(and VTK_QUADRATIC_TRIANGLE): corners 1, 2, 3 counter-clockwise, then the mid-sides 4 (1-2),
5 (2-3), 6 (3-1).  Faces S1, S2, S3 are (1,2,4), (2,3,5), (3,1,6): corner, corner, mid-side,
running with the element on their left like every face.

Gauss rule: the 3-point rule of degree 2 at the interior points (1/6, 1/6), (2/3, 1/6),
(1/6, 2/3) (Abaqus integrates CPE6 and CAX6 with 3 points too), because

* on a straight-sided T6 the strains are linear, so the plane-strain stiffness (a quadratic
  integrand) is exact, and so is the internal force of a uniform stress -- the patch test -- in
  plane strain *and* in axisymmetry, where ``r`` times a linear B and ``r`` times the hoop term
  ``N_a / r`` are quadratic;
* degree 2 = 2p - 2 keeps the optimal convergence rate of a quadratic element (Strang and Fix).
  The axisymmetric stiffness, cubic in its ``r``-weighted terms and rational in its hoop term
  ``N_a N_b / r``, is exact with no rule, and a higher one does not buy accuracy: on Lame's
  cylinder (T6AX, square cells 2 x 1 .. 16 x 8) the radial displacement errors are 3.6e-4,
  5.6e-5, 7.2e-6, 8.3e-7 with 3 points and 9.4e-4, 1.0e-4, 1.0e-5, 1.0e-6 with 6, both h^3;
* 3 points x 3 (4 in axisymmetry) strain components give the element stiffness exactly the
  rank it needs (9 = 12 - 3 rigid modes in plane strain; 11 = 12 - 1 in axisymmetry), and half
  the incompressibility constraints of the 6-point rule: under isochoric plastic flow the
  6-point triangle locks (a J2 perfectly plastic tube carries 1.03 times Hill's limit pressure)
  where the 3-point one collapses at 0.999 of it, loaded in steps of 1 % (``tests/test_t6.py``);
* the points are interior, so ``r > 0`` at each of them even for an element with an edge on
  the axis; the complete linear polynomial through the three Gauss values recovers the linear
  stress of a straight-sided element exactly at the nodes.

The 6-point rule of degree 4 (Dunavant 1985) is there for a subclass (``ngauss = 6``,
recovered by the complete quadratic polynomial).
"""
from __future__ import annotations

import numpy as np

from .solid import SolidElement

__all__ = ["gauss_triangle", "tri6_shape", "Tri6", "T6PlaneStrain", "T6Axisymmetric"]

VTK_QUADRATIC_TRIANGLE = 22


def _orbit(a: float) -> np.ndarray:
    """The three points of area coordinates (a, a, 1 - 2a) and its rotations, as (xi, eta)."""
    b = 1.0 - 2.0 * a
    return np.array([[a, a], [b, a], [a, b]])


# Dunavant (1985), degree 4: orbits (a, weight) with the weights summing to 1 (area 1/2 applied)
_A1, _W1 = 0.44594849091596488632, 0.22338158967801146570
_A2, _W2 = 0.091576213509770743460, 0.10995174365532186764

#: ngauss -> (points (q, 2), weights (q,) summing to the area 1/2, polynomial degree held)
_RULES = {
    3: (_orbit(1.0 / 6.0), np.full(3, 1.0 / 6.0), 2),
    6: (np.concatenate([_orbit(_A1), _orbit(_A2)]), 0.5 * np.repeat([_W1, _W2], 3), 4),
}


def gauss_triangle(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The n-point rule on the reference triangle (n = 3: degree 2; n = 6: degree 4): points
    (q, 2) and weights (q,) summing to the area 1/2."""
    if n not in _RULES:
        raise ValueError(f"triangle rules have {sorted(_RULES)} points, not {n}")
    pts, w, _ = _RULES[n]
    return pts.copy(), w.copy()


def tri6_shape(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """N (q, a) and dN/d(xi, eta) (q, a, 2) of the 6-node triangle at points (q, 2)."""
    xi, eta = np.asarray(pts, float).T
    L = np.stack([1.0 - xi - eta, xi, eta], axis=1)                   # (q, 3) area coordinates
    dL = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])              # dL_k / d(xi, eta)
    corner = L * (2.0 * L - 1.0)
    d_corner = (4.0 * L - 1.0)[:, :, None] * dL
    i, j = np.array([0, 1, 2]), np.array([1, 2, 0])                    # mid-side k between i, j
    mid = 4.0 * L[:, i] * L[:, j]
    d_mid = 4.0 * (L[:, i, None] * dL[j] + L[:, j, None] * dL[i])
    return np.concatenate([corner, mid], axis=1), np.concatenate([d_corner, d_mid], axis=1)


class Tri6:
    """The 6-node quadratic triangle (area coordinates on (0,0), (1,0), (0,1))."""

    nen = 6
    node_xi = np.array([[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5]], float)
    faces = ((0, 1, 3), (1, 2, 4), (2, 0, 5))
    outline = (0, 3, 1, 4, 2, 5)
    vtk_cell = VTK_QUADRATIC_TRIANGLE
    # *MESH: a cell of 3 x 3 grid points is cut along its diagonal from the bottom-left to the
    # top-right corner into two triangles, both counter-clockwise; the cell centre is the
    # diagonal's mid-side node
    grid_order = 2
    cell_elements = (((0, 0), (2, 0), (2, 2), (1, 0), (2, 1), (1, 1)),
                     ((0, 0), (2, 2), (0, 2), (1, 1), (1, 2), (0, 1)))
    ngauss = 3
    reference_domain = "triangle"
    jacobian_degree = 2          # x quadratic, J linear: det J of total degree 2

    @classmethod
    def shape_functions(cls, pts):
        return tri6_shape(pts)

    @classmethod
    def gauss_rule(cls):
        return gauss_triangle(cls.ngauss)

    @classmethod
    def recovery_basis(cls, pts, nq):
        """Complete polynomials through the Gauss points: linear (1, xi, eta) for 3 points,
        quadratic for 6."""
        degree = {3: 1, 6: 2}.get(nq)
        if degree is None:
            raise ValueError(f"{cls.__name__}: no complete polynomial space has {nq} terms")
        xi, eta = np.asarray(pts, float).T
        return np.stack([xi**(k - j) * eta**j for k in range(degree + 1) for j in range(k + 1)],
                        axis=1)


class T6PlaneStrain(Tri6, SolidElement):
    """6-node plane-strain triangle, 3-point Gauss."""
    aliases = ("CPE6",)


class T6Axisymmetric(Tri6, SolidElement):
    """6-node axisymmetric triangle, 3-point Gauss."""
    aliases = ("CAX6",)
    axisymmetric = True
