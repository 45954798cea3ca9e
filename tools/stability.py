"""Stability study: where each method fails, and what the program does then.

    python tools/stability.py [-j 2] [--work DIR] [--studies theta,substeps,auto,indicator,...]

Writes ``docs/data/stability_<study>.csv`` and ``docs/images/stability_<study>.png`` for:

* ``theta``: THETA = 0, 1/2, 1 (one sub-interval, and SUBSTEPS=AUTO) against the increment size on
  ``tools/study_decks/cup_rotation.dat``, a block turned by 60 degrees in a rigid cup (the contact
  surface rotates by 57 degrees in the studied step), with and without cut-backs: error of the
  slip and of T/P at the end against a reference run (THETA = 1/2, 16 sub-intervals, 512
  increments);
* ``substeps``: sub-intervals 1..16 and AUTO against hardening friction (HPHI = 0, 0.01, 0.03 per
  mm of slip) on the same scene at 7.1 degrees asked per increment (cut-backs allowed);
* ``auto``: error against CPU time on the cup for fixed counts 1, 2, 4, 8 and AUTO (SUBTOL =
  0.02, 0.005 rad) over increment sizes: where AUTO beats every fixed count;
* ``indicator``: the classical against the elastic-predictor loading indicator under softening
  friction, single point (:func:`lagamine_py.laws.contact_point.drive_contact_point`) and the Coulomb block
  deck (``block_study.dat``, HB < 0): what the program does with the classical one;
* ``penalty``: KP and KT across six decades on the Coulomb block: penetration, T error, Newton
  iterations, status;
* ``linesearch``: largest push increment that converges at the onset of sliding, with and
  without ``*CONTROLS LINESEARCH=YES`` (no cut-back allowed);
* ``ro``: the Ramberg-Osgood exponent up to n = 50 (``ro_study.dat``), with cut-backs and
  without.

Runs go to ``--work`` (default ``/tmp/lagamine_stability``) and are reused by a rerun.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from accuracy_speed import DOCS, STUDY, run_points  # noqa: E402

from lagamine_py.laws.contact_point import drive_contact_point as drive  # noqa: E402
from lagamine_py.laws.coulomb import Coulomb  # noqa: E402
from lagamine_py.results import copen_gap, read_table  # noqa: E402

CUP = STUDY / "cup_rotation.dat"
BLOCK = STUDY / "block_study.dat"
RO = STUDY / "ro_study.dat"
DTS = ("0.5", "0.25", "0.125", "0.0625", "0.03125", "0.015625")


# ------------------------------------------------------------------ helpers
def end_state(run: Path) -> dict | None:
    """Mean slip (lam) over the contact points and T/P at the last written increment."""
    try:
        pts = read_table(run / "contact.csv")
        tot = read_table(run / "contact_totals.csv")
    except (OSError, ValueError):
        return None
    key = np.asarray(pts["step"], float) * 1e6 + np.asarray(pts["increment"], float)
    last = key == key.max()
    lam = float(np.mean(np.asarray(pts["lambda"], float)[last]))
    P, T = float(np.asarray(tot["P"], float)[-1]), float(np.asarray(tot["T"], float)[-1])
    gap = -copen_gap(pts)            # the penetration (gap is COPEN: positive when open)
    return {"slip": lam, "T_over_P": abs(T) / P if P else math.nan,
            "max_gap": float(np.nanmax(gap)) if gap.size else math.nan}


def cup_errors(rows: list[dict], ref: dict | None) -> None:
    for r in rows:
        st = end_state(Path(r["dir"])) if r["status"] == 0 else None
        r.update(st or {"slip": math.nan, "T_over_P": math.nan})
        if st and ref:
            r["err_slip"] = abs(st["slip"] / ref["slip"] - 1.0)
            r["err_TP"] = abs(st["T_over_P"] / ref["T_over_P"] - 1.0)
            r["error"] = max(r["err_slip"], r["err_TP"])
        else:
            r["err_slip"] = r["err_TP"] = r["error"] = math.nan


def cup_reference(work: Path, hphi: str) -> dict | None:
    ref = {"DT": str(1 / 512), "THETA": "0.5", "SUBSTEPS": "16", "HPHI": hphi}
    row = run_points(CUP, [ref], work / "cup_ref", 1)[0]
    return end_state(Path(row["dir"])) if row["status"] == 0 else None


def write_csv(name: str, rows: list[dict], cols: list[str]) -> None:
    (DOCS / "data").mkdir(parents=True, exist_ok=True)
    with open(DOCS / "data" / f"stability_{name}.csv", "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow([f"{r[c]:.6g}" if isinstance(r.get(c), float) else r.get(c, "")
                        for c in cols])


def figure(ncols=1, w=7.5, h=5):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, ncols, figsize=(w * ncols, h))
    return plt, fig, np.atleast_1d(axes)


def finish_axes(axes, xlabel: str, legend_size: int = 7) -> None:
    """The common x label, a log-log-friendly grid and a legend on every panel."""
    for ax in axes:
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=legend_size)


def save(plt, fig, name: str) -> None:
    (DOCS / "images").mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(DOCS / "images" / f"stability_{name}.png", dpi=110)
    plt.close(fig)


RUN_COLS = ["status", "cpu_s", "newton_iterations", "increments", "failed_attempts"]


def short_reason(r: dict) -> str:
    return "" if r["status"] == 0 else str(r.get("reason", ""))[:240]


# ------------------------------------------------------------------ studies
def study_theta(work: Path, jobs: int) -> None:
    ref = cup_reference(work, "0.005")
    pts = [{"DT": dt, "DTMIN": dtmin, "THETA": th, "SUBSTEPS": sub}
           for th in ("0", "0.5", "1") for sub in ("1", "AUTO") for dt in DTS
           for dtmin in (dt, "1e-5")]
    rows = run_points(CUP, pts, work / "cup", jobs)
    cup_errors(rows, ref)
    for r in rows:
        r["reason_short"] = short_reason(r)
        r["deg_per_increment"] = 57.0 * float(r["DT"])
        r["cutbacks_allowed"] = r["DTMIN"] == "1e-5"
    write_csv("theta", rows, ["THETA", "SUBSTEPS", "DT", "deg_per_increment", "cutbacks_allowed",
                              *RUN_COLS, "slip", "T_over_P", "err_slip", "err_TP", "error",
                              "reason_short"])
    plt, fig, axes = figure(2, 6.5)
    for k, th in enumerate(("0", "0.5", "1")):
        for sub, ls in (("1", "-o"), ("AUTO", "--s")):
            sel = [r for r in rows if r["THETA"] == th and r["SUBSTEPS"] == sub
                   and r["cutbacks_allowed"]]
            x = np.array([r["deg_per_increment"] for r in sel])
            e = np.array([r["error"] for r in sel])
            style = dict(color=f"C{k}", mfc="none" if sub == "AUTO" else None,
                         label=f"THETA={th}, SUBSTEPS={sub}")
            axes[0].loglog(x, np.maximum(e, 1e-9), ls, **style)
            axes[1].semilogx(x, [r["failed_attempts"] for r in sel], ls, **style)
            raw = [r for r in rows if r["THETA"] == th and r["SUBSTEPS"] == sub
                   and not r["cutbacks_allowed"]]
            bad = [r["deg_per_increment"] for r in raw if r["status"] != 0]
            if bad:
                axes[1].semilogx(bad, np.full(len(bad), -1 - 0.3 * k), "x", color=f"C{k}",
                                 ms=10, mew=2)
    axes[0].set_ylabel("error of slip and T/P against the reference (cut-backs allowed)")
    axes[0].set_title("cup rotation, step TURN (57 degrees): error")
    axes[1].set_ylabel("failed attempts (cut-backs); x below 0: without cut-backs, exit 3")
    axes[1].set_title("... and what it costs: cut-backs, and failures without them")
    finish_axes(axes, "rotation per increment asked [degrees]")
    save(plt, fig, "theta")


def study_substeps(work: Path, jobs: int) -> None:
    hphis = ("0", "0.01", "0.03")
    refs = {h: cup_reference(work, h) for h in hphis}
    subs = ("1", "2", "4", "8", "16", "AUTO")
    pts = [{"DT": "0.125", "THETA": "1", "SUBSTEPS": s, "HPHI": h} for h in hphis for s in subs]
    rows = run_points(CUP, pts, work / "cup", jobs)
    for h in hphis:
        cup_errors([r for r in rows if r["HPHI"] == h], refs[h])
    for r in rows:
        r["reason_short"] = short_reason(r)
    write_csv("substeps", rows, ["HPHI", "SUBSTEPS", "DT", *RUN_COLS, "slip", "T_over_P",
                                 "err_slip", "err_TP", "error", "reason_short"])
    plt, fig, axes = figure(2, 6)
    for k, h in enumerate(hphis):
        sel = [r for r in rows if r["HPHI"] == h]
        x = np.arange(len(sel))
        axes[0].semilogy(x, np.maximum([r["err_TP"] for r in sel], 1e-12), "-o", color=f"C{k}",
                         label=f"HPHI={h}")
        axes[1].semilogy(x, np.maximum([r["err_slip"] for r in sel], 1e-12), "-o",
                         color=f"C{k}", label=f"HPHI={h}")
    for ax, what in zip(axes, ("T/P", "slip")):
        ax.set_xticks(range(len(subs)), subs)
        ax.set_xlabel("SUBSTEPS (7.1 degrees asked per increment, cut back where needed; "
                      "THETA = 1)")
        ax.set_ylabel(f"error of {what} against the reference")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title("sub-intervals against hardening friction: T/P")
    axes[1].set_title("... and slip")
    save(plt, fig, "substeps")


def study_auto(work: Path, jobs: int) -> None:
    ref = cup_reference(work, "0.005")
    variants = [("1", None), ("2", None), ("4", None), ("8", None), ("AUTO", "0.02"),
                ("AUTO", "0.005")]
    pts = []
    for th in ("1", "0.5"):
        for dt in ("0.25", "0.125", "0.0625", "0.015625"):
            for sub, tol in variants:
                p = {"DT": dt, "DTMIN": "1e-5", "THETA": th, "SUBSTEPS": sub}
                if tol:
                    p["SUBTOL"] = tol
                pts.append(p)
    rows = run_points(CUP, pts, work / "cup", jobs)
    cup_errors(rows, ref)
    for r in rows:
        r["variant"] = r["SUBSTEPS"] + (f" SUBTOL={r['SUBTOL']}" if r.get("SUBTOL") else "")
        r["reason_short"] = short_reason(r)
    write_csv("auto", rows, ["THETA", "DT", "variant", *RUN_COLS, "slip", "T_over_P", "error",
                             "reason_short"])
    plt, fig, axes = figure(2, 6.5)
    for ax, th in zip(axes, ("1", "0.5")):
        for k, (sub, tol) in enumerate(variants):
            name = sub + (f" SUBTOL={tol}" if tol else "")
            sel = [r for r in rows if r["THETA"] == th and r["variant"] == name
                   and r["status"] == 0]
            ax.loglog([r["cpu_s"] for r in sel], np.maximum([r["error"] for r in sel], 1e-12),
                      "--s" if tol else "-o", color=f"C{k}", label=f"SUBSTEPS={name}")
        ax.set_xlabel("CPU time [s] (points: 14, 7, 3.6, 0.9 degrees per increment)")
        ax.set_ylabel("error of slip and T/P")
        ax.set_title(f"cup rotation, THETA = {th}: fixed counts against AUTO")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    save(plt, fig, "auto")


def indicator_single_point() -> list[dict]:
    """Press, then slide forward under softening adhesion (HB < 0): both indicators."""
    par = dict(KP=1000.0, KT=500.0, PHI=0.2, B=2.0, HB=-100.0)
    u = np.r_[0.0, np.full(40, 0.01)]
    v = np.r_[0.0, np.linspace(0.0, 0.1, 40)]
    out = []
    for ind in ("PREDICTOR", "CLASSICAL"):
        law = Coulomb(**par, INDICATOR=ind)
        res = drive(law, u, v)
        outside = [bool(law.inadmissible({k: res[k][i] for k in ("tau", "p", "lam")}))
                   for i in range(len(u))]
        b, _ = law.adhesion(res["lam"])
        phi, _ = law.friction(res["lam"])
        for i in range(len(u)):
            out.append({"indicator": ind, "v": float(v[i]), "p": float(res["p"][i]),
                        "tau": float(res["tau"][i]), "lam": float(res["lam"][i]),
                        "radius": float(b[i] + phi[i] * res["p"][i]),
                        "outside_cone": outside[i]})
    return out


def study_indicator(work: Path, jobs: int) -> None:
    sp = indicator_single_point()
    write_csv("indicator_point", sp, ["indicator", "v", "p", "tau", "lam", "radius",
                                      "outside_cone"])
    pts = [{"HB": hb, "INDICATOR": ind} for hb in ("0", "-50", "-200")
           for ind in ("PREDICTOR", "CLASSICAL")]
    rows = run_points(BLOCK, pts, work / "block", jobs)
    for r in rows:
        r["reason_short"] = short_reason(r)
    write_csv("indicator", rows, ["HB", "INDICATOR", *RUN_COLS, "SLIDING_error",
                                  "reason_short"])
    plt, fig, (ax,) = figure()
    for k, ind in enumerate(("PREDICTOR", "CLASSICAL")):
        sel = [r for r in sp if r["indicator"] == ind]
        v = [r["v"] for r in sel]
        ax.plot(v, [r["tau"] for r in sel], "-o", ms=3, color=f"C{k}", label=f"tau, {ind}")
        ax.plot(v, [r["radius"] for r in sel], ":", color=f"C{k}",
                label=f"cone radius B + phi p, {ind}")
        bad = [r for r in sel if r["outside_cone"]]
        if bad:
            ax.plot([r["v"] for r in bad], [r["tau"] for r in bad], "x", color="k", ms=9,
                    label="outside the cone: the contact element fails the increment")
    ax.set_xlabel("tangential displacement v [mm]")
    ax.set_ylabel("tau [MPa]")
    ax.set_title("softening adhesion (B = 2, HB = -100): classical vs elastic-predictor indicator")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    save(plt, fig, "indicator")


DECADES = ("2e3", "2e4", "2e5", "2e6", "2e7", "2e8", "2e9")


def study_penalty(work: Path, jobs: int) -> None:
    pts = ([{"KP": k, "KT": "2e6"} for k in DECADES] + [{"KP": "2e6", "KT": k} for k in DECADES])
    rows = run_points(BLOCK, pts, work / "block", jobs)
    for r in rows:
        st = end_state(Path(r["dir"])) if r["status"] == 0 else None
        r["max_gap"] = st["max_gap"] if st else math.nan
        r["gap_over_h"] = r["max_gap"] / 2.5
        r["p_over_KP"] = 100.0 / float(r["KP"])
        r["varied"] = "KP" if r["KT"] == "2e6" and r["KP"] != "2e6" else (
            "KT" if r["KP"] == "2e6" and r["KT"] != "2e6" else "both=2e6")
        r["reason_short"] = short_reason(r)
    write_csv("penalty", rows, ["varied", "KP", "KT", *RUN_COLS, "SLIDING_error", "max_gap",
                                "p_over_KP", "gap_over_h", "reason_short"])
    plt, fig, axes = figure(3, 5)
    for k, which in enumerate(("KP", "KT")):
        sel = [r for r in rows if r[which] != "2e6" or r["varied"] == "both=2e6"]
        sel = [r for r in sel if (r["KT"] == "2e6") if which == "KP"] if which == "KP" else \
            [r for r in sel if r["KP"] == "2e6"]
        sel.sort(key=lambda r: float(r[which]))
        x = np.array([float(r[which]) for r in sel]) / (210000 / 2.5)
        ok = np.array([r["status"] == 0 for r in sel])
        axes[0].loglog(x[ok], np.maximum([r["SLIDING_error"] for r in np.array(sel)[ok]], 1e-16),
                       "-o", color=f"C{k}", label=f"{which} varied (other 2e6)")
        axes[1].semilogx(x, [r["newton_iterations"] for r in sel], "-o", color=f"C{k}",
                         label=f"{which} varied")
        if which == "KP":
            axes[2].loglog(x[ok], [r["max_gap"] for r in np.array(sel)[ok]], "-o", color="C0",
                           label="max penetration, run")
            axes[2].loglog(x, [r["p_over_KP"] for r in sel], "--", color="0.4",
                           label="p / KP (p = 100 MPa)")
        for r, xx in zip(sel, x):
            if r["status"] != 0:
                axes[1].plot(xx, r["newton_iterations"], "x", color="k", ms=12, mew=2)
    axes[0].set_ylabel("error of T = phi P + B A")
    axes[1].set_ylabel("Newton iterations (all attempts)")
    axes[2].set_ylabel("penetration [mm]")
    finish_axes(axes, "penalty / (E / h)")
    axes[0].set_title("Coulomb block: KP, KT over six decades")
    save(plt, fig, "penalty")


def study_linesearch(work: Path, jobs: int) -> None:
    dts = ("1", "0.5", "0.25", "0.125", "0.0625", "0.03125")
    pts = [{"DT": dt, "DTMIN": dt, "LINESEARCH": ls, "KP": kp, "KT": kp, "MAXIT": "25"}
           for kp in ("2e6", "2e8") for ls in ("NO", "YES") for dt in dts]
    rows = run_points(BLOCK, pts, work / "block", jobs)
    for r in rows:
        r["reason_short"] = short_reason(r)
    write_csv("linesearch", rows, ["KP", "LINESEARCH", "DT", *RUN_COLS, "SLIDING_error",
                                   "reason_short"])
    plt, fig, (ax,) = figure()
    for k, (kp, ls) in enumerate([(kp, ls) for kp in ("2e6", "2e8") for ls in ("NO", "YES")]):
        sel = [r for r in rows if r["KP"] == kp and r["LINESEARCH"] == ls]
        x = [float(r["DT"]) for r in sel]
        y = [r["newton_iterations"] if r["status"] == 0 else np.nan for r in sel]
        ax.semilogx(x, y, "-o", color=f"C{k}", label=f"KP=KT={kp}, LINESEARCH={ls}")
        bad = [float(r["DT"]) for r in sel if r["status"] != 0]
        ax.plot(bad, np.zeros(len(bad)), "x", color=f"C{k}", ms=12, mew=2)
    ax.set_xlabel("push increment (fraction of the 0.05 mm push), no cut-back allowed")
    ax.set_ylabel("Newton iterations of the run (x at 0: did not converge, exit 3)")
    ax.set_title("onset of sliding: increment size with and without line search")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    save(plt, fig, "linesearch")


def study_ro(work: Path, jobs: int) -> None:
    ns = ("3", "5", "10", "20", "30", "40", "50")
    pts = ([{"N": n, "DT": "0.05", "DTMIN": "1e-4"} for n in ns]
           + [{"N": n, "DT": dt, "DTMIN": dt} for n in ns for dt in ("1", "0.2", "0.05")])
    rows = run_points(RO, pts, work / "ro", jobs)
    # a non-uniform case: the press-then-slide block (local yielding under the loaded edge)
    ps = run_points(STUDY / "press_slide_study.dat", [{"N": n} for n in ("5", "10", "20", "50")],
                    work / "ro_press_slide", jobs)
    for r in ps:
        st = end_state(Path(r["dir"])) if r["status"] == 0 else None
        r["T_over_phiP"] = st["T_over_P"] / 0.2 if st else math.nan
        r["reason_short"] = short_reason(r)
    write_csv("ro_press_slide", ps, ["N", *RUN_COLS, "T_over_phiP", "reason_short"])
    for r in rows:
        r["cutbacks_allowed"] = r["DTMIN"] == "1e-4"
        r["reason_short"] = short_reason(r)
    write_csv("ro", rows, ["N", "DT", "DTMIN", "cutbacks_allowed", *RUN_COLS, "CURVE_error",
                           "reason_short"])
    plt, fig, axes = figure(2, 6)
    for k, (dt, dtmin) in enumerate((("0.05", "1e-4"), ("1", "1"), ("0.2", "0.2"),
                                     ("0.05", "0.05"))):
        sel = [r for r in rows if r["DT"] == dt and r["DTMIN"] == dtmin]
        n = [float(r["N"]) for r in sel]
        lab = f"dt={dt}" + (" with cut-backs" if dtmin == "1e-4" else ", no cut-back")
        axes[0].semilogy(n, [r.get("CURVE_error", np.nan) if r["status"] == 0 else np.nan
                             for r in sel], "-o", color=f"C{k}", label=lab)
        axes[1].plot(n, [r["newton_iterations"] for r in sel], "-o", color=f"C{k}", label=lab)
        for r in sel:
            if r["status"] != 0:
                axes[1].plot(float(r["N"]), r["newton_iterations"], "x", color="k", ms=12, mew=2)
    axes[0].set_ylabel("error against the uniaxial Ramberg-Osgood curve")
    axes[1].set_ylabel("Newton iterations (x: stopped, exit 3)")
    finish_axes(axes, "Ramberg-Osgood exponent n", 8)
    axes[0].set_title("compression of a Ramberg-Osgood cylinder (30 %)")
    axes[1].plot([float(r["N"]) for r in ps], [r["newton_iterations"] for r in ps], "-s",
                 color="C5", label="press-then-slide block (right axis scale: iterations)")
    axes[1].legend(fontsize=8)
    save(plt, fig, "ro")


STUDIES = {"theta": study_theta, "substeps": study_substeps, "auto": study_auto,
           "indicator": study_indicator, "penalty": study_penalty,
           "linesearch": study_linesearch, "ro": study_ro}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--work", type=Path, default=Path("/tmp/lagamine_stability"))
    ap.add_argument("--studies", default=",".join(STUDIES))
    args = ap.parse_args(argv)
    for name in args.studies.split(","):
        print(f"== {name}")
        STUDIES[name](args.work, args.jobs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
