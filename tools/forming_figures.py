"""Figures and numbers of the forming scenes of docs/scenes.md (issue 15, item 4).

Usage (from the repository root)::

    python tools/forming_figures.py upsetting [--work DIR]    # docs/images/upsetting_mesh.png
    python tools/forming_figures.py ring [--work DIR] [-j 2]  # docs/images/ring_chart.png, docs/data/ring_chart.csv
    python tools/forming_figures.py rolling [--work DIR]      # docs/images/rolling.png

``upsetting`` runs ``decks/upsetting.dat`` and draws its mesh at 10 and 20 % height reduction,
true to scale (``lagamine-py plot --scale 1``): the barrelling.  ``ring`` runs
``lagamine-py sweep decks/ring.dat --set PHI=0,0.02,0.05,0.1,0.2,0.3`` and draws the
friction-calibration chart: the change of the bore's smallest diameter against the height
reduction at the deck's five step ends (10 ... 50 %), one curve per PHI, with the frictionless
closed form ``r/r0 = sqrt(H0/H)``; the chart's points go to ``docs/data/ring_chart.csv``.
``rolling`` runs ``decks/rolling.dat`` and draws the contact pressure and shear along the roll gap
at the end against the slab solution (:func:`lagamine_py.checks.forming.rolling_slab`), and the
roll force and torque against the roll's angle.  Every number is printed as well.
"""
from __future__ import annotations

import argparse
import csv
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from lagamine_py.results import read_table  # noqa: E402

PHIS = (0.0, 0.02, 0.05, 0.1, 0.2, 0.3)
RING_R0, RING_H0 = 15.0, 20.0          # bore radius and full height of decks/ring.dat


def lagamine(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "lagamine_py", *args], check=True, cwd=ROOT)


def upsetting(work: Path) -> None:
    out = work / "upsetting"
    lagamine("run", "decks/upsetting.dat", "-o", str(out), "-q", "--overwrite")
    lagamine("plot", str(out), "--scale", "1", "--axes", "xy", "--states", "@0.5,1",
             "-o", str(out / "plots"))
    shutil.copy(out / "plots" / "mesh.png", ROOT / "docs" / "images" / "upsetting_mesh.png")
    d = read_table(out / "displacements.csv")
    x = d["x"] + d["u1"]
    print(f"upsetting at H = 8: mid-plane radius {x[np.isclose(d['y'], 0)].max():.3f}, "
          f"platen face radius {x[np.isclose(d['y'], 5)].max():.3f}, constant-volume radius "
          f"{10 * math.sqrt(10 / 8):.3f} mm")


def bore_curve(point: Path) -> tuple[np.ndarray, np.ndarray]:
    """Height reduction (%) and change of the bore's smallest diameter (%) at every step end."""
    d = read_table(point / "displacements.csv")
    tools = read_table(point / "tool_forces.csv")
    red, change = [0.0], [0.0]
    for k in np.unique(d["step"]):
        h = RING_H0 + 2 * tools["U2"][tools["step"] == k][-1]
        r = (d["x"] + d["u1"])[(d["step"] == k) & np.isclose(d["x"], RING_R0)]
        red.append(100 * (1 - h / RING_H0))
        change.append(100 * (r.min() / RING_R0 - 1))
    return np.array(red), np.array(change)


def ring(work: Path, jobs: int) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sweep = work / "ring_sweep"
    lagamine("sweep", "decks/ring.dat", "--set", "PHI=" + ",".join(f"{p:g}" for p in PHIS),
             "-o", str(sweep), "-j", str(jobs))
    rows = []
    fig, ax = plt.subplots(figsize=(7, 5))
    for phi in PHIS:
        red, change = bore_curve(sweep / f"PHI={phi:g}")
        ax.plot(red, change, "o-", label=f"φ = {phi:g}")
        rows += [(phi, r, c) for r, c in zip(red, change)]
        print(f"phi = {phi:g}: " + ", ".join(f"{r:.0f} % -> {c:+.2f} %" for r, c in zip(red, change)))
    red = np.linspace(0, 50, 51)
    ax.plot(red, 100 * (np.sqrt(1 / (1 - red / 100)) - 1), "k--", lw=1,
            label="φ = 0 closed form √(H0/H) − 1")
    ax.axhline(0, color="grey", lw=0.5)
    ax.set_xlabel("height reduction (%)")
    ax.set_ylabel("change of the bore's smallest diameter (%)")
    ax.set_title("ring 6 : 3 : 2, perfectly plastic: friction-calibration chart (decks/ring.dat)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "images" / "ring_chart.png", dpi=100)
    with open(ROOT / "docs" / "data" / "ring_chart.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(("phi", "height_reduction_pct", "bore_diameter_change_pct"))
        w.writerows((f"{p:g}", f"{r:.4f}", f"{c:.4f}") for p, r, c in rows)


def rolling(work: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from lagamine_py.checks import evaluate_checks
    from lagamine_py.checks.forming import rolling_slab
    from lagamine_py.deck import load_deck
    out = work / "rolling"
    lagamine("run", "decks/rolling.dat", "-o", str(out), "-q", "--overwrite")
    res = {c["name"]: c for c in evaluate_checks(load_deck(ROOT / "decks" / "rolling.dat").checks, out)}
    slab = res["SLAB"]
    for q in ("force", "torque", "forward_slip"):
        print(f"rolling {q}: {slab['measured'][q]:.6g} against the slab's {slab['closed_form'][q]:.6g} "
              f"({100 * (slab['measured'][q] / slab['closed_form'][q] - 1):+.2f} %)")
    print(f"energy balance, worst step end: {100 * res['ENERGY']['error']:.3f} % of the work")
    cf = rolling_slab(250.0, 0.1, 100.0, 2.0, 1.6, profile=True)
    c = read_table(out / "contact.csv")
    final = c["step"] == c["step"].max()
    last = final & (c["increment"] == c["increment"][final].max())
    tools = read_table(out / "tool_forces.csv")
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.5))
    order = np.argsort(c["x"][last])
    ax.plot(c["x"][last][order], c["p"][last][order], "o-", ms=3, label="p, run")
    ax.plot(c["x"][last][order], c["tau"][last][order], "s-", ms=3, label="τ, run")
    ax.plot(-cf["x"], cf["p"], "k--", label="p, slab (von Kármán)")
    # tau > 0 pulls a top face towards -x: the entry zone draws the strip to +x, tau = -phi p
    tau = 0.1 * cf["p"] * np.where(cf["x"] >= cf["neutral"], -1.0, 1.0)
    ax.plot(-cf["x"], tau, "k:", label="τ = ∓φ p, slab")
    ax.axvline(-cf["neutral"], color="grey", lw=0.5)
    ax.set_xlim(-1.2 * cf["length"], 0.4 * cf["length"])
    ax.set_xlabel("x (mm): entry at −L = −6.32, roll centre at 0")
    ax.set_ylabel("contact stress (MPa)")
    ax.set_title("roll gap at the end (strip moving +x)")
    ax.legend(fontsize=8)
    turning = tools["step"] >= 3
    bx.plot(tools["UR6"][turning], -tools["RF2"][turning], "C0", label="roll force |RF2|, run")
    bx.axhline(cf["force"], color="C0", ls="--", lw=1, label="roll force, slab")
    bx.set_ylim(0, 1.5 * cf["force"])
    bx.set_ylabel("roll force (N/mm)", color="C0")
    tx = bx.twinx()
    tx.plot(tools["UR6"][turning], tools["RM6"][turning], "C1", label="torque RM6, run")
    tx.axhline(cf["torque"], color="C1", ls="--", lw=1, label="torque, slab")
    tx.set_ylim(0, 1.5 * cf["torque"])
    tx.set_ylabel("roll torque (N mm/mm)", color="C1")
    bx.set_xlabel("roll angle (rad); STEADY from 0.04")
    bx.set_title("roll force and torque per unit width")
    bx.legend(loc="lower left", fontsize=8)
    tx.legend(loc="lower right", fontsize=8)
    fig.suptitle("decks/rolling.dat: R = 100, 2 → 1.6 mm, φ = 0.1, perfectly plastic")
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "images" / "rolling.png", dpi=100)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", choices=("upsetting", "ring", "rolling"))
    ap.add_argument("--work", type=Path, default=ROOT / "out" / "forming",
                    help="directory for the runs (default out/forming)")
    ap.add_argument("-j", "--jobs", type=int, default=2, help="sweep points at a time (ring)")
    args = ap.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    if args.scene == "upsetting":
        upsetting(args.work)
    elif args.scene == "ring":
        ring(args.work, args.jobs)
    else:
        rolling(args.work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
