"""Element faces (edges) and the edge interpolation shared by faces, pressure loads and contact.

A face is a 2- or 3-node line in the node order of its element class's ``faces`` (corner,
corner[, mid-side]), interpolated by ``shapes.line_shape`` on xi in [-1, 1].  Faces run
counter-clockwise around their element, so the body lies on the *left* of the tangent
``t = dx/dxi`` and the outward normal (unnormalised, length |t|) is the right normal
``(t_y, -t_x)``.

Axes: ``f`` face, ``q`` Gauss point on the face, ``a``/``b`` face node, ``i``/``k`` spatial
component, ``d`` face DOF (``2 a + i``).
"""
from __future__ import annotations

import numpy as np

from .. import registry
from ..core.tensors import RIGHT, right_normal
from .base import Group, GroupResult, StepContext
from .shapes import gauss_1d, line_shape

__all__ = ["face_nodes", "surface_faces", "edge_geometry", "PressureGroup"]


def face_nodes(element_cls, conn: np.ndarray, faces: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(f, nfn) node rows of faces ``faces`` (f,) 1.. of elements at ``rows`` (f,) of ``conn``."""
    local = np.asarray(element_cls.faces, dtype=np.int64)[np.asarray(faces, np.int64) - 1]
    return np.asarray(conn)[np.asarray(rows, np.int64)[:, None], local]


def surface_faces(model, surface_name: str):
    """Faces of a ``*SURFACE``: ``(face_node_rows (f, nfn), element_ids (f,), faces (f,))``.

    Raises KeyError for an unknown surface or element, ValueError when the surface mixes
    faces with different node counts (Q4 and Q8 elements, say).
    """
    surf = model.surfaces.get(surface_name)
    if surf is None:
        surf = model.surfaces.get(surface_name.upper())
    if surf is None:
        raise KeyError(f"unknown surface {surface_name}")
    lookup = model.element_lookup()
    elements = np.asarray(surf.elements, dtype=np.int64)
    faces = np.asarray(surf.faces, dtype=np.int64)
    missing = [int(e) for e in elements if int(e) not in lookup]
    if missing:
        raise KeyError(f"surface {surf.name} refers to unknown element(s) {missing[:10]}")
    where = np.array([lookup[int(e)] for e in elements], dtype=np.int64).reshape(-1, 2)
    out = [None] * len(elements)
    for b in np.unique(where[:, 0]):        # loop over element blocks, not faces
        sel = np.flatnonzero(where[:, 0] == b)
        blk = model.blocks[b]
        cls = registry.get("elements", blk.type)
        rows = face_nodes(cls, blk.conn, faces[sel], where[sel, 1])
        for k, s in enumerate(sel):
            out[s] = rows[k]
    sizes = {len(r) for r in out}
    if len(sizes) > 1:
        raise ValueError(f"surface {surf.name} mixes faces of {sorted(sizes)} nodes")
    nfn = sizes.pop() if sizes else 2
    return np.array(out, dtype=np.int64).reshape(-1, nfn), elements, faces


def edge_geometry(x: np.ndarray, N: np.ndarray, dN: np.ndarray):
    """Points, tangents and unnormalised outward normals of faces with nodes ``x`` (f, a, 2).

    ``N``, ``dN`` (q, a) from ``line_shape``.  Returns ``xq`` (f, q, 2), ``t`` (f, q, 2) =
    dx/dxi and ``n`` (f, q, 2) = (t_y, -t_x) (|n| = |t| is the length Jacobian).
    """
    xq = np.einsum("qa,fai->fqi", N, x)
    t = np.einsum("qa,fai->fqi", dN, x)
    return xq, t, right_normal(t)


class PressureGroup(Group):
    """Uniform pressure on element faces, positive into the body.

    Parameters
    ----------
    face_nodes : (f, nfn) node rows (nfn = 2 or 3, corner, corner[, mid]).
    coords0 : (n, 2) reference coordinates.
    axisymmetric : integrals per radian (``r ds``) instead of per thickness.
    thickness : plane-strain thickness.
    ids : optional (f,) labels for messages (e.g. the owning element ids).

    ``pressure`` (f,) (or a scalar) is set by the step controller before each ``compute`` to
    its value at ``t_new``.  With ``ctx.nlgeom``
    the load follows the deformed face (exact, non-symmetric tangent, including the change
    of ``r`` in axisymmetry); otherwise it acts on the reference face and ``K = 0``.
    ``f`` is minus the external force (residual convention of ``elements.base``).
    """

    def __init__(self, face_nodes, coords0, axisymmetric: bool, thickness: float = 1.0,
                 ids=None):
        self.face_nodes = np.asarray(face_nodes, dtype=np.int64)
        self.coords0 = np.asarray(coords0, float)
        self.axisymmetric = bool(axisymmetric)
        self.thickness = float(thickness)
        nf, nfn = self.face_nodes.shape
        self.ids = np.arange(1, nf + 1) if ids is None else np.asarray(ids)
        self.dofs = (2 * self.face_nodes[:, :, None] + np.arange(2)).reshape(nf, 2 * nfn)
        xg, self.wq = gauss_1d(3 if nfn == 3 else 2)
        self.N, self.dN = line_shape(nfn, xg)
        self.pressure = np.zeros(nf)

    def init_state(self) -> dict[str, np.ndarray]:
        return {}

    def compute(self, u_new: np.ndarray, u_old: np.ndarray, state: dict[str, np.ndarray],
                ctx: StepContext, tangent: bool = True) -> GroupResult:
        nf, nfn = self.face_nodes.shape
        x = self.coords0[self.face_nodes]
        if ctx.nlgeom:
            x = x + u_new[self.face_nodes]
        xq, _, n = edge_geometry(x, self.N, self.dN)
        p = np.broadcast_to(np.asarray(self.pressure, float), (nf,))
        scale = xq[..., 0] if self.axisymmetric else np.full(xq.shape[:2], self.thickness)
        pw = p[:, None] * self.wq                                          # (f, q)
        # -f_ext: traction -p n_out, so f = + sum p N_a n r w
        f = np.einsum("fq,qa,fqi->fai", pw * scale, self.N, n).reshape(nf, 2 * nfn)
        if ctx.nlgeom and self.axisymmetric and np.any(scale <= 0):
            bad = (scale <= 0).any(axis=1)
            ids = ", ".join(str(int(i)) for i in self.ids[bad][:20])
            return GroupResult(f, np.zeros((nf, 2 * nfn, 2 * nfn)) if tangent else None, state,
                               failure=f"pressure face crosses the axis (r <= 0) at face(s) {ids}")
        if not tangent:
            return GroupResult(f, None, state)
        K = np.zeros((nf, nfn, 2, nfn, 2))
        if ctx.nlgeom:
            # d n_i / d u_bk = dN_b R_ik ; d r / d u_bk = N_b delta_k0
            K += np.einsum("fq,qa,qb,ik->faibk", pw * scale, self.N, self.dN, RIGHT)
            if self.axisymmetric:
                K[:, :, :, :, 0] += np.einsum("fq,qa,fqi,qb->faib", pw, self.N, n, self.N)
        return GroupResult(f, K.reshape(nf, 2 * nfn, 2 * nfn), state)
