"""The contact element group (paper section 6): CT3 on the 3-node faces of quadratic elements (Q8,
T6), and its linear counterpart on the 2-node faces of Q4 elements, against a rigid parabolic-arc
foundation.

Axes: ``f`` face (contact element), ``q`` Gauss point on the face, ``g`` = ``f*nq + q``
flattened contact point, ``a`` face node (corner, corner[, mid]), ``i``/``j`` spatial
component, ``J``/``L`` face DOF ``2a + i``.

Kinematics at a Gauss point P of the deformed face, with ``t = (x_xi, y_xi)`` (faces run in
the element's counter-clockwise order, so the body lies on their left)::

    e_u = (y_xi, -x_xi)/|t|     outward normal of the body (towards the foundation)
    e_v = -(x_xi, y_xi)/|t|

Q is where the line (P, e_u) meets the foundation, ``Q = P - d e_u`` (``d > 0``: contact);
see :mod:`lagamine_py.foundation`.  Points whose line misses the foundation are open (d is
passed to the law as 0, with zero derivative).

Integration over an increment (paper section 5): the increment is split into ``N =
law.substeps`` sub-intervals with the nodal positions and the foundation translation moving
linearly; the penetration moves linearly too between its values projected at the start and at
the end of the increment, ``d_k = d_0 + (k/N) (d_N - d_0)``, ``du_k = d_k - d_{k-1}``, and the
tangential relative displacement ``dv_k = e_v(theta) . (dP_k - dc_k)`` uses the axes at
``t_{k-1} + theta (t_k - t_{k-1})`` (``theta = law.theta``).  The penetration is *not*
projected from the intermediate configurations: on a curved foundation the straight-line
(chord) path of the nodes under a rotation lifts the face off the foundation by the chord's
sag, ``R (1 - cos(dalpha/2))``, far more than a penalty penetration (the block turned in a cup,
``tools/study_decks/cup_rotation.dat``, 3.6 degrees per increment: sag 0.01 mm against a
penetration of 1e-4 mm).  Projected, every sub-interval but the last opened the contact and the
slip restarted elastic: 2 sub-intervals lost 70-90 % of a 21 mm slip (measured,
``docs/stability.md``).

``SUBSTEPS=AUTO`` (adaptive sub-intervals): the law integrates each sub-interval exactly, so
the only error the count controls is that of taking the axes fixed at one instant of each
sub-interval while the face turns.  The nodes move on the straight chord of the increment, so
sub-intervals cannot recover the arc of a rotation: for a rigid turn by ``dalpha`` the slip
measured falls short of the arc by about ``dalpha^2/6`` (relative) with one sub-interval and
THETA = 0 or 1, ``dalpha^2/24`` with THETA = 1/2, and tends to ``dalpha^2/12`` for many
sub-intervals whatever THETA (``tests/test_substeps_auto.py`` checks the closed form): more
sub-intervals help THETA = 0 and 1, not THETA = 1/2.  The element measures the rotation angle
of the face
tangent between the start and end configurations at every Gauss point and takes
``N = ceil(max angle / SUBTOL)``, clipped to ``[1, SUBMAX]`` -- one count for the whole group
in this increment (the sub-interval loop is batched over all points, so a per-point count
would cost the same as the largest one and be less accurate).  Without NLGEOM the axes do
not turn: N = 1.  N is a piecewise-constant function of ``u_new``; for a given N the
residual and the tangent are those of the fixed count, so the tangent stays exact between the
(measure-zero) switches.

Nodal forces (virtual work, section 6), the group's contribution to the internal side::

    F_ai = sum_q (p e_u + tau e_v)_i |t| N_a W  * (r in axisymmetry, per radian; thickness in
                                                   plane strain)
    i.e. Fx = sum (p y_xi - tau x_xi) N W,  Fy = sum (-p x_xi - tau y_xi) N W,

with r the radius of P in the end configuration.  ``K = dF/du_new`` is exact: constitutive
part (p, tau through d and dv, chained through the sub-intervals in forward mode) plus the
geometric part (moving face tangent/normal, moving point Q, moving radius).

Small strain (``ctx.nlgeom`` False) is the geometrically linear version, consistent with the
pressure loads of ``elements.edges``: the axes (e_u, e_v), the Jacobian |t| and the radius r
are those of the *reference* face; d is still measured from the current point P (along the
reference normal) to the foundation, and dv = e_v0 . (dP - dc).  Its tangent is the
constitutive part only (through dd/dP), still non-symmetric through the friction law.

A rigid tool.  The foundation's placement is a translation ``c`` of its reference point ``X_R``
and a rotation ``theta`` about it (:mod:`lagamine_py.foundation`): prescribed (``ctx``, from
``*FOUNDATION MOTION``), or the DOFs of the tool's reference node (``tool_dofs``: u, v and, in
plane strain, the rotation; the solver puts their values into ``ctx`` too).  A rotated chain is
projected in its own frame: ``P' = X_R + R^T (P - x_R)``, ``e_u' = R^T e_u`` with ``x_R = X_R +
c`` (d is invariant), the derivatives of d turned back by ``R``.  With respect to the tool::

    dd/dc = -dd/dP,     dd/dtheta = (dd/dP) x (Q - x_R)     (z of the cross product)

(turning the tool by ``dtheta`` about ``x_R`` moves the chain point at Q by ``dtheta J (Q - x_R)``,
``J`` the quarter turn).  The tangential relative displacement is measured against the motion of
the tool's material point at the start position of P, ``w = c_new - c_old + (R(dtheta) - I)
(P_old - x_R,old)``: ``dv = e_v . (dP - w)`` (the translation ``dc`` alone without rotation), so a
common rigid motion of body and tool slides nothing.

With a reference node the group's rows and columns include the tool's DOFs: the tool's internal
force is minus the sum of the forces on the faces, ``f_c = -sum_g F_g`` (``F_g`` the force of the
point on its nodes, ``(p e_u + tau e_v) |t| W``), and its moment about ``x_R``, ``f_theta = -sum_g
(P_g - x_R) x F_g``: the contact forces are self-equilibrated (no net force or moment), so a rigid
motion of everything does no work, and at equilibrium the tool's reactions are the force and
moment the tool exerts on the body.  The tangent is their exact derivative (the moment's arm moves
with P and with the tool).

Contact stabilisation (``ctx.stabilisation[name] = (kn, kt, range)``, set by the step controller
from ``*CONTACT STABILIZATION``): on the points within ``range`` of the foundation (whose normal
met it at the start and at the end of the increment), a viscous normal traction ``p_s = kn w_n
(d_end - d_start)`` and a tangential one ``tau_s = kt w_t sum_k dv_k`` are added to p and tau in
the forces, with their exact derivatives.  ``w_n`` is 1 in contact and fades to 0 at the range;
``w_t`` acts on open points only, 0 at touching and at the range (:func:`_stab_weights`): both
continuous, so a point that closes or opens sees no jump of its force (a jump makes Newton
chatter).  They resist the approach and the sliding of a body or tool that nothing else holds
yet; where the contact is closed the normal one only resists the change of the penetration
(``kn << KP``).  ``ps`` and ``ts`` are the tractions of the last increment; their work,
in the trapezoidal form of the energy balance, is kept per point in the state (``stab``, see
:meth:`ContactGroup._increment_totals`).

Chaining the law's derivatives.  The law (``lagamine_py.laws.base.ContactLaw``) returns, per
sub-interval, derivatives named ``<out>_<in>`` with ``out`` in ``p, tau, lam`` and ``in`` in
``u`` (du, with d moving with it), ``v`` (dv), ``d`` (d_{k-1} with du fixed, i.e. an explicit
dependence on d beyond du), ``p``, ``tau``, ``lam`` (old state values).  Missing keys are 0,
except ``p_d`` which defaults to ``p_u`` (``p_new = KP max(d, 0)`` depends on d only).  So a
law returning just ``p_u, tau_u, tau_v, tau_tau`` is chained as
``D tau_k = tau_tau D tau_{k-1} + tau_u D du_k + tau_v D dv_k``.
"""
from __future__ import annotations

import numpy as np

from .. import kernels
from ..core.errors import ReturnMappingError
from ..core.status import NONE, OPEN, SLIP, STICK
from ..core.tensors import RIGHT as _R, right_normal as _right
from ..foundation import Foundation, Projection
from ..laws.base import ContactLaw
from .base import ContactPoints, Group, GroupResult, StepContext
from .shapes import gauss_1d, line_shape, lobatto_1d

__all__ = ["ContactGroup", "FAR", "RULES", "integration_rule"]

FAR = 1e30          # penetration handed to the law for a point whose line misses the foundation
#: the contact element's integration rules (*CONTACT, GAUSS=): Gauss-Legendre with 2 or 3
#: points, or Gauss-Lobatto at the face's nodes (nodal integration, see the module docstring)
RULES = (2, 3, "LOBATTO2", "LOBATTO3", "LINEAR")


def integration_rule(gauss) -> tuple[np.ndarray, np.ndarray]:
    """Points xi (q,) and weights (q,) of a rule of :data:`RULES` (``LINEAR``: the law's points
    at the corners, each with the weight of its linear shape function)."""
    if gauss in (2, 3):
        return gauss_1d(int(gauss))
    if isinstance(gauss, str) and gauss.upper() in ("LOBATTO2", "LOBATTO3", "LINEAR"):
        return lobatto_1d(2 if gauss.upper() == "LINEAR" else int(gauss[-1]))
    raise ValueError(f"GAUSS must be one of {', '.join(map(str, RULES))}, not {gauss!r}")


class _Sampling:
    """Shape functions and their derivative blocks at points ``xi`` of every face (tiled over the
    faces: g = f nq + q): N, dN (q, a), w (q,); Wg (g,), Ng, dNg (g, a); AP, At, RAt (g, 2, nd)
    (d P / d x, d t / d x and d (R t) / d x); P0, t0 (g, 2) on the reference faces ``x0``."""

    def __init__(self, nfn: int, xi, w, x0):
        nf, nd = len(x0), 2 * nfn
        self.nq = len(xi)
        self.N, self.dN = line_shape(nfn, xi)                     # (q, a)
        self.w = np.asarray(w, float)
        eye = np.eye(2)
        AP = np.einsum("qa,ij->qiaj", self.N, eye).reshape(self.nq, 2, nd)
        At = np.einsum("qa,ij->qiaj", self.dN, eye).reshape(self.nq, 2, nd)
        self.AP, self.At = np.tile(AP, (nf, 1, 1)), np.tile(At, (nf, 1, 1))
        self.RAt = np.tile(np.einsum("ij,qjJ->qiJ", _R, At), (nf, 1, 1))
        self.Wg = np.tile(self.w, nf)
        self.Ng, self.dNg = np.tile(self.N, (nf, 1)), np.tile(self.dN, (nf, 1))
        self.P0, self.t0 = self.at(x0)

    def at(self, x):
        """P and t = dx/dxi (g, 2) at face node positions x (f, a, 2)."""
        return (np.einsum("qa,fai->fqi", self.N, x).reshape(-1, 2),
                np.einsum("qa,fai->fqi", self.dN, x).reshape(-1, 2))


def _norm(t):
    """|t| (g,) of t (g, 2): sqrt(t_x^2 + t_y^2), as np.linalg.norm sums, without its overhead."""
    return np.sqrt((t * t).sum(axis=-1))


_I2 = np.eye(2)
_OUT = ("p", "tau", "lam")
#: the group's own state arrays (besides the law's): see init_state and the module doc
_OWN = ("dvp", "energy", "fdis", "ps", "ts", "stab")


def _unit(t):
    """|t| (g,), t_hat (g, 2)."""
    n = _norm(t)
    return n, t / np.where(n > 0, n, 1.0)[:, None]


def normal_axis(t):
    """e_u (g, 2) and d e_u / d t (g, 2, 2) for e_u = R t / |t|."""
    n, th = _unit(t)
    e_u = _right(th)
    D = (_R[None] - e_u[:, :, None] * th[:, None, :]) / n[:, None, None]
    return e_u, D


def _as_placement(v) -> tuple[np.ndarray, float]:
    """``(c (2,), theta)`` of a placement given as (2,), (3,) or ``(c, theta)``."""
    if isinstance(v, tuple) and len(v) == 2 and np.ndim(v[0]) == 1:
        return np.asarray(v[0], float), float(v[1])
    a = np.asarray(v, float).ravel()
    return a[:2].copy(), (float(a[2]) if a.size > 2 else 0.0)


def _stab_weights(d_end, d_start, rng):
    """The stabilisation's weights and their derivatives in ``d_end``: normal ``w_n = 1`` in
    contact (``d >= 0``), ``1 + d/range`` down to 0 at the range; tangential ``w_t = 4 s (1 - s)``
    with ``s = -d/range`` on the open points within the range, 0 elsewhere.  Both are continuous
    where the law is (at closing ``p`` and the re-contact ``tau`` start from 0), so a point
    crossing ``d = 0`` sees no jump; 0 where the normal missed the foundation at either end."""
    ok = (d_end > -rng) & (d_start > -0.5 * FAR)
    closed = ok & (d_end >= 0.0)
    gap = ok & (d_end < 0.0)
    x = np.where(gap, -d_end / rng, 0.0)
    wn = np.where(closed, 1.0, np.where(gap, 1.0 - x, 0.0))
    dwn = np.where(gap, 1.0 / rng, 0.0)
    wt = np.where(gap, 4.0 * x * (1.0 - x), 0.0)
    dwt = np.where(gap, -4.0 * (1.0 - 2.0 * x) / rng, 0.0)
    return wn, dwn, wt, dwt


def _placement_key(place) -> np.ndarray:
    """(3,) array of a placement (for the start cache and the kernel)."""
    c, theta = _as_placement(place)
    return np.array([c[0], c[1], theta])


def tangent_axis(t):
    """e_v (g, 2) and d e_v / d t (g, 2, 2) for e_v = -t / |t|."""
    n, th = _unit(t)
    D = -(_I2[None] - th[:, :, None] * th[:, None, :]) / n[:, None, None]
    return -th, D


def sub_penetration(k, nsub, d_start, d_end, Dd_end):
    """The penetration at the end of sub-interval ``k`` of ``nsub`` and its derivative in
    ``u_new``: linear from ``d_start`` (fixed with respect to ``u_new``) to ``d_end``."""
    if nsub == 1:
        return d_end, Dd_end
    a_k = k / nsub
    return (d_start + a_k * (d_end - d_start),
            None if Dd_end is None else a_k * Dd_end)


class ContactGroup(Group):
    """Contact elements on the faces of one surface against one rigid foundation.

    Parameters
    ----------
    name : str, the contact pair's name (``"<surface>-><foundation>"``); key of
        ``ctx.freeze_contact``.
    face_nodes : (f, nfn) node rows of each face, corner, corner[, mid], in the element's
        counter-clockwise order (the element class's ``faces``).
    elements : (f,) deck ids of the solid elements owning the faces.
    faces : (f,) face numbers 1.. (for messages and outputs).
    coords0 : (n, 2) reference coordinates of all nodes.
    foundation : :class:`lagamine_py.foundation.Foundation`.
    foundation_name : str, key of ``ctx.foundation_old/new``.
    law : :class:`lagamine_py.laws.base.ContactLaw` (its ``theta``, ``substeps``, ``subtol``,
        ``submax`` split the increment).
    gauss : the integration rule, one of :data:`RULES`: 2 or 3 Gauss points per face, or
        ``"LOBATTO2"`` / ``"LOBATTO3"`` (points at the face's nodes).
    axisymmetric : forces per radian (times the radius r of P) instead of times thickness.
    thickness : plane-strain out-of-plane thickness.
    tool_dofs : the global DOFs of the foundation's reference node (u, v[, rotation]), or None
        for a foundation moved by ``ctx`` only; every face then couples to them (``dofs`` gains
        their columns).
    """

    def __init__(self, name: str, face_nodes, elements, faces, coords0, foundation: Foundation,
                 foundation_name: str, law: ContactLaw, gauss: int = 3, axisymmetric: bool = False,
                 thickness: float = 1.0, tool_dofs=None):
        self.name = name
        self.face_nodes = np.asarray(face_nodes, int)
        nf, nfn = self.face_nodes.shape
        if nfn not in (2, 3):
            raise ValueError(f"contact {name!r}: faces have 2 or 3 nodes, not {nfn}")
        try:
            xi, self.w = integration_rule(gauss)
        except ValueError as exc:
            raise ValueError(f"contact {name!r}: {exc}") from None
        if nfn == 3 and gauss == "LOBATTO2":
            raise ValueError(f"contact {name!r}: LOBATTO2 puts no point at the mid-side node of a "
                             f"3-node face: use LOBATTO3")
        self.rule = gauss
        self.ids = np.asarray(elements, int)
        self.faces = np.asarray(faces, int)
        self.coords0 = np.asarray(coords0, float)
        self.foundation = foundation
        self.foundation_name = foundation_name
        self.law = law
        self.axisymmetric = bool(axisymmetric)
        self.thickness = float(thickness)
        self.nf, self.nfn, self.nq = nf, nfn, len(xi)
        self.ng = nf * self.nq
        self.nd = 2 * nfn
        self.dofs = (2 * self.face_nodes[:, :, None] + np.arange(2)).reshape(nf, self.nd)
        # the tool's DOFs (nt = 0, 2 or 3): columns nd.. of every face's rows and blocks
        self.tool_dofs = np.zeros(0, np.int64) if tool_dofs is None else np.asarray(tool_dofs, np.int64)
        self.nt = len(self.tool_dofs)
        if self.nt not in (0, 2, 3):
            raise ValueError(f"contact {name!r}: a tool has 2 or 3 DOFs, not {self.nt}")
        self.nw = self.nd + self.nt
        if self.nt:
            self.dofs = np.concatenate([self.dofs, np.broadcast_to(self.tool_dofs, (nf, self.nt))], axis=1)
        # |d| below round-off of the coordinates is exact touching (a body meshed on the
        # foundation); relative to the coordinates' size, so a model in metres or nanometres
        # behaves as one in millimetres (an absolute 1e-12 swallowed the whole penetration of
        # a 1e-9 model: no contact stiffness, a "singular" matrix)
        size = float(np.abs(self.coords0).max(initial=0.0))
        self._touch_tol = 1e-12 * size
        self.N, self.dN = line_shape(nfn, xi)                     # (q, a)
        # d P_i / d x_J and d t_i / d x_J per Gauss point, tiled over faces: (g, 2, nd)
        eye = np.eye(2)
        AP = np.einsum("qa,ij->qiaj", self.N, eye).reshape(self.nq, 2, self.nd)
        At = np.einsum("qa,ij->qiaj", self.dN, eye).reshape(self.nq, 2, self.nd)
        self._AP = np.tile(AP, (nf, 1, 1))
        self._At = np.tile(At, (nf, 1, 1))
        self._Wg = np.tile(self.w, nf)                            # (g,)
        self._Ng = np.tile(self.N, (nf, 1))                       # (g, a)
        self._dNg = np.tile(self.dN, (nf, 1))                     # (g, a)
        # R A_t (g, 2, nd): d (R t) / d x_J, the moving normal's part of the geometric tangent
        self._RAt = np.tile(np.einsum("ij,qjJ->qiJ", _R, At), (nf, 1, 1))
        self._x0 = np.ascontiguousarray(self.coords0[self.face_nodes])   # (f, a, 2) reference
        self._P0, self._t0 = self._at_points(self._x0)
        # GAUSS=LINEAR: the law at the corners (the points above), its tractions interpolated
        # linearly to the Gauss points that integrate the forces (see the module docstring)
        self._lift = self._force = None
        if gauss == "LINEAR":
            xf, wf = gauss_1d(nfn)
            self._lift = line_shape(2, xf)[0]                     # (qF, corners)
            self._force = _Sampling(nfn, xf, wf, self._x0)
        self._jac_tol = 1e-14 * size
        self._start_cache = None          # see _start_penetration
        self._kernel = False              # the fused kernel (use_kernels)
        self._kernel_wanted = False
        self._kernel_static = None

    # ----------------------------------------------------------------- helpers
    def use_kernels(self, on: bool) -> None:
        """Compute the whole group through :mod:`lagamine_py.kernels.contact` (``on``, when the
        law has a kernel vector -- COULOMB -- and the foundation a kernel, and numba imports),
        or the NumPy reference; the foundation projects through its kernel likewise."""
        self.foundation.use_kernels(on)
        self._kernel_wanted = bool(on)
        self._kernel = (bool(on) and self.law.kernel_vector() is not None and self._lift is None
                        and self.foundation.has_kernel() and kernels.module("contact") is not None)

    def init_state(self) -> dict[str, np.ndarray]:
        """The law's state of the points, and the group's own: ``dvp`` the signed slip of the
        last increment and ``energy`` the frictional energy each point has dissipated (see
        :meth:`_increment_totals`)."""
        state = self.law.init_state(self.ng)
        state["dvp"] = np.zeros(self.ng)
        state["energy"] = np.zeros(self.ng)
        for key in _OWN[2:]:          # fdis and the stabilisation (ps, ts, stab): module doc
            state[key] = np.zeros(self.ng)
        return state

    def set_law(self, law: ContactLaw, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Use ``law`` from now on (``*CHANGE CONTACT LAW``); returns the committed ``state``
        carried over: the law's :data:`~lagamine_py.laws.base.ContactLaw.STATE_KEYS` (p, tau,
        the slip lambda and its measures, the dissipation, the status) and the group's own
        arrays as they are, any other array of the new law from its ``init_state``.  The new
        law integrates the next increment from them: a tau outside its cone returns to it
        (slip), its hardening functions start at the lambda reached."""
        self.law = law
        self._kernel = (self._kernel_wanted and law.kernel_vector() is not None
                        and self._lift is None
                        and self.foundation.has_kernel() and kernels.module("contact") is not None)
        new = law.init_state(self.ng)
        keep = set(ContactLaw.STATE_KEYS) | set(_OWN)
        for key, value in state.items():
            if key in keep or key not in new:
                new[key] = np.array(value, copy=True)
        return new

    def _areas(self, P, t, geo, x) -> np.ndarray:
        """The area (g,) each law point stands for, ``W |t|`` times thickness or radius; with
        GAUSS=LINEAR ``int L_c dA`` of each corner's linear shape, by the force points (x the
        face positions)."""
        if self._lift is None:
            wt, _ = self._weights(P, geo)
            return wt * _norm(t)
        fs = self._force
        Pf, tf = fs.at(x)
        wt, _ = self._weights(Pf, geo, fs)
        dA = (wt * _norm(tf if geo else fs.t0)).reshape(self.nf, fs.nq)
        return (dA @ self._lift).reshape(-1)

    def _increment_totals(self, st, state, P, t, geo, d_start, d_end, dv,
                          x=None) -> dict[str, np.ndarray]:
        """The group's own state after the law's: ``dvp = vp - vp_old``; ``energy +=
        (dissip - dissip_old) dA``, ``dA`` the area the forces are integrated on at the end of
        the increment (so the sum over points and increments is the work of the friction
        stresses along the slip, as the forces see it); and in the trapezoidal form of the
        energy balance (:mod:`lagamine_py.solver.energy`), ``fdis += 1/2 (tau_old + tau) dvp
        dA`` and ``stab += (1/2 (ps_old + ps) dd + 1/2 (ts_old + ts) dv) dA`` (``dd = d_end -
        d_start``, ``dv`` the increment's tangential relative displacement, where the normal met
        the foundation at both ends).  ``x``: the face positions (GAUSS=LINEAR, :meth:`_areas`)."""
        dA = self._areas(P, t, geo, x)
        st["dvp"] = np.asarray(st["vp"], float) - np.asarray(state["vp"], float)
        st["energy"] = (np.asarray(state["energy"], float)
                        + (np.asarray(st["dissip"], float) - np.asarray(state["dissip"], float)) * dA)
        tau_old = np.asarray(state["tau"], float)
        st["fdis"] = (np.asarray(state["fdis"], float)
                      + 0.5 * (tau_old + np.asarray(st["tau"], float)) * st["dvp"] * dA)
        both = (d_start > -0.5 * FAR) & (d_end > -0.5 * FAR)
        dd = np.where(both, d_end - d_start, 0.0)
        dv = np.where(both, dv, 0.0)
        ps, ts = np.asarray(st["ps"], float), np.asarray(st["ts"], float)
        st["stab"] = np.asarray(state["stab"], float) + (
            0.5 * (np.asarray(state["ps"], float) + ps) * dd
            + 0.5 * (np.asarray(state["ts"], float) + ts) * dv) * dA
        return st

    def _face_x(self, u) -> np.ndarray:
        """Current face node positions (f, a, 2)."""
        return self._x0 + np.asarray(u, float)[self.face_nodes]

    def _at_points(self, x) -> tuple[np.ndarray, np.ndarray]:
        """P (g, 2) and t = dx/dxi (g, 2) from face node positions x (f, a, 2)."""
        return self._interp(self.N, x), self._interp(self.dN, x)

    def _kron(self, Ng, v):
        """``v_i A_iJ`` (g, nd) for ``A = N_a delta_ij`` (``_AP`` with ``Ng = _Ng``, ``_At``
        with ``_dNg``): the broadcast product, without the (g, 2, nd) operand."""
        return (Ng[:, :, None] * v[:, None, :]).reshape(self.ng, self.nd)

    def _interp(self, N, x):
        """``sum_a N_qa x_fai`` (g, 2) for x (f, a, 2): summed over a in order, as a broadcast
        product (bit-identical to the einsum it replaces, a fraction of its overhead)."""
        out = N[None, :, 0, None] * x[:, None, 0, :]
        for a in range(1, self.nfn):
            out = out + N[None, :, a, None] * x[:, None, a, :]
        return out.reshape(self.ng, 2)

    def _placement(self, ctx: StepContext, which: str) -> tuple[np.ndarray, float]:
        """The foundation's translation ``c`` (2,) and rotation ``theta`` at the start
        (``which`` "old") or end of the increment: ``ctx.foundation_old/new[name]``, (dx, dy)
        or (dx, dy, theta)."""
        table = ctx.foundation_old if which == "old" else ctx.foundation_new
        return _as_placement(table.get(self.foundation_name, np.zeros(2)))

    def _stabilisation(self, ctx: StepContext):
        """``(kn, kt, range)`` of this pair in this increment, or None (see the module doc)."""
        table = ctx.stabilisation
        if not table or self.name not in table or table[self.name] is None:
            return None
        return table[self.name]

    def _project(self, P, e_u, place) -> Projection:
        """The foundation at ``place`` met by the lines (P, e_u), in the current frame: without
        rotation :meth:`Foundation.project` as it is, else the lines turned into the chain's
        frame and the result (Q, tangent, normal, the derivatives of d) turned back."""
        c, theta = place
        if theta == 0.0:
            return self.foundation.project(P, e_u, c)
        cs, sn = np.cos(theta), np.sin(theta)
        X = self.foundation.centre
        rx, ry = P[:, 0] - (X[0] + c[0]), P[:, 1] - (X[1] + c[1])
        Pp = np.column_stack([X[0] + (cs * rx + sn * ry), X[1] + (-sn * rx + cs * ry)])
        ep = np.column_stack([cs * e_u[:, 0] + sn * e_u[:, 1], -sn * e_u[:, 0] + cs * e_u[:, 1]])
        pr = self.foundation.project(Pp, ep, None)

        def back(v):                         # R v, row by row
            v = np.asarray(v, float)
            return np.column_stack([cs * v[:, 0] - sn * v[:, 1], sn * v[:, 0] + cs * v[:, 1]])

        Q = np.column_stack([X[0] + c[0], X[1] + c[1]]) + back(np.asarray(pr.Q) - X)
        return Projection(Q=Q, d=pr.d, arc=pr.arc, s=pr.s, tangent=back(pr.tangent),
                          normal=back(pr.normal), found=pr.found, dd_dP=back(pr.dd_dP),
                          dd_de=back(pr.dd_de))

    def _tool_columns(self, pr, P, e_u, d, place) -> np.ndarray:
        """D d / D (c, theta) (g, nt) of the tool's DOFs: ``-dd/dP`` and ``(dd/dP) x (Q - x_R)``
        (0 where the line misses)."""
        c, _ = place
        a = np.asarray(pr.dd_dP, float)
        out = np.zeros((self.ng, self.nt))
        out[:, 0], out[:, 1] = -a[:, 0], -a[:, 1]
        if self.nt == 3:
            X = self.foundation.centre
            dq = np.where(pr.found, d, 0.0)
            qx = P[:, 0] - dq * e_u[:, 0] - (X[0] + c[0])
            qy = P[:, 1] - dq * e_u[:, 1] - (X[1] + c[1])
            out[:, 2] = a[:, 0] * qy - a[:, 1] * qx
        out[~pr.found] = 0.0
        return out

    def _frozen(self, ctx: StepContext):
        fc = ctx.freeze_contact
        if isinstance(fc, dict) and self.name in fc and fc[self.name] is not None:
            return np.asarray(fc[self.name])
        return None

    def _axes_t(self, x, geo):
        """P (g, 2) at positions x and the tangent t (g, 2) defining the axes: of x when
        ``geo`` (NLGEOM), of the reference face otherwise."""
        P, t = self._at_points(x)
        return P, (t if geo else self._t0)

    def _penetration(self, x, place, scale, geo):
        """d (g,) and D d / D u_new (g, nw) (zeros when ``scale`` is 0) for positions x
        (f, a, 2) that move with ``scale`` * u_new, the foundation at ``place`` (a translation
        (2,), (dx, dy, theta), or ``(c, theta)``).  Points not found: far open (d = -FAR),
        derivative 0.  Round-off touching (|d| <= tolerance) is snapped to d = 0, which the law
        treats as closed with p = 0: a body meshed on the foundation has contact stiffness from
        the first iteration, without a fake gap or spring.  The columns ``nd..`` (a tool's
        DOFs) are the derivatives with respect to the tool's placement (moving with u_new)."""
        P, t = self._axes_t(x, geo)
        return self._penetration_at(P, t, place, scale, geo)

    def _penetration_at(self, P, t, place, scale, geo):
        """:meth:`_penetration` from P (g, 2) and the axes' tangent t (g, 2)."""
        place = _as_placement(place)
        e_u, de = normal_axis(t)
        pr = self._project(P, e_u, place)
        d = np.where(pr.found, pr.d, -FAR)
        d = np.where(np.abs(d) <= self._touch_tol, 0.0, d)
        if scale == 0.0:
            return d, np.zeros((self.ng, self.nw)), pr
        Dd = self._kron(self._Ng, np.asarray(pr.dd_dP, float))
        if scale != 1.0:
            Dd *= scale
        if geo:                                                   # the normal turns with the face
            dd_de = np.asarray(pr.dd_de, float)
            dd_dt = dd_de[:, 0, None] * de[:, 0, :] + dd_de[:, 1, None] * de[:, 1, :]
            Dd_t = self._kron(self._dNg, dd_dt)
            Dd += Dd_t if scale == 1.0 else scale * Dd_t
        if not pr.found.all():
            Dd[~pr.found] = 0.0
        if self.nt:
            tool = self._tool_columns(pr, P, e_u, d, place)
            Dd = np.concatenate([Dd, tool if scale == 1.0 else scale * tool], axis=1)
        return d, Dd, pr

    def _start_penetration(self, xo, place, geo):
        """d (g,) at the start of the increment (face positions xo, placement ``place``).  It is
        the same at every Newton iteration of an increment, so the last one is kept and reused
        while the positions, the placement, NLGEOM and the foundation are bitwise the same."""
        c = self._start_cache
        key = _placement_key(place)
        if (c is not None and c[0] == geo and c[1] is self.foundation
                and np.array_equal(c[2], xo) and np.array_equal(c[3], key)):
            return c[4].copy()
        d, _, _ = self._penetration(xo, place, 0.0, geo)
        self._start_cache = (geo, self.foundation, xo.copy(), key, d.copy())
        return d

    def start_penetration(self) -> np.ndarray:
        """d (g,) of the reference configuration against the foundation where the deck puts it
        (-FAR where a point's normal misses it): the faces near it, for the penalty advice."""
        d, _, _ = self._penetration(self._x0, np.zeros(2), 0.0, False)
        return d

    def point_lengths(self) -> np.ndarray:
        """(g,) the reference corner-to-corner length of each point's face (the length PTOL of
        METHOD=AUGMENTED is relative to)."""
        x = self._x0
        return np.repeat(np.linalg.norm(x[:, 1] - x[:, 0], axis=1), self.nq)

    def chain_neighbours(self) -> tuple[np.ndarray, np.ndarray]:
        """The points before and after each point along the surface (g,) each, -1 at an end:
        within a face in the order of xi (from its first corner to its second), across faces
        through a shared corner (the next face starts where this one ends)."""
        g = np.arange(self.ng).reshape(self.nf, self.nq)
        prev, nxt = np.full((self.nf, self.nq), -1), np.full((self.nf, self.nq), -1)
        prev[:, 1:], nxt[:, :-1] = g[:, :-1], g[:, 1:]
        starts = {int(n): f for f, n in enumerate(self.face_nodes[:, 0])}
        for f, end in enumerate(self.face_nodes[:, 1]):
            f2 = starts.get(int(end))
            if f2 is not None and f2 != f:
                nxt[f, -1], prev[f2, 0] = g[f2, 0], g[f, -1]
        return prev.reshape(-1), nxt.reshape(-1)

    def rotation(self, x_old, x_new) -> np.ndarray:
        """Angle (rad, (g,)) the face tangent turns through between face positions x_old
        and x_new (f, a, 2)."""
        _, t_o = self._at_points(x_old)
        _, t_n = self._at_points(x_new)
        cross = t_o[:, 0] * t_n[:, 1] - t_o[:, 1] * t_n[:, 0]
        return np.abs(np.arctan2(cross, t_o[:, 0] * t_n[:, 0] + t_o[:, 1] * t_n[:, 1]))

    def substeps_for(self, x_old, x_new, geo: bool) -> int:
        """Sub-intervals for this increment: ``law.substeps``, or with ``AUTO`` the smallest
        count that keeps the rotation of the axes per sub-interval below ``law.subtol``
        (capped at ``law.submax``; 1 without NLGEOM, where the axes do not turn)."""
        n = self.law.substeps
        if not (isinstance(n, str) and n.upper() == "AUTO"):
            return max(int(n), 1)
        if not geo:
            return 1
        angle = float(self.rotation(x_old, x_new).max(initial=0.0))
        tol, cap = float(self.law.subtol), int(self.law.submax)
        if not np.isfinite(angle):
            return cap
        return int(min(max(int(np.ceil(angle / tol - 1e-9)), 1), cap))

    # ----------------------------------------------------------------- compute
    @staticmethod
    def _hold_open(new, st, D, frozen_open):
        """The state of a sub-interval with the points the flip-flop control holds OPEN put back:
        no traction, their history (lam, slip, vp, dissip) that of ``st``, no tangent rows."""
        if frozen_open is None or not frozen_open.any():
            return new
        new = dict(new)
        for key in ("p", "tau"):
            new[key] = np.where(frozen_open, 0.0, new[key])
        for key in ("lam", "slip", "vp", "dissip"):
            if key in new and key in st:
                new[key] = np.where(frozen_open, st[key], new[key])
        status = np.asarray(new["status"])
        new["status"] = np.where(frozen_open, OPEN, status).astype(status.dtype)
        for key in _OUT:
            if D[key] is not None:
                D[key][frozen_open] = 0.0
        return new

    def _detached(self, st, state, D, tangent):
        """``st`` sharing no array with the committed ``state`` (a law may pass some through),
        and zero p and tau rows in ``D`` where no sub-interval wrote any."""
        st = {k: (v.copy() if v is state.get(k) else v) for k, v in st.items()}
        for key in ("p", "tau"):
            if tangent and D[key] is None:
                D[key] = np.zeros((self.ng, self.nw))
        return st

    def _point_record(self, state, P, p, tau, gap, status, dA, F, M) -> ContactPoints:
        """The output record of the points (:class:`ContactPoints`): ``P`` positions, ``p``,
        ``tau``, ``gap``, ``status`` per point, ``dA`` their areas, ``F`` and ``M`` the resultant
        force and moment on the other side of the pair."""
        try:
            stored = float(np.sum(np.asarray(self.law.stored_energy(state), float) * dA))
        except NotImplementedError:          # the law keeps no account of it (energy: NaN)
            stored = float("nan")
        closed = (status == STICK) | (status == SLIP)
        return ContactPoints(
            name=self.name, element=np.repeat(self.ids, self.nq),
            face=np.repeat(self.faces, self.nq), gauss=np.tile(np.arange(1, self.nq + 1), self.nf),
            x=P, p=p, tau=tau, gap=gap, slip=np.asarray(state["slip"], float),
            lam=np.asarray(state["lam"], float), status=status,
            P=float(np.sum(p * dA)), T=float(np.sum(tau * dA)),
            A=float(np.sum(dA[closed])), F=F, x0=self._P0.copy(),
            vp=np.asarray(state["vp"], float), dvp=np.asarray(state["dvp"], float),
            dissip=np.asarray(state["dissip"], float),
            E=float(np.sum(np.asarray(state["energy"], float))), M=M, stored=stored,
            stabilisation=float(np.sum(np.asarray(state.get("stab", 0.0), float))),
            friction=float(np.sum(np.asarray(state.get("fdis", 0.0), float))))

    def _integrate(self, u_new, u_old, state, ctx, tangent, stab=False):
        """Run the law over the sub-intervals; returns the end state, D p, D tau (g, nw), P, t
        (g, 2) of the end configuration (``_axes_t`` of u_new, reused by ``compute``) and
        ``(d_start, d_end, D d_end, sum dv, D sum dv)`` (the last one None unless ``stab`` and
        ``tangent``: the stabilisation's)."""
        xo, xn = self._face_x(u_old), self._face_x(u_new)
        dx = xn - xo
        (co, tho), (cn, thn) = self._placement(ctx, "old"), self._placement(ctx, "new")
        geo = bool(ctx.nlgeom)
        nsub = self.substeps_for(xo, xn, geo)
        theta = float(self.law.theta)
        frozen = self._frozen(ctx)
        frozen_open = None if frozen is None else (frozen == OPEN)

        d_prev = self._start_penetration(xo, (co, tho), geo)   # start: fixed w.r.t. u_new
        d_start = d_prev
        # penetration at the end (the last sub-interval's); in between it moves linearly (see doc)
        P_end, t_end = self._axes_t(xn, geo)
        d_end, Dd_end, _ = self._penetration_at(P_end, t_end, (cn, thn), 1.0 if tangent else 0.0,
                                                geo)
        st = state
        D = dict.fromkeys(_OUT)                # None: a derivative known to be zero
        Dd_prev = None
        dc = (cn - co) / nsub
        dP = self._interp(self.N, dx) / nsub
        rel = dP - dc
        if self.nt == 3 or thn != tho:
            # the tool turns: its material point at P_old moves by (R(dtheta) - I) (P_old - x_R)
            X = self.foundation.centre
            arm = self._interp(self.N, xo) - (X + co)
            cs, sn = np.cos(thn - tho), np.sin(thn - tho)
            q = np.column_stack([cs * arm[:, 0] - sn * arm[:, 1], sn * arm[:, 0] + cs * arm[:, 1]])
            if thn != tho:
                rel = rel - (q - arm) / nsub
        dv_sum, Ddv_sum = 0.0, None
        for k in range(1, nsub + 1):
            d_k, Dd_k = sub_penetration(k, nsub, d_start, d_end, Dd_end)
            a_th = (k - 1 + theta) / nsub
            t_th = self._interp(self.dN, xo + a_th * dx) if geo else self._t0
            e_v, dev = tangent_axis(t_th)
            dv = e_v[:, 0] * rel[:, 0] + e_v[:, 1] * rel[:, 1]
            du = d_k - d_prev
            new, tan = self.law.update(st, d_k, du, dv, frozen=frozen)
            dv_sum = dv_sum + dv
            if tangent:
                Ddv = self._kron(self._Ng, e_v)
                if nsub != 1:
                    Ddv /= nsub
                if geo:
                    # sum_i (rel_i dev_ij) A_t: the i terms summed last, as the former einsum
                    turn = (self._kron(self._dNg, rel[:, 0, None] * dev[:, 0, :])
                            + self._kron(self._dNg, rel[:, 1, None] * dev[:, 1, :]))
                    Ddv += turn if a_th == 1.0 else a_th * turn
                if self.nt:              # dv = e_v . (dP - w): w moves with the tool's DOFs
                    tool = np.empty((self.ng, self.nt))
                    tool[:, 0], tool[:, 1] = -e_v[:, 0] / nsub, -e_v[:, 1] / nsub
                    if self.nt == 3:      # d w / d theta = J q
                        tool[:, 2] = -(e_v[:, 1] * q[:, 0] - e_v[:, 0] * q[:, 1]) / nsub
                    Ddv = np.concatenate([Ddv, tool], axis=1)
                if stab:
                    Ddv_sum = Ddv.copy() if Ddv_sum is None else Ddv_sum + Ddv
                Ddu = Dd_k if Dd_prev is None else Dd_k - Dd_prev
                D = self._chain(tan, D, Ddu, Dd_prev, Ddv, lam=k < nsub)
            st = self._hold_open(new, st, D, frozen_open)
            d_prev, Dd_prev = d_k, Dd_k
        st = self._detached(st, state, D, tangent)
        return st, D, P_end, t_end, (d_start, d_end, Dd_end, dv_sum, Ddv_sum)

    def _chain(self, tan, D, Ddu, Dd_old, Ddv, lam=True):
        """Forward-mode step: derivatives of (p, tau, lam) after a sub-interval.  Inputs and
        outputs known to be zero are None (the first sub-interval starts from zeros); ``lam``
        False skips D lam (not needed after the last sub-interval)."""
        out = {}
        ins = {"u": Ddu, "v": Ddv, "d": Dd_old, "p": D["p"], "tau": D["tau"], "lam": D["lam"]}
        for o in _OUT if lam else _OUT[:2]:
            acc = None
            for i, Dx in ins.items():
                if Dx is None:
                    continue
                c = tan.get(f"{o}_{i}")
                if c is None and o == "p" and i == "d":
                    c = tan.get("p_u")
                if c is not None:
                    term = np.asarray(c, float)[:, None] * Dx
                    if acc is None:
                        acc = term
                    else:
                        acc += term
            out[o] = acc
        if not lam:
            out["lam"] = None
        return out

    def _weights(self, P, geo, sampling=None):
        """Integration weight per point without |t| (which sits in the force vectors):
        W * thickness (PE) or W * r (AX, r of P when ``geo``, of the reference point
        otherwise); and its derivative (g, nd) (None when constant).  ``sampling``: the force
        points of GAUSS=LINEAR (default: the law's points)."""
        Wg, P0, AP = ((self._Wg, self._P0, self._AP) if sampling is None else
                      (sampling.Wg, sampling.P0, sampling.AP))
        if not self.axisymmetric:
            return Wg * self.thickness, None
        if not geo:
            return Wg * P0[:, 0], None
        return Wg * P[:, 0], Wg[:, None] * AP[:, 0, :]

    def _lifted(self, p, tau, D, x, geo, tangent):
        """GAUSS=LINEAR: p, tau (gF,) and their derivatives (gF, nw) at the force points,
        linear between the corners' values ``p``, ``tau`` (g,); P, t (gF, 2) there."""
        fs, L = self._force, self._lift
        lift = lambda v: np.einsum("qc,fc...->fq...", L, v.reshape(  # noqa: E731
            (self.nf, self.nq) + v.shape[1:])).reshape((-1,) + v.shape[1:])
        p, tau = lift(np.asarray(p, float)), lift(np.asarray(tau, float))
        Dl = {k: lift(D[k]) for k in ("p", "tau")} if tangent else D
        P, t = fs.at(x)
        return p, tau, Dl, P, (t if geo else fs.t0)

    def compute(self, u_new, u_old, state, ctx: StepContext, tangent: bool = True) -> GroupResult:
        """Contact forces ``f`` (f, nw) and ``K = df/du_new`` (f, nw, nw) (``nw = nd`` without a
        tool's DOFs); see the module doc.

        With the COULOMB law, a :class:`~lagamine_py.foundation.Foundation` and numba, when
        switched on (:meth:`use_kernels`), the whole computation runs in one compiled loop over
        the points (:func:`lagamine_py.kernels.contact.contact_group`), equal to this NumPy code
        to round-off."""
        if self._kernel:
            return self._compute_fused(u_new, u_old, state, ctx, tangent)
        geo = bool(ctx.nlgeom)
        stab = self._stabilisation(ctx)
        with np.errstate(invalid="ignore", divide="ignore"):
            st, D, P, t, extra = self._integrate(u_new, u_old, state, ctx, tangent, stab is not None)
        xn = self._face_x(u_new)
        jac = _norm(t)
        st, p, tau = self._end_stresses(stab, st, state, extra, D, tangent, P, t, geo, xn)
        pts = self                                 # the points the forces are integrated on
        if self._lift is not None:                 # GAUSS=LINEAR: at the force points
            pts = self._force
            p, tau, D, P, t = self._lifted(p, tau, D, xn, geo, tangent)
        Ng_all, nq = (self._Ng, self.nq) if pts is self else (pts.Ng, pts.nq)
        Rt = _right(t)
        vec = p[:, None] * Rt - tau[:, None] * t                      # (p e_u + tau e_v) |t|
        wt, Dwt = self._weights(P, geo, None if pts is self else pts)
        f = Ng_all[:, :, None] * vec[:, None, :] * wt[:, None, None]            # (g, a, i)
        f = f.reshape(self.nf, nq, self.nd).sum(axis=1)
        failure = self._failure((jac <= self._jac_tol).any(), self._nonfinite(f, p, tau), st, ctx)
        if self.nt:
            f = np.concatenate([f, self._tool_force(vec * wt[:, None], P, ctx, nq)], axis=1)
        K = None
        if tangent:
            Dvec = Rt[:, :, None] * D["p"][:, None, :] - t[:, :, None] * D["tau"][:, None, :]
            if geo:                                   # the face (normal, length) moves
                RAt, At = (self._RAt, self._At) if pts is self else (pts.RAt, pts.At)
                Dvec[:, :, :self.nd] += p[:, None, None] * RAt - tau[:, None, None] * At
            if Dwt is not None and self.nt:
                Dwt = np.concatenate([Dwt, np.zeros((len(Dwt), self.nt))], axis=1)
            Ng = Ng_all[:, :, None, None]
            Kg = Ng * Dvec[:, None] * wt[:, None, None, None]         # (g, a, i, J)
            if Dwt is not None:
                Kg = Kg + Ng * vec[:, None, :, None] * Dwt[:, None, None, :]
            K = Kg.reshape(self.nf, nq, self.nd, self.nw).sum(axis=1)
            if self.nt:
                DF = Dvec * wt[:, None, None]
                if Dwt is not None:
                    DF = DF + vec[:, :, None] * Dwt[:, None, :]
                K = np.concatenate([K, self._tool_tangent(vec * wt[:, None], DF, P, ctx, pts)],
                                   axis=1)
        return GroupResult(f=f, K=K, state=st, failure=failure)

    def _stabilise(self, stab, st, extra, D, tangent):
        """p and tau with the stabilisation's tractions (see the module doc); D p, D tau updated
        in place; ``st`` gets ``ps``, ``ts``."""
        kn, kt, rng = stab
        d_start, d_end, Dd_end, dv_sum, Ddv_sum = extra
        wn, dwn, wt_, dwt = _stab_weights(d_end, d_start, rng)
        dd = np.where(wn > 0.0, d_end - d_start, 0.0)
        dv = np.where(wt_ > 0.0, dv_sum, 0.0)
        ps, ts = kn * wn * dd, kt * wt_ * dv
        st["ps"], st["ts"] = ps, ts
        if tangent:
            a = (kn * (wn + dd * dwn))[:, None]
            b = (kt * dv * dwt)[:, None]
            c = (kt * wt_)[:, None]
            D["p"] = D["p"] + a * Dd_end
            D["tau"] = D["tau"] + (c * Ddv_sum + b * Dd_end)
        return np.asarray(st["p"], float) + ps, np.asarray(st["tau"], float) + ts

    def _tool_force(self, F, P, ctx, nq) -> np.ndarray:
        """The tool's rows of ``f`` (f, nt): ``-sum F_g`` and ``-sum (P_g - x_R) x F_g`` per face,
        ``F`` (g, 2) the forces of the nq points per face they are integrated on."""
        Ff = F.reshape(self.nf, nq, 2).sum(axis=1)
        if self.nt == 2:
            return -Ff
        arm = P - self._tool_point(ctx)
        m = (arm[:, 0] * F[:, 1] - arm[:, 1] * F[:, 0]).reshape(self.nf, nq).sum(axis=1)
        return -np.column_stack([Ff, m])

    def _tool_tangent(self, F, DF, P, ctx, pts) -> np.ndarray:
        """The tool's rows of ``K`` (f, nt, nw): the derivatives of :meth:`_tool_force`; ``DF``
        (g, 2, nw) the derivatives of the points' forces; ``pts`` the points (self, or the force
        points of GAUSS=LINEAR)."""
        nq, AP = (self.nq, self._AP) if pts is self else (pts.nq, pts.AP)
        rows = -DF.reshape(self.nf, nq, 2, self.nw).sum(axis=1)
        if self.nt == 2:
            return rows
        arm = P - self._tool_point(ctx)
        Dm = arm[:, 0, None] * DF[:, 1, :] - arm[:, 1, None] * DF[:, 0, :]       # arm x DF
        Dm[:, :self.nd] += (AP[:, 0, :] * F[:, 1, None]
                            - AP[:, 1, :] * F[:, 0, None])                  # dP x F
        Dm[:, self.nd] -= F[:, 1]                                                # -dx_R x F
        Dm[:, self.nd + 1] += F[:, 0]
        Dm = -Dm.reshape(self.nf, nq, self.nw).sum(axis=1)
        return np.concatenate([rows, Dm[:, None, :]], axis=1)

    def _tool_point(self, ctx) -> np.ndarray:
        """The current position (2,) of the tool's reference point, ``X_R + c_new``."""
        c, _ = self._placement(ctx, "new")
        return self.foundation.centre + c

    def _compute_fused(self, u_new, u_old, state, ctx, tangent) -> GroupResult:
        """:meth:`compute` through the fused kernel (same sub-intervals, start penetration and
        its cache, placement, tool rows, stabilisation, failures)."""
        kc = kernels.module("contact")
        geo = bool(ctx.nlgeom)
        po = _placement_key(self._placement(ctx, "old"))
        pn = _placement_key(self._placement(ctx, "new"))
        cache = self._start_cache                 # see _start_penetration
        if cache is not None and cache[0] == geo and cache[1] is self.foundation:
            cache = cache[2:]
        else:
            cache = None
        if self._kernel_static is None:
            c, nq = np.ascontiguousarray, self.nq
            self._kernel_static = (
                c(self.N, float), c(self.dN, float), c(self.w, float), c(self._t0, float),
                c(self._P0, float), c(self._At[:nq], float), c(self._RAt[:nq], float),
                c(self._AP[:nq, 0, :], float), c(self._AP[:nq, 1, :], float),
                self.axisymmetric, self.thickness, self._touch_tol, FAR, self._jac_tol)
            self._face_nodes64 = c(self.face_nodes, np.int64)
        xo, xn, reuse = kc.face_positions(u_old, u_new, self._face_nodes64, self._x0, cache, po)
        nsub = self.substeps_for(xo, xn, geo)
        stab = self._stabilisation(ctx)
        st, f, K, outside, d_start, (snap, degenerate, nonfinite) = kc.contact_group(
            self._kernel_static, self.foundation.kernel_arrays(), self.law.kernel_vector(),
            xo, xn, reuse, None if cache is None else cache[2], po, pn, self.foundation.centre,
            self.nt, stab, nsub, float(self.law.theta), geo, tangent, state, self._frozen(ctx))
        if not reuse:
            self._start_cache = (geo, self.foundation, xo, po, d_start)
        d_end, dv = st.pop("d_end"), st.pop("dv")
        st = self._increment_totals(st, state, *self._axes_t(xn, geo), geo, d_start, d_end, dv)
        if snap:
            raise ReturnMappingError(self.law.failure_message)
        failure = self._failure(degenerate, nonfinite, st, ctx, outside)
        return GroupResult(f=f, K=K, state=st, failure=failure)

    def _end_stresses(self, stab, st, state, extra, D, tangent, P, t, geo, x=None):
        """``(st, p, tau)`` at the end of the increment: the law's stresses, plus the viscous
        ones of ``*CONTACT STABILIZATION`` when ``stab`` (zero otherwise), with the group's own
        totals (:meth:`_increment_totals`; ``extra`` as :meth:`_integrate` returns it)."""
        p, tau = np.asarray(st["p"], float), np.asarray(st["tau"], float)
        if stab is not None:
            p, tau = self._stabilise(stab, st, extra, D, tangent)
        else:
            st["ps"], st["ts"] = np.zeros(self.ng), np.zeros(self.ng)
        st = self._increment_totals(st, state, P, t, geo, extra[0], extra[1], extra[3], x)
        return st, p, tau

    @staticmethod
    def _nonfinite(*arrays) -> bool:
        """True when any entry of ``arrays`` is NaN or infinite."""
        return not all(np.isfinite(a).all() for a in arrays)

    def _failure(self, degenerate: bool, nonfinite: bool, st, ctx, bad=None) -> str | None:
        """The group's failure message, the first that applies: a face of zero Jacobian,
        non-finite forces or stresses, points the law cannot accept (:meth:`_inadmissible`)."""
        if degenerate:
            return f"contact {self.name}: degenerate face (zero Jacobian)"
        if nonfinite:
            return f"contact {self.name}: non-finite contact stresses"
        return self._inadmissible(st, ctx, bad)

    def _inadmissible(self, st, ctx, bad=None) -> str | None:
        """A failure message when the law finds points it cannot accept
        (:meth:`ContactLaw.inadmissible`, or ``bad`` (g,) when already known), except points
        held STICK by the solver."""
        bad = np.asarray(self.law.inadmissible(st) if bad is None else bad, bool)
        frozen = self._frozen(ctx)
        if frozen is not None:
            bad = bad & (np.asarray(frozen) != STICK)
        if not bad.any():
            return None
        return (f"contact {self.name}: {int(bad.sum())} point(s) end outside the friction cone "
                f"|tau| <= B + phi p{self.law.inadmissible_hint()}")

    # ------------------------------------------------------------------ output
    def points(self, u_new, state, ctx: StepContext):
        """Contact points for writers (:class:`~lagamine_py.elements.base.ContactPoints`).

        ``x`` current P and ``x0`` its reference position; ``p``, ``tau``, ``slip``, ``vp``,
        ``dvp``, ``lam``, ``dissip``, ``status`` from ``state``, except that a point whose
        normal misses the foundation at the end configuration has status NONE; ``gap`` in the
        COPEN convention, ``-d`` (positive when open), or for a NONE point the distance from P
        to the foundation.  Totals over the surface the forces are integrated on (the current
        face with NLGEOM, the reference face otherwise), ``dA = thickness ds`` (plane strain)
        or ``r ds`` (axisymmetry, per radian): ``P = int p dA``, ``T = int tau dA``, ``A = int
        dA`` over the points in contact (status STICK or SLIP), ``F`` (2,) the resultant force
        of the foundation on the body, ``-sum f`` (sum of the nodal contact forces), and ``E``
        the energy dissipated by friction (the sum of the points' ``energy``); ``M`` the moment of
        the forces on the body about the tool's reference point, ``stored`` the energy in the
        contact springs (:meth:`ContactLaw.stored_energy` over ``dA``; NaN when the law does not
        say), ``friction`` the frictional dissipation and ``stabilisation`` the energy the
        stabilisation has dissipated, both in the trapezoidal form of the energy balance.  ``F`` and ``M``
        include the stabilisation's tractions: they are the tool's reactions."""
        geo = bool(ctx.nlgeom)
        c, theta = self._placement(ctx, "new")
        P, t = self._axes_t(self._face_x(u_new), geo)
        e_u, _ = normal_axis(t)
        pr = self._project(P, e_u, (c, theta))
        dA = self._areas(P, t, geo, self._face_x(u_new))
        p = np.asarray(state["p"], float)
        tau = np.asarray(state["tau"], float)
        status = np.where(pr.found, np.asarray(state["status"], np.int8), NONE).astype(np.int8)
        gap = np.where(pr.found, -pr.d, 0.0)
        if not pr.found.all():
            # the distance is frame-free: measured to the chain turned back
            X = self.foundation.centre
            rel = P[~pr.found] - (X + c)
            cs, sn = np.cos(theta), np.sin(theta)
            back = X + np.column_stack([cs * rel[:, 0] + sn * rel[:, 1], -sn * rel[:, 0] + cs * rel[:, 1]])
            gap[~pr.found] = self.foundation.distance(back if theta else P[~pr.found],
                                                      None if theta else c)
        # the forces include the stabilisation's tractions (as the solver's equilibrium)
        pf = p + np.asarray(state.get("ps", 0.0), float)
        tf = tau + np.asarray(state.get("ts", 0.0), float)
        Pv, tv = P, t                             # the points the forces are integrated on
        if self._lift is None:
            wt, _ = self._weights(P, geo)
        else:                                     # GAUSS=LINEAR: the force points
            pf, tf, _, Pv, tv = self._lifted(pf, tf, None, self._face_x(u_new), geo, False)
            wt, _ = self._weights(Pv, geo, self._force)
        vec = pf[:, None] * _right(tv) - tf[:, None] * tv
        F = -np.einsum("gi,g->i", vec, wt)                         # sum_a N_a = 1 on a face
        arm = Pv - (self.foundation.centre + c)
        Fg = vec * wt[:, None]
        M = -float(np.sum(arm[:, 0] * Fg[:, 1] - arm[:, 1] * Fg[:, 0]))
        return self._point_record(state, P, p, tau, gap, status, dA, F, M)
