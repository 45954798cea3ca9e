"""Fuzz ``lagamine-py run``: mutated example decks, run a few increments, judged.

    python tools/fuzz_run.py [--examples N] [--seed S] [--increments K] [--keep DIR]

Each example takes an example deck of ``decks/``, applies 1-4 random mutations (a number
replaced by an edge value -- 0, a negative, a huge or a tiny one, its tenth or tenfold --, a
line dropped, duplicated or swapped with another, a keyword line's parameter value changed; a
``*CONTROLS`` line put into a step, its key one of ``model.CONTROL_PARAMS`` and its value
out of range, of the wrong type, empty, a bad word or given twice; a change of the text's form:
CRLF or CR line ends, a BOM, tabs, a trailing comma, a comment after data, a keyword line split
over two lines) and runs ``lagamine-py check`` on it, then ``lagamine-py run`` in this process
(``lagamine_py.cli.main``) with every step capped at K increments (``INC``), into a fresh
directory.  A run is *bad* when

* ``main`` raises (a traceback), or its exit status is not 0, 2 or 3 -- 1 only for a setup
  error of the step (``*CONTROLS`` asking for a solver that is not installed);
* its stderr holds a traceback or "an unexpected error", or a NumPy warning (RuntimeWarning) is
  issued;
* an output table or a VTK array holds NaN (or inf);
* ``check`` and ``run`` disagree: ``check`` accepts a deck that ``run`` refuses at setup (exit 2,
  or 1 for a step that cannot start), or refuses one that ``run`` runs;
* the mutations only changed the text's form (line ends, BOM, tabs, spaces, case: NEUTRAL) and
  ``check``'s summary or the run's exit status differ from those of the deck as written.

The counts per outcome are printed; every bad deck is written to ``--keep`` (default
``/tmp/lagamine_fuzz_run``) with what went wrong.  ``tests/test_run_fuzz.py`` runs the same
judge on a few derandomised examples under hypothesis.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import random
import re
import shutil
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"
#: the example decks fuzzed (the small ones: a run of a few increments takes ~0.1-0.5 s)
FUZZED = ("coulomb_block.dat", "flat_punch.dat", "stick_slip.dat", "compression_ro.dat",
          "axisym_press_friction.dat", "tube_limit.dat", "hertz.dat",
          # the keywords added since: tools with a REF NODE, *FOUNDATION MOTION, CIRCLE=,
          # *CHANGE CONTACT LAW, *CONTACT STABILIZATION, MASTER=, *AMPLITUDE, *OUTPUT ...
          "press_slide.dat", "upsetting.dat", "tube_crimp.dat", "tube_joint.dat", "rolling.dat",
          "ring.dat", "hertz_two_body.dat", "tests/data/tools/two_tools.dat",
          "tests/data/tools/roll_turn.dat", "tests/data/tools/hertz_force.dat",
          "tests/data/tools/change_law.dat", "tests/data/decks_md/walk_tools.dat",
          "tests/data/decks_md/walk_two_body.dat")
#: files the fuzzed decks include, linked beside the mutated decks
INCLUDED = (DECKS / "meshes", ROOT / "tests/data/decks_md/walk_mesh.inc")
#: form-only changes of a deck's text: its meaning stays (the judge compares outcomes)
NEUTRAL = ("crlf", "cr", "bom", "tabs", "blanks", "lower")
#: form changes that may make a deck unreadable (then refused with a message) or keep it
FORMS = NEUTRAL + ("trailing", "inline", "split", "indent")
CONTROL_BAD = ("0", "-1", "1e30", "-1e30", "2.5", "", "X", "CUBIC", "YES", "NO", "1e-30", "nan",
               "inf", "1001", "2147483648", "<UNDEFINED>", "0x10", "1,", "AUTO")
EDGE_VALUES = ("0", "-1", "1e30", "1e-30", "-0.5", "2", "1e-300", "0.5", "1e300", "-1e300")
_NUMBER = re.compile(r"(?<![\w.<])[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?(?![\w.>])")
ALLOWED = (0, 2, 3)
KINDS = ("number", "number", "number", "drop", "dup", "swap", "param", "control", "control",
         "form", "form")


@dataclass
class Verdict:
    status: int | None
    problems: list[str] = field(default_factory=list)
    stderr: str = ""
    check: int | None = None          # exit status of ``lagamine-py check``
    summary: str = ""                 # what ``check`` printed (its OK line or its messages)
    sta: str = ""                     # the run's .sta table (the increments, as run)

    @property
    def bad(self) -> bool:
        return bool(self.problems)


# ---------------------------------------------------------------- mutations

def mutate(text: str, ops: list[tuple]) -> str:
    """``text`` with the mutations ``ops`` applied in order; each op is ``(kind, a, b, c)``
    with integers ``a, b, c`` choosing where and what (any size: taken modulo)."""
    lines = text.splitlines()
    for kind, a, b, c in ops:
        if not lines:
            break
        k = a % len(lines)
        if kind == "number":
            hits = list(_NUMBER.finditer(lines[k]))
            if not hits or lines[k].lstrip().startswith("**"):
                continue
            m = hits[b % len(hits)]
            old = m.group(0)
            choices = EDGE_VALUES + (_scaled(old, 0.1), _scaled(old, 10.0), "-" + old.lstrip("+-"))
            lines[k] = lines[k][:m.start()] + choices[c % len(choices)] + lines[k][m.end():]
        elif kind == "drop":
            del lines[k]
        elif kind == "dup":
            lines.insert(k, lines[k])
        elif kind == "swap":
            j = b % len(lines)
            lines[k], lines[j] = lines[j], lines[k]
        elif kind == "control":
            lines = _with_control(lines, a, b, c)
        elif kind == "form":
            lines = _form(lines, FORMS[b % len(FORMS)], a, c)
        elif kind == "param":
            m = list(re.finditer(r"=\s*([^,\s]+)", lines[k]))
            if lines[k].startswith("*") and m:
                g = m[b % len(m)]
                new = ("0", "-1", "2", "YES", "NO", "X", "1e9")[c % 7]
                lines[k] = lines[k][:g.start(1)] + new + lines[k][g.end(1):]
    text = "\n".join(lines) + "\n"
    for kind, a, b, c in ops:              # whole-text forms go last: line ops see plain lines
        if kind == "form" and FORMS[b % len(FORMS)] in ("crlf", "cr", "bom"):
            text = {"crlf": lambda t: t.replace("\n", "\r\n"), "cr": lambda t: t.replace("\n", "\r"),
                    "bom": lambda t: "\ufeff" + t.lstrip("\ufeff")}[FORMS[b % len(FORMS)]](text)
    return text


def control_params():
    """The ``*CONTROLS`` keys and their declarations (new keys are fuzzed as they come)."""
    from lagamine_py.model import CONTROL_PARAMS
    return CONTROL_PARAMS


def _control_values(param) -> tuple[str, ...]:
    """Values to give ``param``: its bounds and one past each, its choices, and bad ones."""
    out = list(CONTROL_BAD)
    low, high = param.bounds
    for v in (low, high):
        if v is not None:
            out += [repr(v), repr(v - 1 if param.type is int else v * 0.5 - 1e-3),
                    repr(v + 1 if param.type is int else v * 2 + 1e-3)]
    out += [str(c) for c in param.allowed()]
    return tuple(out)


def _with_control(lines: list[str], a: int, b: int, c: int) -> list[str]:
    """A ``*CONTROLS`` line ``KEY=VALUE`` (or ``KEY=VALUE, KEY=VALUE``: given twice) after the
    ``a``-th ``*STEP`` line (or in its ``*CONTROLS`` when it has one)."""
    steps = [k for k, line in enumerate(lines) if re.match(r"\s*\*\s*STEP\b", line, re.I)]
    if not steps:
        return lines
    params = control_params()
    param = params[b % len(params)]
    values = _control_values(param)
    value = values[c % len(values)]
    key = param.name if c % 3 else param.name.lower()
    entry = f"{key}={value}"
    if (c // len(values)) % 4 == 1:
        entry += f", {key}={values[(c // 7) % len(values)]}"      # given twice
    k = steps[a % len(steps)]
    if k + 1 < len(lines) and re.match(r"\s*\*\s*CONTROLS\b", lines[k + 1], re.I):
        return lines[:k + 2] + [entry] + lines[k + 2:]
    return lines[:k + 1] + ["*CONTROLS", entry] + lines[k + 1:]


def _form(lines: list[str], form: str, a: int, c: int) -> list[str]:
    """``lines`` with the form change ``form`` (line ends and the BOM are done on the text)."""
    lines = list(lines)
    k = a % len(lines)
    line = lines[k]
    keyword = line.lstrip().startswith("*") and not line.lstrip().startswith("**")
    comment = line.lstrip().startswith("**")
    if form == "tabs":          # a tab after every comma, or around '='
        lines[k] = line.replace(", ", ",\t") if c % 2 else line.replace("=", "\t=\t")
    elif form == "blanks":      # blanks around separators and at the end
        lines[k] = re.sub(r"\s*,\s*", " , ", line) + "  " if not comment else line
    elif form == "lower" and not comment:      # keywords, parameter and set names
        lines[k] = _lower(lines, k)
    elif form == "trailing" and not comment and line.strip():
        lines[k] = line + ("," if c % 2 else ",,")
    elif form == "inline" and not comment and not keyword and line.strip():
        lines[k] = line + "  ** a note"
    elif form == "indent":
        lines[k] = ("\t" if c % 2 else "   ") + line
    elif form == "split" and keyword and "," in line:
        cut = [m.end() for m in re.finditer(",", line)]
        at = cut[c % len(cut)]
        lines[k:k + 1] = [line[:at], line[at:].lstrip()]
    return lines


def _lower(lines: list[str], k: int) -> str:
    """Line ``k`` in lower case where case does not matter (DECKS.md: keywords, parameter names
    and set names): not a file path, a step's name (a label, as written), nor the text of a
    ``*HEADING`` or ``*UNITS`` (``MPa`` is not ``mPa``)."""
    line = lines[k]
    if line.lstrip().startswith("*"):
        kept = re.compile(r"(INPUT|NAME)\s*=\s*[^,]*", re.I) if re.match(
            r"\s*\*\s*(STEP|INCLUDE|IMPORT)\b", line, re.I) else None
        if kept is None:
            return line.lower()
        out, pos = [], 0
        for m in kept.finditer(line):
            out += [line[pos:m.start()].lower(), m.group(0)]
            pos = m.end()
        return "".join(out) + line[pos:].lower()
    keyword = next((w for w in reversed(lines[:k]) if w.lstrip().startswith("*")
                    and not w.lstrip().startswith("**")), "")
    if re.match(r"\s*\*\s*(HEADING|UNITS|PARAMETER)\b", keyword, re.I):
        return line
    return line.lower()


def neutral(ops: list[tuple]) -> bool:
    """True when every op of ``ops`` only changes the text's form (its meaning stays)."""
    return bool(ops) and all(kind == "form" and FORMS[b % len(FORMS)] in NEUTRAL
                             for kind, _a, b, _c in ops)


def _scaled(text: str, factor: float) -> str:
    try:
        return repr(float(text.replace("d", "e").replace("D", "e")) * factor)
    except ValueError:
        return text


def random_ops(rng: random.Random, kinds: tuple[str, ...] = KINDS) -> list[tuple]:
    return [(rng.choice(kinds), rng.randrange(10**6), rng.randrange(10**6), rng.randrange(10**6))
            for _ in range(rng.randint(1, 4))]


# ---------------------------------------------------------------- one run, judged

def _capped_loader(increments: int):
    from lagamine_py import deck as deck_pkg
    real = deck_pkg.load_deck

    def load(path, parameters=None):
        model = real(path, parameters=parameters)
        for step in model.steps:
            step.max_increments = min(int(step.max_increments), increments)
        return model
    return deck_pkg, real, load


def judge(deck: Path, outdir: Path, increments: int = 2) -> Verdict:
    """Run ``deck`` into ``outdir`` through the command line, each step capped at
    ``increments``, and say what is wrong (:class:`Verdict`)."""
    import warnings

    from lagamine_py.cli import main

    deck_pkg, real, capped = _capped_loader(increments)
    err = io.StringIO()
    verdict = Verdict(None)
    verdict.check, verdict.summary = _check(deck)
    deck_pkg.load_deck = capped
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()), \
                warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                verdict.status = main(["run", str(deck), "-o", str(outdir), "-q"])
            except BaseException as exc:        # noqa: BLE001 - what the judge looks for
                verdict.problems.append(f"main raised {type(exc).__name__}: {exc}")
    finally:
        deck_pkg.load_deck = real
    verdict.problems += [f"{w.category.__name__}: {w.message}" for w in caught
                         if issubclass(w.category, RuntimeWarning)]        # NumPy's
    verdict.stderr = err.getvalue()
    text = verdict.stderr
    if verdict.status is not None and verdict.status not in ALLOWED and not (
            verdict.status == 1 and "*CONTROLS" in text):
        verdict.problems.append(f"exit status {verdict.status}")
    for bad in ("Traceback", "unexpected error", "Warning:"):
        if bad in text:
            verdict.problems.append(f"stderr holds {bad!r}")
    if outdir.is_dir():
        verdict.problems += non_finite(outdir)
        sta = sorted(outdir.glob("*.sta"))
        verdict.sta = sta[0].read_text() if sta else ""
    verdict.problems += disagreement(verdict.check, verdict.status, text)
    return verdict


def _check(deck: Path) -> tuple[int | None, str]:
    """``lagamine-py check DECK``: its exit status and what it printed (the deck's path left
    out), None when it raised (the run judges that)."""
    from lagamine_py.cli import main

    out = io.StringIO()
    with contextlib.redirect_stderr(out), contextlib.redirect_stdout(out):
        try:
            status = main(["check", str(deck)])
        except BaseException as exc:            # noqa: BLE001 - reported by the run's judge
            return None, f"check raised {type(exc).__name__}: {exc}"
    return status, out.getvalue().replace(str(deck), "DECK")


def disagreement(check: int | None, run: int | None, stderr: str) -> list[str]:
    """What is wrong when ``check``'s exit status ``check`` and ``run``'s ``run`` disagree:
    ``check`` must refuse (2) every deck that ``run`` refuses before it starts a step -- a
    deck error (2) or a step that cannot start (1, "step N (NAME): ...") -- and accept (0)
    every deck that ``run`` runs."""
    if check is None or run is None:
        return [] if check == run else ["check raised"] if check is None else []
    if check == 0 and run == 2:
        return ["check accepts what run refuses (exit 2)"]
    if check == 0 and run == 1 and re.search(r"lagamine-py: step \d+ \(", stderr):
        return ["check accepts a step that run cannot start (exit 1)"]
    if check != 0 and run in (0, 3):
        return [f"check refuses (exit {check}) what run runs (exit {run})"]
    return []


def same_outcome(ref: Verdict, got: Verdict) -> list[str]:
    """What differs between the outcome of a deck and that of its text in another form."""
    out = []
    if (ref.check, ref.summary) != (got.check, got.summary):
        out.append(f"check differs from the deck as written: {got.summary.strip()[:200]!r} "
                   f"against {ref.summary.strip()[:200]!r}")
    if ref.status != got.status or ref.sta != got.sta:
        out.append(f"run differs from the deck as written: exit {got.status} against {ref.status}"
                   + ("" if ref.sta == got.sta else ", other increments (.sta)"))
    return out


def non_finite(outdir: Path) -> list[str]:
    """Output tables and VTK arrays of ``outdir`` holding NaN or inf."""
    from lagamine_py.results import read_table, read_vtu

    out = []
    for path in sorted(outdir.glob("*.csv")) + sorted(outdir.glob("*.sta")):
        table = read_table(path)
        for name, col in table.items():
            if col.dtype != object and not np.all(np.isfinite(col)):
                out.append(f"{path.name}: column {name} holds {col[~np.isfinite(col)][0]}")
    for path in sorted(outdir.glob("*.vtu")):
        for name, arr in read_vtu(path).items():
            a = np.asarray(arr)
            if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                out.append(f"{path.name}: array {name} holds non-finite values")
    return out


def deck_dir(tmp: Path) -> Path:
    """A directory for mutated decks that sees what they include (:data:`INCLUDED`)."""
    tmp.mkdir(parents=True, exist_ok=True)
    for target in INCLUDED:
        link = tmp / target.name
        if not link.exists():
            link.symlink_to(target)
    return tmp


def source(name: str) -> Path:
    """The fuzzed deck ``name``: a deck of ``decks/``, or a path from the repository's root."""
    return ROOT / name if "/" in name else DECKS / name


def fuzz_one(name: str, ops: list[tuple], work: Path, increments: int = 2, tag: str = "x"):
    """Mutate deck ``name`` by ``ops``, run and judge it: (deck path, verdict)."""
    text = mutate(source(name).read_text(), ops)
    deck = deck_dir(work) / f"{Path(name).stem}_{tag}.dat"
    deck.write_text(text)
    out = work / f"out_{tag}"
    shutil.rmtree(out, ignore_errors=True)
    verdict = judge(deck, out, increments)
    if neutral(ops):
        verdict.problems += same_outcome(reference(name, work, increments), verdict)
    return deck, verdict


_REFERENCES: dict = {}


def reference(name: str, work: Path, increments: int) -> Verdict:
    """The verdict of deck ``name`` as written (once per process, deck and cap)."""
    key = (name, increments)
    if key not in _REFERENCES:
        tag = f"ref_{Path(name).stem}"
        text = source(name).read_text()
        deck = deck_dir(work) / f"{Path(name).stem}_{tag}.dat"
        deck.write_text(mutate(text, []))
        out = work / f"out_{tag}"
        shutil.rmtree(out, ignore_errors=True)
        _REFERENCES[key] = judge(deck, out, increments)
        _REFERENCES[key].summary = _REFERENCES[key].summary.replace(deck.name, "DECK")
    return _REFERENCES[key]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--examples", type=int, default=200)
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--increments", type=int, default=2)
    ap.add_argument("--keep", type=Path, default=Path("/tmp/lagamine_fuzz_run"))
    ap.add_argument("--kinds", default=",".join(KINDS),
                    help="the mutation kinds drawn from, comma-separated, repeats weigh "
                         f"(default {','.join(KINDS)}; the fuzz before *CONTROLS and forms: "
                         "number,number,number,drop,dup,swap,param)")
    args = ap.parse_args(argv)
    kinds = tuple(k.strip() for k in args.kinds.split(",") if k.strip())
    unknown = set(kinds) - set(KINDS)
    if unknown or not kinds:
        ap.error(f"--kinds: unknown {', '.join(sorted(unknown))}; known: {', '.join(sorted(set(KINDS)))}")
    rng = random.Random(args.seed)
    counts: Counter = Counter()
    checks: Counter = Counter()
    bad = 0
    t0 = time.perf_counter()
    args.keep.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="fuzz_run_") as tmp:
        for k in range(args.examples):
            name = rng.choice(FUZZED)
            ops = random_ops(rng, kinds)
            deck, v = fuzz_one(name, ops, Path(tmp), args.increments, tag=str(k))
            counts[v.status] += 1
            checks[v.check] += 1
            if v.bad:
                bad += 1
                keep = args.keep / f"bad_{k}_{deck.name}"
                shutil.copy(deck, keep)
                keep.with_suffix(".why").write_text("\n".join(v.problems) + "\n\n" + v.stderr)
                print(f"BAD {k} {name} {ops}: {'; '.join(v.problems)[:300]}", flush=True)
            shutil.rmtree(Path(tmp) / f"out_{k}", ignore_errors=True)
    took = time.perf_counter() - t0
    summary = ", ".join(f"exit {s}: {n}" for s, n in sorted(counts.items(), key=lambda x: str(x[0])))
    checked = ", ".join(f"{s}: {n}" for s, n in sorted(checks.items(), key=lambda x: str(x[0])))
    print(f"{args.examples} mutated decks in {took:.0f} s: {summary}; check exit {checked}; bad: {bad}"
          + (f" (kept in {args.keep})" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main())
