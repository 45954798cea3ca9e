"""Benchmark: how long ``lagamine-py check`` takes on a large mesh deck, and its peak memory.

Writes a deck of an ``n x n`` Q8 block (``*NODE`` and ``*ELEMENT`` lines, a material, a step),
or the same block as a gmsh 4.1 mesh (``--msh ascii`` or ``--msh binary``, physical groups BODY
and BOTTOM) read by a deck through ``*IMPORT``, then runs ``lagamine-py check`` on it in a
fresh process, ``--repeat`` times, and reports the line count (or the node count), the file
size, the wall time of each run and the peak resident memory of the child
(``resource.getrusage``), with the machine's load.

    python tools/bench_deck.py --cells 520                # 1.08 million lines, 45 MB
    python tools/bench_deck.py --cells 520 --msh binary   # 812 k nodes, 270 k Q8 in a .msh
    python tools/bench_deck.py --cells 100 --repeat 3

Measured 2026-11-24 on this project's 2-core machine (load 0.6), 520 cells (1 083 693 lines,
44.8 MB): before the bulk path (c36b20f~1) 73.5 s and 4.72 GB; after it (c36b20f) 2.77 s and
0.48 GB.  After the meshes work (the Jacobian proved over whole elements, clockwise elements,
unused and coincident nodes, surfaces on the boundary checked), each measured right after the
other on the same machine: 2.81 - 2.97 s against 2.72 - 2.75 s before (8778381) at load 1.4,
4.60 - 4.66 s against 4.18 - 4.27 s at load 2.8; peak 525 MB both.  The block as a gmsh 4.1
mesh through *IMPORT (--cells 580: 1 011 521 nodes, 336 400 Q8): binary 1.40 - 1.92 s at load
1.4 (2.21 - 2.76 s at 2.9), ASCII 3.19 - 3.41 s (5.08 - 5.43 s), peak 0.38 - 0.42 GB.
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


def write_msh(path: Path, n: int, binary: bool) -> int:
    """The same n x n Q8 block as a gmsh 4.1 mesh (one surface entity with the nodes and the
    elements, physical group BODY; the bottom side as 3-node lines of a curve, group BOTTOM);
    returns the number of nodes."""
    m = 2 * n + 1
    ii, jj = np.meshgrid(np.arange(m), np.arange(m))
    keep = ~((ii % 2 == 1) & (jj % 2 == 1))
    num = np.zeros((m, m), np.int64)
    num[keep] = np.arange(1, keep.sum() + 1)
    xyz = np.column_stack([ii[keep] * 10.0 / (m - 1), jj[keep] * 10.0 / (m - 1), np.zeros(keep.sum())])
    ex, ey = np.meshgrid(np.arange(n), np.arange(n))
    i0, j0 = (2 * ex).ravel(), (2 * ey).ravel()
    quads = np.stack([num[j0, i0], num[j0, i0 + 2], num[j0 + 2, i0 + 2], num[j0 + 2, i0],
                      num[j0, i0 + 1], num[j0 + 1, i0 + 2], num[j0 + 2, i0 + 1], num[j0 + 1, i0]], 1)
    k = np.arange(n)
    lines = np.stack([num[0, 2 * k], num[0, 2 * k + 2], num[0, 2 * k + 1]], 1)   # end, end, mid
    nn, nq = len(xyz), len(quads)
    head = ("$MeshFormat\n4.1 %d 8\n" % binary)
    entities = ("$Entities\n0 1 1 0\n1 0 0 0 10 0 0 1 2 0\n1 0 0 0 10 10 0 1 1 0\n$EndEntities\n")
    names = '$PhysicalNames\n2\n2 1 "BODY"\n1 2 "BOTTOM"\n$EndPhysicalNames\n'
    with open(path, "wb") as fh:
        fh.write(head.encode())
        if binary:
            fh.write(np.array([1], np.int32).tobytes() + b"\n")
        fh.write(b"$EndMeshFormat\n" + names.encode())
        if binary:                 # curve 1 (group 2), surface 1 (group 1): tag, box, groups, bounds
            box = np.array([0, 0, 0, 10, 10, 0], float).tobytes()
            fh.write(b"$Entities\n" + np.array([0, 1, 1, 0], np.uint64).tobytes())
            for group in (2, 1):
                fh.write(np.array([1], np.int32).tobytes() + box + np.array([1], np.uint64).tobytes()
                         + np.array([group], np.int32).tobytes() + np.array([0], np.uint64).tobytes())
            fh.write(b"\n$EndEntities\n")
        else:
            fh.write(entities.encode())
        fh.write(b"$Nodes\n")
        if binary:
            fh.write(np.array([1, nn, 1, nn], np.uint64).tobytes())
            fh.write(np.array([2, 1, 0], np.int32).tobytes() + np.array([nn], np.uint64).tobytes())
            fh.write(np.arange(1, nn + 1, dtype=np.uint64).tobytes() + xyz.tobytes())
            fh.write(b"\n$EndNodes\n$Elements\n")
            fh.write(np.array([2, n + nq, 1, n + nq], np.uint64).tobytes())
            for dim, typ, cells, first in ((1, 8, lines, 1), (2, 16, quads, n + 1)):
                fh.write(np.array([dim, 1, typ], np.int32).tobytes() + np.array([len(cells)], np.uint64).tobytes())
                tags = np.arange(first, first + len(cells))[:, None]
                fh.write(np.hstack([tags, cells]).astype(np.uint64).tobytes())
            fh.write(b"\n$EndElements\n")
        else:
            fh.write(f"1 {nn} 1 {nn}\n2 1 0 {nn}\n".encode())
            np.savetxt(fh, np.arange(1, nn + 1), fmt="%d")
            np.savetxt(fh, xyz, fmt="%.10g")
            fh.write(f"$EndNodes\n$Elements\n2 {n + nq} 1 {n + nq}\n".encode())
            for dim, typ, cells, first in ((1, 8, lines, 1), (2, 16, quads, n + 1)):
                fh.write(f"{dim} 1 {typ} {len(cells)}\n".encode())
                np.savetxt(fh, np.hstack([np.arange(first, first + len(cells))[:, None], cells]), fmt="%d")
            fh.write(b"$EndElements\n")
    return nn


def write_import_deck(path: Path, mesh: Path) -> None:
    path.write_text(f"*IMPORT, INPUT={mesh.name}\n*MATERIAL, NAME=M, LAW=ELASTIC\nE=1000, NU=0.3\n"
                    "*SOLID, ELSET=BODY, MATERIAL=M\n*STEP\n*STATIC\n1, 1\n*BOUNDARY\nBOTTOM, 1, 2, 0\n"
                    "*END STEP\n")


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
    ap.add_argument("--msh", choices=("ascii", "binary"), help="the block as a gmsh 4.1 mesh read by *IMPORT")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(tmp) / "big.dat"
        if args.msh:
            mesh = Path(tmp) / "big.msh"
            nodes = write_msh(mesh, args.cells, args.msh == "binary")
            write_import_deck(deck, mesh)
            print(f"mesh: {nodes} nodes, {args.cells ** 2} Q8, gmsh 4.1 {args.msh}, "
                  f"{mesh.stat().st_size / 1e6:.1f} MB; load {os.getloadavg()[0]:.2f}")
        else:
            lines = write_deck(deck, args.cells)
            size = deck.stat().st_size / 1e6
            print(f"deck: {lines} lines, {size:.1f} MB; load {os.getloadavg()[0]:.2f}")
        for k in range(args.repeat):
            wall, peak = check(deck)
            print(f"run {k + 1}: check {wall:.2f} s wall, peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
