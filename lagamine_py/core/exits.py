"""Exit statuses of ``lagamine-py`` (DECKS.md, "Exit status"), and SIGTERM as an interruption."""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["EXIT_OK", "EXIT_OTHER", "EXIT_DECK", "EXIT_DIVERGED", "EXIT_INTERRUPTED",
           "sigterm_interrupts"]

EXIT_OK = 0            # every step finished
EXIT_OTHER = 1         # anything else (a setup error, a failed comparison ...)
EXIT_DECK = 2          # a deck error: nothing ran
EXIT_DIVERGED = 3      # a step could not converge; what converged is written
EXIT_INTERRUPTED = 130  # interrupted (Ctrl-C)


@contextmanager
def sigterm_interrupts():
    """Within the block, SIGTERM raises KeyboardInterrupt in the main thread, as Ctrl-C does:
    a run or a sweep stopped by ``kill`` (a batch system, a sweep stopping its runs) closes its
    files and says how to go on, instead of dying mid-write.  Does nothing outside the main
    thread (signals cannot be handled there)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt
    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
