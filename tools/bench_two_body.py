"""Cost per Newton iteration of two-body contact against a rigid foundation (issue 18, item 4).

The two-body Hertz deck (decks/hertz_two_body.dat, both cylinders; ``--mesh xfine`` is the
20 k DOF mesh of tools/make_two_body_meshes.py) against the same two meshes where the upper
cylinder presses a rigid flat instead (the lower one held apart, no contact): same DOFs, same
solid work, the contact group and its pattern differ.

Per variant (median of ``--repeat`` runs): the DOFs, the set-up (deck, problem and pattern
build, timed apart), the converged iterations and the solves (every factorisation, those of
cut-back attempts included), and the run's wall time per solve, split into the contact group,
the solids, assembly and the linear solver.  ``--kernel`` is ``*CONTROLS KERNEL=`` of both
(AUTO: numba solids above 2000 elements, NumPy contact; NUMBA: the rigid contact group's numba
kernel too -- the two-body group has none and stays NumPy).

    python tools/bench_two_body.py [--mesh xfine] [--repeat 3] [--kernel AUTO] [--search 0.5]

Set MKL_NUM_THREADS=1 for stable counts (docs/performance.md).
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from lagamine_py.deck import load_deck
from lagamine_py.output.base import Writer
from lagamine_py.solver import problem as problem_mod
from lagamine_py.solver import steps as steps_mod

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


def _timed(obj, name: str, label: str, t: dict, n: dict) -> None:
    """Wrap ``obj.name`` to add its wall time to ``t[label]`` and count calls in ``n``."""
    fn = getattr(obj, name)

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            t[label] += time.perf_counter() - t0
            n[label] += 1
    setattr(obj, name, timed)


def timed(deck: Path, params: dict) -> dict:
    """One run of ``deck``: set-up and run wall times, iterations, solves, time per part."""
    t0 = time.perf_counter()
    model = load_deck(deck, parameters=params)
    problem = problem_mod.build_problem(model)
    setup = time.perf_counter() - t0
    t, n = defaultdict(float), defaultdict(int)
    for g, kind in zip(problem.groups, problem.kinds):
        _timed(g, "compute", kind, t, n)
        if kind == "solid":
            _timed(g, "compute_into", kind, t, n)       # the fused numba path
    _timed(problem.pattern, "assemble_data", "assembly", t, n)
    orig_make = steps_mod.make_solver

    def make_solver(name):
        s = orig_make(name)
        _timed(s, "factor", "factor", t, n)
        _timed(s, "solve", "solve", t, n)
        return s
    steps_mod.make_solver = make_solver
    counter = Iterations()
    try:
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            steps_mod.run(model, Path(out), writers=[counter], deck_path=deck, problem=problem)
            wall = time.perf_counter() - t0
    finally:
        steps_mod.make_solver = orig_make
    solves = max(n["factor"], 1)
    return {"ndof": model.ndof, "setup": setup, "wall": wall, "iterations": counter.count,
            "solves": n["factor"], "per_solve": wall / solves,
            "contact": t["contact"] / solves, "solid": t["solid"] / solves,
            "assembly": t["assembly"] / solves, "linear": (t["factor"] + t["solve"]) / solves}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="xfine")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--kernel", default="AUTO", help="*CONTROLS KERNEL= of both runs")
    ap.add_argument("--passes", default="1", help="PASSES= of the two-body pair")
    ap.add_argument("--search", type=float, default=None,
                    help="SEARCH= of the two-body pair (default: the element's)")
    args = ap.parse_args()
    text = with_kernel((DECKS / "hertz_two_body.dat").read_text(), args.kernel)
    two = DECKS / "_bench_two_body.dat"
    rigid = DECKS / "_bench_rigid_two_meshes.dat"
    search = "" if args.search is None else f", SEARCH={args.search}"
    two.write_text(text.replace("PASSES=<PASSES>\n", f"PASSES=<PASSES>{search}\n"))
    rigid.write_text(rigid_variant(text))
    ratio = []
    try:
        for label, deck in (("two bodies", two), ("rigid flat", rigid)):
            runs = [timed(deck, {"MESH": args.mesh, "PASSES": args.passes})
                    for _ in range(args.repeat)]
            med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            ratio.append(med["per_solve"])
            print(f"{label:11s} ndof {int(med['ndof']):6d}  set-up {med['setup']:6.2f} s  "
                  f"iterations {int(med['iterations']):3d}  solves {int(med['solves']):3d}  "
                  f"run {med['wall']:6.2f} s  per solve {med['per_solve'] * 1e3:7.1f} ms "
                  f"(contact {med['contact'] * 1e3:6.1f}, solids {med['solid'] * 1e3:6.1f}, "
                  f"assembly {med['assembly'] * 1e3:5.1f}, linear {med['linear'] * 1e3:6.1f})")
        print(f"two bodies / rigid flat per solve: {ratio[0] / ratio[1]:.2f}")
    finally:
        two.unlink()
        rigid.unlink()


if __name__ == "__main__":
    main()
