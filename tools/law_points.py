"""Where the Ramberg-Osgood law's time goes, point by point:
``python tools/law_points.py NXxNY [--max-increments N] --save F.npz`` then
``python tools/law_points.py --load F.npz [--repeat R]``.

``--save``: press-then-slide at ``NXxNY`` (``tools/bench.py``'s deck, ``KERNEL=NUMPY``, so
the NumPy twin of the law runs and can be watched), stopped after ``N`` converged increments;
every call of ``RambergOsgood.update`` is watched: how many points it had, and the trial
``q_tr`` and committed ``peeq_n`` of its plastic points (the return map's inputs) are kept,
with the number of residual evaluations each point's safeguarded Newton made.

``--load``: the report on those points:

* points per evaluation, the plastic fraction, the branch (``x = ln q`` or ``y = ln P``) and the
  histogram of local Newton iterations (residual evaluations) per plastic point;
* the transcendental calls (exp, log) per point of the numba kernel's law
  (``kernels.solid._law_update``), counted from its source's calls per branch;
* CPU ns per plastic point of the kernel's return map ``kernels.solid._ro_return_map`` over all
  the recorded points in one compiled loop, against a loop of the same number of ``exp`` and
  ``log`` calls (their share), and the elastic points' yield test.

Timings only, never asserted in tests.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def record(nx: int, ny: int, max_increments: int | None) -> dict[str, np.ndarray]:
    """The watched run: inputs and iteration counts of every plastic point's return map."""
    from bench import run_one

    from lagamine_py.laws import ramberg_osgood as ro

    points, q_tr, peeq_n, iters, branch = [], [], [], [], []
    real_update, real_map, real_newton = (ro.RambergOsgood.update, ro.RambergOsgood._return_map,
                                          ro.safeguarded_newton)

    def update(self, eps_e_trial, state):
        points.append(int(np.prod(np.shape(eps_e_trial)[:-1])))
        seen[:] = [self]
        return real_update(self, eps_e_trial, state)

    def newton(fun, lo, hi, tol, max_iter, **kw):
        count = np.zeros(len(lo), dtype=np.int64)

        def counted(x, k):
            count[k] += 1
            return fun(x, k)
        x, ok = real_newton(counted, lo, hi, tol, max_iter, **kw)
        iters.append(count)
        branch.append(np.full(len(lo), fun.__code__.co_names[-1] == "_g_q"))
        return x, ok

    def return_map(self, qt, pn):
        n0 = len(iters)
        out = real_map(self, qt, pn)
        # the branches in the order _return_map ran them: by q first, then by P
        got = np.concatenate(iters[n0:]) if len(iters) > n0 else np.zeros(0, np.int64)
        flags = np.concatenate(branch[n0:]) if len(branch) > n0 else np.zeros(0, bool)
        by_q = _by_q(self, qt, pn)
        order = np.r_[np.flatnonzero(by_q), np.flatnonzero(~by_q)]
        it = np.empty(len(qt), np.int64)
        it[order] = got
        del iters[n0:], branch[n0:]
        iters_all.append(it)
        flags_all.append(by_q)
        assert flags.sum() == by_q.sum()
        q_tr.append(np.array(qt))
        peeq_n.append(np.array(pn))
        return out

    iters_all, flags_all, seen = [], [], []
    ro.RambergOsgood.update, ro.RambergOsgood._return_map = update, return_map
    ro.safeguarded_newton = newton
    try:
        r = run_one(nx, ny, max_increments=max_increments, kernel="NUMPY",
                    controls={"KRYLOV": 0, "SDI": "NO"})
    finally:
        ro.RambergOsgood.update, ro.RambergOsgood._return_map = real_update, real_map
        ro.safeguarded_newton = real_newton
    return {"points": np.array(points), "q_tr": np.concatenate(q_tr),
            "peeq_n": np.concatenate(peeq_n), "iterations": np.concatenate(iters_all),
            "by_q": np.concatenate(flags_all), "lp": seen[0].kernel_parameters()[1],
            "status": np.array(str(r.get("status")))}


def _by_q(law, qt, pn):
    """``_return_map``'s choice of unknown (x = ln q where True)."""
    G3, n = 3.0 * law.G, law.values["N"]
    x_star = np.log(n * (qt + G3 * pn) / (n + 1.0))
    lo, hi = law._bracket(qt, pn)
    return (x_star >= hi) | (law._g_q(np.minimum(x_star, hi), qt, pn)[0] >= 0.0)


class _CountingMath:
    """``math`` with its ``exp`` and ``log`` counted (the kernel's Python source run as is)."""

    def __init__(self):
        import math
        self.counts = {"exp": 0, "log": 0}
        self.inf, self.nan, self.isfinite, self.sqrt = math.inf, math.nan, math.isfinite, math.sqrt
        # NumPy's semantics, as the kernel's error_model="numpy": log 0 = -inf, no exceptions
        self._exp, self._log = np.exp, np.log

    def exp(self, x):
        self.counts["exp"] += 1
        with np.errstate(all="ignore"):
            return float(self._exp(x))

    def log(self, x):
        self.counts["log"] += 1
        with np.errstate(all="ignore"):
            return float(self._log(x))


def kernel_counts(qt, pn, lp) -> dict[str, np.ndarray]:
    """Per point, the calls the kernel's return map makes: its own source
    (``kernels.solid._ro_return_map`` and the functions it calls, their ``py_func``) run in
    Python with ``math`` counted: residual evaluations (local Newton iterations), exp, log,
    and the branch (x = ln q)."""
    from types import FunctionType

    from lagamine_py.kernels import solid

    m = _CountingMath()
    env = dict(solid._ro_return_map.py_func.__globals__)
    env["math"] = m
    residuals = [0]
    for name in ("_ro_residual", "_safeguarded_newton", "_ro_log_yield", "_ro_return_map",
                 "_quad_x"):
        if name in env:
            f = env[name].py_func
            env[name] = FunctionType(f.__code__, env, name, f.__defaults__)
    inner = env["_ro_residual"]

    def residual(by_q, *args):
        residuals[0] += 1
        residual.by_q = by_q
        return inner(by_q, *args)
    env["_ro_residual"] = residual
    G3, a, n, tol, maxit = 3.0 * lp[1], lp[4], lp[5], lp[6], int(lp[7])
    out = {k: np.zeros(len(qt), np.int64) for k in ("iterations", "exp", "log")}
    out["by_q"] = np.zeros(len(qt), bool)
    for k in range(len(qt)):
        residuals[0], m.counts["exp"], m.counts["log"] = 0, 0, 0
        env["_ro_return_map"](float(qt[k]), float(pn[k]), m.log(float(pn[k])), G3, a, n, tol,
                              maxit)
        by_q = residual.by_q
        # the branch test's own residual (the old kernel) is not an iteration
        calls = residuals[0]
        out["iterations"][k] = calls - (1 if calls and _tests_by_residual(env) else 0)
        out["exp"][k], out["log"][k], out["by_q"][k] = m.counts["exp"], m.counts["log"], by_q
    return out


def _tests_by_residual(env) -> bool:
    """Whether this tree's return map evaluates ``_ro_residual`` to choose its unknown."""
    return "_ro_residual" in env["_ro_return_map"].__code__.co_names


def report(data, repeat: int, sample: int) -> str:
    """The report of ``--load``."""
    from numba import njit

    from lagamine_py.kernels import solid

    ro_map = solid._ro_return_map
    qt, pn, lp = data["q_tr"], data["peeq_n"], data["lp"]

    @njit(cache=False)
    def all_points(qt, pn, lp, out):
        G3 = 3.0 * lp[1]
        acc = 0.0
        for k in range(len(qt)):
            ln_pn = np.log(pn[k])
            q, peeq, dq, ok = ro_map(qt[k], pn[k], ln_pn, G3, lp[4], lp[5], lp[6], int(lp[7]))
            out[k] = q
            acc += dq
        return acc

    @njit(cache=False)
    def transcendentals(xs, n_exp, n_log):
        acc = 0.0
        for k in range(len(xs)):
            x = xs[k]
            for _ in range(n_exp):
                acc += np.exp(x)
                x += 1e-3
            for _ in range(n_log):
                acc += np.log(x)
                x += 1e-3
        return acc

    total, m = int(data["points"].sum()), len(qt)
    pick = np.unique(np.linspace(0, m - 1, min(sample, m)).round().astype(int))
    c = kernel_counts(qt[pick], pn[pick], lp)
    it, by_q = c["iterations"], c["by_q"]
    lines = [f"{total} law points in {len(data['points'])} evaluations, {m} plastic "
             f"({m / total:.1%}); counted on {len(pick)} of them, by the kernel's own source: "
             f"branch x = ln q {by_q.mean():.1%}, y = ln P {1 - by_q.mean():.1%}",
             f"local Newton iterations (residual evaluations) per plastic point: mean "
             f"{it.mean():.2f} (x branch {it[by_q].mean() if by_q.any() else 0:.2f}, "
             f"y branch {it[~by_q].mean() if (~by_q).any() else 0:.2f}); histogram:"]
    counts = np.bincount(it)
    lines.append("  " + ", ".join(f"{k}: {n / len(it):.1%}" for k, n in enumerate(counts) if n))
    n_exp, n_log = c["exp"].mean(), c["log"].mean()
    lines.append(f"transcendental calls per plastic point, the return map with ln peeq_n: exp "
                 f"{n_exp:.2f}, log {n_log:.2f} (the yield test adds one exp at every point)")
    out = np.empty(m)
    all_points(qt[:10], pn[:10], lp, out[:10])
    transcendentals(qt[:10], 2, 2)
    best_map = best_tr = np.inf
    e_law, l_law = int(round(n_exp)), int(round(n_log))
    for _ in range(repeat):
        t = time.process_time()
        all_points(qt, pn, lp, out)
        best_map = min(best_map, time.process_time() - t)
        t = time.process_time()
        transcendentals(qt, e_law, l_law)
        best_tr = min(best_tr, time.process_time() - t)
    lines.append(f"kernel return map (_ro_return_map plus log peeq_n, every recorded point): "
                 f"{best_map / m * 1e9:.1f} ns per plastic point; {e_law} exp + {l_law} log "
                 f"alone: {best_tr / m * 1e9:.1f} ns ({best_tr / best_map:.0%})")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("size", nargs="?", help="NXxNY: record press-then-slide")
    ap.add_argument("--max-increments", type=int)
    ap.add_argument("--save", type=Path)
    ap.add_argument("--load", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sample", type=int, default=20000, help="points counted in Python")
    a = ap.parse_args(argv)
    if a.size:
        nx, ny = (int(n) for n in a.size.split("x"))
        data = record(nx, ny, a.max_increments)
        if a.save:
            np.savez_compressed(a.save, **data)
    else:
        data = dict(np.load(a.load))
    print(report(data, a.repeat, a.sample))
    return 0


if __name__ == "__main__":
    sys.exit(main())
