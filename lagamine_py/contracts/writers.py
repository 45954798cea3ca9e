"""The writer contract (:class:`lagamine_py.output.base.Writer`) as checks.

A real run (:data:`SAMPLE_DECK`: a press, then a push whose first attempt fails and is cut
back) is run once per process with a recording writer; its hook calls are replayed into the
writer under test in the contract's order while ``open`` (and so ``Path.open``) hands out
tracked files: after every hook no file holds unflushed data, and what was written is on disk.
"""
from __future__ import annotations

import builtins
import functools
import io
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .findings import Finding, Skip, Suite, require


WRITER_ITEMS = ("hooks", "flushed", "files")

#: the sample run: a block pressed onto a flat and pushed sideways; the first increment of the
#: push fails (MAXIT=3) and is cut back, field output every second increment of the push; its
#: energy balance is kept (energy.csv)
SAMPLE_DECK = """** lagamine_py contract sample: a block pressed onto a flat, then pushed sideways
*MESH, NAME=BLOCK, TYPE=Q8PE, X0=0, Y0=0, LX=4, LY=2, NX=2, NY=1
*MATERIAL, NAME=STEEL, LAW=ELASTIC
E=210000, NU=0.3
*SOLID, ELSET=BLOCK, MATERIAL=STEEL
*FOUNDATION, NAME=FLAT
-20, 0
2, 0
24, 0
*CONTACT LAW, NAME=DRY, TYPE=COULOMB
KP=2e6, KT=2e6, PHI=0.3
*CONTACT, SURFACE=BLOCK_BOTTOM, FOUNDATION=FLAT, LAW=DRY, GAUSS=3
*CHECK, NAME=ENERGY, TYPE=ENERGY
*STEP, NAME=PRESS
*STATIC
0.5, 1, 1e-3, 0.5
*DLOAD
BLOCK_TOP, P, 100
*END STEP
*STEP, NAME=PUSH
*STATIC
0.5, 1, 1e-3, 0.5
*CONTROLS
MAXIT=3
*OUTPUT, FREQUENCY=2
*BOUNDARY
BLOCK_LEFT, 1, 1, 0.05
*END STEP
"""


@dataclass
class SampleRun:
    """A real run's writer hook calls, in order (``(hook, args)``), its model and its
    finished output directory (the default writers' files)."""
    model: Any
    calls: list
    outdir: Path
    status: int


_KEEP: list = []          # the sample run's directory lives as long as the process


@functools.lru_cache(maxsize=1)
def sample_run() -> SampleRun:
    """Run :data:`SAMPLE_DECK` once per process (a fraction of a second), recording the hooks."""
    from ..deck import load_deck
    from ..output import default_writers
    from ..output.base import Writer
    from ..solver import run

    class Recorder(Writer):
        def __init__(self):
            self.calls = []

        def start_run(self):
            self.calls.append(("start_run", ()))

        def start_step(self, step_number, step):
            self.calls.append(("start_step", (step_number, step)))

        def increment(self, result):
            self.calls.append(("increment", (result,)))

        def failed_attempt(self, attempt):
            self.calls.append(("failed_attempt", (attempt,)))

        def close(self, status, message):
            self.calls.append(("close", (status, message)))

    tmp = tempfile.TemporaryDirectory(prefix="lagamine_contract_")   # removed at exit
    _KEEP.append(tmp)
    root = Path(tmp.name)
    deck = root / "sample.dat"
    deck.write_text(SAMPLE_DECK)
    model = load_deck(deck)
    outdir = root / "out"
    rec = Recorder()
    outcome = run(model, outdir, writers=default_writers(outdir, model) + [rec], deck_path=deck)
    return SampleRun(model, rec.calls, outdir, outcome.status)


class _Tracked:
    """A file opened by the writer under test: writes and flushes counted, the rest passed on."""

    def __init__(self, fh, path: Path, mode: str):
        self._fh = fh
        self.path = path
        self.mode = mode
        self.text = isinstance(fh, io.TextIOBase)
        self.auto = (self.text and getattr(fh, "line_buffering", False)) or \
            isinstance(fh, io.RawIOBase)
        st = os.fstat(fh.fileno())
        self.inode = (st.st_dev, st.st_ino)
        self.start = st.st_size if "a" in mode else 0
        self.written = 0          # bytes written in all
        self.pending = 0          # bytes written since the last flush

    def write(self, data):
        n = self._fh.write(data)
        size = len(data.encode(self._fh.encoding or "utf-8", self._fh.errors or "strict")) \
            if self.text else len(data)
        self.written += size
        if not self.auto:
            self.pending += size
        elif self.text and "\n" in data:
            self.pending = 0
        return n

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def flush(self):
        self._fh.flush()
        self.pending = 0

    def close(self):
        self._fh.close()
        self.pending = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __iter__(self):
        return iter(self._fh)

    def __next__(self):
        return next(self._fh)

    def __getattr__(self, name):
        return getattr(self._fh, name)


class _OpenTracker:
    """While active, ``open``/``io.open`` (and so ``Path.open``) hand out :class:`_Tracked`
    files for every file opened for writing."""

    def __init__(self):
        self.files: list[_Tracked] = []

    def __enter__(self):
        self._open = builtins.open
        real = self._open

        def tracked_open(file, mode="r", *args, **kwargs):
            fh = real(file, mode, *args, **kwargs)
            if isinstance(file, int) or not any(c in mode for c in "wax+"):
                return fh
            t = _Tracked(fh, Path(os.fsdecode(file)), mode)
            self.files.append(t)
            return t

        builtins.open = io.open = tracked_open
        return self

    def __exit__(self, *exc):
        builtins.open = io.open = self._open


@dataclass
class _Replay:
    error: str = ""
    unflushed: list = field(default_factory=list)
    short: list = field(default_factory=list)
    outside: list = field(default_factory=list)
    tracker: _OpenTracker | None = None
    hooks: int = 0
    outdir: Path | None = None


def _hook_order(calls) -> str:
    """The recorded calls follow the contract's order (the replay is only as good)."""
    names = [c[0] for c in calls]
    ok = names[0] == "start_run" and names[-1] == "close" and names.count("close") == 1
    step = 0
    for name, args in calls[1:-1]:
        if name == "start_step":
            ok &= args[0] > step
            step = args[0]
        elif name in ("increment", "failed_attempt"):
            ok &= args[0].step == step
    return "" if ok else f"the recorded calls break the contract's order: {names}"


def _replay(cls, root: Path) -> _Replay:
    run = sample_run()
    out = _Replay()
    out.outdir = outdir = (root / "out").resolve()
    problem = _hook_order(run.calls)
    if problem:
        out.error = problem
        return out
    with _OpenTracker() as tracker:
        out.tracker = tracker
        calls = [("__init__", ())] + run.calls
        writer = None
        for name, args in calls:
            try:
                if name == "__init__":
                    writer = cls(outdir, run.model, append=False)
                    hooks = {"start_run": writer.start_run, "start_step": writer.start_step,
                             "increment": writer.increment, "close": writer.close,
                             "failed_attempt": writer.failed_attempt}
                else:
                    hooks[name](*args)
            except Exception as exc:
                out.error = f"{name}() raised {type(exc).__name__}: {exc} (call {out.hooks + 1} " \
                            f"of {len(calls)})"
                return out
            out.hooks += 1
            where = name if name != "increment" else \
                f"increment(step {args[0].step}, increment {args[0].increment})"
            for t in tracker.files:
                if t.pending:
                    out.unflushed.append(f"after {where}: {t.path.name} holds {t.pending} "
                                         f"unflushed bytes")
                if not t.closed and "+" not in t.mode:
                    size = os.fstat(t.fileno()).st_size
                    if size < t.start + t.written:
                        out.short.append(f"after {where}: {t.path.name} has {size} bytes on "
                                         f"disk, {t.start + t.written} written")
    for t in tracker.files:
        path = (t.path if t.path.is_absolute() else Path.cwd() / t.path).resolve()
        if outdir not in path.parents and str(path) not in out.outside:
            out.outside.append(str(path))
    return out


def _writer_files(rep: _Replay) -> str:
    require(not rep.outside, f"wrote outside the output directory: {rep.outside}")
    require(not rep.short, "; ".join(rep.short[:5]))
    present = sorted(p for p in rep.outdir.rglob("*") if p.is_file()) if rep.outdir.exists() else []
    require(present, "nothing in the output directory after the replay")
    inodes = {(p.stat().st_dev, p.stat().st_ino): p for p in present}
    short = []
    for t in rep.tracker.files:
        p = inodes.get(t.inode)
        if p is not None and t.written and p.stat().st_size < t.start + t.written:
            short.append(f"{p.name}: {p.stat().st_size} bytes, {t.start + t.written} written")
    require(not short, "; ".join(short))
    total = sum(p.stat().st_size for p in present)
    return (f"{len(present)} files, {total} bytes in the output directory "
            f"({', '.join(p.name for p in present[:6])}{' ...' if len(present) > 6 else ''}); "
            f"every byte written through Python is on disk")


def check_writer(cls) -> list[Finding]:
    """The writer contract (:class:`~lagamine_py.output.base.Writer`) on ``cls``: a recorded
    real run replayed into it, in the contract's order, with ``open`` tracked."""
    with tempfile.TemporaryDirectory(prefix="lagamine_writer_") as root:
        return _writer_findings(cls, Path(root))


def _writer_findings(cls, root: Path) -> list[Finding]:
    s = Suite(WRITER_ITEMS)
    run = sample_run()
    rep = _replay(cls, root)
    kinds = [c[0] for c in run.calls]

    def hooks():
        require(not rep.error, rep.error)
        return (f"{rep.hooks} calls replayed without an exception: start_run, "
                f"{kinds.count('start_step')} start_step, {kinds.count('increment')} increment, "
                f"{kinds.count('failed_attempt')} failed_attempt, close (recorded from a real "
                f"run)")

    def flushed():
        require(not rep.unflushed, "; ".join(rep.unflushed[:5])
                + (f" ... ({len(rep.unflushed)} in all)" if len(rep.unflushed) > 5 else ""))
        if rep.tracker is None or not rep.tracker.files:
            raise Skip("the writer opened no file through Python's open()")
        return (f"{len(rep.tracker.files)} file(s) opened through open(), "
                f"{sum(t.written for t in rep.tracker.files)} bytes written: nothing unflushed "
                f"after any of the {rep.hooks} calls")

    if not s.run("hooks", hooks):
        s.run("flushed", flushed)
        return s.blocked("the replay stopped")
    s.run("flushed", flushed)
    s.run("files", _writer_files, rep)
    return s.findings
