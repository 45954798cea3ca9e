"""The numba kernel of the solid groups against the NumPy path (the reference implementation).

For every element type x law x kinematics, on a distorted mesh with random (not small)
displacement increments from a random committed state with plastic points, the fused
compute + scatter (``SolidGroup.compute_into``) gives the same global force, the same CSR data
and the same trial state as ``SolidGroup.compute`` followed by the pattern's scatter, to 1e-11
of each array's largest entry; the same failures with the same messages; whole decks give the
same histories; Newton stays quadratic.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py.deck import load_deck                          # noqa: E402
from lagamine_py.elements.base import StepContext               # noqa: E402
from lagamine_py.elements.structured import rectangle           # noqa: E402
from lagamine_py.core.tensors import von_mises
from lagamine_py.laws.j2 import J2Linear             # noqa: E402
from lagamine_py.output import default_writers                  # noqa: E402
from lagamine_py.registry import get                            # noqa: E402
from lagamine_py.results import read_table                      # noqa: E402
from lagamine_py import kernels                                 # noqa: E402
from lagamine_py.solver import problem as problem_mod           # noqa: E402
from lagamine_py.solver import run                              # noqa: E402
from lagamine_py.solver.pattern import Pattern                  # noqa: E402
from runner import DECKS, Capture, is_quadratic                 # noqa: E402

ELEMENTS = ("Q8PE", "Q8AX", "Q8PER", "Q8AXR", "Q4PE", "Q4AX", "T6PE", "T6AX")
LAWS = {
    "ELASTIC": dict(E=210e3, NU=0.3),
    "J2_LINEAR": dict(E=210e3, NU=0.3, SIGMAY=250.0, H=2000.0),
    "RAMBERG_OSGOOD": dict(E=210e3, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0),
}
RTOL = 1e-11


def mesh(cls, nx: int = 4, ny: int = 3, seed: int = 0):
    """Distorted structured mesh of the annulus-like region r in [1, 3] (positive radius for
    the axisymmetric types), filled with elements of ``cls`` as ``*MESH`` fills a rectangle
    (the class's own cells): coordinates (n, 2), connectivity (e, nen)."""
    rng = np.random.default_rng(seed)
    m = rectangle(cls, 1.0, 0.0, 2.0, 1.5, nx, ny)
    xy = m.coords + 0.04 * rng.uniform(-1, 1, m.coords.shape)    # distorted, still valid
    return xy, m.conn


def setup(etype: str, law_name: str, seed: int = 1, amplitude: float = 0.02):
    cls = get("elements", etype)
    xy, conn = mesh(cls)
    law = get("laws", law_name)(**LAWS[law_name])
    group = cls(np.arange(100, 100 + len(conn)), conn, xy, law, 2.0)
    rng = np.random.default_rng(seed)
    state = group.init_state()
    state["eps_e"] = 1e-3 * rng.standard_normal(state["eps_e"].shape)
    state["peeq"] = np.abs(2e-3 * rng.standard_normal(state["peeq"].shape))
    state["peeq"][0] = 0.0                     # virgin points: RO's small-correction branch
    state["eps_e"][0] *= 0.05
    u_old = 0.05 * amplitude * rng.standard_normal(xy.shape)
    du = amplitude * rng.standard_normal(xy.shape)
    du[conn[0]] *= 1e-3                        # a small increment: small plastic corrections
    return group, state, u_old + du, u_old


def both(group, state, u_new, u_old, nlgeom, tangent=True):
    """(NumPy result, force vector, data), (numba result, force vector, data)."""
    pattern = Pattern(2 * len(group.coords0), [group.dofs])
    ctx = StepContext(nlgeom=nlgeom)
    r0 = group.compute(u_new, u_old, state, ctx, tangent)
    f0 = pattern.group_vector(0, r0.f)
    d0 = pattern.assemble_data([r0.K]) if tangent else None
    f1 = np.zeros(pattern.ndof)
    d1 = np.zeros(pattern.nnz) if tangent else None
    r1 = group.compute_into(u_new, u_old, state, ctx, tangent, d1, f1, pattern.positions[0])
    return (r0, f0, d0), (r1, f1, d1)


def assert_close(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, what
    scale = float(np.abs(a).max())
    err = float(np.abs(a - b).max())
    assert err <= RTOL * scale, f"{what}: {err:.3g} > {RTOL:g} x {scale:.3g}"


@pytest.mark.parametrize("nlgeom", [False, True], ids=["small", "nlgeom"])
@pytest.mark.parametrize("law_name", list(LAWS))
@pytest.mark.parametrize("etype", ELEMENTS)
def test_kernel_equals_numpy(etype, law_name, nlgeom):
    group, state, u_new, u_old = setup(etype, law_name)
    assert group.law.kernel_parameters() is not None
    (r0, f0, d0), (r1, f1, d1) = both(group, state, u_new, u_old, nlgeom)
    assert r0.failure is None and r1.failure is None
    if law_name != "ELASTIC":                  # the return map is exercised, not only elasticity
        plastic = r0.state["peeq"] > state["peeq"]
        assert plastic.mean() > 0.5
        # RO yields from zero stress: element 0's small increment is plastic too; J2_LINEAR
        # keeps it elastic (both branches of the radial return)
        assert plastic[0].any() == (law_name == "RAMBERG_OSGOOD")
    assert_close(f0, f1, "global force")
    assert_close(d0, d1, "CSR data")
    assert_close(r0.f, r1.f, "element forces")
    assert r1.K is None
    assert list(r0.state) == list(r1.state)
    for k in r0.state:
        assert_close(r0.state[k], r1.state[k], f"state {k}")


@pytest.mark.parametrize("etype", ["Q8AX", "Q4PE"])
def test_kernel_without_tangent(etype):
    group, state, u_new, u_old = setup(etype, "RAMBERG_OSGOOD", seed=3)
    for nlgeom in (False, True):
        (r0, f0, d0), (r1, f1, d1) = both(group, state, u_new, u_old, nlgeom, tangent=False)
        assert d0 is None and d1 is None
        assert_close(f0, f1, "global force")
        for k in r0.state:
            assert_close(r0.state[k], r1.state[k], f"state {k}")


def test_ramberg_osgood_both_branches_of_the_return_map():
    """The comparison above covers both unknowns of RambergOsgood._return_map: points whose
    root has rho = q / (3G N peeq) > 1 (solved in ln P) and rho <= 1 (solved in ln q)."""
    group, state, u_new, u_old = setup("Q8PE", "RAMBERG_OSGOOD")
    law = group.law
    r = group.compute(u_new, u_old, state, StepContext(nlgeom=False), False)
    plastic = r.state["peeq"] > state["peeq"]
    rho = von_mises(r.state["stress"]) / (3 * law.G * law.values["N"] * r.state["peeq"])
    assert (rho[plastic] > 1).any() and (rho[plastic] <= 1).any()


def test_non_positive_det_f_same_failure():
    group, state, u_new, u_old = setup("Q8PE", "J2_LINEAR")
    first = group.conn[[2, 7]]
    u_new = u_new.copy()
    for c in first:                             # fold elements 2 and 7 over themselves
        u_new[c[2]] = group.coords0[c[0]] - group.coords0[c[2]]
    (r0, _, _), (r1, _, _) = both(group, state, u_new, u_old, nlgeom=True)
    assert r0.failure is not None and r0.failure.startswith("non-positive det F")
    assert r1.failure == r0.failure
    assert "102" in r1.failure and "107" in r1.failure


def test_return_mapping_failure_same_failure():
    """Ramberg-Osgood with a 2-iteration cap fails on some points: the same elements."""
    group, state, u_new, u_old = setup("Q8AX", "RAMBERG_OSGOOD")
    group.law.max_iter = 2                      # instance attribute read by both paths
    for nlgeom in (False, True):
        (r0, _, _), (r1, _, _) = both(group, state, u_new, u_old, nlgeom)
        assert r0.failure is not None and r0.failure.startswith("return mapping failed")
        assert r1.failure == r0.failure


def test_nan_displacement_is_a_return_mapping_failure_in_j2():
    group, state, u_new, u_old = setup("Q4AX", "J2_LINEAR")
    u_new = u_new.copy()
    u_new[3] = np.nan
    (r0, _, _), (r1, _, _) = both(group, state, u_new, u_old, nlgeom=False)
    assert r0.failure is not None and r1.failure == r0.failure


def test_reference_jacobian_failure():
    group, state, u_new, u_old = setup("Q8AX", "ELASTIC")
    group._bad0 = group._bad0.copy()
    group._bad0[1] = True
    (r0, _, _), (r1, _, _) = both(group, state, u_new, u_old, nlgeom=False)
    assert r0.failure is not None and r1.failure == r0.failure


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
