"""Fuzz ``lagamine-py run``: mutated example decks, run a few increments, judged.

    python tools/fuzz_run.py [--examples N] [--seed S] [--increments K] [--keep DIR]

Each example takes an example deck of ``decks/``, applies 1-4 random mutations (a number
replaced by an edge value -- 0, a negative, a huge or a tiny one, its tenth or tenfold --, a
line dropped, duplicated or swapped with another, a keyword line's parameter value changed)
and runs it in this process through the command line (``lagamine_py.cli.main``) with every
step capped at K increments (``INC``), into a fresh directory.  A run is *bad* when

* ``main`` raises (a traceback), or its exit status is not 0, 2 or 3 -- 1 only for a setup
  error of the step (``*CONTROLS`` asking for a solver that is not installed);
* its stderr holds a traceback or "an unexpected error", or a NumPy warning (RuntimeWarning) is
  issued;
* an output table or a VTK array holds NaN (or inf).

The counts per outcome are printed; every bad deck is written to ``--keep`` (default
``/tmp/lagamine_fuzz_run``) with what went wrong.  ``tests/test_run_fuzz.py`` runs the same
judge on a few derandomised examples under hypothesis.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import random
import re
import shutil
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"
#: the example decks fuzzed (the small ones: a run of a few increments takes ~0.1-0.5 s)
FUZZED = ("coulomb_block.dat", "flat_punch.dat", "stick_slip.dat", "compression_ro.dat",
          "axisym_press_friction.dat", "tube_limit.dat", "hertz.dat")
EDGE_VALUES = ("0", "-1", "1e30", "1e-30", "-0.5", "2", "1e-300", "0.5", "1e300", "-1e300")
_NUMBER = re.compile(r"(?<![\w.<])[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?(?![\w.>])")
ALLOWED = (0, 2, 3)


@dataclass
class Verdict:
    status: int | None
    problems: list[str] = field(default_factory=list)
    stderr: str = ""

    @property
    def bad(self) -> bool:
        return bool(self.problems)


# ---------------------------------------------------------------- mutations

def mutate(text: str, ops: list[tuple]) -> str:
    """``text`` with the mutations ``ops`` applied in order; each op is ``(kind, a, b, c)``
    with integers ``a, b, c`` choosing where and what (any size: taken modulo)."""
    lines = text.splitlines()
    for kind, a, b, c in ops:
        if not lines:
            break
        k = a % len(lines)
        if kind == "number":
            hits = list(_NUMBER.finditer(lines[k]))
            if not hits or lines[k].lstrip().startswith("**"):
                continue
            m = hits[b % len(hits)]
            old = m.group(0)
            choices = EDGE_VALUES + (_scaled(old, 0.1), _scaled(old, 10.0), "-" + old.lstrip("+-"))
            lines[k] = lines[k][:m.start()] + choices[c % len(choices)] + lines[k][m.end():]
        elif kind == "drop":
            del lines[k]
        elif kind == "dup":
            lines.insert(k, lines[k])
        elif kind == "swap":
            j = b % len(lines)
            lines[k], lines[j] = lines[j], lines[k]
        elif kind == "param":
            m = list(re.finditer(r"=\s*([^,\s]+)", lines[k]))
            if lines[k].startswith("*") and m:
                g = m[b % len(m)]
                new = ("0", "-1", "2", "YES", "NO", "X", "1e9")[c % 7]
                lines[k] = lines[k][:g.start(1)] + new + lines[k][g.end(1):]
    return "\n".join(lines) + "\n"


def _scaled(text: str, factor: float) -> str:
    try:
        return repr(float(text.replace("d", "e").replace("D", "e")) * factor)
    except ValueError:
        return text


def random_ops(rng: random.Random) -> list[tuple]:
    kinds = ("number", "number", "number", "drop", "dup", "swap", "param")
    return [(rng.choice(kinds), rng.randrange(10**6), rng.randrange(10**6), rng.randrange(10**6))
            for _ in range(rng.randint(1, 4))]


# ---------------------------------------------------------------- one run, judged

def _capped_loader(increments: int):
    from lagamine_py import deck as deck_pkg
    real = deck_pkg.load_deck

    def load(path, parameters=None):
        model = real(path, parameters=parameters)
        for step in model.steps:
            step.max_increments = min(int(step.max_increments), increments)
        return model
    return deck_pkg, real, load


def judge(deck: Path, outdir: Path, increments: int = 2) -> Verdict:
    """Run ``deck`` into ``outdir`` through the command line, each step capped at
    ``increments``, and say what is wrong (:class:`Verdict`)."""
    import warnings

    from lagamine_py.cli import main

    deck_pkg, real, capped = _capped_loader(increments)
    err = io.StringIO()
    verdict = Verdict(None)
    deck_pkg.load_deck = capped
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                verdict.status = main(["run", str(deck), "-o", str(outdir), "-q"])
            except BaseException as exc:        # noqa: BLE001 - what the judge looks for
                verdict.problems.append(f"main raised {type(exc).__name__}: {exc}")
    finally:
        deck_pkg.load_deck = real
    verdict.problems += [f"{w.category.__name__}: {w.message}" for w in caught
                         if issubclass(w.category, RuntimeWarning)]        # NumPy's
    verdict.stderr = err.getvalue()
    text = verdict.stderr
    if verdict.status is not None and verdict.status not in ALLOWED and not (
            verdict.status == 1 and "*CONTROLS" in text):
        verdict.problems.append(f"exit status {verdict.status}")
    for bad in ("Traceback", "unexpected error", "Warning:"):
        if bad in text:
            verdict.problems.append(f"stderr holds {bad!r}")
    if outdir.is_dir():
        verdict.problems += non_finite(outdir)
    return verdict


def non_finite(outdir: Path) -> list[str]:
    """Output tables and VTK arrays of ``outdir`` holding NaN or inf."""
    from lagamine_py.results import read_table, read_vtu

    out = []
    for path in sorted(outdir.glob("*.csv")) + sorted(outdir.glob("*.sta")):
        table = read_table(path)
        for name, col in table.items():
            if col.dtype != object and not np.all(np.isfinite(col)):
                out.append(f"{path.name}: column {name} holds {col[~np.isfinite(col)][0]}")
    for path in sorted(outdir.glob("*.vtu")):
        for name, arr in read_vtu(path).items():
            a = np.asarray(arr)
            if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                out.append(f"{path.name}: array {name} holds non-finite values")
    return out


def deck_dir(tmp: Path) -> Path:
    """A directory for mutated decks that sees ``decks/meshes`` (the includes)."""
    tmp.mkdir(parents=True, exist_ok=True)
    link = tmp / "meshes"
    if not link.exists():
        link.symlink_to(DECKS / "meshes")
    return tmp


def fuzz_one(name: str, ops: list[tuple], work: Path, increments: int = 2, tag: str = "x"):
    """Mutate deck ``name`` by ``ops``, run and judge it: (deck path, verdict)."""
    text = mutate((DECKS / name).read_text(), ops)
    deck = deck_dir(work) / f"{Path(name).stem}_{tag}.dat"
    deck.write_text(text)
    out = work / f"out_{tag}"
    shutil.rmtree(out, ignore_errors=True)
    return deck, judge(deck, out, increments)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--examples", type=int, default=200)
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--increments", type=int, default=2)
    ap.add_argument("--keep", type=Path, default=Path("/tmp/lagamine_fuzz_run"))
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    counts: Counter = Counter()
    bad = 0
    t0 = time.perf_counter()
    args.keep.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="fuzz_run_") as tmp:
        for k in range(args.examples):
            name = rng.choice(FUZZED)
            ops = random_ops(rng)
            deck, v = fuzz_one(name, ops, Path(tmp), args.increments, tag=str(k))
            counts[v.status] += 1
            if v.bad:
                bad += 1
                keep = args.keep / f"bad_{k}_{deck.name}"
                shutil.copy(deck, keep)
                keep.with_suffix(".why").write_text("\n".join(v.problems) + "\n\n" + v.stderr)
                print(f"BAD {k} {name} {ops}: {'; '.join(v.problems)[:300]}", flush=True)
            shutil.rmtree(Path(tmp) / f"out_{k}", ignore_errors=True)
    took = time.perf_counter() - t0
    summary = ", ".join(f"exit {s}: {n}" for s, n in sorted(counts.items(), key=lambda x: str(x[0])))
    print(f"{args.examples} mutated decks in {took:.0f} s: {summary}; bad: {bad}"
          + (f" (kept in {args.keep})" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
