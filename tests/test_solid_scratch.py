"""The NumPy NLGEOM solid path's work arrays and its reorganised operations (issue 17 item 8:
the per-call cost of the solid group, with results bit for bit).

The path writes its largest temporaries into work arrays through ``out=`` and a
chunk's tangent straight into the group's ``K``.  What must hold: a later call -- of the same
group, another chunk, another state -- never changes an earlier result (forces, tangent, state,
a deferred tangent); and every result is the one of a fresh group, to the bit.  (The work
arrays were kept between calls for a while; that held 3 MB at 40x20 and was undone.  These
tests are what would catch a pool that leaks into a result.)  ``_spectral`` writes out the einsum it replaced in that
einsum's order of operations: the same bytes, signed zeros included.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.elements.base import LATER, StepContext
from lagamine_py.elements.solid import _spectral, sym_eig2
from lagamine_py.registry import get

from meshgen import structured

CTX = StepContext(nlgeom=True, t_old=0.0, t_new=1.0, foundation_old={}, foundation_new={})
LAWS = {
    "Q8PE": ("RAMBERG_OSGOOD", dict(E=210000.0, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0)),
    "Q8AX": ("J2_LINEAR", dict(E=70000.0, NU=0.3, SIGMAY=200.0, H=1000.0)),
}


def _group(etype, nx=12, ny=10):
    ids, coords, elements = structured(nx, ny, lambda s, t: (40.0 * s + 3.0 * t * t + 1.0,
                                                              20.0 * t))
    nodes = np.array(sorted(coords))
    xy = np.array([coords[n] for n in nodes])
    index = {n: k for k, n in enumerate(nodes)}
    conn = np.array([[index[n] for n in el] for el in elements])
    name, params = LAWS[etype]
    return get("elements", etype)(np.arange(len(conn)), conn, xy, get("laws", name)(**params),
                                  1.0), xy


def _loads(xy, seed):
    rng = np.random.default_rng(seed)
    u = np.c_[0.004 * xy[:, 0], -0.006 * xy[:, 1]] + 1e-3 * rng.standard_normal(xy.shape)
    return u, 0.5 * u


def _bytes(r):
    """Every array of a result, copied as bytes."""
    out = {"f": r.f.tobytes()}
    if r.K is not None:
        out["K"] = r.K.tobytes()
    out.update({k: np.asarray(v).tobytes() for k, v in r.state.items()})
    return out


@pytest.mark.parametrize("etype", ["Q8PE", "Q8AX"])
@pytest.mark.parametrize("chunk", [None, 40])
def test_a_later_call_never_changes_an_earlier_result(etype, chunk):
    group, xy = _group(etype)
    if chunk:
        group.chunk = chunk                          # 120 elements: three chunks of 40
    state = group.init_state()
    (u1, o1), (u2, o2) = _loads(xy, 1), _loads(xy, 2)
    first = group.compute(u1, o1, state, CTX, True)
    deferred = group.compute(u1, o1, state, CTX, LATER)
    kept = _bytes(first)
    assert (first.state["peeq"] > 0).any()           # the return mapping ran
    # another evaluation, other displacements: the first results are untouched ...
    second = group.compute(u2, o2, first.state, CTX, True)
    assert _bytes(first) == kept
    assert _bytes(second) != kept
    # ... the deferred tangent, taken after it, is the first one's ...
    K_later = deferred.later()
    assert K_later.tobytes() == kept["K"]
    # ... and a fresh group gives the same bytes
    fresh, _ = _group(etype)
    if chunk:
        fresh.chunk = chunk
    assert _bytes(fresh.compute(u2, o2, first.state, CTX, True)) == _bytes(second)


def test_spectral_is_the_einsum_to_the_bit():
    rng = np.random.default_rng(7)
    eps = rng.standard_normal((300, 9, 4)) * 1e-3
    eps[::3, :, 3] = 0.0                             # principal axes on x, y: zero terms ...
    eps[1::3, :, 3] = -0.0                           # ... of both signs
    eps[::4, :, 1] = eps[::4, :, 0]                  # equal eigenvalues
    lam, V = sym_eig2(_tensor(eps))
    f = np.exp(2.0 * lam)
    ref = np.einsum("...ik,...k,...jk->...ij", V, f, V)
    got = _spectral(f, V)
    assert (got == 0.0).any()                        # the signed zeros were reached
    assert got.tobytes() == ref.tobytes()
    # any V (the function is generic): entries of both zero signs, so that both terms of a
    # sum can be -0.0, whose einsum sum is 0.0
    V = rng.choice([-1.0, -0.0, 0.0, 0.5, 1.0], size=(500, 2, 2))
    f = rng.choice([0.25, 1.0, 3.0], size=(500, 2))
    ref = np.einsum("...ik,...k,...jk->...ij", V, f, V)
    got = _spectral(f, V)
    assert np.signbit(ref[ref == 0.0]).sum() < np.signbit(
        (V[..., :, None, 0] * f[..., None, None, 0] * V[..., None, :, 0]
         + V[..., :, None, 1] * f[..., None, None, 1] * V[..., None, :, 1])[ref == 0.0]).sum()
    assert got.tobytes() == ref.tobytes()


def _tensor(eps):
    T = np.empty(eps.shape[:-1] + (2, 2))
    T[..., 0, 0], T[..., 1, 1] = eps[..., 0], eps[..., 1]
    T[..., 0, 1] = T[..., 1, 0] = 0.5 * eps[..., 3]
    return T
