"""``*CHECK, TYPE=ENERGY``: the energy balance of a run at every step end.

The run keeps the balance when its deck has this check (:mod:`lagamine_py.solver.energy`) and
writes ``energy.csv``; the check reads it back at the last increment of every step:

    work = elastic + plastic + friction + penalty + stabilisation

(the work of the loads, reactions, pressures and tools; the energy stored in the bodies, that
their laws dissipated, the frictional dissipation, the energy in the contact springs, and what
the contact stabilisation dissipated).  ``measured`` holds the terms of every step end
(``<term>_<step>``) and the share of the work the stabilisation took; ``errors`` the relative
balance error ``|balance| / |work|`` per step (``step<k>``); the headline ``error`` is the
largest.  The run's log says the same at every step end.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..results import RunResults
from .base import Check, CheckError, result, table

__all__ = ["EnergyBalance"]

_TERMS = ("work", "elastic", "plastic", "friction", "penalty", "stabilisation", "balance")


class EnergyBalance(Check):
    """Energy balance at every step end: work = stored + dissipated."""

    params = ()

    def evaluate(self, run: RunResults) -> dict[str, Any]:
        tab = table(run, "energy.csv", ("step", "increment") + _TERMS)
        steps = np.asarray(tab["step"], int)
        measured, closed, errors = {}, {}, {}
        for k in np.unique(steps):
            last = np.flatnonzero(steps == k)[-1]
            terms = {t: float(tab[t][last]) for t in _TERMS}
            work = terms["work"]
            held = sum(terms[t] for t in _TERMS[1:-1])
            scale = max(abs(work), abs(held))
            if not scale > 0:
                raise CheckError(f"step {k}: no work done and nothing stored: nothing to balance")
            for t, v in terms.items():
                measured[f"{t}_{k}"] = v
            measured[f"stabilisation_share_{k}"] = terms["stabilisation"] / scale
            closed[f"work_{k}"] = held
            errors[f"step{k}"] = abs(work - held) / scale
        return result(measured, closed, errors)
