"""Serial chains, derived symbolically: ``chain`` (link transforms, fk,
Jacobians), ``ik_closed_form`` (closed-form inverse kinematics written as SymPy statements
with the arm's constants) and ``kernels`` (the batched kernels of one arm).
"""
