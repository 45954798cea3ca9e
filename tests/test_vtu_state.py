"""tools/vtu_state.py: the VTK writer timed on one recorded state of press-then-slide."""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
import vtu_state  # noqa: E402


def test_records_the_asked_increment_and_times_its_files(tmp_path):
    """The state kept is the writer's N-th increment (its step and time those of the run's
    second increment of the press), a saved state is timed like a recorded one, and --out
    writes that state's files."""
    model, result = vtu_state.record(4, 2, 2)
    assert (result.step, result.increment) == (1, 2)
    saved = tmp_path / "state.pkl"
    assert vtu_state.main(["4", "2", "--increment", "2", "--repeat", "1", "--save", str(saved)]) == 0
    out = tmp_path / "files"
    assert vtu_state.main(["--load", str(saved), "--repeat", "1", "--out", str(out)]) == 0
    assert (out / f"{model.name}_0000.vtu").stat().st_size > 0
    times = vtu_state.time_state(model, result, 1)
    assert set(times) == {"state_ms", "body_grid_ms", "body_file_ms", "body_file_mb"}
    assert times["body_file_mb"] > 0 and times["state_ms"] > 0
