"""One registry for every plugin kind: elements, material laws, contact laws, writers, solvers.

A plugin is a class with a class attribute ``params``: a tuple of :class:`Param` declaring
the deck parameters it accepts.  Built-ins and third-party packages register the same way:
through the ``setup.cfg`` entry-point groups ``lagamine_py.<kind>`` (``elements``, ``laws``,
``contact_laws``, ``writers``, ``solvers``), or with the :func:`register` decorator.  When the
package runs from a source tree without being installed, the built-in modules are imported
directly so that the decorators fill the registry.
"""
from __future__ import annotations

import difflib
import importlib
import math
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any

KINDS = ("elements", "laws", "contact_laws", "writers", "solvers")

# Modules holding built-in plugins; imported when entry points are not installed.
_BUILTIN_MODULES = {
    "elements": ("lagamine_py.elements.solid",),
    "laws": ("lagamine_py.laws.elastic", "lagamine_py.laws.j2", "lagamine_py.laws.ramberg_osgood"),
    "contact_laws": ("lagamine_py.laws.coulomb",),
    "writers": ("lagamine_py.output.vtk", "lagamine_py.output.tables", "lagamine_py.output.status",
                "lagamine_py.output.nodal"),
    "solvers": ("lagamine_py.solver.linear",),
}


class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED = _Required()


class ParamError(ValueError):
    """A deck value does not fit a plugin's declared parameters (message names the parameter)."""


@dataclass(frozen=True)
class Param:
    """A declared plugin parameter.

    ``type`` is ``float``, ``int``, ``str`` or ``bool``; ``bounds`` is an inclusive
    ``(low, high)`` pair (``None`` for unbounded); ``choices`` restricts strings (and also
    lets a numeric parameter accept a keyword such as ``AUTO``).
    """

    name: str
    type: type = float
    default: Any = REQUIRED
    bounds: tuple = (None, None)
    unit: str = ""
    doc: str = ""
    choices: tuple = ()

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def convert(self, raw: Any) -> Any:
        """Convert a deck token (str) or a Python value, checking type, bounds and choices."""
        if isinstance(raw, str):
            text = raw.strip()
            if self.choices and text.upper() in self.choices:
                return text.upper()
            if self.type is str:
                if self.choices:
                    raise ParamError(f"{self.name} must be one of {', '.join(self.choices)}, got {text!r}")
                return text
            if self.type is bool:
                up = text.upper()
                if up in ("YES", "TRUE", "1", "ON"):
                    return True
                if up in ("NO", "FALSE", "0", "OFF"):
                    return False
                raise ParamError(f"{self.name} expects YES or NO, got {text!r}")
            try:
                value = float(text.replace("d", "e").replace("D", "E"))
            except ValueError:
                expected = "an integer" if self.type is int else "a number"
                extra = f" or one of {', '.join(self.choices)}" if self.choices else ""
                raise ParamError(f"{self.name} expects {expected}{extra}, got {text!r}") from None
        else:
            value = raw
            if self.type is str or self.type is bool:
                return value
        if not math.isfinite(float(value)):
            raise ParamError(f"{self.name} must be finite, got {value!r}")
        if self.type is int:
            if float(value) != int(value):
                raise ParamError(f"{self.name} expects an integer, got {value!r}")
            value = int(value)
        else:
            value = float(value)
        low, high = self.bounds
        if low is not None and value < low:
            raise ParamError(f"{self.name} = {value:g} is below its lower bound {low:g}")
        if high is not None and value > high:
            raise ParamError(f"{self.name} = {value:g} is above its upper bound {high:g}")
        return value

    def describe(self) -> str:
        default = "required" if self.required else f"default {self.default}"
        lo, hi = self.bounds
        rng = ""
        if lo is not None or hi is not None:
            rng = f", in [{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}]"
        unit = f" [{self.unit}]" if self.unit else ""
        choices = f", or {'/'.join(self.choices)}" if self.choices else ""
        return f"{self.name} ({self.type.__name__}{unit}, {default}{rng}{choices}): {self.doc}"


def did_you_mean(word: str, candidates) -> str:
    """' (did you mean X?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(word.upper(), [c.upper() for c in candidates], n=1, cutoff=0.5)
    return f" (did you mean {close[0]}?)" if close else ""


def validate_params(cls, given: dict[str, Any]) -> dict[str, Any]:
    """Check ``given`` (names case-insensitive) against ``cls.params``; return converted values.

    Raises ParamError listing unknown names (with a did-you-mean), missing required ones and
    bad values, all in one message.
    """
    declared = {p.name.upper(): p for p in getattr(cls, "params", ())}
    errors, out = [], {}
    for key, raw in given.items():
        p = declared.get(key.upper())
        if p is None:
            errors.append(f"unknown parameter {key.upper()}{did_you_mean(key, declared)}; "
                          f"expected one of {', '.join(declared) or '(none)'}")
            continue
        try:
            out[p.name] = p.convert(raw)
        except ParamError as exc:
            errors.append(str(exc))
    for name, p in declared.items():
        if p.name not in out and not any(k.upper() == name for k in given):
            if p.required:
                errors.append(f"missing required parameter {p.name}")
            else:
                out[p.name] = p.default
    if errors:
        raise ParamError("; ".join(errors))
    return out


@dataclass
class Entry:
    name: str
    cls: type
    origin: str


@dataclass
class Registry:
    tables: dict[str, dict[str, Entry]] = field(default_factory=lambda: {k: {} for k in KINDS})
    _loaded: bool = False

    def add(self, kind: str, name: str, cls: type, origin: str = "") -> None:
        if kind not in self.tables:
            raise ValueError(f"unknown plugin kind {kind!r}; kinds are {', '.join(KINDS)}")
        _check_plugin(kind, name, cls)
        key = name.upper()
        old = self.tables[kind].get(key)
        if old is not None and old.cls is not cls:
            raise ValueError(f"{kind} plugin {key} from {origin or cls.__module__} clashes with "
                             f"the one from {old.origin}")
        if old is None:
            self.tables[kind][key] = Entry(key, cls, origin or cls.__module__)

    def load(self) -> None:
        """Import entry points (once), then built-in modules not found through them."""
        if self._loaded:
            return
        self._loaded = True
        for kind in KINDS:
            for ep in metadata.entry_points(group=f"lagamine_py.{kind}"):
                try:
                    cls = ep.load()
                except Exception as exc:  # a broken third-party plugin must not stop the program
                    _broken.append(f"{kind} plugin {ep.name} ({ep.value}) failed to load: {exc}")
                    continue
                dist = getattr(ep, "dist", None)
                origin = f"{dist.name} {dist.version}" if dist is not None else ep.value
                self.add(kind, ep.name, cls, origin)
        for kind, modules in _BUILTIN_MODULES.items():
            for mod in modules:
                try:
                    importlib.import_module(mod)
                except ModuleNotFoundError as exc:
                    if exc.name != mod:
                        raise

    def get(self, kind: str, name: str) -> type:
        self.load()
        entry = self.tables[kind].get(name.upper())
        if entry is None:
            names = sorted(self.tables[kind])
            raise KeyError(f"unknown {kind[:-1].replace('_', ' ')} {name.upper()}"
                           f"{did_you_mean(name, names)}; installed: {', '.join(names) or '(none)'}")
        return entry.cls

    def names(self, kind: str) -> list[str]:
        self.load()
        return sorted(self.tables[kind])

    def entries(self, kind: str) -> list[Entry]:
        self.load()
        return [self.tables[kind][n] for n in sorted(self.tables[kind])]


_broken: list[str] = []
REGISTRY = Registry()


def _check_plugin(kind: str, name: str, cls: type) -> None:
    """Validate a plugin when it registers, so a mistake shows up at once and by name."""
    if not isinstance(cls, type):
        raise TypeError(f"{kind} plugin {name} must be a class, got {cls!r}")
    params = getattr(cls, "params", None)
    if params is None or not all(isinstance(p, Param) for p in params):
        raise TypeError(f"{kind} plugin {name} ({cls.__module__}.{cls.__qualname__}) must declare "
                        f"`params` as a tuple of lagamine_py.registry.Param")


def register(kind: str, name: str):
    """Class decorator: ``@register("laws", "ELASTIC")``."""
    def deco(cls):
        REGISTRY.add(kind, name, cls, f"lagamine_py ({cls.__module__})"
                     if cls.__module__.startswith("lagamine_py") else cls.__module__)
        return cls
    return deco


def get(kind: str, name: str) -> type:
    return REGISTRY.get(kind, name)


def broken_plugins() -> list[str]:
    REGISTRY.load()
    return list(_broken)
