"""The ``.dat`` deck language (see DECKS.md): text -> keyword blocks -> :class:`~lagamine_py.model.Model`.

``load_deck(path)`` parses, builds and validates a deck; every problem found is collected and
raised at once as one :class:`DeckError` (``file:line: *KEYWORD: message`` per problem), so
nothing runs on a bad deck.  ``parse_deck(path)`` stops after the first phase (blocks with
their file and line).  ``reference_markdown()`` writes the keyword reference from the table.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..model import DeckSource, Model
from .builder import build_model
from .errors import DeckError, DeckProblem, Problems
from .grammar import Block, DataRow, parse_deck_blocks
from .keywords import KEYWORDS, reference_markdown

__all__ = ["load_deck", "parse_deck", "deck_digest", "DeckError", "DeckProblem", "Block", "DataRow", "KEYWORDS",
           "reference_markdown"]


def parse_deck(path, parameters: dict[str, str] | None = None) -> list[Block]:
    """Keyword blocks of the deck at ``path`` (``*INCLUDE`` expanded, ``<name>`` substituted).

    ``parameters`` overrides values of the deck's ``*PARAMETER`` definitions (NAME -> text).
    Raises DeckError on text that cannot be read.
    """
    problems = Problems()
    blocks, _, _ = parse_deck_blocks(path, problems, parameters)
    problems.raise_if_any()
    return blocks


def deck_digest(path, parameters: dict[str, str] | None = None) -> str:
    """The digest of the deck's expanded text (every file read, the parameter values given,
    the mesh files of ``*IMPORT``): what :attr:`Model.source` records, without building the
    model (the deck may have errors)."""
    blocks, _, digest = parse_deck_blocks(path, Problems(), parameters)
    return _with_imports(digest, blocks)


def _with_imports(digest: str, blocks: list[Block]) -> str:
    """``digest`` extended by the bytes of the files ``*IMPORT`` reads (the builder reads them,
    not the reader); unchanged for a deck without ``*IMPORT``."""
    imports = [b for b in blocks if b.keyword == "IMPORT" and b.params.get("INPUT")]
    if not imports:
        return digest
    h = hashlib.sha256(digest.encode())
    for blk in imports:
        path = Path(blk.file).parent / str(blk.params["INPUT"])
        try:
            data = path.read_bytes() if path.is_file() else b""
        except OSError:
            data = b""
        h.update(b"\0IMPORT %d\0" % len(data) + data)
    return h.hexdigest()


def load_deck(path, parameters: dict[str, str] | None = None) -> Model:
    """Parse, build and validate the deck at ``path``; raise one DeckError listing every problem.

    ``parameters`` overrides ``*PARAMETER`` values (NAME -> text), as ``run --param`` and
    ``sweep`` do.  ``Model.name`` is the deck's file stem.
    """
    problems = Problems()
    blocks, _, digest = parse_deck_blocks(path, problems, parameters)
    if not blocks and not problems:
        problems.add(str(path), 1, "", "the deck has no keyword lines (an empty deck?)")
    with np.errstate(all="ignore"):     # huge values are reported as deck errors, not warnings
        model = build_model(Path(path).stem, blocks, problems)
    problems.raise_if_any()
    model.source = DeckSource(str(Path(path).resolve()), _with_imports(digest, blocks),
                              {str(k): str(v) for k, v in (parameters or {}).items()})
    return model
