"""The numba solid kernel computes ``LANES`` elements side by side (``kernels.solid``): groups
of several blocks and a remainder block against the NumPy path.

``tests/test_kernel_twins.py`` covers every element, law and branch on 12-element groups, one
partial block.  Here the groups hold two or more full blocks and a remainder (element counts
not a multiple of ``LANES``), so an element read from the wrong block, a spare lane scattered
or a flag of one lane written to another shows: the forces, CSR data and trial state against
``SolidElement.compute``, and the failures (BAD_DET_F, RETURN_MAP_FAILED) element by element,
in the second block and in the remainder.  Tolerance as the twin table's (``RTOL`` of each
array's largest entry: the two paths sum some terms in other orders)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py import kernels                                  # noqa: E402
from lagamine_py.elements.base import StepContext                # noqa: E402
from lagamine_py.elements.structured import rectangle            # noqa: E402
from lagamine_py.registry import get                             # noqa: E402
from lagamine_py.solver.pattern import Pattern                   # noqa: E402

RTOL = 1e-12
LAW = dict(E=210e3, NU=0.3, SIGMAY=250.0, H=2000.0)


def lanes() -> int:
    return kernels.module("solid").LANES


def group_and_state(ename: str, seed: int = 3):
    """A distorted 5 x 7 mesh (Q8: 35 elements, T6: 70), J2_LINEAR with a random committed
    state and increment (some points plastic); the element count is not a multiple of LANES and
    spans at least two full blocks."""
    cls = get("elements", ename)
    rect = rectangle(cls, 1.0, 0.0, 2.0, 1.5, 5, 7)
    rng = np.random.default_rng(seed)
    xy = rect.coords.copy()
    xy[:, 0] += 0.05 * np.sin(2.0 * rect.coords[:, 1])
    xy += 0.02 * rng.uniform(-1.0, 1.0, xy.shape)
    conn = rect.conn
    ne = len(conn)
    assert ne % lanes() != 0 and ne > 2 * lanes()
    group = cls(np.arange(ne), conn, xy, get("laws", "J2_LINEAR")(**LAW), 2.0)
    state = group.init_state()
    state["eps_e"] = 1e-3 * rng.standard_normal(state["eps_e"].shape)
    state["peeq"] = np.abs(2e-3 * rng.standard_normal(state["peeq"].shape))
    u_old = 1e-3 * rng.standard_normal(xy.shape)
    return group, state, u_old + 0.01 * rng.standard_normal(xy.shape), u_old


def both_paths(group, state, u_new, u_old, nlgeom: bool, tangent: bool):
    """(NumPy, kernel) outputs: failure, element forces, global force, data, trial state."""
    pattern = Pattern(2 * len(group.coords0), [group.dofs])
    ctx = StepContext(nlgeom=nlgeom)
    out = []
    for fused in (False, True):
        group.use_kernels(fused)
        assert group.fused == fused
        calls = kernels.calls["solid"]
        f_out = np.zeros(pattern.ndof)
        data = np.zeros(pattern.nnz) if tangent else None
        if fused:
            r = group.compute_into(u_new, u_old, state, ctx, tangent, data, f_out,
                                   pattern.positions[0])
            assert kernels.calls["solid"] == calls + 1
        else:
            r = group.compute(u_new, u_old, state, ctx, tangent)
            if r.failure is None:
                f_out = pattern.group_vector(0, r.f)
                data = pattern.assemble_data([r.K]) if tangent else None
        out.append({"failure": r.failure, "f": r.f, "f_out": f_out, "data": data,
                    **{f"state {k}": v for k, v in r.state.items()}})
    return out


def assert_close(ref, fast, what):
    if ref is None or isinstance(ref, str):
        assert fast == ref, f"{what}: kernel {fast!r} != NumPy {ref!r}"
        return
    a, b = np.asarray(ref), np.asarray(fast)
    assert a.shape == b.shape and np.isfinite(b).all(), what
    assert np.abs(a - b).max() <= RTOL * np.abs(a).max(), f"{what}: {np.abs(a - b).max():.3g}"


@pytest.mark.parametrize("ename", ["Q8PE", "Q8AX", "T6AX"])
@pytest.mark.parametrize("nlgeom", [False, True])
@pytest.mark.parametrize("tangent", [True, False])
def test_blocks_and_remainder_match_numpy(ename, nlgeom, tangent):
    group, state, u_new, u_old = group_and_state(ename)
    ref, fast = both_paths(group, state, u_new, u_old, nlgeom, tangent)
    assert ref["failure"] is None
    assert (ref["state peeq"] > state["peeq"]).any()          # plastic points in the blocks
    for key in ref:
        if key == "data" and not tangent:
            continue
        assert_close(ref[key], fast[key], f"{ename} {key}")


def _mirror(group, u, elements):
    """``u`` with ``elements`` mirrored about their centroid (det F < 0 there)."""
    u = u.copy()
    for e in elements:
        X = group.coords0[group.conn[e]]
        u[group.conn[e], 0] = 2 * X[:, 0].mean() - 2 * X[:, 0]
        u[group.conn[e], 1] = 0.0
    return u


@pytest.mark.parametrize("ename", ["Q8PE", "T6AX"])
def test_failures_element_by_element_across_blocks(ename):
    """det F <= 0 in an element of the second block and one of the remainder (and their
    neighbours, whose shared nodes moved): the kernel names the same elements; a NaN
    displacement of one node of the last element: a return-map failure of exactly the
    elements around it (NumPy's message)."""
    group, state, u_new, u_old = group_and_state(ename)
    ne, w = len(group.conn), lanes()
    bad = [w + 2, ne - 1]
    assert set(group.conn[bad[0]]).isdisjoint(group.conn[bad[1]])
    ref, fast = both_paths(group, state, _mirror(group, u_new, bad), u_old, True, True)
    assert ref["failure"] == fast["failure"]
    assert ref["failure"].startswith("non-positive det F in element(s) ")
    named = ref["failure"].split("element(s) ")[1].split(", ")
    assert {str(e) for e in bad} <= set(named) and len(named) < ne // 2
    u_nan = u_new.copy()
    u_nan[group.conn[ne - 1, 0]] = np.nan
    ref, fast = both_paths(group, state, u_nan, u_old, False, True)
    assert ref["failure"] == fast["failure"]
    assert ref["failure"].startswith("return mapping failed in element(s) ")


def test_a_bad_lane_runs_no_law():
    """A BAD_DET_F element's lanes skip the law: with RAMBERG_OSGOOD capped at 2 iterations
    every plastic point's return fails, so a law run in a mirrored element's lane would turn
    its flag into RETURN_MAP_FAILED (and its forces into the scatter); the message stays
    NumPy's det F one, naming the same elements."""
    group, state, u_new, u_old = group_and_state("Q8PE")
    group.law = get("laws", "RAMBERG_OSGOOD")(E=210e3, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0)
    group.law.max_iter = 2                       # read by both paths
    ne, w = len(group.conn), lanes()
    bad = [3, w + 2, ne - 1]
    ref, fast = both_paths(group, state, _mirror(group, u_new, bad), u_old, True, True)
    assert ref["failure"].startswith("non-positive det F in element(s) ")
    assert fast["failure"] == ref["failure"]
    # the same increment unmirrored does fail by the cap (the test can tell the two apart)
    ref, fast = both_paths(group, state, u_new, u_old, True, True)
    assert ref["failure"].startswith("return mapping failed") and fast["failure"] == ref["failure"]
