"""The Model: what a deck declares, resolved to arrays, ready for the step controller.

The deck builder (``lagamine_py.deck.builder``) produces a :class:`Model`; the solver
(``lagamine_py.solver``) consumes it.  Nothing here knows about text or line numbers except
``Where``, kept so that errors found late (a degenerate element, unrestrained DOFs) can still
point at the deck.

Conventions
-----------
* Nodes are stored in deck order; ``node_ids[r]`` is the deck id of row ``r`` and
  ``coords[r] = (x, y)`` (``(r, z)`` in axisymmetry).  Everything below refers to node *rows*
  (0-based), never to deck ids, except where a field name says ``_ids``.
* Global DOF of node row ``r``, direction ``c`` (0 = x/r, 1 = y/z) is ``2*r + c``.  The
  reference nodes of rigid tools (``*FOUNDATION, REF NODE=``) also have an in-plane rotation
  (deck DOF 6, counter-clockwise, in radians) in plane strain: those DOFs come after all the
  nodal ones, ``2*n + k`` for the ``k``-th reference node of :attr:`Model.rotation_nodes`
  (:meth:`Model.dof`).  Every array of nodal values keeps two columns per node; the rotations
  are the tail ``u[2*n:]`` of the global vectors.
* Element connectivity follows Abaqus (CPE8/CAX8, CPE6/CAX6, ...): corners counter-clockwise,
  then mid-sides; face Sk runs from corner k to corner k+1 (through its mid-side node).  The
  element class says which node is which (``lagamine_py.elements.base.Element``: ``faces``):
  Q8 faces S1..S4 are (1,2,5), (2,3,6), (3,4,7), (4,1,8); T6 faces S1..S3 (1,2,4), (2,3,5),
  (3,1,6).
* Axisymmetric loads and forces are per radian.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import kernels
from .core.params import Param


@dataclass(frozen=True)
class Where:
    """Position of a keyword block in the deck, for messages."""
    file: str
    line: int
    keyword: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: *{self.keyword}"


@dataclass
class ElementBlock:
    """Elements of one deck type and one solid section (material)."""
    type: str                 # registry name of the element plugin, e.g. "Q8PE"
    ids: np.ndarray           # (e,) deck element ids
    conn: np.ndarray          # (e, nen) node rows
    material: str             # material name
    thickness: float = 1.0    # plane strain out-of-plane thickness
    elset: str = ""
    where: Where | None = None


@dataclass
class Surface:
    """Element faces: ``elements[k]`` is a deck element id, ``faces[k]`` its face number 1.. (S1
    .. S4 on a quadrilateral, S1 .. S3 on a triangle)."""
    name: str
    elements: np.ndarray      # (f,) deck element ids
    faces: np.ndarray         # (f,) face numbers 1..
    where: Where | None = None


@dataclass
class MaterialSpec:
    name: str
    law: str                  # registry name in "laws"
    params: dict[str, Any]    # validated against the law's declared params
    where: Where | None = None


@dataclass
class ContactLawSpec:
    name: str
    type: str                 # registry name in "contact_laws"
    params: dict[str, Any]
    where: Where | None = None


@dataclass
class FoundationSpec:
    """A rigid tool.  It moves rigidly with its reference node ``ref_node`` (a node row, whose
    DOFs 1, 2 and, in plane strain, 6 carry the tool's translation and rotation), or, without
    one, by ``*FOUNDATION MOTION`` (a prescribed translation and rotation about ``centre``)."""
    name: str
    points: np.ndarray        # (m, 2), m odd >= 3; arcs through (0,1,2), (2,3,4), ...
    where: Where | None = None
    ref_node: int | None = None          # node row of the reference node, or None
    centre: tuple[float, float] = (0.0, 0.0)   # reference point (the ref node's coordinates)


@dataclass
class ContactSpec:
    """A ``*CONTACT`` pair: the slave ``surface`` against a rigid ``foundation`` or, with
    ``master`` (``foundation`` then ""), against another surface's faces
    (:mod:`lagamine_py.elements.two_body`; ``search`` its window's reach, None: default;
    ``passes`` 2: the master's points project on the slave's faces too, forces averaged)."""
    surface: str
    foundation: str
    law: str
    gauss: int | str = 3           # 2, 3, LOBATTO2, LOBATTO3 (elements.contact.RULES)
    where: Where | None = None
    master: str | None = None
    search: float | None = None
    passes: int = 1                # 2: the master's points project on the slave's faces too

    @property
    def target(self) -> str:
        """What the surface contacts: the master surface or the foundation (the pair's name
        is ``surface->target``)."""
        return self.master or self.foundation


@dataclass
class Amplitude:
    name: str
    time: np.ndarray
    value: np.ndarray
    where: Where | None = None

    def __call__(self, t):
        return np.interp(t, self.time, self.value)


@dataclass
class Boundary:
    """Imposed displacement: nodes (rows), DOFs first..last (1-based, as in the deck); ``dofs``
    the deck DOFs of that range that exist (1, 2, and 6 on reference nodes; default 1..2 of
    the range)."""
    target: str               # node id or nset name as written, for messages and reactions
    nodes: np.ndarray
    first: int
    last: int
    value: float
    amplitude: str | None = None
    where: Where | None = None
    dofs: tuple[int, ...] = ()

    @property
    def components(self) -> tuple[int, ...]:
        """The deck DOFs (1, 2, 6) this line imposes."""
        return self.dofs or tuple(d for d in (1, 2) if self.first <= d <= self.last)


@dataclass
class CLoad:
    target: str
    nodes: np.ndarray
    dof: int                  # 1, 2 or 6 (a moment on a reference node)
    value: float              # per node
    amplitude: str | None = None
    where: Where | None = None


@dataclass
class DLoad:
    surface: str
    kind: str                 # "P": pressure, positive into the body, follower
    value: float
    amplitude: str | None = None
    where: Where | None = None


@dataclass
class FoundationMotion:
    """Rigid motion of a foundation without a reference node reached at the step end: the
    translation (dx, dy) of its reference point and the rotation ``angle`` (radians,
    counter-clockwise) about it.  (On a foundation with a reference node the builder turns
    ``*FOUNDATION MOTION`` into ``*BOUNDARY`` lines on that node.)"""
    foundation: str
    dx: float
    dy: float
    amplitude: str | None = None
    where: Where | None = None
    angle: float = 0.0


@dataclass
class LawChange:
    """``*CHANGE CONTACT LAW``: from its step on, the pair ``pair`` (``SURFACE->FOUNDATION``)
    uses the contact law ``law``."""
    pair: str
    law: str
    where: Where | None = None


@dataclass
class Stabilisation:
    """``*CONTACT STABILIZATION`` of a step (see :mod:`lagamine_py.solver.tools`): viscous
    normal and tangential tractions on the open points of the pairs ``pairs`` (all when
    empty) that lie within ``range`` of their foundation (None: one face length)."""
    factor: float
    tangential: float = 1.0
    range: float | None = None
    pairs: tuple[str, ...] = ()
    where: Where | None = None


#: ``*OUTPUT, FIELDS=`` names: what the VTK body files carry besides the mesh and the ids
OUTPUT_FIELDS = {"U": "displacement", "S": "stress (tensor, von Mises, pressure)",
                 "LE": "total strain (logarithmic under NLGEOM, small strain otherwise)",
                 "PE": "plastic strain", "PEEQ": "equivalent plastic strain",
                 "RF": "reaction forces"}


@dataclass
class OutputRequest:
    frequency: int = 1
    fields: tuple[str, ...] = ()      # subset of OUTPUT_FIELDS; empty: all of them
    contact: bool = True
    writers: tuple[str, ...] = ()     # registry names of the writers; empty: the defaults


#: the Newton and step-controller settings a step may give with ``*CONTROLS`` (validated by the
#: deck builder, read by the step controller)
CONTROL_PARAMS: tuple[Param, ...] = (
    Param("RTOL", float, 1e-8, (0, 1), doc="relative force residual tolerance |R| / max(|F|, |RF|, floor)"),
    Param("ETOL", float, 1e-14, (0, 1), doc="relative energy tolerance |du.R| / first-iteration energy"),
    Param("MAXIT", int, 25, (1, 1000), doc="Newton iterations before the increment is cut back (up to 3 more when the residual, no contact state switching, reaches RTOL within them at its rate; 10 from a release of frozen contact points)"),
    Param("IR", int, 8, (0, 1000), doc="iterations after which (counted from the increment's start or a failed review of frozen contact points) an equilibrium iteration, one that switched no contact state, is judged by its logarithmic rate of convergence: the increment is cut back at once when the residual did not fall or would reach RTOL only after more than IC further iterations at that rate (Abaqus' I_R; 1 acts as 2: the rate needs two residuals of the round); 0: off"),
    Param("IC", int, 10, (1, 1000), doc="iterations to go allowed by the IR rule (Abaqus' I_C)"),
    Param("CUTBACK", float, 0.25, (0.01, 0.9), doc="factor applied to dt on a cut-back"),
    Param("GROWTH", float, 1.5, (1.0, 10.0), doc="factor applied to dt after an easy increment (not after a step's first increment, whose count is the contact-state search)"),
    Param("EASY", int, 5, (1, 1000), doc="an increment converged in at most this many iterations is easy"),
    Param("LINESEARCH", bool, False, doc="backtracking line search on the energy"),
    Param("SOLVER", str, "AUTO", upper=True,
          doc="sparse linear solver: a registered solver (AUTO, SPLU, PARDISO, or a plugin's)"),
    Param("KERNEL", str, "AUTO", choices=kernels.SETTINGS,
          doc="numba kernels (NUMBA, needs the fast extra), NumPy (NUMPY), or numba from "
              f"{kernels.AUTO_NUMBA_ELEMENTS} solid elements when installed (AUTO)"),
    Param("EXTRAPOLATION", str, "LINEAR", choices=("LINEAR", "PARABOLIC", "NONE"),
          doc="first iterate of an increment: the last increment of the step, scaled, its slip fronts moved on at their speed (LINEAR); the quadratic in time through the step's last two increments, the fronts as LINEAR (PARABOLIC; LINEAR after the step's first increment); or none"),
    Param("FLIPFLOP", int, 4, (1, 100), doc="contact status switches or slip reversals of a point before it is frozen"),
    Param("SDI", bool, True,
          doc="a residual growing while contact points change state is not a divergence (severe discontinuity iterations) unless it grows over 6 iterations running; MAXIT still bounds the increment"),
    Param("KRYLOV", int, 4, (0, 200),
          doc="GMRES steps on the factor in hand before the tangent is factorised anew (0: every Newton iteration factorises)"),
    Param("KRYLOVDOFS", int, 5000, (0, 10**9),
          doc="free DOFs from which KRYLOV applies (below, SPLU factorises in milliseconds and a run's path stays that of plain Newton)"),
)


@dataclass
class Step:
    """One ``*STEP``: what it gives anew.  ``op_new`` lists the load kinds given with OP=NEW
    ("BOUNDARY", "CLOAD", "DLOAD"); persistence is resolved by the step controller."""
    name: str
    nlgeom: bool = False
    max_increments: int = 1000
    dt0: float = 1.0
    period: float = 1.0
    dt_min: float = 1e-5
    dt_max: float = 1.0
    boundaries: list[Boundary] = field(default_factory=list)
    cloads: list[CLoad] = field(default_factory=list)
    dloads: list[DLoad] = field(default_factory=list)
    motions: list[FoundationMotion] = field(default_factory=list)
    op_new: set[str] = field(default_factory=set)
    law_changes: list[LawChange] = field(default_factory=list)
    stabilisation: Stabilisation | None = None
    output: OutputRequest = field(default_factory=OutputRequest)
    controls: dict[str, Any] = field(default_factory=dict)   # *CONTROLS values (tolerances ...)
    where: Where | None = None


@dataclass(frozen=True)
class DeckSource:
    """The deck a Model was read from: its absolute ``path``, the ``digest`` of its expanded
    text (SHA-256 hex of every file read and of the parameter values given from outside) and
    those ``parameters`` (NAME -> text).  Restarts and sweeps compare digests to know that
    they resume the same model."""
    path: str
    digest: str
    parameters: dict = field(default_factory=dict)


@dataclass
class Model:
    name: str                                  # deck stem, used for output file names
    heading: str = ""
    node_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    coords: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    blocks: list[ElementBlock] = field(default_factory=list)
    nsets: dict[str, np.ndarray] = field(default_factory=dict)      # name (upper) -> node rows
    elsets: dict[str, np.ndarray] = field(default_factory=dict)     # name (upper) -> element ids
    surfaces: dict[str, Surface] = field(default_factory=dict)
    materials: dict[str, MaterialSpec] = field(default_factory=dict)
    contact_laws: dict[str, ContactLawSpec] = field(default_factory=dict)
    foundations: dict[str, FoundationSpec] = field(default_factory=dict)
    contacts: list[ContactSpec] = field(default_factory=list)
    amplitudes: dict[str, Amplitude] = field(default_factory=dict)
    steps: list[Step] = field(default_factory=list)
    axisymmetric: bool = False
    parameters: dict[str, Any] = field(default_factory=dict)        # *PARAMETER values
    checks: list[dict[str, Any]] = field(default_factory=list)      # *CHECK requests
    units: tuple[str, ...] = ()           # *UNITS: names of the length, force, stress units
    source: DeckSource | None = None      # the deck it was read from (None: built by a script)
    #: what the deck builder changed or left out without it being an error ("file:line: *KW:
    #: text"): clockwise elements renumbered, nodes used by no element, keywords skipped ...
    notices: list[str] = field(default_factory=list)

    @property
    def rotation_nodes(self) -> list[int]:
        """Node rows with a rotation DOF (DOF 6): the reference nodes of the foundations, in
        the order the foundations are declared, each once; none in axisymmetry (a tool of
        revolution only translates)."""
        if self.axisymmetric:
            return []
        out: list[int] = []
        for spec in self.foundations.values():
            if spec.ref_node is not None and int(spec.ref_node) not in out:
                out.append(int(spec.ref_node))
        return out

    @property
    def ndof(self) -> int:
        return 2 * len(self.node_ids) + len(self.rotation_nodes)

    def dof(self, rows, c: int) -> np.ndarray:
        """Global DOFs of node rows ``rows`` in direction ``c`` (0 = x/r, 1 = y/z, 5 = the
        rotation, deck DOF 6, of reference nodes); KeyError for a row without that DOF."""
        rows = np.asarray(rows, np.int64)
        if c in (0, 1):
            return 2 * rows + c
        if c != 5:
            raise KeyError(f"no DOF {c + 1}: DOFs are 1, 2 and 6 (reference nodes)")
        rot = self.rotation_nodes
        at = {r: 2 * len(self.node_ids) + k for k, r in enumerate(rot)}
        missing = [int(r) for r in rows.ravel() if int(r) not in at]
        if missing:
            raise KeyError(f"node row {missing[0]} has no DOF 6 (not a reference node)")
        return np.array([at[int(r)] for r in rows.ravel()], np.int64).reshape(rows.shape)

    def dof_names(self) -> list[str]:
        """``node <id> x|y|rotation`` for every global DOF (messages)."""
        names = [f"node {int(i)} {c}" for i in self.node_ids for c in ("x", "y")]
        names += [f"node {int(self.node_ids[r])} rotation" for r in self.rotation_nodes]
        return names

    def element_lookup(self) -> dict[int, tuple[int, int]]:
        """deck element id -> (block index, row in block)."""
        out = {}
        for b, blk in enumerate(self.blocks):
            for k, eid in enumerate(blk.ids):
                out[int(eid)] = (b, k)
        return out
