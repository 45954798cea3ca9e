"""Single-point driver of a contact law, without a mesh (fixed local axes).

Used by tests and studies to exercise a :class:`~lagamine_py.laws.base.ContactLaw` along a
prescribed path of normal approach ``u`` (penetration, > 0 in contact) and tangential relative
displacement ``v``.  Several independent points can be driven at once (paths of shape
``(N+1, g)``); the law sees them as one batch.
"""
from __future__ import annotations

import numpy as np

from .base import ContactLaw

__all__ = ["drive"]

_FIELDS = ("p", "tau", "lam", "slip", "dissip", "status")


def drive(law: ContactLaw, u_path, v_path, substeps: int | None = None) -> dict[str, np.ndarray]:
    """Drive ``law`` along a piecewise-linear path, splitting each interval in sub-intervals.

    Parameters
    ----------
    law : ContactLaw
    u_path, v_path : (N+1,) or (N+1, g) arrays
        Penetration and tangential relative displacement at the path points.  The point starts
        unloaded (``tau = 0``) at ``u_path[0]``.
    substeps : int, optional
        Sub-intervals per path interval; default ``law.substeps``.

    Returns
    -------
    dict of arrays (N+1,) or (N+1, g): ``p``, ``tau``, ``lam``, ``slip``, ``dissip``,
    ``status`` at the path points, plus the path itself as ``u`` and ``v``.
    """
    u = np.asarray(u_path, float)
    v = np.asarray(v_path, float)
    single = u.ndim == 1 and v.ndim == 1
    u, v = np.broadcast_arrays(u.reshape(len(u), -1), v.reshape(len(v), -1))
    n = law.substeps if substeps is None else substeps
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"substeps must be an integer >= 1, got {n!r}")
    g = u.shape[1]
    state = law.init_state(g)
    state, _ = law.update(state, u[0], u[0], np.zeros(g))  # load the normal part, tau = 0
    out = {k: [np.array(state[k], copy=True)] for k in _FIELDS}
    for i in range(len(u) - 1):                            # time loop, batched over points
        du = (u[i + 1] - u[i]) / n
        dv = (v[i + 1] - v[i]) / n
        for k in range(1, n + 1):
            d = u[i + 1] if k == n else u[i] + k * du
            state, _ = law.update(state, d, du, dv)
        for key in _FIELDS:
            out[key].append(np.array(state[key], copy=True))
    res = {k: np.stack(vals) for k, vals in out.items()}
    res["u"], res["v"] = u.copy(), v.copy()
    if single:
        res = {k: a[:, 0] for k, a in res.items()}
    return res
