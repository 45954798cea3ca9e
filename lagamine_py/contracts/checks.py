"""The check contract (:class:`lagamine_py.checks.base.Check`) as checks.

An empty directory must be reported (error NaN and a message through
:func:`~lagamine_py.checks.base.evaluate_checks`, never a traceback); the sample run of
:mod:`.writers` (a finished run with the built-in writers' files) must give the contract's keys,
or a :class:`~lagamine_py.checks.base.CheckError` saying why it cannot answer.
"""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

from .findings import ContractFailure, Finding, Skip, Suite, require
from .writers import sample_run


CHECK_ITEMS = ("parameters", "empty directory", "finished run")


def _check_empty(check) -> str:
    from ..results import RunResults
    with tempfile.TemporaryDirectory(prefix="lagamine_check_empty_") as empty:
        return _check_empty_in(check, RunResults(Path(empty)))


def _check_empty_in(check, run) -> str:
    from ..checks.base import CheckError, evaluate_check
    try:
        got = check.evaluate(run)
        direct = f"evaluate() returned {got!r}"
    except CheckError as exc:
        direct = f"evaluate() raised CheckError: {exc}"
    except Exception as exc:
        direct = f"evaluate() raised {type(exc).__name__}: {exc}"
    try:
        entry = evaluate_check(check, run)
    except Exception as exc:
        raise ContractFailure(f"{direct}; evaluate_checks lets {type(exc).__name__} escape: "
                              f"{exc}") from None
    require(math.isnan(float(entry["error"])) and entry["message"],
            f"{direct}; evaluate_checks reports error {entry['error']!r}, message "
            f"{entry['message']!r} (want NaN and a message)")
    return f"{direct}; evaluate_checks: error NaN, message {entry['message']!r}"


def _check_finished(check) -> str:
    from ..checks.base import CheckError
    from ..results import RunResults
    run = sample_run()
    try:
        got = check.evaluate(RunResults(run.outdir))
    except CheckError as exc:
        raise Skip(f"the sample run cannot answer it (CheckError: {exc})") from None
    require(isinstance(got, dict), f"evaluate() returned {type(got).__name__}, not a dict")
    missing = [k for k in ("measured", "closed_form", "errors", "error") if k not in got]
    require(not missing, f"evaluate() lacks {', '.join(missing)}: {got!r}")
    bad = [k for k in ("measured", "closed_form", "errors") if not isinstance(got[k], dict)]
    require(not bad, f"{', '.join(bad)} must be dicts: {got!r}")
    try:
        error = float(got["error"])
    except (TypeError, ValueError):
        raise ContractFailure(f"error {got['error']!r} is not a number") from None
    return (f"on a finished run (the sample press-and-push): error {error:.3g}, measured "
            f"{sorted(got['measured'])}, closed_form {sorted(got['closed_form'])}")


def check_check(cls) -> list[Finding]:
    """The check contract (:class:`~lagamine_py.checks.base.Check`) on ``cls``."""
    s = Suite(CHECK_ITEMS)
    check = s.build(cls)
    if check is None:
        return s.blocked("the check could not be built from example_values()")
    s.run("empty directory", _check_empty, check)
    s.run("finished run", _check_finished, check)
    return s.findings
