"""Where the CPU time of one run goes: ``python tools/run_phases.py DECK [lagamine-py run options]``.

Runs ``lagamine-py run DECK -q --overwrite -o <temporary directory>`` in this process with the
methods that do the work wrapped (the code is not changed), and prints the CPU time
(``time.process_time``: what a loaded machine changes least) of each: the imports, the deck,
the problem, the element groups (indented: inside ``evaluate``), the linear solves, the writers
(indented: inside ``hand_out``) and the restart data.  Timings only, never asserted in tests.
"""
from __future__ import annotations

import sys
import tempfile
import time
from collections import Counter

T: Counter = Counter()
N: Counter = Counter()


def wrap(owner, name: str, label: str) -> None:
    """Replace ``owner.name`` by a function that adds its CPU time to ``T[label]``."""
    real = vars(owner)[name]

    def timed(*args, **kwargs):
        t = time.process_time()
        try:
            return real(*args, **kwargs)
        finally:
            T[label] += time.process_time() - t
            N[label] += 1
    setattr(owner, name, timed)


def main(argv: list[str]) -> int:
    c0 = time.process_time()
    from lagamine_py import cli
    from lagamine_py.elements import contact, solid
    from lagamine_py.output import nodal, status, tables, vtk
    from lagamine_py.solver import newton, problem, steps
    imports = time.process_time() - c0
    for owner, name, label in (
            (cli, "_load", "deck"), (steps, "build_problem", "problem (pattern, groups)"),
            (steps.Controller, "_hand_out_initial", "output of t = 0"),
            (problem.Problem, "evaluate", "evaluate"),
            (solid.SolidElement, "compute", "  solid groups"),
            (contact.ContactGroup, "compute", "  contact groups"),
            (newton, "_linear_solve", "linear solves"),
            (steps.Controller, "_hand_out", "writers"),
            (vtk.VtkWriter, "increment", "  VTU + PVD"),
            (tables.ContactWriter, "increment", "  contact.csv, contact_totals.csv"),
            (nodal.DisplacementsWriter, "increment", "  displacements.csv"),
            (status.StatusWriter, "increment", "  .sta"),
            (steps.Controller, "_save_restart", "restart data"),
            (steps.Controller, "run", "controller (all increments)")):
        wrap(owner, name, label)
    with tempfile.TemporaryDirectory() as tmp:
        code = cli.main(["run", *argv, "-q", "--overwrite", "-o", f"{tmp}/out"])
    total = time.process_time() - c0
    print(f"{argv[0]}: exit {code}; CPU in this process {total * 1e3:.0f} ms, of which imports "
          f"of the CLI, solver and writers {imports * 1e3:.0f} ms (the interpreter's start "
          f"comes on top)")
    for label, t in T.items():
        print(f"  {label:34s} {t * 1e3:8.1f} ms  {N[label]:5d} calls")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
