"""The deck text -> keyword blocks, with (file, line) kept on every block and data line.

The whole text of a file is parsed by one line-aware pyparsing grammar (newline significant):
each line is a comment (``**``), a keyword line (``*NAME, PARAM=VALUE, FLAG``), a data line
(comma-separated numbers, names or ``KEY=VALUE`` pairs), free text after ``*HEADING``, or --
when it fits none of these -- a *bad line*, kept so that every error of the deck is reported
together (the reason is found by re-parsing that line alone with the strict grammar).

Lines of numbers only -- the bulk of a mesh: ``*NODE``, ``*ELEMENT``, set lists -- do not go
through the grammar one by one: each run of consecutive such lines is read at once with NumPy
into a :class:`NumberRows` (its values, the count per line and the number of its first line),
and falls back to the grammar when a line of it is not plain numbers.  A 1-million-line mesh
is read in seconds, with every line still known for messages.

Then :func:`parse_deck` walks the lines in order: ``*PARAMETER`` data lines define parameters,
``<name>`` in later lines is replaced by its value (as Abaqus does), ``*INCLUDE, INPUT=path``
is replaced by the lines of that file (path relative to the including file), and the lines are
grouped into :class:`Block` objects, one per keyword line.  Nothing is evaluated.
"""
from __future__ import annotations

import bisect
import hashlib
import os
import re
import stat
import threading
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyparsing as pp

from ..core.params import did_you_mean, parse_number
from ..model import Where
from .errors import Problems

_WHITE = " \t\r"   # newline is significant


# ---------------------------------------------------------------- tokens of data lines

class Num(float):
    """A number token; ``text`` is how the deck wrote it (``1.5D3``)."""
    text: str

    def __new__(cls, text: str):
        obj = super().__new__(cls, parse_number(text))
        obj.text = text
        return obj


class Name(str):
    """A name token (node set, surface, face ``S1``, load kind ``P`` ...), as written."""


@dataclass(frozen=True)
class Ref:
    """A field holding ``<name>`` parameter references, resolved by :func:`parse_deck`."""
    text: str


@dataclass(frozen=True)
class Pair:
    """``KEY=VALUE``: ``key`` upper-case, ``value`` a Num, Name or Ref."""
    key: str
    value: object

    @property
    def text(self) -> str:
        v = self.value
        return v.text if isinstance(v, (Num, Ref)) else str(v)


# ---------------------------------------------------------------- lines and blocks

@dataclass
class KeywordLine:
    line: int
    keyword: str                                  # upper case, single spaces: "CONTACT LAW"
    params: list[tuple[str, str | None]]          # (NAME upper, raw value or None for a flag)
    continued: bool = False                       # it ends with ',' (Abaqus would read on)


@dataclass
class DataLine:
    line: int
    items: list


@dataclass
class TextLine:
    line: int
    text: str


@dataclass
class BadLine:
    line: int
    text: str


@dataclass
class DataRow:
    """One data line of a block, with its own position (it may come from an included file)."""
    file: str
    line: int
    items: list


@dataclass
class NumberRows:
    """Consecutive data lines of numbers only, read in bulk: ``values`` (n,) float, ``counts``
    (k,) the number of values on each line, lines ``line``, ``line + 1`` ... of ``file`` (or
    ``lines`` (k,) when some were taken out); ``raw`` the lines' text (for messages), None when
    the values were changed after reading (an Abaqus part placed by an instance): the text is
    then written from the values."""
    file: str
    line: int
    counts: np.ndarray
    values: np.ndarray
    raw: list[str] | None
    lines: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.counts)

    def line_numbers(self) -> np.ndarray:
        """(k,) the line number of each row."""
        return self.line + np.arange(len(self.counts)) if self.lines is None else self.lines

    def starts(self) -> np.ndarray:
        """(k,) the index in ``values`` of the first value of each row."""
        return np.cumsum(self.counts) - self.counts

    def text(self, k: int) -> str:
        """The text of row ``k``."""
        if self.raw is not None:
            return self.raw[k]
        s = int(self.starts()[k])
        return ", ".join(f"{v:.17g}" for v in self.values[s:s + int(self.counts[k])])

    def texts(self) -> list[str]:
        return self.raw if self.raw is not None else [self.text(k) for k in range(len(self))]

    def with_values(self, values: np.ndarray) -> "NumberRows":
        """The same rows holding ``values`` (n,) instead (their text written from them)."""
        return NumberRows(self.file, self.line, self.counts, np.asarray(values, float), None,
                          self.lines)

    def table(self) -> np.ndarray | None:
        """The values as a (k, w) array when every line holds ``w`` values, else None."""
        if len(self.counts) and (self.counts == self.counts[0]).all():
            return self.values.reshape(len(self.counts), int(self.counts[0]))
        return None

    def rows(self) -> list[DataRow]:
        """The lines as :class:`DataRow` objects with :class:`Num` tokens (the slow path)."""
        return [DataRow(self.file, int(line), [Num(t.strip()) for t in text.rstrip(" \t\r,").split(",")])
                for line, text in zip(self.line_numbers(), self.texts())]


@dataclass
class Block:
    """A keyword line and the data lines that follow it."""
    keyword: str
    params: dict[str, str | None]
    file: str
    line: int
    data: list[DataRow | NumberRows] = field(default_factory=list)
    text: list[str] = field(default_factory=list)          # *HEADING free text
    broken: bool = False      # its keyword line could not be read (already reported)
    continued: bool = False   # its keyword line ends with ',' (parameters on the next line?)

    @property
    def where(self) -> Where:
        return Where(self.file, self.line, self.keyword)


# ---------------------------------------------------------------- the grammar

@contextmanager
def _newline_significant():
    """Build pyparsing elements that skip only blanks and tabs (restored afterwards)."""
    old = "".join(sorted(pp.ParserElement.DEFAULT_WHITE_CHARS))
    pp.ParserElement.set_default_whitespace_chars(_WHITE)
    try:
        yield
    finally:
        pp.ParserElement.set_default_whitespace_chars(old)


def _keyword_name(text: str) -> str:
    return " ".join(text.lstrip("*").split()).upper()


class _Grammar:
    """The pyparsing pieces; ``deck`` parses a whole file into a list of line objects."""

    def __init__(self):
        self._local = threading.local()          # line starts of the text being parsed, per thread
        with _newline_significant():
            self._build()

    def _build(self):
        nl = pp.Literal("\n").set_name("end of line").suppress()

        def eol(what):
            return pp.FollowedBy((pp.Literal("\n") | pp.StringEnd()).set_name(what))
        comma = pp.Suppress(",").set_name("','")

        num = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?"
        number = pp.Regex(num + r"(?![\w.<>])").set_name("number")
        number.set_parse_action(lambda t: Num(t[0]))
        name = pp.Regex(r"[A-Za-z_][\w.\-]*(?![<>])").set_name("name")
        name.set_parse_action(lambda t: Name(t[0]))
        ref = pp.Regex(r"[^,=\n<>]*(?:<[A-Za-z_]\w*>[^,=\n<>]*)+").set_name("<parameter>")
        ref.set_parse_action(lambda t: Ref(t[0].strip()))
        value = (ref | number | name).set_name("value")
        key = pp.Regex(r"[A-Za-z_]\w*").set_name("KEY")
        pair = (key + pp.Suppress("=") + value).set_name("KEY=VALUE")
        pair.set_parse_action(lambda t: Pair(t[0].upper(), t[1]))
        item = (pair | value).set_name("number, name or KEY=VALUE")
        self.item = item

        items = item + pp.ZeroOrMore(comma + item) + pp.Optional(comma)
        data_line = (items + eol("',' and a number, name or KEY=VALUE, or the end of the line")).set_name("data line")
        data_line.set_parse_action(self._data_line)
        # Fast path for the bulk of a mesh (nodes, elements): a line of numbers only, one Regex.
        numbers_line = pp.Regex(rf"{num}(?:[ \t]*,[ \t]*{num})*[ \t]*,?[ \t\r]*(?=\n|$)").set_name("numbers")
        numbers_line.set_parse_action(self._numbers_line)

        kw = pp.Regex(r"\*[ \t]*[A-Za-z][\w\-]*(?:[ \t]+[A-Za-z][\w\-]*)*").set_name("*KEYWORD")
        # a name may hold single spaces (Abaqus's REF NODE=): words until "=", "," or the end
        pname = pp.Regex(r"[A-Za-z_][\w\-]*(?:[ \t]+[A-Za-z_][\w\-]*)*").set_name("parameter name")
        # no "**" in a value: a comment after a keyword line's parameters is an error, not a name
        pvalue = (pp.QuotedString('"') | pp.Regex(r"(?:[^,=\n\"*]|\*(?!\*))*[^,=\s\"*]")
                  ).set_name("parameter value")
        param = pp.Group(pname + pp.Optional(pp.Suppress("=") + pvalue)).set_name("NAME=VALUE")
        kw_line = (kw + pp.ZeroOrMore(comma + param) + pp.Optional(comma)
                   + eol("', NAME=VALUE' or the end of the line")).set_name("keyword line")
        kw_line.set_parse_action(self._kw_line)

        comment = pp.Regex(r"\*\*[^\n]*").set_name("comment").suppress()
        heading = pp.Regex(r"\*[ \t]*HEADING[ \t\r]*(?=\n|$)", re.IGNORECASE).set_name("*HEADING")
        heading.set_parse_action(lambda s, loc, t: KeywordLine(self.lineno(loc), "HEADING", []))
        text = pp.Regex(r"[^*\s][^\n]*").set_name("text")
        text.set_parse_action(lambda s, loc, t: TextLine(self.lineno(loc), t[0].rstrip()))
        heading_section = heading + pp.ZeroOrMore(nl + pp.Optional(comment | text) + eol("end of line"))

        # a data line of one comma: no value given (Abaqus writes "," for a default, as the
        # thickness of a *SOLID SECTION)
        empty = pp.Regex(r",[ \t\r]*(?=\n|$)").set_name("empty data line")
        empty.set_parse_action(lambda s, loc, t: DataLine(self.lineno(loc), []))

        bad = pp.Regex(r"[^\n]+").set_name("line")
        bad.set_parse_action(lambda s, loc, t: BadLine(self.lineno(loc), t[0].rstrip()))

        # most frequent first: line ends, then lines of numbers (the mesh)
        line = (nl | numbers_line | comment | heading_section | kw_line | data_line | empty
                | bad).set_name("line")
        self.deck = (pp.ZeroOrMore(line) + pp.StringEnd()).set_name("deck")
        self.strict_kw = kw_line + pp.StringEnd()
        self.strict_data = data_line + pp.StringEnd()
        self.strict_item = item + pp.StringEnd()

    def lineno(self, loc: int) -> int:
        """Line number (1-based, in the file) of a position in the text being parsed."""
        return bisect.bisect_right(self._local.starts, loc) + 1 + self._local.offset

    def _numbers_line(self, s, loc, t):
        return DataLine(self.lineno(loc), [Num(v.strip()) for v in t[0].rstrip(" \t\r,").split(",")])

    def _data_line(self, s, loc, t):
        return DataLine(self.lineno(loc), list(t))

    def _kw_line(self, s, loc, t):
        params = [(" ".join(g[0].split()).upper(), g[1].strip() if len(g) > 1 else None)
                  for g in t[1:]]
        end = s.find("\n", loc)
        continued = s[loc:end if end >= 0 else len(s)].rstrip(" \t\r").endswith(",")
        return KeywordLine(self.lineno(loc), _keyword_name(t[0]), params, continued)

    def parse_text(self, text: str, offset: int = 0) -> list:
        """Line objects of a stretch of a file's text that starts after line ``offset``."""
        # positions in the text pyparsing parses: its parse_string expands the tabs first
        self._local.starts = [m.end() for m in re.finditer("\n", text.expandtabs())]
        self._local.offset = offset
        return list(self.deck.parse_string(text, parse_all=True))

    def why_bad(self, text: str) -> str:
        """The reason a line fits no form, from the strict grammar of what it looks like."""
        self._local.starts, self._local.offset = [], 0
        strict = self.strict_kw if text.lstrip().startswith("*") else self.strict_data
        what = "keyword line" if strict is self.strict_kw else "data line"
        try:
            strict.parse_string(text, parse_all=True)
        except pp.ParseBaseException as exc:
            found = text[exc.loc:exc.loc + 12]
            start = len(text) - len(text.lstrip()) + (what == "keyword line")
            if "**" in text[start:]:        # Abaqus has no end-of-line comments either
                return (f"cannot read this {what}: a comment ('**') must be a line of its own, "
                        f"found one at column {text.index('**', start) + 1}")
            empty = re.search(r",[ \t]*,", text)
            if empty and empty.start() <= exc.loc:
                return (f"cannot read this {what}: an empty field (',,') at column "
                        f"{empty.start() + 1}: a value is missing, or a ',' is one too many")
            return f"cannot read this {what}: {exc.msg[:1].lower() + exc.msg[1:]} at column {exc.col}" + \
                   (f" (found {found!r})" if found else "")
        return f"cannot read this {what}"

    def parse_item(self, text: str):
        """A single data field (after parameter substitution): Num, Name or Pair."""
        return self.strict_item.parse_string(text, parse_all=True)[0]


GRAMMAR = _Grammar()


# ---------------------------------------------------------------- parameters, includes, blocks

_REF = re.compile(r"<([A-Za-z_]\w*)>")
_LONE_CR = re.compile(r"\r(?!\n)")
_NUMERIC_START = frozenset("0123456789+-.")
_NUMERIC_CHARS = re.compile(r"[0-9\s,.+\-eEdD]*")
_HEADING = re.compile(r"[ \t]*\*[ \t]*HEADING[ \t\r]*", re.IGNORECASE)
BULK_MIN_LINES = 8       # shorter runs of number lines go through the grammar: nothing to gain


def _number_rows(lines: list[str], file: str, first: int) -> NumberRows | None:
    """``lines`` read at once as numbers (:class:`NumberRows`), or None when one of them is not
    plain comma-separated numbers (the grammar then reads and explains them)."""
    chunk = "\n".join(lines)
    if not _NUMERIC_CHARS.fullmatch(chunk):
        return None
    if "d" in chunk or "D" in chunk:
        chunk = chunk.replace("d", "e").replace("D", "e")
    try:
        values = np.array(chunk.replace(",", " ").split(), dtype=float)
    except ValueError:
        return None
    counts = np.fromiter((t.count(",") + 1 - t.rstrip(" \t\r").endswith(",") for t in lines),
                         np.int64, len(lines))
    if counts.sum() != values.size or (counts < 1).any():
        return None                       # an empty field (",,") or an empty line: the grammar says
    return NumberRows(file, first, counts, values, lines)


def _segments(text: str):
    """``(first line number, lines, bulk)`` runs of the text: ``bulk`` True for runs of at
    least :data:`BULK_MIN_LINES` lines that start like numbers (outside a ``*HEADING``)."""
    lines = text.split("\n")
    start, bulk, heading = 0, False, False
    for i, line in enumerate(lines):
        head = line.lstrip()[:1]
        if head == "*" and not line.lstrip().startswith("**"):    # a keyword line, not a comment
            heading = bool(_HEADING.fullmatch(line))
        numeric = head in _NUMERIC_START and head != "" and not heading
        if numeric != bulk:
            if i > start:
                yield start + 1, lines[start:i], bulk
            start, bulk = i, numeric
    if len(lines) > start:
        yield start + 1, lines[start:], bulk


MAX_INCLUDE_DEPTH = 64   # *INCLUDE levels (a chain deeper than this is a mistake, not a model)


def _unreadable(path: Path) -> str:
    """Why ``path`` cannot be read as a deck ("" when it can): missing, a directory, or not a
    regular file (a FIFO would block the reader, a device never end).  ``os.stat`` does not
    open the file."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "does not exist"
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    if stat.S_ISDIR(st.st_mode):
        return "is a directory, not a file"
    if not stat.S_ISREG(st.st_mode):
        return "is not a regular file (a FIFO, a socket or a device)"
    return ""


class _Reader:
    """Walks the lines of a deck and its includes in order, substituting parameters.

    ``digest`` hashes what was read, as read: every file's bytes in reading order, then the
    parameter values given from outside (:func:`parse_deck_blocks`) -- the identity of the
    expanded deck that restarts and sweeps compare."""

    def __init__(self, problems: Problems, overrides: dict[str, str] | None):
        self.problems = problems
        self.digest = hashlib.sha256()
        self.params: dict[str, str] = {}            # NAME -> value text
        self.overrides = {k.upper(): str(v) for k, v in (overrides or {}).items()}
        self.used_overrides: set[str] = set()
        self.lines: list[tuple[str, object]] = []   # (file, line object)
        self.keyword = ""                            # keyword whose data lines are being read

    def substitute(self, text: str, file: str, line: int, keyword: str, strict=True) -> str | None:
        """``text`` with ``<name>`` replaced; None (and a problem) if a name is undefined."""
        bad = []

        def repl(m):
            key = m.group(1).upper()
            if key in self.params:
                return self.params[key]
            bad.append(key)
            return m.group(0)

        out = _REF.sub(repl, text)
        if bad and strict:
            for key in bad:
                self.problems.add(file, line, keyword,
                                  f"parameter <{key}> is not defined by an earlier *PARAMETER"
                                  f"{did_you_mean(key, self.params)}")
            return None
        return out

    def read(self, path: Path, label: str, stack: tuple[Path, ...]) -> None:
        why = _unreadable(path)
        if why:
            self.problems.add(label, 0, "", f"cannot read the deck: {label} {why}")
            return
        try:
            raw = path.read_bytes()
        except OSError as exc:
            self.problems.add(label, 0, "", f"cannot read the deck: {exc.strerror or exc}")
            return
        self.digest.update(b"%d\0" % len(raw) + raw)
        text = raw.decode("utf-8-sig", errors="replace")      # a UTF-8 BOM is no text
        if "\r" in text:       # a CR alone ends a line too (old Mac OS files; CRLF stays CRLF)
            text = _LONE_CR.sub("\n", text)
        for first, lines, bulk in _segments(text):
            rows = _number_rows(lines, label, first) if bulk and len(lines) >= BULK_MIN_LINES else None
            if rows is not None:
                self.lines.append((label, rows))
                continue
            try:
                objs = GRAMMAR.parse_text("\n".join(lines), first - 1)
            except pp.ParseBaseException as exc:     # the grammar accepts any text; a guard
                self.problems.add(label, first - 1 + exc.lineno, "", f"cannot read the deck: {exc.msg}")
                return
            self._lines(objs, path, label, stack)

    def _lines(self, objs, path: Path, label: str, stack) -> None:
        """Take the line objects of one stretch of a file, in order."""
        for obj in objs:
            keyword = self.keyword
            if isinstance(obj, KeywordLine):
                if obj.keyword != "INCLUDE":    # after an include, data goes on with its last keyword
                    self.keyword = obj.keyword
                if not self._keyword(obj, path, label, stack):
                    continue
            elif isinstance(obj, DataLine):
                resolved = self._data(obj, label, keyword)
                if resolved is None:
                    if not keyword:     # before any keyword: that is said too (by _group)
                        self.lines.append((label, DataLine(obj.line, [])))
                    continue
                obj = resolved
                if keyword == "PARAMETER":
                    self._define(obj, label)
            elif isinstance(obj, BadLine):
                self.keyword = _bad_keyword(obj.text) or keyword
            elif isinstance(obj, TextLine):
                obj = TextLine(obj.line, self.substitute(obj.text, label, obj.line, keyword, strict=False))
            self.lines.append((label, obj))

    def _keyword(self, kl: KeywordLine, path: Path, label: str, stack) -> bool:
        """Substitute in parameter values; expand *INCLUDE.  False if the line is consumed."""
        params = []
        for name, value in kl.params:
            if value is not None and "<" in value:
                value = self.substitute(value, label, kl.line, kl.keyword)
                if value is None:
                    value = ""
            params.append((name, value))
        kl.params = params
        if kl.keyword != "INCLUDE":
            return True
        given = dict(params)
        unknown = [n for n in given if n != "INPUT"]
        for n in unknown:
            self.problems.add(label, kl.line, "INCLUDE", f"unknown parameter {n}{did_you_mean(n, ['INPUT'])}; "
                                                       f"expected INPUT")
        rel = given.get("INPUT")
        if not rel:
            if "INPUT" in given or not unknown:
                self.problems.add(label, kl.line, "INCLUDE", "missing required parameter INPUT=path")
            return False
        target = (path.parent / rel)
        shown = str(Path(label).parent / rel)
        why = _unreadable(target)
        if why:
            self.problems.add(label, kl.line, "INCLUDE", f"included file {shown} {why}")
            return False
        other = _not_deck_text(target)
        if other:
            self.problems.add(label, kl.line, "INCLUDE", f"{shown} {other}")
            return False
        if any(target.resolve() == p for p in stack):
            self.problems.add(label, kl.line, "INCLUDE",
                              f"{shown} includes itself (directly or through other *INCLUDE)")
            return False
        if len(stack) > MAX_INCLUDE_DEPTH:
            self.problems.add(label, kl.line, "INCLUDE",
                              f"*INCLUDE nested more than {MAX_INCLUDE_DEPTH} files deep: a chain "
                              f"this long is a mistake (files including copies of each other?)")
            return False
        self.read(target, shown, stack + (target.resolve(),))
        return False

    def _data(self, dl: DataLine, label: str, keyword: str):
        """Resolve Ref fields and Pair values to typed tokens; None if one cannot be."""
        if all(type(it) is Num for it in dl.items):
            return dl
        items, ok = [], True
        for it in dl.items:
            if isinstance(it, Pair) and isinstance(it.value, Ref):
                v = self._resolve(it.value, label, dl.line, keyword, value_only=True)
                ok &= v is not None
                items.append(Pair(it.key, v))
            elif isinstance(it, Ref):
                v = self._resolve(it, label, dl.line, keyword)
                ok &= v is not None
                items.append(v)
            else:
                items.append(it)
        return DataLine(dl.line, items) if ok else None

    def _resolve(self, ref: Ref, label, line, keyword, value_only=False):
        text = self.substitute(ref.text, label, line, keyword)
        if text is None:
            return None
        try:
            tok = GRAMMAR.parse_item(text)
        except pp.ParseBaseException:
            tok = None
        if tok is None or (value_only and isinstance(tok, Pair)):
            self.problems.add(label, line, keyword, f"{ref.text} gives {text!r}, which is not a "
                                                    f"number{'' if value_only else ', a name or KEY=VALUE'}")
            return None
        return tok

    def _define(self, dl: DataLine, label: str) -> None:
        for it in dl.items:
            if not isinstance(it, Pair):
                continue    # reported by the builder (the keyword table wants NAME = value)
            if it.key in self.overrides:
                self.used_overrides.add(it.key)
                self.params[it.key] = self.overrides[it.key]
            else:
                self.params[it.key] = it.text


def _not_deck_text(path: Path) -> str | None:
    """Why the file at ``path`` is not deck text for *INCLUDE (a gmsh mesh, a binary file), or
    None."""
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if path.suffix.lower() == ".msh" or head.lstrip().startswith(b"$MeshFormat"):
        return (f"is a gmsh mesh, not deck text: read it with *IMPORT, INPUT={path.name} "
                f"(nodes, elements and physical groups)")
    if b"\0" in head:
        return "is not a text file (it holds binary data): *INCLUDE reads deck text"
    return None


def _bad_keyword(text: str) -> str | None:
    """The keyword of an unreadable keyword line (None for a data line): the words before the
    first comma, less a parameter name glued to it (``*SOLID ELSET=E`` -> ``SOLID``)."""
    m = re.match(r"\s*\*([^,]*)", text)
    if m is None:
        return None
    words = m.group(1).split("=")[0].split()
    if "=" in m.group(1) and len(words) > 1:
        words = words[:-1]
    return " ".join(words).upper() or "?"


def _group(lines, problems: Problems) -> list[Block]:
    """Group line objects into blocks; data before any keyword is an error."""
    blocks: list[Block] = []
    for file, obj in lines:
        if isinstance(obj, KeywordLine):
            params = {}
            for name, value in obj.params:
                if name in params:
                    problems.add(file, obj.line, obj.keyword, f"parameter {name} is given twice")
                params[name] = value
            blocks.append(Block(obj.keyword, params, file, obj.line, continued=obj.continued))
        elif isinstance(obj, BadLine):
            kw = _bad_keyword(obj.text)
            # past a few screens of messages nobody reads the reasons: skip the re-parse
            why = (GRAMMAR.why_bad(obj.text) if len(problems.items) < problems.EXPLAINED else
                   f"cannot read this {'data' if kw is None else 'keyword'} line")
            if kw is None:
                problems.add(file, obj.line, blocks[-1].keyword if blocks else "", why)
            else:   # its data lines go with it, unread: one message for the keyword line
                problems.add(file, obj.line, kw, why)
                blocks.append(Block(kw, {}, file, obj.line, broken=True))
        elif not blocks:
            problems.add(file, obj.line, "", "data line outside any keyword: a data line must follow "
                                             "a keyword line such as *NODE")
        elif isinstance(obj, NumberRows):
            blocks[-1].data.append(obj)
        elif isinstance(obj, TextLine):
            blk = blocks[-1]
            if blk.keyword == "HEADING":
                blk.text.append(obj.text)
        else:
            blocks[-1].data.append(DataRow(file, obj.line, obj.items))
    return blocks


def parse_deck_blocks(path, problems: Problems, parameters: dict[str, str] | None = None):
    """Blocks of the deck at ``path`` (includes expanded, parameters substituted), the
    parameter values (NAME -> text) and the digest of the expanded deck (SHA-256 hex of every
    file read and of the parameter values given: see :class:`_Reader`).  Problems go to
    ``problems``."""
    path = Path(path)
    reader = _Reader(problems, parameters)
    reader.read(path, str(path), (path.resolve(),))
    for key in sorted(set(reader.overrides) - reader.used_overrides):
        problems.add(str(path), 1, "PARAMETER", f"parameter {key} given to override is not defined by a "
                                                f"*PARAMETER of the deck{did_you_mean(key, reader.params)}")
    for key in sorted(reader.overrides):
        reader.digest.update(f"\0{key}={reader.overrides[key]}".encode(errors="surrogatepass"))
    return _group(reader.lines, problems), dict(reader.params), reader.digest.hexdigest()
