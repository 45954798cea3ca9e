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
import numpy as np

from ..core.plugin import Plugin
from ..core.tensors import det2

__all__ = ["StepContext", "GroupResult", "Group", "Element", "CellBlock", "ContactPoints"]


@dataclass
class StepContext:
    """What a group needs to know about the increment being solved."""
    nlgeom: bool = False
    t_old: float = 0.0              # total time at the start of the increment
    t_new: float = 0.0              # total time at its end
    foundation_old: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (2,) translation at t_old
    foundation_new: dict[str, np.ndarray] = field(default_factory=dict)  # name -> (2,) translation at t_new
    freeze_contact: dict[str, np.ndarray] | None = None   # contact group name -> (g,) statuses held


@dataclass
class GroupResult:
    """``f`` (e, nd) and ``K`` (e, nd, nd) (None when not asked, or when a fused kernel added it
    into the global data); ``state`` the trial state (committed by the solver only when the
    increment converges); ``failure`` a message when the group could not compute (negative
    Jacobian, return mapping failed): the step controller then cuts back."""
    f: np.ndarray
    K: np.ndarray | None
    state: dict[str, np.ndarray]
    failure: str | None = None


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

    def __post_init__(self):
        g = len(np.asarray(self.p).ravel())
        if self.x0 is None:
            self.x0 = np.asarray(self.x, float).reshape(-1, 2).copy()
        self.vp = np.zeros(g) if self.vp is None else self.vp
        self.dvp = np.zeros(g) if self.dvp is None else self.dvp
        self.dissip = np.zeros(g) if self.dissip is None else self.dissip


class Group:
    """Base of everything the solver assembles.  ``dofs`` (e, nd) global DOF numbers and ``ids``
    (e,) labels for messages, both fixed for the run."""

    dofs: np.ndarray
    ids: np.ndarray
    #: True when the solver calls :meth:`compute_into` (a fused kernel computing and scattering)
    #: instead of :meth:`compute`; set by :meth:`use_kernels`
    fused: bool = False

    def init_state(self) -> dict[str, np.ndarray]:
        return {}

    def compute(self, u_new: np.ndarray, u_old: np.ndarray, state: dict[str, np.ndarray],
                ctx: StepContext, tangent: bool = True) -> GroupResult:
        """``u_new``/``u_old``: global nodal displacements (n, 2) at the end / start of the
        increment.  ``state``: committed state at the start of the increment (not modified)."""
        raise NotImplementedError

    def use_kernels(self, on: bool) -> None:
        """Use the numba kernels where the group has them (``on``) or the NumPy reference.
        Default: the group has none."""

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
                   (i, j) of their nodes.

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

    @classmethod
    def sample_points(cls) -> np.ndarray:
        """(m, 2) natural points where :meth:`min_jacobian` evaluates det J: the nodes, the
        Gauss points and a grid over the whole element, edges included."""
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
    def min_jacobian(cls, coords: np.ndarray) -> np.ndarray:
        """(e,) smallest det J of elements ``coords`` (e, nen, 2) over :meth:`sample_points`.

        In axisymmetry an element with a node at r < 0, or a Gauss point at r <= 0, gets
        ``-|min det J|`` (or -1 if that is 0), so that a ``> 0`` test rejects it."""
        coords = np.asarray(coords, float)
        pts = cls.sample_points()
        _, dN = cls.shape_functions(pts)
        nq, na = len(pts), cls.nen
        dN_flat = np.ascontiguousarray(dN.transpose(1, 0, 2).reshape(na, nq * 2))   # (a, q k)
        out = np.empty(len(coords))
        for lo in range(0, len(coords), 4096):                 # chunks: bounded temporaries
            X = coords[lo:lo + 4096]
            # J (e, i, q k) = X^T dN, one BLAS product per chunk
            J = (np.swapaxes(X, 1, 2) @ dN_flat).reshape(len(X), 2, nq, 2).transpose(0, 2, 1, 3)
            out[lo:lo + 4096] = det2(J).min(axis=1)
        if cls.axisymmetric:
            gauss, _ = cls.gauss_rule()
            N, _ = cls.shape_functions(gauss)
            r = coords[..., 0]
            size = np.ptp(coords.reshape(len(coords), -1), axis=1) + 1e-300
            r_gauss = np.einsum("qa,ea->eq", N, r)
            bad = (r.min(axis=1) < -1e-12 * size) | (r_gauss.min(axis=1) <= 0.0)
            out = np.where(bad, np.where(out == 0.0, -1.0, -np.abs(out)), out)
        return out

    @classmethod
    def invalid(cls, coords: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Elements that are inverted or degenerate: ``(bad (e,) bool, min det J (e,))``, with
        det J compared to the element's size (``<= 1e-10 size^2`` is degenerate)."""
        coords = np.asarray(coords, float)
        detj = cls.min_jacobian(coords)
        size = np.ptp(coords, axis=1).max(axis=1)
        return ~(detj > 1e-10 * size**2), detj

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
