"""Where a run's peak resident memory is set: the run of a deck in this process, with the
resident set's high-water mark (``VmHWM`` of ``/proc/self/status``) read around the phases of
an iteration, so that each rise of the peak is booked to the innermost phase running when it
happened (issue 17 item 5).

    python tools/peak_memory.py DECK [--kernel AUTO|NUMPY|NUMBA] [--solver NAME]
                                     [--controls KEY=VALUE ...] [--libraries] [--tracemalloc]
                                     [--trim PHASE ...]

Prints the resident set after the imports and after the deck, then per phase: calls, the
high-water mark's total rise inside it, the peak after its last rise and at which call, and the
final peak (the same figure as ``/usr/bin/time``'s ``%M`` for the whole process, give or take
the few MB of this script); then the resident set after ``malloc_trim(0)`` (what the heap held
freed).  ``--tracemalloc`` adds, per phase, the largest growth of the traced (Python and NumPy)
allocations within one call (slow).  ``--libraries`` adds the mapped shared libraries' resident
sizes at the end (``/proc/self/smaps``: numba's LLVM, MKL ...).  ``--trim PHASE`` calls
``malloc_trim(0)`` before each call of the phases named (an experiment: does the heap's freed
memory set the peak?).  Not a test: the measurement of ``docs/performance.md``'s memory
paragraphs.
"""
from __future__ import annotations

import argparse
import functools
import sys
import tempfile
import time
import tracemalloc
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def status_kb(field: str) -> int:
    """``VmHWM``, ``VmRSS`` ... of this process, kB."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


class Book:
    """Rises of the high-water mark booked to the innermost running phase."""

    def __init__(self):
        self.stack: list[str] = []
        self.calls = defaultdict(int)
        self.rise = defaultdict(int)          # kB of peak rise inside the phase (own)
        self.at = {}                          # phase -> (peak after its last rise, call number)
        self.hwm = status_kb("VmHWM")
        self.order: list[str] = []
        self.traced = defaultdict(int)        # kB: largest traced growth inside one call
        self.tracing = False
        import ctypes
        self.libc = ctypes.CDLL("libc.so.6")
        self.trim, self.trims, self.trim_cpu = set(), 0, 0.0

    def _settle(self):
        """Book the rise since the last reading to the phase on top of the stack."""
        hwm = status_kb("VmHWM")
        if hwm > self.hwm:
            who = self.stack[-1] if self.stack else "(outside)"
            self.rise[who] += hwm - self.hwm
            self.at[who] = (hwm, self.calls[who])
            self.hwm = hwm

    def wrap(self, owner, attr: str, label: str):
        fn = owner.__dict__[attr]
        book = self
        if label not in self.order:
            self.order.append(label)

        @functools.wraps(fn)
        def wrapper(*a, **k):
            if label in book.trim:
                book.trims += 1
                t = time.process_time()
                book.libc.malloc_trim(0)
                book.trim_cpu += time.process_time() - t
            book._settle()
            book.stack.append(label)
            book.calls[label] += 1
            if book.tracing:
                start = tracemalloc.get_traced_memory()[0]
                tracemalloc.reset_peak()
            try:
                return fn(*a, **k)
            finally:
                book._settle()
                book.stack.pop()
                if book.tracing:
                    grown = (tracemalloc.get_traced_memory()[1] - start) // 1024
                    book.traced[label] = max(book.traced[label], grown)
        setattr(owner, attr, wrapper)


def libraries() -> list[tuple[str, int]]:
    """(mapped file, resident kB) of the shared libraries in ``/proc/self/smaps``, largest first."""
    sizes = defaultdict(int)
    name = None
    with open("/proc/self/smaps") as fh:
        for line in fh:
            head = line.split()
            if "-" in head[0] and len(head) >= 5 and ":" in head[3]:
                name = head[5] if len(head) > 5 else "[anon]"
            elif head[0] == "Rss:":
                sizes[name] += int(head[1])
    return sorted(sizes.items(), key=lambda kv: -kv[1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("deck", type=Path)
    ap.add_argument("--kernel")
    ap.add_argument("--solver")
    ap.add_argument("--controls", nargs="*", default=[])
    ap.add_argument("--libraries", action="store_true")
    ap.add_argument("--trim", nargs="*", default=[],
                    help="phases before which malloc_trim(0) returns the heap's free pages")
    ap.add_argument("--tracemalloc", action="store_true",
                    help="also the largest growth of NumPy/Python allocations inside one call of "
                         "each phase (slow; nested phases reset the outer one's peak)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    base = status_kb("VmRSS")
    from lagamine_py.core.threads import pin_openblas_at_load
    from lagamine_py.core.lazy_modules import defer_numpy_submodules
    pin_openblas_at_load()
    defer_numpy_submodules()
    from lagamine_py.deck import load_deck
    from lagamine_py.solver import run
    from lagamine_py.solver import linear, newton, problem as problem_mod, reuse, steps
    from lagamine_py.solver.pattern import Pattern
    from lagamine_py.output import vtk, tables
    print(f"interpreter {base / 1024:.0f} MB, after the imports {status_kb('VmRSS') / 1024:.0f} MB")
    book = Book()
    book.trim = set(args.trim)
    book.wrap(problem_mod.Problem, "evaluate", "evaluate")
    book.wrap(Pattern, "assemble_data", "assemble_data")
    book.wrap(linear.FreeDofs, "kff", "kff")
    book.wrap(linear.PardisoSolver, "factor", "pardiso factor")
    book.wrap(linear.PardisoSolver, "solve", "pardiso solve")
    book.wrap(linear.SpluSolver, "factor", "splu factor")
    book.wrap(linear.SpluSolver, "solve", "splu solve")
    book.wrap(reuse.FactorReuse, "solve", "linear solve (GMRES, factor)")
    book.wrap(steps.Controller, "_hand_out", "output (results + writers)")
    book.wrap(vtk.VtkWriter, "_write_state", "vtk")
    book.wrap(steps.Controller, "_save_restart", "restart")
    book.wrap(steps.Controller, "_setup_step", "step setup")
    book.wrap(newton, "solve_increment", "increment (rest of Newton)")
    for name, w in vars(tables).items():
        if isinstance(w, type) and "increment" in w.__dict__:
            book.wrap(w, "increment", f"tables.{name}")
    model = load_deck(args.deck)
    for step in model.steps:
        if args.kernel:
            step.controls["KERNEL"] = args.kernel
        if args.solver:
            step.controls["SOLVER"] = args.solver
        for kv in args.controls:
            k, v = kv.split("=", 1)
            step.controls[k.upper()] = v
    print(f"after the deck {status_kb('VmRSS') / 1024:.0f} MB")
    if args.tracemalloc:
        tracemalloc.start()
        book.tracing = True
    with tempfile.TemporaryDirectory() as out:
        outcome = run(model, Path(out) / "run")
    book._settle()
    print(f"run: {outcome.message}  ({time.perf_counter() - t0:.1f} s wall, "
          f"{time.process_time():.1f} s CPU; {book.trims} trims, {book.trim_cpu:.2f} s CPU)")
    print(f"final resident {status_kb('VmRSS') / 1024:.0f} MB, peak {status_kb('VmHWM') / 1024:.0f} MB")
    print("| phase | calls | peak rise (MB) | peak after its last rise (MB) | at call | "
          "largest traced growth in a call (MB) |")
    print("|---|---|---|---|---|---|")
    for label in book.order + ["(outside)"]:
        if book.calls[label] or book.rise[label]:
            at = book.at.get(label)
            print(f"| {label} | {book.calls[label]} | {book.rise[label] / 1024:.1f} | "
                  f"{at[0] / 1024 if at else 0:.1f} | {at[1] if at else ''} | "
                  f"{book.traced[label] / 1024:.1f} |")
    import ctypes
    ctypes.CDLL("libc.so.6").malloc_trim(0)
    print(f"after malloc_trim(0): resident {status_kb('VmRSS') / 1024:.0f} MB")
    if args.libraries:
        print("| mapping | resident MB |\n|---|---|")
        for name, kb in libraries()[:15]:
            print(f"| {name} | {kb / 1024:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
