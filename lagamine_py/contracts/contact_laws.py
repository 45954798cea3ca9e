"""The contact-law contract (:class:`lagamine_py.laws.base.ContactLaw`) as checks.

Sub-intervals in every regime are found from the law's own answers (close at a penetration d0,
then a sweep of tangential increments for the first that slips); every tangent entry
``<out>_<in>`` is compared with central differences of ``update()`` there, and chained over
sub-intervals as the contact element chains them (:func:`lagamine_py.laws.contact_point.drive`)
against differences of whole paths.  The frozen holds: OPEN gives no contact and keeps the
history; STICK stays elastic beyond the cone, ``tau = tau0 + k dv`` with the stick stiffness
``k`` measured on the free law (a linear tangential elasticity).  ``stored_energy()`` (when the
law has one) is checked along a closed path (press, slide both ways): the work of the contact
stresses ``1/2 (p_n + p_n+1) dd + 1/2 (tau_n + tau_n+1) dv`` against the change of the stored
energy plus the trapezoidal friction term ``1/2 (tau_n + tau_n+1) dvp`` (the energy balance's).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from .findings import (ContractFailure, Finding, Suite, all_within, changed_keys,
                       require, within)


CONTACT_ITEMS = ("parameters", "state and status", "tangent entries", "tangent chained",
                 "state unchanged", "admissible path", "frozen holds", "energy")

_D0 = 1e-3              # penetration of the probes; tangential increments follow the law's
                        # own slip onset


@dataclass
class _CPoint:
    """A contact sub-interval to evaluate: committed state (g = 1), d, du, dv, expected
    status (or None)."""
    label: str
    state: dict
    d: float
    du: float
    dv: float
    status: int | None = None


def _cupdate(law, state, d, du, dv, frozen=None):
    arr = lambda x: np.array([float(x)])             # noqa: E731
    return law.update(state, arr(d), arr(du), arr(dv),
                      None if frozen is None else np.array([frozen], np.int8))


@dataclass
class _ContactProbe:
    points: list
    closed: dict            # in contact at d0, tau = 0
    slip_state: dict | None  # slipping at 1.1 d0
    dv_slip: float          # tangential increment from `closed` at which the point first slips
    has_stick: bool
    has_slip: bool
    scales: dict            # reference values of p, tau, lam and of the inputs u, d, v


def _contact_probe(law) -> _ContactProbe:
    """Sub-intervals in every regime, found from the law's own answers: close at d0, then a
    sweep of tangential increments for the first one that slips (dv_slip); stick points take a
    quarter of it, slip points four times it (the margin keeps the differences off the kinks).
    Each sub-interval's d - du is where its committed state was computed."""
    from ..core.status import OPEN, SLIP, STICK
    s0 = law.init_state(1)
    closed, _ = _cupdate(law, s0, _D0, _D0, 0.0)
    n = 64
    dvs = _D0 * 1e-9 * 2.0 ** np.arange(n)
    sweep, _ = law.update({k: np.repeat(np.asarray(v), n) for k, v in closed.items()},
                          np.full(n, _D0), np.zeros(n), dvs)
    status = np.asarray(sweep["status"])
    slips = np.flatnonzero(status == SLIP)
    has_slip = len(slips) > 0
    k = int(slips[0]) if has_slip else n - 1
    has_stick = bool(np.any(status[:k] == STICK))
    dv_s = float(dvs[k])
    opened, _ = _cupdate(law, closed, -_D0, -2 * _D0, 0.0)                # at -d0
    pts = [_CPoint("open", opened, -0.5 * _D0, 0.5 * _D0, 0.3 * dv_s, OPEN),
           _CPoint("closing within the sub-interval", opened, 0.5 * _D0, 1.5 * _D0, 0.1 * dv_s)]
    slip_state = None
    if has_stick:
        stick, _ = _cupdate(law, closed, 1.1 * _D0, 0.1 * _D0, 0.25 * dv_s)  # at 1.1 d0
        pts += [_CPoint("stick", closed, 1.1 * _D0, 0.1 * _D0, 0.25 * dv_s, STICK),
                _CPoint("separating from stick", stick, -0.5 * _D0, -1.6 * _D0, 0.1 * dv_s,
                        OPEN)]
    if has_slip:
        slip_state, _ = _cupdate(law, closed, 1.1 * _D0, 0.1 * _D0, 4 * dv_s)  # at 1.1 d0
        pts += [_CPoint("slip", closed, 1.1 * _D0, 0.1 * _D0, 4 * dv_s, SLIP),
                _CPoint("slip, continuing", slip_state, 1.15 * _D0, 0.05 * _D0, 2 * dv_s, SLIP)]
        if has_stick:
            pts.append(_CPoint("stick, unloading from slip", slip_state, 1.1 * _D0, 0.0,
                               -0.25 * dv_s, STICK))
    outs = [_cupdate(law, p.state, p.d, p.du, p.dv)[0] for p in pts]
    p_ref = max(abs(float(o["p"][0])) for o in outs)
    require(p_ref > 0, f"no contact pressure at a penetration of {_D0:g}")
    tau_ref = max(max(abs(float(o["tau"][0])) for o in outs), 1e-3 * p_ref)
    scales = {"p": p_ref, "tau": tau_ref, "lam": dv_s, "u": _D0, "d": _D0, "v": dv_s}
    return _ContactProbe(pts, closed, slip_state, dv_s, has_stick, has_slip, scales)


def _entry(tan, out: str, inp: str) -> float:
    c = tan.get(f"{out}_{inp}")
    if c is None and (out, inp) == ("p", "d"):
        c = tan.get("p_u")
    return 0.0 if c is None else float(np.asarray(c, float).reshape(-1)[0])


def _contact_tangent(law, probe: _ContactProbe) -> str:
    from ..core.status import STATUS_NAMES
    from ..laws.base import ContactLaw
    sc = probe.scales
    measures = []
    for p in probe.points:
        new, tan = _cupdate(law, p.state, p.d, p.du, p.dv)
        status = STATUS_NAMES[int(new["status"][0])]
        worst, where = 0.0, ""
        for inp in ContactLaw.TANGENT_IN:
            h = 1e-6 * sc[inp]

            def out(sign, inp=inp, h=h):
                st = copy.deepcopy(p.state)
                d, du, dv = p.d, p.du, p.dv
                if inp == "u":
                    d, du = d + sign * h, du + sign * h
                elif inp == "d":
                    d += sign * h
                elif inp == "v":
                    dv += sign * h
                else:
                    st[inp] = np.asarray(st[inp], float) + sign * h
                return _cupdate(law, st, d, du, dv)[0]

            plus, minus = out(1.0), out(-1.0)
            for o in ContactLaw.TANGENT_OUT:
                fd = (float(plus[o][0]) - float(minus[o][0])) / (2 * h)
                err = abs(_entry(tan, o, inp) - fd) * sc[inp] / sc[o]
                if err > worst:
                    worst, where = err, f" ({o}_{inp}: {_entry(tan, o, inp):.6g} vs {fd:.6g})"
        measures.append((f"{p.label} [{status}]: max |entry - central difference| "
                         f"x input scale / output scale{where}", worst, 1e-5))
    notes = []
    if not probe.has_stick:
        notes.append("no stick state (the law slips at once)")
    if not probe.has_slip:
        notes.append("no slip state up to a tangential increment of "
                     f"{probe.dv_slip:.3g}")
    return ("; ".join(notes) + ": " if notes else "") + all_within(measures)


def _contact_chained(law, probe: _ContactProbe) -> str:
    from ..laws.contact_point import drive_contact_point as drive
    dv = probe.dv_slip
    u_path = np.array([_D0, 1.2 * _D0, 1.3 * _D0, 1.25 * _D0])
    v_path = np.array([0.0, 0.5 * dv, 6 * dv, 5.7 * dv])          # stick, into slip, back
    n = 3
    res = drive(law, u_path, v_path, substeps=n, tangent=True)
    sc = probe.scales
    measures = []
    for i in range(1, len(u_path)):
        for key, path, other, h, scale in (("dtau_du", u_path, v_path, 1e-6 * _D0, _D0),
                                           ("dtau_dv", v_path, u_path, 1e-6 * dv, dv)):
            plus, minus = path[:i + 1].copy(), path[:i + 1].copy()
            plus[i] += h
            minus[i] -= h
            if key == "dtau_du":
                tp = drive(law, plus, other[:i + 1], substeps=n)["tau"][-1]
                tm = drive(law, minus, other[:i + 1], substeps=n)["tau"][-1]
            else:
                tp = drive(law, other[:i + 1], plus, substeps=n)["tau"][-1]
                tm = drive(law, other[:i + 1], minus, substeps=n)["tau"][-1]
            fd = (tp - tm) / (2 * h)
            measures.append((f"interval {i}: |{key} - central difference| x input scale / "
                             f"tau scale", abs(res[key][i] - fd) * scale / sc["tau"], 1e-5))
    return (f"{len(u_path) - 1} intervals of {n} sub-intervals (stick, into slip, back), the "
            f"derivatives of tau chained as contact_point.drive does: " + all_within(measures))


def _contact_state(law, probe: _ContactProbe) -> str:
    from ..core.status import OPEN, STATUS_NAMES
    from ..laws.base import ContactLaw
    st = law.init_state(3)
    missing = [k for k in ContactLaw.STATE_KEYS if k not in st]
    require(not missing, f"init_state lacks {', '.join(missing)}")
    shapes = {k: np.shape(st[k]) for k in ContactLaw.STATE_KEYS if np.shape(st[k]) != (3,)}
    require(not shapes, f"init_state(3) arrays must be (3,): {shapes}")
    require(np.all(np.asarray(st["status"]) == OPEN) and not np.any(st["p"]),
            "init_state must be open (status OPEN, p = 0)")
    problems, statuses = [], []
    for p in probe.points:
        new, tan = _cupdate(law, p.state, p.d, p.du, p.dv)
        miss = [k for k in ContactLaw.STATE_KEYS if k not in new]
        bad_shape = [k for k in ContactLaw.STATE_KEYS if k in new and np.shape(new[k]) != (1,)]
        bad_tan = [k for k, v in tan.items() if np.shape(v) not in ((1,), ())]
        status = np.asarray(new.get("status", [99]))
        if miss or bad_shape or bad_tan:
            problems.append(f"{p.label}: missing {miss}, not (g,): {bad_shape + bad_tan}")
            continue
        if status.dtype.kind not in "iu" or int(status[0]) not in range(len(STATUS_NAMES)):
            problems.append(f"{p.label}: status {status!r} is not an int code OPEN/STICK/SLIP")
            continue
        if p.status is not None and int(status[0]) != p.status:
            problems.append(f"{p.label}: status {STATUS_NAMES[int(status[0])]}, expected "
                            f"{STATUS_NAMES[p.status]}")
        if float(new["p"][0]) < 0:
            problems.append(f"{p.label}: p = {float(new['p'][0]):.3g} < 0")
        statuses.append(f"{p.label} {STATUS_NAMES[int(status[0])]}")
    # a batch answers as its points one by one
    batch = {k: np.concatenate([np.asarray(p.state[k]) for p in probe.points])
             for k in ContactLaw.STATE_KEYS}
    pts = probe.points
    bnew, _ = law.update(batch, np.array([p.d for p in pts]), np.array([p.du for p in pts]),
                         np.array([p.dv for p in pts]))
    diff = 0.0
    for j, p in enumerate(probe.points):
        one, _ = _cupdate(law, p.state, p.d, p.du, p.dv)
        for k in ("p", "tau", "lam"):
            diff = max(diff, abs(float(bnew[k][j]) - float(one[k][0]))
                       / probe.scales[k])
    require(not problems, "; ".join(problems))
    return f"{'; '.join(statuses)}; " + within("batch vs point by point, max difference / scale",
                                               diff, 1e-12)


def _contact_state_unchanged(law, probe: _ContactProbe) -> str:
    from ..core.status import OPEN, STICK
    changed = []
    for p in probe.points:
        for frozen in (None, STICK, OPEN):
            before = copy.deepcopy(p.state)
            _cupdate(law, p.state, p.d, p.du, p.dv, frozen)
            keys = changed_keys(before, p.state)
            if keys:
                changed.append(f"{p.label} (frozen {frozen}): {', '.join(keys)}")
                p.state.clear()
                p.state.update(before)
    require(not changed, "update() modified the committed state: " + "; ".join(changed))
    return f"the committed state is unchanged after update() at {len(probe.points)} points, " \
           f"free and frozen"


def _contact_admissible(law, probe: _ContactProbe) -> str:
    dv = probe.dv_slip
    # close, slide on, slide back, separate, re-close sliding: the law's own path
    path = [(_D0, 0.0), (1.2 * _D0, 3 * dv), (1.2 * _D0, 8 * dv), (1.1 * _D0, -4 * dv),
            (0.8 * _D0, -10 * dv), (-0.5 * _D0, -11 * dv), (0.6 * _D0, -6 * dv),
            (0.9 * _D0, 2 * dv)]
    state = law.init_state(1)
    d_old, v_old, flagged = 0.0, 0.0, []
    for k, (d, v) in enumerate(path):
        state, _ = _cupdate(law, state, d, d - d_old, v - v_old)
        if np.any(law.inadmissible(state)):
            flagged.append(f"point {k} (d {d:.3g}, v {v:.3g}: p {float(state['p'][0]):.4g}, "
                           f"tau {float(state['tau'][0]):.4g})")
        d_old, v_old = d, v
    for p in probe.points:
        new, _ = _cupdate(law, p.state, p.d, p.du, p.dv)
        if np.any(law.inadmissible(new)):
            flagged.append(p.label)
    require(not flagged, "inadmissible() flags states the law itself produced: "
            + "; ".join(flagged))
    return f"inadmissible() is empty at the {len(path)} points of a closing, sliding, " \
           f"reversing, separating, re-closing path and at {len(probe.points)} sub-intervals"


def _contact_frozen(law, probe: _ContactProbe) -> str:
    from ..core.status import OPEN, STICK
    measures = []
    closed = probe.closed
    # -1 frees every point: the same as no frozen array
    for p in probe.points:
        a, _ = _cupdate(law, p.state, p.d, p.du, p.dv)
        b, _ = _cupdate(law, p.state, p.d, p.du, p.dv, -1)
        keys = changed_keys({k: a[k] for k in ("p", "tau", "lam", "status")},
                            {k: b[k] for k in ("p", "tau", "lam", "status")})
        require(not keys, f"{p.label}: frozen -1 differs from no frozen array in {keys}")
    # OPEN: no contact, the history kept
    src, d = (probe.slip_state, 1.1 * _D0) if probe.has_slip else (closed, _D0)
    held, _ = _cupdate(law, src, d + 0.1 * _D0, 0.1 * _D0, probe.dv_slip, OPEN)
    require(int(held["status"][0]) == OPEN and float(held["p"][0]) == 0.0
            and float(held["tau"][0]) == 0.0,
            f"frozen OPEN at d > 0 gives status {int(held['status'][0])}, p "
            f"{float(held['p'][0]):.4g}, tau {float(held['tau'][0]):.4g} (want OPEN, 0, 0)")
    kept = max(abs(float(held[k][0]) - float(src[k][0])) for k in ("lam", "slip", "dissip"))
    measures.append(("frozen OPEN at d > 0: p = tau = 0, OPEN; max |change of lam, slip, "
                     "dissip|", kept, 0.0))
    if probe.has_stick and probe.has_slip:
        # STICK: elastic even beyond the cone, with the stick stiffness measured free
        small, _ = _cupdate(law, closed, 1.1 * _D0, 0.1 * _D0, 0.25 * probe.dv_slip)
        kt = (float(small["tau"][0]) - float(closed["tau"][0])) / (0.25 * probe.dv_slip)
        big, _ = _cupdate(law, closed, 1.1 * _D0, 0.1 * _D0, 4 * probe.dv_slip, STICK)
        want = float(closed["tau"][0]) + kt * 4 * probe.dv_slip
        require(int(big["status"][0]) == STICK, f"frozen STICK gives status "
                f"{int(big['status'][0])}")
        measures.append(("frozen STICK beyond the cone: |tau - (tau0 + k_stick dv)| / |tau|",
                         abs(float(big["tau"][0]) - want) / abs(want), 1e-10))
        measures.append(("and |lam - lam0|", abs(float(big["lam"][0]) - float(closed["lam"][0])),
                         0.0))
    return all_within(measures)


def _contact_energy(law, probe: _ContactProbe) -> str:
    from .findings import Skip
    try:
        stored0 = float(np.asarray(law.stored_energy(probe.closed)).ravel()[0])
    except NotImplementedError as exc:
        raise Skip(f"{exc}: the energy balance (*CHECK, TYPE=ENERGY) cannot use it") from None
    st = law.init_state(1)
    d = 0.0
    work = friction = peak = gap = 0.0
    stored_start = float(np.asarray(law.stored_energy(st)).ravel()[0])
    steps = [(_D0 / 20, 0.0)] * 20                                    # press to d0
    steps += [(0.0, probe.dv_slip / 5)] * 40 + [(0.0, -probe.dv_slip / 5)] * 80  # slide, back
    steps += [(_D0 / 40, probe.dv_slip / 10)] * 20                    # press while sliding
    for du, dv in steps:
        d += du
        new, _ = _cupdate(law, st, d, du, dv)
        p0, p1 = float(st["p"][0]), float(new["p"][0])
        t0, t1 = float(st["tau"][0]), float(new["tau"][0])
        work += 0.5 * (p0 + p1) * du + 0.5 * (t0 + t1) * dv
        friction += 0.5 * (t0 + t1) * (float(new["vp"][0]) - float(st["vp"][0]))
        stored = float(np.asarray(law.stored_energy(new)).ravel()[0])
        peak = max(peak, abs(work))
        gap = max(gap, abs(work - (stored - stored_start) - friction))
        st = new
    require(stored0 >= 0.0, f"stored_energy of a closed point is {stored0:.3g} < 0")
    return within(f"press, slide both ways ({len(steps)} sub-intervals; at the end work "
                  f"{work:.4g}, friction {friction:.4g}): max |work - (stored + friction)| / max "
                  f"|work|", gap / max(peak, 1e-300), 1e-6)


def check_contact_law(cls) -> list[Finding]:
    """The contact-law contract (:class:`~lagamine_py.laws.base.ContactLaw`) on ``cls``."""
    s = Suite(CONTACT_ITEMS)
    law = s.build(cls)
    if law is None:
        return s.blocked("the law could not be built from example_values()")
    try:
        probe = _contact_probe(law)
    except ContractFailure as exc:
        return s.blocked(f"probing the law: {exc}")
    except Exception as exc:
        return s.blocked(f"probing the law raised {type(exc).__name__}: {exc}")
    s.run("state and status", _contact_state, law, probe)
    s.run("tangent entries", _contact_tangent, law, probe)
    s.run("tangent chained", _contact_chained, law, probe)
    s.run("state unchanged", _contact_state_unchanged, law, probe)
    s.run("admissible path", _contact_admissible, law, probe)
    s.run("frozen holds", _contact_frozen, law, probe)
    s.run("energy", _contact_energy, law, probe)
    return s.findings
