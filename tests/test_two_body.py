"""Two deformable bodies in contact (elements/two_body.py): the master chain's projection, the
forces on both bodies (action = reaction), and the exact tangent, master nodes included,
against central finite differences in open, stick and slip states."""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.elements.base import StepContext
from lagamine_py.elements.two_body import MasterChain, TwoBodyGroup, master_shape


def _pair():
    """Two slave faces (bottom of an upper body, running +x) above three master faces (top of a
    lower body, running -x), curved, non-matching."""
    slave = np.array([[-0.7, 0.05], [0.1, 0.03], [0.9, 0.06], [-0.3, 0.045], [0.5, 0.04]])
    master = np.array([[1.4, 0.0], [0.5, 0.01], [-0.4, -0.01], [-1.3, 0.0],
                       [0.95, 0.012], [0.05, 0.008], [-0.85, -0.012]])
    coords = np.vstack([slave, master])
    slave_faces = np.array([[0, 1, 3], [1, 2, 4]])
    master_faces = np.array([[5, 6, 9], [6, 7, 10], [7, 8, 11]])
    return coords, slave_faces, master_faces


def _law(**kw):
    values = dict(KP=1e3, KT=5e2, PHI=0.3)
    values.update(kw)
    return registry.get("contact_laws", "COULOMB")(**values)


def _setup(case, nlgeom=True, ax=False, substeps=1, passes=1):
    coords, sf, mf = _pair()
    if ax:
        coords = coords + [3.0, 0.0]
    law = _law(SUBSTEPS=substeps)
    grp = TwoBodyGroup("S->M", sf, [1, 2], [1, 1], coords, mf, "M", law, gauss=3,
                       axisymmetric=ax, thickness=2.0, search=1.0, passes=passes,
                       master_elements=[3, 4, 5], master_element_faces=[1, 1, 1])
    rng = np.random.default_rng(3)
    n = len(coords)
    u_old = 2e-3 * rng.standard_normal((n, 2))
    u_old[:5, 1] -= 0.08                      # the slave sinks about 0.01..0.03 into the master
    dv = {"open": 0.0, "stick": 1e-5, "slip": 3e-2}[case]
    u_new = u_old + 1e-4 * rng.standard_normal((n, 2))
    u_new[:5] += [dv, -5e-4]
    u_new[5:] += [-0.3 * dv, 1e-4]
    if case == "open":
        u_old[:5, 1] += 0.2
        u_new[:5, 1] += 0.2
    state = grp.init_state()
    if case != "open":
        d, _, _, _ = grp._master_project(*grp._axes_t(grp._face_x(u_old), nlgeom),
                                         grp.master.positions(u_old), nlgeom, False)
        state["p"] = law.kp * np.maximum(d, 0.0)
        state["tau"] = -0.5 * law.phi * state["p"]
        state["status"][:] = STICK
    return grp, u_old, u_new, state, StepContext(nlgeom=nlgeom)


def _global(grp, f, n):
    b = np.zeros(2 * n)
    np.add.at(b, grp.dofs.ravel(), f.ravel())
    return b


def _fd_check(grp, u_old, u_new, state, ctx, h=1e-7):
    n = len(u_new)
    res = grp.compute(u_new, u_old, state, ctx, tangent=True)
    K = np.zeros((2 * n, 2 * n))
    for e in range(grp.nf):
        np.add.at(K, (grp.dofs[e][:, None], grp.dofs[e][None, :]), res.K[e])
    Kfd = np.zeros_like(K)
    for j in range(2 * n):
        e = np.zeros(2 * n)
        e[j] = h
        fp = grp.compute(u_new + e.reshape(-1, 2), u_old, state, ctx, tangent=False).f
        fm = grp.compute(u_new - e.reshape(-1, 2), u_old, state, ctx, tangent=False).f
        Kfd[:, j] = (_global(grp, fp, n) - _global(grp, fm, n)) / (2 * h)
    return res, K, Kfd


@pytest.mark.parametrize("case", ["open", "stick", "slip"])
@pytest.mark.parametrize("nlgeom,ax,substeps", [(True, False, 1), (False, False, 1),
                                                (True, True, 1), (True, False, 3)])
def test_tangent_matches_finite_differences(case, nlgeom, ax, substeps):
    grp, u_old, u_new, state, ctx = _setup(case, nlgeom, ax, substeps)
    res, K, Kfd = _fd_check(grp, u_old, u_new, state, ctx)
    status = np.asarray(res.state["status"])
    want = {"open": OPEN, "stick": STICK, "slip": SLIP}[case]
    assert (status == want).all(), status
    scale = max(np.abs(K).max(), 1e-12)
    if case == "open":
        assert np.abs(res.f).max() == 0.0 and np.abs(K).max() == 0.0
    else:
        master_cols = grp.dofs[:, grp.nd:].ravel()
        assert np.abs(K[:, master_cols]).max() > 1e-3 * scale      # the master's columns play
        assert np.abs(K - Kfd).max() <= 1e-6 * scale


@pytest.mark.parametrize("case", ["stick", "slip"])
def test_action_equals_reaction(case):
    """The forces on the master's nodes are exactly minus those on the slave's."""
    grp, u_old, u_new, state, ctx = _setup(case)
    res = grp.compute(u_new, u_old, state, ctx, tangent=False)
    n = len(u_new)
    b = _global(grp, res.f, n).reshape(-1, 2)
    slave, master = b[:5].sum(axis=0), b[5:].sum(axis=0)
    assert np.abs(slave).max() > 1.0
    assert np.abs(slave + master).max() <= 1e-13 * np.abs(slave).max()
    # the slave's resultant is what the writers report as the master's force on it
    cp = grp.points(u_new, res.state, ctx)
    assert np.allclose(cp.F, -slave, rtol=1e-12, atol=0)


def test_common_rigid_translation_slides_nothing():
    """Both bodies translated alike: dv = 0, the stuck state stays as it was."""
    grp, u_old, _, state, ctx = _setup("stick")
    u_new = u_old + [0.37, -0.0]
    res = grp.compute(u_new, u_old, state, ctx, tangent=False)
    assert np.allclose(res.state["tau"], state["tau"], rtol=0, atol=1e-12)


def test_projection_against_closed_form():
    """A flat master face y = 0 from x = 1 to -1 (corner, corner, mid): the line from (x, h)
    straight down meets it at s = -x, d = -h."""
    coords = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 0.0]])
    ch = MasterChain([[0, 1, 2]], coords)
    P = np.array([[0.3, 0.2], [-0.5, -0.1], [1.5, 0.1]])
    e_u = np.tile([0.0, -1.0], (3, 1))
    pr = ch.project(P, e_u, ch.positions(np.zeros_like(coords)), np.zeros((3, 1), int))
    assert list(pr["found"]) == [True, True, False]
    assert np.allclose(pr["s"][:2], [-0.3, 0.5]) and np.allclose(pr["d"][:2], [-0.2, 0.1])
    N, dN = master_shape(np.array([-0.3, 0.5]))
    assert np.allclose(N.sum(axis=1), 1.0) and np.allclose(dN.sum(axis=1), 0.0)
    # facing: a line pointing up (slave below the master's top) is not valid
    pr = ch.project(P[:1], -e_u[:1], ch.positions(np.zeros_like(coords)), np.zeros((1, 1), int))
    assert not pr["found"][0]


def test_window_grows_when_points_slide():
    """Sliding the slave far along the master changes its windows (the pattern must grow),
    and refresh says so; a refresh with nothing moved keeps them."""
    grp, u_old, _, _, _ = _setup("stick")
    assert not grp.refresh(u_old) or not grp.refresh(u_old)
    dofs = grp.dofs.copy()
    assert not grp.refresh(u_old)
    u = u_old.copy()
    u[:5, 0] += 2.5
    assert grp.refresh(u)
    assert not np.array_equal(dofs, grp.dofs) or dofs.shape != grp.dofs.shape


# ------------------------------------------------------------------ two passes (PASSES=2)


@pytest.mark.parametrize("case", ["stick", "slip"])
@pytest.mark.parametrize("nlgeom", [True, False])
def test_two_pass_tangent_matches_finite_differences(case, nlgeom):
    """PASSES=2: the master's points project on the slave's faces too; the tangent of both
    passes, each surface's nodes in the other's columns, against central differences."""
    grp, u_old, u_new, state, ctx = _setup(case, nlgeom, passes=2)
    assert grp.nf == 5 and grp.ng == 15
    # each surface's faces pair with the other's only (chain faces 0-1 slave, 2-4 master)
    win = grp.window
    assert ((win[:2] >= 2) | (win[:2] < 0)).all() and (win[2:] < 2).all() and (win >= 0).any()
    res, K, Kfd = _fd_check(grp, u_old, u_new, state, ctx)
    status = np.asarray(res.state["status"]).reshape(grp.nf, grp.nq)
    want = {"stick": STICK, "slip": SLIP}[case]
    assert (status[:2] == want).all()                   # the slave's points
    assert (status[2:] == want).any()                   # and some of the master's
    scale = np.abs(K).max()
    assert np.abs(K - Kfd).max() <= 1e-6 * scale


@pytest.mark.parametrize("case", ["stick", "slip"])
def test_two_passes_average_the_two_one_pass_pairs(case):
    """The two-pass forces are half the sum of the one-pass pairs S on M and M on S (each pass
    at its full penalty, half the weight), and action = reaction holds for the sum."""
    coords, sf, mf = _pair()
    two, u_old, u_new, state, ctx = _setup(case, passes=2)
    law = two.law
    s_on_m = TwoBodyGroup("S->M", sf, [1, 2], [1, 1], coords, mf, "M", law, gauss=3,
                          thickness=2.0, search=1.0)
    m_on_s = TwoBodyGroup("M->S", mf, [3, 4, 5], [1, 1, 1], coords, sf, "S", law, gauss=3,
                          thickness=2.0, search=1.0)
    n = len(coords)
    st = {k: np.asarray(v) for k, v in state.items()}
    half = [{k: v[:6] for k, v in st.items()}, {k: v[6:] for k, v in st.items()}]
    ones = [g.compute(u_new, u_old, h, ctx, tangent=False) for g, h in zip((s_on_m, m_on_s), half)]
    f1 = _global(s_on_m, ones[0].f, n) + _global(m_on_s, ones[1].f, n)
    res = two.compute(u_new, u_old, state, ctx, tangent=False)
    f2 = _global(two, res.f, n)
    assert np.abs(ones[1].f).max() > 1.0                 # the second pass carries force
    assert np.allclose(f2, 0.5 * f1, rtol=0, atol=1e-12 * np.abs(f1).max())
    b = f2.reshape(-1, 2)
    assert np.abs(b[:5].sum(axis=0) + b[5:].sum(axis=0)).max() <= 1e-13 * np.abs(b[:5]).max()


def test_two_pass_points_report_the_other_surface():
    """Writers' records with two passes: every point of both surfaces, the resultant F the sum
    over both passes (minus the master-side forces: here the slave's resultant), and an open
    point's gap measured to the other surface's faces, never to its own (0 would be its own
    face)."""
    grp, u_old, u_new, state, ctx = _setup("open", passes=2)
    res = grp.compute(u_new, u_old, state, ctx, tangent=False)
    cp = grp.points(u_new, res.state, ctx)
    assert len(cp.p) == 15 and (np.asarray(cp.gap) > 0.05).all()     # lifted by 0.2
    grp, u_old, u_new, state, ctx = _setup("stick", passes=2)
    res = grp.compute(u_new, u_old, state, ctx, tangent=False)
    cp = grp.points(u_new, res.state, ctx)
    b = _global(grp, res.f, len(u_new)).reshape(-1, 2)
    assert np.allclose(cp.F, -b[:5].sum(axis=0), rtol=1e-12, atol=0)
