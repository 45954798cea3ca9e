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
from ..foundation import Foundation
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


def _unit(t):
    """|t| (g,), t_hat (g, 2)."""
    n = _norm(t)
    return n, t / np.where(n > 0, n, 1.0)[:, None]


def _de_u_dt(t):
    """e_u (g, 2) and d e_u / d t (g, 2, 2) for e_u = R t / |t|."""
    n, th = _unit(t)
    e_u = _right(th)
    D = (_R[None] - e_u[:, :, None] * th[:, None, :]) / n[:, None, None]
    return e_u, D


def _de_v_dt(t):
    """e_v (g, 2) and d e_v / d t (g, 2, 2) for e_v = -t / |t|."""
    n, th = _unit(t)
    D = -(_I2[None] - th[:, :, None] * th[:, None, :]) / n[:, None, None]
    return -th, D


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
    """

    def __init__(self, name: str, face_nodes, elements, faces, coords0, foundation: Foundation,
                 foundation_name: str, law: ContactLaw, gauss: int = 3, axisymmetric: bool = False,
                 thickness: float = 1.0):
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
        # |d| below round-off of the coordinates is exact touching (a body meshed on the foundation)
        self._touch_tol = 1e-12 * max(1.0, float(np.abs(self.coords0).max(initial=0.0)))
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
        self._jac_tol = 1e-14 * max(1.0, float(np.abs(self.coords0).max(initial=1.0)))
        self._start_cache = None          # see _start_penetration
        self._kernel = False              # the fused kernel (use_kernels)
        self._kernel_static = None

    # ----------------------------------------------------------------- helpers
    def use_kernels(self, on: bool) -> None:
        """Compute the whole group through :mod:`lagamine_py.kernels.contact` (``on``, when the
        law has a kernel vector -- COULOMB -- and the foundation a kernel, and numba imports),
        or the NumPy reference; the foundation projects through its kernel likewise."""
        self.foundation.use_kernels(on)
        self._kernel = (bool(on) and self.law.kernel_vector() is not None and self._lift is None
                        and self.foundation.has_kernel() and kernels.module("contact") is not None)

    def init_state(self) -> dict[str, np.ndarray]:
        """The law's state of the points, and the group's own: ``dvp`` the signed slip of the
        last increment and ``energy`` the frictional energy each point has dissipated (see
        :meth:`_increment_totals`)."""
        state = self.law.init_state(self.ng)
        state["dvp"] = np.zeros(self.ng)
        state["energy"] = np.zeros(self.ng)
        return state

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

    def _increment_totals(self, st, state, P, t, geo, x=None) -> dict[str, np.ndarray]:
        """The group's own state after the law's: ``dvp = vp - vp_old`` and ``energy +=
        (dissip - dissip_old) dA``, ``dA`` the area the forces are integrated on at the end of
        the increment (so the sum over points and increments is the work of the friction
        stresses along the slip, as the forces see it)."""
        dA = self._areas(P, t, geo, x)
        st["dvp"] = np.asarray(st["vp"], float) - np.asarray(state["vp"], float)
        st["energy"] = (np.asarray(state["energy"], float)
                        + (np.asarray(st["dissip"], float) - np.asarray(state["dissip"], float)) * dA)
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

    def _translation(self, ctx: StepContext, which: str) -> np.ndarray:
        table = ctx.foundation_old if which == "old" else ctx.foundation_new
        return np.asarray(table.get(self.foundation_name, np.zeros(2)), float)

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

    def _penetration(self, x, c, scale, geo):
        """d (g,) and D d / D u_new (g, nd) (zeros when ``scale`` is 0) for positions x
        (f, a, 2) that move with ``scale`` * u_new.  Points not found: far open (d = -FAR),
        derivative 0.  Round-off touching (|d| <= tolerance) is snapped to d = 0, which the law
        treats as closed with p = 0: a body meshed on the foundation has contact stiffness from
        the first iteration, without a fake gap or spring."""
        P, t = self._axes_t(x, geo)
        return self._penetration_at(P, t, c, scale, geo)

    def _penetration_at(self, P, t, c, scale, geo):
        """:meth:`_penetration` from P (g, 2) and the axes' tangent t (g, 2)."""
        e_u, de = _de_u_dt(t)
        pr = self.foundation.project(P, e_u, c)
        d = np.where(pr.found, pr.d, -FAR)
        d = np.where(np.abs(d) <= self._touch_tol, 0.0, d)
        if scale == 0.0:
            return d, np.zeros((self.ng, self.nd)), pr
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
        return d, Dd, pr

    def _start_penetration(self, xo, co, geo):
        """d (g,) at the start of the increment (face positions xo, translation co).  It is the
        same at every Newton iteration of an increment, so the last one is kept and reused
        while the positions, the translation, NLGEOM and the foundation are bitwise the same."""
        c = self._start_cache
        if (c is not None and c[0] == geo and c[1] is self.foundation
                and np.array_equal(c[2], xo) and np.array_equal(c[3], co)):
            return c[4].copy()
        d, _, _ = self._penetration(xo, co, 0.0, geo)
        self._start_cache = (geo, self.foundation, xo.copy(), np.array(co, copy=True), d.copy())
        return d

    def start_penetration(self) -> np.ndarray:
        """d (g,) of the reference configuration against the foundation where the deck puts it
        (-FAR where a point's normal misses it): the faces near it, for the penalty advice."""
        d, _, _ = self._penetration(self._x0, np.zeros(2), 0.0, False)
        return d

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
    def _integrate(self, u_new, u_old, state, ctx, tangent):
        """Run the law over the sub-intervals; returns the end state, D p, D tau (g, nd), and
        P, t (g, 2) of the end configuration (``_axes_t`` of u_new, reused by ``compute``)."""
        xo, xn = self._face_x(u_old), self._face_x(u_new)
        dx = xn - xo
        co, cn = self._translation(ctx, "old"), self._translation(ctx, "new")
        geo = bool(ctx.nlgeom)
        nsub = self.substeps_for(xo, xn, geo)
        theta = float(self.law.theta)
        frozen = self._frozen(ctx)
        frozen_open = None if frozen is None else (frozen == OPEN)

        d_prev = self._start_penetration(xo, co, geo)          # start: fixed w.r.t. u_new
        d_start = d_prev
        # penetration at the end (the last sub-interval's); in between it moves linearly (see doc)
        P_end, t_end = self._axes_t(xn, geo)
        d_end, Dd_end, _ = self._penetration_at(P_end, t_end, cn, 1.0 if tangent else 0.0, geo)
        st = state
        D = dict.fromkeys(_OUT)                # None: a derivative known to be zero
        Dd_prev = None
        dc = (cn - co) / nsub
        dP = self._interp(self.N, dx) / nsub
        rel = dP - dc
        for k in range(1, nsub + 1):
            a_k = k / nsub
            if nsub == 1:
                d_k, Dd_k = d_end, Dd_end
            else:
                d_k = d_start + a_k * (d_end - d_start)
                Dd_k = a_k * Dd_end
            a_th = (k - 1 + theta) / nsub
            t_th = self._interp(self.dN, xo + a_th * dx) if geo else self._t0
            e_v, dev = _de_v_dt(t_th)
            dv = e_v[:, 0] * rel[:, 0] + e_v[:, 1] * rel[:, 1]
            du = d_k - d_prev
            new, tan = self.law.update(st, d_k, du, dv, frozen=frozen)
            if tangent:
                Ddv = self._kron(self._Ng, e_v)
                if nsub != 1:
                    Ddv /= nsub
                if geo:
                    # sum_i (rel_i dev_ij) A_t: the i terms summed last, as the former einsum
                    turn = (self._kron(self._dNg, rel[:, 0, None] * dev[:, 0, :])
                            + self._kron(self._dNg, rel[:, 1, None] * dev[:, 1, :]))
                    Ddv += turn if a_th == 1.0 else a_th * turn
                Ddu = Dd_k if Dd_prev is None else Dd_k - Dd_prev
                D = self._chain(tan, D, Ddu, Dd_prev, Ddv, lam=k < nsub)
            if frozen_open is not None and frozen_open.any():
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
            st = new
            d_prev, Dd_prev = d_k, Dd_k
        # the result never shares arrays with the committed state (a law may pass some through)
        st = {k: (v.copy() if v is state.get(k) else v) for k, v in st.items()}
        for key in ("p", "tau"):
            if tangent and D[key] is None:
                D[key] = np.zeros((self.ng, self.nd))
        return st, D, P_end, t_end

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

    def _lifted(self, st, D, x, geo, tangent):
        """GAUSS=LINEAR: p, tau (gF,) and their derivatives (gF, nd) at the force points,
        linear between the corners' values; P, t (gF, 2) there."""
        fs, L = self._force, self._lift
        lift = lambda v: np.einsum("qc,fc...->fq...", L, v.reshape(  # noqa: E731
            (self.nf, self.nq) + v.shape[1:])).reshape((-1,) + v.shape[1:])
        p, tau = lift(np.asarray(st["p"], float)), lift(np.asarray(st["tau"], float))
        Dl = {k: lift(D[k]) for k in ("p", "tau")} if tangent else D
        P, t = fs.at(x)
        return p, tau, Dl, P, (t if geo else fs.t0)

    def compute(self, u_new, u_old, state, ctx: StepContext, tangent: bool = True) -> GroupResult:
        """Contact forces ``f`` (f, nd) and ``K = df/du_new`` (f, nd, nd); see the module doc.

        With the COULOMB law, a :class:`~lagamine_py.foundation.Foundation` and numba, when
        switched on (:meth:`use_kernels`), the whole computation runs in one compiled loop over
        the points (:func:`lagamine_py.kernels.contact.contact_group`), equal to this NumPy code
        to round-off."""
        if self._kernel:
            return self._compute_fused(u_new, u_old, state, ctx, tangent)
        geo = bool(ctx.nlgeom)
        with np.errstate(invalid="ignore", divide="ignore"):
            st, D, P, t = self._integrate(u_new, u_old, state, ctx, tangent)
        xn = self._face_x(u_new)
        st = self._increment_totals(st, state, P, t, geo, xn)
        p, tau = np.asarray(st["p"], float), np.asarray(st["tau"], float)
        pts = self                                 # the points the forces are integrated on
        jac = _norm(t)
        if self._lift is not None:                 # GAUSS=LINEAR: at the force points
            pts = self._force
            p, tau, D, P, t = self._lifted(st, D, xn, geo, tangent)
        Ng_all, nq = (self._Ng, self.nq) if pts is self else (pts.Ng, pts.nq)
        Rt = _right(t)
        vec = p[:, None] * Rt - tau[:, None] * t                      # (p e_u + tau e_v) |t|
        wt, Dwt = self._weights(P, geo, None if pts is self else pts)
        f = Ng_all[:, :, None] * vec[:, None, :] * wt[:, None, None]            # (g, a, i)
        f = f.reshape(self.nf, nq, self.nd).sum(axis=1)
        failure = None
        if (jac <= self._jac_tol).any():
            failure = f"contact {self.name}: degenerate face (zero Jacobian)"
        elif not (np.isfinite(f).all() and np.isfinite(p).all() and np.isfinite(tau).all()):
            failure = f"contact {self.name}: non-finite contact stresses"
        else:
            failure = self._inadmissible(st, ctx)
        K = None
        if tangent:
            Dvec = Rt[:, :, None] * D["p"][:, None, :] - t[:, :, None] * D["tau"][:, None, :]
            if geo:                                   # the face (normal, length) moves
                RAt, At = (self._RAt, self._At) if pts is self else (pts.RAt, pts.At)
                Dvec += p[:, None, None] * RAt - tau[:, None, None] * At
            Ng = Ng_all[:, :, None, None]
            Kg = Ng * Dvec[:, None] * wt[:, None, None, None]         # (g, a, i, J)
            if Dwt is not None:
                Kg = Kg + Ng * vec[:, None, :, None] * Dwt[:, None, None, :]
            K = Kg.reshape(self.nf, nq, self.nd, self.nd).sum(axis=1)
        return GroupResult(f=f, K=K, state=st, failure=failure)

    def _compute_fused(self, u_new, u_old, state, ctx, tangent) -> GroupResult:
        """:meth:`compute` through the fused kernel (same sub-intervals, start penetration and
        its cache, failures)."""
        kc = kernels.module("contact")
        geo = bool(ctx.nlgeom)
        co, cn = self._translation(ctx, "old"), self._translation(ctx, "new")
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
                c(self._AP[:nq, 0, :], float), self.axisymmetric, self.thickness,
                self._touch_tol, FAR, self._jac_tol)
            self._face_nodes64 = c(self.face_nodes, np.int64)
        xo, xn, reuse = kc.face_positions(u_old, u_new, self._face_nodes64, self._x0, cache, co)
        nsub = self.substeps_for(xo, xn, geo)
        st, f, K, outside, d_start, (snap, degenerate, nonfinite) = kc.contact_group(
            self._kernel_static, self.foundation.kernel_arrays(), self.law.kernel_vector(),
            xo, xn, reuse, None if cache is None else cache[2], co, cn, nsub,
            float(self.law.theta), geo, tangent, state, self._frozen(ctx))
        if not reuse:
            self._start_cache = (geo, self.foundation, xo, np.array(co, float), d_start)
        st = self._increment_totals(st, state, *self._axes_t(xn, geo), geo)
        if snap:
            raise ReturnMappingError(self.law.failure_message)
        failure = None
        if degenerate:
            failure = f"contact {self.name}: degenerate face (zero Jacobian)"
        elif nonfinite:
            failure = f"contact {self.name}: non-finite contact stresses"
        elif outside.any():
            failure = self._inadmissible(st, ctx, outside)
        return GroupResult(f=f, K=K, state=st, failure=failure)

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
        the energy dissipated by friction (the sum of the points' ``energy``)."""
        geo = bool(ctx.nlgeom)
        c = self._translation(ctx, "new")
        P, t = self._axes_t(self._face_x(u_new), geo)
        e_u, _ = _de_u_dt(t)
        pr = self.foundation.project(P, e_u, c)
        dA = self._areas(P, t, geo, self._face_x(u_new))
        p = np.asarray(state["p"], float)
        tau = np.asarray(state["tau"], float)
        status = np.where(pr.found, np.asarray(state["status"], np.int8), NONE).astype(np.int8)
        gap = np.where(pr.found, -pr.d, 0.0)
        if not pr.found.all():
            gap[~pr.found] = self.foundation.distance(P[~pr.found], c)
        if self._lift is None:
            wt, _ = self._weights(P, geo)
            vec = p[:, None] * _right(t) - tau[:, None] * t
        else:                                     # the forces' points of GAUSS=LINEAR
            pf, tauf, _, Pf, tf = self._lifted(state, None, self._face_x(u_new), geo, False)
            wt, _ = self._weights(Pf, geo, self._force)
            vec = pf[:, None] * _right(tf) - tauf[:, None] * tf
        F = -np.einsum("gi,g->i", vec, wt)                         # sum_a N_a = 1 on a face
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
            E=float(np.sum(np.asarray(state["energy"], float))))
