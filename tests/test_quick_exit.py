"""cli._quick_exit: ``run`` and ``check`` as the process's command end it by ``os._exit``
after the atexit handlers and a flush of the standard streams, without the interpreter's
teardown (docs/performance.md, "Start-up, first run, memory"); in-process calls return.

The teardown is seen by an object whose ``__del__`` prints when the interpreter deletes the
globals of ``__main__``: it prints after a normal exit and not after the quick one.
"""
import os
import subprocess
import sys
from pathlib import Path

from lagamine_py.cli import QUICK_EXIT, main
from lagamine_py.core.exits import EXIT_DECK, EXIT_OK

ROOT = Path(__file__).resolve().parents[1]
DECK = ROOT / "decks" / "coulomb_block.dat"

_SCRIPT = """
import atexit, sys, threading, time
class Witness:
    def __del__(self):
        print("teardown", flush=True)
witness = Witness()
atexit.register(print, "atexit ran")
done = threading.Event()
if sys.argv[1] == "thread":                 # a non-daemon thread still running at the end
    threading.Thread(target=done.wait, args=(60,)).start()
sys.argv = ["lagamine-py"] + sys.argv[2:]
from lagamine_py.cli import main
print("before", flush=True)
sys.stdout.write("unflushed, ")             # left in the buffer for the exit to flush
status = main()
done.set()
sys.exit(status)
"""


def _run(tmp_path, *argv, thread=False):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}   # buffered streams
    return subprocess.run([sys.executable, "-c", _SCRIPT, "thread" if thread else "-", *map(str, argv)],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300, env=env)


def test_run_ends_by_the_quick_exit_with_atexit_and_streams(tmp_path):
    out = tmp_path / "out"
    res = _run(tmp_path, "run", DECK, "-q", "-o", out)
    assert res.returncode == EXIT_OK, res.stderr
    assert "unflushed, " in res.stdout and "atexit ran" in res.stdout
    assert "teardown" not in res.stdout                 # no interpreter teardown
    log = next(out.glob("*.log")).read_text()
    assert "run finished" in log and log.endswith("\n")    # the log handler closed
    assert not list(out.glob(".lagamine-retired-*"))


def test_check_passes_its_status_through_the_quick_exit(tmp_path):
    bad = tmp_path / "bad.dat"
    bad.write_text(DECK.read_text().replace("*STEP", "*STEPP", 1))
    res = _run(tmp_path, "check", bad)
    assert res.returncode == EXIT_DECK
    assert "teardown" not in res.stdout and "atexit ran" in res.stdout
    res = _run(tmp_path, "check", DECK)
    assert res.returncode == EXIT_OK and "teardown" not in res.stdout


def test_a_running_thread_keeps_the_interpreters_exit(tmp_path):
    res = _run(tmp_path, "check", DECK, thread=True)
    assert res.returncode == EXIT_OK
    assert "teardown" in res.stdout and "atexit ran" in res.stdout


def test_other_commands_and_in_process_calls_return(tmp_path):
    # the witness prints on the way out of the interpreter's own exit
    res = _run(tmp_path, "plugins")
    assert res.returncode == EXIT_OK and "teardown" in res.stdout
    assert "plugins" not in QUICK_EXIT
    # in-process, with an explicit command line: main returns its status
    assert main(["check", str(DECK)]) == EXIT_OK
