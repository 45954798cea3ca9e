"""Restart data written from a template (solver/restart.py, issue 17 item 3): the bytes of each
save are those ``np.savez`` writes for the same arrays, whichever way they were produced."""
from __future__ import annotations

import io

import numpy as np
import pytest

from lagamine_py.solver import restart as rs


def _savez(arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _arrays(rng, k: int, n: int = 40) -> dict:
    """Arrays of the kinds restart data holds (strings, 0-d numbers, floats, ints, booleans),
    with an only-Fortran-contiguous, a non-contiguous and an empty one."""
    return {"deck": np.array("/decks/press_slide.dat"), "step": np.array(k),
            "t": np.array(rng.uniform()), "u": rng.normal(size=n),
            "state0:status": rng.integers(0, 3, 12).astype(np.int8),
            "state0:open": rng.normal(size=(3, 4)) > 0,
            "state1:F": np.asfortranarray(rng.normal(size=(5, 3))),
            "state1:strided": rng.normal(size=(4, 6))[:, ::2],
            "state1:none": np.zeros((0, 2)), "ids": rng.integers(0, 1 << 40, 5)}


def test_each_save_is_the_bytes_of_np_savez(monkeypatch):
    """Saves of new values with the same names, dtypes and shapes come from one template and
    equal ``np.savez``'s bytes (values, CRC-32s); a changed shape builds a new template."""
    monkeypatch.setattr(rs, "_template", None)
    rng = np.random.default_rng(17)
    first = None
    for k in range(5):
        arrays = _arrays(rng, k)
        assert rs.npz_bytes(arrays) == _savez(arrays)
        first = first or rs._template
        assert rs._template is first               # the values alone changed: the template
    arrays = _arrays(rng, 5, n=41)                  # another shape of u
    assert rs.npz_bytes(arrays) == _savez(arrays)
    assert rs._template is not first
    arrays = _arrays(rng, 6, n=41)
    arrays["deck"] = np.array("/decks/a_longer_name.dat")       # another string dtype
    assert rs.npz_bytes(arrays) == _savez(arrays)
    again = rs._template
    arrays = _arrays(rng, 7, n=41)
    arrays["deck"] = np.array("/decks/a_longer_name.dat")
    assert rs.npz_bytes(arrays) == _savez(arrays) and rs._template is again


def test_object_arrays_are_written_by_np_savez(monkeypatch):
    """A pickled array's size depends on its value: no template."""
    monkeypatch.setattr(rs, "_template", None)
    arrays = {"u": np.zeros(3), "o": np.array([{"a": 1}, None], dtype=object)}
    assert rs.template_key(arrays) is None
    assert rs.npz_bytes(arrays) == _savez(arrays) and rs._template is None


def test_large_restart_data_keeps_no_template(monkeypatch):
    """Above ``TEMPLATE_BYTES`` each save is ``np.savez``'s and no template is held (its bytes
    and their copies would sit beside the run's peak); a small save after it builds one."""
    monkeypatch.setattr(rs, "_template", None)
    monkeypatch.setattr(rs, "TEMPLATE_BYTES", 2000)
    rng = np.random.default_rng(3)
    small = _arrays(rng, 1)
    assert rs.npz_bytes(small) == _savez(small) and rs._template is not None
    large = _arrays(rng, 2, n=400)                   # 3.2 kB of displacements
    assert rs.npz_bytes(large) == _savez(large) and rs._template is None
    assert rs.npz_bytes(large) == _savez(large) and rs._template is None


def test_save_writes_what_np_savez_writes_and_loads_back(tmp_path, monkeypatch):
    monkeypatch.setattr(rs, "_template", None)
    rng = np.random.default_rng(3)
    for k in range(3):
        arrays = _arrays(rng, k)
        rs.save(tmp_path, arrays)
        np.savez(tmp_path / "reference.npz", **arrays)
        assert (tmp_path / rs.FILE).read_bytes() == (tmp_path / "reference.npz").read_bytes()
        back = rs.load(tmp_path)
        assert list(back) == list(arrays)
        for name, a in arrays.items():
            np.testing.assert_array_equal(back[name], a)


@pytest.mark.parametrize("name", ["u", "state1:F", "state1:strided"])
def test_a_changed_value_changes_the_crc(monkeypatch, name):
    """One value changed (the first or last byte of an array): the file still reads (the
    CRC-32 was recomputed: zipfile checks it) and gives the new value."""
    monkeypatch.setattr(rs, "_template", None)
    rng = np.random.default_rng(5)
    arrays = _arrays(rng, 0)
    rs.npz_bytes(arrays)
    arrays[name] = np.array(arrays[name], order="K")
    arrays[name].flat[-1] += 1.0
    data = rs.npz_bytes(arrays)
    assert data == _savez(arrays)
    with np.load(io.BytesIO(data)) as z:
        np.testing.assert_array_equal(z[name], arrays[name])
