"""Element groups: the element plugins (:mod:`.base` holds the contract; :mod:`.quad` and
:mod:`.t6` the built-in shapes and types; :mod:`.solid` the isoparametric continuum element),
the contact element (:mod:`.contact`), pressure loads on faces (:mod:`.edges`) and structured
meshes (:mod:`.structured`)."""
from __future__ import annotations

from .. import registry

__all__ = ["outline_of_cell"]


def outline_of_cell(vtk_cell: int) -> tuple[int, ...]:
    """The boundary outline (local node order) of a VTK cell type, from a registered element
    class of that type; KeyError when no element writes such cells."""
    for entry in registry.REGISTRY.entries("elements"):
        if entry.cls.vtk_cell == vtk_cell:
            return tuple(entry.cls.outline)
    raise KeyError(f"no registered element writes VTK cells of type {vtk_cell}")
