"""*UNITS: the names of the deck's length, force and stress units, kept as written (MPa is not
mPa), optional, given once; nothing is converted."""
import pytest

from lagamine_py.deck import DeckError, load_deck

from test_deck_errors import BASE


def deck(tmp_path, units):
    path = tmp_path / "u.dat"
    path.write_text(units + BASE)
    return path


def test_units_are_kept_as_written(tmp_path):
    assert load_deck(deck(tmp_path, "*UNITS\nmm, N, MPa\n")).units == ("mm", "N", "MPa")
    assert load_deck(deck(tmp_path, "*units\nm, kN, kPa\n")).units == ("m", "kN", "kPa")
    assert load_deck(deck(tmp_path, "")).units == ()


@pytest.mark.parametrize("text, words", [
    ("*UNITS\nmm, N\n", "stress"),                         # three names
    ("*UNITS\nmm, N, 1\n", "must be a name"),
    ("*UNITS\nmm, N, MPa\n*UNITS\nm, N, Pa\n", "given twice"),
    ("*UNITS\nmm, N, MPa\nm, N, Pa\n", "expected 1 data line"),
])
def test_bad_units_are_refused_where_they_are(tmp_path, text, words):
    with pytest.raises(DeckError) as info:
        load_deck(deck(tmp_path, text))
    assert any(p.keyword == "UNITS" and words in p.message for p in info.value.problems), \
        str(info.value)
