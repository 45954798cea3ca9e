"""Restart data: what a run needs to resume after its last converged increment.

Saved as ``np.savez`` writes it (the bytes patched into a template of the same arrays:
:class:`NpzTemplate`) after every converged increment, in ``OUT/restart.npz``: the
displacement, the committed state of every group, the reactions, the step index, the time within
the step, the next time increment, the increment counters, the current step's resolved loads
(:class:`~lagamine_py.solver.loads.StepLoads`) and the deck: its absolute path, the digest of its
expanded text and the parameter values given on the command line
(:class:`~lagamine_py.core.outdir.DeckIdentity`).  A restart of a deck whose digest differs is
refused (:class:`RestartMismatch`, exit status 2): it would go on from the state of another model.

Written atomically (a temporary file renamed over the previous one: a process killed at any
moment leaves the old file or the new one; the old one's blocks freed on a background thread,
:func:`lagamine_py.core.outdir.replace`) and not fsynced: the rename is what protects against
the death of the process (SIGKILL, a crash), whose written pages the OS keeps; an fsync would
only add durability against a crash of the machine, which the CSV and VTU files the restart
point must agree with do not have either, and it cost ~6 ms of wall time a save on this
machine's disk (0.1 s of the main job's 0.7 s).  Abaqus and CalculiX write restart data only
when a deck asks for it (``*RESTART, WRITE``).
"""
from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from ..core.exits import EXIT_DECK, EXIT_OTHER
from ..core.outdir import DeckIdentity, replace

FILE = "restart.npz"
#: restart data up to this size is assembled in memory and written in one call: ``np.savez``
#: seeks back over each array's zip header, on a file a flush and a few system calls per
#: array (the main job's 55 arrays: 2.8 ms a save against 0.7 ms in memory, every increment)
IN_MEMORY_BYTES = 32 * 2**20


class RestartError(RuntimeError):
    """The restart data is missing, damaged or does not fit the model (exit status 1)."""
    status = EXIT_OTHER


class RestartMismatch(RestartError):
    """The restart data is of another deck, or of this deck before it changed (status 2)."""
    status = EXIT_DECK


def save(outdir: Path, data: dict[str, np.ndarray]) -> None:
    """Write ``data`` to ``outdir/restart.npz`` atomically."""
    outdir = Path(outdir)
    tmp = outdir / "restart.tmp.npz"
    arrays = {k: np.asarray(v) for k, v in data.items()}
    size = sum(v.nbytes for v in arrays.values())
    with open(tmp, "wb") as fh:
        if size <= TEMPLATE_BYTES:
            fh.write(npz_bytes(arrays))
        elif size <= IN_MEMORY_BYTES:              # one write, no copy of the buffer
            buf = io.BytesIO()
            np.savez(buf, **arrays)
            fh.write(buf.getbuffer())
        else:
            np.savez(fh, **arrays)
    replace(tmp, outdir / FILE)             # the old file unlinked on a background thread


class NpzTemplate:
    """The bytes ``np.savez`` writes for arrays of given names, dtypes and shapes, with the
    places of each array's bytes and CRC-32s: the .npz of new values of the same arrays is the
    template with those bytes and CRCs replaced (uncompressed entries: nothing else in the file
    depends on the values).

    A restart file holds the same arrays at every increment (the main job's 59): ``np.savez``
    built each array's .npy header and zip headers again, and seeked back over each (1.2 ms a
    save against ~0.2 ms patched; ``tests/test_restart_template.py`` compares the bytes with
    ``np.savez``'s)."""

    def __init__(self, arrays: dict[str, np.ndarray]):
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        self.data = bytes(buf.getbuffer())
        self.key = template_key(arrays)
        # per array: where its entry's data (.npy header and bytes) starts, where its bytes
        # start and end, where its CRC-32 is in the local header and in the central directory
        self.places = []
        with zipfile.ZipFile(io.BytesIO(self.data)) as zf:
            infos = zf.infolist()
            central = zf.start_dir
        for info, a in zip(infos, arrays.values()):
            h = info.header_offset
            n, m = struct.unpack_from("<HH", self.data, h + 26)
            start = h + 30 + n + m
            end = start + info.file_size                  # the array's bytes end its entry
            n2, m2, k2 = struct.unpack_from("<HHH", self.data, central + 28)
            self.places.append((start, end - a.nbytes, end, h + 14, central + 16))
            central += 46 + n2 + m2 + k2

    def fill(self, arrays: dict[str, np.ndarray]) -> bytes:
        """The .npz bytes of ``arrays`` (of this template's :func:`template_key`)."""
        out = bytearray(self.data)
        view = memoryview(self.data)
        for (start, a, b, local, central), v in zip(self.places, arrays.values()):
            raw = _raw_bytes(v)
            out[a:b] = raw
            # CRC of the whole entry: the .npy header (unchanged) and the array's bytes
            crc = zlib.crc32(raw, zlib.crc32(view[start:a]))
            struct.pack_into("<I", out, local, crc)
            struct.pack_into("<I", out, central, crc)
        return bytes(out)


def _raw_bytes(a: np.ndarray) -> bytes:
    """An array's bytes as ``np.lib.format.write_array`` writes them: Fortran order for an
    array only Fortran-contiguous, C order otherwise."""
    order = "F" if a.flags.f_contiguous and not a.flags.c_contiguous else "C"
    return a.tobytes(order=order)


def template_key(arrays: dict[str, np.ndarray]):
    """What the bytes of an .npz depend on besides the values: the names, dtypes, shapes and
    storage orders (None when an array is stored by pickle: its size depends on the value)."""
    key = []
    for name, a in arrays.items():
        if a.dtype.hasobject:
            return None
        key.append((name, a.dtype.str, a.dtype.descr if a.dtype.names else None, a.shape,
                    bool(a.flags.f_contiguous and not a.flags.c_contiguous)))
    return tuple(key)


_template: NpzTemplate | None = None
#: restart data above this size is written by ``np.savez`` each time, and no template is kept:
#: the template pays at small sizes (1 ms a save of the main job's 126 kB), while above this a
#: template held for the run and its filled copies (2.6 MB each at 80x40) raised the 80x40 peak
#: by ~5 MB against a margin of under 1 MB to CalculiX's (issue 17 item 5).
TEMPLATE_BYTES = 2**20


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """The bytes ``np.savez(file, **arrays)`` writes, from the template of the last call when
    the arrays' names, dtypes and shapes are the same (:class:`NpzTemplate`)."""
    global _template
    key = template_key(arrays)
    if key is None or sum(a.nbytes for a in arrays.values()) > TEMPLATE_BYTES:
        _template = None
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        return bytes(buf.getbuffer())
    if _template is None or _template.key != key:
        _template = NpzTemplate(arrays)
        return _template.data
    return _template.fill(arrays)


def load(outdir: Path) -> dict[str, np.ndarray]:
    """The arrays of ``outdir/restart.npz``; :class:`RestartError` when it is missing or
    cannot be read (cut, garbage, not an ``.npz``)."""
    path = Path(outdir) / FILE
    if not path.exists():
        raise RestartError(f"{outdir} holds no restart data ({FILE} is missing)")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, AttributeError) as exc:
        raise RestartError(f"{path} cannot be read ({type(exc).__name__}: {exc}): it is damaged; "
                           f"run the deck again from the start") from None


def saved_deck(outdir: Path) -> DeckIdentity | None:
    """The deck recorded in ``outdir``'s restart data (path, digest, parameters), or None when
    there is no readable restart data."""
    try:
        return deck_of(load(outdir))
    except RestartError:
        return None


def deck_of(data: dict) -> DeckIdentity:
    """The deck recorded in restart data (path, digest, parameters)."""
    try:
        params = json.loads(str(data.get("deck_parameters", "{}")) or "{}")
    except ValueError:
        params = {}
    return DeckIdentity(str(data.get("deck", "")), "", str(data.get("deck_digest", "")),
                        params if isinstance(params, dict) else {})


def restart_deck(outdir: Path) -> Path | None:
    """The deck path recorded in ``outdir``'s restart data, or None."""
    deck = saved_deck(outdir)
    return Path(deck.path) if deck is not None and deck.path else None


def check_deck(outdir: Path, data: dict, deck: DeckIdentity) -> None:
    """:class:`RestartMismatch` unless the restart ``data`` was saved by a run of ``deck``
    as it is now (same digest of the expanded text); a deck known by its path only (a model
    built by a script) is compared by path."""
    saved_path = str(data.get("deck", ""))
    saved = str(data.get("deck_digest", "")) if "deck_digest" in data else None
    if deck.digest:
        if saved is None:
            raise RestartMismatch(f"{outdir / FILE} was written by an older lagamine-py that did "
                                  f"not record which deck it ran: cannot tell that it is "
                                  f"{deck.path}; run the deck again from the start")
        if saved != deck.digest:
            same = saved_path == deck.path
            raise RestartMismatch(
                f"{outdir / FILE} was saved by a run of {saved_path or 'another deck'}"
                + (", which has changed since (its text, an included file or a parameter value "
                   "differs)" if same else
                   f", not of {deck.path} (their expanded texts differ)")
                + "; a restart must resume the same model: restore that deck, or run the deck "
                  "again from the start")
    elif saved_path and deck.path and saved_path != deck.path:
        raise RestartMismatch(f"{outdir / FILE} was saved by a run of {saved_path}, not of "
                              f"{deck.path}")


def pack_states(states: list[dict]) -> dict[str, np.ndarray]:
    """Group states as flat ``state<k>:<key>`` arrays."""
    out = {}
    for k, st in enumerate(states):
        for key, val in st.items():
            out[f"state{k}:{key}"] = np.asarray(val)
    return out


def unpack_states(data: dict[str, np.ndarray], templates: list[dict]) -> list[dict]:
    """Group states back from :func:`pack_states`, checked against ``init_state()`` templates."""
    states = []
    for k, tpl in enumerate(templates):
        st = {}
        for key, val in tpl.items():
            name = f"state{k}:{key}"
            if name not in data:
                raise RestartError(f"restart data lacks {name}: the model changed since the run")
            saved = data[name]
            if np.shape(saved) != np.shape(val):
                raise RestartError(f"restart data {name} has shape {np.shape(saved)}, "
                                   f"the model expects {np.shape(val)}")
            st[key] = saved.copy()
        for name in data:
            if name.startswith(f"state{k}:") and name.split(":", 1)[1] not in st:
                st[name.split(":", 1)[1]] = data[name].copy()
        states.append(st)
    return states
