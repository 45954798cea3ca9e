"""The fused numba solid kernel's cost per call, and its answers bit for bit:
``python tools/kernel_calls.py WHAT... [--calls N] [--repeat R] [--save F | --check F]``.

The twin of ``tools/solid_calls.py`` for :mod:`lagamine_py.kernels.solid`.  ``WHAT``:
``NXxNY``, press-then-slide at that mesh (``tools/bench.py``'s deck), or deck files
(``decks/*.dat``).  Each is run with ``KERNEL=NUMBA``; the inputs of ``N`` of its solid groups'
``compute_into`` calls spread over the run (displacements, committed state, context, the
tangent asked, the pattern positions) are recorded, then replayed in their order into zeroed
CSR data and force vectors:

* the time per call with and without the tangent (best of ``R`` passes over the calls, CPU),
  with the start of the increment (F_old^-1, b_e_n) computed again at every call, as at a
  Newton iteration's first evaluation, and kept (``kept start``), as at the later ones,
* ``--save F``: every answer (the scattered data and force, the element forces, the trial
  state, the failure) to ``F`` (npz) and the calls to ``F.calls.pickle``; ``--check F``: the
  saved calls replayed and their answers compared bit for bit with ``F`` (exit 1 on any
  difference; with ``--rtol R``, on any array whose finite entries differ by more than ``R``
  times its largest entry, or whose failures or non-finite entries differ).
  ``--split-elements N`` replays with the kernel's element ranges on threads from
  ``2 N`` elements (``kernels.solid.Split``): ``--check`` then compares them with the saved
  one-thread answers.  Save with one tree and check with another (``PYTHONPATH=<tree> python
  tools/kernel_calls.py ...``): a change that keeps every byte keeps every run's path.

``--plastic NXxNY [--element Q8PE] [--law RAMBERG_OSGOOD]``: instead, the ``tools/bench.py
assembly`` group (a Ramberg-Osgood Q8 block, NLGEOM) from a committed state at 0.9 of its
displacement, every point plastic (the ln P branch of the return map, as in press-then-slide's
plastic zone): us per element with and without the tangent, the start of the increment kept
(best of ``R`` calls, CPU).  Steadier than replayed calls under load: one large call.  ``--law
ELASTIC`` or ``J2_LINEAR`` (same block and displacements) splits the cost of the return map off.

Timings only, never asserted in tests; what the kernel computes is held by the tests.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solid_calls import collect_runs, groups_of, record_calls, save_or_check  # noqa: E402  (tools/ on the path)


def record(what: str, calls: int):
    """The inputs of ``calls`` of the fused solid groups' calls in the run of ``what``
    (``NXxNY`` or a deck file), evenly spread, and how many the run made."""
    def inputs(group, u_new, u_old, state, ctx, tangent, data, f_out, positions):
        return (group, np.array(u_new), np.array(u_old),
                {k: np.array(v) for k, v in state.items()}, ctx, bool(tangent),
                np.array(positions), int(np.max(positions)) + 1, len(f_out))
    return record_calls(what, calls, "compute_into", "NUMBA", inputs)


def replay(call, tangent: bool, fresh_start: bool = True):
    """One recorded call into zeroed data and force: (data, force, GroupResult)."""
    g, un, uo, state, ctx, _, positions, nnz, ndof = call
    if fresh_start:
        g._cache.pop("kernel_old_key", None)
    data, f = (np.zeros(nnz) if tangent else None), np.zeros(ndof)
    r = g.compute_into(un, uo, state, ctx, tangent, data, f, positions)
    return data, f, r


def answers(calls, prefix: str = "") -> dict[str, np.ndarray]:
    """Every output of every call, with and without the tangent."""
    out = {}
    for n, call in enumerate(calls):
        for mode, t in (("now", True), ("none", False)):
            data, f, r = replay(call, t)
            key = f"{prefix}{n}/{mode}"
            out[f"{key}/failure"] = np.array(str(r.failure or ""))
            out[f"{key}/f_out"] = f
            out[f"{key}/f"] = np.asarray(r.f)
            if t:
                out[f"{key}/data"] = data
            for k, v in (r.state or {}).items():
                out[f"{key}/state/{k}"] = np.asarray(v)
    return out


def cpu_per_call(calls, tangent: bool, repeat: int, fresh_start: bool) -> float:
    """Best over ``repeat`` passes of the CPU per call (s), the zeroed arrays' cost excluded."""
    best = np.inf
    for _ in range(repeat):
        spent = 0.0
        for call in calls:
            g, un, uo, state, ctx, _, positions, nnz, ndof = call
            if fresh_start:
                g._cache.pop("kernel_old_key", None)
            else:                                   # the start arrays of this call kept
                g.compute_into(un, uo, state, ctx, False, None, np.zeros(ndof), positions)
            data, f = (np.zeros(nnz) if tangent else None), np.zeros(ndof)
            t = time.process_time()
            g.compute_into(un, uo, state, ctx, tangent, data, f, positions)
            spent += time.process_time() - t
        best = min(best, spent / len(calls))
    return best


#: ``--law``: the plastic block's law (ELASTIC and J2_LINEAR split the cost of the law off)
LAWS = {"RAMBERG_OSGOOD": dict(SIGMA0=250.0, ALPHA=0.5, N=10.0),
        "J2_LINEAR": dict(SIGMAY=250.0, H=1000.0), "ELASTIC": {}}


def plastic_block(size: str, element: str, repeat: int, law: str = "RAMBERG_OSGOOD") -> str:
    """us per element of the fused kernel on the assembly group from a plastic committed state
    (``--plastic``)."""
    from bench import E_STEEL, structured_q8

    from lagamine_py.elements.base import StepContext
    from lagamine_py.registry import get
    from lagamine_py.solver.pattern import Pattern

    nx, ny = (int(n) for n in size.split("x"))
    xy, conn = structured_q8(nx, ny)
    xy = xy + [10.0, 0.0]                                   # off the axis (axisymmetric)
    material = get("laws", law)(E=E_STEEL, NU=0.3, **LAWS[law])
    group = get("elements", element)(np.arange(len(conn)), conn, xy, material, 1.0)
    group.use_kernels(True)
    pattern = Pattern(2 * len(xy), [group.dofs])
    rng = np.random.default_rng(0)
    u = np.c_[0.002 * xy[:, 0], -0.004 * xy[:, 1]] + 1e-4 * rng.standard_normal(xy.shape)
    ctx = StepContext(nlgeom=True, t_old=0.0, t_new=1.0, foundation_old={}, foundation_new={})
    u_old = 0.9 * u
    first = group.compute_into(u_old, np.zeros_like(u), group.init_state(), ctx, False, None,
                               np.zeros(pattern.ndof), pattern.positions[0])
    state = {k: np.array(v) for k, v in first.state.items()}
    out, wall = {}, {}
    for tangent in (True, False):
        best = best_wall = np.inf
        for _ in range(repeat):
            data, f = (np.zeros(pattern.nnz) if tangent else None), np.zeros(pattern.ndof)
            t, w = time.process_time(), time.perf_counter()
            r = group.compute_into(u, u_old, state, ctx, tangent, data, f, pattern.positions[0])
            best = min(best, time.process_time() - t)
            best_wall = min(best_wall, time.perf_counter() - w)
        out[tangent] = 1e6 * best / len(conn)
        wall[tangent] = 1e6 * best_wall / len(conn)
    plastic = float((r.state["peeq"] > state["peeq"]).mean())
    return (f"{element} {law} {size}, {len(conn)} elements, {plastic:.0%} of the points plastic: "
            f"with tangent {out[True]:.3f} us per element, forces only {out[False]:.3f} "
            f"(CPU; wall {wall[True]:.3f} and {wall[False]:.3f})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="*", help="NXxNY (press-then-slide) or deck files")
    ap.add_argument("--plastic", metavar="NXxNY", help="the plastic block instead")
    ap.add_argument("--element", default="Q8PE")
    ap.add_argument("--law", default="RAMBERG_OSGOOD", choices=sorted(LAWS))
    ap.add_argument("--calls", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--save")
    ap.add_argument("--check")
    ap.add_argument("--rtol", type=float, help="--check to this relative tolerance (of each "
                    "array's largest entry), not bit for bit")
    ap.add_argument("--split-elements", type=int, metavar="N",
                    help="elements per thread at least for the kernel's element ranges "
                         "(SolidElement.split_elements: a group of 2N elements or more is split "
                         "when the kernel has two threads); the count of split calls is printed")
    a = ap.parse_args(argv)
    if a.split_elements:
        from lagamine_py.elements.solid import SolidElement
        SolidElement.split_elements = a.split_elements
    if a.plastic:
        print(plastic_block(a.plastic, a.element, a.repeat, a.law))
        return 0
    runs, got = collect_runs(a.what, a.check, record, a.calls, reset_recorded=True), {}
    for what, (calls, total) in runs.items():
        ne = sum(len(g.conn) for g in groups_of(calls))
        print(f"{what}: {ne} solid elements, {len(calls)} of the run's {total} fused "
              f"evaluations replayed")
        got.update(answers(calls, f"{what}/"))
    code = save_or_check(a.save, a.check, runs, got, rtol=a.rtol)
    if a.split_elements:
        from lagamine_py import kernels
        print(f"split calls (element ranges on threads): {kernels.calls['solid_split']}")
    for what, (calls, _) in runs.items():
        elements = np.mean([len(c[0].conn) for c in calls])
        print(what)
        for label, t, fresh in (("with tangent", True, False), ("forces only", False, False),
                                ("tangent, fresh start", True, True)):
            cpu = cpu_per_call(calls, t, a.repeat, fresh)
            print(f"  {label:22s} {cpu * 1e3:8.3f} ms CPU per call, "
                  f"{cpu / elements * 1e6:6.3f} us per element")
    return code


if __name__ == "__main__":
    sys.exit(main())
