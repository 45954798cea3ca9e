"""Kills at the worst moments of a run, then ``run --restart``: the same files as a run that was
never killed.

Each scenario forks this process; the child runs ``coulomb_block.dat`` (2 steps, 12 increments)
through the command line with one function patched to end the process (``os._exit``: no
``finally``, no flush, as SIGKILL) at a chosen point: at a step end before and after the
restart point is saved, in the middle of writing the end-of-step displacements or a contact
row, at the run's end before the files are closed.  The parent then resumes the run with
``lagamine-py run --restart`` and compares every output file, byte for byte, with those of an
uninterrupted run (the log, which has times, and the restart file itself excepted).

Before the end-of-step displacements were written with the step's last increment (they were
held until the next step started), the kills after the restart point at a step end lost a whole
step of ``displacements.csv``; a row torn by a kill was glued to the resumed run's first row.
"""
import filecmp
import os
from pathlib import Path

import pytest

from lagamine_py.cli import main

DECK = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"
KILLED = 77
SKIP = {"coulomb_block.log", "restart.npz", "lagamine-run.json"}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("full") / "out"
    assert main(["run", str(DECK), "-o", str(out), "-q"]) == 0
    return out


def die():
    os._exit(KILLED)


def kill_after_restart_point(step: int):
    """At the end of ``step``: the restart point saved, the next step not started."""
    from lagamine_py.solver import steps
    real = steps.Controller._save_restart

    def save(self, si, loads, stepper, *rest):
        real(self, si, loads, stepper, *rest)
        if si + 1 == step and stepper.finished:
            die()
    steps.Controller._save_restart = save


def kill_before_restart_point(step: int):
    """At the end of ``step``: every writer took the last increment, the restart point is not
    yet replaced (killed between writing its temporary file and renaming it; the old file
    already hard-linked to a retired name, core.outdir.replace: the resumed run unlinks it)."""
    from lagamine_py.core import outdir
    from lagamine_py.solver import restart
    real = outdir.os.replace

    def replace(src, dst):
        if Path(dst).name == restart.FILE:
            import numpy as np
            with np.load(src) as z:
                end = int(z["step"]) + 1 == step and float(z["t"]) >= 1.0
            if end:
                die()
        return real(src, dst)
    outdir.os.replace = replace


def kill_writing_displacements(step: int):
    """Half of the end-of-step displacement rows of ``step`` written, then killed."""
    from lagamine_py.output import nodal
    real = nodal.DisplacementsWriter._write

    def write(self, r):
        if r.step == step:
            text = "".join(f"{r.step},{r.increment},{r.time!r},{int(n)},0,0,0,0\n"
                           for n in self.model.node_ids)
            self._fh.write(text[:len(text) // 2 + 7])      # mid-row
            self._fh.flush()
            die()
        real(self, r)
    nodal.DisplacementsWriter._write = write


def kill_tearing_a_contact_row(step: int, increment: int):
    """At (step, increment) the contact rows are written, then the start of the next
    increment's first row ("2,1" of "2,10,..."), and the process dies."""
    from lagamine_py.output import tables
    real = tables.ContactWriter.increment

    def increment_(self, result):
        real(self, result)
        if (result.step, result.increment) == (step, increment):
            fh = self._csv.handles["_points"]
            fh.write(f"{step},1")
            fh.flush()
            die()
    tables.ContactWriter.increment = increment_


def kill_tearing_the_pvd(step: int, increment: int):
    """At (step, increment) the VTU files are written and half of their new PVD lines are
    written over the index's footer (a write cut short), then the process dies."""
    from lagamine_py.output import vtk
    real = vtk.VtkWriter._append_pvd

    def append(self, first):
        r = self.entries[first]
        if r[0] == self._kill_time:
            data = "".join(vtk._pvd_line(*e) for e in self.entries[first:]).encode()
            with open(self.pvd_path, "r+b") as fh:
                fh.seek(self._pvd_end)
                fh.write(data[:len(data) // 2 + 5])
            die()
        real(self, first)
    vtk.VtkWriter._append_pvd = append
    # the time of (step, increment) in coulomb_block.dat: step 1 ends at 1, step 2 has 10 of 0.1
    vtk.VtkWriter._kill_time = round(1.0 + 0.1 * increment, 10) if step == 2 else None


def kill_at_close():
    """Every increment written and saved; killed as the files are being closed."""
    from lagamine_py.output import status

    def close(self, status_, message):
        die()
    status.StatusWriter.close = close


SCENARIOS = {
    "step 1 end, after the restart point": lambda: kill_after_restart_point(1),
    "step 1 end, before the restart point": lambda: kill_before_restart_point(1),
    "step 1 end, displacements half written": lambda: kill_writing_displacements(1),
    "step 2 increment 9, a contact row torn": lambda: kill_tearing_a_contact_row(2, 9),
    "run end, after the last restart point": lambda: kill_after_restart_point(2),
    "step 2 increment 5, the PVD index torn": lambda: kill_tearing_the_pvd(2, 5),
    "run end, closing the files": kill_at_close,
}


def killed_run(out: Path, inject) -> int:
    pid = os.fork()
    if pid == 0:                                  # the child: patched, run, killed
        code = 0
        try:
            inject()
            code = main(["run", str(DECK), "-o", str(out), "-q"])
        finally:
            os._exit(code if code else 0)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status)


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_a_killed_run_resumes_to_the_same_files(tmp_path, uninterrupted, scenario):
    out = tmp_path / "out"
    assert killed_run(out, SCENARIOS[scenario]) == KILLED        # it did die there
    assert (out / "restart.npz").exists()
    assert main(["run", "--restart", str(out), "-q"]) == 0
    names = sorted(p.name for p in uninterrupted.iterdir() if p.name not in SKIP)
    assert sorted(p.name for p in out.iterdir() if p.name not in SKIP) == names
    differ = [n for n in names if not filecmp.cmp(out / n, uninterrupted / n, shallow=False)]
    assert not differ, f"{scenario}: these files differ from the uninterrupted run: {differ}"
