"""Writers: the observers that turn converged increments into the files of the output contract.

:func:`default_writers` builds writers from their registry names (entry-point group
``lagamine_py.writers``): a third-party package adds a writer, or replaces a built-in one, by
name, and a deck chooses them with ``*OUTPUT, WRITERS=``.
"""
from __future__ import annotations

from pathlib import Path

from .. import registry
from .base import CellBlock, ContactPoints, FailedAttempt, IncrementResult, Writer

__all__ = ["CellBlock", "ContactPoints", "FailedAttempt", "IncrementResult", "Writer",
           "DEFAULT_WRITERS", "default_writers"]

#: the built-in writers every run gets unless ``*OUTPUT, WRITERS=`` says otherwise: VTK series,
#: contact tables, reactions, status/log, end-of-step displacements (for compare), tool forces
DEFAULT_WRITERS = ("VTK", "CONTACT", "REACTIONS", "STATUS", "DISPLACEMENTS", "TOOLS")


def default_writers(outdir: Path, model, names=DEFAULT_WRITERS, append: bool = False) -> list[Writer]:
    """Instances of the writers ``names`` (registry names, default the built-ins), for a run
    writing into ``outdir``; ``append=True`` resumes into an existing output directory."""
    return [registry.get("writers", name)(Path(outdir), model, append=append) for name in names]
