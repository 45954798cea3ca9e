"""What laws and their kernel twins share: the layout of the parameter vectors, the law kinds, the
flags the kernels write and the tolerances both sides use.  Plain constants (importing this
module does not import numba)."""
from __future__ import annotations

# -- solid kernel (kernels.solid) ------------------------------------------------------------
#: law kinds of the solid kernel
ELASTIC, J2_LINEAR, RAMBERG_OSGOOD = 0, 1, 2
#: slots of the solid law vector (8,): bulk and shear moduli, J2_LINEAR's SIGMAY and H,
#: RAMBERG_OSGOOD's log-coefficient, exponent, Newton tolerance and iteration cap
SOLID_K, SOLID_G, SOLID_SIGMAY, SOLID_H, SOLID_A, SOLID_N, SOLID_TOL, SOLID_MAXIT = range(8)
SOLID_VECTOR = 8
#: per-element flags written by the solid kernel
OK, BAD_DET_F, RETURN_MAP_FAILED = 0, 1, 2
#: J2: relative margin above the current yield stress for a point to count as plastic (a point
#: re-evaluated at its converged state, a zero increment, stays elastic despite round-off)
YIELD_RTOL = 1e-12
#: RAMBERG_OSGOOD's local Newton stops after a Newton step d with ``quad d^2 <= tol``: the
#: error of the next iterate is below ``quad d^2``.  Newton from the right on a convex
#: increasing g has error e_k <= 2 d_k (g' varies by at most a factor 2 on the bracket) and
#: e_k+1 = g''/(2 g') e_k^2 with g''/g' <= 1 in y = ln P (g' = 1 + r, g'' = r + r^2/N, r < 1)
#: and <= (1 + N)/2 in x = ln q (g' = N + s, g'' = s + s^2, s <= N): quad 2 and 1 + N.
QUAD_Y = 2.0


def quad_x(n: float) -> float:
    """The x = ln q branch's factor ``quad`` (see ``QUAD_Y``) for the exponent ``n``."""
    return 1.0 + n

# -- contact kernel (kernels.contact) --------------------------------------------------------
#: COULOMB: a point with ``f >= -ON_SURFACE_RTOL (radius + |tau|)`` starts on the yield surface
ON_SURFACE_RTOL = 1e-10
#: slots of the COULOMB law vector: penalties, the loading indicator, whether a softening
#: snap-back is possible, the shear limit TAUMAX (inf: none), the counts of breaks and table
#: rows, whether a form is smooth (exponential: the return iterates), the smallest length of an
#: exponential form (the dissipation's panels), then each of B and phi as four slots
#: ``kind, v0, a, c``: LINEAR ``v0, slope, kink``; EXP ``v0, v_inf, lamc``; TABLE ``v0, -, -``
(COULOMB_KP, COULOMB_KT, COULOMB_CLASSICAL, COULOMB_PREDICTOR, COULOMB_SNAP, COULOMB_TAUMAX,
 COULOMB_NBREAK, COULOMB_NTABLE, COULOMB_SMOOTH, COULOMB_SCALE) = range(10)
COULOMB_B_FORM, COULOMB_PHI_FORM = 10, 14
#: the fixed part; after it, variable-length: the breaks (sorted lam where a derivative jumps,
#: NBREAK), then with a table: its lam rows, B's values and slopes, phi's values and slopes
#: (NTABLE each)
COULOMB_VECTOR = 18
#: form kinds
FORM_LINEAR, FORM_EXP, FORM_TABLE = 0, 1, 2
#: COULOMB with an exponential form: the return's safeguarded Newton stops when a step is below
#: this times (|lam| + the slip scale), or after RETURN_MAXIT iterations (bisection keeps it
#: inside its bracket); the dissipation's 8-point Gauss-Legendre panels are at most
#: PANEL_LENGTH times the smallest LAMC long (relative error below 1e-18 on an exponential),
#: at most MAX_PANELS per piece
RETURN_XTOL = 4e-16
RETURN_MAXIT = 60
PANEL_LENGTH = 2.0
MAX_PANELS = 64
#: COULOMB with TAUMAX: bisection steps locating where the cap takes over inside a dissipation
#: piece
CAP_BISECTIONS = 60
#: order of the tangent rows of the Coulomb point update
TAN_KEYS = ("lam_d", "tau_d", "lam_du", "tau_du", "lam_v", "tau_v", "lam_tau", "tau_tau",
            "lam_lam", "tau_lam", "p_d", "p_u", "tau_u", "lam_u")
