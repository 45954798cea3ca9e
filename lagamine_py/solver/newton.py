"""Full Newton-Raphson on one increment, with the assembled (non-symmetric) tangent.

Convergence (tolerances from ``*CONTROLS``, defaults in :mod:`lagamine_py.solver.controls`):

* force: ``|R_f| / max(|F_ext|, |RF|, max_g |f_g|, floor) <= RTOL``, ``R_f`` the residual at the
  free DOFs, ``RF`` the reactions, ``f_g`` each group's assembled force vector (so a body loaded
  by pressure only, or by imposed displacements only, still has a meaningful scale), ``floor`` a
  small fraction of the largest scale of earlier increments (unloading to zero);
* energy: ``|du_f . r_f| <= ETOL * (same at the first iteration)``, ``r_f`` the right-hand side
  that produced ``du_f``.  It is an *alternative* test: it lets an increment whose force scale
  degenerates still converge; as ``energy ~ |R|^2`` it is as strict as the force test.

Each iteration's norms go to the ``lagamine_py.solver`` logger (quadratic convergence shows
there).  Failures are typed (:class:`IterationLimit`, :class:`DivergingResidual`,
:class:`NotANumber`, :class:`GroupFailure`, and ``SingularMatrixError`` from
:mod:`~lagamine_py.solver.linear`); the step controller catches them and cuts back.

Imposed DOFs: the first iteration solves ``K_ff du_f = -R_f - K_fc du_c`` with ``du_c`` the
increment of the imposed values, later ones ``K_ff du_f = -R_f`` (``du_c = 0``).
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import (ContactNotSettled, ConvergenceFailure, DivergingResidual,  # noqa: F401
                           GroupFailure, IterationLimit, NotANumber, SingularMatrixError)
from ..core.status import SLIP, STICK

log = logging.getLogger("lagamine_py.solver")

DIVERGED_REL = 1e10          # a relative residual above this is a blow-up
FLOOR_FRACTION = 1e-6        # floor of the force scale, times the largest earlier scale
_SLIP_NEG = 3                # flip-flop state code of a point slipping with tau < 0


@dataclass
class Settings:
    rtol: float = 1e-8
    etol: float = 1e-14
    maxit: int = 25
    linesearch: bool = False
    flipflop: int = 4

    @classmethod
    def from_controls(cls, controls: dict[str, Any]) -> "Settings":
        return cls(rtol=float(controls["RTOL"]), etol=float(controls["ETOL"]),
                   maxit=int(controls["MAXIT"]), linesearch=bool(controls["LINESEARCH"]),
                   flipflop=int(controls["FLIPFLOP"]))


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


def solve_increment(problem, solver, free, u_old: np.ndarray, states: list[dict], ctx,
                    u_c: np.ndarray, f_ext: np.ndarray, settings: Settings,
                    floor: float = 0.0, u_start: np.ndarray | None = None) -> Converged:
    """Solve one increment.

    Parameters
    ----------
    problem : object with ``evaluate(u_new, u_old, states, ctx, tangent) -> Evaluation``
        (``f_int`` (ndof,), ``data`` CSR data or None, ``states``, ``scale``), see
        :class:`lagamine_py.solver.problem.Problem`.
    solver : LinearSolver plugin instance.
    free : :class:`lagamine_py.solver.linear.FreeDofs` of the constrained set.
    u_old : (ndof,) displacement at the start of the increment.
    states : committed group states at the start of the increment.
    ctx : StepContext of the increment.
    u_c : (c,) imposed values at the end of the increment, at ``free.constrained``.
    f_ext : (ndof,) external nodal forces at the end of the increment.
    floor : absolute floor of the force scale.
    u_start : (ndof,) first iterate (the step controller's extrapolation), default ``u_old``
        (translated with a moving foundation, see :func:`_foundation_shift`).  Its constrained
        entries are corrected to ``u_c`` by the first iteration like any imposed increment.
    """
    c = free.constrained
    u = np.array(u_old if u_start is None else u_start, float)
    shift = _foundation_shift(ctx, u.size) if u_start is None else None
    if shift is not None:
        u += shift        # start translated with a moving foundation (see _foundation_shift)
    predicted = u - u_old if u_start is not None else None     # the extrapolated part
    du_imposed = np.zeros_like(u)
    du_imposed[c] = u_c - u[c]
    imposing = bool(np.any(du_imposed[c] != 0.0))
    tracker = _FlipFlop(problem, settings.flipflop)
    ctx_k = ctx
    ev = problem.evaluate(u, u_old, states, ctx_k, True)
    history: list[float] = []
    energy0 = None
    for k in range(settings.maxit + 1):
        R = ev.f_int - f_ext
        Rf = R[free.free]
        scale = max(float(np.linalg.norm(f_ext)), float(np.linalg.norm(R[c])), ev.scale, floor,
                    1e-300)
        rel = float(np.linalg.norm(Rf)) / scale
        history.append(rel)
        if not np.isfinite(rel):
            raise NotANumber(f"non-finite residual at iteration {k}", history)
        if not imposing and rel <= settings.rtol:
            if not tracker.active:
                log.info("    iter %2d  |R|/F = %.3e  converged", k, rel)
                return Converged(u, ev.states, ev.f_int, k, rel, scale, history)
            done, ev, ctx_k = _unfrozen(problem, tracker, u, u_old, states, ctx, f_ext, free,
                                        scale, settings.rtol, history, k)
            if done is not None:
                return done
            continue
        if k == settings.maxit:
            raise IterationLimit(f"no convergence in {settings.maxit} iterations "
                                 f"(|R|/F = {rel:.3e})", history)
        _check_divergence(history)
        rhs = -Rf - (free.kfc_dot(ev.data, du_imposed) if imposing else 0.0)
        du_f = _linear_solve(solver, free, ev.data, rhs)
        energy = abs(float(du_f @ rhs))
        log.info("    iter %2d  |R|/F = %.3e  energy = %.3e", k, rel, energy)
        if not np.all(np.isfinite(du_f)):
            raise NotANumber(f"non-finite correction at iteration {k}", history)
        du = np.zeros_like(u)
        du[free.free] = du_f
        du[c] = du_imposed[c]
        if energy0 is None:
            energy0 = max(energy, _predicted_energy(problem, ev.data, predicted))
        elif energy <= settings.etol * energy0:
            # converged in energy: take this last (tiny) correction, states consistent with it
            u = u + du
            ev = problem.evaluate(u, u_old, states, ctx_k, False)
            R = ev.f_int - f_ext
            rel = float(np.linalg.norm(R[free.free])) / scale
            history.append(rel)
            if not tracker.active:
                log.info("    iter %2d  |R|/F = %.3e  converged (energy)", k + 1, rel)
                return Converged(u, ev.states, ev.f_int, k + 1, rel, scale, history)
            # frozen points: the free law must give the same (energy-converged) residual
            done, ev, ctx_k = _unfrozen(problem, tracker, u, u_old, states, ctx, f_ext, free,
                                        scale, max(settings.rtol, rel * (1.0 + 1e-6)), history,
                                        k + 1)
            if done is not None:
                return done
            continue
        ctx_k = tracker.context(ctx, ev.states)
        if settings.linesearch and not imposing:
            u, ev = _line_search(problem, u, du, u_old, states, ctx_k, f_ext, free, rhs, du_f)
        else:
            u = u + du
            ev = problem.evaluate(u, u_old, states, ctx_k, True)
        imposing = False
        du_imposed[:] = 0.0
    # a solve that converged with frozen points on the last allowed iteration, whose free-law
    # check asked for more iterations
    raise IterationLimit(f"no convergence in {settings.maxit} iterations (|R|/F = {history[-1]:.3e})",
                         history)


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


def _foundation_shift(ctx, ndof: int) -> np.ndarray | None:
    """(ndof,) rigid translation ``T`` of every node by the foundations' motion over the
    increment, when they all move by the same nonzero ``dc`` (else None): the first iterate.

    Contact, solid and pressure forces are invariant under a common translation of body and
    foundation (exactly in plane strain, and along the axis in axisymmetry), so at
    ``u_old + T`` every group is in its converged state again: the first iteration is the
    usual predictor from the converged state and its tangent (stick where the body stuck),
    the motion entering through the imposed DOFs, which now move by ``u_c - u_old_c - T_c``.
    Starting from ``u_old`` instead puts a tangential trial ``KT dc`` on every stuck point,
    all of them slipping at once, the whole interface then slipping back and forth over the
    iterations (the Cattaneo-Mindlin stall)."""
    old, new = getattr(ctx, "foundation_old", None), getattr(ctx, "foundation_new", None)
    if not old or not new or set(old) != set(new):
        return None
    steps = [np.asarray(new[n], float) - np.asarray(old[n], float) for n in new]
    dc = steps[0]
    if not np.any(dc != 0.0) or any(np.any(s_ != dc) for s_ in steps[1:]) or ndof % 2:
        return None
    return np.tile(dc, ndof // 2)


def _unfrozen(problem, tracker, u, u_old, states, ctx, f_ext, free, scale, tol, history, k):
    """Acceptance of a solve converged with frozen contact points: the free law (no freezing)
    evaluated at ``u`` must satisfy the tolerance too, else the frozen status was wrong.

    Returns ``(Converged | None, ev, ctx_k)``: the accepted result, with the free law's states;
    or None with the evaluation and context to iterate on (the disagreeing points held in the
    free law's status, :meth:`_FlipFlop.settle`).  Raises :class:`ContactNotSettled` when the
    contact state cannot settle."""
    ev = problem.evaluate(u, u_old, states, ctx, True)
    rel = float(np.linalg.norm((ev.f_int - f_ext)[free.free])) / scale
    if rel <= tol:
        history[-1] = rel           # the same iterate u: its residual with the states accepted
        log.info("    iter %2d  |R|/F = %.3e  converged (frozen contact points agree with the "
                 "free law)", k, rel)
        return Converged(u, ev.states, ev.f_int, k, rel, scale, history), ev, ctx
    log.info("    iter %2d  frozen contact points disagree with the free law (|R|/F = %.3e)",
             k, rel)
    ctx_k = tracker.settle(ctx, ev.states)
    if ctx_k is None:
        raise ContactNotSettled(f"the contact status did not settle: frozen points disagree with "
                                f"the law at convergence (|R|/F = {rel:.3e} with the free law)",
                                history + [rel])
    return None, problem.evaluate(u, u_old, states, ctx_k, True), ctx_k


def _linear_solve(solver, free, data, rhs):
    """Solve ``K_ff du_f = rhs``; a singular ``K_ff`` raises SingularMatrixError naming the DOFs
    (in global numbering) that nothing restrains."""
    A = free.kff(data)
    try:
        solver.factor(A)
    except SingularMatrixError as exc:
        raise SingularMatrixError(free.free[exc.dofs], exc.detail) from None
    return solver.solve(rhs)


def _check_divergence(history: list[float]) -> None:
    rel = history[-1]
    if rel > DIVERGED_REL:
        raise DivergingResidual(f"residual blew up (|R|/F = {rel:.3e})", history)
    if len(history) >= 5 and all(history[-i] > history[-i - 1] for i in (1, 2, 3)) \
            and rel > history[0]:
        raise DivergingResidual(f"residual grew over 3 iterations (|R|/F = {rel:.3e})", history)


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


class _FlipFlop:
    """Watches the contact status of every point over the iterations of one increment and
    freezes the points that chatter.

    A point's *state* is its status with the direction of slip: open, stick, slip+ or slip-
    (a point slipping one way at one iteration and the other way at the next has the zero
    tangential stiffness of sliding on both sides of the answer, so Newton jumps over the
    narrow elastic range in between for ever: the status alone does not change).  After
    ``limit`` state changes a point is frozen: in STICK when it has slipped both ways (the
    only state left between the two), else in its current status.  A frozen SLIP point that
    still reverses is re-frozen in STICK.

    Freezing changes the law Newton solves, so a converged increment is accepted only if the
    free law agrees (:meth:`settle`); where it does not, the points concerned take the free
    law's status and Newton goes on, at most ``max_rounds`` times.

    ``ctx.freeze_contact`` becomes ``{group_name: (g,) int8}`` with -1 for free points and the
    status to hold otherwise (None while nothing is frozen)."""

    max_rounds = 2

    def __init__(self, problem, limit: int):
        self.limit = limit
        self.names = getattr(problem, "group_names", None)
        kinds = getattr(problem, "kinds", None)
        self.watched = None if kinds is None else {k for k, kd in enumerate(kinds) if kd == "contact"}
        self.last: dict[int, np.ndarray] = {}
        self.count: dict[int, np.ndarray] = {}
        self.both_ways: dict[int, np.ndarray] = {}
        self.frozen: dict[int, np.ndarray] = {}
        self.rounds = 0

    @property
    def active(self) -> bool:
        return bool(self.frozen)

    def _states(self, states):
        """(group index, status (g,), state code (g,)) of the watched groups: code = status,
        or ``_SLIP_NEG`` for a point slipping with tau < 0."""
        for k, st in enumerate(states):
            if self.watched is not None and k not in self.watched:
                continue
            status = st.get("status") if isinstance(st, dict) else None
            if status is None:
                continue
            status = np.asarray(status).ravel()
            tau, p = st.get("tau"), st.get("p")
            code = status.astype(np.int8)
            if tau is not None and np.shape(tau) == status.shape:
                # a slip direction only where tau is not round-off (frictionless contact has
                # tau ~ 1e-12 p of either sign: no reversal to freeze there)
                floor = 1e-9 * np.abs(np.asarray(p).ravel()) if p is not None else 0.0
                code = np.where((status == SLIP) & (np.asarray(tau).ravel() < -floor), _SLIP_NEG, code)
            yield k, status, code.astype(np.int8)

    def context(self, ctx, states):
        """Update the counts with the states of the last evaluation; the context of the next."""
        for k, status, code in self._states(states):
            if k in self.last and self.last[k].shape == code.shape:
                prev = self.last[k]
                switched = code != prev
                self.count[k] = self.count.get(k, 0) + switched
                reversal = switched & np.isin(code, (SLIP, _SLIP_NEG)) & np.isin(prev, (SLIP, _SLIP_NEG))
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

    def _with_frozen(self, ctx):
        if not self.frozen:
            return ctx
        name = (lambda k: self.names[k]) if self.names else str
        return dataclasses.replace(ctx, freeze_contact={name(k): v.copy()
                                                        for k, v in self.frozen.items()})

    def settle(self, ctx, free_states) -> Any:
        """After a converged solve with frozen points whose free-law evaluation does not converge:
        give the frozen points where the free law disagrees the free law's status (held) and
        return the context for more iterations; None when ``max_rounds`` are used up."""
        self.rounds += 1
        if self.rounds > self.max_rounds:
            return None
        for k, status, _ in self._states(free_states):
            fz = self.frozen.get(k)
            if fz is not None:
                wrong = (fz >= 0) & (fz != status)
                fz[wrong] = status[wrong]
        return self._with_frozen(ctx)
