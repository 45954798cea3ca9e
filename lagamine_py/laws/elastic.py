"""Isotropic linear elasticity (Hooke), batched over any leading axes.

In small strain the stress is the Cauchy stress of the infinitesimal strain; under NLGEOM the
element hands over the Hencky elastic strain and the same formula gives the Kirchhoff stress
(the classical Hencky hyperelastic model, exact for moderate elastic stretches).
"""
from __future__ import annotations

import numpy as np

from ..registry import Param, ParamError, register
from .base import MaterialLaw

__all__ = ["LinearElastic", "hooke_matrix"]


def hooke_matrix(E: float, nu: float) -> np.ndarray:
    """D (4, 4) mapping [e11, e22, e33, g12] to [s11, s22, s33, s12] (g12 engineering shear)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    D = np.zeros((4, 4))
    D[:3, :3] = lam
    D[[0, 1, 2], [0, 1, 2]] += 2 * mu
    D[3, 3] = mu
    return D


@register("laws", "ELASTIC")
class LinearElastic(MaterialLaw):
    """Isotropic linear elasticity: ``stress = D eps_e_trial``; never plastic (peeq stays)."""

    params = (
        Param("E", float, bounds=(0.0, None), unit="stress", doc="Young's modulus (> 0)"),
        Param("NU", float, bounds=(-0.999, 0.4999), doc="Poisson's ratio"),
    )
    doc = "Isotropic linear elasticity (Kirchhoff stress of the Hencky strain under NLGEOM)."

    def __init__(self, **values):
        super().__init__(**values)
        if self.e <= 0.0:  # the declared bound is inclusive, E = 0 is not a material
            raise ParamError(f"E must be > 0, got {self.e:g}")
        self.D = hooke_matrix(self.e, self.nu)

    def update(self, eps_e_trial: np.ndarray, state: dict[str, np.ndarray]):
        """Stress (..., 4), D (..., 4, 4), new state, ok (...) -- see MaterialLaw.update."""
        eps = np.asarray(eps_e_trial, float)
        stress = eps @ self.D.T
        D = np.broadcast_to(self.D, eps.shape[:-1] + (4, 4)).copy()
        new_state = {k: v for k, v in state.items()}
        new_state["eps_e"] = eps.copy()
        new_state["peeq"] = np.array(state["peeq"], float, copy=True)
        return stress, D, new_state, np.ones(eps.shape[:-1], bool)
