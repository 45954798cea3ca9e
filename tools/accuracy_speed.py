"""Accuracy against CPU time: what each modelling choice buys and costs, measured.

    python tools/accuracy_speed.py [-j 2] [--work DIR] [--scenes hertz_classic,partial_slip,...]

runs the study decks of ``tools/study_decks/`` over mesh density, element (Q8, Q8 reduced, Q4),
the contact integration rule (2 or 3 Gauss points, LOBATTO3, LINEAR), KP and KT,
METHOD=AUGMENTED, THETA, sub-intervals (fixed and AUTO), increment size and NLGEOM, and writes

* ``docs/data/accuracy_<scene>.csv``: one row per run (parameters, status, CPU and wall time,
  Newton iterations, error, and whether it is on the Pareto front);
* ``docs/images/accuracy_<scene>.png``: error against CPU time, the Pareto front marked;
* ``docs/data/accuracy_targets.csv``: per scene the cheapest run reaching 5 %, 1 %, 0.2 %,
  0.05 % (the tube scene has none: its 'error' is the alternation of the pressure).

The runs go to ``--work`` (default ``/tmp/lagamine_accuracy``); a rerun reuses the runs that
finished there (the sweep's ``point.json`` markers), so delete it to measure afresh.  Every
point runs as its own ``lagamine-py run`` process (``lagamine_py.sweep``), ``-j`` at a time,
BLAS pinned to one thread; CPU time is that of the process (``os.wait4``), start-up included.

Error measures (the docstring of each ``*_error`` function says more):

* the classic Hertz benchmark (``hertz_classic.dat``, R = 50, P = 1000 N/mm, force control):
  ``max(|a/a_H - 1|, |p0/p0_H - 1|)``, a_H = 0.525232 mm, p0_H = 1212.07 MPa;
* partial slip at nu = 0.3 (``partial_slip_study.dat``): the larger distance, in units of a_H,
  of the stick zone's two edges at Q = phi P / 2 from the coupled reference's;
* the tube deck (``decks/tube_crimp.dat`` with each rule): the alternation of the pressure
  over the groove bottom (:func:`tube_alternation`);

* Hertz (displacement-controlled, ``hertz_study.dat``): ``max(|a/a_H - 1|, |p0/p0_H - 1|)`` with
  the half-width a and the peak pressure p0 fitted to the run's last contact pressures
  (:func:`lagamine_py.checks.fit_hertz`) and a_H, p0_H the Hertz closed form at the force P the
  run reached;
* press-then-slide (``press_slide_study.dat``): ``max_t |T(t) - T_ref(t)| / (phi P_ref)`` over the
  slide step, T the total tangential contact force, against a fine reference run of the same
  scene (32 x 16 Q8, 3 Gauss points, dt = 0.025, THETA = 1/2, SUBSTEPS = AUTO);
* Cattaneo-Mindlin (``decks/cattaneo_mindlin.dat`` as it is, swept over MESH, ETYPE, KP = KT
  and DT): its ``*CHECK, TYPE=CATTANEO`` error, the stick half-width c at Q = phi P / 2 against
  a sqrt(1 - Q/(phi P)), relative to a;
* fretting, two deformable bodies (``decks/fretting.dat`` as it is, swept over MESH, KP = KT and
  DT): from its ``*CHECK, TYPE=FRETTING``, the larger error of the stick half-widths c (first
  loading, Cattaneo-Mindlin) and c' (first unloading at Q = 0, Mindlin-Deresiewicz), relative
  to a (:func:`fretting_error`).
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "tools" / "study_decks"
DOCS = ROOT / "docs"
TARGETS = (0.05, 0.01, 0.002, 0.0005)
sys.path.insert(0, str(ROOT))

from lagamine_py.checks.closed_forms import fit_hertz, hertz_closed_form  # noqa: E402
from lagamine_py.results import read_table  # noqa: E402
from lagamine_py.sweep import (PointDeckError, finished_row, load_point_checks,  # noqa: E402
                               point_digest, point_dirname, point_task, run_point)


# ------------------------------------------------------------------ running points
def run_points(deck: Path, points: list[dict[str, str]], workdir: Path, jobs: int,
               log=print) -> list[dict]:
    """Run the points ``jobs`` at a time (threads waiting on subprocesses); a point that
    finished in ``workdir`` before is reused.  Rows are the sweep's, plus ``dir``."""
    workdir.mkdir(parents=True, exist_ok=True)
    rows: list[dict | None] = []
    todo = []
    for p in points:                 # decks are read here, in this thread (registry loading)
        pointdir = workdir / point_dirname(p)
        digest = point_digest(deck, p)          # a point of a changed deck runs again
        row = finished_row(pointdir, digest)
        if row is None:
            try:
                todo.append((len(rows), p, pointdir, load_point_checks(deck, p), digest))
            except PointDeckError as exc:
                row = {"point": pointdir.name, **p, "status": 2, "reason": str(exc),
                       "cpu_s": math.nan, "wall_s": math.nan, "newton_iterations": 0}
        rows.append(None if row is None else {**row, "dir": pointdir})
    runner = partial(run_point, threads=1)
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futs = [(i, pool.submit(point_task, deck, p, d, c, runner, dg), d)
                for i, p, d, c, dg in todo]
        for k, (i, fut, d) in enumerate(futs):
            rows[i] = {**fut.result(), "dir": d}
            log(f"  [{k + 1}/{len(futs)}] {d.name}: status {rows[i]['status']}, "
                f"cpu {float(rows[i].get('cpu_s', math.nan)):.2f} s")
    return rows


def unique(points: list[dict[str, str]]) -> list[dict[str, str]]:
    seen, out = set(), []
    for p in points:
        key = tuple(sorted(p.items()))
        if key not in seen:
            seen.add(key)
            out.append(p)
    return out


def vary(base: dict[str, str], **axes) -> list[dict[str, str]]:
    """One-at-a-time variations of ``base``; a value may be a dict of several parameters."""
    pts = []
    for name, values in axes.items():
        for v in values:
            p = dict(base)
            p.update(v if isinstance(v, dict) else {name: str(v)})
            pts.append(p)
    return pts


# ------------------------------------------------------------------ Pareto and targets
def pareto(cost: np.ndarray, err: np.ndarray) -> np.ndarray:
    """Mask of the points no other point beats in both cost and error (NaN never on it)."""
    ok = np.isfinite(cost) & np.isfinite(err)
    front = np.zeros(len(cost), bool)
    order = np.lexsort((err, cost))
    best = np.inf
    for i in order:
        if ok[i] and err[i] < best:
            front[i] = True
            best = err[i]
    return front


def cheapest(rows: list[dict], target: float) -> dict | None:
    hits = [r for r in rows if r["status"] == 0 and r["error"] <= target]
    return min(hits, key=lambda r: r["cpu_s"]) if hits else None


# ------------------------------------------------------------------ Hertz
HERTZ_R, HERTZ_E, HERTZ_NU = 10.0, 200000.0, 0.3


def q4_split_mesh(src: Path, dst: Path) -> None:
    """Write a Q4 version of a Q8 mesh file: each Q8 split into 2 x 2 Q4 through its mid-side
    nodes and a centre node (the serendipity map at xi = eta = 0); faces split likewise."""
    lines = src.read_text().splitlines()
    nodes, elems, out, section = {}, {}, [], None
    for ln in lines:
        if ln.startswith("*"):
            section = ln.split(",")[0].upper()
        elif not ln.startswith("**") and section == "*NODE":
            n, x, y = ln.split(",")
            nodes[int(n)] = np.array([float(x), float(y)])
        elif not ln.startswith("**") and section == "*ELEMENT":
            v = [int(t) for t in ln.split(",")]
            elems[v[0]] = v[1:]
    nid = max(nodes) + 1
    sub = {}
    for e, (c1, c2, c3, c4, m5, m6, m7, m8) in sorted(elems.items()):
        centre = (-0.25 * sum(nodes[c] for c in (c1, c2, c3, c4))
                  + 0.5 * sum(nodes[m] for m in (m5, m6, m7, m8)))
        nodes[nid] = centre
        C = nid
        nid += 1
        base = 4 * (e - 1)
        sub[base + 1] = (c1, m5, C, m8)
        sub[base + 2] = (m5, c2, m6, C)
        sub[base + 3] = (C, m6, c3, m7)
        sub[base + 4] = (m8, C, m7, c4)
    # Q8 face -> (sub-element offset, face) pairs
    face_map = {1: ((1, 1), (2, 1)), 2: ((2, 2), (3, 2)), 3: ((3, 3), (4, 3)), 4: ((4, 4), (1, 4))}
    section = None
    for ln in lines:
        if ln.startswith("*"):
            section = ln.split(",")[0].upper()
            if section == "*NODE":
                out.append(ln)
                out += [f"{n}, {x:.15g}, {y:.15g}" for n, (x, y) in sorted(nodes.items())]
            elif section == "*ELEMENT":
                out.append(ln)
                out += [f"{k}, " + ", ".join(map(str, c)) for k, c in sorted(sub.items())]
            else:
                out.append(ln)
        elif ln.startswith("**"):
            out.append(ln)
        elif section == "*SURFACE":
            e, f = ln.split(",")
            for off, face in face_map[int(f.strip()[1:])]:
                out.append(f"{4 * (int(e) - 1) + off}, S{face}")
        elif section in ("*NODE", "*ELEMENT"):
            continue
        else:
            out.append(ln)
    dst.write_text("\n".join(out) + "\n")


def hertz_meshes() -> None:
    mesh_dir = STUDY / "meshes"
    mesh_dir.mkdir(exist_ok=True)
    for tag in ("coarse", "medium", "fine"):
        src = ROOT / "decks" / "meshes" / f"cylinder_quarter_{tag}.inp"
        (mesh_dir / f"cylinder_quarter_{tag}_q8.inp").write_text(src.read_text())
        q4_split_mesh(src, mesh_dir / f"cylinder_quarter_{tag}_q4.inp")


def last_pressures(run: Path) -> tuple | None:
    """``(x, p, P)`` of a Hertz quarter's last increment: the contact points' x and p, and the
    force P = 2 x (the quarter's total normal force); None when the tables cannot be read."""
    try:
        pts = read_table(run / "contact.csv")
        tot = read_table(run / "contact_totals.csv")
    except (OSError, ValueError):
        return None
    inc = np.asarray(pts["increment"], float) + 1e6 * np.asarray(pts["step"], float)
    last = inc == inc.max()
    P = 2.0 * abs(float(np.asarray(tot["P"], float)[-1]))
    return np.asarray(pts["x"], float)[last], np.asarray(pts["p"], float)[last], P


def hertz_error(row: dict) -> dict:
    """Fit a, p0 to the last increment's contact pressures; compare with Hertz at the reached
    force P = 2 x (quarter's total normal force)."""
    found = last_pressures(Path(row["dir"]))
    if found is None:
        return {"error": math.nan}
    x, p, P = found
    a, p0 = fit_hertz(x, p)
    a_h, p0_h = hertz_closed_form(P, HERTZ_R, HERTZ_E, HERTZ_NU)
    ea, ep = abs(a / a_h - 1.0), abs(p0 / p0_h - 1.0)
    return {"error": max(ea, ep), "err_a": ea, "err_p0": ep, "P": P, "a": a, "p0": p0}


HERTZ_ELEM = {"Q8": {"ELEM": "q8", "ETYPE": "Q8PE"}, "Q8R": {"ELEM": "q8", "ETYPE": "Q8PER"},
              "Q4": {"ELEM": "q4", "ETYPE": "Q4PE"}}


HERTZ_BASE = {"MESH": "medium", "ELEM": "q8", "ETYPE": "Q8PE", "GAUSS": "3", "KP": "1e8",
              "DT": "0.25", "NLGEOM": "NO", "DEPTH": "0.16"}


def hertz_points() -> list[dict[str, str]]:
    base = HERTZ_BASE
    pts = []
    for mesh in ("coarse", "medium", "fine"):
        m = dict(base, MESH=mesh)
        pts += vary(m, ELEM=list(HERTZ_ELEM.values()), GAUSS=(2, 3), NLGEOM=("NO", "YES"),
                    DT=(1, 0.25))
    pts += vary(base, KP=("1e6", "1e7", "1e9", "1e10"))
    pts += vary(dict(base, MESH="coarse"), KP=("1e7", "1e9"))
    pts += vary(dict(base, MESH="fine"), KP=("1e7", "1e9"))
    pts += [dict(base, MESH="fine", KP="1e7", **HERTZ_ELEM[e]) for e in ("Q4", "Q8R")]
    pts += [dict(base, MESH=m, KP="1e7", GAUSS="2", DT="1") for m in ("coarse", "medium", "fine")]
    # KP = 20 E / h (README), h = 0.267, 0.133, 0.0667 mm
    pts += [dict(base, MESH=m, KP=k, DT="1") for m, k in (("coarse", "1.5e7"), ("medium", "3e7"),
                                                          ("fine", "6e7"))]
    return unique(pts)


# ------------------------------------------------------------------ the classic Hertz benchmark
CLASSIC = {"R": 50.0, "E": 210000.0, "NU": 0.3, "P": 1000.0}      # a = 0.525232, p0 = 1212.07
#: MESH -> (elements across the even 1.2 mm zone, graded along the arc, graded to the top)
CLASSIC_MESHES = {"coarse": (12, 12, 10), "medium": (24, 14, 12), "fine": (48, 16, 14)}
CLASSIC_BASE = {"MESH": "medium", "GAUSS": "3", "KP": "8.4e7", "LAW": "penalty", "PTOL": "1e-3",
                "DT": "1"}
CLASSIC_KP = {"coarse": 4.2e7, "medium": 8.4e7, "fine": 1.68e8}       # 20 E / h


def classic_meshes(full: bool = False) -> None:
    """The quarter cylinders of ``hertz_classic.dat`` (``hertz50_<MESH>.inc``), or the lower
    halves of ``partial_slip_study.dat`` (``hertz50h_<MESH>.inc``): tools/make_meshes.py's
    half_cylinder."""
    sys.path.insert(0, str(ROOT / "tools"))
    from make_meshes import half_cylinder, write_inc
    (STUDY / "meshes").mkdir(exist_ok=True)       # a fresh checkout has none (hertz_meshes makes it too)
    for tag, (n_zone, n_arc, n_rad) in CLASSIC_MESHES.items():
        path = STUDY / "meshes" / f"hertz50{'h' if full else ''}_{tag}.inc"
        if path.exists():
            continue
        nodes, els, arc, tops, top, axis = half_cylinder(CLASSIC["R"], 1.2, n_zone, n_arc, n_rad,
                                                         full)
        sets = {"TOP": top} if full else {"TOP": top, "AXIS": axis}
        write_inc(path, nodes, els, "Q8PE", sets, {"ARC": arc, "TOPFACE": tops},
                  f"quarter of a cylinder R = 50 (classic Hertz benchmark), h = {1.2 / n_zone:.3g}"
                  f" mm over the first 1.2 mm; written by tools/accuracy_speed.py")
        lines = path.read_text().replace("<ETYPE>", "Q8PE").splitlines(keepends=True)
        path.write_text("".join(x for x in lines if "*PARAMETER ETYPE" not in x))


def classic_error(row: dict) -> dict:
    """a and p0 fitted to the last contact pressures against the closed form at P = 1000 N/mm
    (a = 0.525232 mm, p0 = 1212.07 MPa); the run's own force P (2 x the quarter's) is reported,
    it is 1000 to round-off (force control)."""
    found = last_pressures(Path(row["dir"]))
    if found is None:
        return {"error": math.nan}
    x, p, P = found
    a, p0 = fit_hertz(x, p)
    a_h, p0_h = hertz_closed_form(CLASSIC["P"], CLASSIC["R"], CLASSIC["E"], CLASSIC["NU"])
    ea, ep = a / a_h - 1.0, p0 / p0_h - 1.0
    return {"error": max(abs(ea), abs(ep)), "err_a": ea, "err_p0": ep, "P": P, "a": a, "p0": p0}


def classic_points() -> list[dict[str, str]]:
    pts = []
    for mesh, kp in CLASSIC_KP.items():
        base = dict(CLASSIC_BASE, MESH=mesh, KP=f"{kp:g}")
        pts.append(base)
        pts += vary(base, GAUSS=("2", "LOBATTO3", "LINEAR"))
        pts += vary(base, KP=("1e9", "1e10"))
        pts += [dict(base, KP="1e9", GAUSS=g) for g in ("LOBATTO3", "LINEAR")]
        pts += [dict(base, KP="1e10", GAUSS=g) for g in ("LOBATTO3", "LINEAR")]
        pts += [dict(base, LAW="augmented", PTOL=t, GAUSS=g) for t in ("1e-3", "1e-4")
                for g in ("3", "LINEAR")]
    return unique(pts)


def sweep_scene(scene: str, deck: Path, pts: list[dict], work: Path, jobs: int, error,
                names: list[str], base: dict[str, str]) -> list[dict]:
    """Run ``deck`` at every point of ``pts`` (in ``work/scene``), each converged row updated
    with ``error(row)`` (a dict with 'error'; NaN for a failed run), and write the scene."""
    print(f"{scene}: {len(pts)} runs")
    rows = run_points(deck, pts, work / scene, jobs)
    for r in rows:
        r.update(error(r) if r["status"] == 0 else {"error": math.nan})
    return write_scene(scene, rows, names, base)


def scene_hertz_classic(work: Path, jobs: int) -> list[dict]:
    classic_meshes()
    return sweep_scene("hertz_classic", STUDY / "hertz_classic.dat", classic_points(), work, jobs,
                       classic_error, ["MESH", "GAUSS", "KP", "LAW", "PTOL", "DT"], CLASSIC_BASE)


# ------------------------------------------------------------------ partial slip at nu = 0.3
#: the coupled reference (boundary elements, rigid flat, flat sheared towards +x, penalties
#: infinite), stick zone edges in units of the Hertz a_H at Q = phi P / 2
PARTIAL_REF = {"DRY": (-0.825, 0.032), "SMOOTH": (-0.676, 0.754)}
PARTIAL_PHI = 0.3
PARTIAL_BASE = {"MESH": "medium", "GAUSS": "3", "KP": "8.4e7", "PRESS": "DRY", "LAW": "penalty",
                "PTOL": "1e-3", "DT": "0.05", "TRAVEL": "0.004"}


def partial_error(row: dict) -> dict:
    """Stick-zone edges (:func:`lagamine_py.checks.closed_forms.stick_edges`, centre 0) at each
    shear increment, interpolated linearly in ``Q / (phi P)`` at 1/2, in units of a_H (Hertz at
    the P reached); error = the larger distance of the two edges from the reference's, in a_H."""
    from lagamine_py.checks.closed_forms import stick_edges
    run = Path(row["dir"])
    try:
        pts = read_table(run / "contact.csv")
        tot = read_table(run / "contact_totals.csv")
    except (OSError, ValueError):
        return {"error": math.nan}
    step, inc = np.asarray(pts["step"], int), np.asarray(pts["increment"], int)
    tstep, tinc = np.asarray(tot["step"], int), np.asarray(tot["increment"], int)
    P_all, T_all = np.abs(np.asarray(tot["P"], float)), np.abs(np.asarray(tot["T"], float))
    ratios, edges, a_hs = [], [], []
    for k in np.unique(inc[step == 2]):
        m = (step == 2) & (inc == k)
        j = np.where((tstep == 2) & (tinc == k))[0][-1]
        x = np.asarray(pts["x"], float)[m]
        p, tau = np.asarray(pts["p"], float)[m], np.asarray(pts["tau"], float)[m]
        ratio = np.where(p > 0, np.abs(tau) / np.where(p > 0, PARTIAL_PHI * p, 1.0), 0.0)
        a_h, _ = hertz_closed_form(P_all[j], CLASSIC["R"], CLASSIC["E"], CLASSIC["NU"])
        ratios.append(T_all[j] / (PARTIAL_PHI * P_all[j]))
        edges.append(np.array(stick_edges(x, np.asarray(pts["status"])[m], ratio, 0.0)) / a_h)
        a_hs.append(a_h)
    ratios, edges = np.array(ratios), np.array(edges)
    if len(ratios) < 2 or not ratios.min() <= 0.5 <= ratios.max():
        return {"error": math.nan}
    left = float(np.interp(0.5, ratios, edges[:, 0]))
    right = float(np.interp(0.5, ratios, edges[:, 1]))
    ref = PARTIAL_REF[row.get("PRESS", "DRY")]
    err = max(abs(left - ref[0]), abs(right - ref[1]))
    return {"error": err, "left": left, "right": right, "c": 0.5 * (right - left),
            "a": float(np.mean(a_hs))}


def partial_points() -> list[dict[str, str]]:
    pts = []
    for press in ("DRY", "SMOOTH"):
        for mesh, kp in CLASSIC_KP.items():
            if mesh == "fine":
                continue
            base = dict(PARTIAL_BASE, MESH=mesh, KP=f"{kp:g}", PRESS=press)
            pts.append(base)
            pts += vary(base, GAUSS=("2", "LINEAR"), KP=(f"{10 * kp:g}", f"{100 * kp:g}"),
                        DT=("0.025",))
            pts += [dict(base, LAW="augmented", PTOL=t, GAUSS=g) for t in ("1e-3", "1e-4")
                    for g in ("3", "LINEAR")]
            pts.append(dict(base, KP=f"{100 * kp:g}", GAUSS="LINEAR"))
    return unique(pts)


def scene_partial_slip(work: Path, jobs: int) -> list[dict]:
    classic_meshes(full=True)
    return sweep_scene("partial_slip", STUDY / "partial_slip_study.dat", partial_points(), work,
                       jobs, partial_error,
                       ["MESH", "GAUSS", "KP", "PRESS", "LAW", "PTOL", "DT", "TRAVEL"],
                       PARTIAL_BASE)


# ------------------------------------------------------------------ the tube deck's pressure
TUBE_DECK = ROOT / "decks" / "tube_crimp.dat"
TUBE_RULES = ("3", "2", "LINEAR", "LOBATTO3")


def tube_alternation(run: Path) -> dict:
    """The contact pressure over the groove bottom (z = 8..12) at the end of the run: its range
    and its alternation, the largest ``|p_i - (p_{i-1} + p_{i+1}) / 2|`` over neighbouring
    points, relative to the largest p there."""
    try:
        pts = read_table(run / "contact.csv")
    except (OSError, ValueError):
        return {"error": math.nan}
    step, inc = np.asarray(pts["step"], int), np.asarray(pts["increment"], int)
    last = (step == step.max()) & (inc == inc[step == step.max()].max())
    z, p = np.asarray(pts["y"], float)[last], np.asarray(pts["p"], float)[last]
    order = np.argsort(z)
    z, p = z[order], p[order]
    p = p[(z > 8.0) & (z < 12.0)]
    wiggle = float(np.abs(p[1:-1] - 0.5 * (p[:-2] + p[2:])).max() / p.max())
    return {"error": wiggle, "p_min": float(p.min()), "p_max": float(p.max())}


def scene_tube(work: Path, jobs: int) -> list[dict]:
    """decks/tube_crimp.dat at the end of the crimp with each contact integration rule (its
    GAUSS=2 replaced):
    the 'error' is the alternation of the pressure over the groove bottom (tube_alternation)."""
    text = TUBE_DECK.read_text()
    decks = work / "tube_decks"
    decks.mkdir(parents=True, exist_ok=True)
    rows = []
    for rule in TUBE_RULES:
        deck = decks / f"tube_{rule}.dat"
        deck.write_text(text.replace("LAW=FREE, GAUSS=2", f"LAW=FREE, GAUSS={rule}"))
        row = run_points(deck, [{}], work / f"tube_{rule}", 1)[0]
        row["GAUSS"] = rule
        row.update(tube_alternation(Path(row["dir"])) if row["status"] == 0
                   else {"error": math.nan})
        rows.append(row)
    return write_scene("tube", rows, ["GAUSS"], {"GAUSS": "2"})


# ------------------------------------------------------------------ press-then-slide
PS_PHI = 0.2
PS_REF = {"NX": "32", "NY": "16", "ETYPE": "Q8PE", "GAUSS": "3", "KP": "1.68e6",
          "KT": "1.68e6", "THETA": "0.5", "SUBSTEPS": "AUTO", "DT": "0.025", "NLGEOM": "YES"}


def ps_mesh(nx: int, ny: int) -> dict[str, str]:
    """Mesh parameters, with the top-row elements under the pressure (left 3/4)."""
    first = (ny - 1) * nx + 1
    return {"NX": str(nx), "NY": str(ny), "L1": str(first), "L2": str(first + 3 * nx // 4 - 1)}


def ps_history(run: Path) -> tuple[np.ndarray, np.ndarray, float] | None:
    """(t, T) over the slide step and P at its end, from contact_totals.csv."""
    try:
        tot = read_table(run / "contact_totals.csv")
    except (OSError, ValueError):
        return None
    step = np.asarray(tot["step"], float)
    t = np.asarray(tot["time"], float)[step == 2]
    if t.size == 0:
        return None
    T = np.abs(np.asarray(tot["T"], float)[step == 2])
    P = abs(float(np.asarray(tot["P"], float)[step == 2][-1]))
    return np.concatenate([[1.0], t]), np.concatenate([[0.0], T]), P


def ps_error(row: dict, ref: tuple) -> dict:
    """max |T(t) - T_ref(t)| / (phi P_ref) on t in [1, 2] (both linearly interpolated)."""
    h = ps_history(Path(row["dir"]))
    if h is None or ref is None or row["status"] != 0:
        return {"error": math.nan}
    t, T, P = h
    tr, Tr, Pr = ref
    grid = np.linspace(1.0, 2.0, 201)
    err = np.max(np.abs(np.interp(grid, t, T) - np.interp(grid, tr, Tr))) / (PS_PHI * Pr)
    return {"error": float(err), "T_over_phiP": float(T[-1] / (PS_PHI * P))}


def ps_points() -> list[dict[str, str]]:
    base = {**ps_mesh(16, 8), "ETYPE": "Q8PE", "GAUSS": "3", "KP": "1.68e6", "KT": "1.68e6",
            "THETA": "1", "SUBSTEPS": "1", "DT": "0.05", "NLGEOM": "YES"}
    pts = vary(base, MESH=(ps_mesh(8, 4), ps_mesh(24, 12)), ETYPE=("Q4PE", "Q8PER"),
               GAUSS=(2,), KP=({"KP": "1.68e5", "KT": "1.68e5"}, {"KP": "1.68e7", "KT": "1.68e7"}),
               KT=("1.68e5", "1.68e7"), THETA=(0, 0.5), SUBSTEPS=(4, "AUTO"),
               DT=(0.2, 0.0125), NLGEOM=("NO",))
    pts += vary(dict(base, **ps_mesh(8, 4)), ETYPE=("Q4PE",), DT=(0.2,), NLGEOM=("NO",))
    pts += [dict(base, **ps_mesh(8, 4), ETYPE="Q4PE", DT="0.2", NLGEOM="NO"),
            dict(base, **ps_mesh(32, 16), ETYPE="Q4PE")]
    # the same choices with the onset of full sliding sampled finely (DT = 0.003125 from the start
    # of the slide): the model's error apart from how coarse increments cut the knee of T(t)
    pts += vary(dict(base, DT="0.003125"), MESH=(ps_mesh(8, 4),), ETYPE=("Q4PE", "Q8PER"),
                GAUSS=(2,), THETA=(0, 0.5), NLGEOM=("NO",))
    return unique([base] + pts)


# ------------------------------------------------------------------ output
def label(params: dict[str, str], base: dict[str, str]) -> str:
    diff = [f"{k}={v}" for k, v in params.items()
            if base.get(k) != v and k not in ("L1", "L2", "ELEM")]
    return " ".join(diff) or "baseline"


def write_scene(scene: str, rows: list[dict], names: list[str], base: dict[str, str]) -> list[dict]:
    cost = np.array([float(r.get("cpu_s", math.nan)) for r in rows])
    err = np.array([float(r.get("error", math.nan)) if r["status"] == 0 else math.nan
                    for r in rows])
    front = pareto(cost, err)
    for r, f in zip(rows, front):
        r["pareto"] = bool(f)
        r["label"] = label({k: r[k] for k in names}, base)
    extra = [k for k in ("err_a", "err_p0", "P", "a", "p0", "T_over_phiP", "left", "right", "c",
                         "p_min", "p_max", "err_c", "err_c_rev", "cycle3", "stick_shift",
                         "q_rms_shifted")
             if any(k in r for r in rows)]
    cols = (["label", *names, "status", "cpu_s", "wall_s", "newton_iterations", "increments",
             "failed_attempts", "error", "pareto", *extra, "reason"])
    (DOCS / "data").mkdir(parents=True, exist_ok=True)
    with open(DOCS / "data" / f"accuracy_{scene}.csv", "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(c, "")) for c in cols])
    plot_scene(scene, rows, cost, err, front)
    return rows


def _cell(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def plot_scene(scene: str, rows, cost, err, front) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9, 6))
    ok = np.isfinite(err) & np.isfinite(cost)
    floor = 1e-5
    ax.loglog(cost[ok], np.maximum(err[ok], floor), "o", color="0.6", ms=5, label="runs")
    fi = np.where(front)[0]
    fi = fi[np.argsort(cost[fi])]
    ax.loglog(cost[fi], np.maximum(err[fi], floor), "-o", color="C3", ms=7, label="Pareto front")
    auto = [i for i, r in enumerate(rows) if r.get("SUBSTEPS") == "AUTO" and ok[i]]
    if auto:
        ax.loglog(cost[auto], np.maximum(err[auto], floor), "s", mfc="none", color="C0", ms=11,
                  label="SUBSTEPS=AUTO")
    for i in np.where(ok)[0]:
        if front[i] or rows[i]["label"] == "baseline":
            ax.annotate(rows[i]["label"], (cost[i], max(err[i], floor)), fontsize=7,
                        xytext=(4, 3), textcoords="offset points")
    failed = [i for i, r in enumerate(rows) if r["status"] != 0]
    if failed:
        ax.loglog(cost[failed], np.full(len(failed), floor), "x", color="k",
                  label=f"did not finish ({len(failed)})")
    for t in TARGETS:
        ax.axhline(t, color="0.8", lw=0.8, ls="--")
    ax.set_xlabel("CPU time of the run [s]")
    ax.set_ylabel("relative error")
    ax.set_title(f"{scene}: error against CPU time ({int(ok.sum())} runs)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    (DOCS / "images").mkdir(parents=True, exist_ok=True)
    fig.savefig(DOCS / "images" / f"accuracy_{scene}.png", dpi=110)
    plt.close(fig)


def write_targets(all_rows: dict[str, list[dict]]) -> None:
    """Rewrite the rows of the scenes run; the other scenes' rows stay as they were."""
    path = DOCS / "data" / "accuracy_targets.csv"
    kept = []
    if path.exists():
        with open(path, newline="") as fh:
            kept = [r for r in list(csv.reader(fh))[1:] if r and r[0] not in all_rows]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["scene", "target", "configuration", "error", "cpu_s"])
        w.writerows(kept)
        for scene, rows in all_rows.items():
            for t in TARGETS:
                best = cheapest(rows, t)
                if best is None:
                    w.writerow([scene, t, "none reached it", "", ""])
                else:
                    w.writerow([scene, t, best["label"], f"{best['error']:.4g}",
                                f"{best['cpu_s']:.3g}"])


def stored_rows(scene: str) -> list[dict]:
    """The rows of ``docs/data/accuracy_<scene>.csv`` as written by :func:`write_scene`, with
    the fields :func:`cheapest` reads as numbers."""
    with open(DOCS / "data" / f"accuracy_{scene}.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        r["status"] = int(r["status"])
        r["error"] = float(r["error"]) if r["error"] else math.nan
        r["cpu_s"] = float(r["cpu_s"]) if r["cpu_s"] else math.nan
    return rows


# ------------------------------------------------------------------ main
def scene_hertz(work: Path, jobs: int) -> list[dict]:
    hertz_meshes()
    return sweep_scene("hertz", STUDY / "hertz_study.dat", hertz_points(), work, jobs,
                       hertz_error, ["MESH", "ELEM", "ETYPE", "GAUSS", "KP", "DT", "NLGEOM", "DEPTH"],
                       HERTZ_BASE)


def scene_press_slide(work: Path, jobs: int) -> list[dict]:
    ref_params = {**PS_REF, **ps_mesh(32, 16)}
    pts = ps_points()
    print(f"press_slide: reference + {len(pts)} runs")
    deck = STUDY / "press_slide_study.dat"
    ref_row = run_points(deck, [ref_params], work / "press_slide_ref", 1)[0]
    ref = ps_history(Path(ref_row["dir"])) if ref_row["status"] == 0 else None
    if ref is None:
        print("press_slide: the reference run failed; errors are NaN", file=sys.stderr)
    rows = run_points(deck, pts, work / "press_slide", jobs)
    for r in rows:
        r.update(ps_error(r, ref))
    names = ["NX", "NY", "L1", "L2", "ETYPE", "GAUSS", "KP", "KT", "THETA", "SUBSTEPS", "DT",
             "NLGEOM"]
    return write_scene("press_slide", rows, names, pts[0])


CM_KP = {"coarse": "1.5e7", "medium": "3e7", "fine": "6e7"}      # 20 E / h (the deck's header)
CM_BASE = {"MESH": "coarse", "ETYPE": "Q8PER", "KP": "1.5e7", "DT": "0.1"}


def cm_points() -> list[dict[str, str]]:
    pts = []
    for mesh, kp in CM_KP.items():
        base = dict(CM_BASE, MESH=mesh, KP=kp)
        pts.append(base)
        if mesh != "fine":
            pts += vary(base, KP=(f"{float(kp) / 5:g}", f"{float(kp) * 5:g}"), DT=("0.2", "0.05"))
    pts.append(dict(CM_BASE, ETYPE="Q8PE"))
    return unique(pts)


def scene_cattaneo(work: Path, jobs: int) -> list[dict]:
    """decks/cattaneo_mindlin.dat as it is (its *CHECK CATTANEO error: stick half-width c
    against a sqrt(1 - Q/(phi P)) at Q = phi P / 2, relative to a)."""
    return sweep_scene("cattaneo", ROOT / "decks" / "cattaneo_mindlin.dat", cm_points(), work, jobs,
                       lambda r: {"error": float(r.get("STICK_error", math.nan))},
                       ["MESH", "ETYPE", "KP", "DT"], CM_BASE)


# ------------------------------------------------------------------ fretting (two bodies)
FRET_KP = {"coarse": "8e6", "medium": "1.6e7", "fine": "3.2e7"}      # 20 E* / h (the deck's)
FRET_BASE = {"MESH": "coarse", "KP": "8e6", "DT": "0.03125"}


def fretting_points() -> list[dict[str, str]]:
    pts = []
    for mesh, kp in FRET_KP.items():
        base = dict(FRET_BASE, MESH=mesh, KP=kp)
        pts.append(base)
        if mesh != "fine":
            pts += vary(base, DT=("0.0625",))
    pts += vary(FRET_BASE, KP=("1.6e6", "4e7"), DT=("0.015625",))
    return unique(pts)


def fretting_error(row: dict) -> dict:
    """From the deck's ``*CHECK FRETTING`` columns: the stick half-widths at the first loading
    (``c``, Cattaneo-Mindlin) and where the first unloading passes Q = 0 (``c'``,
    Mindlin-Deresiewicz), both in units of a; the error is the larger.  Reported besides: the
    third cycle's |W - D| / W, the stick zone's offset (units of a) and the RMS error of the
    shear traction at Q* with the stick term centred there (units of phi p0)."""
    def col(name):
        return float(row.get(f"FRETTING_{name}", math.nan))
    ec = abs(col("c_over_a") - col("c_over_a_cf"))
    er = abs(col("c_rev_over_a") - col("c_rev_over_a_cf"))
    W, D = col("W_3"), col("D_3")
    return {"error": max(ec, er), "err_c": ec, "err_c_rev": er, "cycle3": abs(W - D) / W,
            "stick_shift": col("stick_shift_over_a"), "q_rms_shifted": col("q_error_shifted")}


def scene_fretting(work: Path, jobs: int) -> list[dict]:
    """decks/fretting.dat as it is, swept over MESH (KP = KT = 20 E*/h), DT and KP."""
    return sweep_scene("fretting", ROOT / "decks" / "fretting.dat", fretting_points(), work, jobs,
                       fretting_error, ["MESH", "KP", "DT"], FRET_BASE)


SCENES = {"hertz_classic": scene_hertz_classic, "partial_slip": scene_partial_slip,
          "hertz": scene_hertz, "cattaneo": scene_cattaneo, "press_slide": scene_press_slide,
          "tube": scene_tube, "fretting": scene_fretting}
#: scenes whose 'error' is not an error against a reference (no targets)
NO_TARGETS = ("tube",)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--work", type=Path, default=Path("/tmp/lagamine_accuracy"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--targets-only", action="store_true",
                    help="rewrite accuracy_targets.csv from the stored scene tables, no runs")
    args = ap.parse_args(argv)
    all_rows = {}
    for scene in args.scenes.split(","):
        all_rows[scene] = (stored_rows(scene) if args.targets_only
                           else SCENES[scene](args.work, args.jobs))
    targets = {k: v for k, v in all_rows.items() if k not in NO_TARGETS}
    write_targets(targets)
    for scene, rows in targets.items():
        for t in TARGETS:
            best = cheapest(rows, t)
            print(f"{scene}: {t * 100:g} %: " + (f"{best['label']} ({best['error']:.3g}, "
                                          f"{best['cpu_s']:.2f} s CPU)" if best else "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
