"""The single-material-point driver: mixed strain/stress paths with a local Newton.

Asserted numbers: closed forms of isotropic elasticity under the prescribed constraints,
and of perfect J2 plasticity in pure shear (``s12 = SIGMAY / sqrt(3)``).
"""
import numpy as np
import pytest

from lagamine_py.laws.j2 import J2Linear
from lagamine_py.laws.material_point import drive_material_point as drive, plane_strain_uniaxial, uniaxial_stress
from lagamine_py.laws.ramberg_osgood import RambergOsgood

E, NU = 70e3, 0.25


def elastic_law():
    return J2Linear(E=E, NU=NU, SIGMAY=1e12)                         # never yields


def test_uniaxial_stress_elastic_closed_form():
    e = np.linspace(0, 2e-3, 5)[1:]
    res = uniaxial_stress(elastic_law(), e)
    assert res.converged.all() and res.stress.shape == (4, 4) and res.peeq.shape == (4,)
    assert np.allclose(res.stress[:, 0], E * e, rtol=1e-12)
    assert np.allclose(res.strain[:, 1:3], (-NU * e)[:, None], rtol=1e-12)
    assert np.allclose(res.stress[:, 1:], 0.0, atol=1e-12 * E * e.max())
    assert np.all(res.peeq == 0.0)


def test_plane_strain_uniaxial_elastic_closed_form():
    e = np.array([1e-3, -5e-4, 2e-3])                                # any sign, non-monotone
    res = plane_strain_uniaxial(elastic_law(), e)
    s11 = E / (1 - NU ** 2) * e
    assert np.allclose(res.stress[:, 0], s11, rtol=1e-12)
    assert np.allclose(res.stress[:, 2], NU * s11, rtol=1e-12)
    assert np.allclose(res.strain[:, 1], -NU / (1 - NU) * e, rtol=1e-12)
    assert np.all(res.strain[:, 2] == 0.0)


def test_prescribed_nonzero_stress_component():
    """e11 prescribed, s22 = 50 prescribed, s33 = s12 = 0: e11 = (s11 - NU s22)/E."""
    e = np.array([1e-3, 2e-3])
    path = np.zeros((2, 4))
    path[:, 0] = e
    res = drive(elastic_law(), path, free=(1, 2, 3), stress_path=[[50.0, 0, 0], [50.0, 0, 0]])
    s11 = E * e + NU * 50.0
    assert np.allclose(res.stress[:, 0], s11, rtol=1e-12)
    assert np.allclose(res.stress[:, 1], 50.0, rtol=1e-12)
    assert np.allclose(res.strain[:, 1], (50.0 - NU * s11) / E, rtol=1e-12)


def test_pure_shear_saturates_at_perfect_plastic_shear_yield():
    sy = 240.0
    law = J2Linear(E=E, NU=NU, SIGMAY=sy)
    G = E / (2 * (1 + NU))
    g = np.linspace(0, 4 * sy / (np.sqrt(3) * G), 9)[1:]             # engineering shear strain
    path = np.zeros((8, 4))
    path[:, 3] = g
    res = drive(law, path, free=(0, 1, 2))
    assert res.converged.all()
    s12 = np.minimum(G * g, sy / np.sqrt(3))
    assert np.allclose(res.stress[:, 3], s12, rtol=1e-12)
    assert np.allclose(res.strain[:, :3], 0.0, atol=1e-15)         # no dilatancy, no normal strain
    plastic = G * g > sy / np.sqrt(3)
    assert np.allclose(res.peeq[plastic], (g[plastic] - s12[plastic] / G) / np.sqrt(3), rtol=1e-10)


class _FailsBeyond(J2Linear):
    """A law that reports a failed return mapping once |e11_trial| > 5e-3."""

    def update(self, eps_e_trial, state):
        stress, D, new, ok = super().update(eps_e_trial, state)
        return stress, D, new, ok & (np.abs(eps_e_trial[..., 0]) <= 5e-3)


def test_failed_increment_stops_the_path():
    res = uniaxial_stress(_FailsBeyond(E=E, NU=NU, SIGMAY=1e12), [1e-3, 4e-3, 6e-3, 1e-3])
    assert res.converged.tolist() == [True, True, False, False]
    assert np.isnan(res.stress[2:]).all() and np.isfinite(res.stress[:2]).all()
    assert np.allclose(res.stress[:2, 0], E * np.array([1e-3, 4e-3]), rtol=1e-12)


def test_module_example_runs():
    import doctest

    import lagamine_py.laws.material_point as mp
    assert doctest.testmod(mp).failed == 0


@pytest.mark.parametrize("n", [5, 50])
def test_large_first_increment_converges_quickly(n):
    """One increment deep into the plastic range from the virgin state (infinite initial
    hardening slope): the local Newton with the consistent tangent must still converge."""
    law = RambergOsgood(E=E, NU=NU, SIGMA0=200.0, ALPHA=0.5, N=n)
    for driver in (uniaxial_stress, plane_strain_uniaxial):
        res = driver(law, [0.1])
        assert res.converged.all() and res.iterations[0] <= 8
