"""The contracts of material laws and contact laws: everything the program calls or reads.

Array axes are named by letters, the same in docstrings and ``einsum`` strings:
``e`` element, ``q`` Gauss point, ``a``/``b`` element node, ``i``/``j``/``k``/``l`` spatial
component, ``s``/``t`` stress/strain component in the 4-vector convention of
:mod:`lagamine_py.core.tensors`, ``g`` contact Gauss point (flattened over contact elements x
Gauss points).

A law is a *pure batched function* of the committed state and an increment: it never keeps
per-point data on ``self`` and never modifies the state it is given.  The state it returns is a
*trial* state, committed by the solver only when the increment converges.
"""
from __future__ import annotations

import numpy as np

from ..core.plugin import Parametrized

__all__ = ["MaterialLaw", "ContactLaw"]


class MaterialLaw(Parametrized):
    """Base of material-law plugins (entry-point group ``lagamine_py.laws``).

    Built as ``Law(**values)`` from the deck's ``*MATERIAL`` data (see
    :class:`~lagamine_py.core.plugin.Parametrized`).  A subclass declares ``params`` and writes
    :meth:`update`; the rest has defaults.  ``example_values()`` (from
    :class:`~lagamine_py.core.plugin.Parametrized`) gives the values the contract checks build
    the law from: override it with realistic ones (a yield stress well below E, say).

    The element computes the trial elastic strain from its kinematics (small strain:
    ``eps - eps_p``; NLGEOM: the Hencky strain ``1/2 ln b_e_trial``) and the law returns the
    stress in that strain space (the Kirchhoff stress under NLGEOM), so a law written for small
    strain works at large strain unchanged.
    """

    #: rotating the trial strain rotates the stress (and the state) alike: the contract check
    #: rotates the trial strain and the state's ``eps_e`` (taking the other state arrays as
    #: invariant scalars) for laws that say so; a law with other tensorial state says False
    isotropic: bool = True

    def init_state(self, shape: tuple[int, ...]) -> dict[str, np.ndarray]:
        """Committed state at t = 0 for points of ``shape`` (``(e, q)`` in an element).

        Must hold ``eps_e`` (shape + (4,)), the elastic strain, and ``peeq`` (shape), the
        equivalent plastic strain that writers show; a law may add its own arrays."""
        return {"eps_e": np.zeros(shape + (4,)), "peeq": np.zeros(shape)}

    def update(self, eps_e_trial: np.ndarray, state: dict[str, np.ndarray]):
        """Integrate the increment of every point at once.

        Parameters: ``eps_e_trial`` (..., 4); ``state`` the committed state (not modified).

        Returns ``(stress, D, new_state, ok)``: ``stress`` (..., 4); ``D`` (..., 4, 4)
        = d stress / d eps_e_trial (the algorithmic tangent, engineering-shear columns);
        ``new_state`` a dict like :meth:`init_state`'s with ``eps_e`` the elastic strain after
        the return; ``ok`` (...) bool, False where the integration failed (the increment is
        then cut back).
        """
        raise NotImplementedError

    def energy(self, state_old: dict[str, np.ndarray], state_new: dict[str, np.ndarray]):
        """The energy of an increment from the committed state ``state_old`` to ``state_new``
        (what :meth:`update` returned), per unit (reference) volume, for the energy balance
        (``*CHECK, TYPE=ENERGY``, :mod:`lagamine_py.solver.energy`).

        Returns ``(stored, dissipated)``, each of the points' shape: the elastic energy of
        ``state_new`` and the energy dissipated over the increment.  Their sum over a path
        must match the work ``sum 1/2 (s_n + s_n+1) . (e_n+1 - e_n)`` of the stresses along the
        total strain increments (the trapezoidal rule, which the solver's balance uses): the
        contract checks compare them along a loading-unloading path.  The default refuses: a law
        that does not say cannot be checked."""
        raise NotImplementedError(f"material law {type(self).__name__} does not report its energy: "
                                  f"it has no energy() (the stored and dissipated energy an "
                                  f"energy balance needs)")

    def elastic_moduli(self) -> tuple[float, float]:
        """(E, nu) of the elastic part, the law's initial stiffness (``D`` of a zero trial strain
        from :meth:`init_state` is Hooke's with them: the contract check compares): penalty
        advice and the contract checks use them.  The default reads the parameters ``E`` and
        ``NU``; a law declaring others overrides it."""
        return float(self.values["E"]), float(self.values["NU"])

    def kernel_parameters(self):
        """``(kind, p (8,), D (4, 4))`` when :mod:`lagamine_py.kernels.solid` reproduces this
        law (built-in laws, exact types only), else None: the element then uses :meth:`update`."""
        return None

    @classmethod
    def contract_problem(cls) -> str:
        return "" if cls.update is not MaterialLaw.update else "it does not implement update()"


class ContactLaw(Parametrized):
    """Base of contact-law plugins (entry-point group ``lagamine_py.contact_laws``).

    The contact element computes, per contact Gauss point ``g`` and per sub-interval of the
    increment, the penetration ``d`` at the end of the sub-interval (``d >= 0``: contact), its
    increment ``du`` and the tangential relative displacement increment ``dv`` in the local
    axes taken at ``t0 + theta dt`` of the sub-interval; the law integrates the sub-interval::

        new_state, tan = law.update(state, d, du, dv, frozen)

    ``state`` / ``new_state``: dicts of (g,) arrays holding at least :data:`STATE_KEYS`:
    ``p`` (>= 0), ``tau``, ``lam`` (the plastic multiplier), ``slip`` (accumulated
    ``|dlam|``), ``vp`` (the signed slip ``int sgn(tau) dlam``: the paper's plastic tangential
    displacement, positive along ``e_v``), ``dissip`` (``int |tau| dlam``, the frictional
    dissipation per unit area, the paper's D) and ``status`` (int8 OPEN/STICK/SLIP of
    :mod:`lagamine_py.core.status`; a law never returns NONE).

    ``frozen``: None, or (g,) int8: -1 leaves a point free, OPEN/STICK/SLIP hold it in that
    status for this sub-interval (the solver's flip-flop control: STICK is elastic even
    outside the cone, SLIP returns to the cone even when unloading, OPEN keeps the history and
    gives no contact).

    ``tan``: dict of (g,) arrays, exact derivatives of the integrated sub-interval, named
    ``<out>_<in>`` with ``out`` in ``p, tau, lam`` (the new values) and ``in`` in ``u`` (du,
    with d moving with it), ``v`` (dv), ``d`` (d at fixed du), ``p``, ``tau``, ``lam`` (the
    values of the old state).  A key left out is zero, except ``p_d``, which defaults to ``p_u``
    (``p = KP max(d, 0)`` depends on d only).  The element chains them over the sub-intervals::

        D tau_k = tau_tau D tau_{k-1} + tau_lam D lam_{k-1} + tau_u D du_k + tau_v D dv_k + ...

    so a law with one internal variable returns ``p_u, tau_u, tau_v, tau_tau`` and is done.

    The element reads how to split an increment from :attr:`theta`, :attr:`substeps`,
    :attr:`subtol` and :attr:`submax` (a law declaring parameters of those names overrides the
    defaults below).

    The contract checks (``lagamine-py plugins --check``) build the law from
    ``example_values()`` (:class:`~lagamine_py.core.plugin.Parametrized`) and compare every
    tangent entry with central differences of :meth:`update` in open, closing, stick, slip and
    separating sub-intervals.
    """

    #: the arrays of every contact point's state
    STATE_KEYS = ("p", "tau", "lam", "slip", "vp", "dissip", "status")
    #: outputs and inputs of the tangent's keys ``<out>_<in>``
    TANGENT_OUT = ("p", "tau", "lam")
    TANGENT_IN = ("u", "v", "d", "p", "tau", "lam")

    #: the message of a failed integration (when a kernel reports one)
    failure_message: str = "the contact law could not integrate the increment"
    #: local axes taken at ``t0 + theta dt`` of each sub-interval
    theta: float = 1.0
    #: sub-intervals per increment: an int, or "AUTO" (chosen from the rotation of the axes)
    substeps: int | str = 1
    #: SUBSTEPS=AUTO: largest rotation of the axes per sub-interval (rad), and the cap
    subtol: float = 0.01
    submax: int = 32

    def init_state(self, n: int) -> dict[str, np.ndarray]:
        """State of ``n`` points at t = 0: open, nothing slipped."""
        z = np.zeros(n)
        return {"p": z.copy(), "tau": z.copy(), "lam": z.copy(), "slip": z.copy(),
                "vp": z.copy(), "dissip": z.copy(), "status": np.zeros(n, dtype=np.int8)}

    def update(self, state, d, du, dv, frozen=None):
        """Integrate one sub-interval of every point; see the class docstring."""
        raise NotImplementedError

    def stored_energy(self, state) -> np.ndarray:
        """(g,) the energy per unit area stored in the points' contact springs in ``state`` (the
        penalty energy of the energy balance, ``*CHECK, TYPE=ENERGY``); with the frictional
        dissipation ``dissip`` it accounts for the work of the contact stresses along the
        relative displacements.  The default refuses: a law that does not say cannot be
        checked."""
        raise NotImplementedError(f"contact law {type(self).__name__} does not report its stored "
                                  f"(penalty) energy: it has no stored_energy()")

    def inadmissible(self, state) -> np.ndarray:
        """(g,) bool: points whose state the law itself cannot accept (beyond round-off outside
        its yield surface, say).  The contact element fails the increment on them (cut-back,
        then exit 3), so a wrong answer is never passed on.  Default: none."""
        return np.zeros(np.shape(state["p"]), bool)

    def inadmissible_hint(self) -> str:
        """A hint appended to the message about inadmissible points ("" for none)."""
        return ""

    def penalties(self) -> dict[str, float]:
        """The law's penalty stiffnesses by parameter name (stress/length), for the penalty
        advice at the start of a run, and whether each plays a role: ``{"KP": (kp, True),
        "KT": (kt, has_friction)}``.  Default: none."""
        return {}

    def kernel_vector(self):
        """The law's parameters as :mod:`lagamine_py.kernels.contact` reads them, when that
        kernel reproduces this law (the built-in COULOMB, exact type only), else None: the
        element then calls :meth:`update`."""
        return None

    @classmethod
    def contract_problem(cls) -> str:
        return "" if cls.update is not ContactLaw.update else "it does not implement update()"
