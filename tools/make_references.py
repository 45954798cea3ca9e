"""Regenerate the archived reference outputs of the decks: ``decks/reference/<deck>/``.

Usage (from anywhere)::

    python tools/make_references.py                 # every deck at the top level of decks/
    python tools/make_references.py press_slide hertz.dat decks/tube_crimp.dat

Each deck is run by ``python -m lagamine_py run DECK -o TMP -q --kernel NUMPY`` (the NumPy
solid kernel, the reference implementation) in a fresh process, from the repository root (so
the package of this checkout is the one that runs).  The text tables that ``lagamine-py
compare`` reads (``contact.csv``, ``contact_totals.csv``, ``reactions.csv``,
``displacements.csv``: those the run wrote) are copied into ``decks/reference/<deck>/``, which is
emptied first so that no stale table survives, next to a one-line ``PROVENANCE``: the command, the
git commit (``+dirty`` when the package, the decks or setup.cfg differ from it), the date, Python,
NumPy, SciPy, pypardiso (or its absence), the machine, the run's exit status, increments and wall
time.

A deck whose run does not finish (exit status other than 0) keeps its old reference; the tool
reports it and exits with status 1.  Review the differences with ``git diff decks/reference``
before committing: a reference is regenerated deck by deck, for a reason, never wholesale by
habit.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import importlib.metadata
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"
REFERENCE = DECKS / "reference"
TABLES = ("contact.csv", "contact_totals.csv", "reactions.csv", "displacements.csv")


def all_decks() -> list[Path]:
    """Every ``*.dat`` at the top level of ``decks/``, sorted by name."""
    return sorted(DECKS.glob("*.dat"))


def resolve_deck(name: str) -> Path:
    """``press_slide``, ``press_slide.dat`` or a path -> the deck file (must exist)."""
    p = Path(name)
    for cand in (p, DECKS / p, DECKS / f"{p}.dat"):
        if cand.is_file():
            return cand.resolve()
    raise FileNotFoundError(f"no deck {name!r} (looked in {DECKS})")


def _git(*args: str) -> str:
    try:
        out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return ""
    return out.stdout.strip()


def _version(distribution: str) -> str:
    """The installed version, read from the distribution's metadata: importing pypardiso
    would search the file tree for MKL and leave it loaded for the rest of the process."""
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


def environment() -> str:
    """Commit, Python, library versions and machine, as one line fragment."""
    commit = _git("rev-parse", "--short=12", "HEAD") or "unknown"
    # dirty: what can change the numbers (the package, the decks, the metadata) differs from HEAD
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", "lagamine_py", "decks",
                 ":(exclude)decks/reference", "setup.cfg")
    commit += "+dirty" if dirty else ""
    return (f"git {commit}; Python {platform.python_version()}; numpy {_version('numpy')}; "
            f"scipy {_version('scipy')}; pypardiso {_version('pypardiso')}; "
            f"{platform.system()} {platform.machine()} ({os.cpu_count()} CPUs, {platform.platform()})")


def _increments(sta: Path) -> int:
    """Converged increments listed in a status file (rows not marked failed)."""
    if not sta.exists():
        return 0
    rows = sta.read_text().splitlines()[1:]
    return sum(1 for r in rows if ",no," in r)


def run_deck(deck: Path, outdir: Path) -> tuple[int, float, str]:
    """Run one deck in a fresh process; (exit status, wall seconds, last stderr line)."""
    cmd = [sys.executable, "-m", "lagamine_py", "run", str(deck), "-o", str(outdir), "-q",
           "--kernel", "NUMPY"]     # the reference kernel (tests/test_regression.py pins it)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    tail = (proc.stderr.strip().splitlines() or [""])[-1]
    return proc.returncode, wall, tail


def make_reference(deck: Path, env: str, command: str) -> bool:
    """Run ``deck`` and replace ``decks/reference/<stem>/``; False when the run failed."""
    with tempfile.TemporaryDirectory(prefix=f"ref_{deck.stem}_") as tmp:
        out = Path(tmp) / "out"
        status, wall, tail = run_deck(deck, out)
        if status != 0:
            print(f"{deck.name}: run failed with exit status {status}: {tail}", file=sys.stderr)
            return False
        target = REFERENCE / deck.stem
        if target.exists():
            shutil.rmtree(target)
        target.mkdir(parents=True)
        copied = [t for t in TABLES if (out / t).exists()]
        for t in copied:
            shutil.copyfile(out / t, target / t)
        incs = _increments(out / f"{deck.stem}.sta")
    date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    rel = deck.relative_to(ROOT) if deck.is_relative_to(ROOT) else deck
    line = (f"produced by `{command}` (lagamine-py run {rel}: exit 0, {incs} increments, "
            f"{wall:.1f} s) on {date}; {env}; tables: {', '.join(copied)}")
    (target / "PROVENANCE").write_text(line + "\n")
    print(f"{deck.name}: {incs} increments, {wall:.1f} s -> {target.relative_to(ROOT)}")
    return True


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("decks", nargs="*", help="deck names or paths (default: every deck in decks/)")
    args = ap.parse_args(argv)
    try:
        decks = [resolve_deck(d) for d in args.decks] if args.decks else all_decks()
    except FileNotFoundError as exc:
        print(f"make_references: {exc}", file=sys.stderr)
        return 2
    command = " ".join(["python tools/make_references.py", *args.decks])
    env = environment()
    failed = [d.name for d in decks if not make_reference(d, env, command)]
    if failed:
        print(f"make_references: no new reference for {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
