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

OPS = st.lists(st.tuples(st.sampled_from(fuzz.KINDS),
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


def test_the_judge_sees_check_and_run_disagree(tmp_path, monkeypatch):
    """A deck ``check`` accepts and ``run`` refuses (a step that cannot start), or the other way
    round: each is a disagreement."""
    from lagamine_py.solver import steps

    def cannot_start(self, si, step):
        raise steps.SetupError(f"step {si + 1} ({step.name}): *CONTROLS: refused at setup")
    monkeypatch.setattr(steps.Controller, "_setup_step", cannot_start)
    _, verdict = fuzz.fuzz_one("coulomb_block.dat", [], tmp_path, tag="setup")
    assert verdict.check == 0 and verdict.status == 1
    assert "check accepts a step that run cannot start (exit 1)" in verdict.problems
    assert fuzz.disagreement(0, 2, "") == ["check accepts what run refuses (exit 2)"]
    assert fuzz.disagreement(2, 3, "") == ["check refuses (exit 2) what run runs (exit 3)"]
    assert fuzz.disagreement(2, 2, "") == fuzz.disagreement(0, 3, "") == []


def test_the_judge_compares_neutral_forms_with_the_deck_as_written(tmp_path, monkeypatch):
    """Form-only mutations (CRLF, tabs, case ...) must not change check's summary nor the run;
    the judge sees a difference when the reader is made to drop the deck's last step."""
    ops = [("form", 0, fuzz.FORMS.index("crlf"), 0)]
    assert fuzz.neutral(ops) and not fuzz.neutral(ops + [("drop", 0, 0, 0)])
    _, verdict = fuzz.fuzz_one("coulomb_block.dat", ops, tmp_path, tag="crlf")
    assert not verdict.bad, verdict.problems
    from lagamine_py import deck as deck_pkg
    real = deck_pkg.load_deck

    def short(path, parameters=None):
        model = real(path, parameters=parameters)
        if "\r" in Path(path).read_text(newline=""):
            model.steps = model.steps[:1]
        return model
    monkeypatch.setattr(deck_pkg, "load_deck", short)
    _, verdict = fuzz.fuzz_one("coulomb_block.dat", ops, tmp_path, tag="crlf2")
    assert any(p.startswith("check differs from the deck as written") for p in verdict.problems)
    assert any(p.startswith("run differs from the deck as written") for p in verdict.problems)


@pytest.mark.parametrize("form, line, expected", [
    ("lower", "*STEP, NAME=PUSH", "*step, NAME=PUSH"),
    ("lower", "BLOCK_LEFT, 1, 1, 0.05", "block_left, 1, 1, 0.05"),
    ("tabs", "BLOCK_LEFT, 1, 1, 0.05", "BLOCK_LEFT,\t1,\t1,\t0.05"),
    ("trailing", "BLOCK_LEFT, 1, 1, 0.05", "BLOCK_LEFT, 1, 1, 0.05,"),
    ("split", "*STEP, NAME=PUSH", "*STEP,\nNAME=PUSH"),
    ("indent", "*STEP, NAME=PUSH", "\t*STEP, NAME=PUSH"),
    ("inline", "BLOCK_LEFT, 1, 1, 0.05", "BLOCK_LEFT, 1, 1, 0.05  ** a note")])
def test_form_mutations(form, line, expected):
    assert "\n".join(fuzz._form([line], form, 0, 1)) == expected


def test_control_mutations_cover_every_controls_key():
    """Every *CONTROLS key is drawn, with values past its bounds and a bad word."""
    text = (fuzz.DECKS / "coulomb_block.dat").read_text()
    params = fuzz.control_params()
    seen = set()
    for b in range(len(params)):
        out = fuzz.mutate(text, [("control", 0, b, 1)])
        assert "*CONTROLS\n" in out
        seen.add(out.split("*CONTROLS\n")[1].split("=")[0].upper())
    assert seen == {p.name for p in params}
    ir = next(p for p in params if p.name == "IR")
    assert {"-1", "1001", "2.5", "CUBIC", ""} <= set(fuzz._control_values(ir))


@pytest.mark.parametrize("ops, changed", [
    ([("number", 13, 0, 1)], True), ([("drop", 0, 0, 0)], True), ([("swap", 3, 3, 0)], False)])
def test_mutations_change_the_text(ops, changed):
    text = (fuzz.DECKS / "coulomb_block.dat").read_text()
    assert (fuzz.mutate(text, ops) != text) == changed
