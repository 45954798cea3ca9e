"""Structured meshes of a rectangle (``*MESH``), for any element type that says how to fill a
cell of a grid (``grid_order``, ``cell_elements``).

The rectangle is cut into ``nx x ny`` cells; each cell holds a grid of ``grid_order + 1`` points a
side (corners, and mid-sides and centre for a quadratic element).  The element class lists the
elements of one cell as the grid offsets of their nodes (a Q8: one element using every point but
the centre; a T6: two triangles).  Nodes are numbered row by row from the bottom-left corner,
left to right, over the grid points some element uses; elements cell by cell in the same order,
in the order the class lists them.  Sides BOTTOM, RIGHT, TOP, LEFT give a node set (the grid points
on the side, in order along it: left to right, bottom to top) and a surface (the element faces
lying on the side, in the same order).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Rectangle", "rectangle", "SIDES"]

SIDES = ("BOTTOM", "RIGHT", "TOP", "LEFT")


@dataclass
class Rectangle:
    """A structured mesh: ``coords`` (n, 2) of its nodes (numbered 0..n-1 here), ``conn`` (e, nen)
    node numbers, and per side ``nodes`` (k,) and faces ``(elements (f,), faces (f,) 1-based)``."""
    coords: np.ndarray
    conn: np.ndarray
    side_nodes: dict[str, np.ndarray]
    side_faces: dict[str, tuple[np.ndarray, np.ndarray]]


def rectangle(element, x0: float, y0: float, lx: float, ly: float, nx: int, ny: int) -> Rectangle:
    """The structured mesh of ``[x0, x0 + lx] x [y0, y0 + ly]`` in ``nx x ny`` cells of the
    element class ``element``."""
    m = int(element.grid_order)
    offsets = np.asarray(element.cell_elements, int)                  # (k, nen, 2)
    ni, nj = m * nx + 1, m * ny + 1
    ci, cj = np.meshgrid(np.arange(nx), np.arange(ny))               # (ny, nx): row by row
    ci, cj = ci.ravel(), cj.ravel()                                   # cells in order
    gi = m * ci[:, None, None] + offsets[None, :, :, 0]               # (cells, k, nen)
    gj = m * cj[:, None, None] + offsets[None, :, :, 1]
    flat = (gj * ni + gi).reshape(-1, offsets.shape[1])               # grid index of each node
    used = np.zeros(ni * nj, bool)
    used[flat.ravel()] = True
    number = np.full(ni * nj, -1)
    number[used] = np.arange(used.sum())                              # row by row, left to right
    ii, jj = np.meshgrid(np.arange(ni), np.arange(nj))
    ii, jj = ii.ravel()[used], jj.ravel()[used]
    coords = np.column_stack([x0 + lx * ii / (ni - 1), y0 + ly * jj / (nj - 1)])
    conn = number[flat]

    grid = number.reshape(nj, ni)
    on_side = {"BOTTOM": grid[0, :], "RIGHT": grid[:, -1], "TOP": grid[-1, :], "LEFT": grid[:, 0]}
    side_nodes = {side: nodes[nodes >= 0] for side, nodes in on_side.items()}
    faces = [np.asarray(f) for f in element.faces]
    side_faces = {}
    for side, nodes in side_nodes.items():
        members = np.zeros(len(coords), bool)
        members[nodes] = True
        on = np.stack([members[conn[:, f]].all(axis=1) for f in faces], axis=1)   # (e, faces)
        elems, face_ids = np.nonzero(on)           # element order: cell order along the side
        side_faces[side] = (elems.astype(int), face_ids.astype(int) + 1)
    return Rectangle(coords, conn, side_nodes, side_faces)
