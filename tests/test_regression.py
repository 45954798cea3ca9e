"""Regression: every deck of ``decks/`` run now agrees with its archived reference.

The references (``decks/reference/<deck>/``) are produced by ``tools/make_references.py``, which
records in ``PROVENANCE`` the command, commit, date, library versions and machine.  A failure here
means the numbers of a deck changed: either a bug, or a deliberate change whose reference must be
regenerated (deck by deck, with the reason in the commit message).

Tolerances are those of ``lagamine-py compare``: relative 1e-6 with an absolute floor of 1e-6
times the scale of the quantity in the reference, where the components of one vector share one
scale (tau with p, T with P, RF1 with RF2, u1 with u2) and forces share the largest force of the
run (a reaction at a symmetry axis is round-off beside the contact force): a quantity that is zero
up to rounding gets the floor of the scale the deck actually produces, not of its own noise.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from lagamine_py.compare import compare_dirs

from conftest import DECKS

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "decks" / "reference"


def test_every_deck_has_a_reference_with_provenance():
    assert DECKS, "no deck found in decks/"
    missing = [d.stem for d in DECKS if not (REFERENCE / d.stem).is_dir()]
    assert not missing, (f"no reference folder for {missing}: "
                         f"run python tools/make_references.py {' '.join(missing)}")
    for d in DECKS:
        prov = (REFERENCE / d.stem / "PROVENANCE").read_text().strip().splitlines()
        assert len(prov) == 1 and prov[0].startswith("produced by `python tools/make_references.py"), d.stem
        assert "git " in prov[0] and "numpy " in prov[0] and "scipy " in prov[0], d.stem


def test_no_orphan_reference():
    """A reference folder whose deck is gone would never be checked."""
    stems = {d.stem for d in DECKS}
    orphans = [p.name for p in REFERENCE.iterdir() if p.is_dir() and p.name not in stems]
    assert not orphans, f"reference folders without a deck: {orphans}"


def test_floor_is_the_companion_scale(tmp_path):
    """A round-off quantity is judged against its companion's and the run's force scale, not its
    own noise: T ~ 1e-12 beside P = 4000, RF1 ~ 1e-14 at an axis beside P."""
    ref, run_ = tmp_path / "ref", tmp_path / "run"
    for d, t, rf1 in ((ref, 1e-12, 1e-14), (run_, 3e-4, 2e-3)):
        d.mkdir()
        (d / "contact_totals.csv").write_text(
            f"step,increment,time,contact,P,T\n1,1,1.0,C,2000.0,{t}\n1,2,2.0,C,4000.0,{-t}\n")
        (d / "reactions.csv").write_text(
            f"step,increment,time,nset,RF1,RF2\n1,1,1.0,AXIS,{rf1},0.0\n1,2,2.0,AXIS,{rf1},0.0\n")
    assert compare_dirs(run_, ref).ok             # 3e-4 and 2e-3 are within 1e-6 * 4000
    (run_ / "reactions.csv").write_text(
        "step,increment,time,nset,RF1,RF2\n1,1,1.0,AXIS,1e-14,0.0\n1,2,2.0,AXIS,0.01,0.0\n")
    rep = compare_dirs(run_, ref)
    assert not rep.ok and "RF1" in rep.text()     # 0.01 is not


@pytest.mark.parametrize("deck", DECKS, ids=[d.stem for d in DECKS])
def test_deck_matches_reference(deck, deck_run):
    """The run of the deck (tests/conftest.py: the reference kernel, the table writers) agrees
    with its archived reference.  The references predate the COPEN sign of ``gap`` and the
    signed-slip and dissipation columns: compare reads them as they are (see compare.py)."""
    ref = REFERENCE / deck.stem
    got = deck_run(deck)
    assert got.outcome.status == 0, f"{deck.name}: {got.outcome.message}"
    if not ref.is_dir():
        pytest.fail(f"no reference for {deck.name}: run python tools/make_references.py {deck.stem}")
    report = compare_dirs(got.outdir, ref)
    assert report.ok, f"{deck.name} differs from {ref}:\n{report.text()}"


#: three of the tool's configurations: OpenBLAS's kernels of two other processor classes,
#: NumPy's AVX-512 loops switched off
OTHER_CPUS = ("sandybridge", "prescott", "numpy-no-avx512")


@pytest.mark.parametrize("cpu", OTHER_CPUS)
def test_main_job_matches_its_reference_with_another_processors_round_off(cpu, tmp_path):
    """The main job, run with the arithmetic of another processor class, still matches its
    reference: its slide step's first increment took 9, 4 or 11 Newton solves across these
    (the contact-state search at the onset of sliding), and while that count decided the
    increment's growth the slide took other increments with NumPy's AVX-512 loops off or
    OpenBLAS's SandyBridge kernels (T mid-slide 0.8 % off: compare failed).  The stepper does not
    grow after a step's first increment (solver/stepper.py)."""
    tool = _tool("other_cpus")            # its configurations, environments and one run
    env = tool.cpu_env(tool.CPUS[cpu])
    if env is None:
        pytest.skip(f"this NumPy dispatches none of {cpu}'s targets")
    verdict = tool.run_one(ROOT / "decks" / "press_slide.dat", env, tmp_path / "out")
    assert verdict.startswith("PASS"), verdict        # the run in a process of its own


def _tool(name: str = "make_references"):
    """The module ``tools/<name>.py``."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_make_references_finds_decks_by_name_and_counts_converged_increments(tmp_path):
    tool = _tool()
    deck = ROOT / "decks" / "press_slide.dat"
    assert tool.resolve_deck("press_slide") == deck.resolve()
    assert tool.resolve_deck("press_slide.dat") == deck.resolve()
    assert tool.resolve_deck(str(deck)) == deck.resolve()
    with pytest.raises(FileNotFoundError):
        tool.resolve_deck("no_such_deck")
    assert tool.all_decks() == DECKS
    sta = tmp_path / "x.sta"
    sta.write_text("step,step_name,increment,time,dt,iterations,residual,cutbacks,failed,reason\n"
                   "1,A,1,0.5,0.5,3,1e-12,0,no,\n1,A,2,1.0,0.5,0,,1,yes,element failure\n"
                   "1,A,2,0.625,0.125,4,1e-12,1,no,\n")
    assert tool._increments(sta) == 2
    env = tool.environment()
    assert env.startswith("git ") and "numpy " in env and "scipy " in env and "Python " in env
