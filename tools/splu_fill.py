"""SuperLU's fill on a deck's tangent: the size AUTO's solver choice reads.

``python tools/splu_fill.py DECK [--param NAME=VALUE ...]`` runs the deck on SPLU and prints, for
its first factorisation, the free DOFs, the entries of K_ff, SuperLU's factor entries
(``SuperLU.nnz``, compared with ``AUTO_SPLU_FILL``) and the factorisation's CPU time. The
output goes to a temporary directory.
"""
import argparse
import sys
import tempfile
import time

from lagamine_py.cli import main as lagamine_main
from lagamine_py.solver import linear


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("deck")
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE")
    args = ap.parse_args(argv)
    first = []
    factor = linear.SpluSolver.factor

    def counted(self, A):
        t = time.process_time()
        factor(self, A)
        if not first:
            first.append((A.shape[0], A.nnz, self.lu.nnz, time.process_time() - t))
    linear.SpluSolver.factor = counted
    with tempfile.TemporaryDirectory() as out:
        run = ["run", args.deck, "--output", out, "--solver", "SPLU", "-q"]
        lagamine_main(run + [f"--param={p}" for p in args.param])
    if not first:
        print("no factorisation", file=sys.stderr)
        return 1
    n, nnz, fill, t = first[0]
    print(f"{args.deck}: {n} free DOFs, K_ff {nnz} entries, SuperLU factor {fill} entries "
          f"({fill / nnz:.1f}x; AUTO_SPLU_FILL {linear.AUTO_SPLU_FILL}), first factorisation "
          f"{t * 1e3:.1f} ms CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
