"""Fuzzing ``run``, not only ``check``: mutated example decks run a few increments through the
command line; no traceback, no NaN in any output, every exit status 0, 2 or 3.

The mutations and the judge are those of ``tools/fuzz_run.py`` (the longer offline hunt); here
hypothesis draws a few, derandomised (the same examples every time: a failure is reproducible).
The judge itself is shown to catch what it looks for.
"""
import importlib.util
import math
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("fuzz_run", ROOT / "tools" / "fuzz_run.py")
fuzz = importlib.util.module_from_spec(_spec)
sys.modules["fuzz_run"] = fuzz                 # its dataclasses look their module up
_spec.loader.exec_module(fuzz)

OPS = st.lists(st.tuples(st.sampled_from(("number", "number", "number", "drop", "dup", "swap",
                                          "param")),
                         st.integers(0, 10**6), st.integers(0, 10**6), st.integers(0, 10**6)),
               min_size=1, max_size=4)


@settings(max_examples=25, derandomize=True, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(st.sampled_from(fuzz.FUZZED), OPS)
def test_mutated_decks_run_cleanly(tmp_path_factory, name, ops):
    work = tmp_path_factory.mktemp("fuzz")
    deck, verdict = fuzz.fuzz_one(name, ops, work, increments=2)
    assert not verdict.bad, f"{name} {ops}: {verdict.problems}\n{verdict.stderr}"


def test_the_unmutated_decks_run(tmp_path):
    for name in fuzz.FUZZED[:3]:
        _, verdict = fuzz.fuzz_one(name, [], tmp_path, increments=2, tag=name)
        assert verdict.status in (0, 3) and not verdict.bad, verdict.problems


def test_the_judge_sees_nan_tracebacks_and_warnings(tmp_path, monkeypatch):
    """A NaN in a table, an exception escaping, a NumPy warning on stderr: each is caught."""
    from lagamine_py.output import tables
    real = tables.ContactWriter.increment

    def nan_gap(self, result):
        for cp in result.contacts:
            cp.gap[0] = math.nan
        real(self, result)
    monkeypatch.setattr(tables.ContactWriter, "increment", nan_gap)
    _, verdict = fuzz.fuzz_one("coulomb_block.dat", [], tmp_path, tag="nan")
    assert any("contact.csv: column gap holds nan" in p for p in verdict.problems)
    monkeypatch.setattr(tables.ContactWriter, "increment", real)

    import numpy as np
    from lagamine_py.solver import steps

    def boom(self, *a, **k):
        np.float64(1e308) * 10                    # a leaking overflow warning
        raise RuntimeError("bug")
    monkeypatch.setattr(steps.Controller, "_save_restart", boom)
    _, verdict = fuzz.fuzz_one("coulomb_block.dat", [], tmp_path, tag="boom")
    assert "exit status 1" in verdict.problems
    assert "stderr holds 'unexpected error'" in verdict.problems
    assert any(p.startswith("RuntimeWarning: overflow") for p in verdict.problems)


@pytest.mark.parametrize("ops, changed", [
    ([("number", 13, 0, 1)], True), ([("drop", 0, 0, 0)], True), ([("swap", 3, 3, 0)], False)])
def test_mutations_change_the_text(ops, changed):
    text = (fuzz.DECKS / "coulomb_block.dat").read_text()
    assert (fuzz.mutate(text, ops) != text) == changed
