"""The first iterate of an increment: where Newton starts.

Two predictors, tried in this order (:func:`first_iterate`):

* **linear extrapolation** (``*CONTROLS EXTRAPOLATION=LINEAR``, the default, as Abaqus does for
  static steps): the last converged increment of the step, scaled to the new time increment.
  Started from the converged state instead, every contact point and material point is in the
  elastic (stick) state of a zero increment, and the slip zone of the previous increment is
  rediscovered one front point per iteration (10-15 iterations an increment on fine meshes,
  cut-backs when the front oscillates);
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

import numpy as np

__all__ = ["first_iterate", "extrapolated", "foundation_shift"]


def first_iterate(u: np.ndarray, last, dt: float, mode: str, ctx,
                  nodal: int | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Newton's first iterate and its *predicted* part (the extrapolated displacement, whose
    energy the energy test counts; None when the start is the converged state or its rigid
    translation, which cost no energy).  ``nodal``: the number of nodal DOFs (two per node),
    which come first in ``u`` (default all; the rest, the rotations of reference nodes, are
    not shifted)."""
    ext = extrapolated(u, last, dt, mode)
    if ext is not None:
        return ext, ext - u
    shift = foundation_shift(ctx, u.size if nodal is None else nodal)
    if shift is not None and shift.size < u.size:
        shift = np.concatenate([shift, np.zeros(u.size - shift.size)])
    return (u + shift if shift is not None else u.copy()), None


def extrapolated(u: np.ndarray, last, dt: float, mode: str) -> np.ndarray | None:
    """``u + (dt / dt_last) du_last`` (LINEAR), from the last converged increment
    ``last = (du_last, dt_last)`` of the same step; None with NONE or at the start of a step."""
    if mode != "LINEAR" or last is None or not last[1] > 0:
        return None
    du, dt_last = last
    return u + (dt / dt_last) * du


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
