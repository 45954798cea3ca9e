"""One registry for every plugin kind, keyed by the name a deck uses.

Kinds, their entry-point groups and the base class that holds each kind's whole contract:

==============  ==============================  ===============================================
kind            entry-point group               base class (contract)
==============  ==============================  ===============================================
elements        ``lagamine_py.elements``        :class:`lagamine_py.elements.base.Element`
laws            ``lagamine_py.laws``            :class:`lagamine_py.laws.base.MaterialLaw`
contact_laws    ``lagamine_py.contact_laws``    :class:`lagamine_py.laws.base.ContactLaw`
writers         ``lagamine_py.writers``         :class:`lagamine_py.output.base.Writer`
solvers         ``lagamine_py.solvers``         :class:`lagamine_py.solver.linear.LinearSolver`
checks          ``lagamine_py.checks``          :class:`lagamine_py.checks.base.Check`
==============  ==============================  ===============================================

The built-ins register exactly as a third-party package does: through entry points in
``setup.cfg`` (the package must be installed, ``pip install -e .`` for a source tree), or with
the :func:`register` decorator.  A plugin is checked when it registers (a subclass of its kind's
base class, declaring ``params``) and the registry remembers which distribution supplied it.

Names: a third-party plugin may *replace* a built-in of the same name (say a VTK writer of your
own); ``lagamine-py plugins`` says so.  Two third-party plugins with one name clash: the first
found is kept and the clash is reported (:func:`broken_plugins`), as is a plugin that fails to
load; neither stops the program.
"""
from __future__ import annotations

import importlib
import os
import re
import sys
from dataclasses import dataclass, field

from .core.params import Param, ParamError, did_you_mean, validate_params  # noqa: F401 (re-exported)

__all__ = ["KINDS", "BASES", "Registry", "Entry", "REGISTRY", "register", "get", "names", "canonical",
           "broken_plugins", "Param", "ParamError", "validate_params", "did_you_mean"]

#: plugin kind -> the base class holding its contract ("module:Class", imported when needed:
#: the registry sits below every plugin layer)
BASES = {
    "elements": "lagamine_py.elements.base:Element",
    "laws": "lagamine_py.laws.base:MaterialLaw",
    "contact_laws": "lagamine_py.laws.base:ContactLaw",
    "writers": "lagamine_py.output.base:Writer",
    "solvers": "lagamine_py.solver.linear:LinearSolver",
    "checks": "lagamine_py.checks.base:Check",
}
KINDS = tuple(BASES)
BUILTIN = "lagamine_py"        # the distribution name of the built-ins


@dataclass(frozen=True)
class EntryPoint:
    """One entry point of an installed distribution, as ``importlib.metadata`` gives it (name,
    value ``module:attr [extras]``, group) and the distribution's metadata directory, or its
    ``"<name> <version>"`` when already known."""
    name: str
    value: str
    group: str
    dist_dir: str = ""
    origin: str = ""

    def load(self):
        """The object the value names (``module:attr.sub``), the module imported."""
        module, _, attrs = self.value.split("[")[0].strip().partition(":")
        obj = importlib.import_module(module.strip())
        for attr in filter(None, attrs.strip().split(".")):
            obj = getattr(obj, attr)
        return obj


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def scan_entry_points(prefix: str = "lagamine_py.", path: list[str] | None = None) -> list[EntryPoint]:
    """The entry points of the groups starting with ``prefix`` of the distributions installed
    in the directories of ``path`` (default ``sys.path``), the first distribution of a name
    winning, as ``importlib.metadata.entry_points()`` finds them (``tests/test_registry_scan.py``
    compares the two).  Read here: ``importlib.metadata`` imports ``email``, ``csv`` and
    ``zipfile`` (11 ms) and parses more than the groups asked (together ~15 ms of the main
    job's 0.7 s).  None when a ``path`` entry is not a directory (a zipped egg): the caller
    then asks ``importlib.metadata``."""
    seen, found = set(), []
    for entry in (sys.path if path is None else path):
        root = entry or "."
        if os.path.isfile(root):
            return None
        try:
            names = sorted(os.listdir(root))
        except OSError:                 # a missing sys.path directory, as importlib skips it
            continue
        for d in names:
            stem, ext = os.path.splitext(d)
            if ext not in (".dist-info", ".egg-info"):
                continue
            key = _normalized(stem.split("-")[0])
            if key in seen:
                continue
            seen.add(key)
            try:
                with open(os.path.join(root, d, "entry_points.txt"), encoding="utf-8") as fh:
                    text = fh.read()
            except OSError:             # no entry points, or a lone PKG-INFO file
                continue
            group = ""
            for line in text.splitlines():
                line = line.strip()
                if not line or line[0] in "#;":
                    continue
                if line.startswith("[") and line.endswith("]"):
                    group = line[1:-1].strip()
                elif group.startswith(prefix) and "=" in line:
                    name, _, value = line.partition("=")
                    found.append(EntryPoint(name.strip(), value.strip(), group,
                                            os.path.join(root, d)))
    return found


def installed_entry_points(path: list[str] | None = None) -> list[EntryPoint]:
    """The entry points of the ``lagamine_py.*`` groups installed on ``path`` (default
    ``sys.path``): :func:`scan_entry_points`, or ``importlib.metadata``'s for every plugin
    kind when a zipped distribution is on the path (``origin`` then given, ``path`` not
    applied).  Shared by :class:`Registry` and the sweep's program digest."""
    every = scan_entry_points(path=path)
    if every is None:
        from importlib import metadata
        every = [EntryPoint(ep.name, ep.value, ep.group,
                            origin=f"{ep.dist.name} {ep.dist.version}" if ep.dist else "")
                 for k in KINDS for ep in metadata.entry_points(group=f"lagamine_py.{k}")]
    return every


def dist_origin(dist_dir: str) -> str:
    """``"<name> <version>"`` from a distribution's METADATA (or PKG-INFO) headers."""
    fields = {}
    for fname in ("METADATA", "PKG-INFO"):
        try:
            with open(os.path.join(dist_dir, fname), encoding="utf-8") as fh:
                for line in fh:
                    if not line.strip():
                        break
                    key, _, value = line.partition(":")
                    if key in ("Name", "Version"):
                        fields.setdefault(key, value.strip())
            break
        except OSError:
            continue
    return f"{fields.get('Name', os.path.basename(dist_dir))} {fields.get('Version', '')}".strip()


def base_class(kind: str) -> type:
    """The base class of plugin kind ``kind``."""
    module, _, name = BASES[kind].partition(":")
    return getattr(importlib.import_module(module), name)


@dataclass
class Entry:
    name: str
    cls: type
    origin: str                  # "<distribution> <version>" or the module
    replaces: str = ""           # origin of the built-in it replaces, if any
    alias_of: str = ""           # the plugin's own name, when this entry is one of its aliases

    @property
    def builtin(self) -> bool:
        return self.origin.split()[0].replace("-", "_").lower() == BUILTIN


@dataclass
class Registry:
    """The plugins by kind and name.  Entry points are imported lazily, one name at a time where
    the name is an entry point's, every plugin of a kind when a listing (or an alias) needs
    them: loading a deck imports the plugins it names, not every installed one."""

    tables: dict[str, dict[str, Entry]] = field(default_factory=lambda: {k: {} for k in KINDS})
    problems: list[str] = field(default_factory=list)
    _eps: dict[str, list] = field(default_factory=dict)     # kind -> entry points (not imported)
    _imported: set = field(default_factory=set)              # (kind, name, value) imported
    _origins: dict = field(default_factory=dict)             # distribution -> "name version"

    def add(self, kind: str, name: str, cls: type, origin: str = "") -> None:
        """Register ``cls`` as plugin ``name`` of ``kind``; raises TypeError or ValueError on a
        bad plugin or a clash between two non-built-in plugins."""
        if kind not in self.tables:
            raise ValueError(f"unknown plugin kind {kind!r}; kinds are {', '.join(KINDS)}")
        _check_plugin(kind, name, cls)
        origin = origin or cls.__module__
        self._put(kind, Entry(name.upper(), cls, origin))
        for alias in cls.aliases:
            self._put(kind, Entry(alias.upper(), cls, origin, alias_of=name.upper()))

    def _put(self, kind: str, entry: Entry) -> None:
        key, cls, origin = entry.name, entry.cls, entry.origin
        old = self.tables[kind].get(key)
        if old is None or old.cls is cls:
            self.tables[kind].setdefault(key, entry)
        elif old.builtin and not entry.builtin:
            entry.replaces = old.origin
            self.tables[kind][key] = entry
        elif entry.builtin and not old.builtin:
            old.replaces = origin
        else:
            raise ValueError(f"{kind} plugin {key} from {origin} clashes with the one from "
                             f"{old.origin}")

    def entry_points(self, kind: str) -> list:
        """The entry points of ``kind`` (read from the installed distributions once)."""
        if not self._eps:
            every = installed_entry_points()      # one scan of the distributions, every kind
            self._eps.update({k: [ep for ep in every if ep.group == f"lagamine_py.{k}"]
                              for k in KINDS})
        return self._eps[kind]

    def _origin(self, ep) -> str:
        """"<distribution> <version>" of an entry point, read once per distribution (the
        built-ins are ~20 entry points of one distribution)."""
        if ep.origin or not ep.dist_dir:
            return ep.origin or ep.value
        if ep.dist_dir not in self._origins:
            self._origins[ep.dist_dir] = dist_origin(ep.dist_dir)
        return self._origins[ep.dist_dir]

    def load(self, kind: str | None = None, name: str | None = None) -> None:
        """Import the entry points of ``kind`` (every kind when None; those called ``name``
        only, when given), each once.  A plugin that fails to import or to register is recorded
        in :attr:`problems`: a broken third-party plugin must not stop the program."""
        for k in (KINDS if kind is None else (kind,)):
            for ep in self.entry_points(k):
                if name is not None and ep.name.upper() != name.upper():
                    continue
                key = (k, ep.name, ep.value)
                if key in self._imported:
                    continue
                self._imported.add(key)
                origin = self._origin(ep)
                try:
                    self.add(k, ep.name, ep.load(), origin)
                except Exception as exc:
                    self.problems.append(f"{k} plugin {ep.name} ({ep.value}, {origin}) "
                                         f"is not usable: {exc}")

    def get(self, kind: str, name: str) -> type:
        """The class registered as ``name`` (case-insensitive); KeyError with a did-you-mean."""
        key = str(name).upper()
        self.load(kind, key)
        if key not in self.tables[kind]:
            self.load(kind)                  # an alias, or unknown: every plugin of the kind
        entry = self.tables[kind].get(key)
        if entry is None:
            broken = [p for p in self.problems if p.startswith(f"{kind} plugin {key} ")]
            if broken:
                raise KeyError(broken[0])
            known = sorted(self.tables[kind])
            raise KeyError(f"unknown {_singular(kind)} {key}"
                           f"{did_you_mean(name, known)}; installed: {', '.join(known) or '(none)'}")
        return entry.cls

    def names(self, kind: str) -> list[str]:
        """Every name a deck may use, aliases included (imports every plugin of the kind)."""
        self.load(kind)
        return sorted(self.tables[kind])

    def canonical(self, kind: str, name: str) -> str:
        """The plugin's own name for ``name`` (an alias resolved), without importing it when the
        name is an entry point's own; KeyError as :meth:`get`."""
        key = str(name).upper()
        if key not in self.tables[kind] and any(ep.name.upper() == key
                                                for ep in self.entry_points(kind)):
            return key
        self.get(kind, key)
        entry = self.tables[kind][key]
        return entry.alias_of or entry.name

    def entries(self, kind: str) -> list[Entry]:
        """The plugins of ``kind``, one entry each (aliases left out), by name."""
        self.load(kind)
        return [e for n, e in sorted(self.tables[kind].items()) if not e.alias_of]


def _singular(kind: str) -> str:
    return {"laws": "material law", "contact_laws": "contact law"}.get(kind, kind[:-1])


REGISTRY = Registry()


def _check_plugin(kind: str, name: str, cls: type) -> None:
    """Validate a plugin when it registers, so that a mistake shows at once and by name."""
    where = f"{kind} plugin {name} ({getattr(cls, '__module__', '?')}." \
            f"{getattr(cls, '__qualname__', repr(cls))})"
    if not isinstance(cls, type):
        raise TypeError(f"{kind} plugin {name} must be a class, got {cls!r}")
    base = base_class(kind)
    if not issubclass(cls, base):
        raise TypeError(f"{where} must derive from {base.__module__}.{base.__qualname__}")
    params = cls.params
    if not isinstance(params, tuple) or not all(isinstance(p, Param) for p in params):
        raise TypeError(f"{where} must declare `params` as a tuple of lagamine_py.Param")
    problem = cls.contract_problem()
    if problem:
        raise TypeError(f"{where}: {problem}")


def register(kind: str, name: str):
    """Class decorator registering a plugin: ``@register("laws", "ELASTIC")``.  Packages
    should rather declare an entry point (the registry then knows the distribution)."""
    def deco(cls):
        module = cls.__module__
        REGISTRY.add(kind, name, cls, BUILTIN if module.startswith("lagamine_py.") else module)
        return cls
    return deco


def get(kind: str, name: str) -> type:
    return REGISTRY.get(kind, name)


def names(kind: str) -> list[str]:
    return REGISTRY.names(kind)


def canonical(kind: str, name: str) -> str:
    return REGISTRY.canonical(kind, name)


def broken_plugins() -> list[str]:
    """Plugins that could not be registered (failed to load, bad contract, name clash)."""
    REGISTRY.load()
    return list(REGISTRY.problems)
