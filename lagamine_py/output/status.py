"""The status file ``<deck>.sta`` and the log ``<deck>.log``.

``<deck>.sta`` is a CSV (read back by :func:`lagamine_py.results.read_table`)::

    step,step_name,increment,time,dt,iterations,residual,cutbacks,failed,reason,load

one row per converged increment (``failed`` = ``no``) and one per failed attempt
(``failed`` = ``yes``, ``reason`` says why; ``time`` and ``dt`` are those attempted;
``residual`` empty when the attempt's last residual is not finite), in the
order they happened, flushed each time: a glance at the tail tells how a run is going.
``load``: the loads the step drives, reached at that increment
(:func:`lagamine_py.solver.loads.driving_loads`), as ``label=value`` items separated by ``; ``
(``U1 BLOCK_RIGHT=-0.005; P PRESSED=200``); ``lagamine-py plot`` labels its states with them.

``<deck>.log`` holds the run's messages: a start line, the Newton residual history of every
converged increment, every failed attempt with its reason, the final line with the exit status,
and everything logged to the ``lagamine_py`` logger (and its children) from the thread that
started the run, through a :class:`logging.Handler` attached for the run's duration.

Option ``append`` (resuming a run): both files are kept and appended to; the status rows at or
after the first resumed (step, increment) are dropped (see :mod:`lagamine_py.output.tables`).
"""
from __future__ import annotations

import logging
import math
import threading
from datetime import datetime, timezone

from .base import FailedAttempt, IncrementResult, Writer
from .tables import CsvFiles

STA_HEADER = ("step", "step_name", "increment", "time", "dt", "iterations", "residual",
              "cutbacks", "failed", "reason", "load")
LOGGER = "lagamine_py"
LOG_FORMAT = "%(asctime)s %(levelname)-7s %(name)s: %(message)s"


def _g(x) -> str:
    return "" if x is None else repr(float(x))      # shortest exact text


def load_text(loads: dict[str, float]) -> str:
    """``{"U1 RIGHT": -0.005, "P TOP": 200.0}`` -> ``"U1 RIGHT=-0.005; P TOP=200.0"``."""
    return "; ".join(f"{label}={float(v)!r}" for label, v in loads.items())


def parse_load_text(text: str) -> dict[str, float]:
    """The inverse of :func:`load_text` (items that do not read as ``label=number`` skipped)."""
    out = {}
    for item in str(text or "").split(";"):
        label, eq, value = item.strip().rpartition("=")
        try:
            out[label.strip()] = float(value)
        except ValueError:
            continue
    return {k: v for k, v in out.items() if k}


def _ends_a_line(path) -> bool:
    """Whether the file is empty or ends with a newline."""
    with open(path, "rb") as fh:
        fh.seek(0, 2)
        if fh.tell() == 0:
            return True
        fh.seek(-1, 2)
        return fh.read(1) == b"\n"


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


class _ThreadFilter(logging.Filter):
    """Keep records from one thread: parallel runs in one process keep separate logs."""

    def __init__(self, thread: int):
        super().__init__()
        self.thread = thread

    def filter(self, record: logging.LogRecord) -> bool:
        return record.thread == self.thread


class StatusWriter(Writer):
    """<deck>.sta (one row per increment or failed attempt) and <deck>.log (messages)."""

    always = True
    _handler: logging.Handler | None = None

    def start_run(self) -> None:
        deck = self.model.name or "run"
        append = self.append
        self._sta_files = CsvFiles(self.outdir, {"sta": (f"{deck}.sta", STA_HEADER)}, append)
        log_path = self.outdir / f"{deck}.log"
        torn = append and log_path.exists() and not _ends_a_line(log_path)
        self._log_fh = open(log_path, "a" if append else "w")
        if torn:                        # a line cut by a kill: the resumed log starts afresh
            self._log_fh.write("\n")
        self.step_name = ""
        self._attach_handler()
        heading = self.model.heading
        units = tuple(self.model.units)
        n_nodes = len(self.model.node_ids)
        n_elem = sum(len(b.ids) for b in self.model.blocks)
        self._line(f"lagamine-py run of deck {deck} {'resumed' if append else 'started'} {_now()}: "
                   f"{n_nodes} nodes, {n_elem} elements"
                   + (f"; units: length {units[0]}, force {units[1]}, stress {units[2]}"
                      if len(units) == 3 else "")
                   + (f"; heading: {heading.strip()}" if heading and heading.strip() else ""))

    def _sta_row(self, step: int, increment: int, row: list) -> None:
        """Write one status row (dropping a resumed run's stale rows first) and flush."""
        self._sta_files.resume_at(int(step), int(increment))
        self._sta_files.writers["sta"].writerow(row)
        self._sta_files.flush()

    def _attach_handler(self) -> None:
        self._handler = logging.StreamHandler(self._log_fh)
        self._handler.setFormatter(logging.Formatter(LOG_FORMAT))
        self._handler.addFilter(_ThreadFilter(threading.get_ident()))
        logger = logging.getLogger(LOGGER)
        self._old_level = logger.level
        if logger.getEffectiveLevel() > logging.INFO:
            logger.setLevel(logging.INFO)       # the solver's INFO messages belong in the log
        logger.addHandler(self._handler)

    def _line(self, text: str) -> None:
        """A message of this writer: same layout as the logging handler's lines, flushed."""
        record = logging.LogRecord(LOGGER, logging.INFO, __file__, 0, text, None, None)
        self._log_fh.write(self._handler.format(record) + "\n")
        self._log_fh.flush()

    def start_step(self, step_number: int, step) -> None:
        self.step_name = step.name or ""
        self._line(f"step {step_number} {self.step_name} starts")

    def increment(self, r: IncrementResult) -> None:
        self._sta_row(r.step, r.increment,
                      [r.step, r.step_name or self.step_name, r.increment, _g(r.time), _g(r.dt),
                       r.iterations, _g(r.residual), r.cutbacks, "no", "", load_text(r.loads)])
        history = " ".join(f"{x:.3e}" for x in r.residual_history)
        self._line(f"step {r.step} increment {r.increment} converged: time {r.time:.6g}, dt {r.dt:.6g}, "
                   f"{r.iterations} iterations, residual {r.residual:.3e}, cutbacks {r.cutbacks}"
                   + (f"; residuals {history}" if history else ""))

    def failed_attempt(self, a: FailedAttempt) -> None:
        """One failed attempt: a .sta row whose ``time`` is the end time the attempt aimed at
        (``time + dt``, comparable with the converged rows) and a log line with the message."""
        history = list(a.residual_history)
        # a residual that blew up to inf or NaN is left empty (the reason says "NaN"): tables
        # hold no NaN for readers to trip on; the log keeps the whole history
        residual = history[-1] if history and math.isfinite(history[-1]) else None
        self._sta_row(a.step, a.increment,
                      [a.step, a.step_name or self.step_name, a.increment, _g(a.time + a.dt),
                       _g(a.dt), a.iterations, _g(residual), a.cutbacks, "yes",
                       a.reason.strip() or "unknown", ""])
        text = a.message.strip() or a.reason
        self._line(f"step {a.step} increment {a.increment} attempt failed (dt {a.dt:.6g}): {text}"
                   + (f"; residuals {' '.join(f'{x:.3e}' for x in history)}" if history else ""))

    def close(self, status: int, message: str) -> None:
        if self._handler is None:
            return
        self._line(f"run finished {_now()} with exit status {status}: {message}")
        logger = logging.getLogger(LOGGER)
        logger.removeHandler(self._handler)
        logger.setLevel(self._old_level)
        self._handler = None
        self._sta_files.close()
        self._log_fh.close()
