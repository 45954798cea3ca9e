"""A third-party lagamine_py writer: one JSON record per line, ``<deck>.jsonl``.

The entry point in setup.cfg (group ``lagamine_py.writers``) makes it available to decks as
``*OUTPUT, WRITERS=.../JSONL``.  Records: ``start``, ``step``, ``increment`` (time, Newton
iterations, the total reaction force and the reaction of every imposed-displacement set, the
contact totals), ``failed`` (a failed attempt) and ``end`` (exit status and message), each
flushed as it is written.  A resumed run appends to the file.
"""
import json

import numpy as np

from lagamine_py.output.base import Writer


class JsonLinesWriter(Writer):
    """<deck>.jsonl: one JSON record per event of the run (increments with their reactions)."""

    def start_run(self):
        self.outdir.mkdir(parents=True, exist_ok=True)
        self.fh = open(self.outdir / f"{self.model.name or 'run'}.jsonl",
                       "a" if self.append else "w")
        self._record({"event": "start", "deck": self.model.name,
                      "nodes": int(len(self.model.node_ids))})

    def start_step(self, step_number, step):
        self._record({"event": "step", "step": int(step_number), "name": step.name})

    def increment(self, result):
        total = np.asarray(result.reaction, float).sum(axis=0)
        self._record({"event": "increment", "step": result.step, "increment": result.increment,
                      "time": float(result.time), "iterations": int(result.iterations),
                      "reaction_total": [float(total[0]), float(total[1])],
                      "reactions": {name: [float(v) for v in np.ravel(rf)[:2]]
                                    for name, rf in result.reactions_by_set.items()},
                      "contacts": {cp.name: {"P": float(cp.P), "T": float(cp.T)}
                                   for cp in result.contacts}})

    def failed_attempt(self, attempt):
        self._record({"event": "failed", "step": attempt.step, "increment": attempt.increment,
                      "time": float(attempt.time), "dt": float(attempt.dt),
                      "reason": attempt.reason})

    def close(self, status, message):
        self._record({"event": "end", "status": int(status), "message": message})
        self.fh.close()

    def _record(self, record):
        self.fh.write(json.dumps(record) + "\n")
        self.fh.flush()
