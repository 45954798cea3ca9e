"""The energy balance of a run: the work of the loads and tools against what the bodies and the
contacts store and dissipate.

Terms, cumulative from t = 0, at every converged increment (``IncrementResult.energy``,
written to ``OUT/energy.csv`` by the ENERGY writer, checked by ``*CHECK, TYPE=ENERGY``):

``work``
    the work of everything applied from outside: nodal forces and moments (``*CLOAD``), the
    reactions of prescribed DOFs (supports, and the reference nodes of tools moved by
    ``*BOUNDARY``), pressures (the nodal forces of the pressure groups), and the tools moved by
    ``*FOUNDATION MOTION`` (their force and moment times their translation and rotation).
``elastic``
    the energy stored in the bodies, ``sum w psi`` (:meth:`MaterialLaw.energy`, per reference
    volume).
``plastic``
    the energy the bodies' laws have dissipated (:meth:`MaterialLaw.energy`).
``friction``
    the frictional dissipation of the contact pairs in the trapezoidal form below
    (``ContactPoints.friction``); ``friction_path`` is the dissipation the contact tables report
    (``ContactPoints.E``, the law's integral along each increment): the two agree while ``tau``
    stays on the cone through an increment, and differ at first order where a point goes from
    stick to slip within one.
``penalty``
    the energy stored in the contact springs (:meth:`ContactLaw.stored_energy`).
``stabilisation``
    the energy the contact stabilisation has dissipated (trapezoidal form).
``balance``
    ``work - (elastic + plastic + friction + penalty + stabilisation)``; ``relative`` divides it
    by the work (or, when the work is nearly zero, by the largest term).

The discrete form.  A converged increment satisfies equilibrium at its end (backward Euler), so
the work is integrated by the trapezoidal rule on converged increments,
``W += 1/2 (F_n + F_n+1) . (u_n+1 - u_n)``: at equilibrium ``F = f_int``, and in small strain
(``eps = B u``, B constant) ``1/2 (f_n + f_n+1) . du = sum w 1/2 (sig_n + sig_n+1) : deps``
exactly.  With the elastic energy ``psi = 1/2 eps_e : D eps_e`` and ``sig = D eps_e``,
``1/2 (sig_n + sig_n+1) : deps_e = psi_n+1 - psi_n`` exactly, so the laws report their
dissipation in the same trapezoidal form, ``1/2 (sig_n + sig_n+1) : deps_p`` (J2: ``deps_p =
dp 3/2 s_n+1 / q_n+1``), and the material part of the balance holds to round-off (and the
Newton tolerance).  The contact points likewise: with ``p = KP d`` and ``tau_n+1 = tau_n + KT
(dv - dvp)``, ``1/2 (p_n + p_n+1) dd + 1/2 (tau_n + tau_n+1) dv`` is the change of the spring
energy ``p^2/2KP + tau^2/2KT`` plus ``1/2 (tau_n + tau_n+1) dvp``, the friction term (and the
stabilisation's tractions are counted as ``1/2 (ps_n + ps_n+1) dd + ...``).  So in small strain,
against a flat foundation, the balance holds to round-off through stick-slip transitions
(measured 5e-12 of the work on a pressed Ramberg-Osgood block with friction).  What is left:
first order in the increment size where a contact point closes or opens within an increment
(``1/2 p_n+1`` times the gap it had), and a term of the order of the angle between the body's
face and the foundation times the slip (the paper's contact force follows the body's normal,
the penetration the foundation's: against a curved foundation the two differ by that angle);
under NLGEOM, in addition, the trapezoid on a curved path (second order).  (A rectangle rule
``F_n+1 . du``, which backward Euler suggests, would add ``1/2 deps_e : D : deps_e`` per
increment: a first-order error that does not vanish for elastic loading.)
"""
from __future__ import annotations

import numpy as np

from .problem import PRESSURE, SOLID

__all__ = ["TERMS", "EnergyAccount", "energy_laws_problem"]

TERMS = ("work", "elastic", "plastic", "friction", "penalty", "stabilisation", "balance",
         "relative", "friction_path")


def energy_laws_problem(problem) -> str:
    """"" when every material law and contact law of ``problem`` reports its energy, else what
    does not (the deck builder and the controller refuse an energy check then)."""
    for k in problem.indices(SOLID):
        law = problem.groups[k].law
        try:
            st = law.init_state((1, 1))
            law.energy(st, st)
        except NotImplementedError as exc:
            return str(exc)
    for law in problem.contact_laws.values():
        try:
            law.stored_energy(law.init_state(1))
        except NotImplementedError as exc:
            return str(exc)
    return ""


class EnergyAccount:
    """The running sums of the energy balance (see the module doc).  ``commit`` after every
    converged increment; ``to_arrays``/``from_arrays`` carry the sums through a restart."""

    def __init__(self, ndof: int):
        self.work = 0.0
        self.plastic = 0.0
        self.force = np.zeros(ndof)          # the applied nodal forces at the last increment
        self.tools: dict[str, tuple] = {}    # prescribed tools: (placement, force, moment)

    def applied_forces(self, problem, u: np.ndarray, ctx, f_ext, reaction) -> np.ndarray:
        """(ndof,) the nodal forces applied at ``u``: loads, reactions and pressures."""
        F = np.asarray(f_ext, float) + np.asarray(reaction, float)
        n2 = 2 * len(problem.model.node_ids)
        u2 = u[:n2].reshape(-1, 2)
        for k in problem.indices(PRESSURE):
            r = problem.groups[k].compute(u2, u2, {}, ctx, tangent=False)
            F = F - problem.pattern.group_vector(k, r.f)
        return F

    def commit(self, problem, u_old, u_new, states_old, states_new, F_new, contacts,
               tools) -> dict[str, float]:
        """Add the increment from ``u_old`` to ``u_new``; returns the terms at its end.

        ``F_new`` the applied forces at ``u_new`` (:meth:`applied_forces`), ``contacts`` the
        contact pairs' points and ``tools`` the :class:`~lagamine_py.output.base.ToolState` of
        the foundations at ``u_new``."""
        self.work += 0.5 * float((self.force + F_new) @ (u_new - u_old))
        self.force = np.array(F_new, float)
        for name, ts in tools.items():
            if ts.ref_node is not None:
                continue                     # its work is that of its reference node's DOFs
            old = self.tools.get(name, (np.zeros(3), np.zeros(2), 0.0))
            dv = np.asarray(ts.placement, float) - old[0]
            self.work += (0.5 * float((old[1] + ts.force) @ dv[:2])
                          + 0.5 * (old[2] + ts.moment) * float(dv[2]))
            self.tools[name] = (np.asarray(ts.placement, float).copy(), np.asarray(ts.force).copy(),
                                float(ts.moment))
        elastic = 0.0
        for k in problem.indices(SOLID):
            stored, dissipated = problem.groups[k].energy(states_old[k], states_new[k])
            elastic += stored
            self.plastic += dissipated
        friction = float(sum(cp.friction for cp in contacts))
        penalty = float(sum(cp.stored for cp in contacts))
        stab = float(sum(cp.stabilisation for cp in contacts))
        held = elastic + self.plastic + friction + penalty + stab
        balance = self.work - held
        scale = max(abs(self.work), abs(elastic), abs(self.plastic), abs(friction), abs(penalty),
                    abs(stab), 1e-300)
        return {"work": self.work, "elastic": elastic, "plastic": self.plastic,
                "friction": friction, "penalty": penalty, "stabilisation": stab,
                "balance": balance, "relative": balance / scale,
                "friction_path": float(sum(cp.E for cp in contacts))}

    # -- restart ---------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        names = sorted(self.tools)
        return {"energy_sums": np.array([self.work, self.plastic]), "energy_force": self.force,
                "energy_tools": np.array(names, dtype=str),
                "energy_tool_values": np.array([np.concatenate([self.tools[n][0], self.tools[n][1],
                                                                [self.tools[n][2]]])
                                                for n in names]).reshape(len(names), 6)}

    def from_arrays(self, data) -> None:
        if "energy_sums" not in data:
            return
        self.work, self.plastic = (float(v) for v in data["energy_sums"])
        self.force = np.array(data["energy_force"], float)
        for name, v in zip(data["energy_tools"], data["energy_tool_values"]):
            self.tools[str(name)] = (v[:3].copy(), v[3:5].copy(), float(v[5]))
