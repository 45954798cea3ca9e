"""Shared fixtures: each example deck is run once per test session (tests/test_regression.py
compares its tables with the reference; tests/test_recovery.py checks what its writers were
handed)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DECKS = sorted((ROOT / "decks").glob("*.dat"))
#: the writers of a regression run: the tables (no VTK: not compared)
TABLE_WRITERS = ("CONTACT", "REACTIONS", "STATUS", "DISPLACEMENTS", "TOOLS", "ENERGY")
# The solid-element kernel of tools/make_references.py.  The numba kernel differs from NumPy by
# round-off (1e-14 relative), which is enough to turn contact decisions in press_slide and
# tube_crimp (other increments, other histories): tests/test_kernel_twins.py compares them.
REFERENCE_KERNEL = "NUMPY"


@dataclass
class DeckRun:
    deck: Path
    outcome: object
    outdir: Path
    model: object
    results: list          # every IncrementResult the writers were handed, in order


@pytest.fixture(scope="session")
def deck_run(tmp_path_factory):
    """``deck_run(path)``: the run of an example deck with the reference kernel and the table
    writers into a temporary directory, done once per session."""
    from lagamine_py.deck import load_deck
    from lagamine_py.output import Writer, default_writers
    from lagamine_py.solver import run

    class Keep(Writer):
        def __init__(self):
            super().__init__(".", None)
            self.results = []

        def increment(self, result):
            self.results.append(result)

    done: dict[Path, DeckRun] = {}

    def get(deck: Path) -> DeckRun:
        if deck not in done:
            model = load_deck(deck)
            for step in model.steps:        # the kernel the references were made with
                step.controls["KERNEL"] = REFERENCE_KERNEL
            out = tmp_path_factory.mktemp(deck.stem)
            keep = Keep()
            writers = default_writers(out, model, names=TABLE_WRITERS) + [keep]
            outcome = run(model, out, writers=writers, deck_path=deck)
            done[deck] = DeckRun(deck, outcome, out, model, keep.results)
        return done[deck]

    return get
