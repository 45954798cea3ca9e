"""The numba solid kernel on element ranges, one thread each (``kernels.solid.Split``): the same
bytes as on one thread.

Every output of a split call (the CSR data and global force summed into arrays that already
hold values, the element forces, the trial state, the failure) is compared byte for byte with
the one-thread call on the same inputs.  The groups are small and the split threshold lowered
(``SolidElement.split_elements``), so that ranges share nodes: the entries both touch must be
summed in the one-thread order.  A worst-order executor runs the later ranges to completion
before the first starts, so a range that wrote a shared entry directly instead of deferring it
changes its sum's last bits every time, not only when the threads happen to interleave; the
real thread pool is checked too.  The policy (``core.threads.kernel_threads``, ``split_parts``)
by its environment variables, and a whole press-then-slide run: every output file the same
with the split on and off."""
from __future__ import annotations

from concurrent.futures import Future
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")     # the fast extra; CI installs it with the test extra

from lagamine_py import kernels                                  # noqa: E402
from lagamine_py.core import threads                             # noqa: E402
from lagamine_py.deck import load_deck                           # noqa: E402
from lagamine_py.elements.base import StepContext                # noqa: E402
from lagamine_py.elements.solid import SolidElement              # noqa: E402
from lagamine_py.elements.structured import rectangle            # noqa: E402
from lagamine_py.output import default_writers                   # noqa: E402
from lagamine_py.registry import get                             # noqa: E402
from lagamine_py.solver import run                               # noqa: E402
from lagamine_py.solver.pattern import Pattern                   # noqa: E402
from runner import DECKS                                         # noqa: E402

LAW = dict(E=210e3, NU=0.3, SIGMAY=250.0, H=2000.0)


class WorstOrder:
    """An executor that runs a submitted range at once, to its end: the later ranges before
    the first (which the caller's thread runs after submitting them)."""

    def submit(self, fn, *args):
        f = Future()
        f.set_result(fn(*args))
        return f


def group_and_state(ename: str, nx: int = 9, ny: int = 11, seed: int = 5):
    """A distorted ``nx`` x ``ny`` mesh, J2_LINEAR with a random committed state (some points
    plastic), displacements at the start and end of an increment."""
    cls = get("elements", ename)
    rect = rectangle(cls, 1.0, 0.0, 2.0, 1.5, nx, ny)
    rng = np.random.default_rng(seed)
    xy = rect.coords + 0.02 * rng.uniform(-1.0, 1.0, rect.coords.shape)
    group = cls(np.arange(len(rect.conn)), rect.conn, xy, get("laws", "J2_LINEAR")(**LAW), 2.0)
    group.use_kernels(True)
    assert group.fused
    state = group.init_state()
    state["eps_e"] = 1e-3 * rng.standard_normal(state["eps_e"].shape)
    state["peeq"] = np.abs(2e-3 * rng.standard_normal(state["peeq"].shape))
    u_old = 1e-3 * rng.standard_normal(xy.shape)
    return group, state, u_old + 0.002 * rng.standard_normal(xy.shape), u_old


def outputs(group, state, u_new, u_old, nlgeom, tangent, split_elements, workers=None,
            parts=2, pattern=None):
    """Every output of one ``compute_into`` call, the group split into ``parts`` ranges of
    ``split_elements`` elements at least (one range: a huge value); data and force start from
    the same non-zero values, so that any change of a sum's order shows in its last bits.  A
    new split unless ``pattern`` is the last call's (its split kept, buffers and all)."""
    if pattern is None:
        pattern = Pattern(2 * len(group.coords0), [group.dofs])
        group._cache.pop("kernel_split_key", None)
    rng = np.random.default_rng(11)
    data = rng.standard_normal(pattern.nnz) if tangent else None
    f_out = rng.standard_normal(pattern.ndof)
    group.split_elements = split_elements
    calls = kernels.calls["solid_split"]
    original = threads.kernel_threads
    threads.kernel_threads = lambda: parts
    try:
        if workers is None:
            r = group.compute_into(u_new, u_old, state, StepContext(nlgeom=nlgeom), tangent,
                                   data, f_out, pattern.positions[0])
        else:                       # the split built, then its executor replaced
            group._kernel_split(pattern.positions[0], group._kernel_geometry()[-1]).workers = \
                workers
            r = group.compute_into(u_new, u_old, state, StepContext(nlgeom=nlgeom), tangent,
                                   data, f_out, pattern.positions[0])
    finally:
        threads.kernel_threads = original
        del group.split_elements
    split = kernels.calls["solid_split"] - calls
    out = {"failure": np.array(str(r.failure or "")), "f_out": f_out, "f": np.asarray(r.f)}
    if tangent:
        out["data"] = data
    out.update({f"state {k}": np.asarray(v) for k, v in (r.state or {}).items()})
    out["pattern"] = pattern
    return out, split, group._cache.get("kernel_split")


def assert_same_bytes(one, split):
    one, split = dict(one), dict(split)
    del one["pattern"], split["pattern"]
    assert one.keys() == split.keys()
    for k, v in one.items():
        assert v.dtype == split[k].dtype and v.shape == split[k].shape, k
        assert v.tobytes() == split[k].tobytes(), \
            f"{k}: {np.count_nonzero(v != split[k])} entries differ from the one-thread call"


@pytest.mark.parametrize("ename", ["Q8PE", "Q8AX", "T6PE"])
@pytest.mark.parametrize("nlgeom", [False, True])
@pytest.mark.parametrize("tangent", [True, False])
def test_split_same_bytes_as_one_thread_worst_order(ename, nlgeom, tangent):
    group, state, u_new, u_old = group_and_state(ename)
    one, n1, _ = outputs(group, state, u_new, u_old, nlgeom, tangent, 10**9)
    two, n2, split = outputs(group, state, u_new, u_old, nlgeom, tangent, 16, WorstOrder())
    assert (n1, n2) == (0, 1)                               # the split path ran, once
    assert len(split.ranges) == 2 and split.ranges[0][1] % kernels.module("solid").LANES == 0
    deferred = split.deferred[0]
    # the ranges share nodes: entries of both, with several contributions of the second
    assert len(deferred.defer[3]) > 0 and len(deferred.defer[4]) > 0
    assert len(deferred.f_waves) >= 2 and len(deferred.k_waves) >= 2
    assert str(one["failure"]) == ""
    assert_same_bytes(one, two)


def test_split_same_bytes_on_the_thread_pool_and_three_ranges():
    """The process's worker pool (threads that may interleave with the caller's), and three
    ranges (the third defers entries of the first two, added after the second's)."""
    group, state, u_new, u_old = group_and_state("Q8PE", 12, 14)
    one, _, _ = outputs(group, state, u_new, u_old, True, True, 10**9)
    for parts, workers in ((2, None), (3, None), (3, WorstOrder())):
        for _ in range(3):
            got, n, split = outputs(group, state, u_new, u_old, True, True, 16, workers, parts)
            assert n == 1 and len(split.ranges) == parts
            assert_same_bytes(one, got)


def test_split_failure_in_a_deferring_element():
    """An inverted element at the second range's boundary: the same BAD_DET_F failure, and its
    buffer slots (not written: they hold the last call's values) left out of the sums."""
    group, state, u_new, u_old = group_and_state("Q8PE")
    last, _, split = outputs(group, state, u_new, u_old, True, True, 16, WorstOrder())
    lo = split.ranges[1][0]
    rows = np.flatnonzero(split.deferred[0].defer[0] >= 0)
    e = lo + rows[len(rows) // 2]
    nodes = group.conn[e]
    centre = group.coords0[nodes].mean(axis=0)
    bad = u_new.copy()
    bad[nodes] = u_old[nodes] - 2.0 * (group.coords0[nodes] - centre)   # turned inside out
    one, _, _ = outputs(group, state, bad, u_old, True, True, 10**9, pattern=last["pattern"])
    two, _, kept = outputs(group, state, bad, u_old, True, True, 16, WorstOrder(),
                           pattern=last["pattern"])
    assert kept is split and np.abs(split.deferred[0].defer[4]).max() > 0.0
    assert "det F" in str(one["failure"])
    assert_same_bytes(one, two)


def test_thread_count_policy(monkeypatch):
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    for var in ("LAGAMINE_THREADS", "OMP_NUM_THREADS"):
        monkeypatch.delenv(var, raising=False)
    assert threads.kernel_threads() == min(2, threads.DEFAULT_KERNEL_THREADS)
    for value, want in (("1", 1), ("2", 2), ("8", 2), ("off", 1), ("OFF", 1)):
        monkeypatch.setenv("LAGAMINE_THREADS", value)
        assert threads.kernel_threads() == want, value
    for value in ("0", "two", "-1"):
        monkeypatch.setenv("LAGAMINE_THREADS", value)
        with pytest.raises(ValueError, match="LAGAMINE_THREADS"):
            threads.kernel_threads()
    monkeypatch.delenv("LAGAMINE_THREADS")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")             # as CalculiX reads it
    assert threads.kernel_threads() == 1
    monkeypatch.setenv("LAGAMINE_THREADS", "2")            # ours first
    assert threads.kernel_threads() == 2
    monkeypatch.setattr(threads, "available_cores", lambda: 1)
    assert threads.kernel_threads() == 1                   # never more than the cores
    assert threads.split_parts(10**6, threads=1) == 1
    assert threads.split_parts(4095, threads=2, per_thread=2048) == 1
    assert threads.split_parts(4096, threads=2, per_thread=2048) == 2


def test_press_slide_every_output_byte_the_same_split_or_not(tmp_path, monkeypatch):
    """press-then-slide (its contact decisions amplify round-off) with KERNEL=NUMBA, the solid
    group on two ranges of 64 elements and on one: every CSV byte the same."""
    monkeypatch.setattr(threads, "available_cores", lambda: 2)
    monkeypatch.setattr(SolidElement, "split_elements", 16)
    texts = {}
    for setting in ("1", "2"):
        monkeypatch.setenv("LAGAMINE_THREADS", setting)
        model = load_deck(DECKS / "press_slide.dat")
        for step in model.steps:
            step.controls["KERNEL"] = "NUMBA"
        out = tmp_path / setting
        writers = default_writers(out, model, names=("CONTACT", "REACTIONS", "DISPLACEMENTS"))
        calls = kernels.calls["solid_split"]
        assert run(model, out, writers=writers).status == 0
        assert (kernels.calls["solid_split"] > calls) == (setting == "2")
        texts[setting] = {p.name: p.read_bytes() for p in sorted(out.glob("*.csv"))}
    assert texts["1"].keys() == texts["2"].keys() and len(texts["1"]) >= 3
    for name, text in texts["1"].items():
        assert text == texts["2"][name], name


def test_a_bad_thread_count_stops_run_before_anything_runs(tmp_path, monkeypatch, capsys):
    """LAGAMINE_THREADS=yes is said at once (exit 2, nothing written), not as "an unexpected
    error" at the first large group's evaluation, after earlier increments had run."""
    from lagamine_py.cli import main
    monkeypatch.setenv("LAGAMINE_THREADS", "yes")
    out = tmp_path / "out"
    deck = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert "LAGAMINE_THREADS='yes': expected a count (1, 2, ...) or off; nothing was run" in err
    assert not out.exists()
    assert main(["check", str(deck)]) == 2                  # check refuses what run refuses
    assert "LAGAMINE_THREADS='yes'" in capsys.readouterr().err
