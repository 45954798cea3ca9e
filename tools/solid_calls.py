"""The NumPy solid groups' cost per call, and their answers bit for bit:
``python tools/solid_calls.py WHAT... [--calls N] [--repeat R] [--save F | --check F] [--profile]``.

``WHAT``: ``NXxNY``, press-then-slide at that mesh (``tools/bench.py``'s deck; 16x8 is
``decks/press_slide.dat``), or deck files (``decks/*.dat``).  Each is run with ``KERNEL=NUMPY``;
the inputs of ``N`` of its solid groups' ``compute`` calls spread over the run (displacements,
committed state, context, the tangent asked) are recorded, then replayed in their order:

* the time per call with and without the tangent (best of ``R`` passes over the calls, CPU),
* the NumPy / Python C functions called per evaluation (``sys.setprofile`` ``c_call`` events:
  ufuncs, ``np.einsum``, array methods ...), by name with ``--profile``,
* ``--save F``: every answer (forces, tangent now and deferred, the trial state) to ``F`` (npz);
  ``--check F``: the saved calls (``F.calls.pickle``: a changed answer moves a run's later calls)
  replayed and their answers compared bit for bit with ``F`` (exit 1 on any difference).

Timings only, never asserted in tests; what the element computes is held by the tests.
"""
from __future__ import annotations

import argparse
import pickle
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def record_calls(what: str, calls: int, method: str, kernel: str, inputs):
    """The inputs of ``calls`` of ``SolidElement.<method>``'s calls in the run of ``what``
    (``NXxNY`` or a deck file) with ``KERNEL=kernel``, evenly spread, and how many the run
    made; ``inputs(group, *args)`` is what a call keeps (copies of its arrays).  Shared with
    ``tools/kernel_calls.py``."""
    from bench import press_slide_deck

    from lagamine_py.deck import load_deck
    from lagamine_py.elements.solid import SolidElement
    from lagamine_py.output import default_writers
    from lagamine_py.solver import run

    seen = []
    real = getattr(SolidElement, method)

    def kept(self, *args, **kwargs):
        seen.append(inputs(self, *args, **kwargs))
        return real(self, *args, **kwargs)

    with tempfile.TemporaryDirectory() as tmp:
        if what.endswith(".dat"):
            deck = Path(what).resolve()
        else:
            nx, ny = (int(n) for n in what.split("x"))
            deck = Path(tmp) / "press_slide.dat"
            deck.write_text(press_slide_deck(nx, ny))
        model = load_deck(deck)
        for step in model.steps:
            step.controls["KERNEL"] = kernel
        setattr(SolidElement, method, kept)
        try:
            run(model, Path(tmp) / "out", writers=default_writers(Path(tmp) / "out", model,
                                                                  names=("STATUS",)),
                deck_path=deck)
        finally:
            setattr(SolidElement, method, real)
    pick = np.unique(np.linspace(0, len(seen) - 1, min(calls, len(seen))).round().astype(int))
    return [seen[i] for i in pick], len(seen)


def record(what: str, calls: int):
    """The inputs of ``calls`` of the NumPy solid groups' compute calls in the run of ``what``
    (``NXxNY`` or a deck file), evenly spread, and how many the run made."""
    def inputs(group, u_new, u_old, state, ctx, tangent=True):
        return (group, np.array(u_new), np.array(u_old),
                {k: np.array(v) for k, v in state.items()}, ctx, tangent)
    return record_calls(what, calls, "compute", "NUMPY", inputs)


def answers(calls, prefix: str = "") -> dict[str, np.ndarray]:
    """Every output of every call: forces and state of ``tangent=False``, forces, tangent and
    state of ``tangent=True``, the tangent of ``tangent=LATER``."""
    from lagamine_py.elements.base import LATER
    out = {}
    for n, (g, un, uo, state, ctx, _) in enumerate(calls):
        for mode, t in (("now", True), ("none", False), ("later", LATER)):
            r = g.compute(un, uo, state, ctx, t)
            key = f"{prefix}{n}/{mode}"
            out[f"{key}/failure"] = np.array(str(r.failure or ""))
            out[f"{key}/f"] = np.asarray(r.f)
            if mode == "now":
                out[f"{key}/K"] = np.asarray(r.K)
            if mode == "later" and r.later is not None:
                out[f"{key}/K"] = np.asarray(r.later())
            for k, v in (r.state or {}).items():
                out[f"{key}/state/{k}"] = np.asarray(v)
    return out


def cpu_per_call(calls, tangent, repeat: int) -> float:
    """Best over ``repeat`` passes of the CPU per call (s)."""
    from lagamine_py.elements.base import LATER
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        for g, un, uo, state, ctx, _ in calls:
            r = g.compute(un, uo, state, ctx, tangent)
            if tangent is LATER and r.later is not None:
                r.later()
        best = min(best, (time.process_time() - t) / len(calls))
    return best


#: the opcodes that are an array operation when their operands are arrays (``a * b``, ``a[i]``,
#: ``a[i] = b``, ``a < b``, ``-a``)
OPERATOR_OPCODES = ("BINARY_OP", "BINARY_SUBSCR", "STORE_SUBSCR", "COMPARE_OP", "UNARY_NEGATIVE",
                    "UNARY_INVERT")


def c_calls(calls, tangent) -> Counter:
    """Operations per run of the calls: C functions called (``sys.setprofile`` ``c_call``
    events: ``np.einsum``, ``np.where``, array methods ...) by name, and the operators executed
    in lagamine_py's own frames (``a * b``, ``a[i]``: ufuncs and indexing NumPy runs without a
    call event) by opcode, each counted once whatever its operands (a product of two floats
    too: an upper bound of the array operators)."""
    import dis
    count: Counter = Counter()
    names = dis.opname

    def prof(frame, event, arg):
        if event == "c_call":
            count[getattr(arg, "__qualname__", str(arg))] += 1

    def trace(frame, event, arg):
        if "lagamine_py" not in frame.f_code.co_filename:
            return None
        frame.f_trace_opcodes = True
        if event == "opcode":
            op = names[frame.f_code.co_code[frame.f_lasti]]
            if op in OPERATOR_OPCODES:
                count[op] += 1
        return trace

    sys.setprofile(prof)
    sys.settrace(trace)
    try:
        for g, un, uo, state, ctx, _ in calls:
            g.compute(un, uo, state, ctx, tangent)
    finally:
        sys.settrace(None)
        sys.setprofile(None)
    return count


def _kinds(keys) -> list[str]:
    """The outputs (``now/K``, ``none/f`` ...) of answer keys ``<run>/<call>/<mode>/<output>``."""
    return sorted({"/".join(k.split("/")[-2:]) if "/state/" not in k
                   else "/".join(k.split("/")[-3:]) for k in keys})


def _bits(a: np.ndarray) -> np.ndarray:
    """The bytes of ``a``: -0.0 is not 0.0, a NaN's payload counts (np.array_equal would not)."""
    return np.ascontiguousarray(a).view(np.uint8) if a.dtype.kind in "fcbiu" else a


def groups_of(calls):
    """The distinct groups of recorded calls (each call's first item)."""
    return {id(c[0]): c[0] for c in calls}.values()


def collect_runs(whats, check: str | None, record, calls: int, reset_recorded: bool = False):
    """``{what: (calls, total)}``: the calls saved beside ``check`` (a changed result moves a
    run's later calls, so the check replays the saved ones) or, for a run not saved, ``record``'s;
    a saved run's groups are reset as built (and a recorded run's with ``reset_recorded``)."""
    saved = {}
    if check:
        with open(check + ".calls.pickle", "rb") as fh:
            saved = pickle.load(fh)
    runs = {}
    for what in whats:
        found, (run_calls, total) = what in saved, saved.get(what) or record(what, calls)
        if found or reset_recorded:
            for g in groups_of(run_calls):
                g._cache, g._views = {}, None                        # as built
        runs[what] = run_calls, total
    return runs


def save_or_check(save: str | None, check: str | None, runs: dict, got: dict,
                  describe=lambda differ: "", rtol: float | None = None) -> int:
    """``save``: the answers ``got`` to ``save`` (npz) and the runs' calls (their groups reset as
    built) to ``save.calls.pickle``; ``check``: ``got`` against the answers saved in ``check`` for
    the runs asked, bit for bit (``describe(differ)`` adds to the verdict).  1 when any differs.
    ``rtol``: an array that differs agrees still when its non-finite entries are the same and
    its finite ones within ``rtol`` of the array's largest magnitude (the largest such
    difference is printed).  Shared with ``tools/kernel_calls.py``."""
    if save:
        np.savez(save, **got)
        for calls, _ in runs.values():
            for g in groups_of(calls):
                g._cache, g._views = {}, None
        with open(save + ".calls.pickle", "wb") as fh:
            pickle.dump({w: (c, t) for w, (c, t) in runs.items()}, fh)
        print(f"answers saved to {save} ({len(got)} arrays)")
    if not check:
        return 0
    ref = {k: v for k, v in np.load(check).items()               # the runs asked for only
           if any(k.startswith(w + "/") for w in runs)}
    differ = sorted(set(ref) ^ set(got))
    differ += [k for k in ref if k in got and not (
        ref[k].shape == got[k].shape and ref[k].dtype == got[k].dtype
        and np.array_equal(_bits(ref[k]), _bits(got[k])))]
    print(f"bit for bit against {check}: "
          + ("identical" if not differ else f"{len(differ)} arrays differ: {differ[:8]}"
             + describe(differ)))
    if rtol is None or not differ:
        return 1 if differ else 0
    worst, where, beyond = 0.0, "", []
    for k in differ:
        d = _relative_difference(ref.get(k), got.get(k))
        if d > worst:
            worst, where = d, k
        if not d <= rtol:
            beyond.append(k)
    print(f"within rtol {rtol:g} of each array's largest entry: "
          + ("all" if not beyond else f"{len(beyond)} arrays not: {beyond[:8]}")
          + f"; largest relative difference {worst:.3g} ({where})")
    return 1 if beyond else 0


def _relative_difference(a, b) -> float:
    """max |a - b| / max |a| over the finite entries; inf when shapes, kinds, the non-finite
    entries or (strings) the values differ."""
    if a is None or b is None or a.shape != b.shape or a.dtype.kind != b.dtype.kind:
        return np.inf
    if a.dtype.kind not in "fc":
        return 0.0 if np.array_equal(a, b) else np.inf
    fa, fb = np.isfinite(a), np.isfinite(b)
    if not np.array_equal(fa, fb) or not np.array_equal(a[~fa], b[~fb], equal_nan=True):
        return np.inf
    scale = np.max(np.abs(a[fa]), initial=0.0)
    diff = np.max(np.abs(a[fa] - b[fb]), initial=0.0)
    return 0.0 if diff == 0.0 else (diff / scale if scale > 0.0 else np.inf)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="+", help="NXxNY (press-then-slide) or deck files")
    ap.add_argument("--calls", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--save")
    ap.add_argument("--check")
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args(argv)
    runs, got = collect_runs(a.what, a.check, record, a.calls), {}
    for what, (calls, total) in runs.items():
        ne = sum(len(g.conn) for g in groups_of(calls))
        print(f"{what}: {ne} solid elements, {len(calls)} of the run's {total} solid "
              f"evaluations replayed")
        got.update(answers(calls, f"{what}/"))
    code = save_or_check(a.save, a.check, runs, got,
                         lambda differ: f"; outputs: {_kinds(differ)}")
    from lagamine_py.elements.base import LATER
    for what, (calls, _) in runs.items():
        points = np.mean([c[0].conn.shape[0] * c[0].nq for c in calls])
        print(what)
        for label, t in (("with tangent", True), ("forces only", False),
                         ("LATER + later()", LATER)):
            n = sum(c_calls(calls, t).values()) / len(calls)
            cpu = cpu_per_call(calls, t, a.repeat)
            print(f"  {label:16s} {cpu * 1e3:7.3f} ms CPU per call, {cpu / points * 1e9:6.0f} "
                  f"ns per Gauss point, {n:5.0f} operations per evaluation")
        if a.profile:
            for name, n in c_calls(calls, True).most_common(40):
                print(f"    {n / len(calls):6.1f}  {name}")
    return code


if __name__ == "__main__":
    sys.exit(main())
