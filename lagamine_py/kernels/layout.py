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

# -- contact kernel (kernels.contact) --------------------------------------------------------
#: COULOMB: a point with ``f >= -ON_SURFACE_RTOL (radius + |tau|)`` starts on the yield surface
ON_SURFACE_RTOL = 1e-10
#: slots of the COULOMB law vector (12,): penalties, friction and adhesion with their slopes,
#: the loading indicator, the finite clipping kinks (at most two, their count) and whether a
#: softening snap-back is possible
(COULOMB_KP, COULOMB_KT, COULOMB_PHI, COULOMB_B, COULOMB_HPHI, COULOMB_HB, COULOMB_CLASSICAL,
 COULOMB_PREDICTOR, COULOMB_K1, COULOMB_K2, COULOMB_NK, COULOMB_SNAP) = range(12)
COULOMB_VECTOR = 12
#: order of the tangent rows of the Coulomb point update
TAN_KEYS = ("lam_d", "tau_d", "lam_du", "tau_du", "lam_v", "tau_v", "lam_tau", "tau_tau",
            "lam_lam", "tau_lam", "p_d", "p_u", "tau_u", "lam_u")
