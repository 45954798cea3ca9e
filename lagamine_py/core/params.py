"""Declared parameters: one declaration for plugin parameters and keyword parameters alike.

A :class:`Param` says what a parameter accepts (type, default or required, bounds, choices, unit,
doc).  The same declaration validates what a deck gives (:func:`validate`), reports mistakes by
name with a did-you-mean, and writes the reference (``lagamine-py plugins``,
``docs/keywords.md``).  Numbers are read as Fortran writes them too (``1.5D3``):
:func:`parse_number` is the one reader of numbers in text.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Sequence

__all__ = ["Param", "REQUIRED", "ParamError", "validate", "validate_params", "did_you_mean",
           "parse_number", "INT_MAX"]

INT_MAX = 2**31 - 1          # ids and counts must fit the int arrays of the Model
_YES = ("YES", "TRUE", "ON", "1")
_NO = ("NO", "FALSE", "OFF", "0")


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED = _Required()


class ParamError(ValueError):
    """A value does not fit a declared parameter (the message names the parameter)."""


def parse_number(text: str) -> float:
    """A number as decks write it: ``1.5``, ``.5``, ``1.5e3``, ``1.5E+3``, Fortran's ``1.5D3``.

    Raises ValueError for anything else (``inf`` and ``nan`` are read; callers that need a
    finite value check it)."""
    return float(str(text).strip().replace("d", "e").replace("D", "E"))


def did_you_mean(word: str, candidates: Iterable) -> str:
    """' (did you mean X?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(str(word).upper(), [str(c).upper() for c in candidates],
                                      n=1, cutoff=0.5)
    return f" (did you mean {close[0]}?)" if close else ""


@dataclass(frozen=True)
class Param:
    """A declared parameter.

    ``type`` is ``float``, ``int``, ``str`` or ``bool``.  ``default`` is :data:`REQUIRED` for a
    required parameter (``None``: optional, absent unless given).  ``bounds`` is an inclusive
    ``(low, high)`` pair (``None``: unbounded), ``gt`` a strict lower bound (``gt=0.0``: > 0).
    ``type`` may also be ``tuple``: a table of numbers, rows of ``columns`` values (a law's
    hardening curve), given by a deck as the data lines of a keyword named like the parameter
    (``*PLASTIC`` after ``*MATERIAL``), never as ``KEY=VALUE``.
    ``choices`` restricts a string to those names, a number to those numbers, and lets a number
    accept a keyword such as ``AUTO``; it may be a callable returning the tuple, resolved when a
    value is checked (the registered solvers, say).  ``upper`` upper-cases a string (names are case-insensitive); ``flag``
    declares a parameter written without a value (``*NSET, NSET=A, GENERATE``).
    """

    name: str
    type: type = float
    default: Any = REQUIRED
    bounds: tuple = (None, None)
    unit: str = ""
    doc: str = ""
    choices: tuple | Callable[[], tuple] = ()
    gt: float | None = None
    upper: bool = False
    flag: bool = False
    columns: tuple[str, ...] = ()

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def allowed(self) -> tuple:
        """The choices (called when they are given as a function)."""
        return tuple(self.choices()) if callable(self.choices) else tuple(self.choices)

    def convert(self, raw: Any) -> Any:
        """The value of a deck token (str, None for a flag) or of a Python value, checked
        against type, bounds and choices; ParamError says what was expected."""
        if self.flag:
            if raw is not None and raw is not True:
                raise ParamError(f"{self.name} takes no value")
            return True
        if self.type is tuple:
            return self._table(raw)
        if raw is None or (isinstance(raw, str) and not raw.strip()):
            raise ParamError(f"{self.name} needs a value ({self.name}=...)")
        choices = self.allowed()
        if isinstance(raw, str):
            text = raw.strip()
            names = [c for c in choices if isinstance(c, str)]
            if names and text.upper() in (c.upper() for c in names):
                return text.upper()
            if self.type is str:
                if choices:
                    raise ParamError(f"{self.name} must be one of {', '.join(map(str, choices))}, "
                                     f"got {text!r}{did_you_mean(text, choices)}")
                return text.upper() if self.upper else text
            if self.type is bool:
                up = text.upper()
                if up in _YES:
                    return True
                if up in _NO:
                    return False
                raise ParamError(f"{self.name} must be YES or NO, got {text!r}")
            try:
                value = parse_number(text)
            except ValueError:
                expected = "an integer" if self.type is int else "a number"
                extra = f" or one of {', '.join(names)}" if names else ""
                raise ParamError(f"{self.name} must be {expected}{extra}, got {text!r}") from None
        else:
            value = raw
            if self.type is str:
                return value.upper() if self.upper and isinstance(value, str) else value
            if self.type is bool:
                return bool(value)
        if not math.isfinite(float(value)):
            raise ParamError(f"{self.name} must be finite, got {value!r}")
        if self.type is int:
            if float(value) != int(value):
                raise ParamError(f"{self.name} must be an integer, got {raw!r}")
            if abs(value) > INT_MAX:
                raise ParamError(f"{self.name} must be below 2^31, got {raw!r}")
            value = int(value)
        else:
            value = float(value)
        numeric = tuple(c for c in choices if isinstance(c, (int, float)))
        if numeric and value not in numeric:
            raise ParamError(f"{self.name} must be one of {', '.join(map(str, numeric))}, "
                             f"got {raw!r}")
        low, high = self.bounds
        if self.gt is not None and not value > self.gt:
            raise ParamError(f"{self.name} must be > {self.gt:g}, got {value:g}")
        if low is not None and value < low:
            raise ParamError(f"{self.name} = {value:g} is below its lower bound {low:g}")
        if high is not None and value > high:
            raise ParamError(f"{self.name} = {value:g} is above its upper bound {high:g}")
        return value

    def example(self) -> Any:
        """A valid value derived from the declaration alone (the contract checks build plugins
        from these, see :meth:`~lagamine_py.core.plugin.Parametrized.example_values`): the
        default when there is one, else the first choice, else a number inside the bounds
        (their midpoint when both are given, one unit -- or the bound's magnitude -- inside a
        single bound, 1 when unbounded).  None for an optional parameter without a default and
        for a string without choices or a table: nothing valid can be told from the declaration."""
        if self.flag:
            return False
        if not self.required:
            return self.default
        choices = self.allowed()
        if choices:
            return choices[0]
        if self.type is bool:
            return False
        if self.type in (str, tuple):      # a table's valid rows depend on the plugin
            return None
        low, high = self.bounds
        if self.gt is not None:
            low = self.gt if low is None else max(low, self.gt)
        if low is not None and high is not None:
            value = 0.5 * (low + high)
        elif low is not None:
            value = low + max(1.0, abs(low))
        elif high is not None:
            value = high - max(1.0, abs(high))
        else:
            value = 1.0
        if self.type is int:
            value = round(value)
            if self.gt is not None and value <= self.gt:
                value = math.floor(self.gt) + 1
        return self.type(value)

    def _table(self, raw: Any) -> tuple[tuple[float, ...], ...]:
        """A table value: rows of ``len(columns)`` finite numbers, at least one."""
        if isinstance(raw, str):
            raise ParamError(f"{self.name} is a table ({', '.join(self.columns)} rows): give it as the "
                             f"data lines of a *{self.name} block, not as {self.name}=")
        try:
            rows = tuple(tuple(float(v) for v in row) for row in raw)
        except (TypeError, ValueError):
            raise ParamError(f"{self.name} must be rows of numbers ({', '.join(self.columns)})") from None
        if not rows or any(len(r) != len(self.columns) for r in rows):
            raise ParamError(f"{self.name} must be at least one row of {len(self.columns)} numbers "
                             f"({', '.join(self.columns)})")
        if not all(math.isfinite(v) for r in rows for v in r):
            raise ParamError(f"{self.name} must hold finite numbers")
        return rows

    def describe(self) -> str:
        """One line for ``lagamine-py plugins``: name, type, unit, default, range, doc."""
        if self.flag:
            return f"{self.name} (flag): {self.doc}"
        if self.type is tuple:
            return (f"{self.name} (table of rows: {', '.join(self.columns)}; "
                    f"{'required' if self.required else 'optional'}, a *{self.name} block): {self.doc}")
        default = "required" if self.required else f"default {self.default}"
        lo, hi = self.bounds
        rng = ""
        if self.gt is not None:
            rng = f", > {self.gt:g}"
        if lo is not None or hi is not None:
            rng += f", in [{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
        unit = f" [{self.unit}]" if self.unit else ""
        choices = self.allowed()
        extra = f", or {'/'.join(map(str, choices))}" if choices else ""
        return f"{self.name} ({self.type.__name__}{unit}, {default}{rng}{extra}): {self.doc}"


def validate(params: Sequence[Param], given: dict[str, Any]) -> tuple[dict[str, Any], list[tuple[str, str]]]:
    """Check ``given`` (names case-insensitive) against ``params``.

    Returns the converted values (declared name -> value; defaults filled in, optional
    parameters without a default left out) and the problems as ``(name, message)`` pairs:
    unknown names with a did-you-mean, missing required ones, bad values.  Nothing raises."""
    declared = {p.name.upper(): p for p in params}
    errors: list[tuple[str, str]] = []
    out: dict[str, Any] = {}
    for key, raw in given.items():
        p = declared.get(str(key).upper())
        if p is None:
            expected = f"expected one of {', '.join(declared)}" if declared else "it takes none"
            errors.append((str(key).upper(), f"unknown parameter {str(key).upper()}"
                                             f"{did_you_mean(key, declared)}; {expected}"))
            continue
        try:
            out[p.name] = p.convert(raw)
        except ParamError as exc:
            errors.append((p.name, str(exc)))
    given_upper = {str(k).upper() for k in given}
    for name, p in declared.items():
        if name in given_upper:
            continue
        if p.required:
            errors.append((p.name, f"missing required parameter {p.name}"))
        elif not p.flag and p.default is not None:
            out[p.name] = p.default
    return out, errors


def validate_params(cls, given: dict[str, Any]) -> dict[str, Any]:
    """:func:`validate` against ``cls.params``; raises one ParamError holding every problem
    ('; '-joined).  A value None stands for a parameter not given (Python callers); optional
    parameters without a default come out as None."""
    out, errors = validate(cls.params, {k: v for k, v in given.items() if v is not None})
    if errors:
        raise ParamError("; ".join(msg for _, msg in errors))
    for p in cls.params:
        out.setdefault(p.name, None if not p.flag else False)
    return out
