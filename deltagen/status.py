"""Per-point status codes shared by the generated C core and the numpy reference.

The values are part of the C ABI (see generated/delta_kinematics.h): keep them in sync
with the ``DELTAGEN_*`` constants the templates emit from :data:`STATUS_NAMES`.
"""

OK = 0
UNREACHABLE = 1  # spheres do not meet (fk) / target out of reach of a crank (ik)
SINGULAR = 2  # det J_p ~ 0 (fk level), a J_q diagonal entry ~ 0 (ik), collinear centres
INVALID = 3  # a non-finite input value

STATUS_NAMES = {
    OK: "OK",
    UNREACHABLE: "UNREACHABLE",
    SINGULAR: "SINGULAR",
    INVALID: "INVALID",
}

#: Default relative threshold below which a pose is called singular. Quantities are
#: normalised by the robot's size: |det J_p| / (8 l_b^3) and |J_q,ii| / (2 l_a l_b).
SINGULAR_TOL = 1e-9

#: Relative definiteness threshold of a mass matrix (forward dynamics): SINGULAR when a
#: Cholesky pivot L_jj^2 is not above MASS_MATRIX_TOL times the largest diagonal entry.
MASS_MATRIX_TOL = 1e-12
