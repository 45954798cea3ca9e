"""Mutation study of the kernel twin test: can ``tests/test_kernel_twins.py`` fail?

Each mutation below breaks one branch of a numba kernel (``lagamine_py/kernels/solid.py``,
``lagamine_py/kernels/contact.py``) -- or, to show that the comparison is two-sided, of a NumPy
reference -- by replacing one exact piece of source text.  The tool applies them one at a time,
runs ``pytest -x -q tests/test_kernel_twins.py tests/test_solid_lanes.py
tests/test_ro_return_map.py tests/test_solid_threads.py`` (the second: the solid kernel's
blocks of several ``LANES`` elements and a remainder; the third: the Ramberg-Osgood return map
against closed forms, where a mutant that changes the iterations but not the answers beyond the
twins' tolerance is caught; the fourth: its element ranges on threads; numba recompiles the
mutated module: its cache is keyed on the source file's time stamp), always restores the file
(also on an error or Ctrl-C), and prints a table: the mutation and the test that caught it, or
SURVIVED.

Every mutation must be caught.  A control (``equivalent`` set) changes the code but not what it
computes; it must survive, which shows that a survivor would be reported.

Run it offline (each run compiles a kernel module, 10-30 s; the whole list takes about 25
minutes on 2 cores; the last full run: 112 mutations, the 106 mutants caught, the 6 controls
survived; the 7 mutations of a rigid tool and the stabilisation, added since, were run with
``-k tool -k stabilisation -k "turned chain"``: all caught; after the merge of the tools, ``-k cap
-k outside-the-cone -k exponential -k table``: the 16 mutants caught, the uncapped outside check
made a control, see its reason)::

    python tools/kernel_mutations.py              # all
    python tools/kernel_mutations.py -k hoop      # the mutations whose name contains "hoop"
    python tools/kernel_mutations.py --list

The numba cache of the runs goes to a temporary directory (``NUMBA_CACHE_DIR``), and the
restored file gets its time stamp back, so the checkout's own cache stays valid.
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEST = "tests/test_kernel_twins.py"
#: the Ramberg-Osgood return map point by point against closed forms (kernel and NumPy law)
LAW_TEST = "tests/test_ro_return_map.py"
#: the solid kernel's blocks of several LANES elements and a remainder, run after TEST
LANES_TEST = "tests/test_solid_lanes.py"
#: the solid kernel on element ranges, one thread each, against one thread byte for byte
THREADS_TEST = "tests/test_solid_threads.py"
SOLID = "lagamine_py/kernels/solid.py"
CONTACT = "lagamine_py/kernels/contact.py"


@dataclass(frozen=True)
class Mutation:
    name: str
    path: str            # relative to the repository
    old: str             # exact source text, found exactly once in the file
    new: str
    equivalent: str = ""  # a control: why it computes the same (it must survive)


M = Mutation
MUTATIONS = [
    # -- kernels/solid.py: laws --------------------------------------------------------------
    M("solid: ELASTIC stress from the wrong strain component", SOLID,
      "acc += eps[t] * Del[s, t]", "acc += eps[s] * Del[s, t]"),
    M("solid: J2 hardening H dropped from the return", SOLID,
      "dp = (q_tr - sy_n) / (G3 + H)", "dp = (q_tr - sy_n) / G3"),
    M("solid: J2 consistent tangent dq/dq_tr = 1", SOLID,
      "q, peeq, dq = q_tr - G3 * dp, peeq_n + dp, H / (G3 + H)",
      "q, peeq, dq = q_tr - G3 * dp, peeq_n + dp, 1.0"),
    M("solid: plastic flag margin YIELD_RTOL dropped", SOLID,
      "plastic = q_tr > sy_n * (1.0 + YIELD_RTOL)", "plastic = q_tr > sy_n"),
    M("solid: plastic flag margin's sign", SOLID,
      "plastic = q_tr > sy_n * (1.0 + YIELD_RTOL)", "plastic = q_tr > sy_n * (1.0 - YIELD_RTOL)"),
    M("solid: consistent tangent's n x n term dropped", SOLID,
      "a_dev, b_nn = G2 * theta, G2 * (dq - theta)", "a_dev, b_nn = G2 * theta, 0.0"),
    M("solid: plastic elastic strain's shear factor 2 dropped", SOLID,
      "eps_e[3] = 2.0 * (sv3 / G2)", "eps_e[3] = sv3 / G2"),
    M("solid: non-finite stress not a failure", SOLID,
      "        if not math.isfinite(stress[s]):\n            ok = False",
      "        if False:\n            ok = False"),
    M("solid: RO branch swap (ln q <-> ln P)", SOLID,
      "    if by_q:\n        x_star, ln_qt = math.log(q_star), math.log(qt)",
      "    if not by_q:\n        x_star, ln_qt = math.log(q_star), math.log(qt)"),
    M("solid: RO branch choice without the residual test", SOLID,
      "by_q = a + n * x_star - y_hi >= 0.0", "by_q = False"),
    M("solid: RO branch choice's q* < q_tr test reversed", SOLID,
      "if q_star < qt and p_star > 0.0:", "if q_star > qt and p_star > 0.0:"),
    M("solid: RO residual in ln q, sign of ln P", SOLID,
      "g = a + n * x - math.log(P)", "g = a + n * x + math.log(P)"),
    M("solid: RO residual in ln P, sign of a", SOLID,
      "g = x - a - n * math.log(q)", "g = x + a - n * math.log(q)"),
    M("solid: RO Newton step in ln P without its n 3G P / q", SOLID,
      "return g, g * q / (q + n * G3 * P), P", "return g, g * q / (q + G3 * P), P"),
    M("solid: RO Newton step in ln q without its q / 3G P", SOLID,
      "return g, g * (G3 * P) / (n * (G3 * P) + q), q", "return g, g * (G3 * P) / (n * (G3 * P)), q"),
    M("solid: RO bracket upper end from q_tr only", SOLID,
      "hi = _nmin(ln_qt, _ro_log_yield(pn + qt / G3, a, n))",
      "hi = _nmax(ln_qt, _ro_log_yield(pn + qt / G3, a, n))"),
    M("solid: RO ln P's start without the bound ln peeq(q_tr)", SOLID,
      "y_hi = _nmin(y_hi, a + n * math.log(qt))", "y_hi = y_hi"),
    M("control: RO bracket of ln P, lower end lowered", SOLID,
      "y_lo = _nmax(ln_pn, a + n * x_star)", "y_lo = _nmin(ln_pn, a + n * x_star)",
      equivalent="Newton from the upper end of a convex increasing residual decreases "
                 "monotonically to the root: it never reaches the lower end"),
    M("solid: RO virgin points (peeq = 0) never yield", SOLID,
      "sy_n = math.exp((ln_pn - lp[_A]) / lp[_N])",
      "sy_n = math.exp((ln_pn - lp[_A]) / lp[_N]) if peeq_n > 0.0 else math.inf"),
    M("solid: RO Newton never converges by its step", SOLID,
      "if newton and (abs(step) <= tol or quad * step * step <= tol or g == 0.0):",
      "if False:"),
    M("solid: RO Newton stops by the step alone (the quadratic bound dropped)", SOLID,
      "if newton and (abs(step) <= tol or quad * step * step <= tol or g == 0.0):",
      "if newton and (abs(step) <= tol or g == 0.0):"),
    M("solid: RO quadratic stop 1e6 times too loose in ln P", SOLID,
      "tol, QUAD_Y, max_iter", "tol, 1e-6 * QUAD_Y, max_iter"),
    M("solid: RO answer's exp by the Taylor factor's wrong sign", SOLID,
      "return x_newton, ex * (1.0 - step + 0.5 * step * step), True",
      "return x_newton, ex * (1.0 + step + 0.5 * step * step), True"),
    M("control: RO answer's exp without the Taylor factor's d^2 / 2", SOLID,
      "return x_newton, ex * (1.0 - step + 0.5 * step * step), True",
      "return x_newton, ex * (1.0 - step), True",
      equivalent="d^2/2 <= tol / (2 quad) <= tol / 4 where the quadratic rule stops: within "
                 "the law's tolerance; the tests assert the answers to 2e-13"),
    M("solid: RO bisection fallback dropped", SOLID,
      "x_new = x_newton if newton else 0.5 * (lo + hi)", "x_new = x_newton"),
    M("solid: RO tangent dq/dq_tr without peeq", SOLID,
      "return q, peeq, q / (q + G3 * n * peeq), ok", "return q, peeq, q / (q + G3 * n), ok"),
    M("solid: plastic elastic strain without its volume part", SOLID,
      "eps_e[0], eps_e[1], eps_e[2] = third + sv0 / G2, third + sv1 / G2, third + sv2 / G2",
      "eps_e[0], eps_e[1], eps_e[2] = sv0 / G2, sv1 / G2, sv2 / G2"),
    M("solid: plastic tangent's bulk part dropped", SOLID,
      "D[s, t] = K + a_dev * dev + b_nn * ns * nt", "D[s, t] = a_dev * dev + b_nn * ns * nt"),
    # -- kernels/solid.py: kinematics, failures, scatter --------------------------------------
    M("solid: det F <= 0 failure flag skipped", SOLID,
      "flags[e] = BAD_DET_F", "flags[e] = OK"),
    M("solid: det F_old <= 0 (start of increment) ignored", SOLID,
      "bad = bad_old[e] != 0", "bad = False"),
    M("solid: F33 <= 0 (r <= 0) not checked", SOLID,
      "bad |= (det <= 0.0) or (Fq[o + 4 * _L] <= 0.0)", "bad |= (det <= 0.0)"),
    M("solid: return mapping failure not flagged", SOLID,
      "flags[e] = RETURN_MAP_FAILED", "flags[e] = OK"),
    M("solid: axisymmetric hoop strain dropped (small strain)", SOLID,
      "g[2 * _L + l] = na / v[_R0 + l] if axisym else 0.0", "g[2 * _L + l] = 0.0"),
    M("solid: hoop row dropped under NLGEOM", SOLID,
      "g[2 * _L + l] = na / Fp[5 * _L + l] if axisym else 0.0", "g[2 * _L + l] = 0.0"),
    M("solid: hoop stress dropped from the force", SOLID,
      "fa[l] += x0 * t0 + h * t2 + x1 * t3", "fa[l] += x0 * t0 + x1 * t3"),
    M("solid: F33 = 1 in axisymmetry", SOLID,
      "Fp[4 * _L + l] = Fp[5 * _L + l] / R0[el[l], q]", "Fp[4 * _L + l] = 1.0"),
    M("start: F33_old = 1 in axisymmetry", SOLID,
      "F33[q] = r[q] / R0[e, q]", "F33[q] = 1.0"),
    M("solid: b33 = f33 b33_n (square dropped)", SOLID,
      "= f33 ** 2 * bn33", "= f33 * bn33"),
    M("solid: relative f33 without F33_old", SOLID,
      "f33 = Fp[4 * _L + l] / v[_OLD + 4 * _L + l]", "f33 = Fp[4 * _L + l]"),
    M("solid: NLGEOM material tangent's hoop row dropped", SOLID,
      "m[2 * _L + l] = g[2 * _L + l]", "m[2 * _L + l] = 0.0"),
    M("solid: Cauchy stress with J = det of the in-plane F", SOLID,
      "J = det2 * Fp[4 * _L + l]", "J = det2"),
    M("solid: geometric tangent dropped", SOLID,
      "wt00, wt11, wt01 = t0, t1, t3", "wt00, wt11, wt01 = 0.0, 0.0, 0.0"),
    M("solid: axisymmetric geometric tangent tau33 / r^2 dropped", SOLID,
      "cax = t2 / (r * r)", "cax = 0.0"),
    M("solid: 2x2-rule weights all taken from the first point", SOLID,
      "v[_W + l] = w0[el[l], q]", "v[_W + l] = w0[el[l], q] if nq != 4 else w0[el[l], 0]"),
    M("solid: Daleckii-Krein divided difference without 1/x", SOLID,
      "ratio = math.atanh(_nmin(xr, 1 - 1e-16)) / xr", "ratio = math.atanh(_nmin(xr, 1 - 1e-16))"),
    M("solid: Daleckii-Krein equal-stretch limit wrong", SOLID,
      "ratio = 1.0 + xr * xr / 3.0", "ratio = 0.5 + xr * xr / 3.0"),
    M("solid: eigenvector angle's sign", SOLID,
      "return m + rho, m - rho, h / rho, c / rho", "return m + rho, m - rho, h / rho, -c / rho"),
    M("control: tangent scattered transposed", SOLID,
      "return ((d2 // 2 * nen + d // 2) * 4 + 2 * (d % 2) + d2 % 2) * _L + l",
      "return ((d // 2 * nen + d2 // 2) * 4 + 2 * (d2 % 2) + d % 2) * _L + l",
      equivalent="every element tangent of these laws is symmetric (Hencky hyperelasticity, "
                 "J2's associative radial return: the derivative of a potential's gradient)"),
    M("solid: global force overwritten, not added", SOLID,
      "f_out[dofs[e, d]] += fl[d * _L + l]", "f_out[dofs[e, d]] = fl[d * _L + l]"),
    # -- kernels/solid.py: the blocks of LANES elements (tests/test_solid_lanes.py: groups of
    # several blocks and a remainder) -------------------------------------------------------
    M("lanes: every block reads the first block's elements", SOLID,
      "el[l] = e0 + min(l, n - 1)", "el[l] = min(l, n - 1)"),
    M("lanes: the spare lanes of the remainder block scattered", SOLID,
      "    for l in range(n):\n        if flags[el[l]] != BAD_DET_F:\n            _scatter_element(",
      "    for l in range(_L):\n        if flags[el[l]] != BAD_DET_F:\n            _scatter_element("),
    M("lanes: the law run in a BAD_DET_F lane", SOLID,
      "        if flags[e] == BAD_DET_F:\n            continue\n        # 1/2 ln b",
      "        # 1/2 ln b"),
    M("lanes: a lane's element force from the next lane", SOLID,
      "fe[e, d] = fl[d * _L + l]", "fe[e, d] = fl[d * _L + min(l + 1, _L - 1)]"),
    M("start: F_old^-1 off-diagonal sign", SOLID,
      "old[e, q, 0], old[e, q, 1] = F[q, 1, 1] * s, -F[q, 0, 1] * s",
      "old[e, q, 0], old[e, q, 1] = F[q, 1, 1] * s, F[q, 0, 1] * s"),
    M("start: b_e_n33 = exp(eps33) (factor 2 dropped)", SOLID,
      "old[e, q, 8] = math.exp(2.0 * eps_e_n[e, q, 2])",
      "old[e, q, 8] = math.exp(eps_e_n[e, q, 2])"),
    M("start: F33_old = 1", SOLID,
      "old[e, q, 4] = F33[q]", "old[e, q, 4] = 1.0"),
    M("start: F33_old <= 0 not flagged", SOLID,
      "            bad |= (det <= 0.0) or (F33[q] <= 0.0)\n            s = 1.0",
      "            bad |= (det <= 0.0)\n            s = 1.0"),
    M("start: b_e_n off-diagonal from cos instead of sin", SOLID,
      "old[e, q, 6] = 0.5 * (x0 - x1) * sn", "old[e, q, 6] = 0.5 * (x0 - x1) * cs"),
    M("control: double eigenvalue's axes (any basis is one)", SOLID,
      "return m, m, 1.0, 0.0", "return m, m, 0.0, 1.0",
      equivalent="at a double eigenvalue P0 + P1 = I and P0xP0 + P1xP1 + SxS/2 is the "
                 "symmetric identity whatever the axes: same b_e_n, E and tangent"),
    # -- kernels/solid.py: element ranges on threads (caught by THREADS_TEST) ----------------
    M("solid split: no deferral (a later range sums shared entries straight in)", SOLID,
      "deferring = brow.shape[0] > 0", "deferring = False"),
    M("solid split: a deferred tangent contribution dropped", SOLID,
      "kbuf[-t - 1] = Ke[_ke_at(d, d2, nen, l)]", "kbuf[-t - 1] = 0.0"),
    M("solid split: a deferred force summed straight in", SOLID,
      "fbuf[-t - 1] = x", "f_out[dofs[e, d]] += x"),
    M("solid split: the earlier ranges' tangent entries not marked shared", SOLID,
      "seen_k[p] = True", "seen_k[p] = False"),
    M("solid split: the deferred waves added last first", SOLID,
      "for slots, element, target in waves:", "for slots, element, target in waves[::-1]:"),
    M("solid split: a BAD_DET_F element's stale slots added", SOLID,
      "ok = flags[element] != BAD_DET_F", "ok = flags[element] >= OK"),
    # -- kernels/contact.py: the Coulomb point ------------------------------------------------
    M("contact: Coulomb return's hardening term dropped", CONTACT,
      "step = resid / (kt + h)", "step = resid / kt"),
    M("contact: loading indicator's pressure term sign", CONTACT,
      "indicator = sig0 * dte - rho_rate", "indicator = sig0 * dte + rho_rate"),
    M("contact: loading iff indicator < 0", CONTACT,
      "loading_on = on and ((indicator > 0.0) or ((indicator == 0.0) and pos_tr))",
      "loading_on = on and ((indicator < 0.0) or ((indicator == 0.0) and pos_tr))"),
    M("contact: neutral loading without f_tr > 0", CONTACT,
      "((indicator == 0.0) and pos_tr))", "(indicator == 0.0))"),
    M("contact: CLASSICAL indicator = predictor's", CONTACT,
      "indicator = h0 * indicator / (h0 + kt)", "indicator = indicator"),
    M("contact: on-the-surface tolerance's sign", CONTACT,
      "on = active and (f0 >= -_ON_SURFACE_RTOL * (radius0 + abs_tau0))",
      "on = active and (f0 >= _ON_SURFACE_RTOL * (radius0 + abs_tau0))"),
    M("contact: contact at d > 0 only (touching open)", CONTACT,
      "contact = (dg >= 0.0) and closable", "contact = (dg > 0.0) and closable"),
    M("contact: re-contact fraction skipped", CONTACT,
      "frac = dg / dug", "frac = 1.0"),
    M("contact: separation fraction skipped", CONTACT,
      "frac = d_old / (d_old - dg)", "frac = 1.0"),
    M("contact: separation without p_old > 0", CONTACT,
      "sep = (not contact) and (po > 0.0) and (d_old > 0.0)",
      "sep = (not contact) and (d_old > 0.0)"),
    M("contact: re-contact starts from the old p", CONTACT,
      "p0 = 0.0 if recon else po", "p0 = po"),
    M("control: direction at tau0 = 0 not taken from dv", CONTACT,
      "sig0 = 1.0 if dte >= 0.0 else -1.0", "sig0 = 1.0",
      equivalent="a point on the surface with tau0 = 0 sits at the cone's tip: for dv < 0 the "
                 "test 'through the cone' (sig != sig0) makes it plastic exactly when the "
                 "indicator would (f_tr > 0 iff the indicator > 0 there); they differ only "
                 "at an indicator of exactly 0 under CLASSICAL"),
    M("contact: reversal through the cone not plastic", CONTACT,
      "((not on) or (sig != sig0))", "(not on)"),
    M("contact: tangent's return modulus without H", CONTACT,
      "        dmat = kt + h\n        lam = lam + step", "        dmat = kt\n        lam = lam + step"),
    M("contact: tangent's phi at the start of the return", CONTACT,
      "        _, _, phi1, _ = _hardening(lv, lam)\n        return lam, dmat, phi1, bad",
      "        _, _, phi1, _ = _hardening(lv, lam0)\n        return lam, dmat, phi1, bad"),
    M("contact: re-contact starts from the old tau", CONTACT,
      "tau0 = 0.0 if recon else tau_old", "tau0 = tau_old"),
    M("contact: softening kink walk dropped", CONTACT,
      "if step > 0.0 and lam + step > ahead:", "if False:"),
    M("contact: slope kept beyond a clipping kink", CONTACT,
      "return _nmax(v0 + slope * lam, 0.0), (slope if lam < lv[base + 3] else 0.0)",
      "return _nmax(v0 + slope * lam, 0.0), slope"),
    M("contact: STICK hold ignored", CONTACT,
      "    if h_g == STICK:\n        plastic = False", "    if False:\n        plastic = False"),
    M("contact: SLIP hold ignored", CONTACT,
      "    elif h_g == SLIP:\n        plastic = contact",
      "    elif False:\n        plastic = contact"),
    M("contact: SLIP hold's dlam clipped at 0", CONTACT,
      "if predictor and h_g != SLIP:", "if predictor:"),
    M("contact: OPEN hold lets the point close", CONTACT,
      "closable = h_g != OPEN", "closable = True"),
    M("control: OPEN hold's history kept by the group only", CONTACT,
      "np_, ntau, nlam, nslip, nvp, ndis, nstat = (0.0, 0.0, slam, sslip, svp,\n"
      "                                                                sdis, OPEN)",
      "np_, ntau, nstat = 0.0, 0.0, OPEN",
      equivalent="the Coulomb point already keeps lam, slip and dissip of a point held OPEN "
                 "(never active): the group's override restates them"),
    M("contact: snap-back not reported", CONTACT,
      "return lam, dmat, lv[_SNAP] != 0.0 and dmat <= 0.0", "return lam, dmat, False"),
    M("contact: dissipation without the pressure change", CONTACT,
      "    return b + phi * (p0 + dp * s)", "    return b + phi * p0"),
    M("contact: dissipation's pieces after the first kink dropped", CONTACT,
      "for piece in range(nb + 1):", "for piece in range(1):"),
    M("contact: tangent's d lam / d p1 term dropped", CONTACT,
      "lam_d = act * (lam_tr * dtr_d + lam_p1 * kpc)", "lam_d = act * (lam_tr * dtr_d)"),
    M("contact: tangent tau_lam's sign", CONTACT,
      "tan[9] = c * (-skt * (lam_lam - 1.0) if plastic else 0.0)",
      "tan[9] = c * (skt * (lam_lam - 1.0) if plastic else 0.0)"),
    M("contact: tangent of the re-contact fraction dropped", CONTACT,
      "        frac_d = 1.0 / dug\n        frac_du = -frac / dug",
      "        frac_d = 0.0\n        frac_du = 0.0"),
    M("control: tangent of the separation fraction dropped", CONTACT,
      "        frac_d = -1.0 / dug\n        frac_du = (1.0 - frac) / dug",
      "        frac_d = 0.0\n        frac_du = 0.0",
      equivalent="it reaches only D lam of the separating point, which stays open for the "
                 "rest of the increment (d moves linearly): no force or tangent sees it"),
    # -- kernels/contact.py: the hardening forms and TAUMAX -----------------------------------
    M("contact: exponential form's slope sign", CONTACT,
      "return v_inf + dv * e, (-dv / c) * e", "return v_inf + dv * e, (dv / c) * e"),
    M("contact: exponential form's value from v0", CONTACT,
      "return v_inf + dv * e, (-dv / c) * e", "return v0 + dv * e, (-dv / c) * e"),
    M("contact: table slope of the next segment", CONTACT,
      "    slope = lv[values + nt + k]\n", "    slope = lv[values + nt + min(k + 1, nt - 1)]\n"),
    M("contact: table never enters its last (flat) segment", CONTACT,
      "while k + 1 < nt and lv[x0 + k + 1] <= lam:", "while k + 2 < nt and lv[x0 + k + 1] <= lam:"),
    M("contact: exponential piece, crossing to the next piece skipped", CONTACT,
      "                if r_ahead > 0.0:             # the root lies beyond this piece",
      "                if False:"),
    M("contact: Newton's slope without the pressure term", CONTACT,
      "return abs_tr - kt * (x - lam0) - b - phi * p1, kt + hb + hphi * p1",
      "return abs_tr - kt * (x - lam0) - b - phi * p1, kt + hb"),
    M("contact: Newton's residual without the adhesion", CONTACT,
      "return abs_tr - kt * (x - lam0) - b - phi * p1, kt + hb + hphi * p1",
      "return abs_tr - kt * (x - lam0) - phi * p1, kt + hb + hphi * p1"),
    M("control: Newton's bisection safeguard dropped", CONTACT,
      "        if math.isfinite(lo) and math.isfinite(hi) and not (xn > lo and xn < hi):",
      "        if False:",
      equivalent="the residual is monotone and smooth on the piece and Newton converges to its "
                 "one root from every start the batches give; the safeguard changes the "
                 "iterates, not the root (it is there for a start the batches do not reach)"),
    M("contact: Newton stops after one step", CONTACT,
      "        conv = (r == 0.0) or (abs(xn - x) <= _RETURN_XTOL * (abs(x) + abs(x - lam0)))",
      "        conv = True"),
    M("contact: TAUMAX ignored in the return", CONTACT,
      "    if lam_c > lam_u:                         # on the cap", "    if False:"),
    M("contact: on the cap, the return modulus keeps H", CONTACT,
      "        return lam_c, lv[_KT], 0.0, False", "        return lam_c, dmat, 0.0, False"),
    M("contact: on the cap, the tangent keeps d rho / d p", CONTACT,
      "        return lam_c, lv[_KT], 0.0, False", "        return lam_c, lv[_KT], phi0, False"),
    M("contact: trial radius not capped", CONTACT,
      "f_tr = abs(tau_tr) - _nmin(b0 + phi0 * p1, cap)", "f_tr = abs(tau_tr) - (b0 + phi0 * p1)"),
    M("contact: radius at the start not capped", CONTACT,
      "        radius0 = _nmin(u0, cap)", "        radius0 = u0"),
    M("contact: indicator's pressure rate kept on the cap", CONTACT,
      "        elif u0 > cap:\n            rho_rate = 0.0", "        elif False:\n            rho_rate = 0.0"),
    M("contact: at the cap exactly, the pressure rate two-sided", CONTACT,
      "            rho_rate = _nmin(rho_rate, 0.0)", "            rho_rate = rho_rate"),
    M("contact: CLASSICAL keeps H on the cap", CONTACT,
      "        if capped_law and not u0 < cap:\n            h0 = 0.0",
      "        if False:\n            h0 = 0.0"),
    M("contact: dissipation integrand not capped", CONTACT,
      "acc += _nmin(_path_u(lv, lam, tau0, p0, dp, dte, lam0, sig), cap) * _GL_W[k]",
      "acc += _path_u(lv, lam, tau0, p0, dp, dte, lam0, sig) * _GL_W[k]"),
    M("contact: dissipation not cut where the cap takes over", CONTACT,
      "    if oa != oc:", "    if False:"),
    M("contact: dissipation on one panel whatever the slide", CONTACT,
      "            if n != n:                        # NaN (a NaN state): one panel, NaN as NumPy",
      "            n = 1.0\n            if n != n:"),
    M("contact: outside-the-cone check with the uncapped radius", CONTACT,
      "    radius = _nmin(b + phi * p, lv[_TAUMAX])", "    radius = b + phi * p",
      equivalent="the check differs only for a point ending with TAUMAX < |tau| <= B + phi p "
                 "that is not held STICK (held STICK points are not failures); the exact "
                 "integration ends free and SLIP-held points on the capped cone; the one law "
                 "that leaves the cone, CLASSICAL under softening, leaves it by an elastic step "
                 "from the surface below the cap (on the cap its indicator is 0: plastic) where "
                 "KT dv > phi dp, so |tau_tr| - (B + phi p1) = KT dv - phi dp > 0: beyond the "
                 "uncapped radius too"),
    # -- kernels/contact.py: the group: sub-intervals, axes, forces, failures -----------------
    M("contact: sub-interval Ddv scaling dropped", CONTACT,
      "Ddv[J] /= nsub", "Ddv[J] /= 1"),
    M("contact: THETA ignored in the axes", CONTACT,
      "a_th = (k - 1 + theta) / nsub", "a_th = k / nsub"),
    M("contact: turning axes' dv derivative not scaled", CONTACT,
      "Ddv[2 * a + i] += turn if a_th == 1.0 else a_th * turn", "Ddv[2 * a + i] += turn"),
    M("contact: penetration not interpolated over sub-intervals", CONTACT,
      "d_k = d_start[g] + a_k * (d_end - d_start[g])", "d_k = d_end"),
    M("contact: chain's p_d term dropped", CONTACT,
      "acc += tl[10] * Dd_prev[J]", "acc += 0.0"),
    M("contact: chain's tau_lam term dropped", CONTACT,
      "acc += tl[9] * Dlam[J]", "acc += 0.0"),
    M("contact: lam derivative not carried to the next sub-interval", CONTACT,
      "lam_needed = k < nsub", "lam_needed = False"),
    M("contact: a line that misses counts as touching", CONTACT,
      "d_end = bd if ok else -far", "d_end = bd if ok else 0.0"),
    M("contact: start penetration, a miss counts as touching", CONTACT,
      "    d = bd if ok else -far", "    d = bd if ok else 0.0"),
    M("contact: start penetration, round-off touching not snapped", CONTACT,
      "return 0.0 if abs(d) <= touch_tol else d", "return d"),
    M("contact: penetration derivative dd/dP's sign", CONTACT,
      "dP0, dP1 = mb0 / me, mb1 / me", "dP0, dP1 = -mb0 / me, -mb1 / me"),
    M("contact: round-off touching not snapped to d = 0", CONTACT,
      "            if abs(d_end) <= touch_tol:\n                d_end = 0.0",
      "            if False:\n                d_end = 0.0"),
    M("contact: penetration derivative, turning normal dropped", CONTACT,
      "Dd_end[2 * a] += dNq[a] * dt0", "Dd_end[2 * a] += 0.0"),
    M("contact: dd_de sign in the group", CONTACT,
      "dE0, dE1 = -bd * dP0, -bd * dP1", "dE0, dE1 = bd * dP0, bd * dP1"),
    M("contact: axisymmetric weight with the reference radius under NLGEOM", CONTACT,
      "wt = W[q] * P_0", "wt = W[q] * P0[g, 0]"),
    M("contact: tangent of the moving radius dropped", CONTACT,
      "kg = kg + Nq[a] * veci * (W[q] * AP0[q, J])", "kg = kg"),
    M("contact: geometric tangent (moving axes) dropped", CONTACT,
      "Dvec[0, J] += sp * RAt[q, 0, J] - stau * At[q, 0, J]", "Dvec[0, J] += 0.0"),
    M("contact: outside-the-cone check dropped", CONTACT,
      "outside[g] = _outside(lv, sp, stau, slam)", "outside[g] = False"),
    M("contact: degenerate face not reported", CONTACT,
      "degenerate += n <= jac_tol", "degenerate += 0"),
    M("contact: non-finite force not reported", CONTACT,
      "nonfinite += not math.isfinite(f[e, J])", "nonfinite += 0"),
    M("contact: start cache ignores the foundation's move", CONTACT,
      "        if same and not cco[i] == co[i]:\n            same = False",
      "        if False:\n            same = False"),
    M("contact: start cache ignores moved faces", CONTACT,
      "                if same and not xo[e, a, i] == cxo[e, a, i]:\n"
      "                    same = False",
      "                if False:\n                    same = False"),
    M("control: start penetration never reused", CONTACT,
      "same = cached and cco.shape[0] == co.shape[0]", "same = False",
      equivalent="recomputing the start penetration gives the same numbers"),
    # -- kernels/contact.py: a rigid tool (its DOFs, its rotation) and the stabilisation -------
    M("contact: tool's rotation column of d dropped", CONTACT,
      "Dd_end[nd + 2] = dP0 * qy - dP1 * qx", "Dd_end[nd + 2] = 0.0"),
    M("contact: turned chain's derivative not turned back", CONTACT,
      "dP0, dP1 = cs * dP0 - sn_ * dP1, sn_ * dP0 + cs * dP1", "dP0, dP1 = dP0, dP1"),
    M("contact: tool's rotation ignored in the slip", CONTACT,
      "                    rel0 = rel0 - (qa0 - arm0) / nsub\n", ""),
    M("contact: tool moment's moving arm dropped", CONTACT,
      "                            elif J == nd:\n                                dm -= F1",
      "                            elif J == nd:\n                                dm -= 0.0"),
    M("contact: tool rows not negated", CONTACT,
      "            f[e, r] = -f[e, r]", "            f[e, r] = f[e, r]"),
    M("contact: stabilisation's weight derivative dropped", CONTACT,
      "sa = stab[0] * (wn + dd * dwn)", "sa = stab[0] * wn"),
    M("contact: stabilisation's tangential traction dropped", CONTACT,
      "ps, ts = stab[0] * wn * dd, stab[1] * wts * dvs", "ps, ts = stab[0] * wn * dd, 0.0"),
    # -- kernels/contact.py: the projection ---------------------------------------------------
    M("projection: end half-lines skipped", CONTACT,
      "            if not ds * sign > 0:\n                continue",
      "            if True:\n                continue"),
    M("projection: back-facing test dropped", CONTACT,
      "if not (m_norm > 0 and cosn < -cos_min):", "if not (m_norm > 0):"),
    M("projection: second root skipped", CONTACT,
      "                s = c0 / q", "                s = math.nan"),
    M("projection: first root skipped", CONTACT,
      "                s = q / a", "                s = math.nan"),
    M("projection: dd_de sign", CONTACT,
      "dd_de[g, 0], dd_de[g, 1] = -bd * dd_dP[g, 0], -bd * dd_dP[g, 1]",
      "dd_de[g, 0], dd_de[g, 1] = bd * dd_dP[g, 0], bd * dd_dP[g, 1]"),
    M("projection: d not divided by |e_u|^2", CONTACT,
      "dist = ((px - X0) * ex + (py - X1) * ey) / (ex * ex + ey * ey)",
      "dist = ((px - X0) * ex + (py - X1) * ey)"),
    M("projection: translation ignored on the arcs", CONTACT,
      "c0 = w0 * ((A[j, 0] + c[0]) - px) + w1 * ((A[j, 1] + c[1]) - py)",
      "c0 = w0 * (A[j, 0] - px) + w1 * (A[j, 1] - py)"),
    # -- the NumPy references (two-sided comparison) ------------------------------------------
    M("NumPy: Coulomb return's hardening term dropped", "lagamine_py/laws/coulomb.py",
      "step = resid / (kt + h)", "step = resid / kt"),
    M("NumPy: TAUMAX ignored in the return", "lagamine_py/laws/coulomb.py",
      "        capped = plastic & (lam_c > lam_u)", "        capped = plastic & False"),
    M("NumPy: exponential form's slope sign", "lagamine_py/laws/contact_hardening.py",
      "return self.v_inf + dv * e, (-dv / self.lamc) * e",
      "return self.v_inf + dv * e, (dv / self.lamc) * e"),
    M("NumPy: J2 hardening H dropped from the return", "lagamine_py/laws/j2.py",
      "dp = (q_tr - self.yield_stress(peeq_n)) / (G3 + H)",
      "dp = (q_tr - self.yield_stress(peeq_n)) / G3"),
    M("NumPy: RO branch swap", "lagamine_py/laws/ramberg_osgood.py",
      "            if in_q:", "            if not in_q:"),
    M("NumPy: RO stop by the step alone (the quadratic bound dropped)",
      "lagamine_py/laws/ramberg_osgood.py",
      "done = ((newton & ((np.abs(step) <= tol) | (quad * step * step <= tol)))",
      "done = ((newton & (np.abs(step) <= tol))"),
    M("NumPy: RO ln P's start without the bound ln peeq(q_tr)",
      "lagamine_py/laws/ramberg_osgood.py",
      "y_hi = np.minimum(ln_p_star[i], self._a + n * np.log(qt))", "y_hi = ln_p_star[i]"),
    M("NumPy: axisymmetric hoop row dropped", "lagamine_py/elements/solid.py",
      "            B[:, :, 2, :, 0] = self.N / r[..., None]",
      "            B[:, :, 2, :, 0] = 0.0"),
    M("NumPy: end half-lines skipped", "lagamine_py/foundation.py",
      "roots[:, 2 * j + col] = np.where(ds * sign > 0, sign + ds, np.nan)",
      "roots[:, 2 * j + col] = np.nan"),
    M("NumPy: THETA ignored in the axes", "lagamine_py/elements/contact.py",
      "a_th = (k - 1 + theta) / nsub", "a_th = k / nsub"),
    M("NumPy: YIELD_RTOL changed", "lagamine_py/kernels/layout.py",
      "YIELD_RTOL = 1e-12", "YIELD_RTOL = 1e-11"),
]


def check(mutations) -> None:
    """Every mutation's text is found exactly once (the source may have moved on)."""
    for m in mutations:
        n = (ROOT / m.path).read_text().count(m.old)
        if n != 1:
            raise SystemExit(f"mutation {m.name!r}: its text occurs {n} times in {m.path}")


class Mutated:
    """The file with the mutation applied; restored (bytes and time stamp) on exit."""

    def __init__(self, m: Mutation, serial: int):
        self.path = ROOT / m.path
        self.m = m
        self.serial = serial

    def __enter__(self):
        self.original = self.path.read_bytes()
        st = self.path.stat()
        self.times = (st.st_atime_ns, st.st_mtime_ns)
        text = self.original.decode()
        self.path.write_text(text.replace(self.m.old, self.m.new))
        # a time stamp of its own: numba's cache index is keyed on (mtime, size)
        stamp = self.times[1] + (1000 + self.serial) * 10**9
        os.utime(self.path, ns=(stamp, stamp))
        return self

    def __exit__(self, *exc):
        self.path.write_bytes(self.original)
        os.utime(self.path, ns=self.times)
        return False


def run_tests(env: dict, timeout: float) -> tuple[str, str]:
    """``("passed" | "failed" | "timeout" | "invalid", what failed)``."""
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-rf", "-p", "no:cacheprovider", TEST,
           LANES_TEST, LAW_TEST, THREADS_TEST]
    try:
        out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                             timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", f"no result in {timeout:.0f} s"
    if out.returncode == 0:
        return "passed", ""
    if "numba.core.errors" in out.stdout:         # the mutant itself is broken
        return "invalid", "does not compile: " + next(
            line for line in out.stdout.splitlines() if "numba.core.errors" in line)[:200]
    failed = [line for line in out.stdout.splitlines() if line.startswith(("FAILED", "ERROR"))]
    if not failed:
        return "failed", (out.stdout + out.stderr).strip().splitlines()[-1][:300]
    line = re.sub(r"^(FAILED|ERROR) tests/test_(kernel_twins|solid_lanes|ro_return_map|"
                  r"solid_threads).py::", "", failed[0])
    return "failed", line[:300]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-k", action="append", default=[],
                    help="only the mutations whose name contains this (repeatable: any)")
    ap.add_argument("--list", action="store_true", help="list the mutations and stop")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per test run")
    args = ap.parse_args(argv)
    chosen = [m for m in MUTATIONS
              if not args.k or any(k.lower() in m.name.lower() for k in args.k)]
    check(chosen)
    if args.list:
        for m in chosen:
            print(f"{m.name}  [{m.path}]")
        return 0
    # SIGTERM restores the file as Ctrl-C does
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    with tempfile.TemporaryDirectory(prefix="kernel_mutations_") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONDONTWRITEBYTECODE="1",
                   COLUMNS="400")
        t0 = time.time()
        status, what = run_tests(env, args.timeout)
        if status != "passed":
            print(f"the unmutated sources fail the test ({what}): nothing to study")
            return 2
        print(f"unmutated: passed ({time.time() - t0:.0f} s)\n")
        rows = []
        for i, m in enumerate(chosen):
            t = time.time()
            with Mutated(m, i):
                status, what = run_tests(env, args.timeout)
            if m.equivalent:
                verdict = "survived (control)" if status == "passed" else "CAUGHT (control!)"
            else:
                verdict = {"passed": "SURVIVED", "failed": "caught", "timeout": "caught (timeout)",
                           "invalid": "INVALID"}[status]
            rows.append((m, verdict, what))
            print(f"[{i + 1}/{len(chosen)} {time.time() - t:4.0f} s] {verdict:18s} {m.name}"
                  + (f"\n        by {what}" if what else ""), flush=True)
    print("\n| mutation | file | result | caught by |\n|---|---|---|---|")
    for m, verdict, what in rows:
        print(f"| {m.name} | {m.path.removeprefix('lagamine_py/')} | {verdict} | "
              f"{what.replace('|', '/')} |")
    bad = [m.name for m, v, _ in rows if v in ("SURVIVED", "CAUGHT (control!)", "INVALID")]
    print(f"\n{len(rows)} mutations, {len(bad)} not as expected" + (": " + "; ".join(bad)
                                                                  if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
