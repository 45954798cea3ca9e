"""``*CHECK`` error measures on synthetic output directories built from the closed forms.

Every field written here is the closed form itself (Johnson §4.2 and §7.1, Lamé, Ramberg-Osgood,
Hill), sampled the way a run samples it; the checks must find error 0 on it, and the known
relative error on a field perturbed by a known factor.
"""
import csv
import math

import numpy as np
import pytest

from lagamine_py import registry
from lagamine_py.checks import Check, check_columns, evaluate_checks

# the Hertz deck (decks/hertz.dat): its comment states a = 1.0000 mm, p0 = 10989 MPa
P, R, E, NU = 17261.5, 10.0, 200000.0, 0.3
A_HZ = math.sqrt(4 * P * R * (1 - NU**2) / (math.pi * E))
P0_HZ = 2 * P / (math.pi * A_HZ)
GAUSS3 = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])


def write_csv(path, columns):
    names = list(columns)
    n = len(next(iter(columns.values())))
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(names)
        for k in range(n):
            w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else v
                        for v in (columns[c][k] for c in names)])


def gauss_points(lo, hi, n_seg):
    """Three Gauss points in each of ``n_seg`` equal segments of [lo, hi] (element faces)."""
    edges = np.linspace(lo, hi, n_seg + 1)
    mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
    return (mid[:, None] + half[:, None] * GAUSS3).ravel()


def contact_rows(points, step=1, inc=1, time=1.0):
    """contact.csv columns for a list of (x, p, tau, gap, status)."""
    x, p, tau, gap, st = (list(c) for c in zip(*points))
    n = len(x)
    return {"step": [step] * n, "increment": [inc] * n, "time": [time] * n,
            "element": list(range(1, n + 1)), "gauss": [1] * n, "x": x, "y": [-R] * n,
            "p": p, "tau": tau, "gap": gap, "slip": [0.0] * n, "lambda": [0.0] * n, "status": st}


def concat(tables):
    return {k: sum((t[k] for t in tables), []) for k in tables[0]}


def hertz_p(x, a, p0):
    return p0 * np.sqrt(np.clip(1 - x**2 / a**2, 0, None))


def write_hertz(d, a=A_HZ, p0=P0_HZ, xc=0.0, lo=0.0, hi=2.0, n_seg=23, total=P / 2):
    x = xc + gauss_points(lo, hi, n_seg)
    p = hertz_p(x - xc, a, p0)
    # an earlier increment with other values: only the last one may count
    early = contact_rows([(xi, 0.5 * pi, 0.0, 0.0, "stick") for xi, pi in zip(x, p)], inc=1, time=0.5)
    last = contact_rows([(xi, pi, 0.0, pi / 1e8, "stick" if pi > 0 else "open") for xi, pi in zip(x, p)],
                        inc=2)
    write_csv(d / "contact.csv", concat([early, last]))
    write_csv(d / "contact_totals.csv", {"step": [1, 1], "increment": [1, 2], "time": [0.5, 1.0],
                                         "contact": ["ARC->FLAT"] * 2, "P": [total / 2, total],
                                         "T": [0.0, 0.0]})


def hertz_check(**extra):
    return {"name": "HZ", "type": "HERTZ", "where": None,
            "params": {"P": P, "R": R, "E": E, "NU": NU, "SYMMETRY": 2, **extra}}


def test_hertz_deck_numbers():
    assert A_HZ == pytest.approx(1.0, abs=5e-5) and P0_HZ == pytest.approx(10989, abs=1)


def test_exact_hertz_pressure_gives_zero_error(tmp_path):
    write_hertz(tmp_path)
    (res,) = evaluate_checks([hertz_check()], tmp_path)
    assert res["message"] == ""
    assert res["error"] < 1e-10
    assert res["measured"]["a"] == pytest.approx(A_HZ, rel=1e-10)
    assert res["measured"]["p0"] == pytest.approx(P0_HZ, rel=1e-10)
    assert res["measured"]["P"] == pytest.approx(P, rel=1e-12)      # twice the half model's force
    # the second-moment cross-check: a^2 = 4 <x^2>_p, trapezoid over 3-point samples, h = a/11.5
    assert res["measured"]["a_moment"] == pytest.approx(A_HZ, rel=0.02)


def test_perturbed_hertz_pressure_gives_its_error(tmp_path):
    write_hertz(tmp_path, a=1.03 * A_HZ, p0=0.98 * P0_HZ)
    (res,) = evaluate_checks([hertz_check()], tmp_path)
    assert res["errors"]["a"] == pytest.approx(0.03, rel=1e-8)
    assert res["errors"]["p0"] == pytest.approx(0.02, rel=1e-8)
    assert res["error"] == pytest.approx(0.03, rel=1e-8)


def test_full_hertz_model_is_centred_on_the_peak(tmp_path):
    # full cylinder centred at x = 5 (odd segment count: a Gauss point sits on the peak)
    write_hertz(tmp_path, xc=5.0, lo=-2.0, hi=2.0, n_seg=31, total=P)
    (res,) = evaluate_checks([hertz_check(SYMMETRY=1)], tmp_path)
    assert res["error"] < 1e-10 and res["measured"]["P"] == pytest.approx(P)
    (off,) = evaluate_checks([hertz_check(SYMMETRY=1, X0=5.2)], tmp_path)   # wrong centre: worse
    assert off["error"] > 1e-3


# ---------------------------------------------------------------- Cattaneo-Mindlin

PHI, NU_C, P_C = 0.3, 0.49, 20671.0
A_C = math.sqrt(4 * P_C * R * (1 - NU_C**2) / (math.pi * E))


def cattaneo_tau(x, a, c, p0, phi):
    """Johnson §7.1: q = phi p0 [sqrt(1 - x^2/a^2) - (c/a) sqrt(1 - x^2/c^2)] inside the stick
    zone |x| < c, phi p outside."""
    q = phi * hertz_p(x, a, p0)
    inner = np.abs(x) < c
    q[inner] -= phi * p0 * (c / a) * np.sqrt(1 - x[inner] ** 2 / c**2)
    return q


def write_cattaneo(d, ratios, c_factor=1.0, n_seg=41):
    a, p0 = A_C, 2 * P_C / (math.pi * A_C)
    x = gauss_points(-1.5 * a, 1.5 * a, n_seg)
    p = hertz_p(x, a, p0)
    tables, totals = [], {k: [] for k in ("step", "increment", "time", "contact", "P", "T")}
    # step 1 (pressing): full stick, must be ignored
    tables.append(contact_rows([(xi, pi, 0.0, 0.0, "stick" if pi > 0 else "open")
                                for xi, pi in zip(x, p)], step=1, inc=1))
    for k, (name, val) in enumerate((("step", 1), ("increment", 1), ("time", 1.0),
                                     ("contact", "ARC->FLAT"), ("P", P_C), ("T", 0.0))):
        totals[name].append(val)
    for inc, q in enumerate(ratios, 1):
        c = c_factor * a * math.sqrt(1 - q)
        tau = cattaneo_tau(x, a, c, p0, PHI)
        st = np.where(p <= 0, "open", np.where(np.abs(x) < c, "stick", "slip"))
        tables.append(contact_rows(list(zip(x, p, tau, p / 1e8, st)), step=2, inc=inc, time=1 + q))
        for name, val in (("step", 2), ("increment", inc), ("time", 1 + q), ("contact", "ARC->FLAT"),
                          ("P", P_C), ("T", -PHI * P_C * q)):
            totals[name].append(val)
    write_csv(d / "contact.csv", concat(tables))
    write_csv(d / "contact_totals.csv", totals)
    return x


CATT = {"name": "STICK", "type": "CATTANEO", "where": None,
        "params": {"P": P_C, "R": R, "E": E, "NU": NU_C, "PHI": PHI, "QRATIO": 0.5}}


def test_cattaneo_exact_tractions(tmp_path):
    x = write_cattaneo(tmp_path, ratios=[0.1, 0.3, 0.5, 0.7, 0.9])
    (res,) = evaluate_checks([CATT], tmp_path)
    assert res["message"] == ""
    assert res["closed_form"]["c"] == pytest.approx(A_C * math.sqrt(0.5), rel=1e-12)
    # the edge lies between a stick and a slip point: at worst half a point spacing off
    spacing = np.diff(np.sort(x)).max()
    assert res["error"] <= 0.5 * spacing / A_C
    # the sqrt-extrapolated edge does much better than that on the exact tractions
    assert res["error"] < 0.01


def test_cattaneo_interpolates_between_increments(tmp_path):
    # c(Q) is sampled at Q/(phi P) = 0.45 and 0.55: linear interpolation of a sqrt(1 - q)
    write_cattaneo(tmp_path, ratios=[0.25, 0.45, 0.55, 0.75], n_seg=201)
    (res,) = evaluate_checks([CATT], tmp_path)
    c_lin = 0.5 * A_C * (math.sqrt(0.55) + math.sqrt(0.45))
    assert res["measured"]["c"] == pytest.approx(c_lin, abs=0.01 * A_C)
    assert res["error"] == pytest.approx(abs(c_lin - A_C * math.sqrt(0.5)) / A_C, abs=0.01)


def test_cattaneo_perturbed_stick_zone(tmp_path):
    # a stick zone 20 % wider than Cattaneo's: error 0.2 sqrt(1 - 0.5) of a
    write_cattaneo(tmp_path, ratios=[0.3, 0.5, 0.7], c_factor=1.2, n_seg=201)
    (res,) = evaluate_checks([CATT], tmp_path)
    assert res["error"] == pytest.approx(0.2 * math.sqrt(0.5), abs=0.01)


def test_cattaneo_qratio_outside_the_step(tmp_path):
    write_cattaneo(tmp_path, ratios=[0.1, 0.2, 0.3])
    (res,) = evaluate_checks([CATT], tmp_path)
    assert math.isnan(res["error"]) and "outside" in res["message"]


# ---------------------------------------------------------------- Coulomb, penetration


def write_totals(d, P_, T_):
    write_csv(d / "contact_totals.csv", {"step": [1, 2, 2], "increment": [1, 1, 2], "time": [1, 1.5, 2.0],
                                         "contact": ["B->F"] * 3, "P": [P_, P_, P_], "T": [0.0, 50.0, T_]})


COUL = {"name": "SLIDING", "type": "COULOMB", "params": {"PHI": "0.3", "B": "5", "A": "20"}}


@pytest.mark.parametrize("factor", [1.0, 1.05, 0.9])
def test_coulomb(tmp_path, factor):
    write_totals(tmp_path, 2000.0, -factor * (0.3 * 2000.0 + 5 * 20))   # sign of T is irrelevant
    (res,) = evaluate_checks([COUL], tmp_path)
    assert res["closed_form"]["T"] == pytest.approx(700.0)
    assert res["error"] == pytest.approx(abs(factor - 1), abs=1e-12)


@pytest.mark.parametrize("copen", (True, False))
def test_penetration(tmp_path, copen):
    """gap is -d in the COPEN convention (tables with the signed_slip column); a table written
    before it has gap = +d: the check reads both."""
    d = 50 / 1e6
    sign = -1.0 if copen else 1.0
    pts = [(float(k), 50.0, 0.0, sign * d, "stick") for k in range(6)]
    pts[3] = (3.0, 50.0, 0.0, sign * 1.1 * d, "stick")
    pts.append((9.0, 0.0, 0.0, -sign * 0.5, "open"))                    # open: not counted
    pts.append((10.0, 0.0, 0.0, 0.7, "none"))                           # no foundation opposite
    rows = contact_rows(pts)
    if copen:
        rows["signed_slip"] = [0.0] * len(pts)
    write_csv(tmp_path / "contact.csv", rows)
    (res,) = evaluate_checks([{"name": "PEN", "type": "PENETRATION", "params": {"P": 50, "KP": 1e6}}],
                             tmp_path)
    assert res["error"] == pytest.approx(0.1, rel=1e-9)
    assert res["measured"]["penetration"] == pytest.approx(1.1 * d)


# ---------------------------------------------------------------- bodies

RO = dict(E=70000.0, SIGMA0=200.0, ALPHA=0.5, N=8.0, R0=5.0, H0=10.0)


def ro_strain(s):
    return s / RO["E"] + RO["ALPHA"] * RO["SIGMA0"] / RO["E"] * (s / RO["SIGMA0"]) ** RO["N"]


def write_compression(d, stresses, force_factor=1.0):
    """Homogeneous compression (deck compression_ro.dat) ending at the Kirchhoff stresses s given,
    one per step: height h0 exp(-eps), radius r0 exp(nu s/E + eps_p/2), volume ratio
    J = (r/r0)^2 h/h0, axial force (s/J) r^2/2 per radian (Cauchy stress s/J)."""
    X, Y = np.meshgrid(np.linspace(0, RO["R0"], 3), np.linspace(0, RO["H0"], 5))
    X, Y = X.ravel(), Y.ravel()
    disp = {k: [] for k in ("step", "increment", "time", "node", "x", "y", "u1", "u2")}
    reac = {k: [] for k in ("step", "increment", "time", "nset", "RF1", "RF2")}
    for step, s in enumerate(stresses, 1):
        eps = ro_strain(s)
        eps_p = eps - s / RO["E"]
        lam_r = math.exp(0.3 * s / RO["E"] + eps_p / 2)
        J = lam_r**2 * math.exp(-eps)
        F = force_factor * s / J * (RO["R0"] * lam_r) ** 2 / 2
        for n, (x, y) in enumerate(zip(X, Y), 1):
            for k, v in zip(disp, (step, 3, float(step), n, x, y, x * (lam_r - 1), y * (math.exp(-eps) - 1))):
                disp[k].append(v)
        for inc in (1, 2, 3):
            f = F * inc / 3
            for name, rf in (("CYL_LEFT", 0.0), ("CYL_BOTTOM", f), ("CYL_TOP", -f)):
                for k, v in zip(reac, (step, inc, step - 1 + inc / 3, name, 0.0, rf)):
                    reac[k].append(v)
    write_csv(d / "displacements.csv", disp)
    write_csv(d / "reactions.csv", reac)


UNI = {"name": "RO", "type": "UNIAXIAL_RO", "params": RO}


def test_uniaxial_ro_exact(tmp_path):
    write_compression(tmp_path, [180.0, 260.0])
    (res,) = evaluate_checks([UNI], tmp_path)
    assert res["message"] == "" and res["error"] < 1e-12 and res["errors"]["stress"] < 1e-9


def test_uniaxial_ro_perturbed_force(tmp_path):
    write_compression(tmp_path, [260.0], force_factor=1.01)
    (res,) = evaluate_checks([UNI], tmp_path)
    s = 1.01 * 260.0
    assert res["measured"]["stress"] == pytest.approx(s, rel=1e-12)
    assert res["error"] == pytest.approx(abs(ro_strain(260.0) - ro_strain(s)) / ro_strain(s), rel=1e-9)
    # the strain is that of 260 MPa on the curve: the stress is 1 % off
    assert res["closed_form"]["stress"] == pytest.approx(260.0, rel=1e-9)
    assert res["errors"]["stress"] == pytest.approx(0.01, rel=1e-6)


LAME = {"name": "TUBE", "type": "LAME", "params": {"P": 100.0, "A": 10.0, "B": 20.0, "E": 2e5, "NU": 0.3}}


@pytest.mark.parametrize("factor", [1.0, 1.02])
def test_lame(tmp_path, factor):
    # Timoshenko & Goodier: sigma_r = -p at r = a, 0 at r = b; with eps_z = 0, u = r (eps_theta)
    p, a, b, e, nu = 100.0, 10.0, 20.0, 2e5, 0.3
    x = np.repeat(np.linspace(a, b, 9), 2)
    C1, C2 = p * a**2 / (b**2 - a**2), p * a**2 * b**2 / (b**2 - a**2)
    s_r, s_t = C1 - C2 / x**2, C1 + C2 / x**2
    u = factor * x * ((1 + nu) / e) * ((1 - nu) * s_t - nu * s_r)
    n = len(x)
    write_csv(tmp_path / "displacements.csv",
              {"step": [1] * n, "increment": [5] * n, "time": [1.0] * n, "node": list(range(1, n + 1)),
               "x": x, "y": [0.0, 1.0] * (n // 2), "u1": u, "u2": [0.0] * n})
    (res,) = evaluate_checks([LAME], tmp_path)
    assert res["error"] == pytest.approx(factor - 1, abs=1e-12)


@pytest.mark.parametrize("kind, params", [
    ("LAME", {"P": 100.0, "E": 2e5, "NU": 0.3}),
    ("LIMIT_PRESSURE", {"P": 100.0, "SIGMAY": 300.0})])
def test_tube_checks_refuse_an_inner_radius_not_below_the_outer(tmp_path, kind, params):
    # B^2 - A^2 and ln(B / A) would be 0 or negative: refused when the check is built (the
    # deck's `check`), not a ZeroDivisionError when it is evaluated
    for a, b in ((20.0, 20.0), (30.0, 20.0)):
        with pytest.raises(registry.ParamError, match="inner radius A .* must be below"):
            registry.get("checks", kind)(A=a, B=b, **params)
    registry.get("checks", kind)(A=10.0, B=20.0, **params)


def write_sta(d, times, failed_last=False):
    rows = {k: [] for k in ("step", "step_name", "increment", "time", "dt", "iterations", "residual",
                            "cutbacks", "failed", "reason")}
    for k, t in enumerate(times, 1):
        fail = failed_last and k == len(times)
        for name, v in zip(rows, (1, "INFLATE", k, t, 0.1, 4, 1e-9, 0, "yes" if fail else "no",
                                  "too many iterations" if fail else "")):
            rows[name].append(v)
    write_csv(d / "tube.sta", rows)


def test_limit_pressure(tmp_path):
    p_lim = 2 / math.sqrt(3) * 250 * math.log(2.0)
    assert p_lim == pytest.approx(200.09, abs=0.01)                     # the deck's number
    tube = {"SIGMAY": 250, "A": 10, "B": 20}
    chk = {"name": "LIM", "type": "LIMIT_PRESSURE", "params": {"P": 1.03 * p_lim, **tube}}
    t_stop = 1.01 / 1.03
    write_sta(tmp_path, [0.5, t_stop, 0.99], failed_last=True)           # stopped at 1.01 p_lim
    (res,) = evaluate_checks([chk], tmp_path)
    assert res["error"] == pytest.approx(0.01, rel=1e-9)
    below = {"name": "LIM", "type": "LIMIT_PRESSURE", "params": {"P": 0.98 * p_lim, **tube}}
    write_sta(tmp_path, [0.5, 1.0])
    assert evaluate_checks([below], tmp_path)[0]["error"] == 0.0
    write_sta(tmp_path, [0.5, 0.9])                                       # stopped early: 0.882 p_lim
    assert evaluate_checks([below], tmp_path)[0]["error"] == pytest.approx(1 - 0.9 * 0.98, rel=1e-9)


# ---------------------------------------------------------------- plumbing


def test_missing_files_and_unknown_types_are_reported_not_raised(tmp_path):
    res = evaluate_checks([hertz_check(), {"name": "X", "type": "NOPE", "params": {}},
                           {"name": "C", "type": "COULOMB", "params": {"B": 0.3}}], tmp_path)
    assert all(math.isnan(r["error"]) for r in res)
    assert "contact.csv" in res[0]["message"]
    assert "NOPE" in res[1]["message"] and "HERTZ" in res[1]["message"]
    assert "missing required parameter PHI" in res[2]["message"]


def test_check_columns_and_registering_a_type(tmp_path):
    @registry.register("checks", "CONSTANT_T")
    class ConstantT(Check):
        """T against a constant."""
        def evaluate(self, run):
            T = float(run.table("contact_totals.csv")["T"][-1])
            return {"measured": {"T": T}, "closed_form": {"T": 10.0}, "errors": {"T": abs(T - 10) / 10},
                    "error": abs(T - 10) / 10}
    try:
        write_totals(tmp_path, 1.0, 12.0)
        res = evaluate_checks([{"name": "K", "type": "constant_t", "params": {}}], tmp_path)
        assert check_columns(res) == {"K_error": pytest.approx(0.2), "K_T": 12.0, "K_T_cf": 10.0}
    finally:
        registry.REGISTRY.tables["checks"].pop("CONSTANT_T")


def test_contact_points_of_the_named_pair_only(tmp_path):
    """contact.csv names its pairs: a check reads the pair of CONTACT= (default the first), not
    the points of every pair.  A second pair with a Hertz field 3 % wider would otherwise be
    fitted together with the exact one."""
    x = gauss_points(0.0, 2.0, 23)
    pairs = []
    for name, a in (("ARC->FLAT", A_HZ), ("OTHER->FLAT", 1.03 * A_HZ)):
        rows = contact_rows([(xi, pi, 0.0, pi / 1e8, "stick" if pi > 0 else "open")
                             for xi, pi in zip(x, hertz_p(x, a, P0_HZ))])
        rows["contact"] = [name] * len(x)
        pairs.append(rows)
    write_csv(tmp_path / "contact.csv", concat(pairs))
    write_csv(tmp_path / "contact_totals.csv", {"step": [1, 1], "increment": [1, 1], "time": [1.0, 1.0],
                                                "contact": ["ARC->FLAT", "OTHER->FLAT"],
                                                "P": [P / 2, P / 2], "T": [0.0, 0.0]})
    (first,) = evaluate_checks([hertz_check()], tmp_path)
    (named,) = evaluate_checks([hertz_check(CONTACT="other->flat")], tmp_path)
    assert first["message"] == "" and first["errors"]["a"] < 1e-10
    assert named["errors"]["a"] == pytest.approx(0.03, rel=1e-8)
    (by_surface,) = evaluate_checks([hertz_check(CONTACT="OTHER")], tmp_path)   # as a deck writes it
    assert by_surface["errors"]["a"] == pytest.approx(0.03, rel=1e-8)
    (missing,) = evaluate_checks([hertz_check(CONTACT="NONE")], tmp_path)
    assert "has no contact 'NONE'" in missing["message"]


def test_a_deck_names_the_pair_of_a_check_by_its_surface(tmp_path):
    """``CONTACT=`` is the one *CHECK value that is a name (``->`` cannot be written on a data
    line, so the surface stands for its pair); other values must still be numbers."""
    import shutil
    from pathlib import Path

    from lagamine_py.deck import DeckError, load_deck
    decks = Path(__file__).resolve().parents[1] / "decks"
    shutil.copytree(decks / "meshes", tmp_path / "meshes")
    text = (decks / "hertz.dat").read_text()
    line = "R=10, E=200000, NU=0.3, SYMMETRY=2"
    assert text.count(line) == 1
    (tmp_path / "a.dat").write_text(text.replace(line, line + ", CONTACT=arc"))
    (chk,) = load_deck(tmp_path / "a.dat").checks
    assert chk["params"]["CONTACT"] == "ARC"
    (tmp_path / "b.dat").write_text(text.replace(line, line + ", P=arc"))
    with pytest.raises(DeckError, match="P must be a number"):
        load_deck(tmp_path / "b.dat")
