"""Hand-written C, written once and compiled beside each generated module (native/build.py
finds it through ``deltagen.paths.runtime_dir()``): ``deltagen_linalg`` (small dense linear
algebra and the rotation logarithm) and ``deltagen_ik_newton`` (the damped Newton solver of
numerical IK, called by each arm's generated ``deltagen_<arm>_ik_newton`` wrapper) and
``deltagen_limits.h`` (header only: a revolute joint's value fitted into its limits, called
by the generated closed-form ``deltagen_<arm>_ik_all``) and ``deltagen_encoder.h`` (header
only: encoder readings <-> crank angles of a delta robot with encoder offsets, called by the
wrappers of `deltagen export`, templates/robot.c.j2), and ``deltagen_general6r`` with
``deltagen_eigen`` (the eigen step of the general-6R inverse kinematics, native/general6r.py).

``deltagen_hexapod_fk`` is the hexapod's forward kinematics by damped Newton, called by the
generated ``deltagen_hexapod_fk`` wrapper with the module's jacobian kernel.

Generated code calls runtime code, never the other way. No Python lives here.
"""
