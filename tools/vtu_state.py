"""The VTK writer's cost on one recorded state of press-then-slide (issue 17, item 8).

    python tools/vtu_state.py NX NY [--increment 3] [--repeat 8] [--save F | --load F] [--out DIR]

Runs press-then-slide at ``NX x NY`` (``tools/bench.py``'s deck) until the writers are handed
increment N, keeps that :class:`~lagamine_py.output.base.IncrementResult`, and times the VTK
writer on it alone (CPU, best of ``--repeat``): a whole state (every file of it), the body
grid (its fields and their nodal recovery) and the body file's encoding and write.

``--save F`` pickles the model and the state, ``--load F`` times a saved state instead of
running: two source trees then time the same state, alternated (``PYTHONPATH=<tree> python
tools/vtu_state.py --load F`` times that tree's writer).
``--out DIR`` writes the state's files once into DIR, for ``cmp`` between trees (the body file
of a state must not change when only the writer's speed does).
"""
from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


class _Recorded(Exception):
    """Raised by the instrumented writer once it holds the state."""


def record(nx: int, ny: int, number: int):
    """``(model, result)``: press-then-slide at ``nx`` x ``ny`` run up to the ``number``-th
    increment handed to the VTK writer."""
    import bench
    from lagamine_py.deck import load_deck
    from lagamine_py.output.vtk import VtkWriter
    from lagamine_py.solver import steps

    work = Path(tempfile.mkdtemp(prefix="vtu_state_"))
    deck = work / f"press_slide_{nx}x{ny}.dat"
    deck.write_text(bench.press_slide_deck(nx, ny))
    model = load_deck(deck)
    seen, kept = [0], {}
    inner = VtkWriter.increment

    def increment(self, result):
        seen[0] += 1
        if seen[0] == number:
            kept["result"] = result
            raise _Recorded
        inner(self, result)
    VtkWriter.increment = increment
    try:
        steps.run(model, work / "out", deck_path=deck)
    except _Recorded:
        pass
    finally:
        VtkWriter.increment = inner
    if "result" not in kept:
        raise SystemExit(f"the run wrote fewer than {number} increments")
    return model, kept["result"]


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        c = time.process_time()
        fn()
        times.append(time.process_time() - c)
    return 1e3 * min(times)


def time_state(model, result, repeat: int, out: Path | None = None) -> dict:
    """CPU ms (best of ``repeat``) of the writer's parts on ``result``."""
    from lagamine_py.output import vtk

    result.write_fields = True
    work = Path(tempfile.mkdtemp(prefix="vtu_state_"))
    writer = vtk.VtkWriter(out if out is not None else work, model)
    writer.start_run()
    writer._write_state(result)                 # the recovery plan built, files written once
    grid = writer._body_grid(result)
    return {"state_ms": _best(lambda: writer._write_state(result), repeat),
            "body_grid_ms": _best(lambda: writer._body_grid(result), repeat),
            "body_file_ms": _best(lambda: vtk._write_vtu(grid, work / "body.vtu"), repeat),
            "body_file_mb": (work / "body.vtu").stat().st_size / 1e6}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("nx", type=int, nargs="?")
    ap.add_argument("ny", type=int, nargs="?")
    ap.add_argument("--increment", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=8)
    ap.add_argument("--save", type=Path)
    ap.add_argument("--load", type=Path)
    ap.add_argument("--out", type=Path)
    a = ap.parse_args(argv)
    if a.load:
        with open(a.load, "rb") as fh:
            model, result = pickle.load(fh)
    elif a.nx and a.ny:
        model, result = record(a.nx, a.ny, a.increment)
    else:
        ap.error("NX NY or --load F")
    if a.save:
        with open(a.save, "wb") as fh:
            pickle.dump((model, result), fh)
    for key, value in time_state(model, result, a.repeat, a.out).items():
        print(f"{key:14s} {value:9.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
