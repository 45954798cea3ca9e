"""Contact stabilisation: Newton observers that hold chattering contact points.

:class:`FlipFlop` watches the contact status of every point over the iterations of one
increment and freezes the points that chatter.  It is an
:class:`~lagamine_py.solver.newton.IterationObserver`: Newton knows nothing of contact, it asks
the observer for the context of each evaluation and, when a solve converged under a changed
context, has the observer settle it against the model's own laws.
"""
from __future__ import annotations

import dataclasses
import logging

import numpy as np

from ..core.errors import ContactNotSettled
from ..core.status import SLIP, STICK
from .newton import IterationObserver

__all__ = ["FlipFlop", "SLIP_NEG", "state_codes"]

log = logging.getLogger("lagamine_py.solver")

SLIP_NEG = 3                 # state code of a point slipping with tau < 0


def state_codes(status, tau, p) -> np.ndarray:
    """(g,) int8 state of each contact point: its status, or :data:`SLIP_NEG` for a point
    slipping with tau < 0.  A slip direction only where tau is not round-off (frictionless
    contact has tau ~ 1e-12 p of either sign: no reversal there)."""
    status = np.asarray(status).ravel()
    tau, p = np.asarray(tau).ravel(), np.asarray(p).ravel()
    return np.where((status == SLIP) & (tau < -1e-9 * np.abs(p)), SLIP_NEG, status).astype(np.int8)


def _slipping(code: np.ndarray) -> np.ndarray:
    """Points of state codes ``code`` slipping either way (two comparisons: ``np.isin`` sorts,
    ~20 us a call on 48 points, at every Newton iteration)."""
    return (code == SLIP) | (code == SLIP_NEG)


class FlipFlop(IterationObserver):
    """Freezes contact points whose state chatters between Newton iterations.

    A point's *state* is its status with the direction of slip: open, stick, slip+ or slip-
    (a point slipping one way at one iteration and the other way at the next has the zero
    tangential stiffness of sliding on both sides of the answer, so Newton jumps over the
    narrow elastic range in between for ever: the status alone does not change).  After
    ``limit`` state changes a point is frozen: in STICK when it has slipped both ways (the
    only state left between the two), else in its current status.  A frozen SLIP point that
    still reverses is re-frozen in STICK.

    Freezing changes the law Newton solves, so a converged increment is accepted only if the
    free law agrees (:meth:`settle`); where it does not, the points concerned take the free
    law's status and Newton goes on, at most ``max_rounds`` times.  Then, ``releases`` times
    per increment, every point is released (counts cleared) and Newton goes on with the free
    law from the iterate reached, which the frozen law has brought next to the answer but for
    the points in dispute; the increment then has ``release_iterations`` iterations from the
    release on, past MAXIT if need be (:meth:`restart_iterations`).  Only increments that would
    have been cut back ("contact status did not settle") take that path.

    ``watched``: group index -> contact group name, the groups whose states are watched.
    ``ctx.freeze_contact`` becomes ``{group_name: (g,) int8}`` with -1 for free points and the
    status to hold otherwise (None while nothing is frozen).
    """

    max_rounds = 2
    releases = 1
    #: iterations a release is granted, counted from its pass, past MAXIT if need be (Abaqus'
    #: I_R for severely discontinuous problems, *CONTROLS, ANALYSIS=DISCONTINUOUS: iterations
    #: before the convergence rate is judged).  The free law from the iterate the frozen law
    #: reached searches the few disputed points' states again, a front of one or two points a
    #: solve: 2 solves at the 320x160 onset of sliding, 7 with the solid kernel's round-off
    #: changed, where MAXIT came first (docs/performance.md, "The onset of sliding, robust")
    release_iterations = 10
    held = "frozen contact points"
    failure = ContactNotSettled

    def __init__(self, watched: dict[int, str], limit: int):
        self.limit = limit
        self.watched = dict(watched)
        self.last: dict[int, np.ndarray] = {}
        self.count: dict[int, np.ndarray] = {}
        self.both_ways: dict[int, np.ndarray] = {}
        self.frozen: dict[int, np.ndarray] = {}
        self.rounds = 0
        self.released = 0
        self.restarted = False       # the last settle released every point

    @property
    def active(self) -> bool:
        return bool(self.frozen)

    def _states(self, states):
        """(group index, status (g,), state code (g,)) of the watched groups: code = status,
        or :data:`SLIP_NEG` for a point slipping with tau < 0."""
        for k in self.watched:
            st = states[k]
            yield k, np.asarray(st["status"]).ravel(), state_codes(st["status"], st["tau"], st["p"])

    def context(self, ctx, states):
        """Update the counts with the states of the last evaluation; the context of the next."""
        for k, status, code in self._states(states):
            if k in self.last and self.last[k].shape == code.shape:
                prev = self.last[k]
                switched = code != prev
                self.count[k] = self.count.get(k, 0) + switched
                reversal = switched & _slipping(code) & _slipping(prev)
                self.both_ways[k] = self.both_ways.get(k, np.zeros(code.shape, bool)) | reversal
                fz = self.frozen.get(k)
                if fz is not None:               # a frozen slipping point that still reverses
                    fz[(fz == SLIP) & reversal] = STICK
                hit = self.count[k] >= self.limit
                if hit.any():
                    fz = self.frozen.setdefault(k, np.full(code.shape, -1, np.int8))
                    newly = hit & (fz < 0)
                    fz[newly] = np.where(self.both_ways[k][newly], STICK, status[newly])
            self.last[k] = code.copy()
        return self._with_frozen(ctx)

    def restart_iterations(self) -> int:
        """:attr:`release_iterations` after a release, else 0."""
        return self.release_iterations if self.restarted else 0

    def switching(self, states) -> bool:
        """Some watched point's state differs from the last evaluation's."""
        return any(k in self.last and self.last[k].shape == code.shape
                   and bool(np.any(code != self.last[k])) for k, _, code in self._states(states))

    def _with_frozen(self, ctx):
        if not self.frozen:
            return ctx
        return dataclasses.replace(ctx, freeze_contact={self.watched[k]: v.copy()
                                                        for k, v in self.frozen.items()})

    def settle(self, ctx, free_states):
        """After a converged solve with frozen points whose free-law evaluation does not converge:
        give the frozen points where the free law disagrees the free law's status (held) and
        return the context for more iterations; once ``max_rounds`` are used up, every point
        released and the increment's own context (``releases`` times), then None."""
        self.rounds += 1
        self.restarted = False
        if self.rounds > self.max_rounds:
            if self.released >= self.releases:
                return None
            self.released += 1
            self.restarted = True
            log.info("      every frozen contact point released: the free law from this iterate")
            self.rounds = 0
            self.count.clear()
            self.both_ways.clear()
            self.frozen.clear()
            return ctx
        for k, status, _ in self._states(free_states):
            fz = self.frozen.get(k)
            if fz is not None:
                wrong = (fz >= 0) & (fz != status)
                fz[wrong] = status[wrong]
        return self._with_frozen(ctx)
