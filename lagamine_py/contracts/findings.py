"""What a contract check returns, and the little machinery the suites share.

A check is a function returning the detail of what it compared (the numbers), or raising
:class:`ContractFailure` (with the numbers) or :class:`Skip` (with why it cannot be made here);
a :class:`Suite` runs a kind's checks in order and turns each into a :class:`Finding`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

__all__ = ["Finding", "Report", "ContractFailure", "Skip", "Suite", "within", "all_within",
           "require", "construct", "changed_keys"]


@dataclass(frozen=True)
class Finding:
    """One check of a plugin: ``passed`` with the numbers compared in ``detail``; ``skipped``
    when it could not be made here (the detail says why), which counts as passed."""
    check: str
    passed: bool
    detail: str
    skipped: bool = False

    @property
    def verdict(self) -> str:
        return "skip" if self.skipped else ("ok" if self.passed else "FAIL")


@dataclass
class Report:
    """The findings of one registered plugin."""
    kind: str
    name: str
    origin: str
    findings: list[Finding] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(f.passed for f in self.findings)


class ContractFailure(Exception):
    """A check failed; the message gives the numbers."""


class Skip(Exception):
    """A check cannot be made for this plugin here; the message says why."""


def within(what: str, err: float, tol: float) -> str:
    """``what = err <= tol``; raises ContractFailure when ``err`` is not within (NaN is not)."""
    if not err <= tol:
        raise ContractFailure(f"{what} = {err:.2e} > {tol:.0e}")
    return f"{what} = {err:.2e} <= {tol:.0e}"


def all_within(measures: list[tuple[str, float, float]]) -> str:
    """Several :func:`within` at once.  The detail lists the failing measures and then the
    others (past three measures, only the worst of those within)."""
    bad = [f"{w} = {e:.2e} > {t:.0e}" for w, e, t in measures if not e <= t]
    good = [(e / t if t else e, f"{w} = {e:.2e} <= {t:.0e}") for w, e, t in measures if e <= t]
    if len(measures) > 3 and good:
        worst = max(good)[1]
        good = [f"{len(good)} within, the closest: {worst}" if bad else
                f"{len(good)} measures within, the closest to its tolerance: {worst}"]
    else:
        good = [g for _, g in good]
    if bad:
        raise ContractFailure("; ".join(bad + good))
    return "; ".join(good)


def require(ok: bool, message: str) -> None:
    """ContractFailure(message) unless ``ok``."""
    if not ok:
        raise ContractFailure(message)


class Suite:
    """Runs a kind's checks in order, each a function returning its detail (or raising
    ContractFailure / Skip); any other exception fails the check with its text."""

    def __init__(self, items: tuple[str, ...]):
        self.items = items
        self.findings: list[Finding] = []

    def run(self, name: str, fn: Callable[..., str], *args) -> bool:
        assert name in self.items, name
        try:
            self.findings.append(Finding(name, True, fn(*args)))
            return True
        except Skip as exc:
            self.findings.append(Finding(name, True, str(exc), skipped=True))
            return True
        except ContractFailure as exc:
            self.findings.append(Finding(name, False, str(exc)))
        except Exception as exc:                       # the plugin broke: report, go on
            self.findings.append(Finding(name, False, f"raised {type(exc).__name__}: {exc}"))
        return False

    def build(self, cls):
        """The plugin built from ``cls.example_values()`` (the check "parameters"), or None
        when it could not be built."""
        built = []

        def make():
            obj, text = construct(cls)
            built.append(obj)
            return f"built from example_values(): {text}"

        return built[0] if self.run("parameters", make) else None

    def blocked(self, why: str) -> list[Finding]:
        """Fail every check not run yet, saying why (construction failed, say)."""
        done = {f.check for f in self.findings}
        self.findings += [Finding(n, False, f"not checked: {why}") for n in self.items
                          if n not in done]
        return self.findings

    def skip_rest(self, why: str) -> list[Finding]:
        """Skip every check not run yet, saying why (an optional package missing, say)."""
        done = {f.check for f in self.findings}
        self.findings += [Finding(n, True, why, skipped=True) for n in self.items if n not in done]
        return self.findings


def construct(cls) -> tuple[Any, str]:
    """``cls(**cls.example_values())`` and the values as text."""
    values = cls.example_values()
    return cls(**values), ", ".join(f"{k}={v}" for k, v in values.items()) or "(no parameters)"


def changed_keys(before: dict, after: dict) -> list[str]:
    """Keys of two states that differ (added, removed or another value)."""
    keys = set(before) ^ set(after)
    keys |= {k for k in set(before) & set(after)
             if not np.array_equal(np.asarray(before[k]), np.asarray(after[k]))}
    return sorted(keys)
