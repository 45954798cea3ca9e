"""Rigid tools in the step controller: where they are, what they carry, and what holds them.

* :func:`tool_states` -- per foundation and converged increment: its placement (the
  translation of its reference point and its rotation), the current reference point, and its
  reaction force and moment about that point (the sum over its contact pairs of the force and
  moment the tool exerts on the bodies, stabilisation included: at equilibrium, the reactions
  of a tool's reference node).  ``OUT/tool_forces.csv`` writes them.
* :func:`reactions_by_target` -- ``reactions.csv``: RF1, RF2 and RM6 (the reaction moment of
  the rotation DOFs of the reference nodes among a target's nodes; 0 for other nodes).
* :func:`stabilisation_context` -- ``*CONTACT STABILIZATION``: the damping of an increment.
  The viscous coefficient is ``c = FACTOR KP T`` (``T`` the step time), so that over an
  increment of size ``dt`` the normal traction is ``p_s = c (d_end - d_start) / dt``, i.e. a
  spring ``kn = FACTOR KP T / dt`` on the approach of the increment, ramped down linearly over
  the step (times ``1 - t_start / T``: full at the step start, ``FACTOR KP`` in the last
  increment, whatever its size) and acting on the points near the foundation (``RANGE``,
  default a tenth of the surface's median face length): the normal one weighted from 1 in
  contact down to 0 at the range, the tangential one on open points only, both continuous as a
  point closes (see :mod:`lagamine_py.elements.contact`).  The tangential coefficient is
  ``TANGENTIAL`` times the normal one.  A body or tool that touches at a point and is pushed by
  a force approaches at a finite speed until its contact closes; once closed, the penalty holds
  it (the normal damping, ``kn << KP``, then only resists the change of the penetration) and the
  damping of the points still open resists their slowing approach.  Its energy is dissipated:
  the controller logs it at every step end against the work of the loads (a warning above 1 %).
* :func:`predictor_context` -- the placements the first iterate sees: a tool whose DOFs are all
  prescribed moves to its prescribed placement, and when every foundation translates alike the
  bodies are shifted with them (:func:`lagamine_py.solver.predictor.foundation_shift`).
* :func:`explain_singular` -- why a tangent is singular, in the user's words: the rigid-body
  modes that nothing restrains (a tool's free DOFs, a body's translations and rotation), and
  when the body or tool is held only by contact whose points are all open, that the contact is
  not closed yet, with what to do.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp

from ..core.status import SLIP, STICK
from ..foundation import placed
from ..output.base import ToolState
from .problem import CONTACT, SOLID

__all__ = ["tool_states", "reactions_by_target", "stabilisation_context", "predictor_context",
           "explain_singular", "foundation_points"]


def placements(problem, loads, model, u: np.ndarray, t: float) -> dict[str, np.ndarray]:
    """(3,) placement of every foundation at step time ``t`` with displacements ``u``."""
    out = {name: np.asarray(v, float) for name, v in loads.motions(model, t).items()}
    for name in problem.tools:
        out[name] = problem.placement(name, u)
    return out


def foundation_points(model, place: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Current chain points of every foundation for the placements ``place``."""
    return {name: placed(spec.points, spec.centre, place.get(name, np.zeros(3)))
            for name, spec in model.foundations.items()}


def tool_states(model, place: dict[str, np.ndarray], contacts) -> dict[str, ToolState]:
    """The :class:`~lagamine_py.output.base.ToolState` of every foundation: its placement, its
    reference point now, and the sums over its contact pairs (``ContactPoints.F``, ``M``)."""
    out = {}
    for name, spec in model.foundations.items():
        v = np.asarray(place.get(name, np.zeros(3)), float)
        force, moment = np.zeros(2), 0.0
        for cp in contacts:
            if cp.name.split("->", 1)[-1].upper() == name.upper():
                force = force + np.asarray(cp.F, float)
                moment += float(cp.M)
        ref = None if spec.ref_node is None else int(model.node_ids[spec.ref_node])
        out[name] = ToolState(name=name, ref_node=ref, placement=v.copy(),
                              point=np.asarray(spec.centre, float) + v[:2], force=force,
                              moment=moment)
    return out


def reactions_by_target(model, bc_targets: dict, reaction: np.ndarray) -> dict[str, np.ndarray]:
    """Target name -> (RF1, RF2, RM6): the summed reactions of its nodes; RM6 sums the rotation
    DOFs of the reference nodes among them (0 when none)."""
    n2 = 2 * len(model.node_ids)
    r2 = reaction[:n2].reshape(-1, 2)
    rot = {r: n2 + k for k, r in enumerate(model.rotation_nodes)}
    out = {}
    for name, nodes in bc_targets.items():
        nodes = np.asarray(nodes, np.int64)
        rm = sum(float(reaction[rot[int(r)]]) for r in nodes if int(r) in rot)
        out[name] = np.append(r2[nodes].sum(axis=0), rm)
    return out


def stabilisation_context(problem, step, t: float, dt: float):
    """``{pair: (kn, kt, range)}`` of the step's ``*CONTACT STABILIZATION`` for the increment
    from step time ``t`` to ``t + dt`` (None without one); see the module doc."""
    stab = step.stabilisation
    if stab is None:
        return None
    T = float(step.period)
    fade = max(1.0 - t / T, 0.0) if T > 0 else 1.0
    wanted = {p.upper() for p in stab.pairs}
    out = {}
    for k in problem.indices(CONTACT):
        name = problem.group_names[k]
        if wanted and name.upper() not in wanted:
            continue
        grp = problem.groups[k]
        penalties = grp.law.penalties()
        kp = float(penalties["KP"][0]) if "KP" in penalties else 0.0
        kn = stab.factor * kp * (T / dt) * fade
        rng = stab.range if stab.range is not None else RANGE * face_length(grp)
        out[name] = (kn, stab.tangential * kn, float(rng))
    return out


#: the default range of the stabilisation, times the median face length of the pair's surface
RANGE = 0.1


def face_length(group) -> float:
    """The median length of a contact group's faces (the stabilisation's default range)."""
    x = group.coords0[group.face_nodes[:, :2]]
    return float(np.median(np.linalg.norm(x[:, 1] - x[:, 0], axis=1))) if len(x) else 0.0


def predictor_context(problem, ctx, u: np.ndarray, constrained: np.ndarray, u_c: np.ndarray):
    """``ctx`` with the placements of the tools with a reference node at the start (``u``) and
    at the end of the increment when all their DOFs are prescribed (``u_c`` at
    ``constrained``); a tool with a free DOF is left out of the end placements, so no common
    motion is assumed (:func:`lagamine_py.solver.predictor.foundation_shift`)."""
    if not problem.tools:
        return ctx
    u_new = np.array(u, float)
    u_new[constrained] = u_c
    fixed = set(np.asarray(constrained).tolist())
    old, new = dict(ctx.foundation_old), dict(ctx.foundation_new)
    for name, dofs in problem.tools.items():
        old[name] = problem.placement(name, u)
        if all(int(d) in fixed for d in dofs):
            new[name] = problem.placement(name, u_new)
        else:
            new.pop(name, None)
    return dataclasses.replace(ctx, foundation_old=old, foundation_new=new)


# --------------------------------------------------------------------------------------------
# a singular tangent, explained

def _bodies(problem) -> list[np.ndarray]:
    """Node rows of each body: the connected parts of the solid elements' mesh."""
    n = len(problem.model.node_ids)
    rows, cols = [], []
    for k in problem.indices(SOLID):
        conn = np.asarray(problem.groups[k].conn, np.int64)
        rows.append(np.repeat(conn[:, 0], conn.shape[1]))
        cols.append(conn.ravel())
    if not rows:
        return []
    r, c = np.concatenate(rows), np.concatenate(cols)
    # imported here: only a singular tangent needs it, and it is 10 % of a small run's imports
    from scipy.sparse.csgraph import connected_components
    graph = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    used = np.zeros(n, bool)
    used[c] = True
    return [np.flatnonzero((label == b) & used) for b in np.unique(label[used])]


def _rigid_modes(problem, free_mask) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """The candidate rigid-body modes: each tool's free DOFs and each body's translations and
    (in plane strain) rotation about its centroid, ``(owner, direction, nodes or DOFs, m)``;
    a mode with a prescribed component is left out (a support holds it)."""
    model = problem.model
    ndof = problem.ndof
    out = []
    for name, dofs in problem.tools.items():
        for d, what in zip(dofs, ("x", "y", "rotation")):
            m = np.zeros(ndof)
            m[d] = 1.0
            out.append((f"tool {name}", what, np.array([d]), m))
    for nodes in _bodies(problem):
        X = model.coords[nodes]
        for i, what in ((0, "x"), (1, "y")):
            if model.axisymmetric and i == 0:
                continue                       # a radial translation strains the hoop
            m = np.zeros(ndof)
            m[2 * nodes + i] = 1.0
            out.append(("body", what, nodes, m))
        if not model.axisymmetric:
            m = np.zeros(ndof)
            c = X.mean(axis=0)
            m[2 * nodes] = -(X[:, 1] - c[1])
            m[2 * nodes + 1] = X[:, 0] - c[0]
            out.append(("body", "rotation", nodes, m))
    return [mode for mode in out if not np.any(mode[3][~free_mask] != 0.0)]


def _free_modes(problem, K, free_mask) -> list[list[tuple[str, str, np.ndarray]]]:
    """The combinations of rigid-body modes that ``K`` does not restrain: the null vectors of
    ``K M`` at the free DOFs, ``M`` the candidate modes (:func:`_rigid_modes`, unit columns), each
    as the list of its participating modes ``(owner, direction, nodes or DOFs)`` (a body and the
    tool pressing it move together, say)."""
    modes = _rigid_modes(problem, free_mask)
    if not modes:
        return []
    norms = np.array([np.linalg.norm(m) for *_, m in modes])
    M = np.column_stack([m for *_, m in modes]) / norms
    A = (K @ M)[free_mask]
    scale = float(np.abs(K.data).max(initial=0.0)) or 1.0
    _, sv, Vt = np.linalg.svd(A, full_matrices=False)
    peak = np.array([np.abs(m).max() for *_, m in modes]) / norms     # largest motion per unit
    out = []
    for s, v in zip(sv, Vt):
        if s <= 1e-10 * scale:
            amplitude = np.abs(v) * peak              # the largest displacement of each part
            big = amplitude >= 0.1 * amplitude.max()
            out.append([modes[i][:3] for i in np.flatnonzero(big)])
    return out


def explain_singular(problem, data: np.ndarray, free_dofs: np.ndarray, states: list) -> str:
    """Why the tangent (CSR ``data`` of the full pattern) is singular at the free DOFs
    ``free_dofs``: the rigid-body motions that nothing restrains (of tools, bodies, or a body
    and the tool pressing it together), and when they are held only by contact, whether that
    contact has no closed point (not closed yet) or only slipping ones (friction holds nothing
    along the surface at this iterate), with what to do.  ``states``: the groups' states the
    tangent was formed with (the iterate's trial states; the start of the increment's when
    those are not known).  "" when no rigid-body motion is free."""
    K = problem.pattern.matrix(np.asarray(data, float))
    free_mask = np.zeros(K.shape[0], bool)
    free_mask[np.asarray(free_dofs, np.int64)] = True
    try:
        motions = _free_modes(problem, K, free_mask)
    except (ValueError, np.linalg.LinAlgError):     # a NaN tangent, an SVD that fails: no words
        return ""
    if not motions:
        return ""
    model = problem.model
    pairs = {k: problem.group_names[k] for k in problem.indices(CONTACT)}

    def count(k, *codes) -> int:
        return int(np.isin(np.asarray(states[k]["status"]), codes).sum())

    def closed(k) -> int:
        return count(k, STICK, SLIP)

    def label(owner, where) -> str:
        if owner != "body":
            name = owner.split(" ", 1)[1]
            return f"tool {name} (reference node {int(model.node_ids[model.foundations[name].ref_node])})"
        ids = sorted({int(e) for k in problem.indices(SOLID)
                      for e, conn in zip(problem.groups[k].ids, problem.groups[k].conn)
                      if np.isin(conn, where).any()})
        return (f"the body of elements {ids[0]}..{ids[-1]}" if len(ids) > 1
                else f"the body of element {ids[0]}")

    parts, open_contact, all_slip = [], False, False
    for motion in motions:
        owners: dict[str, list[str]] = {}
        nodes, tools = [], set()
        for owner, what, where in motion:
            owners.setdefault(label(owner, where), []).append(what)
            if owner == "body":
                nodes.append(where)
            else:
                tools.add(owner.split(" ", 1)[1])
        nodes = np.concatenate(nodes) if nodes else np.zeros(0, np.int64)
        # the pairs that hold the moving set against what does not move with it
        holding = [k for k in pairs
                   if (np.isin(problem.groups[k].face_nodes, nodes).any()
                       != (problem.groups[k].foundation_name in tools))]
        who = " with ".join(f"{name} ({', '.join(whats)})" for name, whats in owners.items())
        text = f"{who} can move freely"
        if holding:
            held = ", ".join(f"{pairs[k]}: {closed(k)} of {problem.groups[k].ng} points closed"
                             for k in holding)
            if all(closed(k) == 0 for k in holding):
                open_contact = True
                text += f": held only by contact, which is not closed yet ({held})"
            elif all(count(k, STICK) == 0 for k in holding):
                # closed points press (KP holds the normal): what is free is along the surface
                all_slip = True
                text += (f": held only by friction, and every closed point slips at this iterate "
                         f"({held}, none sticking; a slipping point resists no motion along the "
                         f"surface)")
            else:
                text += f" (its contact: {held})"
        else:
            text += ": nothing restrains it (no *BOUNDARY, no contact)"
        parts.append(text)
    head = "contact is not closed yet: " if open_contact else ""
    if open_contact:
        advice = (" -- start the bodies in contact along a face rather than at a point, prescribe "
                  "what moves freely (*BOUNDARY), or add *CONTACT STABILIZATION to the step (it "
                  "damps the motion until the contact closes)")
    elif all_slip:
        advice = (" -- a tangential penalty KT far stiffer than the body sends every trial state "
                  "to slip, and a load along the surface beyond what friction holds leaves nothing "
                  "sticking: a smaller increment (the cut-back) often finds the stick points; if "
                  "the run stops here, soften KT or prescribe the motion along the surface "
                  "(*BOUNDARY)")
    else:
        advice = " -- add the *BOUNDARY that holds it"
    return head + "; ".join(parts) + advice
