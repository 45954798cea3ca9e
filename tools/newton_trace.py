"""Where Newton's solves go: every iteration's residual with the contact points that switched.

    python tools/newton_trace.py 40 20                     # press-then-slide at 40 x 20 (bench.py's deck)
    python tools/newton_trace.py --deck decks/stick_slip.dat --controls FLIPFLOP=2
    python tools/newton_trace.py 40 20 --tail 8 --increments 6

Prints the solver's per-iteration log (``|R|/F``, the energy, the reviews of frozen points, the
cut-backs) and, after each solve, the contact points whose state (open ``o``, stick ``k``, slip
with tau > 0 ``+``, slip with tau < 0 ``-``: :func:`lagamine_py.solver.stabilisation.state_codes`)
changed between the two last iterates, as ``<point><from><to>``.  ``--tail N`` adds the state
and ``tau / p`` of the last N points of each group after every solve (press-then-slide: the
points next to the pushed corner).  What ``docs/performance.md`` ("Newton solves per increment")
reads its traces from; the counts do not depend on the machine's load.

The trace wraps :meth:`FlipFlop.context <lagamine_py.solver.stabilisation.FlipFlop.context>`
(the observer Newton hands the states of every iterate to); the solver itself is not changed.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
CODES = "ok+-"                 # OPEN, STICK, SLIP (tau > 0), SLIP_NEG


class _Stop(Exception):
    """Raised by the trace after the requested number of converged increments."""


def switches(last: np.ndarray, code: np.ndarray, limit: int = 12) -> str:
    """``"n: 3k+ 7+-"``: how many points changed state from ``last`` to ``code`` (g,) and the
    first ``limit`` of them as ``<index><from><to>``."""
    idx = np.flatnonzero(code != last)
    text = " ".join(f"{i}{CODES[int(last[i])]}{CODES[int(code[i])]}" for i in idx[:limit])
    return f"{idx.size}: {text}{' ...' if idx.size > limit else ''}"


def tail(code: np.ndarray, tau: np.ndarray, p: np.ndarray, n: int) -> str:
    """The state and ``tau / p`` of the last ``n`` points: ``k-0.152 ++0.200``."""
    ratio = np.where(p > 0, tau / np.where(p > 0, p, 1.0), 0.0)
    return " ".join(f"{CODES[int(c)]}{r:+.3f}" for c, r in zip(code[-n:], ratio[-n:]))


def trace(model, outdir: Path, tail_points: int = 0, increments: int = 0, out=sys.stdout,
          writers=()):
    """Run ``model`` with the trace on; returns the run's :class:`Outcome` (None when stopped
    after ``increments`` converged increments).  ``writers``: more writers to hand the run to
    (they see every increment before the trace stops)."""
    from lagamine_py.output import Writer, default_writers
    from lagamine_py.solver import stabilisation
    from lagamine_py.solver import steps as steps_mod

    inner = stabilisation.FlipFlop.context

    def context(self, ctx, states):
        for k, _, code in self._states(states):
            last = self.last.get(k)
            if last is not None and last.shape == code.shape and np.any(code != last):
                print(f"      switched {switches(last, code)}", file=out)
            if tail_points:
                st = states[k]
                print(f"      tail {tail(code, np.asarray(st['tau'], float).ravel(), np.asarray(st['p'], float).ravel(), tail_points)}",
                      file=out)
        return inner(self, ctx, states)

    class Counter(Writer):
        params = ()
        done = 0

        def __init__(self):
            pass

        def increment(self, result):
            self.done += 1
            if increments and self.done >= increments:
                raise _Stop()

    handler = logging.StreamHandler(out)
    handler.setFormatter(logging.Formatter("%(message)s"))
    solver_log = logging.getLogger("lagamine_py.solver")
    level = solver_log.level
    solver_log.addHandler(handler)
    solver_log.setLevel(logging.INFO)
    stabilisation.FlipFlop.context = context
    try:
        return steps_mod.run(model, outdir,
                             writers=default_writers(outdir, model) + list(writers) + [Counter()])
    except _Stop:
        return None
    finally:
        stabilisation.FlipFlop.context = inner
        solver_log.removeHandler(handler)
        solver_log.setLevel(level)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("size", type=int, nargs="*", help="NX NY of press-then-slide (bench.py's deck)")
    p.add_argument("--deck", type=Path, help="a deck to trace instead")
    p.add_argument("--controls", nargs="+", default=[], metavar="KEY=VALUE",
                   help="*CONTROLS values set in every step")
    p.add_argument("--tail", type=int, default=0, help="state and tau/p of the last N points")
    p.add_argument("--increments", type=int, default=0, help="stop after N converged increments")
    args = p.parse_args(argv)
    from lagamine_py.deck import load_deck
    work = Path(tempfile.mkdtemp(prefix="newton_trace_"))
    if args.deck is not None:
        deck = args.deck
    elif len(args.size) == 2:
        sys.path.insert(0, str(ROOT))
        from bench import press_slide_deck
        deck = work / f"press_slide_{args.size[0]}x{args.size[1]}.dat"
        deck.write_text(press_slide_deck(*args.size))
    else:
        p.error("give NX NY or --deck")
    model = load_deck(deck)
    values = dict(kv.split("=", 1) for kv in args.controls)
    for step in model.steps:
        step.controls.update(values)
    outcome = trace(model, work / "out", args.tail, args.increments)
    if outcome is not None:
        print("\n".join(outcome.summary[:-1]))
    return 0 if outcome is None or outcome.status == 0 else int(outcome.status)


if __name__ == "__main__":
    sys.exit(main())
