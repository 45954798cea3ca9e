"""Benchmark: how long ``lagamine-py check`` takes on a large mesh deck, and its peak memory.

Writes a deck of an ``n x n`` Q8 block (``*NODE`` and ``*ELEMENT`` lines, a material, a step),
then runs ``lagamine-py check`` on it in a fresh process, ``--repeat`` times, and reports the
line count, the file size, the wall time of each run and the peak resident memory of the child
(``resource.getrusage``), with the machine's load.

    python tools/bench_deck.py --cells 520          # 1.08 million lines, 45 MB
    python tools/bench_deck.py --cells 100 --repeat 3

Measured 2026-11-24 on this project's 2-core machine (load 0.6), 520 cells (1 083 693 lines,
44.8 MB): before the bulk path (c36b20f~1) 73.5 s and 4.72 GB; after it (c36b20f) 2.77 s and
0.48 GB.
"""
from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_deck(path: Path, n: int) -> int:
    """An n x n Q8 block on [0, 10]^2; returns the number of lines written."""
    m = 2 * n + 1
    ii, jj = np.meshgrid(np.arange(m), np.arange(m))
    keep = ~((ii % 2 == 1) & (jj % 2 == 1))
    num = np.zeros((m, m), np.int64)
    num[keep] = np.arange(1, keep.sum() + 1)
    x, y = ii[keep] * 10.0 / (m - 1), jj[keep] * 10.0 / (m - 1)
    ex, ey = np.meshgrid(np.arange(n), np.arange(n))
    i0, j0 = (2 * ex).ravel(), (2 * ey).ravel()
    conn = np.stack([num[j0, i0], num[j0, i0 + 2], num[j0 + 2, i0 + 2], num[j0 + 2, i0],
                     num[j0, i0 + 1], num[j0 + 1, i0 + 2], num[j0 + 2, i0 + 1], num[j0 + 1, i0]], 1)
    with open(path, "w") as fh:
        fh.write("*NODE, NSET=ALL\n")
        np.savetxt(fh, np.column_stack([num[keep], x, y]), fmt="%d, %.10g, %.10g")
        fh.write("*ELEMENT, TYPE=CPE8, ELSET=BODY\n")
        np.savetxt(fh, np.column_stack([np.arange(1, len(conn) + 1), conn]), fmt="%d",
                   delimiter=", ")
        fh.write("*MATERIAL, NAME=M, LAW=ELASTIC\nE=1000, NU=0.3\n"
                 "*SOLID, ELSET=BODY, MATERIAL=M\n*STEP\n*STATIC\n1, 1\n*BOUNDARY\nALL, 1, 2, 0\n"
                 "*END STEP\n")
    return keep.sum() + len(conn) + 12


def check(path: Path) -> tuple[float, float]:
    """Wall time (s) and peak RSS (MB) of ``lagamine-py check path`` in a child process."""
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "lagamine_py", "check", str(path)],
                         capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise SystemExit(f"check failed: {out.stderr}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return wall, peak


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=520, help="Q8 cells a side (520: 1.08M lines)")
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(tmp) / "big.dat"
        lines = write_deck(deck, args.cells)
        size = deck.stat().st_size / 1e6
        print(f"deck: {lines} lines, {size:.1f} MB; load {os.getloadavg()[0]:.2f}")
        for k in range(args.repeat):
            wall, peak = check(deck)
            print(f"run {k + 1}: check {wall:.2f} s wall, peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
