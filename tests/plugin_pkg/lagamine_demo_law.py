"""A third-party lagamine_py material law: isotropic elasticity given by bulk and shear moduli.

It is one class; the entry point in setup.cfg (group ``lagamine_py.laws``) makes it available to
decks as ``*MATERIAL, LAW=BULK_SHEAR`` with data ``K=..., G=...``.
"""
import numpy as np

from lagamine_py.laws.base import MaterialLaw
from lagamine_py.registry import Param


class BulkShearElastic(MaterialLaw):
    """Isotropic linear elasticity from the bulk modulus K and the shear modulus G."""

    params = (
        Param("K", float, bounds=(0.0, None), unit="stress", doc="bulk modulus"),
        Param("G", float, bounds=(0.0, None), unit="stress", doc="shear modulus"),
    )

    def _D(self):
        lam = self.k - 2.0 * self.g / 3.0
        D = np.zeros((4, 4))
        D[:3, :3] = lam
        D[[0, 1, 2], [0, 1, 2]] += 2.0 * self.g
        D[3, 3] = self.g
        return D

    def update(self, eps_e_trial, state):
        D = self._D()
        stress = eps_e_trial @ D.T
        new_state = {"eps_e": eps_e_trial.copy(), "peeq": state["peeq"].copy()}
        ok = np.ones(eps_e_trial.shape[:-1], bool)
        return stress, np.broadcast_to(D, eps_e_trial.shape[:-1] + (4, 4)).copy(), new_state, ok

    def elastic_moduli(self):
        E = 9 * self.k * self.g / (3 * self.k + self.g)
        nu = (3 * self.k - 2 * self.g) / (2 * (3 * self.k + self.g))
        return E, nu
