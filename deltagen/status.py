"""Per-point status codes shared by the generated C core and the numpy reference.

The values are part of the C ABI (see generated/delta_kinematics.h): keep them in sync
with the ``DELTAGEN_*`` constants the templates emit from :data:`STATUS_NAMES`.
"""

OK = 0
UNREACHABLE = 1  # spheres do not meet (fk) / target out of reach of a crank (ik)
SINGULAR = 2  # det J_p ~ 0 (fk level), a J_q diagonal entry ~ 0 (ik), collinear centres
INVALID = 3  # a non-finite input value, or finite inputs whose outputs are not finite

# The finite-output rule, the same in every kernel (deltagen.codegen.lowering.guard_outputs
# for the generated C, the numpy reference and the solvers): a row is OK only if every output
# is finite. A row whose outputs, apart from the NaNs its status explains (e.g. the rates of
# a SINGULAR fk row), are not all finite is INVALID, with all its outputs NaN: finite but
# huge inputs (a target 1e155 m away, rates of 1e155) overflow inside the arithmetic.

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
