"""Thread pools of the numerical libraries: MKL (PARDISO) gets the cores, OpenBLAS one thread.

Two BLAS/OpenMP runtimes live in one process once ``pypardiso`` is imported: numpy's (and
scipy's) OpenBLAS, and MKL with Intel OpenMP.  Left alone, both start one thread per core and
their idle workers spin-wait after each call, so on a 2-core machine the factorisation and the
NumPy assembly that follows it steal each other's cores.  The policy:

* OpenBLAS: 1 thread.  Our BLAS calls are small batched matrix products (16 x 36 element
  blocks), far below the size where threads pay off.
* MKL: all cores, for the PARDISO factorisation (the one big dense-kernel job).
* Intel OpenMP: ``KMP_BLOCKTIME=0`` (set only if the user did not set it, and only before the
  runtime loads, i.e. before ``pypardiso`` is imported): the workers sleep as soon as the
  factorisation returns instead of spinning 200 ms on the cores NumPy needs next.

Users override with the usual variables (``MKL_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``,
``KMP_BLOCKTIME``) or with ``LAGAMINE_THREADS=off`` to leave every pool alone.
"""
from __future__ import annotations

import os

_done = False


def prepare_openmp_env() -> None:
    """Set ``KMP_BLOCKTIME=0`` unless the user chose a value (call before importing MKL)."""
    if os.environ.get("LAGAMINE_THREADS", "").lower() == "off":
        return
    os.environ.setdefault("KMP_BLOCKTIME", "0")


def pin_threads() -> dict[str, int]:
    """Apply the policy above once per process (needs ``threadpoolctl``; silently does nothing
    without it).  Returns ``{internal_api: threads}`` of the pools it limited."""
    global _done
    if _done or os.environ.get("LAGAMINE_THREADS", "").lower() == "off":
        return {}
    _done = True
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return {}
    limits = {}
    if "OPENBLAS_NUM_THREADS" not in os.environ and "OMP_NUM_THREADS" not in os.environ:
        limits["openblas"] = 1
    if limits:
        threadpool_limits(limits=limits)
    return limits
