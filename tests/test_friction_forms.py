"""The hardening forms of COULOMB (exponential phi and B, a table in lam) and the shear limit
TAUMAX, against independent references.

* Single-point paths (press, slide, press while sliding, unload while sliding back, separate,
  re-contact) against the rate equations integrated by scipy (``tests/ode_contact.py``: DOP853 at
  rtol 1e-13, every switch an event), to 1e-8, with one and several sub-intervals per path
  interval: the exact return and its dissipation integral.
* The tangent of one sub-interval, and chained over sub-intervals, against central differences
  at states in every regime, for every form (on and off the cap, across table rows).
* A bad parameter gives one message naming it, at check time.
"""
import numpy as np
import pytest

from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.deck import load_deck
from lagamine_py.deck.errors import DeckError
from lagamine_py.laws.contact_point import drive_contact_point as drive
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.registry import ParamError

from ode_contact import reference

BASE = dict(KP=1000.0, KT=500.0)
TABLE = "CONTACT LAW TABLE"
CASES = {
    # phi rises from 0.3 to 0.6 over a few LAMC: an increment slides 3 LAMC (panels)
    "run-in phi": dict(BASE, PHI=0.3, B=1.0, PHI_INF=0.6, LAMC=0.01),
    # adhesion worn from 2 to 0.2 (softening), phi linear softening to its clipping kink
    "worn B, phi softening": dict(BASE, PHI=0.3, B=2.0, B_INF=0.2, LAMC_B=0.02, HPHI=-2.0),
    # B exponential hardening with a fast phi run-in
    "B hardening, phi run-in": dict(BASE, PHI=0.2, B=0.5, B_INF=3.0, LAMC_B=0.03, PHI_INF=0.5,
                                    LAMC=0.004),
    # rows at lam 0.01 and 0.05, hardening then softening, flat beyond
    "table": dict(BASE, **{TABLE: ((0.0, 0.3, 1.0), (0.01, 0.5, 0.5), (0.05, 0.4, 0.0),
                                   (0.12, 0.2, 0.0))}),
    # the shear limit reached and left while the pressure moves during a slide
    "TAUMAX": dict(BASE, PHI=0.3, B=1.0, TAUMAX=3.7),
    "TAUMAX, run-in": dict(BASE, PHI=0.3, B=1.0, PHI_INF=0.6, LAMC=0.01, TAUMAX=6.0),
    "TAUMAX, table": dict(BASE, TAUMAX=4.2, **{TABLE: ((0.0, 0.2, 0.5), (0.02, 0.6, 1.0))}),
}
# press, slide, press while sliding, unload the pressure while sliding back, separate, re-contact
U_PATH = np.array([0.0, 0.01, 0.01, 0.02, 0.015, 0.015, -0.005, 0.01, 0.01, 0.006])
V_PATH = np.array([0.0, 0.0, 0.04, 0.08, 0.1, 0.05, 0.05, 0.06, 0.09, 0.13])


def _rel(res, ref, key):
    return float(np.max(np.abs(res[key] - ref[key])) / np.max(np.abs(ref[key])))


@pytest.mark.parametrize("case", sorted(CASES))
def test_paths_agree_with_the_ode_integration_of_the_rate_equations(case):
    par = CASES[case]
    ref = reference(par, U_PATH, V_PATH)
    law = Coulomb(**par)
    for n in (1, 7):
        res = drive(law, U_PATH, V_PATH, substeps=n)
        for key in ("p", "tau", "lam", "dissip"):
            assert _rel(res, ref, key) <= 1e-8, f"{case}, SUBSTEPS={n}: {key}"
    # the path visits every regime, slips in both directions and separates
    assert set(res["status"]) == {OPEN, STICK, SLIP}
    assert ref["tau"].max() > 0 > ref["tau"].min() and ref["p"][6] == 0.0


def test_the_path_reaches_the_forms_features():
    """The cases do what their names say along the path (so that the agreement above covers
    them): the cap is held at several path points, a table row and the softening kink are
    crossed within one increment, the run-in slides several LAMC in one increment."""
    cap = drive(Coulomb(**CASES["TAUMAX"]), U_PATH, V_PATH)
    assert np.sum(np.isclose(np.abs(cap["tau"]), 3.7, rtol=0, atol=1e-12)) >= 3
    assert np.any(cap["status"] == SLIP) and np.any(np.abs(cap["tau"][cap["status"] == SLIP])
                                                    < 3.7 - 1e-6)
    tab = drive(Coulomb(**CASES["table"]), U_PATH, V_PATH)["lam"]
    assert any(a < 0.01 < b for a, b in zip(tab[:-1], tab[1:]))
    assert any(a < 0.05 < b for a, b in zip(tab[:-1], tab[1:]))
    worn = drive(Coulomb(**CASES["worn B, phi softening"]), U_PATH, V_PATH)["lam"]
    assert any(a < 0.15 < b for a, b in zip(worn[:-1], worn[1:]))        # phi's kink 0.3 / 2
    runin = drive(Coulomb(**CASES["run-in phi"]), U_PATH, V_PATH)["lam"]
    assert np.max(np.diff(runin)) > 2.5 * 0.01


# --------------------------------------------------------------------------------------------
# the tangent against central differences

def _states(law):
    """(state, d, du, dv): stick, slip forward, slip with pressure rising, reversal that re-yields
    on the other side, unloading, open, partial re-contact (elastic and yielding), a long slide
    (across breaks and LAMC), slip with pressure falling."""
    p_old = np.array([10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 0.0, 0.0, 10.0, 12.0])
    d = np.array([0.011, 0.01, 0.012, 0.01, 0.01, -0.001, 0.0005, 0.0005, 0.0101, 0.0105])
    du = np.array([0.001, 0.0, 0.002, 0.0, 0.0, -0.011, 0.001, 0.001, 0.0001, -0.0015])
    dv = np.array([0.001, 0.01, -0.02, -0.03, -0.002, 0.01, 0.001, 0.02, 0.08, 0.006])
    lam_old = np.full(p_old.size, 0.004)
    sign = np.array([1, 1, -1, 1, 1, 1, 0, 0, 1, 1.0])
    on = np.array([0, 1, 1, 1, 1, 0, 0, 0, 1, 1], bool)
    tau_old = np.where(on, sign * law.radius(lam_old, p_old), 0.3 * law.radius(lam_old, p_old))
    tau_old[6:8] = 0.0
    state = law.init_state(p_old.size)
    state.update(p=p_old, tau=tau_old, lam=lam_old,
                 status=np.where(p_old > 0, STICK, OPEN).astype(np.int8))
    return state, d, du, dv


@pytest.mark.parametrize("case", sorted(CASES))
def test_tangent_matches_central_differences(case):
    law = Coulomb(**CASES[case])
    state, d, du, dv = _states(law)
    new, tan = law.update(state, d, du, dv)
    assert list(new["status"]) == [STICK, SLIP, SLIP, SLIP, STICK, OPEN, STICK, SLIP, SLIP, SLIP]

    def run(key, **kw):
        st = dict(state, tau=kw.pop("tau0", state["tau"]), lam=kw.pop("lam0", state["lam"]))
        args = {**dict(d=d, du=du, dv=dv), **kw}
        return law.update(st, args["d"], args["du"], args["dv"])[0][key]

    h = 1e-8
    inputs = {"v": dict(dv=dv + h), "d": dict(d=d + h), "du": dict(du=du + h),
              "tau": dict(tau0=state["tau"] + h), "lam": dict(lam0=state["lam"] + h)}
    minus = {"v": dict(dv=dv - h), "d": dict(d=d - h), "du": dict(du=du - h),
             "tau": dict(tau0=state["tau"] - h), "lam": dict(lam0=state["lam"] - h)}
    for out in ("tau", "lam"):
        for x in inputs:
            fd = (run(out, **inputs[x]) - run(out, **minus[x])) / (2 * h)
            scale = law.kt if out == "tau" else 1.0
            np.testing.assert_allclose(tan[f"{out}_{x}"], fd, rtol=2e-6, atol=2e-6 * scale,
                                       err_msg=f"{case}: {out}_{x}")
    slip = new["status"] == SLIP
    if "TAUMAX" in case:              # slip points on the cap (tau_v = 0) and below it
        on_cap = np.abs(new["tau"]) == law.cap
        assert np.any(slip & on_cap) and np.any(slip & ~on_cap)
        np.testing.assert_array_equal(tan["tau_v"][slip & on_cap], 0.0)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("n", [1, 3])
def test_tangent_chained_over_substeps_matches_differences(case, n):
    """d tau / d(du, dv) of each path interval chained over its sub-intervals (as the contact
    element chains them) against differences of whole driver runs."""
    law = Coulomb(**CASES[case])
    res = drive(law, U_PATH, V_PATH, substeps=n, tangent=True)
    h = 1e-8
    for i in range(1, len(U_PATH)):
        for key, path, other in (("dtau_du", U_PATH, V_PATH), ("dtau_dv", V_PATH, U_PATH)):
            runs = []
            for sgn in (1, -1):
                moved = path[: i + 1].copy()
                moved[i] += sgn * h
                args = (moved, other[: i + 1]) if key == "dtau_du" else (other[: i + 1], moved)
                runs.append(drive(law, *args, substeps=n)["tau"][-1])
            np.testing.assert_allclose(res[key][i], (runs[0] - runs[1]) / (2 * h), rtol=1e-5,
                                       atol=1e-3, err_msg=f"{case} {key} at path point {i}")


# --------------------------------------------------------------------------------------------
# parameters: one clear message each

BAD = [
    (dict(PHI=0.3, PHI_INF=0.5, LAMC=0.0), "LAMC must be > 0"),
    (dict(PHI=0.3, B=1.0, B_INF=0.5, LAMC_B=-1.0), "LAMC_B must be > 0"),
    (dict(PHI=0.3, PHI_INF=0.5), "PHI_INF and LAMC go together .*LAMC is missing"),
    (dict(PHI=0.3, LAMC=0.1), "PHI_INF and LAMC go together .*PHI_INF is missing"),
    (dict(PHI=0.3, HPHI=1.0, PHI_INF=0.5, LAMC=0.1), "PHI is linear .* or exponential"),
    (dict(PHI=0.3, TAUMAX=0.0), "TAUMAX must be > 0"),
    (dict(PHI=0.3, TAUMAX=-5.0), "TAUMAX must be > 0"),
    (dict(PHI=0.3, B=100.0, B_INF=0.0, LAMC_B=0.1), r"\(B - B_INF\)/LAMC_B = 1000 softens faster"),
    ({TABLE: ((0.0, 0.3, 0.0), (0.02, 0.4, 0.0), (0.01, 0.5, 0.0))},
     "lam must increase, row 3 .0.01. follows 0.02"),
    ({TABLE: ((0.01, 0.3, 0.0), (0.02, 0.4, 0.0))}, "first row must be at lam = 0"),
    ({TABLE: ((0.0, 0.3, 0.0), (0.02, -0.1, 0.0))}, "phi must be >= 0"),
    ({TABLE: ((0.0, 0.3, 10.0), (0.001, 0.3, 0.0))}, "a table slope of B of -10000 softens"),
    (dict(PHI=0.2, **{TABLE: ((0.0, 0.3, 0.0),)}), "the .CONTACT LAW TABLE gives phi and B: leave PHI out"),
    ({}, "missing required parameter PHI"),
    (dict(PHI=0.3, METHOD="AUGMENTED"), "METHOD=AUGMENTED needs PTOL"),
    (dict(PHI=0.3, PTOL=1e-3), "PTOL is the tolerance of METHOD=AUGMENTED"),
]


@pytest.mark.parametrize("extra,message", BAD)
def test_bad_parameters_are_refused_by_name(extra, message):
    with pytest.raises(ParamError, match=message):
        Coulomb(**dict(BASE, **extra))


DECK = """*MESH, NAME=B, TYPE=Q8PE, X0=0, Y0=0, LX=1, LY=1, NX=1, NY=1
*MATERIAL, NAME=M, LAW=ELASTIC
E=1000, NU=0.3
*SOLID, ELSET=B, MATERIAL=M
*FOUNDATION, NAME=F
-2, 0
0, 0
2, 0
*CONTACT LAW, NAME=RUNIN, TYPE=COULOMB
KP=1e4, KT=1e4{extra}
*CONTACT LAW TABLE
0, 0.1, 0
0.01, 0.3, 1
{row}
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=F, LAW=RUNIN
*STEP
*STATIC
1, 1
*END STEP
"""


def test_contact_law_table_in_a_deck(tmp_path):
    path = tmp_path / "t.dat"
    path.write_text(DECK.format(extra="", row="0.05, 0.4, 2"))
    model = load_deck(path)
    law = Coulomb(**model.contact_laws["RUNIN"].params)
    np.testing.assert_allclose(law.friction(np.array([0.0, 0.005, 0.03, 1.0]))[0],
                               [0.1, 0.2, 0.35, 0.4])
    np.testing.assert_allclose(law.adhesion(np.array([0.0, 0.005, 0.03, 1.0]))[0],
                               [0.0, 0.5, 1.5, 2.0])
    # a bad row is reported at the table's line, and nothing runs
    path.write_text(DECK.format(extra="", row="0.005, 0.4, 2"))
    with pytest.raises(DeckError, match=r"t.dat:11: \*CONTACT LAW: CONTACT LAW TABLE: lam must "
                                        r"increase, row 3"):
        load_deck(path)
    path.write_text(DECK.format(extra=", PHI=0.2", row="0.05, 0.4, 2"))
    with pytest.raises(DeckError, match="leave PHI out"):
        load_deck(path)
    path.write_text(DECK.replace("*CONTACT LAW TABLE", "*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=F, "
                                                       "LAW=RUNIN\n*CONTACT LAW TABLE")
                    .format(extra="", row="0.05, 0.4, 2"))
    with pytest.raises(DeckError, match=r"must follow the \*CONTACT LAW"):
        load_deck(path)
