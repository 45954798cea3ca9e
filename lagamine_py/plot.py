"""``lagamine-py plot RUN``: the pictures a user would otherwise build by hand.

* ``interface.png``: p and tau along the interface at chosen states, like figure 6 of the paper
  (abscissa: the coordinate along which the interface runs, x for a block on a flat, z for a tube);
* ``forces.png``: total contact forces P and T against time, and T / P (the friction coefficient
  once the whole interface slides), the ends of the steps marked;
* ``mesh.png``: the deformed mesh at the end of each step (or at the chosen states), coloured by the
  equivalent plastic strain on one colour scale, the undeformed mesh in grey and the foundation
  drawn; axisymmetric runs are drawn with the axis z horizontal and r vertical.

States (``--states``): a comma-separated list of ``STEP:INC`` (an output increment of a step),
``STEP`` or ``STEP:end`` (the last increment of a step) and ``@TIME`` (the output increment nearest
to that total time).  Default: the end of each step, and the thirds (in time) of the last step.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .core.exits import EXIT_DECK, EXIT_OK, EXIT_OTHER
from .elements import outline_of_cell
from .results import RunResults, read_table, read_vtu

__all__ = ["State", "chosen_states", "parse_states", "plot_interface", "plot_forces", "plot_mesh",
           "plot_run"]

DPI = 120
MAX_MESH_PANELS = 6


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


# -- states ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class State:
    """An output state of a run: step, increment, total time and a label for legends."""
    step: int
    increment: int
    time: float
    label: str = ""


def _increments(table: dict) -> list[tuple[int, int, float]]:
    """Sorted unique (step, increment, time) rows of a table with those columns."""
    rows = zip(table["step"].astype(int).tolist(), table["increment"].astype(int).tolist(),
               table["time"].astype(float).tolist())
    seen: dict[tuple[int, int], float] = {}
    for s, i, t in rows:
        seen.setdefault((s, i), t)
    return sorted((s, i, t) for (s, i), t in seen.items())


def _nearest(rows, time: float):
    return min(rows, key=lambda r: (abs(r[2] - time), r[0], r[1]))


def _default_states(rows) -> list[tuple[int, int, float, str]]:
    """End of each step, and the states nearest to 1/3 and 2/3 of the last step's time span."""
    steps = sorted({r[0] for r in rows})
    out = [(*[r for r in rows if r[0] == s][-1], "end") for s in steps]
    last = [r for r in rows if r[0] == steps[-1]]
    earlier = [r for r in rows if r[0] < steps[-1]]
    t0 = earlier[-1][2] if earlier else 0.0
    for frac, name in ((1 / 3, "1/3"), (2 / 3, "2/3")):
        out.append((*_nearest(last, t0 + frac * (last[-1][2] - t0)), name))
    return out


def parse_states(spec: str | None, rows) -> list[tuple[int, int, float, str]]:
    """``spec`` (see the module docstring) -> (step, increment, time, how) rows of ``rows``.

    Raises ValueError naming the item that does not match an output increment."""
    if spec is None or spec.strip().lower() in ("", "default"):
        return _default_states(rows)
    out = []
    for item in (s.strip() for s in spec.split(",") if s.strip()):
        if item.startswith("@"):
            try:
                t = float(item[1:])
            except ValueError:
                raise ValueError(f"state {item!r}: expected @TIME, a number after @") from None
            out.append((*_nearest(rows, t), f"t ~ {t:g}"))
            continue
        step_s, _, inc_s = item.partition(":")
        try:
            step = int(step_s)
        except ValueError:
            raise ValueError(f"state {item!r}: expected STEP, STEP:INC, STEP:end or @TIME") from None
        in_step = [r for r in rows if r[0] == step]
        if not in_step:
            raise ValueError(f"state {item!r}: the run has no output in step {step} "
                             f"(steps {sorted({r[0] for r in rows})})")
        if inc_s.strip().lower() in ("", "end", "last"):
            out.append((*in_step[-1], "end"))
            continue
        try:
            inc = int(inc_s)
        except ValueError:
            raise ValueError(f"state {item!r}: increment {inc_s!r} is not a number or 'end'") from None
        match = [r for r in in_step if r[1] == inc]
        if not match:
            raise ValueError(f"state {item!r}: step {step} has no output increment {inc} "
                             f"(it has {in_step[0][1]}..{in_step[-1][1]})")
        out.append((*match[0], f"inc {inc}"))
    return out


def chosen_states(contact: dict, spec: str | None = None,
                  step_names: dict[int, str] | None = None) -> list[State]:
    """The states to draw, sorted by time, without repeats.

    Parameters
    ----------
    contact : table with ``step``, ``increment``, ``time`` columns (e.g. contact.csv).
    spec : ``--states`` text, or None for the default (end of each step, thirds of the last).
    step_names : step number -> name, for the labels.
    """
    rows = _increments(contact)
    if not rows:
        return []
    names = step_names or {}
    picked: dict[tuple[int, int], State] = {}
    for s, i, t, how in parse_states(spec, rows):
        name = f" {names[s]}" if s in names else ""
        picked.setdefault((s, i), State(s, i, t, f"step {s}{name}, {how} (t = {t:.4g})"))
    return sorted(picked.values(), key=lambda st: (st.time, st.step, st.increment))


# -- run metadata ------------------------------------------------------------------------------
def _step_names(run: Path) -> dict[int, str]:
    """step number -> step name, from the status file of the run (empty when absent)."""
    sta = sorted(Path(run).glob("*.sta"))
    if not sta:
        return {}
    t = read_table(sta[0])
    if "step_name" not in t or "step" not in t:
        return {}
    return {int(s): str(n) for s, n in zip(t["step"], t["step_name"])}


def is_axisymmetric(run: Path) -> bool:
    """True when the deck of the run (named in its restart file) is axisymmetric; False when the
    deck cannot be found or read."""
    path = Path(run) / "restart.npz"
    if not path.exists():
        return False
    try:
        deck = Path(str(np.load(path, allow_pickle=False)["deck"]))
        from .deck import load_deck
        return bool(load_deck(deck).axisymmetric)
    except Exception:              # no deck recorded, moved, or no longer valid: plane axes
        return False


# -- interface ---------------------------------------------------------------------------------
def _along(c: dict, axisym: bool) -> tuple[str, str]:
    """(column, axis label) of the coordinate along which the interface runs: the one of x, y
    with the larger spread of the contact points."""
    spread = {k: float(np.ptp(c[k])) if len(c[k]) else 0.0 for k in ("x", "y")}
    col = "x" if spread["x"] >= spread["y"] else "y"
    label = {"x": "r" if axisym else "x", "y": "z" if axisym else "y"}[col]
    return col, label


def interface_curves(c: dict, states: list[State], col: str) -> list[tuple[int, int, str, dict]]:
    """(state index, pair index, label, {s, p, tau, stick}) of every curve of the interface
    chart: one per state and contact pair (contact.csv names the pairs in its ``contact``
    column; a table without it is one pair), the points of a curve in order along ``col``."""
    step, inc = c["step"].astype(int), c["increment"].astype(int)
    pairs = sorted(set(c["contact"])) if "contact" in c else [None]
    curves = []
    for i, st in enumerate(states):
        for j, pair in enumerate(pairs):
            m = (step == st.step) & (inc == st.increment)
            if pair is not None:
                m &= c["contact"] == pair
            if not m.any():
                continue
            order = np.argsort(c[col][m], kind="stable")
            stick = (np.asarray(c["status"][m][order] == "stick", bool) if "status" in c
                     else np.zeros(int(m.sum()), bool))
            label = st.label if len(pairs) == 1 else f"{st.label}, {pair}"
            curves.append((i, j, label, {"s": c[col][m][order], "p": c["p"][m][order],
                                         "tau": c["tau"][m][order], "stick": stick}))
    return curves


def plot_interface(res: RunResults, outdir: Path, states: list[State],
                   axisym: bool = False) -> Path | None:
    """p and tau along the interface, one curve per state (figure 6 of the paper) and contact
    pair (line styles tell the pairs apart)."""
    c = res.table("contact.csv")
    if not c or len(c.get("p", [])) == 0 or not states:
        return None
    plt = _pyplot()
    col, label = _along(c, axisym)
    fig, (ax_p, ax_t) = plt.subplots(2, 1, sharex=True, figsize=(8, 6.5), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(states)))
    styles = ("-", "--", ":", "-.")
    for i, j, name, cv in interface_curves(c, states, col):
        colour, ls = colours[i], styles[j % len(styles)]
        ax_p.plot(cv["s"], cv["p"], ".", ls=ls, color=colour, ms=4, label=name)
        ax_t.plot(cv["s"], cv["tau"], ".", ls=ls, color=colour, ms=4, label=name)
        # stick points ringed: the stick zone at a glance
        ax_t.plot(cv["s"][cv["stick"]], cv["tau"][cv["stick"]], "o", mfc="none", mec=colour, ms=6)
    ax_t.axhline(0.0, color="0.5", lw=0.6)
    if np.max(np.abs(c["tau"])) <= 1e-9 * max(float(np.max(np.abs(c["p"]))), 1e-300):
        ax_t.set_ylim(-1.0, 1.0)                # rounding noise only: do not blow it up
        ax_t.text(0.5, 0.75, "τ = 0 to rounding (frictionless)", transform=ax_t.transAxes,
                  ha="center", va="center", color="0.4")
    ax_p.set_ylabel("contact pressure p")
    ax_t.set_ylabel("friction stress τ")
    ax_t.set_xlabel(f"{label} of the contact point (deformed); rings: points that stick")
    ax_p.legend(fontsize=8, loc="best")
    for ax in (ax_p, ax_t):
        ax.grid(alpha=0.3)
    fig.suptitle("p and τ along the interface")
    return _save(fig, outdir / "interface.png")


# -- forces ------------------------------------------------------------------------------------
def _step_ends(res: RunResults) -> list[tuple[float, int]]:
    """(end time, step) of every step in the contact totals or the status file."""
    t = res.table("contact_totals.csv")
    rows = _increments(t) if t else []
    ends: dict[int, float] = {}
    for s, _, time in rows:
        ends[s] = max(time, ends.get(s, time))
    return sorted((time, s) for s, time in ends.items())


def plot_forces(res: RunResults, outdir: Path, step_names: dict[int, str] | None = None) -> Path | None:
    """Total contact forces P and T against time, and T / P where P is not negligible."""
    t = res.table("contact_totals.csv")
    if not t or len(t.get("P", [])) == 0:
        return None
    plt = _pyplot()
    fig, (ax_f, ax_r) = plt.subplots(2, 1, sharex=True, figsize=(8, 6),
                                     gridspec_kw={"height_ratios": (2, 1)}, constrained_layout=True)
    for name in sorted(set(t["contact"])):
        m = t["contact"] == name
        time, P, T = t["time"][m], t["P"][m], t["T"][m]
        ms = 3 if len(time) <= 60 else 0          # markers show the increments while they are few
        ax_f.plot(time, P, "o-", ms=ms, label=f"P, {name}")
        ax_f.plot(time, T, "s-", ms=ms, label=f"T, {name}")
        ok = np.abs(P) > 1e-9 * max(float(np.max(np.abs(P))), 1e-300)
        ax_r.plot(time[ok], T[ok] / P[ok], ".-", ms=ms, label=name)
    names = step_names or {}
    for end, s in _step_ends(res)[:-1]:
        for ax in (ax_f, ax_r):
            ax.axvline(end, color="0.6", ls="--", lw=0.8)
        ax_f.annotate(f"end of step {s} {names.get(s, '')}".rstrip(), (end, 1.0),
                      xycoords=("data", "axes fraction"), xytext=(-3, -3), textcoords="offset points",
                      ha="right", va="top", fontsize=8, color="0.4")
    ax_f.set_ylabel("total contact force")
    ax_r.set_ylabel("T / P")
    ax_r.set_xlabel("time")
    ax_f.legend(fontsize=8, loc="best")
    for ax in (ax_f, ax_r):
        ax.grid(alpha=0.3)
    fig.suptitle("total normal (P) and tangential (T) contact forces")
    return _save(fig, outdir / "forces.png")


# -- mesh --------------------------------------------------------------------------------------
def _outlines(grid) -> list[np.ndarray]:
    """The boundary of every cell of ``grid``: its nodes in order around it (the element class
    of its VTK cell type says how, :func:`lagamine_py.elements.outline_of_cell`)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    conn = vtk_to_numpy(grid.GetCells().GetConnectivityArray())
    offs = vtk_to_numpy(grid.GetCells().GetOffsetsArray())
    types = np.array([grid.GetCellType(k) for k in range(grid.GetNumberOfCells())])
    order = {t: list(outline_of_cell(int(t))) for t in np.unique(types)}
    return [conn[offs[k]:offs[k + 1]][order[types[k]]] for k in range(len(offs) - 1)]


@dataclass
class _Frame:
    """One drawn state: element outlines (reference and deformed), PEEQ, foundation lines."""
    state: State
    ref: list[np.ndarray]
    cur: list[np.ndarray]
    peeq: np.ndarray
    foundation: np.ndarray | None


def _frame(state: State, body: Path, foundation: Path | None, swap: bool) -> _Frame:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(body))
    reader.Update()
    grid = reader.GetOutput()
    X = vtk_to_numpy(grid.GetPoints().GetData())[:, :2]
    disp = grid.GetPointData().GetArray("displacement")     # absent under *OUTPUT, FIELDS= without U
    U = vtk_to_numpy(disp)[:, :2] if disp is not None else np.zeros_like(X)
    axes = [1, 0] if swap else [0, 1]
    x, X = (X + U)[:, axes], X[:, axes]
    cells = _outlines(grid)
    arr = grid.GetCellData().GetArray("PEEQ")
    peeq = vtk_to_numpy(arr).astype(float) if arr is not None else np.zeros(len(cells))
    fnd = read_vtu(foundation)["points"][:, :2][:, axes] if foundation is not None else None
    return _Frame(state, [X[c] for c in cells], [x[c] for c in cells], peeq, fnd)


def _files_at(res: RunResults, states: list[State]) -> list[tuple[State, Path, Path | None]]:
    """(state, body VTU, foundation VTU or None) for the states that have a VTU at their time."""
    files = res.pvd()
    out = []
    for st in states:
        tol = 1e-9 * max(1.0, abs(st.time))
        body = [f for t, part, f in files if part == 0 and abs(t - st.time) <= tol]
        fnd = [f for t, part, f in files if part == 2 and abs(t - st.time) <= tol]
        if body:
            out.append((st, body[-1], fnd[-1] if fnd else None))
    return out


def _mesh_states(res: RunResults, spec: str | None, names: dict[int, str]) -> list[State]:
    """States of the mesh figure: ``spec``, or the end of every step (the last ones when many)."""
    times = [(0, k + 1, t) for k, (t, part, _) in enumerate(res.pvd()) if part == 0]
    table = res.table("contact_totals.csv") or res.table("contact.csv")
    if table and len(table.get("step", [])):
        rows = _increments(table)
    elif res.table("reactions.csv"):
        rows = _increments(res.table("reactions.csv"))
    else:
        rows = times
    if not rows:
        return []
    if spec is None:
        spec = ",".join(str(s) for s in sorted({r[0] for r in rows}))
    states = chosen_states({"step": np.array([r[0] for r in rows]),
                            "increment": np.array([r[1] for r in rows]),
                            "time": np.array([r[2] for r in rows])}, spec, names)
    return states[-MAX_MESH_PANELS:]


def _layout(frames: list[_Frame]) -> tuple[int, int, tuple[float, float], np.ndarray]:
    """(rows, cols, figure size, view box [xmin, xmax, ymin, ymax]) for the panels: a wide body
    gives one column of panels, a tall one a row, each sized to the body's aspect ratio."""
    pts = np.concatenate([np.concatenate(f.cur + f.ref) for f in frames])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.06 * float(max(hi - lo))
    box = np.array([lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad])
    aspect = (box[3] - box[2]) / (box[1] - box[0])
    n = len(frames)
    if aspect <= 1.0:
        panel_h = float(np.clip(7.0 * aspect, 1.3, 4.0))
        return n, 1, (8.5, panel_h * n + 0.9), box
    panel_w = float(np.clip(5.0 / aspect, 1.3, 4.0))
    return 1, n, (max(panel_w * n + 1.8, 3.4), 6.2), box


def _peeq_norm(peeq: np.ndarray):
    """(colour norm, "linear" | "log" | "elastic") for the equivalent plastic strain: a log
    scale over three decades when a few elements stand far above the rest (the largest value more
    than 4 times the 90th percentile), so that the rest of the distribution still shows."""
    from matplotlib.colors import LogNorm, Normalize
    vmax = float(np.max(peeq)) if len(peeq) else 0.0
    if vmax <= 0.0:
        return Normalize(0.0, 1.0), "elastic"
    if 4.0 * float(np.percentile(peeq, 90)) < vmax:
        return LogNorm(1e-3 * vmax, vmax, clip=True), "log"
    return Normalize(0.0, vmax), "linear"


def plot_mesh(res: RunResults, outdir: Path, states: list[State], axisym: bool = False) -> Path | None:
    """Deformed meshes coloured by PEEQ (one colour scale), the undeformed mesh in grey and the
    foundation in brown; axisymmetric: z horizontal, r vertical."""
    found = _files_at(res, states)
    if not found:
        return None
    frames = [_frame(st, body, fnd, swap=axisym) for st, body, fnd in found]
    plt = _pyplot()
    from matplotlib.collections import PolyCollection
    rows, cols, size, box = _layout(frames)
    fig, axes = plt.subplots(rows, cols, figsize=size, squeeze=False, constrained_layout=True)
    norm, scale_note = _peeq_norm(np.concatenate([f.peeq for f in frames]))
    hl, vl = ("z", "r") if axisym else ("x", "y")
    coll = None
    for ax, f in zip(axes.ravel(), frames):
        ax.add_collection(PolyCollection(f.ref, facecolors="none", edgecolors="0.75", linewidths=0.4))
        coll = PolyCollection(f.cur, array=f.peeq, cmap="viridis", norm=norm, edgecolors="k",
                              linewidths=0.3)
        ax.add_collection(coll)
        if f.foundation is not None:
            ax.plot(f.foundation[:, 0], f.foundation[:, 1], "-", color="saddlebrown", lw=2.2,
                    label="foundation")
        ax.set_xlim(box[0], box[1])
        ax.set_ylim(box[2], box[3])
        ax.set_aspect("equal")
        ax.set_xlabel(hl)
        ax.set_ylabel(vl)
        ax.set_title(f.state.label, fontsize=9)
    label = "equivalent plastic strain" + {"linear": "", "log": " (log scale)",
                                           "elastic": " (elastic: 0 everywhere)"}[scale_note]
    fig.colorbar(coll, ax=axes.ravel().tolist(), label=label, shrink=0.9)
    sep = " " if size[0] >= 6.0 else "\n"          # a narrow figure gets a two-line title
    fig.suptitle(f"deformed mesh{sep}(grey: undeformed; brown: foundation)", fontsize=10)
    return _save(fig, outdir / "mesh.png")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    _pyplot().close(fig)
    return path


# -- command -----------------------------------------------------------------------------------
def plot_run(run: Path, output: Path | None = None, states: str | None = None,
             axes: str = "auto") -> int:
    """Write interface.png, forces.png and mesh.png of the run ``run`` into ``output``
    (default ``RUN/plots``); print their paths.  Exit status: 0, 1 when there is nothing to plot
    or ``run`` is not a directory, 2 for a bad ``states`` specification.

    ``axes``: ``auto`` (axisymmetric when the run's deck is), ``xy`` or ``rz``."""
    run = Path(run)
    if not run.is_dir():
        print(f"lagamine-py plot: {run} is not a directory", file=sys.stderr)
        return EXIT_OTHER
    res = RunResults(run)
    axisym = is_axisymmetric(run) if axes == "auto" else axes == "rz"
    names = _step_names(run)
    outdir = Path(output) if output else run / "plots"
    try:
        contact = res.table("contact.csv")
        chosen = chosen_states(contact, states, names) if contact and len(contact.get("step", [])) else []
        mesh_states = _mesh_states(res, states, names)
    except ValueError as exc:
        print(f"lagamine-py plot: {exc}", file=sys.stderr)
        return EXIT_DECK
    outdir.mkdir(parents=True, exist_ok=True)
    made = [p for p in (plot_interface(res, outdir, chosen, axisym),
                        plot_forces(res, outdir, names),
                        plot_mesh(res, outdir, mesh_states, axisym)) if p]
    for p in made:
        print(p)
    if not made:
        print(f"lagamine-py plot: nothing to plot in {run}", file=sys.stderr)
        return EXIT_OTHER
    return EXIT_OK
