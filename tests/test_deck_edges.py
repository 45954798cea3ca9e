"""Decks at the edges of what a reader meets: a UTF-8 byte-order mark, a FIFO or a directory
where a file belongs, an include chain hundreds deep, thousands of bad lines, values whose
products overflow, values that ``run`` would refuse.  Each gets one clear message and exit 2
(or runs), never a hang, a traceback, a NumPy warning or megabytes of errors.

Also the identity of a deck that restarts and sweeps compare (``Model.source``): the digest of
the expanded text changes with an included file or a parameter value, not with the place the
deck is read from.
"""
import os
import threading
from pathlib import Path

import pytest

from lagamine_py.cli import MAX_DECK_ERRORS, main
from lagamine_py.deck import DeckError, deck_digest, load_deck

DECKS = Path(__file__).resolve().parents[1] / "decks"
BLOCK = (DECKS / "coulomb_block.dat").read_text()


def check(deck, capsys) -> tuple[int, str]:
    code = main(["check", str(deck)])
    return code, capsys.readouterr().err


def test_a_utf8_byte_order_mark_is_read_as_nothing(tmp_path, capsys):
    deck = tmp_path / "bom.dat"
    deck.write_bytes(b"\xef\xbb\xbf" + BLOCK.encode())      # as Windows editors save UTF-8
    assert check(deck, capsys)[0] == 0
    part = tmp_path / "part.inp"
    part.write_bytes(b"\xef\xbb\xbf*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE=210000, NU=0.3\n")
    inc = tmp_path / "inc.dat"
    inc.write_text(BLOCK.replace("*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE=210000, NU=0.3\n",
                                 "*INCLUDE, INPUT=part.inp\n"))
    assert check(inc, capsys)[0] == 0


def _returns_within(fn, seconds=20.0):
    box = {}
    worker = threading.Thread(target=lambda: box.setdefault("value", fn()), daemon=True)
    worker.start()
    worker.join(seconds)
    assert not worker.is_alive(), "the reader hangs"
    return box["value"]


def test_a_fifo_is_refused_not_waited_on(tmp_path, capsys):
    fifo = tmp_path / "deck.dat"
    os.mkfifo(fifo)
    code = _returns_within(lambda: main(["check", str(fifo)]))
    err = capsys.readouterr().err
    assert code == 2 and "is not a regular file" in err
    deck = tmp_path / "inc.dat"
    deck.write_text("*INCLUDE, INPUT=deck.dat\n" + BLOCK)
    code = _returns_within(lambda: main(["check", str(deck)]))
    assert code == 2 and "inc.dat:1: *INCLUDE: included file" in capsys.readouterr().err


def test_a_directory_as_include_is_named_as_such(tmp_path, capsys):
    (tmp_path / "meshes").mkdir()
    deck = tmp_path / "d.dat"
    deck.write_text("*INCLUDE, INPUT=meshes\n" + BLOCK)
    code, err = check(deck, capsys)
    assert code == 2 and "included file" in err and "is a directory, not a file" in err
    assert "does not exist" not in err


def test_an_include_chain_600_deep_is_an_error_not_a_recursion_error(tmp_path, capsys):
    for k in range(600):
        (tmp_path / f"inc{k}.inp").write_text(f"*INCLUDE, INPUT=inc{k + 1}.inp\n")
    (tmp_path / "inc600.inp").write_text("*HEADING\nend\n")
    deck = tmp_path / "deep.dat"
    deck.write_text("*INCLUDE, INPUT=inc0.inp\n" + BLOCK)
    code, err = check(deck, capsys)
    assert code == 2 and "nested more than 64 files deep" in err
    assert "RecursionError" not in err


def test_errors_are_bounded(tmp_path, capsys):
    deck = tmp_path / "bad.dat"
    deck.write_text("*NODE\n" + "1, 2, x y\n" * 3000)
    code, err = check(deck, capsys)
    lines = err.splitlines()
    assert code == 2
    problems = [ln for ln in lines if ln.startswith(str(deck))]
    assert len(problems) == MAX_DECK_ERRORS == 50
    with pytest.raises(DeckError) as info:                   # a script still gets them all
        load_deck(deck)
    n = len(info.value.problems)
    assert n > 3000                                            # one a bad line, and more
    assert lines[-1] == f"... and {n - 50} more errors ({n} in all; the first 50 are shown)"
    assert len(err) < 20_000


@pytest.mark.parametrize("edit, words", [
    (("-20, 0\n", "-1e308, 0\n"), "a coordinate of magnitude 1e+308 exceeds 1e+150"),
    (("LX=20", "LX=1e308"), "exceeds 1e+150"),
    (("-20, 0\n", "-20, 1e400\n"), "must be finite"),
])
def test_huge_values_give_one_message_and_no_numpy_warning(tmp_path, capsys, edit, words):
    deck = tmp_path / "huge.dat"
    deck.write_text(BLOCK.replace(*edit))
    code, err = check(deck, capsys)
    assert code == 2 and words in err
    assert "Warning" not in err and "coincide" not in err and "inverted" not in err


# every value `run` would refuse (the law, contact-law and check constructors run at check)
REFUSED = [
    ("E=210000", "E=0", "E must be > 0"),
    ("KP=2e6", "KP=0", "KP must be > 0"),
    ("KT=2e6", "KT=0", "KT must be > 0"),
    ("B=5\n*CONTACT,", "B=5, HB=-2e6\n*CONTACT,", "KT + HB must be > 0"),
    ("B=5\n*CONTACT,", "B=5, HB=-3e6\n*CONTACT,", "KT + HB must be > 0"),
    ("NU=0.3", "NU=0.5", "NU = 0.5 is above its upper bound"),
]
RO = (DECKS / "compression_ro.dat").read_text()
REFUSED_RO = [
    ("E=70000, NU=0.3, SIGMA0=200", "E=70000, NU=0.3, SIGMA0=0", "SIGMA0 must be > 0"),
    ("ALPHA=0.5, N=8\n*SOLID", "ALPHA=0, N=8\n*SOLID", "ALPHA must be > 0"),
]


@pytest.mark.parametrize("base, old, new, words",
                         [(BLOCK, *c) for c in REFUSED] + [(RO, *c) for c in REFUSED_RO])
def test_check_refuses_what_run_would_refuse(tmp_path, capsys, base, old, new, words):
    assert base.count(old) == 1, old
    deck = tmp_path / "m.dat"
    deck.write_text(base.replace(old, new))
    code, err = check(deck, capsys)
    assert code == 2 and words in err, err
    assert main(["run", str(deck), "-o", str(tmp_path / "out"), "-q"]) == 2
    assert not (tmp_path / "out").exists()                    # nothing ran


def test_the_digest_follows_the_expanded_text(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        d.mkdir()
        (d / "mat.inp").write_text("*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE=210000, NU=0.3\n")
        (d / "deck.dat").write_text(
            "*PARAMETER\nPHI = 0.3\n" + BLOCK.replace(
                "*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE=210000, NU=0.3\n", "*INCLUDE, INPUT=mat.inp\n")
            .replace("PHI=0.3, B=5\n", "PHI=<PHI>, B=5\n"))
    model = load_deck(a / "deck.dat")
    assert model.source.path == str((a / "deck.dat").resolve())
    assert model.source.digest == deck_digest(a / "deck.dat")
    # the same text elsewhere: the same digest; an included file or a parameter changed: not
    assert deck_digest(b / "deck.dat") == model.source.digest
    (b / "mat.inp").write_text("*MATERIAL, NAME=STEEL, LAW=ELASTIC\nE=210000, NU=0.29\n")
    assert deck_digest(b / "deck.dat") != model.source.digest
    assert deck_digest(a / "deck.dat", {"PHI": "0.4"}) != model.source.digest
    assert load_deck(a / "deck.dat", {"PHI": "0.4"}).source.parameters == {"PHI": "0.4"}


def test_the_digest_covers_imported_meshes(tmp_path):
    """A mesh file read by *IMPORT is part of the model: editing it changes the digest."""
    mesh = tmp_path / "mesh.inp"
    mesh.write_text("*NODE\n1, 0, 0\n2, 1, 0\n3, 1, 1\n4, 0, 1\n*ELEMENT, TYPE=CPE4, ELSET=E\n1, 1, 2, 3, 4\n")
    deck = tmp_path / "deck.dat"
    deck.write_text("*IMPORT, INPUT=mesh.inp\n*MATERIAL, NAME=M, LAW=ELASTIC\nE=100, NU=0.3\n")
    before = deck_digest(deck)
    mesh.write_text(mesh.read_text().replace("3, 1, 1", "3, 1, 1.5"))
    assert deck_digest(deck) != before
