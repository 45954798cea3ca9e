"""What a short run loads (issue 17 item 3): the main job imports no module it does not use.

Each module below cost a measurable part of the main job's 0.9 s (``docs/performance.md``,
"Start-up, first run, memory"); the run is done in a fresh interpreter and its ``sys.modules``
read at the end.
"""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: never needed by ``lagamine-py run`` of a small deck
NOT_LOADED = (
    "numba", "llvmlite",                    # KERNEL=AUTO below AUTO_NUMBA_ELEMENTS
    "vtk", "vtkmodules", "meshio",          # our own VTU writer
    "matplotlib",
    "pypardiso",                            # MKL is found by ctypes
    "scipy.sparse.linalg", "scipy.linalg",  # SuperLU loaded by file (solver.superlu)
    "threadpoolctl",                        # OPENBLAS_NUM_THREADS set before numpy loads
    "xml.sax", "urllib.request",            # the VTU attribute quoting is ours
    "importlib.metadata", "email",          # registry.scan_entry_points reads entry_points.txt
    "socket",                               # the lock's and record's host: platform.node()
    # numpy's f2py and testing stay lazy modules (core.lazy_modules): never executed
    "numpy.f2py.crackfortran", "numpy.testing._private.utils",
)

_SCRIPT = """
import json, os, sys
fsyncs = []
_fsync = os.fsync
os.fsync = lambda fd: (fsyncs.append(fd), _fsync(fd))[1]
from lagamine_py.cli import main
status = main(["run", sys.argv[1], "-q", "--overwrite", "-o", sys.argv[2]])
loaded = sorted(m for m in sys.modules if m.split(".")[0] in {n.split(".")[0] for n in %r})
import threadpoolctl
blas = [i["num_threads"] for i in threadpoolctl.threadpool_info() if i["internal_api"] == "openblas"]
import gc
print(json.dumps({"status": status, "loaded": loaded, "openblas_threads": blas,
                  "fsyncs": len(fsyncs), "frozen": gc.get_freeze_count()}))
"""


@pytest.fixture(scope="module")
def main_job(tmp_path_factory):
    out = tmp_path_factory.mktemp("main_job")
    env = {k: v for k, v in __import__("os").environ.items()
           if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "LAGAMINE_THREADS")}
    res = subprocess.run([sys.executable, "-c", _SCRIPT % (NOT_LOADED,),
                          str(ROOT / "decks" / "press_slide.dat"), str(out / "run")],
                         capture_output=True, text=True, env=env, cwd=out)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_the_main_job_runs(main_job):
    assert main_job["status"] == 0


@pytest.mark.parametrize("name", NOT_LOADED)
def test_the_main_job_does_not_import(main_job, name):
    assert name not in main_job["loaded"]        # a package, so any of its modules loads it


def test_openblas_has_one_thread_without_threadpoolctl(main_job):
    """The environment variable set before numpy loads did what pin_threads did."""
    assert main_job["openblas_threads"] and set(main_job["openblas_threads"]) == {1}


def test_the_main_job_does_not_fsync(main_job):
    """Restart data, run record and lock are renamed into place, not fsynced: ~6 ms of wall
    time each on this machine's disk, 0.1 s of the main job when the restart file was synced
    at every increment (see :mod:`lagamine_py.solver.restart` for why the rename suffices)."""
    assert main_job["fsyncs"] == 0


def test_the_imports_are_frozen_out_of_garbage_collection(main_job):
    """cli._long_lived: the ~30 000 objects of the imports (the deck's modules included) are
    frozen, so the collections during the run do not re-scan them (12 -> ~1 ms of the main job)."""
    assert main_job["frozen"] > 20000


_LAZY_SCRIPT = """
import sys
from lagamine_py.core.lazy_modules import defer_numpy_submodules
deferred = defer_numpy_submodules()
import scipy.sparse                     # clones numpy's namespace, f2py and testing included
assert deferred == ["f2py", "testing"], deferred
assert "numpy.f2py.crackfortran" not in sys.modules and "unittest" not in sys.modules
import numpy as np
from numpy.testing import assert_allclose           # the first use runs the real module
assert_allclose(np.ones(2), [1.0, 1.0])
assert np.testing.assert_allclose is assert_allclose and "unittest" in sys.modules
import numpy.f2py
assert np.f2py is sys.modules["numpy.f2py"] and callable(numpy.f2py.get_include)
assert scipy.sparse.csr_matrix(np.eye(2)).nnz == 2
assert defer_numpy_submodules() == []   # already there: left alone
print("ok")
"""


def test_deferred_numpy_submodules_load_at_first_use():
    """The lazy modules cost nothing until used, and then are the real ones (fresh interpreter:
    this one has numpy.testing loaded)."""
    res = subprocess.run([sys.executable, "-c", _LAZY_SCRIPT], capture_output=True, text=True)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr


def test_the_host_name_is_the_one_socket_gives():
    """The lock and the record name the host by ``platform.node()`` (no ``socket`` import):
    the name ``socket.gethostname()`` gives, which locks written before recorded."""
    import socket

    from lagamine_py.core import outdir
    assert outdir._host() == socket.gethostname()
