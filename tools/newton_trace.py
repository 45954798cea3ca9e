"""Where Newton's solves go: every iteration's residual with the contact points that switched.

    python tools/newton_trace.py 40 20                     # press-then-slide at 40 x 20 (bench.py's deck)
    python tools/newton_trace.py --deck decks/stick_slip.dat --controls FLIPFLOP=2
    python tools/newton_trace.py 40 20 --tail 8 --increments 6
    python tools/newton_trace.py 40 20 --first --controls EXTRAPOLATION=PARABOLIC
    python tools/newton_trace.py 40 20 --strip 0 1 2 4 8      # the strip oracle

Prints the solver's per-iteration log (``|R|/F``, the energy, the reviews of frozen points, the
cut-backs) and, after each solve, the contact points whose state (open ``o``, stick ``k``, slip
with tau > 0 ``+``, slip with tau < 0 ``-``: :func:`lagamine_py.solver.stabilisation.state_codes`)
changed between the two last iterates, as ``<point><from><to>``.  ``--tail N`` adds the state
and ``tau / p`` of the last N points of each group after every solve (press-then-slide: the
points next to the pushed corner).  ``--first`` adds, after each converged increment, where
its first iterate's residual sat (:func:`first_report`).  ``--strip K ...`` adds, after each
converged increment, the oracle of a local relaxation: the first iterate's |R|/F with the DOFs of
the strip of K element layers along the contact interface (:func:`strip_nodes`) replaced by
the converged answer's (:func:`strip_oracle`).  What ``docs/performance.md`` ("Newton solves per increment")
reads its traces from; the counts do not depend on the machine's load.

The trace wraps :meth:`FlipFlop.context <lagamine_py.solver.stabilisation.FlipFlop.context>`
(the observer Newton hands the states of every iterate to); the solver itself is not changed.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
CODES = "ok+-"                 # OPEN, STICK, SLIP (tau > 0), SLIP_NEG


class _Stop(Exception):
    """Raised by the trace after the requested number of converged increments."""


def switches(last: np.ndarray, code: np.ndarray, limit: int = 12) -> str:
    """``"n: 3k+ 7+-"``: how many points changed state from ``last`` to ``code`` (g,) and the
    first ``limit`` of them as ``<index><from><to>``."""
    idx = np.flatnonzero(code != last)
    text = " ".join(f"{i}{CODES[int(last[i])]}{CODES[int(code[i])]}" for i in idx[:limit])
    return f"{idx.size}: {text}{' ...' if idx.size > limit else ''}"


def tail(code: np.ndarray, tau: np.ndarray, p: np.ndarray, n: int) -> str:
    """The state and ``tau / p`` of the last ``n`` points: ``k-0.152 ++0.200``."""
    ratio = np.where(p > 0, tau / np.where(p > 0, p, 1.0), 0.0)
    return " ".join(f"{CODES[int(c)]}{r:+.3f}" for c, r in zip(code[-n:], ratio[-n:]))


def node_count(problem) -> int:
    """Nodes of the problem (its nodal DOFs come first, two per node; the rest are reference
    nodes' rotations)."""
    return problem.nodal // 2 if problem.nodal >= 0 else problem.ndof // 2


def contact_codes(problem, states: list[dict]) -> list[np.ndarray]:
    """The state codes (``o k + -``) of each contact group's points in ``states``."""
    from lagamine_py.solver import stabilisation
    from lagamine_py.solver.problem import CONTACT
    return [stabilisation.state_codes(states[k]["status"], states[k]["tau"], states[k]["p"])
            for k in problem.indices(CONTACT)]


def regions(problem, constrained: np.ndarray) -> dict[str, np.ndarray]:
    """(n,) bool masks of the nodes the first-iterate report splits the residual by: the
    contact surfaces' nodes (``contact``), the nodes sharing a solid element with a node of
    a constrained DOF and on no contact surface (``edge``: the imposed edge's neighbours and
    itself), the rest (``body``)."""
    from lagamine_py.solver.problem import CONTACT, SOLID
    n = node_count(problem)
    contact = np.zeros(n, bool)
    for k in problem.indices(CONTACT):
        contact[np.asarray(problem.groups[k].face_nodes).ravel()] = True
    fixed = np.zeros(n, bool)
    c = np.asarray(constrained, np.int64)
    fixed[c[c < 2 * n] // 2] = True
    edge = np.zeros(n, bool)
    for k in problem.indices(SOLID):
        conn = np.asarray(problem.groups[k].conn, np.int64)
        edge[conn[fixed[conn].any(axis=1)].ravel()] = True
    edge &= ~contact
    return {"contact": contact, "edge": edge, "body": ~(contact | edge)}


def contact_node_zones(problem, codes_end: list[np.ndarray], n: int) -> dict[str, np.ndarray]:
    """(n,) bool masks of the contact nodes by the converged states of the points of their faces
    at the end of the increment: all sticking (``stick``), all slipping (``slip``), some of
    each or open (``front``)."""
    from lagamine_py.core.status import STICK
    from lagamine_py.solver.problem import CONTACT
    sticks, others = np.zeros(n, bool), np.zeros(n, bool)
    for k, code in zip(problem.indices(CONTACT), codes_end):
        g = problem.groups[k]
        per_face = np.asarray(code).reshape(g.nf, g.nq)
        face_stick = (per_face == STICK).any(axis=1)
        face_other = (per_face != STICK).any(axis=1)
        for flag, mask in ((face_stick, sticks), (face_other, others)):
            mask[np.asarray(g.face_nodes)[flag].ravel()] = True
    return {"stick": sticks & ~others, "slip": others & ~sticks, "front": sticks & others}


def first_report(problem, model, R: np.ndarray, free: np.ndarray, constrained: np.ndarray,
                 error: np.ndarray, codes_start: list, codes_end: list, scale: float) -> str:
    """One line: the first iterate's |R|/F and where |R|^2 sits (shares by region, the contact
    nodes split by their converged states, :func:`contact_node_zones`), the node of the largest
    residual, and the prediction's error ``u_start - u_converged`` (its largest by region)
    and the contact points whose state at the first iterate is not their converged one."""
    n = node_count(problem)
    Rn = np.zeros(problem.ndof)
    Rn[free] = R[free]
    r2 = (Rn[:2 * n].reshape(n, 2) ** 2).sum(axis=1)
    e = np.abs(error[:2 * n].reshape(n, 2)).max(axis=1)
    total = max(float(r2.sum()), 1e-300)
    zones = regions(problem, constrained)
    parts = []
    for name, mask in zones.items():
        if name == "contact":
            sub = contact_node_zones(problem, codes_end, n)
            inner = ", ".join(f"{z} {100 * r2[mask & m].sum() / total:.0f}"
                              for z, m in sub.items() if (mask & m).any())
            parts.append(f"{name} {100 * r2[mask].sum() / total:.0f} % ({inner})")
        else:
            parts.append(f"{name} {100 * r2[mask].sum() / total:.0f} %")
    worst = int(np.argmax(r2))
    x = model.coords[worst]
    errs = " ".join(f"{name} {e[mask].max():.2e}" for name, mask in zones.items() if mask.any())
    wrong = sum(int(np.sum(a != b)) for a, b in zip(codes_start, codes_end))
    return (f"    first iterate |R|/F {np.sqrt(total) / scale:.3e}: |R|^2 {'; '.join(parts)}; "
            f"largest at node {worst} ({x[0]:.4g}, {x[1]:.4g}); |u0 - u| max {errs}; "
            f"contact states not the converged ones: {wrong}")


def worst_contact_nodes(problem, R, free, error, starts, firsts, ends, scale, count) -> str:
    """The ``count`` contact nodes of the largest first-iterate residual, one line each: the
    node, x, R/F (x, y), the prediction's error (x, y), and the states (``o k + -``) of the
    points of its faces at the increment's start, at the first iterate and converged."""
    from lagamine_py.solver.problem import CONTACT
    n = node_count(problem)
    Rn = np.zeros(problem.ndof)
    Rn[free] = R[free]
    R2, e2 = Rn[:2 * n].reshape(n, 2), error[:2 * n].reshape(n, 2)
    lines = []
    for k, a, b, c in zip(problem.indices(CONTACT), starts, firsts, ends):
        g = problem.groups[k]
        nodes = np.unique(np.asarray(g.face_nodes))
        r = (R2[nodes] ** 2).sum(axis=1)
        for node in nodes[np.argsort(r)[::-1][:count]]:
            faces = np.flatnonzero((np.asarray(g.face_nodes) == node).any(axis=1))
            pts = (faces[:, None] * g.nq + np.arange(g.nq)).ravel()
            st = "/".join("".join(CODES[int(v[i])] for i in pts) for v in (a, b, c))
            x = problem.model.coords[node]
            lines.append(f"      node {node} x {x[0]:8.4g}: R/F ({R2[node, 0] / scale:+.2e}, "
                         f"{R2[node, 1] / scale:+.2e}) error ({e2[node, 0]:+.2e}, "
                         f"{e2[node, 1]:+.2e}) states {st}")
    return "\n".join(lines)


def strip_nodes(problem, layers: int) -> np.ndarray:
    """(n,) bool mask of the strip: the contact surfaces' nodes (``layers`` 0), then each layer
    the nodes sharing a solid element with a node of the strip (one ring of elements)."""
    from lagamine_py.solver.problem import CONTACT, SOLID
    n = node_count(problem)
    strip = np.zeros(n, bool)
    for k in problem.indices(CONTACT):
        strip[np.asarray(problem.groups[k].face_nodes).ravel()] = True
    conns = [np.asarray(problem.groups[k].conn, np.int64) for k in problem.indices(SOLID)]
    for _ in range(layers):
        grown = strip.copy()
        for conn in conns:
            grown[conn[strip[conn].any(axis=1)].ravel()] = True
        strip = grown
    return strip


def strip_oracle(problem, u0, conv_u, u_old, states, ctx, f_ext, free, scale,
                 layers: list[int]) -> str:
    """One line: the first iterate's |R|/F (over the free DOFs) with the DOFs of each strip
    of ``layers`` element layers replaced by the converged answer's: the best a relaxation
    local to that strip can do; in brackets the strip's share of the nodes and of the
    prediction's squared error ``|u0 - u|^2`` over the free DOFs."""
    n = node_count(problem)
    error = np.zeros(problem.ndof)
    error[free] = (np.asarray(u0) - conv_u)[free]
    total = max(float(error @ error), 1e-300)
    parts = []
    for k in layers:
        strip = strip_nodes(problem, k)
        dofs = np.flatnonzero(np.repeat(strip, 2))
        u = np.array(u0, float)
        u[dofs] = conv_u[dofs]
        R = problem.evaluate(u, u_old, states, ctx, False).f_int - f_ext
        parts.append(f"k={k} {np.linalg.norm(R[free]) / scale:.2e} "
                     f"({100 * strip.sum() / n:.0f} % nodes, "
                     f"{100 * float(error[dofs] @ error[dofs]) / total:.0f} % error)")
    return "    strip oracle |R|/F: " + ", ".join(parts)


def strip_relaxed(problem, u0, u_old, states, ctx0, ctx, f_ext, free, scale, layers: list[int],
                  sweeps: int = 4) -> str:
    """One line: the first iterate's |R|/F after each of ``sweeps`` local relaxations on each
    strip of ``layers`` element layers: ``K_SS du_S = -R_S`` with the strip's block of the
    tangent at the first iterate (factorised once), the rest held.  The first iterate is
    evaluated in ``ctx0`` (Newton's first context: the fronts' holds), the relaxed ones in
    ``ctx`` (the law's states free), as Newton evaluates its first and later iterates."""
    import scipy.sparse.linalg as spla
    ev = problem.evaluate(np.array(u0, float), u_old, states, ctx0, True)
    Kff, R0 = free.kff(ev.data), ev.f_int - f_ext
    where = np.full(problem.ndof, -1, np.int64)
    where[free.free] = np.arange(free.free.size)
    parts = []
    for k in layers:
        dofs = np.flatnonzero(np.repeat(strip_nodes(problem, k), 2))
        pos = where[dofs]
        pos = pos[pos >= 0]
        lu = spla.splu(Kff[pos][:, pos].tocsc())
        u, R, rels = np.array(u0, float), R0, []
        for _ in range(sweeps):
            u[free.free[pos]] -= lu.solve(R[free.free[pos]])
            R = problem.evaluate(u, u_old, states, ctx, False).f_int - f_ext
            rels.append(np.linalg.norm(R[free.free]) / scale)
        parts.append(f"k={k} " + " ".join(f"{r:.2e}" for r in rels))
    return "    strip relaxed |R|/F per sweep: " + ", ".join(parts)


def force_changes(problem, first, converged, free: np.ndarray, scale: float) -> str:
    """How far each kind of group's force at the first iterate is from its converged one, over
    the free DOFs, relative to F: which groups' forces the first iterate's residual is made of
    (the converged residual is ~0, so the residual is the sum of these changes).  Groups
    computed by a fused kernel (no force blocks in their result) are left out."""
    change: dict[str, np.ndarray] = {}
    for k, (a, b) in enumerate(zip(first, converged)):
        if a.f is None or b.f is None:
            continue
        kind = problem.kinds[k]
        d = problem.pattern.group_vector(k, np.asarray(a.f) - np.asarray(b.f))
        change[kind] = change.get(kind, 0.0) + d
    parts = ", ".join(f"{kind} {np.linalg.norm(d[free]) / scale:.2e}" for kind, d in change.items())
    return f"    force change first iterate -> converged, |df|/F by kind: {parts}"


def trace(model, outdir: Path, tail_points: int = 0, increments: int = 0, out=sys.stdout,
          writers=(), first: bool = False, first_nodes: int = 0, strip: tuple = (),
          relax: tuple = ()):
    """Run ``model`` with the trace on; returns the run's :class:`Outcome` (None when stopped
    after ``increments`` converged increments).  ``writers``: more writers to hand the run to
    (they see every increment before the trace stops).  ``first``: after each converged
    increment, :func:`first_report` of its first iterate (an extra evaluation per attempt)."""
    from lagamine_py.output import Writer, default_writers
    from lagamine_py.solver import stabilisation
    from lagamine_py.solver import steps as steps_mod

    inner = stabilisation.FlipFlop.context
    solve = steps_mod.solve_increment

    def solve_reported(problem, solver, free, u_old, states, ctx, u_c, f_ext, settings, **k):
        conv = solve(problem, solver, free, u_old, states, ctx, u_c, f_ext, settings, **k)
        u0 = np.array(u_old if k.get("u_start") is None else k["u_start"], float)
        u0[free.constrained] = u_c            # as Newton's first iteration imposes them
        ctx0 = k["observers"][0].start(ctx) if k.get("observers") else ctx
        ev = problem.evaluate(u0, u_old, states, ctx0, False)
        R = ev.f_int - f_ext
        scale = max(float(np.linalg.norm(f_ext)), float(np.linalg.norm(R[free.constrained])),
                    ev.scale, 1e-300)
        codes, ends = contact_codes(problem, ev.states), contact_codes(problem, conv.states)
        if strip:
            print(strip_oracle(problem, u0, conv.u, u_old, states, ctx0, f_ext, free.free,
                               scale, strip), file=out)
        if relax:
            print(strip_relaxed(problem, u0, u_old, states, ctx0, ctx, f_ext, free, scale,
                                relax),
                  file=out)
        print(first_report(problem, problem.model, R, free.free, free.constrained,
                           u0 - conv.u, codes, ends, scale), file=out)
        print(force_changes(problem, ev.results, problem.evaluate(conv.u, u_old, states, ctx,
                                                                  False).results,
                            free.free, scale), file=out)
        if first_nodes:
            print(worst_contact_nodes(problem, R, free.free, u0 - conv.u,
                                      contact_codes(problem, states), codes, ends,
                                      scale, first_nodes), file=out)
        return conv

    def context(self, ctx, states):
        for k, _, code in self._states(states):
            last = self.last.get(k)
            if last is not None and last.shape == code.shape and np.any(code != last):
                print(f"      switched {switches(last, code)}", file=out)
            if tail_points:
                st = states[k]
                print(f"      tail {tail(code, np.asarray(st['tau'], float).ravel(), np.asarray(st['p'], float).ravel(), tail_points)}",
                      file=out)
        return inner(self, ctx, states)

    class Counter(Writer):
        params = ()
        done = 0

        def __init__(self):
            pass

        def increment(self, result):
            self.done += 1
            if increments and self.done >= increments:
                raise _Stop()

    handler = logging.StreamHandler(out)
    handler.setFormatter(logging.Formatter("%(message)s"))
    solver_log = logging.getLogger("lagamine_py.solver")
    level = solver_log.level
    solver_log.addHandler(handler)
    solver_log.setLevel(logging.INFO)
    stabilisation.FlipFlop.context = context
    if first or first_nodes or strip or relax:
        steps_mod.solve_increment = solve_reported
    try:
        return steps_mod.run(model, outdir,
                             writers=default_writers(outdir, model) + list(writers) + [Counter()])
    except _Stop:
        return None
    finally:
        stabilisation.FlipFlop.context = inner
        steps_mod.solve_increment = solve
        solver_log.removeHandler(handler)
        solver_log.setLevel(level)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("size", type=int, nargs="*", help="NX NY of press-then-slide (bench.py's deck)")
    p.add_argument("--deck", type=Path, help="a deck to trace instead")
    p.add_argument("--controls", nargs="+", default=[], metavar="KEY=VALUE",
                   help="*CONTROLS values set in every step")
    p.add_argument("--tail", type=int, default=0, help="state and tau/p of the last N points")
    p.add_argument("--increments", type=int, default=0, help="stop after N converged increments")
    p.add_argument("--first", action="store_true",
                   help="where each converged increment's first iterate's residual sat")
    p.add_argument("--first-nodes", type=int, default=0,
                   help="with --first: the N contact nodes of the largest first residual")
    p.add_argument("--strip", type=int, nargs="+", default=[], metavar="K",
                   help="the strip oracle with K element layers along the interface")
    p.add_argument("--relax", type=int, nargs="+", default=[], metavar="K",
                   help="the first iterate relaxed on strips of K element layers (4 sweeps)")
    args = p.parse_args(argv)
    from lagamine_py.deck import load_deck
    work = Path(tempfile.mkdtemp(prefix="newton_trace_"))
    if args.deck is not None:
        deck = args.deck
    elif len(args.size) == 2:
        sys.path.insert(0, str(ROOT))
        from bench import press_slide_deck
        deck = work / f"press_slide_{args.size[0]}x{args.size[1]}.dat"
        deck.write_text(press_slide_deck(*args.size))
    else:
        p.error("give NX NY or --deck")
    model = load_deck(deck)
    values = dict(kv.split("=", 1) for kv in args.controls)
    for step in model.steps:
        step.controls.update(values)
    outcome = trace(model, work / "out", args.tail, args.increments, first=args.first,
                    first_nodes=args.first_nodes, strip=tuple(args.strip),
                    relax=tuple(args.relax))
    if outcome is not None:
        print("\n".join(outcome.summary[:-1]))
    return 0 if outcome is None or outcome.status == 0 else int(outcome.status)


if __name__ == "__main__":
    sys.exit(main())
