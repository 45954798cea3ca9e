"""Newton's cost on the decks of ``decks/`` under several ``*CONTROLS`` settings, side by side.

    python tools/newton_decks.py                       # every deck: before (KRYLOV=0, SDI=NO) / now
    python tools/newton_decks.py --decks rolling hertz --configs "KRYLOV=0 SDI=NO" "" "KRYLOVDOFS=0"

For each deck and setting (the settings of one deck run one after the other, so that a load
change of the machine hits them alike): converged increments, failed attempts, Newton solves
(failed attempts included), factorisations and back-substitutions of the tangent, the process
CPU time of the run, and whether the last increment's contact totals and reactions agree with
the first setting's within ``lagamine-py compare``'s tolerances (the regression test's rule).
What ``docs/performance.md`` ("Newton solves per increment") reports.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(deck: Path, controls: str, outdir: Path) -> dict:
    """One run of ``deck`` with ``controls`` ("KEY=VALUE ...") added to every step."""
    from lagamine_py.deck import load_deck
    from lagamine_py.output import Writer, default_writers
    from lagamine_py.solver import run as run_model
    from lagamine_py.solver import steps as steps_mod

    class Count(Writer):
        params = ()

        def __init__(self):
            self.solves = self.increments = self.failures = 0

        def increment(self, result):
            self.increments += 1
            self.solves += result.iterations

        def failed_attempt(self, info):
            self.failures += 1
            self.solves += info.iterations

    model = load_deck(deck)
    values = dict(kv.split("=", 1) for kv in controls.split())
    for step in model.steps:
        step.controls.update(values)
    counts = {"factor": 0, "solve": 0}
    make = steps_mod.make_solver

    def counting(name):
        s = make(name)
        for what in ("factor", "solve"):
            inner = getattr(s, what)

            def counted(*a, _inner=inner, _what=what):
                counts[_what] += 1
                return _inner(*a)
            setattr(s, what, counted)
        return s
    steps_mod.make_solver = counting
    cap = Count()
    try:
        c0 = time.process_time()
        outcome = run_model(model, outdir, writers=default_writers(outdir, model) + [cap],
                            deck_path=deck)
        cpu = time.process_time() - c0
    finally:
        steps_mod.make_solver = make
    return {"status": int(outcome.status), "increments": cap.increments,
            "failures": cap.failures, "solves": cap.solves, "factorisations": counts["factor"],
            "back_substitutions": counts["solve"], "cpu": cpu, "out": outdir}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--decks", nargs="+", help="deck stems (default: every deck of decks/)")
    p.add_argument("--configs", nargs="+", default=["KRYLOV=0 SDI=NO", ""],
                   help='*CONTROLS settings, each "KEY=VALUE ..." ("" = the defaults)')
    args = p.parse_args(argv)
    logging.disable(logging.WARNING)
    from lagamine_py.compare import compare_dirs
    decks = ([ROOT / "decks" / f"{d}.dat" for d in args.decks] if args.decks
             else sorted((ROOT / "decks").glob("*.dat")))
    work = Path(tempfile.mkdtemp(prefix="newton_decks_"))
    print("| deck | setting | increments | failed attempts | Newton solves | factorisations | "
          "back-substitutions | CPU s | agrees with the first |")
    print("|---|---|---|---|---|---|---|---|---|")
    for deck in decks:
        first = None
        for i, cfg in enumerate(args.configs):
            r = run(deck, cfg, work / f"{deck.stem}_{i}")
            agree = "-"
            if first is None:
                first = r["out"]
            else:
                agree = "yes" if compare_dirs(r["out"], first).ok else "**no**"
            print(f"| {deck.stem} | {cfg or 'defaults'} | {r['increments']} | {r['failures']} | "
                  f"{r['solves']} | {r['factorisations']} | {r['back_substitutions']} | "
                  f"{r['cpu']:.2f} | {agree} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
