"""The C heap's policy of a small run (issue 17 item 3): ``lagamine-py run`` of a model of up to
``KEEP_HEAP_DOFS`` DOFs keeps freed blocks in the heap (glibc ``mallopt``), so the arrays an
evaluation or a factorisation makes again are not faulted in again page by page; a larger
model leaves glibc's default (the memory item's peaks)."""
from __future__ import annotations

from pathlib import Path

from lagamine_py import cli
from lagamine_py.solver import linear

DECK = Path(__file__).resolve().parents[1] / "decks" / "flat_punch.dat"


def test_keep_freed_heap_sets_both_thresholds(monkeypatch):
    calls = []
    monkeypatch.setattr(linear, "_mallopt", lambda: lambda param, value: calls.append((param, value)) or 1)
    assert linear.keep_freed_heap()
    assert calls == [(-1, linear.KEPT_TRIM_THRESHOLD), (-3, linear.KEPT_MMAP_THRESHOLD)]
    assert linear.KEPT_MMAP_THRESHOLD >= 1 << 20 and linear.KEPT_TRIM_THRESHOLD > linear.KEPT_MMAP_THRESHOLD


def test_keep_freed_heap_without_mallopt_or_refused(monkeypatch):
    monkeypatch.setattr(linear, "_mallopt", lambda: None)
    assert not linear.keep_freed_heap()
    monkeypatch.setattr(linear, "_mallopt", lambda: lambda param, value: 0)
    assert not linear.keep_freed_heap()


def test_glibc_mallopt_is_found_on_linux():
    import sys
    if sys.platform.startswith("linux"):
        assert linear._mallopt() is not None


def _run_small_deck(monkeypatch, tmp_path, limit):
    kept = []
    monkeypatch.setattr(linear, "keep_freed_heap", lambda: kept.append(True) or True)
    monkeypatch.setattr(linear, "KEEP_HEAP_DOFS", limit)
    assert cli.main(["run", str(DECK), "-q", "--overwrite", "-o", str(tmp_path / f"out{limit}")]) == 0
    return kept


def test_run_keeps_the_heap_of_a_small_model_only(monkeypatch, tmp_path):
    # flat_punch: 4 x 2 Q8, 37 nodes, 74 DOFs
    assert _run_small_deck(monkeypatch, tmp_path, 74) == [True]
    assert _run_small_deck(monkeypatch, tmp_path, 73) == []
