"""decks/tube_joint.dat, the paper's first example (issue 15 item 1): a hydroformed aluminium tube
pulled out of a grooved rigid end-piece by its end, frictionless.  What is checked, each against
a source of its own:

* the forming starts as Lamé's open-ended thick cylinder (the tube is free in its clearance at the
  first increment, 1 MPa: the Ramberg-Osgood plastic part is 1e-6 of the elastic strain there);
* the energy balance (``*CHECK, TYPE=ENERGY`` of the deck) within 0.5 % at every step end;
* global axial equilibrium during the pull-out: the end's reaction is the end-piece's contact
  force resultant (tool_forces.csv), to the Newton tolerance; the contact is frictionless
  (tau = 0 everywhere, no frictional dissipation);
* the interlock resists, not friction: the same deck with the groove taken out of the bore pulls
  out with no force;
* the outputs at 3 % and 5 % of the modelled tube length are the step ends.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from lagamine_py.checks.base import evaluate_checks
from lagamine_py.deck import load_deck

from runner import DECKS, run_deck

DECK = DECKS / "tube_joint.dat"
A, B, E, NU = 10.0, 11.5, 70000.0, 0.33          # the deck's tube and aluminium
PULLED = "TUBE_TOP"                              # the end pulled out (z = L)


@pytest.fixture(scope="module")
def joint(tmp_path_factory):
    out = tmp_path_factory.mktemp("tube_joint")
    outcome, cap, _ = run_deck(DECK, out)
    assert outcome.status == 0
    return out, cap.results


def _pull(results):
    return [r for r in results if r.step_name.startswith("PULL")]


def test_forming_starts_as_lame_open_ended_cylinder(joint):
    """First increment (p = 1 MPa, the tube not yet touching the bore, its end z = L held
    axially, the other end free: sigma_z = 0): u_r(r) = p a^2 / (E (b^2 - a^2)) ((1 - nu) r
    + (1 + nu) b^2 / r) and u_z = -2 nu p a^2 / (E (b^2 - a^2)) (z - L), at every node."""
    _, results = joint
    first = results[0]
    assert first.step_name == "FORM" and not any((c.p > 0).any() for c in first.contacts)
    p = first.loads["P TUBE_LEFT"]
    assert p == pytest.approx(1.0)
    x = first.coords0
    r, z, L = x[:, 0], x[:, 1], x[:, 1].max()
    k = p * A**2 / (E * (B**2 - A**2))
    ur = k * ((1 - NU) * r + (1 + NU) * B**2 / r)
    uz = -2 * NU * k * (z - L)
    assert np.abs(first.u[:, 0] - ur).max() < 5e-4 * ur.max()      # measured 2.2e-4
    assert np.abs(first.u[:, 1] - uz).max() < 5e-4 * np.abs(uz).max()   # 1.8e-4


def test_energy_balance_within_half_a_percent(joint):
    """The deck's *CHECK, TYPE=ENERGY: work of the pressure and of the pulled end = elastic +
    plastic + penalty energy (no friction) at each of the four step ends, within 0.5 %."""
    out, _ = joint
    (report,) = evaluate_checks(load_deck(DECK).checks, out)
    assert report["message"] == "" and set(report["errors"]) == {f"step{k}" for k in (1, 2, 3, 4)}
    assert report["error"] < 5e-3, report["errors"]
    m = report["measured"]
    assert m["plastic_4"] > m["plastic_3"] > m["plastic_2"] > 0      # the pull-out works plastically
    assert abs(m["friction_4"]) < 1e-9 * m["work_4"] and m["stabilisation_4"] == 0


def test_pull_out_force_is_the_end_piece_contact_resultant(joint):
    """Axial equilibrium of the tube while it is pulled (no pressure left): the reaction of the
    pulled end and the end-piece's force on the tube sum to zero (the Newton residual); the
    tractions are normal (phi = 0, B = 0)."""
    _, results = joint
    pull = _pull(results)
    assert len(pull) > 10
    rf = np.array([r.reactions_by_set[PULLED][1] for r in pull])
    tool = np.array([r.tools["END_PIECE"].force[1] for r in pull])
    assert np.abs(rf + tool).max() < 1e-8 * np.abs(rf).max()    # RTOL; measured 2e-11
    assert rf.max() > 100.0                                      # N per radian: it holds
    for r in results:                         # tau = tau_n + KT (dv - dvp): round-off only
        for c in r.contacts:
            assert np.abs(c.tau).max() <= 1e-12 * max(c.p.max(), 1.0)


def test_outputs_at_three_and_five_percent_of_the_length(joint):
    """The two pull steps end with the end displaced by 3 % and 5 % of the modelled length."""
    _, results = joint
    ends = {r.step_name: r for r in results if r.step_end}
    L = np.ptp(results[0].coords0[:, 1])
    top = np.isclose(results[0].coords0[:, 1], results[0].coords0[:, 1].max())
    for name, share in (("PULL_3PCT", 0.03), ("PULL_5PCT", 0.05)):
        assert ends[name].u[top, 1] == pytest.approx(share * L, rel=1e-12)


def test_without_the_groove_nothing_holds(tmp_path, joint):
    """The interlock resists, not friction: with the groove replaced by the plain bore (the same
    deck otherwise: formed, released, pulled), the pull-out force is nil beside the joint's."""
    _, results = joint
    held = max(r.reactions_by_set[PULLED][1] for r in _pull(results))
    text = DECK.read_text()
    plain = re.sub(r"(\*FOUNDATION, NAME=END_PIECE\n)(?:[-\d., ]+\n)+",
                   r"\g<1>11.55, -2\n11.55, 8.5\n11.55, 19\n", text)
    assert plain != text
    deck = tmp_path / "tube_joint_plain.dat"
    deck.write_text(plain)
    outcome, cap, _ = run_deck(deck, tmp_path / "out")
    assert outcome.status == 0
    free = max(abs(r.reactions_by_set[PULLED][1]) for r in _pull(cap.results))
    assert free < 1e-6 * held
