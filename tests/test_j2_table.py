"""J2_TABLE: J2 plasticity with a piecewise-linear hardening table (Abaqus *PLASTIC).

Checked against the uniaxial closed form of the table (eps = sigma / E + eps_p with sigma =
sigma_y(eps_p) read off the table), the linear-hardening law J2_LINEAR where the table is one
straight segment, the radial return equations, and central finite differences of the tangent.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.core.params import ParamError
from lagamine_py.core.tensors import von_mises
from lagamine_py.deck import DeckError, load_deck
from lagamine_py.laws.j2 import J2Linear, J2Table
from lagamine_py.laws.material_point import uniaxial_stress

E, NU = 70000.0, 0.33
G = E / (2 * (1 + NU))
TABLE = [(100.0, 0.0), (130.0, 0.02), (150.0, 0.06), (160.0, 0.15)]


def table_law(table=TABLE):
    return J2Table(E=E, NU=NU, PLASTIC=table)


def uniaxial_closed_form(eps: np.ndarray, table=TABLE) -> np.ndarray:
    """sigma(eps) of monotonic uniaxial stress: elastic up to the first yield stress, then on
    segment k (sigma = s_k + H_k (p - e_k)) eps = sigma / E + p solved for p; flat beyond."""
    s, e = np.array(table, float).T
    out = np.minimum(E * eps, s[0])
    for k in range(len(s) - 1):
        H = (s[k + 1] - s[k]) / (e[k + 1] - e[k])
        p = (eps - (s[k] - H * e[k]) / E) / (1 + H / E)
        on = (p > e[k]) & (p <= e[k + 1])
        out = np.where(on, s[k] + H * (p - e[k]), out)
    return np.where(eps - s[-1] / E > e[-1], s[-1], out)


def test_registered_with_a_table_parameter():
    cls = registry.get("laws", "J2_TABLE")
    assert cls is J2Table
    (p,) = [p for p in cls.params if p.name == "PLASTIC"]
    assert p.type is tuple and p.columns == ("yield stress", "plastic strain")
    assert "table" in p.describe()


@pytest.mark.parametrize("n_inc", [7, 40, 400])
def test_uniaxial_stress_follows_the_table_at_any_increment_size(n_inc):
    """Exact at any increment size: the return walks the segments."""
    eps = np.linspace(0.0, 0.25, n_inc + 1)[1:]
    res = uniaxial_stress(table_law(), eps)
    assert res.converged.all()
    assert np.allclose(res.stress[:, 0], uniaxial_closed_form(eps), rtol=1e-10, atol=1e-9)
    assert np.allclose(res.peeq, np.maximum(eps - res.stress[:, 0] / E, 0.0), atol=1e-12)
    assert np.allclose(res.stress[:, 1:], 0.0, atol=1e-8)


def test_one_increment_across_every_segment():
    res = uniaxial_stress(table_law(), [0.2])                      # from 0 past the last row
    assert res.stress[0, 0] == pytest.approx(160.0, rel=1e-12)
    assert res.peeq[0] == pytest.approx(0.2 - 160.0 / E, rel=1e-12)


def test_unloading_is_elastic_and_reloading_yields_where_it_stopped():
    path = np.concatenate([np.linspace(0, 0.04, 9)[1:], np.linspace(0.04, 0.039, 6)[1:],
                           np.linspace(0.039, 0.05, 9)[1:]])
    res = uniaxial_stress(table_law(), path)
    s_top = uniaxial_closed_form(np.array([0.04]))[0]
    unload = res.stress[8:13, 0]
    assert np.allclose(unload, s_top - E * (0.04 - path[8:13]), rtol=1e-10)
    assert np.allclose(res.peeq[8:13], res.peeq[7], rtol=0, atol=1e-15)
    assert res.stress[-1, 0] == pytest.approx(uniaxial_closed_form(np.array([0.05]))[0], rel=1e-10)


def test_a_straight_table_is_linear_hardening_and_one_row_is_perfect_plasticity():
    eps = np.linspace(0, 0.05, 60)[1:]
    H = 1500.0
    straight = table_law([(120.0, 0.0), (120.0 + H * 0.2, 0.2)])
    linear = J2Linear(E=E, NU=NU, SIGMAY=120.0, H=H)
    assert np.allclose(uniaxial_stress(straight, eps).stress, uniaxial_stress(linear, eps).stress,
                       rtol=1e-11, atol=1e-9)
    flat = table_law([(120.0, 0.0)])
    perfect = J2Linear(E=E, NU=NU, SIGMAY=120.0)
    assert np.allclose(uniaxial_stress(flat, eps).stress, uniaxial_stress(perfect, eps).stress,
                       rtol=1e-12, atol=1e-9)


def random_trials(rng, m, q_tr):
    d = rng.normal(size=(m, 4))
    d[:, :3] -= d[:, :3].mean(1, keepdims=True)
    d /= np.sqrt(np.sum(d[:, :3] ** 2, 1) + 2 * d[:, 3] ** 2)[:, None]
    eps = (q_tr / (np.sqrt(1.5) * 2 * G))[:, None] * d * np.array([1.0, 1.0, 1.0, 2.0])
    eps[:, :3] += rng.uniform(-1e-3, 1e-3, size=(m, 1)) / 3
    return eps


def plastic_states(rng, law, m):
    """Committed plastic strains on every segment (and past the table), trials 1.01 to 3 times
    the current yield stress (some returns cross several rows)."""
    peeq_n = np.concatenate([[0.0] * 4, rng.uniform(0, 0.2, m - 4)])
    q_tr = law.yield_stress(peeq_n) * rng.uniform(1.01, 3.0, m)
    return random_trials(rng, m, q_tr), {"eps_e": np.zeros((m, 4)), "peeq": peeq_n}, q_tr


def test_return_lands_on_the_table_and_keeps_the_radial_return_equations():
    rng = np.random.default_rng(5)
    law = table_law()
    eps, state, q_tr = plastic_states(rng, law, 300)
    stress, D, new, ok = law.update(eps, state)
    assert ok.all()
    q, p = von_mises(stress), new["peeq"]
    s, e = np.array(TABLE).T
    assert np.allclose(q, np.interp(p, e, s), rtol=1e-12)                  # on the curve
    assert np.allclose(p - state["peeq"], (q_tr - q) / (3 * G), rtol=1e-9, atol=1e-15)
    assert np.all(p > state["peeq"])


def fd_tangent(law, eps, state, rel_step=1e-7):
    h = rel_step * np.linalg.norm(eps, axis=-1)
    cols = []
    for t in range(4):
        de = np.zeros_like(eps)
        de[..., t] = h
        cols.append((law.update(eps + de, state)[0] - law.update(eps - de, state)[0]) / (2 * h[..., None]))
    return np.stack(cols, -1)


def test_algorithmic_tangent_matches_finite_differences():
    rng = np.random.default_rng(6)
    law = table_law()
    eps, state, _ = plastic_states(rng, law, 60)
    stress, D, new, ok = law.update(eps, state)
    # away from the rows, where the slope jumps (the derivative is one-sided there)
    e = np.array(TABLE)[:, 1]
    away = np.abs(new["peeq"][:, None] - e[None, :]).min(1) > 1e-5
    D_fd = fd_tangent(law, eps, state)
    err = np.abs(D - D_fd).max((-2, -1)) / np.abs(D).max((-2, -1))
    assert away.sum() > 50 and err[away].max() < 1e-6
    assert not np.allclose(D, law.D_elastic, rtol=1e-3)


@pytest.mark.parametrize("table, words", [
    ([(100.0, 0.01), (120.0, 0.1)], "first row must be at plastic strain 0"),
    ([(100.0, 0.0), (120.0, 0.1), (130.0, 0.1)], "plastic strains must increase"),
    ([(-1.0, 0.0)], "yield stresses must be > 0"),
    ([(100.0, 0.0), (10.0, 1e-6)], "below -3G"),
    ([(100.0,)], "row of 2 numbers"),
])
def test_bad_tables_are_refused(table, words):
    with pytest.raises(ParamError, match=words):
        table_law(table)


DECK = """*NODE
1, 0, 0
2, 1, 0
3, 1, 1
4, 0, 1
*ELEMENT, TYPE=CPE4, ELSET=E
1, 1, 2, 3, 4
{material}
*SOLID, ELSET=E, MATERIAL=AL
*STEP
*STATIC
1, 1
*BOUNDARY
1, 1, 2
2, 2, 2
3, 2, 2, -0.01
4, 2, 2, -0.01
4, 1, 1
*END STEP
"""
OWN = "*MATERIAL, NAME=AL, LAW=J2_TABLE\nE=70000, NU=0.33\n*PLASTIC\n100, 0\n130, 0.02\n150, 0.06\n160, 0.15"
ABAQUS = "*Material, name=Al\n*Density\n2.7e-9,\n*Elastic\n70000., 0.33\n*Plastic\n100., 0.\n130., 0.02\n" \
         "150., 0.06\n160., 0.15"


def test_deck_gives_the_table_with_plastic_in_both_forms(tmp_path):
    """*MATERIAL, LAW=J2_TABLE with *PLASTIC, and Abaqus's *Material / *Elastic / *Plastic, make
    the same law."""
    models = []
    for text in (OWN, ABAQUS):
        deck = tmp_path / "d.dat"
        deck.write_text(DECK.format(material=text))
        models.append(load_deck(deck))
    a, b = (m.materials["AL"] for m in models)
    assert a.law == b.law == "J2_TABLE"
    assert a.params == b.params and a.params["PLASTIC"] == tuple(TABLE)
    assert any("*DENSITY" in n and "skipped" in n for n in models[1].notices)


@pytest.mark.parametrize("material, line, words", [
    (OWN.replace("100, 0\n", "100, 0.01\n"), 10, ["first row must be at plastic strain 0"]),
    (OWN.replace("*PLASTIC\n100, 0\n130, 0.02\n150, 0.06\n160, 0.15", ""), 8, ["missing required parameter PLASTIC"]),
    (OWN.split("\n*PLASTIC")[0] + ", PLASTIC=3", 9, ["PLASTIC is a table", "*PLASTIC block"]),
    (OWN.replace("E=70000, NU=0.33", "E=70000, NU=0.33, PLASTIC=3"), 9, ["PLASTIC is given by the *PLASTIC block"]),
    (ABAQUS.replace("*Elastic\n70000., 0.33\n", ""), 8, ["has no law", "*ELASTIC"]),
    (ABAQUS.replace("160., 0.15", "160., 0.15, 20.\n170., 0.2, 300."), 13, ["depends on temperature"]),
    (ABAQUS.replace("*Elastic", "*Elastic, type=ENGINEERING CONSTANTS"), 11, ["TYPE must be one of ISOTROPIC"]),
    (ABAQUS.replace("*Plastic", "*Plastic, hardening=KINEMATIC"), 13, ["HARDENING must be one of ISOTROPIC"]),
    (OWN + "\n*ELASTIC\n1, 0.3", 15, ["*ELASTIC is for a *MATERIAL without LAW="]),
    ("*ELASTIC\n1, 0.3\n*MATERIAL, NAME=AL, LAW=ELASTIC\nE=1, NU=0.3", 8, ["must follow a *MATERIAL"]),
])
def test_material_card_errors(tmp_path, material, line, words):
    deck = tmp_path / "d.dat"
    deck.write_text(DECK.format(material=material))
    with pytest.raises(DeckError) as info:
        load_deck(deck)
    assert any(p.line == line and all(w in p.message for w in words) for p in info.value.problems), \
        str(info.value)
    from lagamine_py.cli import main
    assert main(["check", str(deck)]) == 2


def test_a_j2_table_block_runs_and_yields(tmp_path):
    """Compressed 1 % in plane strain: the run goes plastic (a von Mises stress above the first
    yield stress) and converges."""
    from lagamine_py.cli import main
    deck = tmp_path / "d.dat"
    deck.write_text(DECK.format(material=OWN))
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0
