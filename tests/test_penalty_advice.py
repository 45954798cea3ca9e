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
