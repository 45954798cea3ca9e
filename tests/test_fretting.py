"""Fretting of a deformable pad on a deformable specimen (decks/fretting.dat, issue 18 item 3).

The deck presses a Q8 half-cylinder (R = 10) on a Q8 block of the same steel, loads it sideways
to Q* = 0.56 phi P and rocks it through three full cycles.  Independent sources: the
Cattaneo-Mindlin and Mindlin-Deresiewicz closed forms for line contact (Johnson, Contact
Mechanics §7.1, §7.3; exact for two half-planes of one material, where normal and tangential
tractions do not couple), the energy balance over a closed cycle (the work of the platen = the
frictional dissipation, the stored energy returns), and the repetition of the loop.  The run is
the regression test's (the session's ``deck_run``), so the deck runs once per session.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from lagamine_py.checks import evaluate_checks
from lagamine_py.checks.closed_forms import hertz_closed_form
from lagamine_py.checks.fretting import mindlin_traction

from conftest import DECKS

DECK = next(d for d in DECKS if d.stem == "fretting")


@pytest.fixture(scope="module")
def checks(deck_run):
    got = deck_run(DECK)
    assert got.outcome.status == 0, got.outcome.message
    return {r["name"]: r for r in evaluate_checks(got.model.checks, got.outdir)}


def test_mindlin_traction_carries_Q():
    """The closed-form traction integrates to Cattaneo's Q = phi P (1 - c^2/a^2) (the two
    elliptic terms carry phi P and phi P c^2/a^2): checks the helper the FRETTING check uses."""
    a, c, phi, P = 1.2, 0.7, 0.3, 5000.0
    p0 = 2.0 * P / (math.pi * a)
    Q, _ = quad(lambda x: float(mindlin_traction(np.array([x]), a, c, phi * p0)[0]), -a, a,
                points=(-c, c), limit=200)
    assert Q == pytest.approx(phi * P * (1.0 - (c / a) ** 2), rel=1e-8)
    # stick zone: the traction stays below phi p; slip zone: on the cone
    x = np.linspace(-a, a, 401)
    q = mindlin_traction(x, a, c, phi * p0)
    p = p0 * np.sqrt(np.clip(1 - (x / a) ** 2, 0, None))
    assert np.all(q <= phi * p + 1e-9)
    assert np.allclose(q[np.abs(x) > c], phi * p[np.abs(x) > c])


def test_stick_zones_against_cattaneo_and_mindlin(checks):
    """Stick half-width at Q = phi P / 2 of the first loading (Cattaneo-Mindlin c/a = sqrt(1/2))
    and where the first unloading passes Q = 0 (Mindlin-Deresiewicz c'/a = sqrt(1 - Q*/(2 phi
    P)) = 0.848).  Tolerance 0.06 a: the coarse mesh's Gauss points are 0.09 a apart and the
    finite bodies shift the stick zone off-centre by about 0.08 a (docs/two_body.md); measured
    0.046 a and 0.009 a (medium mesh: see docs/two_body.md)."""
    r = checks["FRETTING"]
    assert r["message"] == ""
    assert 0.5 < r["measured"]["Q_star_over_phiP"] < 0.7          # partial slip, well inside
    assert r["closed_form"]["c_over_a"] == pytest.approx(math.sqrt(0.5))
    assert r["errors"]["c"] < 0.06
    q_ratio = r["measured"]["Q_star_over_phiP"]
    assert r["closed_form"]["c_rev_over_a"] == pytest.approx(math.sqrt(1 - q_ratio / 2), rel=1e-3)
    assert r["errors"]["c_rev"] < 0.03
    # the reverse slip zone is narrower than the forward one at Q*: c' > c
    assert r["measured"]["c_rev_over_a"] > r["measured"]["c_over_a"] + 0.1


def test_shear_traction_against_cattaneo(checks):
    """q(x) at Q* against the Cattaneo-Mindlin traction, RMS over the contact points relative to
    phi p0: within 0.12 on the coarse mesh (measured 0.10: the stick-zone traction of 3-point
    faces wobbles from point to point, and the off-centre stick zone).  Its peak, at the stick
    zone's edge, phi p0 sqrt(Q*/(phi P)), within 5 % (measured 0.4 %)."""
    r = checks["FRETTING"]
    assert r["errors"]["q"] < 0.12
    P, ratio = r["measured"]["P"], r["measured"]["Q_star_over_phiP"]
    _, p0 = hertz_closed_form(P, 10.0, 109890.1, 0.0)
    assert r["closed_form"]["q_max"] == pytest.approx(0.3 * p0 * math.sqrt(ratio), rel=1e-9)
    assert r["measured"]["q_max"] == pytest.approx(r["closed_form"]["q_max"], rel=0.05)
    # most of the RMS is the stick zone's offset (finite bodies, 0.085 a measured): centred on
    # the run's stick zone the closed form is within 0.06 (medium mesh 0.044)
    assert 0.0 < r["measured"]["stick_shift_over_a"] < 0.15
    assert r["measured"]["q_error_shifted"] < 0.08


def test_energy_per_cycle_and_steady_loop(checks):
    """Over each closed cycle the work of the platen equals the frictional dissipation, the
    stored energy returning (0 to 1e-4 of D once the loop is steady): |W - D| / W < 0.02 for
    the steady cycles (measured 0.0105 with DT = 1/32 and 0.0103 with 1/64: not the increment
    size but the paper's contact force along the slave's normal doing work on the sliding of a
    face inclined by up to a/R = 0.1, lagamine_py.solver.energy).  Cycles 2 and 3 dissipate the
    same to 1e-4; the energy balance of the whole run holds within 1 % at every step end."""
    r = checks["FRETTING"]
    m = r["measured"]
    for k in (2, 3):
        assert r["errors"][f"cycle{k}"] < 0.02
        assert abs(m[f"stored_{k}"]) < 1e-4 * m[f"D_{k}"]
        assert m[f"D_tables_{k}"] == pytest.approx(m[f"D_{k}"], rel=0.01)
        assert m[f"D_{k}"] > 0
    assert r["errors"]["steady"] < 1e-4
    # the first cycle starts from the virgin loading's state: not yet steady
    assert m["stored_1"] > 1e-3 * m["D_1"]
    assert checks["ENERGY"]["error"] < 0.01


def test_the_check_needs_cycles(tmp_path, deck_run):
    """FRETTING names the loading step; without a cycle after it the check says so."""
    from lagamine_py.checks.base import evaluate_check
    from lagamine_py.checks.fretting import Fretting
    from lagamine_py.results import RunResults
    got = deck_run(DECK)
    chk = Fretting(R=10, E=109890.1, NU=0, PHI=0.3, LOAD=5)
    res = evaluate_check(chk, RunResults(got.outdir), "F", "FRETTING")
    assert math.isnan(res["error"]) and "followed by cycles" in res["message"]
