"""``lagamine-py plot RUN``: the pictures a user would otherwise build by hand.

* ``interface.png``: p and tau along the interface at chosen states (default: the end of each
  step and the thirds of the last step), like figure 6 of the paper;
* ``forces.png``: total contact forces P and T against time;
* ``mesh.png``: the deformed mesh coloured by equivalent plastic strain, with the foundation.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .results import RunResults, read_vtu


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def chosen_states(contact: dict) -> list[tuple[int, int]]:
    """(step, increment) pairs: end of each step, and the thirds of the last step."""
    steps = contact["step"].astype(int)
    incs = contact["increment"].astype(int)
    pairs = sorted(set(zip(steps.tolist(), incs.tolist())))
    out = []
    for s in sorted(set(steps.tolist())):
        last = [p for p in pairs if p[0] == s]
        out.append(last[-1])
    last_step = [p for p in pairs if p[0] == pairs[-1][0]]
    for frac in (1 / 3, 2 / 3):
        out.append(last_step[max(0, int(round(frac * len(last_step))) - 1)])
    return sorted(set(out))


def plot_interface(res: RunResults, outdir: Path) -> Path | None:
    c = res.table("contact.csv")
    if not c or len(c.get("p", [])) == 0:
        return None
    plt = _pyplot()
    fig, (ax_p, ax_t) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for step, inc in chosen_states(c):
        m = (c["step"].astype(int) == step) & (c["increment"].astype(int) == inc)
        order = np.argsort(c["x"][m])
        t = c["time"][m][0]
        label = f"step {step}, inc {inc} (t = {t:.3g})"
        ax_p.plot(c["x"][m][order], c["p"][m][order], ".-", label=label)
        ax_t.plot(c["x"][m][order], c["tau"][m][order], ".-", label=label)
    ax_p.set_ylabel("contact pressure p")
    ax_t.set_ylabel("friction stress tau")
    ax_t.set_xlabel("x of the contact point")
    ax_p.legend(fontsize=7)
    for ax in (ax_p, ax_t):
        ax.grid(alpha=0.3)
    fig.suptitle("p and tau along the interface")
    fig.tight_layout()
    path = outdir / "interface.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_forces(res: RunResults, outdir: Path) -> Path | None:
    t = res.table("contact_totals.csv")
    if not t or len(t.get("P", [])) == 0:
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for name in sorted(set(t["contact"])):
        m = t["contact"] == name
        ax.plot(t["time"][m], t["P"][m], "o-", ms=3, label=f"P ({name})")
        ax.plot(t["time"][m], t["T"][m], "s-", ms=3, label=f"T ({name})")
    ax.set_xlabel("time")
    ax.set_ylabel("total contact force")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = outdir / "forces.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _outline(nen: int) -> list[int]:
    """Local node order tracing the element boundary (Q8: corner, mid, corner, ...)."""
    return [0, 4, 1, 5, 2, 6, 3, 7] if nen == 8 else [0, 1, 2, 3]


def plot_mesh(res: RunResults, outdir: Path) -> Path | None:
    files = res.pvd()
    bodies = [(t, f) for t, part, f in files if part == 0]
    if not bodies:
        return None
    t_last = bodies[-1][0]
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(bodies[-1][1]))
    reader.Update()
    grid = reader.GetOutput()
    X = vtk_to_numpy(grid.GetPoints().GetData())[:, :2]
    U = vtk_to_numpy(grid.GetPointData().GetArray("displacement"))[:, :2]
    x = X + U
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    offs = vtk_to_numpy(grid.GetCells().GetOffsetsArray())
    polys = []
    for k in range(len(offs) - 1):
        nodes = conn[offs[k]:offs[k + 1]]
        polys.append(x[nodes[_outline(len(nodes))]])
    peeq_arr = grid.GetCellData().GetArray("PEEQ")
    peeq = vtk_to_numpy(peeq_arr) if peeq_arr is not None else np.zeros(len(polys))
    plt = _pyplot()
    from matplotlib.collections import PolyCollection
    fig, ax = plt.subplots(figsize=(7, 5))
    coll = PolyCollection(polys, array=peeq, cmap="viridis", edgecolors="k", linewidths=0.3)
    ax.add_collection(coll)
    fig.colorbar(coll, ax=ax, label="equivalent plastic strain")
    for t, part, f in files:
        if part == 2 and t == t_last:
            fnd = read_vtu(f)["points"]
            ax.plot(fnd[:, 0], fnd[:, 1], "-", color="saddlebrown", lw=2, label="foundation")
            ax.legend(fontsize=8, loc="best")
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_title(f"deformed mesh at t = {t_last:.3g}")
    fig.tight_layout()
    path = outdir / "mesh.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_run(run: Path, output: Path | None = None) -> int:
    res = RunResults(run)
    if not Path(run).is_dir():
        print(f"lagamine-py plot: {run} is not a directory", file=sys.stderr)
        return 1
    outdir = Path(output) if output else Path(run) / "plots"
    outdir.mkdir(parents=True, exist_ok=True)
    made = [p for p in (plot_interface(res, outdir), plot_forces(res, outdir), plot_mesh(res, outdir)) if p]
    for p in made:
        print(p)
    if not made:
        print(f"lagamine-py plot: nothing to plot in {run}", file=sys.stderr)
        return 1
    return 0
