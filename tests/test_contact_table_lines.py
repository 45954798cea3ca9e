"""contact.csv rows joined by hand (output/tables.py, issue 17 item 3): the text ``csv.writer``
writes for the same rows, and csv.writer itself where a pair's name needs quotes."""
from __future__ import annotations

import csv
import io
from types import SimpleNamespace

import numpy as np
import pytest

from lagamine_py.elements.base import ContactPoints
from lagamine_py.output import tables


def _points(name: str, g: int = 12, seed: int = 0) -> ContactPoints:
    rng = np.random.default_rng(seed)
    special = np.array([np.nan, np.inf, -np.inf, -0.0, 1e-310, 1e300])
    vals = lambda: np.concatenate([special, rng.normal(size=g - 6) * 10.0 ** rng.integers(-9, 9, g - 6)])  # noqa: E731
    return ContactPoints(name=name, element=rng.integers(1, 10**7, g), face=np.ones(g, int),
                         gauss=np.tile([1, 2, 3], g // 3), x=rng.normal(size=(g, 2)), p=vals(),
                         tau=vals(), gap=vals(), slip=vals(), lam=vals(),
                         status=rng.integers(0, 4, g).astype(np.int8), P=1.5, T=-0.25,
                         vp=vals(), dvp=vals(), dissip=vals(), E=2.0)


def _csv_text(rows) -> str:
    buf = io.StringIO(newline="")
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


@pytest.mark.parametrize("seed", range(3))
def test_point_lines_are_what_csv_writer_writes(seed):
    cp = _points("BLOCK_BOTTOM->FLAT", seed=seed)
    head = ["2", "17", tables.fmt(1.575)[()]]
    assert tables.point_lines(",".join(head) + ",", cp) == _csv_text(tables.point_rows(head, cp))


@pytest.mark.parametrize("name,plain", [("BLOCK_BOTTOM->FLAT", True), ("A,B", False),
                                        ('say "x"', False), ("two\nlines", False), ("", False),
                                        ("with space", True)])
def test_the_writer_writes_csv_text_whatever_the_name(tmp_path, name, plain):
    """Through :class:`ContactWriter`: the file holds csv.writer's text, by the joined lines
    for a plain name, by csv.writer for one that needs quotes."""
    assert tables._plain(name) is plain
    cps = [_points(name, seed=1), _points("OTHER", seed=2)]
    w = tables.ContactWriter(tmp_path, SimpleNamespace(name="d"))
    w.start_run()
    result = SimpleNamespace(step=1, increment=3, time=0.25, contacts=cps, write_fields=True)
    w.increment(result)
    w.close(0, "")
    head = ["1", "3", "0.25"]
    expected = _csv_text([tables.CONTACT_HEADER]
                         + [r for cp in cps for r in tables.point_rows(head, cp)])
    assert (tmp_path / "contact.csv").read_text() == expected
