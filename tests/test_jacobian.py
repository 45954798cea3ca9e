"""The Jacobian check proves det J > 0 over the whole element (Bernstein bounds, subdivision).

Every verdict here is set against an independent source: det J in closed form for elements
whose map is written out by hand, or det J by central differences of the position map on a
dense grid for random elements whose minimum is clearly away from zero.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.elements.bernstein import domain
from lagamine_py.elements.quad import Q4PlaneStrain, Q8Axisymmetric, Q8PlaneStrain, gauss_quad
from lagamine_py.elements.t6 import T6PlaneStrain, gauss_triangle

XI8 = Q8PlaneStrain.node_xi                    # the reference square [-1, 1]^2: x = xi, y = eta


def fd_det_j(cls, X, pts, h=1e-6):
    """det J at natural points pts (m, 2) by central differences of x(xi) = N(xi) X."""
    def pos(p):
        return cls.shape_functions(p)[0] @ X
    dx = (pos(pts + [h, 0]) - pos(pts - [h, 0])) / (2 * h)
    dy = (pos(pts + [0, h]) - pos(pts - [0, h])) / (2 * h)
    return dx[:, 0] * dy[:, 1] - dx[:, 1] * dy[:, 0]


def edge_mid_moved(a, b):
    """The reference Q8 with mid-side node 5 (edge eta = -1) moved by (a, b)."""
    X = XI8.copy()
    X[4] += [a, b]
    return X


def closed_form_edge(a, b, xi):
    """det J on the edge eta = -1 of :func:`edge_mid_moved`, written out: along the edge
    x = xi + a (1 - xi^2), y = -1 + b (1 - xi^2); across it dN5/deta = -(1 - xi^2)/2 moves
    (x_eta, y_eta) from (0, 1) by -(1 - xi^2)/2 (a, b)."""
    s = 1.0 - xi**2
    x_xi, y_xi = 1.0 - 2.0 * a * xi, -2.0 * b * xi
    x_eta, y_eta = -0.5 * a * s, 1.0 - 0.5 * b * s
    return x_xi * y_eta - x_eta * y_xi


def test_the_issues_element_positive_at_gauss_points_and_nodes_negative_on_an_edge():
    """Mid-side node 5 at (0.4, 0.9): det J = -0.118 on edge S1 near xi = 0.42, positive at all
    9 Gauss points and 8 nodes; the check refuses it and says where det J is negative."""
    a, b = 0.4, 1.9
    X = edge_mid_moved(a, b)
    xi = np.linspace(-1, 1, 20001)
    edge = closed_form_edge(a, b, xi)
    assert np.allclose(fd_det_j(Q8PlaneStrain, X, np.column_stack([xi[::500], -np.ones(41)])),
                       edge[::500], atol=1e-7)            # the closed form is this element's
    assert edge.min() == pytest.approx(-0.1184, abs=5e-4)
    assert fd_det_j(Q8PlaneStrain, X, gauss_quad(3)[0]).min() > 0.04
    assert fd_det_j(Q8PlaneStrain, X, XI8).min() > 0.04
    check = Q8PlaneStrain.jacobian_check(X[None])
    assert not check.valid[0] and check.min_found[0] < 0
    assert fd_det_j(Q8PlaneStrain, X, check.at)[0] == pytest.approx(check.min_found[0], abs=1e-7)
    assert Q8PlaneStrain.invalid(X[None])[0][0]


def test_a_strongly_curved_valid_element_needs_subdivision_and_passes():
    """Mid-side node 5 pulled 90 % of the way up: det J = 1 - 0.9 (1 - xi^2) >= 0.1 everywhere
    (y = eta + 1.8 N5, x = xi), yet some Bernstein coefficient of the whole element is negative;
    subdividing clears it."""
    X = edge_mid_moved(0.0, 1.8)
    g = np.linspace(-1, 1, 201)
    P = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    assert np.allclose(fd_det_j(Q8PlaneStrain, X, P), 1 - 0.9 * (1 - P[:, 0] ** 2), atol=1e-7)
    dom = domain("square", Q8PlaneStrain.jacobian_degree)
    values = fd_det_j(Q8PlaneStrain, X, dom.points)
    assert (dom.to_bernstein @ values).min() < -0.1           # the bound alone would refuse it
    check = Q8PlaneStrain.jacobian_check(X[None])
    assert check.valid[0] and check.min_found[0] == pytest.approx(0.1, abs=1e-12)
    assert Q8PlaneStrain.min_jacobian(X[None])[0] == pytest.approx(0.1, abs=1e-12)


def test_det_j_zero_along_a_line_is_degenerate():
    """b = 2: det J = xi^2 (zero along xi = 0): refused (degenerate), as is a collapsed element."""
    check = Q8PlaneStrain.jacobian_check(edge_mid_moved(0.0, 2.0)[None])
    assert not check.valid[0] and abs(check.min_found[0]) < 1e-12
    flat = np.column_stack([XI8[:, 0], 0.0 * XI8[:, 1]])        # all nodes on y = 0: zero area
    assert not Q8PlaneStrain.jacobian_check(flat[None]).valid[0]


@pytest.mark.parametrize("cls, spread", [(Q8PlaneStrain, 0.3), (Q4PlaneStrain, 0.7), (T6PlaneStrain, 0.18)])
def test_verdicts_agree_with_dense_sampling(cls, spread):
    """Random distorted elements whose dense-grid minimum of det J is clearly away from 0: the
    check says valid exactly when that minimum is positive (both kinds occur)."""
    rng = np.random.default_rng(7)
    xi = np.asarray(cls.node_xi, float)
    X = xi[None] + spread * rng.normal(size=(300,) + xi.shape)
    if cls.reference_domain == "square":
        g = np.linspace(-1, 1, 81)
        P = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    else:
        g = np.linspace(0, 1, 81)
        P = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
        P = P[P.sum(1) <= 1 + 1e-12]
    h = 1e-6
    N = [cls.shape_functions(P + d)[0] for d in ([h, 0], [-h, 0], [0, h], [0, -h])]
    dx = np.einsum("qa,eai->eqi", N[0] - N[1], X) / (2 * h)
    dy = np.einsum("qa,eai->eqi", N[2] - N[3], X) / (2 * h)
    dense = (dx[..., 0] * dy[..., 1] - dx[..., 1] * dy[..., 0]).min(axis=1)
    clear = np.abs(dense) > 1e-2
    check = cls.jacobian_check(X)
    assert clear.sum() > 250 and (dense[clear] > 0).sum() > 30 and (dense[clear] < 0).sum() > 30
    assert np.array_equal(check.valid[clear], dense[clear] > 0)
    # every negative value reported is det J at the point reported
    neg = ~check.valid & (check.min_found < 0)
    assert np.allclose([fd_det_j(cls, X[k], check.at[k][None])[0] for k in np.flatnonzero(neg)],
                       check.min_found[neg], atol=1e-6)


def test_t6_edge_between_nodes():
    """A T6 whose det J is negative on edge S1 between its nodes, positive at the 3 Gauss points
    and the 6 nodes (mid-sides 4 and 5 pulled inwards and sideways): refused."""
    X = T6PlaneStrain.node_xi + [[0, 0], [0, 0], [0, 0], [-0.2, 0.4], [0.4, 0.0], [0, 0]]
    assert fd_det_j(T6PlaneStrain, X, gauss_triangle(3)[0]).min() > 0.3
    assert fd_det_j(T6PlaneStrain, X, T6PlaneStrain.node_xi).min() > 0.15
    assert fd_det_j(T6PlaneStrain, X, np.array([[0.25, 0.0]]))[0] < -0.05
    assert not T6PlaneStrain.jacobian_check(X[None]).valid[0]


def test_the_mirror_is_the_same_element_turned_over():
    """The mirrored node order of a valid element has det J < 0 everywhere, and turning it again
    gives the element back."""
    for cls in (Q8PlaneStrain, Q4PlaneStrain, T6PlaneStrain):
        xi = np.asarray(cls.node_xi, float)
        perm = cls.mirror()
        assert np.array_equal(perm[perm], np.arange(cls.nen))
        X = 2.0 * xi + [3.0, 1.0]
        assert cls.jacobian_check(X[None]).valid[0]
        assert not cls.jacobian_check(X[perm][None]).valid[0]
        assert cls.jacobian_check(X[perm][perm][None]).valid[0]


def test_axisymmetric_elements_across_the_axis_are_refused():
    X = 0.5 * XI8 + [0.3, 0.0]                       # nodes at r = -0.2
    assert Q8Axisymmetric.jacobian_check(X[None]).valid[0]
    assert Q8Axisymmetric.invalid(X[None])[0][0] and Q8Axisymmetric.min_jacobian(X[None])[0] < 0


def test_deck_refuses_the_issues_element_at_its_line(tmp_path, capsys):
    """The issue: an inverted Q8 (positive at Gauss points and nodes) ran to exit 0; now check
    refuses it with the file, the line and where det J is negative."""
    X = edge_mid_moved(0.4, 1.9)
    nodes = "".join(f"{k + 1}, {x:.17g}, {y:.17g}\n" for k, (x, y) in enumerate(X))
    text = (f"*NODE\n{nodes}*ELEMENT, TYPE=CPE8, ELSET=E\n1, 1, 2, 3, 4, 5, 6, 7, 8\n"
            "*MATERIAL, NAME=M, LAW=ELASTIC\nE=1000, NU=0.3\n*SOLID, ELSET=E, MATERIAL=M\n"
            "*STEP\n*STATIC\n1, 1\n*BOUNDARY\n1, 1, 2\n2, 2, 2\n*END STEP\n")
    deck = tmp_path / "issue.dat"
    deck.write_text(text)
    assert main(["check", str(deck)]) == 2
    err = capsys.readouterr().err
    assert "issue.dat:11: *ELEMENT: element 1 is inverted or degenerate: det J = -0.1" in err
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 2
