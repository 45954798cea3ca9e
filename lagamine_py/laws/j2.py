"""J2 (von Mises) plasticity with isotropic hardening: the radial return shared by its laws.

All arrays carry any leading shape ``...`` (``(e, q)`` in an element group); the 4-vector
axis is last (``s``/``t``), see :mod:`lagamine_py.laws.base`::

    strain = [e11, e22, e33, g12]   (engineering shear)
    stress = [s11, s22, s33, s12]

A subclass of :class:`J2Plasticity` gives the hardening curve ``sigma_y(peeq)`` and solves
the scalar consistency equation of the radial return

    q = sigma_y(peeq_n + dp),    q = q_tr - 3 G dp

for ``q`` (the von Mises stress after the return) on the plastic points only, returning
also ``dq/dq_tr``; everything else (trial split, plastic mask, stress, consistent tangent,
new state) is done here once, batched over all points.
"""
from __future__ import annotations

import numpy as np

from ..core.params import Param, ParamError
from ..core.tensors import NORMAL as _NORMAL, elastic_matrix, isotropic_moduli
from ..kernels.layout import (J2_LINEAR, SOLID_G, SOLID_H, SOLID_K, SOLID_SIGMAY,
                              SOLID_VECTOR, YIELD_RTOL)
from .base import MaterialLaw

__all__ = ["J2Plasticity", "J2Linear", "J2Table"]

_DEV = np.diag([1.0, 1.0, 1.0, 0.5])              # engineering strain -> tensor components
_DEV[:3, :3] -= 1.0 / 3.0                          # ... and deviatoric part (2G * _DEV = dev. stiffness)
_NORMAL_NORMAL = np.outer(_NORMAL, _NORMAL)
_ENGINEERING = np.array([1.0, 1.0, 1.0, 2.0])     # tensor -> engineering shear


class J2Plasticity(MaterialLaw):
    """Base of J2 laws: elastic isotropic moduli ``E``, ``NU`` and a hardening curve.

    Subclasses implement :meth:`yield_stress` and :meth:`_return_map`.
    """

    def __init__(self, **values):
        super().__init__(**values)
        self.K, self.G = isotropic_moduli(self.values["E"], self.values["NU"])
        self.D_elastic = elastic_matrix(self.values["E"], self.values["NU"])

    # -- to implement ---------------------------------------------------------------------
    def yield_stress(self, peeq: np.ndarray) -> np.ndarray:
        """Current yield stress ``sigma_y(peeq)`` (same shape as ``peeq``)."""
        raise NotImplementedError

    def _return_map(self, q_tr: np.ndarray, peeq_n: np.ndarray):
        """Solve ``q = sigma_y(peeq_n + (q_tr - q)/(3G))`` on plastic points (1-D arrays
        with ``q_tr > sigma_y(peeq_n)``).  Returns ``(q, peeq, dq_dqtr, ok)``, each (m,):
        the von Mises stress and plastic strain after the return (``peeq`` computed where it
        is best conditioned, not necessarily as ``peeq_n + (q_tr - q)/3G``), ``dq/dq_tr``
        and convergence flags."""
        raise NotImplementedError

    # -- shared radial return -------------------------------------------------------------
    def update(self, eps_e_trial, state):
        """Radial return of all points at once; see :meth:`MaterialLaw.update`.

        ``eps_e_trial`` (...,4); ``state`` holds ``eps_e`` (...,4) and ``peeq`` (...).
        Returns ``stress`` (...,4), ``D`` (...,4,4), ``new_state``, ``ok`` (...).
        """
        eps = np.asarray(eps_e_trial, dtype=float)
        shape = eps.shape[:-1]
        eps = eps.reshape(-1, 4)                        # axis m: the points, flattened
        peeq_n = np.broadcast_to(np.asarray(state["peeq"], dtype=float), shape).reshape(-1)
        K, G = self.K, self.G

        # sums over the 4-vector written out in the order the reductions along it add (the same
        # values: a reduction over a short last axis runs one inner loop per point)
        tr = eps[:, 0] + eps[:, 1]
        tr += eps[:, 2]                                                # (m,)
        s_tr = 2.0 * G * eps @ _DEV.T                                  # (m, s) tensor components
        sq = s_tr * s_tr
        norm_tr = sq[:, 0] + sq[:, 1]
        norm_tr += sq[:, 2]
        norm_tr += 2.0 * sq[:, 3]
        np.sqrt(norm_tr, out=norm_tr)
        q_tr = np.sqrt(1.5) * norm_tr
        sy_n = self.yield_stress(peeq_n)
        plastic = q_tr > sy_n * (1.0 + YIELD_RTOL)

        q, peeq, dq = q_tr.copy(), peeq_n.copy(), np.ones_like(q_tr)
        ok = np.ones(q_tr.shape, dtype=bool)
        # the plastic points: every point (a slice, no gathered copies) or a mask
        some = plastic.any()
        every = some and plastic.all()
        pl = slice(None) if every else plastic
        if some:
            q[pl], peeq[pl], dq[pl], ok[pl] = self._return_map(q_tr[pl], peeq_n[pl])

        theta = np.divide(q, q_tr, out=np.ones_like(q), where=plastic)  # dev. stress scale
        s = theta[:, None] * s_tr
        stress = s + (K * tr)[:, None] * _NORMAL
        eps_e = eps.copy()
        # elastic strain of the returned stress: same volume, deviator s / 2G (shear s12 / G)
        if some:
            eps_e[pl] = tr[pl, None] / 3.0 * _NORMAL + s[pl] / (2.0 * G) * _ENGINEERING

        # consistent tangent (Simo & Hughes 1998, box 3.2, any hardening):
        # D = K 1x1 + 2G theta P_dev + 2G (dq/dq_tr - theta) n x n,  theta = q / q_tr
        if some:
            n = s_tr[pl] / norm_tr[pl, None]                               # unit flow direction
            th, beta = theta[pl], dq[pl]
            Dp = (K * _NORMAL_NORMAL + (2.0 * G * th)[:, None, None] * _DEV
                  + (2.0 * G * (beta - th))[:, None, None] * np.einsum("ms,mt->mst", n, n))
        if every:
            D = Dp
        else:
            D = np.broadcast_to(self.D_elastic, (eps.shape[0], 4, 4)).copy()
            if some:
                D[plastic] = Dp
        if not (np.isfinite(stress).all() and np.isfinite(D).all()):    # else every point ok
            ok &= np.isfinite(stress).all(-1) & np.isfinite(D.reshape(-1, 16)).all(-1)

        new_state = {"eps_e": eps_e.reshape(shape + (4,)), "peeq": peeq.reshape(shape)}
        return stress.reshape(shape + (4,)), D.reshape(shape + (4, 4)), new_state, ok.reshape(shape)


    def energy(self, state_old, state_new):
        """Stored ``psi = 1/2 eps_e . D eps_e`` of ``state_new``; dissipated over the increment
        ``1/2 (sig_n + sig_n+1) . deps_p`` with ``sig = D eps_e`` and the plastic increment of
        the radial return ``deps_p = dp 3/2 s_n+1 / q_n+1`` (engineering shear), the
        trapezoidal form that makes ``psi_n+1 - psi_n + dissipated`` equal to
        ``1/2 (sig_n + sig_n+1) . deps`` exactly (see :mod:`lagamine_py.solver.energy`)."""
        e_new = np.asarray(state_new["eps_e"], float)
        e_old = np.broadcast_to(np.asarray(state_old["eps_e"], float), e_new.shape)
        s_new, s_old = e_new @ self.D_elastic.T, e_old @ self.D_elastic.T
        psi = 0.5 * np.einsum("...s,...s->...", s_new, e_new)
        dp = (np.asarray(state_new["peeq"], float)
              - np.broadcast_to(np.asarray(state_old["peeq"], float), psi.shape))
        dev = s_new - s_new[..., :3].sum(-1, keepdims=True) / 3.0 * _NORMAL
        q = np.sqrt(1.5 * (np.sum(dev[..., :3] ** 2, -1) + 2.0 * dev[..., 3] ** 2))
        flow = 1.5 * dev * np.array([1.0, 1.0, 1.0, 2.0])             # 3/2 s, engineering
        scale = np.divide(dp, q, out=np.zeros_like(dp), where=(dp != 0.0) & (q > 0.0))
        deps_p = scale[..., None] * flow
        dissipated = 0.5 * np.einsum("...s,...s->...", s_old + s_new, deps_p)
        return psi, dissipated


class J2Linear(J2Plasticity):
    """J2 plasticity with linear isotropic hardening ``sigma_y = SIGMAY + H peeq``
    (``H = 0``: perfect plasticity).  The return mapping is closed-form."""

    params = (
        Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
        Param("NU", float, bounds=(-0.999, 0.4999), doc="Poisson's ratio"),
        Param("SIGMAY", float, gt=0.0, unit="stress", doc="initial yield stress"),
        Param("H", float, 0.0, bounds=(0.0, None), unit="stress",
              doc="hardening modulus d sigma_y / d peeq (0: perfect plasticity)"),
    )

    @classmethod
    def example_values(cls):
        return {"E": 200e3, "NU": 0.3, "SIGMAY": 300.0, "H": 2000.0}

    def yield_stress(self, peeq):
        return self.values["SIGMAY"] + self.values["H"] * np.asarray(peeq, dtype=float)

    def _return_map(self, q_tr, peeq_n):
        H, G3 = self.values["H"], 3.0 * self.G
        dp = (q_tr - self.yield_stress(peeq_n)) / (G3 + H)
        return (q_tr - G3 * dp, peeq_n + dp, np.full_like(q_tr, H / (G3 + H)),
                np.ones(q_tr.shape, dtype=bool))

    def kernel_parameters(self):
        if type(self) is not J2Linear:           # a subclass may change anything: NumPy
            return None
        p = np.zeros(SOLID_VECTOR)
        p[SOLID_K], p[SOLID_G] = self.K, self.G
        p[SOLID_SIGMAY], p[SOLID_H] = self.values["SIGMAY"], self.values["H"]
        return J2_LINEAR, p, np.ascontiguousarray(self.D_elastic, dtype=float)


class J2Table(J2Plasticity):
    """J2 plasticity with piecewise-linear isotropic hardening from a table (Abaqus *PLASTIC).

    The table gives the yield stress against the equivalent plastic strain (a measured flow
    curve, say); the curve is flat beyond its last row.

    The return mapping is exact for the piecewise-linear curve: with ``f(p) = q_tr - 3G (p -
    peeq_n) - sigma_y(p)``, decreasing as long as every slope ``H_k > -3G`` (checked), the root
    lies in the first segment at whose end ``f <= 0``; there ``sigma_y`` is linear and the root
    closed-form, ``dq/dq_tr = H_k / (3G + H_k)`` (the consistent tangent of that segment)."""

    params = (
        Param("E", float, gt=0.0, unit="stress", doc="Young's modulus"),
        Param("NU", float, bounds=(-0.999, 0.4999), doc="Poisson's ratio"),
        Param("PLASTIC", tuple, columns=("yield stress", "plastic strain"),
              doc="the hardening table, first row at plastic strain 0, strains increasing"),
    )

    def __init__(self, **values):
        super().__init__(**values)
        table = np.asarray(self.values["PLASTIC"], float)
        sy, ep = table[:, 0], table[:, 1]
        if ep[0] != 0.0:
            raise ParamError(f"PLASTIC: the first row must be at plastic strain 0 (the initial yield "
                             f"stress), got {ep[0]:g}")
        if np.any(np.diff(ep) <= 0.0):
            k = int(np.flatnonzero(np.diff(ep) <= 0.0)[0])
            raise ParamError(f"PLASTIC: plastic strains must increase, row {k + 2} ({ep[k + 1]:g}) "
                             f"follows {ep[k]:g}")
        if np.any(sy <= 0.0):
            raise ParamError(f"PLASTIC: yield stresses must be > 0, got {sy[sy <= 0.0][0]:g}")
        slopes = np.diff(sy) / np.diff(ep)
        if np.any(slopes <= -3.0 * self.G):
            raise ParamError(f"PLASTIC: a slope of {slopes.min():g} is below -3G = {-3.0 * self.G:g} "
                             f"(softening that steep has no unique return mapping)")
        self._ep, self._sy = ep, sy
        self._slope = np.append(slopes, 0.0)          # segment k starts at row k; flat after the last

    @classmethod
    def example_values(cls):
        # a steep then a gentle segment, flat beyond: the contract's paths cross segment ends
        return {"E": 200e3, "NU": 0.3, "PLASTIC": ((300.0, 0.0), (330.0, 0.002), (360.0, 0.02))}

    def yield_stress(self, peeq):
        return np.interp(np.asarray(peeq, dtype=float), self._ep, self._sy)

    def _return_map(self, q_tr, peeq_n):
        G3, ep, sy = 3.0 * self.G, self._ep, self._sy
        # f at the rows beyond peeq_n: the root's segment ends at the first row where f <= 0
        f_rows = q_tr[:, None] - G3 * (ep[None, :] - peeq_n[:, None]) - sy[None, :]     # (m, n)
        ends = (ep[None, :] > peeq_n[:, None]) & (f_rows <= 0.0)
        inside = ends.any(axis=1)
        k = np.where(inside, ends.argmax(axis=1) - 1, len(ep) - 1)    # segment k: rows k, k + 1
        H = self._slope[k]
        peeq = (q_tr + G3 * peeq_n - sy[k] + H * ep[k]) / (G3 + H)
        peeq = np.maximum(peeq, peeq_n)
        return (q_tr - G3 * (peeq - peeq_n), peeq, H / (G3 + H), np.ones(q_tr.shape, dtype=bool))
