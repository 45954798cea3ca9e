"""Single-point driver of a contact law, without a mesh (fixed local axes).

Used by tests and studies to exercise a :class:`~lagamine_py.laws.base.ContactLaw` along a
prescribed path of normal approach ``u`` (penetration, > 0 in contact) and tangential relative
displacement ``v``.  Several independent points can be driven at once (paths of shape
``(N+1, g)``); the law sees them as one batch.
"""
from __future__ import annotations

import numpy as np

from .base import ContactLaw

__all__ = ["drive_contact_point"]

_FIELDS = ("p", "tau", "lam", "slip", "vp", "dissip", "status")


def drive_contact_point(law: ContactLaw, u_path, v_path, substeps: int | None = None,
          tangent: bool = False) -> dict[str, np.ndarray]:
    """Drive ``law`` along a piecewise-linear path, splitting each interval in sub-intervals.

    Parameters
    ----------
    law : ContactLaw
    u_path, v_path : (N+1,) or (N+1, g) arrays
        Penetration and tangential relative displacement at the path points.  The point starts
        unloaded (``tau = 0``) at ``u_path[0]``.
    substeps : int, optional
        Sub-intervals per path interval; default ``law.substeps``.
    tangent : bool
        Also return ``dtau_du``, ``dtau_dv``: the derivative of ``tau`` at each path point with
        respect to the increments ``u[i+1] - u[i]``, ``v[i+1] - v[i]`` of the interval ending
        there (state at its start held), chained through the sub-intervals with the law's
        tangent entries (the contract's keys, a key left out being zero and ``p_d`` defaulting
        to ``p_u``, as the contact element reads them) -- what a contact element does with
        SUBSTEPS > 1.

    Returns
    -------
    dict of arrays (N+1,) or (N+1, g): ``p``, ``tau``, ``lam``, ``slip``, ``vp``, ``dissip``,
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
    jac = {"dtau_du": [np.zeros(g)], "dtau_dv": [np.zeros(g)]}
    for i in range(len(u) - 1):                            # time loop, batched over points
        du = (u[i + 1] - u[i]) / n
        dv = (v[i + 1] - v[i]) / n
        # (d p, d tau, d lam) / (d Du, d Dv) of the interval, chained over its sub-intervals
        J = {key: np.zeros((2, g)) for key in ContactLaw.TANGENT_OUT}
        for k in range(1, n + 1):
            d = u[i + 1] if k == n else u[i] + k * du
            state, tan = law.update(state, d, du, dv)
            if tangent:
                J = _chain(tan, J, k, n, g)
        for key in _FIELDS:
            out[key].append(np.array(state[key], copy=True))
        jac["dtau_du"].append(J["tau"][0])
        jac["dtau_dv"].append(J["tau"][1])
    if tangent:
        out.update(jac)
    res = {k: np.stack(vals) for k, vals in out.items()}
    res["u"], res["v"] = u.copy(), v.copy()
    if single:
        res = {k: a[:, 0] for k, a in res.items()}
    return res


def _entry(tan, out: str, inp: str, g: int) -> np.ndarray:
    """Tangent entry ``<out>_<inp>`` as (g,): zero when left out, ``p_d`` defaulting to ``p_u``."""
    c = tan.get(f"{out}_{inp}")
    if c is None and (out, inp) == ("p", "d"):
        c = tan.get("p_u")
    return np.zeros(g) if c is None else np.broadcast_to(np.asarray(c, float), (g,))


def _chain(tan, J, k: int, n: int, g: int) -> dict[str, np.ndarray]:
    """Derivatives (2, g) of (p, tau, lam) w.r.t. the interval's (Du, Dv) after sub-interval
    ``k`` of ``n``: ``d_k = u_i + k Du / n`` and ``du_k = Du / n`` (the entry ``u`` moves d with
    du, ``d`` moves d alone), ``dv_k = Dv / n``, plus the old values' dependences."""
    new = {}
    for o in ContactLaw.TANGENT_OUT:
        direct = np.stack([_entry(tan, o, "u", g) / n + _entry(tan, o, "d", g) * (k - 1) / n,
                           _entry(tan, o, "v", g) / n])
        new[o] = direct + sum(_entry(tan, o, i, g) * J[i] for i in ContactLaw.TANGENT_OUT)
    return new
