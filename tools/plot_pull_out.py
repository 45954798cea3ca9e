"""Pull-out force against end displacement of a run whose end is pulled by *BOUNDARY.

    python tools/plot_pull_out.py RUN [--nset TUBE_TOP] [--dof 2] [--foundation END_PIECE]
                                      [--length 16] [--steps PULL] [-o FILE.png]

Reads ``RUN/<deck>.sta`` (the displacement the step imposed on NSET, its ``load`` column),
``RUN/reactions.csv`` (NSET's reaction along DOF) and ``RUN/tool_forces.csv`` (the force of the
foundation on the bodies, when ``--foundation`` is given) over the steps whose name starts with
``--steps``, and draws the force against the displacement, with the step ends marked.  In
axisymmetry the tables hold forces per radian: the chart shows the whole ring (2 pi times) in kN
(for a deck in mm, N).  ``--length`` adds the displacement as a percentage of that length on the
top axis.  Prints the chart's path and the force at every step end.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _imposed(sta: list[dict], nset: str, dof: int) -> dict[tuple[str, str], float]:
    """(step, increment) -> the displacement the step imposed on ``nset`` (converged rows)."""
    key = f"U{dof} {nset.upper()}="
    out = {}
    for r in sta:
        if r.get("failed", "no") != "no":
            continue
        for item in (r.get("load") or "").split(";"):
            item = item.strip()
            if item.upper().startswith(key):
                out[(r["step"], r["increment"])] = float(item[len(key):])
    return out


def pull_out_curve(run: Path, nset: str, dof: int, steps: str, foundation: str | None):
    """Rows (step name, end of step?, displacement, reaction, tool force) of the pull steps,
    forces per radian (axisymmetric) or per unit thickness as the tables hold them."""
    sta_files = sorted(run.glob("*.sta"))
    if not sta_files:
        raise SystemExit(f"plot_pull_out: no .sta file in {run}")
    sta = _rows(sta_files[0])
    names = {r["step"]: r["step_name"] for r in sta}
    last = {}
    for r in sta:
        if r.get("failed", "no") == "no":
            last[r["step"]] = r["increment"]
    u = _imposed(sta, nset, dof)
    rf = {(r["step"], r["increment"]): float(r[f"RF{dof}"])
          for r in _rows(run / "reactions.csv") if r["nset"].upper() == nset.upper()}
    tool = {}
    if foundation:
        tool = {(r["step"], r["increment"]): float(r[f"RF{dof}"])
                for r in _rows(run / "tool_forces.csv") if r["foundation"].upper() == foundation.upper()}
    out = []
    for key in sorted(u, key=lambda k: (int(k[0]), int(k[1]))):
        if not names.get(key[0], "").upper().startswith(steps.upper()) or key not in rf:
            continue
        out.append((names[key[0]], last.get(key[0]) == key[1], u[key], rf[key], tool.get(key)))
    if not out:
        raise SystemExit(f"plot_pull_out: no increment of a step named {steps}* imposes U{dof} on {nset}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("--nset", default="TUBE_TOP", help="the pulled node set (default TUBE_TOP)")
    ap.add_argument("--dof", type=int, default=2, choices=(1, 2), help="the pulled direction (default 2)")
    ap.add_argument("--foundation", default=None, help="also draw minus this foundation's force")
    ap.add_argument("--length", type=float, default=None, help="modelled length: top axis in %% of it")
    ap.add_argument("--steps", default="PULL", help="steps whose name starts with this (default PULL)")
    ap.add_argument("--plane", action="store_true", help="plane strain: forces as in the tables")
    ap.add_argument("-o", "--output", type=Path, default=None, help="PNG (default RUN/plots/pull_out.png)")
    args = ap.parse_args(argv)

    rows = pull_out_curve(args.run, args.nset, args.dof, args.steps, args.foundation)
    ring = 1.0 if args.plane else 2 * math.pi
    unit = "N per unit thickness" if args.plane else "kN, whole ring"
    scale = ring if args.plane else ring / 1000.0
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2))
    u = [0.0] + [r[2] for r in rows]
    f = [0.0] + [r[3] * scale for r in rows]
    ax.plot(u, f, "-o", ms=3, color="C0", label=f"reaction of {args.nset} (reactions.csv)")
    if args.foundation:
        ft = [-r[4] * scale for r in rows if r[4] is not None]
        ax.plot([r[2] for r in rows if r[4] is not None], ft, "x", ms=5, color="C3",
                label=f"minus the force of {args.foundation} (tool_forces.csv)")
    for name, end, d, force, _ in rows:
        if end:
            ax.axvline(d, color="0.6", lw=0.8, ls="--")
            ax.annotate(f"{name}\n{force * scale:.3g}", (d, force * scale), textcoords="offset points",
                        xytext=(-8, -28), ha="right", fontsize=8)
            print(f"{name}: end displacement {d:g}, force {force:.6g} per radian"
                  f" ({force * ring:.6g} whole ring)" if not args.plane else
                  f"{name}: end displacement {d:g}, force {force:.6g}")
    ax.set_xlabel(f"end displacement U{args.dof} of {args.nset} (mm)")
    ax.set_ylabel(f"pull-out force ({unit})")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=min(0.0, min(f)))
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    if args.length:
        top = ax.secondary_xaxis("top", functions=(lambda x: 100 * x / args.length,
                                                   lambda p: p * args.length / 100))
        top.set_xlabel(f"% of the modelled length {args.length:g} mm")
    ax.set_title(f"{args.run.name}: pull-out force against end displacement", fontsize=10)
    out = args.output or args.run / "plots" / "pull_out.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
