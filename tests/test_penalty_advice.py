"""Penalty advice that is right: each face's own length and its body's E, the faces in contact,
the penalties that play a role, the effect of each named; and the alternation of the contact
stresses reported where it happens, never a run that is correct.

The graded gmsh mesh of docs/examples/meshes (Hertz, h = 0.04 mm at the contact, 1.5 mm away)
carries its own *CHECK HERTZ: its error is the independent measure of "correct"."""
from pathlib import Path

import numpy as np

from lagamine_py.checks.base import evaluate_checks
from lagamine_py.cli import main
from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.deck import load_deck
from lagamine_py.solver.problem import PENALTY_RANGE, alternation_advice

from runner import DECKS

GRADED = Path(__file__).resolve().parents[1] / "docs" / "examples" / "meshes" / "hertz_msh.dat"


def _run(tmp_path, capsys, deck, *params, name="out"):
    out = tmp_path / name
    args = ["run", str(deck), "-o", str(out), "-q"]
    for prm in params:
        args += ["--param", prm]
    assert main(args) == 0
    return capsys.readouterr().err, out


def _hertz_error(out) -> float:
    """The deck's *CHECK HERTZ error of the run in ``out``."""
    results = evaluate_checks(load_deck(GRADED).checks, out)
    return max(r["error"] for r in results)


def test_stiff_penalties_on_a_graded_mesh_are_not_called_wrong(tmp_path, capsys):
    """KP = 1e9 and 1e10 (200 and 2000 E/h on the faces in contact) give Hertz within 1 %: no
    warning.  1e11 (20 000 E/h) is still within 1 %: the warning speaks of conditioning only."""
    for kp, warned in (("1e9", False), ("1e10", False), ("1e11", True)):
        err, out = _run(tmp_path, capsys, GRADED, f"KP={kp}", name=f"out{kp}")
        assert _hertz_error(out) < 0.01
        assert ("warning" in err) == warned, err
        assert "wrong" not in err
        if warned:
            assert "KP = 1e+11 is 1.97e+04 E/h on the 12 face(s) in contact" in err
            assert "too stiff" in err and "Newton" in err


def test_soft_penalties_name_their_effect(tmp_path, capsys, monkeypatch):
    """A soft KP: the body sinks in.  A soft KT plays no role without friction or adhesion; with
    friction it is the elastic slip before sliding, not sinking."""
    err, _ = _run(tmp_path, capsys, GRADED, "KP=1e6", name="soft")
    assert "KP = 1e+06 is 0.197 E/h" in err and "sinks" in err and "KT" not in err
    text = GRADED.read_text()
    frictionless = tmp_path / "hertz_soft_kt.dat"
    frictionless.write_text(text.replace("KT=<KP>", "KT=1e3"))
    (tmp_path / "hertz_quarter.msh").write_bytes((GRADED.parent / "hertz_quarter.msh").read_bytes())
    err, _ = _run(tmp_path, capsys, frictionless, name="nokt")
    assert "warning" not in err
    friction = tmp_path / "hertz_soft_kt_phi.dat"
    friction.write_text(text.replace("KT=<KP>, PHI=0", "KT=1e3, PHI=0.1"))
    err, _ = _run(tmp_path, capsys, friction, name="kt")
    assert "KT = 1e+03 is" in err and "slips elastically by tau/KT before it slides" in err
    assert "sinks" not in err


def test_range_and_its_reasons():
    assert PENALTY_RANGE[0] < 20 and PENALTY_RANGE[1] >= 1e4


def test_advised_penalty_gives_no_warning(tmp_path, capsys):
    err, _ = _run(tmp_path, capsys, DECKS / "flat_punch.dat")
    assert "warning" not in err
    err, _ = _run(tmp_path, capsys, DECKS / "stick_slip.dat", name="ss")   # KT = 1200 E/h
    assert "warning" not in err


def test_advice_is_printed_once_per_run_in_one_process(tmp_path, capsys):
    """Runs through ``main`` in one process (a script, a test suite, the fuzzer) each print
    their advice once; the stderr handler of an earlier run does not linger (it printed the
    advice twice, then a "Logging error" traceback once its stream was closed)."""
    deck = tmp_path / "stiff.dat"
    deck.write_text((DECKS / "coulomb_block.dat").read_text().replace("KT=2e6", "KT=1e9"))
    for k in range(2):
        assert main(["run", str(deck), "-o", str(tmp_path / f"out{k}"), "-q"]) == 0
        err = capsys.readouterr().err
        assert err.count("KT = 1e+09 is") == 1 and "Logging error" not in err


def _chain(rule):
    """Three 3-node faces in a row along y = 0 (corners shared), points in the order of x."""
    from lagamine_py.elements.contact import ContactGroup
    from lagamine_py.foundation import Foundation
    from lagamine_py.laws.coulomb import Coulomb
    coords = np.array([[0, 0], [1, 0], [2, 0], [3, 0], [0.5, 0], [1.5, 0], [2.5, 0]], float)
    faces = np.array([[0, 1, 4], [1, 2, 5], [2, 3, 6]])
    return ContactGroup("c", faces, [1, 2, 3], [1, 1, 1], coords,
                        Foundation([[-5.0, -1.0], [0.0, -1.0], [5.0, -1.0]]), "F",
                        Coulomb(KP=1e3, KT=1e3, PHI=0.3), gauss=rule)


def test_alternation_is_reported_where_it_happens_and_not_for_round_off():
    grp = _chain(3)
    ng = grp.ng
    base = {"p": np.full(ng, 100.0), "tau": np.zeros(ng), "status": np.full(ng, SLIP, np.int8)}
    assert alternation_advice("c", grp, base) is None
    # frictionless contact: tau is round-off of either sign, nothing to report
    noise = dict(base, tau=1e-12 * (-1.0) ** np.arange(ng))
    assert alternation_advice("c", grp, noise) is None
    flips = dict(base, tau=30.0 * (-1.0) ** np.arange(ng))
    text = alternation_advice("c", grp, flips)
    assert "7 slipping point(s) with tau against both neighbours" in text
    assert "GAUSS=LINEAR removes it" in text
    gap = dict(base, p=np.where(np.arange(ng) == 4, 0.0, 100.0),
               status=np.where(np.arange(ng) == 4, OPEN, STICK).astype(np.int8))
    assert "1 point(s) open between closed neighbours" in alternation_advice("c", grp, gap)
    # across faces: the last point of face 0 and the first of face 1 are neighbours
    prev, nxt = grp.chain_neighbours()
    assert nxt[2] == 3 and prev[3] == 2 and prev[0] == -1 and nxt[ng - 1] == -1
    text = alternation_advice("c", _chain("LINEAR"), dict(
        base, p=np.array([100.0, 0.0, 100.0, 100.0, 100.0, 100.0]),
        status=np.array([STICK, OPEN, STICK, STICK, STICK, STICK], np.int8),
        tau=np.zeros(6)))
    assert "GAUSS=LINEAR removes" not in text and "finer mesh" in text
