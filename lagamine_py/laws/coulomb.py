"""The paper's elasto-plastic friction law in (p, tau): the COULOMB contact-law plugin.

Godinas, Charlier & Cescotto, sections 2-5 (DESIGN.md section 1).  Per contact point ``g``:

* yield ``f = |tau| - B(lam) - phi(lam) p``, with ``phi(lam) = PHI + HPHI lam`` and
  ``B(lam) = B + HB lam``, each clipped at >= 0 (slope 0 once clipped);
* elastic ``dp = KP du``, ``dtau = KT dv``;
* non-associated flow ``g = |tau|``: ``dv_p = dlam sgn(tau)``, ``du_p = 0``, so the normal
  law is exact, ``p = KP max(d, 0)``;
* plastic loading (paper eq. 10), ``H = B' + phi' p``::

      dtau = (phi KP KT sgn(tau) du + H KT dv) / (H + KT),
      dlam = (KT sgn(tau) dv - phi KP du) / (H + KT).

Time integration of one sub-interval (exact, not a time-stepping scheme)
-----------------------------------------------------------------------
The contact element hands over, for each sub-interval, ``d`` (penetration at its end), ``du``
(its increment) and ``dv`` (tangential increment in the axes at ``t0 + THETA dt``); within the
sub-interval ``u`` and ``v`` therefore move linearly in a pseudo-time ``s in [0, 1]``.

*Elastic part.*  Along an elastic path ``p`` and ``tau`` are linear in ``s`` and ``lam`` is
frozen, so ``f_e(s) = |tau0 + KT dv s| - B0 - phi0 (p0 + dp s)`` is convex and piecewise
linear.  A point starting on the surface (``f0 = 0``) loads plastically iff the paper's
elastic-predictor indicator ``dp_e df/dp + dtau_e df/dtau = sgn(tau0) KT dv - phi0 dp`` is
>= 0, i.e. iff ``f_e`` leaves 0 upwards; a point starting inside (or unloading from the surface
and reversing through to the other side of the cone) yields part-way, at the root ``s*`` of
``f_e`` on the side ``sgn(tau_trial)``; by convexity ``f_e > 0`` on ``(s*, 1]`` and the
elastic trial ``tau_tr = tau0 + KT dv`` ends outside: ``f_tr > 0``.

*Plastic part.*  While loading, ``sgn(tau)`` is constant and ``tau = KT (v - v_p)`` gives
``tau(s) = tau_tr(s) - sgn(tau) KT (lam(s) - lam0)`` *exactly*; together with ``f = 0`` at every
``s`` this is an algebraic equation for ``lam(s)``::

      |tau_tr(s)| - KT Lam - B(lam0 + Lam) - phi(lam0 + Lam) p(s) = 0.

Its solution is the solution of the rate equations (10): differentiating it in ``s`` returns
(10), and its ``Lam``-slope ``-(KT + H)`` never vanishes (``KT + H > 0`` is required).  For the
linear hardening used here ``Lam(s) = a s / (c + b s)`` on each unclipped piece, whose sign
never changes, so loading persists to the end of the sub-interval once started.  Hence the
state at ``s = 1`` is the root of this piecewise-linear equation at ``s = 1``, found exactly by
walking over the (at most two) clipping kinks; it depends only on ``(tau_tr, p_new, lam0)``.
This is the paper's eq. (11) when ``HPHI = HB = 0`` (``tau = sgn (B + phi p_new)``), and it is
exact for *any* increment size with hardening or softening too, so sub-intervals are needed only
to follow the rotation of the local axes in the contact element (``THETA`` and ``SUBSTEPS`` are
read by the contact element; this law does not use them; with ``SUBSTEPS=AUTO`` the element
chooses the count per increment from the rotation of the axes, ``SUBTOL`` and ``SUBMAX``).
The tangent is the exact derivative of this map: ``d tau/d tau_tr = H/(KT+H)``,
``d tau/d p_new = sgn KT phi/(KT+H)``, which equals
the continuum matrix (10) at the end state.

*Dissipation* ``dissip += int |tau| dlam`` along that same exact path: for a given ``lam`` the
algebraic equation is linear in ``s``, so ``|tau| = B(lam) + phi(lam) p(s(lam))`` is known in
closed form and is integrated by 8-point Gauss-Legendre in ``lam`` on each piece between kinks
(exact when ``HPHI = 0`` or ``p`` is constant; rational and smooth otherwise).

*Contact* is ``d >= 0``: a point exactly touching (``d = 0``, e.g. a body meshed on the
foundation) is closed with ``p = 0`` and the elastic tangent, so the first iteration of a
loaded step already has contact stiffness.  *Re-contact* (``p_old == 0`` and ``d >= 0``) starts from ``p = tau = 0`` with the part of ``dv``
after contact, ``dv d/du`` when ``0 < d <= du``.  *Separation* (``d < 0``): ``p = tau = 0``,
OPEN; ``lam``, ``slip``, ``vp``, ``dissip`` are kept while open.  In the sub-interval where a point
separates (``p_old > 0``, ``d < 0``) the part before ``d`` reaches 0 (fraction
``d_old/(d_old - d)`` of ``dv``, ``p`` falling to 0) is integrated like any other, so the slip
forced by the shrinking cone is not lost; only then are ``p`` and ``tau`` zeroed.

``INDICATOR=CLASSICAL`` replaces the predictor indicator, for points starting on the surface,
by the classical one with the actual (plastic) rates of (10) at the start,
``dp df/dp + dtau df/dtau = H (sgn KT dv - phi dp) / (H + KT)``: it is 0 for perfect plasticity
and has the wrong sign when softening (H < 0).  It exists only to show that failure, which
is reported, not passed on: :meth:`Coulomb.inadmissible` finds the points that end outside
the cone and the contact element fails the increment on them (cut-back, then exit 3).
"""
from __future__ import annotations

import numpy as np

from ..core.errors import ReturnMappingError
from ..core.params import Param, ParamError
from ..core.status import OPEN, SLIP, STICK
from ..kernels import layout as kl
from .base import ContactLaw

__all__ = ["Coulomb", "SNAP_BACK"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_ADMISSIBLE_RTOL = 1e-7    # |tau| beyond the cone by more than this (relative): an error
#: the message of a softening snap-back (the increment is cut back)
SNAP_BACK = "COULOMB: KT + dB/dlam + p dphi/dlam <= 0 at a slipping point (softening snap-back)"


def _kink(v0: float, slope: float) -> float:
    """The ``lam`` where ``v0 + slope lam`` reaches 0 going forward (inf if never)."""
    return -v0 / slope if slope < 0.0 else np.inf


def _clipped_linear(v0: float, slope: float, lam: np.ndarray):
    """``max(v0 + slope lam, 0)`` and its right-derivative in ``lam`` (0 once clipped).

    The clipped side is decided by comparing with the kink, so that a ``lam`` set exactly on
    the kink gets the slope of the piece ahead of it.
    """
    active = lam < _kink(v0, slope)
    return np.maximum(v0 + slope * lam, 0.0), np.where(active, slope, 0.0)


def _as_shape(x, shape) -> np.ndarray:
    """``x`` as a float array of ``shape`` (a broadcast view only when it is not one already)."""
    x = np.asarray(x, float)
    return x if x.shape == shape else np.broadcast_to(x, shape)


class Coulomb(ContactLaw):
    """Elasto-plastic Coulomb friction with adhesion and isotropic hardening (paper, eqs. 1-11).

    Arrays are (g,) over contact Gauss points.  See the module docstring for the integration.
    """

    failure_message = SNAP_BACK

    params = (
        Param("KP", float, gt=0.0, unit="stress/length", doc="normal penalty"),
        Param("KT", float, gt=0.0, unit="stress/length", doc="tangential penalty"),
        Param("PHI", float, bounds=(0.0, None), doc="friction coefficient phi at lam = 0"),
        Param("B", float, 0.0, bounds=(0.0, None), unit="stress", doc="adhesion B at lam = 0"),
        Param("HPHI", float, 0.0, unit="1/length", doc="dphi/dlam (phi clipped at >= 0)"),
        Param("HB", float, 0.0, unit="stress/length",
              doc="dB/dlam, < 0 is softening (B clipped at >= 0); KT + HB must stay > 0"),
        Param("THETA", float, 1.0, bounds=(0.0, 1.0),
              doc="local axes taken at t0 + THETA dt (read by the contact element)"),
        Param("SUBSTEPS", int, 1, bounds=(1, None), choices=("AUTO",),
              doc="sub-intervals per increment (read by the contact element); AUTO: chosen "
                  "per increment so that the local axes turn by at most SUBTOL in each"),
        Param("SUBTOL", float, 0.01, gt=0.0, unit="rad",
              doc="SUBSTEPS=AUTO: largest rotation of the local axes per sub-interval"),
        Param("SUBMAX", int, 32, bounds=(1, None),
              doc="SUBSTEPS=AUTO: cap on the number of sub-intervals per increment"),
        Param("INDICATOR", str, "PREDICTOR", choices=("PREDICTOR", "CLASSICAL"),
              doc="loading indicator: PREDICTOR (paper); CLASSICAL only to show its failure"),
    )

    @classmethod
    def example_values(cls):
        """Friction, adhesion and hardening of both: every tangent entry plays."""
        return {"KP": 1e5, "KT": 1e5, "PHI": 0.3, "B": 1.0, "HPHI": 0.5, "HB": 10.0}

    def __init__(self, **values):
        super().__init__(**values)
        if self.kt + min(self.hb, 0.0) <= 0.0:
            raise ParamError(f"HB = {self.hb:g} softens faster than the tangential penalty "
                             f"KT = {self.kt:g} allows (KT + HB must be > 0: snap-back)")
        self._vector = None                   # the kernel's parameter vector, on first use
        # the finite clipping kinks of B(lam) and phi(lam) (softening only); without them the
        # return finishes in one piece and the dissipation integral has one piece
        self._kinks = tuple(k for k in (_kink(self.b, self.hb), _kink(self.phi, self.hphi))
                            if np.isfinite(k))
        # KT + H > 0 always when neither B nor phi softens (H >= 0, p >= 0)
        self._may_snap_back = self.hb < 0.0 or self.hphi < 0.0

    # -- hardening functions ---------------------------------------------------------------
    def adhesion(self, lam):
        """``B(lam)`` and its right-derivative."""
        return _clipped_linear(self.b, self.hb, np.asarray(lam, float))

    def friction(self, lam):
        """``phi(lam)`` and its right-derivative."""
        return _clipped_linear(self.phi, self.hphi, np.asarray(lam, float))

    # -- one sub-interval ----------------------------------------------------------------
    def kernel_vector(self):
        """The parameters as :mod:`lagamine_py.kernels.contact` reads them (layout in
        :mod:`lagamine_py.kernels.layout`); None for a subclass, which may change anything."""
        if type(self) is not Coulomb:
            return None
        if self._vector is None:
            v = np.zeros(kl.COULOMB_VECTOR)
            v[kl.COULOMB_KP], v[kl.COULOMB_KT] = self.kp, self.kt
            v[kl.COULOMB_PHI], v[kl.COULOMB_B] = self.phi, self.b
            v[kl.COULOMB_HPHI], v[kl.COULOMB_HB] = self.hphi, self.hb
            v[kl.COULOMB_CLASSICAL] = self.indicator == "CLASSICAL"
            v[kl.COULOMB_PREDICTOR] = self.indicator == "PREDICTOR"
            v[kl.COULOMB_NK] = len(self._kinks)
            v[kl.COULOMB_K1] = self._kinks[0] if len(self._kinks) > 0 else np.inf
            v[kl.COULOMB_K2] = self._kinks[1] if len(self._kinks) > 1 else np.inf
            v[kl.COULOMB_SNAP] = self._may_snap_back
            self._vector = v
        return self._vector

    def penalties(self) -> dict[str, tuple[float, bool]]:
        """KP always plays; KT only with friction or adhesion (``PHI``, ``B`` or their
        hardening nonzero): frictionless contact never uses it."""
        friction = any(v != 0.0 for v in (self.phi, self.b, self.hphi, self.hb))
        return {"KP": (self.kp, True), "KT": (self.kt, friction)}

    def stored_energy(self, state) -> np.ndarray:
        """``p^2 / (2 KP) + tau^2 / (2 KT)`` per unit area: the elastic energy of the normal and
        tangential penalty springs (``p = KP d``, ``tau`` = KT times the elastic part of the
        tangential displacement); a frictionless law (``tau = 0``) stores none tangentially."""
        p = np.asarray(state["p"], float)
        tau = np.asarray(state["tau"], float)
        return 0.5 * p * p / self.kp + 0.5 * tau * tau / self.kt

    def update(self, state, d, du, dv, frozen=None):
        """Integrate one sub-interval for all points (see :class:`ContactLaw`).

        ``frozen`` (optional, (g,) int): the Newton solver's flip-flop control; -1 leaves a
        point free, OPEN/STICK/SLIP hold that status (STICK: elastic even outside the cone;
        SLIP: returned to the cone even when unloading; OPEN: no contact, history kept).

        Returns ``(new_state, tan)``.  Besides ``p_u``, ``tau_u``, ``tau_v``, ``tau_tau`` the
        tangent holds (all (g,)):

        * ``p_d``, ``tau_d`` (d/dd at fixed du) and ``tau_du`` (d/ddu at fixed d), with
          ``tau_u = tau_d + tau_du``, for elements whose ``d`` and ``du`` vary independently;
        * ``tau_lam`` = d tau_new/d lam_old and ``lam_d``, ``lam_du``, ``lam_u``, ``lam_v``,
          ``lam_tau``, ``lam_lam`` (derivatives of lam_new): with hardening, chaining
          sub-intervals exactly needs the pair (tau, lam)::

              J_tau <- tau_tau J_tau + tau_lam J_lam + tau_d dd + tau_du ddu + tau_v ddv
              J_lam <- lam_tau J_tau + lam_lam J_lam + lam_d dd + lam_du ddu + lam_v ddv

          (``contact_point.drive_contact_point(..., tangent=True)`` does exactly this).
        """
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # masked formulas are evaluated everywhere by np.where; unused lanes may overflow
            return self._update(state, d, du, dv, frozen)

    def _update(self, state, d, du, dv, frozen):
        p_old = np.asarray(state["p"], float)
        shape = p_old.shape
        d, du, dv = (_as_shape(x, shape) for x in (d, du, dv))
        kp, kt = self.kp, self.kt
        free = frozen is None                      # no flip-flop control: skip the hold masks
        hold = None if free else np.broadcast_to(frozen, shape)
        contact = d >= 0.0                         # d = 0: touching, closed with p = 0
        if not free:
            closable = hold != OPEN
            contact &= closable
        p1 = np.where(contact, kp * np.maximum(d, 0.0), 0.0)

        # the in-contact part of the sub-interval: re-contact starts from p = tau = 0 with the
        # part of dv after touching; separation integrates the slip up to the moment p = 0
        d_old = d - du
        # re-contact: the point was open (status, not p: a point touching at d = 0 has p = 0
        # but keeps its tau through the sub-intervals)
        recon = contact & (np.asarray(state["status"]) == OPEN)
        partial = recon & (d <= du) & (du > 0.0)         # du = 0 at d = 0: touching all along
        sep = ~contact & (p_old > 0.0) & (d_old > 0.0) & (d <= 0.0)
        if not free:
            sep &= closable
        any_recon, any_sep = bool(recon.any()), bool(sep.any())
        simple = not (any_recon or any_sep)        # every point stays closed or stays open
        if simple:                                 # frac = 1 everywhere: dv_c = dv exactly
            frac, active, dv_c = 1.0, contact, dv
        else:
            safe_du = np.where(partial, du, 1.0)
            frac = np.where(partial, d / safe_du, 1.0)
            frac = np.where(sep, d_old / np.where(sep, d_old - d, 1.0), frac)
            active = contact | sep
            dv_c = dv * frac
        tau_old = np.asarray(state["tau"], float)
        tau0 = np.where(recon, 0.0, tau_old) if any_recon else tau_old
        p0 = np.where(recon, 0.0, p_old) if any_recon else p_old
        lam0 = np.asarray(state["lam"], float)
        tau_tr = tau0 + kt * dv_c

        hard0 = self._hardening(lam0)
        plastic, sig, f_tr = self._loading(tau0, p0, p1, hard0, dv_c, tau_tr, active)
        if not free:
            plastic = np.where(hold == STICK, False, np.where(hold == SLIP, contact, plastic))
        lam1, dmat, phi1 = self._return(p1, lam0, plastic, f_tr, hard0)
        dlam = np.where(plastic, lam1 - lam0, 0.0)
        if self.indicator == "PREDICTOR":     # roundoff guard at neutral loading
            dlam = np.maximum(dlam, 0.0) if free else np.where(hold == SLIP, dlam,
                                                               np.maximum(dlam, 0.0))
        skt = sig * kt                         # sgn(tau) KT, exactly +-KT
        tau1 = np.where(contact, tau_tr - skt * dlam, 0.0)
        ddis = self._dissipation(tau0, p0, p1 - p0, dv_c, lam0, dlam, sig, plastic)

        new_state = dict(state)
        new_state.update(
            p=p1, tau=tau1, lam=lam0 + dlam, slip=np.asarray(state["slip"], float) + np.abs(dlam),
            vp=np.asarray(state["vp"], float) + sig * dlam,      # dv_p = dlam sgn(tau)
            dissip=np.asarray(state["dissip"], float) + ddis,
            # OPEN, STICK, SLIP = 0, 1, 2: contact + (plastic and contact), as int8
            status=contact.view(np.int8) + (plastic & contact).view(np.int8))
        if simple:
            tan = self._tangent_simple(contact, plastic, dv, skt, dmat, phi1)
        else:
            tan = self._tangent(contact, sep, plastic, recon, partial, d, du, dv, frac, skt,
                                dmat, phi1, active)
        return new_state, tan

    def inadmissible(self, state) -> np.ndarray:
        """(g,) bool: points of ``state`` outside the yield cone, ``|tau| > B(lam) + phi(lam) p``
        beyond round-off (``1e-7 (|tau| + radius + p) + 1e-12 KT``: with PHI = B = 0 the exact
        tau = 0 comes out as the round-off of ``tau_tr - KT dlam``).

        The exact integration never leaves such a point; ``INDICATOR=CLASSICAL`` under softening
        does (it takes plastic loading for unloading) and a frozen STICK point may.  The contact
        element reports these points as a failure of the increment (the solver cuts back, then
        stops with exit 3), so the wrong answer is never passed on silently."""
        tau = np.asarray(state["tau"], float)
        b, _, phi, _ = self._hardening(np.asarray(state["lam"], float))
        p = np.asarray(state["p"], float)
        radius = b + phi * p
        abs_tau = np.abs(tau)
        tol = _ADMISSIBLE_RTOL * (radius + abs_tau + p) + 1e-12 * self.kt
        return abs_tau - radius > tol

    def inadmissible_hint(self) -> str:
        return (" (INDICATOR=CLASSICAL takes plastic loading for unloading under softening; "
                "use PREDICTOR)" if self.indicator == "CLASSICAL" else "")

    def _hardening(self, lam):
        """``B, B', phi, phi'`` at ``lam`` (:meth:`adhesion`, :meth:`friction`), as plain floats
        for a function with slope 0 (the common case: fewer array operations, same values)."""
        if self.hb == 0.0:
            b, hb = self.b, 0.0
        else:
            b, hb = _clipped_linear(self.b, self.hb, lam)
        if self.hphi == 0.0:
            phi, hphi = self.phi, 0.0
        else:
            phi, hphi = _clipped_linear(self.phi, self.hphi, lam)
        return b, hb, phi, hphi

    def _loading(self, tau0, p0, p1, hard0, dv_c, tau_tr, contact):
        """Which points load plastically in this sub-interval, sgn(tau) while they do, and the
        trial yield function ``f_tr`` (at ``lam0``).

        ``contact``: points in contact during (part of) the sub-interval; the others are
        never plastic.  ``hard0``: :meth:`_hardening` at ``lam0``.
        """
        kt = self.kt
        b0, hb0, phi0, hphi0 = hard0
        radius0 = b0 + phi0 * p0
        abs_tau0 = np.abs(tau0)
        f0 = abs_tau0 - radius0
        f_tr = np.abs(tau_tr) - b0 - phi0 * p1
        sig_tr = np.where(tau_tr >= 0.0, 1.0, -1.0)
        sig0 = np.where(tau0 != 0.0, np.sign(tau0), np.where(dv_c >= 0.0, 1.0, -1.0))
        # on the surface at the start (a re-contact starts at tau = p = 0: on it iff B = 0)
        on = contact & (f0 >= -kl.ON_SURFACE_RTOL * (radius0 + abs_tau0))
        indicator = sig0 * kt * dv_c - phi0 * (p1 - p0)        # elastic-predictor rates
        pos_tr = f_tr > 0.0
        if self.indicator == "CLASSICAL":                       # actual (plastic) rates
            h0 = hb0 + hphi0 * p0
            indicator = h0 * indicator / (h0 + kt)
            # kept as the textbook states it
            loading_on = on & (indicator >= 0.0)
        else:
            # paper: unloading iff < 0; at exactly neutral loading (a point resting at the tip
            # of the cone, B = 0, before anything moves) the elastic branch gives the stick
            # tangent, so a body meshed on the foundation is not left without tangential
            # stiffness
            loading_on = on & ((indicator > 0.0) | ((indicator == 0.0) & pos_tr))
        # plastic: loading on the surface; or on it, unloading, and reversed through to the
        # other side of the cone; or starting inside and yielding part-way
        through = pos_tr & contact & (~on | (sig_tr != sig0))
        return loading_on | through, sig_tr, f_tr

    def _return(self, p1, lam0, plastic, f_tr, hard0):
        """Solve ``|tau_tr| - KT Lam - B(lam) - phi(lam) p1 = 0`` piece by piece over kinks,
        from ``f_tr`` (its value at ``Lam = 0``) and ``hard0`` (:meth:`_hardening` at lam0).

        Returns ``lam1``, ``KT + H`` and ``phi`` on the final piece (g,).
        """
        kt = self.kt
        kinks = self._kinks
        lam = lam0
        resid = f_tr
        done = ~plastic
        dmat = np.full_like(lam, kt)
        h = hard0[1] + hard0[3] * p1
        for it in range(len(kinks) + 1):                    # walk over at most two kinks
            if it:
                _, hb, _, hphi = self._hardening(lam)
                h = hb + hphi * p1
            step = resid / (kt + h)
            if kinks:
                ahead = (np.where(lam < kinks[0], kinks[0], np.inf) if len(kinks) == 1 else
                         np.minimum(*(np.where(lam < k, k, np.inf) for k in kinks)))
                cross = ~done & (step > 0.0) & (lam + step > ahead)
                finish = ~done & ~cross
            else:                                           # no kink ahead of any lam
                cross, finish = None, ~done
            if self._may_snap_back and np.any(finish & (kt + h <= 0.0)):
                raise ReturnMappingError(SNAP_BACK)
            dmat = np.where(finish, kt + h, dmat)
            if cross is None:
                lam = np.where(finish, lam + step, lam)
                break
            resid = np.where(cross, resid - (kt + h) * (ahead - lam), resid)  # linear piece
            lam = np.where(finish, lam + step, np.where(cross, ahead, lam))
            done = done | finish
            if done.all():
                break
        phi1 = self._hardening(lam)[2]
        return lam, dmat, phi1

    def _dissipation(self, tau0, p0, dp, dv_c, lam0, dlam, sig, plastic):
        """``int |tau| dlam`` along the exact plastic path (Gauss-Legendre in lam per piece)."""
        act = plastic & (dlam != 0.0)
        if not np.any(act):
            return np.zeros_like(lam0)
        lam1 = lam0 + dlam
        lo, hi = np.minimum(lam0, lam1), np.maximum(lam0, lam1)
        if self._kinks:
            cuts = [np.clip(k, lo, hi) for k in self._kinks]
            edges = np.sort(np.stack([lo, *cuts, hi], axis=-1), axis=-1)   # (g, 2..4)
            a, c = edges[..., :-1], edges[..., 1:]                          # pieces
        else:                                   # no kink anywhere: one piece (g, 1)
            a, c = lo[:, None], hi[:, None]
        lam = 0.5 * (a + c)[..., None] + 0.5 * (c - a)[..., None] * _GL_X   # (g, p, k)
        b, _, phi, _ = self._hardening(lam)
        # s(lam) from |tau_tr(s)| - KT (lam - lam0) = B + phi p(s), linear in s
        ex = lambda x: x[..., None, None]  # noqa: E731  (g,) -> (g, 1, 1)
        num = self.kt * (lam - ex(lam0)) + b + phi * ex(p0) - ex(sig * tau0)
        den = ex(sig * self.kt * dv_c) - phi * ex(dp)
        ok = np.abs(den) > 1e-300
        s = np.minimum(np.maximum(np.where(ok, num / np.where(ok, den, 1.0), 1.0), 0.0), 1.0)
        abs_tau = b + phi * (ex(p0) + ex(dp) * s)
        piece = np.einsum("...pk,k->...p", abs_tau, _GL_W) * 0.5 * (c - a)
        total = piece.sum(axis=-1) if piece.shape[-1] > 1 else piece[..., 0]
        return np.where(act, np.sign(dlam) * total, 0.0)

    def _tangent(self, contact, sep, plastic, recon, partial, d, du, dv, frac, skt, dmat, phi1,
                 active):
        """Exact derivatives of ``tau_new`` and ``lam_new`` (zero ``tau`` derivatives where open).

        The map is ``tau_tr = tau0 + KT dv frac`` and ``p1 = KP max(d, 0)`` followed by the
        return; on the final piece of the return ``D = KT + H``::

            d lam1 = (sgn d tau_tr - phi1 d p1 + KT d lam0) / D
            d tau1 = d tau_tr - sgn KT (d lam1 - d lam0)

        ``skt`` = sgn KT, ``active`` = contact or separating.
        """
        kp, kt = self.kp, self.kt
        c = contact.astype(float)
        active = active.astype(float)
        safe_du = np.where(partial | sep, du, 1.0)
        # frac = d/du on a partial re-contact, d_old/(d_old - d) = 1 - d/du on a separation
        frac_d = np.where(partial, 1.0 / safe_du, np.where(sep, -1.0 / safe_du, 0.0))
        frac_du = np.where(partial, -frac / safe_du, np.where(sep, (1.0 - frac) / safe_du, 0.0))
        ktdv = kt * dv
        dtr = {"d": ktdv * frac_d, "du": ktdv * frac_du, "v": kt * frac,
               "tau": np.where(recon, 0.0, 1.0)}
        kpc = kp * c
        lam_tr, lam_p1, lam_lam = self._lam_rates(plastic, skt, dmat, phi1)
        tan = {}
        for x in ("d", "du", "v", "tau"):
            lam_x = lam_tr * dtr[x]
            if x == "d":
                lam_x = lam_x + lam_p1 * kpc
            lam_x = active * lam_x
            tan["lam_" + x] = lam_x
            tan["tau_" + x] = c * (dtr[x] - skt * lam_x)
        self._tangent_common(tan, c, kpc, plastic, skt, lam_lam)
        return tan

    def _tangent_simple(self, contact, plastic, dv, skt, dmat, phi1):
        """:meth:`_tangent` when no point re-contacts or separates (frac = 1, nothing partial):
        the same values with the zero terms left out."""
        kp, kt = self.kp, self.kt
        c = contact.astype(float)
        kpc = kp * c
        lam_tr, lam_p1, lam_lam = self._lam_rates(plastic, skt, dmat, phi1)
        lam_d = c * (lam_p1 * kpc)
        lam_v = c * (lam_tr * kt)
        lam_tau = c * lam_tr
        zero = np.zeros_like(c)
        tan = {"lam_d": lam_d, "tau_d": c * (0.0 - skt * lam_d), "lam_du": zero,
               "tau_du": zero.copy(), "lam_v": lam_v, "tau_v": c * (kt - skt * lam_v),
               "lam_tau": lam_tau, "tau_tau": c * (1.0 - skt * lam_tau)}
        self._tangent_common(tan, c, kpc, plastic, skt, lam_lam)
        return tan

    def _lam_rates(self, plastic, skt, dmat, phi1):
        """d lam1 / d (tau_tr, p1, lam0) on the final piece (0, 0, 1 where elastic)."""
        kt = self.kt
        sig = skt / kt
        lam_tr = np.where(plastic, sig / dmat, 0.0)
        lam_p1 = np.where(plastic, -phi1 / dmat, 0.0)
        lam_lam = np.where(plastic, kt / dmat, 1.0)
        return lam_tr, lam_p1, lam_lam

    @staticmethod
    def _tangent_common(tan, c, kpc, plastic, skt, lam_lam):
        tan["lam_lam"] = lam_lam
        tan["tau_lam"] = c * np.where(plastic, -skt * (lam_lam - 1.0), 0.0)
        tan["p_d"] = kpc
        tan["p_u"] = kpc.copy()
        tan["tau_u"] = tan["tau_d"] + tan["tau_du"]
        tan["lam_u"] = tan["lam_d"] + tan["lam_du"]
