"""Exit statuses of ``lagamine-py`` (DECKS.md, "Exit status")."""
from __future__ import annotations

__all__ = ["EXIT_OK", "EXIT_OTHER", "EXIT_DECK", "EXIT_DIVERGED", "EXIT_INTERRUPTED"]

EXIT_OK = 0            # every step finished
EXIT_OTHER = 1         # anything else (a setup error, a failed comparison ...)
EXIT_DECK = 2          # a deck error: nothing ran
EXIT_DIVERGED = 3      # a step could not converge; what converged is written
EXIT_INTERRUPTED = 130  # interrupted (Ctrl-C)
