"""lagamine_py against CalculiX (``ccx``, Debian's ``calculix-ccx``) on press-then-slide.

One command writes both decks of each size, runs them in turn (paired: ours, CalculiX, ours,
CalculiX ...; best wall time of each), and prints a markdown table with the wall times, their
ratio, the peak memory of each process and the end state's friction ratio T/P of each code::

    python tools/calculix_compare.py --sizes 40x20 80x40 [--decks D ...] [--repeat 2] [--keep DIR]

The scene is ``decks/press_slide.dat`` refined to NX x NY (``tools/bench.py``'s
``press_slide_deck``: pressed range and penalties adapted).  The CalculiX deck has the same
nodes and CPE8 elements (the Q8 node order is CalculiX's), the same pressure on the same faces,
the same imposed displacement of the right edge, Coulomb friction 0.2 with the same normal and
tangential penalties (``PRESSURE-OVERCLOSURE=LINEAR`` slope KP, ``*FRICTION`` stick slope KT),
and the rigid flat as a fixed slab of CPE8 elements under the block whose top face is the
master surface (surface-to-surface contact).  Two differences, both in CalculiX's favour or
neutral for the time: the Ramberg-Osgood law is CalculiX's ``*DEFORMATION PLASTICITY`` (the same
uniaxial curve, total rather than incremental J2), and CalculiX expands the plane-strain
elements into one layer of 20-node bricks.  Both codes run single-threaded
(``OMP_NUM_THREADS=1``, ``MKL_NUM_THREADS=1``) and write their results every increment
(lagamine_py its default output, CalculiX displacements and stresses to the ``.frd``).
"""
from __future__ import annotations

import argparse
import csv
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import press_slide_deck  # noqa: E402

SLAB_NX = 20            # elements of the fixed slab standing for the rigid flat
SLAB_H = 2.0            # its thickness (mm)


def ccx_deck(nx: int, ny: int) -> str:
    """The CalculiX input of press-then-slide at ``nx`` x ``ny`` (see the module doc)."""
    return ccx_from_deck(press_slide_deck(nx, ny))


def ccx_from_deck(text: str) -> str:
    """The CalculiX input of a lagamine_py deck ``text`` made of one Q8 plane-strain block of an
    ELASTIC or RAMBERG_OSGOOD material, one straight horizontal foundation under it, one COULOMB
    contact without adhesion, and steps of ``*DLOAD`` pressures and ``*BOUNDARY`` values
    (ValueError for anything else)."""
    from lagamine_py.deck import load_deck

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "d.dat"
        path.write_text(text)
        model = load_deck(path)
    if len(model.blocks) != 1 or len(model.contacts) != 1 or len(model.foundations) != 1:
        raise ValueError("one solid block, one contact and one foundation only")
    block, contact = model.blocks[0], model.contacts[0]
    law = model.contact_laws[contact.law]
    if law.type != "COULOMB" or float(law.params.get("B", 0.0)) != 0.0:
        raise ValueError("a COULOMB contact law without adhesion (B=0) only")
    flat = np.asarray(model.foundations[contact.foundation].points, float)
    if np.ptp(flat[:, 1]) != 0.0:
        raise ValueError("a straight horizontal foundation only")
    mat = model.materials[block.material]
    E, nu = float(mat.params["E"]), float(mat.params["NU"])
    xy, nid = model.coords, np.asarray(model.node_ids)
    lines = ["** written by tools/calculix_compare.py", "*NODE, NSET=NBLOCK"]
    lines += [f"{int(i)}, {float(x)!r}, {float(y)!r}" for i, (x, y) in zip(nid, xy)]
    # the flat: a slab of CPE8 under the foundation's line, one row, all nodes fixed
    n0, e0 = int(nid.max()), int(np.max(block.ids))
    xs = np.linspace(flat[:, 0].min(), flat[:, 0].max(), 2 * SLAB_NX + 1)
    y0 = float(flat[0, 1])
    slab = {}
    lines.append("*NODE, NSET=NSLAB")
    k = n0
    for row, y in enumerate((y0 - SLAB_H, y0 - SLAB_H / 2, y0)):
        for col, x in enumerate(xs):
            if row == 1 and col % 2:
                continue
            k += 1
            slab[row, col] = k
            lines.append(f"{k}, {float(x)!r}, {float(y)!r}")
    lines.append("*ELEMENT, TYPE=CPE8, ELSET=BLOCK")
    lines += [f"{int(e)}, " + ", ".join(str(int(nid[r])) for r in c)
              for e, c in zip(block.ids, block.conn)]
    lines.append("*ELEMENT, TYPE=CPE8, ELSET=SLAB")
    for j in range(SLAB_NX):
        c = 2 * j
        conn = [slab[0, c], slab[0, c + 2], slab[2, c + 2], slab[2, c], slab[0, c + 1],
                slab[1, c + 2], slab[2, c + 1], slab[1, c]]
        lines.append(f"{e0 + j + 1}, " + ", ".join(map(str, conn)))
    bottom = model.surfaces[contact.surface]
    lines += ["*SURFACE, NAME=SBOT, TYPE=ELEMENT"]
    lines += [f"{int(e)}, S{int(f)}" for e, f in zip(bottom.elements, bottom.faces)]
    lines += ["*SURFACE, NAME=SFLAT, TYPE=ELEMENT"]
    lines += [f"{e0 + j + 1}, S3" for j in range(SLAB_NX)]
    lines += ["*MATERIAL, NAME=STEEL", "*ELASTIC", f"{E!r}, {nu!r}"]
    if mat.law == "RAMBERG_OSGOOD":
        p = mat.params
        lines += ["*DEFORMATION PLASTICITY",
                  f"{E!r}, {nu!r}, {float(p['SIGMA0'])!r}, {float(p['N'])!r}, {float(p['ALPHA'])!r}"]
    elif mat.law != "ELASTIC":
        raise ValueError(f"material law {mat.law}: ELASTIC or RAMBERG_OSGOOD only")
    kp, kt, phi = (float(law.params[key]) for key in ("KP", "KT", "PHI"))
    lines += ["*MATERIAL, NAME=RIGID", "*ELASTIC", f"{1000 * E!r}, 0.3",
              "*SOLID SECTION, ELSET=BLOCK, MATERIAL=STEEL", f"{float(block.thickness)!r}",
              "*SOLID SECTION, ELSET=SLAB, MATERIAL=RIGID", "1.",
              "*CONTACT PAIR, INTERACTION=DRY, TYPE=SURFACE TO SURFACE", "SBOT, SFLAT",
              "*SURFACE INTERACTION, NAME=DRY",
              "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR", f"{kp:.6g}",
              "*FRICTION", f"{phi!r}, {kt:.6g}",
              "*BOUNDARY", "NSLAB, 1, 2, 0."]
    nsets = 0
    for k, step in enumerate(model.steps):
        if step.cloads or step.motions or step.law_changes:
            raise ValueError(f"step {step.name}: *DLOAD and *BOUNDARY only")
        last = k == len(model.steps) - 1
        lines += [f"*STEP{', NLGEOM' if step.nlgeom else ''}, INC={step.max_increments}",
                  "*STATIC", f"{step.dt0!r}, {step.period!r}, {step.dt_min!r}, {step.dt_max!r}"]
        if step.dloads:
            lines.append("*DLOAD")
            for d in step.dloads:
                surf = model.surfaces[d.surface]
                lines += [f"{int(e)}, P{int(f)}, {float(d.value)!r}"
                          for e, f in zip(surf.elements, surf.faces)]
        for bc in step.boundaries:
            nsets += 1
            lines += [f"*NSET, NSET=BC{nsets}"] + [f"{int(nid[r])}," for r in bc.nodes]
            lines += ["*BOUNDARY", f"BC{nsets}, {bc.first}, {min(bc.last, 2)}, {float(bc.value)!r}"]
        lines += ["*NODE FILE", "U", "*EL FILE", "S"]
        if last:
            lines += ["*NODE PRINT, NSET=NSLAB, TOTALS=ONLY", "RF"]
        lines.append("*END STEP")
    return "\n".join(lines) + "\n"


def _timed(cmd: list[str], cwd: Path, env: dict) -> tuple[float, float, str]:
    """(wall s, peak resident MB, output) of ``cmd`` under /usr/bin/time."""
    out = subprocess.run(["/usr/bin/time", "-f", "@@ %e %M", *cmd], cwd=cwd, env=env,
                         capture_output=True, text=True)
    m = re.search(r"@@ ([0-9.]+) ([0-9]+)", out.stderr)
    if out.returncode != 0 or not m:
        raise RuntimeError(f"{' '.join(cmd)} failed ({out.returncode}):\n{out.stdout[-2000:]}"
                           f"\n{out.stderr[-2000:]}")
    return float(m.group(1)), int(m.group(2)) / 1024.0, out.stdout


def _ours_ratio(out: Path) -> float:
    rows = list(csv.DictReader(open(out / "contact_totals.csv")))
    return abs(float(rows[-1]["T"]) / float(rows[-1]["P"]))


def _dofs(out: Path) -> int:
    """The run's DOFs: two per node of its displacement table."""
    rows = list(csv.DictReader(open(out / "displacements.csv")))
    return 2 * len({r["node"] for r in rows})


def _ccx_ratio(dat: Path) -> float:
    """T / P from the slab's total reaction at the end (the last RF totals of the .dat)."""
    text = dat.read_text()
    blocks = re.findall(r"total force.*?\n\s*\n?\s*([-0-9.eE+]+)\s+([-0-9.eE+]+)\s+([-0-9.eE+]+)",
                        text)
    fx, fy, _ = map(float, blocks[-1])
    return abs(fx / fy)


def compare(scenes, repeat: int, keep: Path | None) -> list[dict]:
    """Paired runs of each scene ``(label, lagamine_py deck text)``."""
    ccx = shutil.which("ccx")
    if ccx is None:
        raise SystemExit("ccx not found: sudo apt-get install -y calculix-ccx")
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1",
               CCX_NPROC_EQUATION_SOLVER="1")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    rows = []
    for label, text in scenes:
        work = Path(tempfile.mkdtemp(prefix=f"ccx_{re.sub(r'[^A-Za-z0-9]+', '_', label)}_",
                                     dir=keep))
        (work / "ours.dat").write_text(text)
        (work / "ccx.inp").write_text(ccx_from_deck(text))
        ours_cmd = [sys.executable, "-m", "lagamine_py", "run", "ours.dat", "-o", "out", "-q",
                    "--overwrite"]
        best = {"ours": (np.inf, 0.0), "ccx": (np.inf, 0.0)}
        for _ in range(repeat):
            for name, cmd in (("ours", ours_cmd), ("ccx", [ccx, "-i", "ccx"])):
                wall, mem, _ = _timed(cmd, work, env)
                if wall < best[name][0]:
                    best[name] = (wall, mem)
        row = {"scene": label, "dofs": _dofs(work / "out"), "ours_s": best["ours"][0], "ccx_s": best["ccx"][0],
               "ratio": best["ours"][0] / best["ccx"][0], "ours_MB": best["ours"][1],
               "ccx_MB": best["ccx"][1], "ours_T/P": _ours_ratio(work / "out"),
               "ccx_T/P": _ccx_ratio(work / "ccx.dat"), "load_average": os.getloadavg()}
        rows.append(row)
        print(row, flush=True)
        if keep is None:
            shutil.rmtree(work, ignore_errors=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", nargs="*", default=["40x20", "80x40"],
                    help="press-then-slide meshes NXxNY")
    ap.add_argument("--decks", nargs="*", type=Path, default=[],
                    help="other decks (one Q8 block on a flat, Coulomb without adhesion, *DLOAD "
                         "and *BOUNDARY steps), e.g. decks/coulomb_block_noadh.dat")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--keep", type=Path, help="directory to keep the decks and results in")
    args = ap.parse_args(argv)
    scenes = []
    for size in args.sizes:
        nx, ny = (int(v) for v in size.lower().split("x"))
        scenes.append((f"press-slide {nx}x{ny}", press_slide_deck(nx, ny)))
    scenes += [(d.stem, d.read_text()) for d in args.decks]
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
    rows = compare(scenes, args.repeat, args.keep)
    print("\n| scene | DOFs | lagamine_py (s) | CalculiX (s) | ours / CalculiX | peak MB ours | "
          "peak MB CalculiX | T/P ours | T/P CalculiX |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['dofs']} | {r['ours_s']:.2f} | {r['ccx_s']:.2f} | {r['ratio']:.3f} | "
              f"{r['ours_MB']:.0f} | {r['ccx_MB']:.0f} | {r['ours_T/P']:.4f} | {r['ccx_T/P']:.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
