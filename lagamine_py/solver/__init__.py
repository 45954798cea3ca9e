"""The solver: model -> groups and sparsity pattern -> steps -> Newton -> sparse LU.

``run(model, outdir, writers=None, restart=False, deck_path=None, progress=False) -> Outcome``
is the entry point; see :mod:`.steps`.
"""
from .problem import Problem, build_problem
from .restart import RestartError, restart_deck
from .steps import Outcome, run

__all__ = ["run", "Outcome", "build_problem", "Problem", "restart_deck", "RestartError"]
