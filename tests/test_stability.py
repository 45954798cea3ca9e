"""Failures the stability study provokes must be reported, never passed on as an answer
(docs/stability.md): the classical loading indicator under softening friction, increments
too large to converge without cut-backs, and the Ramberg-Osgood exponent n = 50."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.core.status import STICK
from lagamine_py.laws.contact_point import drive_contact_point as drive
from lagamine_py.laws.coulomb import Coulomb

from runner import run_deck
from test_contact_element import _setup

STUDY = Path(__file__).resolve().parents[1] / "tools" / "study_decks"
SOFT = dict(KP=1000.0, KT=500.0, PHI=0.2, B=2.0, HB=-100.0)


def _excess(res):
    """|tau| - B(lam) - phi p from the law's data (B = max(2 - 100 lam, 0), phi = 0.2)."""
    return np.abs(res["tau"]) - np.maximum(2.0 - 100.0 * res["lam"], 0.0) - 0.2 * res["p"]


def _path():
    return np.r_[0.0, np.full(40, 0.01)], np.r_[0.0, np.linspace(0.0, 0.1, 40)]


@pytest.mark.parametrize("indicator", ("PREDICTOR", "CLASSICAL"))
def test_outside_cone_flags_exactly_the_inadmissible_points(indicator):
    """The law's own test agrees with the cone computed here; only CLASSICAL leaves it."""
    law = Coulomb(**SOFT, INDICATOR=indicator)
    res = drive(law, *_path())
    flags = np.array([law.inadmissible({k: res[k][i] for k in ("tau", "p", "lam")})[()]
                      for i in range(len(res["tau"]))])
    np.testing.assert_array_equal(flags, _excess(res) > 1e-6)
    assert flags.any() == (indicator == "CLASSICAL")


def _sliding_on_softening_cone(indicator, frozen=None):
    law = Coulomb(KP=1e3, KT=5e2, PHI=0.3, B=0.5, HB=-20.0, INDICATOR=indicator)
    grp, u_old, u_new, state, ctx = _setup(3, 3, False, 1.0, 1, "slip", law=law)
    # committed state on the cone, sliding forward: the next increment loads plastically
    state["tau"] = -(law.b + law.phi * state["p"])
    if frozen is not None:
        ctx.freeze_contact = {grp.name: np.full(grp.ng, frozen)}
    return grp.compute(u_new - [0.02, 0.0], u_old, state, ctx)


def test_contact_element_fails_an_increment_that_leaves_the_cone():
    bad = _sliding_on_softening_cone("CLASSICAL")
    assert bad.failure is not None and "outside the friction cone" in bad.failure
    assert "INDICATOR=CLASSICAL" in bad.failure
    assert _sliding_on_softening_cone("PREDICTOR").failure is None
    # a point the solver holds STICK (flip-flop control) is elastic by request: not a failure
    assert _sliding_on_softening_cone("CLASSICAL", frozen=STICK).failure is None


def _run_cli(deck, tmp_path, **params):
    argv = [sys.executable, "-m", "lagamine_py", "run", str(deck), "-o", str(tmp_path), "-q"]
    for k, v in params.items():
        argv += ["--param", f"{k}={v}"]
    return subprocess.run(argv, capture_output=True, text=True, timeout=120)


def test_classical_indicator_run_stops_with_exit_3(tmp_path):
    """The Coulomb block with softening adhesion: the classical indicator stops the run with
    exit 3 and says why; the predictor finishes."""
    out = _run_cli(STUDY / "block_study.dat", tmp_path / "bad", HB=-200, INDICATOR="CLASSICAL")
    assert out.returncode == 3
    assert "outside the friction cone" in out.stderr and "INDICATOR=CLASSICAL" in out.stderr
    ok = _run_cli(STUDY / "block_study.dat", tmp_path / "ok", HB=-200, INDICATOR="PREDICTOR")
    assert ok.returncode == 0, ok.stderr


def test_too_large_rotation_increment_is_a_clear_stop(tmp_path):
    """The cup scene turned by 28.5 degrees in one increment, no cut-back allowed: the first
    Newton iterate inverts the block; the run stops with exit 3, names the failure, and the
    steps that converged are written."""
    out = _run_cli(STUDY / "cup_rotation.dat", tmp_path, DT=0.5, DTMIN=0.5)
    assert out.returncode == 3
    assert "step 3 (TURN) could not converge" in out.stderr
    assert "non-positive det F" in out.stderr
    steps = np.loadtxt(tmp_path / "contact_totals.csv", delimiter=",", skiprows=1,
                       usecols=0, ndmin=1)
    assert set(steps.astype(int)) == {1, 2}


@pytest.mark.parametrize("n", (10, 50))
def test_ramberg_osgood_exponent_50_follows_the_curve(tmp_path, n):
    """n = 50 in five increments of 6 % strain, no cut-back: the uniaxial response is the
    closed-form Ramberg-Osgood curve (the deck's UNIAXIAL_RO check)."""
    from lagamine_py.checks import evaluate_checks
    outcome, _, _ = run_deck(STUDY / "ro_study.dat", tmp_path,
                             {"N": str(n), "DT": "0.2", "DTMIN": "0.2"})
    assert outcome.status == 0
    from lagamine_py.deck import load_deck
    model = load_deck(STUDY / "ro_study.dat", parameters={"N": str(n)})
    (res,) = evaluate_checks(model.checks, tmp_path)
    assert res["error"] < 1e-6
