"""The first iterate of an increment: where Newton starts.

Two predictors, tried in this order (:func:`first_iterate`):

* **linear extrapolation** (``*CONTROLS EXTRAPOLATION=LINEAR``, the default, as Abaqus does for
  static steps): the last converged increment of the step, scaled to the new time increment.
  Started from the converged state instead, every contact point and material point is in the
  elastic (stick) state of a zero increment, and the slip zone of the previous increment is
  rediscovered one front point per iteration (10-15 iterations an increment on fine meshes,
  cut-backs when the front oscillates); or its variant, **parabolic extrapolation**
  (``EXTRAPOLATION=PARABOLIC``, Abaqus' ``*STEP, EXTRAPOLATION=PARABOLIC``): the quadratic in
  time through the converged displacements at the end of the last two increments of the step
  and now, evaluated at the new time (increments of any lengths); linear while only one
  increment of the step has converged.  Not the default: the slip released behind a moving
  front, which is what the first iterate misses, is no smoother in time (docs/performance.md,
  "A parabolic first iterate");
* **the foundations' translation**, at a step start (nothing to extrapolate) when every
  foundation moves by the same nonzero ``dc`` over the increment: every node translated by
  ``dc``.  Contact, solid and pressure forces are invariant under a common translation of body
  and foundation (exactly in plane strain, and along the axis in axisymmetry), so at
  ``u_old + T`` every group is in its converged state again: the first iteration is the usual
  predictor from the converged state and its tangent (stick where the body stuck), the motion
  entering through the imposed DOFs, which now move by ``u_c - u_old_c - T_c``.  Starting from
  ``u_old`` instead puts a tangential trial ``KT dc`` on every stuck point, all of them slipping
  at once, the whole interface then slipping back and forth over the iterations (the
  Cattaneo-Mindlin stall).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..core.status import SLIP, STICK
from .newton import IterationObserver
from .stabilisation import SLIP_NEG

__all__ = ["first_iterate", "extrapolated", "foundation_shift", "front_holds", "FrontPredictor"]


def first_iterate(u: np.ndarray, last, dt: float, mode: str, ctx,
                  nodal: int | None = None,
                  earlier=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Newton's first iterate and its *predicted* part (the extrapolated displacement, whose
    energy the energy test counts; None when the start is the converged state or its rigid
    translation, which cost no energy).  ``nodal``: the number of nodal DOFs (two per node),
    which come first in ``u`` (default all; the rest, the rotations of reference nodes, are
    not shifted).  ``last``, ``earlier``: the step's last converged increment and the one
    before it, as (du, dt) (:func:`extrapolated`)."""
    ext = extrapolated(u, last, dt, mode, earlier)
    if ext is not None:
        return ext, ext - u
    shift = foundation_shift(ctx, u.size if nodal is None else nodal)
    if shift is not None and shift.size < u.size:
        shift = np.concatenate([shift, np.zeros(u.size - shift.size)])
    return (u + shift if shift is not None else u.copy()), None


def extrapolated(u: np.ndarray, last, dt: float, mode: str, earlier=None) -> np.ndarray | None:
    """The displacement extrapolated to the end of an increment of ``dt``; None with NONE or at
    the start of a step (``last`` None).

    ``last = (du1, dt1)``: the last converged increment of the same step; ``earlier = (du2,
    dt2)``: the one before it (None when ``last`` is the step's first).

    * LINEAR: ``u + (dt / dt1) du1``;
    * PARABOLIC: the quadratic through (-dt1 - dt2, u - du1 - du2), (-dt1, u - du1), (0, u) at
      ``dt``, in Newton's form ``u + (dt / dt1) du1 + dt (dt + dt1) (s1 - s2) / (dt1 + dt2)``
      with the slopes ``s1 = du1 / dt1``, ``s2 = du2 / dt2``: the linear prediction plus the
      curvature of the last two increments; LINEAR when there is no ``earlier``.
    """
    if mode not in ("LINEAR", "PARABOLIC") or last is None or not last[1] > 0:
        return None
    du1, dt1 = last
    linear = u + (dt / dt1) * du1
    if mode == "LINEAR" or earlier is None or not earlier[1] > 0:
        return linear
    du2, dt2 = earlier
    # the second divided difference times dt (dt + dt1): zero on a straight path
    return linear + (du1 / dt1 - du2 / dt2) * (dt * (dt + dt1) / (dt1 + dt2))


def foundation_shift(ctx, ndof: int) -> np.ndarray | None:
    """(ndof,) translation of every node by the foundations' common motion ``dc`` over the
    increment (``ctx.foundation_old/new``, placements (dx, dy) or (dx, dy, theta)), or None
    when they do not all move by the same nonzero ``dc`` without turning."""
    old, new = ctx.foundation_old, ctx.foundation_new
    if not old or not new or set(old) != set(new):
        return None
    steps = [_padded(new[n]) - _padded(old[n]) for n in new]
    dc = steps[0]
    if (not np.any(dc[:2] != 0.0) or dc[2] != 0.0 or any(np.any(s_ != dc) for s_ in steps[1:])
            or ndof % 2):
        return None
    return np.tile(dc[:2], ndof // 2)


def _padded(v) -> np.ndarray:
    """A placement as (dx, dy, theta)."""
    v = np.asarray(v, float).ravel()
    return np.concatenate([v, np.zeros(3 - v.size)]) if v.size < 3 else v


# --------------------------------------------------------------------------------------------
# the slip front, extrapolated

def front_holds(x: np.ndarray, before: np.ndarray, after: np.ndarray, tau: np.ndarray,
                ratio: float) -> np.ndarray | None:
    """Contact statuses to hold at the first evaluation of the next increment: the stick
    points a slip front will pass, extrapolated from how far it went over the last one.

    Parameters
    ----------
    x : (g, 2) reference positions of the contact points of one group.
    before, after : (g,) states (:func:`~.stabilisation.state_codes`: open, stick, slip with
        tau > 0, slip with tau < 0) at the start and at the end of the last converged increment.
    tau : (g,) tangential stress at its end.
    ratio : the next increment's size over the last one's.

    Returns (g,) int8: SLIP for the predicted points, -1 (free) elsewhere; None when no
    front moved over the last increment.

    A point that went from stick to slip in one direction, joined to the points slipping that
    way at the start through such points (:func:`_grown`), advanced that front by its distance
    ``a`` to them; a point still sticking, its
    tau of that direction, is predicted to slip when its distance to the points slipping that
    way now is at most ``ratio * a`` of the advanced point nearest to it: each front moves on
    at its last speed.  Newton's active-set search otherwise finds a moving front one or two
    points per iteration (the stick tangent carries the load beyond the front until the points
    there have slipped): an increment across which a front moves n points took about n / 2
    iterations more than one where it stands.
    """
    x = np.asarray(x, float).reshape(-1, 2)
    before, after, tau = np.asarray(before), np.asarray(after), np.asarray(tau, float).ravel()
    stick = after == STICK
    hold = np.full(x.shape[0], -1, np.int8)
    if not (stick.any() and ratio > 0 and x.shape[0] > 1):
        return None
    reach = 1.5 * _spacing(x)
    for code, sign in ((SLIP, 1.0), (SLIP_NEG, -1.0)):
        then, now = before == code, after == code
        advanced = _grown((before == STICK) & now, then, x, reach)
        ahead = stick & (sign * tau > 0.0)
        if not (advanced.any() and ahead.any()):
            continue
        a = _nearest(x[advanced], x[then])[0]                    # each point's advance
        dist = _nearest(x[ahead], x[now])[0]
        _, front = _nearest(x[ahead], x[advanced])             # the nearest advanced point
        # a front that moved one point (a <= reach) is found at the first iteration anyway:
        # only fronts that moved further are followed (a wrong hold costs iterations)
        moving = a[front] > reach
        hold[np.flatnonzero(ahead)[moving & (dist <= ratio * a[front] * (1.0 + 1e-9))]] = SLIP
    return hold if np.any(hold >= 0) else None


def _grown(new: np.ndarray, old: np.ndarray, x: np.ndarray, reach: float) -> np.ndarray:
    """The points of ``new`` (g,) bool joined to ``old`` by a chain of ``new`` points each within
    ``reach`` of the last: the zone ``old`` grew by them.  A point of ``new`` away from it (a
    slip zone born elsewhere, a single point flipping) advanced no front."""
    grown = np.zeros_like(new)
    if not (new.any() and old.any()):
        return grown
    edge = old.copy()
    while True:
        cand = new & ~grown
        if not cand.any():
            return grown
        near = _nearest(x[cand], x[edge])[0] <= reach
        if not near.any():
            return grown
        idx = np.flatnonzero(cand)[near]
        grown[idx] = True
        edge = np.zeros_like(new)
        edge[idx] = True


def _spacing(x: np.ndarray) -> float:
    """The largest distance from a point of ``x`` (g, 2) to its nearest other point: how far
    apart neighbours along the surface are (the chain's step)."""
    return float(_nearest(x, x, others=True)[0].max())


def _nearest(points: np.ndarray, to: np.ndarray,
             others: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each of ``points`` (n, 2) to the nearest of ``to`` (m, 2), and its index;
    ``others``: ``to`` is ``points`` itself, and each point's nearest *other* point is meant.
    In blocks of rows so that memory stays O(m) per row block."""
    dist, index = np.empty(len(points)), np.empty(len(points), np.int64)
    block = max(1, 2_000_000 // max(len(to), 1))
    for s in range(0, len(points), block):
        d2 = ((points[s:s + block, None, :] - to[None, :, :]) ** 2).sum(axis=2)
        if others:
            d2[np.arange(d2.shape[0]), np.arange(s, s + d2.shape[0])] = np.inf
        index[s:s + block] = np.argmin(d2, axis=1)
        dist[s:s + block] = np.sqrt(d2[np.arange(d2.shape[0]), index[s:s + block]])
    return dist, index


class FrontPredictor(IterationObserver):
    """Holds the predicted slip points (:func:`front_holds`) at the first evaluation of an
    increment only: the first solve then has the tangent and residual of the front where it
    is expected; every later evaluation uses the free law, so a wrong prediction costs the
    iteration that puts those points back in STICK, and the answer is the free law's.

    ``holds``: contact group name -> (g,) int8 (SLIP or -1), the groups with a prediction."""

    held = "predicted slip points"

    def __init__(self, holds: dict[str, np.ndarray]):
        self.holds = {name: h for name, h in holds.items() if h is not None}
        self.holding = bool(self.holds)

    @property
    def active(self) -> bool:
        return self.holding

    def start(self, ctx):
        if not self.holding:
            return ctx
        return dataclasses.replace(ctx, freeze_contact={n: h.copy() for n, h in self.holds.items()})

    def context(self, ctx, states):
        self.holding = False
        return ctx

    def settle(self, ctx, states):
        self.holding = False
        return ctx
