"""Contact scenes of decks/ against closed forms (issue: frictional contact, as in the paper).

Each deck's opening comments state the closed form; these tests run the deck and check it.
"""
import numpy as np
import pytest

from runner import DECKS, is_quadratic, run_deck


def last_contact(cap):
    return cap.results[-1].contacts[0]


def settled_orders(cap, step=None):
    """Newton orders of increments whose stick/slip pattern did not change during the increment."""
    out = []
    for r in cap.results:
        if step is not None and r.step != step:
            continue
        o = is_quadratic(r.residual_history)
        if o is not None:
            out.append(o)
    return out


def test_flat_punch_penetration_is_p_over_kp(tmp_path):
    outcome, cap, _ = run_deck(DECKS / "flat_punch.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    c = last_contact(cap)
    np.testing.assert_allclose(c.gap, 50.0 / 1e6, rtol=1e-8)
    np.testing.assert_allclose(c.p, 50.0, rtol=1e-8)
    assert (c.status != 0).all()
    assert c.P == pytest.approx(50.0 * c.A, rel=1e-8)
    assert c.F[1] == pytest.approx(50.0 * 10.0, rel=1e-8)


@pytest.mark.parametrize("deck, T_expected", [("coulomb_block.dat", 0.3 * 2000 + 5 * 20),
                                               ("coulomb_block_noadh.dat", 0.3 * 2000)])
def test_coulomb_block_slides_at_phi_P_plus_B_A(tmp_path, deck, T_expected):
    outcome, cap, _ = run_deck(DECKS / deck, tmp_path / "out")
    assert outcome.status == 0, outcome.message
    c = last_contact(cap)
    assert (c.status == 2).all(), "the whole interface must slide at the end"
    assert c.P == pytest.approx(2000.0, rel=1e-6)
    # T = phi P + B A with A the current contact area: the contact element is geometrically exact
    B = 5.0 if "noadh" not in deck else 0.0
    assert abs(c.T) == pytest.approx(0.3 * c.P + B * c.A, rel=1e-6)
    assert abs(c.T) == pytest.approx(T_expected, rel=1e-3)
    # the pushing reaction balances the friction force
    rf = cap.results[-1].reactions_by_set["BLOCK_LEFT"][0]
    assert abs(rf) == pytest.approx(T_expected, rel=1e-6)
    orders = settled_orders(cap)
    assert orders and np.median(orders) > 1.7, orders


def test_axisymmetric_frictionless_pressure_is_uniform(tmp_path):
    outcome, cap, _ = run_deck(DECKS / "axisym_press.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    c = last_contact(cap)
    np.testing.assert_allclose(c.p, 80.0, rtol=1e-6)
    assert c.F[1] == pytest.approx(80.0 * 25 / 2, rel=1e-8)


def test_axisymmetric_with_friction_balances_the_applied_force(tmp_path):
    outcome, cap, _ = run_deck(DECKS / "axisym_press_friction.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    c = last_contact(cap)
    # the resultant contact force per radian balances the applied p R^2 / 2 (global equilibrium)
    assert c.F[1] == pytest.approx(1000.0, rel=1e-8)
    assert not np.allclose(c.p, 80.0, rtol=1e-3), "friction should make the pressure non-uniform"
