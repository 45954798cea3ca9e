"""What the contact element hands to writers, against closed forms: a straight face pressed
into a flat foundation and slid along it (rigid-plastic penalty slider), a face whose normal
misses the foundation (status NONE, its distance as the gap), and the distance to a chain."""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.core.status import NONE, SLIP, STICK
from lagamine_py.elements.base import StepContext
from lagamine_py.elements.contact import ContactGroup
from lagamine_py.foundation import Foundation
from lagamine_py.laws.coulomb import Coulomb

KP, KT, PHI, B = 1e5, 4e4, 0.3, 2.0
DY, SLIDE, N = 1e-3, 0.05, 10          # penetration, slide, increments of the slide


def slide_face(ax: bool, direction: float, nlgeom: bool):
    """A 3-node face along y = 0 (running +x: the body lies above it, a bottom face) pressed by
    DY into the flat y = 0, then slid by ``direction * SLIDE`` in N increments; the points of
    every increment."""
    x0 = 1.0 if ax else -1.0
    coords0 = np.array([[x0, 0.0], [x0 + 2, 0.0], [x0 + 1, 0.0]])
    found = Foundation([[-10.0, 0.0], [0.0, 0.0], [10.0, 0.0]])
    law = Coulomb(KP=KP, KT=KT, PHI=PHI, B=B)
    grp = ContactGroup("S->F", [[0, 1, 2]], [7], [1], coords0, found, "F", law, gauss=3,
                       axisymmetric=ax, thickness=2.0)
    ctx = StepContext(nlgeom=nlgeom, foundation_old={"F": np.zeros(2)},
                      foundation_new={"F": np.zeros(2)})
    path = [np.zeros(3)] + [np.full(3, direction * SLIDE * k / N) for k in range(N + 1)]
    state, u_old, points = grp.init_state(), np.zeros((3, 2)), []
    for ux in path[1:]:
        u_new = np.column_stack([ux, np.full(3, -DY)])
        res = grp.compute(u_new, u_old, state, ctx)
        assert res.failure is None
        state, u_old = res.state, u_new
        points.append(grp.points(u_new, state, ctx))
    return points, x0


@pytest.mark.parametrize("ax", (False, True))
@pytest.mark.parametrize("direction", (1.0, -1.0))
def test_sliding_face_signed_slip_dissipation_and_energy(ax, direction):
    """p = KP d; once sliding |tau| = B + PHI p; the friction on the body opposes the motion, so
    on a bottom face (t = +x) tau < 0 when the body moves +x; the slip is the motion less the
    elastic stick part |tau| / KT, signed along e_v = -x; D = |tau| x slip; the pair's energy is
    D times the area (2 x thickness 2, or int r ds per radian)."""
    points, x0 = slide_face(ax, direction, nlgeom=False)
    last, before = points[-1], points[-2]
    p = KP * DY
    tau = B + PHI * p
    slip = SLIDE - tau / KT
    area = ((x0 + 2) ** 2 - x0 ** 2) / 2 if ax else 2.0 * 2.0
    assert (last.status == SLIP).all()
    np.testing.assert_allclose(last.gap, -DY, rtol=1e-12)          # COPEN: minus the penetration
    np.testing.assert_allclose(last.tau, -direction * tau, rtol=1e-12)
    np.testing.assert_allclose(last.vp, -direction * slip, rtol=1e-10)
    np.testing.assert_allclose(last.slip, slip, rtol=1e-10)
    np.testing.assert_allclose(last.dvp, -direction * SLIDE / N, rtol=1e-10)   # steady sliding
    assert np.all(np.sign(last.tau) == np.sign(last.dvp))
    np.testing.assert_allclose(last.dissip, tau * slip, rtol=1e-10)
    assert last.E == pytest.approx(tau * slip * area, rel=1e-10)
    assert last.E - before.E == pytest.approx(tau * SLIDE / N * area, rel=1e-10)
    np.testing.assert_allclose(last.x0[:, 1], 0.0)
    assert np.allclose(last.x[:, 0] - last.x0[:, 0], direction * SLIDE, rtol=1e-12)
    assert points[0].E == 0.0 and (points[0].status == STICK).all()


def test_face_turned_away_has_status_none_and_its_distance():
    """A top face (running -x, the body below it) 3 above a flat foundation: its outward normal
    points up, away from the foundation, and meets none of it -- status NONE; its gap is the
    distance to the foundation (3), not NaN; no stress."""
    coords0 = np.array([[1.0, 3.0], [-1.0, 3.0], [0.0, 3.0]])
    found = Foundation([[-10.0, 0.0], [0.0, 0.0], [10.0, 0.0]])
    grp = ContactGroup("TOP->F", [[0, 1, 2]], [1], [3], coords0, found, "F",
                       Coulomb(KP=KP, KT=KT, PHI=PHI), gauss=2)
    ctx = StepContext(foundation_old={"F": np.zeros(2)}, foundation_new={"F": np.zeros(2)})
    u = np.zeros((3, 2))
    res = grp.compute(u, u, grp.init_state(), ctx)
    pts = grp.points(u, res.state, ctx)
    assert (pts.status == NONE).all()
    np.testing.assert_allclose(pts.gap, 3.0, rtol=1e-12)
    assert not np.isnan(pts.gap).any() and not pts.p.any() and pts.A == 0.0


def test_distance_to_a_chain_is_the_nearest_point():
    """Foundation.distance against a dense sampling of the arcs and the end half-lines."""
    pts = np.array([[0.0, 0.0], [1.0, 0.8], [2.0, 0.1], [3.0, -0.6], [4.0, 0.0]])
    f = Foundation(pts)
    rng = np.random.default_rng(3)
    P = rng.uniform([-3.0, -3.0], [7.0, 3.0], size=(60, 2))
    s = np.linspace(-1.0, 1.0, 20001)
    dense = [f.evaluate(np.full(s.size, j), s)[0] for j in range(f.n_arcs)]
    k = np.linspace(0.0, 50.0, 50001)
    (o0, t0), (o1, t1) = f._start, f._end
    dense += [o0 - k[:, None] * t0, o1 + k[:, None] * t1]
    dense = np.concatenate(dense)
    brute = np.array([np.min(np.linalg.norm(dense - p, axis=1)) for p in P])
    np.testing.assert_allclose(f.distance(P), brute, rtol=0, atol=2e-5)
    np.testing.assert_allclose(f.distance(P + [0.5, 2.0], c=[0.5, 2.0]), f.distance(P), atol=1e-12)
