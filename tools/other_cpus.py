"""Run decks with the round-off of other processors and compare each run with its reference.

The archived references (``decks/reference/<deck>/``) were made on one machine.  Another
processor runs other NumPy loops (NumPy dispatches AVX-512, AVX2 or SSE code at run time) and
other OpenBLAS kernels, which round differently in the last bits.  This tool makes that round-off
here: each configuration sets ``OPENBLAS_CORETYPE`` (OpenBLAS's kernels for a processor class)
and/or ``NPY_DISABLE_CPU_FEATURES`` (NumPy's dispatch targets switched off, those this NumPy
has), runs each deck in a fresh process and prints whether it matches its reference
(``lagamine-py compare``'s verdict), with its increments and Newton solves::

    python tools/other_cpus.py                                  # every deck with a reference
    python tools/other_cpus.py press_slide ring --cpus sandybridge numpy-no-avx512

A deck that fails under a configuration takes another path there: its verdict says which
quantity moved, and ``--keep DIR`` keeps the runs to look at.
"""
from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "decks" / "reference"

NUMPY_AVX512 = ("X86_V4", "AVX512_ICL", "AVX512_SPR")
#: name -> environment; "native" is this machine as it is
CPUS = {
    "native": {},
    "sandybridge": {"OPENBLAS_CORETYPE": "SandyBridge"},
    "prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "zen": {"OPENBLAS_CORETYPE": "Zen"},
    "numpy-no-avx512": {"NPY_DISABLE_CPU_FEATURES": NUMPY_AVX512},
    "zen-numpy-no-avx512": {"OPENBLAS_CORETYPE": "Zen", "NPY_DISABLE_CPU_FEATURES": NUMPY_AVX512},
}


def cpu_env(settings: dict) -> dict[str, str] | None:
    """The process environment of a configuration; None when this NumPy has none of the
    dispatch targets it would switch off (the configuration means nothing here)."""
    env = dict(os.environ, MKL_NUM_THREADS="1", OMP_NUM_THREADS="1")
    for key, value in settings.items():
        if key == "NPY_DISABLE_CPU_FEATURES":
            try:
                from numpy._core._multiarray_umath import __cpu_dispatch__
            except ImportError:
                return None
            value = " ".join(v for v in value if v in __cpu_dispatch__)
            if not value:
                return None
        env[key] = value
    return env


def path_of(sta: Path) -> tuple[int, int]:
    """(converged increments, Newton solves of the converged increments) from a .sta file."""
    with open(sta, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["failed"] == "no"]
    return len(rows), sum(int(r["iterations"]) for r in rows)


def run_one(deck: Path, env: dict, out: Path) -> str:
    """Run ``deck`` into ``out`` with ``env`` and compare it with its reference: one line."""
    from lagamine_py.compare import compare_dirs
    res = subprocess.run([sys.executable, "-m", "lagamine_py", "run", str(deck), "-q", "-o", str(out)],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    if res.returncode != 0:
        return f"exit {res.returncode}: {(res.stdout + res.stderr).strip().splitlines()[:1]}"
    increments, solves = path_of(out / f"{deck.stem}.sta")
    report = compare_dirs(out, REFERENCE / deck.stem)
    if report.ok:
        return f"PASS ({increments} increments, {solves} solves)"
    worst = max(report.findings, key=lambda f: f.worst, default=None)
    why = report.problems[0] if report.problems else \
        f"{worst.quantity} {worst.worst:.3g}x the tolerance at {worst.where}"
    return f"FAIL ({increments} increments, {solves} solves): {why}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("decks", nargs="*", help="deck names (default: every deck with a reference)")
    ap.add_argument("--cpus", nargs="+", choices=list(CPUS), default=list(CPUS))
    ap.add_argument("--keep", type=Path, help="keep the runs in this directory")
    args = ap.parse_args(argv)
    names = args.decks or sorted(p.name for p in REFERENCE.iterdir() if p.is_dir())
    work = args.keep or Path(tempfile.mkdtemp(prefix="other_cpus_"))
    failures = 0
    for cpu in args.cpus:
        env = cpu_env(CPUS[cpu])
        if env is None:
            print(f"{cpu}: this NumPy has none of its dispatch targets; skipped")
            continue
        for name in names:
            verdict = run_one(ROOT / "decks" / f"{name}.dat", env, work / cpu / name)
            failures += not verdict.startswith("PASS")
            print(f"{cpu:<20} {name:<22} {verdict}", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
