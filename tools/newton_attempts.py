"""Every Newton attempt of a run, converged or failed: its residuals, which iterations switched
contact states, its reviews, and where an early cut-back rule would have stopped it.

    python tools/newton_attempts.py --decks rolling fretting          # decks of decks/
    python tools/newton_attempts.py --sizes 40x20 160x80 --json F     # press-then-slide (bench.py)
    python tools/newton_attempts.py --load F                          # the rule on a saved record

For each failed attempt: its verdict, solves, the shape of its residual history (the residual
at each pass, ``*`` after a pass whose solve switched contact states, ``R`` at a failed
review) and the pass at which :func:`rule_stop` (the ``*CONTROLS IR=, IC=``
rule) would have cut it back; for the converged attempts, how many the rule would have stopped
(it must stop none) and the smallest margin it left.  The recorder wraps Newton's divergence
test and review (``newton._check_divergence``, ``newton._review``, ``newton._newton``); the
solver itself runs unchanged, with the rule switched off (``IR=0``) so that every attempt runs
as it did before the rule.  What ``docs/performance.md`` ("Hopeless attempts stopped early")
reads its figures from; the counts do not depend on the machine's load.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def record(model, outdir: Path, problem=None) -> list[dict]:
    """Run ``model`` (its controls as given; ``problem``: a prebuilt one, as
    :func:`lagamine_py.solver.run` takes) and return one dict per Newton attempt:
    ``history`` (|R|/F per pass), ``switched`` (passes whose last solve switched a watched
    state), ``reviews`` (passes of failed reviews), ``limits`` (the iteration limit after each),
    ``maxit``, ``rtol``, ``outcome`` ("converged" or the failure's reason), ``solves``."""
    from lagamine_py.core.errors import ConvergenceFailure, SingularMatrixError
    from lagamine_py.solver import newton
    from lagamine_py.solver import steps as steps_mod

    attempts: list[dict] = []
    inner_newton, inner_check, inner_review = newton._newton, newton._check_divergence, \
        newton._review

    def _newton(problem, reuse, free, u_old, states, ctx, u_c, f_ext, settings, *a):
        rec = {"history": [], "solves": None, "switched": [], "reviews": [], "limits": [], "maxit": settings.maxit,
               "rtol": settings.rtol}
        attempts.append(rec)
        try:
            conv = inner_newton(problem, reuse, free, u_old, states, ctx, u_c, f_ext, settings,
                                *a)
        except ConvergenceFailure as exc:
            rec.update(outcome=exc.reason, message=str(exc))
            if exc.history:
                rec["history"] = list(exc.history)
            raise
        except SingularMatrixError as exc:
            rec.update(outcome="singular matrix", message=str(exc))
            raise
        rec.update(history=list(conv.history), outcome="converged", solves=conv.iterations)
        return conv

    def check(history, excused=lambda: False):
        attempts[-1]["history"] = list(history)       # what a failure without one keeps
        if excused():
            attempts[-1]["switched"].append(len(history) - 1)
        return inner_check(history, excused)

    def review(problem, watch, *a):
        done, ev, ctx_k = inner_review(problem, watch, *a)
        if done is None:
            attempts[-1]["reviews"].append(a[-2])
            attempts[-1]["limits"].append(watch.limit)
        return done, ev, ctx_k

    def solve_increment(*a, **kw):
        try:
            return inner_solve(*a, **kw)
        except ConvergenceFailure as exc:
            attempts[-1]["solves"] = exc.solves
            raise

    inner_solve = steps_mod.solve_increment
    newton._newton, newton._check_divergence, newton._review = _newton, check, review
    steps_mod.solve_increment = solve_increment
    try:
        steps_mod.run(model, outdir, problem=problem)
    finally:
        newton._newton, newton._check_divergence, newton._review = inner_newton, inner_check, \
            inner_review
        steps_mod.solve_increment = inner_solve
    return attempts


def rule_stop(a: dict, ir: int, ic: int) -> int | None:
    """The pass at which the early cut-back (``*CONTROLS IR=ir, IC=ic``:
    :func:`lagamine_py.solver.newton._early_cut`'s conditions, replayed on the record) stops
    the recorded attempt ``a``, or None.  The run's path up to that pass is the recorded one,
    so the replay is what the rule does (passes counted as the rule counts them, by the
    residuals of the history: ``switched`` and ``reviews`` hold such indices)."""
    from lagamine_py.solver.newton import _iterations_to_go
    h, switched, reviews = a.get("history", []), set(a["switched"]), a["reviews"]
    for k in range(1, len(h)):
        since = max([r for r in reviews if r < k], default=0)
        if not ir or k - since < max(ir, 2) or h[k] <= a["rtol"] or k in switched:
            continue
        if _iterations_to_go(h[:k + 1], a["rtol"]) > ic:
            return k
    return None


def verdicts(attempts: list[dict], ir: int, ic: int) -> tuple[list, list]:
    """Replay the rule on recorded attempts: ``(converged attempts it would stop, as (index,
    pass), failed attempts with the pass it stops them at or None)``."""
    wrong, failed = [], []
    for i, a in enumerate(attempts):
        stop = rule_stop(a, ir, ic)
        if a.get("outcome") == "converged":
            if stop is not None:
                wrong.append((i, stop))
        else:
            failed.append((i, stop))
    return wrong, failed


def shape(a: dict, limit: int = 40) -> str:
    """``1.0e+00 3.2e-01* ...``: each pass's residual, ``*`` after a switching solve, ``R`` at
    a failed review."""
    sw, rv = set(a["switched"]), set(a["reviews"])
    return " ".join(f"{r:.1e}{'*' if k in sw else ''}{'R' if k in rv else ''}"
                    for k, r in enumerate(a["history"][:limit]))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--decks", nargs="*", default=[], help="deck stems of decks/ ('all': every one)")
    p.add_argument("--deck", nargs="*", type=Path, default=[], help="other decks (paths)")
    p.add_argument("--param", nargs="*", default=[], metavar="NAME=VALUE",
                   help="*PARAMETER values for --deck and --decks (run --param)")
    p.add_argument("--name", help="the record's name for a single --deck (default: its stem)")
    p.add_argument("--sizes", nargs="*", default=[], help="press-then-slide NXxNY (bench.py's deck)")
    p.add_argument("--controls", nargs="+", default=[], metavar="KEY=VALUE",
                   help="*CONTROLS values set in every step (IR=0 always added)")
    p.add_argument("--json", type=Path, help="save the records here")
    p.add_argument("--load", nargs="*", type=Path, default=[], help="saved records to replay")
    p.add_argument("--ir", type=int, default=None, help="the rule's IR (default: the keyword's)")
    p.add_argument("--ic", type=int, default=None, help="the rule's IC (default: the keyword's)")
    p.add_argument("--shapes", action="store_true", help="print each failed attempt's residuals")
    args = p.parse_args(argv)
    logging.disable(logging.WARNING)
    from lagamine_py.deck import load_deck
    from lagamine_py.model import CONTROL_PARAMS
    default = {c.name: c.default for c in CONTROL_PARAMS}
    ir = default["IR"] if args.ir is None else args.ir
    ic = default["IC"] if args.ic is None else args.ic
    runs: dict[str, list] = {}
    for path in args.load:
        runs.update(json.loads(path.read_text()))
    work = Path(tempfile.mkdtemp(prefix="newton_attempts_"))
    decks = sorted((ROOT / "decks").glob("*.dat")) if args.decks == ["all"] else \
        [ROOT / "decks" / f"{d}.dat" for d in args.decks]
    decks += args.deck
    params = dict(kv.split("=", 1) for kv in args.param) or None
    for size in args.sizes:
        sys.path.insert(0, str(ROOT / "tools"))
        from bench import press_slide_deck
        nx, ny = (int(v) for v in size.split("x"))
        deck = work / f"press_slide_{nx}x{ny}.dat"
        deck.write_text(press_slide_deck(nx, ny))
        decks.append(deck)
    values = dict(kv.split("=", 1) for kv in args.controls)
    values["IR"] = "0"
    for deck in decks:
        model = load_deck(deck, parameters=params if deck.parent != work else None)
        for step in model.steps:
            step.controls.update(values)
        name = args.name if args.name and len(decks) == 1 else deck.stem
        runs[name] = record(model, work / deck.stem)
        print(f"recorded {name}: {len(runs[name])} attempts", file=sys.stderr,
              flush=True)
    if args.json:
        args.json.write_text(json.dumps(runs))
    print(f"IR = {ir}, IC = {ic}")
    print("| run | attempts | failed | solves | solves in failed | converged stopped | "
          "failed stopped early: solves saved |")
    print("|---|---|---|---|---|---|---|")
    for name, attempts in runs.items():
        wrong, failed = verdicts(attempts, ir, ic)
        solves = sum(a.get("solves") or 0 for a in attempts)
        lost = sum(attempts[i].get("solves") or 0 for i, _ in failed)
        # a pass is a solve but for the review passes
        saved = sum((attempts[i].get("solves") or 0) - s
                    + sum(r < s for r in attempts[i]["reviews"]) for i, s in failed if s is not None)
        early = sum(s is not None for _, s in failed)
        print(f"| {name} | {len(attempts)} | {len(failed)} | {solves} | {lost} | "
              f"{len(wrong)} {wrong[:4] if wrong else ''} | {early}: {saved} |")
        if args.shapes:
            for i, s in failed:
                a = attempts[i]
                print(f"    attempt {i} {a['outcome']} after {len(a['history']) - 1} passes, "
                      f"rule at {s}: {shape(a)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
