"""Faces and pressure loads (lagamine_py.elements.edges).

Closed forms: the total force of a uniform pressure p on a face from A to B is, per unit
thickness, p (-(yB - yA), xB - xA) whatever the face's curvature (int t dxi = B - A); per radian
in axisymmetry it is p int r (-dz, dr), e.g. for the face z = c r^2 from r = a to b:
F_r = -2 p c (b^3 - a^3) / 3, F_z = p (b^2 - a^2) / 2.  The follower tangent is checked
against central finite differences.
"""
import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.elements.edges import PressureGroup, face_nodes, surface_faces
from lagamine_py.elements.quad import Q4PlaneStrain, Q8PlaneStrain
from lagamine_py.model import ElementBlock, Model, Surface


def total_force(group, u, nlgeom):
    res = group.compute(u, u, {}, StepContext(nlgeom=nlgeom))
    nf, nd = res.f.shape
    return -res.f.reshape(nf, nd // 2, 2).sum(axis=(0, 1)), res   # external = -f


@pytest.mark.parametrize("nlgeom", [False, True])
@pytest.mark.parametrize("curved", [False, True])
def test_plane_pressure_total_force_is_p_times_projected_length(nlgeom, curved):
    A, B = np.array([0.3, 0.2]), np.array([2.3, 1.7])
    mid = 0.5 * (A + B) + (np.array([-0.4, 0.5]) if curved else 0.0)
    coords = np.array([A, B, mid])
    g = PressureGroup([[0, 1, 2]], coords, axisymmetric=False, thickness=2.5)
    g.pressure = np.array([7.0])
    F, _ = total_force(g, np.zeros_like(coords), nlgeom)
    d = B - A
    assert np.allclose(F, 7.0 * 2.5 * np.array([-d[1], d[0]]), rtol=1e-13, atol=0)


def test_pressure_pushes_into_the_body():
    # bottom face S1 of a Q4 unit square: the body is above, pressure pushes +y
    coords = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    fn = face_nodes(Q4PlaneStrain, np.array([[0, 1, 2, 3]]), np.array([1]), np.array([0]))
    assert fn.tolist() == [[0, 1]]
    g = PressureGroup(fn, coords, axisymmetric=False)
    g.pressure = 3.0
    F, _ = total_force(g, np.zeros_like(coords), False)
    assert np.allclose(F, [0.0, 3.0], rtol=0, atol=1e-14)


@pytest.mark.parametrize("nfn", [2, 3])
def test_axisymmetric_pressure_on_straight_faces(nfn):
    a, b, h, p = 2.0, 5.0, 3.0, 4.0
    # bore face at r = a, running downward (body at r > a): F_r = p a h per radian
    bore = np.array([[a, h], [a, 0.0], [a, 0.5 * h]])[:nfn]
    # top face z = h running from r = b to r = a (body below); mid node off-centre on the line
    top = np.array([[b, h], [a, h], [0.5 * (a + b) + 0.7, h]])[:nfn]
    for coords, expected in ((bore, [p * a * h, 0.0]), (top, [0.0, -p * (b**2 - a**2) / 2])):
        g = PressureGroup([list(range(nfn))], coords, axisymmetric=True)
        g.pressure = p
        F, _ = total_force(g, np.zeros_like(coords), False)
        assert np.allclose(F, expected, rtol=1e-13, atol=1e-12)


def test_axisymmetric_pressure_on_a_parabolic_face():
    a, b, c, p = 1.0, 3.0, 0.2, 5.0
    rm = 0.5 * (a + b)
    # face from r = a to r = b on z = c r^2: the body lies on its left, i.e. above the curve
    coords = np.array([[a, c * a**2], [b, c * b**2], [rm, c * rm**2]])
    g = PressureGroup([[0, 1, 2]], coords, axisymmetric=True)
    g.pressure = p
    F, _ = total_force(g, np.zeros_like(coords), False)
    assert np.allclose(F, [-2 * p * c * (b**3 - a**3) / 3, p * (b**2 - a**2) / 2], rtol=1e-13)


@pytest.mark.parametrize("axisymmetric", [False, True])
@pytest.mark.parametrize("nfn", [2, 3])
def test_follower_tangent_matches_finite_differences(axisymmetric, nfn):
    rng = np.random.default_rng(3 + nfn)
    coords = np.array([[1.0, 0.0], [2.0, 1.0], [1.4, 0.7], [3.0, 0.5], [2.6, 0.9]])
    fn = [[0, 1, 2], [1, 3, 4]] if nfn == 3 else [[0, 1], [1, 3]]
    g = PressureGroup(fn, coords, axisymmetric=axisymmetric, thickness=1.3)
    g.pressure = np.array([2.0, -1.5])
    u = 0.1 * rng.normal(size=coords.shape)
    ctx = StepContext(nlgeom=True)
    res = g.compute(u, u, {}, ctx)
    h = 1e-6
    for k, nodes in enumerate(g.face_nodes):
        Kfd = np.zeros((2 * nfn, 2 * nfn))
        for col in range(2 * nfn):
            du = np.zeros_like(u)
            du[nodes[col // 2], col % 2] = h
            fp = g.compute(u + du, u, {}, ctx, tangent=False).f[k]
            fm = g.compute(u - du, u, {}, ctx, tangent=False).f[k]
            Kfd[:, col] = (fp - fm) / (2 * h)
        assert np.abs(res.K[k] - Kfd).max() < 1e-7 * np.abs(Kfd).max()
        assert np.abs(res.K[k] - res.K[k].T).max() > 1e-3 * np.abs(Kfd).max()  # not symmetric
    # small strain: reference face, no tangent
    res0 = g.compute(u, u, {}, StepContext(nlgeom=False))
    assert not res0.K.any()
    assert np.allclose(res0.f, g.compute(0 * u, 0 * u, {}, ctx).f)


def test_surface_faces_from_a_model():
    # two Q8 elements side by side, surface = top faces (S3) of both
    coords = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1],
                       [.5, 0], [1.5, 0], [1, .5], [2, .5], [.5, 1], [1.5, 1], [0, .5]], float)
    conn = np.array([[0, 1, 4, 3, 6, 8, 10, 12], [1, 2, 5, 4, 7, 9, 11, 8]])
    model = Model(name="m", node_ids=np.arange(1, 14), coords=coords,
                  blocks=[ElementBlock("Q8PE", np.array([10, 20]), conn, "STEEL")],
                  surfaces={"TOP": Surface("TOP", np.array([20, 10]), np.array([3, 3]))})
    rows, eids, faces = surface_faces(model, "top")
    assert rows.tolist() == [[5, 4, 11], [4, 3, 10]]
    assert eids.tolist() == [20, 10] and faces.tolist() == [3, 3]
    assert face_nodes(Q8PlaneStrain, conn, [4], [0]).tolist() == [[3, 0, 12]]
    g = PressureGroup(rows, coords, axisymmetric=False)
    g.pressure = 1.0
    F, _ = total_force(g, np.zeros_like(coords), False)
    assert np.allclose(F, [0.0, -2.0])        # pressing down on the top, length 2
