"""A third-party package adds a material law through the ``lagamine_py.laws`` entry point.

The package in ``tests/plugin_pkg`` is installed (into a temporary target directory, so the test
environment is left as it was) and a deck that uses its law is run in a subprocess.  The answer
is checked against the closed form of a plane-strain bar in uniaxial tension.
"""
import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent

DECK = """** plane-strain bar pulled by a uniform traction, law from a third-party plugin
*MESH, NAME=BAR, TYPE=Q8PE, X0=0, Y0=0, LX=4, LY=1, NX=4, NY=2
*MATERIAL, NAME=DEMO, LAW=BULK_SHEAR
K=<K>, G=<G>
*SOLID, ELSET=BAR, MATERIAL=DEMO
*STEP, NAME=PULL
*STATIC
1, 1, 1e-3, 1
*BOUNDARY
BAR_LEFT, 1, 1, 0
BAR_BOTTOM, 2, 2, 0
*DLOAD
BAR_RIGHT, P, <P>
*END STEP
"""


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    target = tmp_path_factory.mktemp("site")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps",
                    "--no-build-isolation", "--target", str(target), str(HERE / "plugin_pkg")],
                   check=True)
    return target


def _env(plugin_path):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(plugin_path), env.get("PYTHONPATH", "")])
    return env


def test_plugin_is_listed_with_its_parameters(plugin_path):
    out = subprocess.run([sys.executable, "-m", "lagamine_py", "plugins"], env=_env(plugin_path),
                         capture_output=True, text=True, check=True).stdout
    assert "BULK_SHEAR  (lagamine-demo-law 0.1.0)" in out
    assert "K (float [stress], required" in out and "G (float [stress], required" in out


def test_deck_using_the_plugin_runs_and_matches_closed_form(plugin_path, tmp_path):
    K, G, sigma = 160e3, 80e3, 100.0
    deck = tmp_path / "bar.dat"
    deck.write_text(DECK.replace("<K>", str(K)).replace("<G>", str(G)).replace("<P>", str(-sigma)))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "lagamine_py", "run", str(deck), "-o", str(out), "-q"],
                          env=_env(plugin_path), capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    E = 9 * K * G / (3 * K + G)
    nu = (3 * K - 2 * G) / (2 * (3 * K + G))
    # plane strain, sigma_yy = 0: eps_xx = sigma (1 - nu^2) / E
    rows = list(csv.DictReader(open(out / "reactions.csv")))
    left = [r for r in rows if r["nset"].upper() == "BAR_LEFT"][-1]
    assert float(left["RF1"]) == pytest.approx(-sigma * 1.0, rel=1e-9)
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
    files = sorted(out.glob("bar_[0-9]*.vtu"))
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(files[-1]))
    reader.Update()
    grid = reader.GetOutput()
    x = vtk_to_numpy(grid.GetPoints().GetData())[:, 0]
    u = vtk_to_numpy(grid.GetPointData().GetArray("displacement"))[:, 0]
    np.testing.assert_allclose(u, sigma * (1 - nu**2) / E * x, rtol=1e-9, atol=1e-12)
