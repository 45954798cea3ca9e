"""``*CHECK``: what a deck is checked against, as plugins (entry-point group
``lagamine_py.checks``).

:mod:`.base` holds the contract (:class:`~.base.Check`) and :func:`~.base.evaluate_checks`;
:mod:`.closed_forms` the built-in checks (Hertz, Cattaneo-Mindlin, Coulomb, penalty penetration,
Ramberg-Osgood uniaxial, Lame, limit pressure).
"""
from __future__ import annotations

from .base import Check, CheckError, check_columns, evaluate_checks

__all__ = ["Check", "CheckError", "check_columns", "evaluate_checks"]
