"""The contract suites (lagamine_py.contracts) over every registered plugin, and their teeth.

* every registered plugin of every kind (the built-ins and any installed third-party package)
  passes its kind's suite; a built-in known to fail a check is listed in KNOWN_FAILURES with
  the reason, and the test insists that it still fails exactly there (it is reported, not
  hidden);
* every check of every suite fails on a deliberately broken plugin (BROKEN: one or more per
  check), so no check is vacuous;
* ``lagamine-py plugins --check`` prints the findings and exits 0 on a good plugin, 1 on a
  broken one, 2 on an unknown name.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lagamine_py import contracts
from lagamine_py.checks.base import Check, CheckError
from lagamine_py.cli import main
from lagamine_py.core.errors import SingularMatrixError
from lagamine_py.core.params import Param
from lagamine_py.core.status import SLIP
from lagamine_py.elements.quad import Q4PlaneStrain, Q8PlaneStrain
from lagamine_py.elements.solid import SolidElement
from lagamine_py.laws.coulomb import Coulomb
from lagamine_py.laws.elastic import LinearElastic
from lagamine_py.laws.j2 import J2Linear
from lagamine_py.output.base import Writer
from lagamine_py.registry import KINDS, REGISTRY
from lagamine_py.solver.linear import LinearSolver, SpluSolver

#: (kind, name) -> {check: why}: built-ins that fail a contract check, left as they are
KNOWN_FAILURES: dict = {}


def _registered():
    return [pytest.param(kind, e.name, id=f"{kind}-{e.name}")
            for kind in KINDS for e in REGISTRY.entries(kind)]


@pytest.mark.parametrize("kind, name", _registered())
def test_every_registered_plugin_honours_its_contract(kind, name):
    findings = contracts.check_plugin(kind, REGISTRY.get(kind, name))
    assert [f.check for f in findings] == list(contracts.ITEMS[kind])
    failed = {f.check: f.detail for f in findings if not f.passed}
    known = {c: why for c, why in KNOWN_FAILURES.get((kind, name), {}).items()
             if any(f.check == c and not f.skipped for f in findings)}
    assert set(failed) == set(known), "\n".join(f"{c}: {d}" for c, d in failed.items())
    if known:
        pytest.xfail("; ".join(f"{c}: {why} ({failed[c]})" for c, why in known.items()))


class Triangle3:
    """A 3-node triangle (one-point rule), declared here only through the Element contract:
    the suite must not assume quadrilaterals."""

    nen = 3
    node_xi = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    faces = ((0, 1), (1, 2), (2, 0))
    outline = (0, 1, 2)
    vtk_cell = 5                                          # VTK_TRIANGLE
    grid_order = 1
    cell_elements = (((0, 0), (1, 0), (1, 1)), ((0, 0), (1, 1), (0, 1)))
    reference_domain = "triangle"
    jacobian_degree = 1              # det J is constant; degree 1 is the lowest Bernstein form

    @classmethod
    def shape_functions(cls, pts):
        x, y = np.asarray(pts, float).T
        dN = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
        return np.stack([1 - x - y, x, y], 1), np.broadcast_to(dN, (len(x), 3, 2)).copy()

    @classmethod
    def gauss_rule(cls):
        return np.array([[1 / 3, 1 / 3]]), np.array([0.5])

    @classmethod
    def recovery_basis(cls, pts, nq):
        return np.ones((len(pts), 1))



class T3PE(Triangle3, SolidElement):
    """3-node plane-strain triangle."""


class T3AX(Triangle3, SolidElement):
    """3-node axisymmetric triangle."""
    axisymmetric = True


@pytest.mark.parametrize("cls", [T3PE, T3AX], ids=["T3PE", "T3AX"])
def test_a_triangle_passes_the_element_suite(cls):
    findings = contracts.check_element(cls)
    assert all(f.passed and not f.skipped for f in findings), \
        "\n".join(f"{f.check}: {f.detail}" for f in findings if not f.passed)
    patch = next(f.detail for f in findings if f.check == "patch test")
    assert patch.startswith("8 elements of 2 x 2 distorted *MESH cells")


# ============================================================================================
# broken plugins, one or more per check


class FaultyShapes(Q4PlaneStrain):
    @classmethod
    def shape_functions(cls, pts):
        N, dN = super().shape_functions(pts)
        N = N.copy()
        N[:, 0] *= 1.01                                 # no partition of unity
        return N, dN


class SwappedDerivatives(Q4PlaneStrain):
    @classmethod
    def shape_functions(cls, pts):
        N, dN = super().shape_functions(pts)
        return N, dN[..., ::-1].copy()                  # dN/deta where dN/dxi belongs


class LightGauss(Q4PlaneStrain):
    @classmethod
    def gauss_rule(cls):
        pts, w = super().gauss_rule()
        return pts, 0.99 * w


class InwardFaces(Q4PlaneStrain):
    faces = ((1, 0), (2, 1), (3, 2), (0, 3))            # clockwise: element on the right


class ScrambledOutline(Q4PlaneStrain):
    outline = (0, 2, 1, 3)


class AcceptsMirrors(Q4PlaneStrain):
    @classmethod
    def invalid(cls, coords):
        bad, detj = super().invalid(coords)
        return np.zeros_like(bad), np.abs(detj)


class UnderstatesJacobianDegree(Q8PlaneStrain):
    jacobian_degree = (1, 1)         # det J of a Q8 is of degree (3, 3): the bound proves nothing


class MeanRecovery(Q4PlaneStrain):
    @classmethod
    def recovery_matrix(cls, nq=None):
        nq = len(cls.gauss_rule()[0]) if nq is None else nq
        return np.full((cls.nen, nq), 1.0 / nq)          # constants only


class PixelCell(Q4PlaneStrain):
    vtk_cell = 8                                         # VTK_PIXEL: another node order


class WeakShear(Q4PlaneStrain):
    def _operator(self, dNdx, r):
        B = super()._operator(dNdx, r)
        B[:, :, 3] *= 0.9                                # a wrong shear strain
        return B


class SmallStrainOnly(Q4PlaneStrain):
    def compute(self, u_new, u_old, state, ctx, tangent=True):
        return super().compute(u_new, u_old, state, replace(ctx, nlgeom=False), tangent)


class StiffTangent(Q4PlaneStrain):
    def compute(self, u_new, u_old, state, ctx, tangent=True):
        res = super().compute(u_new, u_old, state, ctx, tangent)
        if res.K is not None:
            res.K = 1.05 * res.K
        return res


class NeedsAName(LinearElastic):
    params = LinearElastic.params + (Param("TABLE", str, doc="a file name"),)

    @classmethod
    def example_values(cls):
        return {"E": 200e3, "NU": 0.3}                   # TABLE forgotten


class FlatPeeq(LinearElastic):
    def init_state(self, shape):
        st = super().init_state(shape)
        st["peeq"] = np.zeros(shape + (1,))
        return st


class WrongModuli(LinearElastic):
    def elastic_moduli(self):
        return 2 * self.e, self.nu


class GivesUp(J2Linear):
    def update(self, eps, state):
        s, D, new, ok = super().update(eps, state)
        return s, D, new, ok & (np.abs(eps).max(-1) < 1e-4)


class ElasticTangent(J2Linear):
    def update(self, eps, state):
        s, D, new, ok = super().update(eps, state)
        return s, np.broadcast_to(self.D_elastic, D.shape).copy(), new, ok


class Anisotropic(LinearElastic):
    def __init__(self, **values):
        super().__init__(**values)
        self.D = self.D.copy()
        self.D[0, 0] *= 1.5


class WritesPeeqInPlace(J2Linear):
    def update(self, eps, state):
        s, D, new, ok = super().update(eps, state)
        state["peeq"][...] = new["peeq"]                 # the committed state modified
        return s, D, new, ok


class UnbatchedTangent(LinearElastic):
    def update(self, eps, state):
        s, D, new, ok = super().update(eps, state)
        return s, self.D, new, ok


class RectangleDissipation(J2Linear):
    """Reports the plastic dissipation as s_n+1 . deps_p (the rectangle rule), not in the
    trapezoidal form the balance needs: off by 1/2 (s_n+1 - s_n) . deps_p per increment."""

    def energy(self, state_old, state_new):
        psi, _ = super().energy(state_old, state_new)
        s = np.asarray(state_new["eps_e"], float) @ self.D_elastic.T
        dp = np.asarray(state_new["peeq"], float) - np.asarray(state_old["peeq"], float)
        dev = s[..., :3] - s[..., :3].mean(-1, keepdims=True)
        q = np.sqrt(1.5 * (np.sum(dev ** 2, -1) + 2 * s[..., 3] ** 2))
        return psi, q * dp                     # s_n+1 . deps_p


class DoubleSprings(Coulomb):
    """Stores p^2/KP + tau^2/KT: twice the penalty springs' energy."""

    def stored_energy(self, state):
        return 2.0 * super().stored_energy(state)


class CoulombNeedsAName(Coulomb):
    params = Coulomb.params + (Param("TABLE", str, doc="a file name"),)

    @classmethod
    def example_values(cls):
        return {"KP": 1e5, "KT": 1e5, "PHI": 0.3}


class BadStatus(Coulomb):
    def update(self, state, d, du, dv, frozen=None):
        new, tan = super().update(state, d, du, dv, frozen)
        new["status"] = np.where(new["status"] == SLIP, 7, new["status"]).astype(np.int8)
        return new, tan


class ElasticSlipTangent(Coulomb):
    def update(self, state, d, du, dv, frozen=None):
        new, tan = super().update(state, d, du, dv, frozen)
        tan = dict(tan, tau_v=np.full(np.shape(new["tau"]), self.kt))   # wrong where slipping
        return new, tan


class WritesLamInPlace(Coulomb):
    def update(self, state, d, du, dv, frozen=None):
        new, tan = super().update(state, d, du, dv, frozen)
        state["lam"][...] = new["lam"]
        return new, tan


class NarrowCone(Coulomb):
    def inadmissible(self, state):
        return np.abs(state["tau"]) > 0.5 * (self.b + self.phi * state["p"])


class IgnoresHolds(Coulomb):
    def update(self, state, d, du, dv, frozen=None):
        return super().update(state, d, du, dv, None)


class FailsOnAttempts(Writer):
    def failed_attempt(self, attempt):
        print(attempt.residual)                          # FailedAttempt has no `residual`


class NeverFlushes(Writer):
    def start_run(self):
        self.outdir.mkdir(parents=True, exist_ok=True)
        self.fh = open(self.outdir / "rows.csv", "w")

    def increment(self, result):
        self.fh.write(f"{result.step},{result.increment},{result.time!r}\n")

    def close(self, status, message):
        self.fh.close()


class WritesNothing(Writer):
    pass


class WritesElsewhere(Writer):
    where: Path = Path(".")

    def increment(self, result):
        with open(self.where / "elsewhere.csv", "a") as fh:
            fh.write(f"{result.time!r}\n")


class TransposeSolver(SpluSolver):
    def factor(self, A):
        super().factor(A.T.tocsr())                      # solves A^T x = b: fine if symmetric


class EchoSolver(LinearSolver):
    def factor(self, A):
        pass

    def solve(self, b):
        return np.array(b, float)                        # garbage


class StaleSolver(SpluSolver):
    factored = False

    def factor(self, A):
        if not self.factored:                            # keeps its first factorisation
            super().factor(A)
            self.factored = True


class LeastSquares(LinearSolver):
    def factor(self, A):
        self.A = A.toarray()

    def solve(self, b):
        return np.linalg.lstsq(self.A, b, rcond=None)[0]


class BlamesDofZero(SpluSolver):
    def factor(self, A):
        try:
            super().factor(A)
        except SingularMatrixError:
            raise SingularMatrixError([0], "zero pivot") from None


class CheckNeedsAName(Check):
    params = (Param("FILE", str, doc="a table"),)

    def evaluate(self, run):
        raise CheckError("never")


class AlwaysRight(Check):
    def evaluate(self, run):
        return {"measured": {}, "closed_form": {}, "errors": {}, "error": 0.0}


class Crashes(Check):
    def evaluate(self, run):
        return run.table("reactions.csv").keys_of_nothing       # AttributeError


class BareError(Check):
    def evaluate(self, run):
        if not run.table("reactions.csv"):
            raise CheckError("reactions.csv is missing")
        return {"error": 0.1}


#: (kind, broken class, the checks it must fail)
BROKEN = [
    ("elements", FaultyShapes, {"shape functions"}),
    ("elements", SwappedDerivatives, {"shape derivatives"}),
    ("elements", LightGauss, {"gauss rule"}),
    ("elements", InwardFaces, {"faces"}),
    ("elements", ScrambledOutline, {"outline"}),
    ("elements", AcceptsMirrors, {"jacobian check"}),
    ("elements", UnderstatesJacobianDegree, {"jacobian check"}),
    ("elements", MeanRecovery, {"recovery"}),
    ("elements", PixelCell, {"vtk cell"}),
    ("elements", WeakShear, {"patch test"}),
    ("elements", SmallStrainOnly, {"rigid motion"}),
    ("elements", StiffTangent, {"tangent (small strain)", "tangent (NLGEOM)", "tangent later"}),
    ("laws", NeedsAName, {"parameters"}),
    ("laws", FlatPeeq, {"init_state"}),
    ("laws", WrongModuli, {"elastic moduli"}),
    ("laws", GivesUp, {"material-point paths"}),
    ("laws", ElasticTangent, {"tangent"}),
    ("laws", Anisotropic, {"objectivity"}),
    ("laws", WritesPeeqInPlace, {"state unchanged"}),
    ("laws", UnbatchedTangent, {"batched shapes"}),
    ("laws", RectangleDissipation, {"energy"}),
    ("contact_laws", CoulombNeedsAName, {"parameters"}),
    ("contact_laws", BadStatus, {"state and status"}),
    ("contact_laws", ElasticSlipTangent, {"tangent entries", "tangent chained"}),
    ("contact_laws", WritesLamInPlace, {"state unchanged"}),
    ("contact_laws", NarrowCone, {"admissible path"}),
    ("contact_laws", IgnoresHolds, {"frozen holds"}),
    ("contact_laws", DoubleSprings, {"energy"}),
    ("writers", FailsOnAttempts, {"hooks"}),
    ("writers", NeverFlushes, {"flushed"}),
    ("writers", WritesNothing, {"files"}),
    ("writers", WritesElsewhere, {"files"}),
    ("solvers", TransposeSolver, {"non-symmetric"}),
    ("solvers", EchoSolver, {"non-symmetric", "symmetric"}),
    ("solvers", StaleSolver, {"refactor"}),
    ("solvers", LeastSquares, {"singular"}),
    ("solvers", BlamesDofZero, {"singular"}),
    ("checks", CheckNeedsAName, {"parameters"}),
    ("checks", AlwaysRight, {"empty directory"}),
    ("checks", Crashes, {"empty directory"}),
    ("checks", BareError, {"finished run"}),
]


def test_every_check_has_a_broken_plugin_that_fails_it():
    covered = {(kind, c) for kind, _, checks in BROKEN for c in checks}
    assert covered == {(kind, c) for kind in KINDS for c in contracts.ITEMS[kind]}


@pytest.mark.parametrize("kind, cls, must_fail", [pytest.param(*b, id=b[1].__name__)
                                                  for b in BROKEN])
def test_a_broken_plugin_is_caught(kind, cls, must_fail, tmp_path, monkeypatch):
    monkeypatch.setattr(WritesElsewhere, "where", tmp_path)
    findings = contracts.check_plugin(kind, cls)
    failed = {f.check: f.detail for f in findings if not f.passed}
    assert must_fail <= set(failed), failed
    for c in must_fail:
        assert failed[c] and not failed[c].startswith("not checked"), failed[c]


def test_what_the_failures_say():
    """The details give the numbers compared."""
    def detail(kind, cls, check):
        return next(f.detail for f in contracts.check_plugin(kind, cls) if f.check == check)

    assert "max |D - D_fd| / max |D_fd| = " in detail("laws", ElasticTangent, "tangent")
    assert "plastic loading" in detail("laws", ElasticTangent, "tangent")
    assert "modified the committed state" in detail("laws", WritesPeeqInPlace,
                                                    "state unchanged")
    assert "peeq" in detail("laws", WritesPeeqInPlace, "state unchanged")
    text = detail("writers", NeverFlushes, "flushed")
    assert "rows.csv holds" in text and "unflushed bytes" in text
    assert "names [0]" in detail("solvers", BlamesDofZero, "singular")
    # K scaled by 1.05: the relative error is 0.05 exactly
    assert "max |K - K_fd| / max |K_fd| = 5.00e-02 > 1e-06" in detail(
        "elements", StiffTangent, "tangent (small strain)")
    assert "tau_v" in detail("contact_laws", ElasticSlipTangent, "tangent entries")
    assert "faces" not in detail("elements", InwardFaces, "outline")


# ============================================================================================
# the command


@pytest.fixture
def broken_law_registered():
    REGISTRY.load()
    REGISTRY.add("laws", "ELASTIC_TANGENT", ElasticTangent, "test-suite 0")
    yield "ELASTIC_TANGENT"
    REGISTRY.tables["laws"].pop("ELASTIC_TANGENT")


def test_plugins_check_on_a_good_plugin(capsys):
    assert main(["plugins", "--check", "j2_linear"]) == 0
    out = capsys.readouterr().out
    assert "material law J2_LINEAR (lagamine_py" in out and "): passed" in out
    assert "  ok    tangent: " in out and "max |D - D_fd| / max |D_fd| = " in out
    assert out.rstrip().endswith("1 plugin(s) checked: 1 passed")


def test_plugins_check_on_a_broken_plugin(capsys, broken_law_registered):
    assert main(["plugins", "--check", broken_law_registered, "ELASTIC"]) == 1
    out = capsys.readouterr().out
    assert "material law ELASTIC_TANGENT (test-suite 0): FAILED" in out
    assert "  FAIL  tangent: " in out and "> 1e-05" in out
    assert "material law ELASTIC (lagamine_py" in out
    assert "2 plugin(s) checked: 1 passed, 1 failed (laws ELASTIC_TANGENT)" in out


def test_plugins_check_unknown_name(capsys):
    assert main(["plugins", "--check", "ELASTICK"]) == 2
    assert "no registered plugin ELASTICK (did you mean ELASTIC?)" in capsys.readouterr().err


def test_plugins_lists_the_names_asked(capsys):
    assert main(["plugins", "cpe8"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("elements:\n  Q8PE  (lagamine_py") and "laws:" not in out


def test_sample_run_leaves_no_temporary_files_behind():
    """The suites work in temporary directories and remove them (the sample run's one lives
    as long as the process)."""
    before = set(os.listdir(tempfile.gettempdir()))
    contracts.check_plugin("writers", REGISTRY.get("writers", "REACTIONS"))
    contracts.check_plugin("checks", REGISTRY.get("checks", "COULOMB"))
    after = set(os.listdir(tempfile.gettempdir()))
    assert not {n for n in after - before if n.startswith(("lagamine_writer_",
                                                           "lagamine_check_empty_"))}
    run = contracts.sample_run()
    assert run.status == 0
    kinds = [c[0] for c in run.calls]
    assert kinds.count("failed_attempt") >= 1 and kinds.count("increment") >= 4
