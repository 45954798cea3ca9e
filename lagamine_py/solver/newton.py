"""Full Newton-Raphson on one increment, with the assembled (non-symmetric) tangent.

Convergence (tolerances from ``*CONTROLS``, defaults in :mod:`lagamine_py.solver.controls`):

* force: ``|R_f| / max(|F_ext|, |RF|, max_g |f_g|, floor) <= RTOL``, ``R_f`` the residual at the
  free DOFs, ``RF`` the reactions, ``f_g`` each group's assembled force vector (so a body loaded
  by pressure only, or by imposed displacements only, still has a meaningful scale), ``floor`` a
  small fraction of the largest scale of earlier increments (unloading to zero);
* energy: ``|du_f . r_f| <= ETOL * (same at the first iteration)``, ``r_f`` the right-hand side
  that produced ``du_f``.  It is an *alternative* test: it lets an increment whose force scale
  degenerates still converge; as ``energy ~ |R|^2`` it is as strict as the force test.  The
  first iteration's energy is floored, as the force scale is, by a small fraction of the largest
  of earlier increments (``energy_floor``): in an increment where nothing moves a stress-free
  body's forces and energies are all round-off, and round-off compared with round-off never
  converged (a body lifted off its foundation by imposed motions, then held: exit 3).

Divergence: a residual above ``DIVERGED_REL``, or one that grew over three iterations and is
above the first.  With ``*CONTROLS SDI=YES`` (the default) the growth verdict is not given
(until the residual has grown over ``SDI_GROWTH_LIMIT`` iterations running)
while an observer sees its states switching (:meth:`IterationObserver.switching`: contact points
changing state between the last two iterates), as Abaqus does not count its "severe
discontinuity iterations": at the onset of sliding tens of points change state at each of the
first iterations and the residual grows while they find their states (press-then-slide cut
back its first slide increment at every mesh for it).  MAXIT and the blow-up test still bound
the increment; an increment with no state change is judged as before, bit for bit.

The iteration limit: MAXIT, or later when an observer restarts the search after a failed review
(:meth:`IterationObserver.restart_iterations`: the contact stabilisation's release of every
frozen point); past it, the rate rule (:data:`RATE_GRACE`) lets an attempt that converges
without states switching finish.  Before it, the early cut-back (``*CONTROLS IR``, ``IC``,
:func:`_early_cut`): from IR iterations into the attempt or into the round after a failed
review, an equilibrium iteration (no state switched) whose logarithmic rate needs more than IC
further iterations stops the attempt (:class:`SlowConvergence`), as Abaqus' I_R / I_C check.

Linear solves go through :class:`~lagamine_py.solver.reuse.FactorReuse` (``*CONTROLS
KRYLOV``): GMRES on the factor in hand when it converges within a few steps, a new
factorisation otherwise.

Each iteration's norms go to the ``lagamine_py.solver`` logger (quadratic convergence shows
there).  Failures are typed (:class:`IterationLimit`, :class:`SlowConvergence`,
:class:`DivergingResidual`, :class:`NotANumber`, :class:`GroupFailure`, and
``SingularMatrixError`` from
:mod:`~lagamine_py.solver.linear`); the step controller catches them and cuts back.

Imposed DOFs: the first iteration solves ``K_ff du_f = -R_f - K_fc du_c`` with ``du_c`` the
increment of the imposed values, later ones ``K_ff du_f = -R_f`` (``du_c = 0``).

Newton knows no physics.  What a scene needs beyond plain Newton comes in through
:class:`IterationObserver` objects, which may change the context of the next evaluation (the
contact stabilisation of :mod:`lagamine_py.solver.stabilisation` holds chattering points) and
must then settle a converged solve against the increment's own context.  The first iterate is
the caller's (:mod:`lagamine_py.solver.predictor`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import (ConvergenceFailure, DivergingResidual, IterationLimit,  # noqa: F401
                           NotANumber, SingularMatrixError, SlowConvergence)
from ..elements.base import LATER
from .reuse import FactorReuse, forcing

__all__ = ["Settings", "Converged", "IterationObserver", "solve_increment", "FLOOR_FRACTION"]

log = logging.getLogger("lagamine_py.solver")

DIVERGED_REL = 1e10          # a relative residual above this is a blow-up
#: iterations running of a growing residual that SDI does not excuse.  The states' search grew
#: it over at most 4 running in every converged increment of decks/ and of press-then-slide
#: 16x8 ... 320x160 (the 4 at 40x20's onset of sliding), whose paths the limit leaves alone;
#: an attempt that grows on is mostly losing its states, not finding them: the stiff-KT block's
#: |R|/F went from 1e-2 to 1.0 (every contact point open) and took 19 more solves to MAXIT.
#: Not always: a stiff-penalty partial-slip study run had one increment converge after growing
#: over 6 and is now cut back there (80 -> 68 iterations in all); every study run the limit
#: changed got cheaper (docs/performance.md, "A growth limit for SDI")
SDI_GROWTH_LIMIT = 6
#: the iteration limit's rate rule (after Abaqus' logarithmic-rate check, read the other way):
#: at MAXIT, an attempt whose last iteration switched no state and whose residual falls at a
#: rate that reaches RTOL within this many more solves (:func:`_solves_to_go`) goes on, at
#: most this many iterations past MAXIT.  The onset of sliding at 320x160 stood at |R|/F
#: 6.8e-3 -> 1.4e-4 when MAXIT stopped it two solves short (docs/performance.md, "The onset
#: of sliding, robust")
RATE_GRACE = 3
FLOOR_FRACTION = 1e-6        # floor of the force scale, times the largest earlier scale
#: floor of the energy test's reference, times the largest earlier one (energy ~ force^2)
ENERGY_FLOOR_FRACTION = FLOOR_FRACTION ** 2


@dataclass
class Settings:
    rtol: float = 1e-8
    etol: float = 1e-14
    maxit: int = 25
    linesearch: bool = False
    #: severe discontinuity iterations: no growth verdict while observed states switch
    sdi: bool = True
    #: the early cut-back (:func:`_early_cut`): from this many iterations of an attempt
    #: or of a round after a failed review (0: off) ...
    ir: int = 8
    #: ... an equilibrium iteration whose rate needs more than this many iterations cuts back
    ic: int = 10

    @classmethod
    def from_controls(cls, controls: dict[str, Any]) -> "Settings":
        return cls(rtol=float(controls["RTOL"]), etol=float(controls["ETOL"]),
                   maxit=int(controls["MAXIT"]), linesearch=bool(controls["LINESEARCH"]),
                   sdi=bool(controls["SDI"]), ir=int(controls["IR"]), ic=int(controls["IC"]))


class IterationObserver:
    """Watches the iterations of one increment (a new one per increment).

    :meth:`start` gives the context of the first evaluation; :meth:`context` is called after
    every solve with the states of the last evaluation and
    returns the context of the next evaluation (the increment's own, or one that changes the
    problem: held contact points, say).  While the observer is :attr:`active` (it has changed
    the problem), a converged iterate is reviewed with the increment's own context; if that does
    not converge, :meth:`settle` returns the context to iterate on, or None when it gives up,
    and Newton then raises :attr:`failure` (the increment is cut back).  Never is an increment
    accepted that the increment's own context does not converge.
    """

    #: what the observer holds, for the log ("frozen contact points")
    held = "held values"
    #: the failure raised when the observer cannot settle
    failure: type = ConvergenceFailure

    @property
    def active(self) -> bool:
        return False

    def start(self, ctx):
        """The context of the increment's first evaluation (a predicted state held, say)."""
        return ctx

    def context(self, ctx, states):
        return ctx

    def settle(self, ctx, states):
        return None

    def switching(self, states) -> bool:
        """True when ``states`` (the last evaluation's) differ from those :meth:`context` saw
        last in what the observer watches (contact points changing state): a residual that
        grows then is the search for the states, not a divergence."""
        return False

    def restart_iterations(self) -> int:
        """Asked after :meth:`settle`: the iterations Newton grants the context it returned,
        counted from that pass and past MAXIT if need be, when that context restarts the search
        (every held value dropped: the free law from the iterate reached); 0 (the default) for
        a settle that only adjusts what is held."""
        return 0


@dataclass
class Converged:
    u: np.ndarray                  # (ndof,) displacement at convergence
    states: list[dict]             # trial states of the groups at u (to commit)
    f_int: np.ndarray              # (ndof,) assembled internal force at u
    iterations: int                # linear solves performed
    residual: float                # final relative force residual
    scale: float                   # force scale used by the test
    history: list[float] = field(default_factory=list)
    f_ext: np.ndarray | None = None  # set by the step controller: loads of the increment
    ctx: Any = None                  # and its StepContext
    energy_scale: float = 0.0        # the energy test's reference (first iteration), floored
    factorisations: int = 0          # of the tangent, over the solves (FactorReuse)
    back_substitutions: int = 0


def solve_increment(problem, solver, free, u_old: np.ndarray, states: list[dict], ctx,
                    u_c: np.ndarray, f_ext: np.ndarray, settings: Settings,
                    floor: float = 0.0, energy_floor: float = 0.0,
                    u_start: np.ndarray | None = None,
                    predicted: np.ndarray | None = None,
                    observers: tuple[IterationObserver, ...] = (),
                    solves: FactorReuse | None = None) -> Converged:
    """Solve one increment.

    Parameters
    ----------
    problem : object with ``evaluate(u_new, u_old, states, ctx, tangent) -> Evaluation``
        (``f_int`` (ndof,), ``data`` CSR data or None, ``states``, ``scale``) and ``pattern``,
        see :class:`lagamine_py.solver.problem.Problem`.
    solver : LinearSolver plugin instance.
    free : :class:`lagamine_py.solver.linear.FreeDofs` of the constrained set.
    u_old : (ndof,) displacement at the start of the increment.
    states : committed group states at the start of the increment.
    ctx : StepContext of the increment.
    u_c : (c,) imposed values at the end of the increment, at ``free.constrained``.
    f_ext : (ndof,) external nodal forces at the end of the increment.
    floor : absolute floor of the force scale.
    energy_floor : absolute floor of the energy test's reference.
    u_start : (ndof,) first iterate (:func:`lagamine_py.solver.predictor.first_iterate`),
        default ``u_old``.  Its constrained entries are corrected to ``u_c`` by the first
        iteration like any imposed increment.
    predicted : (ndof,) the predicted part of ``u_start``, whose energy the energy test counts
        (see :func:`_predicted_energy`); None: none.
    observers : :class:`IterationObserver` instances watching this increment.
    solves : :class:`~lagamine_py.solver.reuse.FactorReuse` around ``solver`` (the factor kept
        from one solve to the next, GMRES on it); None: ``solver`` factorises every solve.
    """
    solves = solves if solves is not None else FactorReuse(solver)
    f0, b0 = solves.counts()
    s0 = solves.solves
    try:
        conv = _newton(problem, solves, free, u_old, states, ctx, u_c, f_ext, settings, floor,
                       energy_floor, u_start, predicted, observers)
    except ConvergenceFailure as exc:
        exc.solves = solves.solves - s0          # the attempt's iterations
        raise
    conv.factorisations = solves.factorisations - f0
    conv.back_substitutions = solves.back_substitutions - b0
    return conv


def _newton(problem, reuse, free, u_old, states, ctx, u_c, f_ext, settings, floor,
            energy_floor, u_start, predicted, observers) -> Converged:
    """The iterations of :func:`solve_increment`."""

    def done_with(conv: Converged) -> Converged:
        conv.energy_scale = energy0 or 0.0
        return conv

    c = free.constrained
    u = np.array(u_old if u_start is None else u_start, float)
    du_imposed = np.zeros_like(u)
    du_imposed[c] = u_c - u[c]
    imposing = bool(np.any(du_imposed[c] != 0.0))
    watch = _Observers(observers, settings.maxit)
    ctx_k = watch.start(ctx)
    ev = problem.evaluate(u, u_old, states, ctx_k, True)
    history: list[float] = []
    energy0 = None
    du = np.zeros_like(u)      # the correction: one array per increment (fresh pages per solve)
    solves = 0                 # the iteration count: a pass that only reviews solves nothing
    f_ext_norm = float(np.linalg.norm(f_ext))
    k = -1
    while True:
        k += 1
        R = ev.f_int - f_ext
        Rf = R[free.free]
        scale = max(f_ext_norm, float(np.linalg.norm(R[c])), ev.scale, floor, 1e-300)
        rel = float(np.linalg.norm(Rf)) / scale
        history.append(rel)
        if not np.isfinite(rel):
            raise NotANumber(f"non-finite residual at iteration {k}", history)
        if not imposing and rel <= settings.rtol:
            if not watch.active:
                log.info("    iter %2d  |R|/F = %.3e  converged", k, rel)
                return done_with(Converged(u, ev.states, ev.f_int, solves, rel, scale, history))
            ev = None               # not alive through the review's evaluations
            done, ev, ctx_k = _review(problem, watch, u, u_old, states, ctx, f_ext, free,
                                      scale, settings.rtol, history, k, solves)
            if done is not None:
                return done_with(done)
            continue
        if k >= watch.limit and not _rate_grants(history, settings, k, watch.limit, watch,
                                                  ev.states):
            # iterations count the review passes too, which solve nothing; the .sta counts solves
            raise IterationLimit(f"no convergence in {k} iterations ({solves} linear solves, "
                                 f"|R|/F = {rel:.3e})", history)
        # passes counted as residuals (an energy convergence's extra one included, as the review
        # that follows it counts), two at least: a pair of the round
        if settings.ir and len(history) - 1 - watch.since >= max(settings.ir, 2):
            _early_cut(history, settings, k, lambda: watch.switching(ev.states))
        _check_divergence(history, lambda: settings.sdi and watch.switching(ev.states))
        if not _all_finite(ev.data):               # else the solver calls it "singular"
            raise NotANumber(f"non-finite tangent stiffness at iteration {k} (a material or "
                             f"penalty value near the float range overflows?)", history)
        rhs = -Rf - (free.kfc_dot(ev.data, du_imposed) if imposing else 0.0)
        # a solve on the factor in hand stops at a linear residual that leaves the next
        # iterate's residual as it would be (forcing) or below a tenth of the tolerance
        atol = max(forcing(history) * float(np.linalg.norm(rhs)), 0.1 * settings.rtol * scale)
        if energy0 is None:
            predicted_energy = _predicted_energy(problem, ev.data, predicted)
        du_f = _linear_solve(reuse, free, ev, rhs, atol)
        solves += 1
        energy = abs(float(du_f @ rhs))
        log.info("    iter %2d  |R|/F = %.3e  energy = %.3e", k, rel, energy)
        if not _all_finite(du_f, energy):
            raise NotANumber(f"non-finite correction at iteration {k}", history)
        du[free.free] = du_f        # free and constrained DOFs partition du: all of it set
        du[c] = du_imposed[c]
        if energy0 is None:
            energy0 = max(energy, predicted_energy, energy_floor)
        elif energy <= settings.etol * energy0:
            # converged in energy: take this last (tiny) correction, states consistent with it
            u = u + du
            ev = None               # its states freed before the next ones are computed
            ev = problem.evaluate(u, u_old, states, ctx_k, False)
            R = ev.f_int - f_ext
            rel = float(np.linalg.norm(R[free.free])) / scale
            history.append(rel)
            if not watch.active:
                log.info("    iter %2d  |R|/F = %.3e  converged (energy)", k + 1, rel)
                return done_with(Converged(u, ev.states, ev.f_int, solves, rel, scale, history))
            # held values: the increment's own context must give the same (energy-converged)
            # residual
            ev = None
            done, ev, ctx_k = _review(problem, watch, u, u_old, states, ctx, f_ext, free,
                                      scale, max(settings.rtol, rel * (1.0 + 1e-6)), history,
                                      k + 1, solves)
            if done is not None:
                return done_with(done)
            continue
        ctx_k = watch.context(ctx, ev.states)
        if settings.linesearch and not imposing:
            u, ev = _line_search(problem, u, du, u_old, states, ctx_k, f_ext, free, rhs, du_f)
        else:
            u = u + du
            ev = None               # its tangent freed before the next one is computed
            ev = problem.evaluate(u, u_old, states, ctx_k, _tangent_wanted(history, settings.rtol))
        imposing = False
        du_imposed[:] = 0.0


class _Observers:
    """The observers of an increment as one: the context passes through each in turn.
    ``limit``: the iteration limit, MAXIT or later after a restart (:meth:`restart_iterations`,
    moved by :func:`_review`); ``since``: the pass the early cut-back counts IR from (0, or the
    last failed review: a new problem, whose rate starts anew)."""

    def __init__(self, observers, limit: int):
        self.all = tuple(observers)
        self.limit = limit
        self.since = 0          # the pass of the last failed review (the round's start)

    @property
    def active(self) -> bool:
        return any(o.active for o in self.all)

    def start(self, ctx):
        for o in self.all:
            ctx = o.start(ctx)
        return ctx

    def context(self, ctx, states):
        for o in self.all:
            ctx = o.context(ctx, states)
        return ctx

    def settle(self, ctx, states, message, history):
        """The context to iterate on after a failed review; raises the failure of the first
        active observer that gives up."""
        for o in self.all:
            if o.active:
                ctx = o.settle(ctx, states)
                if ctx is None:
                    raise o.failure(message, history)
        return ctx

    def held(self) -> str:
        return " and ".join(o.held for o in self.all if o.active)

    def switching(self, states) -> bool:
        return any(o.switching(states) for o in self.all)

    def restart_iterations(self) -> int:
        return max((o.restart_iterations() for o in self.all), default=0)


def _rate_grants(history: list[float], settings: Settings, k: int, limit: int, watch,
                 states) -> bool:
    """At iteration ``k >= limit`` (MAXIT, or later after a restart): True when Newton may go
    on (the rate rule, :data:`RATE_GRACE`): ``k`` is less than ``limit + RATE_GRACE``, no
    watched state switched over the last solve (an equilibrium iteration, not a search for
    states) and the residual reaches RTOL within ``limit + RATE_GRACE - k`` more solves by
    :func:`_solves_to_go`."""
    room = limit + RATE_GRACE - k
    to_go = _solves_to_go(history, settings.rtol, room) if room > 0 else None
    if to_go is None or watch.switching(states):
        return False
    log.info("    iter %2d  past MAXIT: |R|/F reaches RTOL in %d more solve(s) at its rate", k,
             to_go)
    return True


def _solves_to_go(history: list[float], rtol: float, most: int) -> int | None:
    """How many more solves Newton's quadratic model ``r_k+1 = r_k^3 / r_k-1^2`` (the ratio of
    successive residuals squared at each solve, as :func:`_tangent_wanted` assumes) needs from
    the last two residuals to reach ``rtol``; None when it needs more than ``most`` (always
    when the residual did not fall over the last solve: the model then grows or stalls)."""
    if len(history) < 2 or not history[-2] > 0.0:
        return None
    prev, r = history[-2], history[-1]
    for n in range(1, most + 1):
        prev, r = r, r ** 3 / prev ** 2
        if r <= rtol:
            return n
    return None


def _early_cut(history: list[float], settings: Settings, k: int, switching) -> None:
    """The early cut-back at pass ``k``, IR or more passes into the attempt or round: raises
    :class:`SlowConvergence` when the last solve switched no watched state (``switching()``
    False: an equilibrium iteration, whose rate is Newton's; asked only when the rate fails)
    and :func:`_iterations_to_go` exceeds IC.  Abaqus' time incrementation control does the
    same with I_R = 8 and I_C = 10 (its "logarithmic rate of convergence" check)."""
    to_go = _iterations_to_go(history, settings.rtol)
    if to_go <= settings.ic or switching():
        return
    why = ("did not fall over the last iteration" if not np.isfinite(to_go) else
           f"would reach RTOL in ~{to_go:.0f} more iterations at its rate")
    raise SlowConvergence(f"cut back at iteration {k}: |R|/F = {history[-1]:.3e} {why} "
                          f"(more than IC = {settings.ic}; no contact state switched)", history)


def _iterations_to_go(history: list[float], rtol: float) -> float:
    """Iterations the residual needs to reach ``rtol`` at the logarithmic rate of the last
    iteration, ``log(rtol / r_k) / log(r_k / r_k-1)`` (linear convergence at that ratio: the
    pessimist's count, where :func:`_solves_to_go`'s quadratic model is the optimist's); inf
    when the residual did not fall, 0 when it is at ``rtol`` already or the rate is unknown
    (a zero residual before it)."""
    prev, r = history[-2], history[-1]
    if r <= rtol or not prev > 0.0:
        return 0.0
    if not r < prev:
        return float("inf")
    return float(np.log(rtol / r) / np.log(r / prev))


def _tangent_wanted(history: list[float], rtol: float):
    """True, or ``LATER`` when the next iterate is expected to converge: Newton's quadratic
    model ``r_k+1 = r_k^3 / r_k-1^2`` below ten times the tolerance.  The evaluation then
    computes the forces first and the tangent only if it is read (bit for bit the same:
    :meth:`lagamine_py.solver.problem.Problem.evaluate`), saving the tangent of the evaluation
    Newton converges at; a wrong guess costs a fused kernel's forces twice."""
    if len(history) < 2 or not history[-2] > 0.0:
        return True
    return LATER if history[-1] ** 3 <= 10.0 * rtol * history[-2] ** 2 else True


def _all_finite(a: np.ndarray, dot: float | None = None) -> bool:
    """``np.all(np.isfinite(a))``, exactly, from one dot product in the usual case: ``a . a``
    (or ``dot``, its absolute value, ``a``'s dot product with another vector) is finite only
    if every entry of ``a`` is (a NaN or an infinity, times anything, makes the sum NaN or
    infinite); a non-finite one (an overflow of finite entries too, above 1e154) is settled by
    the entry-wise test.  One read of ``a`` instead of a boolean temporary and its reduction:
    6.7 -> 3.0 ms at 9.6M entries (the tangent at 309k DOFs, every iteration)."""
    if dot is None:
        with np.errstate(over="ignore", invalid="ignore"):
            dot = a @ a
    return bool(np.isfinite(dot)) or bool(np.all(np.isfinite(a)))


def _predicted_energy(problem, data, d: np.ndarray) -> float:
    """``|d . K d|`` for the predicted part ``d`` of the increment (the first iterate minus the
    start, zero without a predictor): the first-iteration energy a start from the converged
    state would have had.  The energy test is relative to the first iteration's energy; with an
    extrapolated first iterate that energy is only the predictor's error (1e-3 of the increment's
    and less), which made the test 1e3 stricter than the force test it backs up: a stiff-penalty
    block whose residual stalled at its round-off floor (4e-8 of F) no longer converged."""
    if data is None or d is None or not np.any(d):
        return 0.0
    return abs(float(d @ (problem.pattern.matrix(data) @ d)))


def _review(problem, watch, u, u_old, states, ctx, f_ext, free, scale, tol, history, k, solves):
    """Acceptance of a solve converged under an observer's context: the increment's own context
    (the free law, without held values) evaluated at ``u`` must satisfy the tolerance too.

    ``k``: the pass (for the log), ``solves``: the linear solves so far (the iterations).
    Returns ``(Converged | None, ev, ctx_k)``: the accepted result, with the free law's states;
    or None with the evaluation and context to iterate on (the observers' :meth:`settle`).
    Raises the observer's failure when it cannot settle."""
    ev = problem.evaluate(u, u_old, states, ctx, True)
    rel = float(np.linalg.norm((ev.f_int - f_ext)[free.free])) / scale
    held = watch.held()
    if rel <= tol:
        history[-1] = rel           # the same iterate u: its residual with the states accepted
        log.info("    iter %2d  |R|/F = %.3e  converged (%s agree with the free law)", k, rel, held)
        return Converged(u, ev.states, ev.f_int, solves, rel, scale, history), ev, ctx
    log.info("    iter %2d  %s disagree with the free law (|R|/F = %.3e)", k, held, rel)
    ctx_k = watch.settle(ctx, ev.states,
                         f"{held} disagree with the free law at convergence (|R|/F = {rel:.3e} "
                         f"with the free law)", history + [rel])
    watch.limit = max(watch.limit, k + watch.restart_iterations())
    watch.since = len(history) - 1          # the review's residual: the round starts there
    ev = None                       # (its tangent and states) not alive through the next one
    return None, problem.evaluate(u, u_old, states, ctx_k, True), ctx_k


def _linear_solve(solves, free, ev, rhs, atol=0.0):
    """Solve ``K_ff du_f = rhs`` (:meth:`FactorReuse.solve`), ``K_ff`` from the tangent of the
    evaluation ``ev``; a singular ``K_ff`` raises SingularMatrixError naming the DOFs (in
    global numbering) that nothing restrains, with the full tangent data as ``matrix`` and the
    iterate's trial states as ``states``.

    The full tangent becomes ``K_ff``: the entries it leaves out (:meth:`FreeDofs.rest`, the
    rows and columns of constrained DOFs: small) are taken, then ``K_ff``'s values are moved
    to the head of the tangent's own array (``kff(in_place=True)``) and ``ev.data`` is set to
    None: no second array of the tangent's size (77 MB at 309k DOFs) beside the solver's factor
    and last ``K_ff``; the diagnosis gets the full data back bit for bit
    (:meth:`FreeDofs.join`)."""
    rest = free.rest(ev.data)
    A = free.kff(ev.data, in_place=True)
    ev.data = None
    try:
        return solves.solve(free, A, rhs, atol)
    except SingularMatrixError as exc:
        solves.forget()
        err = SingularMatrixError(free.free[exc.dofs], exc.detail, span=diagonal_span(A))
        err.matrix = free.join(A.data, rest)  # for the rigid-body diagnosis of the controller
        err.states = ev.states                # the contact states that tangent was formed with
        raise err from None


def diagonal_span(A) -> tuple[float, float]:
    """(smallest, largest) nonzero magnitude of the diagonal of ``A`` (0, 0 when none): how
    a singular verdict is judged (:class:`~lagamine_py.core.errors.SingularMatrixError`)."""
    d = np.abs(A.diagonal())
    d = d[np.isfinite(d) & (d > 0)]
    return (float(d.min()), float(d.max())) if d.size else (0.0, 0.0)


def _check_divergence(history: list[float], excused=lambda: False) -> None:
    """A blow-up, or a residual above the first grown over three iterations running unless
    ``excused()`` (asked only then: the states switching, see SDI), or over
    :data:`SDI_GROWTH_LIMIT` iterations running, excused or not, raises."""
    rel = history[-1]
    if rel > DIVERGED_REL:
        raise DivergingResidual(f"residual blew up (|R|/F = {rel:.3e})", history)
    grown = _growth_run(history)
    if len(history) >= 5 and grown >= 3 and rel > history[0] \
            and (grown >= SDI_GROWTH_LIMIT or not excused()):
        raise DivergingResidual(f"residual grew over {grown} iterations (|R|/F = {rel:.3e})",
                                history)


def _growth_run(history: list[float]) -> int:
    """How many iterations running, up to the last, the residual grew."""
    n = 0
    while n + 1 < len(history) and history[-1 - n] > history[-2 - n]:
        n += 1
    return n


def _line_search(problem, u, du, u_old, states, ctx, f_ext, free, rhs, du_f, tries: int = 5):
    """Backtracking on the energy ``g(s) = du_f . R_f(u + s du)``: accept when
    ``|g(s)| <= 0.8 |g(0)|``, else interpolate the zero of g (clamped to [0.1, 0.5] s)."""
    g0 = -float(du_f @ rhs)               # du_f . R_f(u)
    ev = problem.evaluate(u + du, u_old, states, ctx, True)
    g = float(du_f @ (ev.f_int - f_ext)[free.free])
    s = 1.0
    for _ in range(tries):
        if not np.isfinite(g) or abs(g) > 0.8 * abs(g0):
            s_new = s * g0 / (g0 - g) if np.isfinite(g) and g0 != g else 0.5 * s
            s = float(np.clip(s_new, 0.1 * s, 0.5 * s))
            ev = problem.evaluate(u + s * du, u_old, states, ctx, False)
            g = float(du_f @ (ev.f_int - f_ext)[free.free])
            log.info("      line search s = %.3f", s)
        else:
            break
    if s != 1.0:
        ev = problem.evaluate(u + s * du, u_old, states, ctx, True)
    return u + s * du, ev
