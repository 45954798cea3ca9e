"""The output directory of a run: its lock, the record of the deck that wrote it, and the
clearing of an earlier run's files.

A run *claims* its directory (:func:`claim`):

* **lock** ``OUT/.lagamine.lock``, created exclusively (``O_CREAT | O_EXCL``), holding the
  holder's pid, host, command and start time.  A second run into the directory is refused
  (:class:`DirectoryInUse`, exit status 2) with who holds it.  A lock whose holder is gone (same
  host, and the pid is dead or now runs another command) is *stale*: it is taken over.  The lock
  goes when the run ends (:meth:`Claim.release`); a killed run leaves it behind, stale.
* **record** ``OUT/lagamine-run.json``: the deck's absolute path, its name (the stem the output
  files carry), the hash of its expanded text (:class:`DeckIdentity`), the parameters given
  on the command line, when and by whom the directory was claimed, and ``foreign``: the files
  that were in the directory before the first run claimed it (a sweep's ``run.stdout``, a
  user's notes), which runs never remove.
* **clearing**: a new run (not a restart) removes every file an earlier run left (all but the
  foreign ones), so no stale ``restart.npz``, ``.vtu`` or table of the old run survives.  A
  directory whose record names another deck is refused (:class:`ResultsOfAnotherDeck`, exit
  status 2) unless ``overwrite``; so is a directory holding output files without a record
  (results of an unknown deck), whose recognisable output files ``overwrite`` removes.
  Directories inside ``OUT`` are never touched.

Readers find the run's own files by the deck name the record holds (:func:`run_name`), never
by "the first ``.sta`` that sorts".

Files are replaced atomically (:func:`write_atomic`: a temporary file, then ``os.replace``).

**Retired files.**  Freeing a file's blocks -- unlinking it, or replacing it by a rename -- waits
for the file system's journal, which on a disk mounted with ``discard`` (this machine's) issues
its discards synchronously: 2-4 ms of wall time a file once its data is on disk (61 earlier
outputs cleared by a rerun: 0.15-0.23 s; a restart file replaced every increment: 2-4 ms each),
with almost no CPU.  So a run *retires* such files (:func:`retire`, :func:`replace`): an old
output is renamed to ``.lagamine-retired-<pid>-<n>-<name>`` (no block is freed), a file about
to be replaced is first hard-linked to such a name (its blocks stay in use through the rename),
and a background thread unlinks the retired names while the run computes.  :meth:`Claim.release`
waits for it (:func:`wait_retired`): a finished run leaves none behind; a killed one may, and
the next claim of the directory (a restart's too) has the thread unlink them.
This module is file-system machinery only: it imports nothing of lagamine_py.
"""
from __future__ import annotations

import errno
import fnmatch
import itertools
import json
import os
import queue
import sys
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

__all__ = ["DeckIdentity", "Claim", "claim", "lock_directory", "run_name", "recorded_identity", "read_record", "write_atomic",
           "retire", "replace", "wait_retired", "RETIRED_PREFIX",
           "OutputDirError", "DirectoryInUse", "ResultsOfAnotherDeck", "LOCK_FILE",
           "RECORD_FILE", "OUTPUT_PATTERNS"]

LOCK_FILE = ".lagamine.lock"
RECORD_FILE = "lagamine-run.json"
#: files a run of lagamine-py writes (``{name}``: the deck name): how a directory without a
#: record is recognised as holding results, and what ``overwrite`` removes from it
OUTPUT_PATTERNS = ("{name}.sta", "{name}.log", "{name}.pvd", "{name}_*.vtu", "*.sta", "*.pvd",
                   "*.vtu", "contact.csv", "contact_totals.csv", "reactions.csv",
                   "displacements.csv", "tool_forces.csv", "energy.csv", "restart.npz", "*.tmp",
                   "*.tmp.npz", ".lagamine-retired-*")
#: the name prefix of retired files (see the module doc)
RETIRED_PREFIX = ".lagamine-retired-"


class OutputDirError(Exception):
    """The output directory cannot be used as asked (the message says why and what to do)."""


class DirectoryInUse(OutputDirError):
    """Another run holds the directory's lock."""


class ResultsOfAnotherDeck(OutputDirError):
    """The directory holds the results of another deck (or of an unknown one)."""


@dataclass(frozen=True)
class DeckIdentity:
    """Which deck a run computes: ``path`` (absolute, "" for a model built by a script),
    ``name`` (the stem of the output files), ``digest`` (SHA-256 of the expanded text --
    every file read and the parameter values --, "" when unknown) and ``parameters`` (the
    values given on the command line, to load the deck again on a restart)."""
    path: str
    name: str
    digest: str = ""
    parameters: dict = field(default_factory=dict)

    def same_deck(self, other: "DeckIdentity") -> bool:
        """Same deck file (the content may have changed: a rerun replaces its results)."""
        return self.path == other.path and self.name == other.name

    def describe(self) -> str:
        return self.path or f"a model named {self.name!r} (no deck file)"


def write_atomic(path: Path, data: str | bytes) -> None:
    """Replace ``path`` by ``data`` atomically: written to ``path.tmp``, closed, renamed (no
    fsync: atomic against the death of the process, as the restart data; see
    :mod:`lagamine_py.solver.restart`); the old file retired (:func:`replace`)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb" if isinstance(data, bytes) else "w") as fh:
        fh.write(data)
    replace(tmp, path)


class _Reaper:
    """The background thread that unlinks retired files, started at the first one; unlinking
    is a system call that releases the GIL, so its wait overlaps the run's computing.  Each
    thread has its own queue: a file retired while another caller waits for the last thread
    goes to a new thread, never behind the sentinel that ends the old one (with one shared
    queue the new thread could take that sentinel and leave the old one, and its waiter,
    blocked for ever)."""

    def __init__(self):
        self.queue: queue.SimpleQueue | None = None
        self.thread: threading.Thread | None = None
        self.lock = threading.Lock()
        self.count = itertools.count()

    def add(self, path: str) -> None:
        with self.lock:
            if self.thread is None:
                self.queue = queue.SimpleQueue()
                self.thread = threading.Thread(target=self._work, args=(self.queue,),
                                               name="lagamine-retired", daemon=True)
                self.thread.start()
            self.queue.put(path)

    @staticmethod
    def _work(paths: queue.SimpleQueue) -> None:
        while (path := paths.get()) is not None:
            try:
                os.unlink(path)
            except OSError:             # gone already; the next claim unlinks what stays
                pass

    def wait(self) -> None:
        """Until every file retired before this call is unlinked."""
        with self.lock:
            thread, paths, self.thread, self.queue = self.thread, self.queue, None, None
            if thread is not None:
                paths.put(None)
        if thread is not None:
            thread.join()

    def name(self, path: Path) -> Path:
        return path.with_name(f"{RETIRED_PREFIX}{os.getpid()}-{next(self.count)}-{path.name}")


_reaper = _Reaper()


def _forked() -> None:
    """A forked child has no thread of its parent: a reaper of its own, from empty (the files
    the parent retired are the parent's to unlink)."""
    global _reaper
    _reaper = _Reaper()


if hasattr(os, "register_at_fork"):             # not on Windows, which does not fork
    os.register_at_fork(after_in_child=_forked)


def retire(path: Path) -> None:
    """Remove ``path`` (a file) from its directory now and free its blocks later, on the
    background thread (see the module doc); nothing when it does not exist."""
    path = Path(path)
    hidden = _reaper.name(path)
    try:
        os.rename(path, hidden)
    except FileNotFoundError:
        return
    _reaper.add(str(hidden))


def replace(tmp: Path, path: Path) -> None:
    """``os.replace(tmp, path)``, the old ``path`` (if any) unlinked later on the background
    thread: it is hard-linked to a retired name first, so the rename frees no block (see the
    module doc).  Where hard links are not possible the rename frees them itself."""
    path = Path(path)
    hidden = _reaper.name(path)
    try:
        os.link(path, hidden)
    except OSError:                     # no old file, or no hard links here
        hidden = None
    try:
        os.replace(tmp, path)
    finally:
        if hidden is not None:
            _reaper.add(str(hidden))


def wait_retired() -> None:
    """Wait until every retired file is unlinked (the background thread ends)."""
    _reaper.wait()


def _host() -> str:
    """This machine's name as ``socket.gethostname()`` gives it: ``platform.node()``, the
    system's ``uname`` (numpy has imported ``platform`` already; ``socket`` was 1.5 ms of the
    main job's imports, for this name alone), ``socket`` where that gives nothing."""
    import platform
    name = platform.node()
    if not name:
        import socket
        name = socket.gethostname()
    return name


def _command() -> str:
    return " ".join(sys.argv) or sys.executable


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def _start_ticks(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, ``/proc/<pid>/stat``), None if
    unknown (no /proc): tells a live holder from a later process that reuses its pid."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    try:
        return int(stat[stat.rindex(")") + 2:].split()[19])     # field 22 of stat
    except (ValueError, IndexError):
        return None


def _alive(holder: dict) -> bool:
    """Whether the lock's holder may still run: another host cannot be asked (True); on this
    host, a pid that is gone, or that now belongs to a process started later (a reused pid),
    is dead."""
    if holder.get("host") != _host():
        return True
    try:
        pid = int(holder["pid"])
        os.kill(pid, 0)
    except (KeyError, ValueError, TypeError, ProcessLookupError, OverflowError):
        return False
    except PermissionError:                 # it exists, owned by someone else
        pass
    started = holder.get("start_ticks")
    now = _start_ticks(pid)
    return started is None or now is None or int(started) == now


class Claim:
    """A run's hold on its output directory; :meth:`release` gives it up (idempotent)."""

    def __init__(self, outdir: Path, lock: Path, note: str = ""):
        self.outdir = outdir
        self.lock = lock
        self.note = note            # what the claim did (took over a stale lock ...), or ""
        self.held = True

    def release(self) -> None:
        """Remove the lock, after the run's retired files are unlinked (:func:`wait_retired`)."""
        if self.held:
            self.held = False
            try:
                wait_retired()
            finally:
                try:
                    self.lock.unlink()
                except OSError:
                    pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


def _take_lock(outdir: Path) -> tuple[Path, str]:
    """Create the lock exclusively; take over a stale one; DirectoryInUse when it is held."""
    lock = outdir / LOCK_FILE
    me = {"pid": os.getpid(), "host": _host(), "command": _command(),
          "started": _now(), "start_ticks": _start_ticks(os.getpid())}
    note = ""
    for _ in range(3):
        try:
            fd = os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            try:
                holder = json.loads(lock.read_text() or "{}")
            except (OSError, ValueError):
                holder = {}
            if holder and _alive(holder):
                raise DirectoryInUse(
                    f"{outdir} is in use by another run: pid {holder.get('pid')} on "
                    f"{holder.get('host')}, since {holder.get('started')} "
                    f"({holder.get('command')}); wait for it to end, or choose another output "
                    f"directory (if that run is gone, remove {lock})") from None
            if not holder:              # being written right now, or garbage: look again
                time.sleep(0.05)
                try:
                    holder = json.loads(lock.read_text() or "{}")
                except (OSError, ValueError):
                    holder = {}
                if holder and _alive(holder):
                    continue
            note = (f"took over the stale lock of pid {holder.get('pid')} ({holder.get('started')})"
                    if holder else "removed an unreadable lock file")
            try:
                lock.unlink()
            except FileNotFoundError:
                pass
            continue
        with os.fdopen(fd, "w") as fh:     # no fsync: a lock is between live processes
            fh.write(json.dumps(me))
        return lock, note
    raise DirectoryInUse(f"{outdir}: could not take the lock {lock} (other runs keep taking it)")


def lock_directory(outdir) -> Claim:
    """Only the lock of ``outdir`` (which must exist): what a sweep takes on its directory."""
    lock, note = _take_lock(Path(outdir))
    return Claim(Path(outdir), lock, note)


def read_record(outdir: Path) -> dict | None:
    """The record of the run that claimed ``outdir`` (see the module doc), or None."""
    try:
        data = json.loads((Path(outdir) / RECORD_FILE).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _identity(record: dict) -> DeckIdentity:
    deck = record.get("deck", {}) if isinstance(record.get("deck"), dict) else {}
    return DeckIdentity(str(deck.get("path", "")), str(deck.get("name", "")),
                        str(deck.get("digest", "")), dict(deck.get("parameters") or {}))


def recorded_identity(outdir: Path) -> DeckIdentity | None:
    """The deck recorded in ``outdir``, or None when there is no record."""
    record = read_record(outdir)
    return None if record is None else _identity(record)


def _files(outdir: Path) -> list[str]:
    return sorted(e.name for e in os.scandir(outdir) if e.is_file(follow_symlinks=False)
                  or e.is_symlink())


def _outputs(names: list[str], name: str = "") -> list[str]:
    """The names among ``names`` that a run writes (:data:`OUTPUT_PATTERNS`)."""
    pats = [p.format(name=name) for p in OUTPUT_PATTERNS if name or "{name}" not in p]
    return [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in pats)]


def claim(outdir, deck: DeckIdentity, restart: bool = False, overwrite: bool = False) -> Claim:
    """Claim ``outdir`` for a run of ``deck`` (see the module doc): create it, take its lock,
    check what it holds, clear an earlier run's files (not on a restart) and write the record.

    Raises :class:`DirectoryInUse` or :class:`ResultsOfAnotherDeck` (exit status 2),
    :class:`OSError` when the directory cannot be created or written (a file in the way, no
    permission, a full disk)."""
    outdir = Path(outdir)
    if outdir.exists() and not outdir.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "the output path exists and is not a directory",
                                 str(outdir))
    outdir.mkdir(parents=True, exist_ok=True)
    lock, note = _take_lock(outdir)
    done = Claim(outdir, lock, note)
    try:
        record = read_record(outdir)
        names = [n for n in _files(outdir) if n not in (LOCK_FILE, RECORD_FILE)]
        for n in names:             # what a killed run left to unlink: never needed
            if n.startswith(RETIRED_PREFIX):
                _reaper.add(str(outdir / n))
        names = [n for n in names if not n.startswith(RETIRED_PREFIX)]
        if restart:                 # the restart data says which deck it resumes (solver.restart)
            return done
        if record is not None:
            old = _identity(record)
            foreign = set(record.get("foreign", []))
            if not old.same_deck(deck) and not overwrite:
                raise ResultsOfAnotherDeck(
                    f"{outdir} holds the results of another deck ({old.describe()}); this run "
                    f"is of {deck.describe()}: choose another output directory, or give "
                    f"--overwrite to replace them")
            stale = [n for n in names if n not in foreign]
        else:
            stale = _outputs(names, deck.name)
            if stale and not overwrite:
                raise ResultsOfAnotherDeck(
                    f"{outdir} holds results that no record attributes to a deck (e.g. "
                    f"{', '.join(stale[:3])}): choose another output directory, or give "
                    f"--overwrite to replace them")
            foreign = set(names) - set(stale)
        for n in stale:
            retire(outdir / n)
        body = {"deck": asdict(deck), "claimed": _now(), "host": _host(),
                "pid": os.getpid(), "command": _command(), "foreign": sorted(foreign)}
        write_atomic(outdir / RECORD_FILE, json.dumps(body, indent=1) + "\n")
    except BaseException:
        done.release()
        raise
    return done


def run_name(outdir) -> str | None:
    """The deck name (stem of ``<name>.sta``, ``<name>.pvd`` ...) of the run in ``outdir``:
    from its record, else from its ``.sta`` or ``.pvd`` files when they name one deck (an
    archived reference).  None when there is none; :class:`ResultsOfAnotherDeck` when the
    files of several decks are there and no record says which is the run's."""
    outdir = Path(outdir)
    record = read_record(outdir)
    if record is not None and _identity(record).name:
        return _identity(record).name
    try:
        names = _files(outdir)
    except OSError:
        return None
    for suffix in (".sta", ".pvd"):
        stems = sorted({n[:-len(suffix)] for n in names if n.endswith(suffix)})
        if len(stems) == 1:
            return stems[0]
        if len(stems) > 1:
            raise ResultsOfAnotherDeck(
                f"{outdir} holds the {suffix} files of several decks ({', '.join(stems)}) and no "
                f"record ({RECORD_FILE}) of which run wrote it: cannot tell which to read")
    return None
