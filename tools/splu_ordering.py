"""What SuperLU's column ordering costs, and that the kept ordering gives the same factor.

``python tools/splu_ordering.py DECK [--param NAME=VALUE ...] [--repeat R]`` runs the deck on
SPLU, keeps every matrix it factorises, then for each structure (the first matrix's ordering
kept, :class:`lagamine_py.solver.superlu.KeptOrdering`) factorises all of them both ways, in
loops of their own: ``splu`` with ``MMD_AT_PLUS_A`` (ordering at every call, as before the kept
ordering) and ``KeptOrdering.factor`` (columns moved beforehand, ``NATURAL``).  It prints the
best CPU time per factorisation of ``R`` passes for each, and whether the factors are the same
bit for bit (``L``, ``U``, ``perm_r`` and the solution of one right-hand side).  The output goes
to a temporary directory.  Timings only, never asserted in tests.
"""
import argparse
import sys
import tempfile
import time

import numpy as np
import scipy.sparse as sp

from lagamine_py.cli import main as lagamine_main
from lagamine_py.solver import linear
from lagamine_py.solver.superlu import CscParts, KeptOrdering, splu


def record(deck: str, params: list[str]) -> list[sp.csc_matrix]:
    """The matrices SPLU factorises in the run of ``deck``, as the CSC ``A^T`` it hands SuperLU."""
    seen = []
    factor = linear.SpluSolver.factor

    def kept(self, A):
        seen.append(sp.csc_matrix((A.data.copy(), A.indices, A.indptr), shape=A.shape))
        return factor(self, A)
    linear.SpluSolver.factor = kept
    try:
        with tempfile.TemporaryDirectory() as out:
            run = ["run", deck, "--output", out, "--solver", "SPLU", "-q"]
            lagamine_main(run + [f"--param={p}" for p in params])
    finally:
        linear.SpluSolver.factor = factor
    return seen


def same_factor(lu, ref, order: KeptOrdering, b: np.ndarray) -> bool:
    """``lu`` (kept order: its ``L`` and ``U`` are :class:`CscParts`, whose arrays may run past
    their last entry) is ``ref`` (``MMD_AT_PLUS_A``) bit for bit."""
    def arrays(M):
        if isinstance(M, CscParts):
            data, indices, indptr = M.arrays
            return indptr, indices[:indptr[-1]], data[:indptr[-1]]
        return M.indptr, M.indices, M.data
    return (np.array_equal(lu.perm_r, ref.perm_r)
            and all(np.array_equal(x, y) for a, r in ((lu.L, ref.L), (lu.U, ref.U))
                    for x, y in zip(arrays(a), arrays(r)))
            and np.array_equal(lu.solve(b[order.columns], trans="T"), ref.solve(b, trans="T")))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("deck")
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    groups: dict[tuple, list[sp.csc_matrix]] = {}
    for A in record(args.deck, args.param):
        groups.setdefault((A.shape, A.nnz), []).append(A)
    if not groups:
        print("no factorisation", file=sys.stderr)
        return 1
    same = True
    for (shape, nnz), mats in groups.items():
        mats = [A for A in mats if np.array_equal(A.indptr, mats[0].indptr)
                and np.array_equal(A.indices, mats[0].indices)]
        order = KeptOrdering(mats[0], splu(mats[0]))
        b = np.random.default_rng(0).standard_normal(shape[0])
        same &= all(same_factor(order.factor(A.data), splu(A), order, b) for A in mats)
        best = {"MMD_AT_PLUS_A": np.inf, "kept": np.inf}
        for _ in range(args.repeat):
            t = time.process_time()
            for A in mats:
                splu(A, permc_spec="MMD_AT_PLUS_A")
            best["MMD_AT_PLUS_A"] = min(best["MMD_AT_PLUS_A"], time.process_time() - t)
            t = time.process_time()
            for A in mats:
                order.factor(A.data)
            best["kept"] = min(best["kept"], time.process_time() - t)
        mmd, kept = (1e3 * best[k] / len(mats) for k in ("MMD_AT_PLUS_A", "kept"))
        print(f"{shape[0]} free DOFs, {nnz} entries, {len(mats)} factorisations: "
              f"MMD_AT_PLUS_A {mmd:.3f} ms, kept ordering {kept:.3f} ms ({kept / mmd:.2f}x)")
    print("the same factors bit for bit" if same else "FACTORS DIFFER")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
