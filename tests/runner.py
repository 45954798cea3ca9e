"""Run a deck in-process and keep every converged IncrementResult (for residual histories)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from lagamine_py.deck import load_deck
from lagamine_py.output import DEFAULT_WRITERS, default_writers
from lagamine_py.output.base import Writer
from lagamine_py.results import RunResults
from lagamine_py.solver import run

DECKS = Path(__file__).resolve().parents[1] / "decks"


class Capture(Writer):
    params = ()

    def __init__(self):
        self.results = []
        self.failures = []

    def increment(self, result):
        self.results.append(result)

    def failed_attempt(self, info):
        self.failures.append(info)


def run_deck(deck, outdir, parameters=None):
    model = load_deck(Path(deck), parameters=parameters)
    cap = Capture()
    writers = default_writers(Path(outdir), model, names=DEFAULT_WRITERS + ("ENERGY",)) + [cap]
    outcome = run(model, Path(outdir), writers=writers, deck_path=Path(deck))
    return outcome, cap, RunResults(Path(outdir))


def convergence_orders(history):
    """log(r_{k+1}) / log(r_k) over the last iterations of a Newton residual history."""
    r = np.asarray(history, float)
    r = r[r > 0]
    return np.log(r[1:]) / np.log(r[:-1])


def is_quadratic(history, floor=1e-12):
    """Newton order at the end of a residual history, or None when too few iterations show it.

    The history is taken from its largest value on (the first iteration of the increment),
    normalised by it; the order is log(r_{k+1}) / log(r_k) for the last pair of residuals with
    r_{k+1} above the round-off floor.  2 is quadratic, 1 linear.
    """
    r = np.asarray(history, float)
    if len(r) == 0:
        return None
    r = r[int(np.argmax(r)):]
    r = r / r[0]
    r = r[r > floor / max(np.max(history), floor)]
    if len(r) < 3 or r[1] >= 1.0:
        return None
    return float(np.log(r[-1]) / np.log(r[-2]))
