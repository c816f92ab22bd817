"""The hexapod (Stewart-Gough platform), derived symbolically: ``symbols`` (the pose, the
joints as struct parameters), ``legs`` (leg vectors, lengths, the leg-length Jacobian and
the joint angles) and ``kernels`` (the batched kernels built from them). The forward
kinematics is numerical (damped Newton, codegen/runtime/deltagen_hexapod_fk.c) on the
``jacobian`` kernel; nothing here solves.
"""
