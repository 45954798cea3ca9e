"""Newton and step-controller settings a deck can give with ``*CONTROLS`` (inside a step)."""
from __future__ import annotations

from ..registry import Param

CONTROL_PARAMS: tuple[Param, ...] = (
    Param("RTOL", float, 1e-8, (0, 1), doc="relative force residual tolerance |R| / max(|F|, |RF|, floor)"),
    Param("ETOL", float, 1e-14, (0, 1), doc="relative energy tolerance |du.R| / first-iteration energy"),
    Param("MAXIT", int, 25, (1, 1000), doc="Newton iterations before the increment is cut back"),
    Param("CUTBACK", float, 0.25, (0.01, 0.9), doc="factor applied to dt on a cut-back"),
    Param("GROWTH", float, 1.5, (1.0, 10.0), doc="factor applied to dt after an easy increment"),
    Param("EASY", int, 5, (1, 1000), doc="an increment converged in at most this many iterations is easy"),
    Param("LINESEARCH", bool, False, doc="backtracking line search on the energy"),
    Param("SOLVER", str, "AUTO", choices=("AUTO", "SPLU", "PARDISO"), doc="sparse linear solver"),
    Param("KERNEL", str, "AUTO", choices=("AUTO", "NUMPY", "NUMBA"),
          doc="solid elements: fused numba kernel (NUMBA, needs the fast extra), NumPy (NUMPY), "
              "or numba from 2000 solid elements when installed and the law is built in (AUTO)"),
    Param("EXTRAPOLATION", str, "LINEAR", choices=("LINEAR", "NONE"),
          doc="first iterate of an increment: the last increment of the step, scaled (LINEAR), or none"),
    Param("FLIPFLOP", int, 4, (1, 100), doc="contact status switches or slip reversals of a point before it is frozen"),
)
