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
           "DivergingResidual", "NotANumber", "ContactNotSettled", "GroupFailure",
           "SingularMatrixError"]


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

    def __init__(self, message: str, history: list[float] | None = None,
                 factor: float | None = None):
        super().__init__(message)
        self.history = list(history or [])
        self.factor = factor


class IterationLimit(ConvergenceFailure):
    reason = "iteration limit"


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
    """The reduced tangent is singular.  ``dofs``: global DOFs that look unrestrained;
    ``matrix``: the CSR data of the full tangent when Newton knows it (for a diagnosis of the
    rigid-body modes, :func:`lagamine_py.solver.tools.explain_singular`), else None."""

    reason = "singular matrix"
    matrix: np.ndarray | None = None

    def __init__(self, dofs, detail: str = "", node_ids=None):
        self.dofs = np.asarray(sorted(set(int(d) for d in dofs)), dtype=np.int64)
        self.detail = detail
        super().__init__(self.describe(node_ids))

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
        text = f"the stiffness matrix is singular; unrestrained DOFs ({label}, direction): {what}"
        return text + (f" [{self.detail}]" if self.detail else "")
