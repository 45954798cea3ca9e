"""tools/newton_trace.py: the per-iteration trace of Newton with the contact points that switched."""
from __future__ import annotations

import io
import re
import sys
from pathlib import Path

import numpy as np

from lagamine_py.deck import load_deck
from lagamine_py.output import Writer

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import newton_trace  # noqa: E402


def test_switches_names_each_point_that_changed_state():
    """Points 0 (stick -> slip+) and 2 (slip+ -> slip-) changed, 1 and 3 did not."""
    last = np.array([1, 1, 2, 3], np.int8)
    code = np.array([2, 1, 3, 3], np.int8)
    assert newton_trace.switches(last, code) == "2: 0k+ 2+-"
    assert newton_trace.switches(np.zeros(20, np.int8), np.ones(20, np.int8), limit=2) == "20: 0ok 1ok ..."


def test_tail_gives_state_and_tau_over_p():
    out = newton_trace.tail(np.array([0, 1, 2], np.int8), np.array([0.0, -1.0, 2.0]),
                            np.array([0.0, 10.0, 10.0]), 2)
    assert out == "k-0.100 ++0.200"


class Results(Writer):
    params = ()

    def __init__(self):
        self.results = []

    def increment(self, result):
        self.results.append(result)


def test_trace_prints_one_line_per_solve_and_the_switches(tmp_path):
    """The main job's first increment (all points sticking at the start): one ``energy`` line per
    linear solve, as many as the controller reports for the increment, and a ``switched`` line
    after the first solve that lists as many points as it counts."""
    model = load_deck(ROOT / "decks" / "press_slide.dat")
    out, seen = io.StringIO(), Results()
    assert newton_trace.trace(model, tmp_path / "out", increments=1, out=out, writers=[seen]) is None
    text = out.getvalue()
    assert len(seen.results) == 1
    solves = re.findall(r"iter +\d+ +\|R\|/F = \S+ +energy", text)
    assert len(solves) == seen.results[0].iterations > 1
    first = re.search(r"switched (\d+): (.*)", text)
    n, listed = int(first.group(1)), first.group(2).replace(" ...", "").split()
    assert n > 0 and len(listed) == min(n, 12)


def test_first_report_is_newtons_first_residual_split_by_region(tmp_path):
    """``--first``: after each converged increment the residual of its first iterate, which must
    be Newton's own iteration-0 residual of that increment (its log line, an independent
    computation) for the increments that impose nothing (the press: no constrained DOF); the
    region shares add up to 100 %; the residual is the sum of the groups' force changes to the
    converged state (~0 residual there), so it is at most the sum of their norms."""
    model = load_deck(ROOT / "decks" / "press_slide.dat")
    out = io.StringIO()
    assert newton_trace.trace(model, tmp_path / "out", increments=3, out=out, first=True) is None
    text = out.getvalue()
    newton0 = [float(v) for v in re.findall(r"iter +0 +\|R\|/F = (\S+)", text)]
    reports = re.findall(r"first iterate \|R\|/F (\S+): \|R\|\^2 contact (\d+) % \([^)]*\); "
                         r"edge (\d+) %; body (\d+) %", text)
    changes = re.findall(r"\|df\|/F by kind: (.*)", text)
    assert len(newton0) == len(reports) == len(changes) == 3
    for r0, (rel, *shares), change in zip(newton0, reports, changes):
        assert float(rel) == np.float64(r0) or abs(float(rel) / r0 - 1.0) < 1e-3
        assert abs(sum(int(s) for s in shares) - 100) <= 2          # each share rounded
        total = sum(float(v) for v in re.findall(r"\w+ (\S+?)(?:,|$)", change))
        assert float(rel) <= total * (1 + 1e-3) + 1e-8
    assert float(reports[1][0]) < 1e-2 < float(reports[0][0])     # extrapolated vs from rest


def test_regions_of_the_main_job():
    """The contact nodes are the bottom edge's (y = 0, closed form from the mesh), the imposed
    edge's neighbours those of the elements touching x = 40 off the bottom edge."""
    from lagamine_py.solver.problem import build_problem
    model = load_deck(ROOT / "decks" / "press_slide.dat")
    problem = build_problem(model)
    x = model.coords
    right = np.flatnonzero(np.isclose(x[:, 0], 40.0))
    constrained = 2 * right                       # BLOCK_RIGHT, DOF 1
    zones = newton_trace.regions(problem, constrained)
    assert np.array_equal(zones["contact"], np.isclose(x[:, 1], 0.0))
    # the right column of Q8 elements spans x = 37.5 .. 40 (h = 2.5)
    assert np.array_equal(zones["edge"], (x[:, 0] >= 37.5 - 1e-9) & ~np.isclose(x[:, 1], 0.0))
    assert np.array_equal(zones["body"], ~(zones["contact"] | zones["edge"]))


def test_strip_nodes_are_the_element_layers_along_the_interface():
    """The main job's mesh is 16 x 8 Q8 elements of 2.5 mm on a 40 x 20 mm block in contact
    along y = 0: the strip of k element layers is the nodes with y <= 2.5 k (closed form from
    the mesh), all of them from k = 8 on."""
    from lagamine_py.solver.problem import build_problem
    model = load_deck(ROOT / "decks" / "press_slide.dat")
    problem = build_problem(model)
    y = model.coords[:, 1]
    for k in (0, 1, 2, 4, 8, 9):
        assert np.array_equal(newton_trace.strip_nodes(problem, k), y <= 2.5 * k + 1e-9)


def test_strip_oracle_and_relaxation_on_the_whole_body_are_the_converged_and_newton(tmp_path):
    """``--strip`` / ``--relax`` with a strip of every node (k = 8 on the main job): the oracle
    is the converged answer itself (its |R|/F at the tolerance's level, 100 % of the error in
    the strip), and one relaxation sweep is Newton's first solve, whose iteration-1 |R|/F the
    log gives (an independent computation; the trace divides by the first iterate's force
    scale, Newton by each iterate's own, so they agree to 1 % once the scale settles: from the
    press's second increment on).  The contact nodes alone (k = 0) hold a part of the error."""
    model = load_deck(ROOT / "decks" / "press_slide.dat")
    out = io.StringIO()
    assert newton_trace.trace(model, tmp_path / "out", increments=4, out=out, strip=(0, 8),
                              relax=(8,)) is None
    text = out.getvalue()
    newton1 = [float(v) for v in re.findall(r"iter +1 +\|R\|/F = (\S+)", text)]
    oracle = re.findall(r"strip oracle \|R\|/F: k=0 (\S+) \((\d+) % nodes, (\d+) % error\), "
                        r"k=8 (\S+) \(100 % nodes, 100 % error\)", text)
    relaxed = [float(v) for v in re.findall(r"strip relaxed \|R\|/F per sweep: k=8 (\S+)", text)]
    assert len(newton1) == len(oracle) == len(relaxed) == 4
    for _, nodes, error, whole in oracle:
        assert float(whole) < 1e-8 and int(nodes) == 8 and int(error) < 100
    for r1, sweep in zip(newton1[1:], relaxed[1:]):
        assert abs(sweep / r1 - 1.0) < 1e-2
