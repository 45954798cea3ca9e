"""Write *NODE / *ELEMENT deck lines for structured Q4/Q8 meshes of a mapped rectangle.

Tests use it to build decks whose geometry is not a plain rectangle (a quarter ring) or whose
node numbers they need to know (loads on chosen nodes).  The node id of grid point (i, j) on the
(2 nx + 1) x (2 ny + 1) grid of a Q8 mesh (or (nx + 1) x (ny + 1) for Q4) is ``ids[i, j]``.
"""
from __future__ import annotations

import numpy as np


def structured(nx, ny, mapping, quadratic=True):
    """Nodes and elements of a structured mesh on the unit square mapped by ``mapping(s, t)``.

    Returns (node_ids (I, J) int array with 0 where Q8 has no node, coords dict id -> (x, y),
    elements list of node-id tuples in Abaqus CPE8/CPE4 order).
    """
    m = 2 if quadratic else 1
    I, J = m * nx + 1, m * ny + 1
    ids = np.zeros((I, J), int)
    coords = {}
    nid = 0
    for j in range(J):
        for i in range(I):
            if quadratic and i % 2 == 1 and j % 2 == 1:
                continue  # serendipity: no centre node
            nid += 1
            ids[i, j] = nid
            coords[nid] = mapping(i / (I - 1), j / (J - 1))
    elements = []
    for ey in range(ny):
        for ex in range(nx):
            i0, j0 = m * ex, m * ey
            corners = [ids[i0, j0], ids[i0 + m, j0], ids[i0 + m, j0 + m], ids[i0, j0 + m]]
            if quadratic:
                mids = [ids[i0 + 1, j0], ids[i0 + 2, j0 + 1], ids[i0 + 1, j0 + 2], ids[i0, j0 + 1]]
                elements.append(tuple(corners + mids))
            else:
                elements.append(tuple(corners))
    return ids, coords, elements


def deck_lines(coords, elements, etype, elset="BODY"):
    lines = ["*NODE"]
    lines += [f"{n}, {x:.17g}, {y:.17g}" for n, (x, y) in coords.items()]
    lines.append(f"*ELEMENT, TYPE={etype}, ELSET={elset}")
    lines += [f"{k + 1}, " + ", ".join(str(n) for n in e) for k, e in enumerate(elements)]
    return "\n".join(lines) + "\n"


def nset_lines(name, node_ids):
    ids = [int(n) for n in np.ravel(node_ids) if n > 0]
    out = [f"*NSET, NSET={name}"]
    for k in range(0, len(ids), 12):
        out.append(", ".join(str(n) for n in ids[k:k + 12]))
    return "\n".join(out) + "\n"
