"""The contracts of what the solver assembles: groups, and the element plugins among them.

A *group* holds many elements of one kind and computes them all at once, batched over
elements x Gauss points (axes ``e``, ``q``; see :mod:`lagamine_py.laws.base` for the letters).
The solver never loops over elements: it asks each group for ``(f, K)`` arrays and scatters
them into a sparse matrix whose pattern was built once from ``group.dofs``.

Residual convention: ``R(u) = sum_groups f_group(u) - f_external = 0`` where a group's ``f`` is
its contribution to the *internal* side (a solid's internal force, a contact element's contact
force as in the paper's virtual work; a pressure load contributes ``-f_pressure``), and ``K`` is
``dR/du`` of that contribution (so the global tangent is the plain sum).

An :class:`Element` plugin is a group class that also answers for its topology: natural node
coordinates, shape functions, Gauss rule, faces, VTK cell type, outline for plots, the recovery
of Gauss values at the nodes and the check of its Jacobian.  Nothing outside ``elements/``
looks at a node count: the deck builder, the writers and the plots ask the element class.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.plugin import Plugin
from ..core.tensors import det2
from . import bernstein

__all__ = ["StepContext", "GroupResult", "Group", "Element", "CellBlock", "ContactPoints",
           "JacobianCheck", "LATER"]

_CHUNK = 4096          # elements (or sub-domains) per vectorised chunk: bounded temporaries
_MAX_OPEN = 250_000    # sub-domains left open beyond this stop the subdivision (refused as undecided)


@dataclass
class StepContext:
    """What a group needs to know about the increment being solved."""
    nlgeom: bool = False
    t_old: float = 0.0              # total time at the start of the increment
    t_new: float = 0.0              # total time at its end
    # name -> placement at t_old / t_new: (dx, dy) or (dx, dy, theta), the translation of the
    # foundation's reference point and its rotation about it (lagamine_py.foundation)
    foundation_old: dict[str, np.ndarray] = field(default_factory=dict)
    foundation_new: dict[str, np.ndarray] = field(default_factory=dict)
    freeze_contact: dict[str, np.ndarray] | None = None   # contact group name -> (g,) statuses held
    # contact group name -> (kn, kt, range) of *CONTACT STABILIZATION in this increment, or None
    stabilisation: dict[str, tuple[float, float, float]] | None = None


class _Later:
    """The type of :data:`LATER` (truthy: a group that does not defer computes its tangent)."""

    def __bool__(self) -> bool:
        return True

    def __repr__(self) -> str:
        return "LATER"


#: ``compute(..., tangent=LATER)`` of a group whose :attr:`Group.defers_tangent` is True: the
#: forces and the trial state now, the tangent only if the solver asks for it, computed then
#: from what the group kept (:attr:`GroupResult.later`).  The evaluation at which Newton
#: converges needs no tangent (:meth:`lagamine_py.solver.problem.Problem.evaluate`).
LATER = _Later()


@dataclass
class GroupResult:
    """``f`` (e, nd) and ``K`` (e, nd, nd) (None when not asked, or when a fused kernel added it
    into the global data); ``state`` the trial state (committed by the solver only when the
    increment converges); ``failure`` a message when the group could not compute (negative
    Jacobian, return mapping failed): the step controller then cuts back.  ``later``: with
    ``tangent=LATER``, a function returning ``K`` (e, nd, nd) -- bit for bit the ``K`` of
    ``tangent=True`` -- from what the group kept, instead of ``K`` now."""
    f: np.ndarray
    K: np.ndarray | None
    state: dict[str, np.ndarray]
    failure: str | None = None
    later: Callable[[], np.ndarray] | None = None


@dataclass
class JacobianCheck:
    """What :meth:`Element.jacobian_check` found: ``valid`` (e,) det J above the floor over the
    whole element (proved); ``min_found`` (e,) the smallest det J met (a value at a point, or,
    for an element within round-off of the floor, its lower bound); ``at`` (e, 2) the natural
    point of that value."""
    valid: np.ndarray
    min_found: np.ndarray
    at: np.ndarray


@dataclass
class CellBlock:
    """What writers get of a solid group: the element class (its topology: VTK cell, recovery),
    the deck ids (e,), the connectivity (e, nen) in node rows, and the Gauss values: the Cauchy
    stress (e, q, 4) and the equivalent plastic strain (e, q); when the element computes them,
    the total strain and the plastic strain (e, q, 4), tensor components [11, 22, 33, 12]
    (``strain_kind`` says which total strain: ``"log"``, the logarithmic (Hencky) strain
    ``ln V`` under NLGEOM, or ``"small"``, the infinitesimal strain)."""
    element: type
    ids: np.ndarray
    conn: np.ndarray
    stress: np.ndarray
    peeq: np.ndarray
    strain: np.ndarray | None = None
    plastic_strain: np.ndarray | None = None
    strain_kind: str = ""


@dataclass
class ContactPoints:
    """What writers get of a contact group: all its Gauss points, flattened (g,).

    Signs (a face runs in the element's counter-clockwise order, direction ``t``, body on its
    left; ``e_v = -t/|t|``): ``tau > 0`` when the friction of the foundation on the body points
    along ``+t`` (a bottom face: +x; a top face: -x); the signed slip ``vp > 0`` when the body
    has slid along ``e_v`` relative to the foundation (a bottom face: towards -x), so a sliding
    point has ``tau`` and ``dvp`` of one sign.  ``gap`` follows COPEN (Abaqus, CalculiX):
    positive when open, ``-d`` (minus the penetration) where the normal meets the foundation;
    where it meets none (status NONE) the distance from P to the nearest point of the
    foundation."""
    name: str                     # "<surface>-><foundation>"
    element: np.ndarray           # (g,) deck id of the solid element owning the face
    face: np.ndarray              # (g,) face number 1..
    gauss: np.ndarray             # (g,) Gauss point number on the face, 1-based
    x: np.ndarray                 # (g, 2) current position of the point P
    p: np.ndarray
    tau: np.ndarray
    gap: np.ndarray               # COPEN: > 0 open, -penetration in contact
    slip: np.ndarray              # accumulated |slip| (the law's slip)
    lam: np.ndarray
    status: np.ndarray            # int8 OPEN/STICK/SLIP/NONE (lagamine_py.core.status)
    P: float                      # total normal force: integral of p over the current surface
    T: float                      # total tangential force: integral of tau
    A: float = float("nan")       # current area (length x thickness, or per radian) of points in contact
    F: np.ndarray | None = None   # (2,) resultant force of the foundation on the body (sum of nodal forces)
    x0: np.ndarray | None = None  # (g, 2) reference position of P (default: x)
    vp: np.ndarray | None = None  # (g,) signed slip (default 0)
    dvp: np.ndarray | None = None     # (g,) signed slip of the last increment (default 0)
    dissip: np.ndarray | None = None  # (g,) frictional dissipation per unit area D (default 0)
    E: float = 0.0                # energy the pair has dissipated: sum over increments of int dD dA
    M: float = 0.0                # moment of the foundation's forces on the body about the tool's
                                  # reference point (its current position; counter-clockwise)
    stored: float = float("nan")  # energy stored in the contact springs (ContactLaw.stored_energy)
    stabilisation: float = 0.0    # energy the contact stabilisation has dissipated since the start
    friction: float = 0.0         # frictional dissipation since the start, in the trapezoidal form
                                  # of the energy balance (E: the law's integral along increments)

    def __post_init__(self):
        g = len(np.asarray(self.p).ravel())
        if self.x0 is None:
            self.x0 = np.asarray(self.x, float).reshape(-1, 2).copy()
        self.vp = np.zeros(g) if self.vp is None else self.vp
        self.dvp = np.zeros(g) if self.dvp is None else self.dvp
        self.dissip = np.zeros(g) if self.dissip is None else self.dissip


class Group:
    """Base of everything the solver assembles.  ``dofs`` (e, nd) global DOF numbers and ``ids``
    (e,) labels for messages, fixed for the run unless :meth:`refresh` says otherwise."""

    dofs: np.ndarray
    ids: np.ndarray
    #: True when the solver calls :meth:`compute_into` (a fused kernel computing and scattering)
    #: instead of :meth:`compute`; set by :meth:`use_kernels`
    fused: bool = False
    #: True when :meth:`compute` accepts ``tangent=LATER`` (forces and state now, the tangent
    #: from :attr:`GroupResult.later` when asked: what the group keeps for it costs less than
    #: computing it again).  Other groups are asked ``tangent=True`` in such an evaluation.
    defers_tangent: bool = False

    def init_state(self) -> dict[str, np.ndarray]:
        return {}

    def compute(self, u_new: np.ndarray, u_old: np.ndarray, state: dict[str, np.ndarray],
                ctx: StepContext, tangent: bool = True) -> GroupResult:
        """``u_new``/``u_old``: global nodal displacements (n, 2) at the end / start of the
        increment.  ``state``: committed state at the start of the increment (not modified).
        ``tangent``: True, False, or :data:`LATER` when :attr:`defers_tangent`."""
        raise NotImplementedError

    def use_kernels(self, on: bool) -> None:
        """Use the numba kernels where the group has them (``on``) or the NumPy reference.
        Default: the group has none."""

    def refresh(self, u: np.ndarray) -> bool:
        """Before an increment, from the converged nodal displacements ``u`` (n, 2): re-pair
        what the group couples (two-body contact: the master faces each slave face may reach)
        and return True when ``dofs`` changed, so the solver rebuilds the sparsity pattern.
        Default: ``dofs`` are fixed for the run (False)."""
        return False

    def compute_into(self, u_new, u_old, state, ctx, tangent, data, f_out, positions) -> GroupResult:
        """:meth:`compute` through a fused kernel that adds the tangent into the CSR ``data`` at
        ``positions`` (the group's ``Pattern.positions``) and the forces into ``f_out`` (ndof,);
        returns the element forces and the trial state with ``K = None``.  Called only when
        :attr:`fused` is True."""
        raise NotImplementedError


class Element(Group, Plugin):
    """Base of element plugins (entry-point group ``lagamine_py.elements``): a group of elements
    of one type and one material.

    A subclass declares its topology as class attributes and class methods -- usually by
    mixing in a reference shape (:class:`lagamine_py.elements.quad.Quad8`, ...) -- and its
    mechanics (``__init__``, :meth:`init_state`, :meth:`compute`), usually by deriving from
    :class:`lagamine_py.elements.solid.SolidElement`, the isoparametric continuum element that
    works for any shape functions.

    Topology
    --------
    ``nen``        number of nodes;
    ``node_xi``    (nen, 2) natural coordinates of the nodes (Abaqus order: corners
                   counter-clockwise, then mid-sides);
    ``faces``      local nodes of faces S1, S2, ... (corner, corner[, mid]), each running with
                   the element on its left;
    ``outline``    local nodes in order around the boundary (plots draw it);
    ``vtk_cell``   VTK cell type, whose node order is ours;
    ``axisymmetric`` integrals per radian (r dr dz) instead of per thickness;
    ``grid_order``, ``cell_elements``  how ``*MESH`` fills a rectangle: grid points per cell side
                   (1 linear, 2 quadratic) and the elements of one cell as the grid offsets
                   (i, j) of their nodes;
    ``reference_domain``, ``jacobian_degree``  the natural domain (``"square"`` [-1, 1]^2 or
                   ``"triangle"`` (0,0), (1,0), (0,1)) and the degree of det J as a polynomial on
                   it (tensor ``(p, q)`` on the square, total on the triangle): the Jacobian check
                   (:meth:`jacobian_check`) proves det J > 0 over the whole element from them.

    Mechanics
    ---------
    Built as ``Cls(ids (e,), conn (e, nen), coords0 (n, 2), law, thickness)`` (``law`` a
    :class:`~lagamine_py.laws.base.MaterialLaw`; ``thickness`` ignored in axisymmetry) and
    keeping ``ids``, ``conn`` and ``dofs`` (e, 2 nen; DOF ``2 node + i``).  :meth:`compute`
    returns ``f`` (e, 2 nen) and ``K`` (e, 2 nen, 2 nen) and a state holding the law's arrays
    (e, q, ...) and ``stress`` (e, q, 4), the Cauchy stress that writers show.

    ``lagamine-py plugins --check`` (:func:`lagamine_py.contracts.check_element`) checks all of
    this on any topology: shape functions, Gauss rule, faces, outline, Jacobian check, recovery,
    VTK node order, a patch test, rigid motions and the tangent against finite differences.
    """

    params = ()
    nen: int = 0
    node_xi: np.ndarray = np.zeros((0, 2))
    faces: tuple[tuple[int, ...], ...] = ()
    outline: tuple[int, ...] = ()
    vtk_cell: int = 0
    axisymmetric: bool = False
    grid_order: int = 1
    cell_elements: tuple[tuple[tuple[int, int], ...], ...] = ()
    reference_domain: str = "square"
    jacobian_degree: int | tuple[int, int] = 0

    # -- topology: what a subclass (or its shape) provides ------------------------------------
    @classmethod
    def shape_functions(cls, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N (q, a) and dN/dxi (q, a, 2) at natural points (q, 2)."""
        raise NotImplementedError

    @classmethod
    def gauss_rule(cls) -> tuple[np.ndarray, np.ndarray]:
        """Points (q, 2) and weights (q,) of the element's integration rule."""
        raise NotImplementedError

    @classmethod
    def recovery_basis(cls, pts: np.ndarray, nq: int) -> np.ndarray:
        """(p, nq) polynomials, as many as Gauss points and unisolvent on them, evaluated at
        natural points (p, 2): :meth:`recovery_matrix` fits them to the Gauss values."""
        raise NotImplementedError

    # -- what follows from the topology --------------------------------------------------------
    @classmethod
    def recovery_matrix(cls, nq: int | None = None) -> np.ndarray:
        """E (a, q) taking Gauss values to the nodes: the polynomial of :meth:`recovery_basis`
        through the Gauss values, evaluated at the nodes (exact for fields the rule holds)."""
        pts, _ = cls.gauss_rule()
        nq = len(pts) if nq is None else nq
        if nq != len(pts):
            raise ValueError(f"{cls.__name__}: {nq} Gauss values, the rule has {len(pts)}")
        at_gauss = cls.recovery_basis(pts, nq)                         # (q, m)
        at_nodes = cls.recovery_basis(np.asarray(cls.node_xi, float), nq)
        return at_nodes @ np.linalg.inv(at_gauss)

    @classmethod
    def gauss_weights(cls) -> np.ndarray:
        """The Gauss weights (q,) normalised to 1: the weights of an element mean."""
        w = cls.gauss_rule()[1]
        return w / w.sum()

    @classmethod
    def jacobian_check(cls, coords: np.ndarray, floor=None, max_depth: int = 10) -> JacobianCheck:
        """Whether det J stays above ``floor`` over the *whole* of each element (not only at
        some points), with the smallest det J found and where.

        det J of an isoparametric element is a polynomial on its reference domain
        (:attr:`reference_domain`, of degree :attr:`jacobian_degree`), so its Bernstein
        coefficients (:mod:`lagamine_py.elements.bernstein`) bound it from below: all above
        ``floor`` proves the element valid everywhere; a value at a lattice point at or below
        ``floor`` proves it invalid.  Elements the bound does not decide are subdivided (four
        sub-domains a level, only the undecided ones) until it does; one still undecided after
        ``max_depth`` levels (or when more than 250 000 sub-domains are open) has det J within
        round-off of ``floor`` somewhere and is refused.

        ``coords`` (e, nen, 2); ``floor`` (e,) or a number, default ``1e-10 size^2`` (the
        element's largest coordinate extent).  Vectorised over elements, in chunks."""
        coords = np.asarray(coords, float)
        ne = len(coords)
        if floor is None:
            floor = 1e-10 * np.ptp(coords, axis=1).max(axis=1) ** 2 if ne else np.zeros(0)
        floor = np.broadcast_to(np.asarray(floor, float), (ne,))
        dom = bernstein.domain(cls.reference_domain, cls.jacobian_degree)
        # level 0, every element on the whole domain (the same lattice for all)
        values = cls._det_j(coords, np.arange(ne), dom.points, shared=True)      # (e, m)
        k = values.argmin(axis=1)
        found = values[np.arange(ne), k]
        at = dom.points[k]
        low = (values @ dom.to_bernstein.T).min(axis=1)
        invalid = found <= floor
        open_ = ~invalid & (low <= floor)
        bound = np.where(open_, low, np.inf)
        # deeper levels: the open sub-domains (element of each, map x = origin + matrix u)
        elem = np.flatnonzero(open_)
        origin = np.zeros((len(elem), 2))
        matrix = np.broadcast_to(np.eye(2), (len(elem), 2, 2))
        for _depth in range(max_depth):
            if not len(elem) or len(elem) > _MAX_OPEN:                # (a bound on the work)
                break
            elem = np.repeat(elem, 4)                                # the four children of each
            origin = (origin[:, None, :] + np.einsum("pij,cj->pci", matrix, dom.origins)).reshape(-1, 2)
            matrix = np.einsum("pij,cjk->pcik", matrix, dom.matrices).reshape(-1, 2, 2)
            pts = origin[:, None, :] + np.einsum("pij,mj->pmi", matrix, dom.points)   # (p, m, 2)
            values = cls._det_j(coords, elem, pts, shared=False)
            k = values.argmin(axis=1)
            v = values[np.arange(len(elem)), k]
            np.minimum.at(found, elem, v)
            hit = v == found[elem]
            at[elem[hit]] = pts[np.flatnonzero(hit), k[hit]]
            invalid[elem[v <= floor[elem]]] = True
            low = (values @ dom.to_bernstein.T).min(axis=1)
            keep = (low <= floor[elem]) & ~invalid[elem]
            open_[:] = False
            open_[elem[keep]] = True
            bound[elem] = np.inf
            np.minimum.at(bound, elem[keep], low[keep])
            elem, origin, matrix = elem[keep], origin[keep], matrix[keep]
        # still open after max_depth: det J within round-off of the floor somewhere; refused
        undecided = open_ & ~invalid
        found = np.where(undecided, np.minimum(bound, floor), found)
        return JacobianCheck(~invalid & ~undecided, found, at)

    @classmethod
    def _det_j(cls, coords, elem, pts, shared: bool) -> np.ndarray:
        """(p, m) det J of elements ``coords[elem]`` (p,) at natural points ``pts``: (m, 2) the
        same for all (``shared``: one BLAS product per chunk), or (p, m, 2) their own."""
        na = cls.nen
        out = np.empty((len(elem), pts.shape[-2]))
        if shared:
            _, dN = cls.shape_functions(pts)
            nq = len(pts)
            dN_flat = np.ascontiguousarray(dN.transpose(1, 0, 2).reshape(na, nq * 2))   # (a, q k)
        for lo in range(0, len(elem), _CHUNK):
            X = coords[elem[lo:lo + _CHUNK]]
            if shared:
                # J (e, i, q k) = X^T dN
                J = (np.swapaxes(X, 1, 2) @ dN_flat).reshape(len(X), 2, nq, 2).transpose(0, 2, 1, 3)
            else:
                P = pts[lo:lo + _CHUNK]
                _, dN = cls.shape_functions(P.reshape(-1, 2))
                J = np.einsum("pai,pmak->pmik", X, dN.reshape(P.shape[0], P.shape[1], na, 2))
            out[lo:lo + _CHUNK] = det2(J)
        return out

    @classmethod
    def min_jacobian(cls, coords: np.ndarray) -> np.ndarray:
        """(e,) the smallest det J found over each element by :meth:`jacobian_check`: > 0
        exactly for the elements shown valid everywhere.

        In axisymmetry an element with a node at r < 0, or a Gauss point at r <= 0, gets
        ``-|min det J|`` (or -1 if that is 0), so that a ``> 0`` test rejects it."""
        coords = np.asarray(coords, float)
        check = cls.jacobian_check(coords, floor=0.0)
        out = np.where(check.valid, check.min_found, np.minimum(check.min_found, 0.0))
        if cls.axisymmetric:
            out = np.where(cls.off_axis(coords), np.where(out == 0.0, -1.0, -np.abs(out)), out)
        return out

    @classmethod
    def off_axis(cls, coords) -> np.ndarray:
        """(e,) elements reaching r < 0 at a node, or r <= 0 at a Gauss point (what an
        axisymmetric element cannot have)."""
        gauss, _ = cls.gauss_rule()
        N, _ = cls.shape_functions(gauss)
        r = coords[..., 0]
        size = np.ptp(coords.reshape(len(coords), -1), axis=1) + 1e-300
        r_gauss = np.einsum("qa,ea->eq", N, r)
        return (r.min(axis=1) < -1e-12 * size) | (r_gauss.min(axis=1) <= 0.0)

    @classmethod
    def invalid(cls, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elements that are inverted or degenerate anywhere inside: ``(bad (e,) bool, min
        det J found (e,))``, det J compared to the element's size (``<= 1e-10 size^2`` is
        degenerate; :meth:`jacobian_check`)."""
        coords = np.asarray(coords, float)
        check = cls.jacobian_check(coords)
        bad = ~check.valid
        if cls.axisymmetric:
            bad |= cls.off_axis(coords)
        return bad, check.min_found

    @classmethod
    def mirror(cls) -> np.ndarray:
        """(nen,) the local node order that turns the element over (clockwise <-> counter-
        clockwise): node ``a`` of the turned element is node ``mirror()[a]``.  The reference
        domain is symmetric about xi = eta, which sends node ``a`` to the node at the swapped
        natural coordinates."""
        xi = np.asarray(cls.node_xi, float)
        swapped = xi[:, ::-1]
        match = np.all(np.isclose(swapped[:, None, :], xi[None, :, :], atol=1e-12), axis=2)
        if not (match.sum(axis=1) == 1).all():
            raise ValueError(f"{cls.__name__}: node_xi is not symmetric about xi = eta")
        return match.argmax(axis=1)

    @classmethod
    def mirror_faces(cls) -> np.ndarray:
        """(faces,) face numbers 1.. of the turned element (:meth:`mirror`) holding face
        ``k + 1`` of the element as given (the same edge, run the other way)."""
        perm = cls.mirror()
        inverse = np.argsort(perm)
        out = []
        for f in cls.faces:
            corners = {int(inverse[a]) for a in f[:2]}
            out.append(next(j + 1 for j, g in enumerate(cls.faces) if set(g[:2]) == corners))
        return np.array(out)

    @classmethod
    def contract_problem(cls) -> str:
        """What the class lacks of the element contract ("" when nothing)."""
        if not isinstance(cls.nen, (int, np.integer)) or cls.nen < 2:
            return "it does not declare its number of nodes (nen)"
        xi = np.asarray(cls.node_xi)
        if xi.shape != (cls.nen, 2):
            return f"node_xi must be ({cls.nen}, 2), got {xi.shape}"
        if not cls.faces or any(len(f) not in (2, 3) or not all(0 <= a < cls.nen for a in f)
                                for f in cls.faces):
            return "faces must list 2 or 3 local nodes (corner, corner[, mid]) per face"
        if sorted(cls.outline) != sorted(set(a for f in cls.faces for a in f)):
            return "outline must visit every node of the faces once"
        if not cls.vtk_cell:
            return "it does not declare its VTK cell type (vtk_cell)"
        if cls.reference_domain not in bernstein.DOMAINS:
            return f"reference_domain must be one of {', '.join(bernstein.DOMAINS)}"
        if not np.all(np.asarray(cls.jacobian_degree) >= 1):
            return "it does not declare the polynomial degree of its det J (jacobian_degree)"
        return ""

    # -- what writers get -------------------------------------------------------------------------
    def cell_block(self, u: np.ndarray, state: dict[str, np.ndarray],
                   nlgeom: bool = False) -> CellBlock:
        """The group's Gauss values for writers: ``stress`` (Cauchy, e, q, 4) and ``peeq`` from
        the state (zeros where the state has none); no strains (an element that computes them
        overrides this, as :class:`~lagamine_py.elements.solid.SolidElement` does).
        ``nlgeom``: the kinematics of the step (which total strain to give)."""
        ne = len(self.ids)
        stress = state.get("stress")
        nq = stress.shape[1] if stress is not None else len(self.gauss_rule()[0])
        peeq = state.get("peeq")
        return CellBlock(type(self), np.asarray(self.ids), np.asarray(self.conn),
                         stress if stress is not None else np.zeros((ne, nq, 4)),
                         peeq if peeq is not None else np.zeros((ne, nq)))

    conn: np.ndarray          # (e, nen) node rows
