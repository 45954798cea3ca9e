"""The fast twins: numba kernels of the hot loops, in one place, and the one rule that picks them.

Each kernel does, point by point, exactly what a NumPy reference does array by array (same
formulas in the same order, same branches), without the fixed cost of ~100 small array
operations per call:

* :mod:`.solid`   -- a solid element group computed and scattered into the CSR data (the laws
  ELASTIC, J2_LINEAR, RAMBERG_OSGOOD; reference: ``SolidElement.compute`` and the law's
  ``update``);
* :mod:`.contact` -- the foundation projection (reference: ``Foundation.project``) and a whole
  contact group with the COULOMB law (reference: ``ContactGroup.compute`` and
  ``Coulomb.update``).

Kernels are pure functions of arrays: they import nothing of the layers above (laws and
elements hand them their parameters as vectors, :mod:`.layout` says how), and numba only when
one is first used (``import numba`` and the cached machine code take a few tenths of a second, a
first compile about ten seconds).  numba is optional (``pip install lagamine_py[fast]``); without
it everything runs on the NumPy references.

:func:`use_numba` is the one rule that chooses: ``*CONTROLS KERNEL=NUMPY`` never, ``NUMBA``
always, ``AUTO`` the solid kernel from :data:`AUTO_NUMBA_ELEMENTS` solid elements (below that,
loading numba costs more than it saves, and the small decks keep the NumPy reference's
round-off) and the contact kernel never (:data:`AUTO_CONTACT`).  A group then uses
its kernel where it has one (a law or foundation the kernel reproduces).

:data:`calls` counts the calls of each kernel: tests use it to prove that a fast path ran.

Compiled kernels are cached on disk by numba (``cache=True``): next to this package when its
directory is writable, else in numba's per-user cache (``~/.cache/numba``), or wherever
``NUMBA_CACHE_DIR`` says.  A first compile of the solid kernel costs about 10 s of CPU -- more
than a whole warm 80x40 press-then-slide run -- so ``lagamine-py compile`` does it once, right
after the install (README, "Install"); :func:`cache_report` says where the machine code lives
and whether a run loaded or compiled it.
"""
from __future__ import annotations

import logging
from collections import Counter
from importlib import import_module
from pathlib import Path
from types import ModuleType

__all__ = ["SETTINGS", "AUTO_NUMBA_ELEMENTS", "AUTO_CONTACT", "available", "module", "use_numba", "calls",
           "ENTRY_KERNELS", "cache_report"]

SETTINGS = ("AUTO", "NUMPY", "NUMBA")
#: KERNEL=AUTO uses numba from this many solid elements in the model.  Below it the kernels save
#: less than they cost to load (numba import and cached machine code 0.4 s, a first compile 9 s),
#: and the small decks keep the NumPy reference's round-off: press_slide's contact decisions turn
#: on 1e-14 (19 increments and a cut-back instead of 16 with numba).
AUTO_NUMBA_ELEMENTS = 2_000
#: whether KERNEL=AUTO uses the contact kernel too.  It does not: its first compile is about
#: half of a fresh install's compile time (11 of 22 s) and it saves 1-2 ms per Newton iteration
#: (a contact Gauss point costs 1.2 us in NumPy, 0.25 us in numba; press-slide has 480 of them
#: at 160x80), so it pays for its compile after thousands of iterations, never in one run.
AUTO_CONTACT = False
#: kernel name -> number of calls (incremented by the kernel modules' entry points)
calls: Counter = Counter()

_MODULES = ("solid", "contact")
#: kernel module -> its compiled entry functions (the ones a run calls; their callees are
#: compiled with them)
ENTRY_KERNELS = {"solid": ("_solid_kernel", "_start_kernel"),
                 "contact": ("_contact", "_faces", "_project")}
_loaded: dict[str, ModuleType | None] = {}


def module(name: str) -> ModuleType | None:
    """The numba kernel module ``name`` (``solid`` or ``contact``), or None when numba does not
    import.  Imported once, on first use."""
    if name not in _MODULES:
        raise KeyError(f"no kernel module {name!r}; kernels are {', '.join(_MODULES)}")
    if name not in _loaded:
        try:
            _loaded[name] = import_module(f"{__name__}.{name}")
        except ImportError:
            _loaded[name] = None
        else:
            _say_if_cold(name, _loaded[name])
    return _loaded[name]


def _say_if_cold(name: str, mod: ModuleType) -> None:
    """Tell (advice log, once per module) that numba is about to compile ``name``'s kernels:
    its cache holds no index for an entry function, as after a fresh install."""
    for fn in ENTRY_KERNELS[name]:
        cache = Path(vars(mod)[fn].stats.cache_path)
        if not any(cache.glob(f"{name}.{fn}-*.nbi")):
            logging.getLogger("lagamine_py.advice").warning(
                f"numba compiles the {name} kernel for this machine first (about 10 s, once; "
                f"`lagamine-py compile{' --contact' if name == 'contact' else ''}` does it "
                f"ahead, right after the install)")
            return


def available() -> bool:
    """True when numba is installed and the kernels import."""
    return module("solid") is not None


def use_numba(setting: str, solid_elements: int, kind: str = "solid") -> bool:
    """Whether the kernel setting asks for the numba kernel of ``kind`` (``solid`` or
    ``contact`` groups) on a model of ``solid_elements``.  ``AUTO`` never picks the contact
    kernel (:data:`AUTO_CONTACT`).

    Raises KeyError for an unknown setting, or for ``NUMBA`` without numba installed."""
    setting = str(setting).upper()
    if setting not in SETTINGS:
        raise KeyError(f"KERNEL={setting}: expected one of {', '.join(SETTINGS)}")
    if setting == "NUMPY":
        return False
    if setting == "NUMBA":
        if not available():
            raise KeyError("KERNEL=NUMBA needs the optional package numba "
                           "(pip install 'lagamine_py[fast]')")
        return True
    if kind == "contact" and not AUTO_CONTACT:
        return False
    return solid_elements >= AUTO_NUMBA_ELEMENTS and available()


def cache_report(name: str) -> dict[str, dict]:
    """For each entry function of kernel module ``name`` that this process has used: numba's
    cache directory, and the signatures loaded from it (``hits``) and compiled (``misses``:
    compiled because the cache had no machine code for them, or could not be written).
    Empty without numba."""
    mod = module(name)
    if mod is None:
        return {}
    out = {}
    for fn in ENTRY_KERNELS[name]:
        stats = vars(mod)[fn].stats
        if stats.cache_hits or stats.cache_misses:
            out[fn] = {"cache": stats.cache_path, "hits": sum(stats.cache_hits.values()),
                       "misses": sum(stats.cache_misses.values())}
    return out
