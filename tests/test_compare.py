"""``lagamine-py compare``: passes within tolerance, fails outside, explains mismatches."""
import pytest

from lagamine_py.cli import main
from lagamine_py.compare import compare_dirs, parse_tolerances


def write_run(d, times=(0.5, 1.0), scale=1.0, shift_point=None, status="slip", steps=(1,)):
    d.mkdir(parents=True, exist_ok=True)
    rows = ["step,increment,time,element,gauss,x,y,p,tau,gap,slip,lambda,status"]
    tot = ["step,increment,time,contact,P,T"]
    rea = ["step,increment,time,nset,RF1,RF2"]
    for s in steps:
        for k, t in enumerate(times, 1):
            T = s - 1 + t
            for g in (1, 2, 3):
                p = 100.0 * T * g * scale
                if shift_point == (s, k, g):
                    p *= 1.01
                rows.append(f"{s},{k},{T!r},7,{g},{g * 0.5},0,{p!r},{0.2 * p!r},{p / 1e6!r},0,0,{status}")
            tot.append(f"{s},{k},{T!r},A->F,{600.0 * T * scale!r},{120.0 * T * scale!r}")
            rea.append(f"{s},{k},{T!r},LEFT,{-50.0 * T * scale!r},0")
    (d / "contact.csv").write_text("\n".join(rows) + "\n")
    (d / "contact_totals.csv").write_text("\n".join(tot) + "\n")
    (d / "reactions.csv").write_text("\n".join(rea) + "\n")


def test_identical_runs_pass(tmp_path):
    write_run(tmp_path / "run")
    write_run(tmp_path / "ref")
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "ref")]) == 0


def test_a_one_percent_change_fails_and_is_located(tmp_path, capsys):
    write_run(tmp_path / "run", shift_point=(1, 2, 3))
    write_run(tmp_path / "ref")
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "ref")]) == 1
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if l.startswith("p "))
    assert "FAIL" in line and "step 1, increment 2, element 7, gauss 3" in line
    # the same pair passes with a looser tolerance on p and tau
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "ref"),
                 "--tol", "p=2e-2", "--tol", "tau=2e-2", "--tol", "gap=2e-2"]) == 0


def test_different_increments_are_interpolated_in_time(tmp_path, capsys):
    write_run(tmp_path / "run", times=(0.25, 0.5, 0.75, 1.0))   # values linear in time
    write_run(tmp_path / "ref", times=(0.5, 1.0))
    rep = compare_dirs(tmp_path / "run", tmp_path / "ref", parse_tolerances([]))
    assert any("interpolated" in n for n in rep.notes)
    assert rep.ok, rep.text()


def test_missing_step_and_status_change_are_reported(tmp_path):
    write_run(tmp_path / "run", steps=(1,))
    write_run(tmp_path / "ref", steps=(1, 2))
    rep = compare_dirs(tmp_path / "run", tmp_path / "ref")
    assert not rep.ok and any("steps [1]" in p for p in rep.problems)
    write_run(tmp_path / "run2", status="stick")
    write_run(tmp_path / "ref2")
    rep = compare_dirs(tmp_path / "run2", tmp_path / "ref2")
    assert not rep.ok and any("status differs" in p for p in rep.problems)


def test_bad_tolerance_is_a_usage_error(tmp_path):
    write_run(tmp_path / "run")
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "run"), "--tol", "pp=1"]) == 2
    with pytest.raises(ValueError, match="unknown quantity"):
        parse_tolerances(["zz=1e-3"])


def _two_pairs(d, scale_b=1.0):
    """contact.csv with two pairs on the same element and Gauss numbers (two faces of one
    element): only the ``contact`` column tells their points apart."""
    d.mkdir(parents=True, exist_ok=True)
    rows = ["step,increment,time,element,gauss,x,y,p,tau,gap,slip,lambda,status,contact"]
    for name, p in (("A->F", 100.0), ("B->F", 300.0 * scale_b)):
        rows += [f"1,1,1.0,7,{g},{g * 0.5},0,{p * g!r},0,0,0,0,stick,{name}" for g in (1, 2, 3)]
    (d / "contact.csv").write_text("\n".join(rows) + "\n")


def test_pairs_are_compared_pair_by_pair(tmp_path):
    _two_pairs(tmp_path / "ref")
    _two_pairs(tmp_path / "same")
    _two_pairs(tmp_path / "changed", scale_b=1.01)
    assert compare_dirs(tmp_path / "same", tmp_path / "ref").ok
    rep = compare_dirs(tmp_path / "changed", tmp_path / "ref")
    assert not rep.ok and "contact B->F" in rep.text()


def test_a_reference_without_the_pair_column_still_compares(tmp_path):
    """References written before contact.csv named its pairs (one pair) compare as before."""
    write_run(tmp_path / "ref")
    write_run(tmp_path / "run")
    text = (tmp_path / "run" / "contact.csv").read_text().splitlines()
    text = [text[0] + ",contact"] + [r + ",A->F" for r in text[1:]]
    (tmp_path / "run" / "contact.csv").write_text("\n".join(text) + "\n")
    assert compare_dirs(tmp_path / "run", tmp_path / "ref").ok
