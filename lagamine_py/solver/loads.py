"""Load and boundary-condition persistence across steps (DECKS.md, "Step keywords").

Rules, per kind (BOUNDARY, CLOAD, DLOAD, FOUNDATION MOTION):

* a value not given again in a step stays at the value it reached;
* a value given in a step goes, without ``AMPLITUDE=``, linearly over the step from where it
  stood (an imposed DOF that was free starts from its current displacement; a new force from 0)
  to the given value; with ``AMPLITUDE=`` it is ``amplitude(step time) * given value``;
* ``OP=NEW`` removes all earlier values of that kind first.  Removed forces and pressures are
  ramped down to zero over the step rather than dropped at once (a sudden load change would
  hit the first increment); a released imposed DOF becomes free at the step start and its
  reaction is applied as a nodal force ramped down to zero (as Abaqus does), so equilibrium is
  not broken at once.

Within one step a later line on the same DOF (or surface) replaces an earlier one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

KINDS = ("bc", "cload", "dload", "motion")


@dataclass
class Ramp:
    """Values of one kind over a step.  ``keys`` (m,) DOFs (bc, cload) or indices into
    ``StepLoads.surfaces`` / ``StepLoads.foundations``; ``start``/``target`` (m,) or (m, 2);
    ``amp`` (m,) index into ``StepLoads.amplitude_names`` (-1: linear ramp)."""
    keys: np.ndarray
    start: np.ndarray
    target: np.ndarray
    amp: np.ndarray

    @classmethod
    def build(cls, entries: dict, width: int = 0) -> "Ramp":
        """From ``{key: (start, target, amp)}``."""
        shape = (len(entries),) + ((width,) if width else ())
        keys = np.fromiter(entries.keys(), np.int64, len(entries))
        start, target = np.zeros(shape), np.zeros(shape)
        amp = np.full(len(entries), -1, np.int64)
        for i, (s, t, a) in enumerate(entries.values()):
            start[i], target[i], amp[i] = s, t, a
        order = np.argsort(keys, kind="stable")
        return cls(keys[order], start[order], target[order], amp[order])

    def at(self, frac: float, amp_values: np.ndarray) -> np.ndarray:
        """Values at step fraction ``frac`` with the amplitudes' values ``amp_values``."""
        lin = self.start + (self.target - self.start) * frac
        a = amp_values[np.maximum(self.amp, 0)] if amp_values.size else np.zeros(len(self.amp))
        use = self.amp >= 0
        if self.target.ndim == 2:
            a, use = a[:, None], use[:, None]
        return np.where(use, self.target * a, lin)


@dataclass
class Reached:
    """Values reached at the end of a step (what the next step starts from)."""
    bc: dict[int, float] = field(default_factory=dict)
    bc_targets: dict[str, np.ndarray] = field(default_factory=dict)
    cload: dict[int, float] = field(default_factory=dict)
    dload: dict[str, float] = field(default_factory=dict)
    motion: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class StepLoads:
    """Everything imposed during one step, as functions of the step time."""
    period: float
    amplitude_names: list[str]
    surfaces: list[str]
    foundations: list[str]
    bc: Ramp
    cload: Ramp
    dload: Ramp
    motion: Ramp
    bc_targets: dict[str, np.ndarray]

    @property
    def constrained(self) -> np.ndarray:
        """(c,) sorted constrained DOFs."""
        return self.bc.keys

    def _amp(self, model, t: float) -> np.ndarray:
        return np.array([model.amplitudes[n](t) for n in self.amplitude_names], float)

    def _frac(self, t: float) -> float:
        return t / self.period if self.period > 0 else 1.0

    def bc_values(self, model, t: float) -> np.ndarray:
        return self.bc.at(self._frac(t), self._amp(model, t))

    def f_ext(self, model, t: float, ndof: int) -> np.ndarray:
        vals = self.cload.at(self._frac(t), self._amp(model, t))
        return np.bincount(self.cload.keys, weights=vals, minlength=ndof).astype(float)

    def pressures(self, model, t: float) -> dict[str, float]:
        vals = self.dload.at(self._frac(t), self._amp(model, t))
        return {self.surfaces[k]: float(v) for k, v in zip(self.dload.keys, vals)}

    def motions(self, model, t: float) -> dict[str, np.ndarray]:
        """Placement (dx, dy, angle) of every foundation moved by ``*FOUNDATION MOTION`` at step
        time ``t`` (zeros for the others)."""
        out = {name: np.zeros(3) for name in self.foundations}
        vals = self.motion.at(self._frac(t), self._amp(model, t))
        for k, v in zip(self.motion.keys, vals):
            out[self.foundations[k]] = _placement(v)
        return out

    def reached(self, model) -> Reached:
        T = self.period
        bc = dict(zip(self.bc.keys.tolist(), self.bc_values(model, T).tolist()))
        f = self.f_ext(model, T, int(self.cload.keys.max()) + 1 if self.cload.keys.size else 0)
        cload = {int(d): float(f[d]) for d in np.unique(self.cload.keys) if f[d] != 0.0}
        dload = {k: v for k, v in self.pressures(model, T).items() if v != 0.0}
        motion = {k: v for k, v in self.motions(model, T).items()}
        return Reached(bc, dict(self.bc_targets), cload, dload, motion)

    # -- restart ---------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {"loads_period": np.array(self.period),
               "loads_amplitudes": np.array(self.amplitude_names, dtype=str),
               "loads_surfaces": np.array(self.surfaces, dtype=str),
               "loads_foundations": np.array(self.foundations, dtype=str),
               "loads_targets": np.array(list(self.bc_targets), dtype=str),
               "loads_target_sizes": np.array([len(v) for v in self.bc_targets.values()], np.int64),
               "loads_target_nodes": np.concatenate([np.asarray(v, np.int64) for v in
                                                     self.bc_targets.values()] or [np.zeros(0, np.int64)])}
        for kind in KINDS:
            r = getattr(self, kind)
            for part in ("keys", "start", "target", "amp"):
                out[f"loads_{kind}_{part}"] = getattr(r, part)
        return out

    @classmethod
    def from_arrays(cls, z) -> "StepLoads":
        ramps = {kind: Ramp(*(np.asarray(z[f"loads_{kind}_{p}"]) for p in ("keys", "start", "target", "amp")))
                 for kind in KINDS}
        nodes = np.split(z["loads_target_nodes"], np.cumsum(z["loads_target_sizes"])[:-1]) \
            if len(z["loads_targets"]) else []
        targets = {str(n): v for n, v in zip(z["loads_targets"], nodes)}
        return cls(float(z["loads_period"]), [str(s) for s in z["loads_amplitudes"]],
                   [str(s) for s in z["loads_surfaces"]], [str(s) for s in z["loads_foundations"]],
                   ramps["bc"], ramps["cload"], ramps["dload"], ramps["motion"], targets)


def step_loads(model, step, reached: Reached, u: np.ndarray, reaction: np.ndarray,
               surfaces: list[str], foundations: list[str]) -> StepLoads:
    """Resolve what ``step`` imposes, given what the previous steps left.

    Parameters
    ----------
    reached : values at the end of the previous step.
    u : (ndof,) displacement at the step start.
    reaction : (ndof,) reaction at the step start (used when OP=NEW releases an imposed DOF).
    surfaces, foundations : names indexing the dload and motion ramps.
    """
    amp_names = sorted(model.amplitudes)
    amp_index = {n.upper(): i for i, n in enumerate(amp_names)}

    def amp_of(item) -> int:
        if item.amplitude is None:
            return -1
        try:
            return amp_index[item.amplitude.upper()]
        except KeyError:
            raise KeyError(f"step {step.name}: unknown amplitude {item.amplitude}") from None

    op_new = {k.upper() for k in step.op_new}
    # BOUNDARY
    keep_bc = {} if "BOUNDARY" in op_new else dict(reached.bc)
    bc = {d: (v, v, -1) for d, v in keep_bc.items()}
    targets = {} if "BOUNDARY" in op_new else dict(reached.bc_targets)
    for b in step.boundaries:
        nodes = np.asarray(b.nodes, np.int64)
        for comp in b.components:
            for d in model.dof(nodes, comp - 1).tolist():
                bc[d] = (float(u[d]), float(b.value), amp_of(b))
        targets[b.target] = np.union1d(targets.get(b.target, np.zeros(0, np.int64)), nodes)
    released = [d for d in reached.bc if d not in bc]

    # CLOAD: removed ones (OP=NEW) ramp to zero; released reactions ramp to zero
    cl = {d: (v, 0.0 if "CLOAD" in op_new else v, -1) for d, v in reached.cload.items()}
    for cload in step.cloads:
        for d in model.dof(np.asarray(cload.nodes, np.int64), cload.dof - 1).tolist():
            cl[d] = (reached.cload.get(d, 0.0), float(cload.value), amp_of(cload))
    cl_ramp = Ramp.build(cl)
    if released:
        rel = Ramp.build({d: (float(reaction[d]), 0.0, -1) for d in released})
        cl_ramp = Ramp(*(np.concatenate([getattr(cl_ramp, p), getattr(rel, p)])
                         for p in ("keys", "start", "target", "amp")))

    # DLOAD (pressure, per surface)
    s_index = {s.upper(): i for i, s in enumerate(surfaces)}
    dl = {s_index[s.upper()]: (v, 0.0 if "DLOAD" in op_new else v, -1)
          for s, v in reached.dload.items()}
    for dload in step.dloads:
        k = s_index[dload.surface.upper()]
        dl[k] = (reached.dload.get(surfaces[k], 0.0), float(dload.value), amp_of(dload))

    # FOUNDATION MOTION (rigid translation and rotation reached at step end)
    f_index = {f.upper(): i for i, f in enumerate(foundations)}
    mo = {f_index[f.upper()]: (v, v, -1) for f, v in reached.motion.items()}
    for m in step.motions:
        k = f_index[m.foundation.upper()]
        here = _placement(reached.motion.get(foundations[k], np.zeros(3)))
        mo[k] = (here, np.array([m.dx, m.dy, m.angle], float), amp_of(m))

    return StepLoads(float(step.period), amp_names, list(surfaces), list(foundations),
                     Ramp.build(bc), cl_ramp, Ramp.build(dl), Ramp.build(mo, width=3), targets)


def _placement(v) -> np.ndarray:
    """A foundation placement as (dx, dy, angle) (a translation alone has angle 0)."""
    v = np.asarray(v, float).ravel()
    return np.concatenate([v, np.zeros(3 - v.size)]) if v.size < 3 else v


def driving_loads(model, step, loads: StepLoads, t: float) -> dict[str, float]:
    """The loads ``step`` gives that change during it, at step time ``t``: ``{label: value}``,
    what a user reads as "the load reached" (``lagamine-py plot`` labels its states with them).

    Labels: ``U<dof> <target>`` an imposed displacement (the mean of its nodes' values: they
    differ only when the nodes started from different displacements; ``UR6`` a reference node's
    rotation), ``P <surface>`` a pressure, ``CF<dof> <target>`` a nodal force (per node;
    ``CM6`` a moment), ``<foundation> dx`` / ``dy`` / ``angle`` a foundation's motion.  A line
    whose value stays what it was (a support held at 0) is not a driving load and is left out."""
    frac, amp = loads._frac(t), loads._amp(model, t)
    out: dict[str, float] = {}

    def moving(ramp: Ramp, rows: np.ndarray) -> bool:
        return bool(len(rows)) and bool((ramp.amp[rows] >= 0).any()
                                        or np.any(ramp.start[rows] != ramp.target[rows]))

    if step.boundaries:
        values = loads.bc.at(frac, amp)
        for b in step.boundaries:
            nodes = np.asarray(b.nodes, np.int64)
            for comp in b.components:
                rows = np.searchsorted(loads.bc.keys, model.dof(nodes, comp - 1))
                if moving(loads.bc, rows):
                    out[f"{'UR' if comp == 6 else 'U'}{comp} {b.target}"] = float(np.mean(values[rows]))
    if step.cloads:
        values = loads.cload.at(frac, amp)
        for cl in step.cloads:
            rows = np.flatnonzero(np.isin(loads.cload.keys, model.dof(np.asarray(cl.nodes), cl.dof - 1)))
            if moving(loads.cload, rows):
                out[f"{'CM' if cl.dof == 6 else 'CF'}{cl.dof} {cl.target}"] = float(np.mean(values[rows]))
    if step.dloads:
        pressures = loads.pressures(model, t)
        for d in step.dloads:
            k = loads.surfaces.index(next(s for s in loads.surfaces if s.upper() == d.surface.upper()))
            rows = np.flatnonzero(loads.dload.keys == k)
            if moving(loads.dload, rows):
                out[f"P {d.surface}"] = pressures[loads.surfaces[k]]
    if step.motions:
        motions = loads.motions(model, t)
        for m in step.motions:
            name = next(f for f in loads.foundations if f.upper() == m.foundation.upper())
            rows = np.flatnonzero(loads.motion.keys == loads.foundations.index(name))
            for i, axis in enumerate(("dx", "dy", "angle")):
                if len(rows) and ((loads.motion.amp[rows] >= 0).any()
                                  or np.any(loads.motion.start[rows, i] != loads.motion.target[rows, i])):
                    out[f"{name} {axis}"] = float(motions[name][i])
    return out
