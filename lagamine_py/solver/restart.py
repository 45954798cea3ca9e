"""Restart data: what a run needs to resume after its last converged increment.

Saved with ``np.savez`` after every converged increment, atomically (a temporary file renamed
over the previous one), in ``OUT/restart.npz``: the displacement, the committed state of every
group, the reactions, the step index, the time within the step, the next time increment, the
increment counters, the current step's resolved loads (:class:`~lagamine_py.solver.loads.StepLoads`)
and the deck path.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

FILE = "restart.npz"


class RestartError(RuntimeError):
    """The restart data is missing or does not fit the model."""


def save(outdir: Path, data: dict[str, np.ndarray]) -> None:
    """Write ``data`` to ``outdir/restart.npz`` atomically."""
    outdir = Path(outdir)
    tmp = outdir / "restart.tmp.npz"
    with open(tmp, "wb") as fh:
        np.savez(fh, **data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, outdir / FILE)


def load(outdir: Path) -> dict[str, np.ndarray]:
    path = Path(outdir) / FILE
    if not path.exists():
        raise RestartError(f"{outdir} holds no restart data ({FILE} is missing)")
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def restart_deck(outdir: Path) -> Path | None:
    """The deck path recorded in ``outdir``'s restart data, or None."""
    try:
        data = load(outdir)
    except RestartError:
        return None
    deck = str(data.get("deck", ""))
    return Path(deck) if deck else None


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
