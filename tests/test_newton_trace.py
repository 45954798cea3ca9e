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
