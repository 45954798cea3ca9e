"""Number lines read in bulk give the model the grammar gives, and the same messages.

Runs of plain number lines (``*NODE``, ``*ELEMENT``, sets) go through NumPy
(:class:`lagamine_py.deck.grammar.NumberRows`); every deck here is read twice, in bulk and with
bulk reading switched off (``BULK_MIN_LINES`` out of reach), and both readings must agree to
the last bit and the last message.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagamine_py.deck import DeckError, grammar, load_deck, parse_deck
from lagamine_py.deck.grammar import NumberRows


def q8_deck(n=6, extra_nodes="", extra_elements="", tail=""):
    """A Q8 block of n x n elements written out with *NODE / *ELEMENT lines."""
    m = 2 * n + 1
    ii, jj = np.meshgrid(np.arange(m), np.arange(m))
    keep = ~((ii % 2 == 1) & (jj % 2 == 1))
    num = np.zeros((m, m), int)
    num[keep] = np.arange(1, keep.sum() + 1)
    lines = ["*HEADING", "1234 a heading line that starts with digits", "*NODE, NSET=ALL"]
    lines += [f"{k}, {x:.6g}, {y:.6g}" for k, x, y in zip(num[keep], ii[keep] * 0.5, jj[keep] * 0.25)]
    lines += [extra_nodes] if extra_nodes else []
    lines.append("*ELEMENT, TYPE=CPE8, ELSET=BODY")
    e = 0
    for j0 in range(0, m - 1, 2):
        for i0 in range(0, m - 1, 2):
            e += 1
            c = [num[j0, i0], num[j0, i0 + 2], num[j0 + 2, i0 + 2], num[j0 + 2, i0],
                 num[j0, i0 + 1], num[j0 + 1, i0 + 2], num[j0 + 2, i0 + 1], num[j0 + 1, i0]]
            lines.append(", ".join(str(v) for v in [e] + c))
    lines += [extra_elements] if extra_elements else []
    lines += ["*NSET, NSET=FIRST", ", ".join(str(v) for v in num[0, :]) + ","]
    lines += ["*ELSET, ELSET=SOME"] + [f"{k}, {k + 1}" for k in range(1, 20, 2)]
    lines += ["*MATERIAL, NAME=M, LAW=ELASTIC", "E=1000, NU=0.3", "*SOLID, ELSET=BODY, MATERIAL=M",
              "*STEP", "*STATIC", "1, 1", "*BOUNDARY", "FIRST, 1, 2", "*END STEP"]
    return "\n".join(lines) + "\n" + tail


def both(path):
    """The deck read in bulk and through the grammar alone: (model or DeckError) twice."""
    out = []
    for bulk in (True, False):
        old = grammar.BULK_MIN_LINES
        grammar.BULK_MIN_LINES = 8 if bulk else 10**9
        try:
            out.append(load_deck(path))
        except DeckError as exc:
            out.append(exc)
        finally:
            grammar.BULK_MIN_LINES = old
    return out


def test_bulk_reading_is_used_and_gives_the_same_model(tmp_path):
    deck = tmp_path / "q8.dat"
    deck.write_text(q8_deck())
    blocks = parse_deck(deck)
    node_block = next(b for b in blocks if b.keyword == "NODE")
    assert any(isinstance(r, NumberRows) for r in node_block.data)      # the fast path ran
    heading = next(b for b in blocks if b.keyword == "HEADING")
    assert heading.text == ["1234 a heading line that starts with digits"]
    bulk, slow = both(deck)
    assert np.array_equal(bulk.node_ids, slow.node_ids)
    assert np.array_equal(bulk.coords, slow.coords)
    assert len(bulk.blocks) == len(slow.blocks) == 1
    assert np.array_equal(bulk.blocks[0].conn, slow.blocks[0].conn)
    assert np.array_equal(bulk.blocks[0].ids, slow.blocks[0].ids)
    for name in ("ALL", "FIRST"):
        assert np.array_equal(bulk.nsets[name], slow.nsets[name])
    assert np.array_equal(bulk.elsets["SOME"], slow.elsets["SOME"]) and len(bulk.elsets["SOME"]) == 20


@pytest.mark.parametrize("extra_nodes, extra_elements, expect", [
    ("5, 9.0, 9.0", "", "duplicate node id 5 (already defined at"),
    ("1.5, 2.0, 3.0", "", "must be an integer"),
    ("0, 1.0, 1.0", "", "node id must be a positive integer"),
    ("900, 1.0, 1.0, 2.0", "", "z = 2, but the model is 2D"),
    ("", "99, 1, 2, 3, 4, 5, 6, 7, 7", "uses node 7 more than once"),
    ("", "99, 1, 2, 3, 4, 5, 6, 7, 1234567", "uses node 1234567 that is not defined"),
    ("", "99, 1, 2, 3", "has 8 nodes, got 3"),
    ("", "1, 1, 2, 3, 4, 5, 6, 7, 8", "duplicate element id 1"),
])
def test_errors_in_bulk_lines_are_the_grammars(tmp_path, extra_nodes, extra_elements, expect):
    """A bad line in the middle of a bulk run: the same messages at the same file and line as
    through the grammar."""
    text = q8_deck(extra_nodes=extra_nodes, extra_elements=extra_elements)
    lines = text.splitlines()
    # move the bad line into the middle of its run, so that the run stays in bulk
    bad = extra_nodes or extra_elements
    at = lines.index(bad)
    lines.insert(at - 5, lines.pop(at))
    deck = tmp_path / "bad.dat"
    deck.write_text("\n".join(lines) + "\n")
    bulk, slow = both(deck)
    assert isinstance(bulk, DeckError) and isinstance(slow, DeckError)
    assert bulk.problems == slow.problems
    assert any(expect in p.message and p.line == at - 5 + 1 for p in bulk.problems), bulk


def test_fortran_exponents_and_names_in_a_number_run(tmp_path):
    """``1.5D0`` is a number in bulk as in the grammar; a name inside a run of numbers sends the
    run to the grammar, which reports it where it stands."""
    text = q8_deck().replace("\n2, 0.5, 0\n", "\n2, 0.5D0, 0.0d0\n")
    deck = tmp_path / "d.dat"
    deck.write_text(text)
    bulk, slow = both(deck)
    assert np.array_equal(bulk.coords, slow.coords) and bulk.coords[1].tolist() == [0.5, 0.0]
    lines = text.splitlines()
    at = lines.index("*NODE, NSET=ALL") + 10
    lines[at] = lines[at].replace(", ", ", x", 1)
    deck.write_text("\n".join(lines) + "\n")
    bulk, slow = both(deck)
    assert isinstance(bulk, DeckError) and bulk.problems == slow.problems
    assert bulk.problems[0].line == at + 1 and "x must be a number, got non-numeric 'x" in bulk.problems[0].message


def test_bulk_lines_of_an_included_file_name_that_file(tmp_path):
    text = q8_deck(extra_nodes="7, 1, 1")
    lines = text.splitlines()
    start, end = lines.index("*NODE, NSET=ALL"), lines.index("*ELEMENT, TYPE=CPE8, ELSET=BODY")
    (tmp_path / "nodes.inc").write_text("\n".join(lines[start:end]) + "\n")
    (tmp_path / "main.dat").write_text("\n".join(lines[:start] + ["*INCLUDE, INPUT=nodes.inc"]
                                                 + lines[end:]) + "\n")
    with pytest.raises(DeckError) as info:
        load_deck(tmp_path / "main.dat")
    (p,) = info.value.problems
    assert p.file.endswith("nodes.inc") and "duplicate node id 7" in p.message
    assert p.line == end - start
