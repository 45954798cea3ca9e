"""Output directories and restarts that know what they hold.

* a run locks its directory: a second run into it is refused (exit 2) naming the holder; the
  lock of a run that died is taken over;
* a directory holding another deck's results is refused (exit 2) unless ``--overwrite``, which
  replaces them; a rerun of the same deck leaves nothing of the old run (no stale ``.vtu``, no
  stale ``restart.npz`` for ``--restart`` to "complete");
* readers (checks, plot, sweep statistics) read the run's own ``<deck>.sta``/``.pvd``;
* the restart data records the deck's absolute path and digest: ``--restart`` from another
  directory resumes the right deck, and refuses a deck that changed;
* a damaged restart file, an output path that is a file, a read-only directory, a full disk, a
  plugin that raises: one message, exit 1, no traceback (``--debug`` shows it).
"""
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.checks import evaluate_checks
from lagamine_py.cli import main
from lagamine_py.core.outdir import LOCK_FILE, RECORD_FILE, ResultsOfAnotherDeck, run_name
from lagamine_py.output import Writer
from lagamine_py.results import RunResults, read_table
from lagamine_py.sweep import run_stats

DECKS = Path(__file__).resolve().parents[1] / "decks"
BLOCK, NOADH = DECKS / "coulomb_block.dat", DECKS / "coulomb_block_noadh.dat"
ROOT = Path(__file__).resolve().parents[1]


def run(*args) -> int:
    return main(["run", *map(str, args), "-q"])


# ---------------------------------------------------------------- the lock

HOLDER = """
import sys, time
from lagamine_py.core.outdir import DeckIdentity, claim
claim(sys.argv[1], DeckIdentity(sys.argv[2], "coulomb_block"))
print("held", flush=True)
time.sleep(60)
"""


def test_a_second_run_into_a_directory_in_use_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(out), str(BLOCK)],
                              stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert holder.stdout.readline().strip() == "held"      # a run in progress holds it
        assert run(BLOCK, "-o", out) == 2
        err = capsys.readouterr().err
        assert f"{out} is in use by another run: pid {holder.pid} on " in err
        assert not (out / "contact.csv").exists()
    finally:
        holder.kill()                  # dies without releasing: its lock is stale
        holder.wait()
    assert (out / LOCK_FILE).exists()
    assert run(BLOCK, "-o", out) == 0
    assert "took over the stale lock of pid" in (out / "coulomb_block.log").read_text()
    assert not (out / LOCK_FILE).exists()                      # released at the end


# ---------------------------------------------------------------- another deck, a rerun

def test_another_decks_results_are_refused_unless_overwrite(tmp_path, capsys):
    out = tmp_path / "out"
    assert run(BLOCK, "-o", out) == 0
    before = sorted(p.name for p in out.iterdir())
    assert run(NOADH, "-o", out) == 2
    assert "holds the results of another deck" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == before         # untouched
    assert run(NOADH, "-o", out, "--overwrite") == 0
    assert not list(out.glob("coulomb_block.*")) and not list(out.glob("coulomb_block_0*"))
    assert run_name(out) == "coulomb_block_noadh"
    T = read_table(out / "contact_totals.csv")["T"][-1]
    assert T == pytest.approx(-600.0, rel=1e-3)                  # T = phi P, B = 0


def test_a_directory_with_results_and_no_record_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    (out / "old_deck.sta").write_text("step,increment\n1,1\n")          # an older version's run
    assert run(BLOCK, "-o", out) == 2
    assert "no record attributes to a deck" in capsys.readouterr().err
    assert run(BLOCK, "-o", out, "--overwrite") == 0
    assert not (out / "old_deck.sta").exists()
    assert (out / "notes.txt").read_text() == "mine"          # not a run's file: kept
    assert run(BLOCK, "-o", out) == 0                          # a rerun keeps it too
    assert (out / "notes.txt").exists()


def test_a_rerun_leaves_nothing_of_the_old_run(tmp_path, capsys):
    """The old run's extra files go; its restart file does not survive a rerun that fails
    before its first increment, so ``--restart`` cannot report "completed" over it."""
    out = tmp_path / "out"
    deck = tmp_path / "block.dat"
    deck.write_text(BLOCK.read_text())
    assert run(deck, "-o", out) == 0
    (out / "block_0099.vtu").write_text("from a longer run")
    deck.write_text(BLOCK.read_text().replace("KP=2e6", "KP=1e15"))   # fails at once: exit 3
    assert run(deck, "-o", out) == 3
    assert not (out / "block_0099.vtu").exists()
    assert not (out / "restart.npz").exists()
    assert len(read_table(out / "block.sta")["step"]) > 0          # the failed attempts
    capsys.readouterr()
    assert run("--restart", out) == 1
    assert "holds no restart data" in capsys.readouterr().err


# ---------------------------------------------------------------- readers

def test_readers_read_the_runs_own_files(tmp_path, capsys):
    out = tmp_path / "out"
    deck = DECKS / "tube_limit.dat"
    assert run(deck, "-o", out, "--param", "PRESSURE=100") == 0
    # a stray status file that sorts first, as an old run's would
    (out / "aaa.sta").write_text("step,step_name,increment,time,dt,iterations,residual,cutbacks,"
                                 "failed,reason,load\n1,X,1,0.25,0.25,99,0,0,no,,\n")
    res = RunResults(out)
    assert res.name == "tube_limit" and res.own(".sta") == out / "tube_limit.sta"
    ours = read_table(out / "tube_limit.sta")
    stats = run_stats(out)
    assert stats["newton_iterations"] == int(ours["iterations"].sum())
    # LIMIT_PRESSURE reads the pressure reached from the run's own .sta: P = 100 reached
    # (below p_lim = (2/sqrt 3) 250 ln 2 = 200.09: the run must finish, error 0)
    [chk] = evaluate_checks([{"name": "L", "type": "LIMIT_PRESSURE",
                              "params": {"P": 100.0, "SIGMAY": 250.0, "A": 10.0, "B": 20.0}}], out)
    assert chk["error"] == 0.0 and chk["message"] == ""
    # without the record, the files of two decks: no reader guesses
    (out / RECORD_FILE).unlink()
    with pytest.raises(ResultsOfAnotherDeck, match="several decks"):
        run_name(out)
    [chk] = evaluate_checks([{"name": "L", "type": "LIMIT_PRESSURE",
                              "params": {"P": 100.0, "SIGMAY": 250.0, "A": 10.0, "B": 20.0}}], out)
    assert np.isnan(chk["error"]) and "several decks" in chk["message"]
    assert main(["plot", str(out)]) == 2
    assert "several decks" in capsys.readouterr().err


# ---------------------------------------------------------------- restart

class Stop(Writer):
    def increment(self, result):
        if (result.step, result.increment) == (2, 3):
            raise KeyboardInterrupt


def interrupted_run(deck: Path, out: Path, monkeypatch, params=()):
    from lagamine_py.output import tables
    real = tables.ReactionsWriter.increment

    def increment(self, result):
        real(self, result)
        if (result.step, result.increment) == (2, 3):
            raise KeyboardInterrupt
    monkeypatch.setattr(tables.ReactionsWriter, "increment", increment)
    assert main(["run", str(deck), "-o", str(out), "-q", *params]) == 130
    monkeypatch.setattr(tables.ReactionsWriter, "increment", real)


def test_restart_from_another_directory_resumes_the_same_deck(tmp_path, monkeypatch):
    """The deck path is recorded absolute: ``--restart`` run elsewhere, beside another deck of
    the same name, resumes the deck the run was started with (and its --param values)."""
    here, there = tmp_path / "here", tmp_path / "there"
    for d in (here, there):
        d.mkdir()
    (here / "block.dat").write_text(BLOCK.read_text().replace("PHI=0.3", "PHI=<PHI>")
                                    .replace("*UNITS", "*PARAMETER\nPHI = 0.1\n*UNITS"))
    (there / "block.dat").write_text(NOADH.read_text())          # same name, another deck
    monkeypatch.chdir(here)
    interrupted_run(Path("block.dat"), Path("out"), monkeypatch, ["--param", "PHI=0.3"])
    monkeypatch.chdir(there)
    assert main(["run", "--restart", str(here / "out"), "-q"]) == 0
    T = read_table(here / "out" / "contact_totals.csv")["T"][-1]
    assert T == pytest.approx(-700.0, rel=1e-3)          # PHI = 0.3, B = 5: 0.3 * 2000 + 5 * 20


def test_restart_of_a_changed_deck_is_refused(tmp_path, monkeypatch, capsys):
    deck, out = tmp_path / "block.dat", tmp_path / "out"
    deck.write_text(BLOCK.read_text())
    interrupted_run(deck, out, monkeypatch)
    deck.write_text(BLOCK.read_text().replace("PHI=0.3, B=5\n", "PHI=0.4, B=5\n"))
    capsys.readouterr()
    assert main(["run", "--restart", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "which has changed since" in err and "restore that deck" in err
    assert main(["run", str(NOADH), "--restart", str(out), "-q"]) == 2     # another deck given
    deck.write_text(BLOCK.read_text())                                     # restored: goes on
    assert main(["run", "--restart", str(out), "-q"]) == 0


@pytest.mark.parametrize("damage", ["cut", "garbage", "empty"])
def test_damaged_restart_data_is_one_message(tmp_path, monkeypatch, capsys, damage):
    out = tmp_path / "out"
    interrupted_run(BLOCK, out, monkeypatch)
    path = out / "restart.npz"
    data = path.read_bytes()
    path.write_bytes({"cut": data[:len(data) // 2], "garbage": b"PK\x03\x04" + os.urandom(500),
                      "empty": b""}[damage])
    capsys.readouterr()
    for given in ([], [str(BLOCK)]):                                       # deck given or not
        assert main(["run", *given, "--restart", str(out), "-q"]) == 1
        err = capsys.readouterr().err
        assert f"{path} cannot be read" in err and "run the deck again from the start" in err
        assert "Traceback" not in err and len(err.splitlines()) == 1


# ---------------------------------------------------------------- the file system says no

def test_an_output_path_that_is_a_file(tmp_path, capsys):
    (tmp_path / "out").write_text("a file")
    assert run(BLOCK, "-o", tmp_path / "out") == 1
    err = capsys.readouterr().err
    assert "cannot use the output directory" in err and "not a directory" in err
    assert "Traceback" not in err


def _make_read_only(path: Path) -> callable:
    """Make ``path`` unwritable (chmod; for root, which ignores modes, the immutable flag)."""
    path.chmod(0o555)
    probe = path / "probe"
    try:
        probe.write_text("x")
    except OSError:
        return lambda: path.chmod(0o755)
    probe.unlink()
    subprocess.run(["chattr", "+i", str(path)], check=True)
    return lambda: subprocess.run(["chattr", "-i", str(path)], check=True)


def test_a_read_only_output_directory(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    undo = _make_read_only(out)
    try:
        assert run(BLOCK, "-o", out) == 1
    finally:
        undo()
    err = capsys.readouterr().err
    assert "cannot use the output directory" in err and "Traceback" not in err


def test_a_full_disk_stops_the_run_with_a_message_and_restart_finishes_it(tmp_path):
    """A file-size limit (the kernel's EFBIG, as ENOSPC would be) hit in the middle of the run:
    exit 1 and one message; with room again, ``--restart`` gives the tables of a run that never
    stopped."""
    full, out = tmp_path / "full", tmp_path / "out"
    assert run(BLOCK, "-o", full) == 0

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, 60_000))
    proc = subprocess.run([sys.executable, "-m", "lagamine_py", "run", str(BLOCK), "-o", str(out),
                           "-q"], preexec_fn=limit, capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 1, proc.stderr
    assert "cannot write the results: File too large" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert main(["run", "--restart", str(out), "-q"]) == 0
    for name in ("contact.csv", "contact_totals.csv", "reactions.csv", "displacements.csv",
                 "coulomb_block.sta"):
        assert (out / name).read_bytes() == (full / name).read_bytes(), name


class Explodes(Writer):
    """A writer plugin that raises in the middle of a run."""

    def increment(self, result):
        if result.increment == 2:
            raise RuntimeError("boom")


def test_a_plugin_that_raises_is_one_message(tmp_path, capsys):
    registry.register("writers", "EXPLODES")(Explodes)
    try:
        deck = tmp_path / "block.dat"
        deck.write_text(BLOCK.read_text().replace(
            "BLOCK_TOP, P, 100\n", "BLOCK_TOP, P, 100\n*OUTPUT, WRITERS=EXPLODES/STATUS\n"))
        assert run(deck, "-o", tmp_path / "out") == 1
        err = capsys.readouterr().err
        assert "RuntimeError: boom" in err and "--debug" in err and "Traceback" not in err
        log = (tmp_path / "out" / "block.log").read_text().splitlines()
        assert "exit status 1: stopped by an error: RuntimeError: boom" in log[-1]
        with pytest.raises(RuntimeError, match="boom"):
            main(["run", str(deck), "-o", str(tmp_path / "out"), "-q", "--debug"])
    finally:
        registry.REGISTRY.tables["writers"].pop("EXPLODES")
