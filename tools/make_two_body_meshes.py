"""The lower cylinder of the two-body Hertz deck (decks/hertz_two_body.dat): the quarter-cylinder
meshes of tools/make_meshes.py mirrored about the contact plane y = -R, node and element ids
offset by 10000 and set names suffixed with 2 (CYL2, TOP2, AXIS2, ARC2, TOPFACE2).  Mirrored
elements run clockwise: the deck builder renumbers them (a notice), surfaces keep their edges.
Also the ``xfine`` quarter cylinder (tools/make_meshes.py's generator, 28 even elements over the
first 1.6 mm, h = 0.057 mm), only for the two-body benchmark: both cylinders make 20 k DOFs
(tools/bench_two_body.py, issue 18 item 4).

    python tools/make_two_body_meshes.py        # writes decks/meshes/cylinder_quarter_*_mirror.inp
"""
from __future__ import annotations

import re
from pathlib import Path

MESHES = Path(__file__).resolve().parents[1] / "decks" / "meshes"
OFFSET = 10000
R = 10.0


def mirror(text: str) -> str:
    out, section = [], None
    for line in text.splitlines():
        if line.startswith("**"):
            if "do not edit" in line:
                out.append("** mirrored about y = -R by tools/make_two_body_meshes.py; do not edit by hand")
            else:
                out.append(line)
            continue
        if line.startswith("*"):
            section = line.split(",")[0].upper()
            line = re.sub(r"(ELSET|NSET|NAME)=(\w+)", lambda m: f"{m.group(1)}={m.group(2)}2", line)
            out.append(line)
            continue
        vals = [v.strip() for v in line.split(",")]
        if section == "*NODE":
            nid, x, y = int(vals[0]), float(vals[1]), float(vals[2])
            out.append(f"{nid + OFFSET}, {x!r}, {-2.0 * R - y!r}")
        elif section in ("*ELEMENT", "*NSET"):
            out.append(", ".join(str(int(v) + OFFSET) for v in vals if v))
        elif section == "*SURFACE":
            out.append(f"{int(vals[0]) + OFFSET}, {vals[1]}")
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def write_xfine() -> None:
    """decks/meshes/cylinder_quarter_xfine.inp, as tools/make_meshes.py writes its meshes."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_meshes", Path(__file__).with_name("make_meshes.py"))
    mm = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mm)
    n_zone = 28
    nodes, els, arc, tops, top, axis = mm.half_cylinder(R, 1.6, n_zone, 13, 12, False)
    mm.write_inc(MESHES / "cylinder_quarter_xfine.inp", nodes, els, "Q8PE",
                 {"TOP": top, "AXIS": axis}, {"ARC": arc, "TOPFACE": tops},
                 f"quarter of a cylinder R={R}, lower side, contact point (0,-R); xfine mesh "
                 f"(tools/make_two_body_meshes.py, for the benchmark), h = {1.6 / n_zone:.3g} mm "
                 f"over the first 1.6 mm")


def main() -> None:
    write_xfine()
    for size in ("coarse", "medium", "fine", "xfine"):
        src = MESHES / f"cylinder_quarter_{size}.inp"
        (MESHES / f"cylinder_quarter_{size}_mirror.inp").write_text(mirror(src.read_text()))


if __name__ == "__main__":
    main()
