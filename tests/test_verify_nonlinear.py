"""Plasticity at large strain through the whole program, against independent numbers.

* compression_ro.dat: homogeneous compression of a Ramberg–Osgood cylinder between frictionless
  platens; with Hencky strains and multiplicative plasticity the closed form is exact (see the deck):
  Kirchhoff stress t solves  ln(h/h0) = t/E + alpha (s0/E) (t/s0)^n  (signs for compression),
  J = exp((1-2 nu) t / E), r = r0 exp(-nu t/E - eps_p/2), Cauchy s = t / J, axial force per radian
  F = s r^2 / 2.
* tube_limit.dat: a perfectly plastic thick tube converges below the limit pressure
  (2/sqrt3) sY ln(b/a) and stops cleanly (exit 3, message naming the step and time) above it.
* Newton converges quadratically on a plastic large-strain increment.
"""
import numpy as np
import pytest
from scipy.optimize import brentq

from runner import DECKS, is_quadratic, run_deck

E, NU, S0, ALPHA, N = 70000.0, 0.3, 200.0, 0.5, 8.0
R0, H0, DROP = 5.0, 10.0, 3.0


def kirchhoff_from_log_strain(eps):
    """|t| for a uniaxial log strain magnitude |eps| on the Ramberg–Osgood curve."""
    f = lambda t: t / E + ALPHA * S0 / E * (t / S0) ** N - eps
    return brentq(f, 0.0, 10 * S0 + E * eps, xtol=1e-14, rtol=1e-15)


def test_ramberg_osgood_compression_matches_homogeneous_closed_form(tmp_path):
    outcome, cap, res = run_deck(DECKS / "compression_ro.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert len(cap.results) >= 5
    for r in cap.results:
        h = H0 - DROP * r.step_time
        eps = -np.log(h / H0)                         # magnitude of the compressive log strain
        t = kirchhoff_from_log_strain(eps)
        eps_p = eps - t / E
        J = np.exp(-(1 - 2 * NU) * t / E)
        radius = R0 * np.exp(NU * t / E + eps_p / 2)
        force = t / J * radius**2 / 2
        rf = r.reactions_by_set["CYL_TOP"][1]
        assert rf == pytest.approx(-force, rel=1e-6), (r.step_time, rf, force)
        outer = np.isclose(r.coords0[:, 0], R0)
        np.testing.assert_allclose(r.coords0[outer, 0] + r.u[outer, 0], radius, rtol=1e-7)


def test_newton_converges_quadratically_in_plastic_large_strain(tmp_path):
    outcome, cap, _ = run_deck(DECKS / "compression_ro.dat", tmp_path / "out")
    orders = [is_quadratic(r.residual_history) for r in cap.results]
    orders = [o for o in orders if o is not None]
    assert orders, "no increment took enough iterations to measure an order"
    assert np.median(orders) > 1.7, orders


P_LIM = 2 / np.sqrt(3) * 250 * np.log(2.0)


def test_thick_tube_converges_below_the_limit_pressure(tmp_path):
    outcome, cap, _ = run_deck(DECKS / "tube_limit.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert cap.results[-1].step_time == pytest.approx(1.0)
    # elastic-plastic boundary c of the plane-strain tube (Hill §V.3, incompressible form):
    # p = (sY/sqrt3) [1 - c^2/b^2 + 2 ln(c/a)]; plastic inside c, elastic outside
    k = 250 / np.sqrt(3)
    c = brentq(lambda c: k * (1 - c**2 / 400 + 2 * np.log(c / 10)) - 196.09, 10, 20)
    last = cap.results[-1]
    cell = last.cells[0]
    xg = (last.coords0 + last.u)[cell.conn].mean(axis=1)[:, 0]     # element centre radius
    plastic = (cell.peeq > 0).any(axis=1)
    h = 10 / 16
    assert plastic[xg < c - h].all() and not plastic[xg > c + h].any(), (c, xg[plastic].max())


def test_thick_tube_above_the_limit_stops_cleanly(tmp_path):
    p = 1.03 * P_LIM
    outcome, cap, res = run_deck(DECKS / "tube_limit.dat", tmp_path / "out", {"PRESSURE": f"{p:.6f}"})
    assert outcome.status == 3
    assert "INFLATE" in outcome.message
    reached = cap.results[-1].step_time * p
    assert 0.97 * P_LIM < reached < 1.0 * P_LIM + 0.5, reached
    # every converged increment is on disk
    sta = (tmp_path / "out" / "tube_limit.sta").read_text()
    assert len(cap.results) > 3 and str(cap.results[-1].increment) in sta
