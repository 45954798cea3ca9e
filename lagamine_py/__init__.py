"""lagamine_py: 2D and axisymmetric large-strain finite elements with the frictional contact
model of Godinas, Charlier & Cescotto, driven by keyword ``.dat`` decks.

The public API -- what plugin authors and scripting users need -- is re-exported here and listed
in ``__all__``; each name is imported on first use (``import lagamine_py`` itself imports
nothing heavy)::

    import lagamine_py as lp

    model = lp.load_deck("decks/press_slide.dat")
    outcome = lp.run(model, "out/press_slide")
    totals = lp.read_table("out/press_slide/contact_totals.csv")

Plugin bases (each holds its kind's whole contract): :class:`Element` (with the reference
shapes :class:`Quad4`, :class:`Quad8`, :class:`Tri6` and the isoparametric
:class:`SolidElement`), :class:`MaterialLaw`, :class:`ContactLaw`, :class:`Writer`,
:class:`LinearSolver`, :class:`Check`; declared parameters :class:`Param`; :func:`register` for a
plugin defined in a script (packages declare entry points, see ``docs/plugins.md``).
"""
from __future__ import annotations

from importlib import import_module

__version__ = "0.1.0"

#: public name -> the module that defines it
_EXPORTS = {
    # plugin contracts and their building blocks
    "Param": "lagamine_py.core.params", "ParamError": "lagamine_py.core.params",
    "REQUIRED": "lagamine_py.core.params",
    "register": "lagamine_py.registry", "get_plugin": "lagamine_py.registry",
    "plugin_names": "lagamine_py.registry",
    "Element": "lagamine_py.elements.base", "SolidElement": "lagamine_py.elements.solid",
    "Quad4": "lagamine_py.elements.quad", "Quad8": "lagamine_py.elements.quad",
    "Tri6": "lagamine_py.elements.t6",
    "StepContext": "lagamine_py.elements.base", "GroupResult": "lagamine_py.elements.base",
    "CellBlock": "lagamine_py.elements.base", "ContactPoints": "lagamine_py.elements.base",
    "MaterialLaw": "lagamine_py.laws.base", "ContactLaw": "lagamine_py.laws.base",
    "Writer": "lagamine_py.output.base", "IncrementResult": "lagamine_py.output.base",
    "FailedAttempt": "lagamine_py.output.base",
    "LinearSolver": "lagamine_py.solver.linear",
    "Check": "lagamine_py.checks.base", "CheckError": "lagamine_py.checks.base",
    "CutbackRequest": "lagamine_py.core.errors",
    "ReturnMappingError": "lagamine_py.core.errors",
    "SingularMatrixError": "lagamine_py.core.errors",
    "OPEN": "lagamine_py.core.status", "STICK": "lagamine_py.core.status",
    "SLIP": "lagamine_py.core.status", "NONE": "lagamine_py.core.status",
    "STATUS_NAMES": "lagamine_py.core.status",
    # running decks and reading results
    "load_deck": "lagamine_py.deck", "DeckError": "lagamine_py.deck", "Model": "lagamine_py.model",
    "run": "lagamine_py.solver.steps", "Outcome": "lagamine_py.solver.steps",
    "default_writers": "lagamine_py.output",
    "RunResults": "lagamine_py.results", "read_table": "lagamine_py.results",
    "read_vtu": "lagamine_py.results",
    "evaluate_checks": "lagamine_py.checks.base", "compare_dirs": "lagamine_py.compare",
    # single-point drivers of laws (no mesh)
    "drive_material_point": "lagamine_py.laws.material_point",
    "uniaxial_stress": "lagamine_py.laws.material_point",
    "plane_strain_uniaxial": "lagamine_py.laws.material_point",
    "drive_contact_point": "lagamine_py.laws.contact_point",
}
_RENAMED = {"get_plugin": "get", "plugin_names": "names"}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'lagamine_py' has no attribute {name!r}")
    value = getattr(import_module(module), _RENAMED.get(name, name))
    globals()[name] = value                     # the next access is a plain attribute
    return value


def __dir__():
    return sorted(__all__)
