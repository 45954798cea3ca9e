"""The writer contract: what the step controller hands to writers, and when.

Writers are observers.  The controller builds the run's writers -- those the steps' ``*OUTPUT,
WRITERS=`` name (by default :data:`lagamine_py.output.DEFAULT_WRITERS`), and every writer whose
class says :attr:`Writer.always` -- and calls, in this order:

* ``start_run()`` once;
* ``initial(result)`` once, with the state at t = 0 (step 1, increment 0), when the run starts
  from the beginning (not when it resumes);
* ``start_step(step_number, step)`` at the start of every step (``step`` is the
  :class:`~lagamine_py.model.Step`, with its ``output`` request);
* ``increment(result)`` after every *converged* increment of the steps whose ``*OUTPUT`` names
  the writer (a writer decides itself about the field-output frequency through
  ``result.write_fields``);
* ``failed_attempt(attempt)`` after each failed attempt (the increment is then cut back);
* ``close(status, message)`` once at the end, with the exit status and the message, whatever
  happened.

Every writer flushes what it wrote before returning from a hook, so a killed run loses nothing
that converged (the controller saves the restart point *after* the writers took the increment:
what a writer holds back past that point -- a step's last state kept for the end of the step --
a kill loses for good, so write it when ``result.step_end`` says the step is done) (``lagamine-py plugins --check`` replays a real run into a writer and checks that
no file it opened through ``open`` holds unflushed data after any hook).  Resuming a run (``lagamine-py run --restart``), writers are built with
``append=True``: they keep what is in the output directory and drop what the interrupted run
wrote at or after the first resumed increment.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import numpy as np

from ..core.plugin import Plugin
from ..elements.base import CellBlock, ContactPoints

__all__ = ["Writer", "IncrementResult", "FailedAttempt", "CellBlock", "ContactPoints", "ToolState"]


@dataclass
class ToolState:
    """A rigid tool (a foundation) at a converged increment: its placement ``(dx, dy, theta)``
    (the translation of its reference point and its rotation about it, counter-clockwise), the
    reference point now ``point`` (2,), and the force (2,) and moment (about ``point``) it
    exerts on the bodies -- at equilibrium the reactions of its reference node.  ``ref_node``
    the node id of its reference node (None for a tool moved by ``*FOUNDATION MOTION``)."""
    name: str
    ref_node: int | None
    placement: np.ndarray
    point: np.ndarray
    force: np.ndarray
    moment: float


@dataclass
class IncrementResult:
    step: int                     # 1-based step number
    step_name: str
    increment: int                # 1-based within the step
    time: float                   # total time at the end of the increment (rounded: see
                                  # lagamine_py.solver.steps.round_time)
    step_time: float              # time within the step
    dt: float
    iterations: int
    residual: float               # final relative force residual
    cutbacks: int                 # cut-backs suffered by this increment
    coords0: np.ndarray           # (n, 2) reference coordinates
    u: np.ndarray                 # (n, 2) displacement
    reaction: np.ndarray          # (n, 2) reaction force at constrained DOFs (0 elsewhere)
    reactions_by_set: dict[str, np.ndarray]     # target name -> (3,) summed RF1, RF2, RM6
    cells: list[CellBlock]        # one per solid group: topology, ids, conn, Gauss stress and PEEQ
    contacts: list[ContactPoints] = field(default_factory=list)
    foundations: dict[str, np.ndarray] = field(default_factory=dict)   # name -> (m,2) current points
    write_fields: bool = True     # this increment is due for field output (*OUTPUT FREQUENCY)
    step_end: bool = False        # the last increment of its step (the step time reached)
    residual_history: list[float] = field(default_factory=list)
    loads: dict[str, float] = field(default_factory=dict)   # the step's loads reached: label -> value
    tools: dict[str, ToolState] = field(default_factory=dict)   # foundation name -> its state
    # the energy balance since t = 0 (lagamine_py.solver.energy.TERMS), when the run tracks it
    energy: dict[str, float] = field(default_factory=dict)


@dataclass
class FailedAttempt:
    """One failed attempt of an increment (the controller then cuts back and tries again)."""
    step: int
    step_name: str
    increment: int                # the increment being attempted (1-based within the step)
    time: float                   # total time at the start of the attempt
    step_time: float
    dt: float                     # the time increment attempted
    reason: str                   # short ("iteration limit", "singular matrix" ...)
    message: str                  # the full text
    iterations: int
    residual_history: list[float]
    cutbacks: int                 # cut-backs of this increment so far, this one included


class Writer(Plugin):
    """Base of writer plugins (entry-point group ``lagamine_py.writers``); see the module
    docstring for the hooks.  Every hook has a do-nothing default: write the ones you need.

    Parameters: ``outdir`` the run's output directory; ``model`` the
    :class:`~lagamine_py.model.Model` (its ``name`` is the deck's stem); ``append`` resume into
    what is there (a restart).
    """

    #: every run gets this writer, whatever ``*OUTPUT, WRITERS=`` says (the status file and the
    #: log are how a run reports what happened)
    always: bool = False
    append: bool = False

    def __init__(self, outdir: Path, model, append: bool = False):
        self.outdir = Path(outdir)
        self.model = model
        self.append = bool(append)

    def start_run(self) -> None: ...

    def initial(self, result: "IncrementResult") -> None: ...

    def start_step(self, step_number: int, step) -> None: ...

    def increment(self, result: IncrementResult) -> None: ...

    def failed_attempt(self, attempt: FailedAttempt) -> None: ...

    def close(self, status: int, message: str) -> None: ...

