"""The paper's elasto-plastic friction law in (p, tau): the COULOMB contact-law plugin.

Godinas, Charlier & Cescotto, sections 2-5 (DESIGN.md section 1).  Per contact point ``g``:

* yield ``f = |tau| - rho(lam, p)``, ``rho = min(B(lam) + phi(lam) p, TAUMAX)`` (no cap
  without TAUMAX), each of ``phi(lam)`` and ``B(lam)`` in one of the forms of
  :mod:`~lagamine_py.laws.contact_hardening`: linear ``PHI + HPHI lam``, ``B + HB lam``
  clipped at >= 0 (slope 0 once clipped), exponential ``PHI_INF + (PHI - PHI_INF)
  exp(-lam/LAMC)``, ``B_INF + (B - B_INF) exp(-lam/LAMC_B)``, or a piecewise-linear table of
  both (``*CONTACT LAW TABLE``);
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
frozen, so ``f_e(s) = |tau0 + KT dv s| - rho(lam0, p0 + dp s)`` is convex (``rho`` is concave
in p: linear, or the minimum of a linear function and TAUMAX) and piecewise linear.  A point
starting on the surface (``f0 = 0``) loads plastically iff the paper's elastic-predictor
indicator ``dp_e df/dp + dtau_e df/dtau = sgn(tau0) KT dv - rho_p dp`` is >= 0 (``rho_p =
phi0`` below the cap, 0 on it; the one-sided derivative at the cap itself), i.e. iff ``f_e``
leaves 0 upwards; a point starting inside (or unloading from the surface
and reversing through to the other side of the cone) yields part-way, at the root ``s*`` of
``f_e`` on the side ``sgn(tau_trial)``; by convexity ``f_e > 0`` on ``(s*, 1]`` and the
elastic trial ``tau_tr = tau0 + KT dv`` ends outside: ``f_tr > 0``.

*Plastic part.*  While loading, ``sgn(tau)`` is constant and ``tau = KT (v - v_p)`` gives
``tau(s) = tau_tr(s) - sgn(tau) KT (lam(s) - lam0)`` *exactly*; together with ``f = 0`` at every
``s`` this is an algebraic equation for ``lam(s)``::

      |tau_tr(s)| - KT Lam - rho(lam0 + Lam, p(s)) = 0.

Its solution is the solution of the rate equations (10): differentiating it in ``s`` returns
(10), and its ``Lam``-slope ``-(KT + H)`` never vanishes (``KT + H > 0`` is required).  Loading
persists to the end of the sub-interval once started, whatever the forms: on the surface,
``s (sgn KT dv - phi dp) = KT Lam + (rho(lam, p0) - rho(lam0, p0))``, whose right side is > 0
for ``Lam > 0`` (it increases with ``Lam``, slope ``KT + H > 0``), so ``dLam/ds = (sgn KT dv -
phi dp) / (KT + H) > 0`` all along.  Hence the state at ``s = 1`` is the root of this equation at
``s = 1``; it depends only on ``(tau_tr, p_new, lam0)``.  The root is found piece by piece
between the breaks of the forms (clipping kinks, table rows): exactly on a piece where both
forms are linear, by a safeguarded Newton iteration (bisection inside a bracket, to
``RETURN_XTOL`` = 4e-16 relative, :mod:`lagamine_py.kernels.layout`) where one is
exponential.  With TAUMAX the equation is ``max(r_u, r_c) = 0`` with ``r_u`` the uncapped one
and ``r_c = |tau_tr| - KT Lam - TAUMAX``, both decreasing: its root is the larger of their
roots (on the cap ``tau = sgn TAUMAX``, ``H = 0``, ``rho_p = 0``).
This is the paper's eq. (11) when ``HPHI = HB = 0`` (``tau = sgn (B + phi p_new)``), and it is
exact for *any* increment size with hardening or softening too, so sub-intervals are needed only
to follow the rotation of the local axes in the contact element (``THETA`` and ``SUBSTEPS`` are
read by the contact element; this law does not use them; with ``SUBSTEPS=AUTO`` the element
chooses the count per increment from the rotation of the axes, ``SUBTOL`` and ``SUBMAX``).
The tangent is the exact derivative of this map: ``d tau/d tau_tr = H/(KT+H)``,
``d tau/d p_new = sgn KT rho_p/(KT+H)``, which equals the continuum matrix (10) at the end
state (implicit differentiation of the root: exact whatever the form).

*Dissipation* ``dissip += int |tau| dlam`` along that same exact path: for a given ``lam`` the
algebraic equation is linear in ``s``, so ``|tau| = min(B(lam) + phi(lam) p(s(lam)), TAUMAX)``
is known in closed form and is integrated by 8-point Gauss-Legendre in ``lam`` on each piece
between breaks (exact when ``p`` is constant and the forms linear; rational and smooth
otherwise), a piece cut where the cap takes over (located by bisection) and, with an
exponential form, into panels at most ``2 LAMC`` long (the rule's relative error on an
exponential is then below 1e-18).

*Contact* is ``d >= 0``: a point exactly touching (``d = 0``, e.g. a body meshed on the
foundation) is closed with ``p = 0`` and the elastic tangent, so the first iteration of a
loaded step already has contact stiffness.  *Re-contact* (``p_old == 0`` and ``d >= 0``) starts from ``p = tau = 0`` with the part of ``dv``
after contact, ``dv d/du`` when ``0 < d <= du``.  *Separation* (``d < 0``): ``p = tau = 0``,
OPEN; ``lam``, ``slip``, ``vp``, ``dissip`` are kept while open.  In the sub-interval where a point
separates (``p_old > 0``, ``d < 0``) the part before ``d`` reaches 0 (fraction
``d_old/(d_old - d)`` of ``dv``, ``p`` falling to 0) is integrated like any other, so the slip
forced by the shrinking cone is not lost; only then are ``p`` and ``tau`` zeroed.

Augmented Lagrangian (``METHOD=AUGMENTED``, :meth:`Coulomb.augment`)
--------------------------------------------------------------------
The penalties stay moderate and multipliers, held fixed during a Newton solve, carry the rest
of the contact stresses (Uzawa, as Abaqus and ANSYS do it: augmentations around Newton, each a
Newton solve of the same increment).  They enter as shifts of the penalty springs, in length
units, in the state: ``an`` (normal, ``lambda_N / KP``) and ``at`` (tangential, ``lambda_T /
KT``) for this solve, ``sn``, ``st`` the ones the committed state was computed with.  The law
integrates the effective penetration ``d + an`` (so ``p = KP max(d + an, 0)``: contact where
``d + an >= 0``) and adds ``KT (at - st)`` to the elastic predictor of ``tau`` (``tau = KT
(v - vp + at)``: the same law, its springs pre-stressed), in the first sub-interval only (its
state then holds ``sn = an``, ``st = at``).  After a converged solve :meth:`Coulomb.augment`
sets ``an = p / KP``, ``at = tau / KT`` (0 where open) and asks for another solve unless every
change is within ``PTOL`` times the point's face length: that change is the penetration ``d``
(or the gap of a point with pressure), and at a sticking point the elastic slip ``tau/KT - at``,
so at convergence both are below ``PTOL h``, whatever KP and KT.  Nothing else is kept between
solves: a cut-back or a restart goes back to the committed state and its multipliers.

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
from .contact_hardening import Exponential, Form, Linear, table_forms

__all__ = ["Coulomb", "SNAP_BACK"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_ADMISSIBLE_RTOL = 1e-7    # |tau| beyond the cone by more than this (relative): an error
#: the message of a softening snap-back (the increment is cut back)
SNAP_BACK = "COULOMB: KT + dB/dlam + p dphi/dlam <= 0 at a slipping point (softening snap-back)"
#: the state arrays of METHOD=AUGMENTED (length-unit multipliers, see the module docstring)
AUGMENTED_KEYS = ("an", "at", "sn", "st")
TABLE = "CONTACT LAW TABLE"


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
        Param("PHI", float, None, bounds=(0.0, None),
              doc="friction coefficient phi at lam = 0 (required unless a *CONTACT LAW TABLE "
                  "gives phi and B)"),
        Param("B", float, 0.0, bounds=(0.0, None), unit="stress", doc="adhesion B at lam = 0"),
        Param("HPHI", float, 0.0, unit="1/length", doc="dphi/dlam (phi clipped at >= 0)"),
        Param("HB", float, 0.0, unit="stress/length",
              doc="dB/dlam, < 0 is softening (B clipped at >= 0); KT + HB must stay > 0"),
        Param("PHI_INF", float, None, bounds=(0.0, None),
              doc="exponential friction: phi = PHI_INF + (PHI - PHI_INF) exp(-lam/LAMC) "
                  "(run-in: PHI_INF > PHI; with LAMC, instead of HPHI)"),
        Param("LAMC", float, None, gt=0.0, unit="length",
              doc="the slip over which phi moves by a factor e towards PHI_INF"),
        Param("B_INF", float, None, bounds=(0.0, None), unit="stress",
              doc="exponential adhesion: B = B_INF + (B - B_INF) exp(-lam/LAMC_B) (wear: "
                  "B_INF < B; with LAMC_B, instead of HB)"),
        Param("LAMC_B", float, None, gt=0.0, unit="length",
              doc="the slip over which B moves by a factor e towards B_INF"),
        Param(TABLE, tuple, None, columns=("lambda", "phi", "B"),
              doc="phi and B piecewise linear in the slip lam, flat beyond the last row (first "
                  "row at lam = 0; instead of PHI, B and their hardening)"),
        Param("TAUMAX", float, None, gt=0.0, unit="stress",
              doc="shear limit: |tau| <= min(B + phi p, TAUMAX) (LAGAMINE's COU2DC)"),
        Param("METHOD", str, "PENALTY", choices=("PENALTY", "AUGMENTED"),
              doc="PENALTY; or AUGMENTED: augmented Lagrangian, Newton solves repeated with "
                  "updated multipliers until the penetration and the elastic slip of sticking "
                  "points are below PTOL times the face length"),
        Param("PTOL", float, None, gt=0.0,
              doc="METHOD=AUGMENTED: tolerance on the penetration and the elastic stick slip, "
                  "relative to each point's face length (required with AUGMENTED)"),
        Param("AUGMAX", int, 20, bounds=(1, None),
              doc="METHOD=AUGMENTED: augmentations per increment at most (then a warning)"),
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
        """Exponential run-in friction, linear adhesion hardening and a shear limit that the
        contract's probes reach: every tangent entry plays, on and off the cap."""
        return {"KP": 1e5, "KT": 1e5, "PHI": 0.3, "B": 1.0, "HB": 10.0, "PHI_INF": 0.5,
                "LAMC": 1e-3, "TAUMAX": 40.0}

    def __init__(self, **values):
        super().__init__(**values)
        self.b_form, self.phi_form = self._forms()
        self.b, self.phi = float(self.b_form(0.0)[0]), float(self.phi_form(0.0)[0])   # at lam = 0
        steep = self.b_form.steepest()
        if self.kt + steep <= 0.0:
            what = {Linear: f"HB = {steep:g}", Exponential: f"(B - B_INF)/LAMC_B = {-steep:g}"}.get(
                type(self.b_form), f"a table slope of B of {steep:g}")
            rule = "KT + HB" if isinstance(self.b_form, Linear) else "KT + dB/dlam"
            raise ParamError(f"{what} softens faster than the tangential penalty KT = "
                             f"{self.kt:g} allows ({rule} must be > 0: snap-back)")
        if self.method == "AUGMENTED" and self.ptol is None:
            raise ParamError("METHOD=AUGMENTED needs PTOL, the penetration tolerance relative to "
                             "the face length (PTOL=1e-4, say)")
        if self.method != "AUGMENTED" and self.values["PTOL"] is not None:
            raise ParamError("PTOL is the tolerance of METHOD=AUGMENTED: give METHOD=AUGMENTED "
                             "or leave PTOL out")
        self.augmented = self.method == "AUGMENTED"
        self.cap = self.taumax if self.taumax is not None else np.inf
        self._vector = None                   # the kernel's parameter vector, on first use
        forms = (self.b_form, self.phi_form)
        # where a derivative jumps (clipping kinks, table rows): the return walks over them
        self._breaks = np.array(sorted(set(b for f in forms for b in f.breaks)), float)
        self._smooth = any(f.smooth for f in forms)
        self._scale = min(f.scale for f in forms)
        # KT + H > 0 always when neither B nor phi ever decreases (H >= 0, p >= 0)
        self._may_snap_back = any(f.steepest() < 0.0 for f in forms)
        self._constant = all(f.constant() for f in forms)

    def _forms(self) -> tuple[Form, Form]:
        """The forms of B and phi from the parameters; one clear message for each misuse."""
        v = self.values
        given = lambda *names: [n for n in names if v[n] not in (None, 0.0)]  # noqa: E731
        if v[TABLE] is not None:
            extra = given("PHI", "B", "HPHI", "HB", "PHI_INF", "LAMC", "B_INF", "LAMC_B")
            if extra or v["PHI"] is not None:
                extra = extra or ["PHI"]
                raise ParamError(f"the *CONTACT LAW TABLE gives phi and B: leave "
                                 f"{', '.join(extra)} out")
            _, phi, b = table_forms(v[TABLE])
            return b, phi
        if v["PHI"] is None:
            raise ParamError("missing required parameter PHI (or a *CONTACT LAW TABLE of lam, "
                             "phi, B)")
        return (self._form("B", v["B"], "HB", "B_INF", "LAMC_B"),
                self._form("PHI", v["PHI"], "HPHI", "PHI_INF", "LAMC"))

    def _form(self, name, v0, slope, inf, length) -> Form:
        v = self.values
        if (v[inf] is None) != (v[length] is None):
            missing = length if v[length] is None else inf
            raise ParamError(f"{inf} and {length} go together (the exponential form of {name}): "
                             f"{missing} is missing")
        if v[inf] is None:
            return Linear(v0, v[slope])
        if v[slope] != 0.0:
            raise ParamError(f"{name} is linear ({slope}) or exponential ({inf}, {length}), not "
                             f"both")
        return Exponential(v0, v[inf], v[length])

    # -- hardening functions ---------------------------------------------------------------
    @property
    def breaks(self) -> tuple[float, ...]:
        """The slips where a derivative of B or phi jumps (clipping kinks, table rows), sorted."""
        return tuple(float(b) for b in self._breaks)

    def adhesion(self, lam):
        """``B(lam)`` and its right-derivative (arrays of lam's shape)."""
        lam = np.asarray(lam, float)
        return tuple(np.broadcast_to(np.asarray(x, float), lam.shape).copy()
                     for x in self.b_form(lam))

    def friction(self, lam):
        """``phi(lam)`` and its right-derivative (arrays of lam's shape)."""
        lam = np.asarray(lam, float)
        return tuple(np.broadcast_to(np.asarray(x, float), lam.shape).copy()
                     for x in self.phi_form(lam))

    def radius(self, lam, p):
        """The yield radius ``min(B(lam) + phi(lam) p, TAUMAX)``."""
        b, _, phi, _ = self._hardening(np.asarray(lam, float))
        return self._radius(b, phi, np.asarray(p, float))

    def _radius(self, b, phi, p):
        u = b + phi * p
        return u if self.taumax is None else np.minimum(u, self.cap)

    # -- one sub-interval ----------------------------------------------------------------
    def kernel_vector(self):
        """The parameters as :mod:`lagamine_py.kernels.contact` reads them (layout in
        :mod:`lagamine_py.kernels.layout`); None for a subclass, which may change anything,
        and for METHOD=AUGMENTED (its multipliers are NumPy's only)."""
        if type(self) is not Coulomb or self.augmented:
            return None
        if self._vector is None:
            nb = len(self._breaks)
            table = self.values[TABLE]
            nt = 0 if table is None else len(table)
            h = kl.COULOMB_VECTOR
            v = np.zeros(h + nb + 5 * nt)
            v[kl.COULOMB_KP], v[kl.COULOMB_KT] = self.kp, self.kt
            v[kl.COULOMB_CLASSICAL] = self.indicator == "CLASSICAL"
            v[kl.COULOMB_PREDICTOR] = self.indicator == "PREDICTOR"
            v[kl.COULOMB_SNAP] = self._may_snap_back
            v[kl.COULOMB_TAUMAX] = self.cap
            v[kl.COULOMB_NBREAK], v[kl.COULOMB_NTABLE] = nb, nt
            v[kl.COULOMB_SMOOTH], v[kl.COULOMB_SCALE] = self._smooth, self._scale
            v[h:h + nb] = self._breaks
            if nt:
                v[h + nb:h + nb + nt] = np.asarray(table, float)[:, 0]
            self.b_form.encode(v, kl.COULOMB_B_FORM, h + nb + nt)
            self.phi_form.encode(v, kl.COULOMB_PHI_FORM, h + nb + 3 * nt)
            self._vector = v
        return self._vector

    def penalties(self) -> dict[str, tuple[float, bool]]:
        """KP always plays; KT only when the law can carry a shear stress (phi or B nonzero
        somewhere): frictionless contact never uses it."""
        forms = (self.b_form, self.phi_form)
        friction = any(f.upper() > 0.0 or f.steepest() != 0.0 for f in forms)
        return {"KP": (self.kp, True), "KT": (self.kt, friction)}

    def init_state(self, n: int) -> dict[str, np.ndarray]:
        state = super().init_state(n)
        if self.augmented:
            for key in AUGMENTED_KEYS:
                state[key] = np.zeros(n)
        return state

    def augment(self, state, h):
        """METHOD=AUGMENTED: the multipliers after a converged solve (see the module docstring)
        and how far the constraints are from the tolerance.

        ``state``: the solve's trial state; ``h`` (g,) the face length of each point.  Returns
        ``(targets, ratio)``: ``targets`` the dict ``{"an": p/KP, "at": tau/KT}`` (0 where open)
        for the next solve, or None when every change is within ``PTOL h`` (nothing to do);
        ``ratio`` the largest change over ``PTOL h``.  PENALTY: ``(None, 0.0)``."""
        if not self.augmented:
            return None, 0.0
        closed = np.asarray(state["status"]) != OPEN
        an = np.where(closed, np.asarray(state["p"], float) / self.kp, 0.0)
        at = np.where(closed, np.asarray(state["tau"], float) / self.kt, 0.0)
        change_n = np.abs(an - np.asarray(state["an"], float))
        # the elastic slip of sticking points (slipping ones carry no tangential constraint)
        stick = np.asarray(state["status"]) == STICK
        change_t = np.where(stick, np.abs(at - np.asarray(state["at"], float)), 0.0)
        tol = self.ptol * np.asarray(h, float)
        ratio = float(np.max(np.maximum(change_n, change_t) / tol, initial=0.0))
        if ratio <= 1.0:
            return None, ratio
        return {"an": an, "at": at}, ratio

    def stored_energy(self, state) -> np.ndarray:
        """``p^2 / (2 KP) + tau^2 / (2 KT)`` per unit area: the elastic energy of the normal and
        tangential penalty springs (``p = KP d``, ``tau`` = KT times the elastic part of the
        tangential displacement); a frictionless law (``tau = 0``) stores none tangentially.
        Not with METHOD=AUGMENTED: the multipliers' work is not a spring's energy, and
        ``p^2 / 2 KP`` would put a wrong number in the balance (an energy check is refused)."""
        if self.method == "AUGMENTED":
            raise NotImplementedError(
                "METHOD=AUGMENTED reports no stored (penalty) energy: the multipliers' work is not "
                "accounted for; use METHOD=PENALTY for an energy check")
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
        tshift = None
        if self.augmented:            # the multipliers' shifts (the module docstring)
            an = np.asarray(state["an"], float)
            d = d + an
            du = du + (an - np.asarray(state["sn"], float))
            tshift = kt * (np.asarray(state["at"], float) - np.asarray(state["st"], float))
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
        dte = kt * dv_c                            # the elastic predictor's tau increment
        if tshift is not None:
            dte = dte + tshift
        tau_tr = tau0 + dte

        hard0 = self._hardening(lam0)
        plastic, sig, f_tr = self._loading(tau0, p0, p1, hard0, dte, tau_tr, active)
        if not free:
            plastic = np.where(hold == STICK, False, np.where(hold == SLIP, contact, plastic))
        lam1, dmat, rho_p = self._return(p1, lam0, plastic, f_tr, hard0, np.abs(tau_tr))
        dlam = np.where(plastic, lam1 - lam0, 0.0)
        if self.indicator == "PREDICTOR":     # roundoff guard at neutral loading
            dlam = np.maximum(dlam, 0.0) if free else np.where(hold == SLIP, dlam,
                                                               np.maximum(dlam, 0.0))
        skt = sig * kt                         # sgn(tau) KT, exactly +-KT
        tau1 = np.where(contact, tau_tr - skt * dlam, 0.0)
        ddis = self._dissipation(tau0, p0, p1 - p0, dte, lam0, dlam, sig, plastic)

        new_state = dict(state)
        new_state.update(
            p=p1, tau=tau1, lam=lam0 + dlam, slip=np.asarray(state["slip"], float) + np.abs(dlam),
            vp=np.asarray(state["vp"], float) + sig * dlam,      # dv_p = dlam sgn(tau)
            dissip=np.asarray(state["dissip"], float) + ddis,
            # OPEN, STICK, SLIP = 0, 1, 2: contact + (plastic and contact), as int8
            status=contact.view(np.int8) + (plastic & contact).view(np.int8))
        if self.augmented:                     # the shifts are in: later sub-intervals add none
            new_state["sn"], new_state["st"] = np.array(an), np.array(state["at"], float)
        if simple:
            tan = self._tangent_simple(contact, plastic, dv, skt, dmat, rho_p)
        else:
            tan = self._tangent(contact, sep, plastic, recon, partial, d, du, dv, frac, skt,
                                dmat, rho_p, active)
        return new_state, tan

    def inadmissible(self, state) -> np.ndarray:
        """(g,) bool: points of ``state`` outside the yield cone, ``|tau| > rho(lam, p)``
        beyond round-off (``1e-7 (|tau| + radius + p) + 1e-12 KT``: with PHI = B = 0 the exact
        tau = 0 comes out as the round-off of ``tau_tr - KT dlam``).

        The exact integration never leaves such a point; ``INDICATOR=CLASSICAL`` under softening
        does (it takes plastic loading for unloading) and a frozen STICK point may.  The contact
        element reports these points as a failure of the increment (the solver cuts back, then
        stops with exit 3), so the wrong answer is never passed on silently."""
        tau = np.asarray(state["tau"], float)
        b, _, phi, _ = self._hardening(np.asarray(state["lam"], float))
        p = np.asarray(state["p"], float)
        radius = self._radius(b, phi, p)
        abs_tau = np.abs(tau)
        tol = _ADMISSIBLE_RTOL * (radius + abs_tau + p) + 1e-12 * self.kt
        return abs_tau - radius > tol

    def inadmissible_hint(self) -> str:
        return (" (INDICATOR=CLASSICAL takes plastic loading for unloading under softening; "
                "use PREDICTOR)" if self.indicator == "CLASSICAL" else "")

    def _hardening(self, lam):
        """``B, B', phi, phi'`` at ``lam``, as plain floats for a linear form with slope 0 (the
        common case: fewer array operations, same values)."""
        b, hb = self.b_form(lam)
        phi, hphi = self.phi_form(lam)
        return b, hb, phi, hphi

    def _loading(self, tau0, p0, p1, hard0, dte, tau_tr, contact):
        """Which points load plastically in this sub-interval, sgn(tau) while they do, and the
        trial yield function ``f_tr`` (at ``lam0``).

        ``contact``: points in contact during (part of) the sub-interval; the others are
        never plastic.  ``hard0``: :meth:`_hardening` at ``lam0``; ``dte`` the elastic
        predictor's increment of tau.
        """
        kt = self.kt
        b0, hb0, phi0, hphi0 = hard0
        u0 = b0 + phi0 * p0
        dp = p1 - p0
        rho_rate = phi0 * dp                 # d rho along the path: 0 on the cap
        if self.taumax is None:
            radius0 = u0
            f_tr = np.abs(tau_tr) - b0 - phi0 * p1
        else:
            radius0 = np.minimum(u0, self.cap)
            f_tr = np.abs(tau_tr) - np.minimum(b0 + phi0 * p1, self.cap)
            rho_rate = np.where(u0 < self.cap, rho_rate,
                                np.where(u0 > self.cap, 0.0, np.minimum(rho_rate, 0.0)))
        abs_tau0 = np.abs(tau0)
        f0 = abs_tau0 - radius0
        sig_tr = np.where(tau_tr >= 0.0, 1.0, -1.0)
        sig0 = np.where(tau0 != 0.0, np.sign(tau0), np.where(dte >= 0.0, 1.0, -1.0))
        # on the surface at the start (a re-contact starts at tau = p = 0: on it iff B = 0)
        on = contact & (f0 >= -kl.ON_SURFACE_RTOL * (radius0 + abs_tau0))
        indicator = sig0 * dte - rho_rate                       # elastic-predictor rates
        pos_tr = f_tr > 0.0
        if self.indicator == "CLASSICAL":                       # actual (plastic) rates
            h0 = hb0 + hphi0 * p0
            if self.taumax is not None:
                h0 = np.where(u0 < self.cap, h0, 0.0)
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

    def _return(self, p1, lam0, plastic, f_tr, hard0, abs_tr):
        """Solve ``|tau_tr| - KT Lam - rho(lam0 + Lam, p1) = 0`` for the plastic points: the
        uncapped equation piece by piece over the breaks (:meth:`_walk`), then the cap.

        Returns ``lam1``, ``KT + H`` and ``rho_p = d rho / d p1`` at the root (g,)."""
        if self.taumax is None:
            lam, dmat, snap = self._walk(p1, lam0, plastic, f_tr, hard0, abs_tr)
            if snap is not None and np.any(snap):
                raise ReturnMappingError(SNAP_BACK)
            return lam, dmat, self._hardening(lam)[2]
        b0, _, phi0, _ = hard0
        lam_u, dmat, snap = self._walk(p1, lam0, plastic, abs_tr - (b0 + phi0 * p1), hard0,
                                       abs_tr)
        lam_c = lam0 + (abs_tr - self.cap) / self.kt
        capped = plastic & (lam_c > lam_u)
        if snap is not None and np.any(snap & ~capped):
            raise ReturnMappingError(SNAP_BACK)
        lam = np.where(capped, lam_c, lam_u)
        phi1 = self._hardening(lam)[2]
        return lam, np.where(capped, self.kt, dmat), np.where(capped, 0.0, phi1)

    def _walk(self, p1, lam0, plastic, resid, hard0, abs_tr):
        """The uncapped return: the root of ``r(lam) = |tau_tr| - KT (lam - lam0) - B(lam) -
        phi(lam) p1`` from ``r(lam0) = resid``, piece by piece between the breaks.  On a piece
        where both forms are linear ``r`` is linear: one step; with an exponential form the
        piece's root comes from :meth:`_newton` once ``r`` at the piece's end is <= 0.

        Returns ``lam1``, ``KT + H`` at it, and the points whose ``KT + H <= 0`` (snap-back;
        None when the law cannot soften)."""
        kt = self.kt
        breaks = self._breaks
        lam = lam0
        done = ~plastic
        dmat = np.full_like(lam, kt)
        snap = np.zeros(lam.shape, bool) if self._may_snap_back else None
        h = hard0[1] + hard0[3] * p1
        for it in range(len(breaks) + 1):                   # walk over the breaks
            if it:
                _, hb, _, hphi = self._hardening(lam)
                h = hb + hphi * p1
            if len(breaks):
                idx = np.searchsorted(breaks, lam, side="right")
                ahead = np.where(idx < len(breaks), breaks[np.minimum(idx, len(breaks) - 1)],
                                 np.inf)
            else:
                ahead = None
            if self._smooth:
                lam, dmat, resid, done, finish = self._smooth_piece(
                    p1, lam0, lam, resid, done, dmat, ahead, abs_tr)
            else:
                step = resid / (kt + h)
                if ahead is None:                           # no break ahead of any lam
                    cross, finish = None, ~done
                else:
                    cross = ~done & (step > 0.0) & (lam + step > ahead)
                    finish = ~done & ~cross
                dmat = np.where(finish, kt + h, dmat)
                if cross is None:
                    lam = np.where(finish, lam + step, lam)
                else:
                    resid = np.where(cross, resid - (kt + h) * (ahead - lam), resid)  # linear
                    lam = np.where(finish, lam + step, np.where(cross, ahead, lam))
                done = done | finish
            if snap is not None:
                snap |= finish & (dmat <= 0.0)
            if done.all():
                break
        return lam, dmat, snap

    def _residual(self, x, lam0, p1, abs_tr):
        """``r(x)`` of :meth:`_walk` and its slope ``-(KT + H(x))``."""
        b, hb, phi, hphi = self._hardening(x)
        return abs_tr - self.kt * (x - lam0) - b - phi * p1, self.kt + hb + hphi * p1

    def _smooth_piece(self, p1, lam0, lam, resid, done, dmat, ahead, abs_tr):
        """One piece of :meth:`_walk` with an exponential form: cross to the piece's end where
        ``r`` is still > 0 there, else iterate to the root inside it."""
        if ahead is None:
            cross = np.zeros(lam.shape, bool)
            r_ahead = resid
            end = np.full_like(lam, np.inf)
        else:
            fin = np.isfinite(ahead)
            end = np.where(fin, ahead, np.inf)
            r_ahead, _ = self._residual(np.where(fin, ahead, lam), lam0, p1, abs_tr)
            cross = ~done & (resid > 0.0) & fin & (r_ahead > 0.0)
        finish = ~done & ~cross
        if finish.any():
            x, slope = self._newton(p1, lam0, lam, resid, finish, end, abs_tr)
            lam = np.where(finish, x, lam)
            dmat = np.where(finish, slope, dmat)
        lam = np.where(cross, ahead if ahead is not None else lam, lam)
        resid = np.where(cross, r_ahead, resid)
        return lam, dmat, resid, done | finish, finish

    def _newton(self, p1, lam0, lam, resid, work, end, abs_tr):
        """Safeguarded Newton for the root of ``r`` from ``lam`` (``r(lam) = resid``) at the
        points ``work``: forwards (resid > 0) inside ``[lam, min(end, lam0 + Lmax)]`` with
        ``Lmax`` from the forms' lower bounds (``r <= 0`` there); backwards (a SLIP hold
        unloading, resid < 0) from ``lam`` down, bracketed by the forms' upper bounds when
        finite.  A Newton step that leaves the bracket is replaced by its midpoint.

        Returns the root and ``KT + H`` there."""
        kt = self.kt
        b_lo, phi_lo = self.b_form.lower(), self.phi_form.lower()
        b_hi, phi_hi = self.b_form.upper(), self.phi_form.upper()
        fwd = resid > 0.0
        lo = np.where(fwd, lam, lam0 + (abs_tr - b_hi - phi_hi * p1) / kt)
        hi = np.where(fwd, np.minimum(end, lam0 + (abs_tr - b_lo - phi_lo * p1) / kt), lam)
        x = lam.copy()
        active = work & (resid != 0.0)
        for _ in range(kl.RETURN_MAXIT):
            if not active.any():
                break
            r, slope = self._residual(x, lam0, p1, abs_tr)
            lo = np.where(active & (r > 0.0), x, lo)
            hi = np.where(active & (r < 0.0), x, hi)
            xn = x + r / slope
            bracketed = np.isfinite(lo) & np.isfinite(hi)
            xn = np.where(bracketed & ~((xn > lo) & (xn < hi)), 0.5 * (lo + hi), xn)
            conv = (r == 0.0) | (np.abs(xn - x) <= kl.RETURN_XTOL * (np.abs(x) + np.abs(x - lam0)))
            x = np.where(active & (r != 0.0), xn, x)
            active = active & ~conv
        _, slope = self._residual(x, lam0, p1, abs_tr)
        return x, slope

    def _dissipation(self, tau0, p0, dp, dte, lam0, dlam, sig, plastic):
        """``int |tau| dlam`` along the exact plastic path: 8-point Gauss-Legendre in lam on each
        piece between breaks, on panels of at most ``PANEL_LENGTH`` LAMC with an exponential
        form, each panel cut where TAUMAX takes over."""
        act = plastic & (dlam != 0.0)
        if not np.any(act):
            return np.zeros_like(lam0)
        lam1 = lam0 + dlam
        lo, hi = np.minimum(lam0, lam1), np.maximum(lam0, lam1)
        if len(self._breaks):
            cuts = [np.clip(k, lo, hi) for k in self._breaks]
            edges = np.sort(np.stack([lo, *cuts, hi], axis=-1), axis=-1)   # (g, pieces + 1)
            a, c = edges[..., :-1], edges[..., 1:]                          # pieces
        else:                                   # no break anywhere: one piece (g, 1)
            a, c = lo[:, None], hi[:, None]
        path = (tau0, p0, dp, dte, lam0, sig)
        if self._smooth:                        # panels of at most PANEL_LENGTH LAMC
            n = np.clip(np.ceil((c - a) / (kl.PANEL_LENGTH * self._scale)), 1, kl.MAX_PANELS)
            n = np.nan_to_num(n, nan=1.0)       # a NaN state: one panel (NaN all the same)
            j = np.arange(int(n.max(initial=1)))
            a, c = (a[..., None] + (c - a)[..., None] * (np.minimum(j, n[..., None]) / n[..., None]),
                    a[..., None] + (c - a)[..., None] * (np.minimum(j + 1, n[..., None])
                                                         / n[..., None]))
            a, c = a.reshape(len(lo), -1), c.reshape(len(lo), -1)
        if self.taumax is None:
            piece = self._gauss(a, c, path)
        else:                                   # cut where the cap takes over
            x = self._cap_switch(a, c, path)
            piece = self._gauss(a, x, path) + self._gauss(x, c, path)
        total = piece.sum(axis=-1) if piece.shape[-1] > 1 else piece[..., 0]
        return np.where(act, np.sign(dlam) * total, 0.0)

    def _abs_tau(self, lam, path):
        """``|tau|`` on the plastic path at ``lam`` (any shape (g, ...)): ``s(lam)`` from the
        consistency condition, linear in s, then ``min(B + phi p(s), TAUMAX)``."""
        tau0, p0, dp, dte, lam0, sig = path
        ex = lambda x: x.reshape(x.shape + (1,) * (lam.ndim - 1))  # noqa: E731  (g,) -> (g, 1..)
        b, _, phi, _ = self._hardening(lam)
        # s(lam) from |tau_tr(s)| - KT (lam - lam0) = B + phi p(s), linear in s
        num = self.kt * (lam - ex(lam0)) + b + phi * ex(p0) - ex(sig * tau0)
        den = ex(sig * dte) - phi * ex(dp)
        ok = np.abs(den) > 1e-300
        s = np.minimum(np.maximum(np.where(ok, num / np.where(ok, den, 1.0), 1.0), 0.0), 1.0)
        abs_tau = b + phi * (ex(p0) + ex(dp) * s)
        return abs_tau if self.taumax is None else np.minimum(abs_tau, self.cap)

    def _gauss(self, a, c, path):
        """8-point Gauss-Legendre of ``|tau|`` on each panel ``[a, c]`` (g, k) -> (g, k)."""
        lam = 0.5 * (a + c)[..., None] + 0.5 * (c - a)[..., None] * _GL_X   # (g, k, 8)
        return np.einsum("...pk,k->...p", self._abs_tau(lam, path), _GL_W) * 0.5 * (c - a)

    def _cap_switch(self, a, c, path):
        """Where in ``[a, c]`` (g, k) the cap takes over or lets go (bisection on
        ``B + phi p(s) - TAUMAX``, ``CAP_BISECTIONS`` steps); ``c`` where the panel has no
        switch (one switch per panel at most is assumed)."""
        def over(lam):
            tau0, p0, dp, dte, lam0, sig = path
            ex = lambda x: x.reshape(x.shape + (1,) * (lam.ndim - 1))  # noqa: E731
            b, _, phi, _ = self._hardening(lam)
            num = self.kt * (lam - ex(lam0)) + b + phi * ex(p0) - ex(sig * tau0)
            den = ex(sig * dte) - phi * ex(dp)
            ok = np.abs(den) > 1e-300
            s = np.minimum(np.maximum(np.where(ok, num / np.where(ok, den, 1.0), 1.0), 0.0),
                           1.0)
            return b + phi * (ex(p0) + ex(dp) * s) >= self.cap
        oa, oc = over(a), over(c)
        switch = oa != oc
        if not switch.any():
            return c
        lo, hi = a.copy(), c.copy()
        for _ in range(kl.CAP_BISECTIONS):
            m = 0.5 * (lo + hi)
            same = over(m) == oa
            lo, hi = np.where(same, m, lo), np.where(same, hi, m)
        return np.where(switch, 0.5 * (lo + hi), c)

    def _tangent(self, contact, sep, plastic, recon, partial, d, du, dv, frac, skt, dmat, rho_p,
                 active):
        """Exact derivatives of ``tau_new`` and ``lam_new`` (zero ``tau`` derivatives where open).

        The map is ``tau_tr = tau0 + KT dv frac`` and ``p1 = KP max(d, 0)`` followed by the
        return; on the final piece of the return ``D = KT + H``::

            d lam1 = (sgn d tau_tr - rho_p d p1 + KT d lam0) / D
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
        lam_tr, lam_p1, lam_lam = self._lam_rates(plastic, skt, dmat, rho_p)
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

    def _tangent_simple(self, contact, plastic, dv, skt, dmat, rho_p):
        """:meth:`_tangent` when no point re-contacts or separates (frac = 1, nothing partial):
        the same values with the zero terms left out."""
        kp, kt = self.kp, self.kt
        c = contact.astype(float)
        kpc = kp * c
        lam_tr, lam_p1, lam_lam = self._lam_rates(plastic, skt, dmat, rho_p)
        lam_d = c * (lam_p1 * kpc)
        lam_v = c * (lam_tr * kt)
        lam_tau = c * lam_tr
        zero = np.zeros_like(c)
        tan = {"lam_d": lam_d, "tau_d": c * (0.0 - skt * lam_d), "lam_du": zero,
               "tau_du": zero.copy(), "lam_v": lam_v, "tau_v": c * (kt - skt * lam_v),
               "lam_tau": lam_tau, "tau_tau": c * (1.0 - skt * lam_tau)}
        self._tangent_common(tan, c, kpc, plastic, skt, lam_lam)
        return tan

    def _lam_rates(self, plastic, skt, dmat, rho_p):
        """d lam1 / d (tau_tr, p1, lam0) on the final piece (0, 0, 1 where elastic)."""
        kt = self.kt
        sig = skt / kt
        lam_tr = np.where(plastic, sig / dmat, 0.0)
        lam_p1 = np.where(plastic, -rho_p / dmat, 0.0)
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
