"""``lagamine-py sweep``: grid, one directory and one sweep.csv row per point, failures recorded,
resume, local process pool and dask.distributed.

The solver is replaced by a stand-in: a small script run exactly as ``python -m lagamine_py run``
would be (same arguments), or a Python function given as the sweep's runner.  The stand-in writes
the files a run writes (``.sta``, ``contact_totals.csv``) with values chosen here, so every number
asserted below is known in advance: the Newton iterations it wrote, the Coulomb error it built in.
"""
import csv
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from functools import partial
from pathlib import Path

import pytest

from lagamine_py import sweep as sw
from lagamine_py.cli import main

# The stand-in for `python -m lagamine_py run DECK -o OUT -q --param NAME=VALUE ...`.  With
# KP = k x 1e6 it writes T = (1 + 0.01 k)(PHI P + B A): a Coulomb error of 0.01 k; it takes
# k + 2 increments of 3 Newton iterations each, plus one failed attempt of 7 iterations.
# KP=bad: stops with exit status 3 and a message on stderr.
STAND_IN = textwrap.dedent('''
    import sys, time
    args = sys.argv[1:]
    deck, out = args[0], args[args.index("-o") + 1]
    assert "-q" in args
    params = dict(args[k + 1].split("=", 1) for k, a in enumerate(args) if a == "--param")
    import pathlib
    open(pathlib.Path(out) / "pid.txt", "w").write(str(__import__("os").getpid()))
    time.sleep(float(params.get("SLEEP", 0)))
    burn = float(params.get("BURN", 0))
    t0 = time.process_time()
    while time.process_time() - t0 < burn:
        pass
    import pathlib
    out = pathlib.Path(out)
    open(out / "argv.txt", "w").write("\\n".join(args))
    sta = ["step,step_name,increment,time,dt,iterations,residual,cutbacks,failed,reason"]
    if params.get("KP") == "kill":
        import os, signal
        os.kill(os.getpid(), signal.SIGKILL)
    if params.get("KP") == "bad":
        sta.append("1,PRESS,1,0.5,0.5,3,1e-9,0,no,")
        sta.append("1,PRESS,2,1.0,0.5,12,1e3,1,yes,residual diverged")
        (out / "stand_in.sta").write_text("\\n".join(sta) + "\\n")
        print("lagamine-py: step 1 PRESS did not converge at time 0.5: residual diverged", file=sys.stderr)
        # the summary the real closing message goes on with
        print("  contact B->F: P = 2000, T = 0, T/P = 0", file=sys.stderr)
        print("  wall time 0.1 s", file=sys.stderr)
        sys.exit(3)
    k = int(float(params.get("KP", "1e6")) / 1e6)
    b = float(params.get("B", 0))
    for inc in range(1, k + 3):
        sta.append(f"1,PRESS,{inc},{inc / (k + 2)},0.1,3,1e-9,0,no,")
    sta.insert(2, "1,PRESS,2,0.9,0.2,7,1e2,1,yes,too many iterations")
    (out / "stand_in.sta").write_text("\\n".join(sta) + "\\n")
    P = 2000.0
    T = (1 + 0.01 * k) * (0.3 * P + b * 20)
    (out / "contact_totals.csv").write_text(
        f"step,increment,time,contact,P,T\\n1,1,1.0,B->F,{P!r},{T!r}\\n")
    print("lagamine-py: 1 step finished")
    print("  wall time 0.1 s")
''')


@pytest.fixture
def stand_in(tmp_path):
    script = tmp_path / "stand_in.py"
    script.write_text(STAND_IN)
    deck = tmp_path / "block.dat"
    deck.write_text("*HEADING\nstand-in deck (not read: the checks come from fake_checks)\n")
    return [sys.executable, str(script)], deck


def fake_checks(deck, params):
    """What load_deck would give for a deck with *CHECK, NAME=SLIDING, TYPE=COULOMB."""
    return [{"name": "SLIDING", "type": "COULOMB", "where": None,
             "params": {"PHI": 0.3, "B": params.get("B", "0"), "A": 20}}]


@pytest.fixture(autouse=True)
def _checks_from_fake(monkeypatch):
    # the checks are read in the sweep's own process, so this holds for every executor
    monkeypatch.setattr(sw, "load_point_checks", fake_checks)


def read_sweep(outdir):
    with open(outdir / "sweep.csv", newline="") as fh:
        return list(csv.DictReader(fh))


# ---------------------------------------------------------------- grid


def test_parse_sets_and_grid():
    axes = sw.parse_sets(["MESH=coarse,fine", "Q= 800, 900 ,800"])
    assert axes == {"MESH": ["coarse", "fine"], "Q": ["800", "900"]}
    points = sw.grid(axes)
    assert points == [{"MESH": "coarse", "Q": "800"}, {"MESH": "coarse", "Q": "900"},
                      {"MESH": "fine", "Q": "800"}, {"MESH": "fine", "Q": "900"}]
    assert sw.point_dirname(points[1]) == "MESH=coarse_Q=900"
    assert sw.point_dirname({"F": "a/b c"}) == "F=a-b-c"
    assert sw.grid({}) == [{}] and sw.point_dirname({}) == "default"


@pytest.mark.parametrize("bad, why", [("Q", "expected NAME=v1,v2"), ("=1,2", "expected NAME=v1,v2"),
                                     ("1Q=3", "expected NAME=v1,v2"), ("Q=", "an empty value"),
                                     ("Q=1,,2", "an empty value")])
def test_bad_sets_are_refused(tmp_path, stand_in, bad, why, capsys):
    _, deck = stand_in
    assert main(["sweep", str(deck), "--set", bad, "-o", str(tmp_path / "s")]) == 2
    assert why in capsys.readouterr().err
    assert not (tmp_path / "s" / "sweep.csv").exists()


def test_a_parameter_set_twice_is_refused(tmp_path, stand_in, capsys):
    _, deck = stand_in
    assert main(["sweep", str(deck), "--set", "Q=1", "--set", "q=2", "-o", str(tmp_path / "s")]) == 2
    assert "set twice" in capsys.readouterr().err


# ---------------------------------------------------------------- one point as a subprocess


def test_run_point_passes_the_parameters_and_measures_the_child(tmp_path, stand_in):
    command, deck = stand_in
    out = sw.run_point(deck, {"KP": "2e6", "BURN": "0.2"}, tmp_path / "pt", command=command)
    assert out["status"] == 0 and out["reason"] == "lagamine-py: 1 step finished"
    argv = (tmp_path / "pt" / "argv.txt").read_text().splitlines()
    assert argv == [str(deck), "-o", str(tmp_path / "pt"), "-q", "--overwrite",
                    "--param", "KP=2e6", "--param", "BURN=0.2"]
    # the child burnt >= 0.2 s of its own CPU time; wait4 accounts it to that child alone
    assert 0.2 <= out["cpu_s"] < 60
    assert sw.run_stats(tmp_path / "pt") == {"newton_iterations": 4 * 3 + 7, "increments": 4,
                                             "failed_attempts": 1}


def test_run_point_reports_why_a_run_stopped(tmp_path, stand_in):
    command, deck = stand_in
    out = sw.run_point(deck, {"KP": "bad"}, tmp_path / "pt", command=command)
    assert out["status"] == 3
    assert out["reason"] == "lagamine-py: step 1 PRESS did not converge at time 0.5: residual diverged"


def test_run_point_reports_the_real_closing_message(tmp_path):
    """The program's own closing message (not the stand-in's): its first line is the reason, not
    the summary lines after it (contact totals, results, wall time)."""
    deck = Path(__file__).resolve().parents[1] / "tools" / "study_decks" / "block_study.dat"
    # one Newton iteration cannot find the onset of sliding: a failure on every CPU (the push at
    # KP = KT = 2e8 in one increment, used before, converged under other BLAS kernels' round-off)
    out = sw.run_point(deck, {"MAXIT": "1"}, tmp_path / "pt")
    assert out["status"] == 3
    assert out["reason"].startswith("lagamine-py: step 2 (PUSH) could not converge")
    assert "last failure" in out["reason"]


def test_run_point_reports_a_killed_run(tmp_path, stand_in):
    command, deck = stand_in
    out = sw.run_point(deck, {"KP": "kill"}, tmp_path / "pt", command=command)
    assert (out["status"], out["reason"]) == (-9, "killed by signal SIGKILL")


# ---------------------------------------------------------------- local sweeps


def check_rows(rows, b_values, kp_values):
    assert [(r["B"], r["KP"]) for r in rows] == [(b, k) for b in b_values for k in kp_values]
    for r in rows:
        k = int(float(r["KP"]) / 1e6)
        assert r["point"] == f"B={r['B']}_KP={r['KP']}"
        assert (r["status"], r["reason"]) == ("0", "lagamine-py: 1 step finished")
        assert int(r["newton_iterations"]) == (k + 2) * 3 + 7
        assert (int(r["increments"]), int(r["failed_attempts"])) == (k + 2, 1)
        assert float(r["SLIDING_error"]) == pytest.approx(0.01 * k, rel=1e-9)
        assert float(r["SLIDING_T_cf"]) == pytest.approx(0.3 * 2000 + float(r["B"]) * 20)
        assert float(r["wall_s"]) > 0 and float(r["cpu_s"]) >= 0


def test_local_sweep_2x2_with_two_workers(tmp_path, stand_in, capsys):
    command, deck = stand_in
    out = tmp_path / "sweep"
    code = sw.sweep_main(deck, ["B=0,5", "KP=1e6,2e6"], out, jobs=2,
                         runner=partial(sw.run_point, command=command))
    assert code == 0
    rows = read_sweep(out)
    check_rows(rows, ["0", "5"], ["1e6", "2e6"])
    for r in rows:
        stored = json.loads((out / r["point"] / "point.json").read_text())
        assert stored["params"] == {"B": r["B"], "KP": r["KP"]} and stored["row"]["status"] == 0
        assert stored["checks"][0]["measured"]["P"] == 2000.0
    assert "4 of 4 points ran to the end" in capsys.readouterr().out


class Counting:
    """A runner that records the points it ran (inline sweeps only: -j 1)."""

    def __init__(self, command):
        self.command, self.ran = command, []

    def __call__(self, deck, params, pointdir):
        self.ran.append(dict(params))
        return sw.run_point(deck, params, pointdir, command=self.command)


def test_resume_skips_finished_points(tmp_path, stand_in):
    command, deck = stand_in
    out = tmp_path / "sweep"
    first = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5", "KP=1e6,2e6"], out, runner=first) == 0
    assert len(first.ran) == 4
    (out / "B=5_KP=1e6" / "point.json").unlink()            # as if interrupted during that point
    again = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5", "KP=1e6,2e6"], out, runner=again) == 0
    assert again.ran == [{"B": "5", "KP": "1e6"}]
    check_rows(read_sweep(out), ["0", "5"], ["1e6", "2e6"])
    # a grid extended by one value runs only the new points
    more = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5", "KP=1e6,2e6,3e6"], out, runner=more) == 0
    assert more.ran == [{"B": "0", "KP": "3e6"}, {"B": "5", "KP": "3e6"}]
    check_rows(read_sweep(out), ["0", "5"], ["1e6", "2e6", "3e6"])


def test_failed_points_are_recorded(tmp_path, stand_in):
    command, deck = stand_in
    out = tmp_path / "sweep"
    code = sw.sweep_main(deck, ["B=5", "KP=1e6,bad"], out, jobs=2,
                         runner=partial(sw.run_point, command=command))
    assert code == 1
    good, bad = read_sweep(out)
    assert good["status"] == "0"
    assert bad["status"] == "3"
    assert bad["reason"] == "lagamine-py: step 1 PRESS did not converge at time 0.5: residual diverged"
    assert (int(bad["newton_iterations"]), int(bad["increments"]), int(bad["failed_attempts"])) == (15, 1, 1)
    # no contact_totals.csv: the check is NaN and says why
    assert math.isnan(float(bad["SLIDING_error"])) and "contact_totals.csv" in bad["SLIDING_message"]
    # a run that finished, even badly, is not run again
    again = Counting(command)
    assert sw.sweep_main(deck, ["B=5", "KP=1e6,bad"], out, runner=again) == 1 and again.ran == []


def broken_runner(deck, params, pointdir):
    if params["KP"] == "2e6":
        raise RuntimeError("scratch disk full")
    return {"status": 0, "reason": "ok", "cpu_s": 0.0}


def test_a_broken_worker_is_recorded_and_retried(tmp_path, stand_in):
    _, deck = stand_in
    out = tmp_path / "sweep"
    assert sw.sweep_main(deck, ["KP=1e6,2e6"], out, jobs=2, runner=broken_runner) == 1
    ok, broken = read_sweep(out)
    assert ok["status"] == "0"
    assert broken["status"] == "1" and broken["reason"] == "sweep: RuntimeError: scratch disk full"
    assert not (out / "KP=2e6" / "point.json").exists()      # so a rerun tries it again
    assert (out / "KP=1e6" / "point.json").exists()


def test_deck_errors_are_recorded_without_running(tmp_path, stand_in, monkeypatch):
    command, deck = stand_in

    def refuse(deck_, params):
        if params["MESH"] == "nope":
            raise sw.PointDeckError(f"{deck_}:3: *INCLUDE: no file meshes/cylinder_nope.inp")
        return []
    monkeypatch.setattr(sw, "load_point_checks", refuse)
    runner = Counting(command)
    assert sw.sweep_main(deck, ["MESH=coarse,nope"], out := tmp_path / "s", runner=runner) == 1
    assert runner.ran == [{"MESH": "coarse"}]
    rows = read_sweep(out)
    assert rows[1]["status"] == "2" and "cylinder_nope.inp" in rows[1]["reason"]
    # once the deck is fixed, a rerun runs that point (and only that one)
    monkeypatch.setattr(sw, "load_point_checks", lambda deck_, params: [])
    again = Counting(command)
    assert sw.sweep_main(deck, ["MESH=coarse,nope"], out, runner=again) == 0
    assert again.ran == [{"MESH": "nope"}]
    assert [r["status"] for r in read_sweep(out)] == ["0", "0"]


# ---------------------------------------------------------------- dask.distributed


class OnDaskWorker:
    """Runs the stand-in and notes which dask worker ran it (get_worker fails outside a task)."""

    def __init__(self, command):
        self.command = command

    def __call__(self, deck, params, pointdir):
        from distributed import get_worker
        Path(pointdir).mkdir(parents=True, exist_ok=True)
        (Path(pointdir) / "worker.txt").write_text(get_worker().address)
        return sw.run_point(deck, params, pointdir, command=self.command)


def test_dask_sweep_through_a_local_cluster(tmp_path, stand_in):
    distributed = pytest.importorskip(
        "distributed", reason="dask.distributed is not installed (optional extra: pip install "
                              "'lagamine_py[dask]'); the --scheduler path is untested here")
    command, deck = stand_in
    out = tmp_path / "sweep"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0") as cluster:
        code = sw.sweep_main(deck, ["B=0,5", "KP=1e6,2e6"], out, scheduler=cluster.scheduler_address,
                             runner=OnDaskWorker(command))
        workers = set(cluster.scheduler_info["workers"])
    assert code == 0
    rows = read_sweep(out)
    check_rows(rows, ["0", "5"], ["1e6", "2e6"])
    assert {(out / r["point"] / "worker.txt").read_text() for r in rows} <= workers


def test_an_unreachable_scheduler_is_a_clear_error(tmp_path, stand_in, monkeypatch, capsys):
    pytest.importorskip("distributed", reason="dask.distributed is not installed (optional extra)")
    import socket
    with socket.socket() as s:              # a loopback port that nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(sw, "DASK_CONNECT_TIMEOUT", "1s")
    _, deck = stand_in
    code = sw.sweep_main(deck, ["KP=1e6"], tmp_path / "s", scheduler=f"tcp://127.0.0.1:{port}")
    assert code == 2
    assert f"cannot connect to the dask scheduler at tcp://127.0.0.1:{port}" in capsys.readouterr().err


# ---------------------------------------------------------------- what a resumed sweep reuses


def test_points_of_a_changed_or_another_deck_run_again(tmp_path, stand_in, capsys):
    """A point is reused only when it ran with the same deck (digest of the expanded text with
    its parameter values): an edited deck, or another deck swept into the same directory, runs
    every point again and the sweep says so."""
    command, deck = stand_in
    out = tmp_path / "sweep"
    first = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5"], out, runner=first) == 0 and len(first.ran) == 2
    same = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5"], out, runner=same) == 0 and same.ran == []
    capsys.readouterr()
    deck.write_text(deck.read_text() + "** PHI 0.2 -> 0.4\n")           # the deck is edited
    edited = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5"], out, runner=edited) == 0
    assert edited.ran == [{"B": "0"}, {"B": "5"}]
    assert "2 point(s) ran with another deck, with this deck before it changed" in \
        capsys.readouterr().out
    other = tmp_path / "other.dat"
    other.write_text("*HEADING\nanother deck\n")
    again = Counting(command)
    assert sw.sweep_main(other, ["B=0,5"], out, runner=again) == 0 and len(again.ran) == 2
    stored = json.loads((out / "B=0" / "point.json").read_text())
    assert stored["deck"]["path"] == str(other.resolve())
    check = json.loads((out / "B=5" / "point.json").read_text())["deck"]["digest"]
    assert check == sw.point_digest(other, {"B": "5"}) != sw.point_digest(deck, {"B": "5"})


def test_points_of_another_program_version_run_again(tmp_path, stand_in, capsys, monkeypatch):
    """A point finished by another version of the program (its source, or NumPy's, SciPy's or
    Python's version) is not reused: the same deck swept again runs every point."""
    command, deck = stand_in
    out = tmp_path / "sweep"
    first = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5"], out, runner=first) == 0 and len(first.ran) == 2
    capsys.readouterr()
    monkeypatch.setattr(sw, "program_digest", lambda: "another version")
    upgraded = Counting(command)
    assert sw.sweep_main(deck, ["B=0,5"], out, runner=upgraded) == 0
    assert upgraded.ran == [{"B": "0"}, {"B": "5"}]
    assert "or with another version of lagamine_py" in capsys.readouterr().out


def test_the_program_digest_covers_every_module(tmp_path, monkeypatch):
    """program_digest reads every module of the package: a changed byte in any changes it."""
    import lagamine_py
    root = Path(lagamine_py.__file__).resolve().parent
    base = sw.program_digest.__wrapped__()
    copy = tmp_path / "lagamine_py"
    import shutil
    shutil.copytree(root, copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(sw, "__file__", str(copy / "sweep.py"))
    assert sw.program_digest.__wrapped__() == base
    target = copy / "solver" / "newton.py"
    target.write_bytes(target.read_bytes() + b"\n")
    assert sw.program_digest.__wrapped__() != base


def test_the_program_digest_covers_plugins_of_other_packages(tmp_path, monkeypatch):
    """A plugin another distribution installs (an entry point naming a module of its own): its
    module's bytes are in the digest, so a point run with another version of the plugin runs
    again; the built-ins' entry points are left to the package's own digest."""
    site = tmp_path / "site"
    (site / "my_plugin-1.0.dist-info").mkdir(parents=True)
    (site / "my_plugin-1.0.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: my-plugin\nVersion: 1.0\n\n")
    (site / "my_plugin-1.0.dist-info" / "entry_points.txt").write_text(
        "[lagamine_py.laws]\nMYLAW = my_plugin_law:MyLaw\n"
        "[lagamine_py.writers]\nBUILT = lagamine_py.output.base:Writer\n")
    module = site / "my_plugin_law.py"
    module.write_text("class MyLaw: pass\n")
    monkeypatch.syspath_prepend(str(site))
    found = sw.plugin_sources(path=[str(site)])
    assert found == [("lagamine_py.laws MYLAW = my_plugin_law:MyLaw",
                      str(module).encode() + b"\0" + module.read_bytes())]
    base = sw.program_digest.__wrapped__()
    assert sw.program_digest.__wrapped__() == base
    module.write_text("class MyLaw:  # version 2\n    pass\n")
    assert sw.program_digest.__wrapped__() != base


def test_a_second_sweep_into_the_same_directory_is_refused(tmp_path, stand_in, capsys):
    from lagamine_py.core.outdir import lock_directory
    command, deck = stand_in
    out = tmp_path / "sweep"
    out.mkdir()
    with lock_directory(out):
        assert main(["sweep", str(deck), "--set", "B=0", "-o", str(out)]) == 2
    assert "is in use by another run" in capsys.readouterr().err
    assert not (out / "sweep.csv").exists()


SWEEP = """
import sys
from functools import partial
from lagamine_py import sweep as sw
sw.load_point_checks = lambda deck, params: []
command, deck, out = sys.argv[1:3], sys.argv[3], sys.argv[4]
sys.exit(sw.sweep_main(deck, ["SLEEP=0,60,61,62"], out, jobs=2,
                       runner=partial(sw.run_point, command=command)))
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_sweep_stops_its_runs_and_keeps_its_finished_points(tmp_path, stand_in, sig):
    """``kill`` (or Ctrl-C) of a sweep with two points running: the runs are stopped (no
    process left behind), the point that finished is in sweep.csv, exit status 130."""
    command, deck = stand_in
    out = tmp_path / "sweep"
    # Ctrl-C's default restored in the child: a pytest started in the background (`nohup ...
    # &`) ignores SIGINT, and Python keeps an inherited SIG_IGN, so the sweep would never see it
    proc = subprocess.Popen([sys.executable, "-c", SWEEP, *command, str(deck), str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    slow = [out / f"SLEEP={s}" / "pid.txt" for s in (60, 61)]
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not all(p.exists() for p in slow):
        time.sleep(0.05)
    assert all(p.exists() for p in slow), proc.stderr.read() if proc.poll() is not None else ""
    time.sleep(0.2)                                    # the pids written, the sleeps begun
    pids = [int(p.read_text()) for p in slow]
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted; the points that finished are in" in err
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)                            # stopped, and reaped by the sweep
    rows = {r["point"]: r for r in read_sweep(out)}
    assert rows["SLEEP=0"]["status"] == "0"
    for s in (60, 61):                                 # stopped, recorded, not reused
        assert rows[f"SLEEP={s}"]["status"] == str(-signal.SIGTERM)
    assert "SLEEP=62" not in rows and not (out / "SLEEP=62").exists()      # never started
