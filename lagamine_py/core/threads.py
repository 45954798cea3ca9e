"""Thread pools of the numerical libraries: MKL (PARDISO) gets the cores, OpenBLAS one thread.

Two BLAS/OpenMP runtimes live in one process once MKL (PARDISO) is loaded: numpy's (and
scipy's) OpenBLAS, and MKL with Intel OpenMP.  Left alone, both start one thread per core and
their idle workers spin-wait after each call, so on a 2-core machine the factorisation and the
NumPy assembly that follows it steal each other's cores.  The policy:

* OpenBLAS: 1 thread.  Our BLAS calls are small batched matrix products (16 x 36 element
  blocks), far below the size where threads pay off.
* MKL: all cores, for the PARDISO factorisation (the one big dense-kernel job).
* Intel OpenMP: ``KMP_BLOCKTIME=0`` (set only if the user did not set it, and only before the
  runtime loads, i.e. before MKL is loaded): the workers sleep as soon as the
  factorisation returns instead of spinning 200 ms on the cores NumPy needs next.

Users override with the usual variables (``MKL_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``,
``KMP_BLOCKTIME``) or with ``LAGAMINE_THREADS=off`` to leave every pool alone.

Our own threads: the numba solid kernel (``kernels.solid``, ``nogil``) computes a large group
(:data:`SPLIT_ELEMENTS` elements per thread at least) in contiguous element ranges on
:func:`kernel_threads` threads, with the same bytes as on one (``kernels.solid.Split``: the
entries two ranges share are summed in the one-thread order).  The count, as CalculiX's
``OMP_NUM_THREADS``: ``LAGAMINE_THREADS=N`` (``1``: one thread; ``off``: one thread and every
library pool left alone), else ``OMP_NUM_THREADS``, else :data:`DEFAULT_KERNEL_THREADS`; never
more than the cores the process may run on (``os.sched_getaffinity``).
"""
from __future__ import annotations

import os
import sys

#: the solid kernel's threads when neither LAGAMINE_THREADS nor OMP_NUM_THREADS says: one, as
#: CalculiX without OMP_NUM_THREADS (two measured no faster on the loaded 2-core machine of
#: docs/performance.md, "The solid kernel on two threads")
DEFAULT_KERNEL_THREADS = 1
#: elements per thread at least: below, the thread start and join and the deferred sums cost
#: what the split saves (docs/performance.md, "The solid kernel on two threads")
SPLIT_ELEMENTS = 2048

_pool = None          # the ThreadPoolExecutor of worker_pool, started on first use

#: set by :func:`pin_openblas_at_load` when the environment did the pinning
_pinned_at_load = False


def pin_openblas_at_load() -> bool:
    """The OpenBLAS half of the policy, through ``OPENBLAS_NUM_THREADS=1``, for a process that
    has not loaded numpy yet (the command line: ``lagamine-py run``): OpenBLAS then starts with
    one thread and :func:`pin_threads` has nothing left to do, which spares the ``threadpoolctl``
    import and its scan of the loaded libraries (~0.02 s of a short run).  Does nothing when
    the user chose (``LAGAMINE_THREADS=off``, ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS``) or
    numpy is already loaded.  True when it set the variable."""
    global _pinned_at_load
    if os.environ.get("LAGAMINE_THREADS", "").lower() == "off" or "numpy" in sys.modules:
        return False
    if "OPENBLAS_NUM_THREADS" in os.environ or "OMP_NUM_THREADS" in os.environ:
        return False
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    _pinned_at_load = True
    return True


def prepare_openmp_env() -> None:
    """Set ``KMP_BLOCKTIME=0`` unless the user chose a value (call before importing MKL)."""
    if os.environ.get("LAGAMINE_THREADS", "").lower() == "off":
        return
    os.environ.setdefault("KMP_BLOCKTIME", "0")


def pin_threads() -> dict[str, int]:
    """Apply the policy above to the OpenBLAS libraries loaded so far (needs ``threadpoolctl``;
    does nothing without it or when the user set ``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS``).
    Cheap; :mod:`lagamine_py.solver.linear` calls it on import and when PARDISO loads.
    Returns ``{library prefix: threads}`` of the pools it limited."""
    if os.environ.get("LAGAMINE_THREADS", "").lower() == "off":
        return {}
    if _pinned_at_load:
        return {"openblas (OPENBLAS_NUM_THREADS at load)": 1}
    if "OPENBLAS_NUM_THREADS" in os.environ or "OMP_NUM_THREADS" in os.environ:
        return {}
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return {}
    # select by internal_api: user_api="blas" would also catch MKL
    pools = ThreadpoolController().select(internal_api="openblas")
    pools.limit(limits=1)
    return {lib.prefix: 1 for lib in pools.lib_controllers}


def available_cores() -> int:
    """The cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                  # no affinity call (macOS, Windows)
        return os.cpu_count() or 1


def kernel_threads() -> int:
    """Threads for the solid kernel, by the rule of the module docstring (at least 1).

    Raises ValueError for a ``LAGAMINE_THREADS`` that is neither ``off`` nor a count."""
    setting = os.environ.get("LAGAMINE_THREADS", "").strip().lower()
    if setting == "off":
        return 1
    if setting:
        if not setting.isdigit() or int(setting) < 1:
            raise ValueError(f"LAGAMINE_THREADS={setting!r}: expected a count (1, 2, ...) or off")
        wanted = int(setting)
    elif os.environ.get("OMP_NUM_THREADS", "").strip().isdigit():
        wanted = max(1, int(os.environ["OMP_NUM_THREADS"]))
    else:
        wanted = DEFAULT_KERNEL_THREADS
    return max(1, min(wanted, available_cores()))


def split_parts(elements: int, threads: int | None = None,
                per_thread: int = SPLIT_ELEMENTS) -> int:
    """Element ranges for a group of ``elements``: one per thread, each of ``per_thread``
    elements at least (1: no split)."""
    threads = kernel_threads() if threads is None else threads
    return max(1, min(threads, elements // max(1, per_thread)))


def worker_pool():
    """The process's worker threads for kernel ranges, a ``ThreadPoolExecutor`` (started on
    first use, kept; the caller's own thread runs a first range, so ``kernel_threads() - 1``
    workers).  ``concurrent.futures`` is imported here, not with the module: a run on one
    thread (the default) does not pay its import (~5-10 ms of the main job's start-up)."""
    global _pool
    if _pool is None:
        from concurrent.futures import ThreadPoolExecutor
        _pool = ThreadPoolExecutor(max_workers=max(1, available_cores() - 1),
                                   thread_name_prefix="lagamine-kernel")
    return _pool


def _forget_pool() -> None:
    """A forked child has none of its parent's threads: it starts its own pool."""
    global _pool
    _pool = None


if os.name == "posix":
    os.register_at_fork(after_in_child=_forget_pool)
