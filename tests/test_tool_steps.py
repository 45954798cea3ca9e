"""Issue 15 in steps: *CHANGE CONTACT LAW (against Coulomb's closed form and a change that
changes nothing), a restart across it, the energy balance (*CHECK, TYPE=ENERGY) of a pressed and
slid elastic-plastic block, and the deck errors of the new keywords (one clear message each, the
same from ``check`` as from ``run``)."""
from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.checks.base import evaluate_checks
from lagamine_py.deck import DeckError, load_deck
from lagamine_py.output import DEFAULT_WRITERS, Writer, default_writers
from lagamine_py.solver import run

from runner import DECKS, run_deck

DATA = Path(__file__).resolve().parent / "data" / "tools"


def table(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------------------------------
# *CHANGE CONTACT LAW

def test_change_contact_law_press_frictionless_then_slide(tmp_path):
    """Pressed with phi = 0, then the pair's law is DRY (phi = 0.3): T = phi P once sliding;
    during the press T = 0; the slip lambda and the dissipation carry over (they only grow)."""
    out, cap, res = run_deck(DATA / "change_law.dat", tmp_path)
    assert out.status == 0
    totals = table(tmp_path / "contact_totals.csv")
    press = [r for r in totals if r["step"] == "1"]
    assert all(abs(float(r["T"])) < 1e-9 * float(r["P"]) for r in press)
    end = totals[-1]
    assert float(end["P"]) == pytest.approx(1000.0, rel=1e-12)
    assert abs(float(end["T"])) == pytest.approx(0.3 * 1000.0, rel=1e-12)
    lam = [np.asarray(r.contacts[0].lam) for r in cap.results]
    assert all(np.all(b >= a - 1e-15) for a, b in zip(lam, lam[1:]))
    model = load_deck(DATA / "change_law.dat")
    checks = {r["name"]: r for r in evaluate_checks(model.checks, tmp_path)}
    assert checks["COULOMB"]["error"] < 1e-10
    assert checks["ENERGY"]["error"] < 1e-10                 # small strain, flat: round-off


def test_changing_to_an_identical_law_changes_nothing(tmp_path):
    """The state carried over is the state: changing to SMOOTH's twin gives, bit for bit, the
    run without a change (the two-deck equivalent: one law throughout)."""
    changed = tmp_path / "changed"
    run_deck(DATA / "change_law.dat", changed, parameters={"LAW2": "SMOOTH2"})
    same = tmp_path / "same"
    run_deck(DATA / "change_law.dat", same, parameters={"LAW2": "SMOOTH"})
    for name in ("contact.csv", "contact_totals.csv", "reactions.csv", "displacements.csv"):
        assert (changed / name).read_text() == (same / name).read_text(), name


class _Stop(Writer):
    def __init__(self, at):
        self.at = at

    def increment(self, result):
        if (result.step, result.increment) == self.at:
            raise KeyboardInterrupt


@pytest.mark.parametrize("deck, at", [("change_law.dat", (2, 1)), ("roll_turn.dat", (2, 2))])
def test_restart_across_a_law_change_and_with_rotations(tmp_path, deck, at):
    """Interrupted after the law changed (or while the roll turns: the rotation DOF in the
    restart data) and resumed: the same tables as the run in one go, energy included."""
    model = load_deck(DATA / deck)
    names = DEFAULT_WRITERS + ("ENERGY",)
    full = tmp_path / "full"
    assert run(model, full, writers=default_writers(full, model, names)).status == 0
    part = tmp_path / "part"
    model = load_deck(DATA / deck)
    out = run(model, part, writers=default_writers(part, model, names) + [_Stop(at)])
    assert out.status == 130
    model = load_deck(DATA / deck)
    out = run(model, part, writers=default_writers(part, model, names, append=True), restart=True)
    assert out.status == 0
    for name in ("contact_totals.csv", "tool_forces.csv", "reactions.csv", "energy.csv"):
        assert (part / name).exists() == (full / name).exists()
        if (full / name).exists():
            assert (part / name).read_text() == (full / name).read_text(), name


# ------------------------------------------------------------------------------------------
# the energy balance

@pytest.mark.parametrize("nlgeom, tol", [("NO", 1e-9), ("YES", 5e-3)])
def test_energy_balance_of_press_slide(tmp_path, nlgeom, tol):
    """decks/press_slide.dat (a Ramberg-Osgood block pressed, then pushed until it slides):
    the work of the pressure and the push against elastic + plastic + friction + penalty energy
    at every step end.  Small strain against a flat: the trapezoidal form holds to round-off
    (stick-slip transitions included); NLGEOM: within 0.5 %."""
    text = (DECKS / "press_slide.dat").read_text().replace("NLGEOM=YES", f"NLGEOM={nlgeom}")
    text = text.replace("*STEP, NAME=PRESS", "*CHECK, NAME=ENERGY, TYPE=ENERGY\n*STEP, NAME=PRESS")
    deck = tmp_path / "press_slide.dat"
    deck.write_text(text)
    out, cap, _ = run_deck(deck, tmp_path / "out")
    assert out.status == 0
    report = evaluate_checks(load_deck(deck).checks, tmp_path / "out")[0]
    assert report["message"] == "" and set(report["errors"]) == {"step1", "step2"}
    assert report["error"] < tol, report
    m = report["measured"]
    assert m["plastic_2"] > m["plastic_1"] > 0 and m["friction_2"] > 10 * m["friction_1"] > 0
    assert m["penalty_2"] > 0 and m["stabilisation_2"] == 0
    log = (tmp_path / "out" / "press_slide.log").read_text()
    assert "energy at the end of step 2: work" in log


def test_energy_check_refuses_a_law_without_energy(tmp_path):
    """A material law that does not report its energy: ``check`` refuses the ENERGY check at
    its line, as ``run`` would."""
    import lagamine_py.registry as registry
    from lagamine_py.laws.elastic import LinearElastic

    class Silent(LinearElastic):
        def energy(self, state_old, state_new):
            return super(LinearElastic, self).energy(state_old, state_new)

    registry.register("laws", "SILENT_TEST")(Silent)
    deck = tmp_path / "d.dat"
    deck.write_text((DATA / "change_law.dat").read_text().replace("LAW=ELASTIC", "LAW=SILENT_TEST"))
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    text = str(info.value)
    assert "d.dat:25: *CHECK: TYPE=ENERGY: material law Silent does not report its energy" in text


# ------------------------------------------------------------------------------------------
# deck errors

BASE = """*MESH, NAME=B, TYPE=Q8PE, X0=0, Y0=0, LX=2, LY=1, NX=2, NY=1
*NODE
900, 1, 3
*MATERIAL, NAME=M, LAW=ELASTIC
E=1000, NU=0.3
*SOLID, ELSET=B, MATERIAL=M
*FOUNDATION, NAME=F, REF NODE=900
5, 1
1, 1
-3, 1
*FOUNDATION, NAME=G
-3, 0
1, 0
5, 0
*CONTACT LAW, NAME=C, TYPE=COULOMB
KP=1e5, KT=1e5, PHI=0.2
*CONTACT, SURFACE=B_TOP, FOUNDATION=F, LAW=C
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=G, LAW=C
*STEP
*STATIC
1, 1
*BOUNDARY
900, 1, 6, 0
B_BOTTOM, 2, 2, 0
*END STEP
"""

_NO_900 = ("900, 1, 6, 0\n", "")          # the BOUNDARY on node 900, left out with it
ERRORS = [
    ("REF NODE used by an element", ("REF NODE=900", "REF NODE=1"), 7, "FOUNDATION",
     "REF NODE=1 of foundation F is a node of element", _NO_900),
    ("REF NODE undefined", ("REF NODE=900", "REF NODE=77"), 7, "FOUNDATION",
     "REF NODE: node 77 is not defined", _NO_900),
    ("REF NODE with XC", ("REF NODE=900", "REF NODE=900, XC=1"), 7, "FOUNDATION",
     "give REF NODE= or XC=, YC=, not both"),
    ("DOF 6 on an ordinary node", ("B_BOTTOM, 2, 2, 0", "B_BOTTOM, 6, 6, 0"), 24, "BOUNDARY",
     "DOF 6 (a rotation) exists only on the reference node of a tool"),
    ("DOF 3", ("B_BOTTOM, 2, 2, 0", "B_BOTTOM, 3, 4, 0"), 24, "BOUNDARY",
     "DOFs must satisfy 1 <= first <= last <= 6 and include 1"),
    ("moment on a node that is no reference node", ("*END STEP", "*CLOAD\n1, 6, 5\n*END STEP"), 26,
     "CLOAD", "DOF 6 (a rotation) exists only on the reference node of a tool"),
    ("unknown pair", ("*END STEP", "*CHANGE CONTACT LAW, SURFACE=B_TOP, FOUNDATION=G, LAW=C\n*END STEP"),
     25, "CHANGE CONTACT LAW", "no contact pair B_TOP->G (SURFACE=B_TOP, FOUNDATION=G): the *CONTACT "
     "pairs are B_TOP->F, B_BOTTOM->G"),
    ("unknown law", ("*END STEP", "*CHANGE CONTACT LAW, SURFACE=B_TOP, FOUNDATION=F, LAW=WET\n*END STEP"),
     25, "CHANGE CONTACT LAW", "LAW=WET: contact law WET is not defined"),
    ("pair twice", ("*STEP\n", "*CONTACT, SURFACE=B_TOP, FOUNDATION=F, LAW=C\n*STEP\n"), 19, "CONTACT",
     "contact pair B_TOP->F is already defined (line 17)"),
    ("angle without a centre", ("*END STEP", "*FOUNDATION MOTION, NAME=G\n0, 0, 0.1\n*END STEP"), 26,
     "FOUNDATION MOTION", "foundation G has no point to turn about"),
    ("stabilisation of nothing", ("*END STEP", "*CONTACT STABILIZATION, SURFACE=B_LEFT\n*END STEP"),
     25, "CONTACT STABILIZATION", "no contact pair to stabilise (SURFACE=B_LEFT"),
]


@pytest.mark.parametrize("case", ERRORS, ids=[e[0] for e in ERRORS])
def test_tool_deck_errors(tmp_path, case):
    label, edit, line, keyword, words, *more = case
    deck = tmp_path / "bad.dat"
    text = BASE
    for old, new in (edit, *more):
        assert old in text
        text = text.replace(old, new, 1)
    deck.write_text(text)
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    text = str(info.value)
    assert f"bad.dat:{line}: *{keyword}: {words}" in text, text
    assert len(text.strip().splitlines()) == 1, text           # one clear message


def test_base_deck_is_good_and_check_refuses_what_run_refuses(tmp_path):
    deck = tmp_path / "good.dat"
    deck.write_text(BASE)
    model = load_deck(deck)
    assert model.rotation_nodes == [int(np.flatnonzero(model.node_ids == 900)[0])]
    assert model.ndof == 2 * len(model.node_ids) + 1
    bad = tmp_path / "bad.dat"
    bad.write_text(BASE.replace("B_BOTTOM, 2, 2, 0", "B_BOTTOM, 6, 6, 0"))
    cmd = [sys.executable, "-m", "lagamine_py"]
    chk = subprocess.run(cmd + ["check", str(bad)], capture_output=True, text=True)
    rn = subprocess.run(cmd + ["run", str(bad), "-o", str(tmp_path / "o"), "-q"], capture_output=True,
                        text=True)
    assert chk.returncode == rn.returncode == 2
    assert "bad.dat:24: *BOUNDARY: DOF 6" in chk.stderr and "bad.dat:24: *BOUNDARY: DOF 6" in rn.stderr
