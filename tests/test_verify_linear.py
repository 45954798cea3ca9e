"""Linear-elastic verification against closed forms, through the whole program (deck -> run -> files).

* Lamé thick cylinder under internal pressure, axisymmetric with plane-strain ends (u_z = 0):
  u_r = r/E [(1+nu)(1-2nu) A + (1+nu) B / r^2], s_r = A - B/r^2, s_t = A + B/r^2,
  A = p a^2 / (b^2 - a^2), B = p a^2 b^2 / (b^2 - a^2)  (Timoshenko & Goodier, §28).
* The same ring as a plane-strain quarter annulus with symmetry conditions.
* A cantilever under a parabolic end shear (Timoshenko & Goodier §21), plane strain
  (E -> E/(1-nu^2), nu -> nu/(1-nu)); the exact displacements are imposed on the clamped end,
  the exact traction is applied on the loaded end as consistent nodal loads; the error must
  fall at the rate of the element (h^3 for Q8, h^2 for Q4 in the nodal displacement).
* Rigid-body motion gives no stress.
"""
import numpy as np
import pytest

from lagamine_py.cli import main
from lagamine_py.elements.shapes import gauss_1d, line_shape
from lagamine_py.results import RunResults

from meshgen import deck_lines, nset_lines, structured

E, NU = 200e3, 0.3


def run(tmp_path, text, name="deck"):
    deck = tmp_path / f"{name}.dat"
    deck.write_text(text)
    out = tmp_path / f"{name}_out"
    status = main(["run", str(deck), "-o", str(out), "-q"])
    assert status == 0
    return RunResults(out)


def lame(r, a, b, p, E=E, nu=NU):
    A = p * a**2 / (b**2 - a**2)
    B = p * a**2 * b**2 / (b**2 - a**2)
    ur = r / E * ((1 + nu) * (1 - 2 * nu) * A + (1 + nu) * B / r**2)
    return ur, A - B / r**2, A + B / r**2


STEP = """*STEP, NAME=LOAD
*STATIC
1, 1, 1e-3, 1
{body}*END STEP
"""


@pytest.mark.parametrize("etype", ["Q8AX", "Q4AX"])
def test_lame_axisymmetric(tmp_path, etype):
    a, b, p = 10.0, 20.0, 100.0
    nx = 8 if etype == "Q8AX" else 32
    text = (f"*MESH, NAME=TUBE, TYPE={etype}, X0={a}, Y0=0, LX={b - a}, LY=1, NX={nx}, NY=1\n"
            f"*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE={E}, NU={NU}\n"
            "*SOLID, ELSET=TUBE, MATERIAL=STEEL\n"
            + STEP.format(body=f"*BOUNDARY\nTUBE_BOTTOM, 2, 2\nTUBE_TOP, 2, 2\n*DLOAD\nTUBE_LEFT, P, {p}\n"))
    res = run(tmp_path, text)
    body = res.body()
    r = body["points"][:, 0]
    ur_exact, sr, st = lame(r, a, b, p)
    ur = body["point:displacement"][:, 0]
    assert np.abs(ur - ur_exact).max() / np.abs(ur_exact).max() < 5e-3
    assert np.abs(body["point:displacement"][:, 1]).max() < 1e-12
    # stresses at the mid-wall nodes, away from the extrapolated ends
    S = body["point:stress"]
    mid = np.abs(r - 0.5 * (a + b)) < 1e-9
    assert np.allclose(S[mid, 0], sr[mid], rtol=5e-3, atol=5e-3 * p)
    assert np.allclose(S[mid, 2], st[mid], rtol=5e-3)
    # the inner pressure is balanced by nothing else: axial reactions carry nu (s_r + s_t) only
    rf = res.table("reactions.csv")
    assert set(rf["nset"]) == {"TUBE_BOTTOM", "TUBE_TOP"}


def test_lame_plane_strain_quarter_ring(tmp_path):
    a, b, p = 10.0, 20.0, 100.0
    nr, nt = 6, 8

    def ring(s, t):
        r, th = a + (b - a) * s, 0.5 * np.pi * t
        return r * np.cos(th), r * np.sin(th)

    ids, coords, elements = structured(nr, nt, ring)
    text = (deck_lines(coords, elements, "Q8PE")
            + nset_lines("XSYM", ids[:, -1]) + nset_lines("YSYM", ids[:, 0])
            + "*SURFACE, NAME=INNER\nBODY, S4\n"
            + f"*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE={E}, NU={NU}\n*SOLID, ELSET=BODY, MATERIAL=STEEL\n"
            + STEP.format(body=f"*BOUNDARY\nXSYM, 1, 1\nYSYM, 2, 2\n*DLOAD\nINNER, P, {p}\n"))
    # S4 on every element is only correct for the inner column; list them explicitly
    inner = [k + 1 for k in range(len(elements)) if k % nr == 0]
    text = text.replace("*SURFACE, NAME=INNER\nBODY, S4\n",
                        "*SURFACE, NAME=INNER\n" + "".join(f"{e}, S4\n" for e in inner))
    res = run(tmp_path, text)
    body = res.body()
    x, y = body["points"][:, 0], body["points"][:, 1]
    r = np.hypot(x, y)
    ur_exact, _, _ = lame(r, a, b, p)
    u = body["point:displacement"][:, :2]
    ur = (u[:, 0] * x + u[:, 1] * y) / r
    ut = (-u[:, 0] * y + u[:, 1] * x) / r
    assert np.abs(ur - ur_exact).max() / np.abs(ur_exact).max() < 5e-3
    assert np.abs(ut).max() < 1e-3 * np.abs(ur_exact).max()


def cantilever_exact(x, y, L, c, P, E, nu):
    """Timoshenko & Goodier cantilever: loaded by P (total shear) at x = 0, clamped at x = L."""
    Es, nus = E / (1 - nu**2), nu / (1 - nu)       # plane strain
    G = Es / (2 * (1 + nus))
    I = 2 * c**3 / 3
    u = (-P * x**2 * y / (2 * Es * I) - nus * P * y**3 / (6 * Es * I) + P * y**3 / (6 * G * I)
         + (P * L**2 / (2 * Es * I) - P * c**2 / (2 * G * I)) * y)
    v = (nus * P * x * y**2 / (2 * Es * I) + P * x**3 / (6 * Es * I) - P * L**2 * x / (2 * Es * I)
         + P * L**3 / (3 * Es * I))
    txy = -P / (2 * I) * (c**2 - y**2)
    return u, v, txy


def cantilever_error(tmp_path, etype, nx, ny, L=10.0, c=1.0, P=1.0):
    quad = etype.startswith("Q8")
    ids, coords, elements = structured(nx, ny, lambda s, t: (L * s, -c + 2 * c * t), quadratic=quad)
    xy = np.array([coords[n] for n in coords])
    nid = np.array(list(coords))
    ue, ve, _ = cantilever_exact(xy[:, 0], xy[:, 1], L, c, P, E, NU)
    # clamped end x = L: exact displacements
    bc = "*BOUNDARY\n" + "".join(
        f"{n}, 1, 1, {ue[k]:.17g}\n{n}, 2, 2, {ve[k]:.17g}\n"
        for k, n in enumerate(nid) if abs(xy[k, 0] - L) < 1e-12)
    # loaded end x = 0, outward normal -x: traction t_y = -txy; consistent nodal loads
    edge = [int(n) for n in ids[0, :] if n > 0]
    loads = np.zeros(len(edge))
    nfn = 3 if quad else 2
    xg, wg = gauss_1d(4)
    N, _ = line_shape(nfn, xg)
    step = nfn - 1
    for s in range(0, len(edge) - 1, step):
        seg = [s, s + step] + ([s + 1] if quad else [])
        ys = np.array([coords[edge[k]][1] for k in seg])
        yq = N @ ys
        jac = (ys[1] - ys[0]) / 2
        _, _, txy = cantilever_exact(0.0, yq, L, c, P, E, NU)
        loads[seg] += N.T @ (-txy * wg) * jac
    cl = "*CLOAD\n" + "".join(f"{n}, 2, {f:.17g}\n" for n, f in zip(edge, loads))
    text = (deck_lines(coords, elements, etype)
            + f"*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE={E}, NU={NU}\n*SOLID, ELSET=BODY, MATERIAL=STEEL\n"
            + STEP.format(body=bc + cl))
    res = run(tmp_path, text, name=f"cant_{etype}_{nx}")
    body = res.body()
    pts = body["points"][:, :2]
    u = body["point:displacement"][:, :2]
    ue, ve, _ = cantilever_exact(pts[:, 0], pts[:, 1], L, c, P, E, NU)
    return np.abs(np.hypot(u[:, 0] - ue, u[:, 1] - ve)).max() / np.abs(ve).max()


@pytest.mark.parametrize("etype, order", [("Q8PE", 3.0), ("Q4PE", 2.0)])
def test_cantilever_converges_at_the_element_rate(tmp_path, etype, order):
    meshes = [(5, 1), (10, 2), (20, 4)] if etype == "Q8PE" else [(10, 2), (20, 4), (40, 8)]
    errs = [cantilever_error(tmp_path, etype, nx, ny) for nx, ny in meshes]
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(etype, "errors", errs, "observed orders", rates)
    assert errs[-1] < 1e-2
    assert rates[-1] > order - 0.35


@pytest.mark.parametrize("etype", ["Q8PE", "Q4PE", "Q8AX", "Q4AX"])
def test_rigid_translation_gives_no_stress(tmp_path, etype):
    text = (f"*MESH, NAME=B, TYPE={etype}, X0=1, Y0=0, LX=2, LY=1, NX=3, NY=2\n"
            f"*MATERIAL, NAME=M, LAW=ELASTIC\nE={E}, NU={NU}\n*SOLID, ELSET=B, MATERIAL=M\n"
            + STEP.format(body="*BOUNDARY\nB_BOTTOM, 1, 1, 0\nB_BOTTOM, 2, 2, 0.25\nB_TOP, 2, 2, 0.25\n"
                          + ("" if "AX" in etype else "B_LEFT, 1, 1, 0.0\n")))
    body = run(tmp_path, text).body()
    u = body["point:displacement"]
    assert np.allclose(u[:, 1], 0.25, rtol=0, atol=1e-12)
    assert np.abs(body["point:stress"]).max() < 1e-9 * E
