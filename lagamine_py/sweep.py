"""``lagamine-py sweep DECK --set NAME=v1,v2 [--set ...] -o DIR [-j N] [--scheduler ADDRESS]``.

Runs a deck over the product grid of ``*PARAMETER`` values, one run directory per point
(``DIR/<name1>=<v1>_<name2>=<v2>/``), each point a separate process::

    python -m lagamine_py run DECK -o POINTDIR -q --overwrite --param NAME=VALUE ...

Where the points run:

* ``-j N`` (default 1): on this machine, ``N`` at a time (``concurrent.futures``
  ``ThreadPoolExecutor`` threads of the sweep's process, each waiting on its run's subprocess,
  so the sweep knows every run it started; BLAS threads are pinned to 1 per run when
  ``N > 1``);
* ``--scheduler ADDRESS``: as tasks of a ``dask.distributed`` cluster (optional extra ``dask``:
  ``pip install "lagamine_py[dask]"``).  The workers must see ``DECK`` and ``DIR`` at the same
  paths (a shared file system) and have ``lagamine_py`` installed.

``DIR/sweep.csv`` gets one row per finished point, rewritten (atomically) each time a point
finishes: ``point`` (its directory name), the parameters, ``status`` (the run's exit code: 0 ok,
2 deck error, 3 did not converge, 1 other), ``reason`` (the first line of the run's closing
message, or a crash's error), ``wall_s`` and ``cpu_s`` (of the run's process, from
``os.wait4``), ``newton_iterations`` (sum of the ``.sta`` iterations column, failed attempts
included: the work done), ``increments`` (converged) and ``failed_attempts``, then the deck's
``*CHECK`` columns from :func:`lagamine_py.checks.check_columns` (``<check>_error``, measured
``<check>_<qty>``, closed form ``<check>_<qty>_cf``).

A point whose run finished leaves ``POINTDIR/point.json`` (its row, full check results, and
the deck it ran: absolute path and digest of the expanded text with the point's parameter
values, :func:`lagamine_py.deck.deck_digest`).  A rerun of the same sweep (or of a grid extended
by more values) skips the points that ran to the end (status 0) or stopped on non-convergence
(status 3) *with the same deck*, reusing their rows, so an interrupted sweep resumes where it
stopped; a point run with another deck, with this deck before it (an included file, a
parameter default) changed, or by another version of the program (:func:`program_digest`: the
package's source, other packages' plugins, Python's, NumPy's and SciPy's versions), runs again,
and the sweep says so.  Points with a deck error (2), a crash (1) or a signal are run again,
on the view that their deck or installation has been fixed in between.  A point whose worker failed (an exception, a lost dask worker) is recorded
in sweep.csv with status 1 and the reason, and leaves no ``point.json``.

The sweep holds a lock on ``DIR`` (a second sweep into it is refused, exit status 2).  Ctrl-C,
or SIGTERM, stops it cleanly: the runs in progress are stopped (they get the signal, then
SIGKILL if they have not stopped within :data:`STOP_GRACE` s), every point that finished is in
sweep.csv, and the exit status is 130; a rerun resumes.
"""
from __future__ import annotations

import csv
import functools
import hashlib
import itertools
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
import uuid
from concurrent.futures import ThreadPoolExecutor, as_completed
from functools import partial
from pathlib import Path
from typing import Any, Callable, Iterable

from .checks import check_columns, evaluate_checks
from .core.exits import EXIT_DECK, EXIT_INTERRUPTED, EXIT_OK, EXIT_OTHER, sigterm_interrupts
from .core.outdir import lock_directory
from .core.outdir import OutputDirError
from .results import RunResults

__all__ = ["sweep_main", "run_sweep", "parse_sets", "grid", "point_dirname", "run_point",
           "point_task", "run_stats", "load_point_checks", "finished_row", "point_digest",
           "stop_runs", "SweepError", "PointDeckError", "NotRun", "POINT_FILE", "SWEEP_FILE"]

POINT_FILE = "point.json"
SWEEP_FILE = "sweep.csv"
FIXED_COLUMNS = ("status", "reason", "wall_s", "cpu_s", "newton_iterations", "increments",
                 "failed_attempts")
DASK_CONNECT_TIMEOUT = "30s"
RESUME_SKIPS = (0, 3)      # exit codes of a point that a rerun does not run again
STOP_GRACE = 10.0          # s a run has to stop after the signal before it is killed
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_UNSAFE = re.compile(r"[^A-Za-z0-9.+\-]")

Runner = Callable[[Path, dict[str, str], Path], dict[str, Any]]


class SweepError(ValueError):
    """A malformed ``--set`` or an unusable sweep setting (the message says which)."""


class NotRun(Exception):
    """The point did not run: the sweep was interrupted first."""


class PointDeckError(Exception):
    """The deck has errors with this point's parameter values (message: the errors, one line)."""


# ---------------------------------------------------------------- the grid


def parse_sets(sets: Iterable[str]) -> dict[str, list[str]]:
    """``["NAME=v1,v2", ...]`` -> ``{NAME: [v1, v2], ...}`` in the order given (values kept as
    text, duplicates dropped)."""
    axes: dict[str, list[str]] = {}
    for item in sets:
        name, eq, values = item.partition("=")
        name = name.strip()
        if not eq or not _NAME.match(name):
            raise SweepError(f"--set {item!r}: expected NAME=v1,v2,... with NAME a parameter name")
        if name.upper() in (n.upper() for n in axes):
            raise SweepError(f"--set {item!r}: parameter {name} is set twice")
        vals = list(dict.fromkeys(v.strip() for v in values.split(",")))
        if not vals or "" in vals:
            raise SweepError(f"--set {item!r}: an empty value")
        axes[name] = vals
    return axes


def grid(axes: dict[str, list[str]]) -> list[dict[str, str]]:
    """Product grid, the last parameter varying fastest; one empty point when there is no axis."""
    names = list(axes)
    return [dict(zip(names, combo)) for combo in itertools.product(*axes.values())]


def point_dirname(point: dict[str, str]) -> str:
    """``NAME1=v1_NAME2=v2``; characters other than letters, digits, ``.+-`` become ``-``."""
    if not point:
        return "default"
    return "_".join(f"{k}={_UNSAFE.sub('-', v)}" for k, v in point.items())


# ---------------------------------------------------------------- one point


def run_point(deck: Path, params: dict[str, str], pointdir: Path, *,
              command: list[str] | None = None, threads: int | None = None) -> dict[str, Any]:
    """Run one point as a subprocess and wait for it.

    ``command`` (default ``[python, -m, lagamine_py, run]``) is followed by
    ``DECK -o POINTDIR -q --overwrite --param NAME=VALUE ...``; its output goes to
    ``POINTDIR/run.stdout`` and ``run.stderr``.  Returns ``status`` (exit code; minus the signal number if killed),
    ``reason`` (see :func:`_reason`) and ``cpu_s`` (user + system time of that child alone, from
    ``os.wait4``, so concurrent runs in one worker do not mix).
    """
    pointdir = Path(pointdir)
    pointdir.mkdir(parents=True, exist_ok=True)
    # --overwrite: the point directory is the sweep's; a point runs again because its results
    # are stale (another deck, a changed one), which the run would otherwise refuse to replace
    argv = [*(command or [sys.executable, "-m", "lagamine_py", "run"]),
            str(deck), "-o", str(pointdir), "-q", "--overwrite"]
    for name, value in params.items():
        argv += ["--param", f"{name}={value}"]
    env = dict(os.environ)
    if threads is not None:
        for var in THREAD_VARS:
            env.setdefault(var, str(threads))
    cpu = math.nan
    with open(pointdir / "run.stdout", "w") as out, open(pointdir / "run.stderr", "w") as err:
        proc = subprocess.Popen(argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env)
        live = _Live(proc)
        try:
            if _STOPPING.is_set():              # the sweep was interrupted as this one started
                live.stop(signal.SIGTERM)
            if hasattr(os, "wait4"):
                _, wstatus, usage = os.wait4(proc.pid, 0)
                proc.returncode = os.waitstatus_to_exitcode(wstatus)
                cpu = usage.ru_utime + usage.ru_stime
            else:                                   # pragma: no cover (not POSIX)
                proc.wait()
            live.reaped.set()
        except BaseException:       # Ctrl-C in this thread: let the run stop, reap it, go on
            live.stop_and_reap(signal.SIGINT)
            raise
        finally:
            live.forget()
    return {"status": proc.returncode, "reason": _reason(pointdir, proc.returncode), "cpu_s": cpu}


# The runs started by run_point in this process and not yet reaped: what an interrupted sweep
# stops.  A run is reaped by the thread that started it (os.wait4 gives its CPU time), never
# by the one that stops it.
_LIVE: set = set()
_LIVE_LOCK = threading.Lock()
_STOPPING = threading.Event()       # the sweep is being interrupted: start no more runs
SETTLE = 0.5                        # s to let a run stop on a Ctrl-C it got from the terminal


class _Live:
    def __init__(self, proc):
        self.proc = proc
        self.reaped = threading.Event()
        with _LIVE_LOCK:
            _LIVE.add(self)

    def forget(self) -> None:
        with _LIVE_LOCK:
            _LIVE.discard(self)

    def stop(self, sig) -> None:
        """Send ``sig`` unless the run was reaped (its pid may belong to another process)."""
        if not self.reaped.is_set():
            try:
                os.kill(self.proc.pid, sig)
            except OSError:
                pass

    def stop_and_reap(self, sig) -> None:
        """From the thread that started the run: give it :data:`SETTLE` s to stop on its own
        (a Ctrl-C at the terminal reached it too), then ``sig``, then SIGKILL after
        :data:`STOP_GRACE` s; reap it."""
        for action, wait in ((None, SETTLE), (sig, STOP_GRACE), (signal.SIGKILL, None)):
            if action is not None:
                self.stop(action)
            try:
                self.proc.wait(wait)
                break
            except subprocess.TimeoutExpired:
                continue
        self.reaped.set()


def stop_runs(sig=signal.SIGTERM) -> None:
    """Stop every run :func:`run_point` started in this process and still running (they are
    reaped by the threads that wait on them): after :data:`SETTLE` s, ``sig`` (a run stops
    cleanly on SIGINT or SIGTERM: its files closed, exit status 130), then SIGKILL for those
    still running :data:`STOP_GRACE` s later."""
    _STOPPING.set()
    with _LIVE_LOCK:
        runs = list(_LIVE)
    for wait, action in ((SETTLE, sig), (STOP_GRACE, signal.SIGKILL)):
        deadline = time.monotonic() + wait
        for run in runs:
            run.reaped.wait(max(deadline - time.monotonic(), 0.0))
        for run in runs:
            run.stop(action)


#: how the first line of ``run``'s closing message starts (the lines after it are its summary:
#: contact totals, where the results are, the wall time)
CLOSING = "lagamine-py:"


def _last_line(path: Path) -> str:
    """The last closing message's first line in ``path``, else its last non-blank line (a
    crash's exception), else ''."""
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    closing = [ln for ln in lines if ln.startswith(CLOSING)]
    return closing[-1] if closing else (lines[-1] if lines else "")


def _reason(pointdir: Path, status: int) -> str:
    """Why the run stopped: the closing message in its stderr (``run`` prints it there when it
    fails; a crash, its exception), else in its stdout (the closing message of a run that
    finished), else the last line of the run's own log."""
    if status < 0:
        return f"killed by signal {signal.Signals(-status).name}"
    try:
        log = RunResults(pointdir).own(".log")
    except OutputDirError:                  # the logs of several decks: none is the run's
        log = None
    for path in (pointdir / "run.stderr", pointdir / "run.stdout", *([log] if log else [])):
        line = _last_line(path)
        if line:
            return line
    return f"exit status {status}"


def run_stats(pointdir: Path) -> dict[str, Any]:
    """Newton iterations (all attempts), converged increments and failed attempts, from the
    run's ``<deck>.sta`` in a run directory (zeros when there is none)."""
    try:
        sta = RunResults(Path(pointdir)).sta()
    except OutputDirError:          # the files of several decks and no record: none is the run's
        sta = {}
    if not sta:
        return {"newton_iterations": 0, "increments": 0, "failed_attempts": 0}
    n = len(sta.get("increment", ()))
    failed = [str(f).strip().lower() == "yes" for f in sta.get("failed", ["no"] * n)]
    iters = sta.get("iterations", [])
    total = sum(int(float(v)) for v in iters if str(v).strip() not in ("", "nan"))
    return {"newton_iterations": total, "increments": n - sum(failed), "failed_attempts": sum(failed)}


def point_task(deck: Path, params: dict[str, str], pointdir: Path, checks: list[dict[str, Any]],
               runner: Runner, digest: str = "") -> dict[str, Any]:
    """Run one point with ``runner`` and build its sweep.csv row; write ``point.json`` (with
    the deck's absolute path and ``digest``) when the run finished.  Runs in a worker (a thread
    or a dask task); never raises for a failed run (:class:`NotRun` when the sweep was
    interrupted before the point started)."""
    if _STOPPING.is_set():
        raise NotRun(f"{Path(pointdir).name}: not run, the sweep was interrupted")
    pointdir = Path(pointdir)
    pointdir.mkdir(parents=True, exist_ok=True)
    (pointdir / POINT_FILE).unlink(missing_ok=True)      # a rerun: not finished until it is
    row: dict[str, Any] = {"point": pointdir.name, **params}
    t0 = time.perf_counter()
    try:
        out = runner(Path(deck), dict(params), pointdir)
    except Exception as exc:        # the runner itself broke: record, leave no marker (retry)
        row.update({"status": EXIT_OTHER, "reason": f"sweep: {type(exc).__name__}: {exc}",
                    "wall_s": time.perf_counter() - t0, "cpu_s": math.nan})
        return row
    row.update({"status": int(out["status"]), "reason": str(out.get("reason", "")),
                "wall_s": time.perf_counter() - t0, "cpu_s": float(out.get("cpu_s", math.nan))})
    row.update(run_stats(pointdir))
    results = evaluate_checks(checks, pointdir) if checks else []
    row.update(check_columns(results))
    _write_json(pointdir / POINT_FILE, {"params": params, "row": row, "checks": results,
                                        "deck": {"path": str(Path(deck).resolve()),
                                                 "digest": digest}})
    return row


def _write_json(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str))
    os.replace(tmp, path)


def finished_row(pointdir: Path, digest: str | None = None) -> dict[str, Any] | None:
    """The stored row of a point a rerun skips: one that ran to the end (status 0) or stopped on
    non-convergence (3), with the deck whose expanded text has ``digest`` (when given).  None
    otherwise: no marker, an unreadable one, another deck or a changed one, or a deck error
    (2), a crash (1) or a signal, which say the deck or the installation needed fixing: run
    again."""
    data = _point_record(pointdir)
    row = data.get("row")
    if not isinstance(row, dict) or row.get("status") not in RESUME_SKIPS:
        return None
    if digest is not None and _recorded_digest(data) != digest:
        return None
    return row


def _point_record(pointdir: Path) -> dict:
    try:
        data = json.loads((Path(pointdir) / POINT_FILE).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _recorded_digest(data: dict) -> str | None:
    deck = data.get("deck")
    return str(deck.get("digest", "")) if isinstance(deck, dict) else None


def stale_deck(pointdir: Path, digest: str) -> bool:
    """Whether the point finished (status 0 or 3) with another deck than the one of ``digest``
    (or before the deck changed): its results are stale and it runs again."""
    data = _point_record(pointdir)
    row = data.get("row")
    return (isinstance(row, dict) and row.get("status") in RESUME_SKIPS
            and _recorded_digest(data) != digest)


def point_digest(deck: Path, params: dict[str, str]) -> str:
    """The digest of what decides a point's results: the deck's expanded text with the point's
    parameter values (errors in the deck do not matter here: they are the checks' business)
    and the program that runs it (:func:`program_digest`)."""
    from .deck import deck_digest
    text = deck_digest(Path(deck), dict(params)) + program_digest()
    return hashlib.sha256(text.encode()).hexdigest()


@functools.lru_cache(maxsize=None)
def program_digest() -> str:
    """The digest of this lagamine_py's source (every module of the package, by relative path
    and bytes), of the installed plugins of other packages (:func:`plugin_sources`) and of the
    Python, NumPy and SciPy versions: a point finished by another version of the program, or
    with another version of a plugin, is not reused."""
    import numpy
    import scipy
    h = hashlib.sha256(f"{sys.version}|{numpy.__version__}|{scipy.__version__}".encode())
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes() + b"\0")
    for label, source in plugin_sources():
        h.update(label.encode() + b"\0" + source + b"\0")
    return h.hexdigest()


def plugin_sources(path: list[str] | None = None) -> list[tuple[str, bytes]]:
    """The plugins other packages install (entry points of the ``lagamine_py.*`` groups whose
    module is not this package's, on ``path``, default ``sys.path``), each as ``("group name =
    value", source)``: the bytes of its module, or of every module of its package, found
    without importing the module itself (its parent packages are imported).  A module that
    cannot be found gives empty bytes (the run will say why)."""
    import importlib.util
    from . import registry
    out = []
    for ep in sorted(registry.installed_entry_points(path),
                     key=lambda e: (e.group, e.name, e.value)):
        module = ep.value.split("[")[0].partition(":")[0].strip()
        if module.split(".")[0] == registry.BUILTIN:
            continue                                    # ours: in the package's own digest
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            spec = None
        files: list[Path] = []
        if spec is not None and spec.submodule_search_locations:
            files = sorted(f for d in spec.submodule_search_locations for f in Path(d).rglob("*.py"))
        elif spec is not None and spec.origin and Path(spec.origin).is_file():
            files = [Path(spec.origin)]
        out.append((f"{ep.group} {ep.name} = {ep.value}",
                    b"\0".join(str(f).encode() + b"\0" + f.read_bytes() for f in files)))
    return out


def load_point_checks(deck: Path, params: dict[str, str]) -> list[dict[str, Any]]:
    """The deck's ``*CHECK`` requests with these parameter values; :class:`PointDeckError` when
    the deck has errors with them."""
    from .deck import DeckError, load_deck
    try:
        model = load_deck(Path(deck), parameters=dict(params))
    except DeckError as exc:
        raise PointDeckError(_one_line(str(exc))) from exc
    return list(model.checks)


# ---------------------------------------------------------------- sweep.csv


def write_sweep_csv(path: Path, names: list[str], rows: list[dict[str, Any] | None]) -> None:
    """Rewrite sweep.csv with the finished rows (grid order); atomic (write, then rename)."""
    done = [r for r in rows if r is not None]
    extra = list(dict.fromkeys(k for r in done for k in r
                               if k not in names and k not in FIXED_COLUMNS and k != "point"))
    header = ["point", *names, *FIXED_COLUMNS, *extra]
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as fh:
        out = csv.writer(fh, lineterminator="\n")
        out.writerow(header)
        out.writerows([_cell(r.get(k, "")) for k in header] for r in done)
    os.replace(tmp, path)


def _cell(v: Any) -> str:
    return repr(v) if isinstance(v, float) else str(v)


# ---------------------------------------------------------------- executors


def _failure(point: dict[str, str], dirname: str, exc: BaseException) -> dict[str, Any]:
    return {"point": dirname, **point, "status": EXIT_OTHER,
            "reason": f"sweep: {type(exc).__name__}: {exc}".strip(), "wall_s": math.nan, "cpu_s": math.nan}


def _run_local(tasks, jobs: int, done: Callable[[int, dict], None]) -> None:
    """``tasks``: [(index, args of point_task)]; ``jobs`` <= 1 runs them here, one by one,
    else ``jobs`` threads.  Interrupted (KeyboardInterrupt: Ctrl-C, or SIGTERM through
    :func:`sweep_main`), it stops the runs in progress, records every point that finished
    (those stopped included) and raises KeyboardInterrupt again."""
    if jobs <= 1:
        for idx, args in tasks:
            try:
                row = point_task(*args)
            except Exception as exc:
                row = _failure(args[1], Path(args[2]).name, exc)
            done(idx, row)
        return
    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="sweep-point")
    futures = {pool.submit(point_task, *args): (idx, args) for idx, args in tasks}
    recorded = set()

    def record(fut) -> None:
        idx, args = futures[fut]
        recorded.add(fut)
        try:
            row = fut.result()
        except NotRun:
            return
        except Exception as exc:                 # the task itself broke
            row = _failure(args[1], Path(args[2]).name, exc)
        done(idx, row)
    try:
        for fut in as_completed(futures):
            record(fut)
    except BaseException:
        for fut in futures:
            fut.cancel()                         # the points not started
        stop_runs(signal.SIGTERM)
        pool.shutdown(wait=True)
        for fut in futures:                      # those that ended meanwhile, in grid order
            if fut not in recorded and fut.done() and not fut.cancelled():
                record(fut)
        raise
    pool.shutdown(wait=True)


def _run_dask(tasks, address: str, done: Callable[[int, dict], None]) -> None:
    try:
        from dask.distributed import Client, as_completed as dask_completed
    except ImportError as exc:
        raise SweepError(f"--scheduler needs dask.distributed ({exc}); install it with "
                         f"pip install \"lagamine_py[dask]\"") from None
    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as exc:
        raise SweepError(f"cannot connect to the dask scheduler at {address}: {exc}") from None
    with client:
        futures = {}
        for idx, args in tasks:
            key = f"lagamine-point-{Path(args[2]).name}-{uuid.uuid4().hex[:8]}"
            futures[client.submit(point_task, *args, key=key, pure=False)] = (idx, args)
        recorded = set()
        try:
            for fut in dask_completed(list(futures)):
                idx, args = futures[fut]
                try:
                    row = fut.result()
                except Exception as exc:             # KilledWorker, a lost connection, ...
                    row = _failure(args[1], Path(args[2]).name, exc)
                recorded.add(fut)
                done(idx, row)
        except BaseException:
            # the points that finished are recorded; the others are cancelled (a task already
            # running on a worker runs to its end there: dask cannot stop it)
            for fut, (idx, args) in futures.items():
                if fut not in recorded and fut.status == "finished":
                    done(idx, fut.result())
            client.cancel([f for f in futures if f not in recorded])
            raise


# ---------------------------------------------------------------- the sweep


def run_sweep(deck: Path, axes: dict[str, list[str]], outdir: Path, jobs: int = 1,
              scheduler: str | None = None, runner: Runner | None = None,
              log: Callable[[str], None] = print) -> list[dict[str, Any] | None]:
    """Run (or resume) the sweep; returns the rows in grid order (None for a point that did
    not finish, which cannot happen unless the sweep was interrupted)."""
    deck, outdir = Path(deck).resolve(), Path(outdir).resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    _STOPPING.clear()
    points = grid(axes)
    dirnames = [point_dirname(p) for p in points]
    if len(set(dirnames)) != len(dirnames):
        raise SweepError("two points map to the same directory name; use values made of letters, "
                         "digits and . + -")
    names = list(axes)
    if runner is None:
        runner = partial(run_point, threads=1 if (jobs > 1 or scheduler) else None)
    digests = [point_digest(deck, p) for p in points]
    rows: list[dict[str, Any] | None] = [finished_row(outdir / d, dg)
                                         for d, dg in zip(dirnames, digests)]
    skipped = sum(r is not None for r in rows)
    stale = [d for d, dg, r in zip(dirnames, digests, rows)
             if r is None and stale_deck(outdir / d, dg)]
    csv_path = outdir / SWEEP_FILE
    write_sweep_csv(csv_path, names, rows)
    if skipped:
        log(f"sweep: {skipped} of {len(points)} points already finished in {outdir} with this "
            f"deck; skipping them")
    if stale:
        log(f"sweep: {len(stale)} point(s) ran with another deck, with this deck before it "
            f"changed (its text, an included file or a parameter value), or with another version "
            f"of lagamine_py, a plugin, NumPy or SciPy; running them again: "
            f"{', '.join(stale[:5])}{' ...' if len(stale) > 5 else ''}")

    counter = itertools.count(skipped + 1)

    def done(idx: int, row: dict[str, Any]) -> None:
        rows[idx] = row
        write_sweep_csv(csv_path, names, rows)
        log(f"sweep: [{next(counter)}/{len(points)}] {dirnames[idx]}: status {row['status']}"
            + (f" ({row['reason']})" if row["status"] != EXIT_OK and row.get("reason") else "")
            + (f", {row['wall_s']:.1f} s" if isinstance(row.get("wall_s"), float)
               and not math.isnan(row["wall_s"]) else ""))

    tasks, warned = [], False
    for idx, (point, dirname) in enumerate(zip(points, dirnames)):
        if rows[idx] is not None:
            continue
        pointdir = outdir / dirname
        try:
            checks = load_point_checks(deck, point)
        except PointDeckError as exc:   # a deck error with these values: recorded, not run
            pointdir.mkdir(parents=True, exist_ok=True)
            row = {"point": dirname, **point, "status": EXIT_DECK,
                   "reason": str(exc), "wall_s": 0.0, "cpu_s": 0.0,
                   "newton_iterations": 0, "increments": 0, "failed_attempts": 0}
            _write_json(pointdir / POINT_FILE, {"params": point, "row": row, "checks": [],
                                                "deck": {"path": str(deck),
                                                         "digest": digests[idx]}})
            done(idx, row)
            continue
        except Exception as exc:        # the deck could not be read here: run it, checks unknown
            if not warned:
                log(f"sweep: cannot read the deck's *CHECK requests ({type(exc).__name__}: {exc}); "
                    f"sweep.csv will have no check columns")
                warned = True
            checks = []
        tasks.append((idx, (deck, point, pointdir, checks, runner, digests[idx])))
    if scheduler:
        _run_dask(tasks, scheduler, done)
    else:
        _run_local(tasks, jobs, done)
    return rows


def _one_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return " | ".join(lines[:3]) + (f" | ... ({len(lines) - 3} more)" if len(lines) > 3 else "")


def sweep_main(deck: Path, sets: list[str], outdir: Path, jobs: int = 1,
               scheduler: str | None = None, *, runner: Runner | None = None) -> int:
    """The ``sweep`` command.  Exit status 0 when every point ran with status 0, 1 when some
    did not (sweep.csv says which and why), 2 for a bad ``--set``, a missing deck or a sweep
    already running into ``outdir``, 130 when interrupted (Ctrl-C or SIGTERM)."""
    from .core.outdir import OutputDirError
    try:
        axes = parse_sets(sets)
        if not Path(deck).is_file():
            raise SweepError(f"no deck {deck}")
        if jobs < 1:
            raise SweepError(f"-j {jobs}: need at least 1")
        Path(outdir).mkdir(parents=True, exist_ok=True)
        with sigterm_interrupts(), lock_directory(Path(outdir)):
            rows = run_sweep(deck, axes, outdir, jobs, scheduler, runner)
    except (SweepError, OutputDirError) as exc:
        print(f"lagamine-py sweep: {exc}", file=sys.stderr)
        return EXIT_DECK
    except KeyboardInterrupt:
        print(f"lagamine-py sweep: interrupted; the points that finished are in "
              f"{Path(outdir) / SWEEP_FILE}; run the same command again to go on",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    bad = [r for r in rows if r is None or int(r["status"]) != EXIT_OK]
    print(f"lagamine-py sweep: {len(rows) - len(bad)} of {len(rows)} points ran to the end; "
          f"table {Path(outdir) / SWEEP_FILE}")
    return EXIT_OK if not bad else EXIT_OTHER
