"""Isotropic linear elasticity (Hooke), batched over any leading axes.

In small strain the stress is the Cauchy stress of the infinitesimal strain; under NLGEOM the
element hands over the Hencky elastic strain and the same formula gives the Kirchhoff stress
(the classical Hencky hyperelastic model, exact for moderate elastic stretches).
"""
from __future__ import annotations

import numpy as np

from ..core.params import Param
from ..core.tensors import elastic_matrix
from ..kernels.layout import ELASTIC, SOLID_VECTOR
from .base import MaterialLaw

__all__ = ["LinearElastic"]


class LinearElastic(MaterialLaw):
    """Isotropic linear elasticity: ``stress = D eps_e_trial``; never plastic (peeq stays)."""

    params = (
        Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
        Param("NU", float, bounds=(-0.999, 0.4999), doc="Poisson's ratio"),
    )

    @classmethod
    def example_values(cls):
        return {"E": 200e3, "NU": 0.3}

    def __init__(self, **values):
        super().__init__(**values)
        self.D = elastic_matrix(self.e, self.nu)

    def update(self, eps_e_trial: np.ndarray, state: dict[str, np.ndarray]):
        """Stress (..., 4), D (..., 4, 4), new state, ok (...) -- see MaterialLaw.update."""
        eps = np.asarray(eps_e_trial, float)
        stress = eps @ self.D.T
        D = np.broadcast_to(self.D, eps.shape[:-1] + (4, 4)).copy()
        new_state = {k: v for k, v in state.items()}
        new_state["eps_e"] = eps.copy()
        new_state["peeq"] = np.array(state["peeq"], float, copy=True)
        return stress, D, new_state, np.ones(eps.shape[:-1], bool)

    def energy(self, state_old, state_new):
        """``1/2 eps_e . D eps_e`` stored, nothing dissipated."""
        eps = np.asarray(state_new["eps_e"], float)
        return 0.5 * np.einsum("...s,...s->...", eps @ self.D.T, eps), np.zeros(eps.shape[:-1])

    def kernel_parameters(self):
        if type(self) is not LinearElastic:      # a subclass may change anything: NumPy
            return None
        return ELASTIC, np.zeros(SOLID_VECTOR), np.ascontiguousarray(self.D, dtype=float)
