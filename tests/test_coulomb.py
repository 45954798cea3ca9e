"""COULOMB contact law (paper sections 2-5) and the single-point driver.

Independent references: closed forms of press-then-slide paths (paper eq. 11), a separate
fine-step explicit integration of the rate equations (2) and (10) written below, central finite
differences of the tangent, and exact invariants (batching, energy of constant-pressure slip).
"""
import functools
import math

import numpy as np
import pytest

from lagamine_py.core.errors import ReturnMappingError
from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.laws.contact_point import drive_contact_point as drive
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.registry import REGISTRY, ParamError

BASE = dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0)


# --------------------------------------------------------------------------------------------
# Independent reference: explicit forward Euler of the rate equations, scalar Python floats.
# --------------------------------------------------------------------------------------------
def _clip(v0, slope, lam):
    raw = v0 + slope * lam
    if raw > 0.0:
        return raw, slope
    return 0.0, (slope if slope > 0.0 else 0.0)


def reference(par, u_path, v_path, nstep):
    """Euler steps of eq. (2) / (10), ``nstep`` per path interval; loading by the predictor
    indicator on the surface, an elastic step that crosses the surface is split at the crossing.

    Returns arrays (N+1,) of p, tau, lam, dissip at the path points.
    """
    KP, KT, PHI, B = par["KP"], par["KT"], par["PHI"], par.get("B", 0.0)
    HPHI, HB = par.get("HPHI", 0.0), par.get("HB", 0.0)
    p, tau, lam, dis = KP * max(u_path[0], 0.0), 0.0, 0.0, 0.0
    rows = [(p, tau, lam, dis)]

    def plastic(p, tau, lam, dis, du, dv):
        b, hb = _clip(B, HB, lam)
        ph, hph = _clip(PHI, HPHI, lam)
        h = hb + hph * p
        sg = math.copysign(1.0, tau) if tau != 0.0 else math.copysign(1.0, dv)
        dlam = (sg * KT * dv - ph * KP * du) / (h + KT)
        dtau = (ph * KP * KT * sg * du + h * KT * dv) / (h + KT)
        dis += 0.5 * (abs(tau) + abs(tau + dtau)) * dlam
        return p + KP * du, tau + dtau, lam + dlam, dis

    for i in range(len(u_path) - 1):
        du = (u_path[i + 1] - u_path[i]) / nstep
        dv = (v_path[i + 1] - v_path[i]) / nstep
        for k in range(nstep):
            ue = u_path[i] + (k + 1) * du
            if ue <= 0.0:
                p = tau = 0.0
                continue
            duc, dvc = du, dv
            if p <= 0.0:                      # re-contact: only the part after touching
                a = ue / du if ue - du <= 0.0 else 1.0
                p, tau, duc, dvc = 0.0, 0.0, ue, dv * a
            b, _ = _clip(B, HB, lam)
            ph, _ = _clip(PHI, HPHI, lam)
            f = abs(tau) - b - ph * p
            sg = math.copysign(1.0, tau) if tau != 0.0 else math.copysign(1.0, dvc)
            on = p > 0.0 and f >= -1e-9 * (b + ph * p)
            if on and sg * KT * dvc - ph * KP * duc > 0.0:
                p, tau, lam, dis = plastic(p, tau, lam, dis, duc, dvc)
                continue
            te, pe = tau + KT * dvc, p + KP * duc
            se = math.copysign(1.0, te)
            if abs(te) - b - ph * pe > 1e-9 * (b + ph * pe):  # elastic to the crossing, plastic
                a = (b + ph * p - se * tau) / (se * KT * dvc - ph * KP * duc)
                a = min(max(a, 0.0), 1.0)
                p, tau = p + KP * duc * a, tau + KT * dvc * a
                p, tau, lam, dis = plastic(p, tau, lam, dis, duc * (1 - a), dvc * (1 - a))
            else:
                p, tau = pe, te
        rows.append((p, tau, lam, dis))
    return {k: np.array(c) for k, c in zip(("p", "tau", "lam", "dissip"), zip(*rows))}


# press, slide, press while sliding, unload the pressure while sliding back, separate, re-contact
U_PATH = np.array([0.0, 0.01, 0.01, 0.02, 0.015, 0.015, -0.005, 0.01, 0.01])
V_PATH = np.array([0.0, 0.0, 0.04, 0.08, 0.1, 0.05, 0.05, 0.06, 0.09])
HARDENING_CASES = {
    "hardening": dict(BASE, HPHI=5.0, HB=20.0),
    "softening_B_to_zero": dict(BASE, HB=-30.0),          # B reaches 0 at lam = 1/30
    "phi_softening_B_hardening": dict(BASE, HPHI=-3.0, HB=10.0),  # phi reaches 0 at 0.1
}


@functools.lru_cache(maxsize=None)
def _ref_path(case, nstep):
    """The reference along (U_PATH, V_PATH) for one of HARDENING_CASES (cached: reused)."""
    return reference(HARDENING_CASES[case], U_PATH, V_PATH, nstep)


def _rel_err(res, ref, keys=("tau", "lam", "dissip")):
    return max(np.max(np.abs(res[k] - ref[k])) / np.max(np.abs(ref[k])) for k in keys)


# --------------------------------------------------------------------------------------------
def test_registered_and_parameters_validated():
    assert REGISTRY.get("contact_laws", "COULOMB") is Coulomb
    law = Coulomb(KP="1e3", KT="500", PHI="0.3")
    assert (law.b, law.hb, law.hphi, law.theta, law.substeps, law.indicator) == \
        (0.0, 0.0, 0.0, 1.0, 1, "PREDICTOR")
    with pytest.raises(ParamError, match="missing required parameter KP"):
        Coulomb(KT=1.0, PHI=0.1)
    with pytest.raises(ParamError, match="KT must be > 0"):
        Coulomb(KP=1.0, KT=0.0, PHI=0.1)
    with pytest.raises(ParamError, match="KT \\+ HB must be > 0"):
        Coulomb(KP=1.0, KT=10.0, PHI=0.1, HB=-10.0)
    with pytest.raises(ParamError, match="INDICATOR must be one of"):
        Coulomb(KP=1.0, KT=1.0, PHI=0.1, INDICATOR="ACTUAL")
    assert Coulomb(KP=1.0, KT=1.0, PHI=0.1, SUBSTEPS="auto").substeps == "AUTO"
    with pytest.raises(ParamError, match="SUBTOL"):          # AUTO: tests/test_substeps_auto.py
        Coulomb(KP=1.0, KT=1.0, PHI=0.1, SUBSTEPS="auto", SUBTOL=0.0)


def test_flat_punch_penetration_is_p_over_kp():
    law = Coulomb(KP=3.7e4, KT=1e3, PHI=0.2)
    d = np.array([1e-3, 0.02, 0.5])
    state, tan = law.update(law.init_state(3), d, d, np.zeros(3))
    np.testing.assert_allclose(state["p"] / law.kp, d, rtol=1e-12, atol=1e-8)
    assert np.all(state["status"] == STICK) and np.all(tan["p_u"] == law.kp)


@pytest.mark.parametrize("n_inc", [1, 2, 7])
def test_constant_phi_b_is_exact_closed_form_for_any_increment(n_inc):
    """Press to u1 while sliding to v1 in the first increment, then slide at constant p.

    Closed forms (eq. 11): p = KP u1, |tau| = min(KT v, B + phi p), slip = v - |tau|/KT.  In
    the first increment tau = KT v1 s, p = KP u1 s: yield at s* = B/(KT v1 - phi KP u1), then
    dlam/ds = (KT v1 - phi KP u1)/KT and D1 = int_{s*}^1 (B + phi KP u1 s) dlam; afterwards
    D grows by (B + phi p) dslip.
    """
    law = Coulomb(**BASE)
    kp, kt, phi, b, u1, v1 = 1000.0, 500.0, 0.3, 1.0, 0.01, 0.05 / n_inc
    u = np.r_[0.0, np.full(n_inc, u1)]
    v = np.r_[0.0, v1 * np.arange(1, n_inc + 1)]
    res = drive(law, u, v)
    p = kp * u1
    np.testing.assert_allclose(res["p"][1:], p, rtol=1e-14)
    tau_cf = np.minimum(kt * v, b + phi * p)
    np.testing.assert_allclose(res["tau"], tau_cf, rtol=1e-12, atol=1e-12)
    slip_cf = v - tau_cf / kt
    np.testing.assert_allclose(res["slip"], slip_cf, rtol=1e-12, atol=1e-14)
    rate = (kt * v1 - phi * kp * u1) / kt
    s0 = min(b / (kt * v1 - phi * kp * u1), 1.0)
    d1 = rate * (b * (1 - s0) + 0.5 * phi * kp * u1 * (1 - s0 ** 2))
    dis_cf = np.where(res["slip"] > 0, d1 + (b + phi * p) * (slip_cf - slip_cf[1]), 0.0)
    np.testing.assert_allclose(res["dissip"], dis_cf, rtol=1e-12, atol=1e-14)
    assert res["status"][-1] == SLIP


def test_eq11_press_while_sliding_in_one_big_increment():
    """On the cone with phi, B constant: dtau = phi KP sgn du, independent of dv (eq. 11)."""
    law = Coulomb(**BASE)
    u = np.array([0.0, 0.01, 0.01, 0.05, 0.03])
    v = np.array([0.0, 0.0, 0.05, 0.5, 0.9])
    res = drive(law, u, v)
    np.testing.assert_allclose(res["tau"][2:], 1.0 + 0.3 * 1000.0 * u[2:], rtol=1e-13)


def test_frictionless_slides_freely():
    law = Coulomb(KP=100.0, KT=100.0, PHI=0.0)
    res = drive(law, [0.0, 0.1, 0.1, 0.1], [0.0, 0.0, 0.3, -0.2])
    np.testing.assert_allclose(res["tau"], 0.0, atol=1e-15)
    np.testing.assert_allclose(res["slip"], [0.0, 0.0, 0.3, 0.8], rtol=1e-14)
    np.testing.assert_allclose(res["dissip"], 0.0, atol=1e-15)


@pytest.mark.parametrize("case", sorted(HARDENING_CASES))
def test_hardening_softening_match_fine_rate_integration(case):
    """Coarse increments (every SUBSTEPS count) against a separate explicit integration of (10).

    The law integrates each sub-interval exactly, so its error against the Euler reference is
    the reference's own O(1/n) error: it falls 10x when the reference is refined 10x, and it is
    the same for every SUBSTEPS count.
    """
    par = HARDENING_CASES[case]
    law = Coulomb(**par)
    ref_coarse = _ref_path(case, 2000)
    ref_fine = _ref_path(case, 20000)
    errs = {}
    for n in (1, 2, 4, 8):
        res = drive(law, U_PATH, V_PATH, substeps=n)
        errs[n] = (_rel_err(res, ref_coarse), _rel_err(res, ref_fine))
        np.testing.assert_allclose(res["p"], ref_fine["p"], rtol=1e-9, atol=1e-9)
    print(case, {n: f"{a:.2e}/{b:.2e}" for n, (a, b) in errs.items()})
    for n, (e_coarse, e_fine) in errs.items():
        assert e_fine < 2e-4, (n, e_fine)
        assert 5.0 < e_coarse / e_fine < 20.0, (n, e_coarse, e_fine)   # first-order reference
    res1 = drive(law, U_PATH, V_PATH, substeps=1)
    res8 = drive(law, U_PATH, V_PATH, substeps=8)
    for k in ("tau", "lam", "dissip"):
        np.testing.assert_allclose(res1[k], res8[k], rtol=1e-10, atol=1e-13)


def test_classical_indicator_fails_on_softening_predictor_does_not():
    """Softening (HB < 0), press then keep sliding forward."""
    par = dict(KP=1000.0, KT=500.0, PHI=0.2, B=2.0, HB=-100.0)
    u = np.r_[0.0, np.full(20, 0.01)]
    v = np.r_[0.0, np.linspace(0.0, 0.1, 20)]
    ref = reference(par, u, v, 5000)
    good = drive(Coulomb(**par), u, v)
    bad = drive(Coulomb(**par, INDICATOR="CLASSICAL"), u, v)

    def excess(res):  # f = |tau| - B(lam) - phi p, > 0 is outside the yield surface
        return np.abs(res["tau"]) - np.maximum(2.0 - 100.0 * res["lam"], 0.0) - 0.2 * res["p"]

    assert np.max(np.abs(good["tau"] - ref["tau"])) < 1e-3 * np.max(ref["tau"])
    assert np.max(excess(good)) < 1e-12
    assert np.max(excess(bad)) > 10.0                     # elastic "unloading" off the cone
    assert np.max(np.abs(bad["tau"] - ref["tau"])) > 10.0
    # the classical indicator judged the first on-surface increment as unloading
    first_slip = np.argmax(good["status"] == SLIP)
    assert bad["status"][first_slip + 1] == STICK and good["status"][first_slip + 1] == SLIP


def test_classical_indicator_cannot_unload_without_hardening():
    """H = 0: the classical indicator is 0, never negative, so a reversal is not seen as an
    unloading and tau is dragged along the surface; the predictor unloads with slope KT."""
    u, v = [0.0, 0.01, 0.01, 0.01], [0.0, 0.0, 0.05, 0.049]
    good = drive(Coulomb(**BASE), u, v)
    bad = drive(Coulomb(**BASE, INDICATOR="CLASSICAL"), u, v)
    np.testing.assert_allclose(good["tau"][2:], [4.0, 3.5], rtol=1e-13)
    np.testing.assert_allclose(bad["tau"][2:], [4.0, 4.0], rtol=1e-13)


@pytest.mark.parametrize("case", ["perfect", "softening_B_to_zero", "hardening"])
def test_unloading_from_slip_is_elastic_with_slope_kt(case):
    par = dict(BASE) if case == "perfect" else HARDENING_CASES[case]
    law = Coulomb(**par)
    u = np.full(5, 0.01)
    u[0] = 0.0
    v = np.array([0.0, 0.0, 0.05, 0.049, 0.045])
    res = drive(law, u, v)
    assert res["status"][2] == SLIP and np.all(res["status"][3:] == STICK)
    np.testing.assert_allclose(np.diff(res["tau"][2:]), 500.0 * np.diff(v[2:]), rtol=1e-12)
    np.testing.assert_allclose(res["lam"][3:], res["lam"][2], rtol=0, atol=0)


def test_recontact_after_separation_starts_elastic_from_zero():
    law = Coulomb(**BASE)
    # slip, separate, stay open (history kept), re-contact halfway through a sliding increment
    u = np.array([0.0, 0.01, 0.01, -0.004, -0.002, 0.004])
    v = np.array([0.0, 0.0, 0.05, 0.05, 0.06, 0.062])
    res = drive(law, u, v)
    assert np.all(res["status"][3:5] == OPEN) and np.all(res["p"][3:5] == 0)
    assert np.all(res["tau"][3:5] == 0)
    # while p falls to 0 at fixed v, the cone shrinks from 4 to B = 1: slip (4 - 1)/KT first
    np.testing.assert_allclose(res["lam"][3:5], res["lam"][2] + 3.0 / 500.0, rtol=1e-14)
    assert res["status"][5] == STICK
    np.testing.assert_allclose(res["tau"][5], 500.0 * 0.002 * (2.0 / 3.0), rtol=1e-13)  # 2/3 of dv
    np.testing.assert_allclose(res["p"][5], 4.0, rtol=1e-13)


def test_dissipation_equals_integral_of_tau_dvp():
    # constant p, phi, B: D = (B + phi p) * slip, with slip back and forth
    law = Coulomb(**BASE)
    res = drive(law, [0.0, 0.01, 0.01, 0.01], [0.0, 0.0, 0.08, -0.03])
    np.testing.assert_allclose(res["dissip"], 4.0 * res["slip"], rtol=1e-13)
    # hardening with varying p: against the reference's trapezoid sum of |tau| dlam
    for case, par in HARDENING_CASES.items():
        ref = _ref_path(case, 20000)
        res = drive(Coulomb(**par), U_PATH, V_PATH, substeps=1)
        np.testing.assert_allclose(res["dissip"], ref["dissip"], rtol=2e-4, atol=1e-12)
    # energy: with p constant and no separation, int tau dv = D + tau^2 / (2 KT)
    par = HARDENING_CASES["hardening"]
    v = np.linspace(0.0, 0.05, 2001)   # tau is linear in v on each side of the yield point
    res = drive(Coulomb(**par), np.r_[0.0, np.full(v.size, 0.01)], np.r_[0.0, v])
    tau = res["tau"][1:]
    work = np.sum(0.5 * (tau[1:] + tau[:-1]) * np.diff(v))
    np.testing.assert_allclose(work, res["dissip"][-1] + tau[-1] ** 2 / 1000.0, rtol=1e-5)


def test_batched_points_equal_single_point_runs():
    law = Coulomb(**HARDENING_CASES["softening_B_to_zero"])
    us = np.stack([U_PATH, 0.5 * U_PATH, U_PATH + 0.003, np.full_like(U_PATH, -0.01)], axis=1)
    vs = np.stack([V_PATH, -V_PATH, 0.3 * V_PATH, V_PATH], axis=1)
    batch = drive(law, us, vs, substeps=3)
    for j in range(us.shape[1]):
        single = drive(law, us[:, j], vs[:, j], substeps=3)
        for k in ("p", "tau", "lam", "slip", "dissip", "status"):
            np.testing.assert_array_equal(batch[k][:, j], single[k])


# --------------------------------------------------------------------------------------------
# Tangent against central finite differences (batched over states away from kinks).
# --------------------------------------------------------------------------------------------
def _states():
    """(state, d, du, dv) for: stick, slip forward, slip with pressure change, reversal that
    re-yields on the other side, unloading, open, partial re-contact (elastic and yielding),
    a long slide (crosses the clipping kinks of the softening cases within the increment)."""
    p_old = np.array([10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 0.0, 0.0, 10.0])
    tau_old = np.array([1.0, 4.0, -4.0, 4.0, 4.0, 1.0, 0.0, 0.0, 4.0])
    d = np.array([0.011, 0.01, 0.012, 0.01, 0.01, -0.001, 0.0005, 0.0005, 0.0101])
    du = np.array([0.001, 0.0, 0.002, 0.0, 0.0, -0.011, 0.001, 0.001, 0.0001])
    dv = np.array([0.001, 0.01, -0.02, -0.03, -0.002, 0.01, 0.001, 0.02, 0.08])
    return p_old, tau_old, d, du, dv


def _make_state(law, p_old, tau_old, lam_old):
    st = law.init_state(p_old.size)
    st.update(p=p_old.copy(), tau=tau_old.copy(), lam=lam_old.copy(),
              status=np.where(p_old > 0, STICK, OPEN).astype(np.int8))   # a consistent state
    return st


def _on_surface(law, p_old, tau_old):
    """(tau_old, lam_old) with the "on surface" points (|tau| = 4) put exactly on the surface
    of ``law`` at lam = 0.01."""
    lam_old = np.full(p_old.size, 0.01)
    radius = law.adhesion(lam_old)[0] + law.friction(lam_old)[0] * p_old
    return np.where(np.abs(tau_old) == 4.0, np.sign(tau_old) * radius, tau_old), lam_old


@pytest.mark.parametrize("extra", [{}, dict(HPHI=5.0, HB=20.0), dict(HB=-30.0),
                                   dict(HPHI=-3.0, HB=10.0)])
def test_tangent_matches_central_differences(extra):
    law = Coulomb(**dict(BASE, **extra))
    p_old, tau_old, d, du, dv = _states()
    tau_old, lam_old = _on_surface(law, p_old, tau_old)
    st = _make_state(law, p_old, tau_old, lam_old)
    new, tan = law.update(st, d, du, dv)
    assert list(new["status"]) == [STICK, SLIP, SLIP, SLIP, STICK, OPEN, STICK, SLIP, SLIP]

    def tau_of(tau0=tau_old, d_=d, du_=du, dv_=dv):
        return law.update(_make_state(law, p_old, tau0, lam_old), d_, du_, dv_)[0]

    h = 1e-7
    fd = {
        "tau_v": (tau_of(dv_=dv + h)["tau"] - tau_of(dv_=dv - h)["tau"]) / (2 * h),
        "tau_tau": (tau_of(tau0=tau_old + h * 10)["tau"]
                    - tau_of(tau0=tau_old - h * 10)["tau"]) / (20 * h),
        "tau_u": (tau_of(d_=d + h, du_=du + h)["tau"]
                  - tau_of(d_=d - h, du_=du - h)["tau"]) / (2 * h),
        "p_u": (tau_of(d_=d + h, du_=du + h)["p"] - tau_of(d_=d - h, du_=du - h)["p"]) / (2 * h),
        "tau_d": (tau_of(d_=d + h)["tau"] - tau_of(d_=d - h)["tau"]) / (2 * h),
        "tau_du": (tau_of(du_=du + h)["tau"] - tau_of(du_=du - h)["tau"]) / (2 * h),
    }
    for key, val in fd.items():
        np.testing.assert_allclose(tan[key], val, rtol=1e-5, atol=1e-5 * law.kt, err_msg=key)
    # derivatives of lam_new (needed to chain sub-intervals with hardening), and d tau/d lam_old
    lam_of = lambda **kw: tau_of(**kw)["lam"]  # noqa: E731
    fd_lam = {
        "lam_v": (lam_of(dv_=dv + h) - lam_of(dv_=dv - h)) / (2 * h),
        "lam_tau": (lam_of(tau0=tau_old + 10 * h) - lam_of(tau0=tau_old - 10 * h)) / (20 * h),
        "lam_d": (lam_of(d_=d + h) - lam_of(d_=d - h)) / (2 * h),
        "lam_du": (lam_of(du_=du + h) - lam_of(du_=du - h)) / (2 * h),
    }
    for key, val in fd_lam.items():
        np.testing.assert_allclose(tan[key], val, rtol=1e-5, atol=1e-6, err_msg=key)
    hl = 1e-6
    up = law.update(_make_state(law, p_old, tau_old, lam_old + hl), d, du, dv)[0]
    dn = law.update(_make_state(law, p_old, tau_old, lam_old - hl), d, du, dv)[0]
    np.testing.assert_allclose(tan["tau_lam"], (up["tau"] - dn["tau"]) / (2 * hl), rtol=1e-5,
                               atol=1e-5 * law.kt, err_msg="tau_lam")
    np.testing.assert_allclose(tan["lam_lam"], (up["lam"] - dn["lam"]) / (2 * hl), rtol=1e-5,
                               atol=1e-6, err_msg="lam_lam")
    # plastic points with phi, B constant follow eq. (11): no dependence on dv or tau_old
    if not extra:
        slip = new["status"] == SLIP
        np.testing.assert_allclose(tan["tau_v"][slip], 0.0, atol=1e-12)
        np.testing.assert_allclose(tan["tau_u"][slip & (p_old > 0)],
                                   0.3 * 1000.0 * np.sign(new["tau"][slip & (p_old > 0)]))


@pytest.mark.parametrize("case", sorted(HARDENING_CASES))
@pytest.mark.parametrize("n", [1, 4])
def test_tangent_chained_over_substeps_matches_differences(case, n):
    """The (tau, lam) chain over SUBSTEPS sub-intervals gives the exact derivative of the
    interval's end tau w.r.t. its increments (differences of whole driver runs)."""
    law = Coulomb(**HARDENING_CASES[case])
    # path points chosen away from kinks (yield, clipping, separation) at the perturbed ends
    res = drive(law, U_PATH, V_PATH, substeps=n, tangent=True)
    h = 1e-8
    for i in range(1, len(U_PATH)):
        for key, path, other in (("dtau_du", U_PATH, V_PATH), ("dtau_dv", V_PATH, U_PATH)):
            plus, minus = path[: i + 1].copy(), path[: i + 1].copy()
            plus[i] += h
            minus[i] -= h
            args = (plus, other[: i + 1]) if key == "dtau_du" else (other[: i + 1], plus)
            margs = (minus, other[: i + 1]) if key == "dtau_du" else (other[: i + 1], minus)
            fd = (drive(law, *args, substeps=n)["tau"][-1]
                  - drive(law, *margs, substeps=n)["tau"][-1]) / (2 * h)
            np.testing.assert_allclose(res[key][i], fd, rtol=1e-5, atol=1e-3,
                                       err_msg=f"{key} at path point {i}")


def test_frozen_status_is_held_and_its_tangent_is_exact():
    """The solver's flip-flop control: -1 free; OPEN/STICK/SLIP held."""
    law = Coulomb(**dict(BASE, HPHI=5.0, HB=20.0))
    p_old, tau_old, d, du, dv = _states()
    tau_old, lam_old = _on_surface(law, p_old, tau_old)
    st = _make_state(law, p_old, tau_old, lam_old)
    free, tan_free = law.update(st, d, du, dv)
    same, tan_same = law.update(st, d, du, dv, frozen=np.full(p_old.size, -1, np.int8))
    for k in free:
        np.testing.assert_array_equal(same[k], free[k])
    for k in tan_free:
        np.testing.assert_array_equal(tan_same[k], tan_free[k])
    # swap stick and slip where in contact, hold the open point in contact open, and vice versa
    swapped = np.where(free["status"] == SLIP, STICK, SLIP).astype(np.int8)
    swapped[5] = -1
    swapped[0] = OPEN
    new, tan = law.update(st, d, du, dv, frozen=swapped)
    assert list(new["status"]) == [OPEN] + list(swapped[1:5]) + [OPEN] + list(swapped[6:])
    assert new["p"][0] == 0 and new["tau"][0] == 0 and new["lam"][0] == lam_old[0]
    stick = new["status"] == STICK                       # held elastic: trial stress, even outside
    frac = np.where(p_old == 0, d / np.where(p_old == 0, du, 1.0), 1.0)  # dv after touching
    np.testing.assert_allclose(new["tau"][stick], (tau_old + law.kt * dv * frac)[stick],
                               rtol=1e-14)
    assert np.any(np.abs(new["tau"][stick]) > (law.adhesion(new["lam"])[0]
                                                + law.friction(new["lam"])[0] * new["p"])[stick])
    slip = new["status"] == SLIP                         # held on the cone, even when unloading
    np.testing.assert_allclose(np.abs(new["tau"][slip]), (law.adhesion(new["lam"])[0]
                               + law.friction(new["lam"])[0] * new["p"])[slip], rtol=1e-12)
    h = 1e-7
    for key, kw in (("tau_v", "dv"), ("tau_d", "d"), ("tau_du", "du")):
        args_p = dict(d=d, du=du, dv=dv)
        args_m = dict(d=d, du=du, dv=dv)
        args_p[kw] = args_p[kw] + h
        args_m[kw] = args_m[kw] - h
        fd = (law.update(st, **args_p, frozen=swapped)[0]["tau"]
              - law.update(st, **args_m, frozen=swapped)[0]["tau"]) / (2 * h)
        np.testing.assert_allclose(tan[key], fd, rtol=1e-5, atol=1e-5 * law.kt, err_msg=key)


def test_snap_back_softening_is_refused_at_runtime():
    law = Coulomb(KP=1000.0, KT=10.0, PHI=0.3, HPHI=-5.0)   # KT + HPHI p < 0 when p > 2
    st = _make_state(law, np.array([10.0]), np.array([3.0]), np.array([0.0]))
    with pytest.raises(ReturnMappingError, match="snap-back"):
        law.update(st, np.array([0.01]), np.array([0.0]), np.array([0.1]))


# --------------------------------------------------------------------------------------------
# The tangent's shortcut for sub-intervals where nothing re-contacts or separates.
# --------------------------------------------------------------------------------------------
SHORTCUT_PARAMS = {
    "plain": dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0),
    "no_adhesion": dict(KP=1.68e6, KT=1.68e6, PHI=0.2),
    "softening_kinks": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=-0.5),
    "hardening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=30.0, HPHI=0.7),
    "classical": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=0.2,
                      INDICATOR="CLASSICAL"),
}


def _closed_or_open_batch(par, rng, g=3000):
    """Committed states around the cone and sub-interval increments in which every point stays
    closed or stays open (no re-contact, no separation)."""
    st = {"p": np.where(rng.random(g) < 0.3, 0.0, 20 * rng.random(g)),
          "lam": np.where(rng.random(g) < 0.3, 0.0, 0.2 * rng.random(g)),
          "slip": rng.random(g), "vp": rng.uniform(-1.0, 1.0, g), "dissip": rng.random(g)}
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
    st["status"] = np.where(d >= 0, rng.integers(1, 3, g), OPEN).astype(np.int8)
    st["p"] = np.where(d < 0, 0.0, st["p"])
    return st, d, du, dv


@pytest.mark.parametrize("name", sorted(SHORTCUT_PARAMS))
def test_simple_tangent_equals_general_tangent(name):
    """No re-contact, no separation: the shortcut (``Coulomb._tangent_simple``) gives the
    general formulas' values, bit for bit."""
    par = SHORTCUT_PARAMS[name]
    law = Coulomb(**par)
    st, d, du, dv = _closed_or_open_batch(par, np.random.default_rng(3))
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


# --------------------------------------------------------------------------------------------
# Exactness as an invariant: splitting a linear sub-interval must not change the result.
# --------------------------------------------------------------------------------------------
from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(hb=st.floats(-200.0, 100.0), hphi=st.floats(-2.0, 20.0), b=st.floats(0.0, 3.0),
       phi=st.floats(0.0, 0.6),
       steps=st.lists(st.tuples(st.floats(-0.01, 0.02, allow_subnormal=False),
                                st.floats(-0.05, 0.05, allow_subnormal=False)),
                      min_size=1, max_size=8))
def test_any_path_is_independent_of_substeps(hb, hphi, b, phi, steps):
    """Hardening, softening, clipping, separation, re-contact, reversal: all exact."""
    law = Coulomb(KP=1000.0, KT=500.0, PHI=phi, B=b, HB=hb, HPHI=hphi)
    u = np.r_[0.0, [s[0] for s in steps]]
    v = np.r_[0.0, np.cumsum([s[1] for s in steps])]
    one = drive(law, u, v, substeps=1)
    three = drive(law, u, v, substeps=3)
    for k in ("p", "tau", "lam", "slip", "dissip"):
        scale = max(np.max(np.abs(one[k])), 1e-3 if k in ("lam", "slip") else 1.0)
        np.testing.assert_allclose(three[k], one[k], rtol=0, atol=1e-9 * scale, err_msg=k)
    # status may differ only at neutral loading (indicator 0 up to roundoff: no slip either way)
    neutral = np.r_[False, np.abs(np.diff(one["lam"])) < 1e-12]
    np.testing.assert_array_equal(three["status"][~neutral], one["status"][~neutral])
