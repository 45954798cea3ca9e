"""A third-party lagamine_py contact law: penalty contact with plain Coulomb friction.

One class against the :class:`lagamine_py.laws.base.ContactLaw` contract, with its own
parameters (``KN``, ``KS``, ``MU``); the entry point in setup.cfg (group
``lagamine_py.contact_laws``) makes it available to decks as ``*CONTACT LAW, TYPE=SIMPLE_FRICTION``.

Per sub-interval: ``p = KN max(d, 0)`` while ``d >= 0``; an elastic trial ``tau0 + KS dv``
(``tau0 = 0`` for a point that was open) returned to the cone ``|tau| <= MU p`` at the end of
the sub-interval.  No adhesion, no hardening: the plastic multiplier only records the slip.
"""
import numpy as np

from lagamine_py.core.status import OPEN, SLIP, STICK
from lagamine_py.laws.base import ContactLaw
from lagamine_py.registry import Param


class SimpleFriction(ContactLaw):
    """Penalty contact with Coulomb friction (MU), no adhesion, no hardening."""

    params = (
        Param("KN", float, gt=0.0, unit="stress/length", doc="normal penalty"),
        Param("KS", float, gt=0.0, unit="stress/length", doc="tangential penalty while sticking"),
        Param("MU", float, bounds=(0.0, None), doc="friction coefficient"),
    )

    @classmethod
    def example_values(cls):
        return {"KN": 1e5, "KS": 1e5, "MU": 0.3}

    def update(self, state, d, du, dv, frozen=None):
        status_old = np.asarray(state["status"])
        shape = status_old.shape
        d, dv = (np.broadcast_to(np.asarray(x, float), shape) for x in (d, dv))
        hold = np.full(shape, -1) if frozen is None else np.broadcast_to(frozen, shape)
        contact = (d >= 0.0) & (hold != OPEN)
        reopened = status_old == OPEN                  # tau starts from 0 on touching again
        p = np.where(contact, self.kn * np.maximum(d, 0.0), 0.0)
        tau0 = np.where(reopened, 0.0, np.asarray(state["tau"], float))
        trial = tau0 + self.ks * dv
        sign = np.where(trial >= 0.0, 1.0, -1.0)
        cone = self.mu * p
        slip = contact & (hold != STICK) & ((np.abs(trial) > cone) | (hold == SLIP))
        stick = contact & ~slip
        tau = np.where(slip, sign * cone, np.where(stick, trial, 0.0))
        dlam = np.where(slip, (np.abs(trial) - cone) / self.ks, 0.0)
        new = {"p": p, "tau": tau, "lam": state["lam"] + dlam,
               "slip": state["slip"] + np.abs(dlam), "vp": state["vp"] + sign * dlam,
               "dissip": state["dissip"] + np.abs(tau * dlam),
               "status": np.where(slip, SLIP, np.where(stick, STICK, OPEN)).astype(np.int8)}
        kept = np.where(reopened, 0.0, 1.0)            # d tau0 / d tau_old
        mu_kn = self.mu * self.kn
        tan = {"p_u": np.where(contact, self.kn, 0.0),
               "tau_u": np.where(slip, sign * mu_kn, 0.0),
               "tau_d": np.where(slip, sign * mu_kn, 0.0),
               "tau_v": np.where(stick, self.ks, 0.0),
               "tau_tau": np.where(stick, kept, 0.0),
               "lam_u": np.where(slip, -mu_kn / self.ks, 0.0),
               "lam_d": np.where(slip, -mu_kn / self.ks, 0.0),
               "lam_v": np.where(slip, sign, 0.0),
               "lam_tau": np.where(slip, sign * kept / self.ks, 0.0),
               "lam_lam": np.ones(shape)}
        return new, tan

    def inadmissible(self, state):
        tau, p = np.abs(np.asarray(state["tau"], float)), np.asarray(state["p"], float)
        return tau > self.mu * p * (1.0 + 1e-9) + 1e-12 * self.kn

    def penalties(self):
        return {"KN": (self.kn, True), "KS": (self.ks, self.mu > 0.0)}
