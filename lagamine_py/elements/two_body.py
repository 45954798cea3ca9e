"""Contact between two deformable bodies: the paper's element on a slave surface whose Gauss
points project onto the current 3-node faces of a master surface (``*CONTACT, SURFACE=slave,
MASTER=surface``).

Axes as in :mod:`lagamine_py.elements.contact` (``f`` slave face, ``q`` Gauss point, ``g =
f*nq + q``, ``a`` slave face node, ``i``/``j`` component), plus ``m`` master face, ``b`` node
of a master face (corner, corner, mid), ``k`` candidate master face of a point, ``J``/``L``
column of a face's DOF vector.

The master chain
----------------
Each 3-node master face is a parabolic arc through its current nodes, ``F(s) = sum_b N_b(s)
X_b`` with ``s = -1`` at its first corner, ``+1`` at its second and ``0`` at the mid node
(``N = (s(s-1)/2, s(s+1)/2, 1-s^2)``): the paper's rigid foundation made of the master's faces,
moving with them.  A slave point P meets it along its outward normal, ``P - d e_u = F(s)``;
valid when ``s`` lies on the face (no extension beyond the master's edges: past an edge the
master body ends) and the faces face each other (``e_u . n < 0``, ``n = right normal of F'``,
the master's outward normal); the smallest ``|d|`` wins.  Differentiating ``P - d e_u - F(s; X)
= 0`` and dotting with a normal ``m`` of ``F'`` (removes ``ds``), then with ``w``, a normal of
``e_u`` (removes ``dd``)::

    dd = [m.(dP - sum_b N_b dX_b) - d m.de_u] / (m.e_u)
    ds = [w.(dP - sum_b N_b dX_b) - d w.de_u] / (w.F')

so ``dd/dX_b = -N_b(s) dd/dP``: the rigid tool's ``dd/dc = -dd/dP`` weighted by the master's
shape functions at Q.

Slip.  The tangential relative displacement of the increment is that of P against the master's
material point now under P: ``dv = e_v . (dP - sum_b N_b(s) dX_b) / N`` per sub-interval (``s``
of the end projection, ``dX_b`` the master nodes' increment), so a common rigid translation of
both bodies slides nothing; its tangent includes ``ds`` (``N'_b(s) dX_b``).  The penetration and
sub-intervals are those of the rigid case (:mod:`lagamine_py.elements.contact`).

Forces (one pass, slave -> master).  A point's force ``F_g = (p e_u + tau e_v) |t| W w`` acts on
the slave nodes with ``N_a`` and, reversed, on the master nodes of its face with ``N_b(s)``:
``sum_b N_b = 1``, so the forces on the two bodies are equal and opposite, exactly.  The
tangent is their derivative, including ``N'_b(s) ds`` of the master's weights.

The sparsity pattern (fixed between re-pairings).  Each slave face couples its own nodes to the
nodes of its *window*: the master faces whose nodes come within ``search`` (plus both faces'
sizes) of its nodes, chosen from the current positions by :meth:`TwoBodyGroup.refresh`.  The
solver calls it before every increment; the pattern is rebuilt only when a window changes (a
point slid onto new master faces), so a run with small sliding keeps the pattern of its start.
Within an increment the points project on their window only; a point that finds no face there
but would find one on the whole master (within half of ``search``) has slid out of its window, and
the group asks for a cut-back (a smaller increment, re-paired at its start).

What one pass gives away (``docs/two_body.md``, measured): the master's nodes are not
constrained, only the slave's Gauss points, so a master node may sink into a coarser slave; and
the master's nodal forces integrate its shape functions, kinked at its face ends, with the
slave's Gauss points, so a flat non-matching interface whose slave faces straddle master face
ends fails the patch test (nested meshes pass it).  Choose the finer (at equal meshes the
stiffer) surface as the slave.

Two passes (``PASSES=2``).  The group's faces are the slave's then the master's, and so are the
chain's; a face's window and candidates are the other surface's faces only.  Each point's
weight is halved, so the forces, the tangent, the areas and totals (P, T, A, energies) are the
average of the two one-pass pairs (slave on master, master on slave).  This reduces the
non-nested patch-test error (most where the slave is the coarser surface) but spoils the nested
case, which one pass gets exact.
"""
from __future__ import annotations

import numpy as np

from ..core.errors import CutbackRequest
from ..core.status import NONE, OPEN
from ..core.tensors import left_normal, right_normal
from ..foundation import GRAZING_COS
from ..laws.base import ContactLaw
from .base import GroupResult, StepContext
from .contact import FAR, ContactGroup, normal_axis, sub_penetration, tangent_axis

__all__ = ["MasterChain", "TwoBodyGroup", "master_shape"]

_OUT = ("p", "tau", "lam")


def master_shape(s):
    """``N_b(s)`` and ``N'_b(s)`` (g, 3) of a master face (corner, corner, mid)."""
    s = np.asarray(s, float)
    N = np.stack([0.5 * s * (s - 1.0), 0.5 * s * (s + 1.0), 1.0 - s * s], axis=-1)
    dN = np.stack([s - 0.5, s + 0.5, -2.0 * s], axis=-1)
    return N, dN


class MasterChain:
    """The 3-node faces of a master surface as parabolic arcs at their current positions.

    Parameters
    ----------
    face_nodes : (m, 3) node rows (corner, corner, mid), each face with its body on its left.
    coords0 : (n, 2) reference coordinates of all nodes.
    s_tol, cos_min : as :class:`lagamine_py.foundation.Foundation` (joints, grazing rays).
    """

    def __init__(self, face_nodes, coords0, s_tol: float = 1e-8, cos_min: float = GRAZING_COS):
        self.face_nodes = np.asarray(face_nodes, np.int64)
        if self.face_nodes.ndim != 2 or self.face_nodes.shape[1] != 3:
            raise ValueError("a master surface needs 3-node faces (Q8, T6 elements)")
        self._x0 = np.asarray(coords0, float)[self.face_nodes]        # (m, 3, 2)
        self.s_tol, self.cos_min = float(s_tol), float(cos_min)

    def positions(self, u) -> np.ndarray:
        """Current node positions (m, 3, 2) of the faces."""
        return self._x0 + np.asarray(u, float)[self.face_nodes]

    def project(self, P, e_u, X, cand) -> dict:
        """Lines (P, e_u) (g, 2) against the candidate faces ``cand`` (g, k) (-1: none) at
        positions X (m, 3, 2).  Returns ``found`` (g,), ``k`` (g,) the winning column of
        ``cand``, ``face`` (g,), ``s``, ``d`` (-inf where not found), ``dF`` (g, 2) = F'(s)."""
        g, kk = cand.shape
        Xc = X[np.maximum(cand, 0)]                                     # (g, k, 3, 2)
        A = Xc[:, :, 2]
        B = 0.5 * (Xc[:, :, 1] - Xc[:, :, 0])
        C = 0.5 * (Xc[:, :, 0] + Xc[:, :, 1]) - Xc[:, :, 2]
        w = left_normal(e_u)[:, None, :]                                # (g, 1, 2)
        a = (w * C).sum(-1)
        b = (w * B).sum(-1)
        c0 = (w * (A - P[:, None, :])).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            disc = b * b - 4.0 * a * c0
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            q = -0.5 * (b + np.where(b >= 0, sq, -sq))
            r1 = q / a
            r2 = np.where((q == 0) & (a != 0), -b / (2.0 * a), c0 / q)
        roots = np.stack([r1, r2], axis=-1)                             # (g, k, 2)
        ok = np.isfinite(roots) & (np.abs(roots) <= 1.0 + self.s_tol) & (cand >= 0)[:, :, None]
        s = np.where(ok, roots, 0.0)
        F = A[:, :, None] + B[:, :, None] * s[..., None] + C[:, :, None] * s[..., None] ** 2
        dF = B[:, :, None] + 2.0 * C[:, :, None] * s[..., None]         # (g, k, 2, 2)
        n = right_normal(dF)
        nn = np.sqrt((n * n).sum(-1))
        cosn = (n * e_u[:, None, None, :]).sum(-1) / np.where(nn > 0, nn, 1.0)
        ok &= (nn > 0) & (cosn < -self.cos_min)
        d = ((P[:, None, None, :] - F) * e_u[:, None, None, :]).sum(-1) / (e_u * e_u).sum(-1)[:, None, None]
        score = np.where(ok, np.abs(d), np.inf).reshape(g, 2 * kk)
        best = np.argmin(score, axis=1) if kk else np.zeros(g, np.int64)
        rows = np.arange(g)
        found = np.isfinite(score[rows, best]) if kk else np.zeros(g, bool)
        k, r = np.divmod(best, 2)
        return {"found": found, "k": k, "face": np.where(found, cand[rows, k], -1),
                "s": np.where(found, s[rows, k, r], 0.0),
                "d": np.where(found, d[rows, k, r], -np.inf),
                "dF": np.where(found[:, None], dF[rows, k, r], 0.0)}

    @staticmethod
    def near(Y, X, search: float) -> np.ndarray:
        """(f, m) bool: faces at Y (f, a, 2) and X (m, 3, 2) whose node circles (centre the
        nodes' mean, radius the largest node distance) come within ``search``."""
        cy, cx = Y.mean(axis=1), X.mean(axis=1)
        ry = np.sqrt(((Y - cy[:, None]) ** 2).sum(-1)).max(axis=1)
        rx = np.sqrt(((X - cx[:, None]) ** 2).sum(-1)).max(axis=1)
        dist = np.sqrt(((cy[:, None, :] - cx[None, :, :]) ** 2).sum(-1))
        return dist <= ry[:, None] + rx[None, :] + search


class TwoBodyGroup(ContactGroup):
    """Contact elements on the faces of a slave surface against the faces of a master surface.

    Parameters
    ----------
    name : str, ``"<slave>-><master>"``.
    face_nodes, elements, faces, coords0, law, gauss, axisymmetric, thickness : the slave's, as
        :class:`~lagamine_py.elements.contact.ContactGroup`.
    master_faces : (m, 3) node rows of the master's faces.
    master_name : str, the master surface (for messages).
    search : float or None, the window's reach (see the module doc); default three times the
        larger median face length of the two surfaces.
    """

    def __init__(self, name: str, face_nodes, elements, faces, coords0, master_faces,
                 master_name: str, law: ContactLaw, gauss: int = 3, axisymmetric: bool = False,
                 thickness: float = 1.0, search: float | None = None, passes: int = 1,
                 master_elements=None, master_element_faces=None):
        if passes not in (1, 2):
            raise ValueError(f"contact {name!r}: PASSES is 1 or 2, not {passes}")
        self.passes = int(passes)
        slave_faces = np.asarray(face_nodes, np.int64)
        master_faces = np.asarray(master_faces, np.int64)
        ns, nm = len(slave_faces), len(master_faces)
        if passes == 2:
            # both surfaces carry points, each projecting on the other's faces (module doc)
            if master_elements is None or master_element_faces is None:
                raise ValueError(f"contact {name!r}: two passes need the master's elements and faces")
            face_nodes = np.concatenate([slave_faces, master_faces])
            elements = np.concatenate([np.asarray(elements, int), np.asarray(master_elements, int)])
            faces = np.concatenate([np.asarray(faces, int), np.asarray(master_element_faces, int)])
            chain = face_nodes
        else:
            chain = master_faces
        super().__init__(name, face_nodes, elements, faces, coords0, None, master_name, law,
                         gauss, axisymmetric, thickness)
        self.master = MasterChain(chain, coords0)
        self.master_name = master_name
        self._slave_dofs = self.dofs.copy()                           # (f, nd)
        self._gface = np.repeat(np.arange(self.nf), self.nq)          # (g,) face of a point
        # the chain faces each face may meet (f, K), -1 padded: the other surface's
        if passes == 2:
            side = np.repeat([0, 1], [ns, nm])                       # 0 slave, 1 master surface
            self._allowed = side[:, None] != side[None, :]            # (f, m)
            width = max(ns, nm)
            own = [np.arange(ns, ns + nm), np.arange(ns)]
            self._others = np.full((self.nf, width), -1, np.int64)
            for k in (0, 1):
                self._others[side == k, :len(own[k])] = own[k]
            self._Wg = 0.5 * self._Wg        # each pass carries half: the forces are averaged
            # +1 where a point's own force acts on the slave, -1 (its reaction does) on the master
            self._on_slave = np.repeat(np.where(side == 0, 1.0, -1.0), self.nq)
        else:
            self._on_slave = np.ones(self.ng)
            self._allowed = None
            self._others = np.broadcast_to(np.arange(nm), (self.nf, nm))
        if search is None:
            def median_length(x):
                return float(np.median(np.linalg.norm(x[:, 1] - x[:, 0], axis=1))) if len(x) else 0.0
            search = 3.0 * max(median_length(self._x0), median_length(self.master._x0))
        self.search = float(search)
        self.window = None
        self.refresh(np.zeros_like(self.coords0))

    # ---------------------------------------------------------------- pairing
    def use_kernels(self, on: bool) -> None:
        """NumPy only: no kernel twin for two bodies yet."""
        self._kernel = self._kernel_wanted = False

    def refresh(self, u) -> bool:
        """Choose every slave face's window from the positions ``u`` (n, 2) (module doc);
        True when ``dofs`` changed (the solver then rebuilds the pattern)."""
        Y = self._face_x(u)
        X = self.master.positions(u)
        near = MasterChain.near(Y, X, self.search)                         # (f, m)
        if self._allowed is not None:
            near &= self._allowed
        if self.window is not None and np.array_equal(near, self._near):
            return False
        self._near = near
        # at least one window column: -1 (no face) everywhere when the bodies are apart
        K = max(int(near.sum(axis=1).max(initial=0)), 1)
        order = np.argsort(~near, axis=1, kind="stable")[:, :K]
        win = np.where(np.take_along_axis(near, order, axis=1), order, -1)   # (f, K)
        # the window's nodes, unique per face, padded by repeating the first (zero columns)
        nodes = np.where(win[:, :, None] >= 0, self.master.face_nodes[np.maximum(win, 0)], -1)
        nodes = np.sort(nodes.reshape(self.nf, -1), axis=1)                # -1 first
        dup = np.zeros(nodes.shape, bool)
        dup[:, 1:] = nodes[:, 1:] == nodes[:, :-1]
        keep = (nodes >= 0) & ~dup
        M = int(keep.sum(axis=1).max(initial=0))
        pick = np.argsort(~keep, axis=1, kind="stable")[:, :M]
        wn = np.take_along_axis(nodes, pick, axis=1)
        valid = np.take_along_axis(keep, pick, axis=1)
        first = np.where(valid[:, :1], wn[:, :1], self.face_nodes[:, :1])
        wn = np.where(valid, wn, first)
        # slot (f, K, 3) of each window face's node among the face's window nodes
        fn = self.master.face_nodes[np.maximum(win, 0)]                    # (f, K, 3)
        hit = (fn[:, :, :, None] == wn[:, None, None, :]) & valid[:, None, None, :]
        # no master face near any slave face (the bodies apart): empty windows, no slots
        slot = np.argmax(hit, axis=-1) if M else np.zeros(fn.shape, np.int64)
        self.window, self._slot, self._wnodes = win, slot, wn
        self.nw = self.nd + 2 * M
        mdofs = (2 * wn[:, :, None] + np.arange(2)).reshape(self.nf, 2 * M)
        self.dofs = np.concatenate([self._slave_dofs, mdofs], axis=1)
        self._start_cache = None
        return True

    # ------------------------------------------------------------ projection
    def _master_project(self, P, t, X, geo, tangent):
        """d (g,) (``-FAR`` where not found, snapped to 0 within round-off), the projection and,
        when ``tangent``, D d and D s (g, nw) with respect to the face's DOF vector."""
        e_u, de = normal_axis(t)
        cand = self.window[self._gface]
        pr = self.master.project(P, e_u, X, cand)
        found = pr["found"]
        d = np.where(found, pr["d"], -FAR)
        d = np.where(np.abs(d) <= self._touch_tol, 0.0, d)
        if not tangent:
            return d, pr, None, None
        m = right_normal(pr["dF"])
        w = left_normal(e_u)
        me = np.where(found, (m * e_u).sum(-1), 1.0)
        wF = np.where(found, (w * pr["dF"]).sum(-1), 1.0)
        out = []
        dist = np.where(found, pr["d"], 0.0)
        for vec, den in ((m, me), (w, wF)):
            a = np.where(found[:, None], vec / den[:, None], 0.0)          # d()/dP
            D = np.zeros((self.ng, self.nw))
            D[:, :self.nd] = self._kron(self._Ng, a)
            if geo:                                  # the normal turns with the slave face
                da = -dist[:, None] * a                                       # d()/de_u
                D[:, :self.nd] += self._kron(self._dNg, np.einsum("gi,giJ->gJ", da, de))
            N, _ = master_shape(pr["s"])
            self._scatter_master(D, pr, -N[:, :, None] * a[:, None, :])
            out.append(D)
        return d, pr, out[0], out[1]

    def _master_cols(self, pr) -> np.ndarray:
        """Columns (g, 3, 2) of each point's master face nodes in its face's DOF vector."""
        slot = self._slot[self._gface, pr["k"]]                              # (g, 3)
        return self.nd + 2 * slot[:, :, None] + np.arange(2)

    def _scatter_master(self, D, pr, vals) -> None:
        """``D[g, column of (b, i)] += vals[g, b, i]`` for the points found."""
        found = pr["found"]
        if not found.any():
            return
        g = np.flatnonzero(found)
        cols = self._master_cols(pr)[g]
        np.add.at(D, (np.broadcast_to(g[:, None, None], cols.shape), cols), vals[g])

    def _start_d(self, xo, Xo, geo):
        """d at the start of the increment (cached while the start positions are the same)."""
        c = self._start_cache
        if (c is not None and c[0] == geo and np.array_equal(c[1], xo)
                and np.array_equal(c[2], Xo) and c[3] is self.window):
            return c[4]
        P, t = self._axes_t(xo, geo)
        d, _, _, _ = self._master_project(P, t, Xo, geo, False)
        self._start_cache = (geo, xo.copy(), Xo.copy(), self.window, d)
        return d

    def _escaped(self, P, t, X, found) -> int:
        """How many points found no face in their window but would on the whole master within
        ``search`` (they slid out of it: the pattern must grow)."""
        lost = np.flatnonzero(~found)
        if not len(lost):
            return 0
        e_u, _ = normal_axis(t[lost])
        cand = np.ascontiguousarray(self._others[self._gface[lost]])
        pr = self.master.project(P[lost], e_u, X, cand)
        return int(np.sum(pr["found"] & (pr["d"] > -0.5 * self.search)))

    # ----------------------------------------------------------------- compute
    def _integrate(self, u_new, u_old, state, ctx, tangent, stab=False):
        """As :meth:`ContactGroup._integrate` against the master: the end state, D p, D tau
        (g, nw), P, t (g, 2) of the end configuration, the end projection, D s, and
        ``(d_start, d_end, D d_end, sum dv, D sum dv)``."""
        xo, xn = self._face_x(u_old), self._face_x(u_new)
        Xo, Xn = self.master.positions(u_old), self.master.positions(u_new)
        dx = xn - xo
        geo = bool(ctx.nlgeom)
        nsub = self.substeps_for(xo, xn, geo)
        theta = float(self.law.theta)
        frozen = self._frozen(ctx)
        frozen_open = None if frozen is None else (frozen == OPEN)
        d_start = self._start_d(xo, Xo, geo)
        P_end, t_end = self._axes_t(xn, geo)
        d_end, pr, Dd_end, Ds = self._master_project(P_end, t_end, Xn, geo, tangent)
        found = pr["found"]
        # the master's material point under P moves by sum_b N_b(s) dX_b
        Xf = (Xn - Xo)[np.maximum(pr["face"], 0)]                          # (g, 3, 2)
        N, dN = master_shape(pr["s"])
        dW = np.where(found[:, None], np.einsum("gb,gbi->gi", N, Xf), 0.0)
        dWs = np.where(found[:, None], np.einsum("gb,gbi->gi", dN, Xf), 0.0)
        rel = (self._interp(self.N, dx) - dW) / nsub
        st, D, d_prev, Dd_prev = state, dict.fromkeys(_OUT), d_start, None
        dv_sum, Ddv_sum = 0.0, None
        for k in range(1, nsub + 1):
            d_k, Dd_k = sub_penetration(k, nsub, d_start, d_end, Dd_end)
            a_th = (k - 1 + theta) / nsub
            t_th = self._interp(self.dN, xo + a_th * dx) if geo else self._t0
            e_v, dev = tangent_axis(t_th)
            dv = (e_v * rel).sum(-1)
            new, tan = self.law.update(st, d_k, d_k - d_prev, dv, frozen=frozen)
            dv_sum = dv_sum + dv
            if tangent:
                Ddv = np.zeros((self.ng, self.nw))
                Ddv[:, :self.nd] = self._kron(self._Ng, e_v) / nsub
                if geo:
                    Ddv[:, :self.nd] += a_th * self._kron(self._dNg, np.einsum("gi,giJ->gJ", rel, dev))
                self._scatter_master(Ddv, pr, -N[:, :, None] * e_v[:, None, :] / nsub)
                Ddv -= ((e_v * dWs).sum(-1) / nsub)[:, None] * Ds
                if stab:
                    Ddv_sum = Ddv.copy() if Ddv_sum is None else Ddv_sum + Ddv
                Ddu = Dd_k if Dd_prev is None else Dd_k - Dd_prev
                D = self._chain(tan, D, Ddu, Dd_prev, Ddv, lam=k < nsub)
            st = self._hold_open(new, st, D, frozen_open)
            d_prev, Dd_prev = d_k, Dd_k
        st = self._detached(st, state, D, tangent)
        return st, D, P_end, t_end, pr, Ds, (d_start, d_end, Dd_end, dv_sum, Ddv_sum)

    def compute(self, u_new, u_old, state, ctx: StepContext, tangent: bool = True) -> GroupResult:
        """Forces ``f`` (f, nw) on the slave face's nodes and its window's master nodes, and
        ``K = df/du_new`` (f, nw, nw); see the module doc."""
        geo = bool(ctx.nlgeom)
        stab = self._stabilisation(ctx)
        with np.errstate(invalid="ignore", divide="ignore"):
            st, D, P, t, pr, Ds, extra = self._integrate(u_new, u_old, state, ctx, tangent,
                                                         stab is not None)
        if self._escaped(P, t, self.master.positions(u_new), pr["found"]):
            raise CutbackRequest(f"contact {self.name}: points slid out of their search window "
                                 f"(SEARCH={self.search:g}); a smaller increment re-pairs them",
                                 factor=0.5)
        st, p, tau = self._end_stresses(stab, st, state, extra, D, tangent, P, t, geo)
        Rt = right_normal(t)
        vec = p[:, None] * Rt - tau[:, None] * t                  # (p e_u + tau e_v) |t|
        wt, Dwt = self._weights(P, geo)
        F = vec * wt[:, None]                                     # (g, 2) force of a point
        Rop, dRop = self._row_operator(pr)                        # (g, nw, 2)
        f = np.einsum("gri,gi->gr", Rop, F).reshape(self.nf, self.nq, self.nw).sum(axis=1)
        jac = np.sqrt((t * t).sum(-1))
        failure = self._failure((jac <= self._jac_tol).any(), self._nonfinite(f, p, tau), st, ctx)
        K = None
        if tangent:
            Dvec = Rt[:, :, None] * D["p"][:, None, :] - t[:, :, None] * D["tau"][:, None, :]
            if geo:
                Dvec[:, :, :self.nd] += p[:, None, None] * self._RAt - tau[:, None, None] * self._At
            DF = Dvec * wt[:, None, None]
            if Dwt is not None:
                DF[:, :, :self.nd] += vec[:, :, None] * Dwt[:, None, :]
            Kg = np.einsum("gri,giJ->grJ", Rop, DF)
            Kg += np.einsum("gri,gi->gr", dRop, F)[:, :, None] * Ds[:, None, :]
            K = Kg.reshape(self.nf, self.nq, self.nw, self.nw).sum(axis=1)
        return GroupResult(f=f, K=K, state=st, failure=failure)

    def _row_operator(self, pr):
        """``R`` (g, nw, 2): the rows a point's force reaches (``N_a`` on the slave, ``-N_b(s)``
        on its master face), and ``dR/ds`` (only the master's part moves)."""
        R = np.zeros((self.ng, self.nw, 2))
        dR = np.zeros((self.ng, self.nw, 2))
        for a in range(self.nfn):
            for i in range(2):
                R[:, 2 * a + i, i] = self._Ng[:, a]
        found = pr["found"]
        if found.any():
            g = np.flatnonzero(found)
            N, dN = master_shape(pr["s"][g])
            cols = self._master_cols(pr)[g]                           # (h, 3, 2)
            gi = np.broadcast_to(g[:, None, None], cols.shape)
            ii = np.broadcast_to(np.arange(2), cols.shape)
            np.add.at(R, (gi, cols, ii), -np.broadcast_to(N[:, :, None], cols.shape))
            np.add.at(dR, (gi, cols, ii), -np.broadcast_to(dN[:, :, None], cols.shape))
        return R, dR

    # ------------------------------------------------------------------ output
    def points(self, u_new, state, ctx: StepContext):
        """Contact points for writers, as :meth:`ContactGroup.points`: ``F`` the resultant force
        of the master on the slave (minus the forces on the slave's nodes, of both passes), ``M``
        0; ``gap`` of a point whose normal meets no face of the other surface is its distance to
        the nearest of that surface's nodes and face quarter points."""
        geo = bool(ctx.nlgeom)
        P, t = self._axes_t(self._face_x(u_new), geo)
        X = self.master.positions(u_new)
        e_u, _ = normal_axis(t)
        pr = self.master.project(P, e_u, X, np.ascontiguousarray(self._others[self._gface]))
        found = pr["found"]
        wt, _ = self._weights(P, geo)
        dA = wt * np.sqrt((t * t).sum(-1))
        p = np.asarray(state["p"], float)
        tau = np.asarray(state["tau"], float)
        status = np.where(found, np.asarray(state["status"], np.int8), NONE).astype(np.int8)
        gap = np.where(found, -pr["d"], 0.0)
        if not found.all():
            N, _ = master_shape(np.linspace(-1.0, 1.0, 5))
            pts = np.einsum("sb,mbi->msi", N, X)                          # (m, 5, 2)
            lost = np.flatnonzero(~found)
            cand = self._others[self._gface[lost]]                        # (h, K)
            dist = np.sqrt(((P[lost, None, None] - pts[np.maximum(cand, 0)]) ** 2).sum(-1))
            dist = np.where(cand[:, :, None] >= 0, dist, np.inf)
            gap[lost] = dist.reshape(len(lost), -1).min(axis=1)
        pf = p + np.asarray(state.get("ps", 0.0), float)
        tf = tau + np.asarray(state.get("ts", 0.0), float)
        vec = pf[:, None] * right_normal(t) - tf[:, None] * t
        Fres = -np.einsum("gi,g->i", vec, wt * self._on_slave)
        return self._point_record(state, P, p, tau, gap, status, dA, Fres, 0.0)
