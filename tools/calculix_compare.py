"""lagamine_py against CalculiX (``ccx`` 2.20, Debian's ``calculix-ccx``) on the scenes of issue 17.

One command writes both codes' decks of every scene, runs them paired (ours, CalculiX, ours,
CalculiX ...; best wall time of each, and least CPU time: user + system, which the other jobs
of a shared machine disturb less), and prints a markdown table: DOFs, wall times and their
ratio, the CPU-time ratio, peak resident memory of each process, and an answer of each code so that a reader sees
both solved the same problem::

    python tools/calculix_compare.py [--scenes S ...] [--sizes 16x8 40x20 80x40] [--repeat 2]
                                     [--keep DIR] [--write-decks] [--json F]

Scenes (``--scenes``; default all but ``block-8x4``):

``press-slide``   ``decks/press_slide.dat`` at each ``--sizes`` NXxNY (``tools/bench.py``'s
                  ``press_slide_deck``: pressed range and penalties adapted); answer T/P at the end.
``hertz-fine``    ``decks/hertz.dat`` with MESH=fine (KP=6e7, the deck's rule): a quarter cylinder
                  pressed on a frictionless flat; answer the half-width a and peak pressure p0 of
                  a least-squares Hertz fit of the last pressures (``checks.closed_forms.fit_hertz``,
                  the same function for both codes) and the force P.
``hertz-medium``  the same with MESH=medium (KP=3e7).
``cattaneo-medium`` ``decks/cattaneo_mindlin.dat`` with MESH=medium (KP=3e7): the half cylinder
                  pressed, then the flat moved sideways; answer the stick half-width c at
                  Q = phi P / 2 (interpolated between the shear increments, as the deck's check)
                  against a sqrt(1 - 1/2).
``cattaneo-fine`` the same with MESH=fine (KP=6e7, 15 114 DOFs: CalculiX 2.20 fails its shear
                  step, "too many cutbacks"); ``cattaneo-coarse`` with the deck's coarse mesh.
``block-20x10``   ``decks/coulomb_block_noadh.dat`` at 20x10 Q8 (1 322 DOFs; the adhesion of
                  ``coulomb_block.dat`` has no CalculiX counterpart); answer T/P.
``block-8x4``     the deck as it is (242 DOFs): the smallest scene, the one the test runs.

What is the same in both decks: the nodes and elements (CPE8 for Q8PE, CPE8R for Q8PER: the Q8
node and face order is CalculiX's), the material, the pressures on the same faces, the imposed
displacements of the same nodes, Coulomb friction with the same normal and tangential penalties
(``PRESSURE-OVERCLOSURE=LINEAR`` slope KP, ``*FRICTION`` stick slope KT; no ``*FRICTION`` when
PHI = 0), the steps and their first/maximum increments.  Every foundation of these scenes is a
straight rigid flat (the curved body is the deformable cylinder); in CalculiX it is a slab of CPE8
under the flat whose every node is prescribed (fixed, or moved as ``*FOUNDATION MOTION`` moves
the foundation), so it adds no unknown and cannot deform: exactly rigid, like ours, at no
solver cost, and its top face is the master of a surface-to-surface contact.  The slab's total
reaction is the contact force.  Two differences, neutral or in CalculiX's favour for the time:
the Ramberg-Osgood law is CalculiX's ``*DEFORMATION PLASTICITY`` (the same uniaxial curve, total
rather than incremental J2), and CalculiX expands the plane-strain elements into one layer of
20-node bricks.  Both run single-threaded (``OMP_NUM_THREADS=1``, ``MKL_NUM_THREADS=1``,
``CCX_NPROC_EQUATION_SOLVER=1``) and write results every increment (lagamine_py its default
output, CalculiX displacements and stresses and the contact tractions to the ``.frd``).

``--write-decks`` also writes both decks of each scene to ``tools/calculix_decks/`` (``NAME.dat``
ours, ``NAME.inp`` CalculiX's: ``ccx -i NAME`` there reruns CalculiX alone).
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import press_slide_deck  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"
OUT_DECKS = ROOT / "tools" / "calculix_decks"
SLAB_NX = 20            # elements of the fixed slab standing for the rigid flat
SLAB_H = 2.0            # its thickness (mm)
CCX_TYPES = {"Q8PE": "CPE8", "Q8PER": "CPE8R"}   # our plane-strain elements -> CalculiX's
STICK = 0.999           # |tau| / (phi p) below which a point sticks (both codes, Cattaneo)


# ------------------------------------------------------------------ scenes


@dataclass
class Scene:
    """One comparison: ``name``, our deck (``deck`` in ``decks/`` with ``params`` put into its
    ``*PARAMETER`` lines, or the whole ``text``), and which answer to read (``T/P``, ``hertz``,
    ``cattaneo``)."""

    name: str
    answer: str
    deck: str = ""
    params: dict = field(default_factory=dict)
    text: str = ""
    radius: float = 10.0      # the cylinder's (hertz, cattaneo)
    symmetry: float = 1.0     # 2: the model is half the scene (forces doubled)

    def ours(self, dest: Path) -> str:
        """Our deck's text, its ``*INCLUDE`` paths relative to the directory ``dest``."""
        text = self.text or (DECKS / self.deck).read_text()
        for key, value in self.params.items():
            text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
            if n != 1:
                raise ValueError(f"{self.deck}: no *PARAMETER line '{key} = ...'")
        meshes = os.path.relpath(DECKS / "meshes", dest).replace(os.sep, "/")
        text = text.replace("INPUT=meshes/", f"INPUT={meshes}/")
        return f"** {self.name}: written by tools/calculix_compare.py\n" + text


def _block_deck(nx: int, ny: int) -> str:
    text = (DECKS / "coulomb_block_noadh.dat").read_text()
    text, n = re.subn(r"NX=8, NY=4", f"NX={nx}, NY={ny}", text)
    if n != 1:
        raise RuntimeError("decks/coulomb_block_noadh.dat changed: update _block_deck")
    return text


def scenes(sizes=("16x8", "40x20", "80x40")) -> dict[str, list[Scene]]:
    """Scene groups by ``--scenes`` name."""
    slides = []
    for size in sizes:
        nx, ny = (int(v) for v in size.lower().split("x"))
        slides.append(Scene(f"press-slide-{nx}x{ny}", "T/P", text=press_slide_deck(nx, ny)))
    return {
        "press-slide": slides,
        "hertz-fine": [Scene("hertz-fine", "hertz", "hertz.dat", {"MESH": "fine", "KP": "6e7"},
                              symmetry=2.0)],
        "hertz-medium": [Scene("hertz-medium", "hertz", "hertz.dat", {"MESH": "medium"},
                                symmetry=2.0)],
        "cattaneo-medium": [Scene("cattaneo-medium", "cattaneo", "cattaneo_mindlin.dat",
                                  {"MESH": "medium", "KP": "3e7"})],
        "cattaneo-fine": [Scene("cattaneo-fine", "cattaneo", "cattaneo_mindlin.dat",
                                {"MESH": "fine", "KP": "6e7"})],
        "cattaneo-coarse": [Scene("cattaneo-coarse", "cattaneo", "cattaneo_mindlin.dat")],
        "block-20x10": [Scene("block-20x10", "T/P", text=_block_deck(20, 10))],
        "block-8x4": [Scene("block-8x4", "T/P", "coulomb_block_noadh.dat")],
    }


DEFAULT_SCENES = ("press-slide", "hertz-fine", "cattaneo-medium", "block-20x10")


# ------------------------------------------------------------------ the CalculiX deck


def ccx_from_model(model, nlgeom: bool | None = None) -> str:
    """The CalculiX input of a model of one Q8PE/Q8PER plane-strain block of an ELASTIC or
    RAMBERG_OSGOOD material, one straight horizontal foundation under it, one COULOMB contact
    without adhesion, and steps of ``*DLOAD`` pressures, ``*BOUNDARY`` values and foundation
    translations (ValueError for anything else).  ``nlgeom`` True or False overrides the steps'
    NLGEOM in CalculiX's deck (``--ccx-nlgeom``)."""
    if len(model.blocks) != 1 or len(model.contacts) != 1 or len(model.foundations) != 1:
        raise ValueError("one solid block, one contact and one foundation only")
    block, contact = model.blocks[0], model.contacts[0]
    if block.type not in CCX_TYPES:
        raise ValueError(f"element {block.type}: {' or '.join(CCX_TYPES)} only")
    law = model.contact_laws[contact.law]
    if law.type != "COULOMB" or float(law.params.get("B", 0.0)) != 0.0:
        raise ValueError("a COULOMB contact law without adhesion (B=0) only")
    flat = np.asarray(model.foundations[contact.foundation].points, float)
    if np.ptp(flat[:, 1]) != 0.0:
        raise ValueError("a straight horizontal foundation only")
    mat = model.materials[block.material]
    E, nu = float(mat.params["E"]), float(mat.params["NU"])
    xy, nid = model.coords, np.asarray(model.node_ids)
    lines = ["** written by tools/calculix_compare.py from a lagamine_py deck", "*NODE, NSET=NBLOCK"]
    lines += [f"{int(i)}, {float(x)!r}, {float(y)!r}" for i, (x, y) in zip(nid, xy)]
    n0, e0 = int(nid.max()), int(np.max(block.ids))
    lines.append("*NODE, NSET=NSLAB")
    slab_nodes, slab_conn = _slab(flat[:, 0].min(), flat[:, 0].max(), float(flat[0, 1]), n0)
    lines += [f"{k}, {float(x)!r}, {float(y)!r}" for k, (x, y) in slab_nodes.items()]
    etype = CCX_TYPES[block.type]
    lines.append(f"*ELEMENT, TYPE={etype}, ELSET=BLOCK")
    lines += [f"{int(e)}, " + ", ".join(str(int(nid[r])) for r in c)
              for e, c in zip(block.ids, block.conn)]
    lines.append("*ELEMENT, TYPE=CPE8, ELSET=SLAB")
    lines += [f"{e0 + j + 1}, " + ", ".join(map(str, c)) for j, c in enumerate(slab_conn)]
    bottom = model.surfaces[contact.surface]
    lines += ["*SURFACE, NAME=SBOT, TYPE=ELEMENT"]
    lines += [f"{int(e)}, S{int(f)}" for e, f in zip(bottom.elements, bottom.faces)]
    lines += ["*SURFACE, NAME=SFLAT, TYPE=ELEMENT"]
    lines += [f"{e0 + j + 1}, S3" for j in range(SLAB_NX)]
    lines += ["*MATERIAL, NAME=BODY", "*ELASTIC", f"{E!r}, {nu!r}"]
    if mat.law == "RAMBERG_OSGOOD":
        p = mat.params
        lines += ["*DEFORMATION PLASTICITY",
                  f"{E!r}, {nu!r}, {float(p['SIGMA0'])!r}, {float(p['N'])!r}, {float(p['ALPHA'])!r}"]
    elif mat.law != "ELASTIC":
        raise ValueError(f"material law {mat.law}: ELASTIC or RAMBERG_OSGOOD only")
    kp, kt, phi = (float(law.params[key]) for key in ("KP", "KT", "PHI"))
    lines += ["*MATERIAL, NAME=RIGID", "*ELASTIC", f"{1000 * E!r}, 0.3",
              "*SOLID SECTION, ELSET=BLOCK, MATERIAL=BODY", f"{float(block.thickness)!r}",
              "*SOLID SECTION, ELSET=SLAB, MATERIAL=RIGID", f"{float(block.thickness)!r}",
              "*CONTACT PAIR, INTERACTION=DRY, TYPE=SURFACE TO SURFACE", "SBOT, SFLAT",
              "*SURFACE INTERACTION, NAME=DRY",
              "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{kp:.6g}"]
    if phi > 0.0:
        lines += ["*FRICTION", f"{phi!r}, {kt:.6g}"]
    lines += ["*BOUNDARY", "NSLAB, 1, 2, 0."]
    nsets = 0
    for step in model.steps:
        if step.cloads or step.law_changes or step.stabilisation or step.op_new:
            raise ValueError(f"step {step.name}: *DLOAD, *BOUNDARY and *FOUNDATION MOTION only")
        large = step.nlgeom if nlgeom is None else nlgeom
        lines += [f"*STEP{', NLGEOM' if large else ''}, INC={step.max_increments}",
                  "*STATIC", f"{step.dt0!r}, {step.period!r}, {step.dt_min!r}, {step.dt_max!r}"]
        if step.dloads:
            lines.append("*DLOAD")
            for d in step.dloads:
                if d.kind != "P" or d.amplitude:
                    raise ValueError("*DLOAD: pressures P on a ramp only")
                surf = model.surfaces[d.surface]
                lines += [f"{int(e)}, P{int(f)}, {float(d.value)!r}"
                          for e, f in zip(surf.elements, surf.faces)]
        for bc in step.boundaries:
            if bc.amplitude or bc.last > 2:
                raise ValueError("*BOUNDARY: DOFs 1 and 2 on a ramp only")
            nsets += 1
            lines += [f"*NSET, NSET=BC{nsets}"] + [f"{int(nid[r])}," for r in bc.nodes]
            lines += ["*BOUNDARY", f"BC{nsets}, {bc.first}, {bc.last}, {float(bc.value)!r}"]
        for m in step.motions:       # totals from where the deck puts the flat, as *BOUNDARY's
            if m.amplitude or m.angle:
                raise ValueError("*FOUNDATION MOTION: a translation on a ramp only")
            lines += ["*BOUNDARY", f"NSLAB, 1, 1, {float(m.dx)!r}", f"NSLAB, 2, 2, {float(m.dy)!r}"]
        lines += ["*NODE FILE", "U", "*EL FILE", "S", "*CONTACT FILE", "CSTR",
                  "*NODE PRINT, NSET=NSLAB, TOTALS=ONLY", "RF", "*END STEP"]
    return "\n".join(lines) + "\n"


def _slab(x0: float, x1: float, y: float, n0: int):
    """Nodes ``{id: (x, y)}`` (ids from ``n0 + 1``) and CPE8 connectivities of one row of
    SLAB_NX elements of height SLAB_H under the line ``y`` from ``x0`` to ``x1``; face S3 is on top."""
    xs = np.linspace(x0, x1, 2 * SLAB_NX + 1)
    ids, nodes, k = {}, {}, n0
    for row, yy in enumerate((y - SLAB_H, y - SLAB_H / 2, y)):
        for col, x in enumerate(xs):
            if row == 1 and col % 2:
                continue
            k += 1
            ids[row, col] = k
            nodes[k] = (x, yy)
    conn = [(ids[0, c], ids[0, c + 2], ids[2, c + 2], ids[2, c], ids[0, c + 1],
             ids[1, c + 2], ids[2, c + 1], ids[1, c]) for c in range(0, 2 * SLAB_NX, 2)]
    return nodes, conn


# ------------------------------------------------------------------ reading CalculiX's results


def read_frd(path: Path) -> list[dict]:
    """The result blocks of an ASCII ``.frd``: ``[{"time", "name", "values": {node: array}}]``."""
    out, cur, time_ = [], None, 0.0
    with open(path) as f:
        for line in f:
            if line.startswith("  100C"):
                time_ = float(line[12:24])
            elif line.startswith(" -4"):
                cur = {"time": time_, "name": line.split()[1], "values": {}}
                out.append(cur)
            elif line.startswith(" -1") and cur is not None:
                n = (len(line.rstrip("\n")) - 13) // 12
                cur["values"][int(line[3:13])] = np.array(
                    [float(line[13 + 12 * i: 25 + 12 * i]) for i in range(n)])
            elif line.startswith(" -3"):
                cur = None
    return out


def read_totals(dat: Path) -> list[tuple[float, float, float]]:
    """``(time, fx, fy)`` of the slab's total reaction at every increment (``.dat``)."""
    pat = (r"total force \(fx,fy,fz\) for set NSLAB and time\s+([-0-9.eE+]+)\s*\n\s*\n?"
           r"\s*([-0-9.eE+]+)\s+([-0-9.eE+]+)")
    return [tuple(map(float, m)) for m in re.findall(pat, dat.read_text())]


def ccx_increments(work: Path, model, surface_nodes: np.ndarray) -> list[dict]:
    """Per CalculiX increment: time, ``Q``, ``P`` (slab reaction), and the slave nodes' current
    ``x``, ``p`` (CPRESS), ``tau`` (CSHEAR1)."""
    blocks = read_frd(work / "ccx.frd")
    totals = {round(t, 9): (fx, fy) for t, fx, fy in read_totals(work / "ccx.dat")}
    rows = {int(i): r for r, i in enumerate(model.node_ids)}
    x0 = np.array([model.coords[rows[n], 0] for n in surface_nodes])
    disp = {b["time"]: b["values"] for b in blocks if b["name"] == "DISP"}
    incs = []
    for b in blocks:
        if b["name"] != "CONTACT" or round(b["time"], 9) not in totals:
            continue
        fx, fy = totals[round(b["time"], 9)]
        u = disp.get(b["time"], {})
        zero = np.zeros(6)
        vals = np.array([b["values"].get(int(n), zero) for n in surface_nodes])
        ux = np.array([u[int(n)][0] if int(n) in u else 0.0 for n in surface_nodes])
        incs.append({"time": b["time"], "Q": abs(fx), "P": abs(fy), "x": x0 + ux,
                     "p": vals[:, 3], "tau": vals[:, 4]})
    return incs


def surface_nodes(model, surface: str) -> np.ndarray:
    """Deck ids of the nodes on the faces of ``surface`` (of the model's one block), sorted."""
    from lagamine_py import registry

    block = model.blocks[0]
    faces = registry.get("elements", block.type).faces
    row = {int(e): r for r, e in enumerate(block.ids)}
    surf = model.surfaces[surface]
    rows = {int(block.conn[row[int(e)], a]) for e, f in zip(surf.elements, surf.faces)
            for a in faces[int(f) - 1]}
    return np.sort(np.asarray(model.node_ids)[sorted(rows)])


# ------------------------------------------------------------------ reading ours


def _csv(path: Path) -> dict[str, np.ndarray]:
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def ours_increments(out: Path) -> list[dict]:
    """Per increment of our run with contact output: time, ``Q``, ``P`` (contact totals) and the
    contact points' ``x``, ``p``, ``tau``."""
    tot, pts = _csv(out / "contact_totals.csv"), _csv(out / "contact.csv")
    ptime = pts["time"].astype(float)
    incs = []
    for t, P, T in zip(tot["time"].astype(float), tot["P"].astype(float), tot["T"].astype(float)):
        at = ptime == t
        if at.any():
            incs.append({"time": t, "Q": abs(T), "P": abs(P), "x": pts["x"][at].astype(float),
                         "p": pts["p"][at].astype(float), "tau": pts["tau"][at].astype(float)})
    return incs


# ------------------------------------------------------------------ the answers


def answer(kind: str, incs: list[dict], phi: float, symmetry: float, model, radius: float) -> dict:
    """The scene's answer from the increments of either code (one function for both):
    ``T/P`` at the end; ``hertz``: P, and a, p0 of the Hertz fit of the last pressures, with
    the closed form's at that P; ``cattaneo``: c at Q = phi P / 2 and the closed form's."""
    from lagamine_py.checks.closed_forms import fit_hertz, hertz_closed_form, stick_half_width

    last = incs[-1]
    if kind == "T/P":
        return {"T/P": last["Q"] / last["P"]}
    mat = model.materials[model.blocks[0].material]
    E, nu = float(mat.params["E"]), float(mat.params["NU"])
    if kind == "hertz":
        a, p0 = fit_hertz(last["x"], last["p"])
        P = symmetry * last["P"]
        a_cf, p0_cf = hertz_closed_form(P, radius, E, nu)
        return {"P": P, "a": a, "p0": p0, "a_cf": a_cf, "p0_cf": p0_cf}
    if kind == "cattaneo":
        t_end = model_step_start(model, -1)
        ratios, widths, forces = [], [], []
        for inc in incs:
            if inc["time"] <= t_end + 1e-9 or inc["P"] == 0:
                continue
            x, p, tau = inc["x"], inc["p"], inc["tau"]
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.where(p > 0, np.abs(tau) / (phi * p), 1.0)
            status = np.where(p <= 0, "open", np.where(r < STICK, "stick", "slip"))
            w = np.clip(p, 0.0, None)
            centre = float(np.sum(x * w) / np.sum(w))
            ratios.append(inc["Q"] / (phi * inc["P"]))
            widths.append(stick_half_width(x, status, r, centre))
            forces.append(symmetry * inc["P"])
        order = np.argsort(ratios)
        ratios, widths, forces = (np.asarray(v)[order] for v in (ratios, widths, forces))
        if not ratios[0] <= 0.5 <= ratios[-1]:
            raise RuntimeError(f"Q/(phi P) spans {ratios[0]:.3g}..{ratios[-1]:.3g}: not 0.5")
        c, P = float(np.interp(0.5, ratios, widths)), float(np.interp(0.5, ratios, forces))
        a = hertz_closed_form(P, radius, E, nu)[0]
        return {"P": P, "c": c, "c_cf": a * np.sqrt(0.5)}
    raise ValueError(kind)


def model_step_start(model, k: int) -> float:
    """Total time at the start of step ``k`` (our steps and CalculiX's both count step time
    from the previous steps' end)."""
    return float(sum(s.period for s in model.steps[:k]))


# ------------------------------------------------------------------ running


def _timed(cmd: list[str], cwd: Path, env: dict) -> tuple[float, float, float]:
    """(wall s, peak resident MB, CPU s: user + system) of ``cmd`` under /usr/bin/time."""
    out = subprocess.run(["/usr/bin/time", "-f", "@@ %e %M %U %S", *cmd], cwd=cwd, env=env,
                         capture_output=True, text=True)
    m = re.search(r"@@ ([0-9.]+) ([0-9]+) ([0-9.]+) ([0-9.]+)", out.stderr)
    if out.returncode != 0 or not m:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stdout[-2000:]}"
                           f"\n{out.stderr[-2000:]}")
    return float(m.group(1)), int(m.group(2)) / 1024.0, float(m.group(3)) + float(m.group(4))


def write_decks(scene: Scene, dest: Path):
    """Our deck ``dest/NAME.dat`` and CalculiX's ``dest/NAME.inp``; returns (ours path, model)."""
    from lagamine_py.deck import load_deck

    dest.mkdir(parents=True, exist_ok=True)
    ours = dest / f"{scene.name}.dat"
    ours.write_text(scene.ours(dest))
    model = load_deck(ours)
    (dest / f"{scene.name}.inp").write_text(ccx_from_model(model))
    return ours, model


def ccx_env() -> dict:
    """The environment of both codes' runs: single-threaded."""
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
               CCX_NPROC_EQUATION_SOLVER="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def run_scene(scene: Scene, repeat: int, work: Path, ccx: str, ccx_nlgeom: bool = False) -> dict:
    """Paired runs (ours, CalculiX, ours, ...) of ``scene`` in ``work``; the best wall time and
    its run's peak memory of each code, the least CPU time, and each code's answer.  ``ccx_nlgeom``: CalculiX's
    steps all NLGEOM (ours as the deck says)."""
    ours, model = write_decks(scene, work)
    (work / "ccx.inp").write_text(ccx_from_model(model, True if ccx_nlgeom else None))
    env = ccx_env()
    cmds = {"ours": [sys.executable, "-m", "lagamine_py", "run", ours.name, "-o", "out", "-q",
                     "--overwrite"],
            "ccx": [ccx, "-i", "ccx"]}
    best = {"ours": (np.inf, 0.0, np.inf), "ccx": (np.inf, 0.0, np.inf)}
    for _ in range(repeat):
        for name, cmd in cmds.items():
            wall, mem, cpu = _timed(cmd, work, env)
            if wall < best[name][0]:
                best[name] = (wall, mem, min(cpu, best[name][2]))
            else:
                best[name] = (*best[name][:2], min(cpu, best[name][2]))
    contact = model.contacts[0]
    phi = float(model.contact_laws[contact.law].params["PHI"])
    nodes = surface_nodes(model, contact.surface)
    answers = {"ours": answer(scene.answer, ours_increments(work / "out"), phi, scene.symmetry,
                              model, scene.radius),
               "ccx": answer(scene.answer, ccx_increments(work, model, nodes), phi,
                             scene.symmetry, model, scene.radius)}
    return {"scene": scene.name + (" (ccx NLGEOM)" if ccx_nlgeom else ""), "dofs": 2 * len(model.node_ids),
            "ours_s": best["ours"][0], "ccx_s": best["ccx"][0],
            "ratio": best["ours"][0] / best["ccx"][0],
            "ours_cpu": best["ours"][2], "ccx_cpu": best["ccx"][2],
            "cpu_ratio": best["ours"][2] / best["ccx"][2],
            "ours_MB": best["ours"][1], "ccx_MB": best["ccx"][1],
            "answer": scene.answer, "ours": answers["ours"], "ccx": answers["ccx"],
            "load_average": os.getloadavg()}


def describe(kind: str, a: dict) -> str:
    """One table cell of an answer."""
    if kind == "T/P":
        return f"T/P {a['T/P']:.4f}"
    if kind == "hertz":
        return f"P {a['P']:.0f}, a {a['a']:.4f}, p0 {a['p0']:.0f}"
    return f"P {a['P']:.0f}, c {a['c']:.4f}"


def reference(kind: str, a: dict) -> str:
    """The closed form at our run's force."""
    if kind == "T/P":
        return "phi"
    if kind == "hertz":
        return f"a {a['a_cf']:.4f}, p0 {a['p0_cf']:.0f}"
    return f"c {a['c_cf']:.4f}"


def table(rows: list[dict]) -> str:
    """The markdown table of ``rows`` (load: the 1-minute load average after the scene)."""
    head = ("| scene | DOFs | wall ours (s) | wall CalculiX (s) | wall ours / CalculiX | "
            "CPU ours (s) | CPU CalculiX (s) | CPU ours / CalculiX | peak MB ours | "
            "peak MB CalculiX | answer ours | answer CalculiX | closed form (our P) | load |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
    return head + "".join(
        f"| {r['scene']} | {r['dofs']} | {r['ours_s']:.2f} | {r['ccx_s']:.2f} | "
        f"**{r['ratio']:.3f}** | {r['ours_cpu']:.2f} | {r['ccx_cpu']:.2f} | "
        f"**{r['cpu_ratio']:.3f}** | {r['ours_MB']:.0f} | {r['ccx_MB']:.0f} | "
        f"{describe(r['answer'], r['ours'])} | {describe(r['answer'], r['ccx'])} | "
        f"{reference(r['answer'], r['ours'])} | {r['load_average'][0]:.1f} |\n" for r in rows)


def main(argv=None) -> int:
    groups = scenes()
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", nargs="*", default=list(DEFAULT_SCENES), choices=list(groups),
                    help=f"default: {' '.join(DEFAULT_SCENES)}")
    ap.add_argument("--sizes", nargs="*", default=["16x8", "40x20", "80x40"],
                    help="press-then-slide meshes NXxNY")
    ap.add_argument("--repeat", type=int, default=2, help="paired runs per scene (best of)")
    ap.add_argument("--keep", type=Path, help="directory to keep the runs in")
    ap.add_argument("--write-decks", action="store_true",
                    help=f"also write both decks of each scene to {OUT_DECKS.relative_to(ROOT)}")
    ap.add_argument("--ccx-nlgeom", action="store_true",
                    help="CalculiX's steps NLGEOM even where ours are small-strain (its contact "
                         "in a small-strain step gives the Hertz cylinder a stiffer response)")
    ap.add_argument("--decks-only", action="store_true", help="write the decks, run nothing")
    ap.add_argument("--json", type=Path, help="write the rows to this file")
    ap.add_argument("--table", nargs="*", type=Path, default=[],
                    help="print the table of the rows of these --json files, run nothing")
    args = ap.parse_args(argv)
    if args.table:
        print(table([r for f in args.table for r in json.loads(f.read_text())]))
        return 0
    groups = scenes(args.sizes)
    chosen = [s for g in args.scenes for s in groups[g]]
    if args.write_decks or args.decks_only:
        for s in chosen:
            write_decks(s, OUT_DECKS)
            print(f"wrote {OUT_DECKS.relative_to(ROOT)}/{s.name}.dat and .inp", flush=True)
    if args.decks_only:
        return 0
    ccx = shutil.which("ccx")
    if ccx is None:
        raise SystemExit("ccx not found: sudo apt-get install -y calculix-ccx")
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
    rows, failed = [], []
    for s in chosen:
        work = Path(tempfile.mkdtemp(prefix=f"ccx_{s.name}_", dir=args.keep))
        try:
            rows.append(run_scene(s, args.repeat, work, ccx, args.ccx_nlgeom))
        except RuntimeError as err:      # one code failed the scene: say so, go on
            print(f"{s.name}: {str(err)[-600:]}", file=sys.stderr, flush=True)
            failed.append(s.name)
            continue
        finally:
            if args.keep is None:
                shutil.rmtree(work, ignore_errors=True)
        print(json.dumps(rows[-1]), flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
    print("\n" + table(rows))
    if failed:
        print(f"failed: {' '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
