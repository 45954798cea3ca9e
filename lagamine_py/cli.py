"""The ``lagamine-py`` command: run | check | plugins | compare | plot | sweep.

Heavy modules (the solver, vtk, matplotlib) are imported inside the sub-commands so that
``lagamine-py --help`` answers at once.

Every error ends with one message on stderr and an exit status (DECKS.md): 2 for a deck error
(at most :data:`MAX_DECK_ERRORS` of them are printed, then their count), an output directory in
use or holding another deck's results, a restart of another deck; 1 for anything else -- a
file that cannot be read or written, damaged restart data, a plugin that raised.  ``--debug``
shows the traceback of an unexpected error instead.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from contextlib import contextmanager
from pathlib import Path

from .core.exits import EXIT_DECK, EXIT_INTERRUPTED, EXIT_OK, EXIT_OTHER, sigterm_interrupts

MAX_DECK_ERRORS = 50        # deck errors printed; the others are counted

MAX_DECK_ERRORS = 50        # deck errors printed; the others are counted


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="lagamine-py",
        description="2D / axisymmetric large-strain finite elements with frictional contact "
                    "(Godinas, Charlier & Cescotto), driven by .dat decks.")
    ap.add_argument("--debug", action="store_true",
                    help="show the traceback of an unexpected error (a bug, a plugin that raised)")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show the traceback of an unexpected error")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    run = sub.add_parser("run", parents=[common], help="run a deck", description="Run a .dat deck and write the "
                         "VTK series, contact and reaction tables, status and log files.")
    run.add_argument("deck", type=Path, nargs="?", help="the .dat deck (not needed with --restart)")
    run.add_argument("-o", "--output", type=Path, help="output directory (default: <deck stem>_out "
                     "next to the current directory)")
    run.add_argument("--restart", type=Path, metavar="OUT",
                     help="resume the run whose output directory is OUT from its last converged "
                          "increment (its deck and --param values are those recorded there)")
    run.add_argument("--overwrite", action="store_true",
                     help="replace the results of another deck in the output directory (a rerun "
                          "of the same deck always replaces its own)")
    run.add_argument("--solver", type=str.upper, metavar="NAME",
                     help="sparse linear solver, any registered one: AUTO, SPLU, PARDISO or a "
                          "plugin's (overrides the deck's *CONTROLS SOLVER)")
    run.add_argument("--kernel", type=str.upper, choices=("AUTO", "NUMPY", "NUMBA"),
                     help="solid-element kernel (overrides the deck's *CONTROLS KERNEL): NUMBA "
                          "needs the fast extra (numba); AUTO uses it when installed, from 2000 "
                          "solid elements")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    run.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                     help="override a *PARAMETER value of the deck (repeatable)")

    chk = sub.add_parser("check", parents=[common], help="parse and validate a deck without running it")
    chk.add_argument("deck", type=Path)
    chk.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                     help="override a *PARAMETER value of the deck (repeatable)")

    plugins = sub.add_parser("plugins", parents=[common], help="list installed elements, laws, contact laws, writers, solvers and checks "
        "with their parameters; --check runs their contract checks",
        description="List the registered plugins of every kind with their distribution and "
                    "parameters.  With --check, run each plugin's contract checks (tangents "
                    "against finite differences, patch tests, flushed output ...) and print "
                    "what passed and what failed, with the numbers; exit status 1 when one "
                    "failed.")
    plugins.add_argument("names", nargs="*", metavar="NAME",
                         help="only these plugins (names as decks write them, any kind)")
    plugins.add_argument("--check", action="store_true",
                         help="run the contract checks (lagamine_py.contracts) on the plugins")

    cmp_ = sub.add_parser("compare", parents=[common], help="compare a run with an archived reference")
    cmp_.add_argument("run", type=Path)
    cmp_.add_argument("ref", type=Path)
    cmp_.add_argument("--tol", action="append", default=[], metavar="QTY=REL[,ABS]",
                      help="tolerance override per quantity, e.g. --tol p=1e-6,1e-3")

    plot = sub.add_parser("plot", parents=[common], help="PNG charts of a run (p and tau along the interface, forces, mesh)")
    plot.add_argument("run", type=Path)
    plot.add_argument("-o", "--output", type=Path, help="directory for the PNG files (default RUN/plots)")
    plot.add_argument("--states", metavar="LIST",
                      help="states to draw: comma-separated STEP:INC, STEP (end of the step) or @TIME "
                           "(default: end of each step and thirds of the last step)")
    plot.add_argument("--axes", choices=("auto", "xy", "rz"), default="auto",
                      help="rz draws z horizontal and r vertical (default: rz when the run's deck is "
                           "axisymmetric)")
    plot.add_argument("--xlim", metavar="MIN,MAX",
                      help="abscissa range of interface.png (default: zoomed on the closed contact "
                           "zone when it is a small part of the interface)")
    plot.add_argument("--scale", type=float, metavar="FACTOR",
                      help="factor of the displacements in mesh.png (default: chosen so that the "
                           "deformation shows; 1 for the true shape)")

    comp = sub.add_parser("compile", parents=[common], help="compile the fast extra's kernels ahead "
                          "(once, after installing it)", description="Compile the numba "
                          "solid-element kernel that KERNEL=AUTO uses from 2000 solid elements into "
                          "numba's on-disk cache, so that the first large run does not pay its "
                          "compile (~10 s); --contact also the contact kernel (KERNEL=NUMBA only).  "
                          "Says where the cache is.")
    comp.add_argument("--contact", action="store_true", help="also the contact kernel")
    sweep = sub.add_parser("sweep", parents=[common], help="run a deck over a grid of *PARAMETER values")
    sweep.add_argument("deck", type=Path)
    sweep.add_argument("--set", action="append", default=[], metavar="NAME=v1,v2,...", dest="sets")
    sweep.add_argument("-o", "--output", type=Path, required=True)
    sweep.add_argument("-j", "--jobs", type=int, default=1)
    sweep.add_argument("--scheduler", help="address of a dask.distributed scheduler")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    handler = {"run": _cmd_run, "check": _cmd_check, "plugins": _cmd_plugins,
               "compare": _cmd_compare, "plot": _cmd_plot, "sweep": _cmd_sweep,
               "compile": _cmd_compile}[args.command]
    try:
        return handler(args)
    except KeyboardInterrupt:            # outside a run's steps (a run reports it itself)
        print("lagamine-py: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:                 # the reader went away (``| head``): stop quietly
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except Exception as exc:
        if args.debug:
            raise
        status, text = _error_text(exc)
        print(f"lagamine-py {args.command}: {text}", file=sys.stderr)
        return status


def _error_text(exc: Exception) -> tuple[int, str]:
    """The exit status and the one message of an error that reached the command line."""
    from .core.outdir import OutputDirError
    if isinstance(exc, OutputDirError):
        return EXIT_DECK, str(exc)
    if isinstance(exc, OSError):
        what = exc.strerror or str(exc)
        return EXIT_OTHER, f"{exc.filename}: {what}" if exc.filename else what
    if isinstance(exc, MemoryError):
        return EXIT_OTHER, "out of memory"
    return EXIT_OTHER, (f"{type(exc).__name__}: {exc} (an unexpected error, in lagamine-py or "
                        f"in a plugin; `lagamine-py --debug ...` shows where)")


def _parameters(items: list[str]) -> dict[str, str] | None:
    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        if not eq or not name.strip():
            raise ValueError(f"--param {item!r}: expected NAME=VALUE")
        out[name.strip()] = value.strip()
    return out


def _load(deck: Path, params: list[str] = ()):
    """Load a deck; on a deck error print it and return None."""
    from .deck import DeckError, load_deck
    try:
        return load_deck(deck, parameters=_parameters(list(params)) or None)
    except ValueError as exc:
        print(f"lagamine-py: {exc}", file=sys.stderr)
        return None
    except DeckError as exc:
        print(f"lagamine-py: the deck has errors; nothing was run:\n{exc.report(MAX_DECK_ERRORS)}",
              file=sys.stderr)
        return None


def _cmd_check(args) -> int:
    if not _thread_setting_ok("check"):
        return EXIT_DECK
    model = _load(args.deck, args.param)
    if model is None:
        return EXIT_DECK
    for notice in model.notices:           # a run logs them as warnings
        print(f"lagamine-py: notice: {notice}", file=sys.stderr)
    print(f"{args.deck}: OK ({len(model.node_ids)} nodes, "
          f"{sum(len(b.ids) for b in model.blocks)} elements, {len(model.steps)} steps)")
    return EXIT_OK


#: the model ``lagamine-py compile`` runs with KERNEL=NUMBA: every branch of the solid kernel
#: is compiled at its first call (the law, NLGEOM and axisymmetry are values, not types), so
#: one small run compiles the machine code any later run loads.  <CONTACT> adds a foundation.
COMPILE_DECK = """*MESH, NAME=B, TYPE=Q8PE, X0=0, Y0=0, LX=2, LY=1, NX=2, NY=1
*MATERIAL, NAME=M, LAW=RAMBERG_OSGOOD
E=210000, NU=0.3, SIGMA0=250, ALPHA=0.5, N=10
*SOLID, ELSET=B, MATERIAL=M
<CONTACT>*STEP, NAME=PRESS, NLGEOM=YES
*STATIC
0.5, 1, 0.01, 0.5
*CONTROLS
KERNEL=NUMBA
*BOUNDARY
B_LEFT, 1, 1, 0
<FIX>B_TOP, 2, 2, -0.002
*END STEP
"""
COMPILE_CONTACT = """*FOUNDATION, NAME=FLAT
-10, 0
0, 0
10, 0
*CONTACT LAW, NAME=DRY, TYPE=COULOMB
KP=2e7, KT=2e7, PHI=0.2, B=0
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=FLAT, LAW=DRY
"""


def _cmd_compile(args) -> int:
    import logging
    import tempfile
    import time

    from . import kernels
    # the compile model's own advice (a cold cache, penalties) is nothing for the user to act on
    logging.getLogger("lagamine_py.advice").addHandler(logging.NullHandler())
    if not kernels.available():
        print("lagamine-py compile: numba is not installed (pip install 'lagamine_py[fast]'); "
              "runs use the NumPy kernels, nothing to compile", file=sys.stderr)
        return EXIT_OTHER
    from .deck import load_deck
    from .solver import run
    deck = COMPILE_DECK.replace("<CONTACT>", COMPILE_CONTACT if args.contact else "")
    deck = deck.replace("<FIX>", "" if args.contact else "B_BOTTOM, 2, 2, 0\n")
    t0 = time.process_time()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "compile.dat"
        path.write_text(deck)
        outcome = run(load_deck(path), Path(tmp) / "out", writers=[])
    if outcome.status != 0:
        print(f"lagamine-py compile: the compile model failed: {outcome.message}", file=sys.stderr)
        return EXIT_OTHER
    for name in ("solid", "contact") if args.contact else ("solid",):
        for fn, info in kernels.cache_report(name).items():
            how = "compiled" if info["misses"] else "already in the cache"
            print(f"{name} kernel {fn}: {how} ({info['cache']})")
            if info["misses"] and not any(Path(info["cache"]).glob("*.nbi")):
                print(f"lagamine-py compile: numba could not write its cache in {info['cache']}: "
                      f"set NUMBA_CACHE_DIR to a writable directory", file=sys.stderr)
                return EXIT_OTHER
    print(f"lagamine-py compile: done in {time.process_time() - t0:.1f} s of CPU")
    return EXIT_OK


@contextmanager
def _advice_on_stderr():
    """Model advice on stderr while the block runs, as ``check`` prints it: the deck builder's
    notices (INFO) and warnings such as a penalty far from 20-100 E/h; they also go to the
    run's .log file.  The handler goes at the end: left behind, a later run in the same process
    would print the advice twice, or to a stream closed since."""
    import logging
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_AdviceFormatter())
    log = logging.getLogger("lagamine_py.advice")
    level = log.level
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    try:
        yield
    finally:
        log.removeHandler(handler)
        log.setLevel(level)


class _AdviceFormatter:
    """``lagamine-py: notice: ...`` for INFO records, ``lagamine-py: warning: ...`` above."""
    def format(self, record) -> str:
        kind = "notice" if record.levelno < 30 else "warning"
        return f"lagamine-py: {kind}: {record.getMessage()}"


@contextmanager
def _long_lived():
    """No cyclic garbage collection while the imports make objects that live as long as the
    process (modules, classes, functions: ~30 000), which are then frozen out of every later
    collection (``gc.freeze``).  The collector ran ~100 times during the main job, 12 ms of its
    CPU (22 ms of Hertz's), mostly re-scanning those objects; 3.5 ms after.  The ~1 000 objects
    of import-time cycles that a collection would have freed are frozen with them (~0.1 MB).
    Not around the deck: its parse leaves ~11 000 objects of garbage cycles (pyparsing's
    exceptions and their frames), which must stay collectable."""
    import gc
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


def _thread_setting_ok(command: str) -> bool:
    """``LAGAMINE_THREADS`` is a count or off; else the one message, for ``run`` and ``check``
    alike (``check`` refuses what ``run`` would)."""
    from .core.threads import kernel_threads
    try:
        kernel_threads()
    except ValueError as exc:
        print(f"lagamine-py {command}: {exc}; nothing was run", file=sys.stderr)
        return False
    return True


def _cmd_run(args) -> int:
    from .core.threads import pin_openblas_at_load
    from .core.lazy_modules import defer_numpy_submodules
    if not _thread_setting_ok("run"):       # said before anything runs
        return EXIT_DECK
    pin_openblas_at_load()                  # before numpy loads: no threadpoolctl needed
    with _long_lived():
        defer_numpy_submodules()            # before scipy.sparse clones numpy's namespace
        from .solver import run
        from .solver.restart import RestartError, deck_of, load
        importlib.import_module(".deck", __package__)      # for _load

    params = args.param
    if args.restart is not None:
        outdir = args.restart
        try:
            saved = deck_of(load(outdir))
        except RestartError as exc:
            print(f"lagamine-py: {exc}; nothing to resume", file=sys.stderr)
            return exc.status
        deck = args.deck or (Path(saved.path) if saved.path else None)
        if deck is None:
            print(f"lagamine-py: the restart data of {outdir} names no deck: give it, "
                  f"lagamine-py run DECK --restart {outdir}", file=sys.stderr)
            return EXIT_DECK
        if not Path(deck).exists():
            print(f"lagamine-py: the deck {deck} of the run in {outdir} no longer exists: give "
                  f"it, lagamine-py run DECK --restart {outdir}", file=sys.stderr)
            return EXIT_DECK
        if not params:           # the values the interrupted run was given
            params = [f"{k}={v}" for k, v in saved.parameters.items()]
    elif args.deck is None:
        print("lagamine-py run: give a DECK, or --restart OUT", file=sys.stderr)
        return EXIT_DECK
    else:
        deck = args.deck
        outdir = args.output or Path(f"{Path(deck).stem}_out")
    model = _load(Path(deck), params)
    if model is None:
        return EXIT_DECK
    from .solver.linear import KEEP_HEAP_DOFS, keep_freed_heap
    if 2 * len(model.coords) <= KEEP_HEAP_DOFS:     # this process runs one small model
        keep_freed_heap()
    if args.solver:
        from .registry import names
        known = names("solvers")
        if args.solver not in known:
            from .core.params import did_you_mean
            print(f"lagamine-py run: --solver {args.solver}: not a registered solver"
                  f"{did_you_mean(args.solver, known)}; installed: {', '.join(known)}",
                  file=sys.stderr)
            return EXIT_DECK
        for step in model.steps:
            step.controls["SOLVER"] = args.solver
    if args.kernel:
        for step in model.steps:
            step.controls["KERNEL"] = args.kernel
    with _advice_on_stderr(), sigterm_interrupts():    # kill stops it as Ctrl-C does
        outcome = run(model, outdir, restart=args.restart is not None, deck_path=Path(deck),
                      progress=not args.quiet, overwrite=args.overwrite)
    stream = sys.stdout if outcome.status == EXIT_OK else sys.stderr
    print(f"lagamine-py: {outcome.message}", file=stream)
    for line in outcome.summary:
        print(f"  {line}", file=stream)
    return outcome.status


def _cmd_plugins(args) -> int:
    from .registry import REGISTRY, KINDS, broken_plugins
    if args.check:
        return _check_plugins(args.names)
    wanted = {n.upper() for n in args.names}
    for kind in KINDS:
        entries = [e for e in REGISTRY.entries(kind)
                   if not wanted or e.name in wanted or wanted & {a.upper() for a in e.cls.aliases}]
        if wanted and not entries:
            continue
        print(f"{kind}:")
        for entry in entries:
            summary = entry.cls.summary()
            extra = [f"also {', '.join(entry.cls.aliases)}"] if entry.cls.aliases else []
            if entry.replaces:
                extra.append(f"replaces the one from {entry.replaces}")
            note = f" [{'; '.join(extra)}]" if extra else ""
            print(f"  {entry.name}  ({entry.origin}){note}{'  - ' + summary if summary else ''}")
            for p in entry.cls.params:
                print(f"      {p.describe()}")
    for msg in broken_plugins():
        print(f"warning: {msg}", file=sys.stderr)
    return EXIT_OK


_KIND_NAMES = {"elements": "element", "laws": "material law", "contact_laws": "contact law",
               "writers": "writer", "solvers": "solver", "checks": "check"}


def _check_plugins(names: list[str]) -> int:
    """``plugins --check``: the contract suites on the registered plugins, one block per plugin
    printed as it is done; exit 1 when a check failed, 2 for an unknown name."""
    from .contracts import check_registered
    from .registry import broken_plugins

    def show(rep) -> None:
        print(f"{_KIND_NAMES[rep.kind]} {rep.name} ({rep.origin}): "
              f"{'passed' if rep.passed else 'FAILED'}")
        for f in rep.findings:
            print(f"  {f.verdict:<4}  {f.check}: {f.detail}")
        sys.stdout.flush()

    try:
        reports = check_registered(names or None, progress=show)
    except KeyError as exc:
        print(f"lagamine-py plugins --check: {exc.args[0]}", file=sys.stderr)
        return EXIT_DECK
    failed = [f"{r.kind} {r.name}" for r in reports if not r.passed]
    problems = broken_plugins()
    for msg in problems:
        print(f"warning: {msg}", file=sys.stderr)
    print(f"{len(reports)} plugin(s) checked: {len(reports) - len(failed)} passed"
          + (f", {len(failed)} failed ({', '.join(failed)})" if failed else ""))
    return EXIT_OTHER if failed else EXIT_OK


def _cmd_compare(args) -> int:
    from .compare import compare_main
    return compare_main(args.run, args.ref, args.tol)


def _cmd_plot(args) -> int:
    from .plot import plot_run
    return plot_run(args.run, args.output, args.states, args.axes, args.xlim, args.scale)


def _cmd_sweep(args) -> int:
    from .sweep import sweep_main
    return sweep_main(args.deck, args.sets, args.output, args.jobs, args.scheduler)
