"""``lagamine-py compile`` (issue 17 item 4): the machine code it leaves in numba's cache is what
a later run loads -- the run compiles nothing -- and where the cache went when
``NUMBA_CACHE_DIR`` is unusable.

The compile uses the suite's usual cache (next to the kernels, warm after the other numba
tests), so a run of this file costs a compile only on a cold tree; the first-run timings are
benchmarks (``docs/performance.md``), not tests.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[1]

_RUN = """
import json, sys
from lagamine_py import kernels
from lagamine_py.cli import main
status = main(["run", sys.argv[1], "-q", "--kernel", "NUMBA", "-o", sys.argv[2]])
print(json.dumps({"status": status, "calls": dict(kernels.calls),
                  "report": kernels.cache_report("solid")}))
"""


def _cli(*args, env=None, cwd=None):
    return subprocess.run([sys.executable, "-m", "lagamine_py", *map(str, args)],
                          capture_output=True, text=True, env=env, cwd=cwd)


def test_a_run_after_compile_loads_the_solid_kernel_and_compiles_nothing(tmp_path):
    res = _cli("compile")
    assert res.returncode == 0, res.stderr
    assert "_solid_kernel" in res.stdout and "_start_kernel" in res.stdout
    # an axisymmetric NLGEOM deck with another mesh, law values and no contact: the same
    # machine code must serve it
    out = subprocess.run([sys.executable, "-c", _RUN, str(ROOT / "decks" / "compression_ro.dat"),
                          str(tmp_path / "out")], capture_output=True, text=True, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["status"] == 0 and got["calls"]["solid"] > 0
    assert set(got["report"]) == {"_solid_kernel", "_start_kernel"}
    for fn, info in got["report"].items():
        assert info["hits"] >= 1 and info["misses"] == 0, (fn, info)


def test_an_unusable_numba_cache_dir_falls_back_to_a_writable_cache(tmp_path):
    """NUMBA_CACHE_DIR under a plain file cannot be created: numba falls back to the next
    cache location (next to the kernels, or the per-user cache), and compile says which."""
    blocked = tmp_path / "file"
    blocked.write_text("not a directory")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(blocked / "cache"))
    res = _cli("compile", env=env, cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    caches = {line.rsplit("(", 1)[1].rstrip(")") for line in res.stdout.splitlines()
              if line.startswith("solid kernel")}
    assert len(caches) == 1
    cache = Path(caches.pop())
    assert not str(cache).startswith(str(blocked))
    assert any(cache.glob("solid._solid_kernel-*.nbi")), sorted(cache.iterdir())


def test_a_cold_cache_is_announced_once_with_the_command(tmp_path):
    code = ("import logging; logging.basicConfig()\n"
            "from lagamine_py import kernels\n"
            "kernels.module('solid'); kernels.module('solid')\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "empty")))
    assert res.returncode == 0, res.stderr
    assert res.stderr.count("lagamine-py compile") == 1, res.stderr
    # the suite's own cache is warm (the test above compiled into it): nothing said
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert "lagamine-py compile" not in res.stderr, res.stderr


def test_compile_contact_compiles_or_finds_the_contact_kernel_too():
    res = _cli("compile", "--contact")
    assert res.returncode == 0, res.stderr
    for fn in ("_solid_kernel", "_start_kernel", "_contact", "_faces", "_project"):
        assert f" {fn}: " in res.stdout, res.stdout
