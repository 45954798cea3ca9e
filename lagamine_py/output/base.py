"""What the step controller hands to writers, and the writer interface.

Writers are observers: the controller calls ``start_run`` once, ``start_step`` per step,
``increment`` after every *converged* increment (writers decide themselves about the output
frequency through ``result.write_fields``), ``failed_attempt`` after each cut-back attempt, and
``close`` at the end with the exit status and message.  Every writer flushes what it wrote
before returning, so a killed run loses nothing that converged.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..registry import Param


@dataclass
class ContactPoints:
    """All contact Gauss points of one contact pair (``*CONTACT``), flattened (g,)."""
    name: str                     # "<surface>-><foundation>"
    element: np.ndarray           # (g,) deck id of the solid element owning the face
    face: np.ndarray              # (g,) face number 1..4
    gauss: np.ndarray             # (g,) Gauss point number on the face, 1-based
    x: np.ndarray                 # (g, 2) current position of the point P
    p: np.ndarray
    tau: np.ndarray
    gap: np.ndarray               # signed distance d (> 0 penetration)
    slip: np.ndarray              # accumulated slip
    lam: np.ndarray
    status: np.ndarray            # int8 OPEN/STICK/SLIP (lagamine_py.laws.base)
    P: float                      # total normal force: integral of p over the current surface
    T: float                      # total tangential force: integral of tau
    A: float = float("nan")       # current area (length x thickness, or per radian) of points in contact
    F: np.ndarray | None = None   # (2,) resultant force of the foundation on the body (sum of nodal forces)


@dataclass
class IncrementResult:
    step: int                     # 1-based step number
    step_name: str
    increment: int                # 1-based within the step
    time: float                   # total time at the end of the increment
    step_time: float              # time within the step
    dt: float
    iterations: int
    residual: float               # final relative force residual
    cutbacks: int                 # cut-backs suffered by this increment
    coords0: np.ndarray           # (n, 2) reference coordinates
    u: np.ndarray                 # (n, 2) displacement
    reaction: np.ndarray          # (n, 2) reaction force at constrained DOFs (0 elsewhere)
    reactions_by_set: dict[str, np.ndarray]     # target name -> (2,) summed RF1, RF2
    cells: list[dict[str, Any]]   # per solid group: {"type", "ids", "conn", "stress" (e,q,4) Cauchy,
                                  #   "peeq" (e,q), "nen"}
    contacts: list[ContactPoints] = field(default_factory=list)
    foundations: dict[str, np.ndarray] = field(default_factory=dict)   # name -> (m,2) current points
    write_fields: bool = True     # this increment is due for field output (*OUTPUT FREQUENCY)
    residual_history: list[float] = field(default_factory=list)


class Writer:
    """Base of writer plugins (``lagamine_py.writers``)."""

    params: tuple[Param, ...] = ()

    def __init__(self, outdir: Path, model, **options: Any):
        self.outdir = Path(outdir)
        self.model = model

    def start_run(self) -> None: ...

    def start_step(self, step_number: int, step) -> None: ...

    def increment(self, result: IncrementResult) -> None: ...

    def failed_attempt(self, info: dict[str, Any]) -> None: ...

    def close(self, status: int, message: str) -> None: ...
