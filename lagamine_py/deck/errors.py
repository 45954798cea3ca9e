"""Deck errors: every problem of a deck is collected, then raised at once as one :class:`DeckError`."""
from __future__ import annotations

from typing import NamedTuple


class DeckProblem(NamedTuple):
    """One problem of a deck: where it is (file, line, keyword) and what was expected."""
    file: str
    line: int
    keyword: str
    message: str

    def __str__(self) -> str:
        kw = f" *{self.keyword}:" if self.keyword else ""
        return f"{self.file}:{self.line}:{kw} {self.message}"


class DeckError(Exception):
    """A deck that cannot run.  ``problems`` is the list of ``(file, line, keyword, message)``
    items; ``str()`` gives one line per problem, ``file:line: *KEYWORD: message``;
    :meth:`report` at most ``limit`` of them, then how many more there are."""

    def __init__(self, problems):
        self.problems = [DeckProblem(*p) for p in problems]
        super().__init__("\n".join(str(p) for p in self.problems))

    @property
    def items(self) -> list[DeckProblem]:
        return self.problems

    def report(self, limit: int = 50) -> str:
        """The first ``limit`` problems, one a line, then a line counting the others."""
        lines = [str(p) for p in self.problems[:limit]]
        if len(self.problems) > limit:
            lines.append(f"... and {len(self.problems) - limit} more errors "
                         f"({len(self.problems)} in all; the first {limit} are shown)")
        return "\n".join(lines)

    def __reduce__(self):           # picklable (sweeps run decks in other processes)
        return (type(self), (self.problems,))


class Problems:
    """Collector of problems; :meth:`raise_if_any` stops with one DeckError holding them all.
    Past :attr:`EXPLAINED` problems, costly explanations may be skipped (a file of 100 000 bad
    lines is not read for 20 s to explain lines nobody reads)."""

    EXPLAINED = 1000

    def __init__(self):
        self.items: list[DeckProblem] = []
        self._seen: set[DeckProblem] = set()

    def add(self, file: str, line: int, keyword: str, message: str) -> None:
        """Add a problem; the same problem again (``KP=<X>, KT=<X>``: two fields of a line
        naming the same undefined parameter) is said once."""
        item = DeckProblem(str(file), int(line), keyword, message)
        if item not in self._seen:
            self._seen.add(item)
            self.items.append(item)

    def at(self, where, message: str, line: int | None = None) -> None:
        """Add a problem at a block (anything with ``file``, ``line``, ``keyword``)."""
        self.add(where.file, where.line if line is None else line, where.keyword, message)

    def __bool__(self) -> bool:
        return bool(self.items)

    def raise_if_any(self) -> None:
        if self.items:
            raise DeckError(self.items)
