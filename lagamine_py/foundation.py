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

The foundation only moves rigidly.  Its placement is a translation ``c`` (2,) of its reference
point ``centre`` (a tool's reference node, or the point a prescribed rotation turns about) and a
rotation ``theta`` (counter-clockwise) about it: a point ``X`` of the chain as given is at
``centre + c + R(theta) (X - centre)`` (:func:`placed`).  The methods below take the
translation ``c``; a rotated chain is projected in its own frame (the contact element turns the
line (P, e_u) into it, see :mod:`lagamine_py.elements.contact`).

:func:`circle_points` generates the points of a circle or circular arc (rolls, dies): ``n``
parabolic arcs through points of the circle, each within ``R (1 - sqrt(1 - (1 - cos phi)^2/4))``
of it (``phi`` half the angle of one arc: the arc's midpoint parameters ``s = +-1/sqrt 2`` lie
furthest inside, see :func:`circle_error`).

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
margin ``cos_min``, :data:`GRAZING_COS`).

At a joint both arcs give the same Q and d (C0 chain), so d is continuous; either arc may be
reported.  Its derivatives jump there when the chain has a kink (the tangent jumps).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import kernels
from .core.tensors import left_normal

__all__ = ["Foundation", "Projection", "placed", "rotation", "circle_points", "circle_error"]


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


def rotation(theta: float) -> np.ndarray:
    """The 2x2 counter-clockwise rotation by ``theta`` (radians)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def placed(points, centre, placement) -> np.ndarray:
    """Points (m, 2) of a chain given at ``points`` after the rigid placement ``placement``
    (``(dx, dy)`` or ``(dx, dy, theta)``) of its reference point ``centre``:
    ``centre + c + R(theta) (X - centre)``."""
    pts = np.asarray(points, float)
    v = np.asarray(placement, float).ravel()
    c = v[:2]
    theta = float(v[2]) if v.size > 2 else 0.0
    if theta == 0.0:
        return pts + c
    x0 = np.asarray(centre, float)
    return x0 + c + (pts - x0) @ rotation(theta).T


def circle_points(xc: float, yc: float, radius: float, start: float, end: float, arcs: int,
                  body: str) -> np.ndarray:
    """Points (2 arcs + 1, 2) of ``arcs`` parabolic arcs through points of the circle of centre
    (xc, yc) and ``radius``, covering the angles ``start`` to ``end`` (degrees, counter-clockwise
    from +x, ``start < end < start + 360``), equally spaced.  ``body`` says where the bodies in
    contact lie: ``"INSIDE"`` (a die, a container: the points run counter-clockwise, the centre
    on their left) or ``"OUTSIDE"`` (a roll, a punch nose: clockwise)."""
    a = np.radians(np.linspace(start, end, 2 * int(arcs) + 1))
    if body.upper() == "OUTSIDE":
        a = a[::-1]
    elif body.upper() != "INSIDE":
        raise ValueError(f"body must be INSIDE or OUTSIDE, got {body!r}")
    return np.column_stack([xc + radius * np.cos(a), yc + radius * np.sin(a)])


def circle_error(radius: float, start: float, end: float, arcs: int) -> float:
    """Largest distance from the chain of :func:`circle_points` to its circle: each arc spans
    ``2 phi`` with ``phi = (end - start) / (2 arcs)``; through three points of the circle at
    angles ``-phi, 0, phi`` the parabola is ``F(s) = (R - R a s^2, R sin(phi) s)`` (``a = 1 -
    cos phi``), whose radius is ``R sqrt(1 - a^2 s^2 (1 - s^2))``: inside the circle, furthest
    at ``s^2 = 1/2``, by ``R (1 - sqrt(1 - a^2/4))`` (about ``R phi^4 / 32``)."""
    phi = np.radians((end - start) / (2.0 * arcs))
    a = 1.0 - np.cos(phi)
    return float(radius * (1.0 - np.sqrt(1.0 - a * a / 4.0)))


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    """Angle (degrees) between two vectors (2,)."""
    c = float(u @ v) / max(float(np.linalg.norm(u) * np.linalg.norm(v)), 1e-300)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-component of the cross product of (..., 2) vectors."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


#: the smallest ``-e_u . n`` of a valid intersection: a ray closer than this to grazing the
#: foundation is a miss.  Its hit would lie ``h / cos`` away (h the point's distance to the
#: foundation's line), a number made of the round-off of the normal: a face exactly parallel to
#: a tool (the ring's flank beside the platen, decks/ring.dat) has a ray 1e-10..1e-9 off
#: grazing, from the last bits of a converged displacement, so its point was "open" with a gap
#: of 1e9..6e9 mm on one CPU and "none" on another (OpenBLAS's Haswell, Zen or SandyBridge
#: kernels against SkylakeX's).  1e-6 leaves a margin of 1e3 over that noise and rejects only
#: rays within 6e-5 degrees of the surface, which cannot carry a contact force.
GRAZING_COS = 1e-6


class Foundation:
    """Rigid chain of 3-point parabolic arcs.

    Parameters
    ----------
    points : (m, 2) array, m odd >= 3, in the direction of travel (body on the left).
    name : str, for messages.
    centre : (2,) the reference point its placement turns about.
    s_tol : tolerance on the arc parameter when accepting a root (joints).
    cos_min : minimal ``-e_u . n`` for a valid intersection (rejects grazing rays;
        :data:`GRAZING_COS`).
    """

    def __init__(self, points, name: str = "", s_tol: float = 1e-8, cos_min: float = GRAZING_COS,
                 centre=(0.0, 0.0)):
        pts = np.asarray(points, float)
        #: the reference point of the placement (see the module docstring)
        self.centre = np.asarray(centre, float).reshape(2)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise ValueError(f"foundation {name!r}: points must be (m, 2), got {pts.shape}")
        m = pts.shape[0]
        if m < 3 or m % 2 == 0:
            raise ValueError(f"foundation {name!r}: needs an odd number >= 3 of points, got {m}")
        self.points = pts
        self.name = name
        # project() through kernels.contact when switched on (use_kernels) and numba imports;
        # off by default: the NumPy path is the reference
        self.use_kernel = False
        self._kernel_arrays = None
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
        j = np.arange(self.n_arcs)
        self._cand_arc = np.concatenate([j, j, [0, self.n_arcs - 1]])  # arc of each candidate

    # ------------------------------------------------------------------ validation
    #: the tangent may not turn by more than this within an arc or at a joint (degrees): more is
    #: a chain that folds back on itself (a point written out of order, the typo of a sign)
    MAX_TURN = 150.0

    def shape_problems(self, samples: int = 16) -> list[str]:
        """What makes the chain unusable as a tool profile, as messages naming the points
        (1-based, as in the deck): coincident points, an arc that folds (its tangent vanishes
        or turns back), a joint where the chain doubles back, a chain that closes or crosses
        itself.  Empty for a good chain."""
        pts = self.points
        size = float(np.ptp(pts, axis=0).max()) or 1.0
        out = []
        # coincident points (any two, not only neighbours: a closed chain repeats its first)
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
        i, j = np.nonzero(np.triu(d <= 1e-9 * size, 1))
        for a, b in list(zip(i, j))[:5]:
            out.append(f"points {a + 1} and {b + 1} coincide"
                       + (": the chain is closed; a tool profile must be open" if (a, b) == (0, len(pts) - 1) else ""))
        if out:
            return out
        s = np.linspace(-1.0, 1.0, 2 * samples + 1)
        for k in range(self.n_arcs):
            tang = self.B[k] + 2.0 * self.C[k] * s[:, None]                   # F'(s)
            speed = np.linalg.norm(tang, axis=1)
            chord = float(np.linalg.norm(pts[2 * k + 2] - pts[2 * k]))
            turn = _angle(tang[0], tang[-1])
            if speed.min() <= 1e-3 * max(chord, 1e-300) or turn > self.MAX_TURN:
                out.append(f"the arc through points {2 * k + 1}, {2 * k + 2}, {2 * k + 3} folds back "
                           f"on itself (its tangent turns by {turn:.0f} degrees): a point is out of "
                           f"order or misplaced")
        for k in range(self.n_arcs - 1):
            before = self.B[k] + 2.0 * self.C[k]
            after = self.B[k + 1] - 2.0 * self.C[k + 1]
            turn = _angle(before, after)
            if turn > self.MAX_TURN:
                out.append(f"the chain doubles back at point {2 * k + 3} (it turns by {turn:.0f} "
                           f"degrees there)")
        if not out:
            out += self._crossings(samples)
        return out

    def _crossings(self, samples: int) -> list[str]:
        """Messages for arcs that cross non-adjacent arcs (a chain crossing itself)."""
        s = np.linspace(-1.0, 1.0, samples + 1)
        arc = np.repeat(np.arange(self.n_arcs), samples + 1)
        X, _ = self.evaluate(arc, np.tile(s, self.n_arcs))
        X = X.reshape(self.n_arcs, samples + 1, 2)
        a, b = X[:, :-1].reshape(-1, 2), X[:, 1:].reshape(-1, 2)       # segments (m, 2)
        owner = np.repeat(np.arange(self.n_arcs), samples)
        out = []
        for lo in range(0, len(a), 2048):                    # chunks: bounded pair arrays
            p, r = a[lo:lo + 2048, None], (b - a)[lo:lo + 2048, None]
            q, t = a[None], (b - a)[None]
            den = _cross(r, t)
            with np.errstate(divide="ignore", invalid="ignore"):
                u = _cross(q - p, t) / den
                v = _cross(q - p, r) / den
            hit = (den != 0) & (u > 1e-9) & (u < 1 - 1e-9) & (v > 1e-9) & (v < 1 - 1e-9)
            near = np.abs(owner[lo:lo + 2048, None] - owner[None]) <= 1
            i, j = np.nonzero(hit & ~near)
            for m, n in zip(i + lo, j):
                if owner[m] < owner[n]:
                    out.append(f"the chain crosses itself: the arc through points {2 * owner[m] + 1}-"
                               f"{2 * owner[m] + 3} crosses the arc through points "
                               f"{2 * owner[n] + 1}-{2 * owner[n] + 3}")
                    return out
        return out

    def side(self, P, normals, extend: bool = False) -> np.ndarray:
        """For body points ``P`` (g, 2) with outward normals ``normals`` (g, 2): +1 where the
        body lies on the left of the chain (the convention), -1 on its right, 0 where it cannot
        tell (a point beyond the chain's ends).  A point off the chain is judged by the side it
        stands on -- the side a body that starts apart approaches from; a point on the chain
        (touching) by its normal, which must face the chain's left normal.  ``extend``: judge
        the points beyond the ends against the end half-lines that continue the chain (as
        :meth:`project` does) instead of answering 0."""
        P = np.atleast_2d(np.asarray(P, float))
        normals = np.atleast_2d(np.asarray(normals, float))
        arc, s, X, dX = self.closest(P)
        t = dX / np.linalg.norm(dX, axis=1)[:, None]
        m = left_normal(t)
        gap = P - X
        side = np.einsum("gi,gi->g", gap, m)
        size = float(np.ptp(self.points, axis=0).max()) or 1.0
        touching = np.linalg.norm(gap, axis=1) <= 1e-6 * size
        facing = -np.einsum("gi,gi->g", normals, m)
        out = np.sign(np.where(touching, facing, side))
        end = ((arc == 0) & (s <= -1.0)) | ((arc == self.n_arcs - 1) & (s >= 1.0))
        beyond = end & ~touching & (np.abs(np.einsum("gi,gi->g", gap, t)) > np.abs(side))
        if not extend:
            out[beyond] = 0                                 # beyond an end: cannot tell
        else:                   # on the half-line itself: touching it, judged by the normal
            on_line = beyond & (np.abs(side) <= 1e-6 * size)
            out[on_line] = np.sign(facing[on_line])
        return out

    def closest(self, P, samples: int = 32):
        """The point of the chain (arcs only, ends not extended) closest to each of ``P``
        (g, 2): ``arc`` (g,), ``s`` (g,), the point ``X`` (g, 2) and ``dF/ds`` (g, 2): the
        nearest of ``samples`` points an arc, refined by Newton on ``s``."""
        P = np.atleast_2d(np.asarray(P, float))
        grid = np.linspace(-1.0, 1.0, samples + 1)
        arcs = np.repeat(np.arange(self.n_arcs), len(grid))
        X, _ = self.evaluate(arcs, np.tile(grid, self.n_arcs))
        near = np.argmin(((P[:, None] - X[None]) ** 2).sum(-1), axis=1)
        arc, s = arcs[near], grid[near % len(grid)]
        B, C, A = self.B[arc], self.C[arc], self.A[arc]
        for _ in range(8):                        # minimise |F(s) - P|^2 on the arc
            F = A + B * s[:, None] + C * s[:, None] ** 2
            dF = B + 2.0 * C * s[:, None]
            g = np.einsum("gi,gi->g", dF, F - P)
            dg = np.einsum("gi,gi->g", 2.0 * C, F - P) + np.einsum("gi,gi->g", dF, dF)
            s = np.clip(s - g / np.where(dg > 0, dg, np.inf), -1.0, 1.0)
        X = A + B * s[:, None] + C * s[:, None] ** 2
        return arc, s, X, B + 2.0 * C * s[:, None]

    # ------------------------------------------------------------------ kernels
    def has_kernel(self) -> bool:
        """Whether :mod:`lagamine_py.kernels.contact` reproduces this foundation (the exact
        type: a subclass may change anything)."""
        return type(self) is Foundation

    def use_kernels(self, on: bool) -> None:
        """Project through the numba kernel (``on``, where :meth:`has_kernel`) or NumPy."""
        self.use_kernel = bool(on) and self.has_kernel()

    def kernel_arrays(self) -> tuple:
        """The chain as the kernels read it: ``A, B, C`` (j, 2) contiguous, the start and end
        half-lines' origins and directions (2,), ``s_tol``, ``cos_min`` (kept)."""
        if self._kernel_arrays is None:
            c = np.ascontiguousarray
            (so, st), (eo, et) = self._start, self._end
            self._kernel_arrays = (c(self.A, float), c(self.B, float), c(self.C, float),
                                   c(so, float), c(st, float), c(eo, float), c(et, float),
                                   self.s_tol, self.cos_min)
        return self._kernel_arrays

    # ------------------------------------------------------------------ geometry
    def sample(self, per_arc: int = 16, c=None) -> np.ndarray:
        """Points along the chain, ``per_arc`` intervals per arc (the arcs' own interpolation),
        translated by ``c``: (per_arc * arcs + 1, 2)."""
        s = np.linspace(-1.0, 1.0, per_arc + 1)
        arc = np.repeat(np.arange(self.n_arcs), per_arc)
        ss = np.tile(s[:-1], self.n_arcs)
        X, _ = self.evaluate(np.append(arc, self.n_arcs - 1), np.append(ss, 1.0), c)
        return X

    def points_at(self, c=None) -> np.ndarray:
        """Current points (m, 2) for the translation ``c`` (2,)."""
        return self.points + (np.zeros(2) if c is None else np.asarray(c, float))

    def evaluate(self, arc, s, c=None) -> tuple[np.ndarray, np.ndarray]:
        """Position (g, 2) and derivative dF/ds (g, 2) at arc indices ``arc`` (g,), ``s`` (g,),
        including the end half-lines (``s < -1`` on arc 0, ``s > 1`` on the last arc)."""
        arc = np.asarray(arc, int)
        s = np.asarray(s, float)
        A, B, C = self.A[arc], self.B[arc], self.C[arc]
        s1 = s[:, None]
        X = A + B * s1 + C * s1 ** 2
        dX = B + 2 * C * s1
        for (o, t), sign, at in ((self._start, -1.0, 0), (self._end, 1.0, self.n_arcs - 1)):
            beyond = (arc == at) & (s * sign > 1)
            if beyond.any():                     # on an end half-line: straight continuation
                X = np.where(beyond[:, None], o + (s1 - sign) * t, X)
                dX = np.where(beyond[:, None], t, dX)
        if c is not None:
            X = X + np.asarray(c, float)
        return X, dX

    def distance(self, P, c=None, samples: int = 16, newton: int = 8) -> np.ndarray:
        """Distance (g,) from points ``P`` (g, 2) to the chain translated by ``c``, end
        half-lines included: the nearest point of each arc is found from the best of
        ``samples + 1`` parameters by Newton's method on ``(F(s) - P) . F'(s) = 0`` (clipped to
        [-1, 1]), that of each half-line in closed form.  Not a hot path: the contact element
        uses it only for the outputs of points whose normal misses the foundation."""
        P = np.atleast_2d(np.asarray(P, float))
        if P.shape[0] == 0:
            return np.zeros(0)
        rel = P - (np.zeros(2) if c is None else np.asarray(c, float))      # (g, 2)
        A, B, C = self.A[None], self.B[None], self.C[None]                  # (1, j, 2)
        grid = np.linspace(-1.0, 1.0, samples + 1)                          # (m,)
        X = A[:, :, None] + B[:, :, None] * grid[:, None] + C[:, :, None] * grid[:, None] ** 2
        d2 = ((X - rel[:, None, None, :]) ** 2).sum(axis=-1)                # (g, j, m)
        s = grid[np.argmin(d2, axis=-1)]                                     # (g, j)
        R = A - rel[:, None, :]                                              # (g, j, 2)
        for _ in range(newton):
            F = R + B * s[..., None] + C * s[..., None] ** 2                # F(s) - P
            dF = B + 2.0 * C * s[..., None]
            g = (F * dF).sum(axis=-1)
            dg = (dF * dF).sum(axis=-1) + 2.0 * (F * C).sum(axis=-1)
            step = np.where(dg > 0, g / np.where(dg > 0, dg, 1.0), 0.0)     # a minimum only
            s = np.clip(s - step, -1.0, 1.0)
        F = R + B * s[..., None] + C * s[..., None] ** 2
        best = np.sqrt((F * F).sum(axis=-1)).min(axis=1)                     # (g,)
        for (o, t), sign in ((self._start, -1.0), (self._end, 1.0)):
            # the half-line o + k t, k sign >= 0 (pointing away from the chain)
            k = sign * np.maximum(sign * ((rel - o) @ t) / (t @ t), 0.0)
            best = np.minimum(best, np.linalg.norm(o + k[:, None] * t - rel, axis=-1))
        return best

    # ---------------------------------------------------------------- projection
    def _candidates(self, P, e_u, c):
        """Arc parameters of the intersections of the lines (P, e_u) with every arc and the
        two end half-lines: ``s`` (g, k) and ``arc`` (k,) (NaN where no root / out of range)."""
        # w = perp(e_u): w . (X - P) = 0 on the line; its components, without the (g, 2) array
        w0, w1 = -e_u[:, 1, None], e_u[:, 0, None]
        a = w0 * self.C[:, 0] + w1 * self.C[:, 1]                  # (g, j)
        b = w0 * self.B[:, 0] + w1 * self.B[:, 1]
        rel = self.A + c                                          # (j, 2)
        c0 = w0 * (rel[:, 0] - P[:, 0, None]) + w1 * (rel[:, 1] - P[:, 1, None])
        # an arc that is nearly straight (a -> 0) sends its far root to +-inf: dropped below
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            disc = b * b - 4 * a * c0
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            # numerically stable pair; when a -> 0, r2 -> -c0/b (the linear case) and r1 -> inf
            q = -0.5 * (b + np.where(b >= 0, sq, -sq))
            roots = np.empty((P.shape[0], 2 * self.n_arcs + 2))   # (g, k)
            j = self.n_arcs
            np.divide(q, a, out=roots[:, :j])
            r2 = np.divide(c0, q, out=roots[:, j:2 * j])
            # b = 0 and disc = 0 with a != 0 (ray through the vertex, tangent): q = 0
            tangent_hit = (q == 0) & (a != 0)
            if tangent_hit.any():
                r2[...] = np.where(tangent_hit, -b / (2 * a), r2)
            # end half-lines: w . (o + c + (s -/+ 1) t - P) = 0
            w = left_normal(e_u)
            for col, ((o, t), sign) in enumerate(((self._start, -1.0), (self._end, 1.0))):
                wt = w @ t                 # a BLAS product, as before (it may fuse multiply-adds)
                oc = o + c
                ds = -(w0[:, 0] * (oc[0] - P[:, 0]) + w1[:, 0] * (oc[1] - P[:, 1])) / wt
                # beyond the end only
                roots[:, 2 * j + col] = np.where(ds * sign > 0, sign + ds, np.nan)
            arcs = roots[:, :2 * j]
            arcs[~((arcs >= -1 - self.s_tol) & (arcs <= 1 + self.s_tol))] = np.nan
        return roots, self._cand_arc

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
        if self.use_kernel and e_u.shape == P.shape:
            fast = kernels.module("contact")
            if fast is not None:
                return Projection(**fast.project_points(self.kernel_arrays(), P, e_u, c))
        g = P.shape[0]
        s, arc = self._candidates(P, e_u, c)                      # (g, k), (k,)
        # evaluate only the candidates that exist (most lines cross few arcs): h hits
        hit_g, hit_k = np.nonzero(np.isfinite(s))
        X, dX = self.evaluate(arc[hit_k], s[hit_g, hit_k], c)     # (h, 2)
        # one hit per line (a single arc, or each line crossing one arc): it is the best one
        one = hit_g.size == g and np.array_equal(hit_g, np.arange(g))
        m = left_normal(dX)                                  # left normals (not unit)
        m_norm = np.linalg.norm(m, axis=-1)
        e_h = e_u if one else e_u[hit_g]
        cosn = np.einsum("hi,hi->h", m, e_h) / np.where(m_norm > 0, m_norm, 1.0)
        # d = e_u . (P - Q) / |e_u|^2: the line parameter, so that Q = P - d e_u holds (and the
        # derivatives below) even for a direction that is not exactly unit
        P_h = P if one else P[hit_g]
        dist = np.einsum("hi,hi->h", P_h - X, e_h) / np.einsum("hi,hi->h", e_h, e_h)
        ok = (m_norm > 0) & (cosn < -self.cos_min)
        score_h = np.where(ok, np.abs(dist), np.inf)
        if one:
            best = hit_k
            found = np.isfinite(score_h)
            h = np.where(found, np.arange(g), 0)
            s_best = s[hit_g, hit_k]
        else:
            score = np.full(s.shape, np.inf)
            score[hit_g, hit_k] = score_h
            where = np.full(s.shape, -1)
            where[hit_g, hit_k] = np.arange(hit_g.size)
            rows = np.arange(g)
            best = np.argmin(score, axis=1)
            found = np.isfinite(score[rows, best])
            h = np.where(found, where[rows, best], 0)
            s_best = s[rows, best]
            if hit_g.size == 0:                                   # nothing crossed at all
                X = dX = m = np.zeros((1, 2))
                dist = m_norm = np.zeros(1)
        if found.all():                       # every line met the foundation: no masking
            Q, d, mb, tn = X[h], dist[h], m[h], dX[h]
            tangent = tn / np.where(m_norm[h] > 0, m_norm[h], 1.0)[:, None]
            me = np.einsum("gi,gi->g", mb, e_u)
            dd_dP = mb / me[:, None]
            dd_de = -d[:, None] * dd_dP
            arc_best = arc[best]
        else:
            f1 = found[:, None]
            Q = np.where(f1, X[h], np.nan)
            d = np.where(found, dist[h], -np.inf)
            mb = np.where(f1, m[h], 0.0)
            tn_norm = m_norm[h]                                   # |dX| = |m|
            tangent = np.where(f1, dX[h] / np.where(tn_norm > 0, tn_norm, 1.0)[:, None], np.nan)
            me = np.where(found, np.einsum("gi,gi->g", mb, e_u), 1.0)
            dd_dP = mb / me[:, None]
            dd_de = -np.where(found, d, 0.0)[:, None] * dd_dP
            arc_best = np.where(found, arc[best], -1)
            s_best = np.where(found, s_best, np.nan)
        return Projection(Q=Q, d=d, arc=arc_best, s=s_best, tangent=tangent,
                          normal=left_normal(tangent), found=found, dd_dP=dd_dP, dd_de=dd_de)
