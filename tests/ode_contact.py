"""An independent reference for the COULOMB law: the rate equations (paper eqs. 2, 8-10)
integrated as ODEs by scipy's DOP853 along a piecewise-linear path of (u, v).

Nothing of lagamine_py is used: the hardening forms, the cap, the loading criterion and every
switch (yield, unloading, separation, re-contact, a break of a form, the cap taken or left) are
written out here from the equations, and each switch is located as an event of the
integration (or as a root of the exact elastic path), so the integration never steps over one.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

RTOL, ATOL = 1e-13, 1e-16


class Forms:
    """B(lam), phi(lam) and their derivatives from the deck parameters of COULOMB."""

    def __init__(self, par: dict):
        self.par = par
        table = par.get("CONTACT LAW TABLE")
        self.table = None if table is None else np.asarray(table, float)
        self.cap = par.get("TAUMAX", math.inf)
        self.breaks = []
        if self.table is not None:
            self.breaks = list(self.table[1:, 0])
        else:
            for v0, h in ((par.get("B", 0.0), par.get("HB", 0.0)),
                          (par["PHI"], par.get("HPHI", 0.0))):
                if h < 0:
                    self.breaks.append(-v0 / h)

    def _one(self, lam, v0, slope, inf, lamc, col):
        if self.table is not None:
            x, y = self.table[:, 0], self.table[:, col]
            k = max(min(int(np.searchsorted(x, lam, side="right")) - 1, len(x) - 2), 0)
            if lam >= x[-1]:
                return y[-1], 0.0
            s = (y[k + 1] - y[k]) / (x[k + 1] - x[k])
            return y[k] + s * (lam - x[k]), s
        if inf is not None:
            e = math.exp(-lam / lamc)
            return inf + (v0 - inf) * e, -(v0 - inf) / lamc * e
        v = v0 + slope * lam
        return (v, slope) if v > 0 or (v == 0 and slope > 0) else (0.0, 0.0)

    def b(self, lam):
        p = self.par
        return self._one(lam, p.get("B", 0.0), p.get("HB", 0.0), p.get("B_INF"), p.get("LAMC_B"), 2)

    def phi(self, lam):
        p = self.par
        return self._one(lam, p.get("PHI", 0.0), p.get("HPHI", 0.0), p.get("PHI_INF"),
                         p.get("LAMC"), 1)


def reference(par: dict, u_path, v_path) -> dict[str, np.ndarray]:
    """p, tau, lam, dissip at the path points (the point starts unloaded at u_path[0])."""
    F = Forms(par)
    KP, KT, cap = par["KP"], par["KT"], F.cap
    tau, lam, dis = 0.0, 0.0, 0.0
    rows = [(KP * max(u_path[0], 0.0), tau, lam, dis)]
    for i in range(len(u_path) - 1):
        ua, du = u_path[i], u_path[i + 1] - u_path[i]
        dv = v_path[i + 1] - v_path[i]
        u = lambda t: ua + du * t                                     # noqa: E731
        t = 0.0
        closed = ua > 0.0 or (ua == 0.0 and du > 0.0)
        if not closed:
            tau = 0.0
        for _ in range(10_000):
            if t >= 1.0:
                break
            if not closed:                         # open: wait for re-contact
                if du > 0.0 and u(1.0) > 0.0:
                    t = max(t, -ua / du)
                    closed, tau = True, 0.0
                    continue
                break
            p = KP * u(t)
            b, hb = F.b(lam)
            ph, hph = F.phi(lam)
            rho_u = b + ph * p
            rho = min(rho_u, cap)
            sg = math.copysign(1.0, tau) if tau != 0.0 else math.copysign(1.0, dv)
            on_cap = rho_u > cap
            if math.isfinite(cap) and abs(rho_u - cap) <= 1e-12 * cap:   # at the cap: does rho_u rise along the path?
                on_cap = (hb + hph * p) * sg * dv + ph * KP * du > 0.0
            rho_p = 0.0 if on_cap else ph
            on = abs(tau) >= rho - 1e-11 * (rho + abs(tau) + 1.0)
            if on and sg * KT * dv - rho_p * KP * du > 0.0:
                t, tau, lam, dis, closed = _plastic(F, KP, KT, u, du, dv, t, tau, lam, dis, sg,
                                                    on_cap)
            else:
                t, tau, closed = _elastic(F, KP, KT, u, du, dv, t, tau, lam)
        else:
            raise RuntimeError("the reference does not reach the end of the segment")
        p_end = KP * max(u(1.0), 0.0) if closed else 0.0
        rows.append((p_end, tau if closed else 0.0, lam, dis))
    return {k: np.array(c) for k, c in zip(("p", "tau", "lam", "dissip"), zip(*rows))}


def _elastic(F, KP, KT, u, du, dv, t0, tau0, lam):
    """Elastic from t0: tau = tau0 + KT dv (t - t0), lam frozen.  Ends at the first yield
    (f rising through 0), a separation (u = 0) or the segment's end."""
    b, _ = F.b(lam)
    ph, _ = F.phi(lam)
    tau = lambda t: tau0 + KT * dv * (t - t0)                       # noqa: E731
    f = lambda t: abs(tau(t)) - min(b + ph * KP * u(t), F.cap)      # noqa: E731
    t_sep = 1.0
    if du < 0.0 and u(1.0) <= 0.0:
        t_sep = -u(0.0) / du
    # f is convex and piecewise linear: its kinks (tau = 0, the cap) bound the pieces
    knots = [t0, t_sep]
    if dv != 0.0:
        knots.append(t0 - tau0 / (KT * dv))
    if du != 0.0 and ph != 0.0 and math.isfinite(F.cap):
        knots.append(((F.cap - b) / (ph * KP) - u(0.0)) / du)
    knots = sorted(k for k in knots if t0 <= k <= t_sep)
    scale = abs(tau0) + b + ph * KP * abs(u(t0)) + 1.0
    for a, c in zip(knots[:-1], knots[1:]):
        fa, fc = f(a), f(c)
        if fa <= 1e-12 * scale and fc > 1e-12 * scale and c > a:
            ty = a if fa >= 0.0 else brentq(f, a, c, xtol=1e-16, rtol=8.9e-16)
            if ty > t0 or fa < 0.0:
                return ty, tau(ty), True
    if t_sep < 1.0:
        return t_sep, 0.0, False
    return 1.0, tau(1.0), True


def _plastic(F, KP, KT, u, du, dv, t0, tau0, lam0, dis0, sg, on_cap):
    """Plastic loading from t0 (eq. 10 and 8, dD = |tau| dlam): the ODE until the segment's
    end or an event: separation, a break of a form, the cap taken or left, unloading."""
    cap = F.cap

    def rates(t, y):
        tau, lam, _ = y
        p = KP * u(t)
        b, hb = F.b(lam)
        ph, hph = F.phi(lam)
        if on_cap:
            return [0.0, sg * dv, abs(tau) * sg * dv]
        h = hb + hph * p
        dlam = (KT * sg * dv - ph * KP * du) / (h + KT)
        dtau = (ph * KP * KT * sg * du + h * KT * dv) / (h + KT)
        return [dtau, dlam, abs(tau) * dlam]

    events = []

    def separation(t, y):
        return u(t)
    separation.terminal, separation.direction = True, -1
    events.append(separation)
    for k in F.breaks:
        if k > lam0 + 1e-15:
            ev = lambda t, y, k=k: y[1] - k                          # noqa: E731
            ev.terminal, ev.direction = True, 1
            events.append(ev)
    if math.isfinite(cap):
        def cap_switch(t, y):
            b, _ = F.b(y[1])
            ph, _ = F.phi(y[1])
            return b + ph * KP * u(t) - cap
        cap_switch.terminal = True
        cap_switch.direction = -1 if on_cap else 1
        events.append(cap_switch)

    def unloading(t, y):
        ph, _ = F.phi(y[1])
        return sg * KT * dv - (0.0 if on_cap else ph) * KP * du
    unloading.terminal, unloading.direction = True, -1
    events.append(unloading)
    sol = solve_ivp(rates, (t0, 1.0), [tau0, lam0, dis0], method="DOP853", rtol=RTOL,
                    atol=ATOL, events=events)
    tau, lam, dis = sol.y[:, -1]
    t = sol.t[-1]
    if sol.status == 1 and sol.t_events[0].size:              # separated: open
        return t, 0.0, lam, dis, False
    return t, tau, lam, dis, True           # the end, or a break, the cap, unloading
