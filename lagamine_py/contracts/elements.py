"""The element contract (:class:`lagamine_py.elements.base.Element`) as checks.

Only the contract is used -- ``node_xi``, ``faces``, ``outline``, ``vtk_cell``, ``cell_elements``,
``shape_functions``, ``gauss_rule``, ``recovery_basis``, ``reference_domain``,
``jacobian_degree``, ``invalid``, ``mirror`` and the
mechanics ``Cls(ids, conn, coords0, law, thickness).compute`` -- so any topology declared through
it is checked (quadrilaterals, triangles ...).  Independent sources: exact invariants (partition
of unity, areas and first moments of affine elements, linear fields, rigid motions), the patch
test, Hooke's law, VTK's own parametric coordinates and central finite differences.
"""
from __future__ import annotations

import math

import numpy as np

from .findings import ContractFailure, Finding, Skip, Suite, all_within, require, within


ELEMENT_ITEMS = ("shape functions", "shape derivatives", "gauss rule", "faces", "outline",
                 "jacobian check", "recovery", "vtk cell", "patch test", "rigid motion",
                 "tangent (small strain)", "tangent (NLGEOM)", "tangent later")

_E, _NU = 200e3, 0.3                 # the elastic and elasto-plastic laws the element checks use
_SIGMAY, _H = 300.0, 2000.0


def _elastic_law():
    from ..laws.elastic import LinearElastic
    return LinearElastic(E=_E, NU=_NU)


def _plastic_law():
    from ..laws.j2 import J2Linear
    return J2Linear(E=_E, NU=_NU, SIGMAY=_SIGMAY, H=_H)


def _signed_area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _centroid(poly: np.ndarray) -> np.ndarray:
    """Centroid of a simple polygon (shoelace)."""
    x, y = poly[:, 0], poly[:, 1]
    c = x * np.roll(y, -1) - np.roll(x, -1) * y
    a = 0.5 * c.sum()
    return np.array([np.sum((x + np.roll(x, -1)) * c), np.sum((y + np.roll(y, -1)) * c)]) / (6 * a)


def _reference_polygon(cls) -> np.ndarray:
    """The reference element as a counter-clockwise polygon: the convex hull of its nodes
    (reference elements are convex; mid-side nodes lie on its edges)."""
    pts = sorted(map(tuple, np.asarray(cls.node_xi, float).round(14)))

    def turn(o, a, b):              # > 0: o -> a -> b turns left
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def half(points):               # Andrew's monotone chain
        chain = []
        for p in points:
            while len(chain) >= 2 and turn(chain[-2], chain[-1], p) <= 0:
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1], float)


def _inside(poly: np.ndarray, pts: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """Points inside or on a convex polygon (either orientation)."""
    s = np.sign(_signed_area(poly))
    a, b = poly, np.roll(poly, -1, axis=0)
    e = b - a                                                         # (m, 2) edges
    rel = pts[:, None, :] - a[None]                                   # (p, m, 2)
    cross = e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0]
    return np.all(s * cross >= -tol * np.abs(e).max(), axis=1)


def _interior_points(cls, n: int, seed: int) -> np.ndarray:
    """Random points inside the reference element: convex combinations of its outline."""
    poly = _reference_polygon(cls)
    w = np.random.default_rng(seed).dirichlet(np.ones(len(poly)), size=n)
    return w @ poly


def _reference_frame(cls) -> tuple[np.ndarray, float]:
    """Centre and size of the reference element (to build elements of unit size)."""
    xi = np.asarray(cls.node_xi, float)
    return _centroid(_reference_polygon(cls)), float(np.ptp(xi, axis=0).max())


def _shape_functions(cls) -> str:
    xi = np.asarray(cls.node_xi, float)
    pts = np.concatenate([_interior_points(cls, 40, 1), cls.gauss_rule()[0], cls.node_xi])
    N, dN = cls.shape_functions(pts)
    require(N.shape == (len(pts), cls.nen) and dN.shape == (len(pts), cls.nen, 2),
            f"shape_functions gives N {N.shape}, dN {dN.shape}; the contract says "
            f"({len(pts)}, {cls.nen}) and ({len(pts)}, {cls.nen}, 2)")
    Nn = cls.shape_functions(xi)[0]
    return all_within([
        ("max |sum_a N_a - 1|", float(np.abs(N.sum(1) - 1).max()), 1e-12),
        ("max |sum_a dN_a|", float(np.abs(dN.sum(1)).max()), 1e-11),
        ("max |N_a(xi_b) - delta_ab|", float(np.abs(Nn - np.eye(cls.nen)).max()), 1e-12),
        ("max |sum_a N_a xi_a - xi| (linear fields)", float(np.abs(N @ xi - pts).max()), 1e-12),
        ("max |sum_a xi_a dN_a - I|",
         float(np.abs(np.einsum("ai,qak->qik", xi, dN) - np.eye(2)).max()), 1e-11)])


def _shape_derivatives(cls) -> str:
    pts = _interior_points(cls, 30, 2)
    _, dN = cls.shape_functions(pts)
    _, size = _reference_frame(cls)
    h = 1e-6 * size
    err = 0.0
    for k in range(2):
        dp = np.zeros(2)
        dp[k] = h
        fd = (cls.shape_functions(pts + dp)[0] - cls.shape_functions(pts - dp)[0]) / (2 * h)
        err = max(err, float(np.abs(dN[..., k] - fd).max()) * size)
    return within("max |dN/dxi - central difference| (x reference size)", err, 1e-7)


_AFFINE = np.array([[1.3, 0.4], [-0.2, 0.9]])         # det 1.25, no symmetry of any element


def _gauss_rule(cls) -> str:
    pts, w = cls.gauss_rule()
    pts, w = np.asarray(pts, float), np.asarray(w, float)
    require(pts.ndim == 2 and pts.shape[1] == 2 and w.shape == (len(pts),),
            f"gauss_rule gives points {pts.shape}, weights {w.shape}")
    poly = _reference_polygon(cls)
    area0 = abs(_signed_area(poly))
    c0 = _centroid(poly)
    outside = ~_inside(poly, pts)
    require(not outside.any(), f"Gauss points outside the reference element: {pts[outside]}")
    shift = np.array([2.0, 1.0])
    x = np.asarray(cls.node_xi, float) @ _AFFINE.T + shift          # an affine element
    N, dN = cls.shape_functions(pts)
    detj = np.linalg.det(np.einsum("ai,qak->qik", x, dN))
    xq = N @ x
    area = float(np.sum(w * detj))
    exact_area = np.linalg.det(_AFFINE) * area0
    moment = np.sum((w * detj)[:, None] * xq, axis=0)
    exact_moment = exact_area * (_AFFINE @ c0 + shift)
    return all_within([
        (f"|area - det(A) area_ref| / area (area {exact_area:.6g})",
         abs(area - exact_area) / exact_area, 1e-12),
        ("max |int x dA - area x_centroid| / (area |x_centroid|)",
         float(np.abs(moment - exact_moment).max() / np.abs(exact_moment).max()), 1e-12)])


def _faces(cls) -> str:
    from ..elements.shapes import line_shape
    xi = np.asarray(cls.node_xi, float)
    gauss = np.asarray(cls.gauss_rule()[0], float)
    s = np.linspace(-1.0, 1.0, 9)
    worst_shape, problems = 0.0, []
    for k, face in enumerate(cls.faces, 1):
        face = list(face)
        Nl, _ = line_shape(len(face), s)
        on_face = Nl @ xi[face]                                      # points along the face
        N, _ = cls.shape_functions(on_face)
        others = [a for a in range(cls.nen) if a not in face]
        # along the face only its nodes interpolate, as the edge line_shape says
        worst_shape = max(worst_shape, float(np.abs(N[:, face] - Nl).max()),
                          float(np.abs(N[:, others]).max()) if others else 0.0)
        t = xi[face[1]] - xi[face[0]]
        rel = gauss - xi[face[0]]
        left = t[0] * rel[:, 1] - t[1] * rel[:, 0]                  # > 0: on the left
        if not (left > 0).all():
            problems.append(f"S{k} {tuple(face)} has Gauss points on its right "
                            f"(min cross {left.min():.3g}): the outward normal points inward")
    if problems:
        raise ContractFailure("; ".join(problems))
    return within("element on the left of every face (all Gauss points); "
                  "max |N along a face - line_shape of its nodes| and |N of other nodes|",
                  worst_shape, 1e-12)


def _adjacent_pairs(faces) -> set:
    pairs = set()
    for f in faces:
        chain = (f[0], f[2], f[1]) if len(f) == 3 else tuple(f)
        pairs |= {frozenset(p) for p in zip(chain, chain[1:])}
    return pairs


def _outline(cls) -> str:
    out = list(cls.outline)
    require(len(set(out)) == len(out), f"outline {tuple(out)} visits a node twice")
    steps = {frozenset(p) for p in zip(out, out[1:] + out[:1])}
    boundary = _adjacent_pairs(cls.faces)
    require(steps == boundary,
            f"outline {tuple(out)} does not walk the boundary along the faces: steps "
            f"{sorted(tuple(sorted(p)) for p in steps - boundary)} are not face segments, "
            f"{sorted(tuple(sorted(p)) for p in boundary - steps)} are missed")
    return f"outline {tuple(out)} walks the {len(boundary)} face segments in order"


def _fd_det_j(cls, X: np.ndarray, pts: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """det dx/dxi of element ``X`` (nen, 2) at natural points ``pts`` by central differences of
    the position map (independent of the shape-function derivatives)."""
    def pos(q):
        return cls.shape_functions(q)[0] @ X
    cols = [(pos(pts + d) - pos(pts - d)) / (2 * h) for d in np.eye(2) * h]
    return cols[0][:, 0] * cols[1][:, 1] - cols[0][:, 1] * cols[1][:, 0]


def _det_j_monomials(cls, pts: np.ndarray) -> np.ndarray:
    """The monomials of the declared det J space at ``pts``: tensor degree ``(p, q)`` on the
    square, total degree on the triangle."""
    deg = np.atleast_1d(cls.jacobian_degree)
    x, y = pts[:, 0], pts[:, 1]
    if cls.reference_domain == "square":
        return np.stack([x**i * y**j for i in range(deg[0] + 1) for j in range(deg[-1] + 1)], 1)
    return np.stack([x**i * y**j for i in range(deg[0] + 1) for j in range(deg[0] + 1 - i)], 1)


def _jacobian(cls) -> str:
    xi = np.asarray(cls.node_xi, float)
    # the Bernstein bound is only a proof if det J lies in the declared polynomial space: a
    # least-squares fit of its monomials through det J of a distorted element is exact
    rng = np.random.default_rng(3)
    size = float(np.ptp(xi, axis=0).max())
    X = xi + 0.08 * size * rng.normal(size=xi.shape)
    pts = _interior_points(cls, 60, 4)
    fd = _fd_det_j(cls, X, pts)
    basis = _det_j_monomials(cls, pts)
    fit = np.linalg.lstsq(basis, fd, rcond=None)[0]
    misfit = float(np.abs(basis @ fit - fd).max() / np.abs(fd).max())
    require(misfit < 1e-6,
            f"det J of a distorted element is not a polynomial of the declared jacobian_degree "
            f"{cls.jacobian_degree} on the {cls.reference_domain} (misfit {misfit:.2g}): the "
            f"whole-element Jacobian check would prove nothing")
    # mirror(): the turned element lists every node once, runs clockwise, keeps the edges
    perm = np.asarray(cls.mirror())
    corners = [f[0] for f in cls.faces]
    require(sorted(perm.tolist()) == list(range(cls.nen)) and _signed_area(xi[perm][corners]) < 0,
            f"mirror() {tuple(perm)} does not turn the element over")
    turned = cls.mirror_faces()
    for k, f in enumerate(cls.faces):
        g = cls.faces[turned[k] - 1]
        require({int(perm[g[0]]), int(perm[g[1]])} == {f[0], f[1]},
                f"mirror_faces() sends face S{k + 1} to S{turned[k]}, another edge")
    lo = xi[:, 0].min()
    shift = np.array([1.0 - lo, 0.0]) if cls.axisymmetric else np.zeros(2)
    mirror_shift = np.array([1.0 + xi[:, 0].max(), 0.0]) if cls.axisymmetric else np.zeros(2)
    reference = xi + shift                                     # det J = 1 everywhere
    affine = xi @ _AFFINE.T + shift + np.array([0.5, 0.0])     # det J = 1.25
    mirror = xi * np.array([-1.0, 1.0]) + mirror_shift         # reflected: det J = -1
    flat = np.column_stack([xi[:, 0] + shift[0], np.zeros(len(xi))])   # degenerate
    coords = [reference, affine, mirror, flat]
    if cls.axisymmetric:
        coords.append(xi - np.array([xi[:, 0].mean(), 0.0]))           # across the axis
    bad, detj = cls.invalid(np.stack(coords))
    want = [False, False, True, True] + ([True] if cls.axisymmetric else [])
    names = ["reference", "affine", "mirror image", "degenerate", "across the axis"]
    wrong = [names[k] for k in range(len(want)) if bool(bad[k]) != want[k]]
    require(not wrong, f"invalid() is wrong for the {', '.join(wrong)} element(s) "
                       f"(min det J {', '.join(f'{d:.3g}' for d in detj)})")
    return all_within([("det J misfit of the declared degree", misfit, 1e-6),
                       ("|min det J - 1| (reference element)", abs(detj[0] - 1.0), 1e-12),
                       ("|min det J - det A| / det A (affine)", abs(detj[1] / 1.25 - 1.0), 1e-12),
                       ("|min det J + 1| (mirror image, refused)", abs(detj[2] + 1.0), 1e-12)])


def _recovery(cls) -> str:
    pts = np.asarray(cls.gauss_rule()[0], float)
    xi = np.asarray(cls.node_xi, float)
    E = np.asarray(cls.recovery_matrix(len(pts)), float)
    require(E.shape == (cls.nen, len(pts)),
            f"recovery_matrix is {E.shape}, the contract says ({cls.nen}, {len(pts)})")
    fields = [np.ones(len(pts))]
    expect = [np.ones(cls.nen)]
    spread = np.linalg.matrix_rank(np.column_stack([np.ones(len(pts)), pts]))
    if spread == 3:              # three non-collinear Gauss points hold every linear field
        for k in range(2):
            fields.append(pts[:, k])
            expect.append(xi[:, k])
    basis_g = cls.recovery_basis(pts, len(pts))
    basis_n = cls.recovery_basis(xi, len(pts))
    c = np.random.default_rng(3).normal(size=basis_g.shape[1])
    fields.append(basis_g @ c)
    expect.append(basis_n @ c)
    err = max(float(np.abs(E @ f - x).max() / max(np.abs(x).max(), 1.0))
              for f, x in zip(fields, expect))
    what = "constant" + (", linear" if spread == 3 else "") + " and recovery_basis fields"
    return within(f"max |recovered - exact| at the nodes ({what})", err, 1e-10)


def _vtk_cell(cls) -> str:
    try:
        from vtkmodules.vtkCommonDataModel import vtkGenericCell
    except ImportError:                                          # pragma: no cover
        raise Skip("vtk is not importable") from None
    cell = vtkGenericCell()
    cell.SetCellType(int(cls.vtk_cell))
    n = cell.GetNumberOfPoints()
    require(n == cls.nen, f"VTK cell type {cls.vtk_cell} has {n} points, the element {cls.nen}")
    pc = np.asarray(cell.GetParametricCoords(), float).reshape(n, 3)[:, :2]
    # the same nodes in the same order: node_xi is an affine image of VTK's parametric points
    M = np.column_stack([pc, np.ones(n)])
    fit, *_ = np.linalg.lstsq(M, np.asarray(cls.node_xi, float), rcond=None)
    err = float(np.abs(M @ fit - cls.node_xi).max())
    if abs(np.linalg.det(fit[:2])) < 1e-12:
        err = math.inf                  # no affine map at all: another node order
    return within(f"node_xi vs VTK cell {cls.vtk_cell}'s parametric points through an affine "
                  f"map (the same node order): max residual", err, 1e-12)


# -- mechanics --------------------------------------------------------------------------------

def _assemble(group, res, n: int, tangent: bool = True):
    F = np.zeros(2 * n)
    np.add.at(F, group.dofs, res.f)
    if not tangent:
        return F, None
    K = np.zeros((2 * n, 2 * n))
    np.add.at(K, (group.dofs[:, :, None], group.dofs[:, None, :]), res.K)
    return F, K


def _compute(group, u, u_old, state, ctx, tangent=True):
    res = group.compute(u, u_old, state, ctx, tangent)
    if res.failure:
        raise ContractFailure(f"compute() failed: {res.failure}")
    return res


def _patch(cls):
    """A distorted patch of 2 x 2 *MESH cells on [x0, x0 + 2] x [0, 2] (x0 = 1 in axisymmetry)
    with straight edges, the classical patch: the centre vertex moved, the side vertices slid
    along their sides, every node the bilinear image of its cell's vertices, mid-face nodes at
    mid-face.  Returns ``(coords, conn, boundary mask, what)``; one element (an affine image of
    the reference element) when the class declares no *MESH cell."""
    from ..elements.structured import rectangle
    x0 = 1.0 if cls.axisymmetric else 0.0
    if not cls.cell_elements:
        c, size = _reference_frame(cls)
        coords = (np.asarray(cls.node_xi, float) - c) / size @ np.array([[1.6, 0.3], [-0.2, 1.4]]).T
        return (coords + np.array([x0 + 1.0, 1.0]), np.arange(cls.nen)[None],
                np.ones(cls.nen, bool), "one element (the class declares no *MESH cell)")
    mesh = rectangle(cls, x0, 0.0, 2.0, 2.0, 2, 2)
    conn = np.asarray(mesh.conn)
    boundary = np.zeros(len(mesh.coords), bool)
    for nodes in mesh.side_nodes.values():
        boundary[nodes] = True
    m = int(cls.grid_order)
    V = np.stack(np.meshgrid([x0, x0 + 1.0, x0 + 2.0], [0.0, 1.0, 2.0], indexing="ij"), -1)
    V[1, 1] += (0.17, -0.12)                     # the centre vertex
    V[1, 0, 0] += 0.21                           # side vertices slide along their sides
    V[1, 2, 0] -= 0.13
    V[0, 1, 1] += 0.09
    V[2, 1, 1] -= 0.16
    g = np.rint((mesh.coords - (x0, 0.0)) * m).astype(int)          # grid indices (spacing 1/m)
    ci, cj = np.minimum(g[:, 0] // m, 1), np.minimum(g[:, 1] // m, 1)
    s, t = (g[:, 0] - m * ci) / m, (g[:, 1] - m * cj) / m
    coords = ((1 - s) * (1 - t))[:, None] * V[ci, cj] + (s * (1 - t))[:, None] * V[ci + 1, cj] \
        + (s * t)[:, None] * V[ci + 1, cj + 1] + ((1 - s) * t)[:, None] * V[ci, cj + 1]
    for face in cls.faces:                       # mid-face nodes at mid-face: straight faces
        if len(face) == 3:
            coords[conn[:, face[2]]] = 0.5 * (coords[conn[:, face[0]]] + coords[conn[:, face[1]]])
    bad = cls.invalid(coords[conn])[0]
    require(not bad.any(), f"the distorted patch has invalid elements {np.flatnonzero(bad)}")
    return coords, conn, boundary, f"{len(conn)} elements of 2 x 2 distorted *MESH cells"


def _linear_field(cls, coords):
    """A linear displacement field of uniform strain (the axisymmetric ones: u_r = c r,
    u_z = d z + e) and its strain 4-vector."""
    if cls.axisymmetric:
        c, d, e = 2e-3, -1e-3, 0.3
        return np.column_stack([c * coords[:, 0], d * coords[:, 1] + e]), np.array([c, d, c, 0.0])
    a0, A = np.array([0.1, -0.2]), np.array([[1e-3, -4e-4], [7e-4, -2e-3]])
    return a0 + coords @ A.T, np.array([A[0, 0], A[1, 1], 0.0, A[0, 1] + A[1, 0]])


def _patch_test(cls) -> str:
    from ..core.tensors import elastic_matrix
    from ..elements.base import StepContext
    coords, conn, boundary, what = _patch(cls)
    n = len(coords)
    g = cls(np.arange(1, len(conn) + 1), conn, coords, _elastic_law(), 1.5)
    exact, eps = _linear_field(cls, coords)
    sig = elastic_matrix(_E, _NU) @ eps
    ctx = StepContext(nlgeom=False)
    res = _compute(g, exact, 0 * exact, g.init_state(), ctx)
    F, _ = _assemble(g, res, n, tangent=False)
    free = np.repeat(~boundary, 2)
    measures = [("max |stress - D eps| / |D eps| (uniform stress)",
                 float(np.abs(res.state["stress"] - sig).max() / np.abs(sig).max()), 1e-10)]
    if free.any():
        measures.append(("max |f| at interior nodes / max |f| (balance)",
                         float(np.abs(F[free]).max() / np.abs(F).max()), 1e-10))
        u = np.where(boundary[:, None], exact, 0.0)
        r0 = _compute(g, u, 0 * u, g.init_state(), ctx)
        F0, K0 = _assemble(g, r0, n)
        u.reshape(-1)[free] += np.linalg.solve(K0[np.ix_(free, free)], -F0[free])
        measures.append(("max |u - exact| / max |exact| (interior nodes solved)",
                         float(np.abs(u - exact).max() / np.abs(exact).max()), 1e-10))
    return f"{what}, {'axisymmetric' if cls.axisymmetric else 'plane strain'}: " + \
        all_within(measures)


def _rigid_motion(cls) -> str:
    from ..elements.base import StepContext
    coords, conn, _, _ = _patch(cls)
    g = cls(np.arange(1, len(conn) + 1), conn, coords, _elastic_law(), 1.0)
    small, large = StepContext(nlgeom=False), StepContext(nlgeom=True)
    # scales: the stress and the nodal forces per unit strain (of a uniaxial stretch)
    stretch = 1e-3 * np.column_stack([coords[:, 0], 0 * coords[:, 0]])
    r = _compute(g, stretch, 0 * stretch, g.init_state(), small)
    sig_ref, f_ref = np.abs(r.state["stress"]).max() / 1e-3, np.abs(r.f).max() / 1e-3
    measures = []
    t = np.array([0.0, 0.3]) if cls.axisymmetric else np.array([0.2, -0.1])
    u = np.broadcast_to(t, coords.shape).copy()
    r = _compute(g, u, 0 * u, g.init_state(), small)
    m = np.abs(t).max() / 2.0                   # the motion over the patch size
    measures += [("translation (small strain): max |stress| / stress(strain |t| / L)",
                  np.abs(r.state["stress"]).max() / (sig_ref * m), 1e-10),
                 ("max |f| / f(strain |t| / L)", np.abs(r.f).max() / (f_ref * m), 1e-10)]
    state, u_old = g.init_state(), np.zeros_like(coords)
    centre = coords.mean(axis=0)
    for k in (1, 2):                   # two increments, the state committed in between
        if cls.axisymmetric:
            u = np.broadcast_to([0.0, 2.5 * k], coords.shape).copy()
            how = "NLGEOM translation along the axis by 5 (rotations are not rigid in axisymmetry)"
        else:
            a = 0.5 * k
            R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            u = (coords - centre) @ R.T + centre + np.array([0.3, -0.2]) * k - coords
            how = "NLGEOM rotation by 1 rad in two increments"
        r = _compute(g, u, u_old, state, large)
        state, u_old = r.state, u
    measures += [(f"{how}: max |stress| / stress(unit strain)",
                  np.abs(state["stress"]).max() / sig_ref, 1e-10),
                 ("max |f| / f(unit strain)", np.abs(r.f).max() / f_ref, 1e-10)]
    return all_within(measures)


def _one_element(cls, seed: int) -> np.ndarray:
    """A distorted element of unit size (r > 0 in axisymmetry)."""
    c, size = _reference_frame(cls)
    x = (np.asarray(cls.node_xi, float) - c) / size @ np.array([[1.1, 0.2], [-0.1, 0.9]]).T
    x = x + (np.array([2.0, 1.0]) if cls.axisymmetric else 0.0)
    rng = np.random.default_rng(seed)
    for scale in (0.04, 0.02, 0.0):
        coords = x + scale * rng.normal(size=x.shape)
        if not cls.invalid(coords[None])[0][0]:
            return coords
    return x


def _fd_error(g, u, u_old, state, ctx) -> float:
    """max |K - dF/du (central differences)| / max |K_fd| of a one-element group."""
    res = _compute(g, u, u_old, state, ctx)
    h = 1e-7
    nd = g.dofs.shape[1]
    Kfd = np.zeros((nd, nd))
    for col in range(nd):
        du = np.zeros(u.size)
        du[g.dofs[0, col]] = h
        fp = _compute(g, u + du.reshape(u.shape), u_old, state, ctx, False).f[0]
        fm = _compute(g, u - du.reshape(u.shape), u_old, state, ctx, False).f[0]
        Kfd[:, col] = (fp - fm) / (2 * h)
    return float(np.abs(res.K[0] - Kfd).max() / np.abs(Kfd).max())


def _tangent(cls, nlgeom: bool) -> str:
    from ..elements.base import StepContext
    ctx = StepContext(nlgeom=nlgeom)
    measures = []
    for label, law in (("elastic", _elastic_law()), ("elasto-plastic J2", _plastic_law())):
        coords = _one_element(cls, 5 if nlgeom else 4)
        g = cls(np.array([7]), np.arange(cls.nen)[None], coords, law, 1.0)
        rng = np.random.default_rng(6)
        centred = coords - coords.mean(axis=0)
        if nlgeom:
            grad = np.array([[0.08, 0.05], [-0.03, -0.1]])           # finite strains
            u_old = coords @ grad.T + 0.01 * rng.normal(size=coords.shape)
            x_new = coords + u_old
            if not cls.axisymmetric:                                   # and a rotation
                a = 0.4
                x_new = x_new @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
            u = x_new - coords + 0.05 * centred @ np.array([[1.0, 0.5], [0.2, -0.7]]).T
        else:
            grad = np.array([[4e-3, 1e-3], [-2e-3, -5e-3]])           # past yield (1.5e-3)
            u_old = coords @ grad.T + 2e-4 * rng.normal(size=coords.shape)
            u = u_old + coords @ (0.3 * grad).T + 2e-4 * rng.normal(size=coords.shape)
        state = _compute(g, u_old, 0 * u_old, g.init_state(), ctx, False).state
        err = _fd_error(g, u, u_old, state, ctx)
        note = ""
        if label != "elastic":
            peeq = _compute(g, u, u_old, state, ctx, False).state["peeq"]
            note = f" ({int((peeq > state['peeq']).sum())} of {peeq.size} Gauss points yielding)"
        measures.append((f"{label}{note}: max |K - K_fd| / max |K_fd|", err, 1e-6))
    return all_within(measures)


def _tangent_later(cls) -> str:
    """An element declaring ``defers_tangent``: ``compute(..., tangent=LATER)`` gives the forces
    and state of ``tangent=True`` and a ``later()`` returning its ``K``, bit for bit (a subclass
    that changes ``K`` after ``compute`` must do it in ``later`` too, or not defer)."""
    from ..elements.base import LATER, StepContext
    if not cls.defers_tangent:
        raise Skip("the element does not defer its tangent (defers_tangent = False)")
    coords = _one_element(cls, 5)
    done = []
    for nlgeom in (False, True):
        ctx = StepContext(nlgeom=nlgeom)
        g = cls(np.array([7]), np.arange(cls.nen)[None], coords, _plastic_law(), 1.0)
        centred = coords - coords.mean(axis=0)
        u = centred @ np.array([[4e-3, 1e-3], [-2e-3, -5e-3]]).T
        now = _compute(g, u, 0 * u, g.init_state(), ctx, True)
        later = _compute(g, u, 0 * u, g.init_state(), ctx, LATER)
        if later.K is None and later.later is None:
            raise ContractFailure("compute(tangent=LATER) returned neither K nor later")
        K = later.K if later.K is not None else later.later()
        same = (np.array_equal(now.f, later.f) and np.array_equal(now.K, K)
                and now.state.keys() == later.state.keys()
                and all(np.array_equal(now.state[k], later.state[k]) for k in now.state))
        kind = "NLGEOM" if nlgeom else "small strain"
        if not same:
            raise ContractFailure(f"{kind}: compute(tangent=LATER) differs from tangent=True "
                                  f"(max |K diff| {float(np.abs(now.K - K).max()):.3g})")
        done.append(kind)
    return f"f, state and K of tangent=LATER equal to tangent=True, bit for bit ({', '.join(done)})"


def check_element(cls) -> list[Finding]:
    """The element contract (:class:`~lagamine_py.elements.base.Element`) on class ``cls``."""
    s = Suite(ELEMENT_ITEMS)
    for name, fn in zip(ELEMENT_ITEMS, (_shape_functions, _shape_derivatives, _gauss_rule,
                                        _faces, _outline, _jacobian, _recovery, _vtk_cell,
                                        _patch_test, _rigid_motion)):
        s.run(name, fn, cls)
    s.run("tangent (small strain)", _tangent, cls, False)
    s.run("tangent (NLGEOM)", _tangent, cls, True)
    s.run("tangent later", _tangent_later, cls)
    return s.findings
