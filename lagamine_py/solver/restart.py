"""Restart data: what a run needs to resume after its last converged increment.

Saved with ``np.savez`` after every converged increment, in ``OUT/restart.npz``: the
displacement, the committed state of every group, the reactions, the step index, the time within
the step, the next time increment, the increment counters, the current step's resolved loads
(:class:`~lagamine_py.solver.loads.StepLoads`) and the deck: its absolute path, the digest of its
expanded text and the parameter values given on the command line
(:class:`~lagamine_py.core.outdir.DeckIdentity`).  A restart of a deck whose digest differs is
refused (:class:`RestartMismatch`, exit status 2): it would go on from the state of another model.

Written atomically (a temporary file renamed over the previous one: a process killed at any
moment leaves the old file or the new one) and not fsynced: the rename is what protects against
the death of the process (SIGKILL, a crash), whose written pages the OS keeps; an fsync would
only add durability against a crash of the machine, which the CSV and VTU files the restart
point must agree with do not have either, and it cost ~6 ms of wall time a save on this
machine's disk (0.1 s of the main job's 0.7 s).  Abaqus and CalculiX write restart data only
when a deck asks for it (``*RESTART, WRITE``).
"""
from __future__ import annotations

import io
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from ..core.exits import EXIT_DECK, EXIT_OTHER
from ..core.outdir import DeckIdentity

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
    with open(tmp, "wb") as fh:
        if sum(np.asarray(v).nbytes for v in data.values()) <= IN_MEMORY_BYTES:
            buf = io.BytesIO()
            np.savez(buf, **data)
            fh.write(buf.getbuffer())
        else:
            np.savez(fh, **data)
    os.replace(tmp, outdir / FILE)


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
