"""The numba kernels in use: which groups a KERNEL setting switches on, and whole problems and
decks run through them.

The kernels' point-by-point agreement with their NumPy references (every entry point, output
and branch) is ``tests/test_kernel_twins.py``.  Here: the selection rules (KERNEL=NUMPY / NUMBA
/ AUTO, laws and foundations the kernels do not know fall back to NumPy, numba stays optional
and unimported by ``--help``), ``Problem.evaluate`` with the fused solid group scattering
before the contact blocks, whole decks giving the same histories, and Newton's quadratic order
with the kernel's tangent.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py import kernels                                 # noqa: E402
from lagamine_py.deck import load_deck                          # noqa: E402
from lagamine_py.elements.base import StepContext               # noqa: E402
from lagamine_py.laws.coulomb import Coulomb                    # noqa: E402
from lagamine_py.laws.j2 import J2Linear                        # noqa: E402
from lagamine_py.output import default_writers                  # noqa: E402
from lagamine_py.results import read_table                      # noqa: E402
from lagamine_py.solver import problem as problem_mod           # noqa: E402
from lagamine_py.solver import run                              # noqa: E402
from runner import DECKS, Capture, is_quadratic                 # noqa: E402

RTOL = 1e-11


def assert_close(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, what
    scale = float(np.abs(a).max())
    err = float(np.abs(a - b).max())
    assert err <= RTOL * scale, f"{what}: {err:.3g} > {RTOL:g} x {scale:.3g}"


class PluginJ2(J2Linear):
    """A third-party law deriving from a built-in one: the kernel cannot know what it changed."""


def test_unsupported_law_falls_back_to_numpy():
    model = load_deck(DECKS / "coulomb_block.dat")
    problem = problem_mod.build_problem(model)
    problem.set_kernel("NUMBA")
    k = problem.kinds.index("solid")
    assert problem.groups[k].fused
    assert not problem.groups[problem.kinds.index("contact")].fused   # no kernel for contact groups
    problem = problem_mod.build_problem(model)
    g = problem.groups[k]
    g.law = PluginJ2(**{key.upper(): v for key, v in g.law.values.items()
                        if key in ("E", "NU")}, SIGMAY=1e9)
    problem.set_kernel("NUMBA")
    assert g.law.kernel_parameters() is None and not problem.groups[k].fused
    ev = problem.evaluate(np.zeros(problem.ndof), np.zeros(problem.ndof),
                          problem.init_states(), context(problem), True)
    assert ev.results[k].K is not None                         # computed by compute()


def test_coulomb_subclass_takes_numpy_path():
    """A third-party law deriving from COULOMB: the kernel cannot know what it changed."""
    class Mine(Coulomb):
        pass
    params = dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0)
    assert Mine(**params).kernel_vector() is None
    assert Coulomb(**params).kernel_vector() is not None


def test_problem_kernel_setting_reaches_contact_groups():
    """KERNEL=NUMPY forces the NumPy law and projection in contact groups, NUMBA selects their
    kernels, AUTO follows the solid kernel's size rule (press_slide is below it: NumPy)."""
    problem = problem_mod.build_problem(load_deck(DECKS / "press_slide.dat"))
    contact = [g for g, kind in zip(problem.groups, problem.kinds) if kind == "contact"]
    assert contact and problem.solid_elements() < kernels.AUTO_NUMBA_ELEMENTS

    def on():
        flags = {(g._kernel, g.foundation.use_kernel) for g in contact}
        assert len(flags) == 1 and len(set(next(iter(flags)))) == 1
        return next(iter(flags))[0]
    problem.set_kernel("NUMBA")
    assert on()
    problem.set_kernel("NUMPY")
    assert not on()
    problem.set_kernel("AUTO")
    assert not on()


def test_auto_never_picks_the_contact_kernel(monkeypatch):
    """AUTO above the size rule: the solid groups on their kernel, the contact groups on the
    NumPy reference (the contact kernel's compile never pays within a run; NUMBA still takes
    it)."""
    problem = problem_mod.build_problem(load_deck(DECKS / "press_slide.dat"))
    monkeypatch.setattr(kernels, "AUTO_NUMBA_ELEMENTS", 1)
    problem.set_kernel("AUTO")
    solid = [g for g, kind in zip(problem.groups, problem.kinds) if kind == "solid"]
    contact = [g for g, kind in zip(problem.groups, problem.kinds) if kind == "contact"]
    assert solid and all(g.fused for g in solid)
    assert contact and not any(g._kernel or g.foundation.use_kernel for g in contact)
    problem.set_kernel("NUMBA")
    assert all(g._kernel and g.foundation.use_kernel for g in contact)


def context(problem, nlgeom=True):
    zero = {name: np.zeros(2) for name in problem.foundations}
    return StepContext(nlgeom=nlgeom, foundation_old=zero, foundation_new=dict(zero))


def test_evaluate_same_with_both_kernels():
    """Problem.evaluate on a deck with contact: same f_int, CSR data and states (the fused
    solid group scatters before the contact group adds its blocks)."""
    model = load_deck(DECKS / "coulomb_block.dat")
    problem = problem_mod.build_problem(model)
    rng = np.random.default_rng(5)
    n = problem.ndof
    bottom = np.repeat(model.coords[:, 1] < 1e-9, 2)
    u = 1e-3 * rng.standard_normal(n) - 1e-2 * bottom
    states = problem.init_states()
    ctx = context(problem)
    out = {}
    for kernel in ("NUMPY", "NUMBA"):
        problem.set_kernel(kernel)
        out[kernel] = problem.evaluate(u, np.zeros(n), states, ctx, True)
    a, b = out["NUMPY"], out["NUMBA"]
    assert_close(a.f_int, b.f_int, "f_int")
    assert_close(a.data, b.data, "data")
    assert b.scale == pytest.approx(a.scale, rel=1e-12)
    k = problem.kinds.index("solid")
    assert b.results[k].K is None and a.results[k].K is not None
    for key in a.states[k]:
        assert_close(a.states[k][key], b.states[k][key], key)


def test_auto_uses_the_kernel_from_a_model_size(monkeypatch):
    """AUTO: NumPy below AUTO_NUMBA_ELEMENTS solid elements, the kernel from there on."""
    problem = problem_mod.build_problem(load_deck(DECKS / "compression_ro.dat"))
    k = problem.kinds.index("solid")
    n = problem.solid_elements()
    assert n == len(problem.groups[k].dofs) and n < kernels.AUTO_NUMBA_ELEMENTS
    assert problem.kernel == "AUTO" and not problem.groups[k].fused
    monkeypatch.setattr(kernels, "AUTO_NUMBA_ELEMENTS", n)
    problem.set_kernel("AUTO")
    assert problem.groups[k].fused


def test_set_kernel_validates(monkeypatch):
    problem = problem_mod.build_problem(load_deck(DECKS / "compression_ro.dat"))
    with pytest.raises(KeyError):
        problem.set_kernel("FORTRAN")
    monkeypatch.setattr(kernels, "available", lambda: False)        # as without numba installed
    with pytest.raises(KeyError, match="numba"):
        problem.set_kernel("NUMBA")
    problem.set_kernel("AUTO")
    assert not problem.groups[0].fused                               # AUTO falls back to NumPy


COMPANIONS = {"RF1": ("RF1", "RF2"), "RF2": ("RF1", "RF2"), "u1": ("u1", "u2"),
              "u2": ("u1", "u2"), "tau": ("p", "tau"), "T": ("P", "T")}


def _tables(out):
    return {name: read_table(out / name) for name in
            ("reactions.csv", "displacements.csv", "contact.csv", "contact_totals.csv")
            if (out / name).exists()}


@pytest.mark.parametrize("deck", ["compression_ro", "coulomb_block"])
def test_deck_same_results_with_both_kernels(deck, tmp_path):
    tables = {}
    for kernel in ("NUMPY", "NUMBA"):
        model = load_deck(DECKS / f"{deck}.dat")
        for step in model.steps:
            step.controls["KERNEL"] = kernel
        out = tmp_path / kernel
        writers = default_writers(out, model, names=("CONTACT", "REACTIONS", "DISPLACEMENTS"))
        assert run(model, out, writers=writers).status == 0
        tables[kernel] = _tables(out)
    for name, cols in tables["NUMPY"].items():
        other = tables["NUMBA"][name]
        for col, v in cols.items():
            v = np.asarray(v)
            if v.dtype.kind != "f":
                np.testing.assert_array_equal(v, other[col], err_msg=f"{name} {col}")
                continue
            # vector components share a scale (a reaction at an axis is round-off beside RF2)
            scale = max(max(float(np.abs(cols[c]).max(initial=0.0))
                            for c in COMPANIONS.get(col, (col,))), 1e-300)
            assert np.abs(v - other[col]).max(initial=0.0) <= 1e-9 * scale, (name, col)


def test_newton_quadratic_with_the_kernel(tmp_path):
    """Plastic large-strain increments of compression_ro converge quadratically with the
    fused kernel's tangent (as test_verify_nonlinear checks for the default)."""
    model = load_deck(DECKS / "compression_ro.dat")
    for step in model.steps:
        step.controls["KERNEL"] = "NUMBA"
    cap = Capture()
    problem = problem_mod.build_problem(model)
    outcome = run(model, tmp_path, writers=[cap], problem=problem)
    assert outcome.status == 0
    assert problem.kernel == "NUMBA" and problem.groups[problem.kinds.index("solid")].fused
    orders = [o for o in (is_quadratic(r.residual_history) for r in cap.results) if o is not None]
    assert orders and min(orders) > 1.8, orders


def test_help_does_not_import_numba():
    code = ("import sys\nfrom lagamine_py.cli import main\ntry:\n    main(['--help'])\n"
            "except SystemExit:\n    pass\nprint('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "False"
