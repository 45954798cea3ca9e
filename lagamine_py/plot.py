"""``lagamine-py plot RUN``: the pictures a user would otherwise build by hand.

* ``interface.png``: p and tau along the interface at chosen states, like figure 6 of the paper
  (abscissa: the coordinate along which the interface runs, x for a block on a flat, z for a tube),
  zoomed on the closed contact zone when it is a small part of the interface (``--xlim`` to
  choose), the points that stick ringed;
* ``forces.png``: total contact forces P and T against time, and T / P (the friction coefficient
  once the whole interface slides), the ends of the steps marked;
* ``mesh.png``: the deformed mesh at the end of each step (or at the chosen states), coloured by the
  equivalent plastic strain on one colour scale, the undeformed mesh in grey and the foundation
  drawn; the displacements scaled so that the deformation shows (the factor is written on the
  figure; ``--scale`` to choose); axisymmetric runs are drawn with the axis z horizontal and r
  vertical.

Every axis says its unit (the deck's ``*UNITS``; "(deck units)" without it), every title the
deck; a state is labelled by the loads its step drives, as reached at that state (the ``load``
column of ``<deck>.sta``: imposed displacement, pressure, nodal force, tool motion), and its
time.  A panel whose values are all below 1e-9 of its scale (tau and T/P of a frictionless run)
is drawn as zero, not autoscaled onto round-off.

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

__all__ = ["State", "Units", "chosen_states", "parse_states", "plot_interface", "plot_forces",
           "plot_mesh", "plot_run", "deformation_scale", "closed_zone", "rounding_only"]

DPI = 120
MAX_MESH_PANELS = 6
#: a panel whose values are all below this fraction of its scale is drawn as zero
ROUNDING = 1e-9
#: the interface is zoomed on the closed zone when the zone spans less than this fraction of it
ZOOM_BELOW = 0.6
#: the displacements are scaled up until the largest is this fraction of the body's size ...
VISIBLE = 0.05
#: ... unless it is already this fraction of it
VISIBLE_ALREADY = 0.01


# -- units ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Units:
    """The deck's ``*UNITS`` (length, force, stress names; empty: none given) as axis labels."""
    names: tuple[str, ...]
    per_radian: bool = False             # axisymmetric: forces are per radian

    def of(self, kind: str) -> str:
        """`` (mm)`` for kind ``length``, ``force``, ``stress``; `` (deck units)`` without."""
        if len(self.names) != 3:
            return " (deck units)"
        unit = dict(zip(("length", "force", "stress"), self.names))[kind]
        return f" ({unit}/rad)" if kind == "force" and self.per_radian else f" ({unit})"

    def loads_text(self, loads: dict[str, float]) -> str:
        """``{"U1 RIGHT": -0.005}`` -> ``"U1 RIGHT = -0.005 mm"`` (items joined by ``, ``)."""
        items = []
        for label, value in loads.items():
            kind = ("stress" if label.startswith("P ") else "force" if label.startswith("CF")
                    else "length")
            unit = self.of(kind).strip(" ()") if len(self.names) == 3 else ""
            items.append(f"{label} = {value:.4g}{' ' + unit if unit else ''}")
        return ", ".join(items)


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
                  step_names: dict[int, str] | None = None,
                  loads: dict[tuple[int, int], dict[str, float]] | None = None,
                  units: "Units | None" = None) -> list[State]:
    """The states to draw, sorted by time, without repeats.

    Parameters
    ----------
    contact : table with ``step``, ``increment``, ``time`` columns (e.g. contact.csv).
    spec : ``--states`` text, or None for the default (end of each step, thirds of the last).
    step_names : step number -> name, for the labels.
    loads : (step, increment) -> the loads reached (the .sta ``load`` column), for the labels.
    units : for the loads' units in the labels.
    """
    rows = _increments(contact)
    if not rows:
        return []
    names = step_names or {}
    loads = loads or {}
    units = units or Units(())
    picked: dict[tuple[int, int], State] = {}
    for s, i, t, how in parse_states(spec, rows):
        name = f" {names[s]}" if s in names else ""
        reached = units.loads_text(loads.get((s, i), {}))
        label = f"step {s}{name}, {how}{': ' + reached if reached else ''} (t = {t:.4g})"
        picked.setdefault((s, i), State(s, i, t, label))
    return sorted(picked.values(), key=lambda st: (st.time, st.step, st.increment))


# -- run metadata ------------------------------------------------------------------------------
@dataclass
class RunInfo:
    """What the pictures say about a run besides its results: the deck's name, whether it is
    axisymmetric, its units, its steps' names and the loads reached at each increment."""
    deck: str
    axisymmetric: bool
    units: Units
    step_names: dict[int, str]
    loads: dict[tuple[int, int], dict[str, float]]


def _model_of(run: Path):
    """The model of the deck recorded in the run's directory, loaded with the run's parameter
    values, or None (no record, the deck moved, changed since the run or no longer reads)."""
    from .core.outdir import recorded_identity
    deck = recorded_identity(Path(run))
    if deck is None or not deck.path:
        return None
    try:
        from .deck import load_deck
        model = load_deck(Path(deck.path), parameters=deck.parameters or None)
    except Exception:              # moved, or no longer valid
        return None
    same = model.source is not None and (not deck.digest or model.source.digest == deck.digest)
    return model if same else None


def is_axisymmetric(run: Path) -> bool:
    """True when the deck of the run (named in its restart file) is axisymmetric; False when the
    deck cannot be found or read."""
    model = _model_of(run)
    return bool(model is not None and model.axisymmetric)


def run_info(run: Path, axes: str = "auto") -> RunInfo:
    """The :class:`RunInfo` of the run directory ``run``; ``axes`` as :func:`plot_run`."""
    run = Path(run)
    model = _model_of(run)
    axisym = bool(model is not None and model.axisymmetric) if axes == "auto" else axes == "rz"
    results = RunResults(run)
    deck = results.name or (model.name if model is not None else run.name)
    names, loads = {}, {}
    sta = results.own(".sta")
    if sta is not None:
        from .output.status import parse_load_text
        t = read_table(sta)
        ok = t.get("failed", np.array(["no"] * len(t.get("step", [])), dtype=object)) == "no"
        for k in np.flatnonzero(ok):
            s, i = int(t["step"][k]), int(t["increment"][k])
            if "step_name" in t:
                names[s] = str(t["step_name"][k])
            if "load" in t:
                loads[(s, i)] = parse_load_text(t["load"][k])
    units = Units(tuple(model.units) if model is not None else (), per_radian=axisym)
    return RunInfo(deck, axisym, units, names, loads)


def rounding_only(values, scale: float) -> bool:
    """Whether every value is below :data:`ROUNDING` of ``scale`` (a frictionless run's tau, T,
    T/P): such a panel is drawn as zero."""
    values = np.asarray(values, float)
    return not values.size or float(np.max(np.abs(values))) <= ROUNDING * abs(scale)


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


def closed_zone(curves, every: np.ndarray) -> tuple[float, float] | None:
    """The x-limits of the interface chart zoomed on the closed contact zone: the span of the
    points with p > 0 in the drawn curves, padded by a quarter of it on each side (at least
    the spacing of the points there); None when that span is not below :data:`ZOOM_BELOW` of
    the interface ``every`` (all its points) or nothing is closed."""
    closed = np.concatenate([cv["s"][cv["p"] > 0] for *_, cv in curves] or [np.zeros(0)])
    if not closed.size or not every.size:
        return None
    lo, hi = float(closed.min()), float(closed.max())
    full = float(np.ptp(every))
    if full <= 0 or hi - lo >= ZOOM_BELOW * full:
        return None
    spacing = float(np.max(np.diff(np.unique(np.concatenate([cv["s"] for *_, cv in curves])),
                                   prepend=lo), initial=0.0)) if curves else 0.0
    pad = max(0.25 * (hi - lo), min(spacing, 0.25 * full), 1e-12 * full)
    return max(lo - pad, float(every.min())), min(hi + pad, float(every.max()))


def plot_interface(res: RunResults, outdir: Path, states: list[State], info: RunInfo,
                   xlim: tuple[float, float] | None = None) -> Path | None:
    """p and tau along the interface, one curve per state (figure 6 of the paper) and contact
    pair (line styles tell the pairs apart), zoomed on the closed zone or on ``xlim``."""
    c = res.table("contact.csv")
    if not c or len(c.get("p", [])) == 0 or not states:
        return None
    plt = _pyplot()
    from matplotlib.lines import Line2D
    col, label = _along(c, info.axisymmetric)
    fig, (ax_p, ax_t) = plt.subplots(2, 1, sharex=True, figsize=(8.5, 7), constrained_layout=True)
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(states)))
    styles = ("-", "--", ":", "-.")
    curves = interface_curves(c, states, col)
    p_scale = max((float(np.max(np.abs(cv["p"]))) for *_, cv in curves), default=0.0)
    frictionless = rounding_only(np.concatenate([cv["tau"] for *_, cv in curves]), p_scale)
    for i, j, name, cv in curves:
        colour, ls = colours[i], styles[j % len(styles)]
        tau = np.zeros_like(cv["tau"]) if frictionless else cv["tau"]
        ax_p.plot(cv["s"], cv["p"], ".", ls=ls, color=colour, ms=4, label=name)
        ax_t.plot(cv["s"], tau, ".", ls=ls, color=colour, ms=4)
        # stick points ringed: the stick zone at a glance
        ax_t.plot(cv["s"][cv["stick"]], tau[cv["stick"]], "o", mfc="none", mec=colour, ms=7)
    ax_t.axhline(0.0, color="0.5", lw=0.6)
    if frictionless:
        ax_t.set_ylim(-1.0, 1.0)
        ax_t.text(0.5, 0.75, f"τ = 0 (|τ| below {ROUNDING:g} of p: frictionless)",
                  transform=ax_t.transAxes, ha="center", va="center", color="0.4")
    zoom = xlim if xlim is not None else closed_zone(curves, np.asarray(c[col], float))
    how = ""
    if zoom is not None:
        ax_p.set_xlim(*zoom)
        how = "" if xlim is not None else "; zoomed on the closed zone (--xlim to choose)"
    ax_p.set_ylabel("contact pressure p" + info.units.of("stress"))
    ax_t.set_ylabel("friction stress τ" + info.units.of("stress"))
    ax_t.set_xlabel(f"{label} of the contact point, deformed{info.units.of('length')}{how}")
    ring = Line2D([], [], ls="none", marker="o", mfc="none", mec="0.3", ms=7,
                  label="ring: the point sticks (others slip or are open)")
    ax_p.legend(handles=ax_p.get_legend_handles_labels()[0] + [ring], fontsize=8, loc="best")
    for ax in (ax_p, ax_t):
        ax.grid(alpha=0.3)
    fig.suptitle(f"{info.deck}: p and τ along the interface")
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


def plot_forces(res: RunResults, outdir: Path, info: RunInfo) -> Path | None:
    """Total contact forces P and T against time, and T / P where P is not negligible."""
    t = res.table("contact_totals.csv")
    if not t or len(t.get("P", [])) == 0:
        return None
    plt = _pyplot()
    fig, (ax_f, ax_r) = plt.subplots(2, 1, sharex=True, figsize=(8.5, 6.5),
                                     gridspec_kw={"height_ratios": (2, 1)}, constrained_layout=True)
    notes = []
    for name in sorted(set(t["contact"])):
        m = t["contact"] == name
        time, P, T = t["time"][m], t["P"][m], t["T"][m]
        ms = 3 if len(time) <= 60 else 0          # markers show the increments while they are few
        P_scale = float(np.max(np.abs(P))) if len(P) else 0.0
        if rounding_only(T, P_scale):
            T = np.zeros_like(T)
            notes.append(f"{name}: T = 0 (|T| below {ROUNDING:g} of P: frictionless)")
        ax_f.plot(time, P, "o-", ms=ms, label=f"P, {name}")
        ax_f.plot(time, T, "s-", ms=ms, label=f"T, {name}")
        ok = np.abs(P) > ROUNDING * max(P_scale, 1e-300)
        ax_r.plot(time[ok], T[ok] / P[ok], ".-", ms=ms, label=name)
    if notes and all(rounding_only(ln.get_ydata(), 1.0) for ln in ax_r.get_lines()):
        ax_r.set_ylim(-1.0, 1.0)
    for k, note in enumerate(notes):
        ax_r.text(0.5, 0.8 - 0.15 * k, note, transform=ax_r.transAxes, ha="center", va="center",
                  color="0.4", fontsize=8)
    for end, s in _step_ends(res)[:-1]:
        for ax in (ax_f, ax_r):
            ax.axvline(end, color="0.6", ls="--", lw=0.8)
        ax_f.annotate(f"end of step {s} {info.step_names.get(s, '')}".rstrip(), (end, 1.0),
                      xycoords=("data", "axes fraction"), xytext=(-3, -3), textcoords="offset points",
                      ha="right", va="top", fontsize=8, color="0.4")
    ax_f.set_ylabel("total contact force" + info.units.of("force"))
    ax_r.set_ylabel("T / P")
    ax_r.set_xlabel("time (the steps' time scale)")
    ax_f.legend(fontsize=8, loc="best")
    for ax in (ax_f, ax_r):
        ax.grid(alpha=0.3)
    fig.suptitle(f"{info.deck}: total normal (P) and tangential (T) contact forces")
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
    """One drawn state: element outlines (reference) and nodal displacements, PEEQ, and the
    foundations (reference points and displacements)."""
    state: State
    X: np.ndarray                 # (n, 2) reference nodes, in the drawing's axes
    U: np.ndarray                 # (n, 2) displacements, in the drawing's axes
    cells: list[np.ndarray]
    peeq: np.ndarray
    foundations: list[tuple[np.ndarray, np.ndarray]]

    def outlines(self, scale: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Reference and deformed (displacements times ``scale``) outlines of every cell."""
        x = self.X + scale * self.U
        return [self.X[c] for c in self.cells], [x[c] for c in self.cells]


def _frame(state: State, body: Path, foundations: list[Path], swap: bool) -> _Frame:
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
    cells = _outlines(grid)
    arr = grid.GetCellData().GetArray("element_PEEQ")
    peeq = vtk_to_numpy(arr).astype(float) if arr is not None else np.zeros(len(cells))
    fnd = []
    for f in foundations:
        v = read_vtu(f)
        d = v.get("point:displacement", np.zeros_like(v["points"]))
        fnd.append((v["points"][:, :2][:, axes], d[:, :2][:, axes]))
    return _Frame(state, X[:, axes], U[:, axes], cells, peeq, fnd)


def _files_at(res: RunResults, states: list[State]) -> list[tuple[State, Path, list[Path]]]:
    """(state, body VTU, foundation VTUs) for the states that have a body VTU at their time."""
    blocks = res.blocks()
    out = []
    for st in states:
        tol = 1e-9 * max(1.0, abs(st.time))
        at = [(name, f) for t, name, f in blocks if abs(t - st.time) <= tol]
        body = [f for name, f in at if name == "body"]
        if body:
            out.append((st, body[-1], [f for name, f in at if name.startswith("foundation")]))
    return out


def _mesh_states(res: RunResults, spec: str | None, info: RunInfo) -> list[State]:
    """States of the mesh figure: ``spec``, or the end of every step (the last ones when many)."""
    times = [(0, k + 1, t) for k, (t, name, _) in enumerate(res.blocks()) if name == "body"]
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
                            "time": np.array([r[2] for r in rows])}, spec, info.step_names,
                           info.loads, info.units)
    return states[-MAX_MESH_PANELS:]


def deformation_scale(displacement: np.ndarray, size: float) -> float:
    """The factor the displacements are drawn with: 1 when the largest is already
    :data:`VISIBLE_ALREADY` of the body's ``size``; else the round number (1, 2 or 5 times a
    power of ten) that brings it closest below :data:`VISIBLE` of the size."""
    umax = float(np.max(np.linalg.norm(np.asarray(displacement, float).reshape(-1, 2), axis=1),
                        initial=0.0))
    if umax <= 0.0 or size <= 0.0 or umax >= VISIBLE_ALREADY * size:
        return 1.0
    want = VISIBLE * size / umax
    decade = 10.0 ** np.floor(np.log10(want))
    return float(max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= want * (1 + 1e-12)))


def _layout(frames: list[_Frame], scale: float) -> tuple[int, int, tuple[float, float], np.ndarray]:
    """(rows, cols, figure size, view box [xmin, xmax, ymin, ymax]) for the panels: a wide body
    gives one column of panels, a tall one a row, each sized to the body's aspect ratio."""
    pts = np.concatenate([np.concatenate([f.X, f.X + scale * f.U]) for f in frames])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.06 * float(max(hi - lo))
    box = np.array([lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad])
    aspect = (box[3] - box[2]) / (box[1] - box[0])
    n = len(frames)
    if aspect <= 1.0:
        panel_h = float(np.clip(7.0 * aspect, 1.3, 4.0))
        return n, 1, (8.5, panel_h * n + 1.1), box
    panel_w = float(np.clip(5.0 / aspect, 1.3, 4.0))
    return 1, n, (max(panel_w * n + 1.8, 3.8), 6.4), box


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


def plot_mesh(res: RunResults, outdir: Path, states: list[State], info: RunInfo,
              scale: float | None = None) -> Path | None:
    """Deformed meshes coloured by PEEQ (one colour scale), the undeformed mesh in grey and the
    foundation in brown, the displacements times ``scale`` (default
    :func:`deformation_scale`); axisymmetric: z horizontal, r vertical."""
    found = _files_at(res, states)
    if not found:
        return None
    frames = [_frame(st, body, fnd, swap=info.axisymmetric) for st, body, fnd in found]
    if scale is None:
        size = float(max(np.ptp(np.concatenate([f.X for f in frames]), axis=0)))
        scale = deformation_scale(np.concatenate([f.U for f in frames]), size)
    plt = _pyplot()
    from matplotlib.collections import PolyCollection
    rows, cols, figsize, box = _layout(frames, scale)
    fig, axes = plt.subplots(rows, cols, figsize=figsize, squeeze=False, constrained_layout=True)
    norm, scale_note = _peeq_norm(np.concatenate([f.peeq for f in frames]))
    hl, vl = ("z", "r") if info.axisymmetric else ("x", "y")
    length = info.units.of("length")
    coll = None
    for ax, f in zip(axes.ravel(), frames):
        ref, cur = f.outlines(scale)
        ax.add_collection(PolyCollection(ref, facecolors="none", edgecolors="0.75", linewidths=0.4))
        coll = PolyCollection(cur, array=f.peeq, cmap="viridis", norm=norm, edgecolors="k",
                              linewidths=0.3)
        ax.add_collection(coll)
        for X, U in f.foundations:
            ax.plot(X[:, 0] + scale * U[:, 0], X[:, 1] + scale * U[:, 1], "-",
                    color="saddlebrown", lw=2.2)
        ax.set_xlim(box[0], box[1])
        ax.set_ylim(box[2], box[3])
        ax.set_aspect("equal")
        ax.set_xlabel(hl + length)
        ax.set_ylabel(vl + length)
        ax.set_title(f.state.label, fontsize=8.5)
    label = "equivalent plastic strain" + {"linear": "", "log": " (log scale)",
                                           "elastic": " (elastic: 0 everywhere)"}[scale_note]
    fig.colorbar(coll, ax=axes.ravel().tolist(), label=label, shrink=0.9)
    magnified = f"displacements × {scale:g}" if scale != 1.0 else "displacements true to scale"
    sep = " " if figsize[0] >= 6.0 else "\n"          # a narrow figure gets two-line titles
    fig.suptitle(f"{info.deck}: deformed mesh, {magnified}{sep}(grey: undeformed; brown: "
                 "foundation)", fontsize=10)
    return _save(fig, outdir / "mesh.png")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    _pyplot().close(fig)
    return path


# -- command -----------------------------------------------------------------------------------
def parse_xlim(text: str | None) -> tuple[float, float] | None:
    """``"2,4.5"`` -> (2.0, 4.5); None for None; ValueError naming the text otherwise."""
    if text is None:
        return None
    parts = [p for p in str(text).replace(" ", "").split(",") if p]
    try:
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--xlim {text!r}: expected two numbers, MIN,MAX") from None
    if not lo < hi:
        raise ValueError(f"--xlim {text!r}: MIN must be below MAX")
    return lo, hi


def plot_run(run: Path, output: Path | None = None, states: str | None = None,
             axes: str = "auto", xlim: str | tuple[float, float] | None = None,
             scale: float | None = None) -> int:
    """Write interface.png, forces.png and mesh.png of the run ``run`` into ``output``
    (default ``RUN/plots``); print their paths.  Exit status: 0, 1 when there is nothing to plot
    or ``run`` is not a directory, 2 for a bad ``states``, ``xlim`` or ``scale``.

    ``axes``: ``auto`` (axisymmetric when the run's deck is), ``xy`` or ``rz``; ``xlim``: the
    interface chart's abscissa range (``"MIN,MAX"``; default: zoomed on the closed zone);
    ``scale``: the factor of the displacements in the mesh picture (default: chosen so that
    the deformation shows)."""
    run = Path(run)
    if not run.is_dir():
        print(f"lagamine-py plot: {run} is not a directory", file=sys.stderr)
        return EXIT_OTHER
    res = RunResults(run)
    info = run_info(run, axes)
    outdir = Path(output) if output else run / "plots"
    try:
        limits = xlim if isinstance(xlim, tuple) else parse_xlim(xlim)
        if scale is not None and not float(scale) > 0:
            raise ValueError(f"--scale {scale}: must be a positive number")
        contact = res.table("contact.csv")
        chosen = (chosen_states(contact, states, info.step_names, info.loads, info.units)
                  if contact and len(contact.get("step", [])) else [])
        mesh_states = _mesh_states(res, states, info)
    except ValueError as exc:
        print(f"lagamine-py plot: {exc}", file=sys.stderr)
        return EXIT_DECK
    outdir.mkdir(parents=True, exist_ok=True)
    made = [p for p in (plot_interface(res, outdir, chosen, info, limits),
                        plot_forces(res, outdir, info),
                        plot_mesh(res, outdir, mesh_states, info, scale)) if p]
    for p in made:
        print(p)
    if not made:
        print(f"lagamine-py plot: nothing to plot in {run}", file=sys.stderr)
        return EXIT_OTHER
    return EXIT_OK
