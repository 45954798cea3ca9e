"""Nodal values that never lie: on every example deck, at every output increment, each nodal
value the VTK writer computes lies within the range of the Gauss values of the elements around
the node (found here node by node from the cell blocks the writers were handed), and PEEQ >= 0.
The strains the element hands over check against the homogeneous compression's closed form."""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.core.tensors import von_mises
from lagamine_py.output.vtk import body_fields, recovered

from conftest import DECKS


def gauss_values(cell, name):
    """Gauss values (e, q, k) of a written field, straight from the cell block."""
    s = np.asarray(cell.stress, float)
    table = {"stress": s, "von_mises": von_mises(s)[..., None],
             "pressure": (-(s[..., 0] + s[..., 1] + s[..., 2]) / 3)[..., None],
             "log_strain": cell.strain, "strain": cell.strain,
             "plastic_strain": cell.plastic_strain,
             "PEEQ": np.asarray(cell.peeq, float)[..., None]}
    return np.asarray(table[name], float)


def patch_ranges(n, cells, name):
    """[min, max] (n, k) over the Gauss values of the elements around each node."""
    k = gauss_values(cells[0], name).shape[-1]
    lo, hi = np.full((n, k), np.inf), np.full((n, k), -np.inf)
    for c in cells:
        g = gauss_values(c, name)
        for e, nodes in enumerate(np.asarray(c.conn)):
            lo[nodes] = np.minimum(lo[nodes], g[e].min(axis=0))
            hi[nodes] = np.maximum(hi[nodes], g[e].max(axis=0))
    return lo, hi


def _as4(values):
    """Written values (n,) or (n, 6) -> the Gauss layout (n, 1) or (n, 4)."""
    return values[:, None] if values.ndim == 1 else values[:, :4]


@pytest.mark.parametrize("deck", DECKS, ids=[d.stem for d in DECKS])
def test_nodal_values_lie_within_the_gauss_values_around_the_node(deck, deck_run):
    got = deck_run(deck)
    assert got.outcome.status == 0, got.outcome.message
    checked = 0
    for r in got.results:
        if not r.write_fields:
            continue
        n = len(r.coords0)
        fields = body_fields(r.cells, lambda code: True)
        nodal, _ = recovered(n, r.cells, fields)
        assert {"stress", "von_mises", "pressure", "plastic_strain", "PEEQ"} <= set(nodal)
        for name, values in nodal.items():
            lo, hi = patch_ranges(n, r.cells, name)
            used = np.isfinite(lo[:, 0])
            v = _as4(values)[used]
            tol = 1e-12 * max(np.abs(lo[used]).max(), np.abs(hi[used]).max(), 1e-300)
            where = (name, r.step, r.increment)
            assert (v >= lo[used] - tol).all() and (v <= hi[used] + tol).all(), where
        assert (nodal["PEEQ"] >= 0).all()
        checked += 1
    assert checked


def test_tube_von_mises_overshoot_is_gone(deck_run):
    """tube_crimp: extrapolated and averaged, the nodal von Mises stress exceeded every
    Gauss value around the node; recovered, its maximum is at most the largest Gauss value."""
    got = deck_run(next(d for d in DECKS if d.stem == "tube_crimp"))
    r = got.results[-1]
    fields = [f for f in body_fields(r.cells, lambda code: True) if f[0] == "von_mises"]
    plain, _ = recovered(len(r.coords0), r.cells, fields, bounded=False)
    bounded, _ = recovered(len(r.coords0), r.cells, fields)
    lo, hi = patch_ranges(len(r.coords0), r.cells, "von_mises")
    gauss_max = max(float(von_mises(np.asarray(c.stress)).max()) for c in r.cells)
    assert (plain["von_mises"] > hi[:, 0] + 1.0).any()          # MPa above the patch: the lie
    assert bounded["von_mises"].max() <= gauss_max * (1 + 1e-12)


def test_homogeneous_compression_strains(deck_run):
    """compression_ro (30 % frictionless upsetting of a Ramberg-Osgood cylinder, homogeneous):
    at every Gauss point the logarithmic strain is ln of the stretches (axial ln(h/H0), radial
    and hoop ln(r/R0) of the outer radius), the plastic strain is traceless (plastic
    incompressibility) with PEEQ = sqrt(2/3 PE:PE) (proportional loading)."""
    got = deck_run(next(d for d in DECKS if d.stem == "compression_ro"))
    r = got.results[-1]
    (c,) = r.cells
    assert c.strain_kind == "log"
    LE, PE = np.asarray(c.strain), np.asarray(c.plastic_strain)
    outer = np.isclose(r.coords0[:, 0], 5.0)
    radius = 5.0 + r.u[outer, 0].mean()
    np.testing.assert_allclose(LE[..., 1], np.log(7.0 / 10.0), rtol=1e-10)
    np.testing.assert_allclose(LE[..., 0], np.log(radius / 5.0), rtol=1e-8)
    np.testing.assert_allclose(LE[..., 2], np.log(radius / 5.0), rtol=1e-8)
    np.testing.assert_allclose(LE[..., 3], 0.0, atol=1e-12)
    scale = np.abs(PE).max()
    np.testing.assert_allclose(PE[..., :3].sum(axis=-1), 0.0, atol=1e-10 * scale)
    contraction = (PE[..., :3] ** 2).sum(axis=-1) + 2 * PE[..., 3] ** 2
    np.testing.assert_allclose(np.sqrt(2.0 / 3.0 * contraction), c.peeq, rtol=1e-8)


def test_a_plan_computes_each_recovery_matrix_once():
    """RecoveryPlan caches the recovery matrix and the Gauss weights per element class: the
    same nodal values as without a plan, and one computation across many states."""
    from lagamine_py.elements.quad import Q8PlaneStrain
    from lagamine_py.output.recovery import RecoveryPlan, nodal_values

    calls = []

    class Counted(Q8PlaneStrain):
        @classmethod
        def recovery_matrix(cls, nq=None):
            calls.append(nq)
            return super().recovery_matrix(nq)

    conn = np.array([[0, 1, 2, 3, 4, 5, 6, 7], [1, 8, 9, 2, 10, 11, 12, 5]])
    rng = np.random.default_rng(2)
    plan = RecoveryPlan(13, [conn])
    for _ in range(3):
        g = rng.normal(size=(2, 9, 2))
        with_plan = nodal_values(13, [(Counted, conn, g)], plan=plan)
        assert np.array_equal(with_plan, nodal_values(13, [(Q8PlaneStrain, conn, g)]))
    assert calls == [9]
    assert plan.gauss_weights(Counted) is plan.gauss_weights(Counted)
    assert np.array_equal(plan.gauss_weights(Counted), Q8PlaneStrain.gauss_weights())


def _q8_grid(nx, ny):
    """Q8 connectivity of an nx x ny grid on the (2 nx + 1) x (2 ny + 1) lattice of nodes
    (the element centres are nodes of no element) and the lattice's node count."""
    row = 2 * nx + 1

    def n(i, j):
        return j * row + i
    conn = [[n(2 * i, 2 * j), n(2 * i + 2, 2 * j), n(2 * i + 2, 2 * j + 2), n(2 * i, 2 * j + 2),
             n(2 * i + 1, 2 * j), n(2 * i + 2, 2 * j + 1), n(2 * i + 1, 2 * j + 2),
             n(2 * i, 2 * j + 1)] for j in range(ny) for i in range(nx)]
    return np.array(conn), row * (2 * ny + 1)


def test_patch_ranges_are_each_nodes_gauss_extremes_bit_for_bit():
    """The bounded recovery (nodes grouped by their number of elements, the ranges by
    element-wise minima and maxima over whole columns) clips each node to exactly the
    [min, max] of the Gauss values of its elements, found here node by node: the same bits,
    signed zeros and NaN included, on two blocks (Q8 and T6) sharing nodes, with nodes of 1, 2,
    3, 4 and 5 elements and nodes of none (left at 0)."""
    from lagamine_py.elements.quad import Q8PlaneStrain
    from lagamine_py.elements.t6 import T6PlaneStrain
    from lagamine_py.output.recovery import RecoveryPlan, nodal_values

    q8, n = _q8_grid(3, 2)
    # two T6 sharing nodes with the grid: corner 0 (then in 3 elements), the interior corner
    # node 16 (in 5); node n + 3 is in none
    t6 = np.array([[0, 2, n, 1, n + 1, n + 2], [0, n, 16, n + 2, n + 4, n + 5]])
    n_nodes = n + 6
    rng = np.random.default_rng(7)
    gq = rng.normal(size=(len(q8), 9, 3))
    gt = rng.normal(size=(len(t6), 3, 3))
    gq[0, :, 0] = 0.0                     # a node whose range ends at +0.0 on one side
    gq[1, :, 0] = -0.0                    # ... and -0.0 on the other
    gq[2, 4, 1] = np.nan                  # NaN propagates to the nodes of element 2
    blocks = [(Q8PlaneStrain, q8, gq), (T6PlaneStrain, t6, gt)]
    plain = nodal_values(n_nodes, blocks, bounded=False)
    plan = RecoveryPlan(n_nodes, [q8, t6])
    assert {len(e) for _, e in plan.patches} == {1, 2, 3, 4, 5}
    got = nodal_values(n_nodes, blocks, plan=plan)

    expected = plain.copy()
    for node in range(n_nodes):
        patch = [g[e] for (_, conn, g) in blocks for e in np.flatnonzero((conn == node).any(1))]
        if patch:
            lo = np.min([p.min(axis=0) for p in patch], axis=0)
            hi = np.max([p.max(axis=0) for p in patch], axis=0)
            expected[node] = np.clip(plain[node], lo, hi)
    assert np.array_equal(got.view(np.int64), expected.view(np.int64))     # bits: -0.0, NaN
    assert np.isnan(got[q8[2], 1]).all() and not np.isnan(np.delete(got[:, 1], q8[2])).any()
    unused = np.setdiff1d(np.arange(n_nodes), np.concatenate([q8.ravel(), t6.ravel()]))
    assert len(unused) and not got[unused].any()
    assert (got != plain).any()           # the clipping acted somewhere


def test_von_mises_closed_forms_and_the_reductions_bits():
    """``von_mises``: uniaxial sigma -> |sigma|, pure shear tau -> sqrt(3) |tau|, a pressure
    -> 0 (closed forms); and on random stresses the same bits as the mean and the sum over the
    short axis it replaced (so the VTU files did not change): those reductions add
    ``(s11 + s22) + s33``."""
    rng = np.random.default_rng(3)
    sigma, tau, p = 123.0, 45.0, 67.0
    stresses = np.array([[sigma, 0, 0, 0], [0, 0, -sigma, 0], [0, 0, 0, tau], [-p, -p, -p, 0]])
    np.testing.assert_allclose(von_mises(stresses), [sigma, sigma, np.sqrt(3) * tau, 0],
                               rtol=1e-15, atol=1e-13)
    s = rng.normal(size=(2000, 9, 4)) * 10.0 ** rng.integers(-3, 4, size=(2000, 9, 1))
    dev = s - s[..., :3].mean(-1, keepdims=True) * np.array([1.0, 1.0, 1.0, 0.0])
    reduced = np.sqrt(1.5 * (np.sum(dev[..., :3] ** 2, -1) + 2.0 * dev[..., 3] ** 2))
    assert np.array_equal(von_mises(s).view(np.int64), reduced.view(np.int64))
