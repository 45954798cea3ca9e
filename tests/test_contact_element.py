"""The contact element group: orientation, closed-form forces, and the exact tangent against
central finite differences of the forces in open, stick and slip states."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.elements.contact import ContactGroup
from lagamine_py.elements.quad import Quad4, Quad8
from lagamine_py.foundation import Foundation
from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.laws.base import ContactLaw


class StandInCoulomb(ContactLaw):
    """Penalty + Coulomb with PHI(lam) = PHI + HPHI lam and constant B, exact derivatives
    (test stand-in for the real law).

    ``form="d"``: the slip limit uses ``p_new = KP max(d, 0)`` (explicit dependence on d,
    reported as ``tau_d``), with the hardening derivatives ``tau_lam`` and ``lam_*``;
    ``form="pold"`` (no hardening): it uses ``p_old + KP du`` (dependence on the old pressure,
    reported as ``tau_p``).  Both exercise the element's chaining of sub-intervals."""

    def __init__(self, KP=1e3, KT=5e2, PHI=0.3, B=0.0, HPHI=0.0, THETA=1.0, SUBSTEPS=1, form="d"):
        self.kp, self.kt, self.phi, self.b, self.hphi = KP, KT, PHI, B, HPHI
        self.theta, self.substeps, self.form = THETA, SUBSTEPS, form
        self.calls = []

    def update(self, state, d, du, dv, frozen=None):
        self.calls.append(None if frozen is None else np.array(frozen))
        kp, kt, hphi = self.kp, self.kt, self.hphi
        contact = d > 0
        p = kp * np.maximum(d, 0.0)
        p_u = kp * contact
        tr = state["tau"] + kt * dv
        s = np.sign(tr)
        lam0 = state["lam"]
        phi0 = self.phi + hphi * lam0
        if self.form == "d":
            lim = self.b + phi0 * p
        else:
            lim = self.b + self.phi * (state["p"] + kp * du)
        slip = contact & (np.abs(tr) > lim)
        if frozen is not None:
            slip = contact & np.where(frozen == SLIP, True, np.where(frozen == STICK, False, slip))
        stick = contact & ~slip
        # slip: |tr| - KT Lam - B - (phi0 + HPHI Lam) p = 0
        A = kt + hphi * p
        dlam = np.where(slip, (np.abs(tr) - lim) / A, 0.0)
        phi1 = phi0 + hphi * dlam
        tau = np.where(slip, s * (np.abs(tr) - kt * dlam), np.where(stick, tr, 0.0))
        dtau_dtr = np.where(slip, hphi * p / A, np.where(stick, 1.0, 0.0))
        tan = {"p_u": p_u, "tau_tau": dtau_dtr, "tau_v": kt * dtau_dtr,
               "lam_tau": np.where(slip, s / A, 0.0), "lam_v": np.where(slip, kt * s / A, 0.0),
               "lam_lam": np.where(slip, 1 - hphi * p / A, 1.0)}
        if self.form == "d":
            tan["tau_u"] = tan["tau_d"] = np.where(slip, s * kt * phi1 * kp / A, 0.0)
            tan["lam_u"] = tan["lam_d"] = np.where(slip, -phi1 * kp / A, 0.0)
            tan["tau_lam"] = np.where(slip, s * kt * hphi * p / A, 0.0)
        else:
            tan["tau_u"] = np.where(slip, s * self.phi * kp, 0.0)
            tan["tau_p"] = np.where(slip, s * self.phi, 0.0)
            tan["lam_u"] = np.where(slip, -self.phi * kp / A, 0.0)
            tan["lam_p"] = np.where(slip, -self.phi / A, 0.0)
        status = np.where(slip, SLIP, np.where(stick, STICK, OPEN)).astype(np.int8)
        new = {"p": p, "tau": tau, "lam": lam0 + dlam, "slip": state["slip"] + dlam,
               "vp": state["vp"] + s * dlam, "dissip": state["dissip"] + dlam * np.abs(tau),
               "status": status}
        return new, tan


# A curved foundation below the body (travel +x, body on the left = above) and a curved face
# along its top; the face runs +x, which is the counter-clockwise order of an element above it.
FOUND = Foundation([[-3.0, 0.1], [-1.0, 0.0], [0.5, 0.02], [1.5, -0.03], [3.0, -0.1]])
X0 = 2.0     # shift everything right in axisymmetry so that r > 0


def _setup(nfn, gauss, ax, theta, substeps, case, form="d", hphi=0.0, law=None, nlgeom=True):
    shift = np.array([X0 if ax else 0.0, 0.0])
    found = Foundation(FOUND.points + shift)
    if nfn == 3:
        coords0 = np.array([[-0.4, 0.05], [0.4, 0.02], [1.2, 0.0], [0.0, 0.06], [0.8, 0.03]]) + shift
        face_nodes = np.array([[0, 1, 3], [1, 2, 4]])
    else:
        coords0 = np.array([[-0.4, 0.05], [0.4, 0.02], [1.2, 0.0]]) + shift
        face_nodes = np.array([[0, 1], [1, 2]])
    if law is None:
        law = StandInCoulomb(THETA=theta, SUBSTEPS=substeps, form=form, HPHI=hphi)
    grp = ContactGroup("S->F", face_nodes, [11, 12], [1, 1], coords0, found, "F", law,
                       gauss=gauss, axisymmetric=ax, thickness=2.5)
    rng = np.random.default_rng(7 + 3 * nfn + gauss)
    n = coords0.shape[0]
    # push the face down onto the foundation (about 0.02..0.04 penetration at the start)
    u_old = np.tile([0.0, -0.08], (n, 1)) + 0.002 * rng.standard_normal((n, 2))
    dv = {"open": 0.0, "stick": 1e-5, "slip": 3e-2}[case]
    du_n = {"open": 0.0, "stick": -5e-4, "slip": -1e-3}[case]
    u_new = u_old + np.array([dv, du_n]) + 1e-4 * rng.standard_normal((n, 2))
    if case == "open":
        u_old = u_old + [0, 0.2]
        u_new = u_new + [0, 0.2]
    ctx = StepContext(nlgeom=nlgeom, foundation_old={"F": np.array([0.001, 0.0])},
                      foundation_new={"F": np.array([0.002, -0.0005])})
    state = grp.init_state()
    if case != "open":
        # committed state: in contact with some friction already, consistent with the start position
        _, _, pr = grp._penetration(grp._face_x(u_old), ctx.foundation_old["F"], 0.0, nlgeom)
        state["p"] = law.kp * np.maximum(pr.d, 0.0)
        state["tau"] = -0.5 * law.phi * state["p"]
        state["status"][:] = STICK
    return grp, u_old, u_new, state, ctx


def _assemble(grp, K, ndof):
    A = np.zeros((ndof, ndof))
    for e in range(K.shape[0]):
        A[np.ix_(grp.dofs[e], grp.dofs[e])] += K[e]
    return A


def _assemble_f(grp, f, ndof):
    b = np.zeros(ndof)
    np.add.at(b, grp.dofs.ravel(), f.ravel())
    return b


def _fd_tangent(grp, u_new, u_old, state, ctx, h=1e-7):
    ndof = u_new.size
    Kfd = np.zeros((ndof, ndof))
    for j in range(ndof):
        up, um = u_new.copy().ravel(), u_new.copy().ravel()
        up[j] += h
        um[j] -= h
        fp = grp.compute(up.reshape(-1, 2), u_old, state, ctx, tangent=False).f
        fm = grp.compute(um.reshape(-1, 2), u_old, state, ctx, tangent=False).f
        Kfd[:, j] = (_assemble_f(grp, fp, ndof) - _assemble_f(grp, fm, ndof)) / (2 * h)
    return Kfd


CASES = ([c + (True,) for c in itertools.product((3, 2), (2, 3), (False, True), (0.0, 0.5, 1.0),
                                                 (1, 3), ("open", "stick", "slip"))]
         + [c + (False,) for c in itertools.product((3, 2), (2, 3), (False, True), (0.5,), (1, 3),
                                                    ("stick", "slip"))])


@pytest.mark.parametrize("nfn,gauss,ax,theta,substeps,case,nlgeom", CASES)
def test_tangent_matches_finite_differences(nfn, gauss, ax, theta, substeps, case, nlgeom):
    """NLGEOM: constitutive + geometric parts; small strain: the axes, Jacobian and radius are
    those of the reference face (still non-symmetric through the friction law)."""
    grp, u_old, u_new, state, ctx = _setup(nfn, gauss, ax, theta, substeps, case, nlgeom=nlgeom)
    res = grp.compute(u_new, u_old, state, ctx)
    assert res.failure is None
    want = {"open": OPEN, "stick": STICK, "slip": SLIP}[case]
    assert np.all(res.state["status"] == want), res.state["status"]
    K = _assemble(grp, res.K, u_new.size)
    Kfd = _fd_tangent(grp, u_new, u_old, state, ctx)
    if case == "open":
        assert np.all(res.f == 0) and np.all(K == 0) and np.all(Kfd == 0)
    else:
        scale = np.abs(Kfd).max()
        assert scale > 0
        assert np.abs(K - Kfd).max() <= 1e-6 * scale
        # the contact tangent is non-symmetric (paper section 6)
        assert np.abs(K - K.T).max() > 1e-3 * scale


@pytest.mark.parametrize("form,hphi", (("d", 0.0), ("pold", 0.0), ("d", 2.0), ("d", -0.4)))
@pytest.mark.parametrize("nfn", (2, 3))
def test_tangent_substeps_chain_state_dependences(form, hphi, nfn):
    """Sub-interval chaining through tau_d (explicit d), tau_p (old pressure) and the
    hardening terms tau_lam, lam_* (lam of one sub-interval feeds the next)."""
    grp, u_old, u_new, state, ctx = _setup(nfn, 3, True, 0.5, 4, "slip", form=form, hphi=hphi)
    res = grp.compute(u_new, u_old, state, ctx)
    assert np.all(res.state["status"] == SLIP)
    K = _assemble(grp, res.K, u_new.size)
    Kfd = _fd_tangent(grp, u_new, u_old, state, ctx)
    assert np.abs(K - Kfd).max() <= 1e-6 * np.abs(Kfd).max()


def test_outward_normal_for_counter_clockwise_faces():
    """e_u = (y_xi, -x_xi)/|J| points out of the element on every face of CCW Q8 and Q4."""
    q8 = np.array([[0, 0], [2, 0], [2, 1], [0, 1], [1, 0], [2, .5], [1, 1], [0, .5]], float)
    for coords, faces in ((q8, Quad8.faces), (q8[:4], Quad4.faces)):
        fn = np.array(faces)
        grp = ContactGroup("c", fn, [1] * 4, [1, 2, 3, 4], coords, FOUND, "F", StandInCoulomb(), gauss=2)
        P, t = grp._at_points(grp._face_x(np.zeros_like(coords)))
        e_u = np.stack([t[:, 1], -t[:, 0]], axis=1) / np.linalg.norm(t, axis=1)[:, None]
        out = np.einsum("gi,gi->g", e_u, P - coords[:4].mean(axis=0))
        assert np.all(out > 0.4)


def _flat_punch(nfn, ax, dy, slide=0.0, B=0.0, phi=0.3):
    """Straight face y = 0 on x in [x0, x0+2] pressed by dy into the flat foundation y = 0."""
    x0 = 1.0 if ax else -1.0
    coords0 = np.array([[x0, 0.0], [x0 + 2, 0.0], [x0 + 1, 0.0]])[:nfn]
    found = Foundation([[-10.0, 0.0], [0.0, 0.0], [10.0, 0.0]])
    law = StandInCoulomb(B=B, PHI=phi)
    grp = ContactGroup("c", np.arange(nfn)[None], [1], [1], coords0, found, "F", law,
                       gauss=3, axisymmetric=ax, thickness=2.0)
    u_new = np.tile([slide, -dy], (nfn, 1))
    ctx = StepContext(nlgeom=True, foundation_old={"F": np.zeros(2)}, foundation_new={"F": np.zeros(2)})
    return grp, u_new, ctx, law, x0


@pytest.mark.parametrize("nfn", (2, 3))
@pytest.mark.parametrize("ax", (False, True))
def test_flat_punch_pressure_and_forces(nfn, ax):
    """Uniform penetration d: p = KP d; total normal force = p * area, pointing down (internal
    side: +p e_u with e_u = -y); consistent nodal loads 1/6, 1/6, 2/3 (3 nodes) or 1/2, 1/2."""
    dy = 0.01
    grp, u_new, ctx, law, x0 = _flat_punch(nfn, ax, dy)
    res = grp.compute(u_new, np.zeros_like(u_new), grp.init_state(), ctx)
    p = law.kp * dy
    assert np.allclose(res.state["p"], p)
    fy = res.f[0, 1::2]
    fx = res.f[0, 0::2]
    assert np.allclose(fx, 0.0, atol=1e-12)
    if ax:
        total = -p * ((x0 + 2) ** 2 - x0 ** 2) / 2          # per radian: int p r dr
    else:
        total = -p * 2.0 * 2.0                               # length 2, thickness 2
    assert fy.sum() == pytest.approx(total, rel=1e-12)
    if not ax:
        share = [1 / 6, 1 / 6, 2 / 3] if nfn == 3 else [0.5, 0.5]
        assert np.allclose(fy, np.array(share) * total, rtol=1e-12)
    pts = grp.points(u_new, res.state, ctx)
    assert pts.P == pytest.approx(-total, rel=1e-12)
    assert pts.A == pytest.approx(-total / p, rel=1e-12)
    assert np.allclose(pts.F, [0.0, -total], rtol=1e-12, atol=1e-12)
    assert np.allclose(pts.gap, -dy)                     # COPEN: minus the penetration
    assert np.allclose(pts.x[:, 1], -dy)


@pytest.mark.parametrize("nfn", (2, 3))
@pytest.mark.parametrize("ax", (False, True))
@pytest.mark.parametrize("nlgeom", (False, True))
def test_stretched_punch_current_or_reference_face(nfn, ax, nlgeom):
    """A face pressed by d and stretched by 10 % about x = 0: p = KP d either way; the normal
    force is integrated on the stretched face with NLGEOM, on the reference face otherwise."""
    dy, eps = 0.01, 0.1
    grp, u_new, ctx, law, x0 = _flat_punch(nfn, ax, dy)
    ctx.nlgeom = nlgeom
    u_new = u_new + np.stack([eps * grp.coords0[:, 0], 0 * grp.coords0[:, 0]], axis=1)
    res = grp.compute(u_new, np.zeros_like(u_new), grp.init_state(), ctx)
    p = law.kp * dy
    assert np.allclose(res.state["p"], p, rtol=1e-12)
    k = 1 + eps if nlgeom else 1.0
    if ax:
        total = p * k * k * ((x0 + 2) ** 2 - x0 ** 2) / 2           # int p r dr on [k x0, k (x0+2)]
    else:
        total = p * k * 2.0 * 2.0
    assert res.f[0, 1::2].sum() == pytest.approx(-total, rel=1e-12)
    pts = grp.points(u_new, res.state, ctx)
    assert pts.P == pytest.approx(total, rel=1e-12) and pts.F[1] == pytest.approx(total, rel=1e-12)


def test_sliding_friction_force_opposes_motion():
    """Sliding by +x along the face direction (e_v = -x): dv < 0, tau = -phi p; the force the
    foundation applies on the body is -f (f is on the internal side): it points up (-Fy > 0) and
    against the motion (-Fx < 0), with |Fx| = phi |Fy| (Coulomb)."""
    grp, u_new, ctx, law, _ = _flat_punch(3, False, 0.01, slide=0.05)
    res = grp.compute(u_new, np.zeros_like(u_new), grp.init_state(), ctx)
    assert np.all(res.state["status"] == SLIP)
    assert np.allclose(res.state["tau"], -law.phi * law.kp * 0.01, rtol=1e-12)
    Fx, Fy = res.f[0, 0::2].sum(), res.f[0, 1::2].sum()
    assert Fx == pytest.approx(-law.phi * Fy, rel=1e-12)
    assert -Fx < 0 and -Fy > 0


def test_moving_foundation_relative_slip():
    """Moving the foundation with the body gives dv = 0 (no friction); moving the foundation
    alone by -x is the same relative slip as moving the body by +x."""
    grp, u_new, ctx, law, _ = _flat_punch(3, False, 0.01, slide=0.0)
    ctx_move = StepContext(nlgeom=True, foundation_old={"F": np.zeros(2)}, foundation_new={"F": np.array([-2e-3, 0.0])})
    res_f = grp.compute(u_new, np.zeros_like(u_new), grp.init_state(), ctx_move)
    u_body = u_new + [2e-3, 0.0]
    res_b = grp.compute(u_body, np.zeros_like(u_new), grp.init_state(), ctx)
    assert np.allclose(res_f.state["tau"], res_b.state["tau"], rtol=1e-12)
    assert np.all(res_f.state["tau"] < 0)
    ctx_both = StepContext(nlgeom=True, foundation_old={"F": np.zeros(2)}, foundation_new={"F": np.array([2e-3, 0.0])})
    res_0 = grp.compute(u_body, np.zeros_like(u_new), grp.init_state(), ctx_both)
    assert np.allclose(res_0.state["tau"], 0.0, atol=1e-9)


def test_rigid_rotation_of_the_tangent_axes():
    """A pressed face rotated rigidly about a point of the flat foundation keeps e_u = outward
    normal: forces stay normal to the rotated face (frictionless, phi = 0)."""
    grp, u_new, ctx, law, _ = _flat_punch(3, False, 0.01, phi=0.0)
    a = 0.05
    Rm = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    x = (grp.coords0 + u_new) @ Rm.T
    res = grp.compute(x - grp.coords0, np.zeros_like(u_new), grp.init_state(), ctx)
    F = res.f[0].reshape(-1, 2).sum(axis=0)
    n_out = Rm @ np.array([0.0, -1.0])
    assert abs(F @ np.array([-n_out[1], n_out[0]])) < 1e-12 * np.linalg.norm(F)
    assert F @ n_out > 0


def test_frozen_status_is_honoured():
    """ctx.freeze_contact: frozen open points give no force; stick/slip are passed to the law."""
    grp, u_old, u_new, state, ctx = _setup(3, 3, False, 1.0, 1, "slip")
    frozen = np.full(grp.ng, -1, np.int8)
    frozen[:3] = OPEN
    frozen[3:] = STICK
    ctx.freeze_contact = {"S->F": frozen}
    res = grp.compute(u_new, u_old, state, ctx)
    assert np.all(res.state["p"][:3] == 0) and np.all(res.state["status"][:3] == OPEN)
    assert np.all(res.state["status"][3:] == STICK)
    assert np.array_equal(grp.law.calls[-1], frozen)
    assert np.all(res.f[0] == 0)                        # face 0 has only frozen-open points
    K = _assemble(grp, res.K, u_new.size)
    Kfd = _fd_tangent(grp, u_new, u_old, state, ctx)
    assert np.abs(K - Kfd).max() <= 1e-6 * np.abs(Kfd).max()


def test_dofs_and_state_layout():
    grp, u_old, u_new, state, ctx = _setup(3, 2, False, 1.0, 1, "stick")
    assert grp.dofs.tolist() == [[0, 1, 2, 3, 6, 7], [2, 3, 4, 5, 8, 9]]
    assert grp.init_state()["p"].shape == (4,)
    pts = grp.points(u_new, state, ctx)
    assert pts.element.tolist() == [11, 11, 12, 12] and pts.gauss.tolist() == [1, 2, 1, 2]


# ---------------------------------------------------------------- with the real COULOMB law
COULOMB_CASES = list(itertools.product((3, 2), (2, 3), (False, True), (0.0, 0.5, 1.0), (1, 3),
                                       ("stick", "slip")))


def _coulomb(theta, substeps, **kw):
    from lagamine_py.laws.coulomb import Coulomb
    return Coulomb(KP=1e3, KT=5e2, PHI=0.3, B=0.5, THETA=theta, SUBSTEPS=substeps, **kw)


def _check_fd(grp, u_old, u_new, state, ctx, want):
    res = grp.compute(u_new, u_old, state, ctx)
    assert res.failure is None
    assert np.all(res.state["status"] == want), res.state["status"]
    K = _assemble(grp, res.K, u_new.size)
    Kfd = _fd_tangent(grp, u_new, u_old, state, ctx)
    assert np.abs(K - Kfd).max() <= 1e-6 * np.abs(Kfd).max()


@pytest.mark.parametrize("nfn,gauss,ax,theta,substeps,case", COULOMB_CASES)
def test_tangent_with_coulomb_law(nfn, gauss, ax, theta, substeps, case):
    law = _coulomb(theta, substeps)
    args = _setup(nfn, gauss, ax, theta, substeps, case, law=law)
    _check_fd(*args, want={"stick": STICK, "slip": SLIP}[case])


@pytest.mark.parametrize("hphi,hb", ((2.0, 5.0), (-0.4, -20.0)))
@pytest.mark.parametrize("case", ("stick", "slip"))
def test_tangent_with_coulomb_hardening_one_substep(hphi, hb, case):
    law = _coulomb(0.5, 1, HPHI=hphi, HB=hb)
    args = _setup(3, 3, True, 0.5, 1, case, law=law)
    _check_fd(*args, want={"stick": STICK, "slip": SLIP}[case])


@pytest.mark.parametrize("hphi,hb", ((2.0, 5.0), (-0.4, -20.0)))
def test_tangent_with_coulomb_hardening_substeps(hphi, hb):
    """With hardening lam of one sub-interval feeds the next (tau_lam, lam_* chained)."""
    law = _coulomb(0.5, 3, HPHI=hphi, HB=hb)
    args = _setup(3, 3, True, 0.5, 3, "slip", law=law)
    _check_fd(*args, want=SLIP)


@pytest.mark.parametrize("substeps", (1, 3))
@pytest.mark.parametrize("slide,want", ((0.004, STICK), (0.3, SLIP)))
def test_tangent_with_coulomb_touch_down(substeps, slide, want):
    """Open at the start of the increment, in contact at its end (re-contact part-way through
    a sub-interval: the law's d/du fraction enters the tangent)."""
    law = _coulomb(0.5, substeps)
    grp, u_old, u_new, _, ctx = _setup(3, 3, False, 0.5, substeps, "open", law=law)
    u_new = u_new + [slide, -0.205]
    _check_fd(grp, u_old, u_new, grp.init_state(), ctx, want)
