"""Drive one material point along a mixed strain/stress path, without a mesh.

Small strain: the total strain is ``eps = eps_e + eps_p``; each increment prescribes some
strain components and some stress components (zero by default), and a local Newton on the
free strain components, with the law's algorithmic tangent, solves
``stress[free](eps) = target[free]``.  The plastic strain of the committed state is
``eps_n - eps_e_n``, so the law is fed ``eps_e_trial = eps - (eps_n - eps_e_n)`` exactly as
a small-strain element does.

Example
-------
>>> from lagamine_py.laws.j2 import J2Linear
>>> law = J2Linear(E=200e3, NU=0.3, SIGMAY=200.0, H=0.0)
>>> res = uniaxial_stress(law, [5e-4, 2e-3])
>>> res.stress[:, 0].round(6).tolist()
[100.0, 200.0]
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import MaterialLaw

__all__ = ["PathResult", "drive_material_point", "uniaxial_stress", "plane_strain_uniaxial"]


@dataclass
class PathResult:
    """States at the end of each increment ``k`` (rows), after the initial (zero) state.

    ``strain``, ``stress``, ``eps_e`` (k, 4); ``peeq`` (k,); ``iterations`` (k,) local Newton
    iterations; ``converged`` (k,) bool.  Rows after the first failed increment are NaN.
    ``states``: the law's whole committed state after each converged increment (dicts of
    arrays of leading shape (1,), every key the law keeps).
    """
    strain: np.ndarray
    stress: np.ndarray
    eps_e: np.ndarray
    peeq: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    states: list = field(default_factory=list)


def _evaluate(law, eps, eps_p, state):
    """Law at total strain ``eps`` (4,) from the committed state (scalar point)."""
    stress, D, new, ok = law.update((eps - eps_p)[None], state)
    return stress[0], D[0], new, bool(np.all(ok))


def drive_material_point(law: MaterialLaw, strain_path, free, stress_path=None, *, rtol: float = 1e-12,
          max_iter: int = 50) -> PathResult:
    """Drive ``law`` through the increments of a mixed path.

    Parameters
    ----------
    law : a MaterialLaw
    strain_path : (k, 4) total strain at the end of each increment; the columns in ``free``
        are unknowns (their values are ignored).
    free : sequence of component indices whose *stress* is prescribed.
    stress_path : (k, len(free)) prescribed stress on ``free`` (default zero).
    rtol : convergence when ``|stress[free] - target| <= rtol * max(|stress|, |target|)``
        (the 2-norms), or when the Newton correction is at round-off level.
    max_iter : local Newton iterations per increment.
    """
    path = np.atleast_2d(np.asarray(strain_path, dtype=float))
    free = np.asarray(free, dtype=int)
    fixed = np.setdiff1d(np.arange(4), free)
    target = np.zeros((len(path), free.size)) if stress_path is None else \
        np.atleast_2d(np.asarray(stress_path, dtype=float)).reshape(len(path), free.size)
    n = len(path)
    out = PathResult(np.full((n, 4), np.nan), np.full((n, 4), np.nan), np.full((n, 4), np.nan),
                     np.full(n, np.nan), np.zeros(n, dtype=int), np.zeros(n, dtype=bool))

    state = {k: v[None] for k, v in law.init_state(()).items()}
    eps_n = np.zeros(4)
    stress_n, D, _, _ = _evaluate(law, eps_n, eps_n, state)   # tangent for the first predictor
    for k in range(n):
        eps_p = eps_n - state["eps_e"][0]
        eps = eps_n.copy()
        eps[fixed] = path[k, fixed]
        # predictor: the free strains follow the last tangent with the stress target
        d_fixed = eps[fixed] - eps_n[fixed]
        rhs = target[k] - stress_n[free] - D[np.ix_(free, fixed)] @ d_fixed
        eps[free] += np.linalg.solve(D[np.ix_(free, free)], rhs)
        for it in range(1, max_iter + 1):
            stress, D, new, ok = _evaluate(law, eps, eps_p, state)
            r = stress[free] - target[k]
            scale = max(np.linalg.norm(stress), np.linalg.norm(target[k]), np.finfo(float).tiny)
            if ok and np.linalg.norm(r) <= rtol * scale:
                break
            de = -np.linalg.solve(D[np.ix_(free, free)], r)
            eps[free] += de
            if ok and np.linalg.norm(de) <= 1e-15 * max(np.linalg.norm(eps), np.finfo(float).tiny):
                stress, D, new, ok = _evaluate(law, eps, eps_p, state)
                break
        else:
            ok = False
        out.iterations[k] = it
        if not (ok and np.all(np.isfinite(stress))):
            break
        out.strain[k], out.stress[k], out.eps_e[k] = eps, stress, new["eps_e"][0]
        out.peeq[k], out.converged[k] = new["peeq"][0], True
        out.states.append(new)
        state, eps_n, stress_n = new, eps, stress
    return out


def _eps11_path(eps11_path):
    e = np.asarray(eps11_path, dtype=float).reshape(-1)
    path = np.zeros((e.size, 4))
    path[:, 0] = e
    return path


def uniaxial_stress(law: MaterialLaw, eps11_path, **kw) -> PathResult:
    """Uniaxial stress: ``eps11`` prescribed (k,), ``s22 = s33 = s12 = 0`` (the
    axisymmetric uniaxial test: 1 axial, 2 and 3 radial and hoop)."""
    return drive_material_point(law, _eps11_path(eps11_path), free=(1, 2, 3), **kw)


def plane_strain_uniaxial(law: MaterialLaw, eps11_path, **kw) -> PathResult:
    """Plane strain uniaxial: ``eps11`` prescribed (k,), ``e33 = 0``, ``s22 = s12 = 0``."""
    return drive_material_point(law, _eps11_path(eps11_path), free=(1, 3), **kw)
