"""The material-law contract (:class:`lagamine_py.laws.base.MaterialLaw`) as checks.

The law is built from ``example_values()`` and driven along material-point paths
(:func:`lagamine_py.laws.material_point.drive`, uniaxial stress and tension-shear) with its own
tangent into plastic states; at those states the tangent is compared with central differences
of ``update()``, objectivity with a rotation of the trial strain, batched results with
point-by-point ones; the committed state must come back unchanged.  ``energy()`` (when the law
has one) is checked along a loading, unloading and shear path of total strain against the work
of the stresses, ``sum 1/2 (s_n + s_n+1) . (e_n+1 - e_n)``.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from .findings import Finding, Skip, Suite, all_within, changed_keys, require, within


LAW_ITEMS = ("parameters", "init_state", "elastic moduli", "material-point paths",
             "tangent", "objectivity", "state unchanged", "batched shapes", "energy")

_PATHS = (("uniaxial stress", np.array([1.0, 0.0, 0.0, 0.0]), (1, 2, 3)),
          ("tension-shear, s33 = 0", np.array([1.0, -0.5, 0.0, 1.5]), (2,)))


@dataclass
class _Point:
    """A committed state (leading shape (1,)) and a trial strain (1, 4) to evaluate;
    ``converged``: the path went through it (the law may refuse the others, ok False)."""
    label: str
    state: dict
    trial: np.ndarray
    converged: bool = True


def _law_points(law) -> tuple[list[_Point], str, str]:
    """States along material-point paths driven with the law's own tangent
    (:func:`~lagamine_py.laws.material_point.drive`): the first increment, two plastic loading
    increments past the first yield, elastic unloading from the last of them, and the increment
    where a path stopped if it did.  Returns the points, a description, and a problem ("" when
    none): a path that stopped before three plastic increments."""
    from ..laws.material_point import drive_material_point as drive
    points, notes, problem = [], [], ""
    init = {k: np.asarray(v)[None] for k, v in law.init_state(()).items()}
    for label, direction, free in _PATHS:
        for n_inc in (10, 20, 30, 36):                 # strains 1e-6 * 1.6^k: up to about 5
            path = 1e-6 * 1.6 ** np.arange(n_inc)[:, None] * direction
            res = drive(law, path, free)
            done = int(res.converged.sum())
            peeq = np.concatenate([[0.0], res.peeq[:done]])
            plastic = np.flatnonzero(np.diff(peeq) > 0) + 1     # increments that yield
            if done < n_inc or len(plastic) >= 3:
                break
        stop = "" if done == n_inc else \
            f", stopped at increment {done + 1} (strain {np.abs(path[done]).max():.2g}): the " \
            f"local Newton with the law's tangent did not converge or ok was False"
        notes.append(f"{label}: {done} increments, {len(plastic)} plastic{stop}")
        if done < n_inc and len(plastic) < 3:
            problem = "; ".join(notes)
        states = [init] + res.states[:done]
        strain = np.vstack([np.zeros(4), res.strain[:done]])
        picks = [(1, "first increment")] if done else []
        if len(plastic):
            later = [int(k) for k in plastic if k > plastic[0]][:2] or [int(plastic[0])]
            picks += [(k, "plastic loading") for k in later]
        for k, what in picks:
            st = states[k - 1]
            points.append(_Point(f"{label}, {what} (strain {np.abs(strain[k]).max():.2g})", st,
                                 (st["eps_e"] + strain[k] - strain[k - 1]).reshape(1, 4)))
        if len(plastic):
            k = picks[-1][0]
            st = states[k]
            points.append(_Point(f"{label}, elastic unloading from a plastic state", st,
                                 (st["eps_e"] - 0.1 * (strain[k] - strain[k - 1])).reshape(1, 4)))
        if done < n_inc:                # the prescribed part of the step it could not make
            fixed = np.setdiff1d(np.arange(4), free)
            step = np.zeros(4)
            step[fixed] = path[done, fixed] - strain[done, fixed]
            st = states[done]
            points.append(_Point(f"{label}, the increment where the path stopped "
                                 f"(strain {np.abs(path[done]).max():.2g})", st,
                                 (st["eps_e"] + step).reshape(1, 4), converged=False))
    return points, "; ".join(notes), problem


def _accepted(law, points) -> list[_Point]:
    """The points whose update the law accepts (ok): a refused one has no tangent to check."""
    return [p for p in points if bool(np.all(law.update(p.trial, p.state)[3]))]


def _law_tangent(law, points) -> str:
    measures, plastic = [], 0
    points = _accepted(law, points)
    for p in points:
        stress, D, new, ok = law.update(p.trial, p.state)
        h = 1e-6 * max(float(np.abs(p.trial).max()), 1e-12)
        fd = np.empty((4, 4))
        for t in range(4):
            e = np.zeros((1, 4))
            e[0, t] = h
            fd[:, t] = (law.update(p.trial + e, p.state)[0][0]
                        - law.update(p.trial - e, p.state)[0][0]) / (2 * h)
        plastic += bool(np.any(new["peeq"] > p.state["peeq"]))
        measures.append((f"{p.label}: max |D - D_fd| / max |D_fd|",
                         float(np.abs(D[0] - fd).max() / np.abs(fd).max()), 1e-5))
    head = f"{len(points)} points, {plastic} plastic: "
    if not plastic:
        head += "no plastic state was reached, the elastic tangent only is checked; "
    return head + all_within(measures)


def _rotation(a: float) -> np.ndarray:
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def _rotate(v: np.ndarray, R: np.ndarray, shear: float) -> np.ndarray:
    """Rotate the in-plane part of 4-vectors (..., 4); ``shear`` 2 for engineering strains,
    1 for stresses."""
    T = np.empty(v.shape[:-1] + (2, 2))
    T[..., 0, 0], T[..., 1, 1] = v[..., 0], v[..., 1]
    T[..., 0, 1] = T[..., 1, 0] = v[..., 3] / shear
    T = R @ T @ R.T
    return np.stack([T[..., 0, 0], T[..., 1, 1], v[..., 2], shear * T[..., 0, 1]], axis=-1)


def _objectivity(law, points) -> str:
    if not law.isotropic:
        raise Skip("the law says isotropic = False")
    R = _rotation(0.6)
    measures = []
    for p in _accepted(law, points):
        stress, _, new, _ = law.update(p.trial, p.state)
        st = dict(p.state)
        st["eps_e"] = _rotate(np.asarray(p.state["eps_e"], float), R, 2.0)
        s_r, _, new_r, _ = law.update(_rotate(p.trial, R, 2.0), st)
        strain = float(np.abs(p.trial).max())
        err = max(float(np.abs(s_r - _rotate(stress, R, 1.0)).max() / np.abs(stress).max()),
                  float(np.abs(new_r["eps_e"] - _rotate(new["eps_e"], R, 2.0)).max()) / strain,
                  float(np.abs(new_r["peeq"] - new["peeq"]).max()) / strain)
        measures.append((f"{p.label}: rotated by 0.6 rad, max relative difference of stress, "
                         f"eps_e, peeq", err, 1e-10))
    return all_within(measures)


def _law_state_unchanged(law, points) -> str:
    changed = []
    for p in points:
        before = copy.deepcopy(p.state)
        law.update(p.trial.copy(), p.state)
        keys = changed_keys(before, p.state)
        if keys:
            changed.append(f"{p.label}: {', '.join(keys)}")
            p.state.clear()
            p.state.update(before)
    require(not changed, "update() modified the committed state it was given: "
            + "; ".join(changed))
    return f"the committed state is unchanged after update() at {len(points)} points"


def _batched_shapes(law, points) -> str:
    st = law.init_state((2, 3))
    require(np.shape(st.get("eps_e")) == (2, 3, 4) and np.shape(st.get("peeq")) == (2, 3),
            f"init_state((2, 3)) gives eps_e {np.shape(st.get('eps_e'))}, peeq "
            f"{np.shape(st.get('peeq'))}")
    m = len(points)
    state = {k: np.stack([np.concatenate([np.asarray(p.state[k]) for p in points])] * 2)
             for k in points[0].state}                                     # (2, m, ...)
    trial = np.stack([np.concatenate([p.trial for p in points])] * 2)       # (2, m, 4)
    stress, D, new, ok = law.update(trial, state)
    shapes = {"stress": (np.shape(stress), (2, m, 4)), "D": (np.shape(D), (2, m, 4, 4)),
              "ok": (np.shape(ok), (2, m))}
    shapes.update({f"new_state[{k!r}]": (np.shape(new.get(k)), np.shape(v))
                   for k, v in state.items()})
    wrong = [f"{k} {got} (expected {want})" for k, (got, want) in shapes.items() if got != want]
    require(not wrong, "batched update() over (2, m) points: " + ", ".join(wrong))
    converged = np.array([p.converged for p in points])
    require(np.asarray(ok).dtype == bool and bool(np.all(ok[:, converged])),
            f"ok must be a bool array, True at the points the paths went through: {ok}")
    err = 0.0
    for j, p in enumerate(points):
        s1, D1, n1, ok1 = law.update(p.trial, p.state)
        require(np.array_equal(ok[:, j], np.broadcast_to(ok1, (2, 1))[:, 0]),
                f"{p.label}: ok batched {ok[:, j]} differs from ok alone {ok1}")
        if not np.all(ok1):
            continue
        strain = float(np.abs(p.trial).max())
        err = max(err, float(np.abs(stress[:, j] - s1).max() / np.abs(s1).max()),
                  float(np.abs(D[:, j] - D1).max() / np.abs(D1).max()),
                  float(np.abs(new["eps_e"][:, j] - n1["eps_e"]).max()) / strain)
    return within(f"shapes as the contract says; batched over (2, {m}) vs point by point: max "
                  f"relative difference", err, 1e-10)


def _law_init(law) -> str:
    st0, st = law.init_state(()), law.init_state((5,))
    got = {k: np.shape(st.get(k)) for k in ("eps_e", "peeq")}
    got0 = {k: np.shape(st0.get(k)) for k in ("eps_e", "peeq")}
    require(got == {"eps_e": (5, 4), "peeq": (5,)} and got0 == {"eps_e": (4,), "peeq": ()},
            f"init_state((5,)) gives {got}, init_state(()) gives {got0}; the contract says "
            f"eps_e shape + (4,), peeq shape")
    require(all(np.all(np.isfinite(np.asarray(v, float))) for v in st.values()),
            "init_state has non-finite values")
    return f"keys {', '.join(sorted(st))}; eps_e {got['eps_e']}, peeq {got['peeq']} for shape (5,)"


def _law_moduli(law) -> str:
    from ..core.tensors import elastic_matrix
    E, nu = law.elastic_moduli()
    require(E > 0 and -1.0 < nu < 0.5, f"elastic_moduli() = ({E}, {nu}): E > 0, -1 < nu < 0.5")
    init = {k: np.asarray(v)[None] for k, v in law.init_state(()).items()}
    D0 = law.update(np.zeros((1, 4)), init)[1][0]
    Dh = elastic_matrix(E, nu)
    return within(f"elastic_moduli() = (E {E:g}, nu {nu:g}): max |D(0) - Hooke(E, nu)| / E",
                  float(np.abs(D0 - Dh).max() / E), 1e-8)


#: the energy path: legs of total strain (deviatoric tension, half unloading, shear, back to
#: zero), times an amplitude grown until the law yields on it
_ENERGY_LEGS = (np.array([1.0, -0.5, -0.5, 0.0]), np.array([0.5, -0.25, -0.25, 0.0]),
                np.array([0.5, -0.25, -0.25, 1.5]), np.zeros(4))
_ENERGY_STEPS = 60


def _energy_path(law, amplitude: float):
    """Drive one point along the legs: the largest work of the stresses along the path
    (trapezoidal), the largest ``|work - (stored + dissipated)|`` met, the work, stored and
    dissipated energy at the end, the smallest dissipation increment and whether it yielded;
    None when the law refused an increment."""
    st = {k: np.asarray(v)[None] for k, v in law.init_state(()).items()}
    eps, sig = np.zeros(4), np.zeros(4)
    work = dissipated = 0.0
    smallest = np.inf
    stored = 0.0
    peak = gap = 0.0
    start = np.zeros(4)
    for leg in _ENERGY_LEGS:
        end = amplitude * leg
        for k in range(1, _ENERGY_STEPS + 1):
            target = start + (end - start) * k / _ENERGY_STEPS
            de = target - eps
            s_new, _, new, ok = law.update((st["eps_e"] + de).reshape(1, 4), st)
            if not np.all(ok):
                return None
            s_new = np.asarray(s_new, float)[0]
            work += 0.5 * float((sig + s_new) @ de)
            psi, dis = law.energy(st, new)
            stored = float(np.asarray(psi).ravel()[0])
            dissipated += float(np.asarray(dis).ravel()[0])
            smallest = min(smallest, float(np.asarray(dis).ravel()[0]))
            peak = max(peak, abs(work))
            gap = max(gap, abs(work - stored - dissipated))
            st, eps, sig = new, target, s_new
        start = end
    return (peak, gap, work, stored, dissipated, smallest,
            bool(np.any(np.asarray(st["peeq"]) > 0)))


def _law_energy(law) -> str:
    init = {k: np.asarray(v)[None] for k, v in law.init_state(()).items()}
    try:
        law.energy(init, init)
    except NotImplementedError as exc:
        raise Skip(f"{exc}: the energy balance (*CHECK, TYPE=ENERGY) cannot use it") from None
    E, _ = law.elastic_moduli()
    found = None
    for amplitude in 1e-4 * 2.0 ** np.arange(14):      # up to about 1: until it yields
        found = _energy_path(law, amplitude)
        require(found is not None, f"the law refused an increment of the energy path (strain "
                                   f"amplitude {amplitude:.2g}, {_ENERGY_STEPS} steps a leg)")
        if found[6]:
            break
    peak, gap, work, stored, dissipated, smallest, plastic = found
    scale = max(peak, 1e-300)
    require(smallest >= -1e-10 * scale, f"a negative dissipation increment: {smallest:.3g} "
                                        f"(the largest work {peak:.3g})")
    what = "plastic" if plastic else "elastic only (the law did not yield up to strain 0.8)"
    return within(f"{what} path of {4 * _ENERGY_STEPS} increments to strain {amplitude:.2g} and "
                  f"back (at its end work {work:.4g}, stored {stored:.4g}, dissipated "
                  f"{dissipated:.4g}): max |work - (stored + dissipated)| / max |work|",
                  gap / scale, 1e-6)


def check_material_law(cls) -> list[Finding]:
    """The material-law contract (:class:`~lagamine_py.laws.base.MaterialLaw`) on ``cls``."""
    s = Suite(LAW_ITEMS)
    law = s.build(cls)
    if law is None:
        return s.blocked("the law could not be built from example_values()")
    s.run("init_state", _law_init, law)
    s.run("elastic moduli", _law_moduli, law)
    built = {}

    def paths():
        built["points"], text, problem = _law_points(law)
        require(not problem, problem)
        return text

    s.run("material-point paths", paths)
    points = built.get("points")
    if not points:               # nothing converged: the first trial of each path
        init = {k: np.asarray(v)[None] for k, v in law.init_state(()).items()}
        points = [_Point(f"{label}, first increment", init, 1e-6 * d[None])
                  for label, d, _ in _PATHS]
    s.run("tangent", _law_tangent, law, points)
    s.run("objectivity", _objectivity, law, points)
    s.run("state unchanged", _law_state_unchanged, law, points)
    s.run("batched shapes", _batched_shapes, law, points)
    s.run("energy", _law_energy, law)
    return s.findings
