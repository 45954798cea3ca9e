"""Benchmarks of lagamine_py: scaling of press-then-slide, bulk/contact assembly, linear solvers,
CLI start-up.  Timings are measured here, never asserted in tests (DESIGN.md §3).

Sub-commands (run from the repository root, in the project's venv)::

    python tools/bench.py scale --sizes 40x20 80x40 160x80 320x160 [--solver AUTO] [--json F]
    python tools/bench.py one NX NY [--solver AUTO] [--json F]     # one size (scale runs this)
    python tools/bench.py assembly [--nx 160 --ny 80]              # us per element / Gauss point
                                                                    # (NumPy and numba kernels)
    python tools/bench.py solvers [--sizes 20x10 40x20 ...]        # SPLU vs PARDISO crossover
    python tools/bench.py startup [--trees A B]                     # --help, check, run of
                                                                    # the main job, whole process
    python tools/bench.py floor [--decks D ...] [--repeat 7]       # a run against the process
                                                                    # that only imports what it
                                                                    # imports (the floor)
    python tools/bench.py first-run [--size 80x40]                 # fresh numba cache vs warm,
                                                                    # with and without `compile`
    python tools/bench.py vtu FILE.vtu                              # VTU encodings: time, size,
                                                                    # does meshio read it
    python tools/bench.py report --json F [--png P]                 # markdown table + plot

``scale`` runs press-then-slide (``decks/press_slide.dat``) with the mesh refined: ``NX x NY`` Q8,
the pressed element set and the penalties (``KP = KT = 20 E / h``, the deck's rule) adapted,
written to a temporary deck; each size runs in its own process (peak memory per size) with the
default writers into a temporary directory.  The time of a run is split by wrapping the
methods that do the work (the solver code is not changed): bulk element groups, contact
groups, pressure groups, scatter into the CSR pattern, reduction to the free DOFs,
factorisation, solve, writers (VTK and the rest), and the rest of the step controller.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DECK = ROOT / "decks" / "press_slide.dat"
E_STEEL = 210000.0


# --------------------------------------------------------------------------------------------
# press-then-slide at a chosen mesh size

def press_slide_deck(nx: int, ny: int) -> str:
    """Text of ``decks/press_slide.dat`` with an ``nx`` x ``ny`` mesh: the pressed range of the
    top row (``*ELSET ... GENERATE``) scaled to the same fraction of the edge, and the penalties
    ``KP = KT = 20 E / h`` (the deck's rule).  ``nx`` must be a multiple of the deck's NX / 4."""
    text = DECK.read_text()
    m = re.search(r"NX=(\d+), NY=(\d+)", text)
    nx0, ny0 = int(m.group(1)), int(m.group(2))
    text = text[:m.start()] + f"NX={nx}, NY={ny}" + text[m.end():]
    g = re.search(r"(\*ELSET, ELSET=TOP_LOADED, GENERATE\s*\n)(\d+), (\d+), 1\n", text)
    top0 = (ny0 - 1) * nx0
    a, b = int(g.group(2)) - top0 - 1, int(g.group(3)) - top0      # columns [a, b) of the top row
    if (a * nx) % nx0 or (b * nx) % nx0:
        raise ValueError(f"NX={nx}: the pressed range {a}..{b} of {nx0} does not scale")
    top = (ny - 1) * nx
    text = (text[:g.end(1)] + f"{top + a * nx // nx0 + 1}, {top + b * nx // nx0}, 1\n"
            + text[g.end():])
    kp = 20 * E_STEEL / (40.0 / nx)
    text, n = re.subn(r"KP=[0-9.eE+]+, KT=[0-9.eE+]+", f"KP={kp:.6g}, KT={kp:.6g}", text)
    if n != 1:
        raise RuntimeError("decks/press_slide.dat changed: update tools/bench.py's substitutions")
    return text


class Timers:
    """Accumulated wall time, CPU time and call counts per label.

    The clocks themselves cost: ``time.process_time`` sums the CPU of every thread of the
    process (MKL's, numba's), 50 us per call on an idle machine and up to 1 ms on a loaded one,
    which booked to the controller made it look like 10 % of an iteration.  Their wall time is
    booked to ``harness`` instead (for a call timed inside another, e.g. PARDISO's phases inside
    ``factor``, taken off the outer label's time too)."""

    def __init__(self):
        self.t = defaultdict(float)       # wall time
        self.cpu = defaultdict(float)     # CPU time of the process (all its threads)
        self.n = defaultdict(int)
        self._open: list[float] = []      # harness time of the calls inside each open call

    def call(self, label: str, fn, *a, count: bool = True, **k):
        """``fn(*a, **k)``, its time booked to ``label`` (and the call counted, if ``count``)."""
        t_a = time.perf_counter()
        c_0 = time.process_time()
        t_b = time.perf_counter()
        self._open.append(0.0)
        try:
            return fn(*a, **k)
        finally:
            t_c = time.perf_counter()
            c_1 = time.process_time()
            t_d = time.perf_counter()
            inner = self._open.pop()
            own = (t_b - t_a) + (t_d - t_c)
            self.t[label] += t_c - t_b - inner
            self.cpu[label] += c_1 - c_0          # (the CPU basis keeps the clocks' cost)
            self.n[label] += count
            self.t["harness"] += own
            if self._open:
                self._open[-1] += own + inner

    def wrap(self, obj, name: str, label: str, count: bool = True):
        fn = getattr(obj, name)

        def timed(*a, **k):
            return self.call(label, fn, *a, count=count, **k)
        setattr(obj, name, timed)


def _wrap_compute(timers: Timers, group, label: str) -> None:
    """Time ``group.compute`` under ``label``, and the tangent it defers (``GroupResult.later``,
    computed when Newton reads the evaluation's data) under the same label."""
    fn = group.compute

    def timed(*a, **k):
        r = timers.call(label, fn, *a, **k)
        if r.later is not None:
            deferred = r.later
            r.later = lambda: timers.call(label, deferred)
        return r
    group.compute = timed


class _Stop(Exception):
    """Raised by the instrumented writer after ``max_increments`` increments."""


def run_one(nx: int, ny: int, solver: str = "AUTO", keep: str | None = None,
            max_increments: int | None = None, kernel: str = "AUTO",
            numba_from: int | None = None, controls: dict | None = None) -> dict:
    """Run press-then-slide at ``nx`` x ``ny``; return the measurements (a JSON-able dict).

    ``controls``: ``*CONTROLS`` values set in every step (``{"KRYLOV": 0}``, say).

    ``max_increments`` stops the run after that many converged increments (status
    ``"truncated"``): the time per iteration is measured, not that the whole run converges.
    ``numba_from``: ``KERNEL=AUTO``'s threshold of solid elements for this run
    (``kernels.AUTO_NUMBA_ELEMENTS``): what AUTO would do with another threshold."""
    from lagamine_py import kernels
    from lagamine_py.deck import load_deck
    from lagamine_py.output import default_writers
    from lagamine_py.solver import linear as linear_mod
    from lagamine_py.solver import problem as problem_mod
    from lagamine_py.solver import steps as steps_mod
    from lagamine_py.solver.linear import FreeDofs
    from lagamine_py.elements.base import LATER

    timers = Timers()
    work = Path(keep) if keep else Path(tempfile.mkdtemp(prefix=f"bench_{nx}x{ny}_"))
    work.mkdir(parents=True, exist_ok=True)
    deck = work / f"press_slide_{nx}x{ny}.dat"
    deck.write_text(press_slide_deck(nx, ny))
    t0 = time.perf_counter()
    model = load_deck(deck)
    t_deck = time.perf_counter() - t0
    for step in model.steps:
        step.controls["SOLVER"] = solver
        step.controls["KERNEL"] = kernel
        step.controls.update(controls or {})
    if numba_from is not None:
        kernels.AUTO_NUMBA_ELEMENTS = numba_from
    t0 = time.perf_counter()
    problem = problem_mod.build_problem(model)
    t_build = time.perf_counter() - t0

    labels = {"solid": "bulk", "contact": "contact", "pressure": "pressure"}
    for g, kind in zip(problem.groups, problem.kinds):
        _wrap_compute(timers, g, labels[kind])
        if hasattr(g, "compute_into"):          # the fused numba kernel: compute + scatter
            timers.wrap(g, "compute_into", labels[kind])
    # evaluations Newton asked with tangent=LATER, and those whose tangent was then read
    later_counts = {"later_evaluations": 0, "later_tangents": 0}
    orig_evaluate, orig_later_data = problem.evaluate, problem._later_data

    def evaluate(*a, **k):
        later_counts["later_evaluations"] += (a[4] if len(a) > 4 else k.get("tangent")) is LATER
        return orig_evaluate(*a, **k)

    def later_data(*a, **k):
        later_counts["later_tangents"] += 1
        return orig_later_data(*a, **k)
    problem.evaluate, problem._later_data = evaluate, later_data
    timers.wrap(problem.pattern, "assemble_data", "scatter")
    timers.wrap(problem.pattern, "group_vector", "scatter")
    orig_kff = FreeDofs.kff

    def kff(self, data, *a, **k):
        return timers.call("reduce", orig_kff, self, data, *a, **k)
    FreeDofs.kff = kff
    orig_free_init = FreeDofs.__init__        # the reduction's index maps, once per free set

    def free_init(self, *a, **k):
        return timers.call("reduce", orig_free_init, self, *a, count=False, **k)
    FreeDofs.__init__ = free_init
    # what the solvers did, recorded as numbers: a list of the solver objects would keep the
    # step-1 solver and its factor alive through step 2 (the peak memory then measured the
    # harness: 3.67 GB instead of the run's 2.57 GB at 309k DOFs)
    used: dict[str, int] = {}
    analyses = {}
    pardiso_memory = {"analysis_peak_mb": 0.0, "factor_mb": 0.0}
    orig_make = steps_mod.make_solver
    # the floor of an iteration: PARDISO's own phases (analysis, numerical factorisation,
    # substitution), timed inside the solver's calls; the rest of factor()/solve() (symmetry
    # test, copies, the residual check of the solve) is the solver's overhead
    orig_pardiso = linear_mod.PardisoSolver._pardiso
    phase_labels = {11: "pardiso_analysis", 22: "pardiso_factor", 33: "pardiso_solve"}

    def pardiso(self, phase, *a, **k):
        label = phase_labels.get(phase)
        if label is None:
            return orig_pardiso(self, phase, *a, **k)
        try:
            return timers.call(label, orig_pardiso, self, phase, *a, **k)
        finally:
            if phase != 33:              # iparm[14], [15] + [16]: PARDISO's memory (KB)
                pardiso_memory["analysis_peak_mb"] = max(pardiso_memory["analysis_peak_mb"],
                                                         self.iparm[14] / 1024.0)
                pardiso_memory["factor_mb"] = max(pardiso_memory["factor_mb"],
                                                  (self.iparm[15] + self.iparm[16]) / 1024.0)
    linear_mod.PardisoSolver._pardiso = pardiso
    orig_symmetric = linear_mod.PardisoSolver.is_symmetric      # inside factor: its share

    def is_symmetric(self, A):
        return timers.call("symmetry_test", orig_symmetric, self, A)
    linear_mod.PardisoSolver.is_symmetric = is_symmetric

    def make_solver(name):
        s = orig_make(name)
        timers.wrap(s, "factor", "factor")
        timers.wrap(s, "solve", "solve")
        inner_factor = s.factor

        def factor(A):
            inner_factor(A)
            impl = getattr(s, "impl", s)
            used[type(impl).__name__] = used.get(type(impl).__name__, 0) + 1
            analyses[id(s)] = getattr(impl, "analyses", 0)
        s.factor = factor
        return s
    steps_mod.make_solver = make_solver

    orig_save = steps_mod.Controller._save_restart

    def save_restart(self, *a, **k):
        timers.call("restart", orig_save, self, *a, **k)
    steps_mod.Controller._save_restart = save_restart
    # what the writers are handed, built by the controller once per increment: the solid
    # groups' cell blocks (stresses, strains: NLGEOM ln V) and the contact points
    orig_cells, orig_contacts = steps_mod.Controller._cells, steps_mod.Controller._contacts

    def cells(self, *a, **k):
        return timers.call("output_data", orig_cells, self, *a, **k)

    def contacts(self, *a, **k):
        return timers.call("output_data", orig_contacts, self, *a, **k)
    steps_mod.Controller._cells, steps_mod.Controller._contacts = cells, contacts

    writers = default_writers(work / "out", model)
    for w in writers:
        label = "vtk" if type(w).__name__.lower().startswith("vtk") else "other_output"
        timers.wrap(w, "increment", label)
        # the state at t = 0 and what a writer writes at the end are output too (they were
        # booked to the controller: 1.2 s of a 4-increment 320x160 run, 40 ms per iteration)
        timers.wrap(w, "initial", label, count=False)
        timers.wrap(w, "close", label, count=False)
    per_increment: list[tuple[int, int, int]] = []      # (step, solves, cut-backs)
    failures: list[dict] = []
    first = writers[0]
    inner_first = first.increment

    factor_marks: list[int] = []       # factorisations (failed attempts' too) up to each increment

    def counted(result):
        per_increment.append((result.step, result.iterations, result.cutbacks))
        factor_marks.append(timers.n["factor"])
        inner_first(result)
    first.increment = counted
    inner_failed = first.failed_attempt

    def failed(attempt):
        failures.append({"step": attempt.step, "increment": attempt.increment,
                         "dt": attempt.dt, "reason": attempt.reason,
                         "solves": attempt.iterations})
        inner_failed(attempt)
    first.failed_attempt = failed
    if max_increments:
        vtk = writers[0]
        inner_inc = vtk.increment

        def limited(result):
            inner_inc(result)
            if timers.n["vtk"] >= max_increments:
                raise _Stop()
        vtk.increment = limited
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        outcome = steps_mod.run(model, work / "out", writers=writers, problem=problem,
                                deck_path=deck)
        status, message = int(outcome.status), outcome.message
    except _Stop:
        status, message = "truncated", f"stopped after {max_increments} increments"
    t_run = time.perf_counter() - t0
    cpu_run = time.process_time() - c0
    FreeDofs.kff, FreeDofs.__init__ = orig_kff, orig_free_init
    steps_mod.make_solver = orig_make
    linear_mod.PardisoSolver._pardiso = orig_pardiso
    linear_mod.PardisoSolver.is_symmetric = orig_symmetric
    steps_mod.Controller._save_restart = orig_save
    steps_mod.Controller._cells, steps_mod.Controller._contacts = orig_cells, orig_contacts

    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    t = dict(timers.t)
    iters = timers.n["factor"]
    inner = COLUMNS[:-1]                      # disjoint parts of the run; the rest: controller
    t["controller"] = t_run - sum(t.get(k, 0.0) for k in inner)
    cpu = dict(timers.cpu)
    cpu["controller"] = cpu_run - sum(cpu.get(k, 0.0) for k in inner)
    nel = int(sum(len(b.ids) for b in model.blocks))
    cgroups = [g for g, kd in zip(problem.groups, problem.kinds) if kd == "contact"]
    ncontact_gp = int(sum(g.dofs.shape[0] for g in cgroups))
    return {
        "nx": nx, "ny": ny, "elements": nel, "dofs": int(problem.ndof),
        "nnz": int(problem.pattern.nnz), "contact_elements": ncontact_gp,
        "status": status, "message": message,
        "increments": timers.n["vtk"], "iterations": iters,
        "bulk_evaluations": timers.n["bulk"], **later_counts,
        "solver": solver, "kernel": kernel, "numba_from": kernels.AUTO_NUMBA_ELEMENTS,
        "fused_groups": int(sum(g.fused for g in problem.groups)),
        "solver_used": sorted(used), "pardiso_analyses": int(sum(analyses.values())),
        "pardiso_memory_mb": pardiso_memory,
        "cutbacks": len(failures), "failed_attempts": failures,
        "solves_per_increment": [n for _, n, _ in per_increment],
        "factorisations": timers.n["factor"], "back_substitutions": timers.n["solve"],
        "factorisations_per_increment": np.diff([0] + factor_marks).tolist(),
        "increment_steps": [st for st, _, _ in per_increment],
        "t_deck": t_deck, "t_build": t_build, "t_run": t_run, "times": t,
        "cpu_run": cpu_run, "cpu_times": cpu, "load_average": os.getloadavg(),
        "cpus": os.cpu_count(),
        "solid_split_calls": int(kernels.calls["solid_split"]),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "python": sys.version.split()[0], "numpy": np.__version__,
    }


# --------------------------------------------------------------------------------------------
# assembly micro-benchmark

def structured_q8(nx: int, ny: int, lx: float = 40.0, ly: float = 20.0):
    """Coordinates (n, 2) and Q8 connectivity (e, 8) of a structured nx x ny mesh."""
    nxn, nyn = 2 * nx + 1, 2 * ny + 1
    X, Y = np.meshgrid(np.linspace(0, lx, nxn), np.linspace(0, ly, nyn))
    odd = (np.arange(nyn)[:, None] % 2 == 1) & (np.arange(nxn)[None, :] % 2 == 1)
    keep = ~odd.ravel()
    index = np.full(nxn * nyn, -1)
    index[keep] = np.arange(keep.sum())
    xy = np.c_[X.ravel(), Y.ravel()][keep]
    ci, cj = np.meshgrid(2 * np.arange(nx), 2 * np.arange(ny))
    ci, cj = ci.ravel(), cj.ravel()

    def n(i, j):
        return index[j * nxn + i]
    conn = np.stack([n(ci, cj), n(ci + 2, cj), n(ci + 2, cj + 2), n(ci, cj + 2),
                     n(ci + 1, cj), n(ci + 2, cj + 1), n(ci + 1, cj + 2), n(ci, cj + 1)], axis=1)
    return xy, conn


def _best(fn, repeat: int, clock=time.perf_counter) -> float:
    """Best time of ``repeat`` calls (``clock=time.process_time``: CPU time, which a loaded
    machine inflates less than wall time)."""
    best = np.inf
    for _ in range(repeat):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def bench_assembly(nx: int = 160, ny: int = 80, repeat: int = 7) -> dict:
    """Microseconds per element of the bulk Q8 3x3 Ramberg-Osgood group (compute with tangent,
    then scatter into the CSR pattern), small strain and NLGEOM, every Gauss point plastic; the
    same through the fused numba kernel (``compute_into``: compute and scatter in one pass,
    after a warm-up call that compiles or loads it) when numba is installed; and microseconds
    per contact Gauss point of the press-slide contact group, pressed."""
    from lagamine_py.elements.base import StepContext
    from lagamine_py.registry import get
    from lagamine_py.solver.pattern import Pattern
    from lagamine_py.kernels import available as numba_available

    xy, conn = structured_q8(nx, ny)
    law = get("laws", "RAMBERG_OSGOOD")(E=E_STEEL, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0)
    group = get("elements", "Q8PE")(np.arange(len(conn)), conn, xy, law, 1.0)
    pattern = Pattern(2 * len(xy), [group.dofs])
    state = group.init_state()
    rng = np.random.default_rng(0)
    u_old = np.zeros_like(xy)
    u = np.c_[0.002 * xy[:, 0], -0.004 * xy[:, 1]] + 1e-4 * rng.standard_normal(xy.shape)
    ne, nq = len(conn), group.nq
    out = {"elements": ne, "dofs": 2 * len(xy), "numba": numba_available()}
    for nlgeom in (False, True):
        ctx = StepContext(nlgeom=nlgeom, t_old=0.0, t_new=1.0,
                          foundation_old={}, foundation_new={})
        res = group.compute(u, u_old, state, ctx, True)
        plastic = float((res.state["peeq"] > 0).mean())
        t_c = _best(lambda: group.compute(u, u_old, state, ctx, True), repeat)
        t_s = _best(lambda: (pattern.assemble_data([res.K]), pattern.group_vector(0, res.f)),
                    repeat)
        c_c = _best(lambda: group.compute(u, u_old, state, ctx, True), repeat, time.process_time)
        c_s = _best(lambda: (pattern.assemble_data([res.K]), pattern.group_vector(0, res.f)),
                    repeat, time.process_time)
        key = "nlgeom" if nlgeom else "small"
        out[key] = {"compute_us": 1e6 * t_c / ne, "scatter_us": 1e6 * t_s / ne,
                    "total_us": 1e6 * (t_c + t_s) / ne, "plastic_fraction": plastic,
                    "per_gauss_point_us": 1e6 * (t_c + t_s) / (ne * nq),
                    "cpu_total_us": 1e6 * (c_c + c_s) / ne,
                    "cpu_per_gauss_point_us": 1e6 * (c_c + c_s) / (ne * nq)}
        if out["numba"]:
            out[key].update(_bench_fused(group, pattern, u, u_old, state, ctx, repeat))
    out["contact"] = _bench_contact(repeat)
    return out


def _bench_fused(group, pattern, u, u_old, state, ctx, repeat: int) -> dict:
    """The fused numba kernel on the same group: zeroed CSR data and force vector, compute and
    scatter (what Problem.evaluate does for the group); us per element and per Gauss point, in
    a Newton iteration and (``numba_cpu_first_iteration_us``) in the first iteration of an
    increment, which also computes F_old^-1 and b_e_n (kept for the next iterations)."""
    def fused():
        data, f = np.zeros(pattern.nnz), np.zeros(pattern.ndof)
        return group.compute_into(u, u_old, state, ctx, True, data, f, pattern.positions[0])

    def first_iteration():                    # NLGEOM: start of the increment recomputed too
        group._cache.pop("kernel_old_key", None)
        return fused()

    t0 = time.perf_counter()
    fused()                                   # compiles, or loads from numba's cache
    first = time.perf_counter() - t0
    ne, nq = len(group.conn), group.nq
    t = _best(fused, repeat)
    c = _best(fused, repeat, time.process_time)
    c1 = _best(first_iteration, repeat, time.process_time)
    return {"numba_first_call_s": first, "numba_total_us": 1e6 * t / ne,
            "numba_per_gauss_point_us": 1e6 * t / (ne * nq),
            "numba_cpu_total_us": 1e6 * c / ne,
            "numba_cpu_per_gauss_point_us": 1e6 * c / (ne * nq),
            "numba_cpu_first_iteration_us": 1e6 * c1 / ne}


def _bench_contact(repeat: int, nx: int = 320, ny: int = 4) -> dict:
    """Contact group of press-slide (3 Gauss points per contact element), every point pressed
    into the foundation and sliding: microseconds per contact Gauss point, with the scatter.

    The top-level keys measure the default path at ``nx x ny`` (the numba kernels of the law
    and the projection when numba is installed); ``rows`` gives, for that group and for the
    120-point group of the 40x20 mesh (the fixed per-call cost dominates there), the NumPy path
    and the numba path side by side (:func:`_contact_case`)."""
    rows = []
    for mx, my in ((nx, ny), (40, 20)):
        for kernel in (False, True):
            rows.append(_contact_case(repeat, mx, my, kernel))
    default = next(r for r in rows if (r["nx"], r["ny"]) == (nx, ny)
                   and r["kernel"] == rows[1]["kernel_available"])
    out = {k: v for k, v in default.items() if k not in ("nx", "ny")}
    out["rows"] = rows
    return out


def _contact_case(repeat: int, nx: int, ny: int, kernel: bool) -> dict:
    """One contact measurement (see :func:`_bench_contact`): ``kernel`` False forces the NumPy
    path (``law.use_kernel = foundation.use_kernel = False``); True uses the numba kernels when
    numba imports (after a warm-up call that compiles them or loads them from the cache).
    ``cpu_first_us_per_gp``: the first Newton iteration of an increment, which also projects
    the start configuration (the group's cache of it cleared before each call)."""
    from lagamine_py.deck import load_deck
    from lagamine_py.elements.base import StepContext
    from lagamine_py.solver.problem import build_problem

    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(tmp) / "d.dat"
        deck.write_text(press_slide_deck(nx, ny))
        model = load_deck(deck)
    problem = build_problem(model)
    k = problem.kinds.index("contact")
    g = problem.groups[k]
    from lagamine_py import kernels
    available = kernels.module("contact") is not None
    g.use_kernels(kernel)
    states = problem.init_states()
    n = len(model.coords)
    u_old = np.zeros((n, 2))
    u = np.zeros((n, 2))
    bottom = model.coords[:, 1] < 1e-9
    u[bottom, 1] = -1e-4                       # pressed
    u[bottom, 0] = 1e-3                        # and slid
    ctx = StepContext(nlgeom=True, t_old=0.0, t_new=1.0,
                      foundation_old={"FLAT": np.zeros(2)}, foundation_new={"FLAT": np.zeros(2)})
    res = g.compute(u, u_old, states[k], ctx, True)         # warm-up (numba: compile / load)
    ngp = int(np.size(res.state.get("status", np.zeros(0))))

    def compute():
        g.compute(u, u_old, states[k], ctx, True)

    def first():
        g._start_cache = None
        g.compute(u, u_old, states[k], ctx, True)

    def scatter():
        problem.pattern.group_vector(k, res.f)
        problem.pattern.assemble_data([res.K if j == k else None
                                       for j in range(len(problem.groups))])
    t_c = _best(compute, repeat)
    t_s = _best(scatter, repeat)
    c_c = _best(compute, repeat, time.process_time)
    c_f = _best(first, repeat, time.process_time)
    # the scatter of a few contact blocks is dominated by zeroing the whole CSR data array
    c_s = _best(scatter, repeat, time.process_time)
    status = np.asarray(res.state.get("status")).ravel()
    per = 1e6 / max(ngp, 1)
    return {"nx": nx, "ny": ny, "kernel": bool(kernel and available),
            "kernel_available": available, "contact_elements": len(g.dofs), "gauss_points": ngp,
            "compute_us_per_gp": t_c * per, "total_us_per_gp": (t_c + t_s) * per,
            "cpu_compute_us_per_gp": c_c * per, "cpu_total_us_per_gp": (c_c + c_s) * per,
            "cpu_first_us_per_gp": c_f * per, "cpu_compute_us_per_call": 1e6 * c_c,
            "status_counts": {int(s): int((status == s).sum()) for s in np.unique(status)}}


# --------------------------------------------------------------------------------------------
# linear solvers

def bench_solvers(sizes, repeat: int = 5) -> list[dict]:
    """Factor + solve times of SPLU and PARDISO on the press-slide tangent at each size
    (tangent of the first iteration of the slide: contact, friction, non-symmetric), with the
    PARDISO analysis done once beforehand (as in a Newton loop)."""
    from lagamine_py.solver.linear import PardisoSolver, SpluSolver, pardiso_available

    rows = []
    for nx, ny in sizes:
        A, b = _slide_tangent(nx, ny)
        row = {"nx": nx, "ny": ny, "dofs": A.shape[0], "nnz": int(A.nnz)}
        cands = [("SPLU", SpluSolver)]
        if pardiso_available():
            cands.append(("PARDISO", PardisoSolver))
        x = {}
        for name, cls in cands:
            s = cls()
            s.factor(A)
            row[f"{name}_factor_s"] = _best(lambda: s.factor(A), repeat)
            row[f"{name}_solve_s"] = _best(lambda: s.solve(b), repeat)
            x[name] = s.solve(b)
            if name == "PARDISO":
                row["PARDISO_mode"] = "symmetric" if s.mtype == -2 else "non-symmetric"
        if len(x) == 2:
            row["rel_diff"] = float(np.abs(x["SPLU"] - x["PARDISO"]).max()
                                    / np.abs(x["SPLU"]).max())
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def bench_pardiso(sizes, repeat: int = 7) -> list[dict]:
    """PARDISO's factorisation with and without the two-level algorithm (``iparm[23] = 10``) on
    the press-slide tangent of :func:`bench_solvers`, and the symmetry test's cost against one
    factorisation + solve.  The threads MKL uses are the process's (run it under
    ``MKL_NUM_THREADS=1`` and ``=2``: ``pardiso-threads`` does both)."""
    from lagamine_py.solver import linear

    rows = []
    for nx, ny in sizes:
        A, b = _slide_tangent(nx, ny)
        row = {"nx": nx, "ny": ny, "dofs": A.shape[0], "nnz": int(A.nnz),
               "mkl_threads": os.environ.get("MKL_NUM_THREADS", "default")}
        # both solvers analysed, then their factorisations alternated: a shared machine's
        # load falls on both alike, and the ratio is taken per pair (median over the pairs)
        solvers, x = {}, {}
        for two in (False, True):
            linear.PardisoSolver.TWO_LEVEL = two
            solvers["two_level" if two else "default"] = s = linear.PardisoSolver()
            s.factor(A)
        times = {k: [] for k in solvers}
        for _ in range(repeat):
            for key, s in solvers.items():
                times[key].append(_best(lambda: s.factor(A), 1))
        for key, s in solvers.items():
            row[f"{key}_factor_s"] = float(np.median(times[key]))
            row[f"{key}_solve_s"] = _best(lambda: s.solve(b), repeat)
            x[key] = s.solve(b)
        row["two_level_over_default_pairs"] = [t2 / t1 for t1, t2 in
                                               zip(times["default"], times["two_level"])]
        s = solvers["two_level"]
        row["symmetry_test_s"] = _best(lambda: s.is_symmetric(A), 5 * repeat)
        d = A.data
        row["whole_symmetry_test_s"] = _best(
            lambda: np.abs(d - d[s._transposed(0, d.size)]).max() <= 1e-13 * np.abs(d).max(), 5 * repeat)
        for s in solvers.values():
            s._release()
        row["two_level_over_default"] = float(np.median(row["two_level_over_default_pairs"]))
        row["symmetry_over_factor_solve"] = (row["symmetry_test_s"]
                                             / (row["two_level_factor_s"] + row["two_level_solve_s"]))
        row["rel_diff"] = float(np.abs(x["default"] - x["two_level"]).max()
                                / np.abs(x["default"]).max())
        row["load_average"] = os.getloadavg()
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def _slide_tangent(nx: int, ny: int):
    """The reduced press-slide tangent of :func:`bench_solvers` (contact pressed and sliding,
    follower pressure: non-symmetric) and a right-hand side."""
    from lagamine_py.deck import load_deck
    from lagamine_py.elements.base import StepContext
    from lagamine_py.solver.linear import FreeDofs
    from lagamine_py.solver.problem import build_problem

    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(tmp) / "d.dat"
        deck.write_text(press_slide_deck(nx, ny))
        model = load_deck(deck)
    problem = build_problem(model)
    n = len(model.coords)
    u = np.zeros(2 * n)
    bottom = np.flatnonzero(model.coords[:, 1] < 1e-9)
    u[2 * bottom + 1] = -1e-4
    u[2 * bottom] = 1e-3
    problem.set_pressures({"PRESSED": 200.0})
    still = {"FLAT": np.zeros(2)}
    ctx = StepContext(nlgeom=True, t_old=0.0, t_new=1.0, foundation_old=still,
                      foundation_new=still)
    ev = problem.evaluate(u, np.zeros(2 * n), problem.init_states(), ctx, True)
    right = np.flatnonzero(model.coords[:, 0] > 40 - 1e-9)
    A = FreeDofs(problem.pattern, 2 * right).kff(ev.data)
    return A, np.random.default_rng(0).standard_normal(A.shape[0])


def bench_startup(repeat: int = 5, trees: list[Path] | None = None,
                  bytecode: bool = True) -> list[dict]:
    """Best whole-process wall time, and the CPU time (user + system) and peak resident memory
    of the same runs, of ``lagamine-py --help``, ``check`` and ``run`` of the main job
    (``decks/press_slide.dat``), each in a fresh interpreter, with the byte code compiled
    (``PYTHONDONTWRITEBYTECODE`` unset, one run beforehand) as after an install, or, with
    ``bytecode=False``, as this machine's agents run (the variable set and a copy of each tree
    without ``__pycache__``: every start compiles lagamine_py from source; numpy's and scipy's
    byte code is the install's).  CPU time is what a loaded machine changes least.  ``trees``:
    source trees to compare (e.g. an export of an older commit), their runs interleaved so a
    shared machine's load falls on all alike; default this one."""
    trees = trees or [ROOT]
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    jobs = {"help": ["--help"], "check": ["check", str(DECK)]}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        run_trees = {t: t for t in trees}
        if not bytecode:
            # a copy of each tree's package without byte code, which none of the runs writes
            env["PYTHONDONTWRITEBYTECODE"] = "1"
            for k, t in enumerate(trees):
                run_trees[t] = Path(tmp) / f"tree{k}"
                shutil.copytree(Path(t) / "lagamine_py", run_trees[t] / "lagamine_py",
                                ignore=shutil.ignore_patterns("__pycache__"))
        jobs["run"] = ["run", str(DECK), "-q", "--overwrite", "-o", str(Path(tmp) / "out")]
        best = {(t, j, k): np.inf for t in trees for j in jobs for k in ("wall", "cpu", "mb")}
        for i in range(repeat + 1):
            for t in trees:
                for j, argv in jobs.items():
                    t0 = time.perf_counter()
                    proc = subprocess.Popen([sys.executable, "-m", "lagamine_py", *argv],
                                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                            cwd=tmp, env=dict(env, PYTHONPATH=str(run_trees[t])))
                    _, status, usage = os.wait4(proc.pid, 0)
                    wall = time.perf_counter() - t0
                    proc.returncode = os.waitstatus_to_exitcode(status)
                    if proc.returncode:
                        raise RuntimeError(f"{argv} in {t}: {proc.stderr.read().decode()}")
                    proc.stderr.close()
                    if i:                                   # the first round compiles
                        for k, v in (("wall", wall), ("cpu", usage.ru_utime + usage.ru_stime),
                                     ("mb", usage.ru_maxrss / 1024)):
                            best[t, j, k] = min(best[t, j, k], v)
        for t in trees:
            rows.append({"tree": str(t), **{j: best[t, j, "wall"] for j in jobs},
                         **{f"{j}_cpu": best[t, j, "cpu"] for j in jobs},
                         **{f"{j}_peak_mb": best[t, j, "mb"] for j in jobs},
                         "bytecode": bytecode, "load_average": os.getloadavg()})
    return rows


_MODULES_OF_RUN = """
import json, sys
from lagamine_py.cli import main
status = main(["run", sys.argv[1], "-q", "--overwrite", "-o", sys.argv[2]])
print(json.dumps([m for m in sys.modules if m != "__main__"]))
"""

_IMPORT_ONLY = """
import importlib, json, sys
from lagamine_py.core.threads import pin_openblas_at_load
from lagamine_py.core.lazy_modules import defer_numpy_submodules
pin_openblas_at_load()
defer_numpy_submodules()          # as a run: numpy's f2py and testing stay lazy
for m in json.load(open(sys.argv[1])):
    if m not in sys.modules:
        try:
            importlib.import_module(m)
        except Exception:         # a module some other import created under that name
            pass
"""


def bench_floor(decks: list[Path], repeat: int = 7) -> list[dict]:
    """The fixed cost no optimisation of ours removes: per deck, the best whole-process wall
    time, least CPU time and peak memory of (a) ``python -c pass``, (b) ``import numpy,
    scipy.sparse``, (c) a process that imports exactly the modules a run of the deck ends with
    (read from a run, imported in that order, numpy's deferred modules left lazy as a run does)
    and nothing else, and (d) the run itself (``lagamine-py run DECK``); interleaved, one MKL
    and OpenMP thread, byte code as after an install (``PYTHONDONTWRITEBYTECODE`` unset)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(MKL_NUM_THREADS="1", OMP_NUM_THREADS="1")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for deck in decks:
            deck = Path(deck).resolve()
            res = subprocess.run([sys.executable, "-c", _MODULES_OF_RUN, str(deck), f"{tmp}/mods"],
                                 capture_output=True, text=True, env=env, cwd=tmp, check=True)
            (Path(tmp) / "modules.json").write_text(res.stdout.strip().splitlines()[-1])
            jobs = {"python": [sys.executable, "-c", "pass"],
                    "numpy_scipy_sparse": [sys.executable, "-c", "import numpy, scipy.sparse"],
                    "imports_of_run": [sys.executable, "-c", _IMPORT_ONLY, f"{tmp}/modules.json"],
                    "run": [sys.executable, "-m", "lagamine_py", "run", str(deck), "-q",
                            "--overwrite", "-o", f"{tmp}/out"]}
            best = {(j, k): np.inf for j in jobs for k in ("wall", "cpu", "peak_mb")}
            for i in range(repeat + 1):
                for j, argv in jobs.items():
                    r = _process(argv, env, tmp)
                    if i:                               # the first round warms the caches
                        for k in ("wall", "cpu", "peak_mb"):
                            best[j, k] = min(best[j, k], r[k])
            row = {"deck": str(deck), "modules": len(json.loads((Path(tmp) / "modules.json").read_text()))}
            row.update({f"{j}_{k}": best[j, k] for j in jobs for k in ("wall", "cpu", "peak_mb")})
            row["load_average"] = os.getloadavg()
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def _process(argv: list[str], env: dict, cwd: str) -> dict:
    """Wall time, CPU time (user + system) and peak resident MB of one child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=cwd,
                            env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status):
        raise RuntimeError(f"{argv}: {err}")
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024}


def bench_first_run(nx: int = 80, ny: int = 40) -> dict:
    """A fresh install's first press-then-slide run against a warm one (issue 17 item 4): each
    in its own process, one MKL thread (so the counts repeat), numba's cache in an empty
    ``NUMBA_CACHE_DIR``: ``cold`` the first run as is (it compiles the solid kernel),
    ``compile`` then ``after_compile`` the same with ``lagamine-py compile`` first, ``warm`` a
    run on that cache.  Ratios to ``warm`` on CPU time, which the load of a shared machine
    changes least, and on wall time."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["MKL_NUM_THREADS"] = "1"
    out = {"mesh": f"{nx}x{ny}"}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "ps.dat").write_text(press_slide_deck(nx, ny))
        run = [sys.executable, "-m", "lagamine_py", "run", "ps.dat", "-q", "--overwrite", "-o"]
        compile_ = [sys.executable, "-m", "lagamine_py", "compile"]
        a, b = dict(env, NUMBA_CACHE_DIR=f"{tmp}/cache_a"), dict(env, NUMBA_CACHE_DIR=f"{tmp}/cache_b")
        out["cold"] = _process(run + ["out_a"], a, tmp)
        out["compile"] = _process(compile_, b, tmp)
        out["after_compile"] = _process(run + ["out_b"], b, tmp)
        out["warm"] = _process(run + ["out_c"], b, tmp)
    for k in ("cold", "after_compile"):
        for q in ("cpu", "wall"):
            out[f"{k}/warm {q}"] = out[k][q] / out["warm"][q]
    out["load_average"] = os.getloadavg()
    return out


# --------------------------------------------------------------------------------------------
# report

COLUMNS = ("bulk", "contact", "pressure", "scatter", "reduce", "factor", "solve", "vtk",
           "other_output", "output_data", "restart", "harness", "controller")


#: PARDISO's own phases (timed inside factor and solve by ``run_one``)
FLOOR = ("pardiso_analysis", "pardiso_factor", "pardiso_solve")


def _per_it(r: dict, basis: str) -> dict:
    """Seconds per Newton iteration of each column, on ``basis`` "cpu" (process CPU time, all
    threads) or "wall"; ``floor`` the factorisation and solve themselves: PARDISO's phases
    (analysis, numerical factorisation, substitution) when recorded, else the whole ``factor``
    and ``solve`` calls (SPLU, older results)."""
    it = max(r["iterations"], 1)
    t = r.get("cpu_times") if basis == "cpu" else r["times"]
    out = {c: t.get(c, 0.0) / it for c in COLUMNS}
    phases = sum(t.get(c, 0.0) for c in FLOOR)
    out["floor"] = phases / it if phases else out["factor"] + out["solve"]
    return out


def iteration_over_floor(r: dict, basis: str = "wall") -> float:
    """A Newton iteration's cost (the whole run's time per linear solve: assembly, contact,
    solver overhead, output, restart, controller; not the benchmark's clocks) over the floor
    (:func:`_per_it`)."""
    per = _per_it(r, basis)
    return _run_cost(per) / per["floor"] if per["floor"] else float("nan")


def _run_cost(per: dict) -> float:
    """The run's time per iteration without the benchmark's own clocks (``harness``)."""
    return sum(per[c] for c in COLUMNS if c != "harness")


def report(results: list[dict], png: Path | None, basis: str = "cpu") -> str:
    """Markdown table (ms per Newton iteration, CPU time by default) and, if ``png``, the
    log-log plot.  ``total``: the run per iteration without the benchmark's clocks
    (``harness``); ``floor``: PARDISO's analysis, factorisation and substitution (the whole
    factor and solve calls for SPLU); ``iteration / floor`` their ratio (issue 17 item 8);
    ``non-factor / factor``: everything but the ``factor`` call over it (the earlier measure;
    with CPU time the factorisation counts the CPU of all MKL threads)."""
    results = [r for r in results if basis != "cpu" or r.get("cpu_times")]
    head = ("| mesh | DOFs | status | incr. | Newton it. | " + " | ".join(COLUMNS)
            + " | total | floor | **iteration / floor** | non-factor / factor | output share | "
              "wall/it | load | peak MB |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in results:
        per = _per_it(r, basis)
        total = _run_cost(per)
        fac = per["factor"]
        out = per["vtk"] + per["other_output"] + per["output_data"]
        ratio = (total - fac) / fac if fac else float("nan")
        load = r.get("load_average")
        lines.append(
            f"| {r['nx']}x{r['ny']} | {r['dofs']} | {_status(r['status'])} "
            f"| {r['increments']} | {r['iterations']} | "
            + " | ".join(f"{1e3 * per[c]:.1f}" for c in COLUMNS)
            + f" | {1e3 * total:.1f} | {1e3 * per['floor']:.1f} "
            f"| **{iteration_over_floor(r, basis):.2f}** | {ratio:.2f} | {out / total:.3f} "
            f"| {1e3 * r['t_run'] / max(r['iterations'], 1):.0f} "
            + (f"| {load[0]:.1f} " if load else "| - ") + f"| {r['peak_rss_mb']:.0f} |")
    if png is not None and results:
        _plot(results, png, basis)
    return "\n".join(lines)


def _status(status) -> str:
    return {0: "converged", "truncated": "truncated"}.get(status, f"FAILED ({status})")


def _plot(results, png: Path, basis: str = "cpu") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dofs = np.array([r["dofs"] for r in results], float)
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    groups = {"total": COLUMNS, "bulk assembly + scatter": ("bulk", "scatter"),
              "contact": ("contact",), "factorisation": ("factor",), "solve": ("solve",),
              "output (VTK, tables)": ("vtk", "other_output", "output_data")}
    for label, cols in groups.items():
        y = np.array([sum(_per_it(r, basis)[c] for c in cols) for r in results])
        ax.loglog(dofs, 1e3 * y, "o-", label=label)
    ref = 1e3 * sum(_per_it(results[0], basis)[c] for c in ("bulk", "scatter"))
    ax.loglog(dofs, ref * dofs / dofs[0], "k:", lw=0.8, label="slope 1")
    ax.set_xlabel("DOFs")
    ax.set_ylabel(f"{'CPU' if basis == 'cpu' else 'wall'} time per Newton iteration (ms)")
    ax.set_title("press-then-slide, Q8 NLGEOM Ramberg-Osgood + Coulomb contact", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


# --------------------------------------------------------------------------------------------
# VTU encodings: write time, size, and whether meshio reads the file

VTU_ENCODINGS = (("appended raw", "none", None), ("appended raw", "lz4", None),
                 ("appended raw", "zlib", 1), ("appended base64", "none", None),
                 ("appended base64", "zlib", 1), ("appended base64", "zlib", 6),
                 ("inline base64", "zlib", 1))


def bench_vtu(path: Path, repeat: int = 12) -> list[dict]:
    """Write the grid of the VTU ``path`` (a body file of a run) with each encoding of
    :data:`VTU_ENCODINGS`, ``repeat`` times: median write time, size, meshio's verdict."""
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader, vtkXMLUnstructuredGridWriter
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    grid = reader.GetOutput()
    try:
        import meshio
    except ImportError:
        meshio = None
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "x.vtu"
        for mode, comp, level in VTU_ENCODINGS:
            times = []
            for _ in range(repeat):
                w = vtkXMLUnstructuredGridWriter()
                w.SetFileName(str(out))
                w.SetInputData(grid)
                if mode.startswith("appended"):
                    w.SetDataModeToAppended()
                    w.SetEncodeAppendedData(mode.endswith("base64"))
                else:
                    w.SetDataModeToBinary()
                {"none": w.SetCompressorTypeToNone, "lz4": w.SetCompressorTypeToLZ4,
                 "zlib": w.SetCompressorTypeToZLib}[comp]()
                if level is not None:
                    w.SetCompressionLevel(level)
                t0 = time.perf_counter()
                w.Write()
                times.append(time.perf_counter() - t0)
            verdict = "not installed"
            if meshio is not None:
                try:
                    meshio.read(out)
                    verdict = "reads"
                except Exception as exc:            # what meshio says is the measurement
                    verdict = f"fails ({type(exc).__name__})"
            rows.append({"encoding": mode, "compressor": comp, "level": level,
                         "ms": 1e3 * float(np.median(times[2:] or times)),
                         "MB": out.stat().st_size / 1e6, "meshio": verdict})
    return rows


def _size(text: str) -> tuple[int, int]:
    nx, ny = text.lower().split("x")
    return int(nx), int(ny)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("scale")
    p.add_argument("--sizes", nargs="+", type=_size,
                   default=[(40, 20), (80, 40), (160, 80), (320, 160)])
    p.add_argument("--solver", default="AUTO")
    p.add_argument("--json", type=Path, default=Path("bench_scale.json"))
    p.add_argument("--timeout", type=float, default=None, help="seconds per size")
    p.add_argument("--max-increments", type=int, nargs="+", default=[0],
                   help="per size (0: the whole run); one value applies to every size")
    p.add_argument("--kernel", default="AUTO", choices=("AUTO", "NUMPY", "NUMBA"))
    p = sub.add_parser("one")
    p.add_argument("nx", type=int)
    p.add_argument("ny", type=int)
    p.add_argument("--solver", default="AUTO")
    p.add_argument("--json", type=Path)
    p.add_argument("--keep", help="work directory to keep (deck and output)")
    p.add_argument("--max-increments", type=int)
    p.add_argument("--kernel", default="AUTO", choices=("AUTO", "NUMPY", "NUMBA"))
    p.add_argument("--numba-from", type=int, help="KERNEL=AUTO's solid-element threshold "
                   "for this run (kernels.AUTO_NUMBA_ELEMENTS)")
    p.add_argument("--controls", nargs="+", default=[], metavar="KEY=VALUE",
                   help="*CONTROLS values for every step (e.g. KRYLOV=0)")
    p.add_argument("--split-elements", type=int, metavar="N", help="the numba solid kernel's "
                   "element ranges on threads from 2N elements (SolidElement.split_elements; "
                   "the threads: LAGAMINE_THREADS)")
    p = sub.add_parser("assembly")
    p.add_argument("--nx", type=int, default=160)
    p.add_argument("--ny", type=int, default=80)
    p = sub.add_parser("solvers")
    p.add_argument("--sizes", nargs="+", type=_size,
                   default=[(20, 10), (40, 20), (60, 30), (80, 40), (120, 60)])
    p = sub.add_parser("pardiso")
    p.add_argument("--sizes", nargs="+", type=_size, default=[(80, 40), (160, 80), (320, 160)])
    p.add_argument("--json", type=Path)
    p = sub.add_parser("pardiso-threads")
    p.add_argument("--sizes", nargs="+", default=["80x40", "160x80", "320x160"])
    p.add_argument("--json", type=Path, default=Path("bench_pardiso.json"))
    p = sub.add_parser("startup")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--trees", type=Path, nargs="+", help="source trees to compare (default: "
                   "this one), e.g. `git archive COMMIT | tar -x -C DIR`")
    p.add_argument("--no-bytecode", action="store_true", help="with PYTHONDONTWRITEBYTECODE=1 "
                   "(every start compiles lagamine_py from source)")
    p = sub.add_parser("floor")
    p.add_argument("--decks", type=Path, nargs="+", default=[DECK])
    p.add_argument("--repeat", type=int, default=7)
    p = sub.add_parser("first-run")
    p.add_argument("--size", type=_size, default=(80, 40))
    p = sub.add_parser("vtu")
    p.add_argument("file", type=Path, help="a body .vtu of a run (e.g. of `one 160 80 --keep DIR`)")
    p.add_argument("--repeat", type=int, default=12)
    p = sub.add_parser("report")
    p.add_argument("--json", type=Path, nargs="+", required=True)
    p.add_argument("--png", type=Path)
    p.add_argument("--basis", choices=("cpu", "wall"), default="cpu")
    args = ap.parse_args(argv)

    if args.cmd == "one":
        controls = dict(kv.split("=", 1) for kv in args.controls)
        if args.split_elements:
            from lagamine_py.elements.solid import SolidElement
            SolidElement.split_elements = args.split_elements
        res = run_one(args.nx, args.ny, args.solver, args.keep, args.max_increments, args.kernel,
                      args.numba_from, controls)
        text = json.dumps(res, indent=1)
        if args.json:
            args.json.write_text(text)
        print(text)
        print(report([res], None, "wall"))
        return 0 if res["status"] in (0, "truncated") else 1
    if args.cmd == "scale":
        results = []
        limits = args.max_increments * (len(args.sizes) if len(args.max_increments) == 1 else 1)
        for (nx, ny), limit in zip(args.sizes, limits):
            out = args.json.with_name(f"{args.json.stem}_{nx}x{ny}.json")
            cmd = [sys.executable, __file__, "one", str(nx), str(ny), "--solver", args.solver,
                   "--kernel", args.kernel, "--json", str(out)] + (["--max-increments", str(limit)] if limit else [])
            print(f"== {nx}x{ny}: {' '.join(cmd)}", flush=True)
            try:
                subprocess.run(cmd, timeout=args.timeout, capture_output=True)
            except subprocess.TimeoutExpired:
                print(f"   {nx}x{ny}: timed out after {args.timeout} s", flush=True)
                continue
            if out.exists():
                results.append(json.loads(out.read_text()))
                print(report(results[-1:], None, "wall").splitlines()[-1], flush=True)
        args.json.write_text(json.dumps(results, indent=1))
        print(report(results, None, "wall"))
        return 0
    if args.cmd == "assembly":
        print(json.dumps(bench_assembly(args.nx, args.ny), indent=1))
        return 0
    if args.cmd == "solvers":
        bench_solvers(args.sizes)
        return 0
    if args.cmd == "vtu":
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
        r = vtkXMLUnstructuredGridReader()
        r.SetFileName(str(args.file))
        r.Update()
        print(f"{args.file}: {r.GetOutput().GetNumberOfPoints()} points, "
              f"{r.GetOutput().GetNumberOfCells()} cells; median of {args.repeat} writes")
        print("| encoding | compressor | ms | MB | meshio |\n|---|---|---|---|---|")
        for row in bench_vtu(args.file, args.repeat):
            comp = row["compressor"] + (f" {row['level']}" if row["level"] else "")
            print(f"| {row['encoding']} | {comp} | {row['ms']:.1f} | {row['MB']:.2f} | {row['meshio']} |")
        return 0
    if args.cmd == "pardiso":
        rows = bench_pardiso(args.sizes)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
        return
    if args.cmd == "pardiso-threads":
        rows = []
        for threads in ("1", "2"):
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "p.json"
                subprocess.run([sys.executable, __file__, "pardiso", "--sizes", *args.sizes,
                                "--json", str(out)], check=True,
                               env=dict(os.environ, MKL_NUM_THREADS=threads))
                rows += json.loads(out.read_text())
        args.json.write_text(json.dumps(rows, indent=1))
        return
    if args.cmd == "startup":
        for row in bench_startup(args.repeat, args.trees, not args.no_bytecode):
            print(json.dumps(row))
        return 0
    if args.cmd == "floor":
        bench_floor(args.decks, args.repeat)
        return 0
    if args.cmd == "first-run":
        print(json.dumps(bench_first_run(*args.size), indent=1))
        return 0
    if args.cmd == "report":
        results = []
        for f in args.json:
            data = json.loads(f.read_text())
            results.extend(data if isinstance(data, list) else [data])
        results.sort(key=lambda r: r["dofs"])
        print(report(results, args.png, args.basis))
        return 0
    return 2


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    sys.exit(main())
