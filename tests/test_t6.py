"""The 6-node triangles T6PE and T6AX (CPE6, CAX6): shape, rule, element, decks, closed forms.

Independent sources of the asserted numbers:
* shape functions: the area-coordinate formulas (corner ``L (2L - 1)``, mid-side ``4 L_i L_j``),
  partition of unity, Kronecker values, central finite differences, and the reproduction of
  every quadratic polynomial on a straight-sided element;
* Gauss rules: the exact moments ``int xi^i eta^j = i! j! / (i + j + 2)!`` of the reference
  triangle;
* patch tests: a linear displacement field on a distorted, unstructured T6 patch is the exact
  solution (plane strain: any linear field; axisymmetry: ``u_r = c r, u_z = d z + e``);
* rigid motions give no stress; tangents equal central finite differences of the force;
* the Jacobian: the shoelace sign of the corners, and det J of the isoparametric map by finite
  differences of the mapping at the edge point where it is negative;
* decks end to end: Lame's thick cylinder (Timoshenko & Goodier §28), the flat punch on the
  penalty foundation (d = p / KP), Hertz (Johnson §4.2), Hill's limit pressure of a thick tube.
"""
from __future__ import annotations

import math
from math import factorial

import numpy as np
import pytest
from runner import DECKS, is_quadratic, run_deck
from scipy.spatial import Delaunay
from test_solid_elements import assemble, check_tangent, previous_increment
from test_verify_contact import assert_newton_tail

from lagamine_py import registry
from lagamine_py.checks import evaluate_checks
from lagamine_py.checks.closed_forms import hertz_closed_form
from lagamine_py.cli import main
from lagamine_py.core.tensors import elastic_matrix
from lagamine_py.deck import load_deck
from lagamine_py.elements.base import StepContext
from lagamine_py.elements.contact import ContactGroup
from lagamine_py.elements.edges import edge_geometry
from lagamine_py.elements.shapes import line_shape
from lagamine_py.elements.structured import rectangle
from lagamine_py.elements.t6 import (T6Axisymmetric, T6PlaneStrain, Tri6, gauss_triangle,
                                     tri6_shape)
from lagamine_py.foundation import Foundation
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.laws.elastic import LinearElastic
from lagamine_py.results import RunResults

E, NU = 200e3, 0.3
TYPES = ("T6PE", "T6AX")


def elastic():
    return LinearElastic(E=E, NU=NU)


def j2(H=2000.0):
    return registry.get("laws", "J2_LINEAR")(E=E, NU=NU, SIGMAY=300.0, H=H)


def moment(i, j):
    """Exact integral of xi^i eta^j over the reference triangle (0,0), (1,0), (0,1)."""
    return factorial(i) * factorial(j) / factorial(i + j + 2)


def cross2(a, b):
    """z component of a x b for in-plane vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def inside(n, seed=0):
    """n random points inside the reference triangle (xi, eta)."""
    L = np.random.default_rng(seed).dirichlet(np.ones(3), size=n)
    return L[:, 1:]


# --------------------------------------------------------------------------------------------
# the reference shape

def test_registry_names_and_aliases():
    assert registry.get("elements", "CPE6") is registry.get("elements", "T6PE") is T6PlaneStrain
    assert registry.get("elements", "cax6") is registry.get("elements", "T6AX") is T6Axisymmetric
    assert T6Axisymmetric.axisymmetric and not T6PlaneStrain.axisymmetric
    assert T6PlaneStrain.vtk_cell == 22                      # VTK_QUADRATIC_TRIANGLE


def test_shape_functions_are_the_area_coordinate_formulas():
    pts = inside(30)
    N, dN = tri6_shape(pts)
    L = np.column_stack([1 - pts.sum(1), pts])
    pairs = ((0, 1), (1, 2), (2, 0))                          # mid-sides 4, 5, 6
    expected = np.column_stack([L * (2 * L - 1)] + [4 * L[:, i] * L[:, j] for i, j in pairs])
    assert np.allclose(N, expected, atol=1e-15)
    # the centroid: corners -1/9, mid-sides 4/9
    Nc, _ = tri6_shape([[1 / 3, 1 / 3]])
    assert np.allclose(Nc, [[-1 / 9] * 3 + [4 / 9] * 3], atol=1e-15)
    assert np.allclose(N.sum(1), 1.0, atol=1e-15)            # partition of unity
    assert np.allclose(dN.sum(1), 0.0, atol=1e-14)
    Nn, _ = tri6_shape(Tri6.node_xi)
    assert np.allclose(Nn, np.eye(6), atol=1e-15)           # Kronecker at the nodes
    h = 1e-6
    for k in range(2):
        dp = np.zeros(2)
        dp[k] = h
        fd = (tri6_shape(pts + dp)[0] - tri6_shape(pts - dp)[0]) / (2 * h)
        assert np.allclose(dN[..., k], fd, atol=1e-9)


def test_quadratic_fields_are_reproduced_on_a_straight_sided_element():
    """Any quadratic f(x, y) interpolated from its nodal values is f itself, and its gradient
    through the isoparametric map is grad f: completeness of degree 2."""
    corners = np.array([[1.0, 0.5], [3.1, 0.9], [1.6, 2.4]])
    x = np.vstack([corners, 0.5 * (corners + np.roll(corners, -1, axis=0))])   # (6, 2)
    f = lambda p: 0.7 - 1.3 * p[..., 0] + 2.1 * p[..., 1] + 0.4 * p[..., 0]**2 \
        - 1.7 * p[..., 0] * p[..., 1] + 0.9 * p[..., 1]**2
    grad = lambda p: np.stack([-1.3 + 0.8 * p[..., 0] - 1.7 * p[..., 1],
                               2.1 - 1.7 * p[..., 0] + 1.8 * p[..., 1]], axis=-1)
    pts = inside(25, seed=3)
    N, dN = tri6_shape(pts)
    xp = N @ x
    assert np.allclose(N @ f(x), f(xp), atol=1e-13)
    J = np.einsum("ai,qak->qik", x, dN)
    dNdx = np.einsum("qak,qki->qai", dN, np.linalg.inv(J))
    assert np.allclose(np.einsum("qai,a->qi", dNdx, f(x)), grad(xp), atol=1e-12)
    # a cubic is not reproduced: the test can tell
    g = lambda p: p[..., 0] ** 3
    assert np.abs(N @ g(x) - g(xp)).max() > 1e-3


@pytest.mark.parametrize("n, degree", [(3, 2), (6, 4)])
def test_gauss_rules_integrate_their_degree_exactly_and_no_more(n, degree):
    pts, w = gauss_triangle(n)
    assert len(w) == n and (w > 0).all()
    assert np.isclose(w.sum(), 0.5, rtol=1e-15)              # the area
    for i in range(degree + 1):
        for j in range(degree + 1 - i):
            got = np.sum(w * pts[:, 0] ** i * pts[:, 1] ** j)
            assert got == pytest.approx(moment(i, j), rel=1e-14, abs=1e-16), (i, j)
    # degree + 1: some monomial is missed (the claimed degree is the rule's)
    missed = [abs(np.sum(w * pts[:, 0] ** i * pts[:, 1] ** (degree + 1 - i)) - moment(i, degree + 1 - i))
              for i in range(degree + 2)]
    assert max(missed) > 1e-6


@pytest.mark.parametrize("n, degree", [(3, 1), (6, 2)])
def test_recovery_is_exact_for_the_complete_polynomials_of_the_rule(n, degree):
    class Shape(T6PlaneStrain):
        ngauss = n
    pts, _ = Shape.gauss_rule()
    E_ = Shape.recovery_matrix()
    assert E_.shape == (6, n)
    rng = np.random.default_rng(n)
    c = rng.normal(size=6)
    f = lambda p: (c[0] + c[1] * p[:, 0] + c[2] * p[:, 1]
                   + (degree == 2) * (c[3] * p[:, 0]**2 + c[4] * p[:, 0] * p[:, 1] + c[5] * p[:, 1]**2))
    assert np.allclose(E_ @ f(pts), f(Tri6.node_xi), atol=1e-12)


def single(cls, corners, law=None):
    """One straight-sided element of ``cls`` on ``corners`` (3, 2): group, coords."""
    corners = np.asarray(corners, float)
    x = np.vstack([corners, 0.5 * (corners + np.roll(corners, -1, axis=0))])
    return cls([1], [np.arange(6)], x, law or elastic()), x


@pytest.mark.parametrize("name, rigid", [("T6PE", 3), ("T6AX", 1)])
def test_element_stiffness_has_only_the_rigid_modes(name, rigid):
    """3 points x 3 (4) strains: rank 9 = 12 - 3 in plane strain, 11 = 12 - 1 in axisymmetry
    (only the translation along z is rigid)."""
    g, x = single(registry.get("elements", name), [[1.0, 0.0], [2.2, 0.3], [1.4, 1.1]])
    K = g.compute(np.zeros((6, 2)), np.zeros((6, 2)), g.init_state(), StepContext()).K[0]
    assert np.allclose(K, K.T, atol=1e-12 * np.abs(K).max())
    ev = np.sort(np.abs(np.linalg.eigvalsh(K))) / np.abs(K).max()
    assert (ev[:rigid] < 1e-12).all() and ev[rigid] > 1e-4, ev[:rigid + 1]


# --------------------------------------------------------------------------------------------
# a distorted, unstructured T6 patch

def t6_mesh(points, triangles):
    """T6 coordinates (n, 2) and connectivity (e, 6) from corner points and triangles, corners
    made counter-clockwise, one mid-side node per edge in the middle of it."""
    pts = [np.asarray(p, float) for p in points]
    mids, conn = {}, []
    for t in np.asarray(triangles):
        a, b, c = (int(v) for v in t)
        if cross2(pts[b] - pts[a], pts[c] - pts[a]) < 0:
            b, c = c, b
        row = [a, b, c]
        for i, j in ((a, b), (b, c), (c, a)):
            key = (min(i, j), max(i, j))
            if key not in mids:
                mids[key] = len(pts)
                pts.append(0.5 * (pts[i] + pts[j]))
            row.append(mids[key])
        conn.append(row)
    return np.array(pts), np.array(conn)


def patch(x0=0.0):
    """Unstructured T6 patch of [x0, x0 + 2] x [0, 2]: boundary points at uneven spacing, five
    interior points off any grid.  Returns coords, conn, boundary mask."""
    side = [0.0, 0.55, 1.3, 2.0]
    b = ([(s, 0.0) for s in side[:-1]] + [(2.0, s) for s in side[:-1]]
         + [(2.0 - s, 2.0) for s in side[:-1]] + [(0.0, 2.0 - s) for s in side[:-1]])
    interior = [(0.52, 0.61), (1.37, 0.48), (1.05, 1.07), (0.63, 1.46), (1.52, 1.41)]
    corners = np.array(b + interior) + [x0, 0.0]
    coords, conn = t6_mesh(corners, Delaunay(corners).simplices)
    x, y = coords.T
    boundary = (np.abs(x - x0) < 1e-12) | (np.abs(x - x0 - 2) < 1e-12) | (y < 1e-12) | (y > 2 - 1e-12)
    return coords, conn, boundary


def group(name, coords, conn, law=None, thickness=1.0):
    return registry.get("elements", name)(np.arange(1, len(conn) + 1), conn, coords,
                                          law or elastic(), thickness)


def test_the_patch_is_distorted_and_valid():
    coords, conn, boundary = patch()
    assert len(conn) >= 16 and (~boundary).sum() >= 10
    bad, detj = T6PlaneStrain.invalid(coords[conn])
    assert not bad.any()
    assert np.ptp(detj) > 0.4 * detj.max()                    # elements of different sizes


@pytest.mark.parametrize("name", TYPES)
def test_patch_test_linear_field_is_exact(name):
    cls = registry.get("elements", name)
    coords, conn, boundary = patch(x0=1.0 if cls.axisymmetric else 0.0)
    g = group(name, coords, conn, thickness=2.0)
    x, y = coords.T
    if cls.axisymmetric:
        c, d, e = 2e-3, -1e-3, 0.3
        exact = np.stack([c * x, d * y + e], axis=1)
        eps = np.array([c, d, c, 0.0])
    else:
        a0, A = np.array([0.1, -0.2]), np.array([[1e-3, -4e-4], [7e-4, -2e-3]])
        exact = a0 + coords @ A.T
        eps = np.array([A[0, 0], A[1, 1], 0.0, A[0, 1] + A[1, 0]])
    u = np.where(boundary[:, None], exact, 0.0)
    free = np.repeat(~boundary, 2)
    ctx = StepContext(nlgeom=False)
    state = g.init_state()
    F, K, _ = assemble(g, u, 0 * u, state, ctx)
    u.reshape(-1)[free] += np.linalg.solve(K[np.ix_(free, free)], -F[free])
    assert np.abs(u - exact).max() < 1e-10 * np.abs(exact).max()
    F, _, res = assemble(g, u, 0 * u, state, ctx)
    assert np.abs(F[free]).max() < 1e-10 * np.abs(F).max()   # interior nodes balance
    sig = elastic_matrix(E, NU) @ eps
    assert np.allclose(res.state["stress"], sig, rtol=0, atol=1e-10 * np.abs(sig).max())


@pytest.mark.parametrize("name", TYPES)
def test_homogeneous_finite_strain_gives_the_hencky_stress(name):
    from scipy.linalg import logm
    cls = registry.get("elements", name)
    coords, conn, _ = patch(x0=1.0 if cls.axisymmetric else 0.0)
    g = group(name, coords, conn)
    if cls.axisymmetric:
        F3 = np.diag([1.15, 0.8, 1.15])
    else:
        F3 = np.eye(3)
        F3[:2, :2] = [[1.2, 0.3], [-0.1, 0.9]]
    u = coords @ F3[:2, :2].T - coords
    res = g.compute(u, 0 * u, g.init_state(), StepContext(nlgeom=True))
    logV = 0.5 * logm(F3 @ F3.T).real
    sig = elastic_matrix(E, NU) @ [logV[0, 0], logV[1, 1], logV[2, 2], 2 * logV[0, 1]]
    sig = sig / np.linalg.det(F3)
    assert np.allclose(res.state["stress"], sig, rtol=0, atol=1e-10 * np.abs(sig).max())


# --------------------------------------------------------------------------------------------
# rigid motions

@pytest.mark.parametrize("name", TYPES)
def test_small_strain_rigid_motions_give_no_stress(name):
    cls = registry.get("elements", name)
    coords, conn, _ = patch(x0=1.0 if cls.axisymmetric else 0.0)
    g = group(name, coords, conn)
    x, y = coords.T
    modes = [np.stack([0 * x, 0 * x + 0.3], 1)]
    if not cls.axisymmetric:
        modes += [np.stack([0 * x + 0.2, 0 * x - 0.1], 1), 1e-3 * np.stack([-y, x], 1)]
    for u in modes:
        F, _, res = assemble(g, u, 0 * u, g.init_state(), StepContext())
        assert np.abs(res.state["stress"]).max() < 1e-12 * E
        assert np.abs(F).max() < 1e-12 * E


def rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


@pytest.mark.parametrize("theta", [1.2, -2.5])
def test_nlgeom_rigid_rotation_by_a_large_angle_gives_no_stress(theta):
    coords, conn, _ = patch()
    g = group("T6PE", coords, conn, j2())
    u = (coords - 1.0) @ rotation(theta).T + 1.0 + np.array([0.4, -0.3]) - coords
    res = g.compute(u, 0 * u, g.init_state(), StepContext(nlgeom=True))
    assert res.failure is None
    assert np.abs(res.state["stress"]).max() < 1e-10 * E
    assert np.abs(res.f).max() < 1e-10 * E
    assert (res.state["peeq"] == 0).all()


def test_nlgeom_rotation_of_a_prestressed_patch_rotates_its_stress():
    coords, conn, _ = patch()
    g = group("T6PE", coords, conn)
    ctx = StepContext(nlgeom=True)
    rng = np.random.default_rng(5)
    u1 = coords @ np.array([[0.05, 0.02], [0.01, -0.04]]).T + 0.01 * rng.normal(size=coords.shape)
    res = g.compute(u1, 0 * u1, g.init_state(), ctx)
    s1, f1, state, u_old = res.state["stress"], res.f, res.state, u1
    for k in range(1, 11):
        u = (coords + u1) @ rotation(0.5 * np.pi * k / 10).T - coords
        res = g.compute(u, u_old, state, ctx)
        assert res.failure is None
        state, u_old = res.state, u
    # 90 degrees: s11 <-> s22, s12 -> -s12, s33 unchanged; nodal forces turn with the body
    expected = np.stack([s1[..., 1], s1[..., 0], s1[..., 2], -s1[..., 3]], -1)
    assert np.abs(state["stress"] - expected).max() < 1e-8 * np.abs(s1).max()
    f_rot = (f1.reshape(len(conn), -1, 2) @ rotation(0.5 * np.pi).T).reshape(f1.shape)
    assert np.abs(res.f - f_rot).max() < 1e-8 * np.abs(f1).max()


def test_nlgeom_axisymmetric_rigid_translation_keeps_the_stress():
    coords, conn, _ = patch(x0=1.0)
    g = group("T6AX", coords, conn, j2())
    ctx = StepContext(nlgeom=True)
    u1 = coords @ np.array([[0.01, 0.004], [0.002, -0.008]]).T
    res = g.compute(u1, 0 * u1, g.init_state(), ctx)
    s1, f1 = res.state["stress"], res.f
    assert (res.state["peeq"] > 0).any()
    res = g.compute(u1 + [0.0, 7.5], u1, res.state, ctx)
    assert np.abs(res.state["stress"] - s1).max() < 1e-10 * np.abs(s1).max()
    assert np.abs(res.f - f1).max() < 1e-10 * np.abs(f1).max()


# --------------------------------------------------------------------------------------------
# tangents against central differences

def one_element(name, seed):
    cls = registry.get("elements", name)
    rng = np.random.default_rng(seed)
    coords = 0.8 * cls.node_xi + (np.array([2.0, 1.0]) if cls.axisymmetric else 0.0)
    return cls, coords + 0.05 * rng.normal(size=coords.shape), rng


@pytest.mark.parametrize("name", TYPES)
def test_small_strain_tangent_plastic(name):
    cls, coords, rng = one_element(name, 1)
    g = cls([7], [np.arange(6)], coords, j2())
    ctx = StepContext(nlgeom=False)
    grad = np.array([[4e-3, 1e-3], [-2e-3, -5e-3]])          # stress ~ 1000 MPa > SIGMAY
    u_old = coords @ grad.T + 2e-4 * rng.normal(size=coords.shape)
    state = previous_increment(g, u_old, ctx)
    assert (state["peeq"] > 0).all()
    u = u_old + coords @ (0.5 * grad).T + 5e-5 * rng.normal(size=coords.shape)
    res = check_tangent(g, u, u_old, state, ctx)
    assert (res.state["peeq"] > state["peeq"]).all()        # every point loads plastically


@pytest.mark.parametrize("lawname", ["elastic", "J2_LINEAR"])
@pytest.mark.parametrize("name", TYPES)
def test_large_strain_tangent(name, lawname):
    cls, coords, rng = one_element(name, 2)
    g = cls([7], [np.arange(6)], coords, elastic() if lawname == "elastic" else j2())
    ctx = StepContext(nlgeom=True)
    grad = np.array([[0.08, 0.05], [-0.03, -0.1]])         # finite strains
    u_old = coords @ grad.T + 0.01 * rng.normal(size=coords.shape)
    state = previous_increment(g, u_old, ctx)
    x_new = coords + u_old
    if not cls.axisymmetric:                                 # and a finite rotation
        x_new = x_new @ rotation(0.4).T
    u = x_new - coords + 0.05 * (coords - coords.mean(0)) @ np.array([[1.0, 0.5], [0.2, -0.7]]).T
    res = check_tangent(g, u, u_old, state, ctx)
    if lawname == "J2_LINEAR":
        assert (res.state["peeq"] > state["peeq"]).all()


# --------------------------------------------------------------------------------------------
# the Jacobian check

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])
#: (name, coords): corners clockwise; mid-side 4 slid to 0.2 of edge 1-2 (past the quarter
#: point: det J < 0 at corner 1); mid-sides 4 and 5 pulled inwards and sideways (det J > 0 at
#: every node and Gauss point, < 0 on edge S1 at xi = 1/4, between the nodes)
BAD = {
    "inverted": UNIT[[0, 2, 1, 5, 4, 3]],
    "quarter point passed": UNIT + [[0, 0], [0, 0], [0, 0], [-0.3, 0.0], [0, 0], [0, 0]],
    "edge between nodes": UNIT + [[0, 0], [0, 0], [0, 0], [-0.2, 0.4], [0.4, 0.0], [0, 0]],
}


def det_j_fd(x, xi, h=1e-6):
    """det of dx/dxi of the isoparametric map by central differences."""
    def pos(p):
        return tri6_shape(np.atleast_2d(p))[0] @ x
    J = np.column_stack([(pos(xi + d) - pos(xi - d))[0] / (2 * h) for d in np.eye(2) * h])
    return np.linalg.det(J)


def test_shoelace_and_jacobian_of_the_bad_elements():
    """The independent facts behind BAD: the inverted one's corners turn clockwise; the others
    have det J < 0 at an edge point and > 0 at all Gauss points (and nodes, for the last)."""
    area = lambda c: 0.5 * cross2(c[1] - c[0], c[2] - c[0])
    assert area(BAD["inverted"]) < 0
    gauss, _ = gauss_triangle(3)
    for name, at in (("quarter point passed", [0.0, 0.0]), ("edge between nodes", [0.25, 0.0])):
        x = BAD[name]
        assert area(x) > 0
        assert det_j_fd(x, np.array(at)) < -0.05
        assert min(det_j_fd(x, p) for p in gauss) > 0.3
    assert min(det_j_fd(BAD["edge between nodes"], p) for p in Tri6.node_xi) > 0.15


@pytest.mark.parametrize("cls", [T6PlaneStrain, T6Axisymmetric])
def test_invalid_refuses_inverted_and_edge_negative_elements(cls):
    shift = np.array([2.0, 0.0]) if cls.axisymmetric else 0.0
    coords = np.stack([UNIT] + list(BAD.values())) + shift
    bad, detj = cls.invalid(coords)
    assert bad.tolist() == [False, True, True, True]
    assert detj[0] == pytest.approx(1.0) and (detj[1:] < 0).all()
    # the element group itself refuses only what its Gauss points see (det J0 <= 0)
    g = cls(np.arange(1, 5), np.arange(24).reshape(4, 6), coords.reshape(-1, 2), elastic())
    assert g._bad0.tolist() == [False, True, False, False]


def test_deck_refuses_bad_triangles_with_file_and_line(tmp_path, capsys):
    nodes, elements, n = [], [], 0
    for k, x in enumerate([UNIT] + list(BAD.values())):
        x = x + [3.0 * k, 0.0]
        nodes += [f"{n + a + 1}, {px:.17g}, {py:.17g}" for a, (px, py) in enumerate(x)]
        elements.append(f"{k + 1}, " + ", ".join(str(n + a + 1) for a in range(6)))
        n += 6
    text = ("*NODE\n" + "\n".join(nodes) + "\n*ELEMENT, TYPE=CPE6, ELSET=E\n" + "\n".join(elements)
            + "\n*MATERIAL, NAME=M, LAW=ELASTIC\nE=1, NU=0.3\n*SOLID, ELSET=E, MATERIAL=M\n"
            "*STEP\n*STATIC\n1, 1, 1, 1\n*END STEP\n")
    deck = tmp_path / "tri.dat"
    deck.write_text(text)
    assert main(["check", str(deck)]) == 2
    err = capsys.readouterr().err
    first = len(nodes) + 3                                   # line of element 1
    for eid in (3, 4):
        assert f"tri.dat:{first + eid - 1}: *ELEMENT: element {eid} is inverted or degenerate" in err
    assert "element 1 " not in err and "element 2 " not in err
    # the good element and the clockwise one (renumbered, with a notice) pass
    good = text.replace("\n" + "\n".join(elements[2:]), "")
    deck.write_text(good)
    assert main(["check", str(deck)]) == 0
    err = capsys.readouterr().err
    assert f"notice: {deck}:{first + 1}: *ELEMENT: 1 element given clockwise renumbered" in err


# --------------------------------------------------------------------------------------------
# *MESH

SIDE = {"BOTTOM": (1, 2.0, (0.0, -1.0)), "RIGHT": (0, 4.0, (1.0, 0.0)),
        "TOP": (1, 4.0, (0.0, 1.0)), "LEFT": (0, 1.0, (-1.0, 0.0))}


@pytest.mark.parametrize("etype", ["T6PE", "CAX6"])
def test_mesh_numbering_sides_and_outward_faces(tmp_path, etype):
    nx, ny = 3, 2
    text = (f"*MESH, NAME=B, TYPE={etype}, X0=1, Y0=2, LX=3, LY=2, NX={nx}, NY={ny}\n"
            "*MATERIAL, NAME=M, LAW=ELASTIC\nE=1, NU=0.3\n*SOLID, ELSET=B, MATERIAL=M\n"
            "*STEP\n*STATIC\n1, 1, 1, 1\n*END STEP\n")
    deck = tmp_path / "mesh.dat"
    deck.write_text(text)
    m = load_deck(deck)
    (blk,) = m.blocks
    assert blk.type == registry.canonical("elements", etype)
    # every point of the (2 nx + 1) x (2 ny + 1) grid, numbered row by row from the bottom left
    i, j = np.meshgrid(np.arange(2 * nx + 1), np.arange(2 * ny + 1))
    grid = np.column_stack([1 + 0.5 * i.ravel(), 2 + 0.5 * j.ravel()])
    np.testing.assert_allclose(m.coords, grid)
    assert list(m.node_ids) == list(range(1, len(grid) + 1))
    # two counter-clockwise triangles per cell, cell by cell, each half a cell
    assert list(blk.ids) == list(range(1, 2 * nx * ny + 1))
    c = m.coords[blk.conn]
    area = 0.5 * cross2(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    np.testing.assert_allclose(area, 0.5)
    np.testing.assert_allclose(c[:, 3:], 0.5 * (c[:, :3] + np.roll(c[:, :3], -1, axis=1)))
    centres = c[:, :3].mean(1)
    cell = np.floor(centres - [1.0, 2.0]).astype(int)
    assert (cell[:, 1] * nx + cell[:, 0]).tolist() == np.repeat(np.arange(nx * ny), 2).tolist()
    # sides: node sets in order along the side, faces on the side with the body on their left
    cls = registry.get("elements", etype)
    N, dN = line_shape(3, np.array([-0.5, 0.0, 0.7]))
    for side, (axis, value, outward) in SIDE.items():
        nodes = m.nsets[f"B_{side}"]
        on = np.flatnonzero(np.isclose(m.coords[:, axis], value))
        assert sorted(nodes) == sorted(on)
        along = m.coords[nodes, 1 - axis]
        assert (np.diff(along) > 0).all()
        surf = m.surfaces[f"B_{side}"]
        assert len(surf.elements) == (nx if axis == 1 else ny)
        rows = np.searchsorted(blk.ids, surf.elements)
        fn = blk.conn[rows[:, None], np.array(cls.faces)[surf.faces - 1]]
        x = m.coords[fn]                                       # (f, 3, 2)
        np.testing.assert_allclose(x[..., axis], value)
        length = np.abs(x[:, 1, 1 - axis] - x[:, 0, 1 - axis])
        assert length.sum() == pytest.approx(3.0 if axis == 1 else 2.0)
        xq, _, n = edge_geometry(x, N, dN)
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        np.testing.assert_allclose(n, np.broadcast_to(outward, n.shape), atol=1e-14)
        # the outward normal points away from the owning element's centre
        assert (np.einsum("fqi,fqi->fq", n, xq - centres[rows][:, None]) > 0).all()


def test_a_triangle_has_no_face_s4(tmp_path):
    text = ("*MESH, NAME=B, TYPE=T6PE, X0=0, Y0=0, LX=1, LY=1, NX=1, NY=1\n"
            "*SURFACE, NAME=S\n1, S4\n*MATERIAL, NAME=M, LAW=ELASTIC\nE=1, NU=0.3\n"
            "*SOLID, ELSET=B, MATERIAL=M\n*STEP\n*STATIC\n1, 1, 1, 1\n*END STEP\n")
    deck = tmp_path / "s4.dat"
    deck.write_text(text)
    from lagamine_py.deck import DeckError
    with pytest.raises(DeckError, match=r"s4.dat:3: \*SURFACE: element 1 \(T6PlaneStrain\) has "
                                        r"faces S1..S3, not S4"):
        load_deck(deck)


# --------------------------------------------------------------------------------------------
# the contact element on T6 faces

def test_contact_normals_point_out_of_every_t6_face():
    x = np.array([[1.0, 0.5], [3.1, 0.9], [1.6, 2.4]])
    x = np.vstack([x, 0.5 * (x + np.roll(x, -1, axis=0)) + [[0.0, -0.1], [0.1, 0.05], [-0.08, 0.0]]])
    law = Coulomb(KP=1e3, KT=1e3, PHI=0.3)
    found = Foundation([[-10.0, -5.0], [0.0, -5.0], [10.0, -5.0]])
    grp = ContactGroup("c", np.array(Tri6.faces), [1] * 3, [1, 2, 3], x, found, "F", law, gauss=3)
    P, t = grp._at_points(grp._face_x(np.zeros_like(x)))
    e_u = np.stack([t[:, 1], -t[:, 0]], axis=1) / np.linalg.norm(t, axis=1)[:, None]
    assert np.all(np.einsum("gi,gi->g", e_u, P - x[:3].mean(axis=0)) > 0.2)


def flat_punch(tmp_path, etype, nlgeom, p):
    """decks/flat_punch.dat with T6 elements: an elastic block pressed by p onto the flat."""
    text = (DECKS / "flat_punch.dat").read_text().replace("TYPE=Q8PE", f"TYPE={etype}")
    text = text.replace("*STEP, NAME=PRESS", f"*STEP, NAME=PRESS, NLGEOM={nlgeom}")
    text = text.replace("BLOCK_TOP, P, 50", f"BLOCK_TOP, P, {p}").replace("P=50,", f"P={p},")
    if etype == "T6AX":                 # a cylinder of radius 10 on the axis: no symmetry BC
        text = text.replace("*BOUNDARY\nBLOCK_LEFT, 1, 1, 0\n", "")
    deck = tmp_path / f"punch_{etype}_{nlgeom}.dat"
    deck.write_text(text)
    out = tmp_path / f"punch_{etype}_{nlgeom}_out"
    outcome, cap, _ = run_deck(deck, out)
    assert outcome.status == 0, outcome.message
    (chk,) = evaluate_checks(load_deck(deck).checks, out)
    return cap, chk, out


@pytest.mark.parametrize("etype, nlgeom, p", [("T6PE", "NO", 50.0), ("T6PE", "YES", 5000.0),
                                               ("T6AX", "YES", 50.0)])
def test_flat_punch_penetration_is_p_over_kp(tmp_path, etype, nlgeom, p):
    """d = p / KP at every contact point; under NLGEOM too (the block spreads freely, top and
    bottom keep equal lengths, so the contact pressure stays p); Newton quadratic under NLGEOM."""
    cap, chk, _ = flat_punch(tmp_path, etype, nlgeom, p)
    assert chk["message"] == "" and chk["error"] < 1e-10, chk
    c = cap.results[-1].contacts[0]
    assert len(c.p) == 3 * 4                                  # 3 points on each of 4 faces
    np.testing.assert_allclose(c.gap, -p / 1e6, rtol=1e-10)      # COPEN: -d
    np.testing.assert_allclose(c.p, p, rtol=1e-10)
    area = c.A                                                # current area (per radian in AX)
    assert c.P == pytest.approx(p * area, rel=1e-10)
    if nlgeom == "YES":
        orders = [o for o in (is_quadratic(r.residual_history) for r in cap.results) if o]
        assert orders and min(orders) > 1.8, orders
    assert_newton_tail(cap)


def test_a_t6_run_is_written_and_drawn(tmp_path):
    _, _, out = flat_punch(tmp_path, "T6PE", "NO", 50.0)
    body = RunResults(out).body()
    assert len(body["points"]) == 9 * 5                       # the 9 x 5 grid of *MESH NX=4, NY=2
    np.testing.assert_allclose(body["point:stress"][:, 1], -50.0, rtol=1e-9)   # recovered exactly
    assert main(["plot", str(out), "-o", str(tmp_path / "png")]) == 0
    assert sorted(p.name for p in (tmp_path / "png").glob("*.png"))


# --------------------------------------------------------------------------------------------
# Lame: the thick cylinder under internal pressure

A_IN, B_OUT, P_IN = 10.0, 20.0, 100.0


def lame(r):
    """u_r, s_r, s_t of the plane-strain thick cylinder (Timoshenko & Goodier §28)."""
    A = P_IN * A_IN**2 / (B_OUT**2 - A_IN**2)
    B = P_IN * A_IN**2 * B_OUT**2 / (B_OUT**2 - A_IN**2)
    ur = r / E * ((1 + NU) * (1 - 2 * NU) * A + (1 + NU) * B / r**2)
    return ur, A - B / r**2, A + B / r**2


def lame_axisymmetric(tmp_path, nx, ny):
    ly = 5.0 * ny / nx                                        # square cells
    text = (f"*MESH, NAME=TUBE, TYPE=T6AX, X0={A_IN}, Y0=0, LX={B_OUT - A_IN}, LY={ly}, "
            f"NX={nx}, NY={ny}\n*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE={E}, NU={NU}\n"
            "*SOLID, ELSET=TUBE, MATERIAL=STEEL\n"
            f"*CHECK, NAME=LAME, TYPE=LAME\nP={P_IN}, A={A_IN}, B={B_OUT}, E={E}, NU={NU}\n"
            "*STEP, NAME=LOAD\n*STATIC\n1, 1, 1e-3, 1\n*BOUNDARY\nTUBE_BOTTOM, 2, 2\n"
            f"TUBE_TOP, 2, 2\n*DLOAD\nTUBE_LEFT, P, {P_IN}\n*END STEP\n")
    deck = tmp_path / f"lame_{nx}.dat"
    deck.write_text(text)
    out = tmp_path / f"lame_{nx}_out"
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 0
    (chk,) = evaluate_checks(load_deck(deck).checks, out)
    assert chk["message"] == ""
    return chk, RunResults(out)


def test_lame_axisymmetric_converges_at_third_order(tmp_path):
    """Radial displacement of both surfaces (the LAME check) on square-celled meshes 2 x 1, 4 x 2
    and 8 x 4: under 0.05 % on 4 x 2 (16 triangles) and falling as h^3 (measured 3.6e-4,
    5.6e-5, 7.2e-6: orders 2.7, 2.9)."""
    errors = []
    for nx, ny in ((2, 1), (4, 2), (8, 4)):
        chk, res = lame_axisymmetric(tmp_path, nx, ny)
        ur_in = lame(np.array(A_IN))[0]
        assert chk["closed_form"]["u_inner"] == pytest.approx(ur_in, rel=1e-12)
        errors.append(chk["error"])
    assert errors[1] < 5e-4, errors
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert (orders > 2.5).all(), (errors, orders)
    # every node of the finest mesh, and the stress at mid-wall, away from the extrapolated ends
    body = res.body()
    r = body["points"][:, 0]
    ur, sr, st = lame(r)
    assert np.abs(body["point:displacement"][:, 0] - ur).max() < 1e-4 * np.abs(ur).max()
    assert np.abs(body["point:displacement"][:, 1]).max() < 1e-4 * np.abs(ur).max()
    mid = np.isclose(r, 15.0)
    S = body["point:stress"]
    np.testing.assert_allclose(S[mid, 0], sr[mid], rtol=0, atol=5e-3 * P_IN)
    np.testing.assert_allclose(S[mid, 2], st[mid], rtol=5e-3)


def test_lame_plane_strain_quarter_ring(tmp_path):
    """T6PE on a curved (isoparametric) quarter ring mapped from a *MESH-like rectangle of 6 x 8
    cells (96 triangles), with symmetry conditions: the radial displacement at every node within
    0.1 % of the largest (measured 0.034 %), the tangential one below 0.1 % (measured 0.012 %)."""
    nr, nt = 6, 8
    m = rectangle(T6PlaneStrain, 0.0, 0.0, 1.0, 1.0, nr, nt)
    r, th = A_IN + (B_OUT - A_IN) * m.coords[:, 0], 0.5 * np.pi * m.coords[:, 1]
    xy = np.column_stack([r * np.cos(th), r * np.sin(th)])
    nodes = "".join(f"{k + 1}, {x:.17g}, {y:.17g}\n" for k, (x, y) in enumerate(xy))
    elems = "".join(f"{k + 1}, " + ", ".join(str(n + 1) for n in e) + "\n" for k, e in enumerate(m.conn))
    sets = lambda name, ids: f"*NSET, NSET={name}\n" + "".join(f"{n + 1}\n" for n in ids)
    els, faces = m.side_faces["LEFT"]                        # r = A: the inner surface
    text = ("*NODE\n" + nodes + "*ELEMENT, TYPE=T6PE, ELSET=BODY\n" + elems
            + sets("YSYM", m.side_nodes["BOTTOM"]) + sets("XSYM", m.side_nodes["TOP"])
            + "*SURFACE, NAME=INNER\n" + "".join(f"{e + 1}, S{f}\n" for e, f in zip(els, faces))
            + f"*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE={E}, NU={NU}\n*SOLID, ELSET=BODY, MATERIAL=STEEL\n"
            "*STEP\n*STATIC\n1, 1, 1e-3, 1\n*BOUNDARY\nXSYM, 1, 1\nYSYM, 2, 2\n"
            f"*DLOAD\nINNER, P, {P_IN}\n*END STEP\n")
    deck = tmp_path / "ring.dat"
    deck.write_text(text)
    out = tmp_path / "ring_out"
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 0
    body = RunResults(out).body()
    x, y = body["points"][:, 0], body["points"][:, 1]
    rr = np.hypot(x, y)
    u = body["point:displacement"][:, :2]
    ur, ut = (u[:, 0] * x + u[:, 1] * y) / rr, (-u[:, 0] * y + u[:, 1] * x) / rr
    exact = lame(rr)[0]
    assert np.abs(ur - exact).max() < 1e-3 * exact.max()
    assert np.abs(ut).max() < 1e-3 * exact.max()


# --------------------------------------------------------------------------------------------
# Hertz: a T6 cylinder on the rigid flat

def q8_to_t6(coords, conn):
    """Each Q8 cut along its 1-3 diagonal into two T6 (1,2,3 | 5,6,c) and (1,3,4 | c,7,8), c a
    new node at the Q8's centre (xi = eta = 0 of the serendipity map); Q8 face S1 becomes face
    S1 of the first triangle, S4 face S3 of the second."""
    centre = -0.25 * coords[conn[:, :4]].sum(1) + 0.5 * coords[conn[:, 4:]].sum(1)
    c = len(coords) + np.arange(len(conn))
    first = np.column_stack([conn[:, 0], conn[:, 1], conn[:, 2], conn[:, 4], conn[:, 5], c])
    second = np.column_stack([conn[:, 0], conn[:, 2], conn[:, 3], c, conn[:, 6], conn[:, 7]])
    return np.vstack([coords, centre]), np.stack([first, second], 1).reshape(-1, 6)


def hertz_t6_deck(tmp_path, mesh, kp):
    """decks/hertz.dat on the T6 cut of its Q8 quarter-cylinder mesh (same contact nodes)."""
    q8 = load_deck(DECKS / "hertz.dat", parameters={"MESH": mesh})
    (blk,) = q8.blocks
    coords, conn = q8_to_t6(q8.coords, blk.conn)
    lines = ["*NODE"] + [f"{k + 1}, {x:.17g}, {y:.17g}" for k, (x, y) in enumerate(coords)]
    lines += ["*ELEMENT, TYPE=T6PE, ELSET=CYL"]
    lines += [f"{k + 1}, " + ", ".join(str(n + 1) for n in e) for k, e in enumerate(conn)]
    for name in ("TOP", "AXIS"):
        lines += [f"*NSET, NSET={name}"] + [str(r + 1) for r in q8.nsets[name]]
    arc = q8.surfaces["ARC"]
    assert set(arc.faces.tolist()) == {1}
    first = 2 * np.searchsorted(blk.ids, arc.elements) + 1
    lines += ["*SURFACE, NAME=ARC"] + [f"{e}, S1" for e in first]
    text = (DECKS / "hertz.dat").read_text()
    text = text.replace("*INCLUDE, INPUT=meshes/cylinder_quarter_<MESH>.inp", "\n".join(lines))
    text = text.replace("KP = 3e7", f"KP = {kp}")
    deck = tmp_path / f"hertz_t6_{mesh}.dat"
    deck.write_text(text)
    return deck


def test_hertz_with_t6(tmp_path):
    """The medium mesh cut into 760 T6 (h = 0.133 mm at the contact, KP = 20 E / h): a and p0
    within 2 % of Johnson's closed form at the force reached (measured 0.48 %, 1.42 %; the Q8
    mesh gives 0.37 %, 1.37 %)."""
    deck = hertz_t6_deck(tmp_path, "medium", 3e7)
    out = tmp_path / "hertz_out"
    outcome, cap, _ = run_deck(deck, out)
    assert outcome.status == 0, outcome.message
    (chk,) = evaluate_checks(load_deck(deck).checks, out)
    assert chk["message"] == ""
    m = chk["measured"]
    assert m["P"] == pytest.approx(17285, rel=0.01)
    a_cf, p0_cf = hertz_closed_form(m["P"], 10.0, E, NU)
    assert abs(m["a"] / a_cf - 1) < 0.02 and abs(m["p0"] / p0_cf - 1) < 0.02, m
    assert abs(m["a_moment"] / a_cf - 1) < 0.02, m
    assert_newton_tail(cap)


# --------------------------------------------------------------------------------------------
# the limit pressure of a thick tube: why 3 Gauss points

P_LIM = 2 / math.sqrt(3) * 250 * math.log(2)                  # Hill: (2/sqrt 3) sY ln(b/a)


def tube(tmp_path, etype, factor, dt):
    text = (DECKS / "tube_limit.dat").read_text().replace("TYPE=Q8AXR", f"TYPE={etype}")
    text = text.replace("0.1, 1, 1e-4, 0.1", f"{dt}, 1, 1e-4, {dt}")
    deck = tmp_path / f"tube_{etype}_{factor}.dat"
    deck.write_text(text)
    return run_deck(deck, tmp_path / f"tube_{etype}_{factor}_out",
                    {"PRESSURE": f"{factor * P_LIM:.6f}"})


def test_tube_collapses_at_hills_limit_pressure(tmp_path):
    """J2 perfectly plastic tube (decks/tube_limit.dat, 16 x 1 cells as T6AX): 0.98 p_lim
    converges with quadratic Newton in the plastic increments; asked for 1.03 p_lim it stops
    (exit 3) within 1.5 % below p_lim (measured 0.989 with DT = 0.02: the last increment before
    the limit)."""
    outcome, cap, _ = tube(tmp_path, "T6AX", 0.98, 0.1)
    assert outcome.status == 0, outcome.message
    plastic = [r for r in cap.results if (r.cells[0].peeq > 0).any()]
    orders = [o for o in (is_quadratic(r.residual_history) for r in plastic) if o]
    assert len(orders) >= 3 and min(orders) > 1.8, orders
    outcome, cap, _ = tube(tmp_path, "T6AX", 1.03, 0.02)
    assert outcome.status == 3
    reached = cap.results[-1].step_time * 1.03
    assert 0.985 < reached < 1.0, reached


def test_a_six_point_triangle_locks_under_plastic_flow(tmp_path):
    """The same tube with the 6-point rule carries 1.03 p_lim to the end: the plastically
    incompressible flow locks (6 constraints per triangle instead of 3), as Q8AX with 3 x 3
    points does -- the reason T6PE/T6AX integrate with 3 points."""
    class T6AX6(T6Axisymmetric):
        aliases = ()
        ngauss = 6
    registry.register("elements", "T6AX6")(T6AX6)
    try:
        outcome, cap, _ = tube(tmp_path, "T6AX6", 1.03, 0.02)
    finally:
        registry.REGISTRY.tables["elements"].pop("T6AX6")
    assert outcome.status == 0, outcome.message
    assert cap.results[-1].step_time == pytest.approx(1.0)
