"""The fast paths of the contact computation against their references.

* The numba kernels (``lagamine_py.kernels.contact``, optional ``fast`` extra) of the foundation
  projection and of the whole contact group (fused) with the COULOMB law against the NumPy
  code, the reference: every state field and tangent entry, every
  projection field, and the contact group's forces, tangent, state and failure messages, over
  batches that visit every branch (open, touching, re-contact, partial re-contact, separation,
  stick, slip, reversal, softening kinks, the flip-flop holds, the CLASSICAL indicator, end
  half-lines, misses).
* The NumPy shortcut for sub-intervals where nothing re-contacts or separates
  (``Coulomb._tangent_simple``) against the general tangent on the same points.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.elements.contact import ContactGroup
from lagamine_py.foundation import Foundation
from lagamine_py.core.errors import ReturnMappingError
from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.laws.coulomb import Coulomb

PARAMS = {
    "plain": dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0),
    "no_adhesion": dict(KP=1.68e6, KT=1.68e6, PHI=0.2),
    "softening_kinks": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=-0.5),
    "hardening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=30.0, HPHI=0.7),
    "classical": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=0.2,
                      INDICATOR="CLASSICAL"),
}
FOUNDATIONS = {
    "parabola": [[-1.0, 1.0], [0.0, 0.0], [1.0, 1.0]],
    "wavy": [[-2.0, 0.0], [-1.0, 0.3], [0.0, 0.1], [1.0, -0.2], [2.0, 0.05], [3.0, 0.1],
             [4.0, -0.1]],
    "u_shape": [[-2, 2], [-2, 1], [-2, 0], [0, 0], [2, 0], [2, 1], [2, 2]],
    "flat": [[-1, 0], [0, 0], [1, 0]],
}


def _kernels():
    pytest.importorskip("numba")
    from lagamine_py import kernels
    return kernels.module("contact")


def _batch(par, rng, g=3000, simple=False):
    """Committed states and sub-interval increments around the cone (every branch)."""
    st = {"p": np.where(rng.random(g) < 0.3, 0.0, 20 * rng.random(g)),
          "lam": np.where(rng.random(g) < 0.3, 0.0, 0.2 * rng.random(g)),
          "slip": rng.random(g), "vp": rng.standard_normal(g), "dissip": rng.random(g),
          "status": rng.integers(0, 3, g).astype(np.int8)}
    radius = par.get("B", 0.0) + par["PHI"] * st["p"]
    on_cone = rng.random(g) < 0.4
    st["tau"] = np.where(on_cone, radius * np.sign(rng.standard_normal(g)),
                         radius * (2 * rng.random(g) - 1))
    st["tau"][rng.random(g) < 0.1] = 0.0
    d = 0.02 * rng.standard_normal(g)
    du = 0.02 * rng.standard_normal(g)
    dv = 0.02 * rng.standard_normal(g) * 10 ** rng.uniform(-4, 1, g)
    for x in (d, du, dv):
        x[rng.random(g) < 0.1] = 0.0
    if simple:                       # nothing re-contacts or separates
        st["status"] = np.where(d >= 0, rng.integers(1, 3, g), OPEN).astype(np.int8)
        st["p"] = np.where(d < 0, 0.0, st["p"])
    return st, d, du, dv


def _close(a, b, rtol=1e-12, what=""):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, what
    if a.dtype.kind != "f":
        np.testing.assert_array_equal(a, b, err_msg=what)
        return
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=what)
    np.testing.assert_array_equal(a[np.isinf(a)], b[np.isinf(a)], err_msg=what)
    ok = np.isfinite(a)
    scale = max(float(np.abs(a[ok]).max(initial=0.0)), 1e-300)
    np.testing.assert_allclose(a[ok], b[ok], rtol=0, atol=rtol * scale, err_msg=what)


def test_coulomb_subclass_takes_numpy_path():
    class Mine(Coulomb):
        pass
    assert Mine(**PARAMS["plain"]).kernel_vector() is None
    assert Coulomb(**PARAMS["plain"]).kernel_vector() is not None


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_simple_tangent_equals_general_tangent(name):
    """No re-contact, no separation: the shortcut gives the general formulas' values."""
    par = PARAMS[name]
    law = Coulomb(**par)
    rng = np.random.default_rng(3)
    st, d, du, dv = _batch(par, rng, simple=True)
    seen = {}
    general = law._tangent

    def spy_simple(contact, plastic, dv_, skt, dmat, phi1):
        seen["args"] = (contact, plastic, dv_, skt, dmat, phi1)
        return Coulomb._tangent_simple(law, contact, plastic, dv_, skt, dmat, phi1)
    law._tangent_simple = spy_simple
    _, tan = law.update(st, d, du, dv)
    contact, plastic, dv_, skt, dmat, phi1 = seen["args"]
    none = np.zeros_like(contact)
    ref = general(contact, none, plastic, none, none, d, du, dv_, 1.0, skt, dmat, phi1, contact)
    assert set(tan) == set(ref)
    for key in ref:
        np.testing.assert_array_equal(tan[key], ref[key], err_msg=key)


@pytest.mark.parametrize("name", sorted(FOUNDATIONS))
def test_projection_kernel_equals_numpy(name):
    _kernels()
    fast = Foundation(FOUNDATIONS[name])
    ref = Foundation(FOUNDATIONS[name])
    ref.use_kernel = False
    rng = np.random.default_rng(len(name))
    g = 4000
    P = rng.uniform(-3.0, 4.0, (g, 2))
    angle = rng.uniform(0.0, 2 * np.pi, g)
    e = np.c_[np.cos(angle), np.sin(angle)]
    e[::5] = [0.0, -1.0]                       # straight down, as a flat contact face
    e[1::7] = [0.0, 1.0]
    for c in (None, np.array([0.05, -0.02])):
        a, b = fast.project(P, e, c), ref.project(P, e, c)
        for key in ("Q", "d", "arc", "s", "tangent", "normal", "found", "dd_dP", "dd_de"):
            _close(getattr(a, key), getattr(b, key), what=key)
        assert b.found.any() and not b.found.all()
        beyond = b.found & (np.abs(np.nan_to_num(b.s)) > 1)
        assert beyond.any()                   # end half-lines visited


def _group(rng, ax, nfn, gauss, law, found_pts, use_kernel):
    shift = np.array([2.0 if ax else 0.0, 0.0])
    if nfn == 3:
        coords0 = np.array([[-0.4, 0.05], [0.4, 0.02], [1.2, 0.0], [0.0, 0.06], [0.8, 0.03]])
        faces = np.array([[0, 1, 3], [1, 2, 4]])
    else:
        coords0 = np.array([[-0.4, 0.05], [0.4, 0.02], [1.2, 0.0]])
        faces = np.array([[0, 1], [1, 2]])
    found = Foundation(np.asarray(found_pts) + shift)
    grp = ContactGroup("S->F", faces, [11, 12], [1, 1], coords0 + shift, found, "F", law,
                       gauss=gauss, axisymmetric=ax, thickness=2.5)
    grp.use_kernels(use_kernel)
    return grp


@pytest.mark.parametrize("nfn,gauss,ax,nlgeom,substeps,theta,case,hold", [
    (3, 3, False, True, 1, 1.0, "slip", False),
    (3, 2, True, True, 3, 0.5, "slip", True),
    (2, 2, False, False, 1, 1.0, "stick", False),
    (3, 3, True, True, "AUTO", 0.0, "separate", False),
    (2, 3, False, True, 3, 1.0, "separate", True),
])
def test_contact_group_kernel_equals_numpy(nfn, gauss, ax, nlgeom, substeps, theta, case, hold):
    _kernels()
    found_pts = [[-3.0, 0.1], [-1.0, 0.0], [0.5, 0.02], [1.5, -0.03], [3.0, -0.1]]
    par = dict(PARAMS["hardening"], THETA=theta, SUBSTEPS=substeps)
    rng = np.random.default_rng(11)
    fast = _group(rng, ax, nfn, gauss, Coulomb(**par), found_pts, True)
    ref = _group(rng, ax, nfn, gauss, Coulomb(**par), found_pts, False)
    n = fast.coords0.shape[0]
    u_old = np.tile([0.0, -0.08], (n, 1)) + 0.002 * rng.standard_normal((n, 2))
    step = {"slip": [3e-2, -1e-3], "stick": [1e-5, -5e-4], "separate": [1e-2, 0.09]}[case]
    u_new = u_old + step + 1e-4 * rng.standard_normal((n, 2))
    kw = dict(nlgeom=nlgeom, foundation_old={"F": np.array([0.001, 0.0])},
              foundation_new={"F": np.array([0.002, -0.0005])})
    if hold:
        kw["freeze_contact"] = {"S->F": rng.integers(-1, 3, fast.ng)}
    ctx = StepContext(**kw)
    state = ref.init_state()
    _, _, pr = ref._penetration(ref._face_x(u_old), kw["foundation_old"]["F"], 0.0, nlgeom)
    state["p"] = ref.law.kp * np.maximum(pr.d, 0.0)
    state["tau"] = -0.5 * ref.law.phi * state["p"]
    state["status"][:] = np.where(pr.d >= 0, STICK, OPEN)
    a = fast.compute(u_new, u_old, state, ctx, True)
    b = ref.compute(u_new, u_old, state, ctx, True)
    assert a.failure == b.failure
    _close(a.f, b.f, what="f")
    _close(a.K, b.K, what="K")
    for key in b.state:
        _close(a.state[key], b.state[key], what=key)


def test_problem_kernel_setting_reaches_contact_groups():
    """KERNEL=NUMPY forces the NumPy law and projection in contact groups, NUMBA selects their
    kernels, AUTO follows the solid kernel's size rule (press_slide is below it: NumPy)."""
    from pathlib import Path

    from lagamine_py.deck import load_deck
    from lagamine_py.kernels import AUTO_NUMBA_ELEMENTS
    from lagamine_py.solver.problem import build_problem
    _kernels()
    deck = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"
    problem = build_problem(load_deck(deck))
    contact = [g for g, kind in zip(problem.groups, problem.kinds) if kind == "contact"]
    assert contact and problem.solid_elements() < AUTO_NUMBA_ELEMENTS

    def on():
        flags = {(g._kernel, g.foundation.use_kernel) for g in contact}
        assert len(flags) == 1 and len(set(next(iter(flags)))) == 1
        return next(iter(flags))[0]
    problem.set_kernel("NUMBA")
    assert on()
    problem.set_kernel("NUMPY")
    assert not on()
    problem.set_kernel("AUTO")
    assert not on()


@pytest.mark.parametrize("indicator,frozen", [("CLASSICAL", None), ("CLASSICAL", STICK),
                                              ("PREDICTOR", None)])
def test_contact_group_kernel_reports_the_same_failures(indicator, frozen):
    """Softening adhesion, sliding on the cone: CLASSICAL leaves the cone (an increment
    failure) unless the solver holds the points STICK; PREDICTOR does not (test_stability's
    case), through the fused kernel as through NumPy."""
    _kernels()
    from test_contact_element import _setup
    out = []
    for use in (True, False):
        law = Coulomb(KP=1e3, KT=5e2, PHI=0.3, B=0.5, HB=-20.0, INDICATOR=indicator)
        grp, u_old, u_new, state, ctx = _setup(3, 3, False, 1.0, 1, "slip", law=law)
        grp.use_kernels(use)
        state["tau"] = -(law.b + law.phi * state["p"])
        if frozen is not None:
            ctx.freeze_contact = {grp.name: np.full(grp.ng, frozen)}
        out.append(grp.compute(u_new - [0.02, 0.0], u_old, state, ctx))
    assert out[0].failure == out[1].failure
    assert (out[1].failure is not None) == (indicator == "CLASSICAL" and frozen is None)
    _close(out[0].f, out[1].f, what="f")
    _close(out[0].K, out[1].K, what="K")
