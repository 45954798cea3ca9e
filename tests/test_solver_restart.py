"""Restart: a run interrupted after a converged increment and resumed reaches the same result,
increment by increment, as an uninterrupted run."""
from pathlib import Path

import numpy as np
import pytest

from lagamine_py.model import Boundary, CLoad, Step
from lagamine_py.solver import restart_deck, run
from lagamine_py.solver.restart import FILE

from test_solver_fakes import GROUND, Failing, PlasticSprings, Recorder, Springs, make_model, make_problem


def model():
    steps = [
        Step("LOAD", dt0=0.2, dt_max=0.5, controls={"GROWTH": 1.7},
             boundaries=[Boundary("N1", np.array([1]), 1, 1, 0.5)],
             cloads=[CLoad("N0", np.array([0]), 2, 3.0)]),
        Step("UNLOAD", dt0=0.3, dt_max=1.0, period=1.5,
             boundaries=[Boundary("N1", np.array([1]), 1, 1, -0.2)]),
    ]
    return make_model(3, steps)


def groups():
    """Plastic springs (history) on the x chain, cubic springs on y, and a group refusing
    increments longer than 0.4 (cut-backs: dt itself must be restored)."""
    plastic = PlasticSprings([[GROUND, 0], [0, 2], [2, 4], [GROUND, 4]], [10.0, 8.0, 6.0, 1.0],
                             fy=0.5, H=2.0)
    picky = Failing(plastic, lambda ctx, u: "too long" if ctx.t_new - ctx.t_old > 0.4 + 1e-12 else None)
    return [picky, Springs([[GROUND, 1], [1, 3], [GROUND, 5], [3, 5]], [2.0, 1.0, 1.0, 3.0], a=1.5)]


def go(outdir, writer, restart=False):
    m = model()
    return run(m, outdir, writers=[writer], restart=restart, problem=make_problem(m, groups()),
               deck_path="some/deck.dat")


def signature(results):
    return [(r.step, r.increment, r.time, r.dt) for r in results]


@pytest.mark.parametrize("stop_at, exc", [((1, 2), KeyboardInterrupt), ((1, 4), SystemExit),
                                          ((2, 1), KeyboardInterrupt)])
def test_restart_reaches_the_uninterrupted_result(tmp_path, stop_at, exc):
    full = Recorder()
    assert go(tmp_path / "full", full).status == 0
    assert any(r.cutbacks for r in full.results)           # the scenario does cut back
    n_step1 = sum(r.step == 1 for r in full.results)
    if stop_at == (1, 4):
        stop_at = (1, n_step1)                               # interrupt at the end of step 1

    class Stopper(Recorder):
        def increment(self, result):
            super().increment(result)
            if (result.step, result.increment) == stop_at:
                raise exc

    first = Stopper()
    if exc is KeyboardInterrupt:        # Ctrl-C: a clean stop, exit status 130, how to resume
        outcome = go(tmp_path / "cut", first)
        assert outcome.status == first.closed[0] == 130
        assert f"lagamine-py run --restart {tmp_path / 'cut'}" in outcome.message
    else:                               # anything else propagates, the writers closed with 1
        with pytest.raises(exc):
            go(tmp_path / "cut", first)
        assert first.closed[0] == 1
    # recorded absolute: a restart from another directory finds the same deck
    assert restart_deck(tmp_path / "cut") == Path("some/deck.dat").resolve()
    second = Recorder()
    out = go(tmp_path / "cut", second, restart=True)
    assert out.status == 0
    assert signature(first.results) == signature(full.results[:len(first.results)])
    # the restart point is saved after the writers took the increment: the increment whose
    # hand-out was interrupted is computed again
    k = len(first.results) - 1
    assert len(second.results) == len(full.results) - k
    assert np.allclose(np.array(signature(second.results)), np.array(signature(full.results[k:])),
                       rtol=1e-14, atol=0)
    for a, b in zip(second.results, full.results[k:]):
        assert np.abs(a.u - b.u).max() <= 1e-12 * np.abs(b.u).max()
        assert np.abs(a.reaction - b.reaction).max() <= 1e-12 * max(np.abs(b.reaction).max(), 1.0)


def test_no_restart_data(tmp_path):
    assert restart_deck(tmp_path) is None
    assert not (tmp_path / FILE).exists()


def test_cli_restart_of_a_deck_rewrites_nothing_twice(tmp_path):
    """Whole program: press_slide.dat interrupted in its second step, resumed with
    ``lagamine-py run --restart OUT``: the tables equal those of an uninterrupted run."""
    from pathlib import Path

    from lagamine_py.cli import main
    from lagamine_py.deck import load_deck
    from lagamine_py.output import default_writers
    from lagamine_py.results import read_table

    deck = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"
    full, cut = tmp_path / "full", tmp_path / "cut"
    assert main(["run", str(deck), "-o", str(full), "-q"]) == 0

    class Stop(Recorder):
        def increment(self, result):
            if (result.step, result.increment) == (2, 3):
                raise KeyboardInterrupt

    model = load_deck(deck)
    assert run(model, cut, writers=default_writers(cut, model) + [Stop()],
               deck_path=deck).status == 130
    assert main(["run", "--restart", str(cut), "-q"]) == 0
    for name in ("contact.csv", "reactions.csv", "displacements.csv", "contact_totals.csv"):
        a, b = read_table(full / name), read_table(cut / name)
        assert a.keys() == b.keys()
        for col in a:
            assert len(a[col]) == len(b[col]), (name, col)
            if a[col].dtype == object:
                assert list(a[col]) == list(b[col]), (name, col)
            else:
                np.testing.assert_allclose(b[col], a[col], rtol=1e-10, atol=1e-12, err_msg=f"{name}:{col}")


def test_ctrl_c_through_the_command_line(tmp_path, monkeypatch, capsys):
    """Ctrl-C during `lagamine-py run`: exit status 130, the files closed, and the message says
    how to go on; `--restart` then finishes the run."""
    from pathlib import Path

    from lagamine_py.cli import main
    from lagamine_py.solver import steps

    deck = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"
    out = tmp_path / "out"
    real = steps.Controller._save_restart
    calls = []

    def interrupt_at_the_fourth(self, *a, **k):
        real(self, *a, **k)
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
    monkeypatch.setattr(steps.Controller, "_save_restart", interrupt_at_the_fourth)
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 130
    err = capsys.readouterr().err
    assert f"lagamine-py run --restart {out}" in err and "results in" in err
    assert "exit status 130" in (out / "coulomb_block.log").read_text().splitlines()[-1]
    monkeypatch.setattr(steps.Controller, "_save_restart", real)
    assert main(["run", "--restart", str(out), "-q"]) == 0


def test_sigterm_stops_a_run_as_ctrl_c_does(tmp_path, monkeypatch, capsys):
    """``kill`` (SIGTERM, as a batch system or an interrupted sweep sends) during
    `lagamine-py run`: exit status 130, the files closed, the restart hint; before, the process
    died at once, mid-write, with its lock and log unfinished."""
    import os
    import signal
    from pathlib import Path

    from lagamine_py.cli import main
    from lagamine_py.solver import steps

    deck = Path(__file__).resolve().parents[1] / "decks" / "coulomb_block.dat"
    out = tmp_path / "out"
    real = steps.Controller._save_restart
    calls = []

    def terminate_at_the_third(self, *a, **k):
        real(self, *a, **k)
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGTERM)
    monkeypatch.setattr(steps.Controller, "_save_restart", terminate_at_the_third)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["run", str(deck), "-o", str(out), "-q"]) == 130
    assert signal.getsignal(signal.SIGTERM) is before          # the handler is given back
    assert f"lagamine-py run --restart {out}" in capsys.readouterr().err
    assert "exit status 130" in (out / "coulomb_block.log").read_text().splitlines()[-1]
    monkeypatch.setattr(steps.Controller, "_save_restart", real)
    assert main(["run", "--restart", str(out), "-q"]) == 0


@pytest.mark.parametrize("in_memory_bytes", [0, 2**40])
def test_save_on_file_and_in_memory_load_the_same(tmp_path, monkeypatch, in_memory_bytes):
    """Small restart data is assembled in memory and written at once, large data streamed
    to the file: the same .npz either way (every array, dtype and shape back), and the
    previous file replaced."""
    from lagamine_py.solver import restart
    monkeypatch.setattr(restart, "IN_MEMORY_BYTES", in_memory_bytes)
    rng = np.random.default_rng(1)
    data = {"deck": np.array("/x/deck.dat"), "step": np.int64(3), "u": rng.standard_normal(7),
            "state0:stress": rng.standard_normal((2, 9, 4)), "flags": np.array([1, 0], np.int8)}
    (tmp_path / FILE).write_bytes(b"an older file")
    restart.save(tmp_path, data)
    back = restart.load(tmp_path)
    assert sorted(back) == sorted(data) and not (tmp_path / "restart.tmp.npz").exists()
    for k, v in data.items():
        v = np.asarray(v)
        assert back[k].dtype == v.dtype and back[k].shape == v.shape and np.array_equal(back[k], v)
