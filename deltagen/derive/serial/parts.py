"""Which kernels each part of a new arm's module holds: data only (no SymPy), so the
build stage (native/serial.py) reads it without importing the derivations."""

#: The parts a new arm's module is built in (native/serial.py; for a short cold load): each
#: is rendered and compiled on the first call of one of its kernels, and derives only its
#: own kernels. "first": what a new arm loads with (the numerical IK's evaluation too);
#: "later": the rest of the kinematics (a UR5's closed-form ik_all is most of it);
#: "dynamics": the torques of a motion (inverse dynamics) and of gravity, a fifth of the
#: dynamics' SymPy for a Panda; "mass": M and h and the forward dynamics (its C wrapper
#: calls mass_matrix and nonlinear_effects of the same module); "coriolis": the
#: Christoffel matrix, as much SymPy as the other four together. ``all`` (what
#: `deltagen generate` writes) has every kernel in its own order (ArmKernels.all).
PARTS = {
    "first": ("fk", "frames", "jacobian", "fk_jacobian"),
    "later": ("jacobian_dot", "ik_all"),
    "dynamics": ("inverse_dynamics", "gravity_torque"),
    "mass": ("mass_matrix", "nonlinear_effects"),
    "coriolis": ("coriolis",),
}
