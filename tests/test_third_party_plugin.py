"""A third-party package adds plugins of every kind but elements through entry points.

The package in ``tests/plugin_pkg`` (``lagamine-demo-plugins``: a material law, a contact law,
a writer, a linear solver and a ``*CHECK``) is installed into a temporary target directory, so
the test environment is left as it was, and decks using its plugins run in subprocesses.
Independent sources of the asserted numbers:

* a plane-strain bar pulled by a uniform end traction: ``u1 = sigma (1 - nu^2) x / E``, the
  reactions balance the traction (``sum RF1 = -sigma LY``, ``sum RF2 = 0``);
* a block pressed onto a flat and pushed until the whole interface slides: ``T = MU P`` with
  ``P`` the pressure times the contact length.

Each test also shows that the plugin really ran: its file, its log line, its check columns,
parameters no built-in accepts.
"""
import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
DIST = "lagamine-demo-plugins 0.2.0"
PLUGINS = ("BULK_SHEAR", "SIMPLE_FRICTION", "JSONL", "DENSE_LU", "BAR_END")
K, G = 160e3, 80e3
E = 9 * K * G / (3 * K + G)
NU = (3 * K - 2 * G) / (2 * (3 * K + G))

BAR = """** plane-strain bar pulled by a uniform traction, law from a third-party plugin
*PARAMETER
P = 100
*MESH, NAME=BAR, TYPE=Q8PE, X0=0, Y0=0, LX=4, LY=1, NX=4, NY=2
*MATERIAL, NAME=DEMO, LAW=BULK_SHEAR
K=<K>, G=<G>
*SOLID, ELSET=BAR, MATERIAL=DEMO
<CHECK>
*STEP, NAME=PULL
*STATIC
1, 1, 1e-3, 1
<CONTROLS>
*OUTPUT, WRITERS=VTK/REACTIONS/STATUS/DISPLACEMENTS/JSONL
*BOUNDARY
BAR_LEFT, 1, 1, 0
BAR_BOTTOM, 2, 2, 0
*DLOAD
BAR_RIGHT, P, -<P>
*END STEP
"""

BLOCK = """** a block pressed onto a flat and pushed until it slides; friction law from a plugin
*MESH, NAME=BLOCK, TYPE=Q8PE, X0=0, Y0=0, LX=20, LY=10, NX=4, NY=2
*MATERIAL, NAME=STEEL, LAW=ELASTIC
E=210000, NU=0.3
*SOLID, ELSET=BLOCK, MATERIAL=STEEL
*FOUNDATION, NAME=FLAT
-20, 0
10, 0
40, 0
*CONTACT LAW, NAME=DRY, TYPE=SIMPLE_FRICTION
KN=2e6, KS=2e6, MU=0.3
*CONTACT, SURFACE=BLOCK_BOTTOM, FOUNDATION=FLAT, LAW=DRY, GAUSS=3
*STEP, NAME=PRESS
*STATIC
0.5, 1, 1e-3, 0.5
*DLOAD
BLOCK_TOP, P, 100
*END STEP
*STEP, NAME=PUSH
*STATIC
0.25, 1, 1e-4, 0.25
*BOUNDARY
BLOCK_LEFT, 1, 1, 0.05
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


def _cli(plugin_path, *args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lagamine_py", *map(str, args)],
                          env=_env(plugin_path), capture_output=True, text=True, cwd=cwd)


def _bar_deck(tmp_path, check="", controls=""):
    deck = tmp_path / "bar.dat"
    deck.write_text(BAR.replace("<K>", str(K)).replace("<G>", str(G))
                    .replace("<CHECK>", check).replace("<CONTROLS>", controls))
    return deck


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_plugins_are_listed_with_their_distribution(plugin_path):
    proc = _cli(plugin_path, "plugins")
    assert proc.returncode == 0, proc.stderr
    for name in PLUGINS:
        assert f"  {name}  ({DIST})" in proc.stdout
    assert "K (float [stress], required" in proc.stdout
    assert "G (float [stress], required" in proc.stdout
    assert "KN (float [stress/length], required, > 0): normal penalty" in proc.stdout
    assert "LENGTH (float [length], required, > 0)" in proc.stdout
    assert "warning" not in proc.stderr


def test_contract_checks_pass_on_the_installed_plugins(plugin_path):
    proc = _cli(plugin_path, "plugins", "--check", *PLUGINS)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for kind, name in (("material law", "BULK_SHEAR"), ("contact law", "SIMPLE_FRICTION"),
                       ("writer", "JSONL"), ("solver", "DENSE_LU"), ("check", "BAR_END")):
        assert f"{kind} {name} ({DIST}): passed" in proc.stdout
    assert "FAIL" not in proc.stdout
    assert proc.stdout.rstrip().endswith("5 plugin(s) checked: 5 passed")


def test_bar_with_the_law_writer_and_solver_plugins(plugin_path, tmp_path):
    """BULK_SHEAR computes the bar, DENSE_LU solves it (run --solver), JSONL records it."""
    deck = _bar_deck(tmp_path)
    out = tmp_path / "out"
    proc = _cli(plugin_path, "run", deck, "-o", out, "-q", "--solver", "DENSE_LU")
    assert proc.returncode == 0, proc.stderr
    sigma = 100.0
    left = [r for r in _rows(out / "reactions.csv") if r["nset"].upper() == "BAR_LEFT"][-1]
    assert float(left["RF1"]) == pytest.approx(-sigma * 1.0, rel=1e-9)
    disp = _rows(out / "displacements.csv")
    x = np.array([float(r["x"]) for r in disp])
    u1 = np.array([float(r["u1"]) for r in disp])
    np.testing.assert_allclose(u1, sigma * (1 - NU**2) / E * x, rtol=1e-9, atol=1e-12)
    # the solver plugin ran: its line in the run's log
    assert "DENSE_LU: dense LU of a" in (out / "bar.log").read_text()
    # the writer plugin ran: its records, the reactions balancing the traction
    records = [json.loads(line) for line in (out / "bar.jsonl").read_text().splitlines()]
    assert [r["event"] for r in records] == ["start", "step", "increment", "end"]
    inc = records[2]
    assert inc["reaction_total"] == pytest.approx([-sigma * 1.0, 0.0], rel=1e-9, abs=1e-9 * sigma)
    assert inc["reactions"]["BAR_LEFT"][0] == pytest.approx(-sigma, rel=1e-9)
    assert records[-1]["status"] == 0


def test_check_plugin_evaluated_by_a_sweep(plugin_path, tmp_path):
    """BAR_END, the deck's *CHECK, is evaluated on every point of a sweep (the solver chosen by
    *CONTROLS SOLVER=DENSE_LU this time)."""
    check = f"*CHECK, NAME=BAR, TYPE=BAR_END\nSIGMA=<P>, E={E!r}, NU={NU!r}, LENGTH=4"
    deck = _bar_deck(tmp_path, check, "*CONTROLS\nSOLVER=DENSE_LU")
    out = tmp_path / "sweep"
    proc = _cli(plugin_path, "sweep", deck, "--set", "P=50,200", "-o", out)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = _rows(out / "sweep.csv")
    assert [float(r["P"]) for r in rows] == [50.0, 200.0]
    for r in rows:
        exact = float(r["P"]) * (1 - NU**2) * 4.0 / E           # the closed form, here
        assert float(r["BAR_u_end"]) == pytest.approx(exact, rel=1e-9)
        assert float(r["BAR_u_end_cf"]) == pytest.approx(exact, rel=1e-12)
        assert float(r["BAR_error"]) < 1e-9
        assert "DENSE_LU: dense LU" in (out / r["point"] / "bar.log").read_text()


def test_contact_law_plugin_block_slides_at_mu_p(plugin_path, tmp_path):
    """SIMPLE_FRICTION (parameters KN, KS, MU, which COULOMB refuses) carries the press with no
    tangential force, then the push slides the whole interface: T = MU P."""
    deck = tmp_path / "block.dat"
    deck.write_text(BLOCK)
    out = tmp_path / "out"
    proc = _cli(plugin_path, "run", deck, "-o", out, "-q")
    assert proc.returncode == 0, proc.stderr
    totals = _rows(out / "contact_totals.csv")
    press = [r for r in totals if r["step"] == "1"][-1]
    last = totals[-1]
    P = 100.0 * 20.0                                             # pressure x contact length
    assert abs(float(press["P"])) == pytest.approx(P, rel=1e-9)
    assert abs(float(press["T"])) < 1e-6 * P                      # no tangential load yet
    assert abs(float(last["P"])) == pytest.approx(P, rel=1e-9)
    assert abs(float(last["T"])) == pytest.approx(0.3 * P, rel=1e-9)
    points = _rows(out / "contact.csv")
    final = [r for r in points if (r["step"], r["increment"]) == (last["step"], last["increment"])]
    assert final and {r["status"] for r in final} == {"slip"}
    builtin = tmp_path / "coulomb.dat"
    builtin.write_text(BLOCK.replace("SIMPLE_FRICTION", "COULOMB"))
    refused = _cli(plugin_path, "check", builtin)
    assert refused.returncode == 2 and "unknown parameter KN" in refused.stderr
