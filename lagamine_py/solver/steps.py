"""The step controller: steps in sequence, increments, cut-backs, writers, restart.

Per step: the loads are resolved against what the previous steps left (:mod:`.loads`); the
increment sizes come from a :class:`~.stepper.Stepper` (start at ``dt0``, grow by ``GROWTH``
after an easy increment, cut by ``CUTBACK`` -- or the factor a failure asks for -- on any typed
failure of Newton); each attempt starts from :func:`~.predictor.first_iterate` and is watched
by the contact stabilisation (:class:`~.stabilisation.FlipFlop`).  When a cut-back would go
below ``dt_min`` the run stops with status 3 and a message naming the step, the time reached and
why; every converged increment has already been handed to the writers (and saved for restart).
Group states are committed only on convergence.

The run's messages (steps, Newton norms, cut-backs, the stop reason) go to the
``lagamine_py.solver`` logger (the STATUS writer copies them into ``OUT/<deck>.log``).

The run claims its output directory first (:mod:`lagamine_py.core.outdir`): a lock (a second
run into it is refused), the record of the deck that writes it, and the files of an earlier run
cleared; a directory in use or holding another deck's results gives status 2 and nothing runs.
A file that cannot be written (a full disk, no permission) stops the run with status 1 and a
message; every increment converged before it is written.

Ctrl-C (KeyboardInterrupt) stops the run between two operations: the writers are closed with
status 130, every converged increment is written and the restart file holds the last one, so
``lagamine-py run --restart OUT`` goes on from there.  The :class:`Outcome` carries the lines a
user reads at the end (:attr:`Outcome.summary`): where the results are, the contact totals per
pair at the last converged increment, and the wall time.
"""
from __future__ import annotations

import json
import logging
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import ConvergenceFailure, SingularMatrixError
from ..core.exits import EXIT_DECK, EXIT_DIVERGED, EXIT_INTERRUPTED, EXIT_OK, EXIT_OTHER
from ..core import outdir as od
from ..core.status import NONE, OPEN, SLIP, STICK
from ..core.params import ParamError, validate_params
from ..elements.base import StepContext
from ..model import CONTROL_PARAMS
from .. import registry
from ..output import DEFAULT_WRITERS, FailedAttempt, IncrementResult, default_writers
from . import restart as rs
from . import tools
from .augmented import augmentation_limit, augmented_start
from .energy import EnergyAccount
from .linear import FreeDofs, make_solver
from .loads import Reached, StepLoads, driving_loads, step_loads
from .newton import ENERGY_FLOOR_FRACTION, FLOOR_FRACTION, Settings, solve_increment
from .reuse import FactorReuse
from .predictor import FrontPredictor, first_iterate, front_holds
from .problem import (CONTACT, SOLID, Problem, alternation_advice, build_problem,
                      dload_surfaces, faces_in_contact, penalty_advice)
from .stabilisation import FlipFlop, state_codes
from .stepper import StepExhausted, Stepper

log = logging.getLogger("lagamine_py.solver")

#: what the restart data keeps of the slip fronts of the last increment, per contact group
FRONT_ARRAYS = ("x0", "before", "after", "tau")


@dataclass
class Outcome:
    status: int        # 0 all steps done, 3 a step could not converge, 130 interrupted,
                       # 2 the output directory refused or a restart of another deck, 1 other
    message: str
    summary: list[str] = field(default_factory=list)    # the lines a user reads at the end


def round_time(t: float, scale: float) -> float:
    """``t`` rounded to 12 significant digits of ``scale`` (the run's total time): what the
    steps define, without the float noise of summed increments (1.6749999999999998 -> 1.675,
    0.30000000000000004 -> 0.3; 0.547265625 stays).  Only the times handed to writers are
    rounded; the solver keeps its own."""
    if not (scale > 0 and np.isfinite(t)):
        return float(t)
    return round(float(t), 12 - int(np.floor(np.log10(scale))))


class StepFailed(Exception):
    """A step cannot go on (cut-backs exhausted, INC= exceeded, singular matrix): status 3."""


class SetupError(Exception):
    """A step cannot start (e.g. its *CONTROLS ask for a solver that is not installed): status 1."""


class _Controls:
    params = CONTROL_PARAMS


def step_controls(step) -> dict[str, Any]:
    """The step's ``*CONTROLS`` values completed with the defaults."""
    return validate_params(_Controls, dict(step.controls))


def run(model, outdir, writers=None, restart: bool = False, deck_path=None,
        progress: bool = False, problem: Problem | None = None,
        overwrite: bool = False) -> Outcome:
    """Run every step of ``model``, writing into ``outdir``.

    ``writers``: a list of :class:`~lagamine_py.output.Writer` instances that observe every
    step (a script's own); by default the writers the steps' ``*OUTPUT, WRITERS=`` name (or
    the built-ins), each observing the steps that name it (:func:`run_writers`).
    ``restart=True`` resumes from ``outdir/restart.npz``.  ``deck_path``: the deck of a model
    without :attr:`~lagamine_py.model.Model.source` (built by a script).  ``overwrite``:
    replace the results of another deck in ``outdir`` (see :mod:`lagamine_py.core.outdir`).

    Typed failures give an :class:`Outcome` with status 3; an output directory in use or
    holding another deck's results, or restart data of another deck, status 2; a file that
    cannot be written, or restart data that cannot be read, status 1.  Other exceptions close
    the writers (status 1) and propagate.
    """
    outdir = Path(outdir)
    deck = deck_identity(model, deck_path)
    try:
        hold = od.claim(outdir, deck, restart=restart, overwrite=overwrite)
    except od.OutputDirError as exc:
        return Outcome(EXIT_DECK, str(exc))
    except OSError as exc:
        return Outcome(EXIT_OTHER, f"cannot use the output directory {outdir}: {os_error_text(exc)}")
    with hold:
        if problem is None:
            problem = build_problem(model)
        if writers is None:
            writers = run_writers(outdir, model, append=restart)
        else:
            writers = {f"#{k}": w for k, w in enumerate(writers)}
            for w in writers.values():
                w.append = w.append or restart
        controller = Controller(model, problem, outdir, writers, deck, progress)
        controller.notes = [f"{outdir}: {hold.note}"] if hold.note else []
        return controller.run(restart)


def deck_identity(model, deck_path=None) -> od.DeckIdentity:
    """The identity of the deck a run computes: the model's source (path, digest, parameters)
    when it was read from a deck, else ``deck_path`` (absolute) without a digest."""
    src = model.source
    if src is not None:
        return od.DeckIdentity(src.path, model.name, src.digest, dict(src.parameters))
    path = str(Path(deck_path).resolve()) if deck_path is not None else ""
    return od.DeckIdentity(path, model.name or "")


def os_error_text(exc: OSError) -> str:
    """``[Errno 28] No space left on device: 'OUT/contact.csv'`` as a reader wants it:
    ``OUT/contact.csv: No space left on device``."""
    what = exc.strerror or str(exc)
    return f"{exc.filename}: {what}" if exc.filename else what


def run_writers(outdir: Path, model, append: bool = False) -> dict:
    """The run's writers: every writer some step's ``*OUTPUT, WRITERS=`` names, the built-ins
    for the steps that name none (:data:`~lagamine_py.output.DEFAULT_WRITERS`), and the writers
    every run gets (``Writer.always``); a dict name -> writer."""
    names: list[str] = []
    for step in model.steps:
        for name in step_writers(step):
            if name not in names:
                names.append(name)
    names = names or list(DEFAULT_WRITERS)
    names += [n for n in registry.names("writers")
              if n not in names and registry.get("writers", n).always]
    return dict(zip(names, default_writers(outdir, model, names, append=append)))


def step_writers(step) -> tuple[str, ...]:
    """The writers a step's output goes to: its ``*OUTPUT, WRITERS=``, else the built-ins."""
    return tuple(step.output.writers) or DEFAULT_WRITERS


class Controller:
    """Runs the steps of a model.  ``writers``: name -> writer; a writer whose name starts with
    ``#`` (given by a script) observes every step, the others the steps whose output names them
    and, if their class is ``always``, every step."""

    def __init__(self, model, problem: Problem, outdir: Path, writers: dict,
                 deck: od.DeckIdentity | None = None, progress: bool = False):
        self.model, self.problem, self.outdir = model, problem, outdir
        self.writers = dict(writers)
        self.active = list(self.writers.values())      # the writers of the current step
        self.deck = deck if deck is not None else deck_identity(model)
        self.total_time = float(sum(float(st.period) for st in model.steps))
        self.progress = Progress(enabled=progress, total=self.total_time)
        self.last_contacts: list = []     # the contact points of the last hand-out (summary)
        self.last_tools: dict = {}        # and the tools' states
        self.wall0 = _time.perf_counter()
        n = problem.ndof
        self.u = np.zeros(n)
        self.reaction = np.zeros(n)
        self.states = problem.init_states()
        self.reached = Reached()
        self.time_offset = 0.0            # total time at the start of the current step
        self.force_ref = 0.0              # largest force scale of converged increments
        self.energy_ref = 0.0             # largest energy reference of converged increments
        self.total_increments = 0
        self.surfaces = dload_surfaces(model)
        self.foundations = list(model.foundations)
        self.has_contact = CONTACT in problem.kinds
        self._kernel_text = None          # what the log last said of the solid kernel
        self.notes: list[str] = []        # said in the log once the writers started
        self.time_reached = 0.0           # total time of the last converged increment
        self.nodal = 2 * len(model.node_ids)      # the rotations of reference nodes follow
        self.energy = EnergyAccount(n) if tracks_energy(model) else None
        # (u, states) before the last commit, from the commit to its hand-out, and only when
        # the energy balance reads it: a whole set of solid states (33 MB at 51k Q8) otherwise
        # alive through the next increment's factorisations
        self._previous = None
        self._solvers: dict = {}          # the linear solver of the last step, by name
        self._solves: FactorReuse | None = None   # and its factor, kept between solves
        self._last_energy: dict = {}      # the energy terms of the last hand-out
        self._advised: set[str] = set()   # the contact advice given (once per pair and what)

    # -- the run ---------------------------------------------------------------------------
    def run(self, restart: bool) -> Outcome:
        self.wall0 = _time.perf_counter()
        try:
            resume = self._load_restart() if restart else None
        except rs.RestartError as exc:         # nothing was written: the writers never started
            return Outcome(exc.status, str(exc))
        self.progress.start(self.time_offset + (resume or {}).get("t", 0.0))
        status, message = EXIT_OTHER, "interrupted"
        started = []
        try:
            for w in self.writers.values():
                w.start_run()
                started.append(w)
            advice_log = logging.getLogger("lagamine_py.advice")
            for notice in self.problem.notices:
                advice_log.info(notice)
            for advice in self.problem.warnings:
                advice_log.warning(advice)
                self._advised.add(_advice_key(advice))
            for note in self.notes:                 # what claiming the directory did
                log.warning(note)
            if resume is None:
                self._hand_out_initial()
            first = resume["step"] if resume else 0
            for si in range(first, len(self.model.steps)):
                self._run_step(si, _resume_or_none(resume) if si == first else None)
            status = EXIT_OK
            names = ", ".join(st.name for st in self.model.steps if st.name)
            message = (f"completed {len(self.model.steps)} step(s){f' ({names})' if names else ''}, "
                       f"{self.total_increments} increments, time {self._time(self.time_offset):g}")
            log.info(message)
        except StepFailed as exc:
            status, message = EXIT_DIVERGED, str(exc)
            log.error(message)
        except SetupError as exc:
            status, message = EXIT_OTHER, str(exc)
            log.error(message)
        except KeyboardInterrupt:
            status, message = EXIT_INTERRUPTED, self._interrupted_text()
            log.warning(message)
        except OSError as exc:                  # a full disk, a file made read-only ...
            status, message = EXIT_OTHER, self._write_failure_text(exc)
            log.error(message)
        except Exception as exc:                # a plugin that raised: say so, then propagate
            status, message = EXIT_OTHER, f"stopped by an error: {type(exc).__name__}: {exc}"
            raise
        finally:
            self.progress.end()
            failure = self._close(started, status, message)
            if failure is not None and status in (EXIT_OK, EXIT_DIVERGED):
                status, message = EXIT_OTHER, self._write_failure_text(failure)
        return Outcome(status, message, self.summary())

    def _close(self, writers, status, message) -> OSError | None:
        """Close every writer that started, even when one fails (a full disk fails them all);
        the first OSError is returned, any other exception raised once all are closed."""
        first, other = None, None
        for w in writers:
            try:
                w.close(status, message)
            except OSError as exc:
                first = first or exc
            except Exception as exc:
                other = other or exc
        if other is not None:
            raise other
        return first

    def _write_failure_text(self, exc: OSError) -> str:
        done = (f"the files hold the increments that converged before (time {self.time_reached:g} "
                f"reached)" if self.total_increments else "no increment converged")
        restart = ((f"; once the cause is fixed go on with `lagamine-py run --restart "
                    f"{self.outdir}`") if (self.outdir / rs.FILE).exists() else "")
        return f"cannot write the results: {os_error_text(exc)}; {done}{restart}"

    def _time(self, t: float) -> float:
        """A total time as writers get it: :func:`round_time` on the run's time scale."""
        return round_time(t, self.total_time)

    def _interrupted_text(self) -> str:
        if (self.outdir / rs.FILE).exists():
            return (f"interrupted at time {self._time(self.time_offset):g} (the start of the step "
                    f"in progress) or later: every converged increment is written; go on with "
                    f"`lagamine-py run --restart {self.outdir}`")
        return "interrupted before the first increment converged: nothing to resume"

    def summary(self) -> list[str]:
        """What a user reads at the end of a run: the contact totals per pair at the last
        converged increment (P, T, T/P, the points open, stick, slip and without a foundation
        opposite), where the results are, and the wall time."""
        lines = []
        units = tuple(self.model.units)
        force = f" {units[1]}" if len(units) > 1 else ""
        for cp in self.last_contacts:
            st = np.asarray(cp.status)
            counts = {name: int(np.sum(st == code)) for name, code in
                      (("open", OPEN), ("stick", STICK), ("slip", SLIP), ("none", NONE))}
            # a frictionless pair's T is round-off: its ratio reads 0, not -0.0000
            ratio = ("-" if cp.P == 0 else "0" if abs(cp.T) <= 1e-9 * abs(cp.P)
                     else f"{cp.T / cp.P:.4f}")
            lines.append(f"contact {cp.name}: P = {cp.P:.6g}{force}, T = {cp.T:.6g}{force}, "
                         f"T/P = {ratio}; {len(st)} points: {counts['open']} open, "
                         f"{counts['stick']} stick, {counts['slip']} slip"
                         + (f", {counts['none']} facing no foundation" if counts["none"] else ""))
        for ts in self.last_tools.values():
            if ts.ref_node is None and not np.any(ts.placement):
                continue                    # a fixed foundation: its force is the contacts' above
            node = f" (reference node {ts.ref_node})" if ts.ref_node is not None else ""
            lines.append(f"tool {ts.name}{node}: force ({ts.force[0]:.6g}, {ts.force[1]:.6g}){force}, "
                         f"moment {ts.moment:.6g}; moved by ({ts.placement[0]:.6g}, "
                         f"{ts.placement[1]:.6g}), turned by {ts.placement[2]:.6g} rad")
        pvd = self.outdir / f"{self.model.name or 'run'}.pvd"
        lines.append(f"results in {self.outdir}" + (f" (ParaView: {pvd})" if pvd.exists() else ""))
        lines.append(f"wall time {_time.perf_counter() - self.wall0:.1f} s")
        return lines

    def _run_step(self, si: int, resume: dict | None) -> None:
        """Run step ``si`` (from its start, or from ``resume``): the increment loop."""
        step = self.model.steps[si]
        controls, settings, solver = self._setup_step(si, step)
        self.states = self.problem.set_step_laws(si, self.states)   # *CHANGE CONTACT LAW
        if resume is not None:
            loads, last, front = resume["loads"], resume["last"], resume["front"]
            earlier = resume["earlier"]
            stepper = Stepper.start(step, controls, resume["t"], resume["dt"], resume["inc"])
        else:
            loads = step_loads(self.model, step, self.reached, self.u, self.reaction,
                               self.surfaces, self.foundations)
            # the last converged increment of the step (displacement change, dt) and the one
            # before it: the predictor of the next one (EXTRAPOLATION=LINEAR uses the last,
            # PARABOLIC both); none at a step start
            last = earlier = front = None        # and how its slip fronts moved (front_holds)
            stepper = Stepper.start(step, controls)
        free = FreeDofs(self.problem.pattern, loads.constrained)
        self._start_step(si, step, loads, controls)
        while not stepper.finished:
            if self.problem.refresh(self.u):      # two-body contact re-paired: a new pattern
                free = FreeDofs(self.problem.pattern, loads.constrained)
            conv = self._increment(si, step, loads, free, solver, settings, controls, stepper,
                                   last, front, earlier)
            # the increment before the last: kept (and in the restart data) for PARABOLIC only
            earlier = last if controls["EXTRAPOLATION"] == "PARABOLIC" else None
            last = (conv.u - self.u, stepper.attempt)
            before = self._contact_states()
            self._commit(conv, loads, free)
            t = stepper.accept(conv.iterations)
            self._hand_out(si, step, loads, stepper.inc, t, stepper.attempt, conv,
                           stepper.cutbacks, stepper.period, stepper.finished)
            front = [(cp.x0, b, a, np.asarray(cp.tau, float)) for cp, b, a in
                     zip(self.last_contacts, before, self._contact_states())]
            self._save_restart(si, loads, stepper, last, front, earlier)
        self._log_step_energy(si)
        self._contact_advice(si)
        self.reached = loads.reached(self.model)
        self.time_offset += stepper.period

    def _contact_advice(self, si: int) -> None:
        """At the end of a step, per contact pair, once per run each: the penalties on the faces
        in contact (:func:`~.problem.penalty_advice`), and stresses that alternate from point to
        point (:func:`~.problem.alternation_advice`)."""
        advice_log = logging.getLogger("lagamine_py.advice")
        for k in self.problem.indices(CONTACT):
            name, group = self.problem.group_names[k], self.problem.groups[k]
            texts = []
            scales = self.problem.face_scales.get(k)
            if scales is not None:
                texts += penalty_advice(name, group.law,
                                        scales[faces_in_contact(group, self.states[k])])
            alternating = alternation_advice(name, group, self.states[k])
            texts += [alternating] if alternating else []
            for text in texts:
                key = _advice_key(text)
                if key not in self._advised:
                    self._advised.add(key)
                    advice_log.warning(f"step {si + 1}: {text}")

    def _setup_step(self, si, step):
        """The step's ``*CONTROLS`` (defaults filled), Newton settings and linear solver; the
        kernel choice applied.  SetupError when the step cannot start."""
        try:
            controls = step_controls(step)
        except ParamError as exc:
            raise SetupError(f"step {si + 1} ({step.name}): *CONTROLS: {exc}") from None
        try:
            # one solver object per name for the whole run: a step whose free DOFs are those of
            # the step before keeps PARDISO's analysis (the structure is compared by value)
            name = str(controls["SOLVER"]).upper()
            solver = self._solvers.get(name) or make_solver(controls["SOLVER"])
            if self._solvers.get(name) is not solver:
                self._solves = FactorReuse(solver)
            self._solvers = {name: solver}      # only one alive: its factor is the run's
            self._solves.krylov = int(controls["KRYLOV"])
            self._solves.min_dofs = int(controls["KRYLOVDOFS"])
            self.problem.set_kernel(controls["KERNEL"])
        except KeyError as exc:
            raise SetupError(f"step {si + 1} ({step.name}): {exc.args[0]}") from None
        if not float(step.period) > 0:
            raise SetupError(f"step {si + 1} ({step.name}): the step time must be positive, "
                             f"got {float(step.period):g}")
        return controls, Settings.from_controls(controls), solver

    def _start_step(self, si, step, loads, controls) -> None:
        log.info("step %d %s: period %g, dt0 %g, %d constrained DOFs", si + 1, step.name,
                 step.period, step.dt0, len(loads.constrained))
        self._log_kernel(controls["KERNEL"])
        wanted = step_writers(step)
        self.active = [w for name, w in self.writers.items()
                       if name.startswith("#") or name in wanted or w.always]
        for w in self.writers.values():
            w.start_step(si + 1, step)

    def _increment(self, si, step, loads, free, solver, settings, controls, stepper, last,
                   front=None, earlier=None):
        """One converged increment: attempts from :meth:`Stepper.trial`, cut back on every
        typed failure until one converges; StepFailed when the stepper runs out."""
        where = lambda: (f"at step time {stepper.t:g} of {stepper.period:g} "    # noqa: E731
                         f"(total time {self.time_offset + stepper.t:g})")
        try:
            stepper.trial()
        except StepExhausted as exc:
            raise StepFailed(f"step {si + 1} ({step.name}): {exc} {where()}") from None
        while True:
            try:
                # a cut-back attempt predicts no front: the prediction may be what failed
                return self._attempt(step, loads, free, solver, settings, controls, stepper, last,
                                     front if stepper.cutbacks == 0 else None, earlier)
            except (ConvergenceFailure, SingularMatrixError) as exc:
                reason = self._failure_text(exc, free)
                if isinstance(exc, SingularMatrixError) and not self.has_contact:
                    raise StepFailed(f"step {si + 1} ({step.name}) stopped at step time "
                                     f"{stepper.t:g} of {stepper.period:g}: {reason}") from None
                self._report_failure(si, step, stepper.inc, stepper.t, stepper.attempt,
                                     stepper.cutbacks + 1, exc, reason)
                try:
                    stepper.cut_back(exc.factor if isinstance(exc, ConvergenceFailure) else None)
                except StepExhausted as out:
                    raise StepFailed(f"step {si + 1} ({step.name}) could not converge: "
                                     f"{where()} {out}; last failure: {reason}") from None

    def _log_kernel(self, setting: str) -> None:
        """Say how the solid groups are computed, once per change (a first use of the numba
        kernel compiles it for ~10 s: a user should know why the first increment waits)."""
        solids = self.problem.indices(SOLID)
        fused = sum(self.problem.groups[k].fused for k in solids)
        text = (f"numba kernel for {fused} of {len(solids)} solid group(s) (KERNEL={setting}; "
                "compiled on first use, then cached)" if fused else f"NumPy (KERNEL={setting})")
        if text != self._kernel_text:
            log.info("solid elements computed by %s", text)
            self._kernel_text = text

    def _contact_states(self) -> list[np.ndarray]:
        """(g,) state codes (:func:`~.stabilisation.state_codes`) of every contact group's
        committed state, in group order."""
        return [state_codes(self.states[k]["status"], self.states[k]["tau"], self.states[k]["p"])
                for k in self.problem.indices(CONTACT)]

    def _front_predictor(self, front, last, dt, controls) -> FrontPredictor:
        """The slip points predicted for the next increment from the fronts' motion over the
        last one (``front``: per contact group (x0, state codes before, after, tau); none at a step
        start or with EXTRAPOLATION=NONE, as the displacement predictor)."""
        holds = {}
        if front is not None and last is not None and controls["EXTRAPOLATION"] != "NONE":
            for k, (x0, before, after, tau) in zip(self.problem.indices(CONTACT), front):
                if before.shape == after.shape == tau.shape == (len(x0),):
                    holds[self.problem.group_names[k]] = front_holds(x0, before, after, tau,
                                                                     dt / last[1])
        return FrontPredictor(holds)

    def _attempt(self, step, loads: StepLoads, free, solver, settings, controls, stepper, last,
                 front=None, earlier=None):
        """One Newton solve of the increment ``stepper.attempt`` from the step time reached."""
        model, problem = self.model, self.problem
        t, dt = stepper.t, stepper.attempt
        t_new = t + dt
        ctx = StepContext(nlgeom=bool(step.nlgeom), t_old=self.time_offset + t,
                          t_new=self.time_offset + t_new,
                          foundation_old=loads.motions(model, t),
                          foundation_new=loads.motions(model, t_new),
                          stabilisation=tools.stabilisation_context(problem, step, t, dt))
        problem.set_pressures(loads.pressures(model, t_new))
        f_ext = loads.f_ext(model, t_new, problem.ndof)
        u_c = loads.bc_values(model, t_new)
        start, predicted = first_iterate(
            self.u, last, dt, controls["EXTRAPOLATION"],
            tools.predictor_context(problem, ctx, self.u, free.constrained, u_c), self.nodal,
            earlier)
        watched = {k: problem.group_names[k] for k in problem.indices(CONTACT)}
        log.info("  increment at step time %g, dt %g", t_new, dt)
        # an overflow becomes inf or NaN, which Newton reports as a typed failure (NotANumber:
        # the increment is cut back), not a warning on the terminal
        contact = problem.indices(CONTACT)
        states, solves, iterations, ratio = self.states, 0, 0, 0.0
        # one predictor for the increment: the fronts are held at the first evaluation of its
        # first solve only, not again from the converged solve an augmentation starts from
        fronts = self._front_predictor(front, last, dt, controls)
        factorisations = back_substitutions = 0
        while True:
            try:
                with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                    trial = solve_increment(
                        problem, solver, free, self.u, states, ctx, u_c, f_ext, settings,
                        floor=FLOOR_FRACTION * self.force_ref,
                        energy_floor=ENERGY_FLOOR_FRACTION * self.energy_ref,
                        u_start=start, predicted=predicted,
                        observers=(fronts, FlipFlop(watched, int(controls["FLIPFLOP"]))),
                        solves=self._solves)
            except ConvergenceFailure as exc:
                if solves == 0:
                    raise
                # an augmentation that does not converge (stick/slip changing with the
                # multipliers): the increment keeps the last converged solve, and says so
                log.warning("  augmented Lagrangian: solve %d did not converge (%s); the "
                            "increment keeps solve %d, its constraints %.3g times PTOL away",
                            solves + 1, str(exc).splitlines()[0], solves, ratio)
                break
            conv = trial
            solves, iterations = solves + 1, iterations + conv.iterations
            factorisations += conv.factorisations
            back_substitutions += conv.back_substitutions
            # METHOD=AUGMENTED: solve again with the multipliers of this solve (augmented.py)
            again, ratio = augmented_start(problem, contact, states, conv.states)
            if again is None:
                if solves > 1:
                    log.info("  augmented Lagrangian: %d solves, %d iterations, largest change "
                             "%.3g PTOL", solves, iterations, ratio)
                break
            if solves >= augmentation_limit(problem, contact):
                log.warning("  augmented Lagrangian: AUGMAX = %d solves reached, the constraints "
                            "still %.3g times PTOL away", solves, ratio)
                break
            log.info("  augmentation %d: the constraints %.3g times PTOL away", solves, ratio)
            states, start, predicted = again, conv.u, None
        conv.iterations = iterations           # the cost of the increment: every solve's
        conv.factorisations, conv.back_substitutions = factorisations, back_substitutions
        conv.f_ext, conv.ctx = f_ext, ctx
        return conv

    def _commit(self, conv, loads, free) -> None:
        self._previous = (self.u, self.states) if self.energy is not None else None
        self.u = conv.u
        self.states = conv.states
        self.reaction = np.zeros_like(self.u)
        c = free.constrained
        self.reaction[c] = (conv.f_int - conv.f_ext)[c]
        self.force_ref = max(self.force_ref, conv.scale)
        self.energy_ref = max(self.energy_ref, conv.energy_scale)
        self.total_increments += 1

    # -- output ----------------------------------------------------------------------------
    def _hand_out(self, si, step, loads, inc, t, dt, conv, cutbacks, T, step_end=False) -> None:
        model = self.model
        u2 = self.u[:self.nodal].reshape(-1, 2)
        reaction2 = self.reaction[:self.nodal].reshape(-1, 2)
        by_set = tools.reactions_by_target(model, loads.bc_targets, self.reaction)
        freq = max(int(step.output.frequency), 1)
        place = tools.placements(self.problem, loads, model, self.u, t)
        ctx = self.problem.tool_context(conv.ctx, self.u, self.u)
        contacts = self._contacts(u2, ctx)
        tool_states = tools.tool_states(model, place, contacts)
        energy = {}
        if self.energy is not None:
            u_old, states_old = self._previous
            self._previous = None             # read once: not held through the next increment
            F = self.energy.applied_forces(self.problem, self.u, ctx, conv.f_ext, self.reaction)
            energy = self.energy.commit(self.problem, u_old, self.u, states_old, self.states, F,
                                        contacts, tool_states)
        result = IncrementResult(
            step=si + 1, step_name=step.name, increment=inc,
            time=self._time(self.time_offset + t), step_time=round_time(t, self.total_time),
            dt=dt, iterations=conv.iterations, residual=conv.residual,
            cutbacks=cutbacks, coords0=model.coords, u=u2.copy(), reaction=reaction2.copy(),
            reactions_by_set=by_set, cells=self._cells(step.nlgeom),
            contacts=contacts, foundations=tools.foundation_points(model, place),
            write_fields=(inc % freq == 0) or t >= T, step_end=bool(step_end),
            residual_history=list(conv.history),
            loads=driving_loads(model, step, loads, t), tools=tool_states, energy=energy)
        self.last_contacts = result.contacts
        self.last_tools = result.tools
        self._last_energy = result.energy
        self.time_reached = result.time
        log.info("  converged: step %d increment %d, time %g, %d iterations, |R|/F %.3e",
                 si + 1, inc, result.time, conv.iterations, conv.residual)
        for w in self.active:
            w.increment(result)
        self.progress.update(si, step, self.time_offset + t, inc, conv.iterations,
                             len(self.model.steps))

    def _hand_out_initial(self) -> None:
        """The state at t = 0 to the writers (:meth:`Writer.initial`): nothing loaded yet, the
        foundations where the deck puts them, the contact points as they start."""
        model, step = self.model, self.model.steps[0] if self.model.steps else None
        u2 = self.u[:self.nodal].reshape(-1, 2)
        ctx = StepContext(nlgeom=bool(step and step.nlgeom),
                          foundation_old={name: np.zeros(3) for name in model.foundations},
                          foundation_new={name: np.zeros(3) for name in model.foundations})
        contacts = self._contacts(u2, ctx)
        place = {name: np.zeros(3) for name in model.foundations}
        result = IncrementResult(
            step=1, step_name=step.name if step else "", increment=0, time=0.0, step_time=0.0,
            dt=0.0, iterations=0, residual=0.0, cutbacks=0, coords0=model.coords, u=u2.copy(),
            reaction=self.reaction[:self.nodal].reshape(-1, 2).copy(), reactions_by_set={},
            cells=self._cells(bool(step and step.nlgeom)), contacts=contacts,
            foundations={name: np.asarray(spec.points, float)
                         for name, spec in model.foundations.items()},
            tools=tools.tool_states(model, place, contacts))
        for w in self.writers.values():
            w.initial(result)

    def _cells(self, nlgeom: bool = False) -> list:
        u2 = self.u[:self.nodal].reshape(-1, 2)
        return [self.problem.groups[k].cell_block(u2, self.states[k], bool(nlgeom))
                for k in self.problem.indices(SOLID)]

    def _contacts(self, u2, ctx) -> list:
        return [self.problem.groups[k].points(u2, self.states[k], ctx)
                for k in self.problem.indices(CONTACT)]

    def _failure_text(self, exc, free=None) -> str:
        if isinstance(exc, SingularMatrixError):
            text = exc.describe(names=self.model.dof_names())
            if exc.ill_conditioned and self.problem.warnings:     # the penalties' advice says why
                text += "; " + "; ".join(self.problem.warnings)
            elif exc.matrix is not None and free is not None:
                states = self.states if exc.states is None else exc.states
                why = tools.explain_singular(self.problem, exc.matrix, free.free, states)
                if why:
                    text += f": {why}"
            return text
        return f"{exc.reason}: {exc}"

    def _log_step_energy(self, si: int) -> None:
        """At a step end: the stabilisation's energy against the work of the loads and tools
        (a warning above 1 %), and the energy balance when the run tracks it."""
        totals = [cp.stabilisation for cp in self.last_contacts]
        work = None
        if self.energy is not None:
            e = self._last_energy
            work = e.get("work")
            if e:
                log.info("  energy at the end of step %d: work %.6g = elastic %.6g + plastic %.6g "
                         "+ friction %.6g + penalty %.6g + stabilisation %.6g; balance %.3g "
                         "(%.3g %% of the work)", si + 1, e["work"], e["elastic"], e["plastic"],
                         e["friction"], e["penalty"], e["stabilisation"], e["balance"],
                         100 * e["relative"])
        if self.model.steps[si].stabilisation is not None or any(totals):
            stab = float(sum(totals))
            share = f" ({100 * stab / abs(work):.3g} % of the work {work:.6g})" if work else ""
            level = logging.WARNING if work and abs(stab) > 0.01 * abs(work) else logging.INFO
            log.log(level, "  contact stabilisation: energy dissipated since the start %.6g%s",
                    stab, share)

    def _report_failure(self, si, step, inc, t, dt, cutbacks, exc, reason) -> None:
        history = exc.history if isinstance(exc, ConvergenceFailure) else []
        solves = exc.solves if isinstance(exc, ConvergenceFailure) else None
        log.warning("  step %d increment %d: attempt with dt %g failed (%s); cutting back",
                    si + 1, inc + 1, dt, reason)
        attempt = FailedAttempt(step=si + 1, step_name=step.name, increment=inc + 1,
                                time=self.time_offset + t, step_time=t, dt=dt, reason=exc.reason,
                                message=reason,
                                iterations=max(len(history) - 1, 0) if solves is None else solves,
                                residual_history=list(history), cutbacks=cutbacks)
        for w in self.active:
            w.failed_attempt(attempt)

    # -- restart ---------------------------------------------------------------------------
    def _save_restart(self, si, loads: StepLoads, stepper: Stepper, last=None,
                      front=None, earlier=None) -> None:
        state = stepper.state()
        data = {"deck": np.array(self.deck.path), "deck_digest": np.array(self.deck.digest),
                "deck_parameters": np.array(json.dumps(self.deck.parameters)),
                "ndof": np.array(self.problem.ndof),
                "ngroups": np.array(len(self.problem.groups)), "step": np.array(si),
                "t": np.array(state["t"]), "dt": np.array(state["dt"]),
                "inc": np.array(state["inc"]),
                "total_increments": np.array(self.total_increments),
                "time_offset": np.array(self.time_offset), "force_ref": np.array(self.force_ref),
                "energy_ref": np.array(self.energy_ref),
                "u": self.u, "reaction": self.reaction}
        if last is not None:            # the predictor of the next increment, for a same-path resume
            data["last_du"], data["last_dt"] = last[0], np.array(last[1])
        if earlier is not None:         # and the increment before it (PARABOLIC)
            data["earlier_du"], data["earlier_dt"] = earlier[0], np.array(earlier[1])
        for i, arrays in enumerate(front or ()):      # and its slip fronts
            for name, v in zip(FRONT_ARRAYS, arrays):
                data[f"front_{name}_{i}"] = v
        data.update(rs.pack_states(self.states))
        data.update(loads.to_arrays())
        if self.energy is not None:
            data.update(self.energy.to_arrays())
        rs.save(self.outdir, data)

    def _load_restart(self) -> dict:
        data = rs.load(self.outdir)
        rs.check_deck(self.outdir, data, self.deck)
        try:
            return self._resume_from(data)
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise rs.RestartError(f"{self.outdir / rs.FILE} is damaged or incomplete "
                                  f"({type(exc).__name__}: {exc}); run the deck again from the "
                                  f"start") from None

    def _resume_from(self, data: dict) -> dict:
        if int(data["ndof"]) != self.problem.ndof or int(data["ngroups"]) != len(self.problem.groups):
            raise rs.RestartError("the restart data does not fit the model (DOFs or groups differ)")
        self.u = data["u"].copy()
        self.reaction = data["reaction"].copy()
        self.states = rs.unpack_states(data, self.problem.init_states())
        self.total_increments = int(data["total_increments"])
        self.time_offset = float(data["time_offset"])
        self.force_ref = float(data["force_ref"])
        # absent from the restart files of earlier versions: no floor, as those runs had
        self.energy_ref = float(data["energy_ref"]) if "energy_ref" in data else 0.0
        if self.energy is not None:
            self.energy.from_arrays(data)
        loads = StepLoads.from_arrays(data)
        si, t = int(data["step"]), float(data["t"])
        self.time_reached = self._time(self.time_offset + t)
        log.info("restart from step %d at step time %g", si + 1, t)
        if t >= loads.period * (1 - 1e-12):     # saved at a step end: go on with the next step
            self.reached = loads.reached(self.model)
            self.time_offset += loads.period
            return {"step": si + 1, "loads": None}
        last = (data["last_du"].copy(), float(data["last_dt"])) if "last_du" in data else None
        earlier = ((data["earlier_du"].copy(), float(data["earlier_dt"]))
                   if "earlier_du" in data else None)
        front = [tuple(data[f"front_{name}_{i}"].copy() for name in FRONT_ARRAYS)
                 for i in range(len(self.problem.indices(CONTACT))) if f"front_x0_{i}" in data]
        return {"step": si, "loads": loads, "t": t, "dt": float(data["dt"]),
                "inc": int(data["inc"]), "last": last, "front": front or None,
                "earlier": earlier}


def tracks_energy(model) -> bool:
    """Whether a run of ``model`` keeps the energy balance: a ``*CHECK, TYPE=ENERGY`` or a step
    whose ``*OUTPUT, WRITERS=`` names ENERGY."""
    return (any(str(c.get("type", "")).upper() == "ENERGY" for c in model.checks)
            or any("ENERGY" in step.output.writers for step in model.steps))


def _advice_key(text: str) -> str:
    """What a piece of contact advice is about, said once per run: the pair and the penalty
    with its value (``contact A->F: KT = 1e+09``), or the pair's alternation."""
    head = text.split(" is ")[0]
    return head if " E/h " in text else text.split(":")[0] + " alternation"


def _resume_or_none(resume):
    return resume if resume and resume.get("loads") is not None else None


class Progress:
    """One-line progress bar of the whole run on a TTY (stderr), plain lines otherwise: the
    fraction of the run's total time reached, the step, the increment, and an estimate of the
    time left (the wall time so far scaled by the time left, measured from where this process
    started: a resumed run does not count the first run's time)."""

    def __init__(self, enabled: bool, stream=None, total: float = 1.0):
        self.enabled = enabled
        self.stream = stream or sys.stderr
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self.open_line = False
        self.total = float(total) if total > 0 else 1.0
        self.t0 = _time.perf_counter()
        self.start_time = 0.0

    def start(self, time: float = 0.0) -> None:
        """The clock starts now, at the run's time ``time`` (> 0 when resuming)."""
        self.t0 = _time.perf_counter()
        self.start_time = float(time)

    def eta(self, time: float) -> float | None:
        """Seconds left, or None before anything was done."""
        done = time - self.start_time
        if done <= 0:
            return None
        return (_time.perf_counter() - self.t0) * max(self.total - time, 0.0) / done

    def update(self, si, step, time, inc, iterations, nsteps) -> None:
        """After a converged increment: ``time`` is the run's total time reached."""
        if not self.enabled:
            return
        frac = min(max(time / self.total, 0.0), 1.0)
        eta = self.eta(time)
        left = "" if eta is None else f"  ETA {_clock(eta)}"
        text = (f"{100 * frac:3.0f}%  step {si + 1}/{nsteps} {step.name}  time {time:.4g}/"
                f"{self.total:g}  inc {inc}  it {iterations}  {_clock(_time.perf_counter() - self.t0)}"
                f"{left}")
        if self.tty:
            bar = "#" * int(20 * frac) + "-" * (20 - int(20 * frac))
            self.stream.write(f"\r[{bar}] {text}\033[K")
            self.open_line = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def end(self) -> None:
        if self.open_line:
            self.stream.write("\n")
            self.stream.flush()
            self.open_line = False


def _clock(seconds: float) -> str:
    """``42s``, ``3m05s``, ``2h07m``."""
    s = int(round(seconds))
    if s < 60:
        return f"{s}s"
    if s < 3600:
        return f"{s // 60}m{s % 60:02d}s"
    return f"{s // 3600}h{(s % 3600) // 60:02d}m"
