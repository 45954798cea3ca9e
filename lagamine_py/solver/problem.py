"""From a :class:`~lagamine_py.model.Model` to the groups the solver iterates on.

:func:`build_problem` instantiates, through the registry, the material laws, one solid group per
element block, the contact laws, the foundations, one contact group per ``*CONTACT`` and one
pressure group per surface that some step loads with ``*DLOAD``; then it builds the sparsity
pattern once.  :meth:`Problem.evaluate` asks every group for its forces (and tangent) and
assembles them.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .. import kernels, registry
from ..core.errors import CutbackRequest, GroupFailure
from ..core.status import OPEN, SLIP
from ..elements.base import LATER
from ..elements.contact import ContactGroup
from ..elements.edges import PressureGroup, surface_faces
from ..elements.two_body import TwoBodyGroup
from ..foundation import Foundation
from .pattern import Pattern

SOLID, CONTACT, PRESSURE = "solid", "contact", "pressure"


@dataclass
class Evaluation:
    f_int: np.ndarray               # (ndof,) sum of the groups' f (internal side)
    data: np.ndarray | None         # (nnz,) CSR data of the tangent, None when not asked
    states: list[dict]              # trial states
    scale: float                    # max over groups of |f_g| (force scale of the residual test)
    results: list[Any] = field(default_factory=list)


class PendingTangent(Evaluation):
    """An :class:`Evaluation` asked with ``tangent=LATER``: ``data`` is computed when first read
    (``finish()``), then kept."""

    def __init__(self, f_int, data, states, scale, results, finish):
        self._finish = finish
        super().__init__(f_int, data, states, scale, results)

    @property
    def data(self):
        if self._data is None and self._finish is not None:
            self._data, self._finish = self._finish(), None
        return self._data

    @data.setter
    def data(self, value):
        self._data = value


@dataclass
class Problem:
    """Groups of a model and the fixed sparsity pattern.

    ``groups[k]`` has kind ``kinds[k]`` (solid / contact / pressure) and label ``group_names[k]``
    (element type and elset, ``surface->foundation``, or the pressure surface).  ``blocks[k]`` is
    the :class:`ElementBlock` of a solid group (None otherwise).  ``pressure_groups`` maps a
    surface name to its pressure group, ``foundations`` a foundation name to its object.
    """
    model: Any
    groups: list
    kinds: list[str]
    group_names: list[str]
    blocks: list
    pressure_groups: dict[str, Any]
    foundations: dict[str, Any]
    pattern: Pattern
    warnings: list[str] = field(default_factory=list)   # model advice, logged when the run starts
    notices: list[str] = field(default_factory=list)    # what the deck builder did, logged too
    kernel: str = "AUTO"        # solid-group kernel: AUTO / NUMPY / NUMBA (see set_kernel)
    #: contact group index -> h / E of its faces (the penalty advice, face_scales)
    face_scales: dict[int, np.ndarray] = field(default_factory=dict)
    #: foundation name -> the global DOFs of its reference node (u, v[, rotation])
    tools: dict[str, np.ndarray] = field(default_factory=dict)
    #: contact law name -> instance (the *CONTACT laws and those *CHANGE CONTACT LAW names)
    contact_laws: dict[str, Any] = field(default_factory=dict)
    #: contact group index -> the name of the law it has now, and its *CONTACT law
    pair_laws: dict[int, str] = field(default_factory=dict)
    initial_laws: dict[int, str] = field(default_factory=dict)
    #: the nodal DOFs (two per node) come first; the rotations of reference nodes after them
    nodal: int = -1

    @property
    def ndof(self) -> int:
        return self.pattern.ndof

    def init_states(self) -> list[dict]:
        return [g.init_state() for g in self.groups]

    def indices(self, kind: str) -> list[int]:
        return [k for k, kd in enumerate(self.kinds) if kd == kind]

    def set_kernel(self, kernel: str) -> None:
        """Choose NumPy or the numba kernels for every group (:func:`lagamine_py.kernels.use_numba`:
        ``NUMPY``, ``NUMBA`` -- KeyError when numba is not installed -- or ``AUTO``); a group
        uses a kernel where it has one (a built-in law, the COULOMB law on a foundation)."""
        n = self.solid_elements()
        on = {kind: kernels.use_numba(kernel, n, kind) for kind in ("solid", "contact")}
        self.kernel = str(kernel).upper()
        for g, kind in zip(self.groups, self.kinds):
            g.use_kernels(on.get(kind, on["solid"]))

    def solid_elements(self) -> int:
        """Number of solid elements of the model."""
        return sum(len(self.groups[k].dofs) for k in self.indices(SOLID))

    def evaluate(self, u_new: np.ndarray, u_old: np.ndarray, states: list[dict], ctx,
                 tangent=True) -> Evaluation:
        """Compute every group at ``u_new`` (ndof,) from the committed ``states``; assemble.

        Groups with a fused kernel (:meth:`fused`) add their tangent into the CSR data and their
        force into their own global vector as they compute (``results[k].K`` is then None);
        the others return (e, nd, nd) blocks scattered afterwards, in group order.

        ``tangent``: True, False, or :data:`~lagamine_py.elements.base.LATER` (Newton's choice
        for an evaluation it expects to converge at, whose tangent nobody uses): the forces and
        states now, the tangent when ``data`` is first read -- from what the groups that defer
        it kept (:attr:`~lagamine_py.elements.base.Group.defers_tangent`), the fused groups
        computed again, the others' blocks computed now --, bit for bit the ``data`` of
        ``tangent=True``.

        Raises :class:`~lagamine_py.core.errors.GroupFailure` when a group reports a failure
        or raises an ``ArithmeticError`` (a ``CutbackRequest``, floating-point errors); a
        cut-back request's factor goes with it."""
        n2 = u_new.size if self.nodal < 0 else self.nodal
        un, uo = u_new[:n2].reshape(-1, 2), u_old[:n2].reshape(-1, 2)
        ctx = self.tool_context(ctx, u_new, u_old)
        later = tangent is LATER
        results, vectors = [], {}
        fused = [g.fused for g in self.groups]
        data = np.zeros(self.pattern.nnz) if tangent and not later and any(fused) else None
        for k, g in enumerate(self.groups):
            ask = bool(tangent)
            if later:
                ask = False if fused[k] else LATER if g.defers_tangent else True
            if fused[k]:
                vectors[k] = np.zeros(self.ndof)
            results.append(self._compute_group(k, un, uo, states[k], ctx, ask, data,
                                               vectors.get(k)))
        f_int = np.zeros(self.ndof)
        scale = 0.0
        for k, r in enumerate(results):
            fk = vectors[k] if fused[k] else self.pattern.group_vector(k, r.f)
            f_int += fk
            scale = max(scale, float(np.linalg.norm(fk)))
        states_new = [r.state for r in results]
        if later:
            return PendingTangent(f_int, None, states_new, scale, results,
                                  finish=lambda: self._later_data(un, uo, states, ctx, results))
        if tangent:             # the other groups' blocks, after the fused ones (solids first)
            data = self.pattern.assemble_data([None if f else r.K for f, r in zip(fused, results)],
                                              out=data)
        return Evaluation(f_int, data, states_new, scale, results)

    def _compute_group(self, k, un, uo, state, ctx, tangent, data, f_out):
        """Group ``k``'s :class:`GroupResult` (through its fused kernel when it has one, adding
        into ``data`` and ``f_out``); a failure raises :class:`GroupFailure`."""
        g = self.groups[k]
        try:
            if g.fused:
                r = g.compute_into(un, uo, state, ctx, tangent, data, f_out,
                                   self.pattern.positions[k])
            else:
                r = g.compute(un, uo, state, ctx, tangent)
        except ArithmeticError as exc:
            factor = exc.factor if isinstance(exc, CutbackRequest) else None
            raise GroupFailure(f"{self.group_names[k]}: {exc}", factor=factor) from exc
        if r.failure:
            raise GroupFailure(f"{self.group_names[k]}: {r.failure}")
        return r

    def _later_data(self, un, uo, states, ctx, results) -> np.ndarray:
        """The CSR data of an evaluation asked with ``tangent=LATER``, in the order of
        :meth:`evaluate` with ``tangent=True``: the fused groups again (their forces into a
        scratch vector), then every other group's block, kept or deferred."""
        fused = [g.fused for g in self.groups]
        data = np.zeros(self.pattern.nnz) if any(fused) else None
        blocks = []
        for k, r in enumerate(results):
            if fused[k]:
                self._compute_group(k, un, uo, states[k], ctx, True, data, np.zeros(self.ndof))
                blocks.append(None)
            else:
                blocks.append(r.K if r.K is not None else r.later())
        return self.pattern.assemble_data(blocks, out=data)

    def refresh(self, u: np.ndarray) -> bool:
        """Let every group re-pair from the displacements ``u`` (ndof,) before an increment
        (:meth:`~lagamine_py.elements.base.Group.refresh`); when one changed its ``dofs``, the
        pattern is rebuilt and True returned (the caller rebuilds what it derived from it)."""
        n2 = u.size if self.nodal < 0 else self.nodal
        u2 = u[:n2].reshape(-1, 2)
        changed = [g.refresh(u2) for g in self.groups]
        if any(changed):
            self.pattern = Pattern(self.ndof, [g.dofs for g in self.groups])
        return any(changed)

    def placement(self, name: str, u: np.ndarray) -> np.ndarray:
        """(3,) placement (dx, dy, theta) of the tool ``name`` (with a reference node) in ``u``."""
        d = self.tools[name]
        out = np.zeros(3)
        out[:len(d)] = u[d]
        return out

    def tool_context(self, ctx, u_new: np.ndarray, u_old: np.ndarray):
        """``ctx`` with the placements of the tools that have a reference node taken from the
        displacements ``u_old`` (start) and ``u_new`` (end of the increment)."""
        if not self.tools:
            return ctx
        old, new = dict(ctx.foundation_old), dict(ctx.foundation_new)
        for name in self.tools:
            old[name] = self.placement(name, u_old)
            new[name] = self.placement(name, u_new)
        return replace(ctx, foundation_old=old, foundation_new=new)

    def laws_of_step(self, si: int) -> dict[int, str]:
        """Contact group index -> the name of the law it uses in step ``si`` (0-based): its
        ``*CONTACT`` law, or the last ``*CHANGE CONTACT LAW`` of steps up to ``si``."""
        out = {}
        for k in self.indices(CONTACT):
            if k in self.initial_laws:
                out[k] = self.initial_laws[k]
        changes = {}
        for step in self.model.steps[:si + 1]:
            for ch in step.law_changes:
                changes[ch.pair.upper()] = ch.law
        for k in self.indices(CONTACT):
            law = changes.get(self.group_names[k].upper())
            if law is not None:
                out[k] = _key(self.contact_laws, law)
        return out

    def set_step_laws(self, si: int, states: list[dict]) -> list[dict]:
        """Give every contact group the law of step ``si`` (:meth:`laws_of_step`); returns the
        committed states, those of the groups whose law changed carried over
        (:meth:`~lagamine_py.elements.contact.ContactGroup.set_law`)."""
        states = list(states)
        for k, law in self.laws_of_step(si).items():
            if self.pair_laws.get(k) != law:
                states[k] = self.groups[k].set_law(self.contact_laws[law], states[k])
                self.pair_laws[k] = law
        return states

    def check_tangent(self, u_new: np.ndarray, u_old: np.ndarray, states: list[dict], ctx,
                      h: float = 1e-7, dofs=None) -> float:
        """Largest difference between the assembled tangent and central finite differences of
        the assembled force, relative to the largest tangent entry (a debugging tool; freeze
        the contact status through ``ctx.freeze_contact`` to check across a status switch).

        ``h`` is relative to the largest |u| (or absolute when u = 0); ``dofs`` restricts the
        checked columns (default: all)."""
        K = self.pattern.matrix(self.evaluate(u_new, u_old, states, ctx, True).data).toarray()
        step = h * max(float(np.abs(u_new).max(initial=0.0)), 1.0)
        cols = np.arange(self.ndof) if dofs is None else np.asarray(dofs)
        err = 0.0
        for j in cols:
            e = np.zeros(self.ndof)
            e[j] = step
            fp = self.evaluate(u_new + e, u_old, states, ctx, False).f_int
            fm = self.evaluate(u_new - e, u_old, states, ctx, False).f_int
            err = max(err, float(np.abs((fp - fm) / (2 * step) - K[:, j]).max()))
        return err / max(float(np.abs(K).max()), 1e-300)

    def set_pressures(self, values: dict[str, float]) -> None:
        """Set the uniform pressure of each loaded surface (surfaces not listed: 0)."""
        for name, grp in self.pressure_groups.items():
            grp.pressure = np.full(np.shape(grp.pressure), float(values.get(name, 0.0)))


def _surface_thickness(model, surface, lookup) -> float:
    """Thickness of the block owning the first face of ``surface`` (plane strain)."""
    if not len(surface.elements):
        return 1.0
    b, _ = lookup[int(surface.elements[0])]
    return float(model.blocks[b].thickness)


def dload_surfaces(model) -> list[str]:
    """Surfaces loaded by ``*DLOAD`` in any step, in order of first appearance."""
    out: list[str] = []
    for step in model.steps:
        for d in step.dloads:
            if d.surface.upper() not in out:
                out.append(d.surface.upper())
    return out


def _surface(model, name: str):
    surf = model.surfaces.get(name) or model.surfaces.get(name.upper())
    if surf is None:
        raise KeyError(f"unknown surface {name}")
    return surf


def build_problem(model) -> Problem:
    """Instantiate every group of ``model`` and the sparsity pattern."""
    get = registry.get
    groups, kinds, names, blocks = [], [], [], []
    advice = []
    scales = {}
    laws = {name: get("laws", spec.law)(**spec.params) for name, spec in model.materials.items()}
    for blk in model.blocks:
        law = laws[blk.material] if blk.material in laws else laws[blk.material.upper()]
        groups.append(get("elements", blk.type)(blk.ids, blk.conn, model.coords, law,
                                                blk.thickness))
        kinds.append(SOLID)
        names.append(f"{blk.type} {blk.elset}".strip())
        blocks.append(blk)

    foundations = {name: Foundation(spec.points, name, centre=spec.centre)
                   for name, spec in model.foundations.items()}
    tools = {name: tool_dofs(model, spec) for name, spec in model.foundations.items()
             if spec.ref_node is not None}
    contact_laws = {name: get("contact_laws", spec.type)(**spec.params)
                    for name, spec in model.contact_laws.items()}
    lookup = model.element_lookup()
    initial_laws = {}
    for cs in model.contacts:
        surf = _surface(model, cs.surface)
        face_nodes, elements, faces = surface_faces(model, surf.name)
        law_name = _key(model.contact_laws, cs.law)
        claw = contact_laws[law_name]
        initial_laws[len(groups)] = law_name
        if cs.master is not None:             # two deformable bodies (elements.two_body)
            master = _surface(model, cs.master)
            name = f"{surf.name}->{master.name}"
            m_nodes, m_elements, m_faces = surface_faces(model, master.name)
            groups.append(TwoBodyGroup(name, face_nodes, elements, faces, model.coords,
                                       m_nodes, master.name, claw, cs.gauss, model.axisymmetric,
                                       _surface_thickness(model, surf, lookup), cs.search,
                                       cs.passes, m_elements, m_faces))
        else:
            fname = _key(model.foundations, cs.foundation)
            name = f"{surf.name}->{fname}"
            groups.append(ContactGroup(name, face_nodes, elements, faces, model.coords,
                                       foundations[fname], fname, claw, cs.gauss,
                                       model.axisymmetric, _surface_thickness(model, surf, lookup),
                                       tools.get(fname)))
        scales[len(groups) - 1] = face_scales(groups[-1], model, laws, lookup)
        # the penalty advice: at the start, the faces already touching a foundation (a body
        # meshed on it); the others, and two-body pairs, when they come into contact (Controller,
        # at the end of each step)
        if cs.master is None:
            touching = (groups[-1].start_penetration() >= 0).reshape(groups[-1].nf, -1).any(axis=1)
            advice.extend(penalty_advice(name, claw, scales[len(groups) - 1][touching],
                                         "touching the foundation at the start"))
        kinds.append(CONTACT)
        names.append(name)
        blocks.append(None)

    pressure_groups = {}
    for sname in dload_surfaces(model):
        surf = _surface(model, sname)
        face_nodes, _, _ = surface_faces(model, surf.name)
        grp = PressureGroup(face_nodes, model.coords, model.axisymmetric,
                            _surface_thickness(model, surf, lookup))
        grp.pressure = np.zeros(len(face_nodes))
        pressure_groups[sname] = grp
        groups.append(grp)
        kinds.append(PRESSURE)
        names.append(f"pressure on {surf.name}")
        blocks.append(None)

    pattern = Pattern(model.ndof, [g.dofs for g in groups])
    problem = Problem(model, groups, kinds, names, blocks, pressure_groups, foundations, pattern,
                      advice, list(model.notices), tools=tools, contact_laws=contact_laws,
                      pair_laws=dict(initial_laws), initial_laws=initial_laws,
                      nodal=2 * len(model.node_ids))
    problem.face_scales = scales
    problem.set_kernel("AUTO")       # a problem used directly behaves as a run's default
    return problem


def tool_dofs(model, spec) -> np.ndarray:
    """The global DOFs of a foundation's reference node: u, v and, in plane strain, the
    rotation (:meth:`~lagamine_py.model.Model.dof`)."""
    r = int(spec.ref_node)
    comps = (0, 1) if model.axisymmetric else (0, 1, 5)
    return np.array([int(model.dof([r], c)[0]) for c in comps], np.int64)


# Penalties outside this range of E/h (h the length of each face near the foundation, E of its
# body) are reported at the start of a run.  Below: the accuracy a penalty costs is a predictable
# penetration p/KP (elastic slip tau/KT).  Above: conditioning (round-off, Newton iterations);
# a stiff penalty is not wrong by itself: the benchmark Hertz run is within 0.2 % at 1000 E/h
# (docs/accuracy_speed.md).  The alternation of p between neighbouring Gauss points that stiff
# penalties can cause on coarse contact zones is reported where it happens (alternation_advice).
PENALTY_RANGE = (5.0, 1e4)
_EFFECT = {
    "KP": ("the body sinks into the foundation by p/KP, {pct:.3g} % of a face length at "
           "p = E/100", "p and tau are more sensitive to round-off and Newton needs more "
           "iterations (METHOD=AUGMENTED reaches the same penetration with about 20 E/h)"),
    "KT": ("each point slips elastically by tau/KT before it slides, {pct:.3g} % of a face length "
           "at tau = E/100 (stick zones shrink, sliding starts late)", "stick and slip flip-flop "
           "between Newton iterations (the FLIPFLOP control holds such points); METHOD=AUGMENTED "
           "enforces stick with a moderate KT"),
}


def penalty_advice(name, law, h_over_e, what: str = "in contact") -> list[str]:
    """Warnings when a penalty of the contact law (:meth:`ContactLaw.penalties`) that plays a
    role is outside :data:`PENALTY_RANGE` times E/h on the faces whose ``h / E`` (each face's
    own length, the E of its own body: :func:`face_scales`) are given: the faces in contact."""
    penalties = {k: v for k, (v, plays) in law.penalties().items() if plays}
    h_over_e = np.asarray(h_over_e, float)
    if not penalties or h_over_e.size == 0:
        return []
    out = []
    for label, k in penalties.items():
        ratio = float(k) * h_over_e
        lo, hi = float(ratio.min()), float(ratio.max())
        soft, stiff = lo < PENALTY_RANGE[0], hi > PENALTY_RANGE[1]
        if not (soft or stiff):
            continue
        worst = lo if soft else hi
        soft_text, stiff_text = _EFFECT.get(label, ("a softer penalty costs accuracy",
                                                    "a stiffer one costs conditioning"))
        effect = soft_text.format(pct=100.0 / worst) if soft else stiff_text
        span = f"{lo:.3g} E/h" if f"{lo:.3g}" == f"{hi:.3g}" else f"{lo:.3g} to {hi:.3g} E/h"
        out.append(f"contact {name}: {label} = {float(k):.3g} is {span} on the {len(ratio)} "
                   f"face(s) {what} (h each face's length, E its body's); "
                   f"{PENALTY_RANGE[0]:g} to {PENALTY_RANGE[1]:g} E/h is advised "
                   f"(20-100 E/h a good start): " + ("too soft: " if soft else "too stiff: ")
                   + effect)
    return out


def face_scales(group, model, laws, lookup) -> np.ndarray:
    """``h / E`` (f,) of the faces of a contact group: h the face's corner-to-corner length, E
    the Young modulus of its element's material."""
    x = model.coords[group.face_nodes[:, :2]]
    h = np.linalg.norm(x[:, 1] - x[:, 0], axis=1)
    moduli = {}
    E = np.empty(group.nf)
    for f, eid in enumerate(group.ids):
        block = model.blocks[lookup[int(eid)][0]]
        if block.material not in moduli:
            mat = laws.get(block.material) or laws.get(block.material.upper())
            moduli[block.material] = float(mat.elastic_moduli()[0])
        E[f] = moduli[block.material]
    return h / E


def faces_in_contact(group, state) -> np.ndarray:
    """(f,) bool: the faces of a contact group with a point that carries pressure."""
    return (np.asarray(state["p"], float) > 0).reshape(group.nf, group.nq).any(axis=1)


def alternation_advice(name, group, state) -> str | None:
    """A warning when the contact stresses of ``state`` alternate along the surface: a point
    open between two closed neighbours, or a slipping point whose tau has the other sign than
    both its neighbours' (the symptom of a stiff penalty on Gauss points where the contact zone
    spans few faces; docs/accuracy_speed.md), or None."""
    prev, nxt = group.chain_neighbours()
    status = np.asarray(state["status"])
    p, tau = np.asarray(state["p"], float), np.asarray(state["tau"], float)
    closed = status != OPEN
    both = (prev >= 0) & (nxt >= 0)
    pi, ni = np.where(both, prev, 0), np.where(both, nxt, 0)
    gaps = both & ~closed & closed[pi] & closed[ni] & (p[pi] > 0) & (p[ni] > 0)
    # a tau of round-off (frictionless contact: tau = 0 up to KT times round-off) says nothing
    real = np.abs(tau) > 1e-6 * max(float(np.abs(p).max(initial=0.0)), 1e-300)
    flips = (both & (status == SLIP) & real & real[pi] & real[ni]
             & (tau * tau[pi] < 0) & (tau * tau[ni] < 0))
    if not (gaps.any() or flips.any()):
        return None
    what = []
    if gaps.any():
        what.append(f"{int(gaps.sum())} point(s) open between closed neighbours")
    if flips.any():
        what.append(f"{int(flips.sum())} slipping point(s) with tau against both neighbours")
    remedy = ("GAUSS=LINEAR removes it, a finer mesh or a softer penalty reduces it"
              if group.rule in (2, 3) else "a finer mesh or a softer penalty reduces it")
    return (f"contact {name}: the contact stresses alternate from point to point ("
            + ", ".join(what) + f", GAUSS={group.rule}): the penalty enforces more constraints "
            f"than the face has nodes where the contact zone spans few faces; {remedy} "
            "(docs/accuracy_speed.md)")


def _key(table: dict, name: str) -> str:
    """The key of ``table`` matching ``name`` case-insensitively."""
    if name in table:
        return name
    for k in table:
        if k.upper() == name.upper():
            return k
    raise KeyError(name)
