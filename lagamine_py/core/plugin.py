"""What every plugin kind shares: declared parameters, a summary, a contract self-check.

Each kind's base class (element, material law, contact law, writer, linear solver, check)
derives from :class:`Plugin` and states the rest of its contract itself.
"""
from __future__ import annotations

from typing import Any

from .params import Param, validate_params

__all__ = ["Plugin", "Parametrized"]


class Plugin:
    """Base of every plugin class.

    ``params``: the parameters a deck may give, as :class:`~.params.Param` declarations (the
    deck builder validates what users write against them, ``lagamine-py plugins`` lists them).
    """

    params: tuple[Param, ...] = ()
    #: other names a deck may use for this plugin (Abaqus element names, say); the registry
    #: resolves them to the entry-point name
    aliases: tuple[str, ...] = ()

    @classmethod
    def contract_problem(cls) -> str:
        """What the class lacks to honour its kind's contract ("" when nothing): checked when
        the plugin registers, so that a mistake shows at once and by name."""
        return ""

    @classmethod
    def summary(cls) -> str:
        """The first line of the class docstring."""
        lines = (cls.__doc__ or "").strip().splitlines()
        return lines[0].strip() if lines else ""


class Parametrized(Plugin):
    """A plugin built from its parameter values: ``Cls(**values)`` validates them against
    ``params`` (raising :class:`~.params.ParamError` naming the parameter) and stores them as
    ``self.values`` (a dict, declared name -> value) and as lower-case attributes (``self.kp``,
    ``self.e`` ...).  A subclass
    checks the constraints between parameters in its ``__init__`` and raises ParamError: the
    deck builder constructs every law once, so ``check`` refuses what ``run`` would.

    :meth:`example_values` gives parameter values the class accepts: the contract checks
    (:mod:`lagamine_py.contracts`, ``lagamine-py plugins --check``) build the plugin from them.
    """

    def __init__(self, **values: Any):
        self.values = validate_params(type(self), values)
        for k, v in self.values.items():
            setattr(self, k.lower(), v)

    @classmethod
    def example_values(cls) -> dict[str, Any]:
        """Parameter values that build a typical instance: ``Cls(**Cls.example_values())``.

        The default derives them from the declarations (:meth:`~.params.Param.example`: the
        defaults, else the first choice, else a number inside the bounds) and leaves out what
        cannot be derived (a string without choices).  Override it when those values do not
        make a sensible instance -- constraints between parameters, a realistic scale (a yield
        stress well below Young's modulus) -- or when a required string has no choices."""
        out = {}
        for p in cls.params:
            value = p.example()
            if value is not None and not (p.flag and value is False):
                out[p.name] = value
        return out
