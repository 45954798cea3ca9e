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


# ---------------------------------------------------------------- files that cannot be trusted

def _damage(path, how):
    text = path.read_text()
    lines = text.splitlines(keepends=True)
    if how == "duplicated increment":          # the rows of step 1 increment 2 written again,
        inc2 = [ln for ln in lines if ln.startswith("1,2,")]     # computed again (round-off)
        return path.write_text(text + "".join(ln.replace(",0,slip", ",1e-17,slip") for ln in inc2))
    if how == "duplicated row":
        return path.write_text(text + lines[1])
    if how == "torn row":                      # a row cut by a kill, the next glued to it
        return path.write_text("".join(lines[:2]) + lines[2][:9] + "".join(lines[3:]))
    if how == "cut file":
        return path.write_text(text[:-7])
    if how == "text in a number":
        return path.write_text(text.replace(lines[2].split(",")[7], "abc", 1))
    if how == "NUL bytes":
        return path.write_bytes(text.encode()[:200] + b"\0\0\0" + text.encode()[200:])
    if how == "NaN key":
        return path.write_text(text.replace(f"\n{lines[2].split(',')[0]},{lines[2].split(',')[1]},",
                                            "\nnan,2,", 1))
    raise ValueError(how)


DAMAGE = {"duplicated increment": "rows repeat", "duplicated row": "repeats line",
          "torn row": "cells where the header has 13", "cut file": "cut short",
          "text in a number": "'abc' is not a number", "NUL bytes": "NUL bytes at line",
          "NaN key": "key column step is nan"}


@pytest.mark.parametrize("how", list(DAMAGE))
@pytest.mark.parametrize("side", ["run", "ref"])
def test_a_damaged_table_fails_with_its_line(tmp_path, capsys, how, side):
    """Either file may be damaged: compare fails (exit 1), says where, and never crashes; before,
    a duplicated increment passed, and NaN keys, text, NUL bytes or torn rows crashed it."""
    write_run(tmp_path / "run")
    write_run(tmp_path / "ref")
    _damage(tmp_path / side / "contact.csv", how)
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "ref")]) == 1
    out = capsys.readouterr().out
    which = "run" if side == "run" else "reference"
    assert f"MISMATCH: contact.csv of the {which} cannot be compared: " in out
    assert DAMAGE[how] in out and "FAIL" in out


def test_duplicated_totals_fail_too(tmp_path):
    write_run(tmp_path / "run")
    write_run(tmp_path / "ref")
    path = tmp_path / "run" / "contact_totals.csv"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines) + lines[-1])
    rep = compare_dirs(tmp_path / "run", tmp_path / "ref")
    assert not rep.ok and any("contact_totals.csv of the run" in p for p in rep.problems)


@pytest.mark.parametrize("tol", ["p=-1e-6", "p=1e-6,-1", "p=nan", "p=inf", "p=x"])
def test_a_negative_or_non_finite_tolerance_is_refused(tmp_path, capsys, tol):
    write_run(tmp_path / "run")
    assert main(["compare", str(tmp_path / "run"), str(tmp_path / "run"), "--tol", tol]) == 2
    assert "--tol" in capsys.readouterr().err


def test_a_point_without_partner_does_not_stop_round_off_passing(tmp_path):
    """A contact point with no partner (status none) has no gap (NaN): the gap column's scale is
    taken over the finite gaps, so round-off elsewhere passes and a real change still fails
    (the NaN scale once allowed no difference at all: hertz_two_body failed on 1.8e-15)."""
    def unpaired(d):
        lines = (d / "contact.csv").read_text().splitlines()
        head, rows = lines[0].split(","), [r.split(",") for r in lines[1:]]
        rows[0][head.index("status")] = "none"
        (d / "contact.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    for name, scale in (("ref", 1.0), ("roundoff", 1.0 + 1e-13), ("changed", 1.01)):
        write_run(tmp_path / name, scale=scale)
        unpaired(tmp_path / name)
    assert compare_dirs(tmp_path / "roundoff", tmp_path / "ref").ok
    rep = compare_dirs(tmp_path / "changed", tmp_path / "ref")
    assert not rep.ok and any(f.quantity == "gap" and f.worst > 1 for f in rep.findings)
