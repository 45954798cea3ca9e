"""Retired files (core/outdir.py, issue 17 item 3): a run frees no file's blocks on its own
thread -- the earlier outputs a rerun clears and the restart file it replaces each increment are
unlinked by a background thread -- and leaves no retired file behind."""
from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from lagamine_py.cli import main
from lagamine_py.core import outdir as od

DECK = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"


def _retired(d: Path) -> list[str]:
    return sorted(n for n in os.listdir(d) if n.startswith(od.RETIRED_PREFIX))


@pytest.fixture
def unlinks(monkeypatch):
    """Every os.unlink: (thread name, file name)."""
    seen = []
    real = os.unlink

    def unlink(path, *a, **k):
        seen.append((threading.current_thread().name, Path(path).name))
        return real(path, *a, **k)
    monkeypatch.setattr(os, "unlink", unlink)
    return seen


def test_replace_keeps_the_old_file_linked_until_the_thread_unlinks_it(tmp_path, unlinks):
    target, tmp = tmp_path / "restart.npz", tmp_path / "restart.tmp.npz"
    target.write_bytes(b"old")
    tmp.write_bytes(b"new")
    inode = target.stat().st_ino
    od.replace(tmp, target)
    assert target.read_bytes() == b"new" and not tmp.exists()
    od.wait_retired()
    assert _retired(tmp_path) == []
    assert [t for t, n in unlinks] == ["lagamine-retired"]           # the old inode, there
    assert unlinks[0][1].startswith(od.RETIRED_PREFIX) and unlinks[0][1].endswith("restart.npz")
    assert target.stat().st_ino != inode
    od.replace(_new(tmp_path, "a.tmp"), tmp_path / "a")              # no old file
    od.wait_retired()
    assert (tmp_path / "a").read_bytes() == b"x" and len(unlinks) == 1   # nothing was there


def _new(d: Path, name: str) -> Path:
    (d / name).write_bytes(b"x")
    return d / name


def test_replace_without_hard_links(tmp_path, monkeypatch):
    """A file system without hard links: a plain rename."""
    def no_link(*a, **k):
        raise OSError(1, "Operation not permitted")
    monkeypatch.setattr(os, "link", no_link)
    (tmp_path / "f").write_text("old")
    od.replace(_new(tmp_path, "f.tmp"), tmp_path / "f")
    od.wait_retired()
    assert (tmp_path / "f").read_bytes() == b"x" and sorted(os.listdir(tmp_path)) == ["f"]


def test_a_rerun_frees_no_block_on_its_own_thread(tmp_path, unlinks):
    """A run into the directory of an earlier run: the 40 earlier files and the 11 restart files
    it replaces are unlinked by the background thread; only the lock on the main thread; no
    retired file left."""
    out = tmp_path / "out"
    assert main(["run", str(DECK), "-o", str(out), "-q"]) == 0
    files = sorted(os.listdir(out))
    unlinks.clear()
    assert main(["run", str(DECK), "-o", str(out), "-q"]) == 0
    assert sorted(os.listdir(out)) == files and _retired(out) == []
    main_thread = [n for t, n in unlinks if t == "MainThread"]
    assert main_thread == [od.LOCK_FILE]
    reaped = [n for t, n in unlinks if t == "lagamine-retired"]
    assert all(n.startswith(od.RETIRED_PREFIX) for n in reaped)
    restarts = [n for n in reaped if n.endswith("-restart.npz")]
    assert len(restarts) >= 11                    # 12 increments: every save but the first
    assert len(reaped) >= len(files) - 1          # the earlier outputs (the lock was gone)


@pytest.mark.parametrize("restart", [False, True])
def test_a_killed_runs_retired_files_go_with_the_next_claim(tmp_path, restart):
    out = tmp_path / "out"
    out.mkdir()
    left = out / f"{od.RETIRED_PREFIX}999999-3-restart.npz"
    left.write_bytes(b"old restart data")
    (out / "notes.txt").write_text("mine")                   # a user's file: kept
    deck = od.DeckIdentity(str(DECK), "coulomb_block")
    with od.claim(out, deck, restart=restart):
        pass
    kept = ["notes.txt"] if restart else ["lagamine-run.json", "notes.txt"]   # a restart: no record
    assert sorted(os.listdir(out)) == kept


def test_release_waits_for_the_retired_files(tmp_path, monkeypatch):
    """The thread slower than the run (a slow disk): the claim's release still leaves none."""
    real = os.unlink

    def slow(path, *a, **k):
        if Path(path).name.startswith(od.RETIRED_PREFIX):
            threading.Event().wait(0.05)
        return real(path, *a, **k)
    monkeypatch.setattr(os, "unlink", slow)
    out = tmp_path / "out"
    out.mkdir()
    for k in range(3):
        (out / f"coulomb_block_000{k}.vtu").write_text("old")
    with od.claim(out, od.DeckIdentity(str(DECK), "coulomb_block"), overwrite=True):
        for k in range(3):
            od.replace(_new(out, "restart.tmp.npz"), out / "restart.npz")
        assert os.listdir(out).count("restart.npz") == 1
    assert _retired(out) == [] and sorted(os.listdir(out)) == ["lagamine-run.json", "restart.npz"]


def test_a_file_retired_while_another_caller_waits_is_unlinked_and_no_wait_hangs(tmp_path,
                                                                                monkeypatch):
    """Two runs of one process (threads): run A waits for the thread while it is slow on A's
    file, and run B retires a file meanwhile.  B's file goes to a thread of its own; A's wait
    ends, and so does B's.  (With one queue for every thread, B's new thread could take the
    sentinel meant for A's, and A's would then wait on the queue, and A on it, for ever.)"""
    real, busy, go = os.unlink, threading.Event(), threading.Event()

    def slow(path, *a, **k):
        if Path(path).name.endswith("-a"):
            busy.set()
            go.wait(5)
        return real(path, *a, **k)
    monkeypatch.setattr(os, "unlink", slow)
    monkeypatch.setattr(od, "_reaper", od._Reaper())
    for name in ("a", "b"):
        (tmp_path / name).write_text("old")
    od.retire(tmp_path / "a")
    assert busy.wait(5)                              # the thread is in A's unlink
    waiter = threading.Thread(target=od.wait_retired)
    waiter.start()
    while od._reaper.thread is not None:             # A's wait has taken the thread
        threading.Event().wait(0.001)
    od.retire(tmp_path / "b")
    go.set()
    waiter.join(5)
    assert not waiter.is_alive()
    done = threading.Thread(target=od.wait_retired)
    done.start()
    done.join(5)
    assert not done.is_alive() and _retired(tmp_path) == []


@pytest.mark.skipif(not hasattr(os, "fork"), reason="fork")
def test_a_forked_child_retires_files_itself(tmp_path):
    """Forked while the parent's thread runs: the child's files are unlinked by a thread of
    its own (a sweep's or a test's fork)."""
    (tmp_path / "p").write_text("old")
    od.replace(_new(tmp_path, "p.tmp"), tmp_path / "p")           # the parent's thread started
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            (tmp_path / "c").write_text("old")
            od.replace(_new(tmp_path, "c.tmp"), tmp_path / "c")
            od.wait_retired()
            code = 0 if not [n for n in _retired(tmp_path) if n.endswith("-c")] else 2
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    od.wait_retired()
    assert os.waitstatus_to_exitcode(status) == 0 and _retired(tmp_path) == []
