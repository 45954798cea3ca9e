"""A third-party lagamine_py linear solver: dense LU with partial pivoting (scipy).

The entry point in setup.cfg (group ``lagamine_py.solvers``) makes it available as
``*CONTROLS SOLVER=DENSE_LU`` or ``lagamine-py run --solver DENSE_LU``.  Dense, so for small
models (and for checking a sparse solver on them).  A pivot below ``1e-12`` times the largest
diagonal entry names its column's DOF as unrestrained (partial pivoting permutes rows only, so
pivot ``j`` belongs to column ``j``).
"""
import logging
import warnings

import numpy as np
import scipy.linalg

from lagamine_py.core.errors import SingularMatrixError
from lagamine_py.solver.linear import LinearSolver

log = logging.getLogger("lagamine_py.plugins.dense_lu")     # goes to the run's .log


class DenseLU(LinearSolver):
    """Dense LU with partial pivoting (scipy.linalg.lu_factor), for small models."""

    def __init__(self):
        self.announced = False

    def factor(self, A):
        M = A.toarray()
        scale = np.abs(np.diag(M)).max() if M.size else 0.0
        with warnings.catch_warnings():          # an exactly zero pivot is reported below
            warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
            self.lu = scipy.linalg.lu_factor(M)
        pivots = np.abs(np.diag(self.lu[0]))
        small = np.flatnonzero(~(pivots > 1e-12 * scale))
        if small.size:
            raise SingularMatrixError(small, "zero pivot of the dense LU")
        if not self.announced:
            log.info("DENSE_LU: dense LU of a %d x %d matrix (scipy.linalg.lu_factor)", *M.shape)
            self.announced = True

    def solve(self, b):
        return scipy.linalg.lu_solve(self.lu, np.asarray(b, float))
