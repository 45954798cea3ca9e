"""LinearElastic: Hooke's law in the 4-vector convention, checked against closed forms.

* uniaxial stress (s22 = s33 = s12 = 0) needs e22 = e33 = -nu e11 and gives s11 = E e11;
* pure shear: s12 = G g12 with G = E / (2 (1 + nu));
* hydrostatic: s = 3 K e with K = E / (3 (1 - 2 nu));
* D equals the finite-difference derivative of the stress; the state is passed through.
"""
import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.laws.elastic import LinearElastic
from lagamine_py.registry import ParamError

E, NU = 70e3, 0.33


def test_registered_and_parameters_validated():
    assert registry.get("laws", "ELASTIC") is LinearElastic
    law = LinearElastic(E="70e3", nu="0.33")
    assert law.elastic_moduli() == (E, NU)
    for bad in (dict(E=0.0, NU=0.3), dict(E=-1.0, NU=0.3), dict(E=1.0, NU=0.5),
                dict(E=1.0, NU=-1.0), dict(E=1.0), dict(E=1.0, NU=0.3, RHO=1.0)):
        with pytest.raises(ParamError):
            LinearElastic(**bad)


def test_closed_forms():
    law = LinearElastic(E=E, NU=NU)
    e = 1e-3
    eps = np.array([[e, -NU * e, -NU * e, 0.0],      # uniaxial stress
                    [0.0, 0.0, 0.0, e],              # pure shear
                    [e, e, e, 0.0]])                 # hydrostatic
    s, D, state, ok = law.update(eps, law.init_state((3,)))
    assert np.allclose(s[0], [E * e, 0, 0, 0], atol=1e-12 * E * e)
    assert np.allclose(s[1], [0, 0, 0, E / (2 * (1 + NU)) * e], atol=1e-12 * E * e)
    assert np.allclose(s[2, :3], E / (1 - 2 * NU) * e, rtol=1e-13) and s[2, 3] == 0
    assert ok.all() and ok.shape == (3,)
    assert np.array_equal(state["eps_e"], eps) and not state["peeq"].any()


def test_batched_tangent_equals_finite_differences():
    law = LinearElastic(E=E, NU=NU)
    rng = np.random.default_rng(0)
    eps = 1e-3 * rng.normal(size=(2, 3, 4))
    st = law.init_state((2, 3))
    st["peeq"][:] = 0.25
    s, D, new, ok = law.update(eps, st)
    assert s.shape == (2, 3, 4) and D.shape == (2, 3, 4, 4) and ok.shape == (2, 3)
    h = 1e-6
    for t in range(4):
        d = np.zeros(4)
        d[t] = h
        fd = (law.update(eps + d, st)[0] - law.update(eps - d, st)[0]) / (2 * h)
        assert np.allclose(D[..., :, t], fd, rtol=1e-8, atol=1e-6)
    assert np.all(new["peeq"] == 0.25)
    new["peeq"][:] = 1.0
    assert np.all(st["peeq"] == 0.25)          # the committed state is not modified
