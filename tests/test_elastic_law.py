"""LinearElastic: Hooke's law in the 4-vector convention, checked against closed forms.

* uniaxial stress (s22 = s33 = s12 = 0) needs e22 = e33 = -nu e11 and gives s11 = E e11;
* pure shear: s12 = G g12 with G = E / (2 (1 + nu));
* hydrostatic: s = 3 K e with K = E / (3 (1 - 2 nu)).

The tangent against finite differences, batched shapes and the committed state left unchanged
are checked for every registered law by tests/test_contracts.py (lagamine_py.contracts).
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
