"""The increment sizes of a step, apart from the solver (after EdelweissFE's adaptive time
stepper): grow after an easy increment (not a step's first), cut back on a failure, hold the
size after a hard one, stop when the minimum is reached, and carry their own restart state.

The controller asks :meth:`Stepper.trial` for the size of the next attempt, then either
:meth:`Stepper.accept` (the increment converged) or :meth:`Stepper.cut_back` (it failed; a
failure may ask for its own factor).  :class:`StepExhausted` says why a step cannot go on.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Stepper", "StepExhausted"]


class StepExhausted(Exception):
    """The step cannot go on: the increment fell below the minimum, or INC= is reached."""


@dataclass
class Stepper:
    """Increments of a step of length ``period``.

    ``dt`` is the size the next increment will try (before clipping to the step end), ``t``
    the step time reached, ``inc`` the converged increments.  ``growth`` multiplies ``dt``
    after an increment converged in at most ``easy`` iterations without a cut-back (never
    beyond ``dt_max``), but not after the first increment of a step; ``cutback`` multiplies the
    size of a failed attempt; an attempt below ``dt_min`` (or 1e-14 of the step) ends the step.

    Why not after a step's first increment: it starts without an extrapolated first iterate,
    often at a change of load or contact state (the onset of sliding), and its count is the
    contact-state search, the count that round-off moves most: the main job's onset takes 9
    solves with this machine's NumPy and OpenBLAS, 4 with NumPy's AVX-512 loops switched off or
    OpenBLAS's SandyBridge kernels, 11 with its Prescott ones; when that count decided the
    growth, the slide took other increments there and T mid-slide moved by 0.8 % (`lagamine-py
    compare` against decks/reference/press_slide failed).  Abaqus grows only after two
    consecutive easy increments, which never counts a step's first increment alone either.
    """
    period: float
    dt: float
    dt_min: float
    dt_max: float
    growth: float
    easy: int
    cutback: float
    max_increments: int
    t: float = 0.0
    inc: int = 0
    cutbacks: int = 0              # cut-backs of the increment being attempted
    attempt: float = 0.0           # size of the attempt in progress

    @classmethod
    def start(cls, step, controls, t: float = 0.0, dt: float | None = None, inc: int = 0):
        """The stepper of ``step`` (a :class:`~lagamine_py.model.Step`) with its ``*CONTROLS``
        values, fresh or resumed at ``(t, dt, inc)``."""
        T = float(step.period)
        first = min(step.dt0, step.dt_max, T) if dt is None else dt
        return cls(T, first, step.dt_min, step.dt_max, float(controls["GROWTH"]),
                   int(controls["EASY"]), float(controls["CUTBACK"]), int(step.max_increments),
                   t, inc)

    @property
    def finished(self) -> bool:
        return self.period - self.t <= 1e-12 * self.period

    def trial(self) -> float:
        """The size of the next increment's first attempt (the step end clips it); raises
        :class:`StepExhausted` when the step already took its INC= increments."""
        if self.inc >= self.max_increments:
            raise StepExhausted(f"reached the maximum of {self.max_increments} increments (INC=)")
        self.cutbacks = 0
        self.attempt = min(self.dt, self.period - self.t)
        return self.attempt

    def cut_back(self, factor: float | None = None) -> float:
        """The failed attempt's size times ``factor`` (default the step's CUTBACK): the next
        attempt; raises :class:`StepExhausted` when it falls below the minimum."""
        self.cutbacks += 1
        self.attempt *= factor or self.cutback
        if self.attempt < self.dt_min or self.attempt <= 1e-14 * self.period:   # dt_min may be 0
            raise StepExhausted(f"the time increment fell to {self.attempt:.3g}, below the "
                                f"minimum {self.dt_min:g}, after {self.cutbacks} cut-back(s)")
        return self.attempt

    def accept(self, iterations: int) -> float:
        """The attempt converged in ``iterations``: advance to its end (snapped to the step end
        within round-off) and choose the next size; returns the new step time."""
        self.inc += 1
        end = self.t + self.attempt
        self.t = self.period if self.period - end <= 1e-12 * self.period else end
        self.dt = self.attempt
        # the first increment of a step (inc 1 after the += above) does not grow dt: see the class
        if iterations <= self.easy and self.cutbacks == 0 and self.inc > 1:
            self.dt = min(self.dt * self.growth, self.dt_max)
        return self.t

    def state(self) -> dict:
        """What a restart needs to go on with the same sizes."""
        return {"t": self.t, "dt": self.dt, "inc": self.inc}
