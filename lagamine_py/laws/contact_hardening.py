"""How adhesion B and friction phi evolve with the slip lam: the hardening forms of COULOMB.

The paper lets B and phi be functions of lam (eqs. 6-8, "c'est-a-dire aussi de la dissipation
d'energie D").  Each of them is one :class:`Form`, evaluated array-wise with its right-derivative:

* :class:`Linear` ``max(v0 + slope lam, 0)`` (``HB``, ``HPHI``), a kink where it reaches 0;
* :class:`Exponential` ``v_inf + (v0 - v_inf) exp(-lam / lamc)`` (``B_INF, LAMC_B``,
  ``PHI_INF, LAMC``): run-in (phi rising to a plateau) or wear (adhesion lost), never clipped
  (it stays between v0 and v_inf, both >= 0), smooth;
* :class:`Table` piecewise linear through rows ``(lam_k, v_k)`` from lam = 0, flat beyond the
  last row (``*CONTACT LAW TABLE``), a kink at every row.

A form says where its derivative jumps (:attr:`Form.breaks`: the return mapping walks over them
one piece at a time and the dissipation integral splits there), whether it is linear between
them (:attr:`Form.smooth` False: the return on a piece is closed-form), bounds of its values
(the bracket of the return) and its steepest descent (the snap-back check), and its slots of the
kernel's parameter vector (:meth:`Form.encode`, layout in :mod:`lagamine_py.kernels.layout`).

Why lam and not the dissipation D: the end state of an exact return depends only on the end
values of a sub-interval when B and phi are functions of lam (the consistency condition is then
an algebraic equation in lam, see :mod:`lagamine_py.laws.coulomb`); as functions of D, with
``dD = (B + phi p) dlam``, it depends on how p moved within the sub-interval, so it could only
be integrated to a tolerance.  A table measured against D at a known pressure converts exactly
to lam (``lam = int dD / (B + phi p)``).
"""
from __future__ import annotations

import numpy as np

from ..core.params import ParamError
from ..kernels import layout as kl

__all__ = ["Form", "Linear", "Exponential", "Table"]


class Form:
    """One of B(lam), phi(lam): value and right-derivative, array-wise."""

    #: the kind number the kernel reads (kernels.layout)
    kind: int = kl.FORM_LINEAR
    #: lam where the derivative jumps (sorted, finite, > 0)
    breaks: tuple[float, ...] = ()
    #: nonlinear between the breaks (the return then iterates on the piece)
    smooth: bool = False
    #: the length over which the form changes by a factor e (dissipation panels); inf if linear
    scale: float = np.inf

    def __call__(self, lam):
        """``(value, right-derivative)`` at ``lam`` (arrays of lam's shape)."""
        raise NotImplementedError

    def lower(self) -> float:
        """A lower bound of the values over lam >= 0."""
        raise NotImplementedError

    def upper(self) -> float:
        """An upper bound of the values over lam >= 0 (inf when unbounded)."""
        raise NotImplementedError

    def steepest(self) -> float:
        """The most negative right-derivative over lam >= 0 (0 when it never decreases)."""
        raise NotImplementedError

    def constant(self) -> bool:
        return False

    def encode(self, v: np.ndarray, base: int, table: int) -> None:
        """Write the form into the kernel vector ``v``: ``base`` its slots (kind, v0, a, c),
        ``table`` the offset of its table values."""
        raise NotImplementedError


class Linear(Form):
    """``max(v0 + slope lam, 0)``; its right-derivative is 0 once clipped.  The clipped side
    is decided by comparing with the kink, so a lam set exactly on the kink gets the slope of
    the piece ahead of it."""

    def __init__(self, v0: float, slope: float):
        self.v0, self.slope = float(v0), float(slope)
        self.kink = -self.v0 / self.slope if self.slope < 0.0 else np.inf
        self.breaks = (self.kink,) if np.isfinite(self.kink) else ()

    def __call__(self, lam):
        if self.slope == 0.0:                 # the common case: plain floats, same values
            return self.v0, 0.0
        lam = np.asarray(lam, float)
        return (np.maximum(self.v0 + self.slope * lam, 0.0),
                np.where(lam < self.kink, self.slope, 0.0))

    def constant(self) -> bool:
        return self.slope == 0.0

    def lower(self) -> float:
        return 0.0 if self.slope < 0.0 else self.v0

    def upper(self) -> float:
        return np.inf if self.slope > 0.0 else self.v0

    def steepest(self) -> float:
        return min(self.slope, 0.0)

    def encode(self, v, base, table):
        v[base:base + 4] = (kl.FORM_LINEAR, self.v0, self.slope, self.kink)


class Exponential(Form):
    """``v_inf + (v0 - v_inf) exp(-lam / lamc)``."""

    kind = kl.FORM_EXP
    smooth = True

    def __init__(self, v0: float, v_inf: float, lamc: float):
        self.v0, self.v_inf, self.lamc = float(v0), float(v_inf), float(lamc)
        self.scale = self.lamc

    def __call__(self, lam):
        e = np.exp(-np.asarray(lam, float) / self.lamc)
        dv = self.v0 - self.v_inf
        return self.v_inf + dv * e, (-dv / self.lamc) * e

    def lower(self) -> float:
        return min(self.v0, self.v_inf)

    def upper(self) -> float:
        return max(self.v0, self.v_inf)

    def steepest(self) -> float:
        return min(-(self.v0 - self.v_inf) / self.lamc, 0.0)

    def encode(self, v, base, table):
        v[base:base + 4] = (kl.FORM_EXP, self.v0, self.v_inf, self.lamc)


class Table(Form):
    """Piecewise linear through ``(x_k, y_k)``, ``x_0 = 0``, flat beyond the last row."""

    kind = kl.FORM_TABLE

    def __init__(self, x, y):
        self.x, self.y = np.asarray(x, float), np.asarray(y, float)
        self.slopes = np.append(np.diff(self.y) / np.diff(self.x), 0.0)  # segment k from row k
        self.breaks = tuple(float(b) for b in self.x[1:])

    def __call__(self, lam):
        # segment k (x_k <= lam < x_k+1; the last row's flat one beyond): y_k + slope_k (lam -
        # x_k), written out (not np.interp) so that the kernel computes the same floats
        lam = np.asarray(lam, float)
        k = np.clip(np.searchsorted(self.x, lam, side="right") - 1, 0, len(self.x) - 1)
        slope = self.slopes[k]
        return self.y[k] + slope * (lam - self.x[k]), slope

    def lower(self) -> float:
        return float(self.y.min())

    def upper(self) -> float:
        return float(self.y.max())

    def steepest(self) -> float:
        return min(float(self.slopes.min()), 0.0)

    def encode(self, v, base, table):
        v[base:base + 4] = (kl.FORM_TABLE, self.y[0], 0.0, 0.0)
        n = len(self.x)
        v[table:table + n] = self.y
        v[table + n:table + 2 * n] = self.slopes


def table_forms(rows) -> tuple[np.ndarray, Table, Table]:
    """``(lam rows, phi table, B table)`` from ``*CONTACT LAW TABLE`` rows ``lam, phi, B``,
    checked: the first row at lam = 0, lam increasing, phi and B >= 0."""
    t = np.asarray(rows, float)
    lam, phi, b = t[:, 0], t[:, 1], t[:, 2]
    if lam[0] != 0.0:
        raise ParamError(f"CONTACT LAW TABLE: the first row must be at lam = 0 (phi and B of a "
                         f"fresh surface), got lam = {lam[0]:g}")
    if np.any(np.diff(lam) <= 0.0):
        k = int(np.flatnonzero(np.diff(lam) <= 0.0)[0])
        raise ParamError(f"CONTACT LAW TABLE: lam must increase, row {k + 2} ({lam[k + 1]:g}) "
                         f"follows {lam[k]:g}")
    for name, col in (("phi", phi), ("B", b)):
        if np.any(col < 0.0):
            raise ParamError(f"CONTACT LAW TABLE: {name} must be >= 0, got {col[col < 0][0]:g}")
    return lam, Table(lam, phi), Table(lam, b)
