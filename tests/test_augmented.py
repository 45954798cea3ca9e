"""METHOD=AUGMENTED (lagamine_py.solver.augmented): the constraints to PTOL times the face length
with a moderate penalty, measured on the geometry the run reports, not on the multipliers.

* Hertz on the graded gmsh mesh (h = 0.04 mm at the contact), KP = 1e8 = 20 E/h: the penetration
  of every closed point (``-gap`` of contact.csv, the geometry) is below PTOL h, where the same
  penalty alone sinks more than 10 times deeper; the contact force is that of a penalty 100 times stiffer.
* Partial slip (the Cattaneo-Mindlin deck, coarse): the points that stick through the whole shear
  step move with the flat, ``|dx - TRAVEL| <= PTOL h`` (the elastic stick slip), where the
  penalty alone lets them lag by more than 3 times that (20 times the augmented lag).
"""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.core.params import ParamError
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.results import read_table

ROOT = Path(__file__).resolve().parents[1]
GRADED = ROOT / "docs" / "examples" / "meshes" / "hertz_msh.dat"
H_CONTACT = 0.04                     # the graded mesh's face length at the contact (its header)


def _run(tmp_path, deck_text, name, *params, files=()):
    deck = tmp_path / f"{name}.dat"
    deck.write_text(deck_text)
    for src in files:
        dst = tmp_path / src.name
        if src.is_dir():
            if not dst.exists():
                dst.symlink_to(src)
        else:
            dst.write_bytes(src.read_bytes())
    out = tmp_path / f"out_{name}"
    args = ["run", str(deck), "-o", str(out), "-q"]
    for prm in params:
        args += ["--param", prm]
    assert main(args) == 0
    return out


def _last(out):
    pts = read_table(out / "contact.csv")
    inc = np.asarray(pts["increment"], float) + 1e6 * np.asarray(pts["step"], float)
    last = inc == inc.max()
    return {k: np.asarray(pts[k])[last] for k in ("x", "p", "gap", "status")}


def test_ptol_is_required_and_belongs_to_augmented():
    with pytest.raises(ParamError, match="PTOL"):
        Coulomb(KP=1e8, KT=1e8, PHI=0.3, METHOD="AUGMENTED")
    with pytest.raises(ParamError, match="PTOL"):
        Coulomb(KP=1e8, KT=1e8, PHI=0.3, PTOL=1e-3)


def test_hertz_penetration_within_ptol_at_20_e_over_h(tmp_path):
    text = GRADED.read_text()
    mesh = GRADED.parent / "hertz_quarter.msh"
    pen = _run(tmp_path, text, "penalty", "KP=1e8", files=[mesh])
    stiff = _run(tmp_path, text, "stiff", "KP=1e10", files=[mesh])
    aug_text = text.replace("KP=<KP>, KT=<KP>, PHI=0",
                            "KP=<KP>, KT=<KP>, PHI=0, METHOD=AUGMENTED, PTOL=1e-4")
    aug = _run(tmp_path, aug_text, "augmented", "KP=1e8", files=[mesh])
    r_pen, r_aug = _last(pen), _last(aug)
    closed = r_aug["status"] != "open"
    sink_aug = float(np.max(-r_aug["gap"][closed]))
    sink_pen = float(np.max(-r_pen["gap"][r_pen["status"] != "open"]))
    assert sink_aug <= 1e-4 * H_CONTACT * (1 + 1e-6)
    assert sink_pen > 10 * 1e-4 * H_CONTACT      # the penalty alone: p0 / KP ~ 5e-5 mm
    # under the imposed DEPTH the body's sinking costs force: the contact force of the
    # 100 x stiffer penalty (KP = 1e10 sinks by 5e-7 mm, about 1e-5 of DEPTH)
    force = {name: abs(float(read_table(out / "contact_totals.csv")["P"][-1]))
             for name, out in (("penalty", pen), ("stiff", stiff), ("augmented", aug))}
    assert abs(force["augmented"] / force["stiff"] - 1) < 5e-5
    assert abs(force["penalty"] / force["stiff"] - 1) > 5e-4
    log = (aug / "augmented.log").read_text()
    assert "augmented Lagrangian: " in log and "augmentation 1:" in log


def test_partial_slip_sticking_points_move_with_the_flat(tmp_path):
    """The Cattaneo-Mindlin deck (coarse mesh, h = 0.267 mm), sheared by TRAVEL = 0.02 mm in
    two increments; GAUSS=LINEAR (an exact constraint at 3 Gauss points per face alternates on
    this coarse mesh, as a stiff penalty does: docs/accuracy_speed.md)."""
    text = (ROOT / "decks" / "cattaneo_mindlin.dat").read_text().replace(
        "LAW=DRY, GAUSS=3", "LAW=DRY, GAUSS=LINEAR")
    meshes = ROOT / "decks" / "meshes"
    h, travel, ptol = 1.6 / 6, 0.02, 1e-4
    params = (f"TRAVEL={travel}", "DT=0.5")
    lags = {}
    for name, law in (("penalty", "PHI=0.3"),
                      ("augmented", f"PHI=0.3, METHOD=AUGMENTED, PTOL={ptol:g}")):
        out = _run(tmp_path, text.replace("PHI=0.3\n", law + "\n", 1), name, *params,
                   files=[meshes])
        pts = read_table(out / "contact.csv")
        step, inc = np.asarray(pts["step"]), np.asarray(pts["increment"])
        press = (step == 1) & (inc == inc[step == 1].max())
        shear = step == 2
        ends = [shear & (inc == k) for k in np.unique(inc[shear])]
        key = lambda m: np.asarray(pts["element"])[m] * 10 + np.asarray(pts["gauss"])[m]  # noqa
        assert all(np.array_equal(key(press), key(e)) for e in ends)
        stuck = np.asarray(pts["status"])[press] == "stick"
        for e in ends:
            stuck &= np.asarray(pts["status"])[e] == "stick"
        assert stuck.sum() >= 4
        x = np.asarray(pts["x"], float)
        dx = x[ends[-1]][stuck] - x[press][stuck]
        lags[name] = float(np.abs(dx - travel).max())
    assert lags["augmented"] <= ptol * h * (1 + 1e-6)
    assert lags["penalty"] > 3 * ptol * h and lags["penalty"] > 10 * lags["augmented"]


def test_an_augmentation_that_fails_keeps_the_converged_solve(tmp_path, monkeypatch):
    """The second solve of every increment made to diverge: the increment keeps the first
    (converged) solve and the log says so; the run does not cut back.  The first solve failing
    is an ordinary failure (cut-back)."""
    from lagamine_py.core.errors import DivergingResidual
    from lagamine_py.solver import steps

    real = steps.solve_increment

    def second_fails(problem, solver, free, u_old, states, *args, **kw):
        # a solve with multipliers (an increment's first starts from none: one increment here)
        if any(np.any(np.asarray(s.get("an", 0.0)) != 0) for s in states):
            raise DivergingResidual("made to fail", [1.0])
        return real(problem, solver, free, u_old, states, *args, **kw)

    monkeypatch.setattr(steps, "solve_increment", second_fails)
    text = GRADED.read_text().replace("KP=<KP>, KT=<KP>, PHI=0",
                                      "KP=<KP>, KT=<KP>, PHI=0, METHOD=AUGMENTED, PTOL=1e-4")
    out = _run(tmp_path, text, "fails", "KP=1e8", files=[GRADED.parent / "hertz_quarter.msh"])
    log = (out / "fails.log").read_text()
    assert "solve 2 did not converge (made to fail); the increment keeps solve 1" in log
    assert "attempt failed" not in log
    # the penalty answer: the penetration of KP = 1e8 alone
    r = _last(out)
    assert float(np.max(-r["gap"][r["status"] != "open"])) > 10 * 1e-4 * H_CONTACT


def test_energy_check_is_refused_with_augmented(tmp_path, capsys):
    """The multipliers' work is not in the balance: an energy check with METHOD=AUGMENTED would
    report p^2/2KP as the stored energy, a wrong number; check and run refuse it (exit 2)."""
    text = (ROOT / "decks" / "coulomb_block.dat").read_text()
    text = text.replace("KP=2e6, KT=2e6, PHI=0.3, B=5",
                        "KP=2e6, KT=2e6, PHI=0.3, B=5, METHOD=AUGMENTED, PTOL=1e-3", 1)
    text = text.replace("*STEP, NAME=PRESS", "*CHECK, NAME=BALANCE, TYPE=ENERGY\n*STEP, NAME=PRESS", 1)
    deck = tmp_path / "block.dat"
    deck.write_text(text)
    for cmd in (["check", str(deck)], ["run", str(deck), "-o", str(tmp_path / "out"), "-q"]):
        assert main(cmd) == 2
        assert "METHOD=AUGMENTED reports no stored (penalty) energy" in capsys.readouterr().err
    assert not (tmp_path / "out" / "contact.csv").exists()
