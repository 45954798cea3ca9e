"""SUBSTEPS=AUTO in the contact element: the count follows the rotation of the axes, the result
is that of the fixed count it picks, and the tangent stays exact (finite differences)."""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.core.status import SLIP
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.registry import ParamError

from test_contact_element import _check_fd, _setup


def _law(**kw):
    base = dict(KP=1e3, KT=5e2, PHI=0.3, B=0.5, THETA=0.5)
    base.update(kw)
    return Coulomb(**base)


def _rotate(x, angle, centre):
    c, s = np.cos(angle), np.sin(angle)
    return (x - centre) @ np.array([[c, -s], [s, c]]).T + centre


@pytest.mark.parametrize("angle,tol,want", ((0.0, 0.01, 1), (0.035, 0.01, 4), (0.2, 0.03, 7),
                                            (0.5, 0.001, 32)))
def test_auto_count_from_rigid_rotation(angle, tol, want):
    """A face turned rigidly by ``angle``: N = ceil(angle / SUBTOL), capped at SUBMAX = 32."""
    law = _law(SUBSTEPS="AUTO", SUBTOL=tol)
    grp, *_ = _setup(3, 3, False, 0.5, 1, "slip", law=law)
    x0 = grp._face_x(np.zeros_like(grp.coords0))
    x1 = _rotate(x0, angle, np.array([0.3, -0.2]))
    np.testing.assert_allclose(grp.rotation(x0, x1), angle, atol=1e-12)
    assert grp.substeps_for(x0, x1, geo=True) == want
    assert grp.substeps_for(x0, x1, geo=False) == 1          # small strain: axes do not turn


def test_auto_equals_the_fixed_count_it_picks():
    """Same forces and state as SUBSTEPS = N with the N that AUTO chose."""
    auto = _law(SUBSTEPS="AUTO", SUBTOL=0.004)
    grp, u_old, u_new, state, ctx = _setup(3, 3, False, 0.5, 1, "slip", law=auto)
    u_new = u_new + 0.02 * (grp.coords0 - grp.coords0.mean(axis=0)) @ np.array([[0, -1], [1, 0]]).T
    n = grp.substeps_for(grp._face_x(u_old), grp._face_x(u_new), geo=True)
    assert n > 2
    res = grp.compute(u_new, u_old, state, ctx)
    grp.law = _law(SUBSTEPS=n)
    ref = grp.compute(u_new, u_old, state, ctx)
    np.testing.assert_array_equal(res.f, ref.f)
    np.testing.assert_array_equal(res.K, ref.K)
    grp.law = _law(SUBSTEPS=1)
    one = grp.compute(u_new, u_old, state, ctx)
    for key in ("lam", "slip"):
        np.testing.assert_array_equal(res.state[key], ref.state[key])
    # sliding without hardening: tau = B + phi p whatever the path, but the slip depends on it
    assert np.abs(one.state["slip"] - ref.state["slip"]).max() > 1e-7


@pytest.mark.parametrize("ax", (False, True))
@pytest.mark.parametrize("hphi,hb", ((0.0, 0.0), (2.0, 5.0)))
def test_auto_tangent_matches_finite_differences(ax, hphi, hb):
    law = _law(SUBSTEPS="AUTO", SUBTOL=0.004, HPHI=hphi, HB=hb)
    grp, u_old, u_new, state, ctx = _setup(3, 3, ax, 0.5, 1, "slip", law=law)
    u_new = u_new + 0.013 * (grp.coords0 - grp.coords0.mean(axis=0)) @ np.array([[0, -1], [1, 0]]).T
    xo, xn = grp._face_x(u_old), grp._face_x(u_new)
    angle = grp.rotation(xo, xn).max()
    n = grp.substeps_for(xo, xn, geo=True)
    # away from a switch of the count: the FD perturbation (1e-7) cannot change N
    assert n > 1 and abs(angle / law.subtol - round(angle / law.subtol)) > 1e-3
    _check_fd(grp, u_old, u_new, state, ctx, want=SLIP)


def test_auto_converges_to_the_many_subinterval_answer():
    """The error against a 256-sub-interval reference falls with SUBTOL (the axis-rotation error
    AUTO controls), and one sub-interval is worse than AUTO with a fine tolerance."""
    grp, u_old, u_new, state, ctx = _setup(3, 3, False, 1.0, 1, "slip", law=_law(THETA=1.0))
    u_new = u_new + 0.1 * (grp.coords0 - grp.coords0.mean(axis=0)) @ np.array([[0, -1], [1, 0]]).T

    def tau(**kw):
        grp.law = _law(THETA=1.0, SUBMAX=256, **kw)
        return grp.compute(u_new, u_old, state, ctx, tangent=False).state["tau"]

    ref = tau(SUBSTEPS=256)
    errs = [np.abs(tau(SUBSTEPS="AUTO", SUBTOL=t) - ref).max() for t in (0.1, 0.01, 0.001)]
    assert errs[0] > errs[1] > errs[2]
    assert np.abs(tau(SUBSTEPS=1) - ref).max() > errs[2]


def test_auto_parameters_validated():
    assert _law(SUBSTEPS="auto").substeps == "AUTO"
    with pytest.raises(ParamError):
        _law(SUBSTEPS="AUTO", SUBTOL=0.0)
    with pytest.raises(ParamError):
        _law(SUBSTEPS="AUTOMATIC")


def test_auto_contextless_defaults():
    """A context without NLGEOM never sub-divides (and the law defaults are usable)."""
    law = _law(SUBSTEPS="AUTO")
    grp, u_old, u_new, state, _ = _setup(3, 3, False, 0.5, 1, "slip", law=law)
    ctx = StepContext(nlgeom=False, foundation_old={"F": np.zeros(2)},
                      foundation_new={"F": np.zeros(2)})
    assert grp.compute(u_new, u_old, state, ctx).failure is None


@pytest.mark.parametrize("nsub", (1, 2, 4, "AUTO"))
def test_rigid_turn_in_a_cup_slips_the_chord_lengths(nsub):
    """A pressed face sliding on a circular foundation, turned rigidly about its centre by
    0.1 rad in one increment (THETA = 1/2): every point keeps sliding, and the slip is what the
    element's kinematics give in closed form: the nodes move on the chord of the increment, each
    sub-interval measures its share of the chord on the axes of its mid-configuration (plus the
    change of the elastic part tau / KT).  With one sub-interval that is the chord itself; more
    sub-intervals on a straight path cannot recover the arc, they measure less.  The chord
    path of the nodes lifts the face by r (1 - cos(dalpha / 2N)) = 6e-3 at
    N = 2, far more than d0 = 1e-3: the penetration must not be projected from it."""
    from lagamine_py.elements.contact import ContactGroup
    from lagamine_py.foundation import Foundation
    from lagamine_py.core.status import SLIP

    R, d0, dalpha = 20.0, 1e-3, 0.1
    ang = np.radians(np.arange(-170.0, -9.0, 5.0))
    found = Foundation(np.stack([R * np.cos(ang), R * np.sin(ang)], axis=1))
    a = np.radians([-92.0, -88.0, -90.0])                         # corner, corner, mid
    coords0 = (R + d0) * np.stack([np.cos(a), np.sin(a)], axis=1)
    law = _law(KP=1e5, KT=1e5, B=0.0, SUBSTEPS=nsub, SUBTOL=0.03)
    grp = ContactGroup("S->F", [[0, 1, 2]], [1], [1], coords0, found, "F", law, gauss=3)
    ctx = StepContext(nlgeom=True, foundation_old={"F": np.zeros(2)},
                      foundation_new={"F": np.zeros(2)})
    state = grp.init_state()
    d_start, _, _ = grp._penetration(coords0[grp.face_nodes], np.zeros(2), 0.0, True)
    state["p"] = law.kp * d_start
    state["tau"] = -law.phi * state["p"]                          # sliding clockwise before
    state["status"][:] = SLIP
    u_new = _rotate(coords0, dalpha, np.zeros(2)) - coords0
    res = grp.compute(u_new, np.zeros_like(coords0), state, ctx, tangent=False)
    n = grp.substeps_for(grp._face_x(0 * u_new), grp._face_x(u_new), geo=True)
    assert n == {"AUTO": 4}.get(nsub, nsub)
    r = np.linalg.norm(grp._at_points(coords0[grp.face_nodes])[0], axis=1)
    np.testing.assert_array_equal(res.state["status"], SLIP)
    # the foundation is parabolic arcs through points of the circle: p moves by a few %
    np.testing.assert_allclose(res.state["p"], state["p"], rtol=0.05)
    # nodes move on the chord x0 + s (R x0 - x0) = rho(s) R(phi(s)) x0: sub-interval k sees
    # dx / N along the chord, measured on the axes turned by phi(s_k), s_k = (k - 1/2) / N
    s_k = (np.arange(n) + 0.5) / n
    phi = np.arctan2(s_k * np.sin(dalpha), 1 - s_k + s_k * np.cos(dalpha))
    sum_dv = 2 * r * np.sin(dalpha / 2) / n * np.cos(phi - dalpha / 2).sum()
    # tau = KT (v - v_p) sliding one way: lam = sum |dv| + (tau_end - tau_start) / KT
    np.testing.assert_allclose(res.state["slip"],
                               sum_dv + (res.state["tau"] - state["tau"]) / law.kt, rtol=1e-9)
