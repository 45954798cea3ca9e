"""Writers: the observers that turn converged increments into the files of the output contract.

:func:`default_writers` builds the writers every run gets; each is looked up in the plugin
registry (``lagamine_py.writers``), so a third-party package may replace one by name.
"""
from __future__ import annotations

from pathlib import Path

from .base import ContactPoints, IncrementResult, Writer

__all__ = ["ContactPoints", "IncrementResult", "Writer", "DEFAULT_WRITERS", "default_writers"]

# VTK series, contact tables, reactions, status/log, end-of-step displacements (for compare)
DEFAULT_WRITERS = ("VTK", "CONTACT", "REACTIONS", "STATUS", "DISPLACEMENTS")


def default_writers(outdir: Path, model, names: tuple[str, ...] = DEFAULT_WRITERS, **options) -> list[Writer]:
    """Instances of the writers ``names`` (registry names) for a run writing into ``outdir``.

    ``options`` go to every writer; ``append=True`` resumes into an existing output directory
    (``lagamine-py run --restart``): the built-in writers keep what is there and drop what the
    interrupted run wrote at or after the first resumed increment.
    """
    from ..registry import get

    return [get("writers", name)(Path(outdir), model, **options) for name in names]
