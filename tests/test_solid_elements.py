"""Solid elements Q8/Q4, plane strain and axisymmetric, small strain and NLGEOM: what is
specific to them.  The element contract -- shape functions, Gauss rule, faces, Jacobian check,
patch test, rigid motions, tangents against finite differences -- is checked on every
registered element class by tests/test_contracts.py (lagamine_py.contracts).

Independent sources of the asserted numbers:
* elastic unloading after plastic loading is the elastic response to the reversal;
* a homogeneous finite strain gives the Hencky stress D ln(V) / J (closed form);
* objectivity: a rigid rotation of a pre-stressed body rotates its stress (R sigma R^T) and
  keeps its invariants; in axisymmetry a rigid rotation is not admissible, a rigid translation
  along z is used instead.
"""
import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.elements.base import StepContext
from lagamine_py.core.tensors import elastic_matrix as hooke_matrix
from lagamine_py.laws.elastic import LinearElastic

E, NU = 200e3, 0.3
BUILTIN = ["Q8PE", "Q8AX", "Q8PER", "Q8AXR", "Q4PE", "Q4AX"]


def elastic():
    return LinearElastic(E=E, NU=NU)


def plastic():
    """The project's Ramberg-Osgood law."""
    return registry.get("laws", "RAMBERG_OSGOOD")(E=E, NU=NU, SIGMA0=300.0, ALPHA=0.5, N=5.0)


# --------------------------------------------------------------------------------------------
# tiny meshes

def patch(nen, x0=0.0):
    """Distorted 2x2 patch on [x0, x0+2] x [0, 2]: interior corner node moved, side nodes slid
    along their sides, straight edges with mid-side nodes at mid-edge.  Returns coords (n, 2),
    conn (4, nen), boundary node mask (n,)."""
    P = np.array([[(x0 + i, j) for j in range(3)] for i in range(3)], float)
    P[1, 1] += (0.17, -0.12)
    P[1, 0, 0] += 0.21
    P[1, 2, 0] -= 0.13
    P[0, 1, 1] += 0.09
    P[2, 1, 1] -= 0.16
    coords = [P[i, j] for i in range(3) for j in range(3)]
    cid = {(i, j): 3 * i + j for i in range(3) for j in range(3)}
    mids, conn = {}, []
    for ex in range(2):
        for ey in range(2):
            c = [cid[ex, ey], cid[ex + 1, ey], cid[ex + 1, ey + 1], cid[ex, ey + 1]]
            if nen == 8:
                for a, b in zip(c, c[1:] + c[:1]):
                    key = (min(a, b), max(a, b))
                    if key not in mids:
                        mids[key] = len(coords)
                        coords.append(0.5 * (coords[a] + coords[b]))
                    c.append(mids[key])
            conn.append(c)
    coords = np.array(coords)
    x, y = coords.T
    boundary = (np.abs(x - x0) < 1e-12) | (np.abs(x - x0 - 2) < 1e-12) | (y < 1e-12) | (y > 2 - 1e-12)
    return coords, np.array(conn), boundary


def group_of(name, coords, conn, law, thickness=1.0):
    cls = registry.get("elements", name)
    return cls(np.arange(1, len(conn) + 1) * 10, conn, coords, law, thickness)


# --------------------------------------------------------------------------------------------
# plasticity and finite strain

def assemble(group, u, u_old, state, ctx, tangent=True):
    """Global force (and tangent) of one group, assembled densely (small test meshes)."""
    n = len(group.coords0)
    res = group.compute(u, u_old, state, ctx, tangent)
    assert res.failure is None, res.failure
    F = np.zeros(2 * n)
    np.add.at(F, group.dofs, res.f)
    K = None
    if tangent:
        K = np.zeros((2 * n, 2 * n))
        np.add.at(K, (group.dofs[:, :, None], group.dofs[:, None, :]), res.K)
    return F, K, res


def fd_tangent(g, u, u_old, state, ctx, h):
    """Element tangents by central differences of the element forces."""
    n = u.size
    Kfd = np.zeros((len(g.conn), g.dofs.shape[1], g.dofs.shape[1]))
    for col in range(g.dofs.shape[1]):
        # perturb DOF `col` of every element at once: elements share nodes, so loop per element
        for e in range(len(g.conn)):
            du = np.zeros(n)
            du[g.dofs[e, col]] = h
            fp = g.compute(u + du.reshape(u.shape), u_old, state, ctx, False).f[e]
            fm = g.compute(u - du.reshape(u.shape), u_old, state, ctx, False).f[e]
            Kfd[e, :, col] = (fp - fm) / (2 * h)
    return Kfd


def check_tangent(g, u, u_old, state, ctx, tol=1e-6):
    """The group's tangent against central differences, relative to its largest entry."""
    res = g.compute(u, u_old, state, ctx)
    assert res.failure is None, res.failure
    Kfd = fd_tangent(g, u, u_old, state, ctx, h=1e-7)
    err = np.abs(res.K - Kfd).max() / np.abs(Kfd).max()
    assert err < tol, err
    return res


def one_element(name, seed):
    cls = registry.get("elements", name)
    rng = np.random.default_rng(seed)
    coords = 0.5 * cls.node_xi + (np.array([2.0, 1.0]) if cls.axisymmetric else 0.0)
    coords = coords + 0.06 * rng.normal(size=coords.shape)
    return cls, coords, rng


def previous_increment(g, u_old, ctx):
    """Committed state after loading from zero to u_old in one increment."""
    res = g.compute(u_old, 0 * u_old, g.init_state(), ctx, tangent=False)
    assert res.failure is None
    return res.state


@pytest.mark.parametrize("name", BUILTIN)
def test_small_strain_elastic_unloading_keeps_the_plastic_strain(name):
    # after plastic loading to u1, a small reversal is elastic: sigma2 = sigma1 + D B (u2 - u1)
    cls, coords, rng = one_element(name, 4)
    g = cls([7], [np.arange(cls.nen)], coords, plastic())
    ctx = StepContext(nlgeom=False)
    u1 = coords @ np.array([[4e-3, 1e-3], [-2e-3, -5e-3]]).T
    state1 = previous_increment(g, u1, ctx)
    assert (state1["peeq"] > 0).all()
    u2 = 0.98 * u1
    res = g.compute(u2, u1, state1, ctx)
    assert np.array_equal(res.state["peeq"], state1["peeq"])
    elastic_group = cls([7], [np.arange(cls.nen)], coords, elastic())
    dsig = elastic_group.compute(u2 - u1, 0 * u1, elastic_group.init_state(), ctx).state["stress"]
    assert np.allclose(res.state["stress"], state1["stress"] + dsig, rtol=0,
                       atol=1e-10 * np.abs(state1["stress"]).max())


@pytest.mark.parametrize("name", BUILTIN)
def test_homogeneous_finite_strain_gives_the_hencky_stress(name):
    # x = F X on a distorted patch: Cauchy stress = D ln(V) / J everywhere, V = sqrt(F F^T)
    from scipy.linalg import logm
    cls = registry.get("elements", name)
    coords, conn, _ = patch(cls.nen, x0=1.0 if cls.axisymmetric else 0.0)
    g = group_of(name, coords, conn, elastic())
    if cls.axisymmetric:
        F3 = np.diag([1.15, 0.8, 1.15])                  # u_r = c r, u_z = d z: F33 = r / R
    else:
        F3 = np.eye(3)
        F3[:2, :2] = [[1.2, 0.3], [-0.1, 0.9]]
    u = coords @ F3[:2, :2].T - coords
    res = g.compute(u, 0 * u, g.init_state(), StepContext(nlgeom=True))
    logV = 0.5 * logm(F3 @ F3.T).real
    tau = hooke_matrix(E, NU) @ np.array([logV[0, 0], logV[1, 1], logV[2, 2], 2 * logV[0, 1]])
    sig = tau / np.linalg.det(F3)
    assert np.allclose(res.state["stress"], sig, rtol=0, atol=1e-10 * np.abs(sig).max())


def test_log_derivative_at_equal_eigenvalues():
    from lagamine_py.elements.solid import log_b
    from scipy.linalg import logm
    b = np.array([[[1.7, 0.0], [0.0, 1.7]], [[1.7, 1e-9], [1e-9, 1.7 + 1e-9]]])
    E, C = log_b(b, derivative=True)
    H = np.array([[0.3, -0.2], [-0.2, 0.5]])
    h = 1e-6
    fd = (np.array([logm(x + h * H) for x in b]) - np.array([logm(x - h * H) for x in b])) / (4 * h)
    assert np.allclose(np.einsum("eijmn,mn->eij", C, H), fd.real, rtol=0, atol=1e-8)
    assert np.allclose(E, 0.5 * np.array([logm(x) for x in b]).real, atol=1e-14)


def test_log_stretch_is_ln_v():
    """The output's ``ln V`` without eigenvectors (:func:`log_stretch`) against its closed form
    ``F = R diag(s) Q``: ``ln V = R diag(ln s) R^T`` (stretches from 1 +- 1e-9 to 3 and 0.3,
    equal stretches, rotations R and Q) and against scipy's ``logm`` of ``F F^T``."""
    from lagamine_py.elements.solid import log_stretch
    from scipy.linalg import logm
    rng = np.random.default_rng(4)
    s = np.array([[1.0, 1.0], [1 + 1e-9, 1.0], [1 + 8e-7, 1.0], [1.001, 0.999], [1.1, 0.95], [3.0, 0.3],
                  [0.5, 0.5], [2.0, 1.0 + 1e-7]])
    ar, aq = rng.uniform(-np.pi, np.pi, (2, len(s)))
    R, Q = np.array([rotation(a) for a in ar]), np.array([rotation(a) for a in aq])
    F = R @ (s[:, :, None] * Q)
    lnV = R @ (np.log(s)[:, :, None] * np.swapaxes(R, 1, 2))
    E11, E22, E12 = log_stretch(F)
    got = np.stack([E11, E22, E12], -1)
    assert np.allclose(got, lnV[:, [0, 1, 0], [0, 1, 1]], rtol=0, atol=1e-15 * 4)
    for Fk, gk in zip(F, got):
        ref = 0.5 * logm(Fk @ Fk.T).real
        assert np.allclose(gk, ref[[0, 1, 0], [0, 1, 1]], rtol=0, atol=1e-13)


# --------------------------------------------------------------------------------------------
# objectivity

def rotation(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def invariants(s):
    """Trace, J2 and det of the 3D stress from 4-vectors (..., 4)."""
    tr = s[..., :3].sum(-1)
    dev = s[..., :3] - tr[..., None] / 3
    j2 = 0.5 * (dev**2).sum(-1) + s[..., 3] ** 2
    det = s[..., 2] * (s[..., 0] * s[..., 1] - s[..., 3] ** 2)
    return np.stack([tr, j2, det], -1)


@pytest.mark.parametrize("name", ["Q8PE", "Q4PE", "Q8PER"])
def test_rigid_rotation_of_a_prestressed_block_plane_strain(name):
    cls = registry.get("elements", name)
    coords, conn, _ = patch(cls.nen)
    g = group_of(name, coords, conn, elastic())
    ctx = StepContext(nlgeom=True)
    rng = np.random.default_rng(5)
    u1 = coords @ np.array([[0.05, 0.02], [0.01, -0.04]]).T + 0.01 * rng.normal(size=coords.shape)
    res = g.compute(u1, 0 * u1, g.init_state(), ctx)
    s1, f1, state = res.state["stress"], res.f, res.state
    inv1 = invariants(s1)
    u_old = u1
    for k in range(1, 11):
        R = rotation(0.5 * np.pi * k / 10)
        u = (coords + u1) @ R.T - coords
        res = g.compute(u, u_old, state, ctx)
        assert res.failure is None
        state, u_old = res.state, u
    s = state["stress"]
    assert np.abs(invariants(s) - inv1).max(axis=(0, 1)).tolist() <= \
        (1e-8 * np.abs(inv1).max(axis=(0, 1))).tolist()
    # 90 degrees: s11 <-> s22, s12 -> -s12, s33 unchanged; nodal forces rotate with the body
    expected = np.stack([s1[..., 1], s1[..., 0], s1[..., 2], -s1[..., 3]], -1)
    assert np.abs(s - expected).max() < 1e-8 * np.abs(s1).max()
    f_rot = (f1.reshape(len(conn), -1, 2) @ R.T).reshape(f1.shape)
    assert np.abs(res.f - f_rot).max() < 1e-8 * np.abs(f1).max()


@pytest.mark.parametrize("name", ["Q8AX", "Q4AX", "Q8AXR"])
def test_rigid_translation_of_a_prestressed_block_axisymmetric(name):
    cls = registry.get("elements", name)
    coords, conn, _ = patch(cls.nen, x0=1.0)
    g = group_of(name, coords, conn, elastic())
    ctx = StepContext(nlgeom=True)
    rng = np.random.default_rng(6)
    u1 = coords @ np.array([[0.05, 0.02], [0.01, -0.04]]).T + 0.01 * rng.normal(size=coords.shape)
    res = g.compute(u1, 0 * u1, g.init_state(), ctx)
    s1, f1, state = res.state["stress"], res.f, res.state
    u_old = u1
    for k in range(1, 11):
        u = u1 + np.array([0.0, 0.3 * k])
        res = g.compute(u, u_old, state, ctx)
        assert res.failure is None
        state, u_old = res.state, u
    assert np.abs(state["stress"] - s1).max() < 1e-8 * np.abs(s1).max()
    assert np.abs(res.f - f1).max() < 1e-8 * np.abs(f1).max()


# --------------------------------------------------------------------------------------------
# failures

def test_failures_name_the_elements():
    cls = registry.get("elements", "Q4PE")
    coords, conn, _ = patch(4)
    g = group_of("Q4PE", coords, conn, elastic())
    # flatten element 30 (third) through itself: det F < 0 at its Gauss points
    u = np.zeros_like(coords)
    top = conn[2, 2:4]
    u[top, 1] = -1.5 * (coords[top, 1] - coords[conn[2, 0], 1])
    res = g.compute(u, 0 * u, g.init_state(), StepContext(nlgeom=True))
    assert res.failure is not None and "30" in res.failure
    # an inverted element in the reference configuration
    bad = cls([5], [[0, 3, 2, 1]], np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), elastic())
    res = bad.compute(np.zeros((4, 2)), np.zeros((4, 2)), bad.init_state(), StepContext())
    assert res.failure is not None and "5" in res.failure

    class Refusing(LinearElastic):
        def update(self, eps, state):
            s, D, st, ok = super().update(eps, state)
            return s, D, st, eps[..., 0] < 1e-3

    g = group_of("Q4PE", coords, conn, Refusing(E=E, NU=NU))
    u = np.stack([2e-3 * coords[:, 0] * (coords[:, 1] > 1.0), 0 * coords[:, 0]], 1)
    res = g.compute(u, 0 * u, g.init_state(), StepContext())
    assert res.failure is not None and "return mapping" in res.failure
    assert "10" not in res.failure.split("element(s)")[1]


def test_gauss_coords_follow_the_displacement():
    coords, conn, _ = patch(8)
    g = group_of("Q8PE", coords, conn, elastic())
    u = 0.1 + 0 * coords
    assert np.allclose(g.gauss_coords(u) - g.gauss_coords(0 * u), 0.1)
    xg = g.gauss_coords(0 * u)
    assert xg.shape == (4, 9, 2) and xg.min() > 0 and xg.max() < 2


@pytest.mark.parametrize("name", ["Q8PE", "Q8AX", "Q4PE"])
@pytest.mark.parametrize("nlgeom", [True, False])
def test_total_strain_by_chunks(name, nlgeom):
    """The output's total strain of a homogeneous stretch u = (F - I) X, F = diag(1.1, 0.95):
    ln 1.1, ln 0.95 (NLGEOM, Hencky) or 0.1, -0.05 (small strain) in-plane, the hoop strain
    ln(r/R) = ln 1.1 (0.1) in axisymmetry, no shear -- computed by chunks of one element
    (as a group larger than ``chunk`` is) and for the whole group at once: the same values."""
    coords, conn, _ = patch(8 if name.startswith("Q8") else 4, x0=1.0)
    g = group_of(name, coords, conn, elastic())
    u = coords * [0.1, -0.05]
    bent = u + 0.02 * coords[:, ::-1] ** 2          # element by element different strains
    whole = g.total_strain(bent, nlgeom)
    g.chunk = 1
    assert np.array_equal(g.total_strain(bent, nlgeom), whole)
    e11, e22 = (np.log(1.1), np.log(0.95)) if nlgeom else (0.1, -0.05)
    e33 = e11 if g.axisymmetric else 0.0
    assert np.allclose(g.total_strain(u, nlgeom), [e11, e22, e33, 0.0], rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# what the contract suite (lagamine_py.contracts) cannot know: the built-ins' faces as the
# Abaqus manual lists them (the whole-element Jacobian check: tests/test_jacobian.py)

#: faces S1, S2, ... of the built-in types as the Abaqus manual lists them (1-based: corner,
#: corner, mid-side), written out here rather than read from the classes
ABAQUS_FACES = {
    "Q4": ((1, 2), (2, 3), (3, 4), (4, 1)),
    "Q8": ((1, 2, 5), (2, 3, 6), (3, 4, 7), (4, 1, 8)),
    "T6": ((1, 2, 4), (2, 3, 5), (3, 1, 6)),
}


@pytest.mark.parametrize("name", [e.name for e in registry.REGISTRY.entries("elements")])
def test_builtin_faces(name):
    cls = registry.get("elements", name)
    if name[:2] in ABAQUS_FACES and cls.__module__.startswith("lagamine_py."):
        assert tuple(tuple(a + 1 for a in f) for f in cls.faces) == ABAQUS_FACES[name[:2]]
