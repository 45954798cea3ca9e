"""J2 plasticity with Ramberg-Osgood and linear hardening.

Independent sources of the asserted numbers: the Ramberg-Osgood closed form
``eps = s/E + ALPHA (SIGMA0/E)(s/SIGMA0)^N`` (uniaxial stress, where the radial return is
exact for any increment since the flow direction never turns); the bilinear closed form of
linear hardening; the rate equations of incremental J2 theory integrated by
``scipy.integrate.solve_ivp`` (plane strain, a non-proportional path); central finite
differences of the stress (algorithmic tangent); the radial-return equations themselves.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lagamine_py.core.tensors import von_mises
from lagamine_py.laws.j2 import J2Linear
from lagamine_py.laws.material_point import plane_strain_uniaxial, uniaxial_stress
from lagamine_py.laws.ramberg_osgood import RambergOsgood
from lagamine_py.registry import REGISTRY, ParamError

E, NU, S0, ALPHA = 200e3, 0.3, 300.0, 3.0 / 7.0
G = E / (2 * (1 + NU))


def ro(n):
    return RambergOsgood(E=E, NU=NU, SIGMA0=S0, ALPHA=ALPHA, N=n)


def ro_plastic(s, n):
    """Plastic strain of the Ramberg-Osgood curve at (von Mises) stress s."""
    return ALPHA * S0 / E * (np.abs(s) / S0) ** n


def rel(a, b):
    return np.max(np.abs(a - b) / np.abs(b))


# --------------------------------------------------------------------- registration, params
def test_registered_and_parameters_checked():
    assert REGISTRY.get("laws", "RAMBERG_OSGOOD") is RambergOsgood
    assert REGISTRY.get("laws", "J2_LINEAR") is J2Linear
    with pytest.raises(ParamError, match="N = 0.5 is below its lower bound 1"):
        RambergOsgood(E=E, NU=NU, SIGMA0=S0, ALPHA=ALPHA, N=0.5)
    with pytest.raises(ParamError, match="SIGMA0 must be > 0"):
        RambergOsgood(E=E, NU=NU, SIGMA0=0.0, ALPHA=ALPHA, N=5)
    with pytest.raises(ParamError, match="NU = 0.5 is above"):
        J2Linear(E=E, NU=0.5, SIGMAY=100.0)
    assert J2Linear(E=E, NU=NU, SIGMAY=100.0).values["H"] == 0.0


# --------------------------------------------------------------------- uniaxial closed form
@pytest.mark.parametrize("n", [3, 10, 20, 50])
@pytest.mark.parametrize("n_inc", [3, 200])
def test_uniaxial_stress_follows_closed_form_at_any_increment_size(n, n_inc):
    eps11 = np.linspace(0.0, 0.05, n_inc + 1)[1:]
    res = uniaxial_stress(ro(n), eps11)
    assert res.converged.all()
    s = res.stress[:, 0]
    p = ro_plastic(s, n)
    assert rel(s / E + p, eps11) < 1e-6                              # the curve itself
    assert rel(res.peeq, p) < 1e-6                                   # hardening variable
    assert rel(res.strain[:, 1], -NU * s / E - 0.5 * p) < 1e-6       # lateral: plastic incompressible
    assert np.allclose(res.strain[:, 1], res.strain[:, 2], rtol=1e-12)
    assert np.abs(res.stress[:, 1:]).max() < 1e-9 * s.max()


def test_unloading_is_elastic_and_reloading_rejoins_the_curve():
    n, e_max = 10, 0.01
    up = np.linspace(0.0, e_max, 21)[1:]
    first = uniaxial_stress(ro(n), up)
    s_max = first.stress[-1, 0]
    e_min = e_max - 0.5 * s_max / E                                  # unload half the stress
    path = np.concatenate([up, np.linspace(e_max, e_min, 6)[1:],
                           np.linspace(e_min, 2 * e_max, 60)[1:]])
    res = uniaxial_stress(ro(n), path)
    assert res.converged.all()
    s, e = res.stress[:, 0], res.strain[:, 0]
    back = slice(20, 25)                                             # unloading increments
    assert rel(s[back], s_max - E * (e_max - e[back])) < 1e-10
    assert np.all(res.peeq[back] == res.peeq[19])
    reload = np.arange(25, len(path))
    below = reload[e[reload] <= e_max]
    above = reload[e[reload] > e_max]
    assert len(below) >= 3 and len(above) >= 10
    assert rel(s[below], s_max - E * (e_max - e[below])) < 1e-10
    assert rel(s[above] / E + ro_plastic(s[above], n), e[above]) < 1e-6


@pytest.mark.parametrize("h", [0.0, 2000.0])
def test_linear_hardening_bilinear_closed_form(h):
    sy = 250.0
    eps11 = np.linspace(0.0, 0.02, 8)[1:] - 0.5e-3                 # 1st increment elastic
    eps11[0] = 0.5 * sy / E
    res = uniaxial_stress(J2Linear(E=E, NU=NU, SIGMAY=sy, H=h), eps11)
    assert res.converged.all()
    ey = sy / E
    s_ref = np.where(eps11 <= ey, E * eps11, sy + E * h / (E + h) * (eps11 - ey))
    p_ref = eps11 - s_ref / E                                       # uniaxial plastic strain
    assert rel(res.stress[:, 0], s_ref) < 1e-10
    assert np.allclose(res.peeq, p_ref, rtol=1e-9, atol=1e-14)
    assert rel(res.strain[:, 1], -NU * s_ref / E - 0.5 * p_ref) < 1e-9


# --------------------------------------------------------------------- plane strain vs ODE
def plane_strain_reference(n, eps11):
    """Incremental J2 rate equations with this hardening, under e33 = 0, s22 = s12 = 0.

    With q the von Mises stress, s the deviator and a = 3 s / (2 q) the flow direction,
    loading gives ``d peeq = peeq'(q) dq`` with ``peeq(q) = ALPHA (S0/E)(q/S0)^N`` and
    ``dq = a : d sigma``, so on the normal components (11, 22, 33)

        d eps = C d sigma,   C = [(1 + NU) I - NU 1 1^T] / E + peeq'(q) a a^T.

    With eps11 as the time and ``d sigma22 = 0``, ``d eps33 = 0``:
    ``[[C11, C13], [C31, C33]] [s11', s33'] = [1, 0]`` and ``e22' = C21 s11' + C23 s33'``.
    ``peeq'(0) = 0`` for N > 1, so the start at zero stress is regular.
    Returns (k, 3): s11, s33, e22 at ``eps11``.
    """
    def rhs(t, y):
        sig = np.array([y[0], 0.0, y[1]])
        s = sig - sig.mean()
        q = np.sqrt(1.5 * s @ s)
        C = ((1 + NU) * np.eye(3) - NU) / E
        if q > 0.0:
            a = 1.5 * s / q
            C = C + ALPHA * n / E * (q / S0) ** (n - 1) * np.outer(a, a)
        ds = np.linalg.solve(C[np.ix_([0, 2], [0, 2])], [1.0, 0.0])
        return [ds[0], ds[1], C[1, 0] * ds[0] + C[1, 2] * ds[1]]

    sol = solve_ivp(rhs, (0.0, eps11[-1]), [0.0, 0.0, 0.0], method="DOP853",
                    rtol=1e-12, atol=1e-13, t_eval=eps11)
    assert sol.success
    return sol.y.T


def _stress_error(res, ref):
    """Max over increments of |(s11, s33) - ref| / |ref|."""
    sig = res.stress[:, [0, 2]] if hasattr(res, "stress") else res
    return np.max(np.linalg.norm(sig - ref[:, :2], axis=1) / np.linalg.norm(ref[:, :2], axis=1))


@pytest.mark.parametrize("n", [3, 50])
def test_plane_strain_fine_increments_match_rate_equations(n):
    """Backward Euler is first order on this non-proportional path (the stress ratio s33/s11
    turns from NU to 1/2): measured max errors 6.5e-5 (N=3) and 2.2e-4 (N=50) with 2000
    increments, halving with the increment.  Richardson extrapolation of 2000/4000 increments
    (2 y_h/2 - y_h) must then match the ODE to 1e-6: it does only if the law's scheme is a
    consistent first-order approximation of the rate equations."""
    law, e_end = ro(n), 0.02
    coarse = plane_strain_uniaxial(law, np.linspace(0.0, e_end, 2001)[1:])
    fine = plane_strain_uniaxial(law, np.linspace(0.0, e_end, 4001)[1:])
    assert coarse.converged.all() and fine.converged.all()
    eps11 = coarse.strain[:, 0]
    ref = plane_strain_reference(n, eps11)
    err_fine = _stress_error(fine.stress[1::2, [0, 2]], ref)
    err_coarse = _stress_error(coarse, ref)
    assert 0.4 < err_fine / err_coarse < 0.6                        # first order
    extrapolated = 2.0 * fine.stress[1::2] - coarse.stress
    assert _stress_error(extrapolated[:, [0, 2]], ref) < 1e-6
    e22 = 2.0 * fine.strain[1::2, 1] - coarse.strain[:, 1]
    assert rel(e22, ref[:, 2]) < 1e-6


@pytest.mark.parametrize("n", [10, 20])
def test_plane_strain_coarse_increments_converge_first_order(n):
    law, e_end = ro(n), 0.02
    errors = []
    for n_inc in (10, 20, 40, 80):
        res = plane_strain_uniaxial(law, np.linspace(0.0, e_end, n_inc + 1)[1:])
        assert res.converged.all()
        errors.append(_stress_error(res, plane_strain_reference(n, res.strain[:, 0])))
    assert np.all(np.diff(errors) < 0.0)
    assert 0.4 < errors[-1] / errors[-2] < 0.65


# --------------------------------------------------------------------- return mapping itself
def random_trials(rng, m, sy, ratio):
    """Trial elastic strains (m, 4) with q_tr = ratio * sy, random deviatoric direction
    (shear included) and random volume change."""
    d = rng.normal(size=(m, 4))
    d[:, :3] -= d[:, :3].mean(1, keepdims=True)
    d /= np.sqrt(np.sum(d[:, :3] ** 2, 1) + 2 * d[:, 3] ** 2)[:, None]   # unit tensor norm
    e_dev = (ratio * sy / (np.sqrt(1.5) * 2 * G))[:, None] * d
    eps = e_dev * np.array([1.0, 1.0, 1.0, 2.0])                       # engineering shear
    eps[:, :3] += rng.uniform(-1e-3, 1e-3, size=(m, 1)) / 3
    return eps


@pytest.mark.parametrize("n", [3, 50])
def test_return_satisfies_the_radial_return_equations_at_any_increment(n):
    rng = np.random.default_rng(1)
    law, m = ro(n), 400
    peeq_n = np.concatenate([np.zeros(m // 4), 10 ** rng.uniform(-8, 0, m - m // 4)])
    sy = np.where(peeq_n > 0, S0 * (peeq_n / (ALPHA * S0 / E)) ** (1 / n), S0)
    ratio = np.where(peeq_n > 0, 1 + 10 ** rng.uniform(-9, 3, m), 10 ** rng.uniform(-8, 3, m))
    eps = random_trials(rng, m, sy, ratio).reshape(20, 20, 4)        # any leading shape
    state = {"eps_e": np.zeros((20, 20, 4)), "peeq": peeq_n.reshape(20, 20)}
    stress, D, new, ok = law.update(eps, state)
    assert ok.all() and stress.shape == (20, 20, 4) and D.shape == (20, 20, 4, 4)
    stress, eps, p = stress.reshape(m, 4), eps.reshape(m, 4), new["peeq"].reshape(m)
    q, q_tr = von_mises(stress), ratio * sy
    big = np.abs(stress[:, :3]).max(1) / q                           # hydrostatic round-off
    assert np.all(np.abs(ro_plastic(q, n) - p) <= 1e-11 * p * (1 + n * big))   # on the curve
    dp = p - peeq_n
    # (q recomputed from the stress carries the round-off of its hydrostatic part)
    scale = peeq_n + (q_tr + np.abs(stress).max(1)) / (3 * G)
    assert np.all(np.abs(dp - (q_tr - q) / (3 * G)) <= 1e-12 * scale)
    K = E / (3 * (1 - 2 * NU))
    assert np.allclose(stress[:, :3].mean(1), K * eps[:, :3].sum(1), rtol=1e-12, atol=1e-9)
    D_e = law.D_elastic
    assert np.allclose(new["eps_e"].reshape(m, 4) @ D_e.T, stress, rtol=1e-10, atol=1e-9)


def test_failure_to_converge_is_flagged():
    rng = np.random.default_rng(2)
    law = ro(50)
    law.max_iter = 1                                                 # instance override
    eps = random_trials(rng, 50, np.full(50, S0), np.full(50, 30.0))
    _, _, _, ok = law.update(eps, {"eps_e": 0 * eps, "peeq": np.full(50, 1e-3)})
    assert not ok.any()


# --------------------------------------------------------------------- algorithmic tangent
def fd_tangent(law, eps, state, rel_step=1e-6):
    """Central differences of the stress w.r.t. each trial strain component, all points."""
    h = rel_step * np.linalg.norm(eps, axis=-1)
    cols = []
    for t in range(4):
        de = np.zeros_like(eps)
        de[..., t] = h
        sp = law.update(eps + de, state)[0]
        sm = law.update(eps - de, state)[0]
        cols.append((sp - sm) / (2 * h[..., None]))
    return np.stack(cols, -1)


def plastic_states(rng, law, m, sy_of):
    peeq_n = np.concatenate([[0.0] * 4, 10 ** rng.uniform(-5, -1, m - 4)])
    sy = sy_of(peeq_n)
    eps = random_trials(rng, m, np.where(sy > 0, sy, S0), rng.uniform(1.05, 4.0, m))
    return eps, {"eps_e": np.zeros((m, 4)), "peeq": peeq_n}


@pytest.mark.parametrize("law, sy_of", [
    (ro(3), lambda p: S0 * (p / (ALPHA * S0 / E)) ** (1 / 3)),
    (ro(20), lambda p: S0 * (p / (ALPHA * S0 / E)) ** (1 / 20)),
    (ro(50), lambda p: S0 * (p / (ALPHA * S0 / E)) ** (1 / 50)),
    (J2Linear(E=E, NU=NU, SIGMAY=250.0), lambda p: 250.0 + 0 * p),
    (J2Linear(E=E, NU=NU, SIGMAY=250.0, H=3000.0), lambda p: 250.0 + 3000.0 * p),
], ids=["RO3", "RO20", "RO50", "perfect", "linear"])
def test_algorithmic_tangent_matches_finite_differences(law, sy_of):
    rng = np.random.default_rng(3)
    eps, state = plastic_states(rng, law, 40, sy_of)
    stress, D, new, ok = law.update(eps, state)
    assert ok.all() and np.all(new["peeq"] > state["peeq"])          # all plastic
    D_fd = fd_tangent(law, eps, state)
    err = np.abs(D - D_fd).max((-2, -1)) / np.abs(D).max((-2, -1))
    assert err.max() < 1e-6
    assert not np.allclose(D, law.D_elastic, rtol=1e-3)              # really the plastic branch


def test_elastic_points_get_elastic_tangent_and_batch_equals_pointwise():
    rng = np.random.default_rng(4)
    law = ro(10)
    peeq_n = np.full(30, 1e-3)
    sy = S0 * (1e-3 / (ALPHA * S0 / E)) ** 0.1
    ratio = np.concatenate([rng.uniform(0.1, 0.95, 10), rng.uniform(1.05, 3.0, 20)])
    eps = random_trials(rng, 30, np.full(30, sy), ratio)
    state = {"eps_e": np.zeros((30, 4)), "peeq": peeq_n}
    stress, D, new, ok = law.update(eps, state)
    elastic = ratio < 1.0
    assert np.all((new["peeq"] > peeq_n) == ~elastic)
    assert np.array_equal(D[elastic], np.broadcast_to(law.D_elastic, D[elastic].shape))
    assert np.array_equal(new["peeq"][elastic], peeq_n[elastic])
    for i in (0, 7, 12, 29):
        s1, D1, n1, _ = law.update(eps[i], {"eps_e": np.zeros(4), "peeq": peeq_n[i]})
        assert np.allclose(s1, stress[i], rtol=1e-13) and np.allclose(D1, D[i], rtol=1e-13)
