"""The rigid foundation: closed-form projections, robustness cases, exact derivatives (FD)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from pathlib import Path

from lagamine_py.deck import DeckError, load_deck
from lagamine_py.foundation import Foundation


def _unit(v):
    v = np.atleast_2d(np.asarray(v, float))
    return v / np.linalg.norm(v, axis=1)[:, None]


# y = x**2 on [-1, 1] is exactly one parabolic arc; travel +x, body on the left = above.
PARABOLA = Foundation([[-1.0, 1.0], [0.0, 0.0], [1.0, 1.0]], name="para")
# A kinked chain of curved arcs, travel +x, body above.
WAVY = Foundation([[-2.0, 0.0], [-1.0, 0.3], [0.0, 0.1], [1.0, -0.2], [2.0, 0.05], [3.0, 0.1], [4.0, -0.1]])


def test_invalid_points_rejected():
    with pytest.raises(ValueError, match="odd"):
        Foundation([[0, 0], [1, 0], [2, 0], [3, 0]])
    with pytest.raises(ValueError, match=r"\(m, 2\)"):
        Foundation([0, 1, 2])


@pytest.mark.parametrize("angle", (-0.6, -0.2, 0.0, 0.3, 0.7))
@pytest.mark.parametrize("P", ([0.3, 0.05], [-0.5, 0.4], [0.1, 0.2], [0.6, 0.1]))
def test_parabola_closed_form(P, angle):
    """Line P + t e against y = x^2: ex^2 t^2 + (2 Px ex - ey) t + Px^2 - Py = 0, d = -t."""
    P = np.array(P, float)
    e = np.array([np.sin(angle), -np.cos(angle)])             # roughly downwards (outward of a body above)
    roots = np.roots([e[0] ** 2, 2 * P[0] * e[0] - e[1], P[0] ** 2 - P[1]])
    roots = roots[np.isreal(roots)].real
    roots = [t for t in roots if abs(P[0] + t * e[0]) <= 1]
    pr = PARABOLA.project(P[None], e[None])
    if not roots:           # this line misses the arc and its end half-lines (checked by hand)
        assert not pr.found[0]
        return
    t = min(roots, key=abs)
    assert pr.found[0]
    assert pr.d[0] == pytest.approx(-t, abs=1e-13)
    assert np.allclose(pr.Q[0], P + t * e, atol=1e-13)
    assert pr.s[0] == pytest.approx(pr.Q[0, 0], abs=1e-13)      # s = x on this arc
    # normal into the body (left of travel): (-2x, 1)/norm
    x = pr.Q[0, 0]
    assert np.allclose(pr.normal[0], _unit([-2 * x, 1.0])[0], atol=1e-13)
    # sign: P below the curve (outside the body) is a penetration
    assert np.sign(pr.d[0]) == np.sign(P[0] ** 2 - P[1] + 0.0) or abs(P[0] ** 2 - P[1]) < 1e-12


def test_translation_moves_everything():
    c = np.array([0.4, -0.25])
    P = np.array([[0.3, 0.05], [-0.2, 0.5]])
    e = _unit([[0.1, -1.0], [-0.2, -1.0]])
    a = PARABOLA.project(P, e, c)
    b = PARABOLA.project(P - c, e)
    assert np.allclose(a.d, b.d, atol=1e-14)
    assert np.allclose(a.Q, b.Q + c, atol=1e-14)
    assert np.allclose(PARABOLA.points_at(c), PARABOLA.points + c)
    assert np.allclose(PARABOLA.points_at(None), PARABOLA.points)


def _brute_force(found, P, e, c):
    """Nearest valid intersection by bracketing w.(F(s) - P) on a dense s grid (scipy brentq),
    over every arc and the end half-lines."""
    w = np.array([-e[1], e[0]])
    best = None
    pieces = [(j, -1.0, 1.0) for j in range(found.n_arcs)] + [(0, -60.0, -1.0), (found.n_arcs - 1, 1.0, 60.0)]
    for j, lo, hi in pieces:
        def h(s, j=j):
            s = np.atleast_1d(s)
            X, _ = found.evaluate(np.full(s.shape, j), s, c)
            return (X - P) @ w
        grid = np.linspace(lo, hi, 4001)
        vals = h(grid)
        for k in np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) <= 0)[0]:
            s = grid[k] if vals[k] == 0 else brentq(lambda z: h(z)[0], grid[k], grid[k + 1], xtol=1e-15)
            X, dX = found.evaluate(np.array([j]), np.array([s]), c)
            n = np.array([-dX[0, 1], dX[0, 0]])
            if e @ n >= 0:
                continue
            d = e @ (P - X[0])
            if best is None or abs(d) < abs(best):
                best = d
    return best


def test_several_candidates_nearest_valid_wins():
    """Shallow lines cross the wavy chain several times: the nearest facing crossing wins."""
    rng = np.random.default_rng(3)
    c = np.array([0.05, 0.02])
    n_checked = 0
    for _ in range(40):
        P = np.array([rng.uniform(-1.5, 3.5), rng.uniform(-0.3, 0.4)])
        ang = rng.uniform(-1.45, 1.45)                       # includes nearly horizontal lines
        e = np.array([np.sin(ang), -np.cos(ang)])
        want = _brute_force(WAVY, P, e, c)
        pr = WAVY.project(P[None], e[None], c)
        if want is None:
            assert not pr.found[0]
        else:
            assert pr.found[0]
            assert pr.d[0] == pytest.approx(want, abs=1e-10)
            n_checked += 1
    assert n_checked > 30


def test_back_facing_intersection_is_rejected():
    """A U-shaped channel (body inside): a horizontal line crosses both walls; only the wall
    facing e_u is valid.  Reversing e_u picks the other wall."""
    U = Foundation([[-2, 2], [-2, 1], [-2, 0], [0, 0], [2, 0], [2, 1], [2, 2]])
    P = np.array([[0.5, 1.0]])
    pr = U.project(P, np.array([[1.0, 0.0]]))
    assert pr.found[0] and pr.d[0] == pytest.approx(-1.5) and pr.arc[0] == 2
    pr = U.project(P, np.array([[-1.0, 0.0]]))
    assert pr.found[0] and pr.d[0] == pytest.approx(-2.5) and pr.arc[0] == 0
    # a body face looking away from a flat foundation (e_u up) is not in contact
    flat = Foundation([[-1, 0], [0, 0], [1, 0]])
    assert not flat.project(np.array([[0.2, 0.3]]), np.array([[0.0, 1.0]])).found[0]


@pytest.mark.parametrize("kernel", [False, True])
def test_a_ray_grazing_the_foundation_is_a_miss(kernel):
    """A body's flank parallel to a flat tool (the ring's beside its platen): its normal is off
    grazing by the round-off of the converged displacement, ~1e-10..1e-9 rad, and would hit the
    tool's extended end 0.3 / 1e-9 = 3e8 away, a gap made of round-off that another CPU's BLAS
    turns into a miss.  Rays closer to grazing than GRAZING_COS (1e-6) are misses, on the NumPy
    path and the numba kernel alike; a shallow ray beyond it (1e-4 rad) is a hit at the distance
    of the closed form 0.3 / sin(angle)."""
    from lagamine_py.foundation import GRAZING_COS
    flat = Foundation([[-1, 0], [0, 0], [1, 0]])
    if kernel:
        pytest.importorskip("numba")
        flat.use_kernels(True)
    P = np.array([[0.2, 0.3], [0.2, 0.3], [0.2, 0.3], [0.2, 0.3]])
    angles = np.array([1e-9, 0.5 * GRAZING_COS, 2.0 * GRAZING_COS, 1e-4])
    e_u = np.column_stack([np.cos(angles), -np.sin(angles)])
    pr = flat.project(P, e_u)
    assert pr.found.tolist() == [False, False, True, True]
    np.testing.assert_allclose(pr.d[2:], -0.3 / np.sin(angles[2:]), rtol=1e-9)


def test_joint_ray_continuous_d():
    """Through a kinked joint (x = 0 on WAVY) d is continuous and either arc is accepted."""
    joint = WAVY.points[2]
    e = _unit([0.15, -1.0])[0]
    P0 = joint + 0.03 * e                                   # P past the joint along e: d = 0.03
    pr = WAVY.project(P0[None], e[None])
    assert pr.found[0] and pr.d[0] == pytest.approx(0.03, abs=1e-13)
    assert pr.arc[0] in (0, 1)
    assert np.allclose(pr.Q[0], joint, atol=1e-13)
    eps = np.array([1e-9, -1e-9, 1e-7, -1e-7])
    Ps = P0 + eps[:, None] * np.array([1.0, 0.0])
    d = WAVY.project(Ps, np.tile(e, (4, 1))).d
    assert np.all(np.abs(d - 0.03) < 2 * np.abs(eps))      # Lipschitz: |dd/dP| < 2 here
    assert set(WAVY.project(Ps, np.tile(e, (4, 1))).arc) == {0, 1}


def test_beyond_the_ends_continued_by_end_tangents():
    """Past the last point the chain goes on along its end tangent: closed form of a line, d
    and its derivative continuous across the end."""
    last = WAVY.n_arcs - 1
    end, dend = WAVY.evaluate(np.array([last]), np.array([1.0]))
    end, dend = end[0], dend[0]
    e = np.array([0.0, -1.0])
    for x in (4.5, 7.0):
        y_line = end[1] + (x - end[0]) * dend[1] / dend[0]
        P = np.array([[x, y_line - 0.02]])
        pr = WAVY.project(P, e[None])
        assert pr.found[0] and pr.d[0] == pytest.approx(0.02, abs=1e-12)
        assert pr.arc[0] == last and pr.s[0] > 1
    # start side
    st, dst = WAVY.evaluate(np.array([0]), np.array([-1.0]))
    x = -3.0
    y_line = st[0, 1] + (x - st[0, 0]) * dst[0, 1] / dst[0, 0]
    pr = WAVY.project(np.array([[x, y_line + 0.01]]), e[None])
    assert pr.found[0] and pr.d[0] == pytest.approx(-0.01, abs=1e-12) and pr.s[0] < -1
    # continuity of d and dd/dP across the end point
    P = np.array([[end[0] - 1e-7, end[1] - 0.01], [end[0] + 1e-7, end[1] - 0.01]])
    pr = WAVY.project(P, np.tile(e, (2, 1)))
    assert abs(pr.d[0] - pr.d[1]) < 1e-7
    assert np.allclose(pr.dd_dP[0], pr.dd_dP[1], atol=1e-6)


def test_nearly_tangent_and_missing_lines():
    flat = Foundation([[-1, 0], [0, 0], [1, 0]])               # degenerate (straight) arc
    ang = 1.5                                                    # 86 degrees from the normal
    e = np.array([np.sin(ang), -np.cos(ang)])
    P = np.array([[-0.8, 0.05]])
    pr = flat.project(P, e[None])
    assert pr.found[0]
    assert pr.d[0] == pytest.approx(-0.05 / np.cos(ang), rel=1e-12)
    # parallel to a straight arc: no intersection
    assert not flat.project(P, np.array([[1.0, 0.0]])).found[0]
    # a line missing the curved arc (negative discriminant) -> not found, d = -inf
    pr = PARABOLA.project(np.array([[0.0, -0.5]]), np.array([[1.0, 0.0]]))
    assert not pr.found[0] and pr.d[0] == -np.inf and np.all(pr.dd_dP == 0)
    # a line grazing the vertex of the parabola: double root, tangent -> not valid
    pr = PARABOLA.project(np.array([[0.3, 0.0]]), np.array([[1.0, 0.0]]))
    assert not pr.found[0]


@pytest.mark.parametrize("seed", range(5))
def test_derivatives_match_finite_differences(seed):
    """dd/dP, dd/de_u (implicit function theorem) and dd/dc = -dd/dP against central FD."""
    rng = np.random.default_rng(seed)
    g = 6
    P = np.stack([rng.uniform(-1.5, 3.5, g), rng.uniform(-0.2, 0.3, g)], axis=1)
    ang = rng.uniform(-0.5, 0.5, g)
    e = np.stack([np.sin(ang), -np.cos(ang)], axis=1)
    c = np.array([0.1, -0.05])
    pr = WAVY.project(P, e, c)
    assert pr.found.all()
    h = 1e-7
    for i in range(2):
        dP = np.zeros(2)
        dP[i] = h
        fd = (WAVY.project(P + dP, e, c).d - WAVY.project(P - dP, e, c).d) / (2 * h)
        assert np.allclose(pr.dd_dP[:, i], fd, atol=1e-7)
        fd = (WAVY.project(P, e + dP, c).d - WAVY.project(P, e - dP, c).d) / (2 * h)
        assert np.allclose(pr.dd_de[:, i], fd, atol=1e-7)
        fd = (WAVY.project(P, e, c + dP).d - WAVY.project(P, e, c - dP).d) / (2 * h)
        assert np.allclose(-pr.dd_dP[:, i], fd, atol=1e-7)


# ---------------------------------------------------------------- validation of the chain

@pytest.mark.parametrize("points, fragment", [
    ([[-20, 0], [10, 0], [-1, 0]], "folds back on itself"),           # the typo of issue 14
    ([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], "the chain is closed"),
    ([[0, 0], [1, 0], [2, 0], [1, 1e-3], [0, 2e-3]], "doubles back at point 3"),
    ([[0, 0], [2, 0], [4, 0], [4, 1], [3, 2], [2, 1], [2, -1]], "crosses itself"),
    ([[0, 0], [1, 0], [2, 0], [3, 1], [0, 0]], "coincide"),
])
def test_bad_chains_are_named(points, fragment):
    problems = Foundation(points).shape_problems()
    assert problems and fragment in problems[0], problems


@pytest.mark.parametrize("points", [
    [[-20, 0], [10, 0], [40, 0]],
    [[np.cos(a), np.sin(a)] for a in np.linspace(0.0, 1.5 * np.pi, 9)],     # 3/4 of a circle
    [[-2, 0.0], [-1, 0.3], [0, 0.1], [1, -0.2], [2, 0.05], [3, 0.1], [4, -0.1]],
])
def test_good_chains_pass(points):
    assert Foundation(points).shape_problems() == []


def test_side_of_bodies():
    """+1 for a body on the left of the direction of travel, -1 on its right; a touching point
    is judged by its outward normal; beyond an end it cannot tell (0)."""
    flat = Foundation([[-20, 0], [10, 0], [40, 0]])
    P = [[0, 1], [5, 0], [50, 1], [0, -1]]
    n = [[0, -1], [0, -1], [0, -1], [0, 1]]
    assert flat.side(P, n).tolist() == [1, 1, 0, -1]
    reverse = Foundation(flat.points[::-1])
    assert reverse.side(P, n).tolist() == [-1, -1, 0, 1]
    top = Foundation([[np.cos(a), np.sin(a)] for a in np.linspace(np.pi, 0.0, 9)])   # clockwise
    assert top.side([[0, 0.5], [0, 1.0]], [[0, 1], [0, 1]]).tolist() == [-1, -1]
    arc, s, X, _ = top.closest(np.array([[0.0, 2.0]]))
    assert np.allclose(X, [[0.0, 1.0]], atol=1e-3)                # the top of the circle


def test_deck_with_a_folded_or_reversed_foundation_is_refused(tmp_path):
    """The typo of coulomb_block.dat (last point 40, 0 -> -1, 0) and the same chain written
    right to left: exit 2 at check, naming the foundation and what to do."""
    from lagamine_py.cli import main
    deck = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"
    text = deck.read_text()
    assert "-20, 0\n10, 0\n40, 0\n" in text
    (tmp_path / "meshes").symlink_to(deck.parent / "meshes")
    typo = tmp_path / "typo.dat"
    typo.write_text(text.replace("-20, 0\n10, 0\n40, 0\n", "-20, 0\n10, 0\n-1, 0\n"))
    reverse = tmp_path / "reverse.dat"
    reverse.write_text(text.replace("-20, 0\n10, 0\n40, 0\n", "40, 0\n10, 0\n-20, 0\n"))
    assert main(["check", str(typo)]) == 2
    assert main(["check", str(reverse)]) == 2
    with pytest.raises(DeckError, match="folds back on itself"):
        load_deck(typo)
    with pytest.raises(DeckError, match="reverse the point order"):
        load_deck(reverse)
