"""``lagamine-py sweep DECK --set NAME=v1,v2 [--set ...] -o DIR [-j N] [--scheduler ADDRESS]``.

Runs a deck over the product grid of ``*PARAMETER`` values, one run directory per point
(``DIR/<name1>=<v1>_<name2>=<v2>/``), each point a separate process::

    python -m lagamine_py run DECK -o POINTDIR -q --param NAME=VALUE ...

Where the points run:

* ``-j N`` (default 1): on this machine, ``N`` at a time (``concurrent.futures``
  ``ProcessPoolExecutor`` workers, each waiting on its run's subprocess; BLAS threads are pinned
  to 1 per run when ``N > 1``);
* ``--scheduler ADDRESS``: as tasks of a ``dask.distributed`` cluster (optional extra ``dask``:
  ``pip install "lagamine_py[dask]"``).  The workers must see ``DECK`` and ``DIR`` at the same
  paths (a shared file system) and have ``lagamine_py`` installed.

``DIR/sweep.csv`` gets one row per finished point, rewritten (atomically) each time a point
finishes: ``point`` (its directory name), the parameters, ``status`` (the run's exit code: 0 ok,
2 deck error, 3 did not converge, 1 other), ``reason`` (the last line the run printed: its
closing message, or the error), ``wall_s`` and ``cpu_s`` (of the run's process, from
``os.wait4``), ``newton_iterations`` (sum of the ``.sta`` iterations column, failed attempts
included: the work done), ``increments`` (converged) and ``failed_attempts``, then the deck's
``*CHECK`` columns from :func:`lagamine_py.checks.check_columns` (``<check>_error``, measured
``<check>_<qty>``, closed form ``<check>_<qty>_cf``).

A point whose run finished leaves ``POINTDIR/point.json`` (its row and full check results).  A
rerun of the same sweep (or of a grid extended by more values) skips the points that ran to the
end (status 0) or stopped on non-convergence (status 3), reusing their rows, so an interrupted
sweep resumes where it stopped; points with a deck error (2), a crash (1) or a signal are run
again, on the view that their deck or installation has been fixed in between.  A point whose
worker failed (an exception, a lost dask worker) is recorded in sweep.csv with status 1 and the
reason, and leaves no ``point.json``.
"""
from __future__ import annotations

import csv
import itertools
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
import uuid
from concurrent.futures import ProcessPoolExecutor, as_completed
from functools import partial
from pathlib import Path
from typing import Any, Callable, Iterable

from .checks import check_columns, evaluate_checks
from .core.exits import EXIT_DECK, EXIT_OK, EXIT_OTHER
from .core.outdir import OutputDirError
from .results import RunResults

__all__ = ["sweep_main", "run_sweep", "parse_sets", "grid", "point_dirname", "run_point",
           "point_task", "run_stats", "load_point_checks", "SweepError", "PointDeckError",
           "POINT_FILE", "SWEEP_FILE"]

POINT_FILE = "point.json"
SWEEP_FILE = "sweep.csv"
FIXED_COLUMNS = ("status", "reason", "wall_s", "cpu_s", "newton_iterations", "increments",
                 "failed_attempts")
DASK_CONNECT_TIMEOUT = "30s"
RESUME_SKIPS = (0, 3)      # exit codes of a point that a rerun does not run again
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_UNSAFE = re.compile(r"[^A-Za-z0-9.+\-]")

Runner = Callable[[Path, dict[str, str], Path], dict[str, Any]]


class SweepError(ValueError):
    """A malformed ``--set`` or an unusable sweep setting (the message says which)."""


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
    ``DECK -o POINTDIR -q --param NAME=VALUE ...``; its output goes to ``POINTDIR/run.stdout``
    and ``run.stderr``.  Returns ``status`` (exit code; minus the signal number if killed),
    ``reason`` (see :func:`_reason`) and ``cpu_s`` (user + system time of that child alone, from
    ``os.wait4``, so concurrent runs in one worker do not mix).
    """
    pointdir = Path(pointdir)
    pointdir.mkdir(parents=True, exist_ok=True)
    argv = [*(command or [sys.executable, "-m", "lagamine_py", "run"]),
            str(deck), "-o", str(pointdir), "-q"]
    for name, value in params.items():
        argv += ["--param", f"{name}={value}"]
    env = dict(os.environ)
    if threads is not None:
        for var in THREAD_VARS:
            env.setdefault(var, str(threads))
    cpu = math.nan
    with open(pointdir / "run.stdout", "w") as out, open(pointdir / "run.stderr", "w") as err:
        proc = subprocess.Popen(argv, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env)
        try:
            if hasattr(os, "wait4"):
                _, wstatus, usage = os.wait4(proc.pid, 0)
                proc.returncode = os.waitstatus_to_exitcode(wstatus)
                cpu = usage.ru_utime + usage.ru_stime
            else:                                   # pragma: no cover (not POSIX)
                proc.wait()
        except BaseException:
            proc.kill()
            proc.wait()
            raise
    return {"status": proc.returncode, "reason": _reason(pointdir, proc.returncode), "cpu_s": cpu}


def _last_line(path: Path) -> str:
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return ""
    return lines[-1] if lines else ""


def _reason(pointdir: Path, status: int) -> str:
    """Why the run stopped: the last line of its stderr (``run`` prints its closing message there
    when it fails, a crash its exception), else of its stdout (the closing message of a run that
    finished), else of its log."""
    if status < 0:
        return f"killed by signal {signal.Signals(-status).name}"
    for path in (pointdir / "run.stderr", pointdir / "run.stdout", *sorted(pointdir.glob("*.log"))):
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
               runner: Runner) -> dict[str, Any]:
    """Run one point with ``runner`` and build its sweep.csv row; write ``point.json`` when the
    run finished.  Runs in a worker (local process or dask); never raises for a failed run."""
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
    _write_json(pointdir / POINT_FILE, {"params": params, "row": row, "checks": results})
    return row


def _write_json(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=str))
    os.replace(tmp, path)


def finished_row(pointdir: Path) -> dict[str, Any] | None:
    """The stored row of a point a rerun skips: one that ran to the end (status 0) or stopped on
    non-convergence (3).  None otherwise: no marker, an unreadable one, or a deck error (2), a
    crash (1) or a signal, which say the deck or the installation needed fixing: run again."""
    try:
        data = json.loads((Path(pointdir) / POINT_FILE).read_text())
    except (OSError, ValueError):
        return None
    row = data.get("row") if isinstance(data, dict) else None
    if not isinstance(row, dict) or row.get("status") not in RESUME_SKIPS:
        return None
    return row


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
    """``tasks``: [(index, args of point_task)]; ``jobs`` <= 1 runs them here, one by one."""
    if jobs <= 1:
        for idx, args in tasks:
            try:
                row = point_task(*args)
            except Exception as exc:
                row = _failure(args[1], Path(args[2]).name, exc)
            done(idx, row)
        return
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(point_task, *args): (idx, args) for idx, args in tasks}
        for fut in as_completed(futures):
            idx, args = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:             # e.g. BrokenProcessPool: a worker died
                row = _failure(args[1], Path(args[2]).name, exc)
            done(idx, row)


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
        for fut in dask_completed(list(futures)):
            idx, args = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:             # KilledWorker, a lost connection, ...
                row = _failure(args[1], Path(args[2]).name, exc)
            done(idx, row)


# ---------------------------------------------------------------- the sweep


def run_sweep(deck: Path, axes: dict[str, list[str]], outdir: Path, jobs: int = 1,
              scheduler: str | None = None, runner: Runner | None = None,
              log: Callable[[str], None] = print) -> list[dict[str, Any] | None]:
    """Run (or resume) the sweep; returns the rows in grid order (None for a point that did
    not finish, which cannot happen unless the sweep was interrupted)."""
    deck, outdir = Path(deck).resolve(), Path(outdir).resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    points = grid(axes)
    dirnames = [point_dirname(p) for p in points]
    if len(set(dirnames)) != len(dirnames):
        raise SweepError("two points map to the same directory name; use values made of letters, "
                         "digits and . + -")
    names = list(axes)
    if runner is None:
        runner = partial(run_point, threads=1 if (jobs > 1 or scheduler) else None)
    rows: list[dict[str, Any] | None] = [finished_row(outdir / d) for d in dirnames]
    skipped = sum(r is not None for r in rows)
    csv_path = outdir / SWEEP_FILE
    write_sweep_csv(csv_path, names, rows)
    if skipped:
        log(f"sweep: {skipped} of {len(points)} points already finished in {outdir}; skipping them")

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
            _write_json(pointdir / POINT_FILE, {"params": point, "row": row, "checks": []})
            done(idx, row)
            continue
        except Exception as exc:        # the deck could not be read here: run it, checks unknown
            if not warned:
                log(f"sweep: cannot read the deck's *CHECK requests ({type(exc).__name__}: {exc}); "
                    f"sweep.csv will have no check columns")
                warned = True
            checks = []
        tasks.append((idx, (deck, point, pointdir, checks, runner)))
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
    did not (sweep.csv says which and why), 2 for a bad ``--set`` or a missing deck."""
    try:
        axes = parse_sets(sets)
        if not Path(deck).is_file():
            raise SweepError(f"no deck {deck}")
        if jobs < 1:
            raise SweepError(f"-j {jobs}: need at least 1")
        rows = run_sweep(deck, axes, outdir, jobs, scheduler, runner)
    except SweepError as exc:
        print(f"lagamine-py sweep: {exc}", file=sys.stderr)
        return EXIT_DECK
    bad = [r for r in rows if r is None or int(r["status"]) != EXIT_OK]
    print(f"lagamine-py sweep: {len(rows) - len(bad)} of {len(rows)} points ran to the end; "
          f"table {Path(outdir) / SWEEP_FILE}")
    return EXIT_OK if not bad else EXIT_OTHER
