"""Every code block of README.md and docs/*.md runs.

Fenced blocks are run according to their language tag:

* ``python``: the blocks of one page run in order, in one interpreter, in a scratch directory
  where ``decks/`` and ``tools/`` of the repository are visible;
* ``dat``: a deck -- written to a file, checked, and run when it has steps;
* ``ini``: an excerpt of a real ``setup.cfg`` -- every line of it must stand in the file its
  page shows (``tests/plugin_pkg/setup.cfg`` for the plugin pages);
* ``console``: ``$ command`` lines run, and every output line shown must appear in what the
  command printed (on either stream, as a terminal shows them);
* ``sh`` or untagged: one command a line (``# comments`` allowed).  ``lagamine-py`` commands run
  for real; ``python tools/<script> ...`` commands (studies and benchmarks that take minutes to
  hours) are checked against the script's ``--help``: the script exists and takes every option
  the command gives; ``git`` commands are not run;
* ``text``: not code (syntax summaries with placeholders, drawings), not run.

The README's first block is the pair of set-up commands: CI runs the second one itself
(``.ci/run``), and this test checks that it is the one ``.ci/run`` runs.
"""
from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([\w-]*)[^\n]*\n(.*?)^```", re.S | re.M)


def blocks(page: Path) -> list[tuple[str, str, int]]:
    """(language, code, line) of every fenced block of a page."""
    text = page.read_text()
    return [(m.group(1), m.group(2), text[:m.start()].count("\n") + 1) for m in FENCE.finditer(text)]


def cases():
    for page in PAGES:
        for k, (lang, code, line) in enumerate(blocks(page)):
            if page.name == "README.md" and k == 0:
                continue                              # the set-up commands: test_setup_commands
            yield pytest.param(page, lang, code, line, id=f"{page.name}:{line}")


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A directory where the repository's decks, tools and docs are visible, for commands to run in,
    with the example plugin package of docs/plugins.md (tests/plugin_pkg) installed for them
    (into a target directory on PYTHONPATH: the test environment is left as it was)."""
    d = tmp_path_factory.mktemp("docs")
    for name in ("decks", "tools", "tests", "docs"):
        (d / name).symlink_to(ROOT / name)
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation",
                    "--target", str(d / "site"), str(ROOT / "tests" / "plugin_pkg")], check=True)
    return d


_ran: dict[str, subprocess.CompletedProcess] = {}


def _env(cwd: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(cwd / "site"), env.get("PYTHONPATH", "")])
    return env


def _run(command: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run a command once per test session (pages repeat each other's commands)."""
    if command not in _ran:
        args = shlex.split(command)
        if args[0] == "lagamine-py":
            args = [sys.executable, "-m", "lagamine_py", *args[1:]]
        _ran[command] = subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=600,
                                       env=_env(cwd))
    return _ran[command]


def _check_tool(command: str) -> None:
    """A ``python tools/x.py ...`` command: the script exists and takes each option given."""
    args = shlex.split(command)
    script = ROOT / args[1]
    assert script.is_file(), f"{command}: no {args[1]}"
    helps = subprocess.run([sys.executable, str(script), "--help"], capture_output=True,
                           text=True, timeout=120)
    assert helps.returncode == 0, helps.stderr
    text = helps.stdout
    sub = [a for a in args[2:] if not a.startswith("-")][:1]
    if sub and re.search(rf"\b{re.escape(sub[0])}\b", text) and "{" in text:   # sub-commands
        helps = subprocess.run([sys.executable, str(script), sub[0], "--help"],
                               capture_output=True, text=True, timeout=120)
        if helps.returncode == 0:
            text += helps.stdout
    for opt in (a.split("=")[0] for a in args[2:] if a.startswith("--")):
        assert opt in text, f"{command}: {args[1]} has no option {opt}"


def _shell_lines(code: str):
    for raw in code.splitlines():
        line = raw.split(" #")[0].strip() if not raw.lstrip().startswith("#") else ""
        if line:
            yield line


@pytest.mark.parametrize("page, lang, code, line", list(cases()))
def test_code_block_runs(page, lang, code, line, scratch):
    where = f"{page.relative_to(ROOT)}:{line}"
    if lang == "text":
        return
    if lang == "python":
        return                                       # run page by page: test_python_blocks
    if lang == "dat":
        deck = scratch / f"{page.stem}_{line}.dat"
        deck.write_text(code)
        out = _run(f"lagamine-py check {deck}", scratch)
        assert out.returncode == 0, f"{where}: {out.stderr}"
        if "*STEP" in code.upper():
            out = _run(f"lagamine-py run {deck} -o {scratch / deck.stem} -q", scratch)
            assert out.returncode == 0, f"{where}: {out.stderr}"
        return
    if lang == "ini":
        shown = [s.strip() for s in code.splitlines() if s.strip()]
        real = (ROOT / "tests" / "plugin_pkg" / "setup.cfg").read_text().splitlines()
        real = [s.strip() for s in real]
        missing = [s for s in shown if s not in real]
        assert not missing, f"{where}: not in tests/plugin_pkg/setup.cfg: {missing}"
        return
    if lang == "console":
        command, expected = None, []
        for raw in code.splitlines() + ["$"]:
            if raw.startswith("$"):
                if command:
                    out = _run(command, scratch)
                    assert out.returncode == 0, f"{where}: {command}: {out.stderr}"
                    for want in expected:
                        assert want.strip() in out.stdout + out.stderr, f"{where}: {command}: no {want!r}"
                command, expected = raw[1:].strip(), []
            elif raw.strip():
                expected.append(raw)
        return
    assert lang in ("", "sh"), f"{where}: unknown code block language {lang!r}"
    for command in _shell_lines(code):
        head = shlex.split(command)
        if head[0] == "git":
            continue
        if head[0] in ("python", "python3") and len(head) > 1 and head[1].startswith("tools/"):
            _check_tool(command)
            continue
        assert head[0] == "lagamine-py", f"{where}: a command the docs test cannot run: {command}"
        out = _run(command, scratch)
        assert out.returncode == 0, f"{where}: {command}: {out.stderr[-2000:]}"


@pytest.mark.parametrize("page", [p for p in PAGES if any(b[0] == "python" for b in blocks(p))],
                         ids=lambda p: p.name)
def test_python_blocks(page, scratch):
    """The python blocks of a page, in order, in one interpreter."""
    code = "\n\n".join(c for lang, c, _ in blocks(page) if lang == "python")
    script = scratch / f"{page.stem}_blocks.py"
    script.write_text(code)
    out = subprocess.run([sys.executable, str(script)], cwd=scratch, capture_output=True,
                         text=True, timeout=600, env=_env(scratch))
    assert out.returncode == 0, f"{page.name}: {out.stderr[-3000:]}"


def test_setup_commands():
    """The README opens with the two set-up-and-go commands; the second is what CI runs."""
    lang, code, _ = blocks(ROOT / "README.md")[0]
    run_job, run_tests = [c.strip() for c in code.strip().splitlines()]
    assert run_job.endswith("lagamine-py run decks/press_slide.dat -o out/press_slide")
    ci = (ROOT / ".ci" / "run").read_text()
    assert run_tests in ci.replace("\n", " ") or run_tests.split("&&")[-1].strip() in ci
