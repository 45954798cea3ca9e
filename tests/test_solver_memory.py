"""Memory of the linear solves (issue 17 item 5): SPLU lets its last factor go before it
computes the next and gives the heap's free pages back to the system first; the K_ff gather
through a mask is the gather through the free entries' indices."""
from __future__ import annotations

import sys

import numpy as np
import pytest
import scipy.sparse as sp

from lagamine_py.solver import linear
from lagamine_py.solver.linear import FreeDofs, SpluSolver
from lagamine_py.solver.pattern import Pattern


def _rss_kb() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS")


def _matrix(n=400, seed=0):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.02, random_state=rng, format="csr") + 10.0 * sp.eye(n)
    A = A.tocsr()
    A.sort_indices()
    return A


def test_splu_drops_its_last_factor_and_trims_before_the_next(monkeypatch):
    """At the call of SuperLU for the second factorisation no earlier factor is held and the
    heap was trimmed just before (matrices past ``TRIM_FILL``); the solutions are those of a
    fresh solver."""
    monkeypatch.setattr(linear, "TRIM_FILL", 0)
    seen = []
    real_splu, real_trim = linear.splu, linear.return_free_heap
    s = SpluSolver()

    def spy_splu(*a, **k):
        seen.append(("splu", getattr(s, "lu", None) is None))
        return real_splu(*a, **k)

    def spy_trim():
        seen.append(("trim", None))
        real_trim()

    monkeypatch.setattr(linear, "splu", spy_splu)
    monkeypatch.setattr(linear, "return_free_heap", spy_trim)
    A1, A2 = _matrix(seed=1), _matrix(seed=2)
    b = np.ones(A1.shape[0])
    s.factor(A1)
    s.factor(A2)
    assert seen == [("trim", None), ("splu", True)] * 2
    fresh = SpluSolver()
    fresh.factor(A2)
    np.testing.assert_array_equal(s.solve(b), fresh.solve(b))


def test_splu_trims_only_past_the_fill_threshold(monkeypatch):
    """A small system (the main job's 849 DOFs, a 74k-entry factor) is factorised without a
    trim: it handed back pages the next factorisation faulted in again.  The trim comes back
    once the last factor, or the matrix to factorise, holds ``TRIM_FILL`` entries."""
    trims = []
    monkeypatch.setattr(linear, "return_free_heap", lambda: trims.append(1))
    A = _matrix(seed=1)
    s = SpluSolver()
    s.factor(A)
    s.factor(A)
    assert linear.TRIM_FILL > s.lu.nnz > A.nnz and trims == []     # the default: no trim
    monkeypatch.setattr(linear, "TRIM_FILL", s.lu.nnz)             # the last factor reaches it
    s.factor(A)
    assert trims == [1]
    monkeypatch.setattr(linear, "TRIM_FILL", A.nnz)                # the matrix alone reaches it
    SpluSolver().factor(A)
    assert trims == [1, 1]
    monkeypatch.setattr(linear, "TRIM_FILL", A.nnz + 1)            # neither: a new solver
    SpluSolver().factor(A)
    assert trims == [1, 1]


@pytest.mark.skipif(not sys.platform.startswith("linux") or linear._malloc_trim() is None,
                    reason="glibc's malloc_trim")
def test_return_free_heap_gives_freed_blocks_back():
    """60 MB of 64 KB blocks (below glibc's mmap threshold: they live in the heap) freed under a
    block still in use stay resident until the trim; the trim returns them."""
    blocks = [bytearray(64 * 1024) for _ in range(960)]
    for b in blocks:
        b[::4096] = b"\x01" * len(b[::4096])          # touched: resident
    keep = bytearray(64 * 1024)                       # above them: the heap's top cannot shrink
    before = _rss_kb()
    del blocks
    held = _rss_kb()
    linear.return_free_heap()
    after = _rss_kb()
    assert held - after > 40_000, (before, held, after)
    del keep


def test_kff_through_the_mask_is_the_gather_through_indices():
    """``FreeDofs.ff`` is a mask of the full data: K_ff equals the reference built from the
    free entries' indices (flatnonzero) and scipy's own slicing of the full matrix."""
    rng = np.random.default_rng(4)
    dofs = [rng.choice(60, size=(25, 6), replace=True)]
    pat = Pattern(60, dofs)
    free = FreeDofs(pat, np.array([0, 1, 7, 30, 59]))
    data = rng.standard_normal(pat.nnz)
    K = free.kff(data)
    full = pat.matrix(data)
    assert free.ff.dtype == bool and free.ff.shape == (pat.nnz,)
    np.testing.assert_array_equal(K.data, data[np.flatnonzero(free.ff)])
    np.testing.assert_array_equal(K.toarray(), full[free.free][:, free.free].toarray())
