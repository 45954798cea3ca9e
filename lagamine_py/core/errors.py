"""The typed failures the step controller reacts to.

Two families, both answered by cutting the increment back (then, when the cut-backs run out, by
stopping cleanly with exit status 3 and every converged increment written):

* :class:`CutbackRequest` -- raised by a law, an element or a foundation that cannot compute
  this increment (a return mapping that fails, a softening snap-back): "try a smaller step".
  ``factor`` (optional) asks for a particular reduction, else the step's ``CUTBACK``.
* :class:`ConvergenceFailure` -- Newton's own verdicts (iteration limit, diverging residual,
  NaN, a group's failure, contact that does not settle), each with the residual history.

:class:`SingularMatrixError` is a linear solver's verdict: the reduced tangent is singular, with
the DOFs that look unrestrained.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CutbackRequest", "ReturnMappingError", "ConvergenceFailure", "IterationLimit",
           "SlowConvergence", "DivergingResidual", "NotANumber", "ContactNotSettled",
           "GroupFailure", "SingularMatrixError"]


class CutbackRequest(ArithmeticError):
    """A plugin asks for a smaller increment.  ``factor`` in (0, 1), or None for the step's
    ``CUTBACK``."""

    def __init__(self, message: str, factor: float | None = None):
        super().__init__(message)
        if factor is not None and not 0.0 < factor < 1.0:
            raise ValueError(f"a cut-back factor must lie in (0, 1), got {factor!r}")
        self.factor = factor


class ReturnMappingError(CutbackRequest):
    """A law could not integrate an increment."""


class ConvergenceFailure(Exception):
    """Base of the typed failures of an increment; ``reason`` is short, ``history`` the
    relative residuals of the attempt, ``factor`` a requested cut-back factor (None: the
    step's)."""

    reason = "failed"
    #: the linear solves the attempt took (set by Newton; None: count ``history``)
    solves: int | None = None

    def __init__(self, message: str, history: list[float] | None = None,
                 factor: float | None = None):
        super().__init__(message)
        self.history = list(history or [])
        self.factor = factor


class IterationLimit(ConvergenceFailure):
    reason = "iteration limit"


class SlowConvergence(ConvergenceFailure):
    """An equilibrium iteration's rate says the residual will not reach the tolerance within
    ``*CONTROLS IC`` more iterations (the early cut-back after ``IR`` iterations)."""
    reason = "slow convergence"


class DivergingResidual(ConvergenceFailure):
    reason = "diverging residual"


class NotANumber(ConvergenceFailure):
    reason = "NaN"


class ContactNotSettled(ConvergenceFailure):
    """Frozen contact points (flip-flop control) disagree with the contact law at convergence."""
    reason = "contact status did not settle"


class GroupFailure(ConvergenceFailure):
    """A group reported a failure (negative Jacobian, return mapping...) or asked for a
    cut-back."""
    reason = "element failure"


class SingularMatrixError(ArithmeticError):
    """The reduced tangent is singular.  ``dofs``: global DOFs that look unrestrained.

    ``span`` ``(smallest, largest)`` nonzero magnitudes of the matrix diagonal, when known:
    beyond :data:`ILL_CONDITIONED_SPAN` between them, a pivot test relative to the largest
    cannot tell an unrestrained DOF from the round-off of eliminating the stiff ones, and the
    message says *ill-conditioned* (a penalty far stiffer than the bodies) instead of blaming
    unrestrained DOFs.  ``matrix``: the CSR data of the full tangent when Newton knows it (for a
    diagnosis of the rigid-body modes, :func:`lagamine_py.solver.tools.explain_singular`), else
    None; ``states``: the groups' trial states at the iterate of that tangent (which contact
    points hold at all: a point that slips there resists no motion along the surface), else
    None."""

    reason = "singular matrix"
    matrix: np.ndarray | None = None
    states: list | None = None

    def __init__(self, dofs, detail: str = "", node_ids=None, span=None):
        self.dofs = np.asarray(sorted(set(int(d) for d in dofs)), dtype=np.int64)
        self.detail = detail
        self.span = None if span is None else (float(span[0]), float(span[1]))
        super().__init__(self.describe(node_ids))

    @property
    def ill_conditioned(self) -> bool:
        lo, hi = self.span or (0.0, 0.0)
        return lo > 0 and hi > ILL_CONDITIONED_SPAN * lo

    def describe(self, node_ids=None, names=None) -> str:
        """Message naming the DOFs as ``node <id> x|y`` (deck ids when ``node_ids`` is given),
        or by ``names`` (one per global DOF: ``node 7 rotation`` for a reference node's)."""
        label = "node" if node_ids is not None or names is not None else "node row"
        listed = []
        for d in self.dofs[:20]:
            if names is not None and int(d) < len(names):
                listed.append(str(names[int(d)]))
                continue
            row, c = divmod(int(d), 2)
            node = int(node_ids[row]) if node_ids is not None and row < len(node_ids) else row
            listed.append(f"node {node} {'xy'[c]}")
        more = f" and {len(self.dofs) - 20} more" if len(self.dofs) > 20 else ""
        what = ", ".join(listed) + more if listed else "(could not tell which)"
        if self.ill_conditioned:
            lo, hi = self.span
            text = (f"the stiffness matrix is ill-conditioned, singular to working precision: "
                    f"its diagonal spans {hi / lo:.2g} (from {lo:.3g} to {hi:.3g}), so its pivots "
                    f"cannot tell an unrestrained DOF from round-off -- a stiffness (a contact "
                    f"penalty KP or KT, a material) far above the rest; smallest pivots at "
                    f"({label}, direction): {what}")
        else:
            text = f"the stiffness matrix is singular; unrestrained DOFs ({label}, direction): {what}"
        return text + (f" [{self.detail}]" if self.detail else "")


#: largest / smallest magnitude of a tangent's diagonal beyond which a singular verdict is put
#: down to ill-conditioning (the pivot tests flag pivots below 1e-12 of the largest diagonal:
#: at a span of 1e8 a healthy DOF keeps 4 digits of margin)
ILL_CONDITIONED_SPAN = 1e8
