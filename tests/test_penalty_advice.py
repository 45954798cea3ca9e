"""A penalty far from 20-100 E/h is reported (stderr and the run's log), never silently used."""
from lagamine_py.cli import main
from lagamine_py.solver.problem import PENALTY_RANGE

from runner import DECKS


def test_stiff_tangential_penalty_is_reported(tmp_path, capsys):
    # stick_slip.dat provokes chatter on purpose with KT = 1e8, about 1200 E/h
    assert main(["run", str(DECKS / "stick_slip.dat"), "-o", str(tmp_path / "out"), "-q"]) == 0
    err = capsys.readouterr().err
    assert "KT = 1e+08 is" in err and "E/h" in err and "oscillate" in err
    assert "KT = 1e+08 is" in (tmp_path / "out" / "stick_slip.log").read_text()
    assert "KP = " not in err                          # KP of that deck is within the range


def test_advised_penalty_gives_no_warning(tmp_path, capsys):
    assert PENALTY_RANGE[0] < 20 and PENALTY_RANGE[1] > 100
    assert main(["run", str(DECKS / "flat_punch.dat"), "-o", str(tmp_path / "out"), "-q"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_advice_is_printed_once_per_run_in_one_process(tmp_path, capsys):
    """Runs through ``main`` in one process (a script, a test suite, the fuzzer) each print
    their advice once; the stderr handler of an earlier run does not linger (it printed the
    advice twice, then a "Logging error" traceback once its stream was closed)."""
    deck = tmp_path / "stiff.dat"
    deck.write_text((DECKS / "coulomb_block.dat").read_text().replace("KT=2e6", "KT=1e9"))
    for k in range(2):
        assert main(["run", str(deck), "-o", str(tmp_path / f"out{k}"), "-q"]) == 0
        err = capsys.readouterr().err
        assert err.count("KT = 1e+09 is") == 1 and "Logging error" not in err
