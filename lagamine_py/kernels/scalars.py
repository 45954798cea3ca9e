"""Scalar helpers shared by the numba kernels (:mod:`.solid`, :mod:`.contact`), with NumPy's NaN
semantics where the NumPy reference paths rely on them.  Imported only by those kernels, so numba
stays an optional dependency."""
from __future__ import annotations

import math

from numba import njit

# no reference counting: these take and return floats only
_JIT = dict(cache=True, fastmath=False, error_model="numpy", nogil=True, _nrt=False)


@njit(**_JIT)
def nmin(a, b):
    """np.minimum of two scalars (NaN propagates)."""
    if a != a or b != b:
        return math.nan
    return a if a < b else b


@njit(**_JIT)
def nmax(a, b):
    """np.maximum of two scalars (NaN propagates)."""
    if a != a or b != b:
        return math.nan
    return a if a > b else b
