"""Augmented Lagrangian: the loop around Newton (``METHOD=AUGMENTED`` of a contact law).

Uzawa's method, as Abaqus and ANSYS do it: an increment is solved by Newton with the contact
law's multipliers fixed; then each contact law with multipliers (:meth:`ContactLaw.augment`)
sets them from the converged stresses and says how far its constraints are from their
tolerance (the penetration and the elastic stick slip, ``PTOL`` times the face length).  While
one is beyond it, the increment is solved again from the converged displacement with the new
multipliers, at most ``AUGMAX`` solves in all.  The multipliers live in the committed state
(``an``, ``at`` of COULOMB): each solve starts from the committed state of the increment with
the new multipliers put in, so a cut-back goes back to the multipliers of the last committed
increment, and the next increment starts from those of this one (a warm start: along a
monotonic load the first solve is already close).

The cost is the Newton iterations of every solve; each later solve starts at the converged
displacement, so it usually takes 1-3 iterations (docs/accuracy_speed.md measures it).
"""
from __future__ import annotations

import numpy as np

__all__ = ["augmented_start", "augmentation_limit"]


def augmentation_limit(problem, contact: list[int]) -> int:
    """The solves an increment may take: the largest ``augmax`` of the contact laws (1 when
    none has multipliers)."""
    return max([int(problem.groups[k].law.augmax) for k in contact], default=1)


def augmented_start(problem, contact: list[int], started: list[dict],
                    trial: list[dict]) -> tuple[list[dict] | None, float]:
    """The start states of another solve of the increment, or None when every contact law's
    constraints are within tolerance; and the largest violation over its tolerance.

    ``started``: the states the last solve started from (the committed states, with the
    multipliers of earlier augmentations); ``trial``: its converged states; ``contact``: the
    indices of the contact groups (a group within tolerance keeps its multipliers)."""
    start, worst = None, 0.0
    for k in contact:
        grp = problem.groups[k]
        targets, ratio = grp.law.augment(trial[k], grp.point_lengths())
        worst = max(worst, float(ratio))
        if targets is None:
            continue
        if start is None:
            start = list(started)
        state = dict(started[k])
        for key, value in targets.items():
            state[key] = np.asarray(value, float)
        start[k] = state
    return start, worst
