"""Write the mesh files (*NODE / *ELEMENT / *NSET / *SURFACE) that the decks in decks/ include.

Meshes that a structured ``*MESH`` rectangle cannot make (a graded half-cylinder for the Hertz and
Cattaneo–Mindlin scenes) are generated here, once, and committed; rerun after changing a size:

    python tools/make_meshes.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

DECKS = Path(__file__).resolve().parents[1] / "decks"


def graded(n: int, ratio: float) -> np.ndarray:
    """n+1 points on [0, 1], geometric sizes with last/first = ratio (1: uniform)."""
    if abs(ratio - 1.0) < 1e-12:
        return np.linspace(0.0, 1.0, n + 1)
    q = ratio ** (1.0 / max(n - 1, 1))
    h = q ** np.arange(n)
    return np.concatenate([[0.0], np.cumsum(h)]) / h.sum()


def uniform_then_graded(n_uniform: int, n_graded: int, s_uniform: float) -> np.ndarray:
    """Points on [0, 1]: ``n_uniform`` equal elements over [0, s_uniform], then ``n_graded`` elements
    growing geometrically from the same size to fill the rest (fine and even where the contact is)."""
    from scipy.optimize import brentq

    h0 = s_uniform / n_uniform
    rest = 1.0 - s_uniform
    if n_graded == 0:
        return np.linspace(0.0, 1.0, n_uniform + 1)
    k = np.arange(1, n_graded + 1)
    q = brentq(lambda q: h0 * np.sum(q ** k) - rest, 1.0 + 1e-12, 10.0) if h0 * n_graded < rest else 1.0
    tail = s_uniform + np.cumsum(h0 * q ** k)
    tail[-1] = 1.0
    return np.concatenate([np.linspace(0.0, s_uniform, n_uniform + 1), tail])


def coons(bottom, right, top, left, s, t):
    """Transfinite (Coons) patch from four boundary curves, each a function of [0,1] -> (2,).

    bottom(s) from corner 00 to 10, right(t) from 10 to 11, top(s) from 01 to 11, left(t) from 00 to 01.
    """
    P00, P10, P01, P11 = bottom(0.0), bottom(1.0), top(0.0), top(1.0)
    return ((1 - t) * bottom(s) + t * top(s) + (1 - s) * left(t) + s * right(t)
            - ((1 - s) * (1 - t) * P00 + s * (1 - t) * P10 + (1 - s) * t * P01 + s * t * P11))


def half_cylinder(R: float, zone: float, n_zone: int, n_arc: int, n_rad: int, full: bool):
    """Q8 mesh of the lower half (full=True) or lower-right quarter of a disc of radius R.

    Around the contact point (0, -R) a zone of arc length ``zone`` (and the same depth) carries
    ``n_zone`` even elements each way; beyond it ``n_arc`` elements along the arc to 45 degrees and
    ``n_rad`` towards the top grow geometrically.  Returns (nodes dict, elements list, arc
    faces, top faces, top nodes, axis nodes).
    """
    arc_a = lambda u: R * np.array([np.sin(np.pi / 4 * u), -np.cos(np.pi / 4 * u)])       # (0,-R) -> 45 deg
    arc_b = lambda u: R * np.array([np.sin(np.pi / 4 * (1 + u)), -np.cos(np.pi / 4 * (1 + u))])  # 45 -> (R,0)
    top = lambda u: np.array([R * u, 0.0])                                                 # (0,0) -> (R,0)
    axis = lambda u: np.array([0.0, -R * (1 - u)])                                         # (0,-R) -> (0,0)
    s_nodes = uniform_then_graded(n_zone, n_arc, zone / (np.pi / 4 * R))
    t_nodes = uniform_then_graded(n_zone, n_rad, zone / R)
    # quadratic grid: mid points in parameter space between graded nodes
    def refine(x):
        out = np.empty(2 * len(x) - 1)
        out[0::2] = x
        out[1::2] = 0.5 * (x[:-1] + x[1:])
        return out
    S, T = refine(s_nodes), refine(t_nodes)
    grid = {}
    for i, s in enumerate(S):
        for j, t in enumerate(T):
            if i % 2 == 1 and j % 2 == 1:
                continue
            grid[i, j] = coons(arc_a, arc_b, top, axis, s, t)
    # patch: bottom = arc_a (s), right = arc_b (t), top = top (s), left = axis (t)
    pts = dict(grid)
    if full:
        for (i, j), p in grid.items():
            if i > 0:                                   # mirror, except the axis column i = 0
                pts[-i, j] = np.array([-p[0], p[1]])
    keys = sorted(pts, key=lambda k: (k[1], k[0]))
    ids = {k: n + 1 for n, k in enumerate(keys)}
    nodes = {ids[k]: pts[k] for k in keys}
    elements, arc_faces, top_faces = [], [], []
    i_lo = -(len(S) - 1) if full else 0
    for j0 in range(0, len(T) - 1, 2):
        for i0 in range(i_lo, len(S) - 1, 2):
            c = [ids[i0, j0], ids[i0 + 2, j0], ids[i0 + 2, j0 + 2], ids[i0, j0 + 2]]
            m = [ids[i0 + 1, j0], ids[i0 + 2, j0 + 1], ids[i0 + 1, j0 + 2], ids[i0, j0 + 1]]
            elements.append(tuple(c + m))
            if j0 == 0:
                arc_faces.append((len(elements), 1))      # face S1 lies on the arc
            if j0 == len(T) - 3:
                top_faces.append((len(elements), 3))      # face S3 lies on the flat top
    # Mirrored elements are ordered with increasing i, so corners stay counter-clockwise.
    top_nodes = [ids[k] for k in keys if abs(pts[k][1]) < 1e-12 and k[1] == len(T) - 1]
    axis_nodes = [ids[k] for k in keys if k[0] == 0]
    return nodes, elements, arc_faces, top_faces, top_nodes, axis_nodes


def write_inc(path: Path, nodes, elements, etype, sets, surfaces, comment):
    lines = [f"** {comment}", "** generated by tools/make_meshes.py; do not edit by hand",
             "** the including deck gives the element type as *PARAMETER ETYPE (Q8PE or Q8PER)", "*NODE"]
    lines += [f"{n}, {x:.15g}, {y:.15g}" for n, (x, y) in nodes.items()]
    lines.append("*ELEMENT, TYPE=<ETYPE>, ELSET=CYL")
    lines += [f"{k + 1}, " + ", ".join(map(str, e)) for k, e in enumerate(elements)]
    for name, ids in sets.items():
        lines.append(f"*NSET, NSET={name}")
        lines += [", ".join(map(str, ids[k:k + 12])) for k in range(0, len(ids), 12)]
    for name, faces in surfaces.items():
        lines.append(f"*SURFACE, NAME={name}")
        lines += [f"{e}, S{f}" for e, f in faces]
    path.write_text("\n".join(lines) + "\n")


def main():
    R = 10.0
    # the Hertz half-width is about 1 mm: the even zone spans 1.6 mm with h = 0.27, 0.13, 0.067 mm
    for tag, n_zone, n_arc, n_rad in (("coarse", 6, 6, 5), ("medium", 12, 8, 7), ("fine", 24, 12, 10)):
        for full, what in ((False, "quarter"), (True, "half")):
            nodes, els, arc, tops, top, axis = half_cylinder(R, 1.6, n_zone, n_arc, n_rad, full)
            sets = {"TOP": top}
            if not full:
                sets["AXIS"] = axis
            write_inc(DECKS / "meshes" / f"cylinder_{what}_{tag}.inp", nodes, els, "Q8PE",
                      sets, {"ARC": arc, "TOPFACE": tops},
                      f"{what} of a cylinder R={R}, lower side, contact point (0,-R); {tag} mesh, "
                      f"h = {1.6 / n_zone:.3g} mm over the first 1.6 mm")


if __name__ == "__main__":
    main()
