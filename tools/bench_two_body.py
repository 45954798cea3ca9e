"""Cost per Newton iteration of two-body contact against a rigid foundation (issue 18, item 4).

The two-body Hertz deck (decks/hertz_two_body.dat, both cylinders, fine mesh by default) against
the same two meshes where the upper cylinder presses a rigid flat instead (the lower one held
apart, no contact): same DOFs, same solid work, the contact group and its pattern differ.
Reports the DOFs, iterations and wall time per iteration of each (median of --repeat runs; a
run's wall time includes building the problem, small against the iterations here).

    python tools/bench_two_body.py [--mesh fine] [--repeat 3]
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from lagamine_py.deck import load_deck
from lagamine_py.output.base import Writer
from lagamine_py.solver import run

DECKS = Path(__file__).resolve().parents[1] / "decks"


def rigid_variant(text: str) -> str:
    """The two-body deck with the upper arc on a rigid flat at y = -10 (no master)."""
    text = text.replace("*CONTACT, SURFACE=<SLAVE>, MASTER=<MASTER>, LAW=SMOOTH, GAUSS=<GAUSS>, PASSES=<PASSES>",
                        "*FOUNDATION, NAME=FLAT\n-5, -10\n5, -10\n15, -10\n"
                        "*CONTACT, SURFACE=ARC, FOUNDATION=FLAT, LAW=SMOOTH, GAUSS=<GAUSS>")
    return text.replace("R=5, E=57870.4, NU=0", "R=10, E=200000, NU=0.3")


class Iterations(Writer):
    """Counts the Newton iterations of the converged increments."""
    params = ()

    def __init__(self):
        self.count = 0

    def increment(self, result):
        self.count += int(result.iterations)


def with_kernel(text: str, kernel: str) -> str:
    """The deck with ``*CONTROLS KERNEL=kernel`` in its step."""
    return text.replace("*BOUNDARY\nAXIS, 1, 1, 0", f"*CONTROLS\nKERNEL={kernel}\n*BOUNDARY\nAXIS, 1, 1, 0")


def timed(deck: Path, params: dict) -> tuple[int, int, float]:
    model = load_deck(deck, parameters=params)
    counter = Iterations()
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        run(model, Path(out), writers=[counter], deck_path=deck)
        wall = time.perf_counter() - t0
    return model.ndof, counter.count, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="fine")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--kernel", default="NUMPY", help="*CONTROLS KERNEL= of both (the two-body "
                    "group is NumPy only; AUTO gives the rigid one its numba kernel)")
    args = ap.parse_args()
    text = with_kernel((DECKS / "hertz_two_body.dat").read_text(), args.kernel)
    two = DECKS / "_bench_two_body.dat"
    rigid = DECKS / "_bench_rigid_two_meshes.dat"
    two.write_text(text)
    rigid.write_text(rigid_variant(text))
    try:
        for label, deck in (("two bodies", two), ("rigid flat", rigid)):
            runs = [timed(deck, {"MESH": args.mesh}) for _ in range(args.repeat)]
            ndof, iters, _ = runs[0]
            wall = statistics.median(r[2] for r in runs)
            print(f"{label:11s} ndof {ndof:6d}  iterations {iters:3d}  wall {wall:7.3f} s  "
                  f"per iteration {wall / max(iters, 1) * 1e3:8.1f} ms")
    finally:
        two.unlink()
        rigid.unlink()


if __name__ == "__main__":
    main()
