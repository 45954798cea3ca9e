"""Solid elements Q8/Q4, plane strain and axisymmetric, small strain and NLGEOM.

Independent sources of the asserted numbers:
* patch tests: a linear displacement field (PE: any; AX: u_r = c r, u_z = d z + e, the linear
  fields with uniform stress) imposed on the boundary of a distorted 2x2 patch is reproduced
  exactly at the interior nodes and gives the uniform stress D eps;
* rigid-body motions give no stress (exact invariant);
* tangents equal central finite differences of the internal force;
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
# tiny meshes and a dense assembly (the real solver lives elsewhere)

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


def assemble(group, u, u_old, state, ctx, tangent=True):
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


# --------------------------------------------------------------------------------------------
# patch tests and rigid-body modes

@pytest.mark.parametrize("name", BUILTIN)
def test_patch_test_linear_field_is_exact(name):
    cls = registry.get("elements", name)
    coords, conn, boundary = patch(cls.nen, x0=1.0 if cls.axisymmetric else 0.0)
    g = group_of(name, coords, conn, elastic(), thickness=2.0)
    x, y = coords.T
    if cls.axisymmetric:
        c, d, e = 2e-3, -1e-3, 0.3
        exact = np.stack([c * x, d * y + e], axis=1)
        eps = np.array([c, d, c, 0.0])
    else:
        a0, A = np.array([0.1, -0.2]), np.array([[1e-3, -4e-4], [7e-4, -2e-3]])
        exact = a0 + coords @ A.T
        eps = np.array([A[0, 0], A[1, 1], 0.0, A[0, 1] + A[1, 0]])
    u = np.where(boundary[:, None], exact, 0.0)
    free = np.repeat(~boundary, 2)
    ctx = StepContext(nlgeom=False)
    state = g.init_state()
    F, K, _ = assemble(g, u, 0 * u, state, ctx)
    du = np.linalg.solve(K[np.ix_(free, free)], -F[free])
    u.reshape(-1)[free] += du
    assert free.sum() >= 2
    assert np.abs(u - exact).max() < 1e-10 * np.abs(exact).max()
    F, _, res = assemble(g, u, 0 * u, state, ctx)
    assert np.abs(F[free]).max() < 1e-9 * np.abs(F).max()
    sig = hooke_matrix(E, NU) @ eps
    assert np.allclose(res.state["stress"], sig, rtol=0, atol=1e-10 * np.abs(sig).max())


@pytest.mark.parametrize("name", BUILTIN)
def test_rigid_body_modes_give_no_stress(name):
    cls = registry.get("elements", name)
    coords, conn, _ = patch(cls.nen, x0=1.0 if cls.axisymmetric else 0.0)
    g = group_of(name, coords, conn, elastic())
    x, y = coords.T
    modes = [np.stack([0 * x, 0 * x + 0.3], 1)]          # translation along y (z)
    if not cls.axisymmetric:
        theta = 1e-3                                      # infinitesimal rotation
        modes += [np.stack([0 * x + 0.2, 0 * x - 0.1], 1), theta * np.stack([-y, x], 1)]
    for u in modes:
        F, _, res = assemble(g, u, 0 * u, g.init_state(), StepContext(nlgeom=False))
        assert np.abs(res.state["stress"]).max() < 1e-12 * E
        assert np.abs(F).max() < 1e-12 * E


# --------------------------------------------------------------------------------------------
# consistent tangents

def fd_tangent(g, u, u_old, state, ctx, h):
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
def test_small_strain_tangent_plastic(name):
    cls, coords, rng = one_element(name, 1)
    law = plastic()
    g = cls([7], [np.arange(cls.nen)], coords, law)
    ctx = StepContext(nlgeom=False)
    grad = np.array([[4e-3, 1e-3], [-2e-3, -5e-3]])      # well past yield (300 / 200e3)
    u_old = coords @ grad.T + 2e-4 * rng.normal(size=coords.shape)
    state = previous_increment(g, u_old, ctx)
    u = u_old + coords @ (0.3 * grad).T + 2e-4 * rng.normal(size=coords.shape)
    res = check_tangent(g, u, u_old, state, ctx)
    assert (res.state["peeq"] > state["peeq"]).all()       # every point loads plastically


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


@pytest.mark.parametrize("lawname", ["elastic", "plastic"])
@pytest.mark.parametrize("name", BUILTIN)
def test_large_strain_tangent(name, lawname):
    cls, coords, rng = one_element(name, 2)
    law = elastic() if lawname == "elastic" else plastic()
    g = cls([7], [np.arange(cls.nen)], coords, law)
    ctx = StepContext(nlgeom=True)
    c, s = np.cos(0.4), np.sin(0.4)
    grad = np.array([[0.08, 0.05], [-0.03, -0.1]])       # finite strains and a rotation
    u_old = coords @ grad.T + 0.01 * rng.normal(size=coords.shape)
    state = previous_increment(g, u_old, ctx)
    x_new = coords + u_old
    if not cls.axisymmetric:                             # no rotation about an in-plane axis in AX
        x_new = x_new @ np.array([[c, -s], [s, c]]).T
    u = x_new - coords + 0.05 * (coords - coords.mean(0)) @ np.array([[1.0, 0.5], [0.2, -0.7]]).T
    res = check_tangent(g, u, u_old, state, ctx)
    if lawname == "plastic":
        assert (res.state["peeq"] > state["peeq"]).all()


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


# --------------------------------------------------------------------------------------------
# contract over every registered element class

#: faces S1, S2, ... of the built-in types as the Abaqus manual lists them (1-based: corner,
#: corner, mid-side), written out here rather than read from the classes
ABAQUS_FACES = {
    "Q4": ((1, 2), (2, 3), (3, 4), (4, 1)),
    "Q8": ((1, 2, 5), (2, 3, 6), (3, 4, 7), (4, 1, 8)),
    "T6": ((1, 2, 4), (2, 3, 5), (3, 1, 6)),
}


def left_of(a, b, pts):
    """Cross product (b - a) x (p - a) of points pts (m, 2): > 0 left of the line a -> b."""
    d, r = b - a, pts - a
    return d[0] * r[:, 1] - d[1] * r[:, 0]


def fd_det_j(cls, X, p, h=1e-6):
    """det of dx/dxi of the element X (nen, 2) at natural point p by central differences of
    the position map (an independent check of the shape function derivatives)."""
    def pos(q):
        return cls.shape_functions(np.atleast_2d(q))[0][0] @ X
    J = np.column_stack([(pos(p + d) - pos(p - d)) / (2 * h) for d in np.eye(2) * h])
    return np.linalg.det(J)


def shoelace(xy):
    """Signed area of the polygon xy (m, 2) (positive when counter-clockwise)."""
    x, y = np.asarray(xy, float).T
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


@pytest.mark.parametrize("name", registry.REGISTRY.names("elements"))
def test_element_contract(name):
    """Every registered element type, through its own topology (nodes, faces, rule)."""
    cls = registry.get("elements", name)
    assert cls.params == () or all(isinstance(p, registry.Param) for p in cls.params)
    xi = np.asarray(cls.node_xi, float)
    assert xi.shape == (cls.nen, 2)
    canonical = registry.canonical("elements", name)
    if canonical[:2] in ABAQUS_FACES:                            # the built-ins: Abaqus faces
        assert tuple(tuple(a + 1 for a in f) for f in cls.faces) == ABAQUS_FACES[canonical[:2]]
    # the faces close counter-clockwise around the reference element (body on their left), each
    # corner once; a mid-side node sits in the middle of its (straight) reference edge
    corners = [f[0] for f in cls.faces]
    assert [f[1] for f in cls.faces] == corners[1:] + corners[:1]
    assert len(set(corners)) == len(corners)
    area = shoelace(xi[corners])
    assert area > 0
    for f in cls.faces:
        if len(f) == 3:
            assert np.allclose(xi[f[2]], 0.5 * (xi[f[0]] + xi[f[1]]), atol=1e-14)
    assert sorted(cls.outline) == list(range(cls.nen))
    assert np.isclose(shoelace(xi[list(cls.outline)]), area)
    # the Gauss weights add up to the reference area; the rule's points lie inside it
    gpts, w = cls.gauss_rule()
    assert np.isclose(w.sum(), area, rtol=1e-14)
    assert all((left_of(xi[f[0]], xi[f[1]], gpts) > 0).all() for f in cls.faces)
    rng = np.random.default_rng(0)
    pts = rng.dirichlet(np.ones(cls.nen), size=20) @ xi         # points inside the element
    N, dN = cls.shape_functions(pts)
    assert np.allclose(N.sum(1), 1.0, atol=1e-14)              # partition of unity
    assert np.allclose(dN.sum(1), 0.0, atol=1e-13)
    assert np.allclose(N @ xi, pts, atol=1e-14)                # isoparametric: x = sum N_a x_a
    Nn, _ = cls.shape_functions(xi)
    assert np.allclose(Nn, np.eye(cls.nen), atol=1e-14)        # nodal values
    h = 1e-6
    for k in range(2):
        dp = np.zeros(2)
        dp[k] = h
        fd = (cls.shape_functions(pts + dp)[0] - cls.shape_functions(pts - dp)[0]) / (2 * h)
        assert np.allclose(dN[..., k], fd, atol=1e-8)
    # recovery: a linear field at the Gauss points comes back exactly at the nodes
    lin = lambda p: 0.3 + 1.7 * p[:, 0] - 0.9 * p[:, 1]
    assert np.allclose(cls.recovery_matrix() @ lin(gpts), lin(xi), atol=1e-12)
    # the declared det J space holds det J: a least-squares fit of the monomials of the declared
    # degree (tensor on the square, total on the triangle) through det J by central differences
    # of the position map at 60 random points of a randomly distorted element is exact
    assert cls.reference_domain in ("square", "triangle")
    X = xi + 0.15 * rng.normal(size=xi.shape)
    pts = rng.dirichlet(np.ones(cls.nen), size=60) @ xi
    fd = np.array([fd_det_j(cls, X, p) for p in pts])
    deg = np.atleast_1d(cls.jacobian_degree)
    if cls.reference_domain == "square":
        p_, q_ = (deg[0], deg[-1])
        basis = np.stack([pts[:, 0]**i * pts[:, 1]**j for i in range(p_ + 1) for j in range(q_ + 1)], 1)
    else:
        basis = np.stack([pts[:, 0]**i * pts[:, 1]**j for i in range(deg[0] + 1)
                          for j in range(deg[0] + 1 - i)], 1)
    fit = np.linalg.lstsq(basis, fd, rcond=None)[0]
    assert np.allclose(basis @ fit, fd, atol=1e-7 * np.abs(fd).max())
    # the turned element (mirror) lists the same nodes, runs the other way, and keeps the edges
    perm = cls.mirror()
    assert sorted(perm) == list(range(cls.nen))
    assert shoelace(xi[perm][[f[0] for f in cls.faces]]) < 0
    for k, f in enumerate(cls.faces):
        g = cls.faces[cls.mirror_faces()[k] - 1]
        assert {perm[g[0]], perm[g[1]]} == {f[0], f[1]}
    good = 0.5 * xi + (np.array([2.0, 1.0]) if cls.axisymmetric else 0.0)
    good = good + 0.05 * rng.normal(size=good.shape)
    inverted = good * np.array([-1.0, 1.0]) + (np.array([6.0, 0.0]) if cls.axisymmetric else 0.0)
    mj = cls.min_jacobian(np.stack([good, inverted]))
    assert mj[0] > 0 and mj[1] < 0
    # the reference element scaled by 1/2: det J = 1/4 everywhere
    square = 0.5 * xi + 2.0
    assert np.isclose(cls.min_jacobian(square[None])[0], 0.25, rtol=1e-12)
    if cls.axisymmetric:
        across_axis = square - np.array([2.2, 0.0])            # a node at r < 0
        assert cls.min_jacobian(across_axis[None])[0] < 0
