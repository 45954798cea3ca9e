"""Rigid foundation: a chain of 3-point parabolic arcs, and the (P, e_u) -> Q projection.

Geometry
--------
``points`` (m, 2), m odd >= 3.  Arc ``j`` runs through points ``2j, 2j+1, 2j+2`` with the
quadratic Lagrange interpolation in ``s`` in [-1, 1] (``s = -1`` at ``2j``, ``0`` at ``2j+1``,
``+1`` at ``2j+2``)::

    F_j(s) = A_j + B_j s + C_j s**2,   A = X1,  B = (X2 - X0)/2,  C = (X0 + X2)/2 - X1.

The arcs join with C0 continuity.  The body lies on the LEFT of the direction of travel, so
the foundation normal pointing into the body is the left normal ``n = (-F'_y, F'_x)/|F'|``.

Beyond its ends the chain is continued by straight half-lines along the end tangents
(``F_0(-1) + (s + 1) F_0'(-1)`` for ``s < -1`` on the first arc, ``F_last(1) + (s - 1)
F_last'(1)`` for ``s > 1`` on the last), so a body sliding past an end keeps a well-defined,
continuous contact instead of dropping out.

The foundation only moves rigidly: every method takes a translation ``c`` (2,) that is added
to all points (the step controller passes ``ctx.foundation_old/new[name]``).

Projection
----------
For a point ``P`` and a unit direction ``e_u`` (the outward normal of the deformed body), Q is
the intersection of the line ``P + t e_u`` with the foundation, written ``Q = P - d e_u``:
``d > 0`` means that Q lies behind P along ``e_u``, i.e. P has penetrated the foundation.

An intersection is *valid* when its arc parameter lies in [-1 - tol, 1 + tol] (or on an end
half-line) and the body faces the foundation there, ``e_u . n < 0`` (the body's outward normal
points against the foundation's body-side normal).  The second condition rejects the far side
of a closed-looking tool and the surfaces of the body that face away from the foundation
(without it a top face above a flat foundation would read as deeply penetrated).  Among valid
intersections the one with the smallest ``|d|`` wins.  No valid intersection (the line misses
the chain: negative discriminant, a line parallel to a straight arc, or only back-facing
hits): ``found`` is False, ``d = -inf``; the contact element treats such points as open.

Exact first derivatives (implicit function theorem).  ``P - d e_u = F(s) + c``; with ``m`` any
normal of the foundation tangent at Q, dotting the differential with ``m`` removes ``ds``::

    dd = [ m.(dP - dc) - d m.de_u ] / (m.e_u)

so ``dd/dP = m/(m.e_u)``, ``dd/de_u = -d m/(m.e_u)``, ``dd/dc = -dd/dP`` (stored as
``dd_dP`` and ``dd_de``).  They do not involve the curvature of the foundation; they blow up
only for rays tangent to the foundation, which are not valid (``e_u . n < 0`` strictly, by a
margin ``cos_min``).

At a joint both arcs give the same Q and d (C0 chain), so d is continuous; either arc may be
reported.  Its derivatives jump there when the chain has a kink (the tangent jumps).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Foundation", "Projection"]


@dataclass
class Projection:
    """Result of :meth:`Foundation.project` for ``g`` points.

    Attributes
    ----------
    Q : (g, 2) intersection point (NaN where not found).
    d : (g,) signed distance, ``Q = P - d e_u``; ``d > 0`` penetration; ``-inf`` where not found.
    arc : (g,) arc index (-1 where not found).
    s : (g,) local coordinate on the arc (< -1 or > 1 on the end half-lines).
    tangent : (g, 2) unit foundation tangent at Q (direction of travel; NaN where not found).
    normal : (g, 2) unit foundation normal at Q, pointing into the body (left normal).
    found : (g,) bool.
    dd_dP : (g, 2) derivative of d w.r.t. P (0 where not found); ``dd/dc = -dd_dP``.
    dd_de : (g, 2) derivative of d w.r.t. e_u (0 where not found).
    """
    Q: np.ndarray
    d: np.ndarray
    arc: np.ndarray
    s: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    found: np.ndarray
    dd_dP: np.ndarray
    dd_de: np.ndarray


def _perp(v: np.ndarray) -> np.ndarray:
    """Left normal (rotation by +90 degrees) of vectors (..., 2)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


class Foundation:
    """Rigid chain of 3-point parabolic arcs.

    Parameters
    ----------
    points : (m, 2) array, m odd >= 3, in the direction of travel (body on the left).
    name : str, for messages.
    s_tol : tolerance on the arc parameter when accepting a root (joints).
    cos_min : minimal ``-e_u . n`` for a valid intersection (rejects grazing rays).
    """

    def __init__(self, points, name: str = "", s_tol: float = 1e-8, cos_min: float = 1e-10):
        pts = np.asarray(points, float)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"foundation {name!r}: points must be (m, 2), got {pts.shape}")
        m = pts.shape[0]
        if m < 3 or m % 2 == 0:
            raise ValueError(f"foundation {name!r}: needs an odd number >= 3 of points, got {m}")
        self.points = pts
        self.name = name
        self.s_tol = float(s_tol)
        self.cos_min = float(cos_min)
        X0, X1, X2 = pts[0:-1:2], pts[1::2], pts[2::2]
        self.A = X1                               # (j, 2)
        self.B = 0.5 * (X2 - X0)
        self.C = 0.5 * (X0 + X2) - X1
        self.n_arcs = X1.shape[0]
        # end half-lines: origin and direction (derivative w.r.t. s of the end arcs)
        self._start = (X0[0], self.B[0] - 2 * self.C[0])      # F_0(-1), F_0'(-1)
        self._end = (X2[-1], self.B[-1] + 2 * self.C[-1])     # F_last(1), F_last'(1)

    # ------------------------------------------------------------------ geometry
    def points_at(self, c=None) -> np.ndarray:
        """Current points (m, 2) for the translation ``c`` (2,)."""
        return self.points + (np.zeros(2) if c is None else np.asarray(c, float))

    def evaluate(self, arc, s, c=None) -> tuple[np.ndarray, np.ndarray]:
        """Position (g, 2) and derivative dF/ds (g, 2) at arc indices ``arc`` (g,), ``s`` (g,),
        including the end half-lines (``s < -1`` on arc 0, ``s > 1`` on the last arc)."""
        arc = np.asarray(arc, int)
        s = np.asarray(s, float)
        A, B, C = self.A[arc], self.B[arc], self.C[arc]
        X = A + B * s[:, None] + C * s[:, None] ** 2
        dX = B + 2 * C * s[:, None]
        lo = (arc == 0) & (s < -1)
        hi = (arc == self.n_arcs - 1) & (s > 1)
        o, t = self._start
        X[lo] = o + (s[lo, None] + 1) * t
        dX[lo] = t
        o, t = self._end
        X[hi] = o + (s[hi, None] - 1) * t
        dX[hi] = t
        if c is not None:
            X = X + np.asarray(c, float)
        return X, dX

    # ---------------------------------------------------------------- projection
    def _candidates(self, P, e_u, c):
        """Arc parameters of the intersections of the lines (P, e_u) with every arc and the
        two end half-lines: ``s`` (g, k) and ``arc`` (k,) (NaN where no root / out of range)."""
        w = _perp(e_u)                                          # (g, 2), w . (X - P) = 0 on the line
        rel = self.A[None] + c - P[:, None]                      # (g, j, 2)
        a = np.einsum("gi,ji->gj", w, self.C)
        b = np.einsum("gi,ji->gj", w, self.B)
        c0 = np.einsum("gi,gji->gj", w, rel)
        with np.errstate(divide="ignore", invalid="ignore"):
            disc = b * b - 4 * a * c0
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            # numerically stable pair; when a -> 0, r2 -> -c0/b (the linear case) and r1 -> inf
            q = -0.5 * (b + np.where(b >= 0, sq, -sq))
            r1 = q / a
            r2 = c0 / q
            # b = 0 and disc = 0 with a != 0 (ray through the vertex, tangent): q = 0
            r2 = np.where((q == 0) & (a != 0), -b / (2 * a), r2)
            roots = np.concatenate([r1, r2], axis=1)            # (g, 2j)
            lo = -1 - self.s_tol
            hi = 1 + self.s_tol
            roots = np.where((roots >= lo) & (roots <= hi), roots, np.nan)
            # end half-lines: w . (o + c + (s -/+ 1) t - P) = 0
            ends = []
            for (o, t), sign in ((self._start, -1.0), (self._end, 1.0)):
                wt = w @ t
                ds = -np.einsum("gi,gi->g", w, o + c - P) / wt    # offset from the end, along t
                ok = ds * sign > 0                              # beyond the end only
                ends.append(np.where(ok, sign + ds, np.nan))
        s = np.concatenate([roots, np.stack(ends, axis=1)], axis=1)
        j = np.arange(self.n_arcs)
        arc = np.concatenate([j, j, [0, self.n_arcs - 1]])
        return s, arc

    def project(self, P, e_u, c=None) -> Projection:
        """Intersect the lines (P, e_u) with the foundation translated by ``c``.

        Parameters
        ----------
        P : (g, 2) points; e_u : (g, 2) unit directions; c : (2,) translation (default 0).

        Returns
        -------
        :class:`Projection` (see the module docstring for the validity rule and derivatives).
        """
        P = np.atleast_2d(np.asarray(P, float))
        e_u = np.atleast_2d(np.asarray(e_u, float))
        c = np.zeros(2) if c is None else np.asarray(c, float)
        g = P.shape[0]
        s, arc = self._candidates(P, e_u, c)                      # (g, k), (k,)
        # evaluate only the candidates that exist (most lines cross few arcs): h hits
        hit_g, hit_k = np.nonzero(np.isfinite(s))
        X, dX = self.evaluate(arc[hit_k], s[hit_g, hit_k], c)     # (h, 2)
        m = _perp(dX)
        m_norm = np.linalg.norm(m, axis=-1)
        e_h = e_u[hit_g]
        cosn = np.einsum("hi,hi->h", m, e_h) / np.where(m_norm > 0, m_norm, 1.0)
        # d = e_u . (P - Q) / |e_u|^2: the line parameter, so that Q = P - d e_u holds (and the
        # derivatives below) even for a direction that is not exactly unit
        dist = np.einsum("hi,hi->h", P[hit_g] - X, e_h) / np.einsum("hi,hi->h", e_h, e_h)
        ok = (m_norm > 0) & (cosn < -self.cos_min)
        score = np.full(s.shape, np.inf)
        score[hit_g, hit_k] = np.where(ok, np.abs(dist), np.inf)
        where = np.full(s.shape, -1)
        where[hit_g, hit_k] = np.arange(hit_g.size)
        rows = np.arange(g)
        best = np.argmin(score, axis=1)
        found = np.isfinite(score[rows, best])
        h = np.where(found, where[rows, best], 0)
        if hit_g.size == 0:                                       # nothing crossed at all
            X = dX = m = np.zeros((1, 2))
            dist = np.zeros(1)
        Q = np.where(found[:, None], X[h], np.nan)
        d = np.where(found, dist[h], -np.inf)
        mb = np.where(found[:, None], m[h], 0.0)
        tn = dX[h]
        tn_norm = np.linalg.norm(tn, axis=-1)
        tangent = np.where(found[:, None], tn / np.where(tn_norm > 0, tn_norm, 1.0)[:, None], np.nan)
        me = np.where(found, np.einsum("gi,gi->g", mb, e_u), 1.0)
        dd_dP = mb / me[:, None]
        dd_de = -np.where(found, d, 0.0)[:, None] * dd_dP
        return Projection(Q=Q, d=d, arc=np.where(found, arc[best], -1),
                          s=np.where(found, s[rows, best], np.nan), tangent=tangent,
                          normal=_perp(tangent), found=found, dd_dP=dd_dP, dd_de=dd_de)
