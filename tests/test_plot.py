"""``lagamine-py plot``: the choice of states, and the pictures of a real (small) run.

The PNG files are checked by reading their bytes (signature, IHDR size) and by Pillow (a decoder
independent of matplotlib's writer): present, valid, of a sensible size, and not blank.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.cli import main as cli_main
from lagamine_py.plot import State, chosen_states, interface_curves, is_axisymmetric, plot_run
from runner import DECKS, run_deck

SMALL = """*HEADING
small press then slide: 8 x 4 Ramberg-Osgood block on a rigid flat
*MESH, NAME=B, TYPE=Q8PE, X0=0, Y0=0, LX=8, LY=4, NX=4, NY=2
*MATERIAL, NAME=S, LAW=RAMBERG_OSGOOD
E=210000, NU=0.3, SIGMA0=250, ALPHA=0.5, N=10
*SOLID, ELSET=B, MATERIAL=S
*FOUNDATION, NAME=F
-10, 0
5, 0
20, 0
*CONTACT LAW, NAME=C, TYPE=COULOMB
KP=1e6, KT=1e6, PHI=0.2
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=F, LAW=C
*STEP, NAME=PRESS, NLGEOM=YES
*STATIC
0.5, 1, 1e-3, 0.5
*DLOAD
B_TOP, P, 200
*END STEP
*STEP, NAME=SLIDE, NLGEOM=YES
*STATIC
0.25, 1, 1e-3, 0.25
*BOUNDARY
B_RIGHT, 1, 1, -0.002
*END STEP
"""
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from the IHDR chunk; asserts the PNG signature and chunk type."""
    head = Path(path).read_bytes()[:24]
    assert head[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    assert head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


def check_png(path: Path) -> tuple[int, int]:
    from PIL import Image
    w, h = png_size(path)
    assert 300 <= w <= 4000 and 200 <= h <= 4000, (path.name, w, h)
    with Image.open(path) as im:
        im.verify()
    with Image.open(path) as im:
        assert im.size == (w, h)
        colours = im.convert("RGB").getcolors(maxcolors=1_000_000)
    assert colours is None or len(colours) > 20, f"{path.name} looks blank"
    return w, h


# -- states on a synthetic contact table ---------------------------------------------------------
def table(rows, points=3):
    """contact-like table: every (step, increment, time) repeated for ``points`` Gauss points."""
    rows = [r for r in rows for _ in range(points)]
    return {"step": np.array([r[0] for r in rows], float),
            "increment": np.array([r[1] for r in rows], float),
            "time": np.array([r[2] for r in rows], float)}


TWO_STEPS = table([(1, 1, 0.25), (1, 2, 0.5), (1, 3, 0.75), (1, 4, 1.0),
                   (2, 1, 1.1), (2, 2, 1.2), (2, 3, 1.35), (2, 4, 1.6), (2, 5, 1.8), (2, 6, 2.0)])


def pairs(states):
    return [(s.step, s.increment) for s in states]


def test_default_states_end_of_steps_and_thirds_of_the_last_in_time():
    # 1/3 of step 2 is t = 1.333: nearest output 1.35 (inc 3); 2/3 is 1.667: nearest 1.6 (inc 4)
    assert pairs(chosen_states(TWO_STEPS)) == [(1, 4), (2, 3), (2, 4), (2, 6)]


def test_default_states_of_a_single_step_run():
    one = table([(1, 1, 0.25), (1, 2, 0.5), (1, 3, 0.75), (1, 4, 1.0)])
    # 1/3 -> 0.333: nearest 0.25 (inc 1); 2/3 -> 0.667: nearest 0.75 (inc 3)
    assert pairs(chosen_states(one)) == [(1, 1), (1, 3), (1, 4)]


def test_default_thirds_that_fall_on_the_end_are_not_repeated():
    short = table([(1, 1, 1.0), (2, 1, 2.0)])
    assert pairs(chosen_states(short)) == [(1, 1), (2, 1)]


@pytest.mark.parametrize("spec, expected", [
    ("2:2, 1", [(1, 4), (2, 2)]),            # sorted by time, STEP alone is its end
    ("1:end,2:last", [(1, 4), (2, 6)]),
    ("@1.75", [(2, 5)]),                     # nearest output time
    ("@0", [(1, 1)]),
    ("2,2:6", [(2, 6)]),                     # the same state once
    ("default", [(1, 4), (2, 3), (2, 4), (2, 6)]),
])
def test_states_spec(spec, expected):
    assert pairs(chosen_states(TWO_STEPS, spec)) == expected


@pytest.mark.parametrize("spec, words", [
    ("3", "no output in step 3"),
    ("1:7", "no output increment 7"),
    ("abc", "expected STEP"),
    ("@x", "expected @TIME"),
    ("2:foo", "not a number"),
])
def test_bad_states_spec_is_refused_by_name(spec, words):
    with pytest.raises(ValueError, match=words):
        chosen_states(TWO_STEPS, spec)


def test_state_labels_carry_step_name_and_time():
    states = chosen_states(TWO_STEPS, "1,2:3", {1: "PRESS", 2: "SLIDE"})
    assert states[0].label == "step 1 PRESS, end (t = 1)"
    assert states[1].label == "step 2 SLIDE, inc 3 (t = 1.35)"
    assert states[1].time == 1.35


# -- pictures of real runs -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("plot")
    deck = d / "small.dat"
    deck.write_text(SMALL)
    outcome, _, _ = run_deck(deck, d / "out")
    assert outcome.status == 0, outcome.message
    return d / "out"


def test_plot_writes_three_valid_pngs(small_run, tmp_path):
    assert plot_run(small_run, tmp_path) == 0
    for name in ("interface.png", "forces.png", "mesh.png"):
        check_png(tmp_path / name)
    assert not is_axisymmetric(small_run)


def test_mesh_of_a_wide_block_stacks_one_panel_per_step(small_run, tmp_path):
    """Two steps -> two panels, one above the other: the picture is taller than one panel."""
    assert plot_run(small_run, tmp_path / "two") == 0
    assert plot_run(small_run, tmp_path / "one", states="2") == 0
    w2, h2 = check_png(tmp_path / "two" / "mesh.png")
    w1, h1 = check_png(tmp_path / "one" / "mesh.png")
    assert w1 == w2 and h2 > 1.5 * h1


def test_cli_states_and_bad_states(small_run, tmp_path, capsys):
    assert cli_main(["plot", str(small_run), "-o", str(tmp_path), "--states", "1:1,2"]) == 0
    check_png(tmp_path / "interface.png")
    assert cli_main(["plot", str(small_run), "-o", str(tmp_path / "bad"), "--states", "5"]) == 2
    assert "no output in step 5" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_axisymmetric_run_is_drawn_with_z_horizontal(tmp_path):
    """axisym_press: a cylinder of radius 5 and height 10.  Drawn r-z (z across), the body is
    twice as wide as tall; drawn x-y it is twice as tall as wide."""
    outcome, _, _ = run_deck(DECKS / "axisym_press.dat", tmp_path / "out")
    assert outcome.status == 0, outcome.message
    assert is_axisymmetric(tmp_path / "out")
    assert plot_run(tmp_path / "out", tmp_path / "rz") == 0
    assert plot_run(tmp_path / "out", tmp_path / "xy", axes="xy") == 0
    w_rz, h_rz = check_png(tmp_path / "rz" / "mesh.png")
    w_xy, h_xy = check_png(tmp_path / "xy" / "mesh.png")
    assert w_rz > h_rz and h_xy > w_xy


def test_nothing_to_plot(tmp_path, capsys):
    assert plot_run(tmp_path) == 1
    assert "nothing to plot" in capsys.readouterr().err
    assert plot_run(tmp_path / "missing") == 1


@pytest.mark.parametrize("peeq, kind", [
    (np.zeros(5), "elastic"),
    (np.array([0.0, 0.1, 0.2, 0.3, 0.4]), "linear"),
    (np.r_[np.full(19, 1e-5), 1e-3], "log"),           # one element 100 x the 90th percentile
])
def test_peeq_colour_scale(peeq, kind):
    from lagamine_py.plot import _peeq_norm
    norm, got = _peeq_norm(peeq)
    assert got == kind
    if kind != "elastic":
        assert norm.vmax == peeq.max()


def test_interface_curves_one_per_state_and_pair():
    """Two pairs whose points interleave along x: each pair is its own curve, in x order (one
    curve through both would zig-zag between them); a table without the pair column is one pair."""
    x = np.array([0.0, 2.0, 1.0, 3.0, 0.5, 2.5])
    c = {"step": np.ones(6), "increment": np.ones(6), "x": x, "p": 10 * x, "tau": x,
         "status": np.array(["stick", "slip", "stick", "slip", "slip", "stick"], dtype=object),
         "contact": np.array(["A->F", "A->F", "A->F", "B->F", "B->F", "B->F"], dtype=object)}
    st = [State(1, 1, 1.0, "end")]
    curves = interface_curves(c, st, "x")
    assert [(i, j, name) for i, j, name, _ in curves] == [(0, 0, "end, A->F"), (0, 1, "end, B->F")]
    assert curves[0][3]["s"].tolist() == [0.0, 1.0, 2.0] and curves[1][3]["s"].tolist() == [0.5, 2.5, 3.0]
    assert curves[0][3]["stick"].tolist() == [True, True, False]
    assert curves[1][3]["p"].tolist() == [5.0, 25.0, 30.0]
    del c["contact"]
    (only,) = interface_curves(c, st, "x")
    assert only[2] == "end" and only[3]["s"].tolist() == sorted(x)


# -- what the pictures say -----------------------------------------------------------------------
def test_state_labels_carry_the_loads_reached_with_their_units():
    from lagamine_py.plot import Units
    loads = {(1, 4): {"P TOP": 200.0}, (2, 3): {"U1 RIGHT": -0.00167, "DIE dy": 0.5}}
    states = chosen_states(TWO_STEPS, "1,2:3", {1: "PRESS", 2: "SLIDE"}, loads, Units(("mm", "N", "MPa")))
    assert states[0].label == "step 1 PRESS, end: P TOP = 200 MPa (t = 1)"
    assert states[1].label == "step 2 SLIDE, inc 3: U1 RIGHT = -0.00167 mm, DIE dy = 0.5 mm (t = 1.35)"
    assert Units(()).of("stress") == " (deck units)" and Units(("m", "kN", "kPa"), True).of("force") == " (kN/rad)"
    assert chosen_states(TWO_STEPS, "1", {}, loads, Units(()))[0].label == "step 1, end: P TOP = 200 (t = 1)"


def test_deformation_scale_makes_small_displacements_visible():
    from lagamine_py.plot import deformation_scale
    u = np.array([[3e-3, 4e-3], [0.0, 0.0]])            # largest 5e-3 on a body of 40
    assert deformation_scale(u, 40.0) == 200.0          # 5e-3 * 200 = 1 = 2.5 % of 40 (below 5 %)
    assert deformation_scale(u * 100, 40.0) == 1.0      # 0.5 is already 1.25 % of 40: true scale
    assert deformation_scale(np.zeros((3, 2)), 40.0) == 1.0
    assert deformation_scale(np.array([[7e-4, 0.0]]), 10.0) == 500.0   # 0.35 of 0.5 wanted


def test_zoom_on_the_closed_zone_and_rounding():
    from lagamine_py.plot import closed_zone, parse_xlim, rounding_only
    s = np.linspace(0.0, 100.0, 101)
    p = np.where(np.abs(s - 50.0) <= 1.0, 10.0, 0.0)   # closed over 49..51
    lo, hi = closed_zone([(0, 0, "", {"s": s, "p": p})], s)
    assert lo < 49.0 < 51.0 < hi and hi - lo < 10.0
    assert closed_zone([(0, 0, "", {"s": s, "p": np.ones_like(s)})], s) is None   # all closed
    assert rounding_only([1e-14, -3e-13], 4000.0) and not rounding_only([1e-3], 4000.0)
    assert parse_xlim("2, 4.5") == (2.0, 4.5) and parse_xlim(None) is None
    for bad in ("4,2", "x,1", "1"):
        with pytest.raises(ValueError, match="--xlim"):
            parse_xlim(bad)


def test_cli_xlim_and_scale(small_run, tmp_path, capsys):
    assert cli_main(["plot", str(small_run), "-o", str(tmp_path), "--xlim", "1,3", "--scale", "100"]) == 0
    check_png(tmp_path / "interface.png")
    check_png(tmp_path / "mesh.png")
    assert cli_main(["plot", str(small_run), "-o", str(tmp_path / "bad"), "--xlim", "3,1"]) == 2
    assert cli_main(["plot", str(small_run), "-o", str(tmp_path / "bad"), "--scale", "-2"]) == 2
    assert "--scale" in capsys.readouterr().err
