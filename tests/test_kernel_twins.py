"""Every numba kernel against its NumPy twin: one table, one row per kernel entry point.

Each kernel of :mod:`lagamine_py.kernels` does, point by point, what a NumPy reference does array
by array.  A row of :data:`TABLE` names a kernel entry point, how to build the batches (each one:
the NumPy reference call and the kernel call on the same inputs) and the branches the batches
must visit.  For every batch :func:`test_twin`

* runs the NumPy reference and checks that it called no kernel (``kernels.calls`` unchanged);
* runs the kernel path and checks that the entry points ran exactly as often as the batch says
  (a twin test comparing NumPy with NumPy, or an untested fast path, fails here);
* compares every output (forces, CSR data, every trial-state array, failure messages and raised
  errors, every projection field and derivative) with :func:`assert_twin`;
* counts, from the reference's inputs and outputs, the points that went through each branch.

Then every branch of the row must have been visited.  The batches reach the branches on purpose:
committed states set by hand (points on the yield surface, virgin points, points held by the
flip-flop control, states just before a softening kink ...) and displacements chosen to land
there.  ``tools/kernel_mutations.py`` proves the table can fail: it breaks each branch of the
kernels (and a few of the references) one at a time and runs this module.

Tolerance: :data:`RTOL` = 1e-12 of each array's largest entry.  The kernels evaluate the same
formulas in the same order as the references, but NumPy sums some of them in another order or
as BLAS products (einsum/matmul over nodes and Gauss points, the CSR scatter, the 8-point
dissipation sum) and takes 2x2 eigenvectors through arctan2/cos/sin where the kernels use
trigonometry-free formulas.  Largest differences measured, relative to the array's largest
entry: solid_group 2.4e-13 (the elastic strains under NLGEOM: 1/2 ln b with b near 1 carries an
absolute round-off of ~1 ulp of 1, 2e-16, against strains of 1e-3), start_group 6e-14 (the
off-diagonal of b_e_n, 1e-3 beside a diagonal of 1), contact_group 4e-16 (the dissipation's
sum), project_points 0 (bit for bit).  A broken branch shows far above it: among the
mutations of ``tools/kernel_mutations.py`` caught by a number, the first difference found is at
least 1.6e-5 of its array's largest entry (median 3e-2); the others change a message, a flag,
a NaN or the outputs' keys.  Integers, booleans, messages, NaN and infinity patterns must be
equal exactly.

Known disagreements, left out of the batches (each path decides on its own round-off):

* NLGEOM, a point re-evaluated at its converged state with a very low stress (10 MPa, the
  virgin element of :func:`solid_setup`): at a zero increment the Hencky trial strain differs
  from the committed one by ~4e-16 (F F_old^-1, exp and log), 1e-11 of such a strain, more than
  ``YIELD_RTOL`` = 1e-12; NumPy then calls 1 or 2 points of a group plastic (dpeeq ~ 1e-28,
  tangent different by 1e-8 relative) where the kernel keeps them elastic.
* Small strain, a NaN displacement at a contact face's node whose line then misses the
  foundation: NumPy's tangent shortcut (``Coulomb._tangent_simple``, taken when no point of the
  group re-contacts or separates) keeps K finite, the kernel's general formula gives NaN * 0 =
  NaN in that face's block of K; neither reports a failure (f, p and tau are finite).
"""
from __future__ import annotations

import copy
from collections import Counter
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
import pytest

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py import kernels                                  # noqa: E402
from lagamine_py.core.errors import ReturnMappingError           # noqa: E402
from lagamine_py.core.status import OPEN, SLIP, STICK            # noqa: E402
from lagamine_py.core.tensors import left_normal, von_mises      # noqa: E402
from lagamine_py.elements.base import StepContext                # noqa: E402
from lagamine_py.elements.contact import ContactGroup, normal_axis  # noqa: E402
from lagamine_py.elements.solid import SolidElement              # noqa: E402
from lagamine_py.elements.structured import rectangle            # noqa: E402
from lagamine_py.foundation import Foundation                    # noqa: E402
from lagamine_py.kernels import layout                           # noqa: E402
from lagamine_py.laws.coulomb import Coulomb                     # noqa: E402
from lagamine_py.registry import REGISTRY                        # noqa: E402
from lagamine_py.solver.pattern import Pattern                   # noqa: E402

RTOL = 1e-12


# --------------------------------------------------------------------------------------------
# the comparison

def assert_twin(ref, fast, what: str, rtol: float = RTOL) -> None:
    """``fast`` equals ``ref``: exactly for anything but floats; floats with NaN and infinities
    at the same places and the finite entries within ``rtol`` of the array's largest entry."""
    if ref is None or isinstance(ref, (str, tuple)):
        assert fast == ref, f"{what}: kernel {fast!r} != reference {ref!r}"
        return
    a, b = np.asarray(ref), np.asarray(fast)
    assert a.shape == b.shape, f"{what}: shape {b.shape} != reference {a.shape}"
    assert a.dtype == b.dtype, f"{what}: dtype {b.dtype} != reference {a.dtype}"
    if a.dtype.kind != "f":
        bad = np.flatnonzero(a.ravel() != b.ravel())
        assert bad.size == 0, (f"{what}: {bad.size} entries differ, first at {bad[0]}: "
                               f"kernel {b.ravel()[bad[0]]} != reference {a.ravel()[bad[0]]}")
        return
    assert np.array_equal(np.isnan(a), np.isnan(b)), f"{what}: NaN at other places"
    inf = np.isinf(a)
    assert np.array_equal(a[inf], b[inf]) and not np.isinf(b[~inf]).any(), \
        f"{what}: infinities differ"
    ok = np.isfinite(a)
    scale = float(np.abs(a[ok]).max(initial=0.0))
    err = np.abs(a[ok] - b[ok])
    worst = float(err.max(initial=0.0))
    assert worst <= rtol * scale, (f"{what}: max |kernel - reference| {worst:.3g} > "
                                   f"{rtol:g} x {scale:.3g} (at {int(np.argmax(err))})")


# --------------------------------------------------------------------------------------------
# the table

@dataclass
class Batch:
    """One comparison: ``reference()`` and ``kernel()`` return dicts of outputs (same keys);
    ``calls`` the increments of ``kernels.calls`` the kernel call must make; ``branches(ref)``
    the points per branch, counted from the reference's outputs."""
    label: str
    reference: Callable[[], dict]
    kernel: Callable[[], dict]
    calls: dict
    branches: Callable[[dict], Counter]


@dataclass
class Twin:
    """A row: the kernel entry point, its batches, the branches they must visit."""
    entry: str
    batches: Callable[[], Iterator[Batch]]
    required: Callable[[], list[str]]


def _calls() -> dict:
    return {k: v for k, v in kernels.calls.items() if v}


def _delta(before: dict, after: dict) -> dict:
    return {k: after.get(k, 0) - before.get(k, 0) for k in set(before) | set(after)
            if after.get(k, 0) != before.get(k, 0)}


def run_twin(twin: Twin) -> Counter:
    """Run every batch of ``twin`` (the checks of the module docstring); the branch counts."""
    visited: Counter = Counter()
    for batch in twin.batches():
        before = _calls()
        ref = batch.reference()
        assert _calls() == before, f"{batch.label}: the NumPy reference called a kernel " \
                                   f"{_delta(before, _calls())}"
        fast = batch.kernel()
        ran = _delta(before, _calls())
        assert ran == batch.calls, f"{batch.label}: kernel calls {ran}, expected {batch.calls}"
        assert set(fast) == set(ref), f"{batch.label}: outputs {sorted(fast)} != {sorted(ref)}"
        for key in ref:
            assert_twin(ref[key], fast[key], f"{batch.label}: {key}")
        visited += batch.branches(ref)
    return visited


# --------------------------------------------------------------------------------------------
# row kernels.solid.solid_group: SolidElement.compute_into against SolidElement.compute

#: parameters of every built-in material law (the kernel knows ELASTIC, J2_LINEAR and
#: RAMBERG_OSGOOD; a new built-in law needs its line here)
SOLID_LAWS = {
    "ELASTIC": dict(E=210e3, NU=0.3),
    "J2_LINEAR": dict(E=210e3, NU=0.3, SIGMAY=250.0, H=2000.0),
    "RAMBERG_OSGOOD": dict(E=210e3, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0),
    "J2_TABLE": dict(E=210e3, NU=0.3, PLASTIC=((250.0, 0.0), (300.0, 0.01))),   # no kernel (NumPy)
}
KIND_NAMES = {layout.ELASTIC: "ELASTIC", layout.J2_LINEAR: "J2_LINEAR",
              layout.RAMBERG_OSGOOD: "RAMBERG_OSGOOD"}


def element_classes() -> list[tuple[str, type]]:
    """Every registered element type.  All must be SolidElements (the solid kernel computes
    them); a type that is not is an error here, not a silent skip."""
    out = []
    for entry in REGISTRY.entries("elements"):
        assert issubclass(entry.cls, SolidElement), (
            f"element {entry.name} is not a SolidElement: give it a twin row of its own")
        out.append((entry.name, entry.cls))
    assert out
    return out


def kernel_laws() -> dict[str, object]:
    """Every built-in material law with a kernel, built from :data:`SOLID_LAWS`; they must
    cover every law kind the kernel knows."""
    laws = {}
    for entry in REGISTRY.entries("laws"):
        if not entry.builtin:
            continue
        assert entry.name in SOLID_LAWS, f"built-in law {entry.name}: add it to SOLID_LAWS"
        law = entry.cls(**SOLID_LAWS[entry.name])
        if law.kernel_parameters() is not None:
            laws[entry.name] = law
    kinds = {law.kernel_parameters()[0] for law in laws.values()}
    assert kinds == set(KIND_NAMES), f"kernel law kinds covered: {kinds}"
    return laws


def solid_mesh(cls, seed: int):
    """A distorted structured mesh (curved sides, no two elements alike) of r in [1, 3]
    (positive radius for the axisymmetric types): coordinates (n, 2), connectivity (e, a)."""
    rect = rectangle(cls, 1.0, 0.0, 2.0, 1.5, 4, 3)
    rng = np.random.default_rng(seed)
    xy = rect.coords.copy()
    x, y = rect.coords.T
    xy[:, 0] += 0.06 * np.sin(2.0 * y)
    xy[:, 1] += 0.05 * np.sin(3.0 * x)
    xy += 0.03 * rng.uniform(-1.0, 1.0, xy.shape)
    bad, _ = cls.invalid(xy[rect.conn])
    assert not bad.any()
    return xy, rect.conn


def solid_setup(cls, law, seed: int = 1, virgin: bool = True):
    """A group with a random committed state and a random (not small) increment.

    Elements 0 and 1 are virgin (peeq = 0; Ramberg-Osgood yields from zero stress), element 0
    with a tiny elastic strain and moving little (small plastic corrections: RO's return in
    ln P), unless not ``virgin``; the last element starts from an isotropic elastic strain and its nodes do not
    move (equal stretches: the Daleckii-Krein limit under NLGEOM)."""
    xy, conn = solid_mesh(cls, seed)
    group = cls(np.arange(100, 100 + len(conn)), conn, xy, copy.deepcopy(law), 2.0)
    rng = np.random.default_rng(seed)
    state = group.init_state()
    state["eps_e"] = 1e-3 * rng.standard_normal(state["eps_e"].shape)
    state["peeq"] = np.abs(2e-3 * rng.standard_normal(state["peeq"].shape))
    if virgin:
        state["peeq"][:2] = 0.0
        state["eps_e"][0] *= 0.05
    state["eps_e"][-1] = [2e-4, 2e-4, -1e-4, 0.0]
    u_old = 1e-3 * rng.standard_normal(xy.shape)
    du = 0.02 * rng.standard_normal(xy.shape)
    if virgin:
        du[conn[0]] *= 1e-3
    du[conn[-1]] = 0.0
    return group, state, u_old + du, u_old


def solid_near_yield(cls, law, seed: int = 2):
    """A committed state 1 % inside the yield surface at a small peeq (1e-6 to 3e-4) and a
    small increment: points end just past yield."""
    group, state, _, u_old = solid_setup(cls, law, seed, virgin=False)
    rng = np.random.default_rng(seed + 100)
    peeq = 10 ** rng.uniform(-6.0, -3.5, state["peeq"].shape)
    scale = 0.99 * group.law.yield_stress(peeq) / _q_of(group.law, state["eps_e"])
    state["eps_e"] = state["eps_e"] * scale[..., None]
    state["peeq"] = peeq
    return group, state, u_old + 2e-4 * rng.standard_normal(u_old.shape), u_old


def _solid_reference(group, state, u_new, u_old, nlgeom, tangent):
    pattern = Pattern(2 * len(group.coords0), [group.dofs])
    r = group.compute(u_new, u_old, state, StepContext(nlgeom=nlgeom), tangent)
    out = {"failure": r.failure, "f": r.f, "state keys": tuple(r.state)}
    if r.failure is None:
        out["f_global"] = pattern.group_vector(0, r.f)
        out["data"] = pattern.assemble_data([r.K]) if tangent else None
        out.update({f"state {k}": v for k, v in r.state.items()})
    return out


def _solid_kernel(group, state, u_new, u_old, nlgeom, tangent):
    """compute_into adds into the global arrays: they start from nonzero values here."""
    pattern = Pattern(2 * len(group.coords0), [group.dofs])
    base_f = np.linspace(-1.0, 1.0, pattern.ndof)
    base_data = np.linspace(1.0, 2.0, pattern.nnz)
    f_out = base_f.copy()
    data = base_data.copy() if tangent else None
    r = group.compute_into(u_new, u_old, state, StepContext(nlgeom=nlgeom), tangent, data, f_out,
                           pattern.positions[0])
    assert r.K is None                  # the tangent went into data
    out = {"failure": r.failure, "f": r.f, "state keys": tuple(r.state)}
    if r.failure is None:
        out["f_global"] = f_out - base_f
        out["data"] = data - base_data if tangent else None
        out.update({f"state {k}": v for k, v in r.state.items()})
    return out


def _q_of(law, eps_e):
    """Von Mises stress of the elastic strains ``eps_e`` (..., 4) (the Kirchhoff stress's
    under NLGEOM, where the state's stress is the Cauchy stress)."""
    return von_mises(eps_e @ law.D_elastic.T)


def _solid_branches(group, state, nlgeom, tangent, ename):
    law = group.law
    kind = KIND_NAMES[law.kernel_parameters()[0]]

    def count(ref):
        c = Counter()
        if ref["failure"] is not None:
            return c
        n = ref["state peeq"].size
        c[f"element {ename}"] += n
        c[f"law {kind}"] += n
        c["NLGEOM" if nlgeom else "small strain"] += n
        c[("NLGEOM" if nlgeom else "small strain") + (", axisymmetric" if group.axisymmetric
                                                       else ", plane strain")] += n
        c["tangent" if tangent else "no tangent"] += n
        peeq_n, peeq = np.broadcast_to(state["peeq"], ref["state peeq"].shape), ref["state peeq"]
        plastic = peeq > peeq_n
        c[f"{kind}: elastic points"] += int((~plastic).sum())
        c[f"{kind}: plastic points"] += int(plastic.sum())
        eps_e = ref["state eps_e"]
        if kind != "ELASTIC":
            # re-evaluated at the converged state: on the yield surface, elastic by the margin
            q, sy = _q_of(law, eps_e), law.yield_stress(peeq_n)
            c[f"{kind}: at yield, kept elastic"] += int((~plastic & (np.abs(q - sy)
                                                                     <= 1e-9 * sy)).sum())
        if kind == "RAMBERG_OSGOOD":
            # the return's unknown: ln q where rho = q / (3G N peeq) <= 1, ln P where > 1;
            # decided by the bracket alone when x* = ln q(rho = 1) >= hi, else by the residual
            q, G3, N = _q_of(law, eps_e), 3 * law.G, law.values["N"]
            with np.errstate(divide="ignore", invalid="ignore"):
                rho = q / (G3 * N * peeq)
                q_tr = q + G3 * (peeq - peeq_n)
                x_star = np.log(N * (q_tr + G3 * peeq_n) / (N + 1))
                by_residual = x_star < law._bracket(q_tr, peeq_n)[1]
            c["RAMBERG_OSGOOD: return in ln q"] += int((plastic & (rho <= 1)).sum())
            c["RAMBERG_OSGOOD: return in ln P"] += int((plastic & (rho > 1)).sum())
            c["RAMBERG_OSGOOD: ln q, chosen by the residual"] += int(
                (plastic & (rho <= 1) & by_residual).sum())
            c["RAMBERG_OSGOOD: ln P, chosen by the residual"] += int(
                (plastic & (rho > 1) & by_residual).sum())
            c["RAMBERG_OSGOOD: virgin point yields"] += int((plastic & (peeq_n == 0)).sum())
        if nlgeom and tangent:
            # equal stretches: 1/2 ln of b's eigenvalues equal (the divided difference's limit)
            gap = np.hypot(eps_e[..., 0] - eps_e[..., 1], eps_e[..., 3])
            c["NLGEOM: equal stretches"] += int((~plastic & (gap < 1e-8)).sum())
        return c
    return count


def _fold(group, u, elements):
    """``u`` with ``elements`` mirrored about their centroid (det F < 0)."""
    u = u.copy()
    for e in elements:
        nodes = group.conn[e]
        X = group.coords0[nodes]
        mirrored = X.copy()
        mirrored[:, 0] = 2 * X[:, 0].mean() - X[:, 0]
        u[nodes] = mirrored - X
    return u


def _failure_branch(name):
    def count(ref):
        assert ref["failure"] is not None, f"{name}: the reference did not fail"
        return Counter({name: 1})
    return count


def _start_failure_branch(group, u_new, element):
    """The reference fails on an element whose end configuration is fine (det F, F33 > 0)."""
    def count(ref):
        assert ref["failure"] is not None, "det F_old <= 0: the reference did not fail"
        F, F33, _ = group._deformation(u_new[group.conn])
        fine = ((F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0] > 0)
                & (F33 > 0)).all(axis=1)
        return Counter({"failure: det F_old <= 0, the end fine": int(fine[element])})
    return count


def solid_batches() -> Iterator[Batch]:
    laws = kernel_laws()
    for ename, cls in element_classes():
        for lname, law in laws.items():
            for nlgeom in (False, True):
                for tangent in (True, False):
                    group, state, u_new, u_old = solid_setup(cls, law)
                    args = (group, state, u_new, u_old, nlgeom, tangent)
                    yield _solid_batch(f"{ename} {lname} {'NLGEOM' if nlgeom else 'small'}"
                                       f"{'' if tangent else ' no tangent'}", args,
                                       _solid_branches(group, state, nlgeom, tangent, ename))
                if lname == "ELASTIC":
                    continue
                # just past yield from a small peeq (1e-6 to 3e-4): RO's choice of unknown is
                # made by the residual at x*, not by the bracket
                group, state, u_new, u_old = solid_near_yield(cls, law)
                args = (group, state, u_new, u_old, nlgeom, True)
                yield _solid_batch(f"{ename} {lname} {'NLGEOM' if nlgeom else 'small'} near "
                                   f"yield", args,
                                   _solid_branches(group, state, nlgeom, True, ename))
                # re-evaluated at its converged state (zero increment): points on the yield
                # surface must stay elastic (YIELD_RTOL), in both paths alike.  Not from the
                # virgin element under NLGEOM: its stress is so low (10 MPa) that the trial
                # strain's round-off at a zero increment (4e-16, F F_old^-1 and exp/log) exceeds
                # YIELD_RTOL of it, and each path decides on its own round-off (the module
                # docstring's first known disagreement)
                group, state, u_new, u_old = solid_setup(cls, law, virgin=not nlgeom)
                r = group.compute(u_new, u_old, state, StepContext(nlgeom=nlgeom), False)
                assert r.failure is None
                committed = {k: v for k, v in r.state.items()}
                args = (group, committed, u_new, u_new, nlgeom, True)
                yield _solid_batch(f"{ename} {lname} {'NLGEOM' if nlgeom else 'small'} at the "
                                   f"converged state", args,
                                   _solid_branches(group, committed, nlgeom, True, ename))
        yield from _solid_failures(ename, cls, laws)


def _solid_batch(label, args, branches, calls=None):
    group, state, u_new, u_old, nlgeom, tangent = args
    if calls is None:
        calls = {"solid": 1, "solid_start": 1} if nlgeom else {"solid": 1}
    return Batch(f"solid_group[{label}]",
                 lambda: _solid_reference(*args), lambda: _solid_kernel(*args), calls, branches)


def _solid_failures(ename, cls, laws):
    """The failures, with the same messages: det F <= 0 now or at the start of the increment,
    r <= 0 (axisymmetric), the return map's iteration cap, a non-finite strain, and the
    reference Jacobian (checked before the kernel: no call)."""
    nl = {"solid": 1, "solid_start": 1}
    group, state, u_new, u_old = solid_setup(cls, laws["J2_LINEAR"])
    yield _solid_batch(f"{ename} det F <= 0",
                       (group, state, _fold(group, u_new, [2, 7]), u_old, True, True),
                       _failure_branch("failure: det F <= 0"), nl)
    group, state, u_new, u_old = solid_setup(cls, laws["ELASTIC"])
    folded = _fold(group, u_old, [5])               # folded at the start, fine at the end
    yield _solid_batch(f"{ename} det F_old <= 0", (group, state, u_new, folded, True, True),
                       _start_failure_branch(group, u_new, 5), nl)
    if cls.axisymmetric:
        group, state, u_new, u_old = solid_setup(cls, laws["ELASTIC"])
        u_new = u_new.copy()
        u_new[group.conn[4], 0] -= 3.5                # rigidly to r < 0: F33 < 0, det F = 1
        yield _solid_batch(f"{ename} F33 <= 0", (group, state, u_new, u_old, True, False),
                           _failure_branch("failure: F33 <= 0 (r <= 0)"), nl)
    for nlgeom in (False, True):
        group, state, u_new, u_old = solid_setup(cls, laws["RAMBERG_OSGOOD"])
        group.law.max_iter = 1                       # read by both paths
        yield _solid_batch(f"{ename} RO iteration cap {'NLGEOM' if nlgeom else 'small'}",
                           (group, state, u_new, u_old, nlgeom, True),
                           _failure_branch("failure: return map, iteration cap"),
                           nl if nlgeom else {"solid": 1})
    group, state, u_new, u_old = solid_setup(cls, laws["J2_LINEAR"])
    u_new = u_new.copy()
    u_new[3] = np.nan
    yield _solid_batch(f"{ename} NaN displacement", (group, state, u_new, u_old, False, True),
                       _failure_branch("failure: return map, non-finite"), {"solid": 1})
    group, state, u_new, u_old = solid_setup(cls, laws["ELASTIC"])
    group._bad0 = group._bad0.copy()
    group._bad0[1] = True
    yield _solid_batch(f"{ename} reference Jacobian", (group, state, u_new, u_old, False, True),
                       _failure_branch("failure: reference Jacobian (no kernel call)"), {})


def solid_required() -> list[str]:
    names = [n for n, _ in element_classes()]
    kinds = list(KIND_NAMES.values())
    req = [f"element {n}" for n in names] + [f"law {k}" for k in kinds]
    req += [f"{kin}, {geo}" for kin in ("small strain", "NLGEOM")
            for geo in ("plane strain", "axisymmetric")]
    req += ["tangent", "no tangent", "NLGEOM: equal stretches"]
    req += ["ELASTIC: elastic points"]
    for k in ("J2_LINEAR", "RAMBERG_OSGOOD"):
        req += [f"{k}: elastic points", f"{k}: plastic points", f"{k}: at yield, kept elastic"]
    req += ["RAMBERG_OSGOOD: return in ln q", "RAMBERG_OSGOOD: return in ln P",
            "RAMBERG_OSGOOD: ln q, chosen by the residual",
            "RAMBERG_OSGOOD: ln P, chosen by the residual", "RAMBERG_OSGOOD: virgin point yields"]
    req += ["failure: det F <= 0", "failure: det F_old <= 0, the end fine",
            "failure: F33 <= 0 (r <= 0)",
            "failure: return map, iteration cap", "failure: return map, non-finite",
            "failure: reference Jacobian (no kernel call)"]
    return req


# --------------------------------------------------------------------------------------------
# row kernels.solid.start_group: the NLGEOM start of the increment against _start_of_increment

def start_batches() -> Iterator[Batch]:
    law = kernel_laws()["ELASTIC"]
    for ename, cls in element_classes():
        for case in ("random", "isotropic", "folded"):
            group, state, _, u_old = solid_setup(cls, law, seed=4)
            eps_e = state["eps_e"]
            if case == "isotropic":                  # b_e_n with a double eigenvalue
                eps_e = np.zeros_like(eps_e)
                eps_e[..., :3] = 1e-3
            if case == "folded":
                u_old = _fold(group, u_old, [3])
                if cls.axisymmetric:
                    u_old[group.conn[9], 0] -= 3.5   # r < 0: F33_old < 0
            yield Batch(f"start_group[{ename} {case}]",
                        lambda g=group, u=u_old, e=eps_e: _start_reference(g, u, e),
                        lambda g=group, u=u_old, e=eps_e: _start_kernel(g, u, e),
                        {"solid_start": 1}, _start_branches(group, u_old, eps_e))


def _start_reference(group, u_old, eps_e):
    group._cache.pop("old_key", None)
    inv, F33, bad, bn2, bn33 = group._start_of_increment(u_old[group.conn], eps_e)
    ne, nq = F33.shape
    return {"F_old^-1": inv.reshape(ne, nq, 4), "F33_old": F33, "b_e_n 00": bn2[..., 0, 0],
            "b_e_n 01": bn2[..., 0, 1], "b_e_n 10": bn2[..., 1, 0], "b_e_n 11": bn2[..., 1, 1],
            "b_e_n 33": bn33, "bad_old": bad.any(axis=1)}


def _start_kernel(group, u_old, eps_e):
    group._cache.pop("kernel_old_key", None)
    old, bad = group._kernel_start(np.ascontiguousarray(u_old, float),
                                   np.ascontiguousarray(eps_e, float))
    return {"F_old^-1": old[..., :4], "F33_old": old[..., 4], "b_e_n 00": old[..., 5],
            "b_e_n 01": old[..., 6], "b_e_n 10": old[..., 6], "b_e_n 11": old[..., 7],
            "b_e_n 33": old[..., 8], "bad_old": bad != 0}


def _start_branches(group, u_old, eps_e):
    def count(ref):
        c = Counter()
        geo = "axisymmetric" if group.axisymmetric else "plane strain"
        c[geo] += ref["F33_old"].size
        det = ref["F_old^-1"][..., 0] * ref["F_old^-1"][..., 3] \
            - ref["F_old^-1"][..., 1] * ref["F_old^-1"][..., 2]
        c["det F_old <= 0"] += int((det <= 0).sum())
        c["F33_old <= 0"] += int((ref["F33_old"] <= 0).sum())
        double = (eps_e[..., 0] == eps_e[..., 1]) & (eps_e[..., 3] == 0)
        c["b_e_n: double eigenvalue"] += int(double.sum())
        c["b_e_n: distinct eigenvalues"] += int((~double).sum())
        return c
    return count


def start_required() -> list[str]:
    return ["plane strain", "axisymmetric", "det F_old <= 0", "F33_old <= 0",
            "b_e_n: double eigenvalue", "b_e_n: distinct eigenvalues"]


# --------------------------------------------------------------------------------------------
# row kernels.contact.project_points: Foundation.project through the kernel and in NumPy

#: a chain with curved arcs around a straight one (points collinear: the arc's C = 0)
CHAIN = [[-3.0, 0.3], [-2.0, 0.1], [-1.0, 0.0], [0.0, 0.0], [1.0, 0.0], [2.0, 0.1], [3.0, 0.35]]
FOUNDATIONS = {
    "chain": CHAIN,
    "parabola": [[-1.0, 1.0], [0.0, 0.0], [1.0, 1.0]],
    "wavy": [[-2.0, 0.0], [-1.0, 0.3], [0.0, 0.1], [1.0, -0.2], [2.0, 0.05], [3.0, 0.1],
             [4.0, -0.1]],
    "u_shape": [[-2, 2], [-2, 1], [-2, 0], [0, 0], [2, 0], [2, 1], [2, 2]],
}


def _lines(rng, g=3000):
    """Lines (P, e_u) all around: random, straight down and up (as flat faces), not unit."""
    P = rng.uniform(-3.5, 4.5, (g, 2))
    angle = rng.uniform(0.0, 2 * np.pi, g)
    e = np.c_[np.cos(angle), np.sin(angle)]
    e[::5] = [0.0, -1.0]
    e[1::7] = [0.0, 1.0]
    e[2::11] *= 1.3
    return P, e


def projection_batches() -> Iterator[Batch]:
    for i, (name, pts) in enumerate(FOUNDATIONS.items()):
        P, e = _lines(np.random.default_rng(i))
        for c in (None, np.array([0.05, -0.02])):
            fast = Foundation(pts)
            fast.use_kernels(True)
            ref = Foundation(pts)
            yield Batch(f"project_points[{name}{'' if c is None else ' translated'}]",
                        lambda f=ref, c=c: _projection(f, P, e, c),
                        lambda f=fast, c=c: _projection(f, P, e, c),
                        {"projection": 1}, _projection_branches(ref, P, e, c))


def _projection(found, P, e, c):
    pr = found.project(P, e, c)
    return {k: getattr(pr, k) for k in ("Q", "d", "arc", "s", "tangent", "normal", "found",
                                         "dd_dP", "dd_de")}


def _candidates(found, P, e, c):
    """Every candidate intersection (NumPy's own): line, candidate, d, valid (front-facing)."""
    cc = np.zeros(2) if c is None else c
    s, arc = found._candidates(P, e, cc)
    gi, ki = np.nonzero(np.isfinite(s))
    X, dX = found.evaluate(arc[ki], s[gi, ki], cc)
    m = left_normal(dX)
    mn = np.linalg.norm(m, axis=-1)
    eh = e[gi]
    cosn = np.einsum("hi,hi->h", m, eh) / np.where(mn > 0, mn, 1.0)
    dist = np.einsum("hi,hi->h", P[gi] - X, eh) / np.einsum("hi,hi->h", eh, eh)
    return gi, ki, dist, (mn > 0) & (cosn < -found.cos_min)


def _projection_branches(found, P, e, c):
    def count(ref):
        cnt = Counter()
        f, s, arc = ref["found"], ref["s"], ref["arc"]
        nj = found.n_arcs
        cnt["hit on an arc"] += int((f & (np.abs(np.nan_to_num(s)) <= 1 + found.s_tol)).sum())
        cnt["start half-line"] += int((f & (arc == 0) & (np.nan_to_num(s) < -1 - found.s_tol))
                                      .sum())
        cnt["end half-line"] += int((f & (arc == nj - 1) & (np.nan_to_num(s) > 1 + found.s_tol))
                                    .sum())
        cnt["miss"] += int((~f).sum())
        cnt["hit on a straight arc"] += int((f & (np.abs(found.C[np.maximum(arc, 0)])
                                                  .sum(-1) == 0)).sum())
        cnt["direction not unit"] += int((f & (np.abs(np.hypot(*e.T) - 1) > 1e-9)).sum())
        if c is not None:
            cnt["translated"] += int(f.sum())
        gi, ki, dist, valid = _candidates(found, P, e, c)
        order = np.lexsort((np.abs(dist), gi))
        first = order[np.r_[True, gi[order][1:] != gi[order][:-1]]]   # nearest per line
        cnt["nearest candidate back-facing, rejected"] += int((~valid[first]).sum())
        win = np.lexsort((ki, np.where(valid, np.abs(dist), np.inf), gi))
        best = win[np.r_[True, gi[win][1:] != gi[win][:-1]]]
        best = best[valid[best]]
        cnt["first root wins"] += int((ki[best] < nj).sum())
        cnt["second root wins"] += int(((ki[best] >= nj) & (ki[best] < 2 * nj)).sum())
        return cnt
    return count


def projection_required() -> list[str]:
    return ["hit on an arc", "start half-line", "end half-line", "miss", "hit on a straight arc",
            "direction not unit", "translated", "nearest candidate back-facing, rejected",
            "first root wins", "second root wins"]


# --------------------------------------------------------------------------------------------
# row kernels.contact.contact_group (with face_positions): ContactGroup._compute_fused against
# ContactGroup.compute in NumPy

CONTACT_LAWS = {
    "plain": dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0),
    "no adhesion": dict(KP=1000.0, KT=500.0, PHI=0.2),
    "hardening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=30.0, HPHI=0.7),
    # kinks at lam = 0.05 (B) and 0.15 (phi): a large slide crosses both in one return
    "softening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=-2.0),
    "classical softening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=0.2,
                                INDICATOR="CLASSICAL"),
    "classical hardening": dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0, HB=20.0,
                                INDICATOR="CLASSICAL"),
}
#: the hardening forms and the shear limit, on a subset of the configurations (NEW_LAW_CONFIGS)
FORM_LAWS = {
    # a slide of 0.1 is 10 LAMC: dissipation panels
    "run-in": dict(KP=1000.0, KT=500.0, PHI=0.3, B=1.0, PHI_INF=0.6, LAMC=0.01),
    # concave residual (softening exponential) with phi's clipping kink at 0.15: Newton from the
    # left overshoots past the kink, the safeguard bisects
    "wear": dict(KP=1000.0, KT=500.0, PHI=0.3, B=2.0, B_INF=0.2, LAMC_B=0.004, HPHI=-2.0),
    "table": {"KP": 1000.0, "KT": 500.0, "CONTACT LAW TABLE": (
        (0.0, 0.3, 1.0), (0.01, 0.5, 0.5), (0.03, 0.4, 2.0), (0.06, 0.2, 0.0))},
    # p up to 20, B + phi p up to 6: some points on the cap, some below; B + phi p = TAUMAX
    # exactly at p = 8, lam = 0 (set by contact_state)
    "cap": dict(KP=1000.0, KT=500.0, PHI=0.25, B=1.0, HB=15.0, TAUMAX=3.0),
    "cap, run-in": dict(KP=1000.0, KT=500.0, PHI=0.25, B=1.0, PHI_INF=0.5, LAMC=0.02,
                        TAUMAX=3.0),
    "classical, cap": dict(KP=1000.0, KT=500.0, PHI=0.25, B=1.0, HB=15.0, TAUMAX=3.0,
                           INDICATOR="CLASSICAL"),
}
ALL_CONTACT_LAWS = {**CONTACT_LAWS, **FORM_LAWS}
AX_SHIFT = np.array([5.0, 0.0])          # axisymmetric groups sit at r in [1.4, 8.6]
FACE_LENGTH = 0.3


def _kinks(law) -> list[float]:
    """Where B or phi's derivative jumps: clipping kinks, table rows."""
    return list(law.breaks)


def contact_faces(rng, nfn: int):
    """Faces of their own nodes near CHAIN: x0 (f, a, 2), their kinds, normals and tangents.

    Kinds: ``near`` (within +-0.012 of an arc), ``beyond`` (over an end half-line), ``flipped``
    (turned away from the foundation: its lines are back-facing), ``touching`` (on the
    straight arc, exactly or within round-off: d = 0) and ``far`` (0.4 above)."""
    found = Foundation(CHAIN)
    kinds = ["near"] * 8 + ["beyond"] * 2 + ["flipped", "touching", "touching", "far"]
    x0, normals, tangents = [], [], []
    for kind in kinds:
        if kind == "touching":                       # exactly, or within round-off
            x = rng.choice([-0.75, -0.5, -0.25, 0.25, 0.5])
            X, t = np.array([x, 0.0]), np.array([1.0, 0.0])
            gap, bend = rng.choice([0.0, 3e-15, -3e-15]), 0.0
        else:
            if kind == "beyond":
                arc, s = (0, rng.uniform(-1.6, -1.2)) if rng.random() < 0.5 else \
                    (found.n_arcs - 1, rng.uniform(1.2, 1.6))
            else:
                arc, s = rng.integers(found.n_arcs), rng.uniform(-0.9, 0.9)
            X, dX = found.evaluate([arc], [s])
            X, t = X[0], dX[0] / np.linalg.norm(dX[0])
            gap = 0.4 if kind == "far" else rng.uniform(-0.012, 0.012)
            bend = 0.002 * rng.standard_normal()
        n = left_normal(t)
        corners = [X + gap * n - 0.5 * FACE_LENGTH * t, X + gap * n + 0.5 * FACE_LENGTH * t]
        if kind == "flipped":
            corners = corners[::-1]
        nodes = corners + ([X + (gap + bend) * n] if nfn == 3 else [])
        x0.append(nodes)
        normals.append(n)
        tangents.append(t)
    return np.array(x0), kinds, np.array(normals), np.array(tangents)


def _rigid(x0, n, t, shift_n, shift_t, angle):
    """Displacements (a, 2) of a face's nodes turned by ``angle`` about its centre and moved."""
    centre = x0.mean(axis=0)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    return centre + (x0 - centre) @ R.T + shift_n * n + shift_t * t - x0


def contact_motion(rng, x0, kinds, normals, tangents, big_slides: bool):
    """u_old, u_new (n, 2): every face moved rigidly (normal moves of +-0.02 in and out of
    contact, slides from 1e-4.5 to 1e-1 -- up to 0.2 with ``big_slides``, turns of up to 0.04
    rad) plus a small deformation; touching faces at rest or sliding along the straight arc."""
    u_old, u_new = [], []
    top = 0.7 if big_slides else -1.0
    for x, kind, n, t in zip(x0, kinds, normals, tangents):
        if kind == "touching":
            slide = 0.0 if rng.random() < 0.5 else rng.uniform(-0.05, 0.05)
            u_old.append(np.zeros_like(x))
            u_new.append(np.tile([slide, 0.0], (len(x), 1)))
            continue
        dn, dt = rng.uniform(-0.012, 0.012), rng.uniform(-1e-3, 1e-3)
        turn = rng.uniform(-0.01, 0.01)
        uo = _rigid(x, n, t, dn, dt, turn) + 1e-4 * rng.standard_normal(x.shape)
        slide = rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-4.5, top)
        un = _rigid(x, n, t, dn + rng.uniform(-0.02, 0.02), dt + slide,
                    turn + rng.uniform(-0.04, 0.04)) + 1e-4 * rng.standard_normal(x.shape)
        u_old.append(uo)
        u_new.append(un)
    return np.concatenate(u_old), np.concatenate(u_new)


def contact_state(law, kinds, nq, rng):
    """A committed state set by hand: p from 0 to 20, lam at 0, anywhere, or just before a
    softening kink; tau on the cone (either side), inside it or 0; any status.  Touching faces
    at rest from a body meshed on the foundation: p = tau = 0, STICK."""
    ng = len(kinds) * nq
    p = np.where(rng.random(ng) < 0.3, 0.0, law.kp * 0.02 * rng.random(ng))
    lam = np.where(rng.random(ng) < 0.3, 0.0, 0.2 * rng.random(ng))
    for k in _kinks(law):
        near = rng.random(ng) < 0.2
        lam = np.where(near, k - 10 ** rng.uniform(-5, -1.5, ng), lam)
    if law.taumax is not None:      # on the cap exactly: B + phi p = TAUMAX at lam = 0
        exact = rng.random(ng) < 0.15
        p = np.where(exact, (law.taumax - law.b) / law.phi, p)
        lam = np.where(exact, 0.0, lam)
    radius = law.radius(lam, p)
    pick = rng.random(ng)
    tau = np.where(pick < 0.4, radius * rng.choice([-1.0, 1.0], ng),
                   np.where(pick < 0.9, radius * rng.uniform(-1, 1, ng), 0.0))
    state = {"p": p, "tau": tau, "lam": lam, "slip": rng.random(ng),
             "vp": rng.uniform(-1.0, 1.0, ng), "dissip": rng.random(ng),
             "dvp": rng.uniform(-1.0, 1.0, ng), "energy": rng.random(ng),
             "fdis": rng.random(ng), "ps": rng.uniform(-1.0, 1.0, ng),
             "ts": rng.uniform(-1.0, 1.0, ng), "stab": rng.random(ng),
             "status": rng.integers(0, 3, ng).astype(np.int8)}
    touching = np.repeat([k == "touching" for k in kinds], nq)
    for key in ("p", "tau"):
        state[key] = np.where(touching, 0.0, state[key])
    state["status"] = np.where(touching, STICK, state["status"]).astype(np.int8)
    return state


@dataclass
class ContactConfig:
    nfn: int
    gauss: int
    ax: bool
    nlgeom: bool
    law: str
    substeps: object
    theta: float
    hold: bool
    translation: int         # 0 none, 1 along x (the straight arc stays at y = 0), 2 any
    seed: int
    tool: bool = False       # the foundation's reference node: the tool's DOFs in the group
                             # (u, v and in PE the rotation: the foundation turns too)
    stab: bool = False       # *CONTACT STABILIZATION's damping

    def label(self) -> str:
        return (f"{self.nfn}-node {self.gauss}gp {'AX' if self.ax else 'PE'} "
                f"{'NLGEOM' if self.nlgeom else 'small'} {self.law} SUBSTEPS={self.substeps} "
                f"THETA={self.theta}{' held' if self.hold else ''} c{self.translation}"
                f"{' tool' if self.tool else ''}{' stabilised' if self.stab else ''}")


#: (face nodes, Gauss points, axisymmetric, NLGEOM) of the FORM_LAWS: the forms are the law's
#: business, the element's variants are covered by CONTACT_LAWS
NEW_LAW_CONFIGS = ((3, 3, False, False), (3, 3, True, True), (2, 2, False, True),
                   (3, 2, True, False))
LOBATTO_CONFIGS = ((3, "LOBATTO3", False, True), (3, "LOBATTO3", True, False),
                   (2, "LOBATTO2", True, True))


def contact_configs() -> list[ContactConfig]:
    """Every face type x Gauss rule x PE/AX x kinematics, each with every law of CONTACT_LAWS,
    and the FORM_LAWS on NEW_LAW_CONFIGS; for each kinematics every pair of SUBSTEPS and THETA
    comes in turn, the holds and translations cycle too."""
    out = []
    seen = Counter()
    for nfn in (2, 3):
        for gauss in (2, 3):
            for ax in (False, True):
                for nlgeom in (False, True):
                    laws = list(CONTACT_LAWS)
                    if (nfn, gauss, ax, nlgeom) in NEW_LAW_CONFIGS:
                        laws += list(FORM_LAWS)
                    for law in laws:
                        j = seen[nlgeom]
                        seen[nlgeom] += 1
                        # each form law needs free points and held ones (a frozen STICK point
                        # leaves the cone): its configs alternate on its own count (the cycle
                        # of j may hold them all)
                        hold = ((j // 3) % 2 == 1 if law in CONTACT_LAWS else
                                seen["form " + law] % 2 == 1)
                        seen["form " + law] += law not in CONTACT_LAWS
                        out.append(ContactConfig(
                            nfn, gauss, ax, nlgeom, law, substeps=(1, 3, "AUTO", 2)[j % 4],
                            theta=(1.0, 0.5, 0.0)[(j // 4) % 3], hold=hold,
                            translation=(0, 1, 2)[(j // 2) % 3], seed=len(out),
                            tool=j % 5 in (1, 3), stab=j % 7 in (2, 5)))
    # the Gauss-Lobatto rules (points at the nodes; LINEAR has no kernel: tests/test_contact_rules)
    for nfn, gauss, ax, nlgeom in LOBATTO_CONFIGS:
        for law in CONTACT_LAWS:
            j = seen[nlgeom]
            seen[nlgeom] += 1
            out.append(ContactConfig(nfn, gauss, ax, nlgeom, law,
                                     substeps=(1, 3, "AUTO", 2)[j % 4],
                                     theta=(1.0, 0.5, 0.0)[(j // 4) % 3], hold=(j // 3) % 2 == 1,
                                     translation=(0, 1, 2)[(j // 2) % 3], seed=len(out),
                                     tool=j % 5 in (1, 3), stab=j % 7 in (2, 5)))
    return out


class Recorder:
    """Records the reference law's sub-intervals (inputs and outputs), for counting branches."""

    def __init__(self, law: Coulomb):
        self.law = law
        self.calls: list[tuple] = []
        law.update = self                       # this instance only; the class is untouched

    def __call__(self, state, d, du, dv, frozen=None):
        new, tan = Coulomb.update(self.law, state, d, du, dv, frozen=frozen)
        self.calls.append((state, np.asarray(d), np.asarray(du), np.asarray(dv), frozen, new))
        return new, tan


def _contact_pair(cfg: ContactConfig, params: dict):
    """The same group twice: NumPy (recording its law) and the fused kernel."""
    rng = np.random.default_rng(cfg.seed)
    x0, kinds, normals, tangents = contact_faces(rng, cfg.nfn)
    shift = AX_SHIFT if cfg.ax else np.zeros(2)
    nf = len(kinds)
    coords0 = (x0 + shift).reshape(-1, 2)
    faces = np.arange(nf * cfg.nfn).reshape(nf, cfg.nfn)
    par = dict(params, THETA=cfg.theta, SUBSTEPS=cfg.substeps, SUBTOL=0.01, SUBMAX=8)
    n2 = 2 * len(coords0)
    tool = None if not cfg.tool else [n2, n2 + 1] + ([] if cfg.ax else [n2 + 2])
    groups = []
    for kernel in (False, True):
        grp = ContactGroup("S->F", faces, np.arange(1, nf + 1), np.ones(nf, int), coords0,
                           Foundation(np.asarray(CHAIN) + shift, centre=(0.2, 0.4) + shift),
                           "F", Coulomb(**par), gauss=cfg.gauss, axisymmetric=cfg.ax,
                           thickness=2.5, tool_dofs=tool)
        grp.use_kernels(kernel)
        assert grp._kernel == kernel
        groups.append(grp)
    return groups[0], groups[1], rng, x0, kinds, normals, tangents


def _contact_run(grp, u_new, u_old, state, ctx, tangent):
    try:
        r = grp.compute(u_new, u_old, copy.deepcopy(state), ctx, tangent)
    except ReturnMappingError as exc:
        return {"raises": f"ReturnMappingError: {exc}"}
    out = {"failure": r.failure, "f": r.f, "K": r.K, "state keys": tuple(sorted(r.state)),
           "start penetration": grp._start_cache[4]}
    out.update({f"state {k}": v for k, v in r.state.items()})
    return out


def contact_batches() -> Iterator[Batch]:
    for cfg in contact_configs():
        ref, fast, rng, x0, kinds, normals, tangents = _contact_pair(cfg,
                                                                     ALL_CONTACT_LAWS[cfg.law])
        rec = Recorder(ref.law)
        state = contact_state(ref.law, kinds, ref.nq, rng)
        u_old, u_new = contact_motion(rng, x0, kinds, normals, tangents,
                                      big_slides=cfg.law in ("softening", "run-in", "wear",
                                                             "table", "cap, run-in"))
        c_old = [np.zeros(2), np.array([1e-3, 0.0]), np.array([1e-3, -1e-3])][cfg.translation]
        c_new = [np.zeros(2), np.array([3e-3, 0.0]), np.array([2e-3, 5e-4])][cfg.translation]
        if cfg.tool and not cfg.ax:          # the tool turns about its reference point too
            c_old, c_new = np.append(c_old, 2e-3), np.append(c_new, 7e-3)
        stab = {"S->F": (50.0, 20.0, 0.05)} if cfg.stab else None
        frozen = rng.integers(-1, 3, ref.ng) if cfg.hold else None
        wiggle = 1e-4 * rng.standard_normal(u_new.shape)
        # the sequence of calls of an increment: the start penetration is computed, reused (same
        # start), recomputed after the start moved, and after the foundation's start moved
        sequence = [("", u_old, u_new, c_old, True, "start penetration computed"),
                    (" same start", u_old, u_new + wiggle, c_old, True, "start penetration reused"),
                    (" start moved", u_old + wiggle, u_new, c_old, True,
                     "start recomputed (faces moved)"),
                    (" foundation start moved, no tangent", u_old + wiggle, u_new,
                     c_old + 1e-4 * np.eye(len(c_old))[0], False,
                     "start recomputed (foundation moved)")]
        for what, uo, un, co, tangent, step in sequence:
            ctx = StepContext(nlgeom=cfg.nlgeom, foundation_old={"F": co},
                              foundation_new={"F": c_new},
                              freeze_contact=None if frozen is None else {"S->F": frozen},
                              stabilisation=stab)

            def reference(uo=uo, un=un, ctx=ctx, tangent=tangent):
                rec.calls.clear()
                return _contact_run(ref, un, uo, state, ctx, tangent)
            yield Batch(f"contact_group[{cfg.label()}{what}]", reference,
                        lambda uo=uo, un=un, ctx=ctx, tangent=tangent:
                        _contact_run(fast, un, uo, state, ctx, tangent),
                        {"contact": 1}, _contact_branches(cfg, ref, rec, un, c_new, step))
    yield from _contact_failures()


def _coulomb_branches(law: Coulomb, rec) -> Counter:
    """Points per branch of one sub-interval of the reference law (its inputs and outputs)."""
    state, d, du, dv, frozen, new = rec
    g = d.shape[0]
    hold = np.full(g, -1) if frozen is None else np.broadcast_to(frozen, (g,))
    free = hold == -1
    closable = hold != OPEN
    contact = (d >= 0) & closable
    p_old, tau_old, lam0 = state["p"], state["tau"], state["lam"]
    recon = contact & (state["status"] == OPEN)
    partial = recon & (d <= du) & (du > 0)
    sep = ~contact & (p_old > 0) & (d - du > 0) & (d <= 0) & closable
    active = contact | sep
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(partial, d / du, np.where(sep, (d - du) / (-du), 1.0))
    dv_c = dv * frac
    tau0, p0 = np.where(recon, 0.0, tau_old), np.where(recon, 0.0, p_old)
    b0, hb0 = law.adhesion(lam0)
    phi0, hphi0 = law.friction(lam0)
    radius0 = law.radius(lam0, p0)
    on = active & (np.abs(tau0) - radius0 >= -layout.ON_SURFACE_RTOL
                   * (radius0 + np.abs(tau0)))
    p1, lam1, status = new["p"], new["lam"], new["status"]
    tau_tr = tau0 + law.kt * dv_c
    sig0 = np.where(tau0 != 0, np.sign(tau0), np.where(dv_c >= 0, 1.0, -1.0))
    indicator = sig0 * law.kt * dv_c - phi0 * (p1 - p0)
    slip, stick = status == SLIP, status == STICK
    h1 = hb0 + hphi0 * p1
    c = Counter()
    c["open"] += int((free & ~active).sum())
    c["touching (d = 0)"] += int((contact & (d == 0)).sum())
    c["stick"] += int((free & stick).sum())
    c["slip"] += int((free & slip).sum())
    c["re-contact, full"] += int((recon & ~partial).sum())
    c["re-contact, partial"] += int(partial.sum())
    c["separation"] += int(sep.sum())
    c["separation, slipping until p = 0"] += int((sep & (lam1 > lam0)).sum())
    c["slip, hardening (H > 0)"] += int((slip & (h1 > 0)).sum())
    c["slip, softening (H < 0)"] += int((slip & (h1 < 0)).sum())
    kinks = _kinks(law)
    crossed = [slip & (lam0 < k) & (lam1 > k) for k in kinks]
    if law.values["CONTACT LAW TABLE"] is not None:
        n_crossed = np.sum(crossed, axis=0)
        c["return crosses a table row"] += int((n_crossed == 1).sum())
        c["return crosses several table rows"] += int((n_crossed > 1).sum())
        c["slip beyond the last table row (flat)"] += int((slip & (lam0 >= kinks[-1])).sum())
    else:
        names = [n for n, f in (("B", law.b_form), ("phi", law.phi_form)) if f.breaks]
        for name, x in zip(names, crossed):
            c[f"return crosses the {name} kink"] += int(x.sum())
        if len(crossed) == 2:
            c["return crosses both kinks"] += int((crossed[0] & crossed[1]).sum())
        if kinks:
            c["slip past a kink (clipped)"] += int((slip & (lam0 >= min(kinks))).sum())
            c["dissipation over kinks"] += int((slip & np.any(crossed, axis=0)).sum())
    c.update(_form_branches(law, state, p0, tau0, lam0, p1, lam1, slip, stick, dv_c, frozen,
                            on, free, contact))
    c["on the surface, loading"] += int((free & on & slip & (np.sign(tau_tr) == sig0)).sum())
    c["on the surface, unloading"] += int((free & on & stick).sum())
    c["on the surface, reversed through the cone"] += int((free & on & slip
                                                          & (np.sign(tau_tr) != sig0)).sum())
    c["inside, yields part-way"] += int((free & ~on & slip).sum())
    c["neutral loading (indicator 0), stick"] += int((free & on & contact & (indicator == 0)
                                                     & stick).sum())
    if law.indicator == "CLASSICAL":
        h0 = hb0 + hphi0 * p0
        c["CLASSICAL, on the surface, H < 0"] += int((free & on & contact & (h0 < 0)).sum())
        c["CLASSICAL, on the surface, H > 0"] += int((free & on & contact & (h0 > 0)).sum())
    if frozen is not None:
        try:
            unheld, _ = Coulomb.update(law, state, d, du, dv)
        except ReturnMappingError:
            return c
        c["held OPEN, in contact"] += int(((hold == OPEN) & (d >= 0)).sum())
        c["held STICK, would slip"] += int(((hold == STICK) & (unheld["status"] == SLIP)).sum())
        c["held SLIP, would stick"] += int(((hold == SLIP) & (unheld["status"] == STICK)).sum())
        c["held SLIP, unloading (dlam < 0)"] += int(((hold == SLIP) & (lam1 < lam0)).sum())
    return c


def _form_branches(law, state, p0, tau0, lam0, p1, lam1, slip, stick, dv_c, frozen, on, free,
                   contact) -> Counter:
    """The branches of the exponential forms and of TAUMAX (FORM_LAWS)."""
    c = Counter()
    forms = (law.b_form, law.phi_form)
    if any(f.smooth for f in forms):
        c["exponential form, Newton return"] += int(slip.sum())
        # the first Newton step from lam0 leaves the bracket [lam0, min(break, lam0 + Lmax)]
        tau_tr = tau0 + law.kt * dv_c
        b0, hb0 = law.adhesion(lam0)
        phi0, hphi0 = law.friction(lam0)
        r0 = np.abs(tau_tr) - b0 - phi0 * p1
        step = r0 / (law.kt + hb0 + hphi0 * p1)
        ahead = np.array([min([k for k in law.breaks if k > x], default=np.inf) for x in lam0])
        lmax = (np.abs(tau_tr) - law.b_form.lower() - law.phi_form.lower() * p1) / law.kt
        c["Newton's first step leaves its bracket (bisection)"] += int(
            (slip & (r0 > 0) & (lam0 + step >= np.minimum(ahead, lam0 + lmax))).sum())
        scale = min(f.scale for f in forms)
        c["dissipation on several panels"] += int((slip & (lam1 - lam0 > 2 * scale)).sum())
    if law.taumax is not None:
        cap = law.taumax
        u0 = law.adhesion(lam0)[0] + law.friction(lam0)[0] * p0
        u1 = law.adhesion(lam1)[0] + law.friction(lam1)[0] * p1
        c["slip on the cap"] += int((slip & (u1 > cap)).sum())
        c["slip below the cap"] += int((slip & (u1 < cap)).sum())
        c["the cap taken in the sub-interval"] += int((slip & (u0 < cap) & (u1 > cap)).sum())
        c["the cap left in the sub-interval"] += int((slip & (u0 > cap) & (u1 < cap)).sum())
        c["on the surface at the cap exactly"] += int((on & contact & (u0 == cap)).sum())
        c["stick on the cap's surface, unloading"] += int((free & on & stick & (u0 > cap)).sum())
        if law.indicator == "CLASSICAL":
            c["CLASSICAL on the cap"] += int((free & on & contact & (u0 > cap)).sum())
    return c


def _contact_branches(cfg, ref_group, rec, u_new, c_new, step):
    def count(ref):
        c = Counter()
        if "raises" in ref:
            return c
        for call in rec.calls:
            c += _coulomb_branches(ref_group.law, call)
        if not (ref["state p"] > 0).any():
            return c                        # the configuration counts with points in contact
        c[f"{cfg.nfn}-node faces, {cfg.gauss} Gauss points, {'AX' if cfg.ax else 'PE'}, "
          f"{'NLGEOM' if cfg.nlgeom else 'small strain'}"] += 1
        c[step] += 1
        nsub = len(rec.calls)
        c[f"SUBSTEPS={cfg.substeps}" + (", several" if cfg.substeps == "AUTO" and nsub > 1
                                        else "")] += 1
        if cfg.nlgeom:
            c[f"NLGEOM, THETA={cfg.theta}" + (", sub-intervals" if nsub > 1 else "")] += 1
        if cfg.translation == 2:
            c["foundation translated across"] += 1
        if cfg.tool:
            c["tool's DOFs, AX translation" if cfg.ax else "tool's DOFs, turned"] += 1
        if cfg.stab:
            c["stabilised, damped points"] += int(np.count_nonzero(ref["state ps"]))
        if ref["failure"] is not None:
            c["failure: outside the cone" if "outside" in ref["failure"]
              else "failure: " + ref["failure"]] += 1
        x = ref_group._face_x(u_new)
        P, t = ref_group._axes_t(x, cfg.nlgeom)
        e_u, _ = normal_axis(t)
        pr = ref_group._project(P, e_u, (c_new[:2], c_new[2] if len(c_new) > 2 else 0.0))
        s = np.nan_to_num(pr.s)
        c["line misses (d = -FAR)"] += int((~pr.found).sum())
        c["round-off touching, snapped to d = 0"] += int((pr.found & (np.abs(pr.d) > 0) & (
            np.abs(pr.d) <= ref_group._touch_tol)).sum())
        c["end half-line"] += int((pr.found & (np.abs(s) > 1 + 1e-8)).sum())
        return c
    return count


def _contact_failures() -> Iterator[Batch]:
    """A face sliding on the cone under softening adhesion: CLASSICAL leaves the cone (a
    failure) unless held STICK, PREDICTOR does not; a softening faster than KT allows at this
    pressure (snap-back: ReturnMappingError); a face of zero length (degenerate); a NaN."""
    softening = dict(KP=1e3, KT=5e2, PHI=0.3, B=0.5, HB=-20.0)
    cases = [   # name, law, hold, what is broken, the failure the reference must give
        ("classical leaves the cone", dict(softening, INDICATOR="CLASSICAL"), None, None,
         "failure: outside the cone"),
        ("classical held STICK", dict(softening, INDICATOR="CLASSICAL"), STICK, None, None),
        ("predictor stays on the cone", softening, None, None, None),
        ("snap-back", dict(KP=1e3, KT=50.0, PHI=0.3, B=2.0, HB=-40.0, HPHI=-0.5), None, None,
         "raises: snap-back"),
        ("degenerate face", CONTACT_LAWS["plain"], None, "degenerate",
         "failure: degenerate face"),
        ("non-finite", CONTACT_LAWS["plain"], None, "nan", "failure: non-finite"),
        # exactly on the cap (B + phi p = TAUMAX, in binary), pressed 0.002 deeper while sliding
        # 0.0005 on: the cap does not rise with p, the point slides on it (KT dv < phi dp)
        ("on the cap exactly, pressure rising",
         dict(KP=1e3, KT=5e2, PHI=0.25, B=0.5, TAUMAX=8.0), None, "press", None),
    ]
    for i, (name, params, hold, broken, expect) in enumerate(cases):
        # a face of zero length is degenerate under NLGEOM only (small strain: the reference face)
        for nfn, nlgeom in ((3, True), (2, broken == "degenerate")):
            cfg = ContactConfig(nfn, 3, False, nlgeom, name, 1, 1.0, False, 1, 1000 + i)
            ref, fast, rng, x0, kinds, normals, tangents = _contact_pair(cfg, params)
            law = ref.law
            # every face pressed 0.03 deep, sliding 0.01 against tau on the cone
            u_old = np.concatenate([_rigid(x, n, t, -0.03 - g0, 0.0, 0.0) for x, n, t, g0 in
                                    zip(x0, normals, tangents, _gaps(x0, normals))])
            press, slide = (0.002, 0.0005) if broken == "press" else (0.0, 0.01)
            u_new = u_old + np.concatenate([np.tile(-press * n - slide * t, (nfn, 1))
                                            for n, t in zip(normals, tangents)])
            state = ref.init_state()
            state["p"][:] = law.kp * 0.03
            state["lam"][:] = 0.01
            b, _ = law.adhesion(state["lam"])
            phi, _ = law.friction(state["lam"])
            state["tau"] = b + phi * state["p"]
            state["status"][:] = SLIP
            if broken == "degenerate":                # face 0's nodes on one point
                u_new[:nfn] = x0[0, 0] + u_new[0] - x0[0]
            if broken == "nan" and nlgeom:
                u_new[2] = np.nan
            if broken == "nan" and not nlgeom:
                # not a NaN displacement: in small strain its point misses the foundation and
                # NumPy's tangent shortcut keeps K finite where the kernel's NaN * 0 does not
                # (the module docstring's second known disagreement); a NaN state fails both
                state["tau"][1] = np.nan
            ctx = StepContext(nlgeom=nlgeom, foundation_old={"F": np.zeros(2)},
                              foundation_new={"F": np.zeros(2)},
                              freeze_contact=None if hold is None else
                              {"S->F": np.full(ref.ng, hold)})
            yield Batch(f"contact_group[{name} {nfn}-node {'NLGEOM' if nlgeom else 'small'}]",
                        lambda ref=ref, un=u_new, uo=u_old, st=state, ctx=ctx:
                        _contact_run(ref, un, uo, st, ctx, True),
                        lambda fast=fast, un=u_new, uo=u_old, st=state, ctx=ctx:
                        _contact_run(fast, un, uo, st, ctx, True),
                        {"contact": 1}, _expected_failure(name, expect))


def _expected_failure(name, expect):
    def count(ref):
        msg = ref.get("failure") or ""
        got = ("raises: snap-back" if "raises" in ref else
               next((kind for key, kind in (("outside", "failure: outside the cone"),
                                            ("degenerate", "failure: degenerate face"),
                                            ("non-finite", "failure: non-finite"))
                     if key in msg), None))
        assert got == expect, f"{name}: the reference gave {got!r}, the batch wants {expect!r}"
        return Counter({expect or f"no failure: {name}": 1})
    return count


def _gaps(x0, normals):
    """Initial gap of each face (mean over its nodes) along its normal, to press it exactly."""
    found = Foundation(CHAIN)
    out = []
    for x, n in zip(x0, normals):
        pr = found.project(x, np.tile(-n, (len(x), 1)))
        out.append(float(np.mean(-pr.d)) if pr.found.all() else 0.0)
    return out


def contact_required() -> list[str]:
    req = ["open", "touching (d = 0)", "stick", "slip", "re-contact, full", "re-contact, partial",
           "separation", "separation, slipping until p = 0", "slip, hardening (H > 0)",
           "slip, softening (H < 0)", "return crosses the B kink", "return crosses the phi kink",
           "return crosses both kinks", "slip past a kink (clipped)", "dissipation over kinks",
           "on the surface, loading", "on the surface, unloading",
           "on the surface, reversed through the cone", "inside, yields part-way",
           "neutral loading (indicator 0), stick", "CLASSICAL, on the surface, H < 0",
           "CLASSICAL, on the surface, H > 0", "held OPEN, in contact", "held STICK, would slip",
           "held SLIP, would stick", "held SLIP, unloading (dlam < 0)",
           "line misses (d = -FAR)", "end half-line", "round-off touching, snapped to d = 0",
           "start penetration computed", "start penetration reused",
           "start recomputed (faces moved)", "start recomputed (foundation moved)",
           "SUBSTEPS=1", "SUBSTEPS=2", "SUBSTEPS=3", "SUBSTEPS=AUTO, several",
           "NLGEOM, THETA=0.0", "NLGEOM, THETA=0.0, sub-intervals", "NLGEOM, THETA=0.5",
           "NLGEOM, THETA=0.5, sub-intervals", "NLGEOM, THETA=1.0",
           "NLGEOM, THETA=1.0, sub-intervals",
           "foundation translated across", "tool's DOFs, turned", "tool's DOFs, AX translation",
           "stabilised, damped points",
           "failure: outside the cone", "raises: snap-back", "failure: degenerate face",
           "failure: non-finite", "no failure: classical held STICK",
           "no failure: predictor stays on the cone",
           "no failure: on the cap exactly, pressure rising"]
    req += ["exponential form, Newton return", "Newton's first step leaves its bracket (bisection)",
            "dissipation on several panels", "return crosses a table row",
            "return crosses several table rows", "slip beyond the last table row (flat)",
            "slip on the cap", "slip below the cap", "the cap taken in the sub-interval",
            "the cap left in the sub-interval", "on the surface at the cap exactly",
            "stick on the cap's surface, unloading", "CLASSICAL on the cap"]
    req += [f"{nfn}-node faces, {gauss} Gauss points, {geo}, {kin}" for nfn in (2, 3)
            for gauss in (2, 3) for geo in ("PE", "AX") for kin in ("small strain", "NLGEOM")]
    req += [f"{nfn}-node faces, {gauss} Gauss points, {'AX' if ax else 'PE'}, "
            f"{'NLGEOM' if nlgeom else 'small strain'}" for nfn, gauss, ax, nlgeom in LOBATTO_CONFIGS]
    return req


# --------------------------------------------------------------------------------------------
# the table and its test

TABLE = [
    Twin("kernels.solid.solid_group", solid_batches, solid_required),
    Twin("kernels.solid.start_group", start_batches, start_required),
    Twin("kernels.contact.project_points", projection_batches, projection_required),
    Twin("kernels.contact.contact_group", contact_batches, contact_required),
]


def test_the_kernels_import():
    """numba imports, so the kernels must (no silent fall-back to NumPy here).  The margins the
    kernels and the laws share (YIELD_RTOL, ON_SURFACE_RTOL) have one definition,
    kernels/layout.py."""
    assert kernels.module("solid") is not None and kernels.module("contact") is not None


@pytest.mark.parametrize("twin", TABLE, ids=[t.entry for t in TABLE])
def test_twin(twin):
    visited = run_twin(twin)
    missing = [b for b in twin.required() if not visited[b]]
    assert not missing, f"{twin.entry}: batches visit no point of {missing}"
