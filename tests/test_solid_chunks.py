"""A solid group computed in chunks of elements gives, bit for bit, what it gives in one block
(SolidElement.chunk sets the chunk size for speed and memory only: issue 17)."""
import numpy as np
import pytest

from lagamine_py.elements.base import StepContext
from lagamine_py.registry import get

from meshgen import structured


def _group(etype, law_name, params, nx=30, ny=20):
    ids, coords, elements = structured(nx, ny, lambda s, t: (40.0 * s + 3.0 * t * t, 20.0 * t))
    nodes = np.array(sorted(coords))
    xy = np.array([coords[n] for n in nodes])
    index = {n: k for k, n in enumerate(nodes)}
    conn = np.array([[index[n] for n in el] for el in elements])
    law = get("laws", law_name)(**params)
    return get("elements", etype)(np.arange(len(conn)), conn, xy, law, 1.0), xy


@pytest.mark.parametrize("nlgeom", [False, True])
@pytest.mark.parametrize("etype,law_name,params", [
    ("Q8PE", "RAMBERG_OSGOOD", dict(E=210000.0, NU=0.3, SIGMA0=250.0, ALPHA=0.5, N=10.0)),
    ("Q8AX", "J2_LINEAR", dict(E=70000.0, NU=0.3, SIGMAY=200.0, H=1000.0)),
])
def test_chunked_equals_one_block(etype, law_name, params, nlgeom):
    group, xy = _group(etype, law_name, params)
    assert len(group.conn) == 600                        # > chunk: three chunks of 200
    rng = np.random.default_rng(0)
    u = np.c_[0.004 * xy[:, 0], -0.006 * xy[:, 1]] + 1e-3 * rng.standard_normal(xy.shape)
    u_old = 0.5 * u
    ctx = StepContext(nlgeom=nlgeom, t_old=0.0, t_new=1.0, foundation_old={}, foundation_new={})
    state = group.init_state()
    chunked = group.compute(u, u_old, state, ctx, True)
    group.chunk = 10 ** 9                                # the whole group in one block
    whole = group.compute(u, u_old, state, ctx, True)
    assert not whole.failure and not chunked.failure
    np.testing.assert_array_equal(chunked.f, whole.f)
    np.testing.assert_array_equal(chunked.K, whole.K)
    assert set(chunked.state) == set(whole.state)
    for key in whole.state:
        np.testing.assert_array_equal(chunked.state[key], whole.state[key])
    # and the load is large enough for the return mapping to run somewhere
    assert (whole.state["peeq"] > 0).any()
