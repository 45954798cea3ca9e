"""DECKS.md walked: every keyword and parameter it names is in the keyword table, and decks that
use all of them -- written the way its "Syntax" section allows -- pass ``check`` and run.

DECKS.md is the deck contract ("a deck written to it must run").  It is not in the repository:
``tests/data/DECKS.md`` is a byte copy of the project's shared ``DECKS.md`` taken on 2026-11-25
(SHA-256 86d4359b236bc6e61e8c30903d52a277d4232dfcb2ae3f3ebd6180297b6f51d6); when the shared file
is on this machine (``/work/shared/DECKS.md``) the copy must match it.  The walk decks are in
``tests/data/decks_md/``: ``walk_tools.dat`` (rigid tools, every step keyword),
``walk_two_body.dat`` (``MASTER=``) and ``walk_import.dat`` (``*IMPORT``); what DECKS.md names
is read off its tables here, so a row added to it without a walk deck using it fails.
"""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest

from lagamine_py import registry
from lagamine_py.cli import main
from lagamine_py.deck.errors import Problems
from lagamine_py.deck.grammar import DataRow, Pair, parse_deck_blocks
from lagamine_py.deck.keywords import KEYWORDS
from lagamine_py.results import read_table

DATA = Path(__file__).parent / "data"
COPY = DATA / "DECKS.md"
SHARED = Path("/work/shared/DECKS.md")
WALKS = sorted((DATA / "decks_md").glob("walk_*.dat"))
DIGEST = "86d4359b236bc6e61e8c30903d52a277d4232dfcb2ae3f3ebd6180297b6f51d6"


def test_the_copy_is_the_contract():
    text = COPY.read_bytes()
    if SHARED.is_file():
        assert SHARED.read_bytes() == text, "DECKS.md changed: copy it to tests/data and walk it"
    else:
        assert hashlib.sha256(text).hexdigest() == DIGEST


# ---------------------------------------------------------------- DECKS.md's tables

def _rows(section: str) -> list[list[str]]:
    """The cells of the table rows of DECKS.md section ``section`` (a '## ' title)."""
    text = COPY.read_text()
    body = text.split(f"## {section}\n", 1)[1].split("\n## ", 1)[0]
    return [[c.strip() for c in line.strip().strip("|").split(" | ")]
            for line in body.splitlines() if line.startswith("| `")]


def _keywords(cell: str) -> list[str]:
    return [k.upper() for k in re.findall(r"`\*([A-Za-z ]+)`", cell)]


def _param_names(cell: str) -> list[str]:
    """``NAME=`` tokens (``REF NODE=``, ``NLGEOM=YES/NO`` ...) and bare flags (``GENERATE``)."""
    names = [m.strip().upper() for m in re.findall(r"`([A-Za-z][A-Za-z _]*)=[^`]*`", cell)]
    return names + [m for m in re.findall(r"`([A-Z]+)`", cell) if m == "GENERATE"]


def contract() -> dict[str, set[str]]:
    """keyword -> the parameters DECKS.md names for it: its model and step tables (a row of two
    keywords, ``*NSET`` / ``*ELSET``, gives a parameter named like one of them to that one
    only), and the ``*INCLUDE, INPUT=path`` of its syntax section."""
    out: dict[str, set[str]] = {"INCLUDE": set(_param_names(
        re.search(r"`\*INCLUDE, (INPUT=)path`", COPY.read_text()).group(0).replace("*INCLUDE, ", "")))}
    for section in ("Model keywords", "Step keywords"):
        for cells in _rows(section):
            row = _keywords(cells[0])
            for kw in row:
                out.setdefault(kw, set()).update(
                    p for p in _param_names(cells[1]) if p == kw or p not in row)
    return out


def _row(keyword: str) -> list[str]:
    return next(c for s in ("Model keywords", "Step keywords") for c in _rows(s)
                if keyword in _keywords(c[0]))


def test_the_tables_are_read():
    """The reader of the tables is shown to find what a reader of DECKS.md sees."""
    kws = contract()
    assert len(kws) == 15 + 9 + 1          # model, step, *INCLUDE
    assert kws["INCLUDE"] == {"INPUT"}
    assert kws["FOUNDATION"] == {"NAME", "REF NODE"}
    assert kws["NSET"] == {"NSET", "GENERATE"} and kws["ELSET"] == {"ELSET", "GENERATE"}
    assert kws["STEP"] == {"NAME", "NLGEOM", "INC"}
    assert kws["IMPORT"] == {"INPUT", "ANALYSIS", "INTEGRATION"}
    assert kws["HEADING"] == kws["END STEP"] == set()


def test_every_keyword_and_parameter_is_declared():
    for kw, params in contract().items():
        assert kw in KEYWORDS, f"*{kw}"
        declared = {p.name for p in KEYWORDS[kw].params}
        assert params <= declared, f"*{kw}: {params - declared} not declared"


def _law_keys(cell: str) -> set[str]:
    """The parameter names of a plugin's data cell (``KP``, ``METHOD=PENALTY`` -> METHOD)."""
    return set(re.findall(r"`([A-Z][A-Z0-9_]*)(?:=[A-Z]+)?`", cell)) - {"PENALTY", "AUGMENTED", "KEY"}


def test_every_element_type_law_and_plugin_parameter_named_is_registered():
    element_row = " ".join(_row("ELEMENT")[1:])
    types = set(re.findall(r"`((?:Q8|Q4|T6|CPE|CAX)[A-Z0-9]*)`", element_row))
    assert types == {"Q8PE", "Q8AX", "Q4PE", "Q4AX", "T6PE", "T6AX",
                     "CPE8", "CAX8", "CPE4", "CAX4", "CPE6", "CAX6"}
    assert types <= set(registry.names("elements"))
    material = " ".join(_row("MATERIAL")[1:])
    for law, keys in (("ELASTIC", "`E`, `NU`"), ("RAMBERG_OSGOOD", "`E`, `NU`, `SIGMA0`, `ALPHA`, `N`")):
        assert f"`{law}`: {keys}" in material
        declared = {p.name for p in registry.get("laws", law).params}
        assert set(re.findall(r"`([A-Z0-9_]+)`", keys)) <= declared
    law_row = _row("CONTACT LAW")
    assert "`COULOMB`" in law_row[1]
    named = _law_keys(law_row[2])
    declared = {p.name for p in registry.get("contact_laws", "COULOMB").params}
    assert named == {"KP", "KT", "PHI", "B", "HPHI", "HB", "PHI_INF", "LAMC", "B_INF", "LAMC_B",
                     "TAUMAX", "METHOD", "PTOL", "THETA", "SUBSTEPS"}
    assert named <= declared


# ---------------------------------------------------------------- the walk decks

def _used(path: Path) -> tuple[dict[str, set[str]], set[str]]:
    """keyword -> parameters the deck's keyword lines give, and the KEYs of its data pairs."""
    problems = Problems()
    blocks, _, _ = parse_deck_blocks(path, problems)
    assert not problems.items, problems.items
    used: dict[str, set[str]] = {}
    if re.search(r"^\*\s*include\s*,\s*input\s*=", path.read_text(), re.I | re.M):
        used["INCLUDE"] = {"INPUT"}             # the reader replaces it by the file's lines
    keys = set()
    for b in blocks:
        used.setdefault(b.keyword, set()).update(b.params)
        for row in b.data:
            if isinstance(row, DataRow):
                keys |= {it.key for it in row.items if isinstance(it, Pair)}
    return used, keys


def test_the_walk_decks_use_every_keyword_and_parameter():
    used: dict[str, set[str]] = {}
    keys: set[str] = set()
    for path in WALKS:
        u, k = _used(path)
        keys |= k
        for kw, params in u.items():
            used.setdefault(kw, set()).update(params)
    for kw, params in contract().items():
        assert kw in used, f"no walk deck uses *{kw}"
        assert params <= used[kw], f"*{kw}: no walk deck gives {params - used[kw]}"
    law = _law_keys(_row("CONTACT LAW")[2])
    assert law | {"E", "NU", "SIGMA0", "ALPHA", "N"} <= keys


def _columns(file: str) -> list[str]:
    """The columns DECKS.md's output table names for ``file`` (its first `a, b, c` list)."""
    rows = [c for c in (line.strip().strip("|").split(" | ") for line in
                        COPY.read_text().split("## Output contract", 1)[1].splitlines()
                        if line.startswith("| `OUT/")) if f"`OUT/{file}`" in c[0]]
    lists = re.findall(r"`([a-z0-9_]+(?:, [A-Za-z0-9_]+)+)`", rows[0][1])
    return lists[0].split(", ")


@pytest.mark.parametrize("path", WALKS, ids=lambda p: p.stem)
def test_a_walk_deck_is_checked_and_runs(path, tmp_path, capsys):
    deck = path
    assert main(["check", str(deck)]) == 0, capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 0, capsys.readouterr().err
    stem = path.stem
    for name in (f"{stem}.pvd", f"{stem}_0001.vtu", f"{stem}.sta", f"{stem}.log", "reactions.csv"):
        assert (out / name).is_file(), name
    assert set(_columns("reactions.csv")) <= set(read_table(out / "reactions.csv"))
    if stem != "walk_import":          # the contact tables
        for name in ("contact.csv", "contact_totals.csv"):
            assert set(_columns(name)) <= set(read_table(out / name)), name
    if stem == "walk_tools":
        assert (out / "tool_forces.csv").is_file()


def test_the_output_columns_are_read():
    assert _columns("contact.csv")[:5] == ["step", "increment", "time", "element", "gauss"]
    assert _columns("contact.csv")[-1] == "status"
    assert _columns("contact_totals.csv") == ["step", "increment", "time", "contact", "P", "T"]
    assert _columns("reactions.csv") == ["step", "increment", "time", "nset", "RF1", "RF2"]


# ---------------------------------------------------------------- every element type named

ELEMENT_DECK = """*MESH, NAME=B, TYPE={etype}, X0=0, Y0=0, LX=2, LY=1, NX=2, NY=1
*MATERIAL, NAME=M, LAW=ELASTIC
E=1000, NU=0.3
*SOLID, ELSET=B, MATERIAL=M
*STEP
*STATIC
1, 1
*BOUNDARY
B_BOTTOM, 2, 2
B_LEFT, 1, 1
B_TOP, 2, 2, -0.01
*END STEP
"""


@pytest.mark.parametrize("etype", ["Q8PE", "Q8AX", "Q4PE", "Q4AX", "T6PE", "T6AX",
                                   "CPE8", "CAX8", "CPE4", "CAX4", "CPE6", "CAX6"])
def test_every_element_type_named_runs(etype, tmp_path, capsys):
    deck = tmp_path / "e.dat"
    deck.write_text(ELEMENT_DECK.format(etype=etype))
    assert main(["check", str(deck)]) == 0, capsys.readouterr().err
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 0, capsys.readouterr().err


def test_the_readme_lists_every_controls_key():
    """The README's extensions to DECKS.md name the *CONTROLS keys: all of them, in order."""
    from lagamine_py.model import CONTROL_PARAMS
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    listed = re.search(r"`\*CONTROLS` inside a step: `([A-Z, \n]+)`", readme).group(1)
    assert [k.strip() for k in listed.split(",")] == [p.name for p in CONTROL_PARAMS]
