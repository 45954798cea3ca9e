"""Meshes made with the gmsh Python API, read by lagamine-py's *IMPORT (docs/meshes.md).

    pip install gmsh          # in any Python environment; lagamine-py itself does not need it
    python gmsh_meshes.py     # writes the .msh and .inp files next to this script

Two scenes:

* ``hertz_quarter``: the lower-right quarter of a cylinder (R = 10 mm) for Hertz line contact,
  graded from 0.04 mm at the contact point to 1.5 mm away from it, 8-node quadrilaterals (and a
  few 6-node triangles where gmsh cannot make quads).  Physical groups: CYL (the body), ARC (the
  contact side), TOP (the diameter plane, pushed down), AXIS (the symmetry plane).
* ``punch``: a block (10 x 5 mm, half of a symmetric scene) under a rigid punch whose profile --
  a flat face, a fillet of radius 1 mm, a vertical side -- is a 1D physical group of 3-node
  lines apart from the block (PUNCH), run with the block on its left: a tool profile for
  ``*FOUNDATION, CURVE=PUNCH``.  Groups of the block: BLOCK, TOP, BOTTOM, AXIS.

Each is written as gmsh 4.1 (``.msh``, ASCII) and as Abaqus input (``.inp``, gmsh's own export:
plane-stress CPS8/CPS6 and T3D3 lines, read with *IMPORT, ANALYSIS=PLANE STRAIN).
"""
from __future__ import annotations

import sys
from pathlib import Path

import gmsh

HERE = Path(__file__).resolve().parent


def second_order_quads() -> None:
    """8-node quadrilaterals: recombined triangles, quadratic, no centre node; mid-side nodes on
    the curved geometry."""
    gmsh.option.setNumber("Mesh.Algorithm", 8)                # frontal-Delaunay for quads
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 1)   # blossom
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)    # 8 nodes, not 9


def write(stem: str) -> None:
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(str(HERE / f"{stem}.msh"))
    gmsh.write(str(HERE / f"{stem}.inp"))


def hertz_quarter(R: float = 10.0, h_contact: float = 0.04, h_far: float = 1.5,
                  zone: float = 0.8) -> None:
    gmsh.model.add("hertz_quarter")
    geo = gmsh.model.geo
    centre = geo.addPoint(0, 0, 0)
    bottom = geo.addPoint(0, -R, 0)
    right = geo.addPoint(R, 0, 0)
    arc = geo.addCircleArc(bottom, centre, right)             # contact side, from the contact point
    top = geo.addLine(right, centre)
    axis = geo.addLine(centre, bottom)
    surface = geo.addPlaneSurface([geo.addCurveLoop([arc, top, axis])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [surface], name="CYL")
    gmsh.model.addPhysicalGroup(1, [arc], name="ARC")
    gmsh.model.addPhysicalGroup(1, [top], name="TOP")
    gmsh.model.addPhysicalGroup(1, [axis], name="AXIS")
    # graded: h_contact within `zone` of the contact point, growing to h_far 6 mm away
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [bottom])
    grade = field.add("Threshold")
    field.setNumber(grade, "InField", dist)
    field.setNumber(grade, "SizeMin", h_contact)
    field.setNumber(grade, "SizeMax", h_far)
    field.setNumber(grade, "DistMin", zone)
    field.setNumber(grade, "DistMax", 6.0)
    field.setAsBackgroundMesh(grade)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    second_order_quads()
    gmsh.model.mesh.generate(2)
    write("hertz_quarter")


def punch(width: float = 10.0, height: float = 5.0, flat: float = 3.0, fillet: float = 1.0,
          h_fine: float = 0.15, h_far: float = 1.0) -> None:
    gmsh.model.add("punch")
    geo = gmsh.model.geo
    # the block, counter-clockwise from the symmetry axis at the bottom
    p = [geo.addPoint(0, -height, 0), geo.addPoint(width, -height, 0),
         geo.addPoint(width, 0, 0), geo.addPoint(0, 0, 0)]
    bottom, right, top, axis = (geo.addLine(p[k], p[(k + 1) % 4]) for k in range(4))
    block = geo.addPlaneSurface([geo.addCurveLoop([bottom, right, top, axis])])
    # the punch profile, run from its side down round the fillet and along the flat face to a
    # little past the axis: the block lies on its left
    side_top = geo.addPoint(flat + fillet, 3.0, 0)
    side_end = geo.addPoint(flat + fillet, fillet, 0)
    fillet_centre = geo.addPoint(flat, fillet, 0)
    flat_start = geo.addPoint(flat, 0, 0)
    flat_end = geo.addPoint(-0.5, 0, 0)
    profile = [geo.addLine(side_top, side_end),
               geo.addCircleArc(side_end, fillet_centre, flat_start),
               geo.addLine(flat_start, flat_end)]
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [block], name="BLOCK")
    gmsh.model.addPhysicalGroup(1, [top], name="TOP")
    gmsh.model.addPhysicalGroup(1, [bottom], name="BOTTOM")
    gmsh.model.addPhysicalGroup(1, [axis], name="AXIS")
    gmsh.model.addPhysicalGroup(1, profile, name="PUNCH")
    # fine under the punch edge, coarser away
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [flat_start])
    grade = field.add("Threshold")
    field.setNumber(grade, "InField", dist)
    field.setNumber(grade, "SizeMin", h_fine)
    field.setNumber(grade, "SizeMax", h_far)
    field.setNumber(grade, "DistMin", 1.5)
    field.setNumber(grade, "DistMax", 6.0)
    field.setAsBackgroundMesh(grade)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    second_order_quads()
    gmsh.model.mesh.generate(2)
    write("punch")


def main() -> None:
    gmsh.initialize(sys.argv)
    gmsh.option.setNumber("General.Terminal", 0)
    try:
        hertz_quarter()
        punch()
    finally:
        gmsh.finalize()


if __name__ == "__main__":
    main()
