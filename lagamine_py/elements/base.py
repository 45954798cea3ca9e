"""The interface every element group follows (solid elements, contact elements, edge loads).

A *group* holds many elements of one kind and computes them all at once, batched over
elements x Gauss points (axes ``e``, ``q``; see ``lagamine_py.laws.base`` for the letters).
The solver never loops over elements: it asks each group for ``(f, K)`` arrays and scatters
them into a sparse matrix whose pattern was built once from ``group.dofs``.

Residual convention: ``R(u) = sum_groups f_group(u) - f_external = 0`` where a group's ``f`` is
its contribution to the *internal* side (a solid's internal force, a contact element's contact
force as in the paper's virtual work; a pressure load contributes ``-f_pressure``), and ``K`` is
``dR/du`` of that contribution (so the global tangent is the plain sum).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class StepContext:
    """What a group needs to know about the increment being solved."""
    nlgeom: bool = False
    t_old: float = 0.0              # total time at the start of the increment
    t_new: float = 0.0              # total time at its end
    load_factor: float = 1.0        # scaling of group-held loads (pressure groups), value at t_new
    foundation_old: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (2,) translation at t_old
    foundation_new: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (2,) translation at t_new
    freeze_contact: Any = None      # None, or per-contact-group status arrays to hold fixed
    extras: dict[str, Any] = field(default_factory=dict)


@dataclass
class GroupResult:
    """``f`` (e, nd) and ``K`` (e, nd, nd) (None when not asked); ``state`` the trial state
    (committed by the solver only when the increment converges); ``failure`` a message when
    the group could not compute (negative Jacobian, return mapping failed): the step
    controller then cuts back."""
    f: np.ndarray
    K: np.ndarray | None
    state: dict[str, np.ndarray]
    failure: str | None = None


class Group:
    """Base of element groups.  ``dofs`` (e, nd) global DOF numbers, fixed for the run."""

    dofs: np.ndarray
    ids: np.ndarray          # (e,) deck element ids (for messages and output)

    def init_state(self) -> dict[str, np.ndarray]:
        return {}

    def compute(self, u_new: np.ndarray, u_old: np.ndarray, state: dict[str, np.ndarray],
                ctx: StepContext, tangent: bool = True) -> GroupResult:
        """``u_new``/``u_old``: global nodal displacements (n, 2) at the end / start of the
        increment.  ``state``: committed state at the start of the increment."""
        raise NotImplementedError
