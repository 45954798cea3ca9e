"""Interfaces of material laws and contact laws.

Array axes are named by letters, the same in docstrings and ``einsum`` strings:
``e`` element, ``q`` Gauss point, ``a``/``b`` element node, ``i``/``j``/``k``/``l`` spatial
component, ``s``/``t`` stress/strain component in the 4-vector convention below, ``g`` contact
Gauss point (flattened over contact elements x Gauss points).

Strain/stress 4-vectors (plane strain and axisymmetry alike)::

    strain = [e11, e22, e33, g12]   (g12 = 2 e12, engineering shear; 3 = out-of-plane / hoop)
    stress = [s11, s22, s33, s12]

A material law is a *pure batched function* of the committed state and a trial elastic
strain: it never keeps per-point data on ``self``.  The element computes the trial elastic
strain from its kinematics (small strain: ``eps - eps_p``; NLGEOM: Hencky ``1/2 ln b_e_trial``)
and the law does the return mapping in that strain space; for NLGEOM the stress it returns is
the Kirchhoff stress.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..registry import Param, validate_params


class ReturnMappingError(ArithmeticError):
    """A law could not integrate an increment (the step controller cuts back)."""


class ParametrizedLaw:
    """What every law plugin shares: declared ``params``, validated at construction and stored
    as ``self.p`` (a dict) and as lower-case attributes (``self.kp``, ``self.e`` ...)."""

    params: tuple[Param, ...] = ()
    doc: str = ""

    def __init__(self, **values: Any):
        self.p = validate_params(type(self), values)
        for k, v in self.p.items():
            setattr(self, k.lower(), v)


class MaterialLaw(ParametrizedLaw):
    """Base of material plugins (``lagamine_py.laws`` entry-point group).

    Subclasses declare ``params`` and implement :meth:`init_state` and :meth:`update`.
    Constructed as ``Law(**validated_params)``; the values are on ``self.p`` (a dict) too.
    """


    def init_state(self, shape: tuple[int, ...]) -> dict[str, np.ndarray]:
        """Committed state at t = 0 for points of ``shape`` (e.g. ``(e, q)``).

        Must hold at least ``eps_e`` (shape + (4,)) and ``peeq`` (shape)."""
        return {"eps_e": np.zeros(shape + (4,)), "peeq": np.zeros(shape)}

    def update(self, eps_e_trial: np.ndarray, state: dict[str, np.ndarray]):
        """Return mapping.

        Parameters: ``eps_e_trial`` (..., 4); ``state`` the committed state (not modified).

        Returns ``(stress, D, new_state, ok)``: ``stress`` (..., 4); ``D`` (..., 4, 4)
        = d stress / d eps_e_trial (algorithmic tangent, engineering-shear columns);
        ``new_state`` a dict like ``init_state`` with ``eps_e`` the elastic strain after the
        return; ``ok`` (...) bool, False where the return mapping failed.
        """
        raise NotImplementedError

    def elastic_moduli(self) -> tuple[float, float]:
        """(E, nu), used for penalty advice and stabilisation-free checks."""
        return float(self.p["E"]), float(self.p["NU"])


# Status codes of contact points, as written in contact.csv
OPEN, STICK, SLIP = 0, 1, 2
STATUS_NAMES = ("open", "stick", "slip")


class ContactLaw(ParametrizedLaw):
    """Base of contact-law plugins (``lagamine_py.contact_laws`` entry-point group).

    The contact element computes, per contact Gauss point ``g`` and per sub-interval, the
    penetration ``d`` at the end of the sub-interval (``d > 0``: contact), its increment ``du``
    over the sub-interval, and the tangential relative displacement increment ``dv`` in the
    local axes taken at ``t0 + theta*dt`` of the sub-interval.  The law integrates one
    sub-interval::

        new_state, tan = law.update(state, d, du, dv)

    ``state`` / ``new_state``: dicts of (g,) arrays with at least ``p``, ``tau``, ``lam``,
    ``slip``, ``dissip``, ``status`` (int: OPEN/STICK/SLIP).  ``tan``: dict of (g,) arrays,
    the exact derivatives of the integrated sub-interval::

        p_u   = d p_new / d du        (d moves with du)
        tau_u = d tau_new / d du
        tau_v = d tau_new / d dv
        tau_tau = d tau_new / d tau_old (to chain sub-intervals)
        (p_new = KP * max(d, 0) depends on d only.)

    ``self.theta`` and ``self.substeps`` are read by the contact element.
    """


    def init_state(self, n: int) -> dict[str, np.ndarray]:
        z = np.zeros(n)
        return {"p": z.copy(), "tau": z.copy(), "lam": z.copy(), "slip": z.copy(),
                "dissip": z.copy(), "status": np.zeros(n, dtype=np.int8)}

    def update(self, state, d, du, dv):
        raise NotImplementedError
